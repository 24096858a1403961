//! The micro suite, the foundation's acceptance test: every micro case, native vs
//! LIGGGHTS 3.8, at every output step within the case's tolerances (1e-6 relative in v
//! and w, 1e-6 r_min in x); the sealed records re-checked against live LIGGGHTS; and
//! every micro gate's negative controls (mu x 1.1, e +- 0.05, nu +- 0.1).

mod common;

use granval::case::{Case, Perturbation};
use granval::compare::{Check, Status};
use granval::experiments::micro::Micro;
use granval::experiments::{Experiment, Role, runner};
use granval::rundata::provenance::EngineKind;

fn print(c: &Check) {
    eprintln!(
        "  {:<44} {:>10.3e} (tol {:.0e}) {:?}",
        c.name, c.value, c.tolerance, c.status
    );
}

#[test]
fn every_micro_case_matches_liggghts() {
    common::live(EngineKind::Liggghts, "micro");
    let cases = common::micro_cases();
    assert!(
        cases.len() >= 14,
        "expected the 14 micro cases, found {}",
        cases.len()
    );
    let mut failures = Vec::new();
    for case in cases {
        let out = tempfile::tempdir().unwrap();
        let name = case.name.clone();
        let o = runner::compare(&Micro { case }, &common::options(), out.path());
        assert!(o.run.is_some(), "{name}: {:?}", o.checks);
        for c in &o.checks {
            print(c);
            if c.status != Status::Pass {
                failures.push(format!(
                    "{} = {:e} {:?} ({})",
                    c.name, c.value, c.status, c.detail
                ));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "micro comparison failed:\n{}",
        failures.join("\n")
    );
}

/// A sealed record must be what LIGGGHTS produces today: with LIGGGHTS live, every
/// record is compared (through its seal) with a live run, to 1e-12.
#[test]
fn recorded_references_match_live_liggghts() {
    if !common::live(EngineKind::Liggghts, "records vs live") {
        common::engineless(
            "records vs live",
            "SKIPPED: cannot re-check reference/ without a live LIGGGHTS",
        );
        return;
    }
    for case in common::micro_cases() {
        let exp = Micro { case };
        let dir = tempfile::tempdir().unwrap();
        let live = exp
            .run_reference(&(), dir.path(), &common::options())
            .unwrap_or_else(|e| panic!("{}: live LIGGGHTS run: {e:#}", exp.name()));
        let root = granval::experiments::reference::record_root(
            &common::root().join("reference"),
            "micro",
            exp.name(),
        );
        let seal = granval::experiments::reference::verify(
            &root,
            exp.source(),
            &exp.canonical_hash(),
            EngineKind::Liggghts,
            &granval::experiments::reference::unit_keys(&exp, &[()]).unwrap(),
            &granval::experiments::reference::store::nothing_regenerable,
        )
        .unwrap_or_else(|e| panic!("{}: {e:#}", exp.name()));
        let rec = exp.read_record(&(), "", &seal).unwrap();
        let drift = exp.drift(&rec, &live);
        eprintln!("{}: {drift}", exp.name());
        for part in drift.split(", ") {
            let v: f64 = part.rsplit(' ').next().unwrap().parse().unwrap();
            assert!(
                v <= 1e-12,
                "{}: record drifted from live LIGGGHTS: {drift}",
                exp.name()
            );
        }
    }
}

/// Runs the suite with a perturbed native engine against the reference; the cases
/// whose gates failed.
fn caught(pert: Perturbation) -> Vec<String> {
    let mut names = Vec::new();
    for case in common::micro_cases() {
        let exp = Micro { case };
        let opts = common::options();
        let dir = tempfile::tempdir().unwrap();
        let live = common::live(EngineKind::Liggghts, &exp.case.name);
        let reference = if live {
            exp.run_reference(&(), &dir.path().join("ref"), &opts)
                .unwrap()
        } else {
            let root = granval::experiments::reference::record_root(
                &opts.reference_root,
                "micro",
                exp.name(),
            );
            let seal = granval::experiments::reference::verify(
                &root,
                exp.source(),
                &exp.canonical_hash(),
                EngineKind::Liggghts,
                &granval::experiments::reference::unit_keys(&exp, &[()]).unwrap(),
                &granval::experiments::reference::store::nothing_regenerable,
            )
            .unwrap();
            exp.read_record(&(), "", &seal).unwrap()
        };
        let native = exp
            .run_native(&(), Role::Control(&pert), &dir.path().join("native"), &opts)
            .unwrap();
        let v = exp.checks(&[()], &[native], &[reference], dir.path(), &opts);
        if v.checks.iter().any(|c| c.status == Status::Fail) {
            names.push(exp.name().to_string());
        }
    }
    names
}

fn assert_caught(pert: Perturbation, must_include: &[&str]) {
    let names = caught(pert);
    eprintln!("{pert:?} caught by: {names:?}");
    for m in must_include {
        assert!(
            names.iter().any(|n| n == m),
            "{pert:?} not caught by {m} (caught by {names:?})"
        );
    }
}

#[test]
fn friction_times_1_1_fails() {
    assert_caught(
        Perturbation {
            friction_factor: 1.1,
            ..Default::default()
        },
        &["oblique-stick", "oblique-slide", "spin", "plane-oblique"],
    );
}

#[test]
fn restitution_shifted_by_0_05_fails() {
    for shift in [0.05, -0.05] {
        assert_caught(
            Perturbation {
                restitution_shift: shift,
                ..Default::default()
            },
            &["head-on-e05", "head-on-e09", "unequal", "plane-normal"],
        );
    }
}

#[test]
fn poisson_shifted_by_0_1_fails() {
    for shift in [0.1, -0.1] {
        assert_caught(
            Perturbation {
                poisson_shift: shift,
                ..Default::default()
            },
            &[
                "head-on-e05",
                "head-on-e09",
                "unequal",
                "plane-normal",
                "oblique-stick",
            ],
        );
    }
}

/// A case's own negative controls run inside `compare` and are gated there.
#[test]
fn negative_controls_declared_in_case_files_bite() {
    let mut seen = 0;
    for case in common::micro_cases() {
        if case.negative_controls.is_empty() {
            continue;
        }
        let out = tempfile::tempdir().unwrap();
        let name = case.name.clone();
        let o = runner::compare(&Micro { case }, &common::options(), out.path());
        for c in o
            .checks
            .iter()
            .filter(|c| c.gate == granval::compare::Gate::NegativeControl)
        {
            print(c);
            assert_eq!(c.status, Status::Pass, "{name}: {}", c.detail);
            seen += 1;
        }
    }
    assert!(
        seen >= 2,
        "expected negative controls in at least two micro case files"
    );
}

fn _unused(_: Case) {}
