//! The wall series of a triaxial run (`walls.csv`), the same for every engine: every
//! output step, the positions of the three moving walls (the lo walls stay at 0) and the
//! normal force the grains exert on each of the six walls.

#[cfg(test)]
use anyhow::bail;
use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::Path;

/// The walls at one output step, SI. Forces are the components along +x, +y, +z of the
/// force of the grains on each wall: negative on the lo walls (pushed out along -axis),
/// positive on the hi walls.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WallRecord {
    pub step: u64,
    /// Positions of x_hi, y_hi, z_hi (m).
    pub hi: [f64; 3],
    /// Force components on x_lo, y_lo, z_lo along their axes (N).
    pub f_lo: [f64; 3],
    /// Force components on x_hi, y_hi, z_hi along their axes (N).
    pub f_hi: [f64; 3],
}

pub(crate) const HEADER: &str = "step,x_hi,y_hi,z_hi,f_xlo,f_ylo,f_zlo,f_xhi,f_yhi,f_zhi";

/// Writes `walls.csv` (full precision).
pub(crate) fn write_csv(path: &Path, records: &[WallRecord]) -> Result<()> {
    let mut w = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?,
    );
    writeln!(w, "{HEADER}")?;
    for r in records {
        writeln!(
            w,
            "{},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e}",
            r.step,
            r.hi[0],
            r.hi[1],
            r.hi[2],
            r.f_lo[0],
            r.f_lo[1],
            r.f_lo[2],
            r.f_hi[0],
            r.f_hi[1],
            r.f_hi[2]
        )?;
    }
    w.flush()?;
    Ok(())
}

/// Reads a `walls.csv` written by [`write_csv`]; errors name file, line and column.
#[cfg(test)]
pub(crate) fn read_csv(path: &Path) -> Result<Vec<WallRecord>> {
    let mut r = csv::Reader::from_reader(super::fsio::open_engine_output(path, "a walls CSV")?);
    let header: Vec<String> = r.headers()?.iter().map(str::to_string).collect();
    if header.join(",") != HEADER {
        bail!(
            "{}: header {:?}, expected {HEADER}",
            path.display(),
            header.join(",")
        );
    }
    let mut out = Vec::new();
    for (k, rec) in r.records().enumerate() {
        let rec = rec.with_context(|| format!("{}: record {}", path.display(), k + 2))?;
        let v = |i: usize| -> Result<f64> {
            let x: f64 = rec[i].parse().with_context(|| {
                format!(
                    "{}: line {}: column {} = {:?}",
                    path.display(),
                    k + 2,
                    i + 1,
                    &rec[i]
                )
            })?;
            if !x.is_finite() {
                bail!(
                    "{}: line {}: column {} is not finite",
                    path.display(),
                    k + 2,
                    i + 1
                );
            }
            Ok(x)
        };
        out.push(WallRecord {
            step: rec[0].parse().with_context(|| {
                format!("{}: line {}: step {:?}", path.display(), k + 2, &rec[0])
            })?,
            hi: [v(1)?, v(2)?, v(3)?],
            f_lo: [v(4)?, v(5)?, v(6)?],
            f_hi: [v(7)?, v(8)?, v(9)?],
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn walls_csv_round_trips_exactly() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("walls.csv");
        let r = vec![WallRecord {
            step: 100,
            hi: [0.1 + 0.2, 1.0 / 3.0, 2e-2],
            f_lo: [-1.0 / 7.0, -0.0, -5e-324],
            f_hi: [1.0 / 7.0, 3.3, 1e300],
        }];
        write_csv(&p, &r).unwrap();
        assert_eq!(read_csv(&p).unwrap(), r);
    }
}
