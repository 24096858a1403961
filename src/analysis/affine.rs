//! Affine and non-affine parts of the grains' motion during an impact (Kondic et al.
//! Sec. IV B, eqs 3-4, after Falk and Langer): for every grain (the central one, r_0)
//! its neighbours are the grains whose centres lie within R of its centre at t - dt; the
//! 2x2 matrix A minimises
//!
//!   D2 = sum_n |r_n(t) - r_0(t) - A (r_n(t - dt) - r_0(t - dt))|^2        (eq 4)
//!
//! (a sum, as eq 4 and Falk and Langer write it), solved in closed form,
//! A = X Y^-1 with X = sum d_n(t) d_n(t - dt)^T and Y = sum d_n(t - dt) d_n(t - dt)^T;
//! D2_min is D2 at that A. The affine field is A_f = A (r_0(t) - r_0(t - dt)), as the
//! paper defines it. Vectors are minimum-image across the periodic sides (length L).
//! A grain with fewer than 2 neighbours, or whose neighbours lie on a line (Y singular),
//! has no A and is left out (counted).

use crate::rundata::impact::GrainPos;
use anyhow::{Result, bail};
use nalgebra::{Matrix2, Vector2};

/// One grain's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AffineGrain {
    pub id: u64,
    /// Position at t.
    pub x: [f64; 2],
    pub af: [f64; 2],
    pub d2min: f64,
}

#[derive(Debug, Clone)]
pub struct AffineField {
    pub grains: Vec<AffineGrain>,
    /// Grains without a defined A (too few or collinear neighbours).
    pub skipped: usize,
}

fn min_image(mut d: [f64; 2], length: Option<f64>) -> [f64; 2] {
    if let Some(l) = length {
        d[0] -= l * (d[0] / l).round();
    }
    d
}

/// The field between the positions `before` (t - dt) and `after` (t), both sorted by id
/// with the same grains; `periodic_length`: L when x is periodic.
pub fn field(
    before: &[GrainPos],
    after: &[GrainPos],
    radius: f64,
    periodic_length: Option<f64>,
) -> Result<AffineField> {
    if before.len() != after.len() || before.iter().zip(after).any(|(a, b)| a.id != b.id) {
        bail!(
            "the two snapshots hold different grains ({} vs {}): the affine field needs the same grains at both times",
            before.len(),
            after.len()
        );
    }
    if radius.is_nan() || radius <= 0.0 {
        bail!("neighbourhood radius {radius:e} must be > 0");
    }
    // Cell list of side >= radius over the positions at t - dt.
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for g in before {
        for a in 0..2 {
            lo[a] = lo[a].min(g.x[a]);
            hi[a] = hi[a].max(g.x[a]);
        }
    }
    if let Some(l) = periodic_length {
        lo[0] = 0.0;
        hi[0] = l;
    }
    let ncell = |a: usize| (((hi[a] - lo[a]) / radius).floor() as usize).max(1);
    let (nx, ny) = (ncell(0), ncell(1));
    let cell_of = |x: [f64; 2]| {
        let cx = (((x[0] - lo[0]) / (hi[0] - lo[0]).max(1e-300)) * nx as f64).floor() as isize;
        let cy = (((x[1] - lo[1]) / (hi[1] - lo[1]).max(1e-300)) * ny as f64).floor() as isize;
        (
            cx.rem_euclid(nx as isize) as usize,
            cy.clamp(0, ny as isize - 1) as usize,
        )
    };
    let mut cells: Vec<Vec<usize>> = vec![Vec::new(); nx * ny];
    for (k, g) in before.iter().enumerate() {
        let (cx, cy) = cell_of(g.x);
        cells[cy * nx + cx].push(k);
    }
    let r2 = radius * radius;
    let mut grains = Vec::with_capacity(before.len());
    let mut skipped = 0;
    for (k, g) in before.iter().enumerate() {
        let (cx, cy) = cell_of(g.x);
        let mut x = Matrix2::<f64>::zeros();
        let mut y = Matrix2::<f64>::zeros();
        let mut pairs: Vec<(Vector2<f64>, Vector2<f64>)> = Vec::new();
        let xs: Vec<usize> = if periodic_length.is_some() {
            let mut v: Vec<usize> = (-1..=1)
                .map(|d| (cx as isize + d).rem_euclid(nx as isize) as usize)
                .collect();
            v.sort_unstable();
            v.dedup();
            v
        } else {
            (cx.saturating_sub(1)..=(cx + 1).min(nx - 1)).collect()
        };
        for &ix in &xs {
            for iy in cy.saturating_sub(1)..=(cy + 1).min(ny - 1) {
                for &n in &cells[iy * nx + ix] {
                    if n == k {
                        continue;
                    }
                    let d0 = min_image(
                        [before[n].x[0] - g.x[0], before[n].x[1] - g.x[1]],
                        periodic_length,
                    );
                    if d0[0] * d0[0] + d0[1] * d0[1] > r2 {
                        continue;
                    }
                    let d1 = min_image(
                        [after[n].x[0] - after[k].x[0], after[n].x[1] - after[k].x[1]],
                        periodic_length,
                    );
                    let (d0, d1) = (Vector2::from(d0), Vector2::from(d1));
                    x += d1 * d0.transpose();
                    y += d0 * d0.transpose();
                    pairs.push((d0, d1));
                }
            }
        }
        let inv = (pairs.len() >= 2)
            .then(|| y.try_inverse())
            .flatten()
            // Collinear neighbours: Y is singular up to round-off.
            .filter(|_| y.determinant().abs() > 1e-12 * y.trace().powi(2));
        let Some(yinv) = inv else {
            skipped += 1;
            continue;
        };
        let a = x * yinv;
        let d2min = pairs
            .iter()
            .map(|(d0, d1)| (d1 - a * d0).norm_squared())
            .sum::<f64>();
        let u = min_image(
            [after[k].x[0] - g.x[0], after[k].x[1] - g.x[1]],
            periodic_length,
        );
        let af = a * Vector2::from(u);
        grains.push(AffineGrain {
            id: g.id,
            x: after[k].x,
            af: [af[0], af[1]],
            d2min,
        });
    }
    Ok(AffineField { grains, skipped })
}

