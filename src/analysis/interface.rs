//! The depth below the moving interface and the long-time oscillations of K Sec. III
//! (Figs 11-12; rules 2 and 4 of docs/impact2d.md, "Depth below the moving interface").
//!
//! - s(t): the rise of the interface tracers' centre of mass since release;
//! - D_rel(t) = D(t) + s(t): a bed that rises by s lifts an intruder riding with it by
//!   s, which lowers D (measured from the surface at t = 0) by s and leaves D_rel as it
//!   was; so oscillations of the whole bed show in D and not in D_rel (K Fig 12);
//! - A[X]: max - min of a series over the final window (the final depth's samples);
//! - a rough period: the mean interval between successive upward crossings of the
//!   window's mean, reported only.

use crate::rundata::impact::IntruderSample;
use anyhow::{Result, bail};

/// s(t) = y_I(t) - y_I(first sample), as (t, s), from the interface heights the samples
/// carry; an error when a sample has none (a run recorded without tracking).
pub fn shift(samples: &[IntruderSample]) -> Result<Vec<(f64, f64)>> {
    let Some(y0) = samples.first().and_then(|s| s.interface_y) else {
        bail!(
            "the intruder samples carry no interface height (a run made without interface tracers: rerun it, or re-record the reference)"
        );
    };
    samples
        .iter()
        .map(|s| match s.interface_y {
            Some(y) => Ok((s.t, y - y0)),
            None => bail!("no interface height at step {}", s.step),
        })
        .collect()
}

/// D_rel(t) = D(t) + s(t), both given at the same sample times.
pub(crate) fn relative_depth(
    depth: &[(f64, f64)],
    shift: &[(f64, f64)],
) -> Result<Vec<(f64, f64)>> {
    if depth.len() != shift.len() {
        bail!(
            "{} depth samples but {} interface samples",
            depth.len(),
            shift.len()
        );
    }
    depth
        .iter()
        .zip(shift)
        .map(|(&(t, d), &(ts, s))| {
            if (t - ts).abs() > 1e-9 * t.abs().max(1e-300) {
                bail!("depth sample at t = {t:e} but interface sample at t = {ts:e}");
            }
            Ok((t, d + s))
        })
        .collect()
}

/// The oscillation of a series over a final window.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Oscillation {
    /// max - min over the window (peak to peak).
    pub amplitude: f64,
    /// Mean interval between successive upward crossings of the window's mean; None
    /// with fewer than 2 crossings.
    pub period: Option<f64>,
    /// Upward crossings of the window's mean.
    pub crossings: usize,
    /// Samples in the window.
    pub samples: usize,
}

