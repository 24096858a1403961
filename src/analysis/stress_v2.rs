//! Estimator v2 of the internal friction angle (docs/stress.md, "Validating the
//! estimator", rule 2 and "How the pre-registration is read"), fixed from the paper's
//! text before it was run: Feng et al. record gamma "at each time step" of the steady
//! state (regime C) and read phi where gamma is largest (Sec. 2 after eq 9, eq 8).
//!
//! v1 (`stress_fields`) takes the 0.995 band of gamma_max of a five-snapshot window,
//! an extreme-value statistic that on CI-scale fields reads noise. v2 averages the
//! eq 9 stress tensor cell by cell over *every* regime-C snapshot of *every* bed (in
//! the intruder's frame), and admits a cell into the band only when a two-level
//! bootstrap (beds, then snapshots) says its gamma is known to 0.01: the maximum is
//! then taken over cells whose gamma is a property of the material, not of the draw.

use super::coarse_grain::{CgParams, CoarseGrainer, RzField, azimuthal_average};
use super::stress::{self, Mask, gamma, principal};
use super::stress_fields::{Forces, N_THETA, mean_rz};
use crate::rundata::snapshot::{self, SnapshotMeta};
use anyhow::{Context, Result, bail, ensure};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Bootstrap resamples (rule 2).
pub(crate) const RESAMPLES: usize = 200;
/// Seed of the bootstrap's xorshift64 (rule 2: the date of the pre-registration).
pub(crate) const SEED: u64 = 20261123;
/// A cell is admitted only if the bootstrap standard error of its gamma is at most this.
pub(crate) const MAX_GAMMA_SE: f64 = 0.01;
/// ... and its kernel holds a grain in at least this many snapshots.
pub(crate) const MIN_GRAIN_SNAPSHOTS: usize = 10;

/// Marsaglia's xorshift64 with shifts (13, 7, 17), as pre-registered; an index below n
/// is `next() % n`. Written out (not a crate) because the exact sequence is part of the
/// registered method and both engines must draw the same one.
#[derive(Debug, Clone)]
pub(crate) struct Xorshift64(u64);

impl Xorshift64 {
    pub fn new(seed: u64) -> Self {
        Xorshift64(seed.max(1))
    }
    pub(crate) fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        self.0 = x;
        x
    }
    pub fn index(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
}

/// The regime-C snapshots of one bed of one engine: a snapshot directory and the
/// snapshot file numbers to use.
#[derive(Debug, Clone)]
pub struct BedSnapshots {
    pub dir: PathBuf,
    pub ks: Vec<usize>,
}

/// The snapshot numbers of `dir` whose depth (meta h) lies in [h_lo, h_hi], with their
/// steps.
pub fn snapshots_in_range(dir: &Path, h_lo: f64, h_hi: f64) -> Result<(Vec<usize>, Vec<u64>)> {
    let mut ks = Vec::new();
    let mut steps = Vec::new();
    for k in snapshot::list(dir)? {
        let m = snapshot::read_meta(dir, k)?;
        if m.h >= h_lo && m.h <= h_hi {
            ks.push(k);
            steps.push(m.step);
        }
    }
    Ok((ks, steps))
}

/// v2's result for one engine.
#[derive(Debug, Clone, Serialize)]
pub struct PhiV2 {
    pub engine: String,
    pub phi_deg: f64,
    /// Sample sd of phi over the bootstrap resamples (deg).
    pub sd_deg: f64,
    pub sin_phi: f64,
    pub gamma_max: f64,
    /// Where gamma_max sits: r / R and depth below the intruder's face / R (negative:
    /// above the face, beside the intruder).
    pub gamma_max_r: f64,
    pub gamma_max_depth: f64,
    /// Cells through the v1 mask on the pooled field, cells admitted (mask, SE <= 0.01,
    /// grains in >= 10 snapshots), cells in the 0.995 band.
    pub n_masked: usize,
    pub n_admitted: usize,
    pub n_top: usize,
    pub n_beds: usize,
    pub n_snapshots: usize,
    /// Depth range of the snapshots (units of R).
    pub h_lo: f64,
    pub h_hi: f64,
    /// v1's band rule on the same pooled field without the SE admission (diagnostic).
    pub phi_pooled_v1_deg: Option<f64>,
    /// phi of each resample (deg; NaN where the resample had no admitted gamma).
    #[serde(skip)]
    pub resample_phi_deg: Vec<f64>,
}

/// Mean and sample sd (n - 1) of the finite values.
fn mean_sd(v: &[f64]) -> (f64, f64) {
    let f: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if f.len() < 2 {
        return (f.first().copied().unwrap_or(f64::NAN), f64::NAN);
    }
    let m = f.iter().sum::<f64>() / f.len() as f64;
    let s = (f.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (f.len() - 1) as f64).sqrt();
    (m, s)
}

