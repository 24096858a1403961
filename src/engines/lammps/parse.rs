//! Streaming readers for LAMMPS' outputs: each frame or line is handed to a callback
//! and dropped, so memory does not grow with the number of output steps.

use anyhow::{Context, Result, bail};
use std::io::BufRead;
use std::path::Path;

/// One atom of a `dump custom ... id type radius mass x y vx vy omegaz fx fy` frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SnapAtom {
    pub id: u64,
    pub type_: usize,
    pub radius: f64,
    pub mass: f64,
    pub x: [f64; 2],
    pub v: [f64; 2],
    pub omega: f64,
    pub f: [f64; 2],
}

pub(crate) const SNAP_COLUMNS: [&str; 11] = [
    "id", "type", "radius", "mass", "x", "y", "vx", "vy", "omegaz", "fx", "fy",
];

fn open(path: &Path) -> Result<std::io::BufReader<crate::rundata::fsio::Bounded>> {
    Ok(std::io::BufReader::new(
        crate::rundata::fsio::open_engine_output(path, "a LAMMPS output")?,
    ))
}

/// Calls `frame(step, atoms)` for every frame of a dump, in file order; returns the
/// number of frames. Atoms come sorted by id (`dump_modify sort id`).
pub fn for_each_snapshot(
    path: &Path,
    mut frame: impl FnMut(u64, &[SnapAtom]) -> Result<()>,
) -> Result<usize> {
    let mut lines = open(path)?.lines().enumerate();
    let mut atoms: Vec<SnapAtom> = Vec::new();
    let mut n_frames = 0;
    // Set at the end of the file: only there may the frames end; a read error is an error.
    let eof = std::cell::Cell::new(false);
    let mut next = |what: &str| -> Result<(usize, String)> {
        match lines.next() {
            Some((k, l)) => Ok((
                k + 1,
                l.with_context(|| format!("{}: line {}", path.display(), k + 1))?,
            )),
            None => {
                eof.set(true);
                bail!(
                    "{}: truncated: end of file while expecting {what}",
                    path.display()
                )
            }
        }
    };
    loop {
        let (ln, head) = match next("ITEM: TIMESTEP") {
            Ok(x) => x,
            Err(_) if eof.get() => break,
            Err(e) => return Err(e),
        };
        if head.trim() != "ITEM: TIMESTEP" {
            bail!(
                "{}: line {ln}: expected `ITEM: TIMESTEP`, found {head:?}",
                path.display()
            );
        }
        let (ln, step) = next("a step number")?;
        let step: u64 = step
            .trim()
            .parse()
            .with_context(|| format!("{}: line {ln}: bad step", path.display()))?;
        let (_, _) = next("ITEM: NUMBER OF ATOMS")?;
        let (ln, n) = next("an atom count")?;
        let n: usize = n
            .trim()
            .parse()
            .with_context(|| format!("{}: line {ln}: bad atom count", path.display()))?;
        let (_, bounds) = next("ITEM: BOX BOUNDS")?;
        if !bounds.starts_with("ITEM: BOX BOUNDS") {
            bail!("{}: expected box bounds, found {bounds:?}", path.display());
        }
        for _ in 0..3 {
            next("a box bound line")?;
        }
        let (ln, cols) = next("ITEM: ATOMS")?;
        let cols: Vec<&str> = cols.split_whitespace().skip(2).collect();
        if cols != SNAP_COLUMNS {
            bail!(
                "{}: line {ln}: columns {cols:?}, expected {SNAP_COLUMNS:?}",
                path.display()
            );
        }
        atoms.clear();
        for _ in 0..n {
            let (ln, l) = next("an atom line")?;
            let v: Vec<&str> = l.split_whitespace().collect();
            if v.len() != SNAP_COLUMNS.len() {
                bail!(
                    "{}: line {ln}: {} fields, expected {}",
                    path.display(),
                    v.len(),
                    SNAP_COLUMNS.len()
                );
            }
            let num = |k: usize| -> Result<f64> {
                v[k].parse::<f64>().with_context(|| {
                    format!(
                        "{}: line {ln}: {} = {:?}",
                        path.display(),
                        SNAP_COLUMNS[k],
                        v[k]
                    )
                })
            };
            atoms.push(SnapAtom {
                id: v[0]
                    .parse()
                    .with_context(|| format!("{}: line {ln}: bad id", path.display()))?,
                type_: v[1]
                    .parse::<usize>()
                    .with_context(|| format!("{}: line {ln}: bad type", path.display()))?,
                radius: num(2)?,
                mass: num(3)?,
                x: [num(4)?, num(5)?],
                v: [num(6)?, num(7)?],
                omega: num(8)?,
                f: [num(9)?, num(10)?],
            });
        }
        frame(step, &atoms)?;
        n_frames += 1;
    }
    Ok(n_frames)
}

