//! The triaxial observables of docs/stress.md rule 5, pure functions of a wall series:
//!
//! - sigma_ii = the mean of the two opposite walls' normal forces / the current face
//!   area (the lo walls at 0, so the face normal to x has area y_hi z_hi);
//! - over a window the three stresses are averaged first; then s1 = the largest, s3 =
//!   the smallest and sin phi = (s1 - s3) / (s1 + s3) (eq 8's gamma);
//! - phi_peak: the largest phi over consecutive windows of `peak_window` in eps_a from 0;
//! - phi_cs: phi of the stresses averaged over eps_a in the critical-state range, with
//!   d eps_v / d eps_a there (least-squares slope) and the sample sd of the phi of its
//!   blocks.
//!
//! Strains are positive in compression: eps_a = (H0 - H) / H0, eps_v = (V0 - V) / V0
//! (so a dilating sample has d eps_v / d eps_a < 0).

use crate::rundata::triaxial::WallRecord;
use anyhow::{Result, bail};

/// One output step in strain and stress.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    pub eps_a: f64,
    pub eps_v: f64,
    /// sigma_xx, sigma_yy, sigma_zz (Pa).
    pub s: [f64; 3],
    /// Stress on the hi walls alone (the servo's measure), for the tracking error.
    pub s_hi: [f64; 3],
}

/// The points of a series starting from hi walls at `hi0` (step 0).
pub fn points(records: &[WallRecord], hi0: [f64; 3]) -> Vec<Point> {
    let v0 = hi0[0] * hi0[1] * hi0[2];
    records
        .iter()
        .map(|r| {
            let h = r.hi;
            let area = [h[1] * h[2], h[0] * h[2], h[0] * h[1]];
            Point {
                eps_a: (hi0[2] - h[2]) / hi0[2],
                eps_v: (v0 - h[0] * h[1] * h[2]) / v0,
                s: [0, 1, 2].map(|i| 0.5 * (r.f_hi[i] - r.f_lo[i]) / area[i]),
                s_hi: [0, 1, 2].map(|i| r.f_hi[i] / area[i]),
            }
        })
        .collect()
}

/// Mobilised friction angle (degrees) of a diagonal stress state: asin((s1 - s3) / (s1 + s3)).
pub fn phi_deg(s: [f64; 3]) -> f64 {
    let s1 = s[0].max(s[1]).max(s[2]);
    let s3 = s[0].min(s[1]).min(s[2]);
    ((s1 - s3) / (s1 + s3)).asin().to_degrees()
}

/// The stresses averaged over the points with `from <= eps_a < to` (`to_inclusive`: <=),
/// and how many there were.
fn mean_stress(pts: &[Point], from: f64, to: f64, to_inclusive: bool) -> ([f64; 3], usize) {
    let mut sum = [0.0; 3];
    let mut n = 0;
    for p in pts {
        if p.eps_a >= from && (p.eps_a < to || (to_inclusive && p.eps_a <= to)) {
            for (a, b) in sum.iter_mut().zip(p.s) {
                *a += b;
            }
            n += 1;
        }
    }
    (sum.map(|x| x / n as f64), n)
}

/// phi of the stresses averaged over `from <= eps_a < to` (or `<= to`); an error when
/// the window holds no point.
pub(crate) fn window_phi(pts: &[Point], from: f64, to: f64, to_inclusive: bool) -> Result<f64> {
    let (s, n) = mean_stress(pts, from, to, to_inclusive);
    if n == 0 {
        bail!("no output step with eps_a in [{from:.4}, {to:.4}]");
    }
    Ok(phi_deg(s))
}

/// Least-squares slope of y on x.
pub(crate) fn slope(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    sxy / sxx
}

/// Sample standard deviation (n - 1).
pub(crate) fn sample_sd(v: &[f64]) -> f64 {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0)).sqrt()
}

/// The windows of the analysis (a case's `[analysis]`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Windows {
    pub peak_window: f64,
    pub critical_state: [f64; 2],
    pub block: f64,
    /// End of the shear in eps_a: peak windows start below it.
    pub final_strain: f64,
}

