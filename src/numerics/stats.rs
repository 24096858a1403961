//! The decision statistics of docs/statistics.md: intervals over beds from Student's t
//! (one sample, paired, Welch), the least-squares slope, the two one-sided tests of
//! equivalence, one-sided minimum-effect tests, their combination over several
//! comparisons (intersection-union for a pass, Bonferroni for a failure), and the bed
//! counts that would decide a comparison. Quantiles come from `statrs`, never a table.
//!
//! Everything here is about numbers; what a verdict means for a check (its name, its gate,
//! its report line) is `compare`'s business.

use statrs::distribution::{ContinuousCDF, FisherSnedecor, StudentsT};

/// The level of every test, per side (docs/statistics.md, "Level").
pub(crate) const ALPHA: f64 = 0.05;
/// The power of every planning statement.
#[cfg(test)]
pub(crate) const POWER: f64 = 0.80;
/// The largest bed count a planning statement reports; beyond it the answer is "more
/// than this", which at these scales means "not decidable by adding beds".
pub(crate) const MAX_BEDS: usize = 10_000;

/// The quantile of Student's t with `df` degrees of freedom at probability `p`.
/// NaN for df <= 0 or p outside (0, 1).
pub(crate) fn t_quantile(p: f64, df: f64) -> f64 {
    if !(df > 0.0 && p > 0.0 && p < 1.0) {
        return f64::NAN;
    }
    match StudentsT::new(0.0, 1.0, df) {
        Ok(t) => t.inverse_cdf(p),
        Err(_) => f64::NAN,
    }
}

/// The upper-tail p value of Fisher's F with (d1, d2) degrees of freedom at `f`.
pub(crate) fn f_upper_p(f: f64, d1: f64, d2: f64) -> f64 {
    match FisherSnedecor::new(d1, d2) {
        Ok(d) if f.is_finite() && f >= 0.0 => 1.0 - d.cdf(f),
        _ => f64::NAN,
    }
}

/// sqrt(mean x^2) and its degrees of freedom (the number of values): the spread of
/// values whose expected mean is zero, such as the log ratios of two runs of the same
/// physics (the chaos baseline of docs/statistics.md). NaN and 0 for no values.
pub(crate) fn root_mean_square(x: &[f64]) -> (f64, usize) {
    if x.is_empty() {
        return (f64::NAN, 0);
    }
    (
        (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt(),
        x.len(),
    )
}

/// An estimate over beds: its value, standard error, degrees of freedom, the number of
/// beds it rests on and the per-bed standard deviation the planning numbers use.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    pub value: f64,
    pub se: f64,
    pub df: f64,
    /// Beds (for a two-sample estimate, the smaller of the two counts).
    pub n: usize,
    /// Per-bed standard deviation (pooled for two samples).
    pub sd: f64,
}

fn mean_sd(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1.0);
    (m, var.sqrt())
}

impl Estimate {
    /// The mean of `x` (one sample, or paired differences): SE = sd / sqrt(n), n - 1
    /// degrees of freedom. None with fewer than two values or a non-finite one.
    pub fn mean(x: &[f64]) -> Option<Estimate> {
        if x.len() < 2 || x.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let (m, sd) = mean_sd(x);
        Some(Estimate {
            value: m,
            se: sd / (x.len() as f64).sqrt(),
            df: (x.len() - 1) as f64,
            n: x.len(),
            sd,
        })
    }

    /// The mean of the paired differences a_k - b_k.
    pub(crate) fn paired(a: &[f64], b: &[f64]) -> Option<Estimate> {
        if a.len() != b.len() {
            return None;
        }
        let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
        Estimate::mean(&d)
    }

    /// mean(a) - mean(b) of two independent samples: Welch's standard error and the
    /// Welch-Satterthwaite degrees of freedom (Welch 1947).
    pub(crate) fn welch(a: &[f64], b: &[f64]) -> Option<Estimate> {
        if a.len() < 2 || b.len() < 2 || a.iter().chain(b).any(|v| !v.is_finite()) {
            return None;
        }
        let (ma, sa) = mean_sd(a);
        let (mb, sb) = mean_sd(b);
        let (na, nb) = (a.len() as f64, b.len() as f64);
        let (va, vb) = (sa * sa / na, sb * sb / nb);
        let se = (va + vb).sqrt();
        let df = if va + vb > 0.0 {
            (va + vb).powi(2) / (va * va / (na - 1.0) + vb * vb / (nb - 1.0))
        } else {
            na + nb - 2.0
        };
        let pooled = (((na - 1.0) * sa * sa + (nb - 1.0) * sb * sb) / (na + nb - 2.0)).sqrt();
        Some(Estimate {
            value: ma - mb,
            se,
            df,
            n: a.len().min(b.len()),
            sd: pooled,
        })
    }

