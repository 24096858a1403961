//! The series of a 2D impact run: intruder samples (`intruder.csv`) and energies
//! (`energy.csv`), the same for every engine.

use anyhow::{Context, Result};
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
