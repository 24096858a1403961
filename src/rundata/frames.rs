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

/// One rigid clump at one output step, SI units: centre of mass, orientation quaternion
/// (w, x, y, z) of the template frame, velocity, angular velocity, and the total force
/// (gravity included) gathered in the step, as LIGGGHTS' `compute multisphere` reports
/// `xcm quat vcm omega fcm`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BodyState {
    pub id: u64,
    pub x: [f64; 3],
    pub q: [f64; 4],
    pub v: [f64; 3],
    pub omega: [f64; 3],
    pub f: [f64; 3],
}

/// All particles at one output step, sorted by id; clump cases add their bodies.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Frame {
    pub step: u64,
    pub t: f64,
    pub particles: Vec<ParticleState>,
    #[serde(default)]
    pub bodies: Vec<BodyState>,
}

/// Column order of `particles.csv`, fixed (documented in docs/commands.md) so scripts can rely on it.
pub(crate) const CSV_HEADER: [&str; 14] = [
    "t", "id", "x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz", "fx", "fy", "fz",
];

/// `particles.csv`, written one frame at a time. `{:e}` of an f64 is
/// shortest-round-trip, so the file carries full double precision without a fixed
/// digit count.
pub(crate) struct FrameWriter {
    w: csv::Writer<std::fs::File>,
    path: std::path::PathBuf,
}

impl FrameWriter {
    pub fn create(path: &Path) -> Result<FrameWriter> {
        let mut w = csv::Writer::from_path(path)
            .with_context(|| format!("cannot create {}", path.display()))?;
        w.write_record(CSV_HEADER)?;
        Ok(FrameWriter {
            w,
            path: path.to_path_buf(),
        })
    }

    pub fn write(&mut self, fr: &Frame) -> Result<()> {
        for p in &fr.particles {
            let mut rec: Vec<String> = Vec::with_capacity(14);
            rec.push(format!("{:e}", fr.t));
            rec.push(p.id.to_string());
            for a in [p.x, p.v, p.omega, p.f] {
                for c in a {
                    rec.push(format!("{c:e}"));
                }
            }
            self.w
                .write_record(&rec)
                .with_context(|| format!("cannot write {}", self.path.display()))?;
        }
        Ok(())
    }

    pub fn finish(mut self) -> Result<()> {
        self.w
            .flush()
            .with_context(|| format!("cannot write {}", self.path.display()))
    }
}

/// `particles.csv` read back one frame at a time (rows grouped by consecutive equal
/// `t`); step numbers are recovered from `t / dt`.
pub struct CsvFrames {
    path: std::path::PathBuf,
    dt: f64,
    records: csv::StringRecordsIntoIter<super::fsio::Bounded>,
    line: usize,
    pending: Option<(f64, ParticleState)>,
    done: bool,
}

impl CsvFrames {
    pub fn open(path: &Path, dt: f64) -> Result<CsvFrames> {
        let mut r =
            csv::Reader::from_reader(super::fsio::open_engine_output(path, "a particle CSV")?);
        let header: Vec<String> = r.headers()?.iter().map(str::to_string).collect();
        if header != CSV_HEADER {
            anyhow::bail!(
                "{}: header {:?} is not the expected {:?}",
                path.display(),
                header,
                CSV_HEADER
            );
        }
        Ok(CsvFrames {
            path: path.to_path_buf(),
            dt,
            records: r.into_records(),
            line: 1,
            pending: None,
            done: false,
        })
    }

    fn row(&mut self) -> Result<Option<(f64, ParticleState)>> {
        let Some(rec) = self.records.next() else {
            return Ok(None);
        };
        self.line += 1;
        let (path, line) = (&self.path, self.line);
        let rec = rec.with_context(|| format!("{}: record {line}", path.display()))?;
        if rec.len() != CSV_HEADER.len() {
            anyhow::bail!(
                "{}: line {line}: {} columns, expected {}",
                path.display(),
                rec.len(),
                CSV_HEADER.len()
            );
        }
        let num = |k: usize| -> Result<f64> {
            rec[k].parse::<f64>().with_context(|| {
                format!(
                    "{}: line {line}: column {} = {:?} is not a number",
                    path.display(),
                    CSV_HEADER[k],
                    &rec[k]
                )
            })
        };
        let t = num(0)?;
        let id: u64 = rec[1]
            .parse()
            .with_context(|| format!("{}: line {line}: bad id {:?}", path.display(), &rec[1]))?;
        let v3 = |k: usize| -> Result<[f64; 3]> { Ok([num(k)?, num(k + 1)?, num(k + 2)?]) };
        Ok(Some((
            t,
            ParticleState {
                id,
                x: v3(2)?,
                v: v3(5)?,
                omega: v3(8)?,
                f: v3(11)?,
            },
        )))
    }

