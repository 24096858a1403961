//! Running a reference engine (LIGGGHTS, LAMMPS) as a subprocess: a timeout, output going
//! to files (no pipes, so a chatty run can never block on a full pipe buffer), and one
//! reading of what a finished run left behind, so that a crashed, killed or silent engine
//! becomes the same kind of error whichever engine it was.

use super::children;
use anyhow::{Context, Result};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

#[derive(Debug)]
pub enum Outcome {
    Exited(ExitStatus),
    /// Ended after [`Limits::timeout`].
    TimedOut,
    /// Ended because no file of its run directory grew for [`Limits::stall`].
    Stalled(Stall),
}

/// What a stalled run had written last.
#[derive(Debug, Clone)]
pub struct Stall {
    /// The file (relative to the run directory) that grew last, if any grew at all.
    pub file: Option<PathBuf>,
    /// Its size when it stopped growing.
    pub size: u64,
    /// How long nothing grew.
    pub quiet: Duration,
}

#[derive(Debug)]
pub struct Finished {
    pub outcome: Outcome,
    pub wall_time_s: f64,
}

/// How long an engine run may take, and how long it may write nothing, each with where
/// the number comes from (the error names it).
#[derive(Debug, Clone)]
pub struct Limits {
    pub timeout: Duration,
    /// `--engine-timeout 2s`, or how the default was derived.
    pub timeout_origin: String,
    /// The run is ended as stalled when no file in its run directory grew for this long.
    pub stall: Duration,
    pub stall_origin: String,
}

/// Reference-engine particle-steps per second that the default `--engine-timeout`
/// assumes, counted in the *estimate of the whole comparison* (every native run, all
/// beds and negative controls, `Experiment::estimate`): that estimate divided by the
/// longest single reference run was at least 9.8e6 per second over every sealed record
/// of this repository whose run took more than 10 s (feng-fig3a-g-1: 7.12e9 estimated,
/// its longest LIGGGHTS bed 728 s on two cores), so this value leaves a margin of
/// about 20 for a slower or busier machine.
pub(crate) const TIMEOUT_PARTICLE_STEPS_PER_S: f64 = 5e5;
/// The shortest default timeout: starting mpirun and reading a deck take seconds, and a
/// loaded machine more.
pub(crate) const MIN_TIMEOUT: Duration = Duration::from_secs(10 * 60);
/// The shortest default stall limit; otherwise a tenth of the timeout, which at the
/// margin of [`TIMEOUT_PARTICLE_STEPS_PER_S`] is about twice the whole run, so a run
/// that writes its log, screen or output files only now and then (LIGGGHTS buffers
/// its log) is never taken for a stalled one.
pub(crate) const MIN_STALL: Duration = Duration::from_secs(10 * 60);

impl Limits {
    /// The limits of a reference run of a comparison estimated at `particle_steps`:
    /// `timeout` and `stall` as given (`--engine-timeout`, `--engine-stall`), else the
    /// defaults above.
    pub(crate) fn derived(
        particle_steps: f64,
        timeout: Option<Duration>,
        stall: Option<Duration>,
    ) -> Limits {
        let (timeout, timeout_origin) = match timeout {
            Some(t) => (t, format!("--engine-timeout {}", fmt_duration(t))),
            None => {
                let s = particle_steps / TIMEOUT_PARTICLE_STEPS_PER_S;
                let t = if s.is_finite() && s > MIN_TIMEOUT.as_secs_f64() {
                    // Capped where a Duration still holds it; the estimate's own limit
                    // (experiments::limits) refuses such runs long before.
                    Duration::from_secs_f64(s.min(1e9))
                } else {
                    MIN_TIMEOUT
                };
                (
                    t,
                    format!(
                        "--engine-timeout default {}: the estimated {particle_steps:.3e} particle-steps at {TIMEOUT_PARTICLE_STEPS_PER_S:.0e} per second, at least {}",
                        fmt_duration(t),
                        fmt_duration(MIN_TIMEOUT)
                    ),
                )
            }
        };
        let (stall, stall_origin) = match stall {
            Some(s) => (s, format!("--engine-stall {}", fmt_duration(s))),
            None => {
                let s = (timeout / 10).max(MIN_STALL).min(timeout);
                (
                    s,
                    format!(
                        "--engine-stall default {}: a tenth of the timeout, at least {}",
                        fmt_duration(s),
                        fmt_duration(MIN_STALL)
                    ),
                )
            }
        };
        Limits {
            timeout,
            timeout_origin,
            stall,
            stall_origin,
        }
    }

