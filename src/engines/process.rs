//! Running a reference engine (LIGGGHTS, LAMMPS) as a subprocess: a timeout, output going
//! to files (no pipes, so a chatty run can never block on a full pipe buffer), and one
//! reading of what a finished run left behind, so that a crashed, killed or silent engine
//! becomes the same kind of error whichever engine it was.

use anyhow::{Context, Result};
use std::path::Path;
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

#[derive(Debug)]
pub enum Outcome {
    Exited(ExitStatus),
    /// Killed after the timeout.
    TimedOut,
}

#[derive(Debug)]
pub struct Finished {
    pub outcome: Outcome,
    pub wall_time_s: f64,
}

/// Quotes one argument for display as a POSIX shell word (only when needed).
pub fn shell_word(s: &str) -> String {
    if !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c))
    {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

pub fn command_line(argv: &[String]) -> String {
    argv.iter()
        .map(|a| shell_word(a))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Runs `argv` in `dir` with stdin from /dev/null and stdout/stderr written to the given
/// files; kills it (SIGTERM, then SIGKILL after a grace period) when `timeout` passes.
pub fn run(
    argv: &[String],
    dir: &Path,
    stdout: &Path,
    stderr: &Path,
    timeout: Duration,
) -> Result<Finished> {
    run_with(argv, dir, stdout, stderr, timeout, || {})
}

/// [`run`], calling `tick` about twice a second while the process lives (progress bars
/// that follow the log).
pub fn run_with(
    argv: &[String],
    dir: &Path,
    stdout: &Path,
    stderr: &Path,
    timeout: Duration,
    mut tick: impl FnMut(),
) -> Result<Finished> {
    let (prog, args) = argv.split_first().context("empty command line")?;
    let out = std::fs::File::create(stdout)
        .with_context(|| format!("cannot create {}", stdout.display()))?;
    let err = std::fs::File::create(stderr)
        .with_context(|| format!("cannot create {}", stderr.display()))?;
    let start = Instant::now();
    let mut child = Command::new(prog)
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::from(out))
        .stderr(Stdio::from(err))
        .spawn()
        .with_context(|| {
            format!(
                "cannot start `{}` in {} (is it installed and on PATH?)",
                command_line(argv),
                dir.display()
            )
        })?;

    let mut pause = Duration::from_millis(5);
    let mut last_tick = Instant::now();
    loop {
        if last_tick.elapsed() >= Duration::from_millis(500) {
            tick();
            last_tick = Instant::now();
        }
        if let Some(status) = child
            .try_wait()
            .with_context(|| format!("waiting for `{}`", command_line(argv)))?
        {
            return Ok(Finished {
                outcome: Outcome::Exited(status),
                wall_time_s: start.elapsed().as_secs_f64(),
            });
        }
        if start.elapsed() >= timeout {
            terminate(&mut child);
            return Ok(Finished {
                outcome: Outcome::TimedOut,
                wall_time_s: start.elapsed().as_secs_f64(),
            });
        }
        std::thread::sleep(
            pause
                .min(timeout.saturating_sub(start.elapsed()))
                .max(Duration::from_millis(1)),
        );
        pause = (pause * 2).min(Duration::from_millis(100));
    }
}

/// Ends the child we started, by its pid only: SIGTERM first (mpirun forwards it to its
/// ranks and cleans up), SIGKILL if it is still alive after a grace period.
fn terminate(child: &mut std::process::Child) {
    #[cfg(unix)]
    {
        let _ = Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status();
        let grace = Instant::now();
        while grace.elapsed() < Duration::from_secs(5) {
            if let Ok(Some(_)) = child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    let _ = child.kill();
    let _ = child.wait();
}

/// `mpirun --allow-run-as-root -np N` for N > 1, nothing for one process: the prefix
/// both engines' command lines start with.
pub fn mpi_prefix(mpi_procs: usize) -> Vec<String> {
    if mpi_procs > 1 {
        let mut argv: Vec<String> = ["mpirun", "--allow-run-as-root", "-np"]
            .map(String::from)
            .to_vec();
        argv.push(mpi_procs.to_string());
        argv
    } else {
        Vec::new()
    }
}

/// Deletes outputs of an earlier run in `dir`, so they are never mistaken for this one's.
pub fn remove_stale(dir: &Path, names: &[&str]) -> Result<()> {
    for name in names {
        let p = dir.join(name);
        if p.exists() {
            std::fs::remove_file(&p)
                .with_context(|| format!("cannot remove stale {}", p.display()))?;
        }
    }
    Ok(())
}

/// A file's text, invalid UTF-8 replaced, empty when it is missing (or not a regular
/// file within the bound of an engine's output).
fn read_lossy(path: &Path) -> String {
    use crate::rundata::fsio;
    fsio::read(path, fsio::max_engine_output(), "an engine's output")
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .unwrap_or_default()
}

/// The first line of `text` that starts with `prefix` (an engine's version banner).
fn banner_line(text: &str, prefix: &str) -> Option<String> {
    text.lines()
        .map(str::trim)
        .find(|l| l.starts_with(prefix))
        .map(str::to_string)
}

/// The version banner (the stdout line starting with `prefix`) of `binary` run on an
/// empty deck without a log in a scratch directory; `None` when it is missing or fails.
pub fn installed_banner(binary: &str, prefix: &str) -> Option<String> {
    let dir = tempfile::tempdir().ok()?;
    let argv: Vec<String> = [binary, "-in", "/dev/null", "-log", "none", "-echo", "none"]
        .map(String::from)
        .to_vec();
    let (out, err) = (dir.path().join("stdout"), dir.path().join("stderr"));
    let fin = run(&argv, dir.path(), &out, &err, Duration::from_secs(60)).ok()?;
    match fin.outcome {
        Outcome::Exited(s) if s.success() => banner_line(&read_lossy(&out), prefix),
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

/// Distinct lines starting with `ERROR` (MPI ranks may each print the same one).
fn error_lines(texts: &[&str]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for l in texts.iter().flat_map(|t| t.lines()).map(str::trim) {
        if l.starts_with("ERROR") && !out.iter().any(|o| o == l) {
            out.push(l.to_string());
        }
    }
    out
}

/// Where an engine writes its log, screen output and stderr inside a run directory.
#[derive(Debug, Clone, Copy)]
pub struct TranscriptFiles {
    /// "LIGGGHTS" or "LAMMPS", for the error text.
    pub engine: &'static str,
    pub log: &'static str,
    /// Screen output; more than one file when the engine's screen and the process'
    /// stdout are separate (LAMMPS' `-screen FILE`), concatenated in this order.
    pub stdout: &'static [&'static str],
    pub stderr: &'static str,
}

/// What a finished engine process left behind, read once; every adapter turns a failed
/// run into the same error text from it.
pub struct Transcript {
    files: TranscriptFiles,
    pub log: String,
    pub stdout: String,
    pub stderr: String,
    /// `ERROR` lines from all three.
    pub errors: Vec<String>,
}

impl Transcript {
    pub fn read(files: TranscriptFiles, dir: &Path) -> Transcript {
        let log = read_lossy(&dir.join(files.log));
        let stdout: String = files
            .stdout
            .iter()
            .map(|f| read_lossy(&dir.join(f)))
            .collect();
        let stderr = read_lossy(&dir.join(files.stderr));
        let errors = error_lines(&[&log, &stdout, &stderr]);
        Transcript {
            files,
            log,
            stdout,
            stderr,
            errors,
        }
    }

    /// The banner line starting with `prefix`, from the log or else the screen output.
    pub fn version(&self, prefix: &str) -> String {
        banner_line(&self.log, prefix)
            .or_else(|| banner_line(&self.stdout, prefix))
            .unwrap_or_else(|| format!("{} (version line not found in log)", self.files.engine))
    }

    /// Distinct warnings from the log, each prefixed "ENGINE warning: "; a bare
    /// `WARNING:` line (LIGGGHTS prints some so) takes its text from the next line.
    pub fn warnings(&self) -> Vec<String> {
        let lines: Vec<&str> = self.log.lines().collect();
        let mut out: Vec<String> = Vec::new();
        for (k, l) in lines.iter().enumerate() {
            if let Some(rest) = l.trim().strip_prefix("WARNING:") {
                let msg = if rest.trim().is_empty() {
                    lines.get(k + 1).map(|s| s.trim()).unwrap_or("")
                } else {
                    rest.trim()
                };
                let msg = format!("{} warning: {msg}", self.files.engine);
                if !out.contains(&msg) {
                    out.push(msg);
                }
            }
        }
        out
    }

    /// "`what` failed: `reason`", the command, the engine's ERROR lines and the tails of
    /// its log (or screen output when the log is empty) and stderr.
    pub fn failure(&self, what: &str, command: &str, dir: &Path, reason: &str) -> anyhow::Error {
        let mut m = format!(
            "{what} failed: {reason}\n  command: `{command}` in {}\n",
            dir.display()
        );
        if !self.errors.is_empty() {
            m += &format!("{} reported:\n", self.files.engine);
            for e in &self.errors {
                m += &format!("  {e}\n");
            }
        }
        let (name, text) = if self.log.trim().is_empty() {
            (self.files.stdout[0], &self.stdout)
        } else {
            (self.files.log, &self.log)
        };
        if !text.trim().is_empty() {
            m += &format!("last lines of {name}:\n{}", tail(text, 15));
        }
        if !self.stderr.trim().is_empty() {
            m += &format!(
                "last lines of {}:\n{}",
                self.files.stderr,
                tail(&self.stderr, 10)
            );
        }
        anyhow::anyhow!(m.trim_end().to_string())
    }

    /// Turns a timeout, a non-zero exit or an `ERROR` line after exit status 0 into
    /// [`Transcript::failure`]; `Ok` only for a clean exit.
    pub fn check_exit(
        &self,
        fin: &Finished,
        timeout: Duration,
        what: &str,
        command: &str,
        dir: &Path,
    ) -> Result<()> {
        let reason = match fin.outcome {
            Outcome::TimedOut => format!(
                "timed out after {:.1} s; the process was killed",
                timeout.as_secs_f64()
            ),
            Outcome::Exited(s) if !s.success() => format!("exited with {s}"),
            Outcome::Exited(_) if !self.errors.is_empty() => format!(
                "ERROR in the {} output although the exit status was 0",
                self.files.engine
            ),
            Outcome::Exited(_) => return Ok(()),
        };
        Err(self.failure(what, command, dir, &reason))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::process::ExitStatusExt;

    const FILES: TranscriptFiles = TranscriptFiles {
        engine: "ENGINE",
        log: "log",
        stdout: &["screen", "process"],
        stderr: "err",
    };

    fn transcript(
        log: &str,
        screen: &str,
        process: &str,
        err: &str,
    ) -> (tempfile::TempDir, Transcript) {
        let dir = tempfile::tempdir().unwrap();
        for (name, text) in [
            ("log", log),
            ("screen", screen),
            ("process", process),
            ("err", err),
        ] {
            std::fs::write(dir.path().join(name), text).unwrap();
        }
        let tr = Transcript::read(FILES, dir.path());
        (dir, tr)
    }

    fn exited(code: i32) -> Finished {
        Finished {
            outcome: Outcome::Exited(ExitStatus::from_raw(code << 8)),
            wall_time_s: 1.0,
        }
    }

    #[test]
    fn clean_exit_passes_and_every_failure_is_an_error() {
        let t = Duration::from_secs(7);
        let (dir, ok) = transcript(
            "ENGINE (v1)\nWARNING: a\nWARNING:\n  b\nWARNING: a\n",
            "",
            "",
            "",
        );
        ok.check_exit(&exited(0), t, "run", "cmd", dir.path())
            .unwrap();
        assert_eq!(ok.version("ENGINE ("), "ENGINE (v1)");
        assert_eq!(ok.warnings(), ["ENGINE warning: a", "ENGINE warning: b"]);

        let e = ok
            .check_exit(&exited(3), t, "run", "cmd", dir.path())
            .unwrap_err();
        let e = format!("{e:#}");
        assert!(
            e.starts_with("run failed: exited with") && e.contains("`cmd`"),
            "{e}"
        );
        assert!(e.contains("last lines of log:\n  | ENGINE (v1)"), "{e}");

        let timed_out = Finished {
            outcome: Outcome::TimedOut,
            wall_time_s: 7.0,
        };
        let e = format!(
            "{:#}",
            ok.check_exit(&timed_out, t, "run", "cmd", dir.path())
                .unwrap_err()
        );
        assert!(e.contains("timed out after 7.0 s"), "{e}");

        // ERROR on any stream fails a run that exited 0; the same line from two MPI
        // ranks is reported once; an empty log falls back to the screen files, in order.
        let (dir, bad) = transcript("", "x\nERROR: boom\n", "ERROR: boom\n", "mpi says\n");
        assert_eq!(bad.errors, ["ERROR: boom"]);
        assert_eq!(
            bad.version("ENGINE ("),
            "ENGINE (version line not found in log)"
        );
        let e = format!(
            "{:#}",
            bad.check_exit(&exited(0), t, "run", "cmd", dir.path())
                .unwrap_err()
        );
        assert!(
            e.contains("ERROR in the ENGINE output although the exit status was 0"),
            "{e}"
        );
        assert!(e.contains("ENGINE reported:\n  ERROR: boom"), "{e}");
        assert!(
            e.contains("last lines of screen:\n  | x\n  | ERROR: boom\n  | ERROR: boom"),
            "{e}"
        );
        assert!(e.contains("last lines of err:\n  | mpi says"), "{e}");
    }

    #[test]
    fn mpi_prefix_only_for_several_processes() {
        assert!(mpi_prefix(1).is_empty());
        assert_eq!(mpi_prefix(2), ["mpirun", "--allow-run-as-root", "-np", "2"]);
        assert_eq!(
            command_line(&["a b".into(), "it's".into()]),
            "'a b' 'it'\\''s'"
        );
    }
}
