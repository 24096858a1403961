//! Penetration comparison (issue 3): two force-depth relations from the same bed,
//! reduced to K_phi, the FDR distance and the regime boundaries, each a gated check.

use super::Check;
use crate::analysis::fdr::{self, Fdr, LinearFit, RegimeBoundaries};
use crate::case::penetration::PenetrationCase;
use anyhow::{Context, Result};
use serde::Serialize;

/// What one engine's run, or the mean of its ensemble of runs, reduces to.
#[derive(Debug, Clone, Serialize)]
pub struct Observables {
    /// The (ensemble-mean) binned FDR, h >= 0.
    pub fdr: Fdr,
    pub fit: LinearFit,
    pub boundaries: Option<RegimeBoundaries>,
    /// Why the boundaries could not be located, if they could not.
    pub boundaries_error: Option<String>,
    /// K_phi and R^2 of each member fitted alone (one entry for a single run).
    pub members: Vec<(f64, f64)>,
}

impl Observables {
    /// Sample standard deviation of the members' K_phi (NaN for one member).
    pub fn k_spread(&self) -> f64 {
        let n = self.members.len() as f64;
        let mean = self.members.iter().map(|m| m.0).sum::<f64>() / n;
        (self
            .members
            .iter()
            .map(|m| (m.0 - mean).powi(2))
            .sum::<f64>()
            / (n - 1.0))
            .sqrt()
    }

    fn members_text(&self) -> String {
        let ks: Vec<String> = self.members.iter().map(|m| format!("{:.2}", m.0)).collect();
        if self.members.len() > 1 {
            format!("beds [{}], sd {:.2}", ks.join(", "), self.k_spread())
        } else {
            "1 bed".into()
        }
    }
}

/// Fit (regime C from `analysis.fit_h_min`) and regime boundaries of one FDR.
pub fn observables(case: &PenetrationCase, fdr: &Fdr) -> Result<Observables> {
    let fdr = fdr.contact_only();
    let fit = fdr::steady_state_fit(&fdr, case.fit_h_min, f64::INFINITY)?;
    let (boundaries, boundaries_error) = match fdr::regime_boundaries(&fdr, &fit) {
        Ok(b) => (Some(b), None),
        Err(e) => (None, Some(format!("{e:#}"))),
    };
    Ok(Observables {
        members: vec![(fit.k_phi, fit.r2)],
        fdr,
        fit,
        boundaries,
        boundaries_error,
    })
}

/// Observables of an ensemble: everything on the mean FDR of the members (the
/// fluctuations of single realisations are what the ensemble averages out), plus each
/// member's own K_phi for the spread.
pub fn ensemble(case: &PenetrationCase, members: &[&Fdr]) -> Result<Observables> {
    let mut per = Vec::with_capacity(members.len());
    for (k, m) in members.iter().enumerate() {
        let fit = fdr::steady_state_fit(&m.contact_only(), case.fit_h_min, f64::INFINITY)
            .with_context(|| format!("bed {k}"))?;
        per.push((fit.k_phi, fit.r2));
    }
    let mean = fdr::ensemble_mean(members, case.h_bin)?;
    let mut obs = observables(case, &mean)?;
    obs.members = per;
    Ok(obs)
}

/// Sec. 3's quasi-static test: K_phi at the case speed and at `quasi_static.speed`.
pub fn quasi_static(
    case: &PenetrationCase,
    v1: &Observables,
    v2: &Observables,
    speed2: f64,
) -> Check {
    Check::at_most(
        format!("{}: quasi-static K_phi", case.name),
        "|K(v2) / K(v1) - 1|",
        (v2.fit.k_phi / v1.fit.k_phi - 1.0).abs(),
        case.tolerances.quasi_static_k_rel,
        format!(
            "native K_phi = {:.3} at {} m/s ({}), {:.3} at {speed2} m/s ({})",
            v1.fit.k_phi,
            case.speed,
            v1.members_text(),
            v2.fit.k_phi,
            v2.members_text()
        ),
    )
}

/// K_phi of one engine against the case's published value (e.g. Table 3).
pub fn published(case: &PenetrationCase, obs: &Observables, engine: &str) -> Option<Check> {
    let p = case.published.as_ref()?;
    Some(Check::at_most(
        format!("{}: K_phi vs published ({engine})", case.name),
        "|K / K_published - 1|",
        (obs.fit.k_phi / p.k_phi - 1.0).abs(),
        case.tolerances.published_k_rel,
        format!(
            "K_phi = {:.3} (R^2 {:.4}, {}) vs {} ({})",
            obs.fit.k_phi,
            obs.fit.r2,
            obs.members_text(),
            p.k_phi,
            p.source
        ),
    ))
}

/// Checks of `test` against `reference`, tolerances from the case file.
pub fn compare(case: &PenetrationCase, test: &Observables, reference: &Observables) -> Vec<Check> {
    let tol = &case.tolerances;
    let name = |w: &str| format!("{}: {w}", case.name);
    let mut checks = vec![Check::at_most(
        name("K_phi"),
        "|K_test / K_ref - 1|",
        (test.fit.k_phi / reference.fit.k_phi - 1.0).abs(),
        tol.k_phi_rel,
        format!(
            "K_test = {:.3} +- {:.3} (R^2 {:.4}; {}), K_ref = {:.3} +- {:.3} (R^2 {:.4}; {}), fitted on h >= {} of the mean FDR",
            test.fit.k_phi,
            test.fit.se_k,
            test.fit.r2,
            test.members_text(),
            reference.fit.k_phi,
            reference.fit.se_k,
            reference.fit.r2,
            reference.members_text(),
            case.fit_h_min
        ),
    )];
    let h_hi = test
        .fdr
        .h
        .last()
        .copied()
        .unwrap_or(0.0)
        .min(reference.fdr.h.last().copied().unwrap_or(0.0));
    checks.push(
        match fdr::rms_distance_over_mean(&test.fdr, &reference.fdr, case.fit_h_min, h_hi, 200) {
            Ok(d) => Check::at_most(
                name("FDR distance"),
                "RMS(p_test - p_ref) / mean p, regime C",
                d,
                tol.fdr_distance,
                format!("h in [{}, {h_hi:.3}]", case.fit_h_min),
            ),
            Err(e) => Check::error(name("FDR distance"), format!("{e:#}")),
        },
    );
    match (&test.boundaries, &reference.boundaries) {
        (Some(a), Some(b)) => {
            checks.push(Check::at_most(
                name("h_A"),
                "|h_A,test - h_A,ref|",
                (a.h_a - b.h_a).abs(),
                tol.h_a_abs,
                format!("h_A: {:.3} vs {:.3} (unified fit, eqs 13-15)", a.h_a, b.h_a),
            ));
            checks.push(Check::at_most(
                name("h_B"),
                "|h_B,test - h_B,ref|",
                (a.h_b - b.h_b).abs(),
                tol.h_b_abs,
                format!("h_B: {:.3} vs {:.3}", a.h_b, b.h_b),
            ));
        }
        _ => checks.push(Check::error(
            name("regime boundaries"),
            format!(
                "could not locate h_A/h_B: test {:?}, reference {:?}",
                test.boundaries_error, reference.boundaries_error
            ),
        )),
    }
    checks
}
