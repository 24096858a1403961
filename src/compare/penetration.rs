//! Penetration comparison (Feng et al. Sec. 3): two force-depth relations from the same bed,
//! reduced to K_phi, the FDR distance and the regime boundaries, each a gated check.

use super::Check;
use crate::analysis::fdr::{self, Fdr, LinearFit, RegimeBoundaries, TwoSegment};
use crate::case::penetration::PenetrationCase;
use anyhow::{Context, Result};
use serde::Serialize;

/// What one engine's run, or the mean of its ensemble of runs, reduces to.
#[derive(Debug, Clone, Serialize)]
pub struct Observables {
    /// The (ensemble-mean) binned FDR, h >= 0.
    pub fdr: Fdr,
    pub fit: LinearFit,
    /// h_A, h_B from the unified fit (eqs 13-15) with phi from K_phi: the paper's own
    /// definition, reported as a diagnostic (ill-conditioned at small R/d, see
    /// [`resolved_boundaries`]).
    pub boundaries: Option<RegimeBoundaries>,
    /// Why the unified fit failed, if it did.
    pub boundaries_error: Option<String>,
    /// h_A, h_B at grain resolution (the gated ones), or why the FDR does not
    /// resolve three regimes.
    pub resolved: Result<RegimeBoundaries, String>,
    /// Straightness of regime C: two-segment fit on h >= fit_h_min.
    pub regime_c: Result<TwoSegment, String>,
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

/// One grain diameter in units of R: the finest scale on which the FDR has
/// regimes (a shorter "segment" is a single force-chain failure).
pub fn grain_resolution(case: &PenetrationCase) -> f64 {
    case.diameter.mean() / case.intruder_radius
}

/// The gated h_A, h_B: [`fdr::regime_boundaries_piecewise`] with smoothing window and
/// minimum regime length both one grain diameter.
///
/// Why not the unified fit of eqs 13-15, which defines h_A and h_B in the paper: its
/// residual is nearly flat along a valley in (h_A, Gaussian width, phi). On the CI case
/// (R = 4 d) it put h_A anywhere in 0.26-1.2 at the same R^2 0.992, and across single
/// beds its h_A scattered with a standard deviation of 0.47 (native) and 0.75
/// (LIGGGHTS) R, five to eight times the 0.1 tolerance — a number that moves that much
/// with nothing physical cannot be gated. The piecewise fit's breakpoints are
/// conditioned by the slope contrasts between regimes instead; when the FDR has no
/// regime B shallower than A and C over at least a grain diameter, this says so
/// rather than return a boundary.
pub fn resolved_boundaries(case: &PenetrationCase, fdr: &Fdr) -> Result<RegimeBoundaries, String> {
    let g = grain_resolution(case);
    fdr::regime_boundaries_piecewise(fdr, g, g).map_err(|e| {
        format!("{e:#} (segments and smoothing window of one grain diameter, d/R = {g:.3})")
    })
}

/// Fit (regime C from `analysis.fit_h_min`) and regime boundaries of one FDR.
pub fn observables(case: &PenetrationCase, fdr: &Fdr) -> Result<Observables> {
    let fdr = fdr.contact_only();
    let fit = fdr::steady_state_fit(&fdr, case.fit_h_min, f64::INFINITY)?;
    let (boundaries, boundaries_error) = match fdr::regime_boundaries(&fdr, &fit) {
        Ok(b) => (Some(b), None),
        Err(e) => (None, Some(format!("{e:#}"))),
    };
    let g = grain_resolution(case);
    Ok(Observables {
        members: vec![(fit.k_phi, fit.r2)],
        resolved: resolved_boundaries(case, &fdr),
        regime_c: fdr::two_segment_fit(&fdr, case.fit_h_min, g, g).map_err(|e| format!("{e:#}")),
        fdr,
        fit,
        boundaries,
        boundaries_error,
    })
}

/// One line on how straight regime C is and where the unified fit puts h_A, h_B.
pub fn shape_text(o: &Observables) -> String {
    let c = match &o.regime_c {
        Ok(t) => format!(
            "regime C two-segment fit: slope {:.2} then {:.2} beyond h = {:.3} (R^2 {:.4})",
            t.slopes[0], t.slopes[1], t.h_break, t.r2
        ),
        Err(e) => format!("regime C two-segment fit failed: {e}"),
    };
    let u = match (&o.boundaries, &o.boundaries_error) {
        (Some(b), _) => format!(
            "unified fit (eqs 13-15, phi from K_phi; diagnostic): h_A = {:.3}, h_B = {:.3}, R^2 {:.4}",
            b.h_a, b.h_b, b.r2
        ),
        (None, e) => format!("unified fit failed: {}", e.as_deref().unwrap_or("?")),
    };
    format!("{c}; {u}")
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

/// Coverage of the steady-state fit of one engine's mean FDR: enough points in
/// regime C for K_phi to mean anything ([`super::coverage::MIN_FIT_POINTS`]).
pub fn fit_coverage(case: &PenetrationCase, o: &Observables, engine: &str) -> Vec<Check> {
    let n = o.fdr.h.iter().filter(|&&h| h >= case.fit_h_min).count();
    let name = format!("{}: coverage of the K_phi fit ({engine})", case.name);
    match super::coverage::fit_points(&name, "regime C (h >= fit_h_min) of the mean FDR", n) {
        Some(c) => vec![c],
        None => vec![Check::at_least(
            name,
            crate::compare::Gate::Coverage,
            "FDR points in regime C",
            n as f64,
            super::coverage::MIN_FIT_POINTS as f64,
            format!("h >= {}", case.fit_h_min),
        )],
    }
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
        crate::compare::Gate::QuasiStatic,
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
        crate::compare::Gate::Published,
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
        crate::compare::Gate::KPhi,
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
                crate::compare::Gate::FdrDistance,
                "RMS(p_test - p_ref) / mean p, regime C",
                d,
                tol.fdr_distance,
                format!("h in [{}, {h_hi:.3}]", case.fit_h_min),
            ),
            Err(e) => Check::error(name("FDR distance"), format!("{e:#}")),
        },
    );
    checks.extend(boundary_checks(case, test, reference));
    checks
}