/// What rule 5 reads from one run.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Observables {
    pub phi_peak: f64,
    /// Start of the window phi_peak was read in (eps_a).
    pub peak_at: f64,
    pub phi_cs: f64,
    /// Sample sd of the blocks' phi in the critical-state range.
    pub block_sd: f64,
    pub blocks: Vec<f64>,
    /// d eps_v / d eps_a over the critical-state range.
    pub dilatancy: f64,
    /// Mean stresses over the critical-state range (Pa).
    pub s_cs: [f64; 3],
    /// phi of every peak window, (start, phi).
    pub windows: Vec<(f64, f64)>,
}

/// Rule 5's observables of a run.
pub(crate) fn observables(pts: &[Point], w: &Windows) -> Result<Observables> {
    let n_peak = ((w.final_strain / w.peak_window) - 1e-9).ceil().max(1.0) as usize;
    let mut windows = Vec::with_capacity(n_peak);
    for k in 0..n_peak {
        let a = k as f64 * w.peak_window;
        windows.push((a, window_phi(pts, a, a + w.peak_window, false)?));
    }
    let (peak_at, phi_peak) = windows.iter().copied().fold(
        (f64::NAN, f64::NEG_INFINITY),
        |m, x| if x.1 > m.1 { x } else { m },
    );
    let [c0, c1] = w.critical_state;
    let (s_cs, n_cs) = mean_stress(pts, c0, c1, true);
    if n_cs < 3 {
        bail!("{n_cs} output step(s) with eps_a in [{c0}, {c1}]: too few for the critical state");
    }
    let phi_cs = phi_deg(s_cs);
    let n_blocks = (((c1 - c0) / w.block) - 1e-9).ceil() as usize;
    let blocks = (0..n_blocks)
        .map(|k| {
            let a = c0 + k as f64 * w.block;
            let last = k + 1 == n_blocks;
            window_phi(pts, a, if last { c1 } else { a + w.block }, last)
        })
        .collect::<Result<Vec<f64>>>()?;
    let (x, y): (Vec<f64>, Vec<f64>) = pts
        .iter()
        .filter(|p| p.eps_a >= c0 && p.eps_a <= c1)
        .map(|p| (p.eps_a, p.eps_v))
        .unzip();
    Ok(Observables {
        phi_peak,
        peak_at,
        phi_cs,
        block_sd: if blocks.len() > 1 {
            sample_sd(&blocks)
        } else {
            f64::NAN
        },
        blocks,
        dilatancy: slope(&x, &y),
        s_cs,
        windows,
    })
}

/// Solid fraction of `n` grains of diameter `d` in the box [0, hi].
pub fn solid_fraction(n: usize, d: f64, hi: [f64; 3]) -> f64 {
    n as f64 * std::f64::consts::PI / 6.0 * d.powi(3) / (hi[0] * hi[1] * hi[2])
}

/// Inertial number I = eps_dot d sqrt(rho / sigma_c).
pub(crate) fn inertial_number(strain_rate: f64, d: f64, density: f64, sigma_c: f64) -> f64 {
    strain_rate * d * (density / sigma_c).sqrt()
}

