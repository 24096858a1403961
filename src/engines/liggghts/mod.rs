//! LIGGGHTS 3.8 adapter: writes a deck and a `read_data` file for a validated [`Case`],
//! runs `liggghts` (optionally under `mpirun`) in the run directory, parses the dump into
//! the common [`RunOutput`].
//!
//! Files in the run directory: `in.granval` (deck), `data.granval` (particles and box),
//! `dump.granval` (trajectory), `log.liggghts`, `liggghts.stdout`, `liggghts.stderr`.
//! A run directory is therefore self-describing and can be re-run by hand with the
//! command recorded in the provenance.

mod deck;
mod dump;
pub mod penetration;
pub(crate) mod runner;
pub mod snapshot;
pub mod stl;

pub use deck::{
    DUMP_COLUMNS, MIN_RESTITUTION_EXCLUSIVE, MIN_YOUNGS_MODULUS_SI, check_liggghts_limits,
    expected_frames, write_data_file, write_deck,
};
pub use dump::parse_dump;

use crate::case::Case;
use crate::engines::Engine;
use crate::engines::output::{Provenance, RunOutput, now_utc, sha256_hex};
use anyhow::{Context, Result};
use std::path::Path;
use std::time::Duration;

pub const DECK_FILE: &str = "in.granval";
pub const DATA_FILE: &str = "data.granval";
pub const DUMP_FILE: &str = "dump.granval";
pub const LOG_FILE: &str = "log.liggghts";
pub const STDOUT_FILE: &str = "liggghts.stdout";
pub const STDERR_FILE: &str = "liggghts.stderr";

/// Prefix of the banner line LIGGGHTS prints first (screen and log).
const VERSION_PREFIX: &str = "LIGGGHTS (Version";

/// How LIGGGHTS is invoked.
#[derive(Debug, Clone)]
pub struct Liggghts {
    /// Executable name or path, `liggghts` by default.
    pub binary: String,
    /// 1: plain `liggghts -in`; N > 1: `mpirun --allow-run-as-root -np N liggghts -in`.
    pub mpi_procs: usize,
    /// The process is killed (and the run is an error) after this long.
    pub timeout: Duration,
}

impl Default for Liggghts {
    fn default() -> Self {
        Liggghts {
            binary: "liggghts".to_string(),
            mpi_procs: 1,
            timeout: Duration::from_secs(30 * 60),
        }
    }
}

impl Liggghts {
    /// The exact argument vector, run inside the run directory.
    pub fn argv(&self) -> Vec<String> {
        let mut argv: Vec<String> = Vec::new();
        if self.mpi_procs > 1 {
            argv.extend(["mpirun", "--allow-run-as-root", "-np"].map(String::from));
            argv.push(self.mpi_procs.to_string());
        }
        argv.push(self.binary.clone());
        argv.extend(["-in", DECK_FILE, "-log", LOG_FILE].map(String::from));
        argv
    }
}

/// The version banner (e.g. `LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, compiled ...)`) if
/// `binary` is installed and runs; `None` otherwise. Runs an empty deck with no log file
/// in a scratch directory (well under a second).
pub fn installed_version(binary: &str) -> Option<String> {
    let dir = tempfile::tempdir().ok()?;
    let argv: Vec<String> = [binary, "-in", "/dev/null", "-log", "none", "-echo", "none"]
        .map(String::from)
        .to_vec();
    let (out, err) = (dir.path().join("stdout"), dir.path().join("stderr"));
    let fin = runner::run(&argv, dir.path(), &out, &err, Duration::from_secs(60)).ok()?;
    match fin.outcome {
        runner::Outcome::Exited(s) if s.success() => {}
        _ => return None,
    }
    version_line(&read_lossy(&out))
}

fn version_line(text: &str) -> Option<String> {
    text.lines()
        .map(str::trim)
        .find(|l| l.starts_with(VERSION_PREFIX))
        .map(str::to_string)
}

fn read_lossy(path: &Path) -> String {
    std::fs::read(path)
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .unwrap_or_default()
}

/// Distinct lines starting with `ERROR` (MPI ranks may each print the same one).
fn error_lines(texts: &[&str]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for t in texts {
        for l in t.lines() {
            let l = l.trim();
            if l.starts_with("ERROR") && !out.iter().any(|o| o == l) {
                out.push(l.to_string());
            }
        }
    }
    out
}

/// Distinct LIGGGHTS warnings; a bare `WARNING:` line takes its text from the next line.
fn warnings(text: &str) -> Vec<String> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out: Vec<String> = Vec::new();
    for (k, l) in lines.iter().enumerate() {
        if let Some(rest) = l.trim().strip_prefix("WARNING:") {
            let msg = if rest.trim().is_empty() {
                lines.get(k + 1).map(|s| s.trim()).unwrap_or("")
            } else {
                rest.trim()
            };
            let msg = format!("LIGGGHTS warning: {msg}");
            if !out.contains(&msg) {
                out.push(msg);
            }
        }
    }
    out
}

fn tail(text: &str, n: usize) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let start = lines.len().saturating_sub(n);
    lines[start..]
        .iter()
        .map(|l| format!("  | {l}\n"))
        .collect()
}

