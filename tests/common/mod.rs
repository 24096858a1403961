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
    micro_suite_cases("micro")
}

/// The cases of a suite of micro cases (`micro`, `micro-lammps`).
pub fn micro_suite_cases(suite: &str) -> Vec<Case> {
    granval::experiments::suite::load(&root().join("cases"), suite)
        .unwrap_or_else(|e| panic!("{suite} suite: {e:#}"))
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

/// Options of the tests: references under `reference/` (or under
/// `GRANVAL_TEST_REFERENCE`, to check freshly recorded references before they replace
/// the shipped ones).
pub fn options() -> Options {
    Options {
        reference_root: std::env::var_os("GRANVAL_TEST_REFERENCE")
            .map(PathBuf::from)
            .unwrap_or_else(|| root().join("reference")),
        ..Options::default()
    }
}

/// GRANVAL_REQUIRE_LIVE (1/true/yes/on): reference engines must run live, no recorded
/// fallback. A value that is not a switch fails the test, as it fails the binary.
pub fn require_live() -> bool {
    granval::experiments::env_flags::require_live().unwrap_or_else(|e| panic!("{e:#}"))
}

/// Says that `test` ran without a live reference engine (`what`: FALLBACK to records,
/// SKIPPED, NATIVE SIDE ONLY ...): on stderr, and as a line appended to the file
/// GRANVAL_TEST_ENGINELESS_LOG names, so `.ci/run` can count what ran without engines.
pub fn engineless(test: &str, what: &str) {
    eprintln!("[{test}] {what}");
    if let Some(p) = std::env::var_os("GRANVAL_TEST_ENGINELESS_LOG") {
        use std::io::Write;
        if let Ok(mut f) = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(p)
        {
            let _ = writeln!(f, "[{test}] {what}");
        }
    }
}

/// A test that needs a live engine and has no recorded path: panics when live engines
/// are required (CI), else says it was skipped. Returns whether the engine is live.
pub fn live_or_skip(engine: EngineKind, test: &str, what_is_skipped: &str) -> bool {
    let live = reference::installed(engine).is_some();
    if !live {
        assert!(
            !require_live(),
            "[{test}] GRANVAL_REQUIRE_LIVE=1 but {engine} is not installed"
        );
        engineless(
            test,
            &format!("SKIPPED: {engine} is not installed; {what_is_skipped}"),
        );
    }
    live
}

/// Whether LAMMPS 22 Jul 2025 (the 3D reference, `engines::lammps3d`) runs live here: a
/// binary that fails its probe panics; a missing one panics when live engines are
/// required (CI), else the test says it was skipped.
pub fn lammps3d_live(test: &str) -> bool {
    let live =
        granval::engines::lammps3d::probe_reference().unwrap_or_else(|e| panic!("[{test}] {e:#}"));
    if live.is_none() {
        assert!(
            !require_live(),
            "[{test}] GRANVAL_REQUIRE_LIVE=1 but LAMMPS (22 Jul 2025) is not installed"
        );
        engineless(test, "SKIPPED: LAMMPS 22 Jul 2025 is not installed");
    }
    live.is_some()
}

/// Whether `engine` runs live here; panics when live engines are required but missing,
/// and says loudly when a test falls back to the recorded references.
pub fn live(engine: EngineKind, test: &str) -> bool {
    // An engine that is there but fails its probe is an error, not a quiet fallback.
    let live = reference::probe(engine)
        .unwrap_or_else(|e| panic!("[{test}] {e:#}"))
        .is_some();
    if !live {
        assert!(
            !require_live(),
            "GRANVAL_REQUIRE_LIVE=1 but {engine} is not installed"
        );
        engineless(
            test,
            &format!("FALLBACK: {engine} is not installed; using the sealed recorded references"),
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

/// The reference runs of `exp`'s units as `runner::compare` would take them: live when
/// the options allow it and the engine is installed (outputs under `dir`), otherwise the
/// sealed record (verified). Says which, loudly.
pub fn reference_runs<E: granval::experiments::Experiment>(
    exp: &E,
    units: &[E::Unit],
    opts: &Options,
    dir: &std::path::Path,
) -> Vec<E::RefRun> {
    use granval::experiments::runner;
    let engine = exp.reference_engine();
    let names: Vec<String> = units.iter().map(|u| exp.unit_name(u)).collect();
    let live = runner::resolve(exp, opts).unwrap_or_else(|e| panic!("{}: {e:#}", exp.name()));
    match live {
        Some(version) => {
            eprintln!("[{}] reference: LIVE {version}", exp.name());
            units
                .iter()
                .zip(&names)
                .map(|(u, n)| {
                    exp.run_reference(u, &runner::reference_out(dir, n, engine), opts)
                        .unwrap_or_else(|e| panic!("{} {n}: {e:#}", exp.name()))
                })
                .collect()
        }
        None => {
            assert!(
                !require_live() || opts.ref_mode == RefMode::Recorded,
                "GRANVAL_REQUIRE_LIVE=1 but {engine} is not installed"
            );
            let root = reference::record_root(&opts.reference_root, exp.kind(), exp.name());
            eprintln!(
                "[{}] reference: RECORDED {} (sealed)",
                exp.name(),
                root.display()
            );
            let fingerprints = reference::unit_keys(exp, units).unwrap();
            let seal = reference::verify(
                &root,
                exp.source(),
                &exp.canonical_hash(),
                engine,
                &fingerprints,
                &runner::regenerator(exp, units, &names),
            )
            .unwrap_or_else(|e| panic!("{}: {e:#}", exp.name()));
            units
                .iter()
                .zip(&names)
                .map(|(u, n)| {
                    exp.read_record(u, n, &seal)
                        .unwrap_or_else(|e| panic!("{} {n}: {e:#}", exp.name()))
                })
                .collect()
        }
    }
}

/// Every check of `exp` with the native engine run in `role` (e.g. a negative control
/// not declared in the case file) against the same reference runs `runner::compare`
/// uses; outputs under `out`.
pub fn checks_with<E: granval::experiments::Experiment>(
    exp: &E,
    role: granval::experiments::Role,
    opts: &Options,
    out: &std::path::Path,
) -> Vec<granval::compare::Check> {
    use granval::experiments::runner;
    let units = exp
        .units(opts)
        .unwrap_or_else(|e| panic!("{}: {e:#}", exp.name()));
    let refs = reference_runs(exp, &units, opts, out);
    let natives: Vec<_> = units
        .iter()
        .map(|u| {
            let n = exp.unit_name(u);
            exp.run_native(u, role, &runner::unit_out(out, &n).join("native"), opts)
                .unwrap_or_else(|e| panic!("{} {n}: {e:#}", exp.name()))
        })
        .collect();
    exp.checks(&units, &natives, &refs, out, opts).checks
}

/// Prints checks as a report would.
pub fn show(label: &str, checks: &[granval::compare::Check]) {
    for c in checks {
        eprintln!(
            "[{label}] {:?} {}: {:.4} (tol {}) {}",
            c.status, c.name, c.value, c.tolerance, c.detail
        );
    }
}

/// Held by a test while it runs MPI jobs: two `mpirun -np 2` at once on a 2-core machine
/// oversubscribe it, and busy-waiting MPI ranks then slow each other down many times.
pub fn mpi_lock() -> std::sync::MutexGuard<'static, ()> {
    static MPI: std::sync::Mutex<()> = std::sync::Mutex::new(());
    MPI.lock().unwrap_or_else(|p| p.into_inner())
}

/// A finished command's stdout and stderr, as one text for messages and searches.
pub fn text(o: &std::process::Output) -> String {
    format!(
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Asserts a finished command's exit code and that its output names every needle.
pub fn expect(o: &std::process::Output, code: i32, needles: &[&str]) {
    let t = text(o);
    assert_eq!(o.status.code(), Some(code), "{t}");
    for n in needles {
        assert!(t.contains(n), "missing {n:?} in:\n{t}");
    }
}

/// A Python that imports VTK (the library inside ParaView), if there is one:
/// `GRANVAL_PYTHON`, /usr/bin/python3 (Debian `python3-vtk9`), then `python3`.
pub fn vtk_python() -> Option<String> {
    let candidates = std::env::var("GRANVAL_PYTHON")
        .ok()
        .into_iter()
        .chain(["/usr/bin/python3".to_string(), "python3".to_string()]);
    candidates.into_iter().find(|p| {
        Command::new(p)
            .args(["-c", "import vtkmodules.vtkIOLegacy"])
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

/// A legacy VTK file as ParaView's reader loads it (`vtkGenericDataObjectReader`):
/// `{"points", "point_arrays", "cells", "cell_arrays"}`, the array names sorted.
pub fn vtk_legacy_summary(py: &str, path: &std::path::Path) -> serde_json::Value {
    const READ: &str = r#"
import json, sys
from vtkmodules.vtkIOLegacy import vtkGenericDataObjectReader
r = vtkGenericDataObjectReader(); r.SetFileName(sys.argv[1]); r.Update(); d = r.GetOutput()
names = lambda a: sorted(a.GetArrayName(i) for i in range(a.GetNumberOfArrays()))
print(json.dumps({"points": d.GetNumberOfPoints(), "point_arrays": names(d.GetPointData()),
    "cells": d.GetNumberOfCells(), "cell_arrays": names(d.GetCellData())}))
"#;
    let o = Command::new(py)
        .args(["-c", READ])
        .arg(path)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{}: {}",
        path.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).unwrap()
}
