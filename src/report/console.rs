//! Standard output that a closed reader cannot crash. `println!` panics when stdout is
//! a pipe whose reader has gone (`granval check --suite micro | head -1`): a backtrace
//! and exit 101 after the work is done. Everything granval prints to stdout goes through
//! [`outln!`](crate::outln) instead: a broken pipe stops the printing quietly (the reader
//! wanted no more; the run goes on, its report files are written and its exit code is
//! the verdict's), and any other write error is kept for [`failure`], which the binary
//! turns into exit 2 naming standard output.
//!
//! Why not restore SIGPIPE's default action at start: the process would then die at the
//! first write after the reader left, mid-run, without releasing its output directory's
//! lock or writing its report, and its exit status would be a signal instead of the
//! verdict.

use std::io::Write;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

static STOPPED: AtomicBool = AtomicBool::new(false);
static FAILURE: Mutex<Option<String>> = Mutex::new(None);

/// Writes `args` to stdout unless an earlier write failed.
pub fn print(args: std::fmt::Arguments) {
    if STOPPED.load(Ordering::Relaxed) {
        return;
    }
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_fmt(args).and_then(|()| out.flush()) {
        STOPPED.store(true, Ordering::Relaxed);
        if e.kind() != std::io::ErrorKind::BrokenPipe {
            let mut f = FAILURE.lock().unwrap_or_else(|p| p.into_inner());
            f.get_or_insert_with(|| e.to_string());
        }
    }
}

/// A write to stdout that failed for another reason than a closed reader (a full disk
/// under a redirection), if any.
pub fn failure() -> Option<String> {
    FAILURE.lock().unwrap_or_else(|p| p.into_inner()).clone()
}

/// `print!` that a closed stdout cannot turn into a panic ([`print`]).
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::report::console::print(format_args!($($arg)*))
    };
}

/// `println!` that a closed stdout cannot turn into a panic ([`print`]).
#[macro_export]
macro_rules! outln {
    () => {
        $crate::report::console::print(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::report::console::print(format_args!("{}\n", format_args!($($arg)*)))
    };
}