    /// Fixed limits (a version probe, a tool check).
    pub fn fixed(timeout: Duration, why: &str) -> Limits {
        Limits {
            timeout,
            timeout_origin: why.to_string(),
            stall: timeout,
            stall_origin: why.to_string(),
        }
    }
}

/// Parses a duration of the command line: a positive number and a unit, `s`, `m` (or
/// `min`), `h` or `d`: `600s`, `90m`, `1.5h`. A bare number is refused (seconds or
/// minutes? the unit is part of the value).
pub fn parse_duration(text: &str) -> Result<Duration, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let scale = match unit.trim() {
        "s" => 1.0,
        "m" | "min" => 60.0,
        "h" => 3600.0,
        "d" => 86400.0,
        "" => {
            return Err(format!(
                "{text:?} has no unit: write e.g. {num}s, {num}m or {num}h"
            ));
        }
        u => {
            return Err(format!(
                "{text:?}: unknown unit {u:?} (use s, m, h or d, e.g. 90m)"
            ));
        }
    };
    let v: f64 = num
        .parse()
        .map_err(|_| format!("{text:?} is not a number with a unit (e.g. 90m, 4h, 600s)"))?;
    let secs = v * scale;
    if !(1.0..=366.0 * 86400.0).contains(&secs) {
        return Err(format!("{text:?}: must lie between 1 s and 366 days"));
    }
    Ok(Duration::from_secs_f64(secs))
}

/// `d` as seconds, minutes or hours, for messages.
pub(crate) fn fmt_duration(d: Duration) -> String {
    let s = d.as_secs_f64();
    if s < 120.0 {
        format!("{s:.1} s")
    } else if s < 7200.0 {
        format!("{:.1} min", s / 60.0)
    } else {
        format!("{:.1} h", s / 3600.0)
    }
}

/// Quotes one argument for display as a POSIX shell word (only when needed).
pub(crate) fn shell_word(s: &str) -> String {
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
/// files, in a session of its own ([`children`]); ends it (SIGTERM, then SIGKILL after a
/// grace period, every process of its session) when a limit is reached.
pub fn run(
    argv: &[String],
    dir: &Path,
    stdout: &Path,
    stderr: &Path,
    limits: &Limits,
) -> Result<Finished> {
    run_with(argv, dir, stdout, stderr, limits, || {})
}

/// [`run`], calling `tick` about twice a second while the process lives (progress bars
/// that follow the log).
pub(crate) fn run_with(
    argv: &[String],
    dir: &Path,
    stdout: &Path,
    stderr: &Path,
    limits: &Limits,
    mut tick: impl FnMut(),
) -> Result<Finished> {
    let (prog, args) = argv.split_first().context("empty command line")?;
    let out = std::fs::File::create(stdout)
        .with_context(|| format!("cannot create {}", stdout.display()))?;
    let err = std::fs::File::create(stderr)
        .with_context(|| format!("cannot create {}", stderr.display()))?;
    let start = Instant::now();
    let mut cmd = Command::new(prog);
    cmd.args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::from(out))
        .stderr(Stdio::from(err));
    let (mut child, session) = children::spawn(&mut cmd).with_context(|| {
        format!(
            "cannot start `{}` in {} (is it installed and on PATH?)",
            command_line(argv),
            dir.display()
        )
    })?;

    let mut growth = Growth::new(dir);
    let mut pause = Duration::from_millis(5);
    let mut last_tick = Instant::now();
    let outcome = loop {
        if last_tick.elapsed() >= Duration::from_millis(500) {
            tick();
            last_tick = Instant::now();
        }
        let status = child.try_wait();
        // A signal to granval ended this engine: its handler exits the process.
        children::wait_if_interrupted();
        if let Some(status) =
            status.with_context(|| format!("waiting for `{}`", command_line(argv)))?
        {
            break Outcome::Exited(status);
        }
        if start.elapsed() >= limits.timeout {
            break Outcome::TimedOut;
        }
        if let Some(stall) = growth.stalled(limits.stall) {
            break Outcome::Stalled(stall);
        }
        std::thread::sleep(
            pause
                .min(limits.timeout.saturating_sub(start.elapsed()))
                .max(Duration::from_millis(1)),
        );
        pause = (pause * 2).min(Duration::from_millis(100));
    };
    let wall_time_s = start.elapsed().as_secs_f64();
    // Ends the run if a limit stopped it, and in any case whatever it left running
    // in its session (a rank, a wrapper's child).
    drop(session);
    let _ = child.wait();
    children::wait_if_interrupted();
    Ok(Finished {
        outcome,
        wall_time_s,
    })
}

