//! Observables of an impact run (K Sec. III), pure functions of what either engine
//! wrote: the intruder's centre-of-mass samples and per-disk snapshots.
//!
//! - D(t): the intruder's lowest point below the initial bed surface at the impact
//!   point (K Sec. III), positive inside the bed: `D = surface - (y_cm - bottom_offset)`.
//! - final depth: the mean of D(t) over the last `final_window` of the run (K: "averaging
//!   D(t) at long times"; the window is a case-file field, stated in the report).
//! - force on the intruder: the sum of contact forces on it (gravity excluded).
//! - energies from snapshots: kinetic (translation + rotation, I = m r^2/2, mobile
//!   disks incl. the intruder), potential `sum m g y` relative to the first snapshot,
//!   elastic `sum k_n x^2 / 2` over touching pairs (normal springs only: the tangential
//!   spring length is history LAMMPS does not dump; wall-wall and intra-cluster pairs
//!   excluded).

pub use crate::rundata::impact::*;
use anyhow::{Result, bail};

/// Potential energies relative to the first sample.
pub(crate) fn relative_potential(e: &[EnergySample]) -> Vec<f64> {
    let p0 = e.first().map(|s| s.potential).unwrap_or(0.0);
    e.iter().map(|s| s.potential - p0).collect()
}

/// D(t) in m.
pub fn depth(samples: &[IntruderSample], surface: f64, bottom_offset: f64) -> Vec<(f64, f64)> {
    samples
        .iter()
        .map(|s| (s.t, surface - (s.x[1] - bottom_offset)))
        .collect()
}

/// Mean of D over `t >= t_end - window`.
/// Samples of D(t) in the final window of length `window`.
pub(crate) fn final_window_samples(d: &[(f64, f64)], window: f64) -> usize {
    let Some(&(t_end, _)) = d.last() else {
        return 0;
    };
    d.iter().filter(|(t, _)| *t >= t_end - window).count()
}

pub fn final_depth(d: &[(f64, f64)], window: f64) -> Result<f64> {
    let Some(&(t_end, _)) = d.last() else {
        bail!("no intruder samples");
    };
    let tail: Vec<f64> = d
        .iter()
        .filter(|(t, _)| *t >= t_end - window)
        .map(|p| p.1)
        .collect();
    if tail.len() < 2 {
        bail!("fewer than 2 samples in the final window of {window:.3e} s");
    }
    Ok(tail.iter().sum::<f64>() / tail.len() as f64)
}

/// RMS of `a - b` over the times both have (matched by time to 1e-9 relative).
pub fn rms_distance(a: &[(f64, f64)], b: &[(f64, f64)]) -> Result<f64> {
    let mut j = 0;
    let (mut s, mut n) = (0.0, 0usize);
    for &(t, da) in a {
        while j < b.len() && b[j].0 < t * (1.0 - 1e-9) - 1e-300 {
            j += 1;
        }
        if j < b.len() && (b[j].0 - t).abs() <= 1e-9 * t.abs().max(1e-12) {
            s += (da - b[j].1).powi(2);
            n += 1;
        }
    }
    if n < 2 {
        bail!("the two D(t) series share fewer than 2 sample times");
    }
    Ok((s / n as f64).sqrt())
}

/// The intruder's first passage through the depth bin `[y - half, y + half]` (K
/// Appendix, Fig 29: "we find a(u) for fixed y"), in the units of the series given.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub(crate) struct Passage {
    /// Bin centre (depth).
    pub y: f64,
    /// Mean speed through the bin: 2 half / (t_out - t_in).
    pub u: f64,
    /// Mean deceleration there: (w_in - w_out) / (t_out - t_in), w the downward speed;
    /// gravity included (the net acceleration of F = Mg + F_d + F_v, eq A1, sign-flipped).
    pub decel: f64,
}

/// First passages through bins centred at `centres` (half-width `half`) of the series
/// `(t, depth, downward speed)`: the first time the depth reaches each edge, by linear
/// interpolation between samples. A bin the run never leaves at the bottom gives none.
pub(crate) fn passages(series: &[(f64, f64, f64)], centres: &[f64], half: f64) -> Vec<Passage> {
    let reach = |level: f64| {
        series.windows(2).find_map(|w| {
            let ((t0, d0, w0), (t1, d1, w1)) = (w[0], w[1]);
            (d0 < level && d1 >= level).then(|| {
                let f = (level - d0) / (d1 - d0);
                (t0 + f * (t1 - t0), w0 + f * (w1 - w0))
            })
        })
    };
    centres
        .iter()
        .filter_map(|&y| {
            let (t_in, w_in) = reach(y - half)?;
            let (t_out, w_out) = reach(y + half)?;
            let dt = t_out - t_in;
            (dt > 0.0).then(|| Passage {
                y,
                u: 2.0 * half / dt,
                decel: (w_in - w_out) / dt,
            })
        })
        .collect()
}

