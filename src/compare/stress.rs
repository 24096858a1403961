//! Stress-field checks: phi native vs reference, each engine's (phi, K_phi) point
//! against the MALT curve (eq 10), and the unified FDR fit (eqs 13-15).

use super::penetration::Observables;
use super::{Check, Comparison, Rule};
use crate::analysis::malt;
use crate::analysis::stress_fields::{EngineFields, mean_std};
use crate::case::penetration::{PenetrationCase, Tolerances};
use crate::numerics::stats::Estimate;
use anyhow::Result;
use serde::Serialize;

/// An engine's (phi, K_phi) point with the FDR it came from.
#[derive(Debug, Clone, Serialize)]
pub struct EnginePoint {
    pub engine: String,
    /// Mean and sample sd of the window-averaged phi over every depth of every bed.
    pub phi_deg: f64,
    pub phi_std_deg: f64,
    /// The window-averaged phi of each requested depth of each bed, bed by bed (NaN
    /// where undefined): both engines snapshot the same steps of the same beds, so their
    /// difference can be taken window by window, which removes the depth-to-depth
    /// variation both share.
    pub phi_by_window: Vec<f64>,
    /// Each bed's phi (mean over its depths). The bed-by-bed difference is the honest
    /// measure of the engines' agreement: windows of one bed share its history and are
    /// not independent.
    pub phi_by_bed: Vec<f64>,
    pub k_phi: f64,
    pub k_phi_se: f64,
    /// Unified fit (eqs 13-15) with phi from the stress field: (h_A, h_B, R^2) or why not.
    pub unified: Result<(f64, f64, f64), String>,
    /// The same fit with the MALT-consistent phi(K_phi) (the penetration regime boundaries),
    /// reported alongside, not gated here.
    #[serde(default)]
    pub unified_malt: Option<(f64, f64, f64)>,
    /// Which force-depth relation K_phi and the unified fit come from.
    pub fdr_source: String,
}

/// |phi_test - phi_ref| <= `tol.phi_abs_deg`, phi pooled over all beds' windows; the
/// detail gives the bed-by-bed and window-by-window paired differences.
pub fn phi_check(
    case: &str,
    tol: &Tolerances,
    test: &EnginePoint,
    reference: &EnginePoint,
) -> Check {
    let beds = test.phi_by_bed.len();
    let paired = |what: &str, a: &[f64], b: &[f64]| match paired_difference(a, b) {
        Some((m, se, n)) => format!(
            "; {what} by {what} over {n}: difference {m:+.2} +- {se:.2} deg (mean +- standard error)"
        ),
        None => String::new(),
    };
    let per_bed = test
        .phi_by_bed
        .iter()
        .zip(&reference.phi_by_bed)
        .map(|(a, b)| format!("{:+.2}", a - b))
        .collect::<Vec<_>>()
        .join(", ");
    Check::at_most(
        format!("{case}: phi {} vs {}", test.engine, reference.engine),
        crate::compare::Gate::Phi,
        "|phi_test - phi_ref| (deg); sin phi = mean gamma over 0.995 gamma_max <= gamma (eqs 8-9)",
        (test.phi_deg - reference.phi_deg).abs(),
        tol.phi_abs_deg,
        format!(
            "phi: {} {:.2} +- {:.2} deg, {} {:.2} +- {:.2} deg (mean +- sd over {beds} bed(s) x depths of the window-averaged phi); per bed difference [{per_bed}]{}{}",
            test.engine,
            test.phi_deg,
            test.phi_std_deg,
            reference.engine,
            reference.phi_deg,
            reference.phi_std_deg,
            paired("bed", &test.phi_by_bed, &reference.phi_by_bed),
            paired("window", &test.phi_by_window, &reference.phi_by_window),
        ),
    )
}

