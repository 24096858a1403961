//! Legacy-ASCII VTK (`STRUCTURED_POINTS`) of coarse-grained fields, the simplest format
//! ParaView opens without plugins. Values are written with Rust's shortest round-trip
//! `{:e}`.
//!
//! Empty cells (no grains within the kernel, or a quantity undefined there: NaN in
//! granval) are written as [`FILL`] and flagged in a companion array: every field
//! `NAME` has an `unsigned_char` scalar `NAME_valid`, 1 where every component of `NAME`
//! at that point is a number, 0 where it was empty. VTK's legacy reader (VTK 9.2,
//! ParaView 5.11) stops at the first ASCII `nan` and loads the arrays before it only,
//! with garbage in the one it stopped in; a fill value and a mask load everywhere, and
//! ParaView's Threshold on `NAME_valid` (lower 1) shows only the defined points.

use crate::analysis::coarse_grain::{Grid3, Sym};
use crate::numerics::vec3::V3;
use anyhow::{Context, Result, ensure};
use std::io::{BufWriter, Write};
use std::path::Path;

/// What an empty cell holds in every array of the file (its `NAME_valid` is 0).
pub const FILL: f64 = 0.0;

/// The suffix of a field's validity mask.
pub const VALID_SUFFIX: &str = "_valid";

/// Named point data on a [`Grid3`], x fastest.
pub struct GridData<'a> {
    pub scalars: Vec<(&'a str, &'a [f64])>,
    pub vectors: Vec<(&'a str, &'a [V3])>,
    pub tensors: Vec<(&'a str, &'a [Sym])>,
}

/// `{:e}`, a non-finite value as [`FILL`].
fn num(x: f64) -> String {
    format!("{:e}", if x.is_finite() { x } else { FILL })
}

/// A field's `NAME_valid` array: 1 where every component is finite.
fn mask<'v>(points: impl Iterator<Item = &'v [f64]>) -> Vec<u8> {
    points
        .map(|c| u8::from(c.iter().all(|x| x.is_finite())))
        .collect()
}

