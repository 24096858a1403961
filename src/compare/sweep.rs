//! Claims that span several penetration cases (Feng et al. Sec. 3 / Fig 3: "Varying
//! mu_gg gradually from 0.0 to 1.5 increases the normalised force consistently by more
//! than an order of magnitude ... and consequently the gradient K_phi"). Each case is an
//! ordinary ensemble with its own beds; what a claim needs from it is the per-engine
//! [`CaseSummary`] the penetration experiment writes as `summary.json`. A claim is
//! evaluated in each engine separately, like K's claims over an impact2d sweep.

use super::{Check, Comparison, Gate, Rule};
use crate::numerics::stats::Estimate;
use anyhow::{Context, Result, ensure};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// File name of a penetration case's summary inside its output directory.
pub(crate) const SUMMARY_FILE: &str = "summary.json";

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
    /// Each bed's own FDR (h, p), in bed order: the replicates of per-bed force
    /// statistics (docs/statistics.md). Empty in summaries written before they were kept.
    #[serde(default)]
    pub bed_fdrs: Vec<(Vec<f64>, Vec<f64>)>,
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

    /// Mean p of the ensemble FDR over `h_at +- half` (an empty window is an error).
    pub(crate) fn p_at(&self, h_at: f64, half: f64) -> Result<f64> {
        window_mean(&self.h, &self.p, h_at, half)
    }

    /// Mean p of each bed's FDR over `h_at +- half`, in bed order.
    pub(crate) fn p_at_beds(&self, h_at: f64, half: f64) -> Result<Vec<f64>> {
        self.bed_fdrs
            .iter()
            .enumerate()
            .map(|(k, (h, p))| window_mean(h, p, h_at, half).with_context(|| format!("bed {k}")))
            .collect()
    }
}

fn window_mean(h: &[f64], p: &[f64], h_at: f64, half: f64) -> Result<f64> {
    let v: Vec<f64> = h
        .iter()
        .zip(p)
        .filter(|(h, _)| (**h - h_at).abs() <= half)
        .map(|(_, p)| *p)
        .collect();
    ensure!(
        !v.is_empty(),
        "the FDR has no point within {half} of h = {h_at} (it spans h {:.3}..{:.3})",
        h.first().copied().unwrap_or(f64::NAN),
        h.last().copied().unwrap_or(f64::NAN)
    );
    Ok(v.iter().sum::<f64>() / v.len() as f64)
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
    /// The quantity rises at every step: a one-sided test per step on the per-bed log
    /// values (paired over shared beds, else Welch) that the rise exceeds zero, every
    /// step passing for a pass, one resolved shortfall (Bonferroni over the steps) for a
    /// failure (docs/statistics.md). `min_step_se`, the old "by k combined standard
    /// errors", is retired: the interval carries the uncertainty.
    Increasing {
        quantity: Quantity,
        #[serde(default)]
        min_step_se: Option<f64>,
        #[serde(default)]
        at_h: Option<f64>,
    },
    /// last / first >= `ratio` ("more than an order of magnitude": 10), a one-sided test
    /// of ln(last / first) against ln(ratio) on the per-bed values.
    RatioAtLeast {
        quantity: Quantity,
        ratio: f64,
        #[serde(default)]
        at_h: Option<f64>,
    },
    /// No effect ("K_phi = 23.00 +- 0.15 for all three cases"): every pair of cases is
    /// equivalent within a ratio of 1 + `max_rel`, two one-sided tests on the per-bed
    /// ln values (paired over shared beds, else Welch) with the margin ln(1 + max_rel);
    /// a pass needs every pair to pass, a failure one pair resolved outside at the
    /// Bonferroni level (docs/statistics.md). Data too noisy to see an effect of
    /// `max_rel` are INCONCLUSIVE, never a pass.
    Independent { quantity: Quantity, max_rel: f64 },
}

