//! Claims that span several penetration cases (Feng et al. Sec. 3 / Fig 3: "Varying
//! mu_gg gradually from 0.0 to 1.5 increases the normalised force consistently by more
//! than an order of magnitude ... and consequently the gradient K_phi"). Each case is an
//! ordinary ensemble with its own beds; what a claim needs from it is the per-engine
//! [`CaseSummary`] the penetration experiment writes as `summary.json`. A claim is
//! evaluated in each engine separately, like K's claims over an impact2d sweep.

use super::{Check, Gate};
use anyhow::{Context, Result, ensure};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// File name of a penetration case's summary inside its output directory.
pub const SUMMARY_FILE: &str = "summary.json";

/// What one engine's ensemble of one case reduces to for cross-case claims.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct EngineSummary {
    /// K_phi of the ensemble-mean FDR on the case's fit range.
    pub k_phi: f64,
    /// Its regression standard error (understates: FDR residuals are correlated).
    pub k_phi_se_regression: f64,
    /// K_phi of each bed alone.
    pub k_phi_beds: Vec<f64>,
    /// The ensemble-mean FDR (eq 5: h = depth / R, p = F / (rho_g psi g S R)).
    pub h: Vec<f64>,
    pub p: Vec<f64>,
    /// Mean initial packing fraction of the beds (the psi of eq 5).
    pub psi: f64,
}

impl EngineSummary {
    /// The uncertainty of `k_phi` a claim uses: the larger of the regression standard
    /// error and the bed-to-bed one (sd / sqrt(n)), fixed before any sweep was run.
    pub fn k_phi_se(&self) -> f64 {
        let n = self.k_phi_beds.len();
        let beds = if n >= 2 {
            let m = self.k_phi_beds.iter().sum::<f64>() / n as f64;
            let var = self.k_phi_beds.iter().map(|k| (k - m).powi(2)).sum::<f64>() / (n - 1) as f64;
            (var / n as f64).sqrt()
        } else {
            0.0
        };
        self.k_phi_se_regression.max(beds)
    }

    /// Mean p of the ensemble FDR over `h_at +- half`, and its standard error over those
    /// points (NaN-free: an empty window is an error).
    pub fn p_at(&self, h_at: f64, half: f64) -> Result<f64> {
        let v: Vec<f64> = self
            .h
            .iter()
            .zip(&self.p)
            .filter(|(h, _)| (**h - h_at).abs() <= half)
            .map(|(_, p)| *p)
            .collect();
        ensure!(
            !v.is_empty(),
            "the FDR has no point within {half} of h = {h_at} (it spans h {:.3}..{:.3})",
            self.h.first().copied().unwrap_or(f64::NAN),
            self.h.last().copied().unwrap_or(f64::NAN)
        );
        Ok(v.iter().sum::<f64>() / v.len() as f64)
    }
}

/// A penetration case's `summary.json`: which case (by canonical hash) and each engine.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct CaseSummary {
    pub case: String,
    pub canonical_hash: String,
    /// sha256 of each bed, in bed order: cases whose lists are equal penetrated the same
    /// beds, and a claim may pair their per-bed K_phi (empty in summaries written before
    /// beds were recorded here).
    #[serde(default)]
    pub bed_hashes: Vec<String>,
    pub engines: BTreeMap<String, EngineSummary>,
}

impl CaseSummary {
    pub fn write(&self, dir: &Path) -> Result<()> {
        let p = dir.join(SUMMARY_FILE);
        std::fs::write(&p, serde_json::to_string_pretty(self)?)
            .with_context(|| format!("writing {}", p.display()))
    }

    pub fn read(dir: &Path) -> Result<CaseSummary> {
        let p = dir.join(SUMMARY_FILE);
        let text = crate::rundata::fsio::read_to_string(
            &p,
            crate::rundata::fsio::MAX_RECORD_JSON,
            "a case summary (JSON)",
        )?;
        serde_json::from_str(&text).with_context(|| format!("{}: not a case summary", p.display()))
    }
}

/// The quantity a claim follows from case to case.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Quantity {
    /// K_phi of the ensemble-mean FDR, with [`EngineSummary::k_phi_se`].
    KPhi,
    /// The normalised force p of eq 5 at depth `at_h` (mean over `at_h +- 0.1`).
    P,
}

