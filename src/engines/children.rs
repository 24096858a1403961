//! granval owns the processes and temporary directories it creates: none outlives it.
//!
//! * Every reference engine starts in a **session of its own** (`setsid` between fork
//!   and exec). A process group is not enough: Open MPI 4.1's `mpirun` puts each rank in
//!   a process group of its own (measured on Debian's 4.1.4: rank pgid = rank pid), but
//!   every rank stays in mpirun's session, so the session holds the whole run. A session
//!   also takes the engine off the terminal: a Ctrl-C reaches granval only, which then
//!   ends the engine itself.
//! * Ending an engine ([`end_session`]): SIGTERM to the session leader's group (mpirun
//!   forwards it to its ranks and cleans up) and to every live process of the session,
//!   then SIGKILL to whatever is still alive after a grace period.
//! * The engine gets a **parent-death signal** (`prctl(PR_SET_PDEATHSIG, SIGTERM)`), so
//!   a granval killed outright (SIGKILL, no handler runs) still ends its direct child.
//!   Linux sends it when the *thread* that started the child ends; the thread that starts
//!   an engine waits for it in the same call, so it outlives the run. That alone is not
//!   enough: mpirun receiving it ended both ranks of an `-np 2` LIGGGHTS run in our
//!   measurements, but left both ranks of an `-np 2 sleep` running with ppid 1 in about
//!   half of the trials, and a wrapper script that neither execs nor forwards signals
//!   leaves its child. So each engine also gets a **watchdog** ([`WATCHDOG`]): a small
//!   `sh` in a session of its own that notices when granval is gone (its parent pid
//!   changes) and then ends every process of the engine's session as [`end_session`]
//!   does. granval ends the watchdog when the engine's session ends.
//! * SIGINT, SIGTERM and SIGHUP to granval ([`exit_on_signals`], installed by the
//!   binary): every live engine session is ended, every temporary directory granval
//!   registered ([`OwnedDir`]) is removed, one line says so, and granval exits with the
//!   shell's code for the signal (130, 143, 129). Nothing outside those directories is
//!   touched.

use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// How long an engine has to end after SIGTERM before it gets SIGKILL.
pub(crate) const GRACE: Duration = Duration::from_secs(5);

/// A live engine session: its id (the leader's pid), the program started, the pid of
/// its watchdog if one could be started.
struct Entry {
    sid: i32,
    program: String,
    watchdog: Option<i32>,
}

/// Live engine sessions.
static SESSIONS: Mutex<Vec<Entry>> = Mutex::new(Vec::new());
/// Directories granval created for itself and removes on exit, a signal included.
static OWNED_DIRS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Set by the signal thread before it ends anything: no new engine starts after it,
/// and a run whose engine it ended waits for the exit instead of reporting on it.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Whether a fatal signal arrived and its cleanup is under way.
pub(crate) fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

/// Blocks forever once a signal's cleanup is under way: the signal thread ends the
/// process with the signal's exit code, and nothing may report on the runs it ended.
pub fn wait_if_interrupted() {
    if interrupted() {
        park()
    }
}

