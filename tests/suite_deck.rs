//! `granval deck --suite S --scheduler slurm`, `granval status` and `granval analyze` of
//! the suite directory, without Slurm (docs/cluster.md): the layout, units.tsv,
//! submit.sh run against a stand-in `sbatch` that records what it was asked, the state
//! of units whose outputs are the sealed LIGGGHTS records of their cases (done), cut
//! short (failed) or absent (missing), and the refusal of an edited deck or case.
//! `.ci/slurm-test` runs the same directory through a real one-node Slurm.

mod common;

use common::{expect, granval, root, text};
use granval::experiments::suite_deck::{self, SuiteRecord};
use std::path::{Path, PathBuf};
use std::process::Output;

const MICRO: [&str; 2] = ["micro/head-on-e05.toml", "micro/plane-oblique.toml"];

/// The slurm-test suite's two micro cases as a suite directory `dir`, with `extra` args.
fn deck(dir: &Path, extra: &[&str]) -> Output {
    let mut c = granval();
    c.args([
        "deck",
        "--suite",
        "slurm-test",
        "--scheduler",
        "slurm",
        "-o",
    ])
    .arg(dir);
    for m in MICRO {
        c.arg("--only").arg(root().join("cases").join(m));
    }
    c.args(extra).output().unwrap()
}

/// Copies the sealed LIGGGHTS outputs of a micro case's record (the real engine's run
/// of this very deck) into the unit directory `unit`.
fn copy_record_outputs(case: &str, unit: &Path) {
    let rec = root().join("reference/micro").join(case);
    for f in ["dump.granval", "log.liggghts"] {
        std::fs::copy(rec.join(f), unit.join(f)).unwrap();
    }
}

/// Marks unit `index` done as run-unit.sh does after the engine exited 0.
fn mark_done(dir: &Path, index: usize) {
    std::fs::write(
        dir.join("state").join(format!("{index}.done")),
        "2026-11-27T00:00:00Z test 1 s\n",
    )
    .unwrap();
}

/// A stand-in `sbatch` that appends its arguments to `log` and answers job ids 101, 102, ...
fn fake_sbatch(bin: &Path, log: &Path) {
    std::fs::create_dir_all(bin).unwrap();
    let script = format!(
        "#!/bin/bash\nn=$(( $(cat {log:?} 2>/dev/null | wc -l) + 101 ))\nprintf '%s\\n' \"$*\" >>{log:?}\necho \"$n;test\"\n"
    );
    let p = bin.join("sbatch");
    std::fs::write(&p, script).unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
}

/// Runs submit.sh of `dir` with the stand-in sbatch first on PATH and no Slurm state;
/// returns its output and the sbatch calls it made.
fn submit(dir: &Path, bin: &Path, log: &Path, args: &[&str]) -> (Output, Vec<String>) {
    let _ = std::fs::remove_file(log);
    let o = std::process::Command::new(dir.join("submit.sh"))
        .args(args)
        .env(
            "PATH",
            format!("{}:{}", bin.display(), std::env::var("PATH").unwrap()),
        )
        .env("GRANVAL", env!("CARGO_BIN_EXE_granval"))
        .env_remove("SLURM_CONF")
        .output()
        .unwrap();
    let calls = std::fs::read_to_string(log)
        .unwrap_or_default()
        .lines()
        .map(String::from)
        .collect();
    (o, calls)
}

fn status(dir: &Path) -> Output {
    granval().arg("status").arg(dir).output().unwrap()
}

