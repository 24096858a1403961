//! Shared helpers for integration tests: where the reference runs come from, said out
//! loud, so a green test on a machine without LIGGGHTS is never mistaken for a live one.
#![allow(dead_code)]

use granval::case::Case;
use granval::engines::Frame;
use granval::pipeline::{self, Options};
use std::path::{Path, PathBuf};

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn load(rel: &str) -> Case {
    Case::load(&root().join(rel)).unwrap_or_else(|e| panic!("{e}"))
}

pub fn micro_cases() -> Vec<Case> {
    pipeline::suite_cases(&root().join("cases"), "micro")
        .expect("micro suite")
        .iter()
        .map(|p| Case::load(p).unwrap_or_else(|e| panic!("{e}")))
        .collect()
}

pub fn options() -> Options {
    Options {
        reference_root: root().join("reference"),
        ..Options::default()
    }
}

/// The reference trajectory of a case: live LIGGGHTS when installed (required in CI via
/// GRANVAL_REQUIRE_LIVE=1), otherwise the recorded run — and the test log says which.
pub fn reference_frames(case: &Case, scratch: &Path) -> Vec<Frame> {
    let (out, source, notes) = pipeline::reference_run(case, &options(), scratch)
        .unwrap_or_else(|e| panic!("reference run of {}: {e:#}", case.name));
    if source == "live" {
        eprintln!("[{}] reference: LIVE {}", case.name, out.provenance.version);
    } else {
        eprintln!(
            "[{}] reference: FALLBACK to {source} (LIGGGHTS not installed). {}",
            case.name,
            notes.join(" ")
        );
    }
    out.frames
}

/// GRANVAL_REQUIRE_LIVE=1: reference engines must run live, no recorded fallback.
pub fn require_live() -> bool {
    std::env::var("GRANVAL_REQUIRE_LIVE").is_ok_and(|v| v == "1")
}

/// The 300-grain penetration case of `tests/data/penetration-tiny.toml` (E above
/// LIGGGHTS' 5e6 Pa floor, seconds per engine) with the intruder diameter set,
/// `analysis` lines added to `[analysis]` and `tail` appended.
pub fn tiny_penetration_toml(intruder_diameter: f64, analysis: &str, tail: &str) -> String {
    let text = std::fs::read_to_string(root().join("tests/data/penetration-tiny.toml")).unwrap();
    let (intruder, fit) = ("[intruder]\ndiameter = 0.010\n", "fit_h_min = 0.5\n");
    assert!(
        text.contains(intruder) && text.contains(fit),
        "tests/data/penetration-tiny.toml changed shape"
    );
    text.replacen(
        intruder,
        &format!("[intruder]\ndiameter = {intruder_diameter:e}\n"),
        1,
    )
    .replacen(fit, &format!("{fit}{analysis}\n"), 1)
        + tail
}
