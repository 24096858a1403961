//! The LAMMPS-family micro suite (cases/suites/micro-lammps.toml): every case, native
//! (LAMMPS' granular sub-models in Rust) vs live LAMMPS 22 Jul 2025, at every output
//! step within the case's tolerances, and every case's negative control biting. Live
//! when LAMMPS 2025 is found (GRANVAL_LMP3D, else /opt/granval-lammps/bin/lmp); when it
//! is not, fails under GRANVAL_REQUIRE_LIVE=1 and otherwise says FALLBACK and compares
//! against the sealed records under reference/micro/lmp-*.

mod common;

use granval::compare::Status;
use granval::experiments::micro::Micro;
use granval::experiments::runner;
use std::path::Path;

fn cases() -> Vec<granval::case::Case> {
    common::micro_suite_cases("micro-lammps")
}

#[test]
fn every_lammps_micro_case_matches_lammps_2025() {
    let test = "micro-lammps";
    if live(test) {
        eprintln!("[{test}] reference: LIVE LAMMPS (22 Jul 2025)");
    } else {
        common::engineless(
            test,
            "FALLBACK: LAMMPS (22 Jul 2025) is not installed; using the sealed recorded references",
        );
    }
    let cases = cases();
    assert!(
        cases.len() >= 8,
        "expected >= 8 cases, found {}",
        cases.len()
    );
    let mut failures = Vec::new();
    for case in cases {
        assert!(case.lammps().is_some(), "{}: not LAMMPS family", case.name);
        let out = tempfile::tempdir().unwrap();
        let name = case.name.clone();
        let o = runner::compare(&Micro { case }, &common::options(), out.path());
        assert!(o.run.is_some(), "{name}: {:?}", o.checks);
        let mut controls = 0;
        for c in &o.checks {
            eprintln!(
                "  {:<56} {:>10.3e} (tol {:.0e}) {:?}",
                c.name, c.value, c.tolerance, c.status
            );
            controls += usize::from(c.name.contains("negative control"));
            if c.status != Status::Pass {
                failures.push(format!(
                    "{} = {:e} {:?} ({})",
                    c.name, c.value, c.status, c.detail
                ));
            }
            // The suite's promise: round-off agreement, far inside the 1e-6 gates.
            if ["position", "velocity", "angular velocity"]
                .iter()
                .any(|g| c.name.ends_with(&format!(": {g}")))
                && c.value > 1e-10
            {
                failures.push(format!("{}: {:e} > 1e-10", c.name, c.value));
            }
        }
        assert!(controls >= 1, "{name}: no negative control ran");
    }
    assert!(
        failures.is_empty(),
        "LAMMPS-family micro comparison failed:\n{}",
        failures.join("\n")
    );
}

/// Whether LAMMPS 2025 runs here; a broken or wrong-version one is an error, and a
/// missing one fails under GRANVAL_REQUIRE_LIVE.
fn live(test: &str) -> bool {
    let live = granval::engines::lammps3d::probe_reference()
        .unwrap_or_else(|e| panic!("[{test}] {e:#}"))
        .is_some();
    assert!(
        live || !common::require_live(),
        "[{test}] GRANVAL_REQUIRE_LIVE=1 but LAMMPS (22 Jul 2025) is not installed \
         (GRANVAL_LMP3D or /opt/granval-lammps/bin/lmp)"
    );
    live
}

