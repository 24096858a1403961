//! LIGGGHTS 3.8 adapter: writes a deck and a `read_data` file for a validated [`Case`],
//! runs `liggghts` (optionally under `mpirun`) in the run directory, parses the dump into
//! the common [`RunOutput`].
//!
//! Files in the run directory: `in.granval` (deck), `data.granval` (particles and box),
//! `dump.granval` (trajectory), `log.liggghts`, `liggghts.stdout`, `liggghts.stderr`.
//! A run directory is therefore self-describing and can be re-run by hand with the
//! command recorded in the provenance.

pub mod clump_bed;
pub mod clumps;
mod deck;
mod dump;
pub mod penetration;
pub mod snapshot;
pub mod stl;
pub mod triaxial;
pub mod units;

pub(crate) use deck::{
    DUMP_COLUMNS, MIN_RESTITUTION_EXCLUSIVE, check_liggghts_limits, check_materials, hardness,
};
pub use deck::{expected_frames, hardness_note, write_data_file, write_deck};
pub(crate) use dump::DumpFrames;
pub use dump::parse_dump;

use crate::case::Case;
use crate::engines::process::{self, Transcript, TranscriptFiles};
use crate::rundata::provenance::{EngineKind, Provenance, Sha256, now_utc};
use anyhow::{Context, Result, bail};
use std::path::Path;

pub const DECK_FILE: &str = "in.granval";
pub const DATA_FILE: &str = "data.granval";
pub(crate) const DUMP_FILE: &str = "dump.granval";
pub const LOG_FILE: &str = "log.liggghts";
pub(crate) const STDOUT_FILE: &str = "liggghts.stdout";
pub(crate) const STDERR_FILE: &str = "liggghts.stderr";

/// Where a LIGGGHTS run directory keeps its transcript.
pub(crate) const TRANSCRIPT: TranscriptFiles = TranscriptFiles {
    engine: "LIGGGHTS",
    log: LOG_FILE,
    stdout: &[STDOUT_FILE],
    stderr: STDERR_FILE,
};

/// Prefix of the banner line LIGGGHTS prints first (screen and log).
const VERSION_PREFIX: &str = "LIGGGHTS (Version";

/// How LIGGGHTS is invoked.
#[derive(Debug, Clone)]
pub struct Liggghts {
    /// Executable name or path, `liggghts` by default.
    pub binary: String,
    /// 1: plain `liggghts -in`; N > 1: `mpirun --allow-run-as-root -np N liggghts -in`.
    pub mpi_procs: usize,
    /// How long the run may take and stay silent (the run is an error past either).
    pub limits: process::Limits,
}

/// The LIGGGHTS executable: `GRANVAL_LIGGGHTS` if set and not empty (a build called
/// `lmp_liggghts` or `liggghts-3.8`, a path, or a missing name to exercise the recorded
/// fallback), else `liggghts`. The same rule as LAMMPS' `GRANVAL_LMP`.
pub fn binary() -> String {
    std::env::var("GRANVAL_LIGGGHTS")
        .ok()
        .filter(|b| !b.trim().is_empty())
        .unwrap_or_else(|| "liggghts".into())
}

impl Default for Liggghts {
    fn default() -> Self {
        Liggghts {
            binary: binary(),
            mpi_procs: 1,
            limits: process::Limits::derived(0.0, None, None),
        }
    }
}

impl Liggghts {
    /// The exact argument vector, run inside the run directory.
    pub fn argv(&self) -> Vec<String> {
        let mut argv = process::mpi_prefix(self.mpi_procs);
        argv.push(self.binary.clone());
        argv.extend(["-in", DECK_FILE, "-log", LOG_FILE].map(String::from));
        argv
    }
}

/// The version probe of `binary` ([`process::probe`]): its banner (e.g. `LIGGGHTS
/// (Version LIGGGHTS-PUBLIC 3.8.0, compiled ...)`) when it is LIGGGHTS 3.x, broken when
/// it is another version (granval's decks are LIGGGHTS 3.8 syntax), absent when there
/// is no such executable.
pub fn probe(binary: &str) -> process::Probe {
    process::probe(
        binary,
        VERSION_PREFIX,
        |banner| match banner_major_version(banner) {
            Some(3) => Ok(()),
            Some(v) => Err(format!(
                "is LIGGGHTS {v}.x ({banner}); granval's decks are written for LIGGGHTS 3.x"
            )),
            None => Err(format!(
                "no version number in its banner ({banner}); granval's decks are written for LIGGGHTS 3.x"
            )),
        },
    )
}

