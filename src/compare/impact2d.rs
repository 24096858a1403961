//! Impact checks (Kondic et al.): native vs LAMMPS per variant (final depth, D(t) RMS
//! distance), and K's claims over a sweep, evaluated separately in each engine.

use super::ensemble::{self, ValueStats};
use super::{Check, Gate};
use crate::analysis::affine::{AffineGrain, AffineSummary};
use crate::analysis::force_network::{B0Curves, integral, relative_l1};
use crate::analysis::impact::{
    DepthExponent, ForceSummary, bins_rms, exponent_at_depth, force_summary,
};
use crate::case::impact2d::{Claim, ClaimQuantity, FieldQuantity, Impact2dCase, TrendDirection};
use crate::numerics::stats::Estimate;

/// Why an `increasing` claim fails although every step met min_step: with min_step 0
/// (and, on an ensemble, zero spread) a step that stays flat or falls meets the bound.
const FLAT_STEP: &str =
    "a step does not rise (increasing means strictly rising, whatever min_step)";

/// The bed fields of one run (K Sec. IV), reduced.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct FieldObs {
    /// (t in tau_c after release, B0 curves of both networks).
    pub networks: Vec<(f64, B0Curves)>,
    /// Affine field and D2_min summary (lengths in d), at `affine_t` (tau_c).
    pub affine: Option<AffineSummary>,
    pub affine_t: f64,
    /// Per grain, positions and A_f in d, D2_min in d^2 (for the maps).
    #[serde(skip)]
    pub affine_map: Vec<AffineGrain>,
}

/// What one run of one variant reduces to (lengths in d).
#[derive(Debug, Clone, serde::Serialize)]
pub struct VariantObs {
    pub label: String,
    pub x: f64,
    pub final_depth: f64,
    pub max_depth: f64,
    /// When the maximum depth was reached (tau_c after release).
    pub t_max_depth: f64,
    /// Total energy (kinetic + potential relative to the first sample + normal elastic)
    /// at each energy sample: (t in tau_c after release, E in m g d).
    pub energy: Vec<(f64, f64)>,
    /// The intruder's impact energy M v^2 / 2 (m g d).
    pub impact_energy: f64,
    /// Largest |v| of the intruder in the final window (d / tau_c): is it at rest?
    pub final_speed: f64,
    /// Samples the final depth was averaged over.
    pub final_samples: usize,
    /// (t in tau_c, D in d, downward speed in d / tau_c) at every intruder sample, for
    /// claims on the force law (K Fig 29).
    #[serde(skip)]
    pub trajectory: Vec<(f64, f64, f64)>,
    /// (t in tau_c, F_y in m g) at every intruder sample: the contact force on the
    /// intruder along y, upward positive (K Fig 21).
    #[serde(skip)]
    pub force: Vec<(f64, f64)>,
    pub fields: Option<FieldObs>,
    /// The depth below the moving interface (K Fig 12), in cases that track it; left out
    /// of `final_depths.json` otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interface: Option<super::interface::InterfaceObs>,
}

/// The bin width of a case's force claims: its `force_impulsive` claim's, else 1 tau_c.
pub(crate) fn force_bin(case: &Impact2dCase) -> f64 {
    case.claims
        .iter()
        .find_map(|c| match c {
            Claim::ForceImpulsive { bin, .. } => Some(*bin),
            _ => None,
        })
        .unwrap_or(1.0)
}

/// Whether a case has force claims (and so the force cross-check).
pub(crate) fn has_force_claims(case: &Impact2dCase) -> bool {
    case.claims
        .iter()
        .any(|c| matches!(c, Claim::ForceImpulsive { .. } | Claim::ForceSimilar { .. }))
}

/// Native vs reference force on the intruder (K Fig 21), for a case with force claims:
/// the largest of the relative differences of the peak bin, of the impulse over the
/// case's force window, and the RMS of the binned F(t) over that window over the peak.
pub(crate) fn force_cross_check(
    case: &Impact2dCase,
    a: &VariantObs,
    b: &VariantObs,
    reference: &str,
) -> Option<Check> {
    if !has_force_claims(case) {
        return None;
    }
    let tol = &case.tolerances;
    let name = format!(
        "{} [{}]: force on the intruder native vs {reference}",
        case.name, a.label
    );
    let bin = force_bin(case);
    let w = tol.force_window;
    let both =
        force_summary(&a.force, bin, w).and_then(|fa| Ok((fa, force_summary(&b.force, bin, w)?)));
    Some(match both {
        Ok((fa, fb)) => {
            let rms = bins_rms(&fa.bins, &fb.bins, fb.t_contact + w);
            match rms {
                Ok(rms) => {
                    let dp = (fa.peak - fb.peak).abs() / fb.peak.abs();
                    let dj = (fa.impulse - fb.impulse).abs() / fb.impulse.abs();
                    let dr = rms / fb.peak.abs();
                    Check::at_most(
                        name,
                        Gate::IntruderForce,
                        format!(
                            "max(|dF_peak|, |dJ|, RMS dF_bin) relative ({w} tau_c after contact)"
                        ),
                        dp.max(dj).max(dr),
                        tol.force_rel,
                        format!(
                            "peak {:.1} vs {:.1} m g ({dp:.2e}); impulse {:.1} vs {:.1} m g tau_c ({dj:.2e}); binned RMS / peak {dr:.2e}; first contact {:.2} vs {:.2} tau_c",
                            fa.peak, fb.peak, fa.impulse, fb.impulse, fa.t_contact, fb.t_contact
                        ),
                    )
                }
                Err(e) => Check::error_in(name, Gate::IntruderForce, format!("{e:#}")),
            }
        }
        Err(e) => Check::error_in(name, Gate::IntruderForce, format!("{e:#}")),
    })
}

