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

use crate::dem2d::neighbor::{Box2, Excluded, PairList};
use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::Path;

/// The intruder at one output step (SI): centre of mass, velocity, contact force.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IntruderSample {
    pub step: u64,
    pub t: f64,
    pub x: [f64; 2],
    pub v: [f64; 2],
    pub f: [f64; 2],
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EnergySample {
    pub step: u64,
    pub t: f64,
    pub kinetic: f64,
    /// `sum m g y` (absolute; [`relative_potential`] subtracts the first).
    pub potential: f64,
    pub elastic: f64,
}

/// One disk of a snapshot, as far as energies need it.
#[derive(Debug, Clone, Copy)]
pub struct SnapDisk {
    pub type_: usize,
    pub radius: f64,
    pub mass: f64,
    pub x: [f64; 2],
    pub v: [f64; 2],
    pub omega: f64,
}

/// Which disks take part, and the normal stiffness of each type pair.
pub struct EnergyModel {
    pub n_types: usize,
    /// `kn[a * n_types + b]`; `None` for pairs that do not interact.
    pub kn: Vec<Option<f64>>,
    /// Types whose disks never move (walls): no kinetic or potential energy.
    pub frozen_type: Vec<bool>,
    pub gravity: f64,
    pub bx: Box2,
}

struct TypeExcl<'a> {
    model: &'a EnergyModel,
    types: &'a [usize],
}

impl Excluded for TypeExcl<'_> {
    fn excluded(&self, i: usize, j: usize) -> bool {
        let n = self.model.n_types;
        self.model.kn[self.types[i] * n + self.types[j]].is_none()
    }
}

pub fn energies(step: u64, t: f64, disks: &[SnapDisk], model: &EnergyModel) -> EnergySample {
    let mut kinetic = 0.0;
    let mut potential = 0.0;
    for d in disks {
        if model.frozen_type[d.type_] {
            continue;
        }
        kinetic += 0.5 * d.mass * (d.v[0] * d.v[0] + d.v[1] * d.v[1])
            + 0.25 * d.mass * d.radius * d.radius * d.omega * d.omega;
        potential += d.mass * model.gravity * d.x[1];
    }
    let x: Vec<[f64; 2]> = disks.iter().map(|d| d.x).collect();
    let r: Vec<f64> = disks.iter().map(|d| d.radius).collect();
    let types: Vec<usize> = disks.iter().map(|d| d.type_).collect();
    let mut list = PairList::default();
    list.build(
        &model.bx,
        &x,
        &r,
        0.0,
        &TypeExcl {
            model,
            types: &types,
        },
    );
    let mut elastic = 0.0;
    for &(i, j) in &list.pairs {
        let (i, j) = (i as usize, j as usize);
        let d = model.bx.delta(x[i], x[j]);
        let overlap = r[i] + r[j] - (d[0] * d[0] + d[1] * d[1]).sqrt();
        if overlap > 0.0 {
            let k = model.kn[types[i] * model.n_types + types[j]].unwrap_or(0.0);
            elastic += 0.5 * k * overlap * overlap;
        }
    }
    EnergySample {
        step,
        t,
        kinetic,
        potential,
        elastic,
    }
}

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

/// `intruder.csv`: t, step, x, y, vx, vy, fx, fy, D (SI, full precision).
pub fn write_intruder_csv(
    path: &Path,
    s: &[IntruderSample],
    surface: f64,
    bottom_offset: f64,
) -> Result<()> {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(w, "t,step,x,y,vx,vy,fx,fy,depth")?;
    for p in s {
        writeln!(
            w,
            "{:e},{},{:e},{:e},{:e},{:e},{:e},{:e},{:e}",
            p.t,
            p.step,
            p.x[0],
            p.x[1],
            p.v[0],
            p.v[1],
            p.f[0],
            p.f[1],
            surface - (p.x[1] - bottom_offset)
        )?;
    }
    Ok(())
}

/// One row of `intruder.csv` (the `depth` column is derived, not read back).
#[derive(Deserialize)]
struct IntruderRow {
    t: f64,
    step: u64,
    x: f64,
    y: f64,
    vx: f64,
    vy: f64,
    fx: f64,
    fy: f64,
}

/// One row of `energy.csv`.
#[derive(Deserialize)]
struct EnergyRow {
    t: f64,
    step: u64,
    kinetic: f64,
    potential_abs: f64,
    elastic: f64,
}

/// Every row of a headed CSV file; an error names the file (csv names line and field).
fn read_rows<T: serde::de::DeserializeOwned>(path: &Path) -> Result<Vec<T>> {
    let mut r =
        csv::Reader::from_path(path).with_context(|| format!("cannot open {}", path.display()))?;
    r.deserialize()
        .map(|row| row.with_context(|| format!("{}", path.display())))
        .collect()
}

pub fn read_intruder_csv(path: &Path) -> Result<Vec<IntruderSample>> {
    Ok(read_rows::<IntruderRow>(path)?
        .into_iter()
        .map(|r| IntruderSample {
            t: r.t,
            step: r.step,
            x: [r.x, r.y],
            v: [r.vx, r.vy],
            f: [r.fx, r.fy],
        })
        .collect())
}

/// `energy.csv`: t, step, kinetic, potential (relative to the first), elastic.
pub fn write_energy_csv(path: &Path, e: &[EnergySample]) -> Result<()> {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(w, "t,step,kinetic,potential_abs,elastic")?;
    for s in e {
        writeln!(
            w,
            "{:e},{},{:e},{:e},{:e}",
            s.t, s.step, s.kinetic, s.potential, s.elastic
        )?;
    }
    Ok(())
}

pub fn read_energy_csv(path: &Path) -> Result<Vec<EnergySample>> {
    Ok(read_rows::<EnergyRow>(path)?
        .into_iter()
        .map(|r| EnergySample {
            t: r.t,
            step: r.step,
            kinetic: r.kinetic,
            potential: r.potential_abs,
            elastic: r.elastic,
        })
        .collect())
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
