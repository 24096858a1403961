//! The intruder force series of a penetration run (`force.csv`), the same for every
//! engine.

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::Path;

/// The intruder at one output step of a penetration run, SI: time, height of its
/// bottom face, and the total force the grains exert on it (+z resists a downward push).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ForceSample {
    pub t: f64,
    pub z_bottom: f64,
    pub f: [f64; 3],
}

/// Writes `force.csv` (t, z_bottom, fx, fy, fz; SI, full precision).
pub(crate) fn write_force_csv(path: &Path, samples: &[ForceSample]) -> Result<()> {
    let mut w = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?,
    );
    writeln!(w, "t,z_bottom,fx,fy,fz")?;
    for s in samples {
        writeln!(
            w,
            "{:e},{:e},{:e},{:e},{:e}",
            s.t, s.z_bottom, s.f[0], s.f[1], s.f[2]
        )?;
    }
    Ok(())
}

/// Reads a `force.csv` written by [`write_force_csv`].
pub fn read_force_csv(path: &Path) -> Result<Vec<ForceSample>> {
    let mut r = csv::Reader::from_reader(super::fsio::open_engine_output(path, "a force CSV")?);
    let mut out = Vec::new();
    for (k, rec) in r.records().enumerate() {
        let rec = rec.with_context(|| format!("{}: record {}", path.display(), k + 2))?;
        let v = |i: usize| -> Result<f64> {
            rec[i].parse::<f64>().with_context(|| {
                format!(
                    "{}: line {}: column {} = {:?}",
                    path.display(),
                    k + 2,
                    i + 1,
                    &rec[i]
                )
            })
        };
        out.push(ForceSample {
            t: v(0)?,
            z_bottom: v(1)?,
            f: [v(2)?, v(3)?, v(4)?],
        });
    }
    Ok(out)
}
