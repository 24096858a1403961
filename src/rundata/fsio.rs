//! Reading and writing files that granval does not control the content of.
//!
//! Every file a user or a record supplies (a case or suite file, a seal, a provenance
//! record, a summary, an engine's dump or log) is read through this module:
//!
//! - it must be a **regular file** after following symlinks, checked on its metadata
//!   *before* it is opened: a FIFO would block the read forever, `/dev/zero` or
//!   `/dev/urandom` never end, a directory is not data. Each is refused with an error
//!   naming the file and what it is;
//! - it is read with a **bound** on its size, named in the error with the file's size and
//!   what the file should hold, so a wrong file (a 2.5 GB dump where a case file was
//!   expected) is an error instead of an allocation that ends in an abort;
//! - files parsed line by line ([`open`]) also have a bound on one line
//!   ([`MAX_LINE_BYTES`]): a line-based parser holds one line at a time, so a file
//!   without newlines must not become one line of gigabytes.
//!
//! Writes of results go through [`write_atomic`]: a temporary file in the same
//! directory, renamed over the target when complete, so a full disk or a crash never
//! leaves a truncated file under the final name, and a write error names the path.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

pub(crate) const KIB: u64 = 1 << 10;
pub(crate) const MIB: u64 = 1 << 20;
pub(crate) const GIB: u64 = 1 << 30;

/// Case files and suite files: text written by people, kilobytes each (the largest
/// case of the release suite is under 10 KiB); 16 MiB leaves three orders of magnitude.
pub const MAX_CASE_FILE: u64 = 16 * MIB;

/// JSON records granval writes and reads back: `seal.json` (at most tens of KiB),
/// `provenance.json`, `summary.json`, MALT points, a prepared bed (the largest, a
/// penetration bed of the release suite, is 3 MB).
pub(crate) const MAX_RECORD_JSON: u64 = 256 * MIB;

/// Small bookkeeping files (the output-directory marker, its lock).
pub(crate) const MAX_SMALL: u64 = 64 * KIB;

/// The longest line a line-based parser accepts. Dump, log, data and CSV lines are at
/// most a few hundred bytes; a LIGGGHTS log echoes deck lines, which granval writes
/// well under 1 KiB.
pub(crate) const MAX_LINE_BYTES: u64 = MIB;

/// The bound on an engine's output file (dump, log, data file, CSV): half the physical
/// memory, clamped to [1 GiB, 64 GiB] (4 GiB when /proc/meminfo cannot be read).
///
/// Why not a bound per file from the run's size: the parsers are line-based and hold
/// what they parse, whose size is of the order of the text (a dump line of ~100 bytes
/// becomes a particle state of 80 bytes), so the text size bounds the memory a parse
/// can take; half the machine's memory is the largest bound that cannot exhaust it,
/// and it is far above any output a run within the resource limits writes per file
/// (the release suite's largest recorded file is 7.6 MB). The per-line bound above
/// keeps a file without newlines from being accumulated at all.
pub(crate) fn max_engine_output() -> u64 {
    static CAP: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    *CAP.get_or_init(|| {
        let total = std::fs::read_to_string("/proc/meminfo").ok().and_then(|t| {
            let line = t.lines().find(|l| l.starts_with("MemTotal:"))?;
            line.split_whitespace().nth(1)?.parse::<u64>().ok()
        });
        match total {
            Some(kib) => (kib * KIB / 2).clamp(GIB, 64 * GIB),
            None => 4 * GIB,
        }
    })
}

/// Why a file could not be read.
#[derive(Debug)]
pub struct ReadError {
    pub path: PathBuf,
    pub problem: Problem,
}

#[derive(Debug)]
pub enum Problem {
    /// Not a regular file after following symlinks: what it is instead.
    NotRegular {
        kind: &'static str,
        what: String,
    },
    /// Larger than the bound.
    TooLarge {
        size: u64,
        max: u64,
        what: String,
    },
    Io(std::io::Error),
}

impl ReadError {
    /// The reason without the path (for errors that name the file themselves).
    pub fn reason(&self) -> String {
        match &self.problem {
            Problem::NotRegular { kind, what } => format!(
                "not a regular file but {kind}; {what} is read from a regular file (a FIFO could block the read forever, a device never end it)"
            ),
            Problem::TooLarge { size, max, what } => format!(
                "{} is larger than the {} {what} may hold here; this is not such a file",
                human(*size),
                human(*max)
            ),
            Problem::Io(e) => format!("cannot read: {e}"),
        }
    }

    /// The file does not exist (some callers treat a missing optional file as absent).
    pub(crate) fn is_not_found(&self) -> bool {
        matches!(&self.problem, Problem::Io(e) if e.kind() == std::io::ErrorKind::NotFound)
    }
}

impl std::fmt::Display for ReadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.reason())
    }
}

impl std::error::Error for ReadError {}

