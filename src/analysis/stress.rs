//! From a coarse-grained stress field to the internal friction angle (Feng et al.
//! Sec. 5, eq 8 and the text after it): principal stresses, gamma, sin phi as the mean
//! gamma over the cells with 0.995 gamma_max <= gamma <= gamma_max, the incipient-yield
//! region gamma >= 0.85 sin phi, and the stagnant zone from the velocity field.
//!
//! Sign convention: compressive stress positive (see `analysis::coarse_grain`), so
//! sigma_1 >= sigma_2 >= sigma_3 are the largest and smallest compressions and
//! gamma = (sigma_1 - sigma_3) / (sigma_1 + sigma_3) lies in [0, 1] where the material
//! is in compression. Cells with sigma_1 + sigma_3 <= 0 (net tension, which a
//! cohesionless packing cannot carry) have no gamma.

use super::coarse_grain::{CgParams, RzField, Sym, sym_matrix};
use anyhow::{Result, bail};
use nalgebra::{Matrix3, SymmetricEigen};
use serde::Serialize;

/// sin phi averages gamma over cells within this fraction of gamma_max (paper: 0.995).
pub(crate) const TOP_FRACTION: f64 = 0.995;
/// Incipient-yield threshold as a fraction of sin phi (paper: 0.85).
pub(crate) const YIELD_FRACTION: f64 = 0.85;
/// A grain moves "with the intruder" when |v_z - v_intruder| is below this fraction of
/// the intruder speed (stagnant-zone criterion).
pub(crate) const STAGNANT_FRACTION: f64 = 0.1;
/// Cells need a kernel solid fraction of at least this fraction of the bed's packing
/// fraction: excludes the free surface, the intruder's interior and loose regions where
/// the few grains in the kernel make gamma meaningless.
pub(crate) const MIN_SOLID_FRACTION_REL: f64 = 0.75;

/// Principal stresses, sigma_1 >= sigma_2 >= sigma_3 (compressive positive).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Principal {
    pub s1: f64,
    pub s2: f64,
    pub s3: f64,
}

/// Eigenvalues of a symmetric stress by nalgebra's symmetric eigen-decomposition,
/// sorted descending.
pub fn principal(s: &Sym) -> Principal {
    let m = sym_matrix(s);
    let a = Matrix3::from_fn(|i, j| m[i][j]);
    let e = SymmetricEigen::new(a).eigenvalues;
    let mut v = [e[0], e[1], e[2]];
    v.sort_by(|a, b| b.total_cmp(a));
    Principal {
        s1: v[0],
        s2: v[1],
        s3: v[2],
    }
}

/// Eq 8: gamma = (s1 - s3) / (s1 + s3); `None` without net compression or if not finite.
pub fn gamma(p: &Principal) -> Option<f64> {
    let den = p.s1 + p.s3;
    let g = (p.s1 - p.s3) / den;
    (den > 0.0 && g.is_finite()).then_some(g)
}

/// Which cells of an (r, z) field count, and why (all lengths SI).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Mask {
    pub min_solid_fraction: f64,
    /// Largest cell radius: the kernel/basic sphere must not reach grains touching the
    /// container wall, whose (primitive-wall) contacts LIGGGHTS does not report.
    pub r_max: f64,
    /// Lowest cell height, for the same reason at the floor.
    pub z_min: f64,
}

impl Mask {
    /// The mask for a bed of packing fraction `psi` in a container of radius
    /// `container_radius` with its floor at `floor_z`, grains of diameter up to `d_max`.
    pub(crate) fn for_bed(
        params: &CgParams,
        psi: f64,
        container_radius: f64,
        floor_z: f64,
        d_max: f64,
    ) -> Mask {
        let reach = params.cutoff.max(params.basic_radius) + d_max;
        Mask {
            min_solid_fraction: MIN_SOLID_FRACTION_REL * psi,
            r_max: container_radius - reach,
            z_min: floor_z + reach,
        }
    }

    pub(crate) fn cells(&self, f: &RzField) -> Vec<bool> {
        let mut m = vec![false; f.nr * f.nz];
        for k in 0..f.nz {
            for i in 0..f.nr {
                let c = f.idx(i, k);
                m[c] = f.r(i) <= self.r_max
                    && f.z(k) >= self.z_min
                    && f.solid_fraction[c] >= self.min_solid_fraction;
            }
        }
        m
    }
}

/// sin phi from a gamma field: the paper's estimator.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PhiEstimate {
    pub sin_phi: f64,
    pub phi_deg: f64,
    pub gamma_max: f64,
    /// Cells averaged (0.995 gamma_max <= gamma <= gamma_max).
    pub n_top: usize,
    /// Cells that passed the mask and had a gamma.
    pub n_cells: usize,
}

/// sin phi = mean gamma over the masked cells with `TOP_FRACTION * gamma_max <= gamma`.
pub fn phi_from_gamma(gamma: &[Option<f64>], mask: &[bool]) -> Result<PhiEstimate> {
    if gamma.len() != mask.len() {
        bail!(
            "phi: {} gamma values but {} mask entries",
            gamma.len(),
            mask.len()
        );
    }
    let vals: Vec<f64> = gamma
        .iter()
        .zip(mask)
        .filter_map(|(g, &m)| if m { *g } else { None })
        .collect();
    if vals.is_empty() {
        bail!("phi: no cell passed the mask with a defined gamma (net compression)");
    }
    let gmax = vals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let top: Vec<f64> = vals
        .iter()
        .copied()
        .filter(|&g| g >= TOP_FRACTION * gmax)
        .collect();
    let sin_phi = top.iter().sum::<f64>() / top.len() as f64;
    if !(0.0..1.0).contains(&sin_phi) {
        bail!("phi: sin phi = {sin_phi} outside [0, 1) (gamma_max {gmax})");
    }
    Ok(PhiEstimate {
        sin_phi,
        phi_deg: sin_phi.asin().to_degrees(),
        gamma_max: gmax,
        n_top: top.len(),
        n_cells: vals.len(),
    })
}

