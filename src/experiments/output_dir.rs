//! Output directories that can only hold granval's own output.
//!
//! Every command that writes a directory (`run --out`, `compare`/`check`/`analyze
//! --report`, `stress --out`, `deck -o`) claims it here first:
//!
//! - **where** it may be: never `/`, `$HOME`, the current directory or one of its
//!   ancestors, a directory holding a `.git`, a directory holding an input of the command
//!   (its case file, a suite's case files, the `--cases` directory), and neither inside
//!   nor around a store the command reads whole (the reference store, a deck directory
//!   being analysed, a `--runs` directory). These are refused even when empty or new;
//! - **what** it may hold: a new directory, an empty one, or one granval created, known
//!   by the marker file [`MARKER`] it writes there. `--force` clears only a directory
//!   with the marker; a non-empty directory without it is refused with or without
//!   `--force` ("not created by granval"), so no flag can make granval delete files it
//!   did not write;
//! - **who** writes it: one command at a time. The claim takes a lock ([`LOCK`], created
//!   exclusively, holding the pid and the process's start time) for the command's
//!   lifetime; a second command on the same directory exits 2 naming the lock and the
//!   pid. A lock whose process no longer runs (a crash, a kill) is stale: it is said so
//!   and taken.

use crate::rundata::fsio;
use anyhow::{Context, Result, bail};
use std::path::{Component, Path, PathBuf};

/// The marker granval writes into every output directory it creates or claims.
pub(crate) const MARKER: &str = ".granval-output";
/// The lock held while a command writes an output directory.
pub(crate) const LOCK: &str = ".granval-lock";
const MARKER_FIRST_LINE: &str = "granval output directory";

/// What an output directory must keep away from, for one command.
#[derive(Debug, Default, Clone)]
pub struct Protected {
    /// Files and directories the command reads (case files, suite files, the cases
    /// directory): the output directory may not hold any of them, at any depth.
    pub inputs: Vec<PathBuf>,
    /// Directories read as a whole or never written by granval's outputs (the reference
    /// store, a deck directory being analysed, `--runs` directories), each with what it
    /// is: the output directory may be neither inside one nor hold one.
    pub stores: Vec<(PathBuf, String)>,
}

impl Protected {
    pub fn input(mut self, p: impl Into<PathBuf>) -> Self {
        self.inputs.push(p.into());
        self
    }

    pub fn store(mut self, p: impl Into<PathBuf>, what: impl Into<String>) -> Self {
        self.stores.push((p.into(), what.into()));
        self
    }
}

/// An output directory claimed by this process; the lock is released when it is dropped.
#[derive(Debug)]
pub struct OutputDir {
    dir: PathBuf,
    lock: PathBuf,
    token: String,
}

impl OutputDir {
    /// The directory (as the user named it).
    pub fn path(&self) -> &Path {
        &self.dir
    }
}

impl Drop for OutputDir {
    fn drop(&mut self) {
        // Only our own lock: if someone removed it and another run took it, it is theirs.
        if std::fs::read_to_string(&self.lock).is_ok_and(|t| t == self.token) {
            let _ = std::fs::remove_file(&self.lock);
        }
    }
}

/// `p` as an absolute path with every symlink of its existing part resolved and `.` and
/// `..` applied: two names of one directory resolve to the same path.
pub fn resolve(p: &Path) -> Result<PathBuf> {
    let cwd = std::env::current_dir().context("cannot read the current directory")?;
    let mut cur = if p.is_absolute() {
        PathBuf::from("/")
    } else {
        std::fs::canonicalize(&cwd).unwrap_or(cwd)
    };
    let mut exists = true;
    for c in p.components() {
        match c {
            Component::RootDir | Component::Prefix(_) => cur = PathBuf::from("/"),
            Component::CurDir => {}
            Component::ParentDir => {
                cur.pop();
            }
            Component::Normal(n) => {
                cur.push(n);
                if exists {
                    match std::fs::canonicalize(&cur) {
                        Ok(real) => cur = real,
                        Err(_) => exists = false,
                    }
                }
            }
        }
    }
    Ok(cur)
}

fn home() -> Option<PathBuf> {
    let h = std::env::var_os("HOME").filter(|h| !h.is_empty())?;
    resolve(Path::new(&h)).ok()
}