/// `n` bytes, with the binary unit a person reads at a glance.
pub(crate) fn human(n: u64) -> String {
    let (v, unit) = if n >= GIB {
        (n as f64 / GIB as f64, "GiB")
    } else if n >= MIB {
        (n as f64 / MIB as f64, "MiB")
    } else if n >= KIB {
        (n as f64 / KIB as f64, "KiB")
    } else {
        return format!("{n} bytes");
    };
    format!("{n} bytes ({v:.1} {unit})")
}

fn kind_of(ft: &std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if ft.is_dir() {
        "a directory"
    } else if ft.is_fifo() {
        "a FIFO (named pipe)"
    } else if ft.is_char_device() {
        "a character device"
    } else if ft.is_block_device() {
        "a block device"
    } else if ft.is_socket() {
        "a socket"
    } else {
        "not a file"
    }
}

/// Checks that `path` is a regular file (after symlinks) of at most `max` bytes, without
/// opening it; returns its size.
pub(crate) fn check_regular(path: &Path, max: u64, what: &str) -> Result<u64, ReadError> {
    let err = |problem| ReadError {
        path: path.to_path_buf(),
        problem,
    };
    let md = std::fs::metadata(path).map_err(|e| err(Problem::Io(e)))?;
    if !md.is_file() {
        return Err(err(Problem::NotRegular {
            kind: kind_of(&md.file_type()),
            what: what.into(),
        }));
    }
    if md.len() > max {
        return Err(err(Problem::TooLarge {
            size: md.len(),
            max,
            what: what.into(),
        }));
    }
    Ok(md.len())
}

/// A file opened for reading after [`check_regular`], that refuses to deliver more than
/// its bound (a file that grows while it is read) or a line longer than its line bound.
#[derive(Debug)]
pub struct Bounded {
    file: std::fs::File,
    path: PathBuf,
    what: String,
    max: u64,
    read: u64,
    max_line: Option<u64>,
    line: u64,
}

impl Bounded {
    fn fail(&self, why: String) -> std::io::Error {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("{}: {why} ({})", self.path.display(), self.what),
        )
    }
}

impl Read for Bounded {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.file.read(buf)?;
        self.read += n as u64;
        if self.read > self.max {
            return Err(self.fail(format!(
                "more than {} while being read: the file grew past its bound",
                human(self.max)
            )));
        }
        if let Some(max_line) = self.max_line {
            let mut segments = buf[..n].split(|&b| b == b'\n');
            if let Some(first) = segments.next() {
                self.line += first.len() as u64;
            }
            for s in segments {
                if self.line > max_line {
                    break;
                }
                self.line = s.len() as u64;
            }
            if self.line > max_line {
                return Err(self.fail(format!(
                    "a line longer than {}: not a line-based text file",
                    human(max_line)
                )));
            }
        }
        Ok(n)
    }
}

fn open_with(
    path: &Path,
    max: u64,
    max_line: Option<u64>,
    what: &str,
) -> Result<Bounded, ReadError> {
    check_regular(path, max, what)?;
    let err = |problem| ReadError {
        path: path.to_path_buf(),
        problem,
    };
    let file = std::fs::File::open(path).map_err(|e| err(Problem::Io(e)))?;
    // Replaced between the check and the open: check what was opened.
    let md = file.metadata().map_err(|e| err(Problem::Io(e)))?;
    if !md.is_file() {
        return Err(err(Problem::NotRegular {
            kind: kind_of(&md.file_type()),
            what: what.into(),
        }));
    }
    Ok(Bounded {
        file,
        path: path.to_path_buf(),
        what: what.into(),
        max,
        read: 0,
        max_line,
        line: 0,
    })
}

/// Opens a text file for a line-based parser: a regular file of at most `max` bytes,
/// no line longer than [`MAX_LINE_BYTES`].
pub fn open(path: &Path, max: u64, what: &str) -> Result<Bounded, ReadError> {
    open_with(path, max, Some(MAX_LINE_BYTES), what)
}

/// Opens an engine's output (a dump, log, data file or CSV) for a line-based parser,
/// bounded by [`max_engine_output`] and [`MAX_LINE_BYTES`]; `what` says what it holds.
pub(crate) fn open_engine_output(path: &Path, what: &str) -> Result<Bounded, ReadError> {
    open(path, max_engine_output(), what)
}

/// Opens a file for a reader that is not line-based (a hash): a regular file of at most
/// `max` bytes, lines not bounded.
pub(crate) fn open_unlined(path: &Path, max: u64, what: &str) -> Result<Bounded, ReadError> {
    open_with(path, max, None, what)
}

/// The whole file: a regular file of at most `max` bytes.
pub fn read(path: &Path, max: u64, what: &str) -> Result<Vec<u8>, ReadError> {
    let mut f = open_with(path, max, None, what)?;
    let mut out = Vec::new();
    f.read_to_end(&mut out).map_err(|e| ReadError {
        path: path.to_path_buf(),
        problem: Problem::Io(e),
    })?;
    Ok(out)
}