#[test]
fn a_suite_directory_holds_each_units_deck_units_tsv_suite_json_and_submit_sh() {
    let t = tempfile::tempdir().unwrap();
    let dir = t.path().join("suite");
    let o = deck(
        &dir,
        &["--np", "3", "--partition", "debug", "--time", "auto"],
    );
    expect(&o, 0, &["liggghts: 2 unit(s)", "submit.sh"]);

    let rows = suite_deck::read_units(&dir).unwrap();
    assert_eq!(rows.len(), 2);
    for (r, case) in rows.iter().zip(["head-on-e05", "plane-oblique"]) {
        assert_eq!(r.id, case);
        assert_eq!(r.case, case);
        assert_eq!(r.engine, "liggghts");
        assert_eq!(r.dir, format!("cases/{case}"));
        assert_eq!(
            r.command,
            "mpirun -np 3 liggghts -in in.granval -log log.liggghts"
        );
        assert_eq!(
            (r.log.as_str(), r.output.as_str()),
            ("log.liggghts", "dump.granval")
        );
        // The unit directory is the case's `granval deck` directory.
        for f in ["case.toml", "README.txt", "in.granval", "data.granval"] {
            assert!(dir.join(&r.dir).join(f).is_file(), "{}/{f}", r.dir);
        }
    }

    let rec: SuiteRecord = suite_deck::read_record(&dir).unwrap().unwrap();
    assert_eq!(rec.suite, "slurm-test");
    assert_eq!(rec.np, 3);
    assert_eq!(rec.partition.as_deref(), Some("debug"));
    assert_eq!(rec.only.len(), 2);
    assert_eq!(rec.granval_version, env!("CARGO_PKG_VERSION"));
    assert_eq!(rec.cases.len(), 2);
    assert!(
        rec.cases
            .iter()
            .all(|c| c.canonical_hash.len() == 64 && c.units == 1)
    );

    // submit.sh against a stand-in sbatch: one array over both units with the rank
    // count, time and partition asked, then the analysis after it.
    let (bin, log) = (t.path().join("bin"), t.path().join("sbatch.log"));
    fake_sbatch(&bin, &log);
    let (o, calls) = submit(&dir, &bin, &log, &[]);
    expect(
        &o,
        0,
        &["liggghts: array job 101, units 1,2", "analysis: job 102"],
    );
    assert_eq!(calls.len(), 2, "{calls:?}");
    let d = dir.display();
    for want in [
        "--array=1,2".to_string(),
        "--ntasks=3".into(),
        "--time=00:10:00".into(),
        "--partition=debug".into(),
        format!("--chdir={d}"),
        format!("--output={d}/state/%a.out"),
    ] {
        assert!(
            calls[0].split(' ').any(|a| a == want),
            "{want} not in {}",
            calls[0]
        );
    }
    assert!(
        calls[0].ends_with(&format!("{d}/run-unit.sh")),
        "{}",
        calls[0]
    );
    assert!(
        calls[1].contains("--dependency=afterany:101 "),
        "{}",
        calls[1]
    );
    assert!(
        calls[1].contains(&format!("analyze {d} --report {d}/report --force")),
        "{}",
        calls[1]
    );
    let jobs = std::fs::read_to_string(dir.join("state/jobs.tsv")).unwrap();
    assert_eq!(jobs, "liggghts\t101\nanalyze\t102\n");
}

#[test]
fn status_tells_done_failed_and_missing_units_and_submit_missing_takes_only_those_not_done() {
    let t = tempfile::tempdir().unwrap();
    let dir = t.path().join("suite");
    expect(&deck(&dir, &[]), 0, &[]);
    let unit = |case: &str| dir.join("cases").join(case);

    // Nothing ran: both missing, exit 1.
    expect(
        &status(&dir),
        1,
        &["0 done, 0 running, 0 failed, 2 missing"],
    );

    // Unit 1 with its record's outputs and run-unit.sh's marker: done. Unit 2 cut short:
    // its log stops before the run ends and its dump is empty: failed, with the log's end.
    copy_record_outputs("head-on-e05", &unit("head-on-e05"));
    mark_done(&dir, 1);
    let log =
        std::fs::read_to_string(root().join("reference/micro/plane-oblique/log.liggghts")).unwrap();
    let cut = &log[..log.find("Loop time of").unwrap()];
    std::fs::write(unit("plane-oblique").join("log.liggghts"), cut).unwrap();
    std::fs::write(unit("plane-oblique").join("dump.granval"), "").unwrap();
    let o = status(&dir);
    expect(&o, 1, &["1 done, 0 running, 1 failed, 0 missing"]);
    let last = cut.lines().rev().find(|l| !l.trim().is_empty()).unwrap();
    assert!(text(&o).contains(last.trim()), "{}", text(&o));
    assert!(
        text(&o)
            .lines()
            .any(|l| l.contains("head-on-e05") && l.trim_end().ends_with("done")),
        "{}",
        text(&o)
    );

    // A done marker without complete outputs is not done (a run cut short after an
    // earlier success).
    mark_done(&dir, 2);
    expect(&status(&dir), 1, &["1 done, 0 running, 1 failed"]);

    // submit.sh --missing asks Slurm for unit 2 only; when it is done too, for nothing
    // but the analysis, which then waits for no array.
    let (bin, slog) = (t.path().join("bin"), t.path().join("sbatch.log"));
    fake_sbatch(&bin, &slog);
    let (o, calls) = submit(&dir, &bin, &slog, &["--missing"]);
    expect(&o, 0, &["units 2"]);
    assert!(calls[0].split(' ').any(|a| a == "--array=2"), "{calls:?}");
    copy_record_outputs("plane-oblique", &unit("plane-oblique"));
    expect(
        &status(&dir),
        0,
        &["2 done, 0 running, 0 failed, 0 missing"],
    );
    let (o, calls) = submit(&dir, &bin, &slog, &["--missing"]);
    expect(&o, 0, &["liggghts: every unit is done"]);
    assert_eq!(calls.len(), 1, "{calls:?}");
    assert!(!calls[0].contains("--dependency"), "{}", calls[0]);

    // A finished unit runs no more: run-unit.sh does not start the engine (here a
    // stand-in `liggghts` that would leave a file behind).
    let started = t.path().join("engine-started");
    let stub = bin.join("liggghts");
    std::fs::write(&stub, format!("#!/bin/sh\ntouch {started:?}\nexit 1\n")).unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&stub, std::fs::Permissions::from_mode(0o755)).unwrap();
    let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap());
    let o = std::process::Command::new(dir.join("run-unit.sh"))
        .arg("1")
        .env("PATH", &path)
        .output()
        .unwrap();
    expect(&o, 0, &["is done: nothing to run"]);
    assert!(!started.exists());
    // The control: a unit not done starts the engine (which fails here): exit 1, failed.
    std::fs::remove_file(dir.join("state/2.done")).unwrap();
    std::fs::write(unit("plane-oblique").join("dump.granval"), "").unwrap();
    let o = std::process::Command::new(dir.join("run-unit.sh"))
        .arg("2")
        .env("PATH", &path)
        .output()
        .unwrap();
    expect(&o, 1, &["FAILED"]);
    assert!(started.exists());
    expect(&status(&dir), 1, &["1 done, 0 running, 1 failed"]);
}