    /// The ordinary least-squares slope of y on x with its standard error and N - 2
    /// degrees of freedom (NIST e-Handbook 4.4.4.4). None with fewer than three points or
    /// no spread in x.
    ///
    /// y is taken relative to its first value (the slope and its SE do not depend on the
    /// shift): values that are all equal then give a slope and an SE of exactly 0, not
    /// the round-off of their mean, so a flat sweep (the same run at every value) is a
    /// zero slope with no scatter and fails a strict "exceeds 0" (docs/statistics.md,
    /// "Decision rules").
    pub(crate) fn slope(x: &[f64], y: &[f64]) -> Option<Estimate> {
        let n = x.len();
        if n < 3 || y.len() != n || x.iter().chain(y).any(|v| !v.is_finite()) {
            return None;
        }
        let y0 = y[0];
        let y: Vec<f64> = y.iter().map(|v| v - y0).collect();
        let y = y.as_slice();
        let nf = n as f64;
        let mx = x.iter().sum::<f64>() / nf;
        let my = y.iter().sum::<f64>() / nf;
        let sxx: f64 = x.iter().map(|v| (v - mx).powi(2)).sum();
        if sxx <= 0.0 {
            return None;
        }
        let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
        let b = sxy / sxx;
        let a = my - b * mx;
        let ssr: f64 = x.iter().zip(y).map(|(u, v)| (v - a - b * u).powi(2)).sum();
        let s = (ssr / (nf - 2.0)).sqrt();
        Some(Estimate {
            value: b,
            se: s / sxx.sqrt(),
            df: nf - 2.0,
            n,
            sd: s,
        })
    }

    /// The two-sided interval at `level` (e.g. 0.90): value +- t((1 + level)/2; df) SE.
    pub(crate) fn interval(&self, level: f64) -> (f64, f64) {
        let t = t_quantile(0.5 + level / 2.0, self.df);
        (self.value - t * self.se, self.value + t * self.se)
    }

    /// The decision interval of every gated comparison, two-sided 1 - 2 alpha (90 %).
    pub(crate) fn decision_interval(&self) -> (f64, f64) {
        self.interval(1.0 - 2.0 * ALPHA)
    }

    /// The interval a failure among `m` comparisons is decided on: 1 - 2 alpha / m
    /// (Bonferroni), equal to the decision interval for m = 1.
    pub(crate) fn failure_interval(&self, m: usize) -> (f64, f64) {
        self.interval(1.0 - 2.0 * ALPHA / m.max(1) as f64)
    }
}

/// What a comparison decides.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    Pass,
    Fail,
    Inconclusive,
}

/// Equivalence by two one-sided tests (Schuirmann 1987) with margin +-`margin`: PASS when
/// the decision interval lies inside (-margin, margin), FAIL when the failure interval
/// (Bonferroni over `m` comparisons) lies wholly outside it, otherwise INCONCLUSIVE.
pub(crate) fn equivalence(e: &Estimate, margin: f64, m: usize) -> Decision {
    let (l, u) = e.decision_interval();
    if !(l.is_finite() && u.is_finite() && margin.is_finite()) {
        return Decision::Inconclusive;
    }
    if -margin < l && u < margin {
        return Decision::Pass;
    }
    let (fl, fu) = e.failure_interval(m);
    if fl > margin || fu < -margin {
        Decision::Fail
    } else {
        Decision::Inconclusive
    }
}

/// A one-sided test that the effect exceeds `delta`: PASS when the decision interval's
/// lower end is above delta, FAIL when the failure interval's upper end (Bonferroni over
/// `m` comparisons) is not above it, otherwise INCONCLUSIVE. "Exceeds" is strict: an
/// effect of exactly delta with no scatter (the same runs twice) fails.
pub(crate) fn exceeds(e: &Estimate, delta: f64, m: usize) -> Decision {
    let (l, _) = e.decision_interval();
    let (_, fu) = e.failure_interval(m);
    if !(l.is_finite() && fu.is_finite() && delta.is_finite()) {
        return Decision::Inconclusive;
    }
    if l > delta {
        Decision::Pass
    } else if fu <= delta {
        Decision::Fail
    } else {
        Decision::Inconclusive
    }
}

