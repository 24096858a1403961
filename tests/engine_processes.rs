//! granval owns its children: a signal to granval ends the reference engine's processes
//! and removes granval's temporary directories; a granval killed outright still ends
//! them (the parent-death signal); a hanging, silent or wrong `liggghts` on PATH is an
//! error within seconds, never a RECORDED pass; `--engine-timeout` and `--engine-stall`
//! end a run and say which limit did it; mpirun's own reason is shown.
//!
//! Fake engines are small shell scripts in a temporary directory put first on PATH for
//! the granval process of one test only. They answer the version probe (`-in
//! /dev/null`) with a LIGGGHTS banner unless the test is about the probe. Processes are
//! found and checked by pid (with their start time, so a reused pid is not mistaken for
//! one of ours), never by name across the machine.

mod common;

use std::collections::BTreeMap;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const BANNER: &str = "LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, fake engine for the granval tests)";
const CASE: &str = "cases/micro/head-on-e09.toml";

/// A scratch area: `bin/` (first on PATH) and `tmp/` (granval's TMPDIR, so the
/// temporary directories granval leaves behind can be counted).
struct Scratch {
    dir: tempfile::TempDir,
}

impl Scratch {
    fn new() -> Scratch {
        let s = Scratch {
            dir: tempfile::tempdir().unwrap(),
        };
        std::fs::create_dir(s.bin()).unwrap();
        std::fs::create_dir(s.tmp()).unwrap();
        s
    }
    fn bin(&self) -> PathBuf {
        self.dir.path().join("bin")
    }
    fn tmp(&self) -> PathBuf {
        self.dir.path().join("tmp")
    }
    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// Writes an executable `bin/liggghts` whose body runs for a real run; the probe
    /// (`-in /dev/null`) gets the banner unless `probe_too`.
    fn fake_liggghts(&self, run: &str, probe_too: bool) {
        use std::os::unix::fs::PermissionsExt;
        let probe = if probe_too {
            String::new()
        } else {
            format!("case \"$*\" in *'-in /dev/null'*) echo '{BANNER}'; exit 0;; esac\n")
        };
        let p = self.bin().join("liggghts");
        std::fs::write(&p, format!("#!/bin/sh\n{probe}{run}\n")).unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
    }

    /// `granval ARGS` with the fake first on PATH and TMPDIR in the scratch area.
    fn granval(&self, args: &[&str]) -> Command {
        let mut c = common::granval();
        let path = std::env::var_os("PATH").unwrap_or_default();
        let mut dirs = vec![self.bin()];
        dirs.extend(std::env::split_paths(&path));
        c.env("PATH", std::env::join_paths(dirs).unwrap())
            .env("TMPDIR", self.tmp())
            .env_remove("GRANVAL_REQUIRE_LIVE")
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        c
    }

    fn tmp_entries(&self) -> Vec<PathBuf> {
        std::fs::read_dir(self.tmp())
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect()
    }
}

/// (state, ppid, session, start time in clock ticks) of a live process.
fn stat(pid: i32) -> Option<(char, i32, i32, u64)> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    let f: Vec<&str> = text[text.rfind(')')? + 2..].split_whitespace().collect();
    Some((
        f[0].chars().next()?,
        f[1].parse().ok()?,
        f[3].parse().ok()?,
        f[19].parse().ok()?,
    ))
}

fn comm(pid: i32) -> String {
    std::fs::read_to_string(format!("/proc/{pid}/comm"))
        .unwrap_or_default()
        .trim()
        .to_string()
}

/// Every live descendant of `root`: pid -> (command name, start time).
fn descendants(root: i32) -> BTreeMap<i32, (String, u64)> {
    let mut parent = BTreeMap::new();
    for e in std::fs::read_dir("/proc").unwrap().flatten() {
        if let Some(pid) = e.file_name().to_str().and_then(|s| s.parse::<i32>().ok())
            && let Some((state, ppid, _, start)) = stat(pid)
            && state != 'Z'
        {
            parent.insert(pid, (ppid, start));
        }
    }
    let mut out = BTreeMap::new();
    let mut frontier = vec![root];
    while let Some(p) = frontier.pop() {
        for (&pid, &(ppid, start)) in &parent {
            if ppid == p && !out.contains_key(&pid) {
                out.insert(pid, (comm(pid), start));
                frontier.push(pid);
            }
        }
    }
    out
}