/// A claim over an ordered list of cases (`[[claim]]` of a suite file).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "snake_case")]
pub enum SweepClaim {
    /// The quantity rises at every step. For K_phi each rise must exceed `min_step_se`
    /// times the combined standard error of the two cases (a resolved rise).
    Increasing {
        quantity: Quantity,
        #[serde(default)]
        min_step_se: f64,
        #[serde(default)]
        at_h: Option<f64>,
    },
    /// last / first >= `ratio` ("more than an order of magnitude": 10).
    RatioAtLeast {
        quantity: Quantity,
        ratio: f64,
        #[serde(default)]
        at_h: Option<f64>,
    },
    /// No effect ("K_phi = 23.00 +- 0.15 for all three cases"): the largest ratio
    /// between two cases, K_max / K_min - 1, is at most `max_rel`. Decided as
    /// [`Check::at_most_resolved`] with the standard error of that ratio (paired over
    /// the beds when both cases penetrated the same ones), so data too noisy to see an
    /// effect of `max_rel` give NOT COMPARED, never a pass. K_phi only: the summaries
    /// carry no per-bed force.
    Independent { quantity: Quantity, max_rel: f64 },
}

impl SweepClaim {
    /// What a claim needs beyond its shape, checked when the suite is read.
    pub fn validate(&self) -> std::result::Result<(), String> {
        let positive = |what: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!("{what} = {v}: must be a positive number"))
            }
        };
        match self {
            SweepClaim::Increasing {
                quantity,
                min_step_se,
                at_h,
            } => {
                if !(min_step_se.is_finite() && *min_step_se >= 0.0) {
                    return Err(format!("min_step_se = {min_step_se}: must be >= 0"));
                }
                needs_depth(*quantity, *at_h)
            }
            SweepClaim::RatioAtLeast {
                quantity,
                ratio,
                at_h,
            } => {
                positive("ratio", *ratio)?;
                needs_depth(*quantity, *at_h)
            }
            SweepClaim::Independent { quantity, max_rel } => {
                positive("max_rel", *max_rel)?;
                if *quantity != Quantity::KPhi {
                    return Err(format!(
                        "kind = \"independent\" takes quantity = \"k_phi\" (its standard error needs per-bed values), not {quantity:?}"
                    ));
                }
                Ok(())
            }
        }
    }

    fn quantity(&self) -> (Quantity, Option<f64>) {
        match self {
            SweepClaim::Increasing { quantity, at_h, .. }
            | SweepClaim::RatioAtLeast { quantity, at_h, .. } => (*quantity, *at_h),
            SweepClaim::Independent { quantity, .. } => (*quantity, None),
        }
    }
}

fn needs_depth(q: Quantity, at_h: Option<f64>) -> std::result::Result<(), String> {
    match (q, at_h) {
        (Quantity::P, None) => Err("quantity = \"p\" needs `at_h` (the depth, in R)".into()),
        (Quantity::P, Some(h)) if !(h.is_finite() && h > 0.0) => {
            Err(format!("at_h = {h}: must be a positive depth in R"))
        }
        _ => Ok(()),
    }
}

/// Half-width of the depth window of [`Quantity::P`], in R.
pub const P_WINDOW_HALF: f64 = 0.1;

fn value(q: Quantity, at_h: Option<f64>, s: &EngineSummary) -> Result<(f64, f64)> {
    match q {
        Quantity::KPhi => Ok((s.k_phi, s.k_phi_se())),
        Quantity::P => {
            let h = at_h.context("quantity p needs `at_h`")?;
            Ok((s.p_at(h, P_WINDOW_HALF)?, 0.0))
        }
    }
}

fn label(q: Quantity, at_h: Option<f64>) -> String {
    match (q, at_h) {
        (Quantity::KPhi, _) => "K_phi".into(),
        (Quantity::P, Some(h)) => format!("p(h = {h})"),
        (Quantity::P, None) => "p".into(),
    }
}

