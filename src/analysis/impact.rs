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

pub use crate::physics::dem2d::energy::{EnergyModel, SnapDisk, energies};
pub use crate::rundata::impact::*;
use anyhow::{Result, bail};

/// Potential energies relative to the first sample.
pub fn relative_potential(e: &[EnergySample]) -> Vec<f64> {
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
pub fn final_window_samples(d: &[(f64, f64)], window: f64) -> usize {
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

/// Least-squares line `y = a + b x` and its R^2.
pub fn linear_r2(x: &[f64], y: &[f64]) -> Result<(f64, f64, f64)> {
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

    #[test]
    fn csv_round_trip_is_exact_and_errors_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let s = [IntruderSample {
            step: 7,
            t: 0.1 + 0.2,
            x: [1.0 / 3.0, -2.5e-3],
            v: [0.0, -0.7],
            f: [1e-300, 3.0],
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
}