/// The (phi, K_phi) point against the MALT curve: in K and in phi, and the unified fit.
pub fn malt_checks(case: &str, tol: &Tolerances, p: &EnginePoint) -> Vec<Check> {
    let name = |w: &str| format!("{case}: {} {w}", p.engine);
    let mut out = Vec::new();
    match malt::k_phi(p.phi_deg.to_radians()) {
        Ok(q) if p.phi_deg.is_finite() => out.push(Check::at_most(
            name("MALT distance in K"), crate::compare::Gate::MaltK,
            "|K_phi / K(phi) - 1| (eq 10)",
            (p.k_phi / q.value - 1.0).abs(),
            tol.malt_k_rel,
            format!(
                "K_phi = {:.3} +- {:.3} (FDR), K(phi = {:.2} deg) = {:.3}; K_phi / K(phi) - 1 = {:+.3}",
                p.k_phi,
                p.k_phi_se,
                p.phi_deg,
                q.value,
                p.k_phi / q.value - 1.0
            ),
        )),
        Ok(_) => out.push(Check::error(name("MALT distance in K"), "phi undefined")),
        Err(e) => out.push(Check::error(name("MALT distance in K"), format!("{e:#}"))),
    }
    match malt::phi_of_k(p.k_phi) {
        Ok(phi_k) if p.phi_deg.is_finite() => out.push(Check::at_most(
            name("MALT distance in phi"), crate::compare::Gate::MaltPhi,
            "|phi(K_phi) - phi| (deg), eq 10 inverted",
            (phi_k.to_degrees() - p.phi_deg).abs(),
            tol.malt_phi_abs_deg,
            format!(
                "phi(K_phi = {:.3}) = {:.2} deg, phi from stress = {:.2} deg; difference {:+.2} deg",
                p.k_phi,
                phi_k.to_degrees(),
                p.phi_deg,
                phi_k.to_degrees() - p.phi_deg
            ),
        )),
        Ok(_) => out.push(Check::error(name("MALT distance in phi"), "phi undefined")),
        Err(e) => out.push(Check::error(name("MALT distance in phi"), format!("{e:#}"))),
    }
    out.push(match &p.unified {
        Ok((ha, hb, r2)) => Check::at_most(
            name("unified FDR fit"), crate::compare::Gate::UnifiedFit,
            "1 - R^2 of the unified fit, eqs 13-15 (phi from stress)",
            1.0 - r2,
            1.0 - tol.unified_r2_min,
            match p.unified_malt {
                Some((ma, mb, mr2)) => format!(
                    "R^2 = {r2:.4}, h_A = {ha:.3}, h_B = {hb:.3}; with phi(K_phi) instead: R^2 = {mr2:.4}, h_A = {ma:.3}, h_B = {mb:.3}"
                ),
                None => format!("R^2 = {r2:.4}, h_A = {ha:.3}, h_B = {hb:.3}"),
            },
        ),
        Err(e) => Check::error(name("unified FDR fit"), e.clone()),
    });
    out
}

/// One engine's FDR reduced to its observables, with where it came from.
pub(crate) struct FdrObservables {
    pub obs: Observables,
    pub source: String,
}

/// The observables of the ensemble-mean FDR of `fdrs`, its source named `origin`.
pub(crate) fn mean_fdr(
    case: &PenetrationCase,
    fdrs: &[crate::analysis::fdr::Fdr],
    origin: &str,
    h_max: f64,
) -> Result<FdrObservables> {
    let o =
        crate::compare::penetration::ensemble_in(case, &fdrs.iter().collect::<Vec<_>>(), h_max)?;
    let source = format!(
        "{origin} (single beds K_phi {:?})",
        o.members
            .iter()
            .map(|m| (m.0 * 100.0).round() / 100.0)
            .collect::<Vec<_>>()
    );
    Ok(FdrObservables { obs: o, source })
}

/// Mean and standard error of `test - reference` over the windows where both are
/// defined; None with fewer than two such windows or different window counts.
pub fn paired_difference(test: &[f64], reference: &[f64]) -> Option<(f64, f64, usize)> {
    if test.len() != reference.len() {
        return None;
    }
    let d: Vec<f64> = test
        .iter()
        .zip(reference)
        .map(|(a, b)| a - b)
        .filter(|x| x.is_finite())
        .collect();
    (d.len() >= 2).then(|| {
        let (m, s) = mean_std(&d);
        (m, s / (d.len() as f64).sqrt(), d.len())
    })
}

/// An engine's (phi, K_phi) point: phi pooled over the stress fields of its beds, K_phi
/// and the unified fit (eqs 13-15, with that phi) from the given FDR.
pub(crate) fn engine_point(beds: &[&EngineFields], fdr: &FdrObservables) -> EnginePoint {
    engine_point_with(beds, fdr, None)
}