/// The oscillation of `(t, x)` (sorted by t) over `t >= t_end - window`: the samples
/// the final depth averages (`impact::final_depth`). Fewer than 2 samples is an error.
pub(crate) fn oscillation(series: &[(f64, f64)], window: f64) -> Result<Oscillation> {
    let Some(&(t_end, _)) = series.last() else {
        bail!("an empty series");
    };
    let tail: Vec<(f64, f64)> = series
        .iter()
        .copied()
        .filter(|(t, _)| *t >= t_end - window)
        .collect();
    if tail.len() < 2 {
        bail!("fewer than 2 samples in the final window of {window:.3e}");
    }
    let (lo, hi) = tail
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.1), b.max(p.1))
        });
    let mean = tail.iter().map(|p| p.1).sum::<f64>() / tail.len() as f64;
    let ups: Vec<f64> = tail
        .windows(2)
        .filter(|w| w[0].1 < mean && w[1].1 >= mean)
        .map(|w| {
            let ((t0, x0), (t1, x1)) = (w[0], w[1]);
            t0 + (mean - x0) / (x1 - x0) * (t1 - t0)
        })
        .collect();
    let period = (ups.len() >= 2).then(|| (ups[ups.len() - 1] - ups[0]) / (ups.len() - 1) as f64);
    Ok(Oscillation {
        amplitude: hi - lo,
        period,
        crossings: ups.len(),
        samples: tail.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(step: u64, y_intruder: f64, interface_y: Option<f64>) -> IntruderSample {
        IntruderSample {
            step,
            t: step as f64,
            x: [0.0, y_intruder],
            v: [0.0; 2],
            f: [0.0; 2],
            interface_y,
        }
    }

    /// A bed that rises and falls by s(t) and an intruder riding with it: D(t) takes the
    /// oscillation (its sign opposite to s), D_rel(t) = D + s does not.
    #[test]
    fn an_intruder_riding_with_the_bed_keeps_its_depth_below_the_interface() {
        let (surface, bottom, rest) = (10.0, 0.5, 2.0);
        let samples: Vec<IntruderSample> = (0..200)
            .map(|k| {
                let s = 0.3 * (k as f64 * 0.2).sin();
                // The intruder's lowest point sits `rest` below the surface, plus s.
                sample(k, surface - rest + s + bottom, Some(4.0 + s))
            })
            .collect();
        let depth = crate::analysis::impact::depth(&samples, surface, bottom);
        let s = shift(&samples).unwrap();
        assert_eq!(s[0].1, 0.0);
        // D falls when the bed rises.
        let k = (0..200).find(|&k| s[k].1 > 0.2).unwrap();
        assert!(depth[k].1 < rest - 0.2, "{:?}", depth[k]);
        let rel = relative_depth(&depth, &s).unwrap();
        for (t, d) in &rel {
            assert!((d - rest).abs() < 1e-12, "t {t}: D_rel {d}");
        }
        let (a_d, a_rel) = (
            oscillation(&depth, 100.0).unwrap().amplitude,
            oscillation(&rel, 100.0).unwrap().amplitude,
        );
        assert!(a_d > 0.55 && a_rel < 1e-12, "{a_d} {a_rel}");
        // With the sign reversed (D - s) the oscillation would double, not vanish.
        let wrong: Vec<(f64, f64)> = depth
            .iter()
            .zip(&s)
            .map(|(d, s)| (d.0, d.1 - s.1))
            .collect();
        assert!(oscillation(&wrong, 100.0).unwrap().amplitude > 1.1);
    }

    /// Peak to peak and the period of a sine over the window; the window is the final
    /// depth's (t >= t_end - window); too few crossings give no period.
    #[test]
    fn amplitude_and_period_of_a_sine() {
        let (a, p) = (0.4, 37.0);
        let x: Vec<(f64, f64)> = (0..=2000)
            .map(|k| {
                let t = k as f64 * 0.5;
                // A step before the window that must not count.
                let offset = if t < 800.0 { 5.0 } else { 0.0 };
                (
                    t,
                    offset + 3.0 + a * (2.0 * std::f64::consts::PI * t / p).sin(),
                )
            })
            .collect();
        let o = oscillation(&x, 200.0).unwrap();
        assert_eq!(o.samples, 401);
        assert!((o.amplitude - 2.0 * a).abs() < 2e-3, "{o:?}");
        assert!((o.period.unwrap() - p).abs() < 0.05, "{o:?}");
        assert!(o.crossings >= 5);
        // A window shorter than one period: at most one crossing, no period.
        let o = oscillation(&x, 20.0).unwrap();
        assert!(o.crossings <= 1 && o.period.is_none(), "{o:?}");
        assert!(oscillation(&x[..1], 200.0).is_err());
    }

    /// `intruder.csv` of a tracked run carries the interface height (read back exactly)
    /// and s; an untracked run's file has neither column; a mix is refused.
    #[test]
    fn intruder_csv_carries_the_interface_only_when_tracked() {
        use crate::rundata::impact::{read_intruder_csv, write_intruder_csv};
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("intruder.csv");
        let tracked = [
            sample(0, 1.0, Some(0.1 + 0.2)),
            sample(50, 0.9, Some(1.0 / 3.0)),
        ];
        write_intruder_csv(&p, &tracked, 2.0, 0.5).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(
            text.starts_with("t,step,x,y,vx,vy,fx,fy,depth,interface_y,interface_s\n"),
            "{text}"
        );
        assert_eq!(read_intruder_csv(&p).unwrap(), tracked);
        let plain = [sample(0, 1.0, None), sample(50, 0.9, None)];
        write_intruder_csv(&p, &plain, 2.0, 0.5).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(!text.contains("interface") && text.lines().all(|l| l.split(',').count() == 9));
        assert_eq!(read_intruder_csv(&p).unwrap(), plain);
        let mixed = [sample(0, 1.0, Some(1.0)), sample(50, 0.9, None)];
        assert!(write_intruder_csv(&p, &mixed, 2.0, 0.5).is_err());
    }

    /// A run without interface heights cannot give s(t); mismatched series are errors.
    #[test]
    fn missing_interface_heights_are_errors() {
        let e = shift(&[sample(0, 1.0, None)]).unwrap_err().to_string();
        assert!(e.contains("no interface height"), "{e}");
        assert!(shift(&[sample(0, 1.0, Some(1.0)), sample(1, 1.0, None)]).is_err());
        assert!(relative_depth(&[(0.0, 1.0)], &[]).is_err());
        assert!(relative_depth(&[(1.0, 1.0)], &[(2.0, 0.0)]).is_err());
    }
}
