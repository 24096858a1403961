//! What granval refuses on the file system and its command line (docs/commands.md "What granval
//! refuses"): output directories that are not granval's own, files that are not regular
//! or too large, switches that are not switches, a closed stdout, names and paths that
//! could only be meant one way but were taken another. Each probe is what a careless or
//! hostile user did; each must end with exit 2 and a message naming the path or value
//! and why — and nothing the user owns may be gone afterwards.

mod common;

use common::{expect, text};

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Runs `c` to its end, or kills it after `secs` and fails: a probe that would hang (a
/// FIFO read) must fail the test, not stall the suite.
fn within(mut c: Command, secs: u64) -> Output {
    let mut child = c
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            return child.wait_with_output().unwrap();
        }
        if start.elapsed() > Duration::from_secs(secs) {
            let _ = child.kill();
            let o = child.wait_with_output().unwrap();
            panic!(
                "granval still ran after {secs} s (a read that never ends?):\n{}",
                text(&o)
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn case(rel: &str) -> PathBuf {
    common::root().join(rel)
}

/// Every file under `dir` (relative path -> content), to show nothing was touched.
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    fn walk(root: &Path, d: &Path, out: &mut Vec<(PathBuf, Vec<u8>)>) {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                out.push((
                    p.strip_prefix(root).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                ));
            }
        }
    }
    let mut v = Vec::new();
    walk(dir, dir, &mut v);
    v.sort();
    v
}

// ---- output directories --------------------------------------------------------------

/// `run CASE --out DIR --force` where DIR holds the case file: refused, the case file and
/// its neighbours intact (it used to delete them and exit 0). Same for `deck -o`.
#[test]
fn force_never_clears_a_directory_holding_the_case_file() {
    let d = tempfile::tempdir().unwrap();
    let c = d.path().join("spin.toml");
    std::fs::copy(case("cases/micro/spin.toml"), &c).unwrap();
    std::fs::write(d.path().join("notes.txt"), "mine").unwrap();
    let before = snapshot(d.path());
    for args in [["run", "--out"], ["deck", "-o"]] {
        let o = common::granval()
            .arg(args[0])
            .arg(&c)
            .arg(args[1])
            .arg(d.path())
            .arg("--force")
            .output()
            .unwrap();
        expect(&o, 2, &["spin.toml", "an input of this command"]);
        // Its parent holds it too.
        let o = common::granval()
            .arg(args[0])
            .arg(&c)
            .arg(args[1])
            .arg(d.path().parent().unwrap())
            .arg("--force")
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    }
    assert_eq!(snapshot(d.path()), before);
}

/// `compare ... --report . --force` (and `..`): the current directory and its ancestors
/// are never output directories; nothing in them is deleted.
#[test]
fn force_never_clears_the_current_directory() {
    let d = tempfile::tempdir().unwrap();
    let cwd = d.path().join("work");
    std::fs::create_dir_all(cwd.join(".git")).unwrap();
    std::fs::write(cwd.join("thesis.tex"), "mine").unwrap();
    let before = snapshot(d.path());
    for (report, why) in [(".", "the current directory"), ("..", "holds the current")] {
        let o = common::granval()
            .current_dir(&cwd)
            .arg("compare")
            .arg(case("cases/micro/spin.toml"))
            .args(["--reference"])
            .arg(common::root().join("reference"))
            .args(["--report", report, "--force"])
            .output()
            .unwrap();
        expect(&o, 2, &[&format!("--report {report}"), why]);
    }
    assert_eq!(snapshot(d.path()), before);
}

/// The reference store (a copy here) is neither an output directory, nor holds one, nor
/// sits inside one; the records are untouched.
#[test]
fn the_reference_store_is_never_an_output_directory() {
    let d = tempfile::tempdir().unwrap();
    let refs = d.path().join("refs");
    let rec = refs.join("micro/spin");
    std::fs::create_dir_all(&rec).unwrap();
    for e in std::fs::read_dir(case("reference/micro/spin")).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), rec.join(e.file_name())).unwrap();
    }
    let before = snapshot(&refs);
    for (report, why) in [
        (refs.clone(), "inside the reference store"),
        (refs.join("micro/new"), "inside the reference store"),
        (d.path().to_path_buf(), "holds the reference store"),
    ] {
        let o = common::granval()
            .args(["compare", "cases/micro/spin.toml", "--reference"])
            .arg(&refs)
            .arg("--report")
            .arg(&report)
            .arg("--force")
            .output()
            .unwrap();
        expect(&o, 2, &[why]);
    }
    assert_eq!(snapshot(&refs), before);
    assert!(!refs.join("micro/new").exists());
}

