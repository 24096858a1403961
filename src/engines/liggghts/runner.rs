//! Running LIGGGHTS as a subprocess with a timeout, output going to files (no pipes, so
//! a chatty run can never block on a full pipe buffer).

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
            .context("waiting for the LIGGGHTS process")?
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