/// A claim made of several comparisons that must all hold: PASS when every one passes
/// (intersection-union, Berger 1982), FAIL when any fails (each decided at its
/// Bonferroni level already), otherwise INCONCLUSIVE. An empty list is INCONCLUSIVE.
pub(crate) fn all_of(parts: &[Decision]) -> Decision {
    if parts.is_empty() {
        Decision::Inconclusive
    } else if parts.contains(&Decision::Fail) {
        Decision::Fail
    } else if parts.iter().all(|d| *d == Decision::Pass) {
        Decision::Pass
    } else {
        Decision::Inconclusive
    }
}

fn smallest_n(ok: impl Fn(usize) -> bool) -> Option<usize> {
    (2..=MAX_BEDS).find(|&n| ok(n))
}

/// Beds that would decide an equivalence at per-bed sd `sd` if the difference stayed at
/// `d`: the smallest n with t(1 - alpha; n - 1) sd / sqrt(n) < margin - |d|. None when
/// |d| >= margin (more beds would not pass it) or beyond [`MAX_BEDS`].
pub(crate) fn beds_to_pass_equivalence(sd: f64, d: f64, margin: f64) -> Option<usize> {
    let room = margin - d.abs();
    if !(room > 0.0 && sd.is_finite()) {
        return None;
    }
    smallest_n(|n| t_quantile(1.0 - ALPHA, (n - 1) as f64) * sd / (n as f64).sqrt() < room)
}

/// Beds that would resolve a one-sided test whose effect stays at distance `gap` from
/// its threshold: the smallest n with t(1 - alpha; n - 1) sd / sqrt(n) < |gap|.
pub(crate) fn beds_to_resolve(sd: f64, gap: f64) -> Option<usize> {
    if !(gap.abs() > 0.0 && sd.is_finite()) {
        return None;
    }
    smallest_n(|n| t_quantile(1.0 - ALPHA, (n - 1) as f64) * sd / (n as f64).sqrt() < gap.abs())
}

/// The bed count that passes an equivalence with margin `margin` with 80 % power when the
/// true difference is zero (Chow, Shao and Wang 2008, Sec. 3.2.3, t quantiles iterated in
/// n): the smallest n with (t(1 - alpha; n - 1) + t(1 - beta/2; n - 1)) sd / sqrt(n) <=
/// margin.
#[cfg(test)]
pub(crate) fn beds_for_equivalence_power(sd: f64, margin: f64) -> Option<usize> {
    if !(sd.is_finite() && margin > 0.0) {
        return None;
    }
    let beta = 1.0 - POWER;
    smallest_n(|n| {
        let df = (n - 1) as f64;
        (t_quantile(1.0 - ALPHA, df) + t_quantile(1.0 - beta / 2.0, df)) * sd / (n as f64).sqrt()
            <= margin
    })
}