/// Everything derived from one (r, z) field.
#[derive(Debug, Clone, Serialize)]
pub struct FieldAnalysis {
    pub mask: Vec<bool>,
    pub gamma_basic: Vec<Option<f64>>,
    pub gamma_kernel: Vec<Option<f64>>,
    pub phi_basic: Result<PhiEstimate, String>,
    pub phi_kernel: Result<PhiEstimate, String>,
    /// gamma_basic >= 0.85 sin phi_basic (masked cells).
    pub yield_basic: Vec<bool>,
    /// Cells below the intruder's bottom, inside its radius, moving with it.
    pub stagnant: Vec<bool>,
    /// Stagnant-zone height on the axis below the intruder, in units of R.
    pub stagnant_height: f64,
}

/// Analyses an (r, z) field; `intruder_bottom_z`, `intruder_radius` and `intruder_vz`
/// locate and drive the intruder.
pub(crate) fn analyse(
    f: &RzField,
    mask: &Mask,
    intruder_bottom_z: f64,
    intruder_radius: f64,
    intruder_vz: f64,
) -> FieldAnalysis {
    let m = mask.cells(f);
    let g = |s: &Vec<Sym>| -> Vec<Option<f64>> { s.iter().map(|t| gamma(&principal(t))).collect() };
    let gamma_basic = g(&f.stress_basic);
    let gamma_kernel = g(&f.stress_kernel);
    let phi_basic = phi_from_gamma(&gamma_basic, &m).map_err(|e| format!("{e:#}"));
    let phi_kernel = phi_from_gamma(&gamma_kernel, &m).map_err(|e| format!("{e:#}"));
    let yield_basic = match &phi_basic {
        Ok(p) => gamma_basic
            .iter()
            .zip(&m)
            .map(|(g, &ok)| ok && g.is_some_and(|g| g >= YIELD_FRACTION * p.sin_phi))
            .collect(),
        Err(_) => vec![false; m.len()],
    };
    let speed = intruder_vz.abs();
    let mut stagnant = vec![false; m.len()];
    for k in 0..f.nz {
        for i in 0..f.nr {
            let c = f.idx(i, k);
            let v = f.velocity[c];
            stagnant[c] = speed > 0.0
                && f.r(i) < intruder_radius
                && f.z(k) < intruder_bottom_z
                && f.solid_fraction[c] >= mask.min_solid_fraction
                && v[2].is_finite()
                && (v[2] - intruder_vz).abs() < STAGNANT_FRACTION * speed;
        }
    }
    // Contiguous stagnant cells on the axis column, from just below the bottom down.
    // The first cells under the face hold little material (the kernel overlaps the
    // intruder); they are skipped, for at most three cells, before the run must start.
    let mut lowest = None;
    let mut skipped = 0;
    for k in (0..f.nz).rev() {
        if f.z(k) >= intruder_bottom_z {
            continue;
        }
        let c = f.idx(0, k);
        if stagnant[c] {
            lowest = Some(k);
        } else if lowest.is_none() && f.solid_fraction[c] < mask.min_solid_fraction && skipped < 3 {
            skipped += 1;
        } else {
            break;
        }
    }
    let stagnant_height = match lowest {
        Some(k) => (intruder_bottom_z - (f.z(k) - 0.5 * f.spacing)) / intruder_radius,
        None => 0.0,
    };
    FieldAnalysis {
        mask: m,
        gamma_basic,
        gamma_kernel,
        phi_basic,
        phi_kernel,
        yield_basic,
        stagnant,
        stagnant_height,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn principal_sorted_and_rotation_invariant() {
        // diag(3, 1, 2) rotated by 30 degrees about z.
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let (a, b) = (3.0, 1.0);
        let t = [
            a * c * c + b * s * s,
            a * s * s + b * c * c,
            2.0,
            (a - b) * c * s,
            0.0,
            0.0,
        ];
        let p = principal(&t);
        assert!((p.s1 - 3.0).abs() < 1e-12 && (p.s2 - 2.0).abs() < 1e-12);
        assert!((p.s3 - 1.0).abs() < 1e-12);
        assert!((gamma(&p).unwrap() - 0.5).abs() < 1e-12);
        assert!(gamma(&principal(&[-1.0, -2.0, -3.0, 0.0, 0.0, 0.0])).is_none());
    }

    #[test]
    fn phi_estimator_averages_top_cells() {
        let g = vec![Some(0.5), Some(0.499), Some(0.3), None, Some(0.9)];
        let mask = vec![true, true, true, true, false];
        let p = phi_from_gamma(&g, &mask).unwrap();
        assert_eq!((p.n_top, p.n_cells), (2, 3));
        assert!((p.sin_phi - 0.4995).abs() < 1e-12 && p.gamma_max == 0.5);
        assert!(phi_from_gamma(&g, &[false; 5]).is_err());
        assert!(phi_from_gamma(&g, &[true; 4]).is_err());
    }
}