impl SweepClaim {
    /// What a claim needs beyond its shape, checked when the suite is read.
    pub(crate) fn validate(&self) -> std::result::Result<(), String> {
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
                if let Some(k) = min_step_se {
                    return Err(format!(
                        "min_step_se = {k}: retired (docs/statistics.md): a rise is now a one-sided test whose interval carries the uncertainty; remove the field"
                    ));
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
                match quantity {
                    Quantity::KPhi => Ok(()),
                    Quantity::P => Err(
                        "kind = \"independent\" takes quantity = \"k_phi\" (it registers no depth for p)"
                            .to_string(),
                    ),
                }
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
pub(crate) const P_WINDOW_HALF: f64 = 0.1;

/// The quantity of one engine's ensemble: (the ensemble value, its standard error for
/// plots, the per-bed values the claim's statistics use).
fn value(q: Quantity, at_h: Option<f64>, s: &EngineSummary) -> Result<(f64, f64, Vec<f64>)> {
    match q {
        Quantity::KPhi => Ok((s.k_phi, s.k_phi_se(), s.k_phi_beds.clone())),
        Quantity::P => {
            let h = at_h.context("quantity p needs `at_h`")?;
            Ok((
                s.p_at(h, P_WINDOW_HALF)?,
                f64::NAN,
                s.p_at_beds(h, P_WINDOW_HALF)?,
            ))
        }
    }
}

/// One case's point of a claim: its label, ensemble value, per-bed values and bed hashes.
struct Point<'a> {
    label: String,
    value: f64,
    se: f64,
    beds: Vec<f64>,
    bed_hashes: &'a [String],
}

/// ln(b) - ln(a) over the beds: paired when both cases penetrated the same beds (equal,
/// non-empty bed hashes: the bed-to-bed scatter cancels in the pair), else Welch. None
/// with fewer than two beds on a side or a value that is not positive.
fn log_step(a: &Point, b: &Point) -> (Option<Estimate>, &'static str) {
    let ln = |v: &[f64]| -> Option<Vec<f64>> {
        v.iter()
            .map(|x| (*x > 0.0 && x.is_finite()).then(|| x.ln()))
            .collect()
    };
    let (Some(la), Some(lb)) = (ln(&a.beds), ln(&b.beds)) else {
        return (None, "a value that is not positive");
    };
    let shared = !a.bed_hashes.is_empty()
        && a.bed_hashes == b.bed_hashes
        && la.len() == a.bed_hashes.len()
        && lb.len() == la.len();
    if shared {
        (Estimate::paired(&lb, &la), "paired over the shared beds")
    } else {
        (Estimate::welch(&lb, &la), "Welch, beds not shared")
    }
}

fn label(q: Quantity, at_h: Option<f64>) -> String {
    match (q, at_h) {
        (Quantity::KPhi, _) => "K_phi".into(),
        (Quantity::P, Some(h)) => format!("p(h = {h})"),
        (Quantity::P, None) => "p".into(),
    }
}

/// One check per engine: the claim `name` over `cases` (labels and summaries, in order),
/// decided by the rules of docs/statistics.md on the per-bed values.
pub(crate) fn evaluate(
    name: &str,
    claim: &SweepClaim,
    cases: &[(String, CaseSummary)],
    engine: &str,
) -> Check {
    let title = format!("{name} ({engine})");
    let (q, at_h) = claim.quantity();
    let mut pts = Vec::new();
    for (l, s) in cases {
        let Some(e) = s.engines.get(engine) else {
            return Check::not_compared(
                title,
                Gate::Claim,
                format!("case {l} has no {engine} run in its summary"),
            );
        };
        match value(q, at_h, e) {
            Ok((value, se, beds)) => pts.push(Point {
                label: l.clone(),
                value,
                se,
                beds,
                bed_hashes: &s.bed_hashes,
            }),
            Err(err) => return Check::error_in(title, Gate::Claim, format!("{l}: {err:#}")),
        }
    }
    let ql = label(q, at_h);
    let listing = format!(
        "{ql} along the cases (ensemble; beds): {}",
        pts.iter()
            .map(|p| {
                let se = if p.se.is_finite() {
                    format!(" +- {:.3}", p.se)
                } else {
                    String::new()
                };
                format!(
                    "{}: {:.3}{se} ({})",
                    p.label,
                    p.value,
                    p.beds
                        .iter()
                        .map(|v| format!("{v:.3}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            })
            .collect::<Vec<_>>()
            .join("; ")
    );
    let step = |a: &Point, b: &Point, rule: Rule, m: usize| {
        let (estimate, how) = log_step(a, b);
        Comparison {
            what: format!("ln({ql} {} / {ql} {}) ({how})", b.label, a.label),
            estimate,
            rule,
            m,
        }
    };
    match claim {
        SweepClaim::Increasing { .. } => {
            if pts.len() < 2 {
                return Check::not_compared(title, Gate::Claim, "a trend needs at least 2 cases");
            }
            let m = pts.len() - 1;
            let parts: Vec<Comparison> = pts
                .windows(2)
                .map(|w| step(&w[0], &w[1], Rule::Exceeds { delta: 0.0 }, m))
                .collect();
            Check::decided(
                title,
                Gate::Claim,
                format!("ln({ql}_k+1 / {ql}_k) at every step, must exceed 0"),
                &parts,
                listing,
            )
        }
        SweepClaim::RatioAtLeast { ratio, .. } => {
            let (Some(first), Some(last)) = (pts.first(), pts.last()) else {
                return Check::not_compared(title, Gate::Claim, "a ratio needs cases");
            };
            Check::decided(
                title,
                Gate::Claim,
                format!("ln({ql}_last / {ql}_first), must exceed ln {ratio}"),
                &[step(first, last, Rule::Exceeds { delta: ratio.ln() }, 1)],
                format!(
                    "ensemble ratio {ql}_last / {ql}_first = {:.3}; {listing}",
                    last.value / first.value
                ),
            )
        }
        SweepClaim::Independent { max_rel, .. } => {
            if pts.len() < 2 {
                return Check::not_compared(title, Gate::Claim, "no effect needs at least 2 cases");
            }
            let m = pts.len() * (pts.len() - 1) / 2;
            let margin = (1.0 + max_rel).ln();
            let mut parts = Vec::with_capacity(m);
            for i in 0..pts.len() {
                for j in i + 1..pts.len() {
                    parts.push(step(&pts[i], &pts[j], Rule::Equivalence { margin }, m));
                }
            }
            Check::decided(
                title,
                Gate::Claim,
                format!("ln({ql}_j / {ql}_i) for every pair, within +-ln(1 + {max_rel})"),
                &parts,
                listing,
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

/// In words, as reports print it.
impl std::fmt::Display for ClaimControl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ClaimControl::SweepIgnored { name } => write!(
                f,
                "control \"{name}\": every case replaced by the first (the swept parameter ignored)"
            ),
            ClaimControl::CaseControl {
                name,
                case,
                control,
            } => write!(
                f,
                "control \"{name}\": case {case} replaced by its negative control \"{control}\""
            ),
        }
    }
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
/// bite); an INCONCLUSIVE evaluation leaves the control INCONCLUSIVE (docs/statistics.md,
/// "Negative controls").
pub(crate) fn control_check(claim: &str, control: &ClaimControl, substituted: &Check) -> Check {
    let label = format!("{claim}: negative control \"{}\"", control.name());
    let detail = format!(
        "{control}; the claim on the substituted native runs: {}, {} = {} ({})",
        substituted.status.label(),
        substituted.metric,
        crate::numerics::fmt::number(substituted.value),
        substituted.detail
    );
    if substituted.status == super::Status::Inconclusive {
        return Check::control_unresolved(label, &["the claim".to_string()], detail);
    }
    let unbitten = if substituted.status == super::Status::Fail {
        Vec::new()
    } else {
        vec!["the claim".to_string()]
    };
    Check::control(label, &unbitten, detail)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare::Status;

    /// A summary whose beds have K_phi `beds` and FDRs p = level_k h (bed k's level is
    /// `p_level` times bed k's K_phi over the first bed's, so per-bed force scatters with
    /// K_phi).
    fn summary(k: f64, beds: &[f64], p_level: f64) -> CaseSummary {
        let h: Vec<f64> = (0..300).map(|i| i as f64 * 0.01).collect();
        let p = h.iter().map(|x| p_level * x).collect();
        let bed_fdrs = beds
            .iter()
            .map(|b| {
                let l = p_level * b / beds[0];
                (h.clone(), h.iter().map(|x| l * x).collect())
            })
            .collect();
        let e = EngineSummary {
            k_phi: k,
            k_phi_se_regression: 0.1,
            k_phi_beds: beds.to_vec(),
            h,
            p,
            bed_fdrs,
            psi: 0.6,
        };
        CaseSummary {
            case: "c".into(),
            canonical_hash: "x".into(),
            bed_hashes: (0..beds.len()).map(|k| format!("b{k}")).collect(),
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

    fn increasing(q: Quantity) -> SweepClaim {
        SweepClaim::Increasing {
            quantity: q,
            min_step_se: None,
            at_h: (q == Quantity::P).then_some(2.0),
        }
    }

    /// Resolved rises pass; a rise the beds cannot resolve is INCONCLUSIVE, a resolved
    /// fall fails; equal points (the sweep ignored) are no rise.
    #[test]
    fn increasing_is_a_one_sided_test_per_step() {
        let claim = increasing(Quantity::KPhi);
        let ok = cases(vec![
            summary(3.0, &[2.9, 3.0, 3.1], 1.0),
            summary(30.0, &[28.0, 30.0, 32.0], 10.0),
            summary(40.0, &[39.0, 40.5, 41.0], 12.0),
        ]);
        let k = evaluate("k", &claim, &ok, "native");
        assert_eq!(k.status, Status::Pass, "{k:?}");
        // 30 -> 32 on scattered, unshared beds: not resolved.
        let mut b = summary(32.0, &[29.0, 31.0, 36.0], 1.0);
        b.bed_hashes = vec!["o0".into(), "o1".into(), "o2".into()];
        let small = cases(vec![summary(30.0, &[28.0, 30.0, 32.0], 1.0), b]);
        let k = evaluate("k", &claim, &small, "native");
        assert_eq!(k.status, Status::Inconclusive, "{k:?}");
        assert!(k.detail.contains("Welch"), "{}", k.detail);
        let falling = cases(vec![
            summary(30.0, &[30.0, 31.0, 29.0], 1.0),
            summary(20.0, &[20.0, 21.0, 19.5], 1.0),
        ]);
        assert_eq!(
            evaluate("k", &claim, &falling, "native").status,
            Status::Fail
        );
        // The sweep ignored: every case is the first, a flat line fails ("rises" is strict).
        let a = summary(3.0, &[2.9, 3.0, 3.2], 5.0);
        for q in [Quantity::KPhi, Quantity::P] {
            let k = evaluate(
                "x",
                &increasing(q),
                &cases(vec![a.clone(), a.clone()]),
                "native",
            );
            assert_eq!(k.status, Status::Fail, "{q:?}: {k:?}");
        }
        let missing = evaluate("k", &claim, &ok, "liggghts");
        assert_eq!(missing.status, Status::NotCompared);
        assert!(claim.validate().is_ok());
        let old = SweepClaim::Increasing {
            quantity: Quantity::KPhi,
            min_step_se: Some(2.0),
            at_h: None,
        };
        assert!(old.validate().unwrap_err().contains("retired"));
    }

    /// No effect: every pair an equivalence test; pairing over shared beds removes the
    /// bed-to-bed scatter; unresolved data are INCONCLUSIVE, never a pass.
    #[test]
    fn independent_is_an_equivalence_test_of_every_pair() {
        let claim = SweepClaim::Independent {
            quantity: Quantity::KPhi,
            max_rel: 0.10,
        };
        // Large bed-to-bed scatter, each bed moves by 3.5-4.5 %: paired, inside 10 %.
        let a = summary(30.0, &[25.0, 30.0, 35.0, 28.0, 32.0], 1.0);
        let b = summary(31.2, &[25.9, 31.3, 36.5, 29.1, 33.3], 1.0);
        let k = evaluate("v", &claim, &cases(vec![a.clone(), b.clone()]), "native");
        assert_eq!(k.status, Status::Pass, "{k:?}");
        assert!((k.value - 0.04).abs() < 0.005, "{}", k.value);
        // The same numbers on different beds: the scatter cannot resolve 10 %.
        let mut other = b.clone();
        other.bed_hashes = (0..5).map(|k| format!("c{k}")).collect();
        let k = evaluate("v", &claim, &cases(vec![a.clone(), other]), "native");
        assert_eq!(k.status, Status::Inconclusive, "{k:?}");
        assert!(k.detail.contains("beds would decide"), "{}", k.detail);
        // A 30 % effect on the same beds fails, even among three pairs (Bonferroni).
        let c = summary(39.0, &[32.5, 39.0, 45.5, 36.4, 41.6], 1.0);
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
    fn ratio_reads_p_of_every_bed_at_the_registered_depth() {
        let claim = SweepClaim::RatioAtLeast {
            quantity: Quantity::P,
            ratio: 10.0,
            at_h: Some(2.0),
        };
        let c = cases(vec![
            summary(3.0, &[3.0, 3.1, 2.9], 1.0),
            summary(40.0, &[40.0, 41.0, 39.0], 11.0),
        ]);
        let k = evaluate("f", &claim, &c, "native");
        assert_eq!(k.status, Status::Pass, "{k:?}");
        assert!((k.value - 11f64.ln()).abs() < 0.02, "{k:?}");
        let c = cases(vec![
            summary(3.0, &[3.0, 3.1, 2.9], 1.0),
            summary(40.0, &[40.0, 41.0, 39.0], 9.0),
        ]);
        assert_eq!(evaluate("f", &claim, &c, "native").status, Status::Fail);
        // One bed per case: no bed-to-bed variance, never resolved.
        let one = cases(vec![
            summary(3.0, &[3.0], 1.0),
            summary(40.0, &[40.0], 11.0),
        ]);
        assert_eq!(
            evaluate("f", &claim, &one, "native").status,
            Status::Inconclusive
        );
        let far = SweepClaim::RatioAtLeast {
            quantity: Quantity::P,
            ratio: 10.0,
            at_h: Some(9.0),
        };
        let e = evaluate("f", &far, &c, "native");
        assert_eq!(e.status, Status::Error);
    }
}
