//! `granval chaos` on Kondic (2D) cases (docs/statistics.md, "The chaos baseline"): the
//! replica machinery on the CI-size impact case. A replica without the nudge is the
//! original run again (c_k = 0 exactly: the engine is deterministic, so whatever the
//! one-ulp replica shows is the nudge's), a one-ulp replica gives a finite c_k per
//! variant, and cases with no chaos spread to measure are refused.

mod common;

use common::{expect, text};
use granval::case::Perturbation;
use granval::case::impact2d::Impact2dCase;
use granval::experiments::Experiment;
use granval::experiments::chaos::{self, ChaosRecord, IMPACT2D};
use granval::experiments::impact2d::Impact2d;

/// cases/impact2d/ci-speed.toml cut to its first two speeds (two variants on one bed:
/// the fewest a spread takes).
fn two_speeds() -> Impact2d {
    let mut case = Impact2dCase::load(&common::root().join("cases/impact2d/ci-speed.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    case.variants.truncate(2);
    assert_eq!(case.variants.len(), 2, "ci-speed.toml lost its sweep");
    Impact2d { case }
}

#[test]
fn a_replica_without_the_nudge_is_the_run_and_one_ulp_gives_a_finite_difference() {
    let exp = two_speeds();
    let opts = common::options();
    let same = tempfile::tempdir().unwrap();
    let r = granval::experiments::impact2d::chaos_replicas(
        &exp,
        "ci",
        &Perturbation::default(),
        &opts,
        same.path(),
    )
    .unwrap_or_else(|e| panic!("{e:#}"));
    assert_eq!(r.kind, IMPACT2D);
    assert_eq!(r.variants.len(), 2);
    assert_eq!(r.bed_hashes.len(), 2);
    assert_eq!(r.final_depth, r.final_depth_nudged, "{r:?}");
    assert_eq!(r.values(), &[0.0, 0.0], "{r:?}");
    assert!(
        r.final_depth.iter().all(|d| d.is_finite() && *d > 0.0),
        "{r:?}"
    );
    let nudged = tempfile::tempdir().unwrap();
    let n = exp
        .chaos("ci", &opts, nudged.path())
        .unwrap_or_else(|e| panic!("{e:#}"));
    // The originals are the same runs in both records.
    assert_eq!(n.final_depth, r.final_depth);
    assert_eq!(n.bed_hashes, r.bed_hashes);
    assert_eq!(n.values().len(), 2);
    assert!(n.values().iter().all(|c| c.is_finite()), "{n:?}");
    let (s, df) = n.spread();
    assert!(s.is_finite() && df == 2, "s_c = {s}, df = {df}");
    // A record reads back as written.
    n.write(nudged.path()).unwrap();
    let back = ChaosRecord::read(&nudged.path().join(chaos::CHAOS_FILE)).unwrap();
    assert_eq!(back, n);
    eprintln!(
        "one-ulp replicas of {}: (D - D') / d = {:?}, s_c = {s:.3e}",
        exp.case.name,
        n.values()
    );
}

/// One variant has no spread: refused with the case file and the count.
#[test]
fn a_case_of_one_variant_is_refused() {
    let case = Impact2dCase::load(&common::root().join("cases/impact2d/ci.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(case.variants.len(), 1);
    let out = tempfile::tempdir().unwrap();
    let e = Impact2d { case }
        .chaos("ci", &common::options(), out.path())
        .unwrap_err();
    let e = format!("{e:#}");
    assert!(
        e.contains("ci.toml") && e.contains("at least two variants") && e.contains("has 1"),
        "{e}"
    );
}

/// A micro case (two grains, no bed) is refused before anything runs: exit 2, the file
/// and the kind named, no output directory made.
#[test]
fn the_command_refuses_a_micro_case() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("chaos");
    let o = common::granval()
        .args([
            "chaos",
            "cases/micro/head-on-e05.toml",
            "--family",
            "x",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    expect(
        &o,
        2,
        &[
            "cases/micro/head-on-e05.toml",
            "not a micro case",
            "penetration or impact2d",
        ],
    );
    assert!(!out.exists(), "{}", text(&o));
}
