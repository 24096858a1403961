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