/// One check per engine: the claim `name` over `cases` (labels and summaries, in order).
pub fn evaluate(
    name: &str,
    claim: &SweepClaim,
    cases: &[(String, CaseSummary)],
    engine: &str,
) -> Check {
    let title = format!("{name} ({engine})");
    let mut pts = Vec::new();
    for (l, s) in cases {
        let Some(e) = s.engines.get(engine) else {
            return Check::not_compared(
                title,
                Gate::Claim,
                format!("case {l} has no {engine} run in its summary"),
            );
        };
        let (q, at_h) = claim.quantity();
        match value(q, at_h, e) {
            Ok(v) => pts.push((l.clone(), v, e, &s.bed_hashes)),
            Err(err) => return Check::error_in(title, Gate::Claim, format!("{l}: {err:#}")),
        }
    }
    let listing = |q: Quantity| {
        pts.iter()
            .map(|(l, (v, se), ..)| {
                if q == Quantity::KPhi {
                    format!("{l}: {v:.3} +- {se:.3}")
                } else {
                    format!("{l}: {v:.3}")
                }
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    match claim {
        SweepClaim::Increasing {
            quantity,
            min_step_se,
            at_h,
        } => {
            if pts.len() < 2 {
                return Check::not_compared(title, Gate::Claim, "a trend needs at least 2 cases");
            }
            // Smallest margin of a step over its required rise: > 0 iff every step
            // rises, and by more than min_step_se combined standard errors ("rises" is
            // strict: equal values are no rise).
            let margin = pts
                .windows(2)
                .map(|w| {
                    let ((a, sa), (b, sb)) = (w[0].1, w[1].1);
                    (b - a) - min_step_se * sa.hypot(sb)
                })
                .fold(f64::INFINITY, f64::min);
            let detail = format!(
                "{} along the cases: {}",
                label(*quantity, *at_h),
                listing(*quantity)
            );
            let q = label(*quantity, *at_h);
            let metric = if *min_step_se > 0.0 {
                format!("min_k (({q}_k+1 - {q}_k) - {min_step_se} x SE_k,k+1), must be > 0")
            } else {
                format!("min_k ({q}_k+1 - {q}_k), must be > 0")
            };
            if margin > 0.0 {
                Check::at_least(title, Gate::Claim, metric, margin, 0.0, detail)
            } else {
                Check::failed(title, Gate::Claim, metric, margin, detail)
            }
        }
        SweepClaim::RatioAtLeast {
            quantity,
            ratio,
            at_h,
        } => {
            let (Some(first), Some(last)) = (pts.first(), pts.last()) else {
                return Check::not_compared(title, Gate::Claim, "a ratio needs cases");
            };
            let (first, last) = (first.1.0, last.1.0);
            Check::at_least(
                title,
                Gate::Claim,
                format!("{q}_last / {q}_first", q = label(*quantity, *at_h)),
                last / first,
                *ratio,
                format!(
                    "{} along the cases: {}",
                    label(*quantity, *at_h),
                    listing(*quantity)
                ),
            )
        }
        SweepClaim::Independent { quantity, max_rel } => {
            let by = |f: fn(f64, f64) -> bool| {
                pts.iter()
                    .reduce(|a, b| if f(b.1.0, a.1.0) { b } else { a })
            };
            let (Some(hi), Some(lo)) = (by(|b, a| b > a), by(|b, a| b < a)) else {
                return Check::not_compared(title, Gate::Claim, "no cases");
            };
            let spread = hi.1.0 / lo.1.0 - 1.0;
            let (se, how) = ratio_se(hi, lo);
            Check::at_most_resolved(
                title,
                Gate::Claim,
                format!("{q}_max / {q}_min - 1", q = label(*quantity, None)),
                spread,
                se,
                *max_rel,
                format!(
                    "largest ratio {} / {} = {:.4} (standard error {se:.4}, {how}); {} along the cases: {}",
                    hi.0,
                    lo.0,
                    hi.1.0 / lo.1.0,
                    label(*quantity, None),
                    listing(*quantity)
                ),
                format!(
                    "the ratio's standard error {se:.4} exceeds half the tolerance {max_rel}: these beds cannot resolve an effect of that size"
                ),
            )
        }
    }
}

/// A claim's negative control (`[[claim.negative_control]]` of a suite): the claim
/// evaluated on the native runs with wrong physics must fail.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "snake_case")]
pub enum ClaimControl {
    /// Every case replaced by the first: what the native engine gives when the swept
    /// parameter is ignored. Equal to running every case with the first case's
    /// parameters, because the cases share their seeds and bed count (checked when the
    /// suite is read) and the native engine is deterministic. For claims of an effect.
    SweepIgnored { name: String },
    /// `case` replaced by its own negative control `control` (the native engine with
    /// wrong physics on the same beds). For claims of no effect.
    CaseControl {
        name: String,
        case: String,
        control: String,
    },
}

impl ClaimControl {
    pub fn name(&self) -> &str {
        match self {
            ClaimControl::SweepIgnored { name } | ClaimControl::CaseControl { name, .. } => name,
        }
    }
}

/// The check of one claim control from the claim's evaluation on the substituted native
/// runs: it bites only when that evaluation fails (an error or NOT COMPARED is not a
/// bite).
pub fn control_check(claim: &str, control: &ClaimControl, substituted: &Check) -> Check {
    let label = format!("{claim}: negative control \"{}\"", control.name());
    let detail = format!(
        "{control:?}; the claim on the substituted native runs: {:?}, {} = {:.4} ({})",
        substituted.status, substituted.metric, substituted.value, substituted.detail
    );
    let unbitten = if substituted.status == super::Status::Fail {
        Vec::new()
    } else {
        vec!["the claim".to_string()]
    };
    Check::control(label, &unbitten, detail)
}

/// One case's point of a claim: label, (value, standard error), its engine summary and
/// the case's bed hashes.
type Point<'a> = (String, (f64, f64), &'a EngineSummary, &'a Vec<String>);

/// Standard error of K_hi / K_lo and how it was obtained: from the per-bed ratios when
/// both cases penetrated the same beds (the bed-to-bed scatter cancels in the pair),
/// else propagated from each case's own standard error.
fn ratio_se(hi: &Point, lo: &Point) -> (f64, &'static str) {
    let (a, b) = (hi.2, lo.2);
    let n = a.k_phi_beds.len();
    if n >= 2 && !hi.3.is_empty() && hi.3 == lo.3 && b.k_phi_beds.len() == n {
        let r: Vec<f64> = a
            .k_phi_beds
            .iter()
            .zip(&b.k_phi_beds)
            .map(|(x, y)| x / y)
            .collect();
        let m = r.iter().sum::<f64>() / n as f64;
        let var = r.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1) as f64;
        ((var / n as f64).sqrt(), "paired over the shared beds")
    } else {
        let (ka, kb) = (hi.1.0, lo.1.0);
        (
            ka / kb * (hi.1.1 / ka).hypot(lo.1.1 / kb),
            "the cases' standard errors combined (beds not shared)",
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn summary(k: f64, beds: &[f64], p_level: f64) -> CaseSummary {
        let h: Vec<f64> = (0..300).map(|i| i as f64 * 0.01).collect();
        let p = h.iter().map(|x| p_level * x).collect();
        let e = EngineSummary {
            k_phi: k,
            k_phi_se_regression: 0.1,
            k_phi_beds: beds.to_vec(),
            h,
            p,
            psi: 0.6,
        };
        CaseSummary {
            case: "c".into(),
            canonical_hash: "x".into(),
            bed_hashes: vec!["b0".into(), "b1".into(), "b2".into()],
            engines: [("native".to_string(), e)].into(),
        }
    }

    fn cases(v: Vec<CaseSummary>) -> Vec<(String, CaseSummary)> {
        v.into_iter()
            .enumerate()
            .map(|(i, s)| (format!("c{i}"), s))
            .collect()
    }

    #[test]
    fn bed_scatter_sets_the_standard_error_when_it_exceeds_the_regression() {
        let s = summary(10.0, &[8.0, 10.0, 12.0], 1.0);
        let e = &s.engines["native"];
        assert!((e.k_phi_se() - 2.0 / 3f64.sqrt()).abs() < 1e-12);
    }

    /// A rise smaller than 2 combined SE fails; a resolved one passes; a fall fails.
    #[test]
    fn increasing_needs_resolved_rises() {
        let claim = SweepClaim::Increasing {
            quantity: Quantity::KPhi,
            min_step_se: 2.0,
            at_h: None,
        };
        let ok = cases(vec![
            summary(3.0, &[2.9, 3.0, 3.1], 1.0),
            summary(30.0, &[28.0, 30.0, 32.0], 10.0),
            summary(40.0, &[39.0, 40.0, 41.0], 12.0),
        ]);
        assert!(evaluate("k", &claim, &ok, "native").passed);
        let small = cases(vec![
            summary(30.0, &[28.0, 30.0, 32.0], 1.0),
            summary(32.0, &[30.0, 32.0, 34.0], 1.0),
        ]);
        assert!(!evaluate("k", &claim, &small, "native").passed);
        let falling = cases(vec![
            summary(30.0, &[30.0; 3], 1.0),
            summary(20.0, &[20.0; 3], 1.0),
        ]);
        assert!(!evaluate("k", &claim, &falling, "native").passed);
        // "Rises" is strict: equal points are no rise, even without a required step.
        let flat = SweepClaim::Increasing {
            quantity: Quantity::P,
            min_step_se: 0.0,
            at_h: Some(2.0),
        };
        let same = cases(vec![summary(3.0, &[3.0], 5.0), summary(3.0, &[3.0], 5.0)]);
        assert!(!evaluate("p", &flat, &same, "native").passed);
        let missing = evaluate("k", &claim, &ok, "liggghts");
        assert_eq!(missing.status, crate::compare::Status::NotCompared);
    }

    /// No effect: decided when the paired ratio is resolved, a resolved effect fails,
    /// and scatter too large to see the tolerance is NOT COMPARED, never a pass.
    #[test]
    fn independent_pairs_shared_beds_and_never_passes_unresolved() {
        use crate::compare::Status;
        let claim = SweepClaim::Independent {
            quantity: Quantity::KPhi,
            max_rel: 0.10,
        };
        // Large bed-to-bed scatter, but each bed moves by the same 4 %: paired, resolved.
        let a = summary(30.0, &[25.0, 30.0, 35.0], 1.0);
        let b = summary(31.2, &[26.0, 31.2, 36.4], 1.0);
        let k = evaluate("v", &claim, &cases(vec![a.clone(), b.clone()]), "native");
        assert_eq!(k.status, Status::Pass, "{k:?}");
        assert!((k.value - 0.04).abs() < 1e-12);
        // The same numbers on different beds: the scatter cannot resolve 10 %.
        let mut other = b.clone();
        other.bed_hashes = vec!["c0".into(), "c1".into(), "c2".into()];
        let k = evaluate("v", &claim, &cases(vec![a.clone(), other]), "native");
        assert_eq!(k.status, Status::NotCompared, "{k:?}");
        // A 30 % effect on the same beds fails.
        let c = summary(39.0, &[32.5, 39.0, 45.5], 1.0);
        let k = evaluate("v", &claim, &cases(vec![a, b, c]), "native");
        assert_eq!(k.status, Status::Fail, "{k:?}");
        assert!(
            SweepClaim::Independent {
                quantity: Quantity::P,
                max_rel: 0.1
            }
            .validate()
            .is_err()
        );
    }

    /// A claim control bites only when the substituted claim fails.
    #[test]
    fn a_claim_control_bites_only_on_a_failure() {
        let c = ClaimControl::SweepIgnored { name: "x".into() };
        let fail = Check::failed("k", Gate::Claim, "m", -1.0, "");
        assert!(control_check("k", &c, &fail).passed);
        let pass = Check::at_most("k", Gate::Claim, "m", 0.0, 1.0, "");
        assert!(!control_check("k", &c, &pass).passed);
        let nc = Check::not_compared("k", Gate::Claim, "why");
        assert!(!control_check("k", &c, &nc).passed);
    }

    #[test]
    fn ratio_reads_p_at_the_registered_depth() {
        let claim = SweepClaim::RatioAtLeast {
            quantity: Quantity::P,
            ratio: 10.0,
            at_h: Some(2.0),
        };
        let c = cases(vec![
            summary(3.0, &[3.0], 1.0),
            summary(40.0, &[40.0], 11.0),
        ]);
        let k = evaluate("f", &claim, &c, "native");
        assert!(k.passed && (k.value - 11.0).abs() < 1e-9, "{k:?}");
        let c = cases(vec![summary(3.0, &[3.0], 1.0), summary(40.0, &[40.0], 9.0)]);
        assert!(!evaluate("f", &claim, &c, "native").passed);
        let far = SweepClaim::RatioAtLeast {
            quantity: Quantity::P,
            ratio: 10.0,
            at_h: Some(9.0),
        };
        let e = evaluate("f", &far, &c, "native");
        assert_eq!(e.status, crate::compare::Status::Error);
    }
}