/// Native vs reference bed fields: B0 curves (per time and network) and the affine
/// summaries.
pub(crate) fn field_cross_checks(
    case: &Impact2dCase,
    a: &VariantObs,
    b: &VariantObs,
    reference: &str,
) -> Vec<Check> {
    let tol = &case.tolerances;
    let mut out = Vec::new();
    let (Some(fa), Some(fb)) = (&a.fields, &b.fields) else {
        if case.fields.is_some() {
            out.push(Check::error_in(
                format!("{} [{}]: fields", case.name, a.label),
                Gate::ForceNetwork,
                "a run has no field snapshots",
            ));
        }
        return out;
    };
    for ((t, ca), (_, cb)) in fa.networks.iter().zip(&fb.networks) {
        for (what, x, y) in [
            ("normal", &ca.normal, &cb.normal),
            ("tangential", &ca.tangential, &cb.tangential),
        ] {
            let d = relative_l1(&ca.thresholds, x, y);
            out.push(Check::at_most(
                format!(
                    "{} [{}]: B0 of the {what} force network at t = {t} tau_c native vs {reference}",
                    case.name, a.label
                ),
                Gate::ForceNetwork,
                "L1 distance of B0/N curves / reference integral",
                d,
                tol.b0_distance,
                format!(
                    "integrals {:.4} vs {:.4}; peak B0/N {:.4} vs {:.4}; grains {} / {}, grain-grain contacts {} / {}",
                    integral(&ca.thresholds, x),
                    integral(&cb.thresholds, y),
                    x.iter().copied().fold(0.0, f64::max),
                    y.iter().copied().fold(0.0, f64::max),
                    ca.grains,
                    cb.grains,
                    ca.grain_contacts,
                    cb.grain_contacts
                ),
            ));
        }
    }
    if fa.networks.len() != fb.networks.len() {
        out.push(Check::error_in(
            format!("{} [{}]: B0 snapshots", case.name, a.label),
            Gate::ForceNetwork,
            format!(
                "{} vs {} network snapshots",
                fa.networks.len(),
                fb.networks.len()
            ),
        ));
    }
    if let (Some(sa), Some(sb)) = (&fa.affine, &fb.affine) {
        let pairs = [
            ("mean |A_f|", sa.mean_af, sb.mean_af),
            ("mean |A_f . j|", sa.mean_af_y, sb.mean_af_y),
            ("mean D2_min", sa.mean_d2min, sb.mean_d2min),
            ("median D2_min", sa.median_d2min, sb.median_d2min),
            ("90th percentile of D2_min", sa.p90_d2min, sb.p90_d2min),
        ];
        let worst = pairs
            .iter()
            .map(|(_, x, y)| (x - y).abs() / y.abs())
            .fold(f64::NEG_INFINITY, f64::max);
        out.push(Check::at_most(
            format!(
                "{} [{}]: affine field and D2_min at t = {} tau_c native vs {reference}",
                case.name, a.label, fa.affine_t
            ),
            Gate::DisplacementField,
            "largest relative difference of the summaries",
            if worst.is_nan() { f64::INFINITY } else { worst },
            tol.field_rel,
            format!(
                "{}; grains {} / {} (left out {} / {})",
                pairs
                    .iter()
                    .map(|(n, x, y)| format!("{n} {x:.4e} vs {y:.4e}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                sa.grains,
                sb.grains,
                sa.skipped,
                sb.skipped
            ),
        ));
    } else if case.fields.as_ref().is_some_and(|f| f.affine.is_some()) {
        out.push(Check::error_in(
            format!("{} [{}]: affine field", case.name, a.label),
            Gate::DisplacementField,
            "a run has no affine field",
        ));
    }
    out
}

/// A field summary of one variant (`None` where it has none).
fn field_value(o: &VariantObs, q: FieldQuantity) -> Vec<(Option<f64>, f64)> {
    let Some(f) = &o.fields else {
        return vec![];
    };
    match q {
        FieldQuantity::B0Normal => f
            .networks
            .iter()
            .map(|(t, c)| (Some(*t), integral(&c.thresholds, &c.normal)))
            .collect(),
        FieldQuantity::B0Tangential => f
            .networks
            .iter()
            .map(|(t, c)| (Some(*t), integral(&c.thresholds, &c.tangential)))
            .collect(),
        FieldQuantity::Affine => f.affine.iter().map(|s| (None, s.mean_af)).collect(),
        FieldQuantity::AffineY => f.affine.iter().map(|s| (None, s.mean_af_y)).collect(),
        FieldQuantity::D2min => f.affine.iter().map(|s| (None, s.mean_d2min)).collect(),
    }
}

/// The force summaries of every variant, or the first error.
fn force_summaries(obs: &[VariantObs], bin: f64, window: f64) -> Result<Vec<ForceSummary>, String> {
    obs.iter()
        .map(|o| force_summary(&o.force, bin, window).map_err(|e| format!("{}: {e:#}", o.label)))
        .collect()
}

/// (max - min) / mean.
fn spread(v: &[f64]) -> f64 {
    let (lo, hi) = v
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    (hi - lo) / (v.iter().sum::<f64>() / v.len() as f64)
}

/// Native vs reference for one variant. `rms` is the D(t) RMS distance in d, or the
/// reason it could not be computed.
pub fn cross_check(
    case: &Impact2dCase,
    a: &VariantObs,
    b: &VariantObs,
    rms: Result<f64, String>,
    reference: &str,
) -> Vec<Check> {
    let tol = &case.tolerances;
    let name = |w: &str| format!("{} [{}]: {w}", case.name, a.label);
    let n = a.final_samples.min(b.final_samples);
    if let Some(c) = super::coverage::fit_points(
        &name("coverage of the final-depth window"),
        "intruder samples in the final window (final_window / output_every)",
        n,
    ) {
        return vec![
            c,
            Check::not_compared(
                name(&format!("final depth native vs {reference}")),
                crate::compare::Gate::FinalDepth,
                "too few samples in the final window",
            ),
        ];
    }
    let mut out = vec![Check::at_most(
        name(&format!("final depth native vs {reference}")),
        crate::compare::Gate::FinalDepth,
        "|D_native - D_ref| / d",
        (a.final_depth - b.final_depth).abs(),
        tol.final_depth_abs,
        format!(
            "D_native = {:.3} d, D_{reference} = {:.3} d (mean over the last {:.0} tau_c; max intruder speed there {:.1e} / {:.1e} d/tau_c)",
            a.final_depth,
            b.final_depth,
            case.final_window / case.scales.tau_c,
            a.final_speed,
            b.final_speed
        ),
    )];
    out.push(match rms {
        Ok(r) => Check::at_most(
            name("D(t) distance"),
            crate::compare::Gate::DepthSeries,
            "RMS(D_native - D_ref) / d",
            r,
            tol.depth_rms,
            format!("max depth {:.3} d vs {:.3} d", a.max_depth, b.max_depth),
        ),
        Err(e) => Check::error(name("D(t) distance"), e),
    });
    out
}

/// K's claims of the case over its variants (in sweep order), for one engine. On a seed
/// ensemble (`[bed] seeds`) each claim is judged on the per-value means over the seeds
/// ([`ensemble_claim_check`]).
pub fn claim_checks(case: &Impact2dCase, engine: &str, obs: &[VariantObs]) -> Vec<Check> {
    if case.is_ensemble() {
        return case
            .claims
            .iter()
            .flat_map(|c| match c {
                Claim::VelocityExponentPerDepth { .. } => {
                    per_depth_exponent_checks(case, c, engine, obs)
                }
                Claim::FieldOrder { .. } => vec![ensemble_field_order_check(case, c, engine, obs)],
                _ => vec![ensemble_claim_check(case, c, engine, obs)],
            })
            .collect();
    }
    case.claims
        .iter()
        .flat_map(|c| {
            let compares = compares_conditions(c);
            single_bed_rule(case, c, engine, obs)
                .into_iter()
                .map(move |k| if compares { one_bed(k) } else { k })
        })
        .collect()
}

/// A claim's rule on one bed, as registered: the verdict of a property of every run, and
/// what a comparison between conditions would say if one bed could decide it.
fn single_bed_rule(
    case: &Impact2dCase,
    claim: &Claim,
    engine: &str,
    obs: &[VariantObs],
) -> Vec<Check> {
    match claim {
        Claim::FieldOrder { .. } => field_order_checks(case, claim, engine, obs),
        _ => vec![claim_check(case, claim, engine, obs)],
    }
}

/// Whether a claim compares measured quantities between conditions (kind 3 of
/// docs/statistics.md, "Three kinds of check") rather than stating a property of every
/// run (energy, the impulsive force, the interface: kind 2). The size claim runs on
/// several seeds and is judged over them.
fn compares_conditions(c: &Claim) -> bool {
    matches!(
        c,
        Claim::Increasing { .. }
            | Claim::Trend { .. }
            | Claim::Linear { .. }
            | Claim::VelocityExponent { .. }
            | Claim::VelocityExponentPerDepth { .. }
            | Claim::ForceSimilar { .. }
            | Claim::FieldOrder { .. }
    )
}

/// A comparison between conditions on one bed (one seed): no bed-to-bed variance, so
/// INCONCLUSIVE whatever the single-bed rule says (docs/statistics.md, "One bed"); the
/// value and what the old rule would have said stay in the report. An error or NOT
/// COMPARED is kept as it is.
fn one_bed(k: Check) -> Check {
    if !matches!(k.status, super::Status::Pass | super::Status::Fail) {
        return k;
    }
    let detail = format!(
        "one bed (one seed): a comparison between conditions has no bed-to-bed variance, so it is not resolved (docs/statistics.md); the single-bed rule gives {} ({} = {:.4}, threshold {}); {}",
        k.status.label(),
        k.metric,
        k.value,
        k.tolerance,
        k.detail
    );
    Check::with_status(
        k.name,
        k.gate,
        k.metric,
        k.value,
        k.tolerance,
        super::Status::Inconclusive,
        detail,
    )
}

/// A `field_order` claim: one check per field time (B0) or one (affine, D2_min).
fn field_order_checks(
    case: &Impact2dCase,
    claim: &Claim,
    engine: &str,
    obs: &[VariantObs],
) -> Vec<Check> {
    let Claim::FieldOrder {
        quantity,
        larger,
        smaller,
        min_ratio,
        max_ratio,
    } = claim
    else {
        return vec![];
    };
    let find = |l: &str| obs.iter().find(|o| o.label == l);
    let base = format!(
        "{}: claim ({engine}): {} larger with {larger} than with {smaller}",
        case.name,
        quantity.describe()
    );
    let (Some(a), Some(b)) = (find(larger), find(smaller)) else {
        return vec![Check::error_in(
            base,
            Gate::Claim,
            "a variant of the claim did not run",
        )];
    };
    let (va, vb) = (field_value(a, *quantity), field_value(b, *quantity));
    if va.is_empty() || va.len() != vb.len() {
        return vec![Check::error_in(
            base,
            Gate::Claim,
            "no field summary in a variant",
        )];
    }
    va.iter()
        .zip(&vb)
        .map(|(&(t, x), &(_, y))| {
            let name = match t {
                Some(t) => format!("{base} at t = {t} tau_c"),
                None => base.clone(),
            };
            let ratio = x / y;
            let detail = format!(
                "{larger}: {x:.5e}, {smaller}: {y:.5e}; ratio {ratio:.4} (registered >= {min_ratio}{})",
                max_ratio.map_or(String::new(), |m| format!(", <= {m}"))
            );
            let metric = format!("{larger} / {smaller}");
            if max_ratio.is_some_and(|m| ratio > m) {
                Check::failed(name, Gate::Claim, metric, ratio, format!("above the maximum: {detail}"))
            } else {
                Check::at_least(name, Gate::Claim, metric, ratio, *min_ratio, detail)
            }
        })
        .collect()
}

/// One seed's run of a sweep value: its seed, its variant and its field summaries
/// ((time, value) per field time, or one).
type SeedRun<'a> = (
    u64,
    &'a crate::case::impact2d::Variant,
    Vec<(Option<f64>, f64)>,
);

/// The runs of sweep value `label` of a seed ensemble, in seed order, with the field
/// summaries of `quantity`; an error names a run without a result or a summary.
fn seed_runs<'a>(
    case: &'a Impact2dCase,
    obs: &[VariantObs],
    quantity: FieldQuantity,
    label: &str,
) -> Result<Vec<SeedRun<'a>>, String> {
    let groups = case.ensemble_groups();
    let g = groups
        .iter()
        .find(|g| g.value == label)
        .ok_or_else(|| format!("no sweep value {label}"))?;
    g.members
        .iter()
        .map(|&k| {
            let v = &case.variants[k];
            let o = obs
                .iter()
                .find(|o| o.label == v.label)
                .ok_or_else(|| format!("run {} has no result", v.label))?;
            let x = field_value(o, quantity);
            if x.is_empty() {
                return Err(format!("run {}: no field summary", v.label));
            }
            Ok((case.bed_of(v).seed, v, x))
        })
        .collect()
}

/// The comparisons of one log ratio `what` (estimated by `est`): above ln `min_ratio`,
/// and with `max_ratio` below its log too (the same estimate, mirrored), each counted
/// among the claim's `m` for the Bonferroni level of a failure.
fn ratio_comparisons(
    what: String,
    est: Option<Estimate>,
    min_ratio: f64,
    max_ratio: Option<f64>,
    m: usize,
) -> Vec<super::Comparison> {
    let mut out = vec![super::Comparison {
        what: what.clone(),
        estimate: est,
        rule: super::Rule::Exceeds {
            delta: min_ratio.ln(),
        },
        m,
    }];
    if let Some(hi) = max_ratio {
        out.push(super::Comparison {
            what: format!("ln {hi} - {what}"),
            estimate: est.map(|e| Estimate {
                value: hi.ln() - e.value,
                ..e
            }),
            rule: super::Rule::Exceeds { delta: 0.0 },
            m,
        });
    }
    out
}

/// A `field_order` claim over a seed ensemble (docs/statistics.md, "A ratio at least
/// R"): for each field time (B0) or once (the affine summaries), the 90 % interval of
/// ln(X_larger / X_smaller) over the seeds, paired by seed when the two variants of every
/// seed ran on the same bed (the bed-to-bed offset cancels), else Welch's interval of
/// the two groups' ln X (each friction model on beds settled with its own law). It must
/// exceed ln(min_ratio), and with `max_ratio` also stay below ln(max_ratio). One check:
/// PASS when every comparison passes (every time, both ends), FAIL when one fails at the
/// Bonferroni level of all of them, else INCONCLUSIVE.
fn ensemble_field_order_check(
    case: &Impact2dCase,
    claim: &Claim,
    engine: &str,
    obs: &[VariantObs],
) -> Check {
    let Claim::FieldOrder {
        quantity,
        larger,
        smaller,
        min_ratio,
        max_ratio,
    } = claim
    else {
        return Check::error_in(
            format!("{}: claim ({engine})", case.name),
            Gate::Claim,
            "not a field_order claim",
        );
    };
    let n = case.seeds.len();
    let name = format!(
        "{}: claim ({engine}): {} larger with {larger} than with {smaller} (over {n} seeds)",
        case.name,
        quantity.describe()
    );
    let members = |label: &str| seed_runs(case, obs, *quantity, label);
    let (big, small) = match (members(larger), members(smaller)) {
        (Ok(a), Ok(b)) => (a, b),
        (Err(e), _) | (_, Err(e)) => return Check::error_in(name, Gate::Claim, e),
    };
    let same_seeds = big.len() == small.len()
        && big
            .iter()
            .zip(&small)
            .all(|(a, b)| a.0 == b.0 && a.2.len() == b.2.len());
    if !same_seeds || big.is_empty() {
        return Check::error_in(
            name,
            Gate::Claim,
            "the two variants do not hold the same seeds and field times",
        );
    }
    // Paired only when every seed's two runs started from the very same bed.
    let paired = big
        .iter()
        .zip(&small)
        .all(|(a, b)| case.bed_of(a.1) == case.bed_of(b.1));
    let times = big[0].2.len();
    let ends = 1 + usize::from(max_ratio.is_some());
    let m = times * ends;
    let mut parts = Vec::with_capacity(m);
    let mut listing = Vec::with_capacity(times);
    for j in 0..times {
        let t = big[0].2[j].0;
        let la: Vec<f64> = big.iter().map(|s| s.2[j].1.ln()).collect();
        let lb: Vec<f64> = small.iter().map(|s| s.2[j].1.ln()).collect();
        let est = if paired {
            Estimate::paired(&la, &lb)
        } else {
            Estimate::welch(&la, &lb)
        };
        let at = t.map_or(String::new(), |t| format!(" at t = {t} tau_c"));
        let ratio = format!("ln({larger} / {smaller}){at}");
        parts.extend(ratio_comparisons(ratio, est, *min_ratio, *max_ratio, m));
        let per_seed = big
            .iter()
            .zip(&small)
            .map(|(a, b)| format!("seed {}: {:.4}", a.0, a.2[j].1 / b.2[j].1))
            .collect::<Vec<_>>()
            .join(", ");
        listing.push(format!("ratios{at}: {per_seed}"));
    }
    Check::decided(
        name,
        Gate::Claim,
        format!(
            "ln({larger} / {smaller}), must exceed ln {min_ratio}{}",
            max_ratio.map_or(String::new(), |h| format!(" and stay below ln {h}"))
        ),
        &parts,
        format!(
            "{} over {n} seeds ({}); {}",
            if paired { "paired" } else { "Welch" },
            if paired {
                "both variants of every seed on the same bed"
            } else {
                "each variant on its own beds"
            },
            listing.join("; ")
        ),
    )
}