/// Exit code and report.json of `granval analyze DIR`.
fn analyze(dir: &Path, report: &PathBuf) -> (Output, String) {
    let o = granval()
        .args(["--quiet", "analyze"])
        .arg(dir)
        .arg("--report")
        .arg(report)
        .output()
        .unwrap();
    let json = std::fs::read_to_string(report.join("report.json")).unwrap_or_default();
    (o, json)
}

#[test]
fn analyze_of_a_suite_directory_refuses_an_edited_deck_or_case() {
    let t = tempfile::tempdir().unwrap();
    let dir = t.path().join("suite");
    expect(&deck(&dir, &[]), 0, &[]);
    for (i, case) in ["head-on-e05", "plane-oblique"].iter().enumerate() {
        copy_record_outputs(case, &dir.join("cases").join(case));
        mark_done(&dir, i + 1);
    }
    // The control: as written, with the engine's real outputs, every check passes.
    let (o, json) = analyze(&dir, &t.path().join("r0"));
    assert_eq!(o.status.code(), Some(0), "{}\n{json}", text(&o));
    assert!(json.contains("\"passed\": true"), "{json}");

    // One command added to a deck: exit 2, the deck named.
    let deck_file = dir.join("cases/head-on-e05/in.granval");
    let original = std::fs::read_to_string(&deck_file).unwrap();
    std::fs::write(&deck_file, original.replace("\nrun ", "\nrun 1\nrun ")).unwrap();
    let (o, json) = analyze(&dir, &t.path().join("r1"));
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(json.contains(&deck_file.display().to_string()), "{json}");
    std::fs::write(&deck_file, original).unwrap();

    // The case copied into the directory edited: refused before anything runs.
    let case_file = dir.join("cases/plane-oblique/case.toml");
    let case = std::fs::read_to_string(&case_file).unwrap();
    // A comment changes no physics: the canonical hash is the same, the analysis passes.
    std::fs::write(&case_file, case.clone() + "\n# a comment\n").unwrap();
    let (o, _) = analyze(&dir, &t.path().join("r2"));
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let changed = edit_a_number(&case);
    std::fs::write(&case_file, changed).unwrap();
    let (o, _) = analyze(&dir, &t.path().join("r3"));
    expect(&o, 2, &["the case was edited", "case.toml"]);
}

/// `case` with the first `duration = X` line's value doubled (a change of physics).
fn edit_a_number(case: &str) -> String {
    let mut out = Vec::new();
    let mut done = false;
    for l in case.lines() {
        if !done
            && let Some(v) = l.trim().strip_prefix("duration = ")
            && let Ok(x) = v.split_whitespace().next().unwrap_or("").parse::<f64>()
        {
            out.push(format!("duration = {:?}", 2.0 * x));
            done = true;
        } else {
            out.push(l.to_string());
        }
    }
    assert!(done, "no `duration = ` line in:\n{case}");
    out.join("\n") + "\n"
}

/// A suite entry with stress = true (contact snapshots) has no deck `granval deck`
/// writes: refused, naming it, before any case is prepared; `--suite` needs a scheduler.
#[test]
fn deck_suite_refuses_stress_entries_and_a_missing_scheduler() {
    let t = tempfile::tempdir().unwrap();
    let o = granval()
        .args(["deck", "--suite", "ci", "--scheduler", "slurm", "-o"])
        .arg(t.path().join("ci"))
        .output()
        .unwrap();
    expect(&o, 2, &["penetration/ci.toml", "stress = true", "--only"]);
    assert!(!t.path().join("ci/units.tsv").exists());
    let o = granval()
        .args(["deck", "--suite", "slurm-test", "-o"])
        .arg(t.path().join("x"))
        .output()
        .unwrap();
    expect(&o, 2, &["--scheduler"]);
}