/// [`engine_point`] with phi (deg, its sd) given, e.g. estimator v2's, instead of the
/// pooled window phi of v1; the per-window and per-bed v1 values stay for the report.
pub(crate) fn engine_point_with(
    beds: &[&EngineFields],
    fdr: &FdrObservables,
    phi: Option<(f64, f64)>,
) -> EnginePoint {
    let phi_by_window: Vec<f64> = beds.iter().flat_map(|f| f.phi_by_window()).collect();
    let finite: Vec<f64> = phi_by_window
        .iter()
        .copied()
        .filter(|x| x.is_finite())
        .collect();
    let (phi_deg, phi_std_deg) = phi.unwrap_or_else(|| mean_std(&finite));
    let obs = &fdr.obs;
    let unified = if phi_deg.is_finite() {
        let c = obs.fdr.contact_only();
        malt::fit_unified_fdr(&c.h, &c.p, obs.fit.k_phi, phi_deg.to_radians())
            .map(|(u, r2)| (u.h_a, u.h_b, r2))
            .map_err(|e| format!("{e:#}"))
    } else {
        Err("phi undefined".to_string())
    };
    EnginePoint {
        engine: beds.first().map_or(String::new(), |f| f.engine.clone()),
        phi_deg,
        phi_std_deg,
        phi_by_window,
        phi_by_bed: beds.iter().map(|f| f.phi_deg).collect(),
        k_phi: obs.fit.k_phi,
        k_phi_se: obs.fit.se_k,
        unified,
        unified_malt: obs.boundaries.as_ref().map(|b| (b.h_a, b.h_b, b.r2)),
        fdr_source: fdr.source.clone(),
    }
}

/// Estimator v2's gate (docs/stress.md rule 2), judged as docs/statistics.md judges an
/// agreement: an equivalence test of phi_v2,test - phi_v2,ref within +-`phi_abs_deg`,
/// its standard error the paired bootstrap sd of the difference (beds and snapshots
/// resampled together) with beds - 1 degrees of freedom. One bed is INCONCLUSIVE: its
/// bootstrap resamples snapshots only and knows nothing of the next bed.
pub(crate) fn phi_v2_check(
    case: &str,
    tol: &Tolerances,
    test: &crate::analysis::stress_v2::PhiV2,
    reference: &crate::analysis::stress_v2::PhiV2,
) -> Check {
    use crate::analysis::stress_v2::paired_sd;
    let name = format!("{case}: phi v2 {} vs {}", test.engine, reference.engine);
    let sd = paired_sd(test, reference);
    let unpaired = test.sd_deg.hypot(reference.sd_deg);
    let detail = format!(
        "phi v2: {} {:.2} +- {:.2} deg, {} {:.2} +- {:.2} deg (bootstrap sd; {} beds, {} snapshots, h in {}); paired sd of the difference {}, unpaired {:.2}; admitted cells {} / {} (band {}) and {} / {} (band {}); gamma_max at r/R {:.2}, depth {:.2} R and r/R {:.2}, depth {:.2} R",
        test.engine,
        test.phi_deg,
        test.sd_deg,
        reference.engine,
        reference.phi_deg,
        reference.sd_deg,
        test.n_beds,
        test.n_snapshots,
        crate::numerics::fmt::interval(test.h_lo, test.h_hi, 3),
        sd.map_or("undefined (different draws)".to_string(), |s| format!(
            "{s:.2}"
        )),
        unpaired,
        test.n_admitted,
        test.n_masked,
        test.n_top,
        reference.n_admitted,
        reference.n_masked,
        reference.n_top,
        test.gamma_max_r,
        test.gamma_max_depth,
        reference.gamma_max_r,
        reference.gamma_max_depth,
    );
    let diff = test.phi_deg - reference.phi_deg;
    let estimate = sd
        .filter(|s| s.is_finite() && test.n_beds >= 2)
        .map(|se| Estimate {
            value: diff,
            se,
            df: (test.n_beds - 1) as f64,
            n: test.n_beds,
            sd: se * (test.n_beds as f64).sqrt(),
        });
    Check::decided(
        name,
        crate::compare::Gate::Phi,
        "phi_v2,test - phi_v2,ref (deg), estimator v2 (docs/stress.md rule 2)",
        &[Comparison {
            what: "phi v2 difference (deg; SE the paired bootstrap sd)".into(),
            estimate,
            rule: Rule::Equivalence {
                margin: tol.phi_abs_deg,
            },
            m: 1,
        }],
        detail,
    )
}

/// A published phi (e.g. 9 +- 1 deg for frictionless grains, Feng et al. Sec. 5)
/// against one engine's phi by one estimator.
pub(crate) fn published_phi_check(
    case: &PenetrationCase,
    engine: &str,
    estimator: &str,
    phi_deg: f64,
) -> Option<Check> {
    let p = case.published_phi.as_ref()?;
    Some(if phi_deg.is_finite() {
        Check::at_most(
            format!("{}: phi {estimator} vs published ({engine})", case.name),
            crate::compare::Gate::Published,
            "|phi - phi_published| (deg)",
            (phi_deg - p.phi_deg).abs(),
            p.abs_deg,
            format!(
                "phi {estimator} = {phi_deg:.2} deg vs {} deg ({})",
                p.phi_deg, p.source
            ),
        )
    } else {
        Check::error_in(
            format!("{}: phi {estimator} vs published ({engine})", case.name),
            crate::compare::Gate::Published,
            format!("phi {estimator} undefined"),
        )
    })
}