impl Engine for Liggghts {
    fn name(&self) -> &'static str {
        "liggghts"
    }

    fn run(&self, case: &Case, dir: &Path) -> Result<RunOutput> {
        let deck = write_deck(case, DUMP_FILE, DATA_FILE)?;
        let data = write_data_file(case)?;
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create run directory {}", dir.display()))?;
        // A stale dump or log from an earlier run must never be mistaken for this one.
        for f in [DUMP_FILE, LOG_FILE, STDOUT_FILE, STDERR_FILE] {
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
        let fin = runner::run(
            &argv,
            dir,
            &dir.join(STDOUT_FILE),
            &dir.join(STDERR_FILE),
            self.timeout,
        )
        .with_context(|| {
            format!(
                "LIGGGHTS run of case {} failed to start",
                case.source.display()
            )
        })?;

        let tr = Transcript::read(dir);
        let (log, stdout, errors) = (&tr.log, &tr.stdout, &tr.errors);
        let what = format!("LIGGGHTS run of case {}", case.source.display());
        let fail = |reason: String| tr.failure(&what, &command, dir, &reason);

        match fin.outcome {
            runner::Outcome::TimedOut => {
                return Err(fail(format!(
                    "timed out after {:.1} s; the process was killed",
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
                "ERROR in the LIGGGHTS output although the exit status was 0".to_string(),
            ));
        }
        let dump_path = dir.join(DUMP_FILE);
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
        let frames = parse_dump(&dump_path, case.dt).map_err(|e| fail(format!("{e:#}")))?;

        let expected = expected_frames(case);
        if frames.len() != expected {
            let which = if frames.len() < expected {
                "fewer"
            } else {
                "more"
            };
            return Err(fail(format!(
                "{} has {} frames, {which} than the expected {expected} (n_steps {} / output_every {} + 1)",
                dump_path.display(),
                frames.len(),
                case.n_steps,
                case.output_every
            )));
        }
        for (k, fr) in frames.iter().enumerate() {
            let step = k as u64 * case.output_every;
            if fr.step != step {
                return Err(fail(format!(
                    "frame {k} of {} is step {}, expected step {step}",
                    dump_path.display(),
                    fr.step
                )));
            }
            if fr.particles.len() != case.particles.len() {
                return Err(fail(format!(
                    "step {} of {} has {} particles, the case has {}",
                    fr.step,
                    dump_path.display(),
                    fr.particles.len(),
                    case.particles.len()
                )));
            }
        }

        let version = log
            .lines()
            .next()
            .map(str::trim)
            .filter(|l| l.starts_with(VERSION_PREFIX))
            .map(str::to_string)
            .or_else(|| version_line(stdout))
            .unwrap_or_else(|| "LIGGGHTS (version line not found in log)".to_string());
        let mut notes = vec![format!("run directory: {}", dir.display())];
        notes.extend(warnings(log));
        Ok(RunOutput {
            frames,
            provenance: Provenance {
                engine: "liggghts".to_string(),
                version,
                command,
                input_hash: sha256_hex(format!("{deck}{data}").as_bytes()),
                date: now_utc(),
                wall_time_s: fin.wall_time_s,
                threads: self.mpi_procs.max(1),
                case_file: case.source.display().to_string(),
                notes,
            },
        })
    }
}

/// What a finished LIGGGHTS process left behind, read once; every adapter turns a
/// failed run into the same error text from it.
pub(crate) struct Transcript {
    pub log: String,
    pub stdout: String,
    pub stderr: String,
    /// `ERROR` lines from all three.
    pub errors: Vec<String>,
}

impl Transcript {
    pub(crate) fn read(dir: &Path) -> Transcript {
        let log = read_lossy(&dir.join(LOG_FILE));
        let stdout = read_lossy(&dir.join(STDOUT_FILE));
        let stderr = read_lossy(&dir.join(STDERR_FILE));
        let errors = error_lines(&[&log, &stdout, &stderr]);
        Transcript {
            log,
            stdout,
            stderr,
            errors,
        }
    }

    /// "`what` failed: `reason`", the command, LIGGGHTS' ERROR lines and the tails of
    /// its log (or stdout when the log is empty) and stderr.
    pub(crate) fn failure(
        &self,
        what: &str,
        command: &str,
        dir: &Path,
        reason: &str,
    ) -> anyhow::Error {
        let mut m = format!(
            "{what} failed: {reason}\n  command: `{command}` in {}\n",
            dir.display()
        );
        if !self.errors.is_empty() {
            m += "LIGGGHTS reported:\n";
            for e in &self.errors {
                m += &format!("  {e}\n");
            }
        }
        let (name, text) = if self.log.trim().is_empty() {
            (STDOUT_FILE, &self.stdout)
        } else {
            (LOG_FILE, &self.log)
        };
        if !text.trim().is_empty() {
            m += &format!("last lines of {name}:\n{}", tail(text, 15));
        }
        if !self.stderr.trim().is_empty() {
            m += &format!("last lines of {STDERR_FILE}:\n{}", tail(&self.stderr, 10));
        }
        anyhow::anyhow!(m.trim_end().to_string())
    }
}
