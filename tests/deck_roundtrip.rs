//! The deck round trip a user makes, end to end through the `granval` binary: `granval
//! deck CASE -o DIR`, the reference engine run by hand in DIR exactly as DIR's README
//! says, `granval analyze DIR` — which must give the very check values `granval
//! compare CASE` gives with the live engine. One small case of each kind that
//! `runner::analyze` serves (micro: LIGGGHTS; impact2d: LAMMPS under mpirun); the
//! penetration round trip is `tests/penetration_deck.rs`.
//!
//! Live only: without the engine the test says so and passes only when
//! GRANVAL_REQUIRE_LIVE is unset (a recorded run cannot stand in for a run by hand).

mod common;

use granval::report::Report;
use granval::rundata::provenance::EngineKind;
use std::path::Path;
use std::process::Command;

/// `granval ARGS`, which must exit with `code`; its stdout.
fn granval(args: &[&str], code: i32) -> String {
    let o = common::granval()
        .args(args)
        .output()
        .expect("granval starts");
    assert_eq!(
        o.status.code(),
        Some(code),
        "granval {}\nstdout:\n{}\nstderr:\n{}",
        args.join(" "),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn report(dir: &Path) -> Report {
    let p = dir.join("report.json");
    serde_json::from_str(&std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{e}")))
        .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// `granval ARGS --report DIR` and its report; the exit code must be the report's
/// (0 pass, 1 a failed gate, 2 an error).
fn with_report(args: &[&str], dir: &Path) -> Report {
    let mut all = args.to_vec();
    let d = dir.display().to_string();
    all.extend(["--report", &d]);
    let o = common::granval()
        .args(&all)
        .output()
        .expect("granval starts");
    let r = report(dir);
    let code = if r.errored {
        2
    } else if r.passed {
        0
    } else {
        1
    };
    assert_eq!(
        o.status.code(),
        Some(code),
        "granval {}\n{}",
        all.join(" "),
        String::from_utf8_lossy(&o.stderr)
    );
    r
}

/// Runs `argv` in `dir` as a person would, and panics with its output if it fails.
fn by_hand(dir: &Path, argv: &[&str]) {
    let o = Command::new(argv[0])
        .args(&argv[1..])
        .current_dir(dir)
        .output()
        .unwrap_or_else(|e| panic!("{}: {e}", argv[0]));
    assert!(
        o.status.success(),
        "`{}` in {} failed:\n{}\n{}",
        argv.join(" "),
        dir.display(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Same checks, in the same order, with bit-identical values and the same verdicts.
fn same_checks(analyzed: &Report, compared: &Report) {
    assert!(!compared.checks.is_empty());
    assert_eq!(
        analyzed
            .checks
            .iter()
            .map(|c| c.name.as_str())
            .collect::<Vec<_>>(),
        compared
            .checks
            .iter()
            .map(|c| c.name.as_str())
            .collect::<Vec<_>>()
    );
    for (a, c) in analyzed.checks.iter().zip(&compared.checks) {
        assert_eq!(a.status, c.status, "{}", a.name);
        assert!(
            a.value.to_bits() == c.value.to_bits() || (a.value.is_nan() && c.value.is_nan()),
            "{}: analyze {:e} vs compare {:e}",
            a.name,
            a.value,
            c.value
        );
        eprintln!("{}: {} = {:e} (both)", a.name, a.metric, a.value);
    }
    assert_eq!(analyzed.passed, compared.passed);
}

/// deck -> engine by hand (per the README) -> analyze, against compare.
/// `np`: the MPI ranks `run` uses; `compare` runs the engine with as many, because a
/// different domain decomposition changes the round-off, which a granular flow
/// amplifies. `edit`: also check that an edited deck is refused (it costs another
/// preparation of the units). `viz`: write the deck with `--viz N` and the files its
/// visualisation dump must leave (a glob's prefix and suffix, at least two frames).
fn round_trip(
    case: &str,
    engine: &str,
    run: &[&str],
    np: &str,
    outputs: &[&str],
    edit: bool,
    viz: Option<(&str, (&str, &str))>,
) {
    let tmp = tempfile::tempdir().unwrap();
    let t = |n: &str| tmp.path().join(n).display().to_string();
    let (deck, analyzed, compared) = (t("deck"), t("analyze"), t("compare"));
    let mut args = vec!["deck", case, "-o", &deck, "--engine", engine, "--np", "2"];
    if let Some((n, _)) = viz {
        args.extend(["--viz", n]);
    }
    granval(&args, 0);
    let deck = Path::new(&deck);
    let readme = std::fs::read_to_string(deck.join("README.txt")).unwrap();
    assert_eq!(
        readme.contains("\nVisualisation\n"),
        viz.is_some(),
        "{readme}"
    );
    // The README gives the commands this test runs (as root, mpirun also needs
    // --allow-run-as-root, which the README says), and the way back.
    let said: Vec<&str> = run
        .iter()
        .copied()
        .filter(|w| *w != "--allow-run-as-root")
        .collect();
    assert!(readme.contains(&said.join(" ")), "{readme}");
    assert!(
        readme.contains("granval analyze DIR --report OUT"),
        "{readme}"
    );
    let run_dirs: Vec<_> = std::fs::read_dir(deck)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_dir())
        .collect();
    let run_dirs = if run_dirs.is_empty() {
        vec![deck.to_path_buf()]
    } else {
        run_dirs
    };
    {
        let _mpi = common::mpi_lock();
        for d in &run_dirs {
            by_hand(d, run);
            for o in outputs {
                assert!(d.join(o).exists(), "{o} missing in {}", d.display());
            }
            if let Some((_, (prefix, suffix))) = viz {
                let frames = std::fs::read_dir(d)
                    .unwrap()
                    .filter_map(|e| e.ok()?.file_name().into_string().ok())
                    .filter(|f| f.starts_with(prefix) && f.ends_with(suffix))
                    .count();
                assert!(frames >= 2, "{frames} {prefix}*{suffix} in {}", d.display());
                // The first frame holds the particles with their radius, in the
                // engine's own format (legacy VTK, LAMMPS text dump).
                let first = std::fs::read_to_string(d.join(format!("{prefix}0{suffix}"))).unwrap();
                let header = if suffix == ".vtk" {
                    "DATASET POLYDATA"
                } else {
                    "ITEM: ATOMS id type radius x y z"
                };
                assert!(
                    first.contains(header) && first.contains("radius"),
                    "{first}"
                );
                if let (".vtk", Some(py)) = (suffix, common::vtk_python()) {
                    // As ParaView reads it: every particle, with every array.
                    let v = common::vtk_legacy_summary(&py, &d.join(format!("{prefix}0{suffix}")));
                    assert!(v["points"].as_u64().unwrap() >= 2, "{v}");
                    for a in ["f", "id", "omega", "radius", "type", "v"] {
                        assert!(
                            v["point_arrays"].as_array().unwrap().iter().any(|x| x == a),
                            "{a}: {v}"
                        );
                    }
                }
            }
        }
    }
    let c = with_report(
        &["compare", case, "--reference-mode", "live", "--np", np],
        Path::new(&compared),
    );
    let a = with_report(
        &["analyze", &deck.display().to_string()],
        Path::new(&analyzed),
    );
    assert!(!a.errored, "{:?}", a.checks);
    same_checks(&a, &c);
    assert!(
        a.runs[0].reference_source.starts_with("run directory"),
        "{:?}",
        a.runs
    );

    if !edit {
        return;
    }
    // A deck edited by hand is not the case's deck: analyze refuses it, naming the file.
    let d = &run_dirs[0];
    let name = run[run.iter().position(|w| *w == "-in").unwrap() + 1];
    let text = std::fs::read_to_string(d.join(name)).unwrap();
    let edited = text.replacen("\ntimestep ", "\ntimestep 1e-12 # was ", 1);
    assert_ne!(edited, text);
    std::fs::write(d.join(name), edited).unwrap();
    let edited = tmp.path().join("edited");
    let o = common::granval()
        .args(["analyze", &deck.display().to_string(), "--report"])
        .arg(&edited)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    // Read as plain JSON: an error check's value is NaN, written as null.
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(edited.join("report.json")).unwrap())
            .unwrap();
    assert_eq!(r["errored"], true);
    let why = r["checks"].to_string();
    assert!(
        why.contains(name) && why.contains("timestep 1e-12"),
        "{why}"
    );
}

#[test]
fn micro_deck_run_by_hand_analyzes_as_compare() {
    if !common::live(
        EngineKind::Liggghts,
        "micro_deck_run_by_hand_analyzes_as_compare",
    ) {
        common::engineless(
            "micro_deck_run_by_hand_analyzes_as_compare",
            "SKIPPED: the round trip needs LIGGGHTS run by hand",
        );
        return;
    }
    round_trip(
        "cases/micro/head-on-e05.toml",
        "liggghts",
        &["liggghts", "-in", "in.granval", "-log", "log.liggghts"],
        "1",
        &["dump.granval", "log.liggghts"],
        true,
        None,
    );
}

/// `granval deck --viz N`: the LIGGGHTS micro deck also writes legacy VTK of every
/// particle, and `analyze` accepts the deck because it declares the dump: the same check
/// values as `compare`. Then the dump edited (one more column) is another deck, refused.
#[test]
fn micro_deck_with_a_visualisation_dump_analyzes_as_compare() {
    let name = "micro_deck_with_a_visualisation_dump_analyzes_as_compare";
    if !common::live(EngineKind::Liggghts, name) {
        common::engineless(name, "SKIPPED: the round trip needs LIGGGHTS run by hand");
        return;
    }
    round_trip(
        "cases/micro/head-on-e05.toml",
        "liggghts",
        &["liggghts", "-in", "in.granval", "-log", "log.liggghts"],
        "1",
        &["dump.granval", "log.liggghts"],
        false,
        Some(("100", ("viz-", ".vtk"))),
    );
}

#[test]
fn impact2d_deck_run_by_hand_under_mpirun_analyzes_as_compare() {
    if !common::live(
        EngineKind::Lammps,
        "impact2d_deck_run_by_hand_under_mpirun_analyzes_as_compare",
    ) {
        common::engineless(
            "impact2d_deck_run_by_hand_under_mpirun_analyzes_as_compare",
            "SKIPPED: the round trip needs LAMMPS run by hand",
        );
        return;
    }
    // cases/impact2d/ci.toml at a third of its grains and run time, without its
    // negative control (tests/impact2d_runs.rs runs it in full): seconds per engine.
    let tmp = tempfile::tempdir().unwrap();
    let mut text = std::fs::read_to_string(common::root().join("cases/impact2d/ci.toml")).unwrap();
    for (from, to) in [
        ("name = \"ci\"", "name = \"ci-small\""),
        ("duration = 1000.0", "duration = 400.0"),
        ("count = 450", "count = 150"),
        ("length = 30.0", "length = 15.0"),
        ("diameter = 6.0", "diameter = 3.0"),
    ] {
        assert!(text.contains(from), "cases/impact2d/ci.toml lacks {from:?}");
        text = text.replacen(from, to, 1);
    }
    let text = &text[..text
        .find("[[negative_control]]")
        .expect("ci.toml has a control")];
    let case = tmp.path().join("ci-small.toml");
    std::fs::write(&case, text).unwrap();
    round_trip(
        &case.display().to_string(),
        "lammps",
        &[
            "mpirun",
            "--allow-run-as-root",
            "-np",
            "2",
            "lmp",
            "-in",
            "in.impact2d",
            "-log",
            "log.lammps",
        ],
        "2",
        &["intruder.txt", "snap.dump", "log.lammps"],
        false,
        Some(("500", ("viz-", ".lammpstrj"))),
    );
}

#[test]
fn deck_refuses_an_engine_that_is_not_the_cases_reference() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("d").display().to_string();
    let o = common::granval()
        .args([
            "deck",
            "cases/impact2d/ci.toml",
            "-o",
            &out,
            "--engine",
            "liggghts",
        ])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("cases/impact2d/ci.toml")
            && err.contains("--engine liggghts")
            && err.contains("lammps"),
        "{err}"
    );
    assert!(!Path::new(&out).exists());
}

#[test]
fn validate_prints_the_derived_quantities_and_runs_nothing() {
    let out = granval(&["validate", "cases/micro/head-on-e05.toml"], 0);
    let line = |out: &str, label: &str, value: &str| {
        assert!(
            out.lines()
                .any(|l| l.trim_start().starts_with(label) && l.contains(value)),
            "no line `{label} ... {value}` in\n{out}"
        );
    };
    assert!(out.contains("valid micro case `head-on-e05`"), "{out}");
    line(&out, "particles", " 2 ");
    line(&out, "Rayleigh time", "2.7366e-5 s");
    line(&out, "time step", "3.65 % of the Rayleigh time");
    line(&out, "run", "1000 steps");
    line(&out, "estimated native time", " s ");
    line(&out, "resource limits", "within");
    let out = granval(&["validate", "cases/impact2d/ci.toml"], 0);
    line(&out, "grains", " 450 ");
    line(&out, "collision time tau_c", "7.0925e-4 s");
    // An invalid case is refused with the file, field and value.
    let tmp = tempfile::tempdir().unwrap();
    let bad = tmp.path().join("bad.toml");
    let text =
        std::fs::read_to_string(common::root().join("cases/micro/head-on-e05.toml")).unwrap();
    let dt_line = text
        .lines()
        .find(|l| l.trim_start().starts_with("dt "))
        .expect("head-on-e05.toml has a dt line")
        .to_string();
    std::fs::write(&bad, text.replacen(&dt_line, "dt = 1.0", 1)).unwrap();
    let o = common::granval()
        .args(["validate", &bad.display().to_string()])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bad.toml") && err.contains("dt"), "{err}");
}

/// `--viz` without an engine: the LAMMPS 2025 micro deck gets the LAMMPS text dump, the
/// LIGGGHTS one the VTK dump, each before the run and once; an interval outside the run
/// is refused with exit 2, naming the option, and no README is written.
#[test]
fn deck_viz_writes_the_engines_dump_and_refuses_what_it_cannot() {
    let tmp = tempfile::tempdir().unwrap();
    for (case, deck_file, line) in [
        (
            "cases/micro-lammps/head-on-e09.toml",
            "in.lammps3d",
            "dump viz all custom 7 viz-*.lammpstrj id type radius x y z",
        ),
        (
            "cases/micro/head-on-e05.toml",
            "in.granval",
            "dump viz all custom/vtk 7 viz-*.vtk id type radius x y z",
        ),
    ] {
        let out = tmp.path().join(deck_file);
        let o = out.display().to_string();
        granval(&["deck", case, "-o", &o, "--viz", "7"], 0);
        let deck = std::fs::read_to_string(out.join(deck_file)).unwrap();
        assert_eq!(deck.matches("dump viz ").count(), 1, "{deck}");
        let (dump, run) = (deck.find(line).expect(line), deck.rfind("\nrun ").unwrap());
        assert!(dump < run, "{deck}");
    }
    for (k, (case, viz)) in [
        ("cases/micro/head-on-e05.toml", "0"),
        ("cases/micro/head-on-e05.toml", "1000000"),
    ]
    .into_iter()
    .enumerate()
    {
        let out = tmp.path().join(format!("refused-{k}"));
        let o = common::granval()
            .args(["deck", case, "-o"])
            .arg(&out)
            .args(["--viz", viz])
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{case} --viz {viz}: {o:?}");
        assert!(
            String::from_utf8_lossy(&o.stderr).contains("--viz"),
            "{o:?}"
        );
        assert!(!out.join("README.txt").exists());
    }
}
