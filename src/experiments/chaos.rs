//! The chaos baseline of docs/statistics.md: how far one engine drifts from itself. Every
//! bed of a penetration case runs natively twice, as prepared and with every grain moved
//! by one unit in the last place of x, and the two runs are reduced exactly as the
//! engine gate reduces a native and a reference run (rule 3's common fit range, each bed
//! fitted alone on it). The per-bed log ratios c_k = ln(K_k / K'_k) are what two runs of
//! the same physics do to each other; an engine difference is evidence of different
//! physics only beyond them.
//!
//! `granval chaos CASE --out DIR` writes `DIR/chaos.json` ([`ChaosRecord`]); the release
//! report's "Engine agreement against chaos" section reads such records.

use super::penetration::{Penetration, fit_range_of};
use super::{Experiment, Options, Role};
use crate::case::Perturbation;
use crate::compare::penetration as cp;
use anyhow::{Context, Result, ensure};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// File name of a chaos record inside its output directory.
pub const CHAOS_FILE: &str = "chaos.json";

/// One case's chaos replicas.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ChaosRecord {
    pub case: String,
    pub canonical_hash: String,
    /// The family the case belongs to (spheres at CI scale, dense, clumps, soft, stiff,
    /// ...), as `granval chaos --family` named it.
    pub family: String,
    /// sha256 of each bed, in bed order.
    pub bed_hashes: Vec<String>,
    /// Rule 3's common fit range of the two sets of runs (h_C,start, h_C,end).
    pub fit_h: (f64, f64),
    /// K_phi of each bed as prepared and as nudged.
    pub k_phi: Vec<f64>,
    pub k_phi_nudged: Vec<f64>,
    /// ln(K_k / K'_k).
    pub log_ratio: Vec<f64>,
    /// The granval version that ran them.
    pub granval: String,
}

impl ChaosRecord {
    /// s_c = sqrt(mean c_k^2): the chaos spread of a per-bed log ratio between two runs
    /// of one engine, with as many degrees of freedom as beds (the expected mean is zero).
    pub fn spread(&self) -> (f64, usize) {
        crate::numerics::stats::root_mean_square(&self.log_ratio)
    }

    pub fn write(&self, dir: &Path) -> Result<()> {
        let p = dir.join(CHAOS_FILE);
        std::fs::write(&p, serde_json::to_string_pretty(self)? + "\n")
            .with_context(|| format!("writing {}", p.display()))
    }

    pub fn read(path: &Path) -> Result<ChaosRecord> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        serde_json::from_str(&text)
            .with_context(|| format!("{}: not a chaos record", path.display()))
    }
}

/// Runs the replicas of every bed of `exp`'s case into `out/prepared/bed-K` and
/// `out/nudged/bed-K` and reduces them.
pub fn penetration(
    exp: &Penetration,
    family: &str,
    opts: &Options,
    out: &Path,
) -> Result<ChaosRecord> {
    let case = &exp.case;
    // Beds a record holds (the ones its reference runs started from) are read, not
    // settled again; their hashes go into the record either way.
    let root = super::reference::record_root(&opts.reference_root, exp.kind(), exp.name());
    let unit_opts = Options {
        recorded_inputs: root.is_dir().then_some(root),
        ..opts.clone()
    };
    let units = exp.units(&unit_opts)?;
    ensure!(
        units.len() >= 2,
        "{}: a chaos spread needs at least two beds ([ensemble] beds = {})",
        case.source.display(),
        units.len()
    );
    let same = Perturbation::default();
    let nudge = Perturbation {
        nudge_one_ulp: true,
        ..Perturbation::default()
    };
    let mut prepared = Vec::new();
    let mut nudged = Vec::new();
    for u in &units {
        let t = std::time::Instant::now();
        let a = exp.run_native(
            u,
            Role::Control(&same),
            &out.join("prepared").join(format!("bed-{}", u.k)),
            opts,
        )?;
        let b = exp.run_native(
            u,
            Role::Control(&nudge),
            &out.join("nudged").join(format!("bed-{}", u.k)),
            opts,
        )?;
        eprintln!(
            "   bed {}: both replicas in {:.0} s",
            u.k,
            t.elapsed().as_secs_f64()
        );
        prepared.push(a.run);
        nudged.push(b.run);
    }
    let pa: Vec<_> = prepared.iter().collect();
    let pb: Vec<_> = nudged.iter().collect();
    let range = fit_range_of(case, &units, &pa, &pb);
    let h_max = super::penetration::k_phi_fit_end(case, &range);
    ensure!(
        range.not_compared.is_none() || h_max.is_infinite(),
        "{}: no common fit range: {}",
        case.source.display(),
        range.not_compared.clone().unwrap_or_default()
    );
    let fit = |runs: &[&super::penetration::bed::EngineRun]| {
        cp::ensemble_in(
            case,
            &runs.iter().map(|r| &r.fdr).collect::<Vec<_>>(),
            h_max,
        )
    };
    let (oa, ob) = (fit(&pa)?, fit(&pb)?);
    let k_phi: Vec<f64> = oa.members.iter().map(|m| m.0).collect();
    let k_phi_nudged: Vec<f64> = ob.members.iter().map(|m| m.0).collect();
    let log_ratio = k_phi
        .iter()
        .zip(&k_phi_nudged)
        .map(|(a, b)| (a / b).ln())
        .collect();
    Ok(ChaosRecord {
        case: case.name.clone(),
        canonical_hash: case.canonical_hash().to_string(),
        family: family.to_string(),
        bed_hashes: units.iter().map(|u| u.bed_hash.to_string()).collect(),
        fit_h: (range.h_start, h_max.min(range.h_final)),
        k_phi,
        k_phi_nudged,
        log_ratio,
        granval: env!("CARGO_PKG_VERSION").to_string(),
    })
}
