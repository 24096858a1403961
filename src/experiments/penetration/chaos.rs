//! The chaos replicas of a penetration case (docs/statistics.md, "The chaos baseline"):
//! every bed run twice natively, once as prepared and once with every grain moved by one
//! ulp, reduced to ln(K_phi / K_phi nudged) per bed.

use super::{Penetration, fit_range_of};
use crate::case::Perturbation;
use crate::compare::penetration as cp;
use crate::experiments::chaos::{ChaosRecord, PENETRATION, one_ulp, units_from_record};
use crate::experiments::{Experiment, Options, Role};
use anyhow::{Result, ensure};
use std::path::Path;

/// Runs the replicas of every bed of `exp`'s case into `out/prepared/bed-K` and
/// `out/nudged/bed-K` and reduces them.
pub fn replicas(
    exp: &Penetration,
    family: &str,
    opts: &Options,
    out: &Path,
) -> Result<ChaosRecord> {
    let case = &exp.case;
    let units = units_from_record(exp, opts)?;
    ensure!(
        units.len() >= 2,
        "{}: a chaos spread needs at least two beds ([ensemble] beds = {})",
        case.source.display(),
        units.len()
    );
    let same = Perturbation::default();
    let nudge = one_ulp();
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
    // The nudged runs sit where the reference engine's would: labelled as before.
    let range = fit_range_of(
        case,
        &units,
        &pa,
        &pb,
        crate::rundata::provenance::EngineKind::Liggghts,
    );
    let h_max = super::k_phi_fit_end(case, &range);
    ensure!(
        range.not_compared.is_none() || h_max.is_infinite(),
        "{}: no common fit range: {}",
        case.source.display(),
        range.not_compared.clone().unwrap_or_default()
    );
    let fit = |runs: &[&super::bed::EngineRun]| {
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
        kind: PENETRATION.to_string(),
        variants: Vec::new(),
        fit_h: Some((range.h_start, h_max.min(range.h_final))),
        k_phi,
        k_phi_nudged,
        log_ratio,
        final_depth: Vec::new(),
        final_depth_nudged: Vec::new(),
        depth_difference: Vec::new(),
        granval: env!("CARGO_PKG_VERSION").to_string(),
    })
}