/// Whether any file in a run directory (and its sub-directories, two levels) still
/// grows: the stall watch of [`run_with`], sampled once a second.
struct Growth {
    dir: PathBuf,
    sizes: BTreeMap<PathBuf, u64>,
    last_change: Instant,
    last_file: Option<PathBuf>,
    last_scan: Instant,
}

impl Growth {
    fn new(dir: &Path) -> Growth {
        let mut sizes = BTreeMap::new();
        scan(dir, dir, 2, &mut sizes);
        Growth {
            dir: dir.to_path_buf(),
            sizes,
            last_change: Instant::now(),
            last_file: None,
            last_scan: Instant::now(),
        }
    }

    fn stalled(&mut self, limit: Duration) -> Option<Stall> {
        if self.last_scan.elapsed() < Duration::from_secs(1).min(limit / 4) {
            return None;
        }
        self.last_scan = Instant::now();
        let mut now = BTreeMap::new();
        scan(&self.dir, &self.dir, 2, &mut now);
        if let Some((f, _)) = now
            .iter()
            .filter(|(f, n)| self.sizes.get(*f) != Some(*n))
            .max_by_key(|(_, n)| **n)
        {
            self.last_file = Some(f.clone());
            self.last_change = Instant::now();
        }
        self.sizes = now;
        let quiet = self.last_change.elapsed();
        (quiet >= limit).then(|| Stall {
            size: self
                .last_file
                .as_ref()
                .and_then(|f| self.sizes.get(f))
                .copied()
                .unwrap_or(0),
            file: self.last_file.clone(),
            quiet,
        })
    }
}

/// Sizes of the regular files under `dir` (relative to `root`), `depth` levels down.
fn scan(root: &Path, dir: &Path, depth: usize, into: &mut BTreeMap<PathBuf, u64>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let Ok(t) = e.file_type() else { continue };
        let p = e.path();
        if t.is_file() {
            if let Ok(m) = e.metadata() {
                let rel = p.strip_prefix(root).unwrap_or(&p).to_path_buf();
                into.insert(rel, m.len());
            }
        } else if t.is_dir() && depth > 0 {
            scan(root, &p, depth - 1, into);
        }
    }
}

/// The executable `binary` names: itself when it holds a `/`, else the first match on
/// PATH.
pub fn on_path(binary: &str) -> Option<PathBuf> {
    use std::os::unix::fs::PermissionsExt;
    if binary.contains('/') {
        return Some(PathBuf::from(binary));
    }
    std::env::split_paths(&std::env::var_os("PATH")?)
        .map(|d| d.join(binary))
        .find(|p| {
            std::fs::metadata(p).is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
        })
}

/// Whether `argv` runs and exits 0 within a few seconds (a tool check).
pub(crate) fn succeeds(argv: &[String]) -> bool {
    let Ok(dir) = children::OwnedDir::temp() else {
        return false;
    };
    let d = dir.path();
    run(
        argv,
        d,
        &d.join("stdout"),
        &d.join("stderr"),
        &Limits::fixed(Duration::from_secs(10), "a tool check"),
    )
    .is_ok_and(|f| matches!(f.outcome, Outcome::Exited(s) if s.success()))
}