    pub(crate) fn next_frame(&mut self) -> Result<Option<Frame>> {
        let first = match self.pending.take() {
            Some(r) => r,
            None => match self.row()? {
                Some(r) => r,
                None => return Ok(None),
            },
        };
        let t = first.0;
        let mut particles = vec![first.1];
        loop {
            match self.row()? {
                Some(r) if r.0 == t => particles.push(r.1),
                Some(r) => {
                    self.pending = Some(r);
                    break;
                }
                None => break,
            }
        }
        particles.sort_by_key(|p| p.id);
        Ok(Some(Frame {
            bodies: Vec::new(),
            step: (t / self.dt).round() as u64,
            t,
            particles,
        }))
    }
}

/// `Iterator<Item = Result<Frame>>` for a streaming frame reader with a `done` field and
/// a `next_frame() -> Result<Option<Frame>>`: it stops for good after the first error, so
/// a truncated file is reported once, not on every later call.
macro_rules! frame_iterator {
    ($t:ty) => {
        impl Iterator for $t {
            type Item = anyhow::Result<$crate::rundata::frames::Frame>;
            fn next(&mut self) -> Option<Self::Item> {
                if self.done {
                    return None;
                }
                match self.next_frame() {
                    Ok(Some(f)) => Some(Ok(f)),
                    Ok(None) => None,
                    Err(e) => {
                        self.done = true;
                        Some(Err(e))
                    }
                }
            }
        }
    };
}
pub(crate) use frame_iterator;

frame_iterator!(CsvFrames);

/// File name of a clump case's native frames.
pub(crate) const JSONL_FILE: &str = "frames.jsonl";

/// Frames of a clump case (`frames.jsonl`): one JSON [`Frame`] per line, bodies included.
/// serde_json writes f64 in shortest round-trip form, so no precision is lost; a CSV row
/// per particle cannot hold a frame that has bodies but no free sphere.
pub(crate) struct JsonlFrameWriter {
    w: std::io::BufWriter<std::fs::File>,
    path: std::path::PathBuf,
}

impl JsonlFrameWriter {
    pub fn create(path: &Path) -> Result<JsonlFrameWriter> {
        let f = std::fs::File::create(path)
            .with_context(|| format!("cannot create {}", path.display()))?;
        Ok(JsonlFrameWriter {
            w: std::io::BufWriter::new(f),
            path: path.to_path_buf(),
        })
    }

    pub fn write(&mut self, fr: &Frame) -> Result<()> {
        use std::io::Write;
        serde_json::to_writer(&mut self.w, fr)
            .and_then(|_| self.w.write_all(b"\n").map_err(serde_json::Error::io))
            .with_context(|| format!("cannot write {}", self.path.display()))
    }

    pub fn finish(mut self) -> Result<()> {
        use std::io::Write;
        self.w
            .flush()
            .with_context(|| format!("cannot write {}", self.path.display()))
    }
}

/// `frames.jsonl` read back one frame at a time.
pub(crate) struct JsonlFrames {
    path: std::path::PathBuf,
    lines: std::io::Lines<std::io::BufReader<super::fsio::Bounded>>,
    no: usize,
}

impl JsonlFrames {
    pub fn open(path: &Path) -> Result<JsonlFrames> {
        use std::io::BufRead;
        let f = super::fsio::open_engine_output(path, "a frames file (JSON lines)")?;
        Ok(JsonlFrames {
            path: path.to_path_buf(),
            lines: std::io::BufReader::new(f).lines(),
            no: 0,
        })
    }
}

impl Iterator for JsonlFrames {
    type Item = Result<Frame>;
    fn next(&mut self) -> Option<Result<Frame>> {
        let line = self.lines.next()?;
        self.no += 1;
        let (path, no) = (&self.path, self.no);
        Some(
            line.with_context(|| format!("{}: line {no}: read error", path.display()))
                .and_then(|l| {
                    serde_json::from_str(&l)
                        .with_context(|| format!("{}: line {no}: not a frame", path.display()))
                }),
        )
    }
}
