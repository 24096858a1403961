//! LAMMPS adapter for the 2D disk cases (K): writes `in.impact2d` + `data.impact2d`
//! from a native [`System`], runs `lmp` (optionally under `mpirun`) in the run
//! directory with a timeout, and hands back where its outputs are. A crashed, killed or
//! silent LAMMPS is an error carrying its transcript, never an empty result.
//!
//! Files in the run directory: `in.impact2d`, `data.impact2d`, `log.lammps`,
//! `lammps.stdout`, `lammps.stderr`, `intruder.txt` (fix ave/time), `snap.dump`.

pub mod deck;
pub mod impact;
pub mod parse;

use crate::engines::process::{self, Transcript, TranscriptFiles};
use crate::engines::viz_dump::{self, VizEngine};
use crate::physics::dem2d::System;
use crate::rundata::provenance::Sha256;
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

pub(crate) use deck::INTRUDER_FILE;
pub use deck::{DATA_FILE, DECK_FILE, Outputs, SNAP_FILE};

pub const LOG_FILE: &str = "log.lammps";
pub(crate) const STDOUT_FILE: &str = "lammps.stdout";
pub(crate) const STDERR_FILE: &str = "lammps.stderr";
/// The process' own stdout: with `-screen FILE` it only carries MPI noise.
pub(crate) const PROCESS_STDOUT_FILE: &str = "lammps.process.stdout";
pub(crate) const TRANSCRIPT: TranscriptFiles = TranscriptFiles {
    engine: "LAMMPS",
    log: LOG_FILE,
    stdout: &[STDOUT_FILE, PROCESS_STDOUT_FILE],
    stderr: STDERR_FILE,
};
/// LAMMPS' banner starts with this (e.g. `LAMMPS (29 Sep 2021 - Update 2)`).
const VERSION_PREFIX: &str = "LAMMPS (";

#[derive(Debug, Clone)]
pub struct Lammps {
    pub binary: String,
    /// 1: plain `lmp`; N > 1: `mpirun --allow-run-as-root -np N lmp`.
    pub mpi_procs: usize,
    /// How long the run may take and stay silent (the run is an error past either).
    pub limits: process::Limits,
}

/// The LAMMPS executable: `GRANVAL_LMP` if set (a different build, or a missing one to
/// exercise the recorded fallback), else `lmp`.
pub fn binary() -> String {
    std::env::var("GRANVAL_LMP").unwrap_or_else(|_| "lmp".into())
}

impl Default for Lammps {
    fn default() -> Self {
        Lammps {
            binary: binary(),
            mpi_procs: 1,
            limits: process::Limits::derived(0.0, None, None),
        }
    }
}

/// A finished, successful LAMMPS run.
#[derive(Debug, Clone)]
pub struct Finished {
    pub dir: PathBuf,
    pub version: String,
    pub command: String,
    /// sha256 of deck + data.
    pub input_hash: Sha256,
    pub wall_time_s: f64,
    /// For the provenance: LAMMPS' warnings, and a visualisation dump the deck declared.
    pub notes: Vec<String>,
}

/// The version probe of `binary` ([`process::probe`]): its banner when it runs and
/// prints one, broken when it hangs, fails or prints none, absent when there is no such
/// executable.
pub fn probe(binary: &str) -> process::Probe {
    process::probe(binary, VERSION_PREFIX, |_| Ok(()))
}

/// The banner of `binary` when it works, `None` otherwise (missing or broken alike;
/// [`probe`] tells them apart).
pub fn installed_version(binary: &str) -> Option<String> {
    match probe(binary) {
        process::Probe::Found(banner) => Some(banner),
        _ => None,
    }
}

/// Writes the deck and data file for `sys` into `dir` (what `granval deck` leaves and
/// what [`Lammps::run`] runs); returns their texts.
/// `viz`: also a visualisation dump every that many steps (`granval deck --viz N`,
/// [`crate::engines::viz_dump`]).
pub fn write_inputs(sys: &System, out: &Outputs, dir: &Path, viz: Option<u64>) -> Result<()> {
    inputs(sys, out, dir, viz).map(|_| ())
}

fn inputs(sys: &System, out: &Outputs, dir: &Path, viz: Option<u64>) -> Result<(String, String)> {
    let mut deck = deck::write_deck(sys, out)?;
    if let Some(n) = viz {
        deck = viz_dump::add(&deck, VizEngine::Lammps2d, n, out.n_steps)?;
    }
    let data = deck::write_data(sys);
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create run directory {}", dir.display()))?;
    for (name, text) in [(DECK_FILE, &deck), (DATA_FILE, &data)] {
        let p = dir.join(name);
        std::fs::write(&p, text).with_context(|| format!("cannot write {}", p.display()))?;
    }
    Ok((deck, data))
}

impl Lammps {
    pub fn argv(&self) -> Vec<String> {
        let mut argv = process::mpi_prefix(self.mpi_procs);
        argv.push(self.binary.clone());
        argv.extend(
            [
                "-in",
                DECK_FILE,
                "-log",
                LOG_FILE,
                "-echo",
                "none",
                "-screen",
                STDOUT_FILE,
            ]
            .map(String::from),
        );
        argv
    }

