//! A seed ensemble along a sweep (Kondic et al.'s claims on several beds, `[bed] seeds`
//! of an impact2d case): per swept value the mean of a quantity over the seeds and its
//! standard error, and the `increasing` rule on the per-seed differences (docs/impact2d.md, "Seed
//! ensembles", registered before any ensemble run). Plain numbers in, plain numbers out:
//! the impact2d checks and the report's error-bar figure both read these.

use super::{Comparison, Rule};
use crate::analysis::stress_fields::mean_std;
use crate::numerics::stats::Estimate;

/// One swept value of an ensemble: the quantity on each seed's bed, its mean and its
/// standard error SE = sample sd (n - 1) / sqrt(n).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub(crate) struct ValueStats {
    /// The value's label without the seed (e.g. `speed=0.7`).
    pub value: String,
    /// The swept value as a number.
    pub x: f64,
    pub mean: f64,
    pub se: f64,
    /// (seed, value) in the case's seed order.
    pub seeds: Vec<(u64, f64)>,
}

impl ValueStats {
    /// Mean and SE of the seeds' values (SE NaN with fewer than 2 seeds: no scatter is
    /// known, so no rule on it can pass).
    pub fn new(value: impl Into<String>, x: f64, seeds: Vec<(u64, f64)>) -> ValueStats {
        let v: Vec<f64> = seeds.iter().map(|s| s.1).collect();
        let (mean, sd) = mean_std(&v);
        let se = if v.len() >= 2 {
            sd / (v.len() as f64).sqrt()
        } else {
            f64::NAN
        };
        ValueStats {
            value: value.into(),
            x,
            mean,
            se,
            seeds,
        }
    }

    /// `speed=0.7: 10.21 +- 0.31 (seed 1: 10.02, seed 2: ...)`.
    pub(crate) fn describe(&self) -> String {
        format!(
            "{}: {:.3} +- {:.3} ({})",
            self.value,
            self.mean,
            self.se,
            self.seeds
                .iter()
                .map(|(s, y)| format!("seed {s}: {y:.3}"))
                .collect::<Vec<_>>()
                .join(", ")
        )
    }
}

/// The `increasing` rule on a seed ensemble (docs/statistics.md, "Rises"): one
/// comparison per step of the sweep, the per-seed differences of the later value minus
/// the earlier one (the seeds are the same beds at every value, so the bed-to-bed
/// scatter cancels in the pair), a one-sided test that the rise exceeds `min_step`, its
/// failure decided at the Bonferroni level of all the steps. A step with fewer than two
/// seeds in common has no estimate and stays INCONCLUSIVE.
pub(crate) fn increasing(stats: &[ValueStats], min_step: f64) -> Vec<Comparison> {
    let m = stats.len().saturating_sub(1);
    stats
        .windows(2)
        .map(|w| {
            let (a, b): (Vec<f64>, Vec<f64>) = w[1]
                .seeds
                .iter()
                .filter_map(|(seed, y)| {
                    w[0].seeds
                        .iter()
                        .find(|(s0, _)| s0 == seed)
                        .map(|(_, y0)| (*y0, *y))
                })
                .unzip();
            Comparison {
                what: format!("{} -> {}, per seed", w[0].value, w[1].value),
                estimate: Estimate::paired(&b, &a),
                rule: Rule::Exceeds { delta: min_step },
                m,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, ys: &[f64]) -> ValueStats {
        ValueStats::new(
            format!("x={x}"),
            x,
            ys.iter()
                .enumerate()
                .map(|(k, y)| (k as u64 + 1, *y))
                .collect(),
        )
    }

    #[test]
    fn mean_and_standard_error_over_seeds() {
        let s = v(0.0, &[1.0, 2.0, 3.0, 4.0, 5.0]);
        assert_eq!(s.mean, 3.0);
        // sd = sqrt(10 / 4), SE = sd / sqrt(5) = sqrt(0.5).
        assert!((s.se - 0.5f64.sqrt()).abs() < 1e-15);
        assert!(s.describe().contains("x=0: 3.000 +- 0.707 (seed 1: 1.000"));
        assert!(v(0.0, &[1.0]).se.is_nan());
    }

    #[test]
    fn increasing_is_a_paired_one_sided_test_per_step() {
        use crate::compare::Check;
        use crate::compare::{Gate, Status};
        let decide = |stats: &[ValueStats], min_step: f64| {
            Check::decided("c", Gate::Claim, "m", &increasing(stats, min_step), "").status
        };
        let shifted =
            |a: &ValueStats, d: f64| v(1.0, &a.seeds.iter().map(|s| s.1 + d).collect::<Vec<_>>());
        // Seeds with a large bed-to-bed scatter, each moved by the same 0.6: the pairs
        // resolve the rise beyond min_step 0.5 although the means' SEs (0.71) do not.
        let n = v(0.0, &[0.0, 2.0, 1.0, -1.0, 3.0]);
        let mut moved = shifted(&n, 0.6);
        moved.seeds[0].1 += 0.01;
        assert_eq!(decide(&[n.clone(), moved], 0.5), Status::Pass);
        // Moved by 0.3 +- 0.01: a resolved shortfall below min_step fails.
        let mut short = shifted(&n, 0.3);
        short.seeds[1].1 -= 0.01;
        assert_eq!(decide(&[n.clone(), short], 0.5), Status::Fail);
        // Per-seed changes of +2, -1, +1, 0, +1.5: mean 0.7 with sd 1.2: undecided.
        let m = v(
            1.0,
            &n.seeds
                .iter()
                .zip([2.0, -1.0, 1.0, 0.0, 1.5])
                .map(|(s, d)| s.1 + d)
                .collect::<Vec<_>>(),
        );
        assert_eq!(decide(&[n.clone(), m], 0.5), Status::Inconclusive);
        // Every step counts: a flat step (the same runs) fails the claim.
        assert_eq!(decide(&[n.clone(), n.clone()], 0.0), Status::Fail);
        // A value with one seed: no estimate, never a pass.
        assert_eq!(decide(&[n, v(1.0, &[9.0])], 0.0), Status::Inconclusive);
    }
}
