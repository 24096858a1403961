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

use crate::dem2d::System;
use crate::engines::liggghts::runner;
use crate::engines::output::sha256_hex;
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use std::time::Duration;

pub use deck::{DATA_FILE, DECK_FILE, INTRUDER_FILE, Outputs, SNAP_FILE};

pub const LOG_FILE: &str = "log.lammps";
pub const STDOUT_FILE: &str = "lammps.stdout";
pub const STDERR_FILE: &str = "lammps.stderr";
/// LAMMPS' banner starts with this (e.g. `LAMMPS (29 Sep 2021 - Update 2)`).
const VERSION_PREFIX: &str = "LAMMPS (";

#[derive(Debug, Clone)]
pub struct Lammps {
    pub binary: String,
    /// 1: plain `lmp`; N > 1: `mpirun --allow-run-as-root -np N lmp`.
    pub mpi_procs: usize,
    pub timeout: Duration,
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
            timeout: Duration::from_secs(3600),
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
    pub input_hash: String,
    pub wall_time_s: f64,
    pub warnings: Vec<String>,
}

fn read_lossy(path: &Path) -> String {
    std::fs::read(path)
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .unwrap_or_default()
}

fn version_line(text: &str) -> Option<String> {
    text.lines()
        .map(str::trim)
        .find(|l| l.starts_with(VERSION_PREFIX))
        .map(str::to_string)
}

/// The banner of an installed `binary`, or `None` if it is missing or does not run.
pub fn installed_version(binary: &str) -> Option<String> {
    let dir = tempfile::tempdir().ok()?;
    let argv: Vec<String> = [binary, "-in", "/dev/null", "-log", "none", "-echo", "none"]
        .map(String::from)
        .to_vec();
    let (out, err) = (dir.path().join("stdout"), dir.path().join("stderr"));
    let fin = runner::run(&argv, dir.path(), &out, &err, Duration::from_secs(60)).ok()?;
    match fin.outcome {
        runner::Outcome::Exited(s) if s.success() => version_line(&read_lossy(&out)),
        _ => None,
    }
}

fn tail(text: &str, n: usize) -> String {
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(n)..]
        .iter()
        .map(|l| format!("  | {l}\n"))
        .collect()
}

/// Distinct `ERROR` lines and warnings from LAMMPS' outputs.
fn scan(texts: &[&str]) -> (Vec<String>, Vec<String>) {
    let (mut errors, mut warnings) = (Vec::<String>::new(), Vec::<String>::new());
    for t in texts {
        for l in t.lines().map(str::trim) {
            if l.starts_with("ERROR") && !errors.iter().any(|e| e == l) {
                errors.push(l.to_string());
            }
            if l.starts_with("WARNING") && !warnings.iter().any(|e| e == l) {
                warnings.push(l.to_string());
            }
        }
    }
    (errors, warnings)
}

impl Lammps {
    pub fn argv(&self) -> Vec<String> {
        let mut argv: Vec<String> = Vec::new();
        if self.mpi_procs > 1 {
            argv.extend(["mpirun", "--allow-run-as-root", "-np"].map(String::from));
            argv.push(self.mpi_procs.to_string());
        }
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
        let deck = deck::write_deck(sys, out)?;
        let data = deck::write_data(sys);
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create run directory {}", dir.display()))?;
        for f in [LOG_FILE, STDOUT_FILE, STDERR_FILE, INTRUDER_FILE, SNAP_FILE] {
            let p = dir.join(f);
            if p.exists() {
                std::fs::remove_file(&p)
                    .with_context(|| format!("cannot remove stale {}", p.display()))?;
            }
        }
        for (name, text) in [(DECK_FILE, &deck), (DATA_FILE, &data)] {
            let p = dir.join(name);
            std::fs::write(&p, text).with_context(|| format!("cannot write {}", p.display()))?;
        }
        let argv = self.argv();
        let command = runner::command_line(&argv);
        // `-screen FILE` sends the screen output to a file; the process' own stdout
        // then only carries MPI noise.
        let fin = runner::run(
            &argv,
            dir,
            &dir.join("lammps.process.stdout"),
            &dir.join(STDERR_FILE),
            self.timeout,
        )
        .with_context(|| format!("LAMMPS failed to start in {}", dir.display()))?;
        let log = read_lossy(&dir.join(LOG_FILE));
        let stdout =
            read_lossy(&dir.join(STDOUT_FILE)) + &read_lossy(&dir.join("lammps.process.stdout"));
        let stderr = read_lossy(&dir.join(STDERR_FILE));
        let (errors, warnings) = scan(&[&log, &stdout, &stderr]);
        let fail = |reason: String| -> anyhow::Error {
            let mut m = format!(
                "LAMMPS run failed: {reason}\n  command: `{command}` in {}\n",
                dir.display()
            );
            if !errors.is_empty() {
                m += "LAMMPS reported:\n";
                for e in &errors {
                    m += &format!("  {e}\n");
                }
            }
            let (name, text) = if log.trim().is_empty() {
                (STDOUT_FILE, &stdout)
            } else {
                (LOG_FILE, &log)
            };
            if !text.trim().is_empty() {
                m += &format!("last lines of {name}:\n{}", tail(text, 15));
            }
            if !stderr.trim().is_empty() {
                m += &format!("last lines of {STDERR_FILE}:\n{}", tail(&stderr, 10));
            }
            anyhow::anyhow!(m.trim_end().to_string())
        };
        match fin.outcome {
            runner::Outcome::TimedOut => {
                return Err(fail(format!(
                    "timed out after {:.0} s; the process was killed",
                    self.timeout.as_secs_f64()
                )));
            }
            runner::Outcome::Exited(s) if !s.success() => {
                return Err(fail(format!("exited with {s}")));
            }
            runner::Outcome::Exited(_) => {}
        }
        if !errors.is_empty() {
            return Err(fail(
                "ERROR in the LAMMPS output although the exit status was 0".into(),
            ));
        }
        if !log.contains("Total wall time") {
            return Err(fail("the log does not end with `Total wall time`: LAMMPS stopped early or wrote nothing".into()));
        }
        let mut wanted = Vec::new();
        if out.intruder_every > 0 && !sys.intruder.is_empty() {
            wanted.push(INTRUDER_FILE);
        }
        if out.snapshot_every > 0 {
            wanted.push(SNAP_FILE);
        }
        for f in wanted {
            match std::fs::metadata(dir.join(f)) {
                Ok(m) if m.len() > 0 => {}
                _ => return Err(fail(format!("{f} is missing or empty"))),
            }
        }
        let version = version_line(&log)
            .or_else(|| version_line(&stdout))
            .unwrap_or_else(|| "LAMMPS (version line not found in log)".into());
        Ok(Finished {
            dir: dir.to_path_buf(),
            version,
            command,
            input_hash: sha256_hex(format!("{deck}{data}").as_bytes()),
            wall_time_s: fin.wall_time_s,
            warnings,
        })
    }
}
