//! Micro cases (a few grains, walls): one unit, the case itself. Both engines' frames
//! are compared output step by output step, streamed from disk: the native run writes
//! `particles.csv`, LIGGGHTS its dump, and neither trajectory is held in memory.

use super::reference::Verified;
use super::{DeckFiles, Derived, Estimate, Experiment, Options, Role, Run, Verdict};
use crate::case::Case;
use crate::compare::Check;
use crate::compare::trajectory::Trajectory;
use crate::engines::lammps3d::{self, Lammps3d};
use crate::engines::liggghts::{self, DumpFrames, Liggghts};
use crate::rundata::frames::{CsvFrames, Frame, JSONL_FILE, JsonlFrames};
use crate::rundata::paired_frames::PairedWriter;
use crate::rundata::provenance::{
    EngineKind, Provenance, Sha256, read_provenance, write_provenance,
};
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};

pub const PARTICLES_FILE: &str = "particles.csv";
const PROVENANCE_FILE: &str = "provenance.json";

pub struct Micro {
    pub case: Case,
}

/// A finished run: where its frames are, and where it came from.
pub struct MicroRun {
    frames: FrameFile,
    provenance: Provenance,
}

enum FrameFile {
    Csv(PathBuf),
    Dump(PathBuf),
    /// Native clump run: `frames.jsonl`.
    Jsonl(PathBuf),
    /// LIGGGHTS clump run: the directory with the body dump (and the free-sphere dump).
    ClumpDump(PathBuf),
}

impl Run for MicroRun {
    fn provenance(&self) -> &Provenance {
        &self.provenance
    }
}

impl MicroRun {
    fn open(&self, case: &Case) -> Result<Box<dyn Iterator<Item = Result<Frame>>>> {
        Ok(match &self.frames {
            FrameFile::Csv(p) => Box::new(CsvFrames::open(p, case.dt)?),
            FrameFile::Dump(p) => Box::new(DumpFrames::open(p, case.dt)?),
            FrameFile::Jsonl(p) => Box::new(JsonlFrames::open(p)?),
            // Clump runs are short (a few bodies): read whole.
            FrameFile::ClumpDump(d) => {
                Box::new(liggghts::clumps::clump_frames(case, d)?.into_iter().map(Ok))
            }
        })
    }
}

/// Feeds two frame streams into the comparison; a read error ends it as an error check.
pub fn compare_streams(
    case: &Case,
    test: impl Iterator<Item = Result<Frame>>,
    reference: impl Iterator<Item = Result<Frame>>,
) -> Vec<Check> {
    compare_streams_into(case, test, reference, None)
}

/// [`compare_streams`], also writing both trajectories in one schema and their
/// deviation into `tables` ([`PairedWriter`]) as the frames pass. A table that cannot
/// be written is an error check of its own: an output a user reads is never silently
/// missing.
pub(crate) fn compare_streams_into(
    case: &Case,
    test: impl Iterator<Item = Result<Frame>>,
    reference: impl Iterator<Item = Result<Frame>>,
    tables: Option<PairedWriter>,
) -> Vec<Check> {
    let mut tables = tables;
    let mut table_error: Option<anyhow::Error> = None;
    let mut t = Trajectory::new(case);
    let (mut test, mut reference) = (test, reference);
    let (mut na, mut nb) = (0usize, 0usize);
    loop {
        match (test.next(), reference.next()) {
            (None, None) => break,
            (Some(Err(e)), _) | (_, Some(Err(e))) => {
                return vec![Check::error(
                    format!("{}: frames", case.name),
                    format!("{e:#}"),
                )];
            }
            (Some(Ok(a)), Some(Ok(b))) => {
                na += 1;
                nb += 1;
                t.push(&a, &b);
                if let Some(w) = tables.as_mut()
                    && let Err(e) = w.push(&a, &b)
                {
                    table_error = Some(e);
                    tables = None;
                }
            }
            (Some(Ok(_)), None) => {
                na += 1;
                na += test.by_ref().count();
                t.length_mismatch(na, nb);
                break;
            }
            (None, Some(Ok(_))) => {
                nb += 1;
                nb += reference.by_ref().count();
                t.length_mismatch(na, nb);
                break;
            }
        }
    }
    if let Some(w) = tables
        && let Err(e) = w.finish(t.scales())
    {
        table_error = Some(e);
    }
    let mut checks = t.finish();
    if let Some(e) = table_error {
        checks.push(Check::error(
            format!("{}: tables", case.name),
            format!("{e:#}"),
        ));
    }
    checks
}

