//! A seed ensemble along a sweep (Kondic et al.'s claims on several beds, `[bed] seeds`
//! of an impact2d case): per swept value the mean of a quantity over the seeds and its
//! standard error, and the `increasing` rule on those means (docs/impact2d.md, "Seed
//! ensembles", registered before any ensemble run). Plain numbers in, plain numbers out:
//! the impact2d checks and the report's error-bar figure both read these.

use crate::analysis::stress_fields::mean_std;

/// One swept value of an ensemble: the quantity on each seed's bed, its mean and its
/// standard error SE = sample sd (n - 1) / sqrt(n).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ValueStats {
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
    pub fn describe(&self) -> String {
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

/// One step of the `increasing` rule: the rise of the means and what it needed,
/// max(min_step, 2 SE_c) with SE_c = sqrt(SE_k^2 + SE_k+1^2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    pub rise: f64,
    pub combined_se: f64,
    pub needed: f64,
}

/// The `increasing` rule on a seed ensemble: each step of the means must rise by at
/// least max(`min_step`, 2 combined SE). Returns max over steps of (needed - rise),
/// which is <= 0 iff the claim holds (NaN, never passing, if a mean or SE is not
/// finite), and the steps.
pub fn increasing(stats: &[ValueStats], min_step: f64) -> (f64, Vec<Step>) {
    let steps: Vec<Step> = stats
        .windows(2)
        .map(|w| {
            let combined_se = w[0].se.hypot(w[1].se);
            Step {
                rise: w[1].mean - w[0].mean,
                combined_se,
                needed: min_step.max(2.0 * combined_se),
            }
        })
        .collect();
    let mut worst = f64::NEG_INFINITY;
    for s in &steps {
        let short = s.needed - s.rise;
        if !(short.is_finite() && s.combined_se.is_finite()) {
            return (f64::NAN, steps);
        }
        worst = worst.max(short);
    }
    (worst, steps)
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
    fn increasing_needs_the_larger_of_min_step_and_two_combined_se() {
        let shifted =
            |a: &ValueStats, d: f64| v(1.0, &a.seeds.iter().map(|s| s.1 + d).collect::<Vec<_>>());
        // Quiet seeds: SE = sqrt(0.025 / 5) = 0.0707 per value, 2 SE_c = 0.2 < min_step
        // 0.5, so 0.5 is needed: a rise of 0.6 passes, 0.4 fails (below min_step).
        let a = v(0.0, &[1.0, 1.2, 1.1, 0.9, 1.3]);
        let (w, steps) = increasing(&[a.clone(), shifted(&a, 0.6)], 0.5);
        assert!(
            (steps[0].combined_se - 0.2 / 2.0).abs() < 1e-12,
            "{steps:?}"
        );
        assert_eq!(steps[0].needed, 0.5);
        assert!((w + 0.1).abs() < 1e-12, "{w}");
        assert!(increasing(&[a.clone(), shifted(&a, 0.4)], 0.5).0 > 0.0);
        // Noisy seeds: SE = 0.707 per value, 2 SE_c = 2.0 > min_step: a rise of 1.5 is
        // within the noise and fails, 2.5 passes.
        let n = v(0.0, &[0.0, 2.0, 1.0, -1.0, 3.0]);
        let (w, steps) = increasing(&[n.clone(), shifted(&n, 1.5)], 0.5);
        assert!((steps[0].needed - 2.0).abs() < 1e-12, "{steps:?}");
        assert!((w - 0.5).abs() < 1e-12, "{w}");
        assert!(increasing(&[n.clone(), shifted(&n, 2.5)], 0.5).0 <= 0.0);
        // Every step counts: the worst one decides.
        let three = [a.clone(), shifted(&a, 0.6), shifted(&a, 0.9)];
        assert!((increasing(&three, 0.5).0 - 0.2).abs() < 1e-12);
        // A value with one seed has no SE: never a pass.
        assert!(increasing(&[a, v(1.0, &[9.0])], 0.0).0.is_nan());
    }
}
