//! A micro comparison as two tables a script loads in one line each (`pandas.read_csv`):
//! both engines' trajectories in one schema (`trajectories.csv`) and their deviation per
//! particle and output step (`deviation.csv`). The native engine writes `particles.csv`
//! and LIGGGHTS a dump; without these, every look at a comparison outside granval starts
//! with a hand-written dump parser.
//!
//! `trajectories.csv`: `engine,step,t,id,x,y,z,vx,vy,vz,wx,wy,wz,fx,fy,fz`, SI units, one
//! row per engine, particle and output step (the spheres of a clump case are its
//! particles; its bodies are not in it).
//!
//! `deviation.csv`: `step,t,id,dx_over_r_min,dv_over_v_max,dw_over_w_max,dx,dv,dw`: the
//! vector norms |x_test - x_ref| (m), |v_test - v_ref| (m/s), |w_test - w_ref| (rad/s)
//! and the same divided by the scales the micro gates use (docs/micro.md): the smallest
//! radius, the largest speed of the reference run, its largest angular speed (or the
//! largest speed over the smallest radius if it never rotates). The largest value of
//! each normalised column is the value of its gate. The scales are known only at the
//! end, so the absolute columns go to a partial file first and the table is written
//! from it when the comparison ends; the normalised columns are empty when the
//! reference never moves (the comparison is then an error).

use super::frames::Frame;
use anyhow::{Context, Result};
use std::fs::File;
use std::path::{Path, PathBuf};

pub(crate) const TRAJECTORIES_FILE: &str = "trajectories.csv";
pub(crate) const DEVIATION_FILE: &str = "deviation.csv";

/// Column order of `trajectories.csv`.
pub(crate) const TRAJECTORIES_HEADER: [&str; 16] = [
    "engine", "step", "t", "id", "x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz", "fx", "fy",
    "fz",
];

/// Column order of `deviation.csv`.
pub(crate) const DEVIATION_HEADER: [&str; 9] = [
    "step",
    "t",
    "id",
    "dx_over_r_min",
    "dv_over_v_max",
    "dw_over_w_max",
    "dx",
    "dv",
    "dw",
];

/// The scales of the normalised deviation columns: (smallest radius, largest reference
/// speed, largest reference angular speed or its stand-in).
pub type Scales = (f64, f64, f64);

/// Writes both tables as the frame pairs of a comparison arrive.
pub(crate) struct PairedWriter {
    dir: PathBuf,
    labels: [String; 2],
    traj: csv::Writer<File>,
    partial: csv::Writer<File>,
}