/// The files a micro record keeps: inputs, dumps, log.
fn record_files(case: &Case) -> Vec<&'static str> {
    if case.lammps().is_some() {
        vec![
            lammps3d::DECK_FILE,
            lammps3d::DATA_FILE,
            lammps3d::DUMP_FILE,
            lammps3d::LOG_FILE,
        ]
    } else if case.clumps.is_empty() {
        vec![
            liggghts::DECK_FILE,
            liggghts::DATA_FILE,
            liggghts::DUMP_FILE,
            liggghts::LOG_FILE,
        ]
    } else {
        let mut v = vec![
            liggghts::DECK_FILE,
            liggghts::clumps::BODY_DUMP_FILE,
            liggghts::LOG_FILE,
        ];
        if !case.particles.is_empty() {
            v.push(liggghts::DUMP_FILE);
        }
        v
    }
}

impl Experiment for Micro {
    type Unit = ();
    type NativeRun = MicroRun;
    type RefRun = MicroRun;
    type Case = Case;

    fn case(&self) -> &Case {
        &self.case
    }
    fn kind(&self) -> &'static str {
        "micro"
    }
    fn reference_engine(&self) -> EngineKind {
        self.case.reference_engine()
    }

    fn estimate(&self) -> Estimate {
        // Spheres the engines integrate: every clump body counts its member spheres.
        let n = self.case.particles.len() as f64
            + self
                .case
                .clumps
                .bodies
                .iter()
                .map(|b| self.case.clumps.template_of(b).radii.len() as f64)
                .sum::<f64>();
        let steps = self.case.n_steps as f64;
        let frames = steps / self.case.output_every as f64 + 1.0;
        // About 300 bytes per particle per frame in particles.csv and in the dump;
        // memory: the state plus neighbour list, ~2 kB per particle.
        Estimate {
            particle_steps: n * steps * (1 + self.case.negative_controls.len()) as f64,
            particles: n,
            output_bytes: 2.0 * 300.0 * n * frames,
            memory_bytes: 2e3 * n + 1e8,
        }
    }

    fn probe_reference(&self) -> Result<Option<String>> {
        if self.case.lammps().is_some() {
            return lammps3d::probe_reference();
        }
        super::reference::probe(self.reference_engine())
    }

    fn preflight(&self) -> Result<()> {
        if self.case.lammps().is_some() {
            return lammps3d::write_deck(&self.case).map(|_| ());
        }
        liggghts::check_liggghts_limits(&self.case)?;
        crate::physics::dem::Simulation::from_case(&self.case)
            .check_start()
            .with_context(|| format!("{}: the start state", self.case.source.display()))
    }

    fn derived(&self) -> Vec<Derived> {
        let c = &self.case;
        vec![
            Derived::new(
                "particles",
                c.particles.len().to_string(),
                format!("{} wall(s), {} material(s)", c.walls.len(), c.n_types()),
            ),
            Derived::new(
                "clumps",
                c.clumps.bodies.len().to_string(),
                format!(
                    "rigid bodies of {} member spheres in all ({} templates); the estimates count every sphere",
                    c.clumps
                        .bodies
                        .iter()
                        .map(|b| c.clumps.template_of(b).radii.len())
                        .sum::<usize>(),
                    c.clumps.templates.len()
                ),
            ),
            Derived::new(
                "Rayleigh time",
                format!("{:.4e} s", c.rayleigh_time),
                "smallest over the particles (Feng et al. Sec. 2)",
            ),
            Derived::new(
                "time step",
                format!("{:e} s", c.dt),
                format!(
                    "{:.2} % of the Rayleigh time (validation refuses > 100 %; about 20 % is usual)",
                    100.0 * c.dt / c.rayleigh_time
                ),
            ),
            Derived::new(
                "run",
                format!("{} steps", c.n_steps),
                format!(
                    "{:.4e} s simulated; {} frames (every {} steps)",
                    c.dt * c.n_steps as f64,
                    liggghts::expected_frames(c),
                    c.output_every
                ),
            ),
        ]
    }

    fn units(&self, _opts: &Options) -> Result<Vec<()>> {
        Ok(vec![()])
    }
    fn unit_name(&self, _unit: &()) -> String {
        String::new()
    }
    fn fingerprint(&self, _unit: &()) -> Result<Sha256> {
        if self.case.lammps().is_some() {
            return lammps3d::micro_input_hash(&self.case);
        }
        liggghts::micro_input_hash(&self.case)
    }
    fn engine_input(&self, _unit: &()) -> Result<Vec<(&'static str, String)>> {
        if self.case.lammps().is_some() {
            return lammps3d::micro_inputs(&self.case);
        }
        liggghts::micro_inputs(&self.case)
    }

    fn run_native(&self, _unit: &(), role: Role, dir: &Path, opts: &Options) -> Result<MicroRun> {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let csv = dir.join(PARTICLES_FILE);
        let bar = crate::report::progress::bar(opts.progress, self.case.n_steps, "native");
        let provenance =
            crate::engines::native::micro(&self.case, &role.perturbation(), &csv, |s| {
                if s.is_multiple_of(1000) {
                    bar.set_position(s);
                }
            })?;
        bar.finish_and_clear();
        write_provenance(&dir.join(PROVENANCE_FILE), &provenance)?;
        Ok(MicroRun {
            frames: if self.case.clumps.is_empty() || self.case.lammps().is_some() {
                FrameFile::Csv(csv)
            } else {
                FrameFile::Jsonl(dir.join(JSONL_FILE))
            },
            provenance,
        })
    }

    fn write_deck(&self, _unit: &(), dir: &Path, opts: &Options) -> Result<()> {
        use crate::engines::viz_dump::{self, VizEngine};
        std::fs::create_dir_all(dir)?;
        let (deck_file, engine) = if self.case.lammps().is_some() {
            (lammps3d::DECK_FILE, VizEngine::Lammps3d)
        } else {
            (liggghts::DECK_FILE, VizEngine::Liggghts)
        };
        for (name, mut text) in self.engine_input(&())? {
            if let (Some(n), true) = (opts.viz_every, name == deck_file) {
                text = viz_dump::add(&text, engine, n, self.case.n_steps)?;
            }
            std::fs::write(dir.join(name), text)?;
        }
        Ok(())
    }

    fn run_reference(&self, _unit: &(), dir: &Path, opts: &Options) -> Result<MicroRun> {
        if self.case.lammps().is_some() {
            let Some(binary) = lammps3d::binary() else {
                bail!(
                    "LAMMPS {} is hidden ({}=none)",
                    lammps3d::REQUIRED_VERSION,
                    lammps3d::ENV_VAR
                );
            };
            let lmp = Lammps3d {
                binary,
                limits: super::engine_limits(self, opts),
            };
            let provenance = lammps3d::micro(&lmp, &self.case, dir)?;
            write_provenance(&dir.join(PROVENANCE_FILE), &provenance)?;
            return Ok(MicroRun {
                frames: FrameFile::Dump(dir.join(lammps3d::DUMP_FILE)),
                provenance,
            });
        }
        let lig = Liggghts {
            mpi_procs: opts.mpi_procs,
            limits: super::engine_limits(self, opts),
            ..Liggghts::default()
        };
        let provenance = liggghts::micro(&lig, &self.case, dir)?;
        write_provenance(&dir.join(PROVENANCE_FILE), &provenance)?;
        Ok(MicroRun {
            frames: if self.case.clumps.is_empty() {
                FrameFile::Dump(dir.join(liggghts::DUMP_FILE))
            } else {
                FrameFile::ClumpDump(dir.to_path_buf())
            },
            provenance,
        })
    }

    fn record(&self, _unit: &(), run: &MicroRun, run_dir: &Path, rec: &Path) -> Result<()> {
        std::fs::create_dir_all(rec)?;
        for f in record_files(&self.case) {
            std::fs::copy(run_dir.join(f), rec.join(f))
                .with_context(|| format!("copying {f} into {}", rec.display()))?;
        }
        let mut p = run.provenance.clone();
        p.notes.retain(|n| !n.starts_with("run directory"));
        write_provenance(&rec.join(PROVENANCE_FILE), &p)
    }

    fn read_record(&self, _unit: &(), name: &str, seal: &Verified) -> Result<MicroRun> {
        let provenance = read_provenance(&seal.file(name, PROVENANCE_FILE)?)?;
        if !provenance.engine.is_reference() {
            bail!(
                "{}: engine {} is not a reference engine",
                seal.root.display(),
                provenance.engine
            );
        }
        let frames = if self.case.lammps().is_some() {
            FrameFile::Dump(seal.file(name, lammps3d::DUMP_FILE)?)
        } else if self.case.clumps.is_empty() {
            FrameFile::Dump(seal.file(name, liggghts::DUMP_FILE)?)
        } else {
            // Every recorded file is checked against the seal before the directory is used.
            for f in record_files(&self.case) {
                seal.file(name, f)?;
            }
            let body = seal.file(name, liggghts::clumps::BODY_DUMP_FILE)?;
            FrameFile::ClumpDump(body.parent().map(Path::to_path_buf).unwrap_or_default())
        };
        Ok(MicroRun { frames, provenance })
    }

    fn read_run_dir(&self, _unit: &(), dir: &Path) -> Result<MicroRun> {
        if self.case.lammps().is_some() {
            let provenance = lammps3d::micro_finished(&self.case, dir)?;
            return Ok(MicroRun {
                frames: FrameFile::Dump(dir.join(lammps3d::DUMP_FILE)),
                provenance,
            });
        }
        let provenance = liggghts::micro_finished(&self.case, dir)?;
        Ok(MicroRun {
            frames: FrameFile::Dump(dir.join(liggghts::DUMP_FILE)),
            provenance,
        })
    }

    fn deck_files(&self) -> DeckFiles {
        if self.case.lammps().is_some() {
            return DeckFiles {
                binary: lammps3d::DEFAULT_BINARY,
                deck: lammps3d::DECK_FILE,
                log: lammps3d::LOG_FILE,
                inputs: &[(
                    lammps3d::DATA_FILE,
                    "the particles (read_data, atom_style sphere): box, and per atom id, type, diameter, density, position, velocity, angular velocity",
                )],
                outputs: &[
                    (
                        lammps3d::DUMP_FILE,
                        "the trajectory: every output_every steps each particle's position, velocity, angular velocity, force and torque (%.17g)",
                    ),
                    (
                        lammps3d::LOG_FILE,
                        "LAMMPS' log (version, warnings, thermo lines)",
                    ),
                ],
            };
        }
        DeckFiles {
            binary: "liggghts",
            deck: liggghts::DECK_FILE,
            log: liggghts::LOG_FILE,
            inputs: &[(
                liggghts::DATA_FILE,
                "the particles (read_data): box, and per atom id, type, diameter, density, position, velocity, angular velocity",
            )],
            outputs: &[
                (
                    liggghts::DUMP_FILE,
                    "the trajectory: every output_every steps each particle's position, velocity, angular velocity and force (%.17g)",
                ),
                (
                    liggghts::LOG_FILE,
                    "LIGGGHTS' log (version, warnings, thermo lines)",
                ),
            ],
        }
    }

    fn drift(&self, previous: &MicroRun, now: &MicroRun) -> String {
        match (now.open(&self.case), previous.open(&self.case)) {
            (Ok(a), Ok(b)) => compare_streams(&self.case, a, b)
                .iter()
                .filter(|c| c.gate != crate::compare::Gate::Coverage)
                .map(|c| format!("{} {:.2e}", c.metric, c.value))
                .collect::<Vec<_>>()
                .join(", "),
            (a, b) => format!(
                "not comparable: {:?} / {:?}",
                a.err().map(|e| e.to_string()),
                b.err().map(|e| e.to_string())
            ),
        }
    }

    fn checks(
        &self,
        _units: &[()],
        native: &[MicroRun],
        reference: &[MicroRun],
        out: &Path,
        _opts: &Options,
    ) -> Verdict {
        let checks = match (native[0].open(&self.case), reference[0].open(&self.case)) {
            (Ok(a), Ok(b)) => {
                match PairedWriter::create(out, "native", reference[0].provenance.engine.label()) {
                    Ok(w) => compare_streams_into(&self.case, a, b, Some(w)),
                    Err(e) => {
                        let mut c = compare_streams(&self.case, a, b);
                        c.push(Check::error(
                            format!("{}: tables", self.case.name),
                            format!("{e:#}"),
                        ));
                        c
                    }
                }
            }
            (Err(e), _) | (_, Err(e)) => vec![Check::error(
                format!("{}: frames", self.case.name),
                format!("{e:#}"),
            )],
        };
        Verdict {
            checks,
            ..Verdict::default()
        }
    }
}