/// One line of the `fix ave/time` intruder file: step, centre of mass, velocity and
/// total force (contacts + gravity) of the intruder group; with interface tracers (K
/// Fig 12) also their centre of mass in y.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct IntruderLine {
    pub step: u64,
    pub x: [f64; 2],
    pub v: [f64; 2],
    pub f: [f64; 2],
    pub interface_y: Option<f64>,
}

/// Calls `line` for every data line of the intruder file, which has the interface
/// column if `interface` (and then every line must have it); returns how many.
pub(crate) fn for_each_intruder_line(
    path: &Path,
    interface: bool,
    mut line: impl FnMut(IntruderLine) -> Result<()>,
) -> Result<usize> {
    let (want, columns) = if interface {
        (8, "step x y vx vy fx fy y_interface")
    } else {
        (7, "step x y vx vy fx fy")
    };
    let mut n = 0;
    for (k, l) in open(path)?.lines().enumerate() {
        let l = l.with_context(|| format!("{}: line {}", path.display(), k + 1))?;
        let t = l.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let v: Vec<&str> = t.split_whitespace().collect();
        if v.len() != want {
            bail!(
                "{}: line {}: {} fields, expected {want} ({columns})",
                path.display(),
                k + 1,
                v.len()
            );
        }
        let num = |i: usize| -> Result<f64> {
            v[i].parse::<f64>().with_context(|| {
                format!(
                    "{}: line {}: field {} = {:?}",
                    path.display(),
                    k + 1,
                    i + 1,
                    v[i]
                )
            })
        };
        line(IntruderLine {
            step: v[0].parse().with_context(|| {
                format!("{}: line {}: bad step {:?}", path.display(), k + 1, v[0])
            })?,
            x: [num(1)?, num(2)?],
            v: [num(3)?, num(4)?],
            f: [num(5)?, num(6)?],
            interface_y: if interface { Some(num(7)?) } else { None },
        })?;
        n += 1;
    }
    Ok(n)
}

