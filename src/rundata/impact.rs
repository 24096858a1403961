//! The series of a 2D impact run: intruder samples (`intruder.csv`) and energies
//! (`energy.csv`), the same for every engine.

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::Path;

/// The intruder at one output step (SI): centre of mass, velocity, contact force; and,
/// in cases that track it (K Fig 12), the interface height at the same step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IntruderSample {
    pub step: u64,
    pub t: f64,
    pub x: [f64; 2],
    pub v: [f64; 2],
    pub f: [f64; 2],
    /// Centre of mass in y of the interface tracers (m); None when not tracked.
    pub interface_y: Option<f64>,
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

/// `intruder.csv`: t, step, x, y, vx, vy, fx, fy, D (SI, full precision); when the
/// samples carry the interface height (K Fig 12), also `interface_y` and the derived
/// `interface_s` (its rise since the first sample). Every sample tracks it or none.
pub(crate) fn write_intruder_csv(
    path: &Path,
    s: &[IntruderSample],
    surface: f64,
    bottom_offset: f64,
) -> Result<()> {
    let tracked = s.first().is_some_and(|p| p.interface_y.is_some());
    if let Some(p) = s.iter().find(|p| p.interface_y.is_some() != tracked) {
        anyhow::bail!(
            "{}: the interface height is recorded at some intruder samples but not at step {}",
            path.display(),
            p.step
        );
    }
    let y0 = s.first().and_then(|p| p.interface_y).unwrap_or(0.0);
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(
        w,
        "t,step,x,y,vx,vy,fx,fy,depth{}",
        if tracked {
            ",interface_y,interface_s"
        } else {
            ""
        }
    )?;
    for p in s {
        write!(
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
        match p.interface_y {
            Some(y) => writeln!(w, ",{y:e},{:e}", y - y0)?,
            None => writeln!(w)?,
        }
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
    /// Only in the files of cases that track the interface.
    #[serde(default)]
    interface_y: Option<f64>,
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
    let mut r = csv::Reader::from_reader(super::fsio::open_engine_output(
        path,
        "an impact-series CSV",
    )?);
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
            interface_y: r.interface_y,
        })
        .collect())
}

/// `energy.csv`: t, step, kinetic, potential (relative to the first), elastic.
pub(crate) fn write_energy_csv(path: &Path, e: &[EnergySample]) -> Result<()> {
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

/// A grain's position in a field snapshot (SI).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GrainPos {
    pub id: u64,
    pub x: [f64; 2],
}

/// One touching pair in a field snapshot: the magnitudes of its normal and tangential
/// contact forces (N), as the contact law gives them at the end of the step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ContactForce {
    pub i: u64,
    pub j: u64,
    #[serde(rename = "fn")]
    pub f_n: f64,
    pub ft: f64,
}

/// The bed at one step (K Sec. IV): every grain's position and, where asked for, every
/// touching pair's force (grains, walls and intruder alike, by atom id).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FieldSnapshot {
    pub step: u64,
    pub grains: Vec<GrainPos>,
    /// None where the snapshot carries positions only.
    pub contacts: Option<Vec<ContactForce>>,
}

const GRAINS_HEAD: &str = "step,id,x,y";
const CONTACTS_HEAD: &str = "step,i,j,fn,ft";

/// `grains.csv` (step, id, x, y) and `contacts.csv` (step, i, j, fn, ft) of the field
/// snapshots, SI, shortest round-trip numbers.
pub(crate) fn write_fields_csv(
    grains: &Path,
    contacts: &Path,
    snaps: &[FieldSnapshot],
) -> Result<()> {
    let mut g = std::io::BufWriter::new(
        std::fs::File::create(grains)
            .with_context(|| format!("cannot write {}", grains.display()))?,
    );
    let mut c = std::io::BufWriter::new(
        std::fs::File::create(contacts)
            .with_context(|| format!("cannot write {}", contacts.display()))?,
    );
    writeln!(g, "{GRAINS_HEAD}")?;
    writeln!(c, "{CONTACTS_HEAD}")?;
    for s in snaps {
        for p in &s.grains {
            writeln!(g, "{},{},{:e},{:e}", s.step, p.id, p.x[0], p.x[1])?;
        }
        for k in s.contacts.iter().flatten() {
            writeln!(c, "{},{},{},{:e},{:e}", s.step, k.i, k.j, k.f_n, k.ft)?;
        }
    }
    g.flush()?;
    c.flush()?;
    Ok(())
}

#[derive(Deserialize)]
struct GrainRow {
    step: u64,
    id: u64,
    x: f64,
    y: f64,
}

#[derive(Deserialize)]
struct ContactRow {
    step: u64,
    i: u64,
    j: u64,
    #[serde(rename = "fn")]
    f_n: f64,
    ft: f64,
}

/// Reads what [`write_fields_csv`] wrote; `contact_steps` are the snapshots that carry
/// contacts (an empty contact list there is a snapshot without touching pairs).
pub(crate) fn read_fields_csv(
    grains: &Path,
    contacts: &Path,
    contact_steps: &[u64],
) -> Result<Vec<FieldSnapshot>> {
    let mut out: Vec<FieldSnapshot> = Vec::new();
    for r in read_rows::<GrainRow>(grains)? {
        if out.last().is_none_or(|s| s.step != r.step) {
            out.push(FieldSnapshot {
                step: r.step,
                grains: Vec::new(),
                contacts: contact_steps.contains(&r.step).then(Vec::new),
            });
        }
        let s = out.last_mut().expect("pushed above");
        s.grains.push(GrainPos {
            id: r.id,
            x: [r.x, r.y],
        });
    }
    for r in read_rows::<ContactRow>(contacts)? {
        let s = out.iter_mut().find(|s| s.step == r.step).with_context(|| {
            format!(
                "{}: contacts at step {} without grains",
                contacts.display(),
                r.step
            )
        })?;
        s.contacts
            .as_mut()
            .with_context(|| {
                format!(
                    "{}: contacts at step {}, which is not a network step",
                    contacts.display(),
                    r.step
                )
            })?
            .push(ContactForce {
                i: r.i,
                j: r.j,
                f_n: r.f_n,
                ft: r.ft,
            });
    }
    Ok(out)
}