/// `analyze DECK --report DECK --force` used to empty the deck before reading it; a
/// report inside the deck directory would mix into it. Both refused, the deck intact.
#[test]
fn analyze_never_writes_into_its_deck_directory() {
    let d = tempfile::tempdir().unwrap();
    let deck = d.path().join("deck");
    let o = common::granval()
        .args(["deck", "cases/micro/spin.toml", "-o"])
        .arg(&deck)
        .output()
        .unwrap();
    expect(&o, 0, &[]);
    let before = snapshot(&deck);
    for (report, why) in [
        (deck.clone(), "holds"),
        (
            deck.join("report"),
            "inside the deck directory being analysed",
        ),
    ] {
        let o = common::granval()
            .arg("analyze")
            .arg(&deck)
            .arg("--report")
            .arg(&report)
            .arg("--force")
            .output()
            .unwrap();
        expect(&o, 2, &[why]);
    }
    assert_eq!(snapshot(&deck), before);
}

/// `check --cases D --report D --force` used to delete every case file; `--runs D
/// --report D` would read and overwrite at once.
#[test]
fn check_never_writes_over_its_cases_or_runs() {
    let d = tempfile::tempdir().unwrap();
    let cases = d.path().join("cases");
    std::fs::create_dir_all(cases.join("suites")).unwrap();
    std::fs::create_dir_all(cases.join("micro")).unwrap();
    std::fs::copy(case("cases/micro/spin.toml"), cases.join("micro/spin.toml")).unwrap();
    std::fs::write(
        cases.join("suites/s.toml"),
        "description = \"one\"\n[[case]]\npath = \"micro/spin.toml\"\n",
    )
    .unwrap();
    let before = snapshot(&cases);
    for report in [cases.clone(), cases.join("micro")] {
        let o = common::granval()
            .args(["check", "--suite", "s", "--cases"])
            .arg(&cases)
            .arg("--report")
            .arg(&report)
            .arg("--force")
            .output()
            .unwrap();
        expect(&o, 2, &["an input of this command"]);
    }
    let runs = d.path().join("runs");
    std::fs::create_dir(&runs).unwrap();
    let o = common::granval()
        .args(["check", "--suite", "s", "--cases"])
        .arg(&cases)
        .arg("--runs")
        .arg(&runs)
        .arg("--report")
        .arg(&runs)
        .arg("--force")
        .output()
        .unwrap();
    expect(&o, 2, &["the --runs directory"]);
    assert_eq!(snapshot(&cases), before);
}

/// Two runs on one `--report` do not both claim success: a report directory whose lock
/// is held by a running process is refused naming the lock and the pid; a lock left by a
/// process that no longer runs is said to be stale and taken. Two real compares started
/// together: exactly one succeeds.
#[test]
fn one_report_directory_one_run() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("r");
    std::fs::create_dir(&out).unwrap();
    // This test process holds the lock (its pid and start time, as granval writes them).
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap();
    let start: u64 = stat[stat.rfind(')').unwrap() + 1..]
        .split_whitespace()
        .nth(19)
        .unwrap()
        .parse()
        .unwrap();
    let pid = std::process::id();
    let lock = out.join(".granval-lock");
    std::fs::write(
        &lock,
        format!("pid {pid}\nstart {start}\ncommand granval check\n"),
    )
    .unwrap();
    let compare = |out: &Path| {
        let mut c = common::granval();
        c.args([
            "compare",
            "cases/micro/spin.toml",
            "--reference-mode",
            "recorded",
            "--report",
        ])
        .arg(out);
        c
    };
    let o = compare(&out).output().unwrap();
    expect(&o, 2, &[&format!("pid {pid}"), ".granval-lock", "in use"]);
    assert!(!out.join("report.json").exists());
    // The process is gone (a pid above Linux's pid_max).
    std::fs::write(&lock, "pid 4194304\nstart 1\ncommand granval check\n").unwrap();
    let o = compare(&out).output().unwrap();
    expect(&o, 0, &["no longer runs"]);
    assert!(!lock.exists(), "the lock outlived its run");

    let together = d.path().join("together");
    let quiet = |mut c: Command| {
        c.stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap()
    };
    let (a, b) = (quiet(compare(&together)), quiet(compare(&together)));
    let mut codes = [a, b].map(|c| c.wait_with_output().unwrap().status.code());
    codes.sort();
    assert_eq!(codes, [Some(0), Some(2)], "both claimed the same report");
}