/// Why `real` (resolved) may not be an output directory, if it may not.
fn misplaced(real: &Path, protected: &Protected) -> Result<Option<String>> {
    if real.parent().is_none() {
        return Ok(Some("is the root directory".into()));
    }
    if home().is_some_and(|h| h == real) {
        return Ok(Some("is your home directory ($HOME)".into()));
    }
    let cwd = resolve(Path::new("."))?;
    if cwd == real {
        return Ok(Some("is the current directory".into()));
    }
    if cwd.starts_with(real) {
        return Ok(Some(format!(
            "holds the current directory {}",
            cwd.display()
        )));
    }
    if std::fs::symlink_metadata(real.join(".git")).is_ok() {
        return Ok(Some(
            "holds a .git (a repository is never an output directory)".into(),
        ));
    }
    for i in &protected.inputs {
        let r = resolve(i)?;
        if r.starts_with(real) {
            return Ok(Some(format!(
                "holds {}, an input of this command",
                i.display()
            )));
        }
    }
    for (s, what) in &protected.stores {
        let r = resolve(s)?;
        if real.starts_with(&r) {
            return Ok(Some(format!("is inside {what} {}", s.display())));
        }
        if r.starts_with(real) {
            return Ok(Some(format!("holds {what} {}", s.display())));
        }
    }
    Ok(None)
}

/// Whether `dir` carries granval's marker (a regular file whose first line is granval's).
pub(crate) fn is_marked(dir: &Path) -> bool {
    fsio::read_to_string(&dir.join(MARKER), fsio::MAX_SMALL, "granval's marker")
        .is_ok_and(|t| t.lines().next() == Some(MARKER_FIRST_LINE))
}

fn write_marker(dir: &Path, command: &str) -> Result<()> {
    let text = format!(
        "{MARKER_FIRST_LINE}\n\
         created by granval {} ({command}), {}\n\
         `--force` clears a directory only when this file is in it; delete this file and \
         granval will never clear the directory.\n",
        env!("CARGO_PKG_VERSION"),
        crate::rundata::provenance::now_utc()
    );
    fsio::write_atomic(&dir.join(MARKER), text.as_bytes())
}

/// Start time of process `pid` in clock ticks since boot (field 22 of /proc/PID/stat):
/// with the pid it tells a live process from a later one that reuses its pid.
fn start_time(pid: u32) -> Option<u64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name (field 2) is in parentheses and may hold spaces.
    let rest = &stat[stat.rfind(')')? + 1..];
    rest.split_whitespace().nth(19)?.parse().ok()
}

/// A lock's holder as written in the lock file.
struct Holder {
    pid: u32,
    start: Option<u64>,
    command: String,
}

fn read_holder(lock: &Path) -> Option<Holder> {
    let text = fsio::read_to_string(lock, fsio::MAX_SMALL, "granval's lock").ok()?;
    let field = |k: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(k).map(|v| v.trim().to_string()))
    };
    Some(Holder {
        pid: field("pid ")?.parse().ok()?,
        start: field("start ").and_then(|s| s.parse().ok()),
        command: field("command ").unwrap_or_default(),
    })
}

/// Whether the holder still runs. Without /proc it cannot be told: taken as running.
fn alive(h: &Holder) -> bool {
    if !Path::new("/proc/self/stat").exists() {
        return true;
    }
    match (start_time(h.pid), h.start) {
        (None, _) => false,
        (Some(now), Some(then)) => now == then,
        (Some(_), None) => true,
    }
}

/// Takes the lock of `dir` (resolved `real`), or says who holds it.
fn lock(dir: &Path, real: &Path, command: &str) -> Result<(PathBuf, String)> {
    let path = real.join(LOCK);
    let pid = std::process::id();
    let token = format!(
        "pid {pid}\nstart {}\ncommand {command}\nsince {}\n",
        start_time(pid).map_or_else(|| "unknown".into(), |s| s.to_string()),
        crate::rundata::provenance::now_utc()
    );
    for attempt in 0..2 {
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&path)
        {
            Ok(mut f) => {
                use std::io::Write;
                f.write_all(token.as_bytes())
                    .and_then(|()| f.sync_all())
                    .with_context(|| format!("cannot write {}", path.display()))?;
                return Ok((path, token));
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                let Some(h) = read_holder(&path) else {
                    bail!(
                        "{}: locked by {} (unreadable lock); if no granval writes into {} now, remove the lock",
                        dir.display(),
                        path.display(),
                        dir.display()
                    );
                };
                if alive(&h) || attempt > 0 {
                    bail!(
                        "{}: in use by granval pid {} ({}); lock {}. Wait for it, or choose another directory",
                        dir.display(),
                        h.pid,
                        h.command,
                        path.display()
                    );
                }
                eprintln!(
                    "note: {} was left by granval pid {} ({}), which no longer runs: taking it",
                    path.display(),
                    h.pid,
                    h.command
                );
                std::fs::remove_file(&path)
                    .with_context(|| format!("cannot remove the stale lock {}", path.display()))?;
            }
            Err(e) => bail!("cannot create {}: {e}", path.display()),
        }
    }
    unreachable!("the loop returns or fails on its second attempt")
}

