//! Native vs LIGGGHTS over an ensemble of beds (`[ensemble] beds`). A single bed at CI
//! scale gives K_phi only to about +-15 % — two correct engines started from the same
//! bed diverge grain by grain within milliseconds (measured: the native engine with the
//! restitution shifted by 1e-9 moved K_phi from 24.4 to 31.7). Both engines therefore
//! penetrate the same N beds, and the checks compare the ensemble-mean FDRs.
//!
//! Output layout: `OUT/case.toml`, `OUT/bed-K/` (the LIGGGHTS deck directory of bed K
//! with its outputs) and `OUT/bed-K/native/` — the layout of [`deck_dir`].

use super::{EngineRun, bed_hash, deck_dir, prepare_bed, run_liggghts, run_native};
use crate::case::penetration::PenetrationCase;
use crate::compare::{Check, penetration as cp};
use crate::physics::dem::packing;
use crate::pipeline::{CaseResult, Options};
use crate::report::CaseRun;
use anyhow::Result;
use std::path::Path;

/// Per-bed runs of both engines (and the native runs at the quasi-static second speed).
#[derive(Default)]
pub struct EnsembleRuns {
    pub native: Vec<EngineRun>,
    pub reference: Vec<EngineRun>,
    pub native_slow: Vec<EngineRun>,
    /// "live" or where the recorded runs came from.
    pub reference_source: String,
    pub notes: Vec<String>,
}

/// Bed `k` of the case, its native run(s) and its LIGGGHTS run (live in
/// `out_dir/bed-k/`, or the recorded one for the very same bed). Returns the bed, so a
/// caller can run more native variants on it (negative controls).
pub fn run_bed(
    case: &PenetrationCase,
    k: usize,
    opts: &Options,
    out_dir: &Path,
    runs: &mut EnsembleRuns,
) -> Result<packing::Bed> {
    let ck = case.realisation(k);
    let bed = prepare_bed(&ck, opts.progress)?;
    let hash = bed_hash(&bed);
    runs.notes.push(format!(
        "bed {k}: {} (sha256 {hash})",
        packing::bed_note(&ck, &bed)
    ));
    let dir = out_dir.join(deck_dir::bed_dir_name(k));
    run_native_bed(&ck, &bed, opts, &dir, runs)?;
    let rec_dir = opts
        .reference_root
        .join("penetration")
        .join(&case.name)
        .join(deck_dir::bed_dir_name(k));
    if crate::engines::liggghts::installed_version("liggghts").is_some() {
        runs.reference.push(run_liggghts(
            &ck,
            &bed,
            &dir,
            opts.mpi_procs.max(2),
            opts.progress,
        )?);
        runs.reference_source = "live".into();
    } else if opts.require_live {
        anyhow::bail!("LIGGGHTS is not installed but live engines are required");
    } else {
        runs.reference
            .push(deck_dir::reduce_recorded(&ck, &bed, &rec_dir, &hash)?);
        runs.notes.push(format!(
            "LIGGGHTS is not installed here: bed {k} of {} was compared against the RECORDED LIGGGHTS run in {}",
            case.name,
            rec_dir.display()
        ));
        runs.reference_source = format!(
            "recorded {}",
            rec_dir.parent().unwrap_or(&rec_dir).display()
        );
    }
    Ok(bed)
}

/// The native run(s) of one bed — at the case speed and, with `[quasi_static]`, at the
/// second speed — saved under `dir/native*` and reduced into `runs`.
pub fn run_native_bed(
    ck: &PenetrationCase,
    bed: &packing::Bed,
    opts: &Options,
    dir: &Path,
    runs: &mut EnsembleRuns,
) -> Result<()> {
    let native = run_native(ck, bed, opts.native.perturbation, opts.progress)?;
    deck_dir::save_native(&dir.join("native"), &native)?;
    runs.native.push(native.reduce(ck, bed)?);
    if let Some(v2) = ck.quasi_static_speed {
        let slow_case = PenetrationCase {
            speed: v2,
            ..ck.clone()
        };
        let slow = run_native(&slow_case, bed, opts.native.perturbation, opts.progress)?;
        deck_dir::save_native(&dir.join(format!("native-v{v2}")), &slow)?;
        runs.native_slow.push(slow.reduce(&slow_case, bed)?);
    }
    Ok(())
}

/// The report entry of an ensemble comparison: checks plus which engines ran where.
pub fn case_result(
    case: &PenetrationCase,
    case_file: &Path,
    test_engine: &str,
    runs: EnsembleRuns,
    out_dir: &Path,
) -> CaseResult {
    let (checks, notes, errored) = verdicts(case, &runs, out_dir);
    let wall = |r: &[EngineRun]| r.iter().map(|r| r.provenance.wall_time_s).sum::<f64>();
    let reference = &runs.reference[0].provenance;
    CaseResult {
        checks,
        run: Some(CaseRun {
            case: case.name.clone(),
            case_file: case_file.display().to_string(),
            test_engine: test_engine.into(),
            reference_engine: reference.engine.clone(),
            reference_version: reference.version.clone(),
            reference_source: runs.reference_source.clone(),
            wall_time_test_s: wall(&runs.native),
            wall_time_reference_s: wall(&runs.reference),
        }),
        notes: runs.notes.into_iter().chain(notes).collect(),
        errored,
    }
}