/// `stress --reuse` and `check --reuse` read only a directory granval wrote (its marker).
#[test]
fn reuse_needs_a_directory_granval_wrote() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("snapshots.txt"), "hand-made").unwrap();
    let o = common::granval()
        .args(["stress", "cases/penetration/ci.toml", "--reuse", "--out"])
        .arg(d.path())
        .output()
        .unwrap();
    expect(&o, 2, &["--reuse", ".granval-output"]);
    // `check --reuse` as well; and it cannot be asked to clear the directory too.
    let o = common::granval()
        .args(["check", "--suite", "ci", "--reuse", "--report"])
        .arg(d.path())
        .output()
        .unwrap();
    expect(&o, 2, &["--reuse", ".granval-output"]);
    let o = common::granval()
        .args(["check", "--suite", "ci", "--reuse", "--force", "--report"])
        .arg(d.path())
        .output()
        .unwrap();
    expect(&o, 2, &["--reuse", "--force"]);
    assert_eq!(
        std::fs::read_to_string(d.path().join("snapshots.txt")).unwrap(),
        "hand-made"
    );
}

// ---- bounded reads -------------------------------------------------------------------

/// `validate /dev/zero` read until memory ran out (exit 134); a FIFO blocked forever.
#[test]
fn validate_refuses_devices_and_fifos_at_once() {
    let mut c = common::granval();
    c.args(["validate", "/dev/zero"]);
    let o = within(c, 30);
    expect(&o, 2, &["/dev/zero", "character device"]);
    let d = tempfile::tempdir().unwrap();
    let fifo = d.path().join("case.toml");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let mut c = common::granval();
    c.arg("validate").arg(&fifo);
    expect(&within(c, 30), 2, &["case.toml", "FIFO"]);
    // Too large to be a case file (sparse: no disk used).
    let big = d.path().join("big.toml");
    std::fs::File::create(&big)
        .unwrap()
        .set_len(20 << 20)
        .unwrap();
    let mut c = common::granval();
    c.arg("validate").arg(&big);
    expect(
        &within(c, 30),
        2,
        &["big.toml", "20971520 bytes", "a case file"],
    );
}

/// A sealed record file that is a FIFO, or a symlink to /dev/zero, and a seal that is a
/// symlink to /dev/zero: each refused within seconds, naming the file (it used to hang
/// or read until the abort).
#[test]
fn a_record_that_is_not_regular_files_is_refused_within_seconds() {
    let zero = |p: &Path| std::os::unix::fs::symlink("/dev/zero", p).unwrap();
    let fifo = |p: &Path| {
        assert!(Command::new("mkfifo").arg(p).status().unwrap().success());
    };
    type Make = fn(&Path);
    let probes: [(&str, Make, &str); 3] = [
        ("dump.granval", fifo, "FIFO"),
        ("dump.granval", zero, "character device"),
        ("seal.json", zero, "character device"),
    ];
    for (file, make, what) in probes {
        let refs = tempfile::tempdir().unwrap();
        let rec = refs.path().join("micro/head-on-e05");
        std::fs::create_dir_all(&rec).unwrap();
        for e in std::fs::read_dir(case("reference/micro/head-on-e05")).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), rec.join(e.file_name())).unwrap();
        }
        std::fs::remove_file(rec.join(file)).unwrap();
        make(&rec.join(file));
        let out = tempfile::tempdir().unwrap();
        let mut c = common::granval();
        c.args([
            "compare",
            "cases/micro/head-on-e05.toml",
            "--reference-mode",
            "recorded",
            "--reference",
        ])
        .arg(refs.path())
        .arg("--report")
        .arg(out.path());
        let o = within(c, 60);
        assert_eq!(o.status.code(), Some(2), "{file}: {}", text(&o));
        let report = std::fs::read_to_string(out.path().join("report.json")).unwrap();
        assert!(
            report.contains(file) && report.contains(what),
            "{file}: {report}"
        );
    }
}

