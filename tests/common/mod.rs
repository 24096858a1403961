//! Shared helpers for integration tests: where the reference runs come from, said out
//! loud, so a green test on a machine without LIGGGHTS is never mistaken for a live one.
#![allow(dead_code)]

use granval::case::{AnyCase, Case};
use granval::experiments::{Options, RefMode, reference};
use granval::rundata::provenance::EngineKind;
use std::path::PathBuf;
use std::process::Command;

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn load(rel: &str) -> Case {
    Case::load(&root().join(rel)).unwrap_or_else(|e| panic!("{e}"))
}

pub fn micro_cases() -> Vec<Case> {
    granval::experiments::suite::load(&root().join("cases"), "micro")
        .expect("micro suite")
        .cases
        .iter()
        .map(
            |e| match AnyCase::load(&e.path).unwrap_or_else(|e| panic!("{e}")) {
                AnyCase::Micro(c) => c,
                _ => panic!("{}: not a micro case", e.path.display()),
            },
        )
        .collect()
}

pub fn options() -> Options {
    Options {
        reference_root: root().join("reference"),
        ..Options::default()
    }
}

/// GRANVAL_REQUIRE_LIVE=1: reference engines must run live, no recorded fallback.
pub fn require_live() -> bool {
    std::env::var("GRANVAL_REQUIRE_LIVE").is_ok_and(|v| v == "1")
}

/// Whether `engine` runs live here; panics when live engines are required but missing,
/// and says loudly when a test falls back to the recorded references.
pub fn live(engine: EngineKind, test: &str) -> bool {
    let live = reference::installed(engine).is_some();
    if !live {
        assert!(
            !require_live(),
            "GRANVAL_REQUIRE_LIVE=1 but {engine} is not installed"
        );
        eprintln!(
            "[{test}] FALLBACK: {engine} is not installed; using the sealed recorded references"
        );
    } else {
        eprintln!("[{test}] reference: LIVE {engine}");
    }
    live
}

/// Options that force the sealed recorded reference.
pub fn recorded() -> Options {
    Options {
        ref_mode: RefMode::Recorded,
        ..options()
    }
}

pub fn granval() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_granval"));
    c.current_dir(root());
    c
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
