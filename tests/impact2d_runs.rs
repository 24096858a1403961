//! The impact experiment at CI size (cases/impact2d/ci*.toml), both engines from the
//! same bed: native vs LAMMPS final depth and D(t), K's claims in each engine, and the
//! negative control (friction models swapped in the native engine) that must make the
//! cross-check fail. LAMMPS runs live when `lmp` is installed; otherwise the recorded
//! runs under reference/impact2d/ are used and the log says so; with
//! GRANVAL_REQUIRE_LIVE=1 a missing `lmp` is a failure. All cases share one prepared
//! bed per packing (prepared once per process).

mod common;

use granval::case::impact2d::Impact2dCase;
use granval::compare::Check;
use granval::impact2d::{Tweak, compare_case_with};

fn case(name: &str) -> Impact2dCase {
    Impact2dCase::load(&common::root().join("cases/impact2d").join(name))
        .unwrap_or_else(|e| panic!("{e}"))
}

fn run(name: &str, tweak: Tweak) -> Vec<Check> {
    let c = case(name);
    let out = tempfile::tempdir().unwrap();
    let r = compare_case_with(&c, &common::options(), out.path(), tweak);
    for n in &r.notes {
        eprintln!("[{name}] note: {n}");
    }
    if let Some(run) = &r.run {
        eprintln!(
            "[{name}] reference: {} {} ({})",
            run.reference_engine, run.reference_version, run.reference_source
        );
    }
    for c in &r.checks {
        eprintln!(
            "[{name}] {} {}: {:.4} (tol {}) {}",
            if c.passed { "PASS" } else { "FAIL" },
            c.name,
            c.value,
            c.tolerance,
            c.detail
        );
    }
    assert!(
        !r.errored,
        "{name}: errored: {:?}",
        r.checks
            .iter()
            .filter(|c| c.metric == "error")
            .collect::<Vec<_>>()
    );
    r.checks
}

fn named<'a>(checks: &'a [Check], part: &str) -> Vec<&'a Check> {
    let v: Vec<&Check> = checks.iter().filter(|c| c.name.contains(part)).collect();
    assert!(!v.is_empty(), "no check named like {part:?}");
    v
}

#[test]
fn native_matches_lammps_on_the_ci_bed() {
    let checks = run("ci.toml", Tweak::None);
    assert_eq!(checks.len(), 2);
    for c in &checks {
        assert!(c.passed, "{c:?}");
    }
}

#[test]
fn swapped_friction_in_the_native_engine_fails_the_cross_check() {
    let checks = run("ci.toml", Tweak::SwapFriction);
    for part in ["final depth", "D(t) distance"] {
        for c in named(&checks, part) {
            assert!(!c.passed, "negative control passed: {c:?}");
        }
    }
}

fn claims_pass(name: &str) {
    let checks = run(name, Tweak::None);
    for engine in ["claim (native)", "claim (lammps)"] {
        for c in named(&checks, engine) {
            assert!(c.passed, "{c:?}");
        }
    }
    for c in named(&checks, "final depth native vs") {
        assert!(c.passed, "{c:?}");
    }
}

#[test]
fn static_friction_penetrates_less_than_kinetic() {
    claims_pass("ci-friction.toml");
}

#[test]
fn swapped_friction_breaks_the_friction_claim_in_the_native_engine() {
    let checks = run("ci-friction.toml", Tweak::SwapFriction);
    for c in named(&checks, "claim (native)") {
        assert!(!c.passed, "negative control passed: {c:?}");
    }
}

#[test]
fn hexagonal_bed_penetrates_less_than_random() {
    claims_pass("ci-packing.toml");
}

#[test]
fn final_depth_grows_with_restitution() {
    claims_pass("ci-en.toml");
}

#[test]
fn final_depth_grows_as_gravity_drops() {
    claims_pass("ci-gravity.toml");
}

#[test]
fn final_depth_is_roughly_linear_in_speed_above_0_4() {
    claims_pass("ci-speed.toml");
}