/// Fit `decel = c u^k` by least squares of ln(decel) on ln(u) over the passages with
/// decel > 0: (k, c, R^2, points used).
pub(crate) fn power_law(p: &[Passage]) -> Result<(f64, f64, f64, usize)> {
    let (x, y): (Vec<f64>, Vec<f64>) = p
        .iter()
        .filter(|q| q.decel > 0.0 && q.u > 0.0)
        .map(|q| (q.u.ln(), q.decel.ln()))
        .unzip();
    let (ln_c, k, r2) = linear_r2(&x, &y)?;
    Ok((k, ln_c.exp(), r2, x.len()))
}

/// k of a ~ u^k at one depth on one bed (K Appendix: "find a(u) for fixed y"): the
/// least-squares slope of ln a on ln u over the first passages of the bed's runs through
/// the bin `y +- half` with a > 0, and the regression's own slope error (printed only:
/// it knows nothing of the next bed, docs/statistics.md "One bed").
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct DepthExponent {
    pub y: f64,
    pub k: f64,
    /// Standard error of the slope within this bed's regression.
    pub se_within: f64,
    /// The passages with a > 0 the slope rests on.
    pub used: Vec<Passage>,
    /// Runs that crossed the bin with a <= 0 (left out).
    pub dropped: usize,
}

/// [`DepthExponent`] of the runs `series` (one per impact speed, `(t, depth, downward
/// speed)`) at depth `y`; an error naming the count when fewer than `min_passages`
/// passages with a > 0 remain (at least 3: a slope with an error).
pub(crate) fn exponent_at_depth(
    series: &[&[(f64, f64, f64)]],
    y: f64,
    half: f64,
    min_passages: usize,
) -> std::result::Result<DepthExponent, String> {
    let all: Vec<Passage> = series
        .iter()
        .flat_map(|s| passages(s, &[y], half))
        .collect();
    let used: Vec<Passage> = all
        .iter()
        .copied()
        .filter(|q| q.decel > 0.0 && q.u > 0.0)
        .collect();
    let need = min_passages.max(3);
    if used.len() < need {
        return Err(format!(
            "{} passage(s) with a > 0 through {y} +- {half} d (of {} runs): at least {need} are needed",
            used.len(),
            series.len()
        ));
    }
    let x: Vec<f64> = used.iter().map(|q| q.u.ln()).collect();
    let l: Vec<f64> = used.iter().map(|q| q.decel.ln()).collect();
    let fit = crate::numerics::stats::Estimate::slope(&x, &l)
        .ok_or_else(|| format!("no slope through {y} +- {half} d: no spread in u"))?;
    Ok(DepthExponent {
        y,
        k: fit.value,
        se_within: fit.se,
        dropped: all.len() - used.len(),
        used,
    })
}

/// Test trajectory `(t, depth, downward speed)` of an intruder hitting at speed `v0`
/// (from depth -1) and slowed by a = c u^k inside the bed, explicit Euler with step `dt`.
#[cfg(test)]
pub(crate) fn power_law_trajectory(v0: f64, c: f64, k: f64, dt: f64) -> Vec<(f64, f64, f64)> {
    let (mut t, mut d, mut w) = (0.0, -1.0, v0);
    let mut s = vec![(t, d, w)];
    while w > 0.005 && t < 2000.0 {
        w -= if d > 0.0 { c * w.powf(k) * dt } else { 0.0 };
        d += w * dt;
        t += dt;
        s.push((t, d, w));
    }
    s
}

/// The force on the intruder during an impact (K Fig 21) from its samples `(t, F_y)`:
/// the first contact t_c (the first sample with a non-zero force), the force averaged
/// over bins of `bin` from t_c, the largest bin and how soon the bins fall below half of
/// it, and the impulse over `[t_c, t_c + window]`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub(crate) struct ForceSummary {
    pub t_contact: f64,
    /// Start of the largest bin.
    pub t_peak: f64,
    pub peak: f64,
    /// Time from the start of the largest bin to the start of the first later bin whose
    /// mean is below peak / 2 (None: never).
    pub half_after: Option<f64>,
    /// Trapezoid integral of F over `[t_c, t_c + window]`.
    pub impulse: f64,
    /// (bin start, bin mean) from t_c on.
    #[serde(skip)]
    pub bins: Vec<(f64, f64)>,
}

