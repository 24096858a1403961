//! Contact snapshots from LIGGGHTS 3.8 (stress fields, Feng et al. eqs 6-9): the deck block that dumps every
//! grain-grain and grain-mesh contact (`compute pair/gran/local`, `compute
//! wall/gran/local`, `dump local`) and the grains (`dump custom`) at chosen steps, and a
//! streaming reader of those dumps that holds one snapshot in memory at a time.
//!
//! Facts of Debian's LIGGGHTS 3.8.0 this relies on (measured):
//! - with keywords `pos id force contactPoint` both computes give 15 columns in the
//!   documented order pos (6), id (3), force (3), contactPoint (3);
//! - pair rows: `x_i, x_j, id_i, id_j, periodic flag, force on i, contact point`, the
//!   contact point being `x_i + (x_j - x_i) r_i / (r_i + r_j)`;
//! - wall rows (mesh walls only; primitive walls are skipped with a warning):
//!   `contact point, x_i, mesh id, triangle id, id_i, force on the grain, 0 0 0` — the
//!   `pos` slot carries the contact point (`add_wall_1`) and `contactPoint` stays zero;
//! - `dump_modify every v_name` with an equal-style variable writes exactly at the steps
//!   the variable returns (it must return a step after the current one);
//! - `%.17g` formats round-trip an f64.

use super::units::Units;
use crate::rundata::snapshot::{Contact, ContactKind, Grain};
use anyhow::{Context, Result, bail};
use std::collections::HashSet;
use std::fmt::Write as _;
use std::io::BufRead;
use std::path::{Path, PathBuf};

pub(crate) const PAIR_PREFIX: &str = "snap_pair";
pub(crate) const WALL_PREFIX: &str = "snap_wall";
pub(crate) const ATOMS_PREFIX: &str = "snap_atoms";
const LOCAL_COLUMNS: usize = 15;

pub fn pair_file(dir: &Path, step: u64) -> PathBuf {
    dir.join(format!("{PAIR_PREFIX}.{step}.txt"))
}
pub(crate) fn wall_file(dir: &Path, step: u64) -> PathBuf {
    dir.join(format!("{WALL_PREFIX}.{step}.txt"))
}
pub(crate) fn atoms_file(dir: &Path, step: u64) -> PathBuf {
    dir.join(format!("{ATOMS_PREFIX}.{step}.txt"))
}