/// sin phi by the band rule over the cells `cells` of `g` (None where undefined).
fn band(g: &[Option<f64>], cells: &[usize]) -> Option<(f64, f64, usize, usize)> {
    let mut gmax = f64::NEG_INFINITY;
    let mut arg = usize::MAX;
    for &c in cells {
        if let Some(x) = g[c]
            && x > gmax
        {
            gmax = x;
            arg = c;
        }
    }
    if arg == usize::MAX {
        return None;
    }
    let top: Vec<f64> = cells
        .iter()
        .filter_map(|&c| g[c])
        .filter(|&x| x >= stress::TOP_FRACTION * gmax)
        .collect();
    let s = top.iter().sum::<f64>() / top.len() as f64;
    (0.0..1.0).contains(&s).then_some((s, gmax, arg, top.len()))
}

/// Estimator v2 of one engine from the regime-C snapshots of its beds. `kernel_width`
/// is w / d_g (d_g / 2 as pre-registered); the grid spacing is w.
pub fn estimate(
    engine: &str,
    beds: &[BedSnapshots],
    forces: Forces,
    kernel_width: f64,
) -> Result<PhiV2> {
    ensure!(!beds.is_empty(), "{engine}: v2 needs at least one bed");
    // Metadata of every snapshot first: the common grid and the frame.
    let mut metas: Vec<Vec<SnapshotMeta>> = Vec::with_capacity(beds.len());
    for b in beds {
        ensure!(
            !b.ks.is_empty(),
            "{engine}: {}: no snapshot in regime C's range",
            b.dir.display()
        );
        metas.push(
            b.ks.iter()
                .map(|&k| snapshot::read_meta(&b.dir, k))
                .collect::<Result<_>>()?,
        );
    }
    let all: Vec<&SnapshotMeta> = metas.iter().flatten().collect();
    let m0 = all[0];
    for m in &all {
        ensure!(
            m.mean_diameter == m0.mean_diameter
                && m.container_radius == m0.container_radius
                && m.floor_z == m0.floor_z
                && m.intruder_radius == m0.intruder_radius,
            "{engine}: the pooled snapshots differ in grain size or geometry (step {})",
            m.step
        );
    }
    let zb_ref = all
        .iter()
        .map(|m| m.intruder_bottom_z)
        .fold(f64::NEG_INFINITY, f64::max);
    let lowest = all
        .iter()
        .map(|m| m.intruder_bottom_z - zb_ref)
        .fold(0.0, f64::min);
    let surface = all
        .iter()
        .map(|m| m.surface_z)
        .fold(f64::NEG_INFINITY, f64::max);
    let params = CgParams::with_width(m0.mean_diameter, kernel_width * m0.mean_diameter)?;
    let spacing = params.w;
    let nr = (m0.container_radius / spacing).ceil() as usize;
    let nz = ((surface + m0.mean_diameter - lowest - m0.floor_z) / spacing).ceil() as usize;
    ensure!(nr > 0 && nz > 0, "{engine}: empty (r, z) grid");
    // Coarse-grain every snapshot on its shifted grid (cell k at the same height above
    // or below the face in all of them).
    let mut fields: Vec<Vec<RzField>> = Vec::with_capacity(beds.len());
    let mut d_max: f64 = 0.0;
    for (b, ms) in beds.iter().zip(&metas) {
        let mut v = Vec::with_capacity(b.ks.len());
        for (&k, m) in b.ks.iter().zip(ms) {
            let mut s = snapshot::read(&b.dir, k)?;
            ensure!(
                s.meta.step == m.step,
                "{}: snapshot {k} changed",
                b.dir.display()
            );
            if forces == Forces::NormalOnly {
                s.drop_tangential();
            }
            d_max = d_max.max(s.grains.iter().map(|g| 2.0 * g.radius).fold(0.0, f64::max));
            let cg = CoarseGrainer::new(&s, s.common_contacts(), params)
                .with_context(|| format!("{}: snapshot {k}", b.dir.display()))?;
            let dz = m.intruder_bottom_z - zb_ref;
            v.push(azimuthal_average(
                &cg,
                spacing,
                nr,
                nz,
                m0.floor_z + dz,
                N_THETA,
            ));
        }
        fields.push(v);
    }
    let psi_mean = metas.iter().map(|m| m[0].psi).sum::<f64>() / metas.len() as f64;
    let base = Mask::for_bed(&params, psi_mean, m0.container_radius, m0.floor_z, d_max);
    let mask = Mask {
        z_min: base.z_min - lowest,
        ..base
    };
    let flat: Vec<RzField> = fields.iter().flatten().cloned().collect();
    let n_snap = flat.len();
    let pooled = mean_rz(&flat, m0.floor_z);
    drop(flat);
    let n_cells = nr * nz;
    let masked = mask.cells(&pooled);
    let g_full: Vec<Option<f64>> = pooled
        .stress_basic
        .iter()
        .map(|t| gamma(&principal(t)))
        .collect();
    let masked_cells: Vec<usize> = (0..n_cells).filter(|&c| masked[c]).collect();
    let phi_pooled_v1_deg = band(&g_full, &masked_cells).map(|b| b.0.asin().to_degrees());
    // Snapshots in which the cell's kernel holds a grain.
    let mut grain_count = vec![0usize; n_cells];
    for f in fields.iter().flatten() {
        for (c, &sf) in f.solid_fraction.iter().enumerate() {
            if sf > 0.0 {
                grain_count[c] += 1;
            }
        }
    }
    // Two-level bootstrap: beds with replacement, then that bed's snapshots.
    let mut rng = Xorshift64::new(SEED);
    let mut g_res: Vec<Vec<Option<f64>>> = Vec::with_capacity(RESAMPLES);
    for _ in 0..RESAMPLES {
        let mut sum = vec![[0.0f64; 6]; masked_cells.len()];
        let mut n = 0usize;
        for _ in 0..beds.len() {
            let bi = rng.index(beds.len());
            let nk = fields[bi].len();
            for _ in 0..nk {
                let f = &fields[bi][rng.index(nk)];
                for (s, &c) in sum.iter_mut().zip(&masked_cells) {
                    for (a, x) in s.iter_mut().zip(&f.stress_basic[c]) {
                        *a += x;
                    }
                }
                n += 1;
            }
        }
        let mut g = vec![None; n_cells];
        for (s, &c) in sum.iter().zip(&masked_cells) {
            let t = s.map(|x| x / n as f64);
            g[c] = gamma(&principal(&t));
        }
        g_res.push(g);
    }
    let admitted: Vec<usize> = masked_cells
        .iter()
        .copied()
        .filter(|&c| {
            if g_full[c].is_none() || grain_count[c] < MIN_GRAIN_SNAPSHOTS {
                return false;
            }
            let vals: Vec<f64> = g_res.iter().filter_map(|g| g[c]).collect();
            if vals.len() < RESAMPLES {
                return false; // undefined in some resample: SE = infinity
            }
            mean_sd(&vals).1 <= MAX_GAMMA_SE
        })
        .collect();
    let Some((sin_phi, gmax, arg, n_top)) = band(&g_full, &admitted) else {
        bail!(
            "{engine}: v2 admitted no cell ({} masked cells, none with a bootstrap SE of gamma <= {MAX_GAMMA_SE} and grains in >= {MIN_GRAIN_SNAPSHOTS} snapshots)",
            masked_cells.len()
        );
    };
    let resample_phi_deg: Vec<f64> = g_res
        .iter()
        .map(|g| band(g, &admitted).map_or(f64::NAN, |b| b.0.asin().to_degrees()))
        .collect();
    let (_, sd_deg) = mean_sd(&resample_phi_deg);
    let (i, k) = (arg % nr, arg / nr);
    let h_of = |m: &SnapshotMeta| m.h;
    Ok(PhiV2 {
        engine: engine.to_string(),
        phi_deg: sin_phi.asin().to_degrees(),
        sd_deg,
        sin_phi,
        gamma_max: gmax,
        gamma_max_r: pooled.r(i) / m0.intruder_radius,
        gamma_max_depth: (zb_ref - pooled.z(k)) / m0.intruder_radius,
        n_masked: masked_cells.len(),
        n_admitted: admitted.len(),
        n_top,
        n_beds: beds.len(),
        n_snapshots: n_snap,
        h_lo: all.iter().map(|m| h_of(m)).fold(f64::INFINITY, f64::min),
        h_hi: all
            .iter()
            .map(|m| h_of(m))
            .fold(f64::NEG_INFINITY, f64::max),
        phi_pooled_v1_deg,
        resample_phi_deg,
    })
}