    /// Writes the deck and data for `sys`, runs LAMMPS in `dir` and checks that it
    /// finished cleanly and wrote the outputs `out` asks for.
    pub fn run(&self, sys: &System, out: &Outputs, dir: &Path) -> Result<Finished> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create run directory {}", dir.display()))?;
        process::remove_stale(
            dir,
            &[
                LOG_FILE,
                STDOUT_FILE,
                PROCESS_STDOUT_FILE,
                STDERR_FILE,
                INTRUDER_FILE,
                SNAP_FILE,
                deck::GRAINS_FILE,
                deck::CONTACTS_FILE,
            ],
        )?;
        let (deck, data) = inputs(sys, out, dir, None)?;
        let argv = self.argv();
        let command = process::command_line(&argv);
        let fin = process::run(
            &argv,
            dir,
            &dir.join(PROCESS_STDOUT_FILE),
            &dir.join(STDERR_FILE),
            &self.limits,
        )
        .with_context(|| format!("LAMMPS failed to start in {}", dir.display()))?;
        let what = "LAMMPS run";
        let tr = Transcript::read(TRANSCRIPT, dir);
        tr.check_exit(&fin, &self.limits, what, &command, dir)?;
        let fail = |reason: String| tr.failure(what, &command, dir, &reason);
        let log = &tr.log;
        if !log.contains("Total wall time") {
            return Err(fail("the log does not end with `Total wall time`: LAMMPS stopped early or wrote nothing".into()));
        }
        if let Some(why) = missing_output(sys, out, dir) {
            return Err(fail(why));
        }
        let version = tr.version(VERSION_PREFIX);
        Ok(Finished {
            dir: dir.to_path_buf(),
            version,
            command,
            input_hash: crate::engines::deck_text::fingerprint(&[&deck, &data]),
            wall_time_s: fin.wall_time_s,
            notes: tr.warnings(),
        })
    }
}

/// Which output `out` asks for is missing or empty in `dir`, if any.
fn missing_output(sys: &System, out: &Outputs, dir: &Path) -> Option<String> {
    let mut wanted = Vec::new();
    if out.intruder_every > 0 && !sys.intruder.is_empty() {
        wanted.push(INTRUDER_FILE);
    }
    if out.snapshot_every > 0 {
        wanted.push(SNAP_FILE);
    }
    if !out.fields.position_steps.is_empty() {
        wanted.push(deck::GRAINS_FILE);
    }
    if !out.fields.contact_steps.is_empty() {
        wanted.push(deck::CONTACTS_FILE);
    }
    wanted
        .into_iter()
        .find_map(|f| match std::fs::metadata(dir.join(f)) {
            Ok(m) if m.len() > 0 => None,
            _ => Some(format!("{} is missing or empty", dir.join(f).display())),
        })
}

/// A run made by hand in `dir` (a `granval deck` directory run here or on a cluster),
/// checked as [`Lammps::run`] checks its own: the deck and data file there are the
/// ones granval writes for `sys` (as LAMMPS reads them), no `ERROR` in the output, the
/// log ends with `Total wall time`, every output `out` asks for is there.
pub(crate) fn finished(sys: &System, out: &Outputs, dir: &Path) -> Result<Finished> {
    use crate::engines::deck_text::check_same_input;
    let (deck, data) = (deck::write_deck(sys, out)?, deck::write_data(sys));
    // The fingerprint stays the deck's without a visualisation dump: the dump changes
    // what is written, not what is computed.
    let (with_viz, viz) =
        viz_dump::expected_deck(dir, DECK_FILE, &deck, VizEngine::Lammps2d, out.n_steps)?;
    check_same_input(dir, DECK_FILE, &with_viz, false)?;
    check_same_input(dir, DATA_FILE, &data, true)?;
    let tr = Transcript::read(TRANSCRIPT, dir);
    if tr.log.is_empty() {
        anyhow::bail!(
            "{}: no {LOG_FILE}: LAMMPS did not run here (run `lmp -in {DECK_FILE} -log {LOG_FILE}` in it first)",
            dir.display()
        );
    }
    let command = "run outside granval";
    let fail = |reason: String| tr.failure("LAMMPS run", command, dir, &reason);
    if !tr.errors.is_empty() {
        return Err(fail("ERROR in the LAMMPS output".into()));
    }
    // LAMMPS writes "Total wall time" to the log as its last line.
    let Some(wall) = tr
        .log
        .lines()
        .rev()
        .find_map(|l| l.strip_prefix("Total wall time:"))
    else {
        return Err(fail(format!(
            "{LOG_FILE} does not end with `Total wall time`: LAMMPS stopped early (or is still running)"
        )));
    };
    if let Some(why) = missing_output(sys, out, dir) {
        return Err(fail(why));
    }
    let wall_time_s = wall
        .trim()
        .split(':')
        .map(|x| x.parse::<f64>().ok())
        .collect::<Option<Vec<_>>>()
        .map(|p| p.iter().fold(0.0, |acc, v| acc * 60.0 + v))
        .unwrap_or(f64::NAN);
    Ok(Finished {
        dir: dir.to_path_buf(),
        version: tr.version(VERSION_PREFIX),
        command: command.into(),
        input_hash: crate::engines::deck_text::fingerprint(&[&deck, &data]),
        wall_time_s,
        notes: tr
            .warnings()
            .into_iter()
            .chain(viz.map(|n| viz_dump::note(n, VizEngine::Lammps2d)))
            .collect(),
    })
}