/// Entries of `dir` other than the marker and the lock.
fn contents(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut v = Vec::new();
    for e in std::fs::read_dir(dir).with_context(|| format!("cannot read {}", dir.display()))? {
        let e = e.with_context(|| format!("cannot read {}", dir.display()))?;
        let n = e.file_name();
        if n != MARKER && n != LOCK {
            v.push(e.path());
        }
    }
    v.sort();
    Ok(v)
}

fn refuse(flag: &str, dir: &Path, why: &str) -> anyhow::Error {
    anyhow::anyhow!(
        "{flag} {}: refused as an output directory: it {why}. Outputs go into a new directory, an empty one, or one granval created",
        dir.display()
    )
}

/// Claims `dir` as the output directory of `command` (named by `flag` in errors):
/// creates it, or takes an empty one, or with `force` clears one granval created; takes
/// its lock. Everything else is refused, naming the path and why.
pub fn claim(
    dir: &Path,
    flag: &str,
    force: bool,
    protected: &Protected,
    command: &str,
) -> Result<OutputDir> {
    let real = resolve(dir)?;
    if let Some(why) = misplaced(&real, protected)? {
        return Err(refuse(flag, dir, &why));
    }
    if std::fs::symlink_metadata(&real).is_err() {
        if let Some(parent) = real.parent() {
            std::fs::create_dir_all(parent)
                .with_context(|| format!("cannot create {}", parent.display()))?;
        }
        match std::fs::create_dir(&real) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(e) => bail!("cannot create {}: {e}", dir.display()),
        }
    }
    if !real.is_dir() {
        return Err(refuse(flag, dir, "is not a directory"));
    }
    let before = contents(&real)?;
    if !before.is_empty() && !is_marked(&real) {
        bail!(
            "{flag} {}: not empty and not created by granval (no {MARKER} in it; it holds e.g. {}); granval clears only directories it created, with or without --force: remove it yourself or choose another",
            dir.display(),
            before[0].display()
        );
    }
    let (lock_path, token) = lock(dir, &real, command)?;
    let claimed = OutputDir {
        dir: dir.to_path_buf(),
        lock: lock_path,
        token,
    };
    let old = contents(&real)?;
    if !old.is_empty() {
        if !force {
            bail!(
                "{flag} {} is not empty (outputs of an earlier granval run): outputs go into a fresh directory; pass --force to clear it",
                dir.display()
            );
        }
        for p in old {
            let md = std::fs::symlink_metadata(&p)
                .with_context(|| format!("cannot clear {}", p.display()))?;
            if md.is_dir() {
                std::fs::remove_dir_all(&p)
            } else {
                std::fs::remove_file(&p)
            }
            .with_context(|| format!("cannot clear {}", p.display()))?;
        }
    }
    write_marker(&real, command)?;
    Ok(claimed)
}