/// The paired bootstrap sd of phi_test - phi_ref: both engines drew the same beds and
/// snapshot positions in resample b (same seed, same counts); None if the counts differ.
pub fn paired_sd(test: &PhiV2, reference: &PhiV2) -> Option<f64> {
    if test.resample_phi_deg.len() != reference.resample_phi_deg.len()
        || test.n_snapshots != reference.n_snapshots
        || test.n_beds != reference.n_beds
    {
        return None;
    }
    let d: Vec<f64> = test
        .resample_phi_deg
        .iter()
        .zip(&reference.resample_phi_deg)
        .map(|(a, b)| a - b)
        .collect();
    Some(mean_sd(&d).1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xorshift_sequence_is_marsaglias() {
        // Marsaglia (2003), xorshift64 (13, 7, 17): first outputs from seed 1.
        let mut r = Xorshift64::new(1);
        assert_eq!(r.next_u64(), 1082269761);
        assert_eq!(r.next_u64(), 1152992998833853505);
    }

    #[test]
    fn band_ignores_undefined_and_takes_the_top() {
        let g = vec![Some(0.5), Some(0.4999), None, Some(0.9), Some(0.1)];
        let (s, gmax, arg, n) = band(&g, &[0, 1, 2, 4]).unwrap();
        assert_eq!((gmax, arg, n), (0.5, 0, 2));
        assert!((s - 0.49995).abs() < 1e-12);
        assert!(band(&g, &[2]).is_none());
    }
}