/// Summary of a force series `(t, F)` (sorted by t), or why there is none.
pub(crate) fn force_summary(series: &[(f64, f64)], bin: f64, window: f64) -> Result<ForceSummary> {
    let Some(c) = series.iter().position(|p| p.1 != 0.0) else {
        bail!("the intruder never touched anything (force zero at every sample)");
    };
    let t_c = series[c].0;
    let mut bins: Vec<(f64, f64)> = Vec::new();
    let (mut sum, mut n, mut k) = (0.0, 0usize, 0usize);
    for &(t, f) in &series[c..] {
        let b = ((t - t_c) / bin + 1e-9).floor() as usize;
        if b != k {
            if n > 0 {
                bins.push((t_c + k as f64 * bin, sum / n as f64));
            }
            (sum, n, k) = (0.0, 0, b);
        }
        sum += f;
        n += 1;
    }
    if n > 0
        && series
            .last()
            .is_some_and(|l| l.0 >= t_c + (k as f64 + 1.0) * bin - 1e-9 * bin)
    {
        bins.push((t_c + k as f64 * bin, sum / n as f64));
    }
    if bins.is_empty() {
        bail!("the run ends within one bin ({bin:e}) of the first contact");
    }
    let (ip, &(t_peak, peak)) = bins
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.1.total_cmp(&b.1.1))
        .expect("non-empty");
    let half_after = bins[ip..]
        .iter()
        .find(|b| b.1 < 0.5 * peak)
        .map(|b| b.0 - t_peak);
    let in_window: Vec<(f64, f64)> = series[c..]
        .iter()
        .copied()
        .filter(|p| p.0 <= t_c + window * (1.0 + 1e-12))
        .collect();
    let impulse = in_window
        .windows(2)
        .map(|w| 0.5 * (w[1].0 - w[0].0) * (w[0].1 + w[1].1))
        .sum();
    Ok(ForceSummary {
        t_contact: t_c,
        t_peak,
        peak,
        half_after,
        impulse,
        bins,
    })
}

/// RMS difference of two binned force series over the bins both have that start
/// before `t_end` (matched by bin start).
pub(crate) fn bins_rms(a: &[(f64, f64)], b: &[(f64, f64)], t_end: f64) -> Result<f64> {
    let (mut s, mut n) = (0.0, 0usize);
    for (p, q) in a.iter().zip(b) {
        if p.0 >= t_end || q.0 >= t_end {
            break;
        }
        if (p.0 - q.0).abs() > 1e-6 * p.0.abs().max(1.0) {
            bail!(
                "the two force series start their bins at different times ({} vs {})",
                p.0,
                q.0
            );
        }
        s += (p.1 - q.1).powi(2);
        n += 1;
    }
    if n < 2 {
        bail!("fewer than 2 common bins before {t_end}");
    }
    Ok((s / n as f64).sqrt())
}