/// Claims `dir` to read and extend an earlier run's outputs (`stress --reuse`): it must
/// be a directory granval created (the marker), not in use; nothing is cleared.
pub fn reuse(dir: &Path, flag: &str, protected: &Protected, command: &str) -> Result<OutputDir> {
    let real = resolve(dir)?;
    if let Some(why) = misplaced(&real, protected)? {
        return Err(refuse(flag, dir, &why));
    }
    if !real.is_dir() {
        bail!(
            "{flag} {}: --reuse reads an earlier run's output directory; this is not a directory",
            dir.display()
        );
    }
    if !is_marked(&real) {
        bail!(
            "{flag} {}: --reuse reads only an output directory granval created (no {MARKER} in it)",
            dir.display()
        );
    }
    let (lock, token) = lock(dir, &real, command)?;
    Ok(OutputDir {
        dir: dir.to_path_buf(),
        lock,
        token,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn claim_in(dir: &Path, force: bool, p: &Protected) -> Result<OutputDir> {
        claim(dir, "--report", force, p, "granval test")
    }

    #[test]
    fn resolve_applies_dots_and_symlinks() {
        let d = tempfile::tempdir().unwrap();
        let real = std::fs::canonicalize(d.path()).unwrap();
        std::fs::create_dir(real.join("a")).unwrap();
        std::os::unix::fs::symlink(real.join("a"), real.join("link")).unwrap();
        assert_eq!(
            resolve(&real.join("link/./x/../y")).unwrap(),
            real.join("a/y")
        );
        assert_eq!(resolve(&real.join("a/../a")).unwrap(), real.join("a"));
    }

    /// A foreign directory is refused with or without --force and keeps its files; a
    /// directory granval created is refused without --force and cleared with it.
    #[test]
    fn only_granvals_own_directory_is_cleared() {
        let d = tempfile::tempdir().unwrap();
        let p = Protected::default();
        let foreign = d.path().join("foreign");
        std::fs::create_dir(&foreign).unwrap();
        std::fs::write(foreign.join("thesis.tex"), "mine").unwrap();
        for force in [false, true] {
            let e = claim_in(&foreign, force, &p).unwrap_err().to_string();
            assert!(e.contains("not created by granval"), "{e}");
            assert!(e.contains("thesis.tex"), "{e}");
        }
        assert!(foreign.join("thesis.tex").exists());

        let out = d.path().join("out");
        let c = claim_in(&out, false, &p).unwrap();
        assert!(is_marked(&out) && out.join(LOCK).exists());
        std::fs::write(out.join("report.json"), "{}").unwrap();
        drop(c);
        assert!(!out.join(LOCK).exists());
        let e = claim_in(&out, false, &p).unwrap_err().to_string();
        assert!(e.contains("not empty") && e.contains("--force"), "{e}");
        assert!(out.join("report.json").exists() && !out.join(LOCK).exists());
        let _c = claim_in(&out, true, &p).unwrap();
        assert!(!out.join("report.json").exists() && is_marked(&out));
        // An empty directory someone made is taken (and marked).
        let empty = d.path().join("empty");
        std::fs::create_dir(&empty).unwrap();
        let _e = claim_in(&empty, false, &p).unwrap();
        assert!(is_marked(&empty));
    }

    #[test]
    fn inputs_stores_and_repositories_are_refused_even_when_new() {
        let d = tempfile::tempdir().unwrap();
        let cases = d.path().join("cases");
        std::fs::create_dir_all(cases.join("micro")).unwrap();
        std::fs::write(cases.join("micro/a.toml"), "").unwrap();
        let refs = d.path().join("reference");
        std::fs::create_dir(&refs).unwrap();
        let p = Protected::default()
            .input(cases.join("micro/a.toml"))
            .store(&refs, "the reference store");
        for (dir, needle) in [
            (cases.join("micro"), "an input of this command"),
            (d.path().to_path_buf(), "an input of this command"),
            (refs.clone(), "inside the reference store"),
            (refs.join("new"), "inside the reference store"),
            (PathBuf::from("/"), "root directory"),
        ] {
            let e = claim_in(&dir, true, &p).unwrap_err().to_string();
            assert!(e.contains(needle), "{}: {e}", dir.display());
        }
        assert!(!refs.join("new").exists());
        assert!(cases.join("micro/a.toml").exists());
        let repo = d.path().join("repo");
        std::fs::create_dir_all(repo.join(".git")).unwrap();
        let e = claim_in(&repo, true, &Protected::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains(".git"), "{e}");
        // A store inside the output directory.
        let e = claim_in(
            d.path(),
            true,
            &Protected::default().store(&refs, "the reference store"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("holds the reference store"), "{e}");
    }

    /// A second claim while the first holds the lock names the lock and the pid; a lock
    /// of a process that no longer runs is taken.
    #[test]
    fn one_writer_at_a_time_and_stale_locks_are_taken() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("out");
        let p = Protected::default();
        let first = claim_in(&out, false, &p).unwrap();
        let e = claim_in(&out, true, &p).unwrap_err().to_string();
        assert!(
            e.contains(&format!("pid {}", std::process::id())) && e.contains(LOCK),
            "{e}"
        );
        assert!(
            out.join(LOCK).exists(),
            "the refused claim removed the lock"
        );
        drop(first);
        // A lock left by a process that is gone (4194304 is above any pid_max of Linux).
        std::fs::write(
            out.join(LOCK),
            "pid 4194304\nstart 1\ncommand granval old\n",
        )
        .unwrap();
        let c = claim_in(&out, true, &p).unwrap();
        assert!(
            std::fs::read_to_string(out.join(LOCK))
                .unwrap()
                .contains(&format!("pid {}", std::process::id()))
        );
        drop(c);
        // --reuse needs the marker.
        let bare = d.path().join("bare");
        std::fs::create_dir(&bare).unwrap();
        let e = reuse(&bare, "--out", &p, "t").unwrap_err().to_string();
        assert!(e.contains(MARKER), "{e}");
        let r = reuse(&out, "--out", &p, "t").unwrap();
        drop(r);
    }

    /// Every file granval writes beside case directories is a name no case may have.
    #[test]
    fn report_files_are_reserved_case_names() {
        for f in [
            crate::report::JSON_FILE,
            crate::report::MARKDOWN_FILE,
            crate::report::JUNIT_FILE,
            crate::experiments::runner::README_FILE,
            crate::compare::sweep::SUMMARY_FILE,
            "case.toml",
            "claims",
            "malt_verdict.svg",
        ] {
            assert!(crate::case::validate::RESERVED_NAMES.contains(&f), "{f}");
        }
    }
}