/// The banner of `binary` when it is a working LIGGGHTS 3.x, `None` otherwise (missing
/// or broken alike; [`probe`] tells them apart).
pub fn installed_version(binary: &str) -> Option<String> {
    match probe(binary) {
        process::Probe::Found(banner) => Some(banner),
        _ => None,
    }
}

/// The major version in a banner such as `LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, ...`:
/// the first word after `Version` that starts with a digit.
fn banner_major_version(banner: &str) -> Option<u32> {
    let rest = banner.split_once("Version")?.1;
    rest.split(|c: char| c.is_whitespace() || c == ',' || c == '-')
        .find(|w| w.starts_with(|c: char| c.is_ascii_digit()))?
        .split('.')
        .next()?
        .parse()
        .ok()
}

/// Runs a micro case in LIGGGHTS in `dir` (deck, data file, dump, log, transcript all
/// stay there) and checks that the dump holds every expected frame of every particle.
/// The frames are read afterwards with [`micro_frames`], one at a time.
pub fn micro(lig: &Liggghts, case: &Case, dir: &Path) -> Result<Provenance> {
    let inputs = micro_inputs(case)?;
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create run directory {}", dir.display()))?;
    process::remove_stale(
        dir,
        &[
            DUMP_FILE,
            clumps::BODY_DUMP_FILE,
            LOG_FILE,
            STDOUT_FILE,
            STDERR_FILE,
        ],
    )?;
    for (name, text) in &inputs {
        let p = dir.join(name);
        std::fs::write(&p, text).with_context(|| format!("cannot write {}", p.display()))?;
    }

    let argv = lig.argv();
    let command = process::command_line(&argv);
    let fin = process::run(
        &argv,
        dir,
        &dir.join(STDOUT_FILE),
        &dir.join(STDERR_FILE),
        &lig.limits,
    )
    .with_context(|| {
        format!(
            "LIGGGHTS run of case {} failed to start",
            case.source.display()
        )
    })?;

    let tr = Transcript::read(TRANSCRIPT, dir);
    let what = format!("LIGGGHTS run of case {}", case.source.display());
    tr.check_exit(&fin, &lig.limits, &what, &command, dir)?;
    let fail = |reason: String| tr.failure(&what, &command, dir, &reason);
    let dump_path = dir.join(if case.clumps.is_empty() {
        DUMP_FILE
    } else {
        clumps::BODY_DUMP_FILE
    });
    match std::fs::metadata(&dump_path) {
        Err(_) => {
            return Err(fail(format!(
                "no dump file {} was written",
                dump_path.display()
            )));
        }
        Ok(m) if m.len() == 0 => {
            return Err(fail(format!("dump file {} is empty", dump_path.display())));
        }
        Ok(_) => {}
    }
    check_dump(case, &dump_path).map_err(|e| fail(format!("{e:#}")))?;

    let version = tr.version(VERSION_PREFIX);
    let mut notes = vec![format!("run directory: {}", dir.display())];
    notes.extend(hardness_note(&case.materials));
    notes.extend(tr.warnings());
    Ok(Provenance {
        engine: EngineKind::Liggghts,
        version,
        command,
        input_hash: micro_input_hash(case)?,
        date: now_utc(),
        wall_time_s: fin.wall_time_s,
        threads: lig.mpi_procs.max(1),
        case_file: case.source.display().to_string(),
        notes,
    })
}

/// The provenance of a micro run made by hand in `dir` (a `granval deck` directory run
/// here or on a cluster): the deck and data file there are the case's as LIGGGHTS reads
/// them, neither log nor screen output has an `ERROR`, and the dump holds every frame of
/// every particle ([`micro`] checks the same after its own runs).
pub(crate) fn micro_finished(case: &Case, dir: &Path) -> Result<Provenance> {
    use crate::engines::viz_dump::{self, VizEngine};
    let mut viz = None;
    for (name, mut text) in micro_inputs(case)? {
        if name == DECK_FILE {
            (text, viz) =
                viz_dump::expected_deck(dir, name, &text, VizEngine::Liggghts, case.n_steps)?;
        }
        crate::engines::deck_text::check_same_input(dir, name, &text, name == DATA_FILE)?;
    }
    let tr = Transcript::read(TRANSCRIPT, dir);
    if tr.log.is_empty() && tr.stdout.is_empty() {
        bail!(
            "{}: neither {LOG_FILE} nor {STDOUT_FILE} exists or has content: LIGGGHTS did not run here (run `liggghts -in {DECK_FILE} -log {LOG_FILE}` in it first)",
            dir.display()
        );
    }
    if !tr.errors.is_empty() {
        bail!(
            "{}: ERROR in the LIGGGHTS output: {}",
            dir.display(),
            tr.errors.join(" | ")
        );
    }
    let dump_path = dir.join(DUMP_FILE);
    if !dump_path.exists() {
        bail!("{}: no dump was written", dump_path.display());
    }
    check_dump(case, &dump_path)?;
    let mut notes = vec![format!("run directory: {} (run by hand)", dir.display())];
    notes.extend(viz.map(|n| viz_dump::note(n, VizEngine::Liggghts)));
    notes.extend(hardness_note(&case.materials));
    notes.extend(tr.warnings());
    Ok(Provenance {
        engine: EngineKind::Liggghts,
        version: tr.version(VERSION_PREFIX),
        command: "run outside granval".into(),
        input_hash: micro_input_hash(case)?,
        date: now_utc(),
        wall_time_s: penetration::log_wall_time(&tr.log)
            .or_else(|| penetration::log_wall_time(&tr.stdout))
            .unwrap_or(f64::NAN),
        threads: 1,
        case_file: case.source.display().to_string(),
        notes,
    })
}