/// A full disk used to say "No space left on device" without a path and leave a 0-byte
/// report.json. On a 64 KiB tmpfs the run's outputs fill the disk: the error names the
/// report file that could not be written, and no report.json (whole or truncated) and
/// no temporary file is left. Mounting needs root: elsewhere this prints SKIP (the error
/// path is unit-tested in `rundata::fsio` with a file where a directory is expected).
#[test]
fn a_full_disk_names_the_path_and_leaves_no_report() {
    let d = tempfile::tempdir().unwrap();
    let mounted = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=64k", "tmpfs"])
        .arg(d.path())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !mounted {
        eprintln!(
            "[a_full_disk_names_the_path_and_leaves_no_report] SKIP: cannot mount a tmpfs here (not root)"
        );
        return;
    }
    struct Unmount(PathBuf);
    impl Drop for Unmount {
        fn drop(&mut self) {
            let _ = Command::new("umount").arg(&self.0).status();
        }
    }
    let _unmount = Unmount(d.path().to_path_buf());
    let out = d.path().join("r");
    let o = common::granval()
        .args([
            "compare",
            "cases/micro/spin.toml",
            "--reference-mode",
            "recorded",
            "--report",
        ])
        .arg(&out)
        .output()
        .unwrap();
    expect(
        &o,
        2,
        &["cannot write", &out.display().to_string(), "No space left"],
    );
    assert!(!out.join("report.json").exists());
    let names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        names
            .iter()
            .all(|n| !n.contains(".tmp-") && n != ".granval-lock"),
        "{names:?}"
    );
}

// ---- switches ------------------------------------------------------------------------

/// GRANVAL_REQUIRE_LIVE=true (or yes, TRUE, " 1") without the engine is refused; it used
/// to be ignored (only "1" counted) and the run passed on the record. "0" and "" keep
/// the recorded fallback (the control), and a value that is no switch is an error
/// naming the variable.
#[test]
fn require_live_takes_the_usual_spellings() {
    let compare = |value: &str| {
        let out = tempfile::tempdir().unwrap();
        // No liggghts, lmp or mpirun on this PATH: the engine is absent.
        let o = common::granval()
            .env("PATH", "/nonexistent")
            .env("GRANVAL_REQUIRE_LIVE", value)
            .args(["compare", "cases/micro/head-on-e05.toml", "--report"])
            .arg(out.path())
            .output()
            .unwrap();
        (o, out)
    };
    for v in ["true", "yes", "TRUE", " 1", "on"] {
        let (o, _out) = compare(v);
        expect(&o, 2, &["live engines are required"]);
    }
    for v in ["0", "", "false"] {
        let (o, _out) = compare(v);
        expect(&o, 0, &["RECORDED"]);
    }
    let (o, out) = compare("ture");
    expect(&o, 2, &["GRANVAL_REQUIRE_LIVE", "\"ture\"", "not a switch"]);
    assert!(!out.path().join("report.json").exists());
}

// ---- a closed stdout -----------------------------------------------------------------

/// `granval check --suite micro | head -0`: the reader is gone before granval prints.
/// It used to panic (exit 101 with a backtrace); it ends quietly with its verdict.
#[test]
fn a_closed_stdout_ends_quietly() {
    let out = tempfile::tempdir().unwrap();
    let mut child = common::granval()
        .args([
            "check",
            "--suite",
            "micro",
            "--only",
            "cases/micro/spin.toml",
            "--reference-mode",
            "recorded",
            "--report",
        ])
        .arg(out.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(out.path().join("report.json").exists());
}

// ---- names and paths -----------------------------------------------------------------

/// A case named like a report file would turn the end of the run into "Is a
/// directory": refused when the case is read.
#[test]
fn a_case_named_like_a_report_file_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let c = d.path().join("c.toml");
    let t = std::fs::read_to_string(case("cases/micro/spin.toml")).unwrap();
    std::fs::write(
        &c,
        t.replacen("name = \"spin\"", "name = \"report.json\"", 1),
    )
    .unwrap();
    let o = common::granval().arg("validate").arg(&c).output().unwrap();
    expect(&o, 2, &["case.name", "report.json", "writes beside"]);
}

/// `--only` names a file: `./cases/...` and an absolute path are the suite's entry; the
/// same case twice is an error naming both; a file outside the suite is not a case of it.
#[test]
fn only_matches_the_file_and_refuses_duplicates() {
    let abs = case("cases/micro/spin.toml");
    for only in [
        "./cases/micro/spin.toml".to_string(),
        abs.display().to_string(),
    ] {
        let out = tempfile::tempdir().unwrap();
        let o = common::granval()
            .args(["check", "--suite", "micro", "--reference-mode", "recorded"])
            .args(["--only", &only, "--report"])
            .arg(out.path())
            .output()
            .unwrap();
        expect(&o, 0, &[]);
        assert!(out.path().join("spin/native/particles.csv").exists());
    }
    let out = tempfile::tempdir().unwrap();
    let o = common::granval()
        .args([
            "check",
            "--suite",
            "micro",
            "--only",
            "cases/micro/spin.toml",
        ])
        .args(["--only", "./cases/micro/spin.toml", "--report"])
        .arg(out.path())
        .output()
        .unwrap();
    expect(
        &o,
        2,
        &[
            "--only cases/micro/spin.toml and --only ./cases/micro/spin.toml",
            "same case",
        ],
    );
}