/// Deck lines (before `run`) that dump contacts and grains at `steps` (ascending, each
/// at most `n_steps`; 0 means after setup). Empty for no steps.
pub(crate) fn deck_block(steps: &[u64], n_steps: u64) -> Result<String> {
    let mut s = String::new();
    if steps.is_empty() {
        return Ok(s);
    }
    for w in steps.windows(2) {
        if w[1] <= w[0] {
            bail!("snapshot steps must be strictly ascending: {steps:?}");
        }
    }
    if let Some(&last) = steps.last()
        && last > n_steps
    {
        bail!("snapshot step {last} is beyond the run's {n_steps} steps");
    }
    // next(step) = the first snapshot step after `step`, or a step the run never reaches.
    let never = 2 * n_steps + 10;
    let mut terms: Vec<String> = Vec::new();
    let mut prev: Option<u64> = None;
    for &st in steps.iter().filter(|&&st| st > 0) {
        terms.push(match prev {
            None => format!("(step<{st})*{st}"),
            Some(p) => format!("(step>={p})*(step<{st})*{st}"),
        });
        prev = Some(st);
    }
    terms.push(match prev {
        None => format!("{never}"),
        Some(p) => format!("(step>={p})*{never}"),
    });
    let first = if steps[0] == 0 { " first yes" } else { "" };
    let fmt15 = vec!["%.17g"; LOCAL_COLUMNS].join(" ");
    let cols = |c: &str| {
        (1..=LOCAL_COLUMNS)
            .map(|k| format!("c_{c}[{k}]"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    writeln!(
        s,
        "# contact snapshots at steps {steps:?}: pos(6) id(3) force(3) contactPoint(3); force on grain i"
    )?;
    writeln!(
        s,
        "compute snpair all pair/gran/local pos id force contactPoint"
    )?;
    writeln!(
        s,
        "compute snwall all wall/gran/local pos id force contactPoint"
    )?;
    writeln!(s, "variable snapnext equal \"{}\"", terms.join(" + "))?;
    writeln!(
        s,
        "dump snp all local 1 {PAIR_PREFIX}.*.txt {}",
        cols("snpair")
    )?;
    writeln!(
        s,
        "dump_modify snp every v_snapnext{first} format \"{fmt15}\""
    )?;
    writeln!(
        s,
        "dump snw all local 1 {WALL_PREFIX}.*.txt {}",
        cols("snwall")
    )?;
    writeln!(
        s,
        "dump_modify snw every v_snapnext{first} format \"{fmt15}\""
    )?;
    writeln!(
        s,
        "dump sna all custom 1 {ATOMS_PREFIX}.*.txt id x y z vx vy vz radius"
    )?;
    writeln!(
        s,
        "dump_modify sna every v_snapnext{first} sort id format \"%d{}\"",
        " %.17g".repeat(7)
    )?;
    Ok(s)
}

/// One `ITEM: TIMESTEP` block of a LIGGGHTS text dump (local or custom).
#[derive(Debug, Clone)]
pub(crate) struct DumpBlock {
    pub step: u64,
    pub columns: Vec<String>,
    /// Row-major, `columns.len()` values per row.
    pub values: Vec<f64>,
}

impl DumpBlock {
    pub fn rows(&self) -> impl Iterator<Item = &[f64]> {
        self.values.chunks(self.columns.len().max(1))
    }
    pub(crate) fn n_rows(&self) -> usize {
        self.values.len() / self.columns.len().max(1)
    }
}

/// Reads dump blocks one at a time: memory holds one block, whatever the file length.
pub(crate) struct DumpReader<R> {
    reader: R,
    path: PathBuf,
    lineno: usize,
    line: String,
}

impl DumpReader<Box<dyn BufRead>> {
    /// Opens the dump at `path`, or its compressed form `path.zst`
    /// ([`compress_dumps`]) when only that exists; either is bounded as every engine
    /// output is, and what a compressed one decompresses to by the same size.
    pub fn open(path: &Path) -> Result<Self> {
        let zst = compressed_name(path);
        if !path.exists() && zst.exists() {
            let f = crate::rundata::fsio::open_engine_output(&zst, "a LIGGGHTS contact dump")?;
            let dec = zstd::stream::Decoder::new(f)
                .with_context(|| format!("{}: not a zstd stream", zst.display()))?;
            let bounded = std::io::Read::take(dec, crate::rundata::fsio::max_engine_output());
            return Ok(DumpReader::new(
                Box::new(std::io::BufReader::new(bounded)),
                &zst,
            ));
        }
        let f = crate::rundata::fsio::open_engine_output(path, "a LIGGGHTS contact dump")?;
        Ok(DumpReader::new(Box::new(std::io::BufReader::new(f)), path))
    }
}

/// `snap_pair.K.txt` -> `snap_pair.K.txt.zst`.
fn compressed_name(path: &Path) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(".zst");
    PathBuf::from(s)
}

/// Whether `name` is one of the snapshot dumps the deck block writes, plain or
/// compressed, or the temporary file of a compression that was interrupted
/// (`.NAME.zst.partial`): what a new run with snapshots replaces.
pub(crate) fn is_dump_name(name: &str) -> bool {
    let name = name
        .strip_prefix('.')
        .and_then(|n| n.strip_suffix(".zst.partial"))
        .unwrap_or(name);
    [PAIR_PREFIX, WALL_PREFIX, ATOMS_PREFIX]
        .iter()
        .any(|p| name.starts_with(&format!("{p}.")))
        && (name.ends_with(".txt") || name.ends_with(".txt.zst"))
}

/// zstd level of the kept dumps: LIGGGHTS writes every value with 17 significant digits,
/// which level 3 shrinks about as much as the converted snapshots (measured in
/// docs/stress.md) at a fraction of the run's time.
const DUMP_ZSTD_LEVEL: i32 = 3;

/// Replaces every snapshot dump LIGGGHTS left in `dir` by its zstd-compressed form
/// (`snap_pair.K.txt` -> `snap_pair.K.txt.zst`, read back by [`read_snapshot`] as it
/// was). The raw dumps are the run's evidence, so they are kept, but as written they are
/// about as large as every other output of a stress bed together. Each file is written
/// under a temporary name, flushed to disk, renamed, and only then is the plain file
/// removed: an interrupted compression leaves the plain dump, never neither. Returns the
/// bytes before and after.
pub(crate) fn compress_dumps(dir: &Path) -> Result<(u64, u64)> {
    let (mut before, mut after) = (0u64, 0u64);
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .with_context(|| format!("cannot list {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().to_string()))
        .filter(|n| is_dump_name(n) && n.ends_with(".txt"))
        .collect();
    names.sort();
    for name in names {
        let src = dir.join(&name);
        let dst = compressed_name(&src);
        let tmp = dir.join(format!(".{name}.zst.partial"));
        let mut input =
            std::fs::File::open(&src).with_context(|| format!("cannot open {}", src.display()))?;
        let out = std::fs::File::create(&tmp)
            .with_context(|| format!("cannot create {}", tmp.display()))?;
        let mut enc = zstd::stream::Encoder::new(out, DUMP_ZSTD_LEVEL)
            .with_context(|| format!("cannot start zstd for {}", tmp.display()))?;
        before += std::io::copy(&mut input, &mut enc)
            .with_context(|| format!("cannot compress {}", src.display()))?;
        let out = enc
            .finish()
            .with_context(|| format!("cannot finish {}", tmp.display()))?;
        out.sync_all()
            .with_context(|| format!("cannot flush {}", tmp.display()))?;
        after += out.metadata()?.len();
        std::fs::rename(&tmp, &dst)
            .with_context(|| format!("cannot rename {} to {}", tmp.display(), dst.display()))?;
        std::fs::remove_file(&src)
            .with_context(|| format!("cannot remove {} after compressing it", src.display()))?;
    }
    Ok((before, after))
}

impl<R: BufRead> DumpReader<R> {
    pub fn new(reader: R, path: &Path) -> Self {
        DumpReader {
            reader,
            path: path.to_path_buf(),
            lineno: 0,
            line: String::new(),
        }
    }

    fn next_line(&mut self) -> Result<Option<&str>> {
        self.line.clear();
        let n = self
            .reader
            .read_line(&mut self.line)
            .with_context(|| format!("{}:{}: read error", self.path.display(), self.lineno + 1))?;
        if n == 0 {
            return Ok(None);
        }
        self.lineno += 1;
        Ok(Some(self.line.trim()))
    }

    fn expect_line(&mut self, what: &str) -> Result<String> {
        let lineno = self.lineno + 1;
        let path = self.path.display().to_string();
        match self.next_line()? {
            Some(l) => Ok(l.to_string()),
            None => bail!("{path}:{lineno}: file ends where {what} was expected"),
        }
    }

    /// The next block, or `None` at the end of the file.
    pub(crate) fn next_block(&mut self) -> Result<Option<DumpBlock>> {
        let first = loop {
            match self.next_line()? {
                None => return Ok(None),
                Some("") => continue,
                Some(l) => break l.to_string(),
            }
        };
        let p = self.path.display().to_string();
        if first != "ITEM: TIMESTEP" {
            bail!(
                "{p}:{}: expected `ITEM: TIMESTEP`, found {first:?}",
                self.lineno
            );
        }
        let st = self.expect_line("the timestep")?;
        let step: u64 = st
            .parse()
            .with_context(|| format!("{p}:{}: timestep {st:?} is not an integer", self.lineno))?;
        let item = self.expect_line("ITEM: NUMBER OF ...")?;
        if !item.starts_with("ITEM: NUMBER OF") {
            bail!(
                "{p}:{}: expected `ITEM: NUMBER OF ENTRIES/ATOMS`, found {item:?}",
                self.lineno
            );
        }
        let nt = self.expect_line("the row count")?;
        let n: usize = nt
            .parse()
            .with_context(|| format!("{p}:{}: row count {nt:?} is not an integer", self.lineno))?;
        let bb = self.expect_line("ITEM: BOX BOUNDS")?;
        if !bb.starts_with("ITEM: BOX BOUNDS") {
            bail!(
                "{p}:{}: expected `ITEM: BOX BOUNDS`, found {bb:?}",
                self.lineno
            );
        }
        for _ in 0..3 {
            self.expect_line("a box bound")?;
        }
        let head = self.expect_line("ITEM: ENTRIES/ATOMS")?;
        let columns: Vec<String> = match head
            .strip_prefix("ITEM: ENTRIES")
            .or_else(|| head.strip_prefix("ITEM: ATOMS"))
        {
            Some(rest) => rest.split_whitespace().map(String::from).collect(),
            None => bail!(
                "{p}:{}: expected `ITEM: ENTRIES ...` or `ITEM: ATOMS ...`, found {head:?}",
                self.lineno
            ),
        };
        let nc = columns.len();
        if nc == 0 {
            bail!("{p}:{}: no columns named in {head:?}", self.lineno);
        }
        let mut values = Vec::with_capacity(n * nc);
        for _ in 0..n {
            let l = self.expect_line("a data row")?;
            let before = values.len();
            for tok in l.split_whitespace() {
                let v: f64 = tok
                    .parse()
                    .ok()
                    .filter(|v: &f64| v.is_finite())
                    .ok_or_else(|| {
                        anyhow::anyhow!("{p}:{}: value {tok:?} is not a finite number", self.lineno)
                    })?;
                values.push(v);
            }
            if values.len() - before != nc {
                bail!(
                    "{p}:{}: {} values, the header names {nc} columns",
                    self.lineno,
                    values.len() - before
                );
            }
        }
        Ok(Some(DumpBlock {
            step,
            columns,
            values,
        }))
    }
}

/// Reads the single block of a per-step dump file and checks its step.
fn read_one(path: &Path, step: u64) -> Result<DumpBlock> {
    let mut r = DumpReader::open(path)?;
    let b = r
        .next_block()?
        .with_context(|| format!("{}: no dump block", path.display()))?;
    if b.step != step {
        bail!("{}: holds step {}, expected {step}", path.display(), b.step);
    }
    if r.next_block()?.is_some() {
        bail!(
            "{}: more than one block (expected one step per file)",
            path.display()
        );
    }
    Ok(b)
}

fn id_of(path: &Path, row: usize, col: &str, v: f64) -> Result<u64> {
    if !(v >= 0.0 && v.fract() == 0.0 && v < 9.0e15) {
        bail!(
            "{}: row {}: {col} = {v} is not an atom id",
            path.display(),
            row + 1
        );
    }
    Ok(v as u64)
}

/// Grains and contacts (SI, the convention of `engines::snapshot`) of the snapshot at
/// `step` in run directory `dir`. Grain-grain contacts reported twice (MPI ranks with
/// `newton off`) are kept once; the count dropped is returned.
pub fn read_snapshot(
    dir: &Path,
    step: u64,
    units: Units,
) -> Result<(Vec<Grain>, Vec<Contact>, usize)> {
    let (l, v, fo) = (units.length(), units.velocity(), units.force());
    let ap = atoms_file(dir, step);
    let a = read_one(&ap, step)?;
    let want = ["id", "x", "y", "z", "vx", "vy", "vz", "radius"];
    if a.columns != want {
        bail!(
            "{}: columns {:?}, expected {want:?}",
            ap.display(),
            a.columns
        );
    }
    let mut grains = Vec::with_capacity(a.n_rows());
    for (k, r) in a.rows().enumerate() {
        grains.push(Grain {
            id: id_of(&ap, k, "id", r[0])?,
            x: [r[1] / l, r[2] / l, r[3] / l],
            v: [r[4] / v, r[5] / v, r[6] / v],
            radius: r[7] / l,
        });
    }
    let mut contacts = Vec::new();
    let mut seen = HashSet::new();
    let mut dropped = 0;
    let pp = pair_file(dir, step);
    let p = read_one(&pp, step)?;
    if p.columns.len() != LOCAL_COLUMNS {
        bail!(
            "{}: {} columns, expected {LOCAL_COLUMNS} (pos id force contactPoint)",
            pp.display(),
            p.columns.len()
        );
    }
    for (k, r) in p.rows().enumerate() {
        let (i, j) = (id_of(&pp, k, "id_i", r[6])?, id_of(&pp, k, "id_j", r[7])?);
        if !seen.insert((i.min(j), i.max(j))) {
            dropped += 1;
            continue;
        }
        let xi = [r[0] / l, r[1] / l, r[2] / l];
        let xj = [r[3] / l, r[4] / l, r[5] / l];
        contacts.push(Contact {
            kind: ContactKind::Pair,
            i,
            j,
            xi,
            point: [r[12] / l, r[13] / l, r[14] / l],
            branch: [xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]],
            force: [r[9] / fo, r[10] / fo, r[11] / fo],
        });
    }
    let wp = wall_file(dir, step);
    let w = read_one(&wp, step)?;
    if w.n_rows() > 0 && w.columns.len() != LOCAL_COLUMNS {
        bail!(
            "{}: {} columns, expected {LOCAL_COLUMNS} (pos id force contactPoint)",
            wp.display(),
            w.columns.len()
        );
    }
    for (k, r) in w.rows().enumerate() {
        let i = id_of(&wp, k, "particle id", r[8])?;
        let point = [r[0] / l, r[1] / l, r[2] / l];
        let xi = [r[3] / l, r[4] / l, r[5] / l];
        contacts.push(Contact {
            kind: ContactKind::Intruder,
            i,
            j: 0,
            xi,
            point,
            branch: [point[0] - xi[0], point[1] - xi[1], point[2] - xi[2]],
            force: [r[9] / fo, r[10] / fo, r[11] / fo],
        });
    }
    Ok((grains, contacts, dropped))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_reader_streams_and_names_errors() {
        let text = "ITEM: TIMESTEP\n5\nITEM: NUMBER OF ENTRIES\n2\nITEM: BOX BOUNDS ff ff ff\n0 1\n0 1\n0 1\nITEM: ENTRIES a b\n1 2\n3 4\nITEM: TIMESTEP\n9\nITEM: NUMBER OF ENTRIES\n0\nITEM: BOX BOUNDS ff ff ff\n0 1\n0 1\n0 1\nITEM: ENTRIES a b\n";
        let mut r = DumpReader::new(std::io::Cursor::new(text), Path::new("x.txt"));
        let b = r.next_block().unwrap().unwrap();
        assert_eq!((b.step, b.n_rows()), (5, 2));
        assert_eq!(b.values, vec![1.0, 2.0, 3.0, 4.0]);
        let b = r.next_block().unwrap().unwrap();
        assert_eq!((b.step, b.n_rows()), (9, 0));
        assert!(r.next_block().unwrap().is_none());
        let bad = text.replace("3 4", "3 nan");
        let mut r = DumpReader::new(std::io::Cursor::new(bad), Path::new("x.txt"));
        let e = r.next_block().unwrap_err().to_string();
        assert!(e.contains("x.txt:11") && e.contains("nan"), "{e}");
        let short = text.replace("3 4", "3");
        let mut r = DumpReader::new(std::io::Cursor::new(short), Path::new("x.txt"));
        let e = r.next_block().unwrap_err().to_string();
        assert!(e.contains("1 values"), "{e}");
    }

    #[test]
    fn deck_block_schedules_steps() {
        let b = deck_block(&[0, 10, 25], 30).unwrap();
        assert!(b.contains("(step<10)*10 + (step>=10)*(step<25)*25 + (step>=25)*70"));
        assert!(b.contains("first yes"));
        assert!(b.contains("pair/gran/local pos id force contactPoint"));
        let b = deck_block(&[10], 30).unwrap();
        assert!(!b.contains("first yes"));
        assert!(deck_block(&[10, 10], 30).is_err());
        assert!(deck_block(&[40], 30).is_err());
        assert!(deck_block(&[], 30).unwrap().is_empty());
    }

    #[test]
    fn compressed_dumps_read_back_as_written_and_replace_the_plain_ones() {
        let dir = tempfile::tempdir().unwrap();
        let text = "ITEM: TIMESTEP\n7\nITEM: NUMBER OF ENTRIES\n2\nITEM: BOX BOUNDS ff ff ff\n0 1\n0 1\n0 1\nITEM: ENTRIES a b\n1.25 2\n3 4.000000000000001\n";
        let pair = pair_file(dir.path(), 7);
        std::fs::write(&pair, text).unwrap();
        std::fs::write(dir.path().join("other.txt"), "kept as it is").unwrap();
        let plain = read_one(&pair, 7).unwrap();
        let (before, after) = compress_dumps(dir.path()).unwrap();
        assert_eq!(before, text.len() as u64);
        assert!(after > 0);
        assert!(!pair.exists(), "the plain dump is replaced");
        assert!(dir.path().join("snap_pair.7.txt.zst").exists());
        assert!(
            dir.path().join("other.txt").exists(),
            "only dumps are compressed"
        );
        let back = read_one(&pair, 7).unwrap();
        assert_eq!(
            (back.step, &back.columns, &back.values),
            (plain.step, &plain.columns, &plain.values)
        );
        // Nothing left to compress: a second call changes nothing.
        assert_eq!(compress_dumps(dir.path()).unwrap(), (0, 0));
        assert!(is_dump_name("snap_atoms.0.txt") && is_dump_name("snap_wall.10.txt.zst"));
        assert!(!is_dump_name("snapshot_00_grains.csv.zst") && !is_dump_name("snap_pair.7.log"));
        // An interrupted compression's temporary file is cleared with the dumps by the
        // next run, but never taken for a dump to compress or read.
        assert!(is_dump_name(".snap_pair.7.txt.zst.partial"));
        assert!(!is_dump_name(".snap_pair.7.txt") && !is_dump_name("snap_pair.7.txt.zst.partial"));
        // A damaged compressed dump is an error naming it, never an empty snapshot.
        std::fs::write(dir.path().join("snap_pair.7.txt.zst"), b"not zstd").unwrap();
        let e = format!("{:#}", read_one(&pair, 7).unwrap_err());
        assert!(e.contains("snap_pair.7.txt.zst"), "{e}");
    }
}