/// The minimal detectable effect of a one-sided test at alpha with 80 % power on `n` beds
/// of per-bed sd `sd`: (t(1 - alpha; n - 1) + t(1 - beta; n - 1)) sd / sqrt(n).
#[cfg(test)]
pub(crate) fn minimal_detectable_effect(sd: f64, n: usize) -> f64 {
    if n < 2 {
        return f64::INFINITY;
    }
    let df = (n - 1) as f64;
    (t_quantile(1.0 - ALPHA, df) + t_quantile(POWER, df)) * sd / (n as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// Quantiles against the printed tables (NIST e-Handbook 1.3.6.7.2).
    #[test]
    fn t_quantiles_match_the_tables() {
        assert_relative_eq!(t_quantile(0.975, 2.0), 4.303, epsilon = 1e-3);
        assert_relative_eq!(t_quantile(0.975, 4.0), 2.776, epsilon = 1e-3);
        assert_relative_eq!(t_quantile(0.95, 1.0), 6.314, epsilon = 1e-3);
        assert_relative_eq!(t_quantile(0.95, 10.0), 1.812, epsilon = 1e-3);
        assert!(t_quantile(0.95, 0.0).is_nan());
    }

    #[test]
    fn one_sample_and_paired_intervals() {
        let e = Estimate::mean(&[1.0, 2.0, 3.0]).unwrap();
        assert_relative_eq!(e.value, 2.0);
        assert_relative_eq!(e.se, 1.0 / 3f64.sqrt(), epsilon = 1e-15);
        assert_eq!(e.df, 2.0);
        let (l, u) = e.interval(0.95);
        assert_relative_eq!(u - 2.0, 4.303 / 3f64.sqrt(), epsilon = 1e-3);
        assert_relative_eq!(2.0 - l, u - 2.0, epsilon = 1e-12);
        let p = Estimate::paired(&[2.0, 3.0, 4.0], &[1.0, 1.0, 1.0]).unwrap();
        assert_eq!(p, e);
        assert!(Estimate::mean(&[1.0]).is_none());
        assert!(Estimate::mean(&[1.0, f64::NAN]).is_none());
    }

    /// Welch's test on the textbook example of equal variances reduces to the pooled one.
    #[test]
    fn welch_degrees_of_freedom() {
        let a = [1.0, 2.0, 3.0, 4.0];
        let b = [2.0, 3.0, 4.0, 5.0];
        let e = Estimate::welch(&a, &b).unwrap();
        assert_relative_eq!(e.value, -1.0);
        assert_relative_eq!(e.df, 6.0, epsilon = 1e-12);
        // Unequal variances: fewer degrees of freedom than pooled.
        let c = [10.0, 20.0, 30.0, 40.0];
        assert!(Estimate::welch(&a, &c).unwrap().df < 6.0);
    }

    #[test]
    fn least_squares_slope() {
        let x = [0.0, 1.0, 2.0, 3.0];
        let y = [1.0, 3.0, 5.0, 7.0];
        let e = Estimate::slope(&x, &y).unwrap();
        assert_relative_eq!(e.value, 2.0, epsilon = 1e-14);
        assert!(e.se < 1e-12);
        assert_eq!(e.df, 2.0);
        assert!(Estimate::slope(&[1.0, 1.0, 1.0], &y[..3]).is_none());
    }

    /// A flat sweep (the same run at every value, as a "sweep ignored" control makes it)
    /// is a slope of exactly 0 with no scatter, and a strict "exceeds 0" fails it. The
    /// depth 0.1 is one whose mean of three copies is not 0.1 in floating point
    /// ((0.1 + 0.1 + 0.1) / 3 = 0.10000000000000002), which is what used to give a
    /// round-off slope and an INCONCLUSIVE flat sweep.
    #[test]
    fn a_flat_sweep_has_slope_exactly_zero_and_fails_exceeds_zero() {
        let y = 0.1_f64;
        assert_ne!((y + y + y) / 3.0, y, "the test needs a mean that rounds");
        let x = [0.4, 0.7, 1.0];
        let slopes: Vec<f64> = [0.1, 7.745646630997781, 11.23, 13.9, 9.7]
            .iter()
            .map(|&d| {
                let e = Estimate::slope(&x, &[d, d, d]).unwrap();
                assert_eq!((e.value, e.se), (0.0, 0.0), "depth {d}");
                e.value
            })
            .collect();
        let mean = Estimate::mean(&slopes).unwrap();
        assert_eq!((mean.value, mean.sd), (0.0, 0.0));
        assert_eq!(exceeds(&mean, 0.0, 1), Decision::Fail);
        // The same seeds with a real rise of 0.3 per unit pass; with one of 0 +- scatter
        // they stay undecided.
        let rising: Vec<f64> = [0.1, 7.7, 11.2]
            .iter()
            .map(|&d| Estimate::slope(&x, &[d, d + 0.09, d + 0.18]).unwrap().value)
            .collect();
        assert_relative_eq!(rising[1], 0.3, epsilon = 1e-12);
        assert_eq!(
            exceeds(&Estimate::mean(&rising).unwrap(), 0.0, 1),
            Decision::Pass
        );
        let scattered = Estimate::mean(&[0.2, -0.1, -0.05]).unwrap();
        assert_eq!(exceeds(&scattered, 0.0, 1), Decision::Inconclusive);
    }

    fn est(value: f64, se: f64, n: usize) -> Estimate {
        Estimate {
            value,
            se,
            df: (n - 1) as f64,
            n,
            sd: se * (n as f64).sqrt(),
        }
    }

    /// Synthetic ensembles with known answers (docs/statistics.md's rules).
    #[test]
    fn equivalence_passes_fails_and_stays_inconclusive() {
        // Tight around zero: inside a 10 % margin.
        assert_eq!(equivalence(&est(0.01, 0.01, 10), 0.10, 1), Decision::Pass);
        // Far outside: resolved failure.
        assert_eq!(equivalence(&est(0.40, 0.02, 10), 0.10, 1), Decision::Fail);
        // The old rule's blind spot: point estimate inside, interval crossing the margin.
        assert_eq!(
            equivalence(&est(0.05, 0.04, 5), 0.10, 1),
            Decision::Inconclusive
        );
        // A true difference at the margin is not a pass even when precisely measured.
        assert_eq!(
            equivalence(&est(0.10, 0.001, 30), 0.10, 1),
            Decision::Inconclusive
        );
        // Bonferroni: a failure barely resolved for one comparison is not for six.
        let e = est(0.20, 0.04, 5);
        assert_eq!(equivalence(&e, 0.10, 1), Decision::Fail);
        assert_eq!(equivalence(&e, 0.10, 6), Decision::Inconclusive);
    }

    #[test]
    fn one_sided_minimum_effects() {
        assert_eq!(exceeds(&est(1.0, 0.1, 5), 0.0, 1), Decision::Pass);
        assert_eq!(exceeds(&est(-1.0, 0.1, 5), 0.0, 1), Decision::Fail);
        assert_eq!(exceeds(&est(0.1, 0.1, 5), 0.0, 1), Decision::Inconclusive);
        // A rise that is real but smaller than the registered minimum fails.
        assert_eq!(exceeds(&est(0.3, 0.05, 10), 1.0, 1), Decision::Fail);
        // No rise at all, without scatter: a failure, not an undecided zero.
        assert_eq!(exceeds(&est(0.0, 0.0, 3), 0.0, 2), Decision::Fail);
    }

    #[test]
    fn several_comparisons_combine() {
        use Decision::*;
        assert_eq!(all_of(&[Pass, Pass]), Pass);
        assert_eq!(all_of(&[Pass, Inconclusive]), Inconclusive);
        assert_eq!(all_of(&[Inconclusive, Fail]), Fail);
        assert_eq!(all_of(&[]), Inconclusive);
    }

    #[test]
    fn bed_counts_that_would_decide() {
        // sd 0.15 per bed, 10 % margin, no true difference: the power rule wants tens.
        let n = beds_for_equivalence_power(0.15, 0.10).unwrap();
        assert!((20..=40).contains(&n), "{n}");
        // With that n the rule holds and one fewer does not.
        let ok = |n: usize| {
            let df = (n - 1) as f64;
            (t_quantile(0.95, df) + t_quantile(0.90, df)) * 0.15 / (n as f64).sqrt() <= 0.10
        };
        assert!(ok(n) && !ok(n - 1));
        assert_eq!(beds_to_pass_equivalence(0.15, 0.12, 0.10), None);
        let m = beds_to_pass_equivalence(0.15, 0.05, 0.10).unwrap();
        assert!(t_quantile(0.95, (m - 1) as f64) * 0.15 / (m as f64).sqrt() < 0.05);
        assert!(beds_to_resolve(0.1, 0.5).unwrap() <= 3);
        assert!(minimal_detectable_effect(0.15, 5) > minimal_detectable_effect(0.15, 20));
        assert!(minimal_detectable_effect(0.15, 1).is_infinite());
    }

    #[test]
    fn root_mean_square_has_as_many_degrees_of_freedom_as_values() {
        let (s, n) = root_mean_square(&[0.1, -0.1, 0.2, -0.2]);
        assert!((s - 0.025f64.sqrt()).abs() < 1e-15);
        assert_eq!(n, 4);
        assert!(root_mean_square(&[]).0.is_nan());
    }

    #[test]
    fn fisher_upper_tail() {
        // F(1, 10) at its 95 % quantile 4.965 (NIST table 1.3.6.7.3).
        assert_relative_eq!(f_upper_p(4.965, 1.0, 10.0), 0.05, epsilon = 1e-3);
    }
}