/// sha256 of what LIGGGHTS is given for a micro case (deck and data file, comments
/// left out: [`crate::engines::deck_text::fingerprint`]): the fingerprint a recorded
/// reference must match.
pub fn micro_input_hash(case: &Case) -> Result<Sha256> {
    let inputs = micro_inputs(case)?;
    let texts: Vec<&str> = inputs.iter().map(|(_, t)| t.as_str()).collect();
    Ok(crate::engines::deck_text::fingerprint(&texts))
}

/// The input files of a micro case: deck and data file, or the clump deck alone (bodies
/// cannot be read from a data file; they are inserted).
pub(crate) fn micro_inputs(case: &Case) -> Result<Vec<(&'static str, String)>> {
    if case.clumps.is_empty() {
        Ok(vec![
            (DECK_FILE, write_deck(case, DUMP_FILE, DATA_FILE)?),
            (DATA_FILE, write_data_file(case)?),
        ])
    } else {
        Ok(vec![(
            DECK_FILE,
            clumps::write_clump_deck(case, DUMP_FILE)?,
        )])
    }
}

/// The frames of a finished micro run in `dir`, one at a time.
pub fn micro_frames(case: &Case, dir: &Path) -> Result<DumpFrames> {
    DumpFrames::open(&dir.join(DUMP_FILE), case.dt)
}

/// Every frame a complete run writes, at the expected steps, with every particle.
fn check_dump(case: &Case, dump_path: &Path) -> Result<()> {
    let expected = expected_frames(case);
    if !case.clumps.is_empty() {
        let dir = dump_path.parent().unwrap_or(Path::new("."));
        let frames = clumps::clump_frames(case, dir)?;
        for (n, fr) in frames.iter().enumerate() {
            let step = n as u64 * case.output_every;
            if fr.step != step {
                bail!(
                    "frame {n} of {} is LIGGGHTS step {}, expected step {} (native step {step})",
                    dump_path.display(),
                    fr.step + 1,
                    step + 1
                );
            }
        }
        if frames.len() != expected {
            bail!(
                "{} has {} frames, expected {expected} (n_steps {} / output_every {} + 1)",
                dump_path.display(),
                frames.len(),
                case.n_steps,
                case.output_every
            );
        }
        return Ok(());
    }
    let mut n = 0usize;
    for fr in DumpFrames::open(dump_path, case.dt)? {
        let fr = fr?;
        let step = n as u64 * case.output_every;
        if fr.step != step {
            bail!(
                "frame {n} of {} is step {}, expected step {step}",
                dump_path.display(),
                fr.step
            );
        }
        if fr.particles.len() != case.particles.len() {
            bail!(
                "step {} of {} has {} particles, the case has {}",
                fr.step,
                dump_path.display(),
                fr.particles.len(),
                case.particles.len()
            );
        }
        n += 1;
    }
    if n != expected {
        let which = if n < expected { "fewer" } else { "more" };
        bail!(
            "{} has {n} frames, {which} than the expected {expected} (n_steps {} / output_every {} + 1)",
            dump_path.display(),
            case.n_steps,
            case.output_every
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::banner_major_version;

    #[test]
    fn major_version_of_a_banner() {
        let b = "LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, compiled 2022-01-26-19:42:32 by buildd, git commit unknown)";
        assert_eq!(banner_major_version(b), Some(3));
        assert_eq!(
            banner_major_version("LIGGGHTS (Version LIGGGHTS-PUBLIC 4.1.0)"),
            Some(4)
        );
        assert_eq!(banner_major_version("LIGGGHTS (Version unknown)"), None);
    }
}