/// `mpirun --allow-run-as-root -np N` for N > 1, nothing for one process: the prefix
/// both engines' command lines start with.
pub(crate) fn mpi_prefix(mpi_procs: usize) -> Vec<String> {
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
pub(crate) fn remove_stale(dir: &Path, names: &[&str]) -> Result<()> {
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

/// How long the version probe of an engine may take: the real engines answer an empty
/// deck in well under a second.
pub(crate) const PROBE_TIMEOUT: Duration = Duration::from_secs(10);

/// What the version probe found.
#[derive(Debug, Clone, PartialEq)]
pub enum Probe {
    /// No executable of that name (not on PATH).
    Absent,
    /// It runs and printed this banner line.
    Found(String),
    /// An executable of that name exists but is not a working engine: why.
    Broken(String),
}

/// Runs `binary` on an empty deck without a log in a scratch directory (ended after
/// [`PROBE_TIMEOUT`]) and reads its banner, the stdout line starting with `prefix`;
/// `accept` may refuse the banner (a wrong version). Only a missing executable is
/// [`Probe::Absent`]: one that hangs, fails, prints no banner or is refused is
/// [`Probe::Broken`] with the reason, naming the executable.
pub fn probe(binary: &str, prefix: &str, accept: impl Fn(&str) -> Result<(), String>) -> Probe {
    let argv: Vec<String> = [binary, "-in", "/dev/null", "-log", "none", "-echo", "none"]
        .map(String::from)
        .to_vec();
    let named = match on_path(binary) {
        Some(p) if p.as_os_str() != binary => format!("`{binary}` ({})", p.display()),
        _ => format!("`{binary}`"),
    };
    let dir = match children::OwnedDir::temp() {
        Ok(d) => d,
        Err(e) => return Probe::Broken(format!("cannot probe {named}: {e:#}")),
    };
    let d = dir.path();
    let (out, err) = (d.join("stdout"), d.join("stderr"));
    let limits = Limits::fixed(PROBE_TIMEOUT, "the version probe");
    let fin = match run(&argv, d, &out, &err, &limits) {
        Ok(f) => f,
        Err(e) => {
            let missing = e.chain().any(|c| {
                c.downcast_ref::<std::io::Error>()
                    .is_some_and(|io| io.kind() == std::io::ErrorKind::NotFound)
            });
            return if missing {
                Probe::Absent
            } else {
                Probe::Broken(format!("{named} cannot be started: {e:#}"))
            };
        }
    };
    let (stdout, stderr) = (read_lossy(&out), read_lossy(&err));
    let said = || {
        let first = stderr
            .lines()
            .chain(stdout.lines())
            .map(str::trim)
            .find(|l| !l.is_empty());
        match first {
            Some(l) => format!("; it printed: {l}"),
            None => "; it printed nothing".into(),
        }
    };
    let command = command_line(&argv);
    match fin.outcome {
        Outcome::TimedOut | Outcome::Stalled(_) => Probe::Broken(format!(
            "{named} did not answer the version probe (`{command}`) within {}: is it {}?",
            fmt_duration(PROBE_TIMEOUT),
            prefix.split(' ').next().unwrap_or(prefix)
        )),
        Outcome::Exited(s) if !s.success() => Probe::Broken(format!(
            "{named} failed the version probe (`{command}`): exited with {s}{}",
            said()
        )),
        Outcome::Exited(_) => match banner_line(&stdout, prefix) {
            None => Probe::Broken(format!(
                "{named} answered the version probe (`{command}`) without a `{prefix}` line{}: it is not {}",
                said(),
                prefix.split(' ').next().unwrap_or(prefix)
            )),
            Some(banner) => match accept(&banner) {
                Ok(()) => Probe::Found(banner),
                Err(why) => Probe::Broken(format!("{named}: {why}")),
            },
        },
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
pub(crate) struct TranscriptFiles {
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
pub(crate) struct Transcript {
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

    /// "`what` failed: `reason`", the command, the engine's ERROR lines, mpirun's own
    /// messages (with a remedy where one is known) and the tails of its log (or screen
    /// output when the log is empty) and stderr.
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
        let mpi = mpi_messages(&[&self.stderr, &self.stdout]);
        if !mpi.is_empty() {
            m += "mpirun reported:\n";
            for l in &mpi {
                m += &format!("  {l}\n");
            }
            if mpi.iter().any(|l| l.contains("not enough slots available")) {
                let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
                m += &format!(
                    "remedy: --np N with N at most the {cores} core(s) Open MPI counts here (granval does not add --oversubscribe: more ranks than cores would only slow every rank down)\n"
                );
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

    /// Turns a timeout, a stall, a non-zero exit or an `ERROR` line after exit status 0
    /// into [`Transcript::failure`]; `Ok` only for a clean exit.
    pub(crate) fn check_exit(
        &self,
        fin: &Finished,
        limits: &Limits,
        what: &str,
        command: &str,
        dir: &Path,
    ) -> Result<()> {
        let engine = self.files.engine;
        let ran = fmt_duration(Duration::from_secs_f64(fin.wall_time_s.max(0.0)));
        let reason = match &fin.outcome {
            Outcome::TimedOut => format!(
                "{engine} ran for {ran}, the limit ({}); its processes were ended. A run that needs longer: pass --engine-timeout DURATION (e.g. 12h)",
                limits.timeout_origin
            ),
            Outcome::Stalled(st) => {
                let last = match &st.file {
                    Some(f) => format!("{} stopped growing at {} bytes", f.display(), st.size),
                    None => "nothing was written after the start".into(),
                };
                format!(
                    "{engine} stalled: no file in {} grew for {} (the limit: {}); {last}; its processes were ended after {ran}",
                    dir.display(),
                    fmt_duration(st.quiet),
                    limits.stall_origin
                )
            }
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

/// The first paragraph of each of mpirun's help blocks (text between lines of dashes,
/// e.g. "There are not enough slots available in the system to satisfy the 3 slots
/// that were requested by the application:"), its lines joined, each once. Open MPI
/// prints the reason first and pages of advice after it, so the tail of stderr shows
/// only the advice.
fn mpi_messages(texts: &[&str]) -> Vec<String> {
    let rule = |l: &str| l.len() >= 20 && l.chars().all(|c| c == '-');
    let mut out: Vec<String> = Vec::new();
    for text in texts {
        let lines: Vec<&str> = text.lines().map(str::trim).collect();
        let mut k = 0;
        while k < lines.len() {
            if rule(lines[k]) {
                let para: Vec<&str> = lines[k + 1..]
                    .iter()
                    .copied()
                    .take_while(|l| !l.is_empty() && !rule(l))
                    .collect();
                let joined = para.join(" ");
                if !joined.is_empty() && !out.contains(&joined) {
                    out.push(joined);
                }
                // Skip to the closing rule of this block.
                k += 1;
                while k < lines.len() && !rule(lines[k]) {
                    k += 1;
                }
            }
            k += 1;
        }
    }
    out
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
        let t = &Limits::derived(1e3, Some(Duration::from_secs(7)), None);
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
        assert!(
            e.contains(
                "ENGINE ran for 7.0 s, the limit (--engine-timeout 7.0 s); its processes were ended"
            ),
            "{e}"
        );
        let stalled = Finished {
            outcome: Outcome::Stalled(Stall {
                file: Some("log".into()),
                size: 12,
                quiet: Duration::from_secs(7),
            }),
            wall_time_s: 9.0,
        };
        let e = format!(
            "{:#}",
            ok.check_exit(&stalled, t, "run", "cmd", dir.path())
                .unwrap_err()
        );
        assert!(
            e.contains("ENGINE stalled: no file in")
                && e.contains("grew for 7.0 s (the limit: --engine-stall default 7.0 s")
                && e.contains("log stopped growing at 12 bytes"),
            "{e}"
        );

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

    #[test]
    fn durations_need_a_unit_and_a_sane_size() {
        assert_eq!(parse_duration("600s"), Ok(Duration::from_secs(600)));
        assert_eq!(parse_duration("90m"), Ok(Duration::from_secs(5400)));
        assert_eq!(parse_duration("90min"), Ok(Duration::from_secs(5400)));
        assert_eq!(parse_duration("1.5h"), Ok(Duration::from_secs(5400)));
        assert_eq!(parse_duration("2d"), Ok(Duration::from_secs(172_800)));
        for bad in ["90", "0s", "0.5s", "-3m", "4x", "h", "", "400d", "1e3s"] {
            assert!(parse_duration(bad).is_err(), "{bad}");
        }
        assert!(parse_duration("90").unwrap_err().contains("no unit"));
    }

    #[test]
    fn default_limits_follow_the_estimate_with_a_floor() {
        // Small: the floor.
        let l = Limits::derived(2e3, None, None);
        assert_eq!((l.timeout, l.stall), (MIN_TIMEOUT, MIN_STALL));
        // feng-fig3a-g-1's 7.125e9 particle-steps: 14 250 s, about 20 times its longest
        // recorded LIGGGHTS bed (728 s); the stall limit a tenth of that.
        let l = Limits::derived(7.125e9, None, None);
        assert_eq!(l.timeout, Duration::from_secs(14_250));
        assert_eq!(l.stall, Duration::from_secs(1425));
        assert!(
            l.timeout_origin.starts_with(
                "--engine-timeout default 4.0 h: the estimated 7.125e9 particle-steps at 5e5 per second"
            ),
            "{}",
            l.timeout_origin
        );
        // Given values win; a stall default never exceeds the timeout.
        let l = Limits::derived(7.125e9, Some(Duration::from_secs(2)), None);
        assert_eq!(
            (l.timeout, l.stall),
            (Duration::from_secs(2), Duration::from_secs(2))
        );
        assert_eq!(l.timeout_origin, "--engine-timeout 2.0 s");
        let l = Limits::derived(f64::NAN, None, Some(Duration::from_secs(3)));
        assert_eq!((l.timeout, l.stall), (MIN_TIMEOUT, Duration::from_secs(3)));
        assert_eq!(l.stall_origin, "--engine-stall 3.0 s");
    }

    /// What Open MPI 4.1.4 prints for `mpirun -np 3` on two cores (stderr, verbatim).
    const NOT_ENOUGH_SLOTS: &str =
        "--------------------------------------------------------------------------
There are not enough slots available in the system to satisfy the 3
slots that were requested by the application:

  liggghts

Either request fewer slots for your application, or make more slots
available for use.

A \"slot\" is the Open MPI term for an allocatable unit where we can
launch a process.
--------------------------------------------------------------------------
";

    #[test]
    fn mpiruns_reason_is_shown_with_a_remedy() {
        assert_eq!(
            mpi_messages(&[NOT_ENOUGH_SLOTS, NOT_ENOUGH_SLOTS]),
            [
                "There are not enough slots available in the system to satisfy the 3 slots that were requested by the application:"
            ]
        );
        assert!(mpi_messages(&["ERROR: x\n----\n"]).is_empty());
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("err"), NOT_ENOUGH_SLOTS).unwrap();
        let tr = Transcript::read(FILES, dir.path());
        let e = format!(
            "{:#}",
            tr.check_exit(
                &exited(1),
                &Limits::derived(0.0, None, None),
                "run",
                "cmd",
                dir.path()
            )
            .unwrap_err()
        );
        assert!(
            e.contains("mpirun reported:\n  There are not enough slots available in the system to satisfy the 3 slots that were requested by the application:\nremedy: --np N with N at most the"),
            "{e}"
        );
        // The tail alone (the old message) never held the reason.
        assert!(!tail(NOT_ENOUGH_SLOTS, 10).contains("not enough slots"));
    }

    fn script(dir: &Path, name: &str, body: &str) -> String {
        use std::os::unix::fs::PermissionsExt;
        let p = dir.join(name);
        std::fs::write(&p, format!("#!/bin/sh\n{body}\n")).unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
        p.display().to_string()
    }

    #[test]
    fn the_probe_tells_missing_from_broken() {
        let d = tempfile::tempdir().unwrap();
        let ok = |_: &str| Ok(());
        assert_eq!(probe("/nonexistent/engine", "ENGINE (", ok), Probe::Absent);
        let good = script(d.path(), "good", "echo 'ENGINE (v1)'");
        assert_eq!(
            probe(&good, "ENGINE (", ok),
            Probe::Found("ENGINE (v1)".into())
        );
        let refuse = |b: &str| Err(format!("is {b}, not v2"));
        assert_eq!(
            probe(&good, "ENGINE (", refuse),
            Probe::Broken(format!("`{good}`: is ENGINE (v1), not v2"))
        );
        let silent = script(d.path(), "silent", "exit 0");
        assert!(
            matches!(probe(&silent, "ENGINE (", ok), Probe::Broken(m) if m.contains("without a `ENGINE (` line; it printed nothing: it is not ENGINE"))
        );
        let fails = script(d.path(), "fails", "echo nope >&2; exit 4");
        assert!(
            matches!(probe(&fails, "ENGINE (", ok), Probe::Broken(m) if m.contains("exited with exit status: 4; it printed: nope"))
        );
        let not_exec = d.path().join("plain");
        std::fs::write(&not_exec, "x").unwrap();
        assert!(matches!(
            probe(not_exec.to_str().unwrap(), "ENGINE (", ok),
            Probe::Broken(m) if m.contains("cannot be started")
        ));
    }
}