fn norm_of_difference(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

fn partial_path(dir: &Path) -> PathBuf {
    dir.join(format!("{DEVIATION_FILE}.partial"))
}

impl PairedWriter {
    /// Tables in `dir`; `test` and `reference` name the engines in the `engine` column.
    pub fn create(dir: &Path, test: &str, reference: &str) -> Result<PairedWriter> {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let open = |p: PathBuf| {
            csv::Writer::from_path(&p).with_context(|| format!("cannot create {}", p.display()))
        };
        let mut traj = open(dir.join(TRAJECTORIES_FILE))?;
        traj.write_record(TRAJECTORIES_HEADER)?;
        let partial = open(partial_path(dir))?;
        Ok(PairedWriter {
            dir: dir.to_path_buf(),
            labels: [test.to_string(), reference.to_string()],
            traj,
            partial,
        })
    }

    /// One output step of both engines. Deviation rows pair particles by id; a pair
    /// the comparison refuses (other steps, other particles) gets none.
    pub fn push(&mut self, test: &Frame, reference: &Frame) -> Result<()> {
        for (label, fr) in self.labels.iter().zip([test, reference]) {
            for p in &fr.particles {
                let mut rec: Vec<String> = Vec::with_capacity(16);
                rec.push(label.clone());
                rec.push(fr.step.to_string());
                rec.push(format!("{:e}", fr.t));
                rec.push(p.id.to_string());
                for a in [p.x, p.v, p.omega, p.f] {
                    rec.extend(a.iter().map(|c| format!("{c:e}")));
                }
                self.traj.write_record(&rec).with_context(|| {
                    format!(
                        "cannot write {}",
                        self.dir.join(TRAJECTORIES_FILE).display()
                    )
                })?;
            }
        }
        if test.step != reference.step {
            return Ok(());
        }
        for (p, q) in test.particles.iter().zip(&reference.particles) {
            if p.id != q.id {
                break;
            }
            self.partial
                .write_record([
                    test.step.to_string(),
                    format!("{:e}", reference.t),
                    p.id.to_string(),
                    format!("{:e}", norm_of_difference(p.x, q.x)),
                    format!("{:e}", norm_of_difference(p.v, q.v)),
                    format!("{:e}", norm_of_difference(p.omega, q.omega)),
                ])
                .with_context(|| format!("cannot write {}", partial_path(&self.dir).display()))?;
        }
        Ok(())
    }

    /// Finishes both tables: `deviation.csv` from the partial file with the normalised
    /// columns (`scales`: `None` leaves them empty), the partial file removed.
    pub fn finish(mut self, scales: Option<Scales>) -> Result<()> {
        self.traj.flush().with_context(|| {
            format!(
                "cannot write {}",
                self.dir.join(TRAJECTORIES_FILE).display()
            )
        })?;
        self.partial.flush()?;
        drop(self.partial);
        let partial = partial_path(&self.dir);
        let out = self.dir.join(DEVIATION_FILE);
        let mut w = csv::Writer::from_path(&out)
            .with_context(|| format!("cannot create {}", out.display()))?;
        w.write_record(DEVIATION_HEADER)?;
        let mut r = csv::ReaderBuilder::new()
            .has_headers(false)
            .from_path(&partial)
            .with_context(|| format!("cannot read {}", partial.display()))?;
        for row in r.records() {
            let row = row.with_context(|| format!("cannot read {}", partial.display()))?;
            let value = |i: usize| -> Result<f64> {
                row[i]
                    .parse::<f64>()
                    .with_context(|| format!("{}: not a number: {}", partial.display(), &row[i]))
            };
            let normalised = match scales {
                Some((r_min, v, w_scale)) => [
                    format!("{:e}", value(3)? / r_min),
                    format!("{:e}", value(4)? / v),
                    format!("{:e}", value(5)? / w_scale),
                ],
                None => [String::new(), String::new(), String::new()],
            };
            w.write_record([
                &row[0],
                &row[1],
                &row[2],
                &normalised[0],
                &normalised[1],
                &normalised[2],
                &row[3],
                &row[4],
                &row[5],
            ])
            .with_context(|| format!("cannot write {}", out.display()))?;
        }
        w.flush()
            .with_context(|| format!("cannot write {}", out.display()))?;
        std::fs::remove_file(&partial)
            .with_context(|| format!("cannot remove {}", partial.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rundata::frames::ParticleState;

    fn frame(step: u64, x: f64, v: f64) -> Frame {
        Frame {
            step,
            t: step as f64 * 1e-6,
            particles: vec![
                ParticleState {
                    id: 1,
                    x: [x, 0.0, 0.0],
                    v: [v, 0.0, 0.0],
                    omega: [0.0; 3],
                    f: [0.0; 3],
                },
                ParticleState {
                    id: 2,
                    x: [1.0, 0.0, 0.0],
                    v: [0.0; 3],
                    omega: [0.0, 0.0, 3.0],
                    f: [0.0, 0.0, -1.0],
                },
            ],
            bodies: vec![],
        }
    }

    /// Both engines' rows in one schema, and deviations that are the vector norms of the
    /// differences divided by the scales given at the end; a pair at different steps
    /// (a comparison error) gets trajectory rows but no deviation rows.
    #[test]
    fn both_engines_in_one_table_and_their_deviation() {
        let tmp = tempfile::tempdir().unwrap();
        let mut w = PairedWriter::create(tmp.path(), "native", "LIGGGHTS").unwrap();
        w.push(&frame(0, 0.0, 2.0), &frame(0, 0.0, 2.0)).unwrap();
        w.push(&frame(10, 3e-3, 1.0), &frame(10, 2e-3, 1.5))
            .unwrap();
        w.push(&frame(20, 0.0, 0.0), &frame(30, 0.0, 0.0)).unwrap();
        w.finish(Some((1e-3, 2.0, 3.0))).unwrap();

        let mut t = csv::Reader::from_path(tmp.path().join(TRAJECTORIES_FILE)).unwrap();
        assert_eq!(t.headers().unwrap(), TRAJECTORIES_HEADER.as_slice());
        let rows: Vec<csv::StringRecord> = t.records().map(Result::unwrap).collect();
        assert_eq!(rows.len(), 12, "two engines x two particles x three steps");
        assert_eq!(&rows[2][0], "LIGGGHTS");
        assert_eq!(&rows[4][1], "10");
        assert_eq!(rows[4][4].parse::<f64>().unwrap(), 3e-3);

        let mut d = csv::Reader::from_path(tmp.path().join(DEVIATION_FILE)).unwrap();
        assert_eq!(d.headers().unwrap(), DEVIATION_HEADER.as_slice());
        let rows: Vec<csv::StringRecord> = d.records().map(Result::unwrap).collect();
        assert_eq!(rows.len(), 4, "two particles at the two matching steps");
        let f = |r: &csv::StringRecord, i: usize| r[i].parse::<f64>().unwrap();
        let step10 = &rows[2];
        assert_eq!(&step10[0], "10");
        assert!((f(step10, 6) - 1e-3).abs() < 1e-15, "|dx| in m");
        assert!((f(step10, 3) - 1.0).abs() < 1e-12, "|dx| / r_min");
        assert!((f(step10, 7) - 0.5).abs() < 1e-15, "|dv| in m/s");
        assert!((f(step10, 4) - 0.25).abs() < 1e-15, "|dv| / V");
        assert_eq!(f(&rows[3], 5), 0.0, "the spinning particle spins alike");
        assert!(!tmp.path().join("deviation.csv.partial").exists());

        // No scales (a reference that never moves): the normalised columns are empty.
        let tmp = tempfile::tempdir().unwrap();
        let mut w = PairedWriter::create(tmp.path(), "native", "LIGGGHTS").unwrap();
        w.push(&frame(0, 0.0, 0.0), &frame(0, 1e-3, 0.0)).unwrap();
        w.finish(None).unwrap();
        let text = std::fs::read_to_string(tmp.path().join(DEVIATION_FILE)).unwrap();
        assert!(
            text.lines().nth(1).unwrap().starts_with("0,0e0,1,,,,1e-3,"),
            "{text}"
        );
    }
}
