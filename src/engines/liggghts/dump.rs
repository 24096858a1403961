//! Streaming parser for LIGGGHTS/LAMMPS `dump custom` text files:
//!
//! ```text
//! ITEM: TIMESTEP
//! 0
//! ITEM: NUMBER OF ATOMS
//! 2
//! ITEM: BOX BOUNDS ff ff ff
//! lo hi (x3)
//! ITEM: ATOMS id x y z vx vy vz omegax omegay omegaz fx fy fz
//! one line per atom
//! ```
//!
//! Columns are mapped by the names in the `ITEM: ATOMS` header, never by position.

use crate::rundata::frames::{Frame, ParticleState};
use anyhow::{Context, Result, bail};
use std::io::{BufRead, BufReader};
use std::path::Path;

/// Column names the parser needs, in [`ParticleState`] order after `id`.
const VECTOR_COLUMNS: [[&str; 3]; 4] = [
    ["x", "y", "z"],
    ["vx", "vy", "vz"],
    ["omegax", "omegay", "omegaz"],
    ["fx", "fy", "fz"],
];

struct Lines<R> {
    inner: std::io::Lines<R>,
    /// 1-based number of the line last returned.
    no: usize,
}

impl<R: BufRead> Lines<R> {
    fn next(&mut self, path: &Path) -> Result<Option<String>> {
        match self.inner.next() {
            None => Ok(None),
            Some(l) => {
                self.no += 1;
                Ok(Some(l.with_context(|| {
                    format!("{}: line {}: read error", path.display(), self.no)
                })?))
            }
        }
    }

    /// The next line, which must exist (`what` says what was expected there).
    fn need(&mut self, path: &Path, what: &str) -> Result<String> {
        match self.next(path)? {
            Some(l) => Ok(l),
            None => bail!(
                "{}: line {}: file ends where {what} was expected (truncated dump?)",
                path.display(),
                self.no + 1
            ),
        }
    }
}

fn parse_num<T: std::str::FromStr>(path: &Path, line: usize, what: &str, s: &str) -> Result<T> {
    s.trim().parse::<T>().map_err(|_| {
        anyhow::anyhow!(
            "{}: line {line}: {what} {:?} is not a valid number",
            path.display(),
            s.trim()
        )
    })
}

/// Frames of a dump file, one at a time (particles sorted by id, `t = step * dt`): a
/// long run is compared without holding its trajectory in memory.
pub struct DumpFrames {
    path: std::path::PathBuf,
    dt: f64,
    lines: Lines<BufReader<crate::rundata::fsio::Bounded>>,
    pending: Option<String>,
    done: bool,
}

impl DumpFrames {
    pub fn open(path: &Path, dt: f64) -> Result<DumpFrames> {
        let file = crate::rundata::fsio::open_engine_output(path, "a LIGGGHTS dump")?;
        Ok(DumpFrames {
            path: path.to_path_buf(),
            dt,
            lines: Lines {
                inner: BufReader::new(file).lines(),
                no: 0,
            },
            pending: None,
            done: false,
        })
    }

