//! Engine agreement against chaos (docs/statistics.md, "The chaos baseline"): for a
//! family of cases, the per-bed log ratios native / reference of every recorded bed pair
//! against the per-bed log ratios of two native runs of one bed that differ by one ulp.
//! Plain numbers in, plain numbers out; the suite report prints them.

use crate::numerics::stats::{Estimate, f_upper_p};
use serde::Serialize;

/// One family's engine differences beside its chaos spread.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub(crate) struct FamilyAgreement {
    pub family: String,
    /// Bed pairs native / reference.
    pub n_pairs: usize,
    /// Mean of ln(K_native / K_reference) over the pairs, its 95 % interval and the
    /// per-bed sd.
    pub mean_log: f64,
    pub interval95: (f64, f64),
    pub sd_engines: f64,
    /// The chaos spread s_c of one engine against itself, and its degrees of freedom.
    pub chaos_sd: f64,
    pub chaos_df: usize,
    /// F = sd_engines^2 / s_c^2 and its upper-tail p value (n_pairs - 1, chaos_df).
    pub f_ratio: f64,
    pub f_p: f64,
    /// mean_log / (s_c / sqrt(n_pairs)).
    pub z_chaos: f64,
    /// "consistent with chaos", or which test says otherwise.
    pub verdict: String,
}

/// The family's verdict from its engine log ratios and its chaos log ratios.
pub(crate) fn family_agreement(
    family: &str,
    engine_logs: &[f64],
    chaos_logs: &[f64],
) -> FamilyAgreement {
    let (chaos_sd, chaos_df) = crate::numerics::stats::root_mean_square(chaos_logs);
    let e = Estimate::mean(engine_logs);
    let n = engine_logs.len();
    let (mean_log, interval95, sd) = match &e {
        Some(e) => (e.value, e.interval(0.95), e.sd),
        None => (
            engine_logs.first().copied().unwrap_or(f64::NAN),
            (f64::NAN, f64::NAN),
            f64::NAN,
        ),
    };
    let f_ratio = (sd / chaos_sd).powi(2);
    let f_p = if n >= 2 && chaos_df >= 1 {
        f_upper_p(f_ratio, (n - 1) as f64, chaos_df as f64)
    } else {
        f64::NAN
    };
    let z_chaos = mean_log / (chaos_sd / (n as f64).sqrt());
    let alpha = crate::numerics::stats::ALPHA;
    let mut why = Vec::new();
    if !(interval95.0.is_finite() && f_p.is_finite()) {
        why.push("too few bed pairs or chaos replicas to say".to_string());
    } else {
        if interval95.0 > 0.0 || interval95.1 < 0.0 {
            why.push(format!(
                "a systematic engine difference: the 95 % interval of the mean ln ratio, [{:+.4}, {:+.4}], excludes zero",
                interval95.0, interval95.1
            ));
        }
        if f_p < alpha {
            why.push(format!(
                "per-bed engine scatter beyond chaos: F = {f_ratio:.2}, p = {f_p:.3}"
            ));
        }
    }
    FamilyAgreement {
        family: family.to_string(),
        n_pairs: n,
        mean_log,
        interval95,
        sd_engines: sd,
        chaos_sd,
        chaos_df,
        f_ratio,
        f_p,
        z_chaos,
        verdict: if why.is_empty() {
            "consistent with chaos".into()
        } else {
            why.join("; ")
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Known answers: engine differences drawn like the chaos replicas are consistent;
    /// an offset of 15 % with chaos-sized scatter is systematic; a scatter three times
    /// chaos is flagged by F.
    #[test]
    fn engines_are_judged_against_the_chaos_spread() {
        let chaos = [0.05, -0.04, 0.06, -0.05, 0.03, -0.06, 0.04, -0.03];
        let same = [0.04, -0.05, 0.02, -0.03, 0.05, -0.02];
        let a = family_agreement("f", &same, &chaos);
        assert_eq!(a.verdict, "consistent with chaos", "{a:?}");
        let offset: Vec<f64> = same.iter().map(|x| x - 0.15).collect();
        let b = family_agreement("f", &offset, &chaos);
        assert!(b.verdict.contains("systematic"), "{b:?}");
        assert!(b.z_chaos < -5.0);
        let wide: Vec<f64> = same.iter().map(|x| 4.0 * x).collect();
        let c = family_agreement("f", &wide, &chaos);
        assert!(c.verdict.contains("beyond chaos"), "{c:?}");
        let d = family_agreement("f", &[0.1], &chaos);
        assert!(d.verdict.contains("too few"), "{d:?}");
    }
}