/// h_A and h_B of two FDRs at grain resolution ([`resolved_boundaries`]).
///
/// Both resolved: |difference| against the case tolerances. One resolved and the other
/// not: a failed check (one engine shows a regime B the other does not). Neither: no
/// check, since there is no boundary to compare at this grain resolution;
/// [`boundaries_not_compared`] gives the report line that says why.
pub fn boundary_checks(
    case: &PenetrationCase,
    test: &Observables,
    reference: &Observables,
) -> Vec<Check> {
    let tol = &case.tolerances;
    let name = |w: &str| format!("{}: {w}", case.name);
    match (&test.resolved, &reference.resolved) {
        (Ok(a), Ok(b)) => vec![
            Check::at_most(
                name("h_A"),
                crate::compare::Gate::RegimeBoundaries,
                "|h_A,test - h_A,ref|",
                (a.h_a - b.h_a).abs(),
                tol.h_a_abs,
                format!(
                    "h_A: {:.3} vs {:.3} (piecewise-linear, grain resolution {:.3})",
                    a.h_a,
                    b.h_a,
                    grain_resolution(case)
                ),
            ),
            Check::at_most(
                name("h_B"),
                crate::compare::Gate::RegimeBoundaries,
                "|h_B,test - h_B,ref|",
                (a.h_b - b.h_b).abs(),
                tol.h_b_abs,
                format!("h_B: {:.3} vs {:.3}", a.h_b, b.h_b),
            ),
        ],
        (Ok(a), Err(e)) | (Err(e), Ok(a)) => {
            let which = if test.resolved.is_ok() {
                "test"
            } else {
                "reference"
            };
            vec![Check::failed(
                name("regime boundaries"),
                crate::compare::Gate::RegimeBoundaries,
                "three regimes resolved in one engine only",
                1.0,
                format!(
                    "{which} has h_A = {:.3}, h_B = {:.3}; the other: {e}",
                    a.h_a, a.h_b
                ),
            )]
        }
        (Err(_), Err(_)) => vec![],
    }
}

