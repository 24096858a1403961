//! Per-particle time series of a micro run (`particles.csv`), the same for every engine.

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One particle at one output step, SI units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ParticleState {
    pub id: u64,
    pub x: [f64; 3],
    pub v: [f64; 3],
    pub omega: [f64; 3],
    pub f: [f64; 3],
}

/// All particles at one output step, sorted by id.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Frame {
    pub step: u64,
    pub t: f64,
    pub particles: Vec<ParticleState>,
}

/// Column order of `particles.csv`, fixed by the issue so scripts can rely on it.
pub const CSV_HEADER: [&str; 14] = [
    "t", "id", "x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz", "fx", "fy", "fz",
];

/// Writes frames as `particles.csv`. `{:e}` of an f64 is shortest-round-trip, so the
/// file carries full double precision without a fixed digit count.
pub fn write_particles_csv(path: &Path, frames: &[Frame]) -> Result<()> {
    let mut w = csv::Writer::from_path(path)
        .with_context(|| format!("cannot create {}", path.display()))?;
    w.write_record(CSV_HEADER)?;
    for fr in frames {
        for p in &fr.particles {
            let mut rec: Vec<String> = Vec::with_capacity(14);
            rec.push(format!("{:e}", fr.t));
            rec.push(p.id.to_string());
            for a in [p.x, p.v, p.omega, p.f] {
                for c in a {
                    rec.push(format!("{c:e}"));
                }
            }
            w.write_record(&rec)?;
        }
    }
    w.flush()?;
    Ok(())
}

/// Reads `particles.csv` back into frames (grouped by consecutive equal `t`). Step
/// numbers are recovered from `t / dt`.
pub fn read_particles_csv(path: &Path, dt: f64) -> Result<Vec<Frame>> {
    let mut r =
        csv::Reader::from_path(path).with_context(|| format!("cannot open {}", path.display()))?;
    let header: Vec<String> = r.headers()?.iter().map(str::to_string).collect();
    if header != CSV_HEADER {
        anyhow::bail!(
            "{}: header {:?} is not the expected {:?}",
            path.display(),
            header,
            CSV_HEADER
        );
    }
    let mut frames: Vec<Frame> = Vec::new();
    for (line, rec) in r.records().enumerate() {
        let rec = rec.with_context(|| format!("{}: record {}", path.display(), line + 2))?;
        let num = |k: usize| -> Result<f64> {
            rec[k].parse::<f64>().with_context(|| {
                format!(
                    "{}: line {}: column {} = {:?} is not a number",
                    path.display(),
                    line + 2,
                    CSV_HEADER[k],
                    &rec[k]
                )
            })
        };
        let t = num(0)?;
        let id: u64 = rec[1].parse().with_context(|| {
            format!(
                "{}: line {}: bad id {:?}",
                path.display(),
                line + 2,
                &rec[1]
            )
        })?;
        let v3 = |k: usize| -> Result<[f64; 3]> { Ok([num(k)?, num(k + 1)?, num(k + 2)?]) };
        let p = ParticleState {
            id,
            x: v3(2)?,
            v: v3(5)?,
            omega: v3(8)?,
            f: v3(11)?,
        };
        match frames.last_mut() {
            Some(fr) if fr.t == t => fr.particles.push(p),
            _ => frames.push(Frame {
                step: (t / dt).round() as u64,
                t,
                particles: vec![p],
            }),
        }
    }
    for fr in &mut frames {
        fr.particles.sort_by_key(|p| p.id);
    }
    Ok(frames)
}
