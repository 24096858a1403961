//! Penetration comparison (Feng et al. Sec. 3): two force-depth relations from the same bed,
//! reduced to K_phi, the FDR distance and the regime boundaries, each a gated check.

use super::{Check, Comparison, Rule};
use crate::analysis::fdr::{self, Fdr, LinearFit, RegimeBoundaries, TwoSegment};
use crate::case::penetration::PenetrationCase;
use crate::numerics::stats::Estimate;
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
    /// Each member's own FDR (h >= 0), in bed order: what per-bed statistics of the
    /// force read (docs/statistics.md: the bed is the replicate).
    pub member_fdrs: Vec<Fdr>,
}

impl Observables {
    /// Sample standard deviation of the members' K_phi (NaN for one member).
    pub(crate) fn k_spread(&self) -> f64 {
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
pub(crate) fn grain_resolution(case: &PenetrationCase) -> f64 {
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
pub(crate) fn resolved_boundaries(
    case: &PenetrationCase,
    fdr: &Fdr,
) -> Result<RegimeBoundaries, String> {
    let g = grain_resolution(case);
    fdr::regime_boundaries_piecewise(fdr, g, g).map_err(|e| {
        format!("{e:#} (segments and smoothing window of one grain diameter, d/R = {g:.3})")
    })
}

/// Fit (regime C from `analysis.fit_h_min`) and regime boundaries of one FDR.
pub(crate) fn observables(case: &PenetrationCase, fdr: &Fdr) -> Result<Observables> {
    observables_in(case, fdr, f64::INFINITY)
}

/// [`observables`] with regime C ending at `h_max` (rule 3, [`fit_range`]).
pub(crate) fn observables_in(case: &PenetrationCase, fdr: &Fdr, h_max: f64) -> Result<Observables> {
    let fdr = fdr.contact_only();
    let fit = fdr::steady_state_fit(&fdr, case.fit_h_min, h_max)?;
    let (boundaries, boundaries_error) = match fdr::regime_boundaries(&fdr, &fit) {
        Ok(b) => (Some(b), None),
        Err(e) => (None, Some(format!("{e:#}"))),
    };
    let g = grain_resolution(case);
    Ok(Observables {
        members: vec![(fit.k_phi, fit.r2)],
        member_fdrs: vec![fdr.clone()],
        resolved: resolved_boundaries(case, &fdr),
        regime_c: fdr::two_segment_fit(&fdr, case.fit_h_min, g, g).map_err(|e| format!("{e:#}")),
        fdr,
        fit,
        boundaries,
        boundaries_error,
    })
}

/// One line on how straight regime C is and where the unified fit puts h_A, h_B.
pub(crate) fn shape_text(o: &Observables) -> String {
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
    ensemble_in(case, members, f64::INFINITY)
}

/// [`ensemble`] with regime C ending at `h_max`: the mean FDR and every member fitted on
/// [fit_h_min, h_max] (rule 3, [`fit_range`]).
pub(crate) fn ensemble_in(
    case: &PenetrationCase,
    members: &[&Fdr],
    h_max: f64,
) -> Result<Observables> {
    let mut per = Vec::with_capacity(members.len());
    for (k, m) in members.iter().enumerate() {
        let fit = fdr::steady_state_fit(&m.contact_only(), case.fit_h_min, h_max)
            .with_context(|| format!("bed {k}"))?;
        per.push((fit.k_phi, fit.r2));
    }
    let mean = fdr::ensemble_mean(members, case.h_bin)?;
    let mut obs = observables_in(case, &mean, h_max)?;
    obs.members = per;
    obs.member_fdrs = members.iter().map(|m| m.contact_only()).collect();
    Ok(obs)
}

/// Rule 3 of docs/stress.md ("The K_phi fit range from geometry"): the floor clearance
/// c of the stagnant cone's tip, in mean grain diameters (one basic-sphere diameter).
pub(crate) const FLOOR_CLEARANCE_D: f64 = 3.0;
/// Rule 3: at most this many fits per engine.
pub(crate) const MAX_RANGE_FITS: usize = 10;
/// Rule 3: a floor-free regime C spans at least this much (units of R), else K_phi is
/// NOT COMPARED.
pub(crate) const MIN_REGIME_C: f64 = 0.5;

/// One engine's self-consistent end of regime C (rule 3).
#[derive(Debug, Clone, Serialize)]
pub struct EngineRange {
    pub engine: String,
    /// h_C,end after each fit, in order (the first from the fit on [h_C,start, h_final]).
    pub ends: Vec<f64>,
    /// K_phi of each fit.
    pub k: Vec<f64>,
    pub h_end: f64,
    /// Whether h_C,end moved by less than one FDR bin (else the smallest end seen).
    pub converged: bool,
    /// phi(K_phi) of the last fit, deg.
    pub phi_deg: f64,
}

/// The K_phi fit range of a comparison (rule 3): regime C from `analysis.fit_h_min` to
/// the smaller of the engines' self-consistent ends.
#[derive(Debug, Clone, Serialize)]
pub struct FitRange {
    pub h_start: f64,
    /// The common end (the smaller engine end), capped at the final depth.
    pub h_end: f64,
    pub h_final: f64,
    /// Smallest bed surface height above the floor among the beds (m).
    pub bed_height: f64,
    /// c = 3 d_g (m).
    pub clearance: f64,
    /// Each engine's iteration, or why it failed.
    pub engines: Vec<(String, Result<EngineRange, String>)>,
    /// Why K_phi cannot be compared on this range (None: it can).
    pub not_compared: Option<String>,
}

impl FitRange {
    /// The upper end of the K_phi fits: the common end, or (when rule 3 gives no usable
    /// range) the whole FDR beyond fit_h_min, for reporting only.
    pub(crate) fn fit_end(&self) -> f64 {
        if self.h_end.is_finite() && self.h_end - self.h_start >= MIN_REGIME_C {
            self.h_end
        } else {
            f64::INFINITY
        }
    }

    pub fn text(&self) -> String {
        let per: Vec<String> = self
            .engines
            .iter()
            .map(|(e, r)| match r {
                Ok(r) => format!(
                    "{e}: h_C,end {:.3} ({}, fits {}, ends [{}], phi(K) {:.2} deg)",
                    r.h_end,
                    if r.converged {
                        "converged"
                    } else {
                        "not converged: smallest end"
                    },
                    r.ends.len(),
                    r.ends
                        .iter()
                        .map(|x| format!("{x:.3}"))
                        .collect::<Vec<_>>()
                        .join(", "),
                    r.phi_deg
                ),
                Err(why) => format!("{e}: {why}"),
            })
            .collect();
        format!(
            "rule 3 fit range: h in {} (bed height {:.4e} m, c = 3 d = {:.2e} m, h_final {:.3}); {}{}",
            crate::numerics::fmt::interval(self.h_start, self.h_end, 3),
            self.bed_height,
            self.clearance,
            self.h_final,
            per.join("; "),
            self.not_compared
                .as_ref()
                .map(|w| format!("; K_phi NOT COMPARED: {w}"))
                .unwrap_or_default()
        )
    }
}

/// h_C,end for a given phi: where the tip of the fully developed stagnant cone,
/// tan(45 deg + phi / 2) R below the face (eq 11's H_ss), comes within c of the floor,
/// capped at the final depth.
pub(crate) fn regime_c_end(case: &PenetrationCase, bed_height: f64, phi: f64) -> f64 {
    let c = FLOOR_CLEARANCE_D * case.diameter.mean();
    let h_final = case.final_depth / case.intruder_radius;
    ((bed_height - c) / case.intruder_radius - (std::f64::consts::FRAC_PI_4 + 0.5 * phi).tan())
        .min(h_final)
}

/// One engine's self-consistent h_C,end on its (ensemble-mean) FDR: fit on
/// [fit_h_min, h_final], phi(K_phi) (eq 10 inverted), h_C,end, refit on [fit_h_min,
/// h_C,end], until h_C,end moves by less than one FDR bin; after [`MAX_RANGE_FITS`]
/// fits the smallest end seen. A range too short to fit stops the iteration.
pub(crate) fn engine_range(
    case: &PenetrationCase,
    fdr: &Fdr,
    bed_height: f64,
    engine: &str,
) -> Result<EngineRange> {
    let fdr = fdr.contact_only();
    let h_final = case.final_depth / case.intruder_radius;
    let mut end = h_final;
    let mut out = EngineRange {
        engine: engine.to_string(),
        ends: Vec::new(),
        k: Vec::new(),
        h_end: f64::NAN,
        converged: false,
        phi_deg: f64::NAN,
    };
    for _ in 0..MAX_RANGE_FITS {
        let fit = match fdr::steady_state_fit(&fdr, case.fit_h_min, end) {
            Ok(f) => f,
            Err(_) if !out.ends.is_empty() => {
                // The range shrank below what can be fitted: it ends here.
                out.h_end = end;
                return Ok(out);
            }
            Err(e) => {
                return Err(e.context(format!("{engine}: fit on [{}, {end}]", case.fit_h_min)));
            }
        };
        let phi = crate::analysis::malt::phi_of_k(fit.k_phi)
            .with_context(|| format!("{engine}: phi(K_phi = {:.3})", fit.k_phi))?;
        let new = regime_c_end(case, bed_height, phi);
        out.k.push(fit.k_phi);
        out.ends.push(new);
        out.phi_deg = phi.to_degrees();
        if (new - end).abs() < case.h_bin {
            out.h_end = new;
            out.converged = true;
            return Ok(out);
        }
        end = new;
    }
    out.h_end = out.ends.iter().copied().fold(f64::INFINITY, f64::min);
    Ok(out)
}

/// Rule 3's common fit range of a comparison: each engine's [`engine_range`] on its mean
/// FDR, the smaller end; NOT COMPARED when an engine has no end or the range is shorter
/// than [`MIN_REGIME_C`].
pub(crate) fn fit_range(
    case: &PenetrationCase,
    bed_height: f64,
    engines: &[(&str, &Fdr)],
) -> FitRange {
    let h_final = case.final_depth / case.intruder_radius;
    let mut out = FitRange {
        h_start: case.fit_h_min,
        h_end: f64::NAN,
        h_final,
        bed_height,
        clearance: FLOOR_CLEARANCE_D * case.diameter.mean(),
        engines: Vec::new(),
        not_compared: None,
    };
    let mut end = f64::INFINITY;
    let mut why = Vec::new();
    for (name, f) in engines {
        match engine_range(case, f, bed_height, name) {
            Ok(r) => {
                end = end.min(r.h_end);
                out.engines.push((name.to_string(), Ok(r)));
            }
            Err(e) => {
                why.push(format!("{name}: {e:#}"));
                out.engines.push((name.to_string(), Err(format!("{e:#}"))));
            }
        }
    }
    out.h_end = if end.is_finite() { end } else { f64::NAN };
    if !why.is_empty() {
        out.not_compared = Some(format!("no regime-C end: {}", why.join("; ")));
    } else if out.h_end.is_nan() || out.h_end - out.h_start < MIN_REGIME_C {
        out.not_compared = Some(format!(
            "no floor-free regime C at this scale: h_C,end - h_C,start = {:.3} - {:.3} = {:.3} < {MIN_REGIME_C}",
            out.h_end,
            out.h_start,
            out.h_end - out.h_start
        ));
    }
    out
}

/// Bed by bed ln(K_test,k / K_ref,k), the per-bed statistic of the engine gate
/// (docs/statistics.md: ratios on the log scale, paired over the same beds); None when
/// the ensembles do not pair bed for bed.
pub(crate) fn paired_log_k(test: &Observables, reference: &Observables) -> Option<Vec<f64>> {
    (test.members.len() == reference.members.len()).then(|| {
        test.members
            .iter()
            .zip(&reference.members)
            .map(|(a, b)| (a.0 / b.0).ln())
            .collect()
    })
}

/// The K_phi gate on rule 3's range: the engines' K_phi agree within `k_phi_rel`, an
/// equivalence test (docs/statistics.md) on the bed-by-bed ln(K_test / K_ref) with the
/// margin ln(1 + k_phi_rel). One bed is INCONCLUSIVE; no floor-free regime C is NOT
/// COMPARED. The mean FDRs' K_phi are reported beside it.
pub(crate) fn k_phi_check(
    case: &PenetrationCase,
    range: &FitRange,
    test: &Observables,
    reference: &Observables,
) -> Check {
    let tol = case.tolerances.k_phi_rel;
    let name = format!("{}: K_phi", case.name);
    let logs = paired_log_k(test, reference);
    let open = case.k_phi_range == crate::case::penetration::KPhiRange::Open;
    let detail = format!(
        "mean FDRs: K_test = {:.3} +- {:.3} (regression SE; R^2 {:.4}; {}), K_ref = {:.3} +- {:.3} (R^2 {:.4}; {}), fitted on h in {}, K_test / K_ref - 1 = {:+.4}; {}",
        test.fit.k_phi,
        test.fit.se_k,
        test.fit.r2,
        test.members_text(),
        reference.fit.k_phi,
        reference.fit.se_k,
        reference.fit.r2,
        reference.members_text(),
        crate::numerics::fmt::interval(test.fit.h_lo, test.fit.h_hi, 3),
        test.fit.k_phi / reference.fit.k_phi - 1.0,
        range.text()
    );
    if let Some(why) = range.not_compared.as_ref().filter(|_| !open) {
        return Check::not_compared(name, crate::compare::Gate::KPhi, format!("{why}; {detail}"));
    }
    let comparison = Comparison {
        what: "bed by bed ln(K_test / K_ref)".into(),
        estimate: logs.as_deref().and_then(Estimate::mean),
        rule: Rule::Equivalence {
            margin: (1.0 + tol).ln(),
        },
        m: 1,
    };
    let detail = if open {
        // `analysis.k_phi_range = "open"`: every bed fitted to its final depth; rule 3's
        // range is reported, not applied.
        format!("open fit range (rule 3 reported, not applied); {detail}")
    } else {
        detail
    };
    Check::decided(
        name,
        crate::compare::Gate::KPhi,
        "ln(K_test / K_ref), mean over beds",
        &[comparison],
        detail,
    )
}

/// Coverage of the steady-state fit of one engine's mean FDR: enough points in
/// regime C for K_phi to mean anything ([`super::coverage::MIN_FIT_POINTS`]).
pub(crate) fn fit_coverage(case: &PenetrationCase, o: &Observables, engine: &str) -> Vec<Check> {
    let n = o
        .fdr
        .h
        .iter()
        .filter(|&&h| h >= case.fit_h_min && h <= o.fit.h_hi)
        .count();
    let name = format!("{}: coverage of the K_phi fit ({engine})", case.name);
    match super::coverage::fit_points(&name, "regime C (h >= fit_h_min) of the mean FDR", n) {
        Some(c) => vec![c],
        None => vec![Check::at_least(
            name,
            crate::compare::Gate::Coverage,
            "FDR points in regime C",
            n as f64,
            super::coverage::MIN_FIT_POINTS as f64,
            format!("h in [{}, {:.3}]", case.fit_h_min, o.fit.h_hi),
        )],
    }
}

/// Sec. 3's quasi-static test: K_phi does not depend on the speed. An equivalence test
/// (docs/statistics.md) on the bed-by-bed ln(K(v2) / K(v1)) of the same beds, margin
/// ln(1 + quasi_static_k_rel).
pub fn quasi_static(
    case: &PenetrationCase,
    v1: &Observables,
    v2: &Observables,
    speed2: f64,
) -> Check {
    Check::decided(
        format!("{}: quasi-static K_phi", case.name),
        crate::compare::Gate::QuasiStatic,
        "ln(K(v2) / K(v1)), mean over beds",
        &[Comparison {
            what: "bed by bed ln(K(v2) / K(v1))".into(),
            estimate: paired_log_k(v2, v1).as_deref().and_then(Estimate::mean),
            rule: Rule::Equivalence {
                margin: (1.0 + case.tolerances.quasi_static_k_rel).ln(),
            },
            m: 1,
        }],
        format!(
            "native K_phi on the mean FDRs = {:.3} at {} m/s ({}), {:.3} at {speed2} m/s ({})",
            v1.fit.k_phi,
            case.speed,
            v1.members_text(),
            v2.fit.k_phi,
            v2.members_text()
        ),
    )
}

/// K_phi of one engine against the case's published value (e.g. Table 3): an
/// equivalence test on the bed-by-bed ln(K / K_published), margin ln(1 +
/// published_k_rel); one bed is INCONCLUSIVE.
pub fn published(case: &PenetrationCase, obs: &Observables, engine: &str) -> Option<Check> {
    let p = case.published.as_ref()?;
    let logs: Vec<f64> = obs.members.iter().map(|m| (m.0 / p.k_phi).ln()).collect();
    Some(Check::decided(
        format!("{}: K_phi vs published ({engine})", case.name),
        crate::compare::Gate::Published,
        "ln(K / K_published), mean over beds",
        &[Comparison {
            what: "bed by bed ln(K / K_published)".into(),
            estimate: Estimate::mean(&logs),
            rule: Rule::Equivalence {
                margin: (1.0 + case.tolerances.published_k_rel).ln(),
            },
            m: 1,
        }],
        format!(
            "K_phi on the mean FDR = {:.3} (R^2 {:.4}, {}) vs {} ({})",
            obs.fit.k_phi,
            obs.fit.r2,
            obs.members_text(),
            p.k_phi,
            p.source
        ),
    ))
}

/// Checks of `test` against `reference` (both fitted on `range`, rule 3), tolerances
/// from the case file.
pub fn compare(
    case: &PenetrationCase,
    range: &FitRange,
    test: &Observables,
    reference: &Observables,
) -> Vec<Check> {
    let tol = &case.tolerances;
    let name = |w: &str| format!("{}: {w}", case.name);
    let mut checks = vec![k_phi_check(case, range, test, reference)];
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
    checks
}

/// h_A and h_B of the two engines, reported and not gated (docs/statistics.md, "Checks
/// without a decision rule"): the grain-resolution detector has no null model and no
/// uncertainty, so what it finds on a mean FDR is not evidence either way. Each line says
/// what the old gate would have said.
pub(crate) fn boundary_notes(
    case: &PenetrationCase,
    test: &Observables,
    reference: &Observables,
) -> Vec<String> {
    boundary_checks(case, test, reference)
        .into_iter()
        .map(|c| {
            format!(
                "REPORTED, not gated (h_A/h_B: no null model or uncertainty, docs/statistics.md): {} = {:.4} against {} -> would {}; {}",
                c.metric,
                c.value,
                c.tolerance,
                c.status.label(),
                c.detail
            )
        })
        .chain(boundaries_not_compared(test, reference))
        .collect()
}

/// h_A and h_B of two FDRs at grain resolution ([`resolved_boundaries`]).
///
/// Both resolved: |difference| against the case tolerances. One resolved and the other
/// not: a failed check (one engine shows a regime B the other does not). Neither: no
/// check, since there is no boundary to compare at this grain resolution;
/// [`boundaries_not_compared`] gives the report line that says why.
pub(crate) fn boundary_checks(
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
pub(crate) fn boundaries_not_compared(
    test: &Observables,
    reference: &Observables,
) -> Option<String> {
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