fn park() -> ! {
    loop {
        std::thread::sleep(Duration::from_secs(3600));
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// A live engine session, ended when dropped (normally after its leader was reaped, to
/// end whatever it left behind), its watchdog with it.
pub struct Session {
    sid: i32,
    watchdog: Option<std::process::Child>,
}

impl Session {
    /// The session (and process group) id: the leader's pid.
    pub fn id(&self) -> i32 {
        self.sid
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        if !session_members(self.sid).is_empty() {
            end_session(self.sid, GRACE);
        }
        if let Some(w) = &mut self.watchdog {
            let _ = w.kill();
            let _ = w.wait();
        }
        lock(&SESSIONS).retain(|e| e.sid != self.sid);
    }
}

/// The watchdog of one engine session (`sh -c WATCHDOG watchdog GRANVAL_PID SID`): once a
/// second it reads its own parent pid from /proc; when that is no longer granval's
/// (granval died and it was re-parented), it ends the session as [`end_session`] does:
/// SIGTERM to the leader's group and to each live member, SIGKILL to those left after 5
/// s. Members are read from /proc/PID/stat with the fields counted after the last `) `,
/// so a command name with spaces cannot shift them; zombies are not members.
pub(crate) const WATCHDOG: &str = r#"g=$1 s=$2
while :; do
  read -r _ _ _ pp _ < /proc/$$/stat || exit 0
  [ "$pp" = "$g" ] || break
  sleep 1
done
members() {
  for f in /proc/[0-9]*/stat; do
    { read -r l < "$f"; } 2>/dev/null || continue
    set -- ${l##*) }
    if [ "$4" = "$s" ] && [ "$1" != Z ]; then p=${f#/proc/}; echo "${p%/stat}"; fi
  done
}
kill -TERM -"$s" 2>/dev/null
for p in $(members); do kill -TERM "$p" 2>/dev/null; done
i=0
while [ $i -lt 50 ]; do
  [ -z "$(members)" ] && exit 0
  sleep 0.1
  i=$((i+1))
done
kill -KILL -"$s" 2>/dev/null
for p in $(members); do kill -KILL "$p" 2>/dev/null; done
"#;

/// Starts the watchdog of session `sid` in a session of its own (a Ctrl-C or hangup of
/// the terminal does not reach it); `None` when it cannot start (the parent-death signal
/// still covers the direct child).
fn start_watchdog(parent: i32, sid: i32) -> Option<std::process::Child> {
    use std::os::unix::process::CommandExt;
    use std::process::Stdio;
    let mut cmd = std::process::Command::new("/bin/sh");
    cmd.args(["-c", WATCHDOG, "granval-watchdog"])
        .arg(parent.to_string())
        .arg(sid.to_string())
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    // SAFETY: setsid is async-signal-safe and allocates nothing.
    unsafe {
        cmd.pre_exec(|| {
            if libc::setsid() < 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    cmd.spawn().ok()
}

/// Spawns `cmd` as the leader of a new session with the parent-death signal set, and
/// registers it so that a signal to granval ends it. Refuses to start anything once a
/// signal's cleanup is under way.
pub fn spawn(cmd: &mut std::process::Command) -> std::io::Result<(std::process::Child, Session)> {
    use std::os::unix::process::CommandExt;
    let parent = std::process::id() as i32;
    // SAFETY: the closure runs between fork and exec and only makes async-signal-safe
    // system calls (setsid, prctl, getppid); it allocates nothing.
    unsafe {
        cmd.pre_exec(move || {
            if libc::setsid() < 0 {
                return Err(std::io::Error::last_os_error());
            }
            #[cfg(target_os = "linux")]
            if libc::prctl(
                libc::PR_SET_PDEATHSIG,
                libc::SIGTERM as libc::c_ulong,
                0 as libc::c_ulong,
                0 as libc::c_ulong,
                0 as libc::c_ulong,
            ) != 0
            {
                return Err(std::io::Error::last_os_error());
            }
            // granval died before the death signal was armed: do not start the engine
            // (ESRCH, "no such process": the parent is gone; nothing is allocated here).
            if libc::getppid() != parent {
                return Err(std::io::Error::from_raw_os_error(libc::ESRCH));
            }
            Ok(())
        });
    }
    let mut sessions = lock(&SESSIONS);
    if interrupted() {
        drop(sessions);
        park();
    }
    let child = cmd.spawn()?;
    let sid = child.id() as i32;
    let program = cmd.get_program().to_string_lossy().into_owned();
    let watchdog = start_watchdog(parent, sid);
    sessions.push(Entry {
        sid,
        program,
        watchdog: watchdog.as_ref().map(|w| w.id() as i32),
    });
    Ok((child, Session { sid, watchdog }))
}

/// The live (not zombie) processes of session `sid`, from /proc.
pub(crate) fn session_members(sid: i32) -> Vec<i32> {
    let Ok(entries) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    entries
        .filter_map(|e| e.ok()?.file_name().to_str()?.parse::<i32>().ok())
        .filter(|&pid| {
            proc_stat(pid).is_some_and(|s| s.session == sid && s.state != 'Z' && s.state != 'X')
        })
        .collect()
}

/// The fields of /proc/PID/stat granval needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ProcStat {
    pub state: char,
    pub ppid: i32,
    pub pgrp: i32,
    pub session: i32,
}

/// /proc/PID/stat of a process, `None` when it is gone. The command name (field 2) may
/// hold spaces and parentheses, so the fields are counted from its last `)`.
pub(crate) fn proc_stat(pid: i32) -> Option<ProcStat> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    parse_stat(&text)
}

fn parse_stat(text: &str) -> Option<ProcStat> {
    let rest = &text[text.rfind(')')? + 1..];
    let mut f = rest.split_whitespace();
    let state = f.next()?.chars().next()?;
    let mut num = || f.next()?.parse::<i32>().ok();
    Some(ProcStat {
        state,
        ppid: num()?,
        pgrp: num()?,
        session: num()?,
    })
}

/// Ends every process of session `sid`: SIGTERM to the leader's process group and to
/// each live member, SIGKILL to those still alive after `grace`. Only processes of that
/// session are signalled, by pid (no names).
pub(crate) fn end_session(sid: i32, grace: Duration) {
    // SAFETY: kill(2) with a pid and a signal number has no memory effects.
    unsafe {
        libc::kill(-sid, libc::SIGTERM);
    }
    for pid in session_members(sid) {
        unsafe {
            libc::kill(pid, libc::SIGTERM);
        }
    }
    let t = Instant::now();
    while t.elapsed() < grace {
        if session_members(sid).is_empty() {
            return;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    unsafe {
        libc::kill(-sid, libc::SIGKILL);
    }
    for pid in session_members(sid) {
        unsafe {
            libc::kill(pid, libc::SIGKILL);
        }
    }
}

/// A directory granval created for itself (a scratch directory, a record being
/// written): removed when dropped and when a signal ends granval; never a user's path.
pub(crate) struct OwnedDir {
    path: PathBuf,
}

impl OwnedDir {
    /// A fresh temporary directory (in `TMPDIR`).
    pub(crate) fn temp() -> Result<OwnedDir> {
        let dir = tempfile::tempdir().context("cannot create a temporary directory")?;
        Ok(OwnedDir::register(dir.keep()))
    }

    /// A directory granval is about to create at `path` (which it cleared itself): it
    /// is removed on drop unless it was moved away first.
    pub(crate) fn adopt(path: &Path) -> OwnedDir {
        OwnedDir::register(path.to_path_buf())
    }

    fn register(path: PathBuf) -> OwnedDir {
        lock(&OWNED_DIRS).push(path.clone());
        OwnedDir { path }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for OwnedDir {
    fn drop(&mut self) {
        let _ = remove_dir(&self.path);
        lock(&OWNED_DIRS).retain(|p| p != &self.path);
    }
}

/// Removes `path` if it exists; retried, since a run may still be writing into it.
fn remove_dir(path: &Path) -> std::io::Result<()> {
    let mut last = Ok(());
    for _ in 0..3 {
        if !path.exists() {
            return Ok(());
        }
        last = std::fs::remove_dir_all(path);
        if last.is_ok() {
            return Ok(());
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    last
}

/// Installs the handling of SIGINT, SIGTERM and SIGHUP (module docs): a thread that, on
/// the first of them, ends every engine session, removes every [`OwnedDir`], prints
/// one line and exits with 128 + the signal number.
pub fn exit_on_signals() -> Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])
        .context("cannot install the signal handlers")?;
    std::thread::Builder::new()
        .name("granval-signals".into())
        .spawn(move || {
            if let Some(sig) = signals.forever().next() {
                let line = clean_up(sig);
                eprintln!("{line}");
                std::process::exit(128 + sig);
            }
        })
        .context("cannot start the signal thread")?;
    Ok(())
}

/// What a fatal signal does before the exit; returns the line that says what was done.
fn clean_up(sig: i32) -> String {
    INTERRUPTED.store(true, Ordering::SeqCst);
    let name = match sig {
        libc::SIGINT => "SIGINT",
        libc::SIGTERM => "SIGTERM",
        libc::SIGHUP => "SIGHUP",
        _ => "a signal",
    };
    // Held to the exit: no engine starts any more.
    let sessions = lock(&SESSIONS);
    let mut ended = Vec::new();
    for e in sessions.iter() {
        let n = session_members(e.sid).len();
        end_session(e.sid, GRACE);
        if let Some(w) = e.watchdog {
            // SAFETY: kill(2) of our own child by pid.
            unsafe {
                libc::kill(w, libc::SIGKILL);
            }
        }
        ended.push(format!(
            "{} (session {}, {n} process(es))",
            e.program, e.sid
        ));
    }
    let dirs = lock(&OWNED_DIRS);
    let mut removed = 0;
    let mut kept = Vec::new();
    for d in dirs.iter().filter(|d| d.exists()) {
        match remove_dir(d) {
            Ok(()) => removed += 1,
            Err(e) => kept.push(format!("{} ({e})", d.display())),
        }
    }
    let mut line = format!("granval: {name}: stopped");
    if ended.is_empty() {
        line += ", no engine was running";
    } else {
        line += &format!(", ended {}", ended.join(", "));
    }
    line += &format!(
        ", removed {removed} temporary director{}",
        if removed == 1 { "y" } else { "ies" }
    );
    if !kept.is_empty() {
        line += &format!(", could not remove {}", kept.join(", "));
    }
    line + &format!("; exit {}", 128 + sig)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::process::ExitStatusExt;

    #[test]
    fn stat_fields_are_counted_from_the_last_parenthesis() {
        let s = parse_stat("4242 (a (b) c) S 17 4242 4240 0 -1 4194560 ...").unwrap();
        assert_eq!(
            s,
            ProcStat {
                state: 'S',
                ppid: 17,
                pgrp: 4242,
                session: 4240
            }
        );
        assert!(parse_stat("4242 (x").is_none());
        let me = proc_stat(std::process::id() as i32).unwrap();
        assert_ne!(me.state, 'Z');
    }

    /// A shell that starts a child of its own: both are in the new session, and ending
    /// the session ends both, the grandchild included (which a kill of the direct child
    /// alone would leave running with ppid 1).
    #[test]
    fn ending_a_session_ends_the_grandchildren_too() {
        let mut cmd = std::process::Command::new("sh");
        cmd.args(["-c", "sleep 300 & wait"]);
        let (mut child, session) = spawn(&mut cmd).unwrap();
        let sid = session.id();
        let t = Instant::now();
        while session_members(sid).len() < 2 && t.elapsed() < Duration::from_secs(10) {
            std::thread::sleep(Duration::from_millis(10));
        }
        let members = session_members(sid);
        assert_eq!(members.len(), 2, "{members:?}");
        assert_eq!(proc_stat(sid).unwrap().session, sid);
        drop(session);
        assert!(session_members(sid).is_empty());
        // The leader is left for its owner to reap (zombies are not members).
        assert!(child.wait().unwrap().signal().is_some());
        for pid in members {
            assert!(
                proc_stat(pid).is_none_or(|s| s.state == 'Z'),
                "{pid} lives on"
            );
        }
    }

    #[test]
    fn an_owned_directory_is_removed_when_dropped() {
        let d = OwnedDir::temp().unwrap();
        let p = d.path().to_path_buf();
        std::fs::write(p.join("x"), "y").unwrap();
        assert!(lock(&OWNED_DIRS).contains(&p));
        drop(d);
        assert!(!p.exists());
        assert!(!lock(&OWNED_DIRS).contains(&p));
    }

    /// The watchdog script on its own: started by a stand-in for granval that then
    /// exits, it ends the whole target session (a shell and its child).
    #[test]
    fn the_watchdog_ends_the_session_when_its_parent_is_gone() {
        use std::os::unix::process::CommandExt;
        let mut target = std::process::Command::new("sh");
        target.args(["-c", "sleep 300 & wait"]);
        unsafe {
            target.pre_exec(|| {
                libc::setsid();
                Ok(())
            });
        }
        let mut target = target.spawn().unwrap();
        let sid = target.id() as i32;
        let t = Instant::now();
        while session_members(sid).len() < 2 && t.elapsed() < Duration::from_secs(10) {
            std::thread::sleep(Duration::from_millis(10));
        }
        let members = session_members(sid);
        assert_eq!(members.len(), 2);
        // The stand-in starts the watchdog with its own pid and exits after 0.5 s.
        let status = std::process::Command::new("sh")
            .args([
                "-c",
                "/bin/sh -c \"$1\" granval-watchdog $$ \"$2\" & sleep 0.5",
                "stand-in",
                WATCHDOG,
                &sid.to_string(),
            ])
            .status()
            .unwrap();
        assert!(status.success());
        let t = Instant::now();
        while !session_members(sid).is_empty() && t.elapsed() < Duration::from_secs(10) {
            std::thread::sleep(Duration::from_millis(50));
        }
        let left = session_members(sid);
        for pid in &left {
            unsafe {
                libc::kill(*pid, libc::SIGKILL);
            }
        }
        assert!(left.is_empty(), "the watchdog left {left:?}");
        assert_eq!(target.wait().unwrap().signal(), Some(libc::SIGTERM));
    }
}
