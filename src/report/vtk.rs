//! Legacy-ASCII VTK (`STRUCTURED_POINTS`) of coarse-grained fields, the simplest format
//! ParaView opens without plugins. Values are written with Rust's shortest round-trip
//! `{:e}`; NaN (no grains within the kernel) is written as `nan`.

use crate::analysis::coarse_grain::{Grid3, Sym};
use crate::numerics::vec3::V3;
use anyhow::{Context, Result, ensure};
use std::io::{BufWriter, Write};
use std::path::Path;

/// Named point data on a [`Grid3`], x fastest.
pub struct GridData<'a> {
    pub scalars: Vec<(&'a str, &'a [f64])>,
    pub vectors: Vec<(&'a str, &'a [V3])>,
    pub tensors: Vec<(&'a str, &'a [Sym])>,
}

/// `{:e}`, but NaN as `nan` (what strtod-style readers, VTK's included, accept).
fn num(x: f64) -> String {
    if x.is_nan() {
        "nan".to_string()
    } else {
        format!("{x:e}")
    }
}

pub fn write_structured_points(
    path: &Path,
    title: &str,
    grid: &Grid3,
    data: &GridData<'_>,
) -> Result<()> {
    let n = grid.len();
    for (name, len) in data
        .scalars
        .iter()
        .map(|(s, v)| (s, v.len()))
        .chain(data.vectors.iter().map(|(s, v)| (s, v.len())))
        .chain(data.tensors.iter().map(|(s, v)| (s, v.len())))
    {
        ensure!(
            len == n,
            "VTK field {name}: {len} values for a grid of {n} points"
        );
        ensure!(
            !name.contains(char::is_whitespace),
            "VTK field name {name:?} contains whitespace"
        );
    }
    let mut w = BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?,
    );
    writeln!(w, "# vtk DataFile Version 3.0")?;
    writeln!(w, "{}", title.replace('\n', " "))?;
    writeln!(w, "ASCII")?;
    writeln!(w, "DATASET STRUCTURED_POINTS")?;
    writeln!(w, "DIMENSIONS {} {} {}", grid.n[0], grid.n[1], grid.n[2])?;
    let o = grid.point(0, 0, 0);
    writeln!(w, "ORIGIN {:e} {:e} {:e}", o[0], o[1], o[2])?;
    writeln!(
        w,
        "SPACING {:e} {:e} {:e}",
        grid.spacing, grid.spacing, grid.spacing
    )?;
    writeln!(w, "POINT_DATA {n}")?;
    for (name, v) in &data.scalars {
        writeln!(w, "SCALARS {name} double 1")?;
        writeln!(w, "LOOKUP_TABLE default")?;
        for x in v.iter() {
            writeln!(w, "{}", num(*x))?;
        }
    }
    for (name, v) in &data.vectors {
        writeln!(w, "VECTORS {name} double")?;
        for x in v.iter() {
            writeln!(w, "{} {} {}", num(x[0]), num(x[1]), num(x[2]))?;
        }
    }
    for (name, v) in &data.tensors {
        writeln!(w, "TENSORS {name} double")?;
        for s in v.iter() {
            for row in [[s[0], s[3], s[4]], [s[3], s[1], s[5]], [s[4], s[5], s[2]]] {
                writeln!(w, "{} {} {}", num(row[0]), num(row[1]), num(row[2]))?;
            }
        }
    }
    w.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_header_and_counts() {
        let dir = tempfile::tempdir().unwrap();
        let g = Grid3 {
            lo: [0.0; 3],
            spacing: 0.5,
            n: [2, 1, 2],
        };
        let s = [1.0, 2.0, 3.0, f64::NAN];
        let v = [[0.0; 3]; 4];
        let t = [[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]; 4];
        let p = dir.path().join("f.vtk");
        let data = GridData {
            scalars: vec![("phi", &s)],
            vectors: vec![("v", &v)],
            tensors: vec![("sigma", &t)],
        };
        write_structured_points(&p, "test", &g, &data).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.contains("DIMENSIONS 2 1 2") && text.contains("POINT_DATA 4"));
        assert!(text.contains("ORIGIN 2.5e-1 2.5e-1 2.5e-1"));
        assert!(text.contains("\nnan\n"));
        assert_eq!(text.lines().count(), 8 + 2 + 4 + 1 + 4 + 1 + 12);
        let bad = GridData {
            scalars: vec![("phi", &s[..3])],
            vectors: vec![],
            tensors: vec![],
        };
        assert!(write_structured_points(&p, "t", &g, &bad).is_err());
    }
}