/// The servo's tracking error: the mean and the largest |sigma / sigma_c - 1| of the
/// lateral hi walls (x, y), over the points with eps_a in [from, to].
pub(crate) fn tracking_error(pts: &[Point], sigma_c: f64, from: f64, to: f64) -> (f64, f64) {
    let (mut sum, mut max, mut n) = (0.0, 0.0f64, 0usize);
    for p in pts.iter().filter(|p| p.eps_a >= from && p.eps_a <= to) {
        for i in 0..2 {
            let e = (p.s_hi[i] / sigma_c - 1.0).abs();
            sum += e;
            max = max.max(e);
            n += 1;
        }
    }
    (sum / n as f64, max)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A synthetic test: H shrinks linearly, the lateral walls hold 1 kPa, the axial
    /// stress rises to a peak of 3 kPa at eps_a = 0.05 and settles to 2.5 kPa from 0.15
    /// on, the volume first shrinks then grows at a known rate.
    fn synthetic() -> (Vec<WallRecord>, [f64; 3]) {
        let hi0 = [0.04, 0.04, 0.04];
        let sigma3 = 1000.0;
        let mut out = Vec::new();
        for k in 1..=3000u64 {
            let eps = k as f64 * 1e-4;
            let h = hi0[2] * (1.0 - eps);
            // eps_v = 0.01 eps - 0.5 max(0, eps - 0.1)^... a slope of -0.2 beyond 0.1.
            let ev = if eps < 0.1 {
                0.01 * eps
            } else {
                0.001 - 0.2 * (eps - 0.1)
            };
            let v = hi0[0] * hi0[1] * hi0[2] * (1.0 - ev);
            let lat = (v / h).sqrt();
            let s1 = if eps <= 0.05 {
                1000.0 + 2000.0 * eps / 0.05
            } else if eps <= 0.15 {
                3000.0 - 500.0 * (eps - 0.05) / 0.1
            } else {
                2500.0
            };
            let (ax, az) = (lat * h, lat * lat);
            out.push(WallRecord {
                step: 100 * k,
                hi: [lat, lat, h],
                f_lo: [-sigma3 * ax, -sigma3 * ax, -s1 * az],
                f_hi: [sigma3 * ax, sigma3 * ax, s1 * az],
            });
        }
        (out, hi0)
    }

    #[test]
    fn known_angles_slopes_and_stresses() {
        let (r, hi0) = synthetic();
        let pts = points(&r, hi0);
        let w = Windows {
            peak_window: 0.01,
            critical_state: [0.20, 0.30],
            block: 0.01,
            final_strain: 0.30,
        };
        let o = observables(&pts, &w).unwrap();
        // Critical state: s1 = 2500, s3 = 1000: sin phi = 1500 / 3500.
        let cs = (1500.0f64 / 3500.0).asin().to_degrees();
        assert!((o.phi_cs - cs).abs() < 1e-9, "{} vs {cs}", o.phi_cs);
        assert!(o.block_sd < 1e-9);
        assert_eq!(o.blocks.len(), 10);
        assert!((o.dilatancy + 0.2).abs() < 1e-6, "{}", o.dilatancy);
        // Peak: the window [0.05, 0.06) averages s1 over 2950 .. 2995.
        assert!((o.peak_at - 0.04).abs() < 1e-12 || (o.peak_at - 0.05).abs() < 1e-12);
        let pk = (2000.0f64 / 4000.0).asin().to_degrees();
        assert!(o.phi_peak < pk && o.phi_peak > pk - 0.5, "{}", o.phi_peak);
        assert_eq!(o.windows.len(), 30);
        assert!((phi_deg([1000.0, 3000.0, 1000.0]) - 30.0).abs() < 1e-12);
        // Tracking: the lateral walls hold sigma_c exactly.
        let (mean, max) = tracking_error(&pts, 1000.0, 0.0, 0.3);
        assert!(mean < 1e-12 && max < 1e-12);
        // 8000 spheres of 2 mm in a 40 mm cube: 8000 pi / 6 * 8e-9 / 6.4e-5 = pi / 6.
        assert!(
            (solid_fraction(8000, 2e-3, [0.04; 3]) - std::f64::consts::FRAC_PI_6).abs() < 1e-12
        );
        assert!((inertial_number(0.158, 2e-3, 2500.0, 1000.0) - 5.0e-4).abs() < 1e-5);
    }

    #[test]
    fn too_short_a_series_is_an_error() {
        let (r, hi0) = synthetic();
        let pts = points(&r[..1500], hi0);
        let w = Windows {
            peak_window: 0.01,
            critical_state: [0.20, 0.30],
            block: 0.01,
            final_strain: 0.30,
        };
        assert!(observables(&pts, &w).is_err());
    }
}