/// Summary statistics of a field over its grains, in the units the positions were given
/// in divided by `unit` (lengths; D2_min in unit^2).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct AffineSummary {
    pub mean_af: f64,
    pub mean_af_y: f64,
    pub mean_d2min: f64,
    pub median_d2min: f64,
    pub p90_d2min: f64,
    pub grains: usize,
    pub skipped: usize,
}

/// The `q` quantile of sorted data (linear between order statistics).
fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let h = q * (sorted.len() - 1) as f64;
    let (k, f) = (h.floor() as usize, h - h.floor());
    let next = sorted[(k + 1).min(sorted.len() - 1)];
    sorted[k] + f * (next - sorted[k])
}

pub fn summary(f: &AffineField, unit: f64) -> AffineSummary {
    let n = f.grains.len().max(1) as f64;
    let mut d2: Vec<f64> = f.grains.iter().map(|g| g.d2min / (unit * unit)).collect();
    d2.sort_by(f64::total_cmp);
    AffineSummary {
        mean_af: f.grains.iter().map(|g| g.af[0].hypot(g.af[1])).sum::<f64>() / n / unit,
        mean_af_y: f.grains.iter().map(|g| g.af[1].abs()).sum::<f64>() / n / unit,
        mean_d2min: d2.iter().sum::<f64>() / n,
        median_d2min: quantile(&d2, 0.5),
        p90_d2min: quantile(&d2, 0.9),
        grains: f.grains.len(),
        skipped: f.skipped,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice(n: usize, map: impl Fn([f64; 2]) -> [f64; 2]) -> Vec<GrainPos> {
        let mut v = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let p = [i as f64 + 0.3 * (j % 2) as f64, j as f64 * 0.9];
                v.push(GrainPos {
                    id: (i * n + j) as u64,
                    x: map(p),
                });
            }
        }
        v
    }

    /// An exact affine map r -> M r + c leaves no non-affine part anywhere, and A_f is
    /// M applied to each grain's own displacement.
    #[test]
    fn exact_affine_deformation_has_zero_d2min() {
        let m = [[1.02, 0.05], [-0.03, 0.97]];
        let map = |p: [f64; 2]| {
            [
                m[0][0] * p[0] + m[0][1] * p[1] + 0.4,
                m[1][0] * p[0] + m[1][1] * p[1] - 0.2,
            ]
        };
        let before = lattice(8, |p| p);
        let after = lattice(8, map);
        let f = field(&before, &after, 2.5, None).unwrap();
        assert_eq!(f.skipped, 0);
        assert_eq!(f.grains.len(), 64);
        for (g, b) in f.grains.iter().zip(&before) {
            assert!(g.d2min < 1e-20, "{g:?}");
            let u = [map(b.x)[0] - b.x[0], map(b.x)[1] - b.x[1]];
            let want = [
                m[0][0] * u[0] + m[0][1] * u[1],
                m[1][0] * u[0] + m[1][1] * u[1],
            ];
            assert!((g.af[0] - want[0]).abs() < 1e-12 && (g.af[1] - want[1]).abs() < 1e-12);
        }
        // The same across a periodic side: shift everything by most of L.
        let l = 20.0;
        let wrap = |v: &[GrainPos]| -> Vec<GrainPos> {
            v.iter()
                .map(|g| GrainPos {
                    id: g.id,
                    x: [(g.x[0] + 15.0).rem_euclid(l), g.x[1]],
                })
                .collect()
        };
        let p = field(&wrap(&before), &wrap(&after), 2.5, Some(l)).unwrap();
        assert!(p.grains.iter().all(|g| g.d2min < 1e-20));
    }

    /// Four neighbours at (+-1, 0), (0, +-1), the one at (1, 0) pushed out by delta:
    /// A = diag(1 + delta/2, 1) and D2_min = delta^2 / 2 (worked by hand).
    #[test]
    fn one_displaced_neighbour_gives_the_hand_computed_d2min() {
        let delta = 0.1;
        let at = |id: u64, x: [f64; 2]| GrainPos { id, x };
        let before = vec![
            at(0, [0.0, 0.0]),
            at(1, [1.0, 0.0]),
            at(2, [-1.0, 0.0]),
            at(3, [0.0, 1.0]),
            at(4, [0.0, -1.0]),
        ];
        let mut after = before.clone();
        after[1].x[0] += delta;
        let f = field(&before, &after, 1.2, None).unwrap();
        let c = f.grains.iter().find(|g| g.id == 0).unwrap();
        assert!((c.d2min - delta * delta / 2.0).abs() < 1e-15, "{c:?}");
        assert_eq!(c.af, [0.0, 0.0], "the central grain did not move");
        // Each outer grain sees only the centre within 1.2: one neighbour, no A.
        assert_eq!(f.skipped, 4);
        let s = summary(&f, 1.0);
        assert_eq!(s.grains, 1);
        assert!((s.mean_d2min - 0.005).abs() < 1e-15);
        assert!(field(&before, &after[..4], 1.2, None).is_err());
    }
}