    /// The next frame, `None` at the end of the file.
    pub(crate) fn next_frame(&mut self) -> Result<Option<Frame>> {
        let path = self.path.as_path();
        let lines = &mut self.lines;
        let mut step: Option<u64> = None;
        let mut natoms: Option<usize> = None;
        loop {
            let line = match self.pending.take() {
                Some(l) => l,
                None => match lines.next(path)? {
                    Some(l) => l,
                    None => break,
                },
            };
            let t = line.trim();
            if t.is_empty() {
                continue;
            }
            let Some(item) = t.strip_prefix("ITEM:") else {
                bail!(
                    "{}: line {}: expected an `ITEM:` line, found {:?}",
                    path.display(),
                    lines.no,
                    t
                );
            };
            let item = item.trim();
            if item == "TIMESTEP" {
                let l = lines.need(path, "the timestep")?;
                step = Some(parse_num(path, lines.no, "timestep", &l)?);
                natoms = None;
            } else if item == "NUMBER OF ATOMS" {
                let l = lines.need(path, "the number of atoms")?;
                natoms = Some(parse_num(path, lines.no, "number of atoms", &l)?);
            } else if item.starts_with("BOX BOUNDS") {
                for _ in 0..3 {
                    lines.need(path, "a box bounds line")?;
                }
            } else if let Some(cols) = item.strip_prefix("ATOMS") {
                let header_line = lines.no;
                let (Some(st), Some(n)) = (step, natoms) else {
                    bail!(
                        "{}: line {header_line}: `ITEM: ATOMS` before `ITEM: TIMESTEP` and `ITEM: NUMBER OF ATOMS`",
                        path.display()
                    );
                };
                let cols: Vec<&str> = cols.split_whitespace().collect();
                let col = |name: &str| -> Result<usize> {
                    cols.iter().position(|c| *c == name).with_context(|| {
                        format!(
                            "{}: line {header_line}: dump has no `{name}` column (columns: {})",
                            path.display(),
                            cols.join(" ")
                        )
                    })
                };
                let id_col = col("id")?;
                let mut vcols = [[0usize; 3]; 4];
                for (k, names) in VECTOR_COLUMNS.iter().enumerate() {
                    for (c, name) in names.iter().enumerate() {
                        vcols[k][c] = col(name)?;
                    }
                }
                let mut particles = Vec::with_capacity(n.min(1 << 24));
                for _ in 0..n {
                    let l = lines.need(path, "an atom line")?;
                    let fields: Vec<&str> = l.split_whitespace().collect();
                    if fields.len() != cols.len() {
                        bail!(
                            "{}: line {}: {} values but the ATOMS header (line {header_line}) names {} columns",
                            path.display(),
                            lines.no,
                            fields.len(),
                            cols.len()
                        );
                    }
                    let id: u64 = parse_num(path, lines.no, "id", fields[id_col])?;
                    let mut v = [[0.0f64; 3]; 4];
                    for k in 0..4 {
                        for c in 0..3 {
                            let name = VECTOR_COLUMNS[k][c];
                            let x: f64 = parse_num(path, lines.no, name, fields[vcols[k][c]])?;
                            if !x.is_finite() {
                                bail!(
                                    "{}: line {}: {name} of atom {id} is {x} (the run blew up?)",
                                    path.display(),
                                    lines.no
                                );
                            }
                            v[k][c] = x;
                        }
                    }
                    particles.push(ParticleState {
                        id,
                        x: v[0],
                        v: v[1],
                        omega: v[2],
                        f: v[3],
                    });
                }
                particles.sort_by_key(|p| p.id);
                if let Some(w) = particles.windows(2).find(|w| w[0].id == w[1].id) {
                    bail!(
                        "{}: frame at step {st} (ATOMS header line {header_line}): atom id {} appears twice",
                        path.display(),
                        w[0].id
                    );
                }
                return Ok(Some(Frame {
                    bodies: Vec::new(),
                    step: st,
                    t: st as f64 * self.dt,
                    particles,
                }));
            } else {
                // Items this parser does not need (e.g. `UNITS`, `TIME` of newer LAMMPS):
                // skip their body up to the next ITEM line.
                loop {
                    match lines.next(path)? {
                        None => break,
                        Some(l) if l.trim_start().starts_with("ITEM:") => {
                            self.pending = Some(l);
                            break;
                        }
                        Some(_) => {}
                    }
                }
            }
        }
        if let Some(st) = step {
            bail!(
                "{}: file ends inside the frame of step {st} (no ATOMS section; truncated dump?)",
                path.display()
            );
        }
        self.done = true;
        Ok(None)
    }
}

crate::rundata::frames::frame_iterator!(DumpFrames);

/// Parses a whole dump file into frames (small runs and tests).
pub fn parse_dump(path: &Path, dt: f64) -> Result<Vec<Frame>> {
    DumpFrames::open(path, dt)?.collect()
}
