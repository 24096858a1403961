//! Progress bars for long runs; hidden when not wanted (tests, CI logs, pipes).

use indicatif::{ProgressBar, ProgressStyle};

pub(crate) fn bar(show: bool, len: u64, label: &str) -> ProgressBar {
    if !show {
        return ProgressBar::hidden();
    }
    let b = ProgressBar::new(len);
    b.set_style(
        ProgressStyle::with_template(
            "{prefix:>9} [{bar:40}] {pos}/{len} steps  {per_sec}  eta {eta}",
        )
        .expect("static template")
        .progress_chars("=> "),
    );
    b.set_prefix(label.to_string());
    b
}

/// A phase of unknown length (bed settling, compaction): its elapsed time and the
/// message the phase sets (time reached, kinetic energy), so a user watching a settle
/// that takes an hour sees whether the energy is still falling.
pub(crate) fn status(show: bool, label: &str) -> ProgressBar {
    if !show {
        return ProgressBar::hidden();
    }
    let b = ProgressBar::new_spinner();
    b.set_style(
        ProgressStyle::with_template("{prefix:>9} {spinner} {elapsed_precise}  {msg}")
            .expect("static template"),
    );
    b.set_prefix(label.to_string());
    b.enable_steady_tick(std::time::Duration::from_millis(500));
    b
}