/// Waits until granval's descendants include every name of `want` (with repeats),
/// and returns them all.
fn wait_for_engine(
    granval: &mut Child,
    want: &[&str],
    within: Duration,
) -> BTreeMap<i32, (String, u64)> {
    let t = Instant::now();
    loop {
        let d = descendants(granval.id() as i32);
        let enough = want.iter().all(|w| {
            d.values().filter(|(c, _)| c == w).count() >= want.iter().filter(|x| *x == w).count()
        });
        if enough {
            // The processes are up; give the engine a moment past its start.
            std::thread::sleep(Duration::from_millis(500));
            return descendants(granval.id() as i32);
        }
        if let Ok(Some(s)) = granval.try_wait() {
            let mut err = String::new();
            use std::io::Read;
            granval
                .stderr
                .take()
                .unwrap()
                .read_to_string(&mut err)
                .unwrap();
            panic!("granval ended ({s}) before the engine {want:?} was seen: {err}");
        }
        assert!(
            t.elapsed() < within,
            "the engine {want:?} did not start within {within:?}; granval's descendants: {d:?}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The processes of `procs` still alive (same pid, same start time, not a zombie).
fn alive(procs: &BTreeMap<i32, (String, u64)>) -> Vec<String> {
    procs
        .iter()
        .filter(|(pid, (_, start))| {
            stat(**pid).is_some_and(|(state, _, _, s)| s == *start && state != 'Z')
        })
        .map(|(pid, (c, _))| format!("{c} (pid {pid})"))
        .collect()
}

/// Asserts that none of `procs` is alive `within` from now (polling), so a failing
/// test leaves nothing behind either: survivors are killed by pid before the panic.
fn assert_all_ended(procs: &BTreeMap<i32, (String, u64)>, within: Duration, what: &str) {
    let t = Instant::now();
    while !alive(procs).is_empty() && t.elapsed() < within {
        std::thread::sleep(Duration::from_millis(50));
    }
    let left = alive(procs);
    if !left.is_empty() {
        for pid in procs.keys() {
            unsafe {
                libc::kill(*pid, libc::SIGKILL);
            }
        }
        panic!("{what}: still running after {within:?}: {left:?}");
    }
}

/// Waits for granval to exit (at most `within`), returning (exit status, stdout, stderr).
fn finish(mut c: Child, within: Duration) -> (std::process::ExitStatus, String, String) {
    let t = Instant::now();
    loop {
        if let Some(_s) = c.try_wait().unwrap() {
            let out = c.wait_with_output().unwrap();
            return (
                out.status,
                String::from_utf8_lossy(&out.stdout).into_owned(),
                String::from_utf8_lossy(&out.stderr).into_owned(),
            );
        }
        if t.elapsed() > within {
            let _ = c.kill();
            let out = c.wait_with_output().unwrap();
            panic!(
                "granval did not exit within {within:?}; stderr: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A fake engine that keeps a child of its own: the grandchild is what a kill of the
/// direct child alone would leave running.
const SLEEPS_WITH_CHILD: &str = "echo running; sleep 300 & wait";

fn signal_ends_engine(sig: i32, code: i32, name: &str) {
    let s = Scratch::new();
    s.fake_liggghts(SLEEPS_WITH_CHILD, false);
    let report = s.path("report");
    let mut g = s
        .granval(&[
            "compare",
            CASE,
            "--report",
            report.to_str().unwrap(),
            "--reference-mode",
            "live",
        ])
        .spawn()
        .unwrap();
    let engine = wait_for_engine(&mut g, &["liggghts", "sleep"], Duration::from_secs(60));
    unsafe {
        libc::kill(g.id() as i32, sig);
    }
    let (status, _, err) = finish(g, Duration::from_secs(20));
    assert_all_ended(&engine, Duration::from_secs(5), name);
    assert_eq!(status.code(), Some(code), "{name}: {status}; stderr: {err}");
    let last = err.trim_end().lines().last().unwrap_or("");
    assert!(
        last.starts_with(&format!(
            "granval: {name}: stopped, ended liggghts (session "
        )) && last.ends_with(&format!("; exit {code}")),
        "{name}: {err}"
    );
    assert!(s.tmp_entries().is_empty(), "{name}: {:?}", s.tmp_entries());
}

#[test]
fn sigterm_ends_the_engine_and_its_children_and_exits_143() {
    signal_ends_engine(libc::SIGTERM, 143, "SIGTERM");
}

#[test]
fn sigint_ends_the_engine_and_its_children_and_exits_130() {
    signal_ends_engine(libc::SIGINT, 130, "SIGINT");
}

#[test]
fn sighup_ends_the_engine_and_its_children_and_exits_129() {
    signal_ends_engine(libc::SIGHUP, 129, "SIGHUP");
}

/// granval killed outright runs no handler: the engine's direct child ends by its
/// parent-death signal, and its own child (which that signal does not reach) by the
/// watchdog.
#[test]
fn sigkill_of_granval_ends_the_engine_and_its_children() {
    let s = Scratch::new();
    s.fake_liggghts(SLEEPS_WITH_CHILD, false);
    let report = s.path("report");
    let mut g = s
        .granval(&[
            "compare",
            CASE,
            "--report",
            report.to_str().unwrap(),
            "--reference-mode",
            "live",
        ])
        .spawn()
        .unwrap();
    let engine = wait_for_engine(&mut g, &["liggghts", "sleep"], Duration::from_secs(60));
    unsafe {
        libc::kill(g.id() as i32, libc::SIGKILL);
    }
    let (status, _, _) = finish(g, Duration::from_secs(10));
    assert_eq!(status.signal(), Some(libc::SIGKILL));
    assert_all_ended(&engine, Duration::from_secs(5), "SIGKILL");
}

/// The same with mpirun and two ranks (fake ranks: mpirun itself is real), for SIGTERM
/// and SIGKILL: Open MPI puts each rank in a process group of its own, so ending
/// mpirun's group alone would not reach them.
#[test]
fn signals_end_mpirun_and_both_ranks() {
    if process_on_path("mpirun").is_none() {
        eprintln!("SKIP signals_end_mpirun_and_both_ranks: mpirun is not installed");
        return;
    }
    for (sig, name) in [(libc::SIGTERM, "SIGTERM"), (libc::SIGKILL, "SIGKILL")] {
        let s = Scratch::new();
        s.fake_liggghts("echo running; exec sleep 300", false);
        let report = s.path("report");
        let mut g = s
            .granval(&[
                "compare",
                CASE,
                "--report",
                report.to_str().unwrap(),
                "--reference-mode",
                "live",
                "--np",
                "2",
            ])
            .spawn()
            .unwrap();
        let engine = wait_for_engine(
            &mut g,
            &["mpirun", "sleep", "sleep"],
            Duration::from_secs(60),
        );
        unsafe {
            libc::kill(g.id() as i32, sig);
        }
        let (status, _, err) = finish(g, Duration::from_secs(20));
        if sig == libc::SIGTERM {
            assert_eq!(status.code(), Some(143), "{err}");
        }
        assert_all_ended(&engine, Duration::from_secs(5), name);
    }
}

fn process_on_path(name: &str) -> Option<PathBuf> {
    granval::engines::process::on_path(name)
}

/// A micro case that runs for minutes in LIGGGHTS (1e9 steps of two spheres).
fn long_micro_case(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(common::root().join(CASE)).unwrap();
    let text = text
        .replace("name = \"head-on-e09\"", "name = \"long-head-on\"")
        .replace("duration = 1e-3", "duration = 1e3")
        .replace("output_every = 5", "output_every = 10000000");
    assert!(text.contains("duration = 1e3"));
    let p = dir.join("long.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// The real engine: SIGTERM, then SIGKILL, to granval during a live `compare --np 2`
/// leave no mpirun or LIGGGHTS rank behind.
#[test]
fn live_liggghts_under_mpirun_ends_with_granval() {
    let live = granval::experiments::reference::installed(
        granval::rundata::provenance::EngineKind::Liggghts,
    )
    .is_some();
    if !live || process_on_path("mpirun").is_none() {
        eprintln!(
            "SKIP live_liggghts_under_mpirun_ends_with_granval: LIGGGHTS or mpirun is not installed (the fake-engine tests above still ran)"
        );
        return;
    }
    for (sig, name) in [(libc::SIGTERM, "SIGTERM"), (libc::SIGKILL, "SIGKILL")] {
        let work = tempfile::tempdir().unwrap();
        let case = long_micro_case(work.path());
        let report = work.path().join("report");
        let mut g = common::granval()
            .args([
                "compare",
                case.to_str().unwrap(),
                "--report",
                report.to_str().unwrap(),
                "--reference-mode",
                "live",
                "--np",
                "2",
            ])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let engine = wait_for_engine(
            &mut g,
            &["mpirun", "liggghts", "liggghts"],
            Duration::from_secs(120),
        );
        unsafe {
            libc::kill(g.id() as i32, sig);
        }
        let (status, _, err) = finish(g, Duration::from_secs(20));
        if sig == libc::SIGTERM {
            assert_eq!(status.code(), Some(143), "{err}");
        }
        assert_all_ended(&engine, Duration::from_secs(5), name);
        eprintln!("[live] {name}: mpirun and both LIGGGHTS ranks ended: {engine:?}");
    }
}

/// An interrupted `reference refresh` leaves neither its scratch run directory nor a
/// half-written record.
#[test]
fn interrupted_refresh_removes_its_temporary_directories() {
    let s = Scratch::new();
    s.fake_liggghts(SLEEPS_WITH_CHILD, false);
    let reference = s.path("reference");
    let mut g = s
        .granval(&[
            "reference",
            "refresh",
            "--only",
            CASE,
            "--reference",
            reference.to_str().unwrap(),
        ])
        .spawn()
        .unwrap();
    let engine = wait_for_engine(&mut g, &["liggghts", "sleep"], Duration::from_secs(60));
    let recording = reference.join("micro").join("head-on-e09.recording");
    assert!(
        !s.tmp_entries().is_empty(),
        "the scratch run directory should be in TMPDIR while the engine runs"
    );
    unsafe {
        libc::kill(g.id() as i32, libc::SIGINT);
    }
    let (status, _, err) = finish(g, Duration::from_secs(20));
    assert_all_ended(&engine, Duration::from_secs(5), "SIGINT");
    assert_eq!(status.code(), Some(130), "{err}");
    assert!(err.contains("removed 1 temporary directory;"), "{err}");
    assert!(s.tmp_entries().is_empty(), "{:?}", s.tmp_entries());
    assert!(!recording.exists(), "{} left behind", recording.display());
}

/// A `liggghts` on PATH that hangs on the version probe: an error naming it within
/// seconds (exit 2), not a minute and then a pass against the record.
#[test]
fn a_hanging_liggghts_on_path_is_an_error_not_a_recorded_pass() {
    let s = Scratch::new();
    s.fake_liggghts("exec sleep 300", true);
    let report = s.path("report");
    let t = Instant::now();
    let g = s
        .granval(&["compare", CASE, "--report", report.to_str().unwrap()])
        .spawn()
        .unwrap();
    let (status, out, err) = finish(g, Duration::from_secs(60));
    let took = t.elapsed();
    assert_eq!(status.code(), Some(2), "{out}\n{err}");
    assert!(took < Duration::from_secs(30), "took {took:?}");
    assert!(
        out.contains("did not answer the version probe")
            && out.contains("within 10.0 s: is it LIGGGHTS?")
            && out.contains("does not fall back to the recorded LIGGGHTS reference"),
        "{out}"
    );
    assert!(!out.contains("RECORDED"), "{out}");
    assert!(s.tmp_entries().is_empty(), "{:?}", s.tmp_entries());
}

/// One that answers at once but is not LIGGGHTS 3.x: an error too.
#[test]
fn a_silent_or_wrong_liggghts_on_path_is_an_error() {
    for (body, says) in [
        (
            "exit 0",
            "without a `LIGGGHTS (Version` line; it printed nothing: it is not LIGGGHTS",
        ),
        (
            "echo 'LIGGGHTS (Version LIGGGHTS-PUBLIC 4.1.0, a newer one)'",
            "is LIGGGHTS 4.x",
        ),
        (
            "echo 'no such option' >&2; exit 1",
            "failed the version probe",
        ),
    ] {
        let s = Scratch::new();
        s.fake_liggghts(body, true);
        let report = s.path("report");
        let g = s
            .granval(&["compare", CASE, "--report", report.to_str().unwrap()])
            .spawn()
            .unwrap();
        let (status, out, err) = finish(g, Duration::from_secs(30));
        assert_eq!(status.code(), Some(2), "{body}: {out}\n{err}");
        assert!(out.contains(says), "{body}: {out}");
        assert!(!out.contains("RECORDED"), "{body}: {out}");
    }
}

#[test]
fn engine_timeout_ends_a_run_that_takes_too_long() {
    let s = Scratch::new();
    // Writes all the time (never stalls) and never ends.
    s.fake_liggghts("while :; do echo step; sleep 0.2; done & wait", false);
    let report = s.path("report");
    let t = Instant::now();
    let mut g = s
        .granval(&[
            "compare",
            CASE,
            "--report",
            report.to_str().unwrap(),
            "--reference-mode",
            "live",
            "--engine-timeout",
            "2s",
        ])
        .spawn()
        .unwrap();
    let engine = wait_for_engine(&mut g, &["liggghts"], Duration::from_secs(60));
    let (status, out, err) = finish(g, Duration::from_secs(60));
    assert_eq!(status.code(), Some(2), "{out}\n{err}");
    assert!(t.elapsed() < Duration::from_secs(30));
    assert!(
        out.contains(
            "LIGGGHTS ran for 2.0 s, the limit (--engine-timeout 2.0 s); its processes were ended"
        ),
        "{out}"
    );
    assert_all_ended(&engine, Duration::from_secs(5), "timeout");
}

#[test]
fn engine_stall_ends_a_run_whose_files_stop_growing() {
    let s = Scratch::new();
    s.fake_liggghts("echo start; sleep 1; echo step 0; exec sleep 300", false);
    let report = s.path("report");
    let mut g = s
        .granval(&[
            "compare",
            CASE,
            "--report",
            report.to_str().unwrap(),
            "--reference-mode",
            "live",
            "--engine-stall",
            "3s",
        ])
        .spawn()
        .unwrap();
    let engine = wait_for_engine(&mut g, &["sleep"], Duration::from_secs(60));
    let (status, out, err) = finish(g, Duration::from_secs(60));
    assert_eq!(status.code(), Some(2), "{out}\n{err}");
    assert!(
        out.contains("LIGGGHTS stalled: no file in")
            && out.contains("(the limit: --engine-stall 3.0 s)")
            && out.contains("liggghts.stdout stopped growing at 13 bytes"),
        "{out}"
    );
    assert_all_ended(&engine, Duration::from_secs(5), "stall");
}

/// `--np` above the cores: mpirun's own reason and a remedy, not its closing advice.
#[test]
fn too_many_ranks_show_mpiruns_reason() {
    if process_on_path("mpirun").is_none() {
        eprintln!("SKIP too_many_ranks_show_mpiruns_reason: mpirun is not installed");
        return;
    }
    let cores = std::thread::available_parallelism().unwrap().get();
    let np = (cores + 1).to_string();
    let s = Scratch::new();
    s.fake_liggghts("echo should not run; exit 3", false);
    let report = s.path("report");
    let g = s
        .granval(&[
            "compare",
            CASE,
            "--report",
            report.to_str().unwrap(),
            "--reference-mode",
            "live",
            "--np",
            &np,
        ])
        .spawn()
        .unwrap();
    let (status, out, err) = finish(g, Duration::from_secs(60));
    assert_eq!(status.code(), Some(2), "{out}\n{err}");
    assert!(
        out.contains(&format!(
            "There are not enough slots available in the system to satisfy the {np} slots that were requested by the application:"
        )) && out.contains(&format!(
            "remedy: --np N with N at most the {cores} core(s)"
        )),
        "{out}"
    );
}