fn claim_check(case: &Impact2dCase, claim: &Claim, engine: &str, obs: &[VariantObs]) -> Check {
    let param = case.sweep_parameter.clone().unwrap_or_default();
    let listing = |f: &dyn Fn(&VariantObs) -> f64| {
        obs.iter()
            .map(|o| format!("{}: {:.3}", o.label, f(o)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    match claim {
        Claim::FieldOrder { .. } => Check::error_in(
            format!("{}: claim ({engine})", case.name),
            Gate::Claim,
            "field_order is evaluated per time (field_order_checks)",
        ),
        Claim::VelocityExponentPerDepth { .. } => Check::error_in(
            format!("{}: claim ({engine})", case.name),
            Gate::Claim,
            "velocity_exponent_per_depth is judged over the beds of a seed ensemble (refused on one bed when the case loads)",
        ),
        Claim::ForceImpulsive {
            bin,
            peak_within,
            half_within,
        } => {
            let name = format!(
                "{}: claim ({engine}): force on the intruder peaks within {peak_within} tau_c of contact and halves within {half_within} tau_c",
                case.name
            );
            match force_summaries(obs, *bin, *bin) {
                Ok(f) => {
                    // <= 0 iff both hold in every variant.
                    let excess = |s: &ForceSummary| {
                        let a = s.t_peak - s.t_contact - peak_within;
                        let b = s.half_after.map_or(f64::INFINITY, |h| h - half_within);
                        a.max(b)
                    };
                    let worst = f.iter().map(excess).fold(f64::NEG_INFINITY, f64::max);
                    Check::at_most(
                        name,
                        Gate::Claim,
                        "max over variants of (t_peak - t_c - peak_within, t_half - half_within) / tau_c",
                        worst,
                        0.0,
                        obs.iter()
                            .zip(&f)
                            .map(|(o, s)| {
                                format!(
                                    "{}: contact {:.2}, peak {:.0} m g at +{:.1}, half after {}",
                                    o.label,
                                    s.t_contact,
                                    s.peak,
                                    s.t_peak - s.t_contact,
                                    s.half_after
                                        .map_or("never".to_string(), |h| format!("{h:.1}"))
                                )
                            })
                            .collect::<Vec<_>>()
                            .join("; ")
                            + " (tau_c)",
                    )
                }
                Err(e) => Check::error_in(name, Gate::Claim, e),
            }
        }
        Claim::ForceSimilar {
            window,
            max_spread_ratio,
            min_depth_spread,
        } => {
            let name = format!(
                "{}: claim ({engine}): force on the intruder similar across {param} while the depths differ",
                case.name
            );
            match force_summaries(obs, force_bin(case), *window) {
                Ok(f) => {
                    let peaks: Vec<f64> = f.iter().map(|s| s.peak).collect();
                    let imp: Vec<f64> = f.iter().map(|s| s.impulse).collect();
                    let depths: Vec<f64> = obs.iter().map(|o| o.final_depth).collect();
                    let span = depths.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                        - depths.iter().copied().fold(f64::INFINITY, f64::min);
                    let (sp, sj, sd) = (spread(&peaks), spread(&imp), spread(&depths));
                    let ratio = sp.max(sj) / sd;
                    let detail = format!(
                        "relative spreads: peak {sp:.3}, impulse over {window} tau_c {sj:.3}, final depth {sd:.3} (span {span:.2} d, registered >= {min_depth_spread}); per variant (peak m g, impulse m g tau_c, depth d): {}",
                        obs.iter()
                            .zip(&f)
                            .map(|(o, s)| format!(
                                "{}: {:.0}, {:.0}, {:.2}",
                                o.label, s.peak, s.impulse, o.final_depth
                            ))
                            .collect::<Vec<_>>()
                            .join("; ")
                    );
                    if span < *min_depth_spread {
                        Check::failed(
                            name,
                            Gate::Claim,
                            "max(spread of peak, of impulse) / spread of final depth",
                            ratio,
                            format!(
                                "the premise fails: the final depths do not differ by {min_depth_spread} d; {detail}"
                            ),
                        )
                    } else {
                        Check::at_most(
                            name,
                            Gate::Claim,
                            "max(spread of peak, of impulse) / spread of final depth",
                            ratio,
                            *max_spread_ratio,
                            detail,
                        )
                    }
                }
                Err(e) => Check::error_in(name, Gate::Claim, e),
            }
        }
        Claim::SizeInsensitive { max_spread } => size_insensitive(case, *max_spread, engine, obs),
        Claim::InterfaceSteadies {
            max_ratio,
            min_amplitude,
        } => {
            let v: Vec<_> = obs
                .iter()
                .map(|o| (o.label.as_str(), o.interface.as_ref()))
                .collect();
            super::interface::steadies(case, *max_ratio, *min_amplitude, engine, &v)
        }
        Claim::Trend { .. } => Check::error_in(
            format!("{}: claim ({engine})", case.name),
            crate::compare::Gate::Claim,
            "a trend is judged over beds (refused on one bed when the case loads)",
        ),
        Claim::Increasing { min_step, of, at } => {
            let (what, unit) = of.describe();
            if obs.len() < 2 {
                return Check::not_compared(
                    format!("{}: claim ({engine}): {what}", case.name),
                    crate::compare::Gate::Claim,
                    "a trend needs at least 2 variants",
                );
            }
            let value = |o: &VariantObs| match of {
                ClaimQuantity::FinalDepth => o.final_depth,
                ClaimQuantity::TimeOfMaxDepth => o.t_max_depth,
                ClaimQuantity::EnergyLost => energy_lost(o, at.unwrap_or(f64::NAN)),
            };
            if let Some(o) = obs.iter().find(|o| !value(o).is_finite()) {
                return Check::error_in(
                    format!("{}: claim ({engine}): {what}", case.name),
                    crate::compare::Gate::Claim,
                    format!(
                        "variant {}: no {what} (no energy sample at or after the time read)",
                        o.label
                    ),
                );
            }
            // Largest y_k + min_step - y_{k+1}: <= 0 iff every step rises by min_step.
            let worst = obs
                .windows(2)
                .map(|w| value(&w[0]) + min_step - value(&w[1]))
                .fold(f64::NEG_INFINITY, f64::max);
            Check::at_most(
                format!(
                    "{}: claim ({engine}): {what} increases along {param}",
                    case.name
                ),
                crate::compare::Gate::Claim,
                format!("max_k (y_k + min_step - y_k+1) / {unit}"),
                worst,
                0.0,
                format!(
                    "min_step {min_step} {unit}; {what} ({unit}): {}",
                    listing(&value)
                ),
            )
            .fail_if(
                obs.windows(2).any(|w| value(&w[1]) <= value(&w[0])),
                FLAT_STEP,
            )
        }
        Claim::EnergyNonIncreasing { max_rise } => {
            // Largest rise of E between consecutive samples, over the impact energy.
            let rise = |o: &VariantObs| {
                o.energy
                    .windows(2)
                    .map(|w| (w[1].1 - w[0].1) / o.impact_energy)
                    .fold(f64::NEG_INFINITY, f64::max)
            };
            let worst = obs.iter().map(rise).fold(f64::NEG_INFINITY, f64::max);
            let per: Vec<String> = obs
                .iter()
                .map(|o| format!("{}: {:.2e}", o.label, rise(o)))
                .collect();
            if obs.iter().any(|o| o.energy.len() < 2) {
                return Check::error_in(
                    format!("{}: claim ({engine}): total energy never rises", case.name),
                    crate::compare::Gate::Claim,
                    "a variant has fewer than 2 energy samples",
                );
            }
            Check::at_most(
                format!("{}: claim ({engine}): total energy never rises", case.name),
                crate::compare::Gate::Claim,
                "max over samples of (E_k+1 - E_k) / (M v^2 / 2)",
                worst,
                *max_rise,
                format!(
                    "largest rise per variant: {}; M v^2 / 2 = {:.4e} m g d",
                    per.join(", "),
                    obs.first().map_or(f64::NAN, |o| o.impact_energy)
                ),
            )
        }
        Claim::VelocityExponent {
            depths,
            half_width,
            min,
            max,
            ..
        } => {
            let name = format!(
                "{}: claim ({engine}): deceleration ~ u^k at depths {depths:?} +- {half_width} d",
                case.name
            );
            match velocity_exponent(obs, depths, *half_width) {
                Ok((k, detail)) if (*min..=*max).contains(&k) => Check::at_least(
                    name,
                    crate::compare::Gate::Claim,
                    format!("k, must lie in [{min}, {max}]"),
                    k,
                    *min,
                    detail,
                ),
                Ok((k, detail)) => Check::failed(
                    name,
                    crate::compare::Gate::Claim,
                    format!("k, must lie in [{min}, {max}]"),
                    k,
                    detail,
                ),
                Err(e) => Check::not_compared(name, crate::compare::Gate::Claim, e),
            }
        }
        Claim::Linear { from, r2_min } => {
            let pts: Vec<&VariantObs> = obs.iter().filter(|o| o.x >= *from).collect();
            if pts.len() < 3 {
                return Check::not_compared(
                    format!("{}: claim ({engine})", case.name),
                    crate::compare::Gate::Claim,
                    format!(
                        "a line through {} point(s) tests nothing: at least 3 variants with {param} >= {from} are needed",
                        pts.len()
                    ),
                );
            }
            let x: Vec<f64> = pts.iter().map(|o| o.x).collect();
            let y: Vec<f64> = pts.iter().map(|o| o.final_depth).collect();
            match crate::analysis::impact::linear_r2(&x, &y) {
                Ok((a, b, r2)) => Check::at_most(
                    format!(
                        "{}: claim ({engine}): final depth linear in {param} for {param} >= {from}",
                        case.name
                    ),
                    crate::compare::Gate::Claim,
                    "1 - R^2 of the least-squares line",
                    // A falling line is no support for "grows linearly".
                    if b > 0.0 { 1.0 - r2 } else { f64::INFINITY },
                    1.0 - r2_min,
                    format!(
                        "D = {a:.3} + {b:.3} x (R^2 {r2:.4}; the slope must be > 0); final depths (d): {}",
                        listing(&|o| o.final_depth)
                    ),
                ),
                Err(e) => {
                    Check::error(format!("{}: claim ({engine})", case.name), format!("{e:#}"))
                }
            }
        }
    }
}

/// The quantity an ensemble claim follows, in one run (NaN where the run has none).
fn claim_value(claim: &Claim, o: &VariantObs) -> f64 {
    match claim {
        Claim::Increasing { of, at, .. } | Claim::Trend { of, at, .. } => match of {
            ClaimQuantity::FinalDepth => o.final_depth,
            ClaimQuantity::TimeOfMaxDepth => o.t_max_depth,
            ClaimQuantity::EnergyLost => energy_lost(o, at.unwrap_or(f64::NAN)),
        },
        _ => o.final_depth,
    }
}

/// Per sweep value of a seed ensemble, `value` of each seed's run, its mean and SE, in
/// sweep order. Runs are matched to the case's variants by label, so a missing or
/// quantity-less run is an error, not a smaller ensemble.
pub(crate) fn ensemble_stats(
    case: &Impact2dCase,
    obs: &[VariantObs],
    value: &dyn Fn(&VariantObs) -> f64,
) -> Result<Vec<ValueStats>, String> {
    case.ensemble_groups()
        .into_iter()
        .map(|g| {
            let seeds = g
                .members
                .iter()
                .map(|&k| {
                    let v = &case.variants[k];
                    let o = obs
                        .iter()
                        .find(|o| o.label == v.label)
                        .ok_or_else(|| format!("run {} has no result", v.label))?;
                    let y = value(o);
                    if !y.is_finite() {
                        return Err(format!("run {}: no value ({y})", v.label));
                    }
                    Ok((case.bed_of(v).seed, y))
                })
                .collect::<Result<Vec<_>, String>>()?;
            Ok(ValueStats::new(g.value, g.x, seeds))
        })
        .collect()
}

/// Per seed, the least-squares slope of its values against `x` (one x per entry of
/// `values`, the same seeds at every value: the bed-to-bed offset drops out), for every
/// seed present at every value; a seed missing somewhere is left out, and the callers
/// decide nothing unless every seed gave a slope.
fn per_seed_slopes(values: &[&ValueStats], seeds: &[u64], x: &[f64]) -> Vec<f64> {
    seeds
        .iter()
        .filter_map(|seed| {
            let ys: Option<Vec<f64>> = values
                .iter()
                .map(|v| v.seeds.iter().find(|s| s.0 == *seed).map(|s| s.1))
                .collect();
            Estimate::slope(x, &ys?).map(|e| e.value)
        })
        .collect()
}

/// A claim on a seed ensemble in one engine (docs/impact2d.md, "Seed ensembles";
/// docs/statistics.md): `increasing` tests the per-seed rise of every step against
/// min_step; `trend` the mean per-seed slope against min_slope; `linear` the per-seed
/// slope, with straightness undecided until a curvature margin is registered. Other
/// kinds are refused when the case loads.
fn ensemble_claim_check(
    case: &Impact2dCase,
    claim: &Claim,
    engine: &str,
    obs: &[VariantObs],
) -> Check {
    let param = case.sweep_parameter.clone().unwrap_or_default();
    let n = case.seeds.len();
    let stats = ensemble_stats(case, obs, &|o| claim_value(claim, o));
    match claim {
        Claim::Increasing { min_step, of, .. } => {
            let (what, unit) = of.describe();
            let name = format!(
                "{}: claim ({engine}): {what} increases along {param} (mean of {n} seeds)",
                case.name
            );
            let stats = match stats {
                Ok(s) => s,
                Err(e) => return Check::error_in(name, Gate::Claim, e),
            };
            Check::decided(
                name,
                Gate::Claim,
                format!("per-seed rise of {what} at every step ({unit}), must exceed min_step"),
                &ensemble::increasing(&stats, *min_step),
                format!(
                    "min_step {min_step} {unit}; {what} ({unit}), mean +- SE over seeds: {}",
                    stats
                        .iter()
                        .map(|s| s.describe())
                        .collect::<Vec<_>>()
                        .join("; ")
                ),
            )
        }
        Claim::Trend {
            direction,
            min_slope,
            of,
            log_x,
            ..
        } => {
            let (what, unit) = of.describe();
            let sign = direction.sign();
            let verb = match direction {
                TrendDirection::Rises => "rises",
                TrendDirection::Falls => "falls",
            };
            let xname = if *log_x {
                format!("ln {param}")
            } else {
                param.clone()
            };
            let name = format!(
                "{}: claim ({engine}): {what} {verb} with {param} (trend over {n} seeds)",
                case.name
            );
            let stats = match stats {
                Ok(s) => s,
                Err(e) => return Check::error_in(name, Gate::Claim, e),
            };
            let x: Vec<f64> = stats
                .iter()
                .map(|s| if *log_x { s.x.ln() } else { s.x })
                .collect();
            // Per seed, the least-squares slope over every value (the same seeds at
            // every value: the bed-to-bed offset drops out), signed so that the claimed
            // direction is positive; the claim's slope is the mean over the seeds.
            let slopes: Vec<f64> =
                per_seed_slopes(&stats.iter().collect::<Vec<_>>(), &case.seeds, &x)
                    .into_iter()
                    .map(|b| sign * b)
                    .collect();
            let per_seed = case
                .seeds
                .iter()
                .zip(&slopes)
                .map(|(s, b)| format!("seed {s}: {b:.4}"))
                .collect::<Vec<_>>()
                .join(", ");
            Check::decided(
                name,
                Gate::Claim,
                format!(
                    "per-seed slope of {what} against {xname} ({unit} per unit{}), must exceed min_slope",
                    if sign > 0.0 {
                        ""
                    } else {
                        "; a fall counts positive"
                    }
                ),
                &[super::Comparison {
                    what: format!("per-seed slope ({verb}) against {xname}"),
                    estimate: if slopes.len() == case.seeds.len() {
                        Estimate::mean(&slopes)
                    } else {
                        None
                    },
                    rule: super::Rule::Exceeds { delta: *min_slope },
                    m: 1,
                }],
                format!(
                    "min_slope {min_slope} {unit} per unit of {xname}; per-seed slopes ({verb}): {per_seed}; {what} ({unit}), mean +- SE over seeds: {}",
                    stats
                        .iter()
                        .map(|s| s.describe())
                        .collect::<Vec<_>>()
                        .join("; ")
                ),
            )
        }
        Claim::Linear { from, r2_min } => {
            let name = format!(
                "{}: claim ({engine}): mean final depth of {n} seeds linear in {param} for {param} >= {from}",
                case.name
            );
            let stats = match stats {
                Ok(s) => s,
                Err(e) => return Check::error_in(name, Gate::Claim, e),
            };
            let fit: Vec<&ValueStats> = stats.iter().filter(|s| s.x >= *from).collect();
            if fit.len() < 3 {
                return Check::not_compared(
                    name,
                    Gate::Claim,
                    format!(
                        "a line through {} value(s) tests nothing: at least 3 values with {param} >= {from} are needed",
                        fit.len()
                    ),
                );
            }
            let x: Vec<f64> = fit.iter().map(|s| s.x).collect();
            let y: Vec<f64> = fit.iter().map(|s| s.mean).collect();
            // Per seed, the least-squares slope over the values >= from; the claim's
            // slope is the mean of those (the seeds are the beds).
            let seeds: Vec<u64> = fit[0].seeds.iter().map(|s| s.0).collect();
            let slopes = per_seed_slopes(&fit, &seeds, &x);
            let means_line = crate::analysis::impact::linear_r2(&x, &y)
                .map(|(a, b, r2)| format!("mean D = {a:.3} + {b:.3} x, R^2 {r2:.4} (reported, never gated: docs/statistics.md)"))
                .unwrap_or_else(|e| format!("no line through the means: {e:#}"));
            Check::decided(
                name,
                Gate::Claim,
                "per-seed slope of the final depth (d per unit), must exceed 0; linearity needs a registered curvature margin",
                &[
                    super::Comparison {
                        what: format!("per-seed slope over {param} >= {from}"),
                        estimate: if slopes.len() == seeds.len() {
                            Estimate::mean(&slopes)
                        } else {
                            None
                        },
                        rule: super::Rule::Exceeds { delta: 0.0 },
                        m: 1,
                    },
                    // The straightness half of the claim: docs/statistics.md judges it by
                    // the curvature against a registered margin; this claim registered
                    // none (its r2_min on the means is no such margin), so it cannot be
                    // decided.
                    super::Comparison {
                        what: format!(
                            "curvature over {param} >= {from}: no registered curvature margin (r2_min = {r2_min} on the means is reported only)"
                        ),
                        estimate: None,
                        rule: super::Rule::Equivalence { margin: f64::NAN },
                        m: 1,
                    },
                ],
                format!(
                    "{means_line}; final depth (d), mean +- SE over seeds: {}",
                    stats
                        .iter()
                        .map(|s| s.describe())
                        .collect::<Vec<_>>()
                        .join("; ")
                ),
            )
        }
        _ => Check::error_in(
            format!("{}: claim ({engine})", case.name),
            Gate::Claim,
            "not defined on a seed ensemble (refused when the case loads)",
        ),
    }
}

/// K Fig 11's two spreads over final depths grouped by size (each inner vector one
/// size's realizations): (max - min over sizes of the size's mean, mean over sizes of
/// the size's max - min). NaN when a size has no realization.
pub(crate) fn size_spreads(groups: &[Vec<f64>]) -> (f64, f64) {
    let span = |v: &[f64]| {
        v.iter().copied().fold(f64::NEG_INFINITY, f64::max)
            - v.iter().copied().fold(f64::INFINITY, f64::min)
    };
    let means: Vec<f64> = groups
        .iter()
        .map(|g| g.iter().sum::<f64>() / g.len() as f64)
        .collect();
    let within = groups.iter().map(|g| span(g)).sum::<f64>() / groups.len() as f64;
    (span(&means), within)
}

/// The `size_insensitive` claim (K Fig 11) in one engine: between-size spread <
/// `max_spread` and < between-realization spread (rule in [`Claim::SizeInsensitive`]).
/// Variants are matched to the case's by label, so a missing run is an error, not a
/// smaller group.
fn size_insensitive(
    case: &Impact2dCase,
    max_spread: f64,
    engine: &str,
    obs: &[VariantObs],
) -> Check {
    let name = format!(
        "{}: claim ({engine}): final depth equivalent between sizes within {max_spread} d",
        case.name
    );
    let d = case.scales.d;
    let mut groups: Vec<Vec<f64>> = Vec::new();
    let mut per_size: Vec<String> = Vec::new();
    for ((n, l), idx) in case.size_groups() {
        let mut depths = Vec::new();
        let mut listed = Vec::new();
        for k in idx {
            let v = &case.variants[k];
            let Some(o) = obs.iter().find(|o| o.label == v.label) else {
                return Check::error_in(
                    name,
                    Gate::Claim,
                    format!("variant {} has no result", v.label),
                );
            };
            if !o.final_depth.is_finite() {
                return Check::error_in(
                    name,
                    Gate::Claim,
                    format!("variant {}: final depth {}", v.label, o.final_depth),
                );
            }
            depths.push(o.final_depth);
            listed.push(format!(
                "seed {}: {:.3}",
                case.bed_of(v).seed,
                o.final_depth
            ));
        }
        let mean = depths.iter().sum::<f64>() / depths.len() as f64;
        per_size.push(format!(
            "count {n}, L {} d: {} (mean {mean:.3})",
            l / d,
            listed.join(", ")
        ));
        groups.push(depths);
    }
    if groups.len() < 2 || groups.iter().any(|g| g.len() < 2) {
        return Check::error_in(
            name,
            Gate::Claim,
            "needs at least 2 sizes with at least 2 realizations each",
        );
    }
    let (between, within) = size_spreads(&groups);
    let m = groups.len() * (groups.len() - 1) / 2;
    let mut parts = Vec::with_capacity(m);
    for a in 0..groups.len() {
        for b in a + 1..groups.len() {
            parts.push(super::Comparison {
                what: format!("size {} - size {} (d, Welch over the seeds)", b + 1, a + 1),
                estimate: crate::numerics::stats::Estimate::welch(&groups[b], &groups[a]),
                rule: super::Rule::Equivalence { margin: max_spread },
                m,
            });
        }
    }
    Check::decided(
        name,
        Gate::Claim,
        "difference of two sizes' mean final depths (d)",
        &parts,
        format!(
            "between sizes {between:.3} d (max - min of the size means), between realizations {within:.3} d (mean over sizes of max - min; reported), registered max_spread {max_spread} d; final depths (d): {}",
            per_size.join("; ")
        ),
    )
}

/// k of a ~ u^k (K Fig 29) over the passages of every variant through the bins, with
/// the fit's description; an error when fewer than 4 passages with a > 0 from at least 3
/// variants remain (a power through fewer tests nothing).
pub(crate) fn velocity_exponent(
    obs: &[VariantObs],
    depths: &[f64],
    half_width: f64,
) -> Result<(f64, String), String> {
    use crate::analysis::impact::{passages, power_law};
    let mut all = Vec::new();
    let mut variants = 0;
    let mut dropped = 0;
    for o in obs {
        let p = passages(&o.trajectory, depths, half_width);
        let positive = p.iter().filter(|q| q.decel > 0.0).count();
        dropped += p.len() - positive;
        if positive > 0 {
            variants += 1;
        }
        all.extend(p);
    }
    let used = all.iter().filter(|q| q.decel > 0.0).count();
    if used < 4 || variants < 3 {
        return Err(format!(
            "{used} passage(s) with a > 0 from {variants} variant(s): a power law needs at least 4 from 3 variants"
        ));
    }
    let (k, c, r2, n) = power_law(&all).map_err(|e| format!("{e:#}"))?;
    let pts = all
        .iter()
        .map(|q| format!("(y {:.1}: u {:.3}, a {:.4})", q.y, q.u, q.decel))
        .collect::<Vec<_>>()
        .join(" ");
    Ok((
        k,
        format!(
            "a = {c:.4} u^{k:.3} (R^2 {r2:.3}) over {n} passages ({dropped} with a <= 0 left out); d, tau_c units: {pts}"
        ),
    ))
}

/// Native vs reference k of every velocity-exponent claim of the case.
pub(crate) fn exponent_cross_checks(
    case: &Impact2dCase,
    native: &[VariantObs],
    reference: &[VariantObs],
    engine: &str,
) -> Vec<Check> {
    let per_depth = case.claims.iter().flat_map(|c| match c {
        Claim::VelocityExponentPerDepth {
            depths,
            half_width,
            min_passages,
            engine_tol,
            ..
        } => per_depth_cross_checks(
            case,
            native,
            reference,
            engine,
            (depths.as_slice(), *half_width, *min_passages, *engine_tol),
        ),
        _ => Vec::new(),
    });
    case.claims
        .iter()
        .filter_map(|c| match c {
            Claim::VelocityExponent {
                depths,
                half_width,
                engine_tol,
                ..
            } => Some((depths, *half_width, *engine_tol)),
            _ => None,
        })
        .map(|(depths, half, tol)| {
            let name = format!("{}: velocity exponent k native vs {engine}", case.name);
            match (
                velocity_exponent(native, depths, half),
                velocity_exponent(reference, depths, half),
            ) {
                (Ok((a, da)), Ok((b, db))) => Check::at_most(
                    name,
                    crate::compare::Gate::Claim,
                    "|k_native - k_ref|",
                    (a - b).abs(),
                    tol,
                    format!("native {da}; {engine} {db}"),
                ),
                (a, b) => Check::not_compared(
                    name,
                    crate::compare::Gate::Claim,
                    format!("native: {:?}; {engine}: {:?}", a.err(), b.err()),
                ),
            }
        })
        .chain(per_depth)
        .collect()
}

/// One bed's seed and its exponent at one depth (or why it has none).
type BedExponent = (u64, Result<DepthExponent, String>);

/// Per bed (seed, in `case.seeds` order), the exponent at depth `y` of the bed's runs
/// (docs/impact2d.md, "Fig 29 per depth"). Runs are matched to the case's variants by
/// label, so a missing run is an error, not a smaller ensemble.
fn exponents_per_bed(
    case: &Impact2dCase,
    obs: &[VariantObs],
    y: f64,
    half: f64,
    min_passages: usize,
) -> Result<Vec<BedExponent>, String> {
    case.seeds
        .iter()
        .map(|&seed| {
            let runs = case
                .variants
                .iter()
                .filter(|v| case.bed_of(v).seed == seed)
                .map(|v| {
                    obs.iter()
                        .find(|o| o.label == v.label)
                        .map(|o| o.trajectory.as_slice())
                        .ok_or_else(|| format!("run {} has no result", v.label))
                })
                .collect::<Result<Vec<_>, String>>()?;
            Ok((seed, exponent_at_depth(&runs, y, half, min_passages)))
        })
        .collect()
}

fn describe_bed(seed: u64, r: &Result<DepthExponent, String>) -> String {
    match r {
        Ok(e) => format!(
            "seed {seed}: k {:.3} (within-bed slope SE {:.3}, printed only; {} passages, {} with a <= 0 left out: {})",
            e.k,
            e.se_within,
            e.used.len(),
            e.dropped,
            e.used
                .iter()
                .map(|q| format!("(u {:.3}, a {:.4})", q.u, q.decel))
                .collect::<Vec<_>>()
                .join(" ")
        ),
        Err(e) => format!("seed {seed}: no k ({e})"),
    }
}

/// A `velocity_exponent_per_depth` claim in one engine: one statistical check per depth
/// (docs/impact2d.md, "Fig 29 per depth"). The estimate is the mean over the beds of
/// k - (min + max) / 2, judged as an equivalence within (max - min) / 2: PASS when the
/// 90 % interval lies inside, FAIL when the Bonferroni interval over the depths lies
/// wholly outside, otherwise INCONCLUSIVE; fewer than `min_seeds` beds with a k: NOT
/// COMPARED.
fn per_depth_exponent_checks(
    case: &Impact2dCase,
    claim: &Claim,
    engine: &str,
    obs: &[VariantObs],
) -> Vec<Check> {
    let Claim::VelocityExponentPerDepth {
        depths,
        half_width,
        min,
        max,
        min_passages,
        min_seeds,
        ..
    } = claim
    else {
        return Vec::new();
    };
    let centre = 0.5 * (min + max);
    let margin = 0.5 * (max - min);
    depths
        .iter()
        .map(|&y| {
            let name = format!(
                "{}: claim ({engine}): deceleration ~ u^k at depth {y} +- {half_width} d, k in [{min}, {max}] (over beds)",
                case.name
            );
            let beds = match exponents_per_bed(case, obs, y, *half_width, *min_passages) {
                Ok(b) => b,
                Err(e) => return Check::error_in(name, Gate::Claim, e),
            };
            let listed = beds
                .iter()
                .map(|(s, r)| describe_bed(*s, r))
                .collect::<Vec<_>>()
                .join("; ");
            let ks: Vec<f64> = beds
                .iter()
                .filter_map(|(_, r)| r.as_ref().ok().map(|e| e.k))
                .collect();
            if ks.len() < *min_seeds {
                return Check::not_compared(
                    name,
                    Gate::Claim,
                    format!(
                        "{} bed(s) give a k at {y} d, at least min_seeds = {min_seeds} are needed; {listed}",
                        ks.len()
                    ),
                );
            }
            let shifted: Vec<f64> = ks.iter().map(|k| k - centre).collect();
            let estimate = Estimate::mean(&shifted);
            let summary = estimate.map_or_else(String::new, |e| {
                let (l, u) = e.decision_interval();
                let (fl, fu) = e.failure_interval(depths.len());
                format!(
                    "mean k {:.3} over {} beds, 90 % interval [{:.3}, {:.3}], Bonferroni ({} depths) [{:.3}, {:.3}]; ",
                    e.value + centre,
                    e.n,
                    l + centre,
                    u + centre,
                    depths.len(),
                    fl + centre,
                    fu + centre
                )
            });
            Check::decided(
                name,
                Gate::Claim,
                format!(
                    "mean k over beds - {}, must lie within +-{}",
                    crate::numerics::fmt::number(centre),
                    crate::numerics::fmt::number(margin)
                ),
                &[super::Comparison {
                    what: format!("mean k - {centre} at {y} d"),
                    estimate,
                    rule: super::Rule::Equivalence { margin },
                    m: depths.len(),
                }],
                format!("{summary}{listed}"),
            )
        })
        .collect()
}

/// Native vs reference k per bed and depth of a `velocity_exponent_per_depth` claim
/// (kind 1 of docs/statistics.md): one check per depth, its value the largest
/// |k_native - k_ref| over the beds; a bed that gives a k in one engine only fails it.
fn per_depth_cross_checks(
    case: &Impact2dCase,
    native: &[VariantObs],
    reference: &[VariantObs],
    engine: &str,
    (depths, half, min_passages, tol): (&[f64], f64, usize, f64),
) -> Vec<Check> {
    depths
        .iter()
        .map(|&y| {
            let name = format!(
                "{}: velocity exponent k at depth {y} d native vs {engine} (per bed)",
                case.name
            );
            let (a, b) = match (
                exponents_per_bed(case, native, y, half, min_passages),
                exponents_per_bed(case, reference, y, half, min_passages),
            ) {
                (Ok(a), Ok(b)) => (a, b),
                (a, b) => {
                    return Check::error_in(
                        name,
                        Gate::Claim,
                        format!("native: {:?}; {engine}: {:?}", a.err(), b.err()),
                    );
                }
            };
            let mut worst = f64::NAN;
            let mut one_sided = Vec::new();
            let mut listed = Vec::new();
            for ((seed, ra), (_, rb)) in a.iter().zip(&b) {
                match (ra, rb) {
                    (Ok(x), Ok(z)) => {
                        let d = (x.k - z.k).abs();
                        worst = if worst.is_nan() { d } else { worst.max(d) };
                        listed.push(format!("seed {seed}: {:.3} vs {:.3}", x.k, z.k));
                    }
                    (Err(_), Err(_)) => listed.push(format!("seed {seed}: no k in either")),
                    (x, z) => {
                        one_sided.push(*seed);
                        listed.push(format!(
                            "seed {seed}: native {}, {engine} {}",
                            x.as_ref()
                                .map_or_else(|e| e.clone(), |e| format!("{:.3}", e.k)),
                            z.as_ref()
                                .map_or_else(|e| e.clone(), |e| format!("{:.3}", e.k))
                        ));
                    }
                }
            }
            let detail = listed.join("; ");
            let metric = "max over beds |k_native - k_ref|";
            if !one_sided.is_empty() {
                Check::failed(
                    name,
                    Gate::Claim,
                    metric,
                    worst,
                    format!("a k in one engine only on seed(s) {one_sided:?}; {detail}"),
                )
            } else if worst.is_nan() {
                Check::not_compared(name, Gate::Claim, format!("no bed gives a k; {detail}"))
            } else {
                Check::at_most(name, Gate::Claim, metric, worst, tol, detail)
            }
        })
        .collect()
}

/// E(0) - E(t) at the first energy sample at or after `t` (tau_c); NaN if none.
fn energy_lost(o: &VariantObs, t: f64) -> f64 {
    let Some(first) = o.energy.first() else {
        return f64::NAN;
    };
    o.energy
        .iter()
        .find(|(s, _)| *s >= t)
        .map_or(f64::NAN, |(_, e)| first.1 - e)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare::Status;
    use std::path::Path;

    fn case(claim: &str, sweep: &str) -> Impact2dCase {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/cases/impact2d/ci.toml"
        ))
        .unwrap();
        Impact2dCase::from_toml_str(&format!("{text}\n{sweep}\n{claim}\n"), Path::new("t.toml"))
            .unwrap()
    }

    fn obs(xs: &[f64], ds: &[f64]) -> Vec<VariantObs> {
        xs.iter()
            .zip(ds)
            .map(|(&x, &d)| VariantObs {
                label: format!("{x}"),
                x,
                final_depth: d,
                max_depth: d,
                t_max_depth: d,
                energy: vec![],
                impact_energy: 1.0,
                final_speed: 0.0,
                final_samples: 100,
                trajectory: Vec::new(),
                force: Vec::new(),
                fields: None,
                interface: None,
            })
            .collect()
    }

    /// The velocity exponent claim reads k off the passages of every variant: in range
    /// it passes, out of range it fails, and native vs reference compares the two k.
    #[test]
    fn velocity_exponent_claim_fits_the_force_law() {
        let c = case(
            "[claim]\nkind = \"velocity_exponent\"\ndepths = [1.0, 2.0, 3.0]\nhalf_width = 0.5\nmin = 0.7\nmax = 1.3\nengine_tol = 0.2",
            "[sweep]\nparameter = \"speed\"\nvalues = [0.2, 0.4, 0.7, 1.0]",
        );
        let speeds = [0.2, 0.4, 0.7, 1.0];
        let with = |k: f64| {
            let mut o = obs(&speeds, &[1.0; 4]);
            for (x, v) in o.iter_mut().zip(speeds) {
                x.trajectory = crate::analysis::impact::power_law_trajectory(v, 0.02, k, 0.01);
            }
            o
        };
        let k = one(&c, &with(1.0)).unwrap();
        assert!(k.passed && (k.value - 1.0).abs() < 0.05, "{k:?}");
        assert!(!one(&c, &with(1.8)).unwrap().passed);
        let x = exponent_cross_checks(&c, &with(1.0), &with(1.1), "lammps");
        assert!(x.len() == 1 && x[0].passed, "{x:?}");
        let x = exponent_cross_checks(&c, &with(1.0), &with(1.5), "lammps");
        assert!(!x[0].passed, "{x:?}");
        // Two variants cannot pin a power law down.
        let few = with(1.0)[..2].to_vec();
        let k = one(&c, &few).unwrap();
        assert_eq!(k.status, crate::compare::Status::NotCompared, "{k:?}");
    }

    /// K Fig 29 per depth on four synthetic beds (docs/impact2d.md, "Fig 29 per depth"):
    /// every bed slowed as a = c u^k with its own c. k = 1 on every bed passes at each
    /// depth; k = 1.8 (the negative control: a force law outside the band) fails at each
    /// depth; beds scattered between 0.7 and 1.3 around a mean of 1 are INCONCLUSIVE
    /// (four beds cannot resolve the band); two speeds are NOT COMPARED; native vs
    /// reference compares k bed by bed.
    #[test]
    fn velocity_exponent_per_depth_is_judged_over_beds() {
        let c = ensemble(
            "[claim]\nkind = \"velocity_exponent_per_depth\"\ndepths = [1.0, 2.0, 3.0]\nhalf_width = 0.5\nmin = 0.7\nmax = 1.3\nmin_passages = 4\nmin_seeds = 3\nengine_tol = 0.2",
            "[sweep]\nparameter = \"speed\"\nvalues = [0.3, 0.5, 0.7, 1.0]",
            "[1, 2, 3, 4]",
        );
        let with = |k: &dyn Fn(usize) -> f64| {
            let mut out = Vec::new();
            for g in c.ensemble_groups() {
                for (j, &m) in g.members.iter().enumerate() {
                    let v = &c.variants[m];
                    let mut o = obs(&[v.x], &[5.0]).remove(0);
                    o.label = v.label.clone();
                    o.trajectory = crate::analysis::impact::power_law_trajectory(
                        v.x,
                        0.02 * (1.0 + 0.05 * j as f64),
                        k(j),
                        0.01,
                    );
                    out.push(o);
                }
            }
            out
        };
        let status = |o: &[VariantObs]| {
            claim_checks(&c, "x", o)
                .iter()
                .map(|k| k.status)
                .collect::<Vec<_>>()
        };
        let right = with(&|_| 1.0);
        assert_eq!(
            status(&right),
            vec![Status::Pass; 3],
            "{:?}",
            claim_checks(&c, "x", &right)
        );
        let wrong = with(&|_| 1.8);
        assert_eq!(
            status(&wrong),
            vec![Status::Fail; 3],
            "{:?}",
            claim_checks(&c, "x", &wrong)
        );
        let scattered = with(&|j| if j % 2 == 0 { 0.7 } else { 1.3 });
        assert_eq!(
            status(&scattered),
            vec![Status::Inconclusive; 3],
            "{:?}",
            claim_checks(&c, "x", &scattered)
        );
        // Runs that never reach the bins leave two passages per bed: no k anywhere.
        let mut few = right.clone();
        for o in few.iter_mut().filter(|o| o.x < 0.6) {
            o.trajectory.clear();
        }
        let k = claim_checks(&c, "x", &few);
        assert!(k.iter().all(|k| k.status == Status::NotCompared), "{k:?}");
        // A missing run is an error, not a smaller ensemble.
        let k = claim_checks(&c, "x", &right[1..]);
        assert!(k.iter().all(|k| k.status == Status::Error), "{k:?}");
        let k = exponent_cross_checks(&c, &right, &with(&|_| 1.1), "lammps");
        assert!(k.len() == 3 && k.iter().all(|k| k.passed), "{k:?}");
        let k = exponent_cross_checks(
            &c,
            &right,
            &with(&|j| if j == 2 { 1.5 } else { 1.0 }),
            "lammps",
        );
        assert!(k.iter().all(|k| k.status == Status::Fail), "{k:?}");
    }

    /// The per-depth claim is refused on one bed and with more required beds than seeds,
    /// naming the field.
    #[test]
    fn velocity_exponent_per_depth_refusals() {
        let base = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/cases/impact2d/ci.toml"
        ))
        .unwrap();
        let claim = |seeds: &str| {
            format!(
                "{}\n[sweep]\nparameter = \"speed\"\nvalues = [0.3, 0.5, 0.7, 1.0]\n[claim]\nkind = \"velocity_exponent_per_depth\"\ndepths = [1.0, 2.0]\nhalf_width = 0.5\nmin = 0.7\nmax = 1.3\nmin_passages = 4\nmin_seeds = 3\nengine_tol = 0.2\n",
                base.replace("seed = 7", seeds)
            )
        };
        let e = Impact2dCase::from_toml_str(&claim("seed = 7"), Path::new("t.toml")).unwrap_err();
        assert!(format!("{e:#}").contains("seed ensemble"), "{e:#}");
        let e =
            Impact2dCase::from_toml_str(&claim("seeds = [1, 2]"), Path::new("t.toml")).unwrap_err();
        assert!(format!("{e:#}").contains("min_seeds"), "{e:#}");
        assert!(
            Impact2dCase::from_toml_str(&claim("seeds = [1, 2, 3]"), Path::new("t.toml")).is_ok()
        );
    }

    /// A `trend` is refused with its field and reason on one bed, on a sweep that is not
    /// numeric, over fewer than 3 values, and with `log_x` over a value <= 0.
    #[test]
    fn trend_claim_refusals() {
        let base = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/cases/impact2d/ci.toml"
        ))
        .unwrap();
        let case = |seeds: &str, sweep: &str, log_x: bool| {
            Impact2dCase::from_toml_str(
                &format!(
                    "{}\n[sweep]\n{sweep}\n[claim]\nkind = \"trend\"\ndirection = \"rises\"\nlog_x = {log_x}\n",
                    base.replace("seed = 7", seeds)
                ),
                Path::new("t.toml"),
            )
        };
        let speeds = "parameter = \"speed\"\nvalues = [0.3, 0.5, 0.7]";
        let refused = |r: Result<Impact2dCase, crate::case::CaseError>, field: &str, why: &str| {
            let e = format!("{:#}", r.unwrap_err());
            assert!(e.contains(field) && e.contains(why), "{e}");
        };
        refused(
            case("seed = 7", speeds, false),
            "claim.kind",
            "seed ensemble",
        );
        refused(
            case(
                "seeds = [1, 2]",
                "parameter = \"friction\"\nvalues = [\"static\", \"kinetic\"]",
                false,
            ),
            "claim.kind",
            "numeric sweep",
        );
        refused(
            case(
                "seeds = [1, 2]",
                "parameter = \"speed\"\nvalues = [0.3, 0.7]",
                false,
            ),
            "sweep.values",
            "at least 3 values",
        );
        refused(
            case(
                "seeds = [1, 2]",
                "parameter = \"mu\"\nvalues = [0.0, 0.3, 0.5]",
                true,
            ),
            "claim.log_x",
            "ln x",
        );
        assert!(case("seeds = [1, 2]", speeds, true).is_ok());
    }

    /// The claims' checks as registered on one bed (the rule one_bed reports), or an
    /// ensemble's checks.
    fn rules(c: &Impact2dCase, obs: &[VariantObs]) -> Vec<Check> {
        if c.is_ensemble() {
            return claim_checks(c, "x", obs);
        }
        c.claims
            .iter()
            .flat_map(|k| single_bed_rule(c, k, "x", obs))
            .collect()
    }

    fn one(c: &Impact2dCase, obs: &[VariantObs]) -> Option<Check> {
        let mut v = rules(c, obs);
        assert!(v.len() <= 1);
        v.pop()
    }

    /// On one bed a comparison between conditions is INCONCLUSIVE whatever its rule
    /// says (the rule is kept in the detail); a property of every run keeps its verdict.
    #[test]
    fn one_bed_decides_properties_of_runs_but_not_comparisons() {
        let c = case(
            "[[claim]]\nkind = \"increasing\"\nmin_step = 0.5\n[[claim]]\nkind = \"energy_non_increasing\"\nmax_rise = 0.01",
            "[sweep]\nparameter = \"e_n\"\nvalues = [0.1, 0.5]",
        );
        let mut o = obs(&[0.1, 0.5], &[1.0, 3.0]);
        o[0].energy = vec![(0.0, 10.0), (50.0, 8.0)];
        o[1].energy = vec![(0.0, 10.0), (50.0, 5.0)];
        let v = claim_checks(&c, "x", &o);
        assert_eq!(v[0].status, Status::Inconclusive, "{v:?}");
        assert!(
            v[0].detail.contains("one bed") && v[0].detail.contains("rule gives pass"),
            "{}",
            v[0].detail
        );
        assert_eq!(v[1].status, Status::Pass, "{v:?}");
        o[1].energy[1].1 = 12.0;
        assert_eq!(claim_checks(&c, "x", &o)[1].status, Status::Fail);
    }

    #[test]
    fn increasing_claim_passes_rising_and_fails_falling_or_too_flat() {
        let c = case(
            "[claim]\nkind = \"increasing\"\nmin_step = 0.5",
            "[sweep]\nparameter = \"e_n\"\nvalues = [0.1, 0.5, 0.9]",
        );
        assert!(
            one(&c, &obs(&[0.1, 0.5, 0.9], &[1.0, 2.0, 3.0]))
                .unwrap()
                .passed
        );
        assert!(
            !one(&c, &obs(&[0.1, 0.5, 0.9], &[3.0, 2.0, 1.0]))
                .unwrap()
                .passed
        );
        assert!(
            !one(&c, &obs(&[0.1, 0.5, 0.9], &[1.0, 1.3, 3.0]))
                .unwrap()
                .passed
        );
    }

    /// With min_step 0 the bound `y_k + 0 - y_k+1 <= 0` is met by a flat step; the claim
    /// says "increases", so a flat step fails, alone and on a seed ensemble without
    /// spread (the sweep-ignored control's identical runs), while a real rise passes.
    #[test]
    fn increasing_claim_with_min_step_zero_fails_a_flat_step() {
        let c = case(
            "[claim]\nkind = \"increasing\"\nmin_step = 0.0",
            "[sweep]\nparameter = \"e_n\"\nvalues = [0.1, 0.5, 0.9]",
        );
        let k = one(&c, &obs(&[0.1, 0.5, 0.9], &[1.0, 1.0, 2.0])).unwrap();
        assert!(k.value <= 0.0, "the min_step bound alone is met: {k:?}");
        assert!(
            k.status == crate::compare::Status::Fail && k.detail.contains("does not rise"),
            "{k:?}"
        );
        assert!(
            one(&c, &obs(&[0.1, 0.5, 0.9], &[1.0, 1.01, 2.0]))
                .unwrap()
                .passed
        );
        let e = ensemble(
            "[claim]\nkind = \"increasing\"\nmin_step = 0.0",
            "[sweep]\nparameter = \"friction\"\nvalues = [\"static\", \"kinetic\"]",
            "[1, 2, 3, 4, 5]",
        );
        let k = one(&e, &ensemble_obs(&e, &|_, _| 3.0)).unwrap();
        assert!(
            k.value <= 0.0 && k.status == crate::compare::Status::Fail,
            "{k:?}"
        );
        assert!(
            one(&e, &ensemble_obs(&e, &|i, _| 3.0 + 0.1 * i as f64))
                .unwrap()
                .passed
        );
    }

    /// Two claims give two checks; the time claim reads t_max_depth, not the depth.
    #[test]
    fn time_of_max_claim_follows_its_own_quantity() {
        let c = case(
            "[[claim]]\nkind = \"increasing\"\nmin_step = 1.0\n[[claim]]\nkind = \"increasing\"\nof = \"time_of_max_depth\"\nmin_step = 5.0",
            "[sweep]\nparameter = \"gravity\"\nvalues = [2.0, 1.0, 0.5]",
        );
        let mut o = obs(&[2.0, 1.0, 0.5], &[5.0, 7.0, 9.0]);
        for (k, t) in [40.0, 60.0, 62.0].into_iter().enumerate() {
            o[k].t_max_depth = t;
        }
        let v = rules(&c, &o);
        assert_eq!(v.len(), 2);
        assert!(v[0].passed, "depths rise by 2 d per step");
        assert!(!v[1].passed, "the last delay is 2 tau_c < 5");
        assert!((v[1].value - 3.0).abs() < 1e-12, "{}", v[1].value);
        o[2].t_max_depth = 70.0;
        assert!(rules(&c, &o).iter().all(|k| k.passed));
    }

    /// Energy claims: the loss at a time rises with friction; a rise of E fails.
    #[test]
    fn energy_claims_read_the_total_energy_series() {
        let c = case(
            "[[claim]]\nkind = \"increasing\"\nof = \"energy_lost\"\nat = 100.0\n[[claim]]\nkind = \"energy_non_increasing\"\nmax_rise = 0.01",
            "[sweep]\nparameter = \"mu\"\nvalues = [0.0, 0.5]",
        );
        let mut o = obs(&[0.0, 0.5], &[5.0, 4.0]);
        o[0].energy = vec![(0.0, 10.0), (50.0, 8.0), (100.0, 7.0)];
        o[1].energy = vec![(0.0, 10.0), (50.0, 5.0), (100.0, 4.0)];
        let v = rules(&c, &o);
        assert!(v[0].passed && v[1].passed, "{v:?}");
        // E rises from 5 to 7.5 (2.5 impact energies); the loss by t = 100 drops to 2.5.
        o[1].energy[2].1 = 7.5;
        let v = rules(&c, &o);
        assert!(!v[0].passed, "loss 2.5 < 3 with friction");
        assert!(
            !v[1].passed && (v[1].value - 2.5).abs() < 1e-12,
            "{:?}",
            v[1]
        );
    }

    /// K Fig 21's claims on synthetic forces: a sharp peak that halves fast passes, a
    /// slow rise fails; similar forces with different depths pass, equal depths (the
    /// sweep ignored) fail the premise; native vs reference fails on a 10 % peak change.
    #[test]
    fn force_claims_judge_peak_decay_and_similarity() {
        let c = case(
            "[[claim]]\nkind = \"force_impulsive\"\nbin = 2.0\npeak_within = 5.0\nhalf_within = 10.0\n[[claim]]\nkind = \"force_similar\"\nwindow = 10.0\nmax_spread_ratio = 0.5\nmin_depth_spread = 2.0",
            "[sweep]\nparameter = \"mu\"\nvalues = [0.0, 0.5]",
        )
        .clone();
        // 0.2 tau_c samples; contact at t = 7; shape(t - 7) after it.
        let series = |shape: &dyn Fn(f64) -> f64| -> Vec<(f64, f64)> {
            (0..500)
                .map(|k| {
                    let t = k as f64 * 0.2;
                    (t, if t < 7.0 - 1e-9 { 0.0 } else { shape(t - 7.0) })
                })
                .collect()
        };
        let sharp = |a: f64| move |s: f64| a * 1000.0 * (-s / 3.0).exp() + 50.0;
        let mut o = obs(&[0.0, 0.5], &[17.0, 10.0]);
        o[0].force = series(&sharp(1.0));
        o[1].force = series(&sharp(1.05));
        let v = rules(&c, &o);
        assert!(v[0].passed && v[1].passed, "{v:?}");
        // A force that builds up over 30 tau_c is not "very large immediately".
        o[1].force = series(&|s: f64| 30.0 * s.min(30.0));
        let v = rules(&c, &o);
        assert!(!v[0].passed, "{:?}", v[0]);
        // Equal depths: the premise "the depths differ significantly" fails.
        let mut same = obs(&[0.0, 0.5], &[10.0, 10.0]);
        same[0].force = series(&sharp(1.0));
        same[1].force = series(&sharp(1.0));
        let v = rules(&c, &same);
        assert!(
            !v[1].passed && v[1].detail.contains("premise"),
            "{:?}",
            v[1]
        );
        // Native vs reference: identical passes, a 10 % larger force fails 5 %.
        let mut b = o[0].clone();
        assert!(force_cross_check(&c, &o[0], &b, "lammps").unwrap().passed);
        b.force = series(&sharp(1.1));
        assert!(!force_cross_check(&c, &o[0], &b, "lammps").unwrap().passed);
    }

    /// K Figs 22-27's ordering claims: one check per network time, the ratio against
    /// min and max; the native-vs-reference B0 distance fails on a shifted curve.
    #[test]
    fn field_order_claims_compare_variants_per_time() {
        use crate::analysis::force_network::B0Curves;
        let c = case(
            "[[claim]]\nkind = \"field_order\"\nquantity = \"b0_normal\"\nlarger = \"friction=static\"\nsmaller = \"friction=kinetic\"\nmin_ratio = 1.1\nmax_ratio = 3.0",
            "[fields]\nnetwork_times = [12.0, 24.0]\n[sweep]\nparameter = \"friction\"\nvalues = [\"kinetic\", \"static\"]",
        );
        let curve = |h: f64| B0Curves {
            thresholds: vec![0.0, 1.0, 2.0],
            normal: vec![0.0, h, 0.0],
            tangential: vec![0.0, h, 0.0],
            mean_normal: 1.0,
            grains: 100,
            grain_contacts: 200,
        };
        let with = |label: &str, h: [f64; 2]| VariantObs {
            label: label.into(),
            fields: Some(FieldObs {
                networks: vec![(12.0, curve(h[0])), (24.0, curve(h[1]))],
                ..Default::default()
            }),
            ..obs(&[0.0], &[1.0])[0].clone()
        };
        let o = vec![
            with("friction=kinetic", [0.10, 0.10]),
            with("friction=static", [0.12, 0.105]),
        ];
        let v = rules(&c, &o);
        assert_eq!(v.len(), 2);
        assert!(v[0].passed && !v[1].passed, "{v:?}");
        assert!((v[0].value - 1.2).abs() < 1e-12);
        let big = vec![o[0].clone(), with("friction=static", [0.4, 0.4])];
        assert!(rules(&c, &big).iter().all(|k| !k.passed));
        let x = field_cross_checks(&c, &o[1], &o[1], "lammps");
        assert!(x.len() == 4 && x.iter().all(|k| k.passed), "{x:?}");
        let x = field_cross_checks(&c, &o[1], &with("friction=static", [0.12, 0.115]), "lammps");
        assert!(x.iter().filter(|k| !k.passed).count() == 2, "{x:?}");
    }

    /// K Fig 11's rule on synthetic final depths (two sizes, three seeds each), as an
    /// equivalence of the sizes' means within 1 d (Welch over the seeds): close, quiet
    /// sizes pass; sizes 3 d apart fail; sizes 0.2 d apart with seeds scattered by 2 d are
    /// INCONCLUSIVE (three seeds cannot tell); equal depths everywhere pass (nothing varies,
    /// and the control of the claim is a half-speed size, which moves it).
    #[test]
    fn size_insensitive_claim_is_an_equivalence_of_the_sizes() {
        let c = case(
            "[claim]\nkind = \"size_insensitive\"\nmax_spread = 1.0",
            "[sweep]\nparameter = \"bed\"\nvalues = [{ count = 450, length = 30, seed = 1 }, { count = 450, length = 30, seed = 2 }, { count = 450, length = 30, seed = 3 }, { count = 600, length = 30, seed = 1 }, { count = 600, length = 30, seed = 2 }, { count = 600, length = 30, seed = 3 }]",
        );
        let with = |d: [f64; 6]| {
            let mut o = obs(&[0.0, 1.0, 2.0, 3.0, 4.0, 5.0], &d);
            for (x, v) in o.iter_mut().zip(&c.variants) {
                x.label = v.label.clone();
            }
            o
        };
        let k = one(&c, &with([4.9, 5.0, 5.1, 5.0, 5.1, 5.2])).unwrap();
        assert_eq!(k.status, Status::Pass, "{k:?}");
        assert!((k.value - 0.1).abs() < 1e-12, "{}", k.value);
        assert!(k.detail.contains("seed 2: 5.100"), "{}", k.detail);
        let k = one(&c, &with([4.9, 5.0, 5.1, 7.9, 8.0, 8.1])).unwrap();
        assert_eq!(k.status, Status::Fail, "{k:?}");
        let k = one(&c, &with([4.0, 5.0, 6.0, 4.2, 5.2, 6.2])).unwrap();
        assert_eq!(k.status, Status::Inconclusive, "{k:?}");
        let k = one(&c, &with([5.0; 6])).unwrap();
        assert_eq!(k.status, Status::Pass, "{k:?}");
        // A variant without a result is an error, not a smaller group.
        let k = one(&c, &with([5.0; 6])[..5]).unwrap();
        assert!(k.is_error(), "{k:?}");
        assert_eq!(
            size_spreads(&[vec![1.0, 3.0], vec![2.0, 2.5, 3.0]]),
            (0.5, 1.5)
        );
    }

    /// A seed ensemble of the CI case (seeds 1-5, or as given) with a sweep and a claim.
    fn ensemble(claim: &str, sweep: &str, seeds: &str) -> Impact2dCase {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/cases/impact2d/ci.toml"
        ))
        .unwrap()
        .replace("seed = 7", &format!("seeds = {seeds}"));
        Impact2dCase::from_toml_str(&format!("{text}\n{sweep}\n{claim}\n"), Path::new("t.toml"))
            .unwrap()
    }

    /// Runs of every variant of `c` with the final depth (and time of the maximum)
    /// `depth(value index, seed index)`.
    fn ensemble_obs(c: &Impact2dCase, depth: &dyn Fn(usize, usize) -> f64) -> Vec<VariantObs> {
        let mut out = Vec::new();
        for (i, g) in c.ensemble_groups().iter().enumerate() {
            for (j, &k) in g.members.iter().enumerate() {
                let v = &c.variants[k];
                let mut o = obs(&[v.x], &[depth(i, j)]).remove(0);
                o.label = v.label.clone();
                out.push(o);
            }
        }
        out
    }

    /// The ensemble `increasing` rule (K Fig 6): static vs kinetic friction on five
    /// seeds, judged on the per-seed rises (docs/statistics.md). A clean 2 d step passes;
    /// the same mean step with per-seed rises scattered by several d is INCONCLUSIVE; a
    /// clean step below min_step fails; equal ensembles (the sweep ignored) fail; a
    /// missing run is an error.
    #[test]
    fn increasing_claim_on_a_seed_ensemble_is_a_paired_one_sided_test() {
        let c = ensemble(
            "[claim]\nkind = \"increasing\"\nmin_step = 0.5",
            "[sweep]\nparameter = \"friction\"\nvalues = [\"static\", \"kinetic\"]",
            "[1, 2, 3, 4, 5]",
        );
        let scatter = [0.0, 0.2, -0.1, 0.3, -0.2];
        let jitter = [0.05, -0.1, 0.0, 0.1, -0.05];
        let k = one(
            &c,
            &ensemble_obs(&c, &|i, j| 3.0 + scatter[j] + i as f64 * (2.0 + jitter[j])),
        )
        .unwrap();
        assert_eq!(k.status, Status::Pass, "{k:?}");
        assert!(
            k.detail
                .contains("friction=static: 3.040 +- 0.093 (seed 1: 3.000, seed 2: 3.200")
                && k.detail.contains("friction=kinetic: 5.040 +-")
                && k.detail
                    .contains("friction=static -> friction=kinetic, per seed: 2.0000"),
            "{}",
            k.detail
        );
        assert!((k.value - 2.0).abs() < 1e-12, "{}", k.value);
        // The same mean step, per-seed rises of -2 .. +6 d: undecided, with the beds it
        // would take.
        let wide = [0.0, 4.0, -2.0, 6.0, -4.0];
        let k = one(
            &c,
            &ensemble_obs(&c, &|i, j| 5.0 + i as f64 * (2.0 + wide[j])),
        )
        .unwrap();
        assert_eq!(k.status, Status::Inconclusive, "{k:?}");
        assert!(k.detail.contains("beds would decide"), "{}", k.detail);
        // Resolved but only 0.3 d: below min_step.
        let k = one(
            &c,
            &ensemble_obs(&c, &|i, j| {
                3.0 + scatter[j] + i as f64 * (0.3 + 0.2 * jitter[j])
            }),
        )
        .unwrap();
        assert_eq!(k.status, Status::Fail, "{k:?}");
        let k = one(&c, &ensemble_obs(&c, &|_, j| 3.0 + scatter[j])).unwrap();
        assert_eq!(k.status, Status::Fail, "{k:?}");
        let mut missing = ensemble_obs(&c, &|i, j| 3.0 + 2.0 * i as f64 + scatter[j]);
        missing.remove(7);
        let k = one(&c, &missing).unwrap();
        assert!(
            k.is_error() && k.detail.contains("friction=kinetic,seed=3"),
            "{k:?}"
        );
    }

    /// The ensemble `trend` rule (K Fig 9 read as a tendency): the mean per-seed slope
    /// of the final depth against ln g, sign flipped for `falls`, one-sided against
    /// min_slope. A clean fall of 2 d per e-fold passes; the same mean fall with per-seed
    /// slopes scattered by more than their mean is INCONCLUSIVE; a fall of 0.3 d per
    /// e-fold (resolved, below min_slope 1) fails; depth rising with g fails; the same
    /// clean fall judged as `rises` fails (the direction is not ignored).
    #[test]
    fn trend_claim_judges_the_per_seed_slopes_against_min_slope() {
        let sweep = "[sweep]\nparameter = \"gravity\"\nvalues = [2.53, 1.0, 0.377, 0.163, 0.0633]";
        let claim = |dir: &str| {
            format!(
                "[claim]\nkind = \"trend\"\ndirection = \"{dir}\"\nmin_slope = 1.0\nlog_x = true"
            )
        };
        let c = ensemble(&claim("falls"), sweep, "[1, 2, 3, 4, 5]");
        let lng: Vec<f64> = c.ensemble_groups().iter().map(|g| g.x.ln()).collect();
        let scatter = [0.0, 0.4, -0.3, 0.2, -0.1];
        let jitter = [0.05, -0.1, 0.0, 0.1, -0.05];
        let depth = |slope: f64, spread: &[f64; 5]| {
            let (lng, spread) = (lng.clone(), *spread);
            move |i: usize, j: usize| 10.0 + scatter[j] + slope * (1.0 + spread[j]) * lng[i]
        };
        let k = one(&c, &ensemble_obs(&c, &depth(-2.0, &jitter))).unwrap();
        assert_eq!(k.status, Status::Pass, "{k:?}");
        assert!((k.value - 2.0).abs() < 1e-9, "{}", k.value);
        assert!(
            k.name
                .contains("final depth falls with gravity (trend over 5 seeds)")
                && k.detail.contains("seed 1: 2.1000")
                && k.detail.contains("min_slope 1 d per unit of ln gravity"),
            "{k:?}"
        );
        let wide = [0.0, 2.0, -2.5, 3.0, -2.5];
        let k = one(&c, &ensemble_obs(&c, &depth(-2.0, &wide))).unwrap();
        assert_eq!(k.status, Status::Inconclusive, "{k:?}");
        let small = [0.01, -0.02, 0.0, 0.02, -0.01];
        let k = one(&c, &ensemble_obs(&c, &depth(-0.3, &small))).unwrap();
        assert_eq!(k.status, Status::Fail, "{k:?}");
        let k = one(&c, &ensemble_obs(&c, &depth(0.5, &small))).unwrap();
        assert_eq!(k.status, Status::Fail, "{k:?}");
        let rises = ensemble(&claim("rises"), sweep, "[1, 2, 3, 4, 5]");
        let k = one(&rises, &ensemble_obs(&rises, &depth(-2.0, &jitter))).unwrap();
        assert_eq!(k.status, Status::Fail, "{k:?}");
        assert!((k.value + 2.0).abs() < 1e-9, "{}", k.value);
    }

    /// The ensemble `field_order` rule (K Figs 22-25 on five seeds per friction model):
    /// the per-seed ln ratios of the two values, paired when both values of a seed ran
    /// on one bed and Welch's when each value settled its own beds. A clean 1.3-fold
    /// ratio at both times passes; the same ratio with one time at 1.0 fails (every time
    /// must pass); ratios scattered around 1.1 are INCONCLUSIVE; a band claim fails
    /// above its maximum; identical runs (the sweep ignored: ratio exactly 1) fail.
    #[test]
    fn field_order_claim_on_a_seed_ensemble_is_a_ratio_over_the_beds() {
        use crate::analysis::force_network::B0Curves;
        let fields = "[fields]\nnetwork_times = [12.0, 24.0]\n";
        let sweep = "[sweep]\nparameter = \"friction\"\nvalues = [\"kinetic\", \"static\"]";
        let claim = "[[claim]]\nkind = \"field_order\"\nquantity = \"b0_normal\"\nlarger = \"friction=static\"\nsmaller = \"friction=kinetic\"\nmin_ratio = 1.1";
        let shared = ensemble(claim, &format!("{fields}{sweep}"), "[1, 2, 3, 4, 5]");
        let own = ensemble(
            claim,
            &format!("{fields}{sweep}"),
            "[1, 2, 3, 4, 5]\nsettled_with = \"variant\"",
        );
        assert!(own.beds_per_variant && !shared.beds_per_variant);
        let curve = |h: f64| B0Curves {
            thresholds: vec![0.0, 1.0, 2.0],
            normal: vec![0.0, h, 0.0],
            tangential: vec![0.0, h, 0.0],
            mean_normal: 1.0,
            grains: 100,
            grain_contacts: 200,
        };
        // h(value index, seed index, time index)
        let runs = |c: &Impact2dCase, h: &dyn Fn(usize, usize, usize) -> f64| {
            let mut out = Vec::new();
            for (i, g) in c.ensemble_groups().iter().enumerate() {
                for (j, &k) in g.members.iter().enumerate() {
                    let v = &c.variants[k];
                    let mut o = obs(&[v.x], &[1.0]).remove(0);
                    o.label = v.label.clone();
                    o.fields = Some(FieldObs {
                        networks: vec![(12.0, curve(h(i, j, 0))), (24.0, curve(h(i, j, 1)))],
                        ..Default::default()
                    });
                    out.push(o);
                }
            }
            out
        };
        let bed = [1.0, 1.4, 0.75, 1.25, 0.85];
        let jitter = [0.01, -0.02, 0.0, 0.02, -0.01];
        let clean =
            |i: usize, j: usize, _t: usize| bed[j] * if i == 1 { 1.3 + jitter[j] } else { 1.0 };
        let k = one(&shared, &runs(&shared, &clean)).unwrap();
        assert_eq!(k.status, Status::Pass, "{k:?}");
        assert!(
            k.detail.contains("paired over 5 seeds") && k.detail.contains("seed 3: 1.3000"),
            "{}",
            k.detail
        );
        // Each value on its own beds: Welch's interval carries the bed-to-bed scatter.
        let k = one(&own, &runs(&own, &clean)).unwrap();
        assert!(k.detail.contains("Welch over 5 seeds"), "{}", k.detail);
        assert_eq!(k.status, Status::Inconclusive, "{k:?}");
        let quiet = |i: usize, j: usize, _t: usize| {
            if i == 1 {
                1.3 + jitter[j]
            } else {
                1.0 + jitter[j]
            }
        };
        assert_eq!(one(&own, &runs(&own, &quiet)).unwrap().status, Status::Pass);
        let one_time = |i: usize, j: usize, t: usize| {
            bed[j]
                * if i == 1 && t == 0 {
                    1.3 + jitter[j]
                } else {
                    1.0 + jitter[j]
                }
        };
        assert_eq!(
            one(&shared, &runs(&shared, &one_time)).unwrap().status,
            Status::Fail
        );
        let loose = [0.3, -0.25, 0.2, -0.3, 0.1];
        let scattered =
            |i: usize, j: usize, _t: usize| bed[j] * if i == 1 { 1.1 + loose[j] } else { 1.0 };
        assert_eq!(
            one(&shared, &runs(&shared, &scattered)).unwrap().status,
            Status::Inconclusive
        );
        let same = |_i: usize, j: usize, _t: usize| bed[j];
        let k = one(&shared, &runs(&shared, &same)).unwrap();
        assert_eq!(k.status, Status::Fail, "{k:?}");
        let band = ensemble(
            &format!("{claim}\nmax_ratio = 1.2"),
            &format!("{fields}{sweep}"),
            "[1, 2, 3, 4, 5]",
        );
        assert_eq!(
            one(&band, &runs(&band, &clean)).unwrap().status,
            Status::Fail
        );
    }

    /// The ensemble `linear` rule (K Fig 8b) under statistics v1: the per-seed slope must
    /// exceed 0 (a one-sided test over the seeds) and linearity itself has no registered
    /// curvature margin, so the best verdict is INCONCLUSIVE; R^2 of the means is
    /// reported. Equal depths at every speed (the sweep ignored) fail on the slope.
    #[test]
    fn linear_claim_on_a_seed_ensemble_fits_the_means() {
        let c = ensemble(
            "[claim]\nkind = \"linear\"\nfrom = 0.4\nr2_min = 0.9",
            "[sweep]\nparameter = \"speed\"\nvalues = [0.1, 0.4, 0.7, 1.0]",
            "[3, 1, 2]",
        );
        assert_eq!(c.seeds, [3, 1, 2]);
        let xs = [0.1, 0.4, 0.7, 1.0];
        let scatter = [0.4, -0.3, -0.1];
        let k = one(
            &c,
            &ensemble_obs(&c, &|i, j| 5.0 + 8.0 * xs[i] + scatter[j]),
        )
        .unwrap();
        assert_eq!(k.status, Status::Inconclusive, "{k:?}");
        assert!(
            k.detail.contains("must exceed 0.0000: PASS")
                && k.detail.contains("mean D = 5.000 + 8.000 x")
                && k.detail
                    .contains("speed=0.7: 10.600 +- 0.208 (seed 3: 11.000, seed 1: 10.300"),
            "{}",
            k.detail
        );
        let curved = [0.0, 2.0, 2.1, 9.0];
        let k = one(&c, &ensemble_obs(&c, &|i, j| curved[i] + scatter[j])).unwrap();
        assert!(!k.passed, "{k:?}");
        let k = one(&c, &ensemble_obs(&c, &|_, j| 10.0 + scatter[j])).unwrap();
        assert_eq!(k.status, Status::Fail, "{k:?}");
    }

    #[test]
    fn linear_claim_fails_curved_and_falling_data() {
        let c = case(
            "[claim]\nkind = \"linear\"\nfrom = 0.4\nr2_min = 0.9",
            "[sweep]\nparameter = \"speed\"\nvalues = [0.1, 0.4, 0.7, 1.0]",
        );
        let x = [0.1, 0.4, 0.7, 1.0];
        assert!(one(&c, &obs(&x, &[0.0, 2.0, 3.5, 5.0])).unwrap().passed);
        assert!(!one(&c, &obs(&x, &[0.0, 1.0, 1.0, 9.0])).unwrap().passed);
        assert!(!one(&c, &obs(&x, &[0.0, 5.0, 3.5, 2.0])).unwrap().passed);
    }

    #[test]
    fn cross_check_fails_beyond_a_grain() {
        let c = case("", "");
        let a = &obs(&[0.0], &[5.0])[0];
        let b = &obs(&[0.0], &[6.5])[0];
        let checks = cross_check(&c, a, b, Ok(1.2), "lammps");
        assert!(checks.iter().all(|k| !k.passed));
        let checks = cross_check(&c, a, a, Ok(0.1), "lammps");
        assert!(checks.iter().all(|k| k.passed));
    }
}