pub fn write_structured_points(
    path: &Path,
    title: &str,
    grid: &Grid3,
    data: &GridData<'_>,
) -> Result<()> {
    let n = grid.len();
    let names: Vec<&str> = data
        .scalars
        .iter()
        .map(|(s, _)| *s)
        .chain(data.vectors.iter().map(|(s, _)| *s))
        .chain(data.tensors.iter().map(|(s, _)| *s))
        .collect();
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
            !name.is_empty() && !name.contains(char::is_whitespace),
            "VTK field name {name:?} is empty or contains whitespace"
        );
        let masked = format!("{name}{VALID_SUFFIX}");
        ensure!(
            !names.contains(&masked.as_str()),
            "VTK field {name}: its mask {masked} would clash with a field of that name"
        );
    }
    ensure!(
        names
            .iter()
            .enumerate()
            .all(|(i, a)| !names[..i].contains(a)),
        "VTK fields with the same name: {names:?}"
    );
    let mut w = BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?,
    );
    writeln!(w, "# vtk DataFile Version 3.0")?;
    // The title line is at most 256 characters (VTK file-format documentation).
    let title = format!(
        "{}; empty cells: {FILL}, NAME{VALID_SUFFIX} = 0",
        title.replace(['\n', '\r'], " ")
    );
    writeln!(w, "{}", title.chars().take(255).collect::<String>())?;
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
    let mut masks: Vec<(&str, Vec<u8>)> = Vec::new();
    for (name, v) in &data.scalars {
        writeln!(w, "SCALARS {name} double 1")?;
        writeln!(w, "LOOKUP_TABLE default")?;
        for x in v.iter() {
            writeln!(w, "{}", num(*x))?;
        }
        masks.push((name, mask(v.iter().map(std::slice::from_ref))));
    }
    for (name, v) in &data.vectors {
        writeln!(w, "VECTORS {name} double")?;
        for x in v.iter() {
            writeln!(w, "{} {} {}", num(x[0]), num(x[1]), num(x[2]))?;
        }
        masks.push((name, mask(v.iter().map(|x| &x[..]))));
    }
    for (name, v) in &data.tensors {
        writeln!(w, "TENSORS {name} double")?;
        for s in v.iter() {
            for row in [[s[0], s[3], s[4]], [s[3], s[1], s[5]], [s[4], s[5], s[2]]] {
                writeln!(w, "{} {} {}", num(row[0]), num(row[1]), num(row[2]))?;
            }
        }
        masks.push((name, mask(v.iter().map(|x| &x[..]))));
    }
    for (name, m) in masks {
        writeln!(w, "SCALARS {name}{VALID_SUFFIX} unsigned_char 1")?;
        writeln!(w, "LOOKUP_TABLE default")?;
        for x in m {
            writeln!(w, "{x}")?;
        }
    }
    w.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    /// Array name -> (components per point, values).
    type Arrays = BTreeMap<String, (usize, Vec<f64>)>;

    /// Every point-data array of a legacy-ASCII STRUCTURED_POINTS file, read as VTK's
    /// legacy reader reads it: a header of counted blocks whose every value must be a
    /// number (the reader's `>>` into a double stops at `nan`), nothing left over.
    fn read_vtk(text: &str) -> Result<(usize, Arrays), String> {
        let mut lines = text.lines();
        let header: Vec<&str> = lines.by_ref().take(8).collect();
        if header.len() < 8 || header[0] != "# vtk DataFile Version 3.0" || header[2] != "ASCII" {
            return Err(format!("bad header {header:?}"));
        }
        if header[1].len() > 256 {
            return Err("title longer than 256 characters".into());
        }
        let n: usize = header[7]
            .strip_prefix("POINT_DATA ")
            .and_then(|s| s.parse().ok())
            .ok_or(format!("no POINT_DATA in {header:?}"))?;
        let mut tokens = lines.flat_map(str::split_whitespace);
        let mut arrays = BTreeMap::new();
        while let Some(kind) = tokens.next() {
            let name = tokens.next().ok_or("array without a name")?.to_string();
            let ty = tokens.next().ok_or("array without a type")?;
            if !matches!(ty, "double" | "unsigned_char") {
                return Err(format!("{name}: type {ty}"));
            }
            let comps = match kind {
                "SCALARS" => {
                    let c = tokens.next();
                    let (l, d) = (tokens.next(), tokens.next());
                    if c != Some("1") || l != Some("LOOKUP_TABLE") || d != Some("default") {
                        return Err(format!("{name}: bad SCALARS line"));
                    }
                    1
                }
                "VECTORS" => 3,
                "TENSORS" => 9,
                k => return Err(format!("unknown block {k}")),
            };
            let mut v = Vec::with_capacity(n * comps);
            for _ in 0..n * comps {
                let t = tokens.next().ok_or(format!("{name}: too few values"))?;
                let x: f64 = t.parse().map_err(|_| format!("{name}: {t:?}"))?;
                if !x.is_finite() {
                    return Err(format!("{name}: {t:?} is not a number VTK reads"));
                }
                v.push(x);
            }
            if arrays.insert(name.clone(), (comps, v)).is_some() {
                return Err(format!("{name} twice"));
            }
        }
        Ok((n, arrays))
    }

    /// A field file with empty cells reads back completely: all six arrays and their six
    /// masks, every value a number, the defined values exactly as written (shortest
    /// round-trip), the empty ones [`FILL`] with mask 0, tensors symmetric as the
    /// six-component input says. Before, empty cells were written as `nan`, which VTK's
    /// reader stops at (the reader here refuses it: see the negative control).
    #[test]
    fn every_array_reads_back_complete_with_empty_cells_masked() {
        let dir = tempfile::tempdir().unwrap();
        let g = Grid3 {
            lo: [0.0; 3],
            spacing: 0.5,
            n: [2, 1, 2],
        };
        let nan = f64::NAN;
        let sf = [0.55, 0.6, 0.0, 0.1 + 0.2];
        let gb = [0.3, nan, nan, 1.0 / 3.0];
        let gk = [f64::INFINITY, 0.25, nan, 0.125];
        let v = [
            [1e-3, -2.0, 0.0],
            [nan; 3],
            [0.5, nan, 1.0],
            [1.0, 2.0, 3.0],
        ];
        let t = [
            [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
            [nan; 6],
            [1e5, 2e5, 3e5, -1.5, 0.0, nan],
            [0.1, 0.2, 0.3, 0.4, 0.5, 0.6],
        ];
        let t2 = [[7.0; 6], [nan; 6], [8.0; 6], [9.5e-12; 6]];
        let p = dir.path().join("f.vtk");
        let data = GridData {
            scalars: vec![
                ("solid_fraction", &sf),
                ("gamma_basic", &gb),
                ("gamma_kernel", &gk),
            ],
            vectors: vec![("velocity", &v)],
            tensors: vec![("stress_basic", &t), ("stress_kernel", &t2)],
        };
        write_structured_points(&p, "granval CG fields\nsecond line", &g, &data).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.contains("DIMENSIONS 2 1 2") && text.contains("ORIGIN 2.5e-1 2.5e-1 2.5e-1"));
        let (n, arrays) = read_vtk(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(n, 4);
        assert_eq!(arrays.len(), 12, "{:?}", arrays.keys());
        let check = |name: &str, comps: usize, want: Vec<Vec<f64>>| {
            let (c, got) = &arrays[name];
            assert_eq!(*c, comps, "{name}");
            let (_, m) = &arrays[&format!("{name}{VALID_SUFFIX}")];
            for (k, w) in want.iter().enumerate() {
                let ok = w.iter().all(|x| x.is_finite());
                assert_eq!(m[k], f64::from(u8::from(ok)), "{name} mask at {k}");
                for (j, x) in w.iter().enumerate() {
                    let expect = if x.is_finite() { *x } else { FILL };
                    assert_eq!(
                        got[k * comps + j].to_bits(),
                        expect.to_bits(),
                        "{name}[{k}][{j}]"
                    );
                }
            }
        };
        for (name, s) in [
            ("solid_fraction", &sf),
            ("gamma_basic", &gb),
            ("gamma_kernel", &gk),
        ] {
            check(name, 1, s.iter().map(|x| vec![*x]).collect());
        }
        check("velocity", 3, v.iter().map(|x| x.to_vec()).collect());
        let full = |s: &Sym| vec![s[0], s[3], s[4], s[3], s[1], s[5], s[4], s[5], s[2]];
        check("stress_basic", 9, t.iter().map(full).collect());
        check("stress_kernel", 9, t2.iter().map(full).collect());
        // The point with a NaN yz only is invalid as a whole tensor.
        assert_eq!(arrays["stress_basic_valid"].1, [1.0, 0.0, 0.0, 1.0]);
        assert!(!text.contains("nan") && !text.contains("inf"));
        assert!(
            text.lines()
                .nth(1)
                .unwrap()
                .ends_with("empty cells: 0, NAME_valid = 0")
        );

        let bad = GridData {
            scalars: vec![("phi", &sf[..3])],
            vectors: vec![],
            tensors: vec![],
        };
        assert!(write_structured_points(&p, "t", &g, &bad).is_err());
        let clash = GridData {
            scalars: vec![("phi", &sf), ("phi_valid", &sf)],
            vectors: vec![],
            tensors: vec![],
        };
        assert!(write_structured_points(&p, "t", &g, &clash).is_err());
    }

    /// The negative control: the reader refuses a file with an ASCII `nan`, as the old
    /// writer produced, so the test above can fail.
    #[test]
    fn the_reader_refuses_ascii_nan() {
        let old = "# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 1 1\nORIGIN 0 0 0\nSPACING 1 1 1\nPOINT_DATA 2\nSCALARS phi double 1\nLOOKUP_TABLE default\n1e0\nnan\n";
        assert!(read_vtk(old).unwrap_err().contains("nan"));
        assert!(read_vtk(&old.replace("nan", "2e0")).is_ok());
    }
}