/// Calls `frame(step, rows)` for every frame of a `dump custom` (`item` = "ATOMS") or
/// `dump local` (`item` = "ENTRIES") file whose columns must be `columns`, every value
/// read as f64 (ids too: exact below 2^53); returns the number of frames.
pub(crate) fn for_each_table_frame(
    path: &Path,
    item: &str,
    columns: &[&str],
    mut frame: impl FnMut(u64, &[Vec<f64>]) -> Result<()>,
) -> Result<usize> {
    let mut lines = open(path)?.lines().enumerate();
    let mut n_frames = 0;
    let mut rows: Vec<Vec<f64>> = Vec::new();
    let mut next = || -> Result<Option<(usize, String)>> {
        match lines.next() {
            Some((k, l)) => Ok(Some((
                k + 1,
                l.with_context(|| format!("{}: line {}", path.display(), k + 1))?,
            ))),
            None => Ok(None),
        }
    };
    let truncated = |what: &str| {
        anyhow::anyhow!(
            "{}: truncated: end of file while expecting {what}",
            path.display()
        )
    };
    while let Some((ln, head)) = next()? {
        if head.trim() != "ITEM: TIMESTEP" {
            bail!(
                "{}: line {ln}: expected `ITEM: TIMESTEP`, found {head:?}",
                path.display()
            );
        }
        let (ln, step) = next()?.ok_or_else(|| truncated("a step number"))?;
        let step: u64 = step
            .trim()
            .parse()
            .with_context(|| format!("{}: line {ln}: bad step", path.display()))?;
        next()?.ok_or_else(|| truncated("ITEM: NUMBER OF ..."))?;
        let (ln, n) = next()?.ok_or_else(|| truncated("a row count"))?;
        let n: usize = n
            .trim()
            .parse()
            .with_context(|| format!("{}: line {ln}: bad row count", path.display()))?;
        let (_, bounds) = next()?.ok_or_else(|| truncated("ITEM: BOX BOUNDS"))?;
        if !bounds.starts_with("ITEM: BOX BOUNDS") {
            bail!("{}: expected box bounds, found {bounds:?}", path.display());
        }
        for _ in 0..3 {
            next()?.ok_or_else(|| truncated("a box bound line"))?;
        }
        let (ln, cols) = next()?.ok_or_else(|| truncated(&format!("ITEM: {item}")))?;
        let want = format!("ITEM: {item}");
        let got: Vec<&str> = cols
            .strip_prefix(&want)
            .map(|c| c.split_whitespace().collect())
            .unwrap_or_default();
        if got != columns {
            bail!(
                "{}: line {ln}: {cols:?}, expected `{want} {}`",
                path.display(),
                columns.join(" ")
            );
        }
        rows.clear();
        for _ in 0..n {
            let (ln, l) = next()?.ok_or_else(|| truncated("a data row"))?;
            let v = l
                .split_whitespace()
                .map(|x| x.parse::<f64>())
                .collect::<Result<Vec<f64>, _>>()
                .with_context(|| format!("{}: line {ln}: {l:?}", path.display()))?;
            if v.len() != columns.len() {
                bail!(
                    "{}: line {ln}: {} fields, expected {}",
                    path.display(),
                    v.len(),
                    columns.len()
                );
            }
            rows.push(v);
        }
        frame(step, &rows)?;
        n_frames += 1;
    }
    Ok(n_frames)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The intruder file has the interface column exactly when asked for: a line of
    /// the other width is an error naming the file, the line and the columns.
    #[test]
    fn intruder_lines_read_the_interface_column_when_tracked() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("intruder.txt");
        std::fs::write(
            &p,
            "# Time-averaged data\n0 1 2 3 4 5 6 0.25\n10 1 2 3 4 5 6 0.5\n",
        )
        .unwrap();
        let mut got = Vec::new();
        for_each_intruder_line(&p, true, |l| {
            got.push(l.interface_y);
            Ok(())
        })
        .unwrap();
        assert_eq!(got, vec![Some(0.25), Some(0.5)]);
        let e = for_each_intruder_line(&p, false, |_| Ok(())).unwrap_err();
        let e = format!("{e:#}");
        assert!(
            e.contains("intruder.txt") && e.contains("line 2") && e.contains("expected 7"),
            "{e}"
        );
        std::fs::write(&p, "0 1 2 3 4 5 6\n").unwrap();
        let e = format!(
            "{:#}",
            for_each_intruder_line(&p, true, |_| Ok(())).unwrap_err()
        );
        assert!(e.contains("expected 8") && e.contains("y_interface"), "{e}");
    }

    /// A `dump local` frame reads back row by row; other columns or a cut-off file are
    /// errors naming the file.
    #[test]
    fn table_frames_read_and_name_their_mistakes() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("contacts.dump");
        let frame = "ITEM: TIMESTEP\n600\nITEM: NUMBER OF ENTRIES\n2\nITEM: BOX BOUNDS pp ff pp\n0 1\n0 1\n-1 1\nITEM: ENTRIES a b\n1 2.5\n3 4e-3\n";
        std::fs::write(&p, frame.repeat(2)).unwrap();
        let mut got = Vec::new();
        let n = for_each_table_frame(&p, "ENTRIES", &["a", "b"], |s, rows| {
            got.push((s, rows.to_vec()));
            Ok(())
        })
        .unwrap();
        assert_eq!(n, 2);
        assert_eq!(got[1], (600, vec![vec![1.0, 2.5], vec![3.0, 4e-3]]));
        let e = for_each_table_frame(&p, "ENTRIES", &["a", "c"], |_, _| Ok(())).unwrap_err();
        assert!(format!("{e:#}").contains("contacts.dump"), "{e:#}");
        std::fs::write(&p, &frame[..frame.len() - 7]).unwrap();
        let e = for_each_table_frame(&p, "ENTRIES", &["a", "b"], |_, _| Ok(())).unwrap_err();
        assert!(format!("{e:#}").contains("truncated"), "{e:#}");
    }
}