/// A sealed record must be what LAMMPS 2025 computes today: with it live, every
/// record's trajectory is compared (through its seal) with a live run.
#[test]
fn recorded_references_match_live_lammps_2025() {
    use granval::experiments::{Experiment, reference};
    let test = "micro-lammps records vs live";
    if !live(test) {
        common::engineless(
            test,
            "SKIPPED: cannot re-check the records without LAMMPS 2025",
        );
        return;
    }
    for case in cases() {
        let exp = Micro { case };
        let dir = tempfile::tempdir().unwrap();
        let fresh = exp
            .run_reference(&(), dir.path(), &common::options())
            .unwrap_or_else(|e| panic!("{}: live LAMMPS run: {e:#}", exp.name()));
        let root = reference::record_root(&common::root().join("reference"), "micro", exp.name());
        let seal = reference::verify(
            &root,
            exp.source(),
            &exp.canonical_hash(),
            granval::rundata::provenance::EngineKind::Lammps,
            &reference::unit_keys(&exp, &[()]).unwrap(),
            &reference::store::nothing_regenerable,
        )
        .unwrap_or_else(|e| panic!("{}: {e:#}", root.display()));
        let recorded = exp.read_record(&(), "", &seal).unwrap();
        let drift = exp.drift(&recorded, &fresh);
        eprintln!("  {:<24} {drift}", exp.name());
        for part in drift.split(", ") {
            let v: f64 = part
                .rsplit(' ')
                .next()
                .and_then(|x| x.parse().ok())
                .unwrap_or_else(|| panic!("{}: drift {drift:?}", exp.name()));
            assert!(
                v <= 1e-12,
                "{}: record drifted from live LAMMPS: {drift}",
                exp.name()
            );
        }
    }
}

/// Bad family values are refused with file, field, value and reason.
#[test]
fn a_bad_family_is_refused_plainly() {
    let path = common::root().join("cases/micro-lammps/head-on-e09.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    for (from, to, field) in [
        (
            "family = \"lammps\"",
            "family = \"lammps2\"",
            "models.family",
        ),
        (
            "normal = \"hertz/material\"",
            "normal = \"hertz\"",
            "models.normal",
        ),
        (
            "tangential_damping = 1.0",
            "tangential_damping = -1.0",
            "models.tangential_damping",
        ),
    ] {
        let bad = text.replace(from, to);
        let e = granval::case::Case::from_toml_str(&bad, &path)
            .unwrap_err()
            .to_string();
        assert!(e.contains(field) && e.contains("head-on-e09.toml"), "{e}");
    }
}

/// A LAMMPS-family micro case is LAMMPS 2025's everywhere, not only in `compare`:
/// `validate` names it, `deck --engine lammps` writes its deck, and asking for LIGGGHTS
/// (which would run or write LAMMPS' deck under LIGGGHTS' name) is refused with exit 2,
/// naming the engine; a LIGGGHTS-family case refuses LAMMPS the same way. No engine runs.
#[test]
fn every_command_takes_the_cases_own_reference_engine() {
    let lmp_case = "cases/micro-lammps/head-on-e09.toml";
    let lig_case = "cases/micro/head-on-e05.toml";
    let run = |args: &[&str]| common::granval().args(args).output().unwrap();
    common::expect(
        &run(&["validate", lmp_case]),
        0,
        &["(reference engine LAMMPS 22 Jul 2025)"],
    );
    common::expect(
        &run(&["validate", lig_case]),
        0,
        &["(reference engine LIGGGHTS 3.8)"],
    );
    let tmp = tempfile::tempdir().unwrap();
    let d = |n: &str| tmp.path().join(n).display().to_string();
    common::expect(
        &run(&["deck", lmp_case, "-o", &d("deck"), "--engine", "lammps"]),
        0,
        &["deck directory written"],
    );
    assert!(tmp.path().join("deck/in.lammps3d").is_file());
    for (case, engine, own) in [
        (lmp_case, "liggghts", "lammps"),
        (lig_case, "lammps", "liggghts"),
    ] {
        for cmd in ["run", "deck"] {
            let out = d(&format!("{cmd}-{engine}"));
            let flag = if cmd == "run" { "--out" } else { "-o" };
            common::expect(
                &run(&[cmd, case, flag, &out, "--engine", engine]),
                2,
                &[&format!("--engine {engine}"), own],
            );
            assert!(!Path::new(&out).exists(), "{cmd} {case}: {out} was made");
        }
    }
}