/// `--runs /nonexistent` was accepted silently; `--suite ../../x` read any TOML on disk.
#[test]
fn runs_must_exist_and_suites_are_names() {
    let out = tempfile::tempdir().unwrap();
    let o = common::granval()
        .args([
            "check",
            "--suite",
            "micro",
            "--claims-only",
            "--runs",
            "/nonexistent/runs",
            "--report",
        ])
        .arg(out.path())
        .output()
        .unwrap();
    expect(&o, 2, &["--runs /nonexistent/runs", "no such directory"]);
    let o = common::granval()
        .args(["check", "--suite", "../../x", "--report"])
        .arg(out.path())
        .output()
        .unwrap();
    expect(&o, 2, &["../../x", "plain name"]);
}

/// A case file listed twice in a suite (a glob and its own entry) ran twice into one
/// directory: an error naming both entries.
#[test]
fn a_case_listed_twice_in_a_suite_is_refused() {
    let d = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(d.path().join("suites")).unwrap();
    std::fs::create_dir_all(d.path().join("micro")).unwrap();
    std::fs::copy(
        case("cases/micro/spin.toml"),
        d.path().join("micro/spin.toml"),
    )
    .unwrap();
    std::fs::write(
        d.path().join("suites/twice.toml"),
        "description = \"twice\"\n[[case]]\npath = \"micro/*.toml\"\n[[case]]\npath = \"micro/./spin.toml\"\n",
    )
    .unwrap();
    let out = tempfile::tempdir().unwrap();
    let o = common::granval()
        .args(["check", "--suite", "twice", "--cases"])
        .arg(d.path())
        .arg("--report")
        .arg(out.path())
        .output()
        .unwrap();
    expect(
        &o,
        2,
        &[
            "case[0].path = \"micro/*.toml\"",
            "case[1].path = \"micro/./spin.toml\"",
        ],
    );
}

/// A negative control whose perturbation is capped (restitution 1.0 + 0.05 = 1.0) runs
/// the case's own physics: "not applicable", said when the case is read, not "the
/// control did not bite" after the runs. head-on-e05's own control (restitution + 0.05)
/// on e = 1.0 is refused; on e = 0.9 it is accepted.
#[test]
fn a_clamped_control_is_not_applicable() {
    let d = tempfile::tempdir().unwrap();
    let base = std::fs::read_to_string(case("cases/micro/head-on-e05.toml")).unwrap();
    assert!(base.contains("perturbation = { restitution_shift = 0.05 }"));
    for (e, code) in [("1.0", 2), ("0.9", 0)] {
        let c = d.path().join(format!("e{e}.toml"));
        std::fs::write(
            &c,
            base.replace("restitution = 0.5", &format!("restitution = {e}")),
        )
        .unwrap();
        let o = common::granval().arg("validate").arg(&c).output().unwrap();
        if code == 2 {
            expect(
                &o,
                2,
                &[
                    "negative_control[0].perturbation.restitution_shift",
                    "not applicable",
                    "capped at 1",
                ],
            );
        } else {
            expect(&o, 0, &[]);
        }
    }
}

/// `--only` names a case file; a case's name given instead is refused with the file it
/// names (exit 2), for `reference verify` as for `check`, and a name that is no case of
/// the suite says only that no such file exists.
#[test]
fn only_with_a_case_name_names_the_case_file() {
    let run = |only: &str| {
        common::granval()
            .args(["reference", "verify", "--suite", "micro", "--only", only])
            .output()
            .unwrap()
    };
    let o = run("spin");
    expect(
        &o,
        2,
        &[
            "--only spin: no such case file",
            "--only cases/micro/spin.toml",
        ],
    );
    let o = run("no-such-case");
    expect(&o, 2, &["--only no-such-case: no such case file"]);
    assert!(!text(&o).contains("give the case file"), "{}", text(&o));
}