/// The whole file as UTF-8 text: a regular file of at most `max` bytes.
pub fn read_to_string(path: &Path, max: u64, what: &str) -> Result<String, ReadError> {
    let bytes = read(path, max, what)?;
    String::from_utf8(bytes).map_err(|e| ReadError {
        path: path.to_path_buf(),
        problem: Problem::Io(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text ({what}): {e}"),
        )),
    })
}

/// Writes `bytes` to `path` so that `path` is either its old content or all of the new:
/// a temporary file beside it, flushed to disk, renamed over it. Any error (a full disk,
/// a directory where the file should be) names `path` and leaves no temporary behind.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    use std::sync::atomic::{AtomicU64, Ordering};
    static SEQ: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .map_or_else(|| "output".into(), |n| n.to_string_lossy().into_owned());
    let tmp = path.with_file_name(format!(
        ".{name}.tmp-{}-{}",
        std::process::id(),
        SEQ.fetch_add(1, Ordering::Relaxed)
    ));
    let result = (|| -> std::io::Result<()> {
        let mut f = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        anyhow::anyhow!("cannot write {}: {e}", path.display())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_regular_file_within_its_bound_reads() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("a.toml");
        std::fs::write(&p, "x = 1\n").unwrap();
        assert_eq!(read_to_string(&p, 6, "a case file").unwrap(), "x = 1\n");
        let e = read_to_string(&p, 5, "a case file").unwrap_err();
        let m = e.to_string();
        assert!(
            m.contains("a.toml") && m.contains("6 bytes") && m.contains("5 bytes"),
            "{m}"
        );
        assert!(m.contains("a case file"), "{m}");
    }

    /// /dev/zero never ends and a FIFO blocks its reader: both are refused on their
    /// metadata, before any read, so this test returns at once.
    #[test]
    fn devices_fifos_and_directories_are_refused_before_reading() {
        let e = read(Path::new("/dev/zero"), GIB, "a seal").unwrap_err();
        assert!(e.to_string().contains("character device"), "{e}");
        let d = tempfile::tempdir().unwrap();
        let e = read(d.path(), GIB, "a seal").unwrap_err();
        assert!(e.to_string().contains("a directory"), "{e}");
        let fifo = d.path().join("fifo");
        let st = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(st.success());
        let t = std::time::Instant::now();
        let e = open(&fifo, GIB, "a dump").unwrap_err();
        assert!(e.to_string().contains("FIFO"), "{e}");
        assert!(t.elapsed().as_secs() < 5);
        // Through a symlink, too.
        let link = d.path().join("zero");
        std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
        let e = check_regular(&link, GIB, "a dump").unwrap_err();
        assert!(e.to_string().contains("character device"), "{e}");
        assert!(
            read(&d.path().join("missing"), 1, "x")
                .unwrap_err()
                .is_not_found()
        );
    }

    #[test]
    fn a_line_longer_than_the_bound_is_an_error_not_an_allocation() {
        use std::io::BufRead;
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("dump");
        let mut text = "short\n".repeat(3);
        text.push_str(&"x".repeat(MAX_LINE_BYTES as usize + 10));
        std::fs::write(&p, &text).unwrap();
        let r = std::io::BufReader::new(open(&p, GIB, "a dump").unwrap());
        // The error repeats on every later read: take the lines up to the first error.
        let lines: Vec<_> = r.lines().take(4).collect();
        assert!(lines[..3].iter().all(|l| l.as_ref().unwrap() == "short"));
        let e = lines[3].as_ref().unwrap_err().to_string();
        assert!(
            e.contains("a line longer than") && e.contains("dump"),
            "{e}"
        );
        // Many lines of exactly the bound are fine.
        let ok = format!("{}\n", "y".repeat(MAX_LINE_BYTES as usize)).repeat(3);
        std::fs::write(&p, &ok).unwrap();
        let r = std::io::BufReader::new(open(&p, GIB, "a dump").unwrap());
        assert_eq!(r.lines().map(Result::unwrap).count(), 3);
    }

    /// The error path of a write: the target's directory is a file. The error names
    /// the target and no temporary is left.
    #[test]
    fn a_failed_write_names_the_path_and_leaves_nothing() {
        let d = tempfile::tempdir().unwrap();
        let blocker = d.path().join("report");
        std::fs::write(&blocker, "a file where a directory is expected").unwrap();
        let target = blocker.join("report.json");
        let e = write_atomic(&target, b"{}").unwrap_err().to_string();
        assert!(e.contains(&target.display().to_string()), "{e}");
        let left: Vec<_> = std::fs::read_dir(d.path()).unwrap().collect();
        assert_eq!(left.len(), 1);
        // A directory where the file should be: the old content stays, no temporary.
        let dir_target = d.path().join("sub");
        std::fs::create_dir(&dir_target).unwrap();
        let e = write_atomic(&dir_target, b"{}").unwrap_err().to_string();
        assert!(e.contains("sub"), "{e}");
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 2);
        let ok = d.path().join("ok.json");
        write_atomic(&ok, b"{\"a\": 1}").unwrap();
        assert_eq!(std::fs::read(&ok).unwrap(), b"{\"a\": 1}");
    }
}