/// Every check of the penetration experiment from the runs of both engines, with the
/// FDR CSVs and the overlay SVG written to `out_dir`. Shared by `granval compare` and
/// `granval analyze`, so both give the same report from the same runs.
pub fn verdicts(
    case: &PenetrationCase,
    runs: &EnsembleRuns,
    out_dir: &Path,
) -> (Vec<Check>, Vec<String>, bool) {
    let name = |w: &str| format!("{}: {w}", case.name);
    let mut notes = Vec::new();
    let mut checks = Vec::new();
    let fdrs = |r: &[EngineRun]| r.iter().map(|r| r.fdr.clone()).collect::<Vec<_>>();
    let obs = |r: &[EngineRun]| {
        let f = fdrs(r);
        cp::ensemble(case, &f.iter().collect::<Vec<_>>())
    };
    let reference = if runs.reference.is_empty() {
        None
    } else {
        Some(obs(&runs.reference))
    };
    let native = if runs.native.is_empty() {
        None
    } else {
        Some(obs(&runs.native))
    };
    let _ = std::fs::create_dir_all(out_dir);
    let mut curves = Vec::new();
    for (label, o) in [("native", &native), ("liggghts", &reference)] {
        match o {
            Some(Ok(o)) => {
                let _ = crate::analysis::fdr::write_csv(
                    &out_dir.join(format!("fdr_{label}.csv")),
                    &o.fdr,
                    Some(&o.fit),
                );
                notes.push(format!(
                    "{label}: K_phi = {:.3} +- {:.3} (R^2 {:.4}) on the mean FDR of {} bed(s); single beds {:?}",
                    o.fit.k_phi,
                    o.fit.se_k,
                    o.fit.r2,
                    o.members.len(),
                    o.members
                        .iter()
                        .map(|m| format!("K {:.2} R^2 {:.3}", m.0, m.1))
                        .collect::<Vec<_>>()
                ));
                notes.push(format!("{label}: {}", cp::shape_text(o)));
                if let Some(c) = cp::published(case, o, label) {
                    checks.push(c);
                }
                curves.push((
                    if label == "native" {
                        "native"
                    } else {
                        "LIGGGHTS"
                    },
                    o,
                ));
            }
            Some(Err(e)) => checks.push(Check::error(
                name(&format!("{label} observables")),
                format!("{e:#}"),
            )),
            None => {}
        }
    }
    if let (Some(Ok(a)), Some(Ok(b))) = (&native, &reference) {
        checks.extend(cp::compare(case, a, b));
        notes.extend(cp::boundaries_not_compared(a, b));
    }
    if let (Some(v2), Some(Ok(a))) = (case.quasi_static_speed, &native) {
        match obs(&runs.native_slow) {
            Ok(slow) => checks.push(cp::quasi_static(case, a, &slow, v2)),
            Err(e) => checks.push(Check::error(name("quasi-static K_phi"), format!("{e:#}"))),
        }
    }
    let series: Vec<_> = curves
        .iter()
        .map(|(l, o)| (*l, o.fdr.h.as_slice(), o.fdr.p.as_slice(), Some(&o.fit)))
        .collect();
    if !series.is_empty()
        && let Err(e) = crate::report::svg::fdr_overlay(
            &out_dir.join("fdr.svg"),
            &series,
            &format!("{}: force-depth relation (mean of beds)", case.name),
        )
    {
        notes.push(format!("SVG not written: {e:#}"));
    }
    let errored = checks.iter().any(|c| c.metric == "error");
    (checks, notes, errored)
}

/// Creates `out_dir` with the case file in it, so that the per-bed outputs that follow
/// make it a deck directory (`granval analyze`, `granval stress --fdr-from` re-read it).
pub fn start_out_dir(case: &PenetrationCase, out_dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(out_dir)?;
    std::fs::copy(&case.source, out_dir.join(deck_dir::CASE_FILE)).map(|_| ())
}

/// `granval compare` / `check` for a penetration case: N beds, both engines on each.
pub fn compare_case(case: &PenetrationCase, opts: &Options, out_dir: &Path) -> CaseResult {
    let mut runs = EnsembleRuns::default();
    if let Err(e) = start_out_dir(case, out_dir) {
        runs.notes.push(format!(
            "case file not copied to {}: {e}",
            out_dir.display()
        ));
    }
    for k in 0..case.ensemble_beds {
        if let Err(e) = run_bed(case, k, opts, out_dir, &mut runs) {
            return CaseResult {
                checks: vec![Check::error(
                    format!("{}: bed {k}", case.name),
                    format!("{e:#}"),
                )],
                run: None,
                notes: runs.notes,
                errored: true,
            };
        }
    }
    case_result(case, &case.source, "native", runs, out_dir)
}