/// Least-squares line `y = a + b x` and its R^2.
pub(crate) fn linear_r2(x: &[f64], y: &[f64]) -> Result<(f64, f64, f64)> {
    let n = x.len();
    if n < 3 || y.len() != n {
        bail!("a linear fit needs >= 3 points (got {n})");
    }
    let mx = x.iter().sum::<f64>() / n as f64;
    let my = y.iter().sum::<f64>() / n as f64;
    let sxx: f64 = x.iter().map(|v| (v - mx).powi(2)).sum();
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let syy: f64 = y.iter().map(|v| (v - my).powi(2)).sum();
    if sxx == 0.0 {
        bail!("all x values are equal");
    }
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    let r2 = if syy == 0.0 {
        1.0
    } else {
        sxy * sxy / (sxx * syy)
    };
    Ok((intercept, slope, r2))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A force series with a known shape: zero before contact at t = 2, a triangle
    /// peaking in the second bin, then a plateau at a quarter of the peak.
    #[test]
    fn force_summary_finds_contact_peak_half_time_and_impulse() {
        let s: Vec<(f64, f64)> = (0..200)
            .map(|k| {
                let t = k as f64 * 0.1;
                let f = if t < 2.0 - 1e-9 {
                    0.0
                } else if t < 3.5 {
                    100.0 * (t - 1.9)
                } else if t < 5.0 {
                    160.0 - 100.0 * (t - 3.5)
                } else {
                    10.0
                };
                (t, f)
            })
            .collect();
        let f = force_summary(&s, 1.0, 3.0).unwrap();
        assert!((f.t_contact - 2.0).abs() < 1e-12);
        // Bins [2,3): mean of 10..100 = 55; [3,4): 110,120,...,160,150,...,110 peak bin.
        assert!((f.t_peak - 3.0).abs() < 1e-9, "{f:?}");
        assert!(f.peak > 120.0 && f.peak < 160.0);
        // [4,5): 110 down to 20: mean 65 < peak/2? peak ~ 136 -> 65 < 68: 1 bin later.
        assert_eq!(f.half_after.map(|h| h.round()), Some(1.0), "{f:?}");
        // Impulse over [2, 5] by trapezoid of the samples.
        let want: f64 = s
            .windows(2)
            .filter(|w| w[0].0 >= 2.0 - 1e-9 && w[1].0 <= 5.0 + 1e-9)
            .map(|w| 0.5 * (w[1].0 - w[0].0) * (w[0].1 + w[1].1))
            .sum();
        assert!((f.impulse - want).abs() < 1e-9, "{} vs {want}", f.impulse);
        // A slow ramp never falls to half: no half time; no contact at all is an error.
        let ramp: Vec<(f64, f64)> = (0..100).map(|k| (k as f64 * 0.1, k as f64)).collect();
        assert_eq!(force_summary(&ramp, 1.0, 3.0).unwrap().half_after, None);
        assert!(force_summary(&[(0.0, 0.0), (1.0, 0.0)], 1.0, 1.0).is_err());
        assert_eq!(bins_rms(&f.bins, &f.bins, 10.0).unwrap(), 0.0);
    }

    /// A trajectory with known deceleration decel = c u^k: the passages and the fit
    /// return k and c (to the discretisation of a fine series).
    #[test]
    fn passages_of_a_known_force_law_fit_its_exponent() {
        let (c, k) = (0.3, 1.4);
        let mut runs = Vec::new();
        for v0 in [0.2, 0.4, 0.7, 1.0] {
            let s = power_law_trajectory(v0, c, k, 1e-4);
            runs.extend(passages(&s, &[1.0, 2.0, 3.0], 0.5));
        }
        let (kf, cf, r2, n) = power_law(&runs).unwrap();
        assert!(n >= 6, "{n} passages");
        assert!(
            (kf - k).abs() < 0.05 && (cf / c - 1.0).abs() < 0.05,
            "k {kf} c {cf}"
        );
        assert!(r2 > 0.99);
    }

    #[test]
    fn csv_round_trip_is_exact_and_errors_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let s = [IntruderSample {
            step: 7,
            t: 0.1 + 0.2,
            x: [1.0 / 3.0, -2.5e-3],
            v: [0.0, -0.7],
            f: [1e-300, 3.0],
            interface_y: None,
        }];
        let p = dir.path().join("intruder.csv");
        write_intruder_csv(&p, &s, 0.1, 0.01).unwrap();
        assert_eq!(read_intruder_csv(&p).unwrap(), s);
        let e = [EnergySample {
            step: 3,
            t: 0.5,
            kinetic: 2.0 / 7.0,
            potential: -1.0,
            elastic: 0.0,
        }];
        let q = dir.path().join("energy.csv");
        write_energy_csv(&q, &e).unwrap();
        assert_eq!(read_energy_csv(&q).unwrap(), e);
        std::fs::write(&q, "t,step,kinetic,potential_abs,elastic\n0.5,x,1,2,3\n").unwrap();
        let err = format!("{:#}", read_energy_csv(&q).unwrap_err());
        assert!(
            err.contains("energy.csv") && err.contains("line: 2"),
            "{err}"
        );
    }

    /// One depth of K Fig 29 on one bed: a = c u^k at four speeds gives k back (exactly
    /// for k = 1, where the bin's mean deceleration is c times its mean speed); a steeper
    /// law gives a steeper k; fewer passages than required are refused.
    #[test]
    fn exponent_at_one_depth() {
        let runs = |k: f64| -> Vec<Vec<(f64, f64, f64)>> {
            [0.3, 0.5, 0.7, 1.0]
                .iter()
                .map(|&v| power_law_trajectory(v, 0.02, k, 0.01))
                .collect()
        };
        let one = runs(1.0);
        let refs: Vec<&[(f64, f64, f64)]> = one.iter().map(Vec::as_slice).collect();
        let e = exponent_at_depth(&refs, 2.0, 0.5, 4).unwrap();
        assert!((e.k - 1.0).abs() < 1e-6 && e.used.len() == 4, "{e:?}");
        let steep = runs(1.8);
        let refs: Vec<&[(f64, f64, f64)]> = steep.iter().map(Vec::as_slice).collect();
        let e = exponent_at_depth(&refs, 2.0, 0.5, 4).unwrap();
        assert!(e.k > 1.6, "{e:?}");
        assert!(exponent_at_depth(&refs[..3], 2.0, 0.5, 4).is_err());
        assert!(exponent_at_depth(&refs, 500.0, 0.5, 4).is_err());
    }
}