/// Why no h_A / h_B check was made, when neither FDR resolves three regimes.
pub fn boundaries_not_compared(test: &Observables, reference: &Observables) -> Option<String> {
    match (&test.resolved, &reference.resolved) {
        (Err(a), Err(b)) => Some(format!(
            "h_A / h_B NOT COMPARED: neither mean FDR resolves three regimes at grain resolution — test: {a}; reference: {b}"
        )),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::malt::{self, UnifiedFdr};

    /// The full-size d = 2 mm case: grain resolution d/R = 2/15.
    fn case() -> PenetrationCase {
        PenetrationCase::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("cases/penetration/feng-table2-d2mm.toml"),
        )
        .unwrap()
    }

    /// Fig. 2-like unified FDR (K_phi 23) with the given regime boundaries.
    fn fdr(h_a: f64, h_b: f64) -> Fdr {
        let m = UnifiedFdr {
            k_a: 60.0,
            k_phi: 23.0,
            h_a,
            h_b,
            delta: 0.03,
            p0: 0.5,
            phi: malt::phi_of_k(23.0).unwrap(),
        };
        let h: Vec<f64> = (0..=190).map(|i| i as f64 * 0.0125).collect();
        let p = h.iter().map(|&x| m.p(x)).collect();
        Fdr::new(h, p).unwrap()
    }

    fn line() -> Fdr {
        let h: Vec<f64> = (0..=190).map(|i| i as f64 * 0.0125).collect();
        let p = h.iter().map(|&x| 23.0 * x + 2.0).collect();
        Fdr::new(h, p).unwrap()
    }

    #[test]
    fn boundaries_agree_with_themselves() {
        let c = case();
        let o = observables(&c, &fdr(0.16, 0.61)).unwrap();
        let b = o.resolved.as_ref().unwrap();
        assert!((b.h_a - 0.16).abs() < 0.03, "{b:?}");
        let checks = boundary_checks(&c, &o, &o);
        assert_eq!(checks.len(), 2);
        assert!(
            checks.iter().all(|k| k.passed && k.value == 0.0),
            "{checks:?}"
        );
        assert!(boundaries_not_compared(&o, &o).is_none());
    }

    /// Negative controls: a regime A ending 0.3 R later, and a regime B that is absent in
    /// one engine, each fail.
    #[test]
    fn shifted_or_missing_regimes_fail() {
        let c = case();
        let a = observables(&c, &fdr(0.16, 0.61)).unwrap();
        let late = observables(&c, &fdr(0.46, 0.91)).unwrap();
        let checks = boundary_checks(&c, &a, &late);
        let h_a = checks.iter().find(|k| k.name.ends_with(": h_A")).unwrap();
        assert!(!h_a.passed && (h_a.value - 0.3).abs() < 0.1, "{h_a:?}");

        let straight = observables(&c, &line()).unwrap();
        assert!(straight.resolved.is_err());
        for (t, r) in [(&a, &straight), (&straight, &a)] {
            let checks = boundary_checks(&c, t, r);
            assert_eq!(checks.len(), 1);
            assert!(!checks[0].passed, "{checks:?}");
            assert!(checks[0].metric.contains("one engine only"));
        }
        // Neither resolves: nothing gated, and the report says so.
        assert!(boundary_checks(&c, &straight, &straight).is_empty());
        let note = boundaries_not_compared(&straight, &straight).unwrap();
        assert!(note.contains("NOT COMPARED"), "{note}");
    }
}
