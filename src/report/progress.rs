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
