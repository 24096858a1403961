//! How report text is made safe and readable in every format granval writes: Markdown
//! table cells that GitHub- and GitLab-flavoured Markdown keep in their column, XML
//! that every parser accepts (an engine's crash output may hold terminal escape codes),
//! and numbers as a reader expects them (counts as integers, a unit where the metric
//! has one, "n/a" with the reason instead of NaN).

use crate::compare::{Check, Status};

/// `s` as the text of one GFM table cell that renders back to `s` (line breaks become
/// spaces; control characters are shown as `\xNN`). GFM splits a row at every
/// unescaped `|`, even inside code spans, so `max |dx| / r_min` would shift every cell
/// after it: pipes, and the characters that would start emphasis, code, links or HTML,
/// are backslash-escaped (CommonMark 0.31 section 2.4; GFM section 4.10 for `\|`).
pub(crate) fn md_cell(s: &str) -> String {
    let s = visible(s);
    let chars: Vec<char> = s.chars().collect();
    let mut out = String::with_capacity(s.len() + 8);
    for (i, &ch) in chars.iter().enumerate() {
        // An underscore between two letters or digits (`r_min`, `K_phi`) cannot open
        // or close emphasis (CommonMark 6.2): left as written, the raw file stays
        // readable.
        let intraword = |k: Option<usize>| {
            k.and_then(|k| chars.get(k))
                .is_some_and(|c| c.is_alphanumeric())
        };
        match ch {
            '\n' | '\r' | '\t' => out.push(' '),
            '_' if intraword(i.checked_sub(1)) && intraword(Some(i + 1)) => out.push('_'),
            '\\' | '|' | '*' | '_' | '`' | '[' | ']' | '<' | '>' | '~' | '&' => {
                out.push('\\');
                out.push(ch);
            }
            c => out.push(c),
        }
    }
    // A cell starting with these would not start a block inside a table, but leading
    // or trailing spaces are trimmed by the parser: keep what the reader sees.
    out.trim().to_string()
}

/// Control characters (other than tab and line breaks) as `\xNN`: an engine's output
/// copied into a detail may hold ANSI escapes or NUL bytes, which XML 1.0 forbids and a
/// terminal would interpret.
pub(crate) fn visible(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '\t' | '\n' | '\r' => out.push(ch),
            c if (c as u32) < 0x20 || c == '\u{7f}' || c == '\u{fffe}' || c == '\u{ffff}' => {
                out.push_str(&format!("\\x{:02x}", c as u32));
            }
            c => out.push(c),
        }
    }
    out
}

/// `s` escaped for XML 1.0 text and attribute values, control characters made
/// [`visible`] (XML 1.0 section 2.2 allows only tab, LF, CR below U+0020); `attribute`
/// also keeps line breaks as character references, which attribute-value normalisation
/// would otherwise turn into spaces.
pub fn xml(s: &str, attribute: bool) -> String {
    let mut out = String::with_capacity(s.len() + 16);
    for ch in visible(s).chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\n' if attribute => out.push_str("&#10;"),
            '\r' => out.push_str("&#13;"),
            '\t' if attribute => out.push_str("&#9;"),
            c => out.push(c),
        }
    }
    out
}

pub use crate::numerics::fmt::number;

/// The unit a metric's value carries, when the metric names one (`(deg)`, `(rad)`,
/// `(s)`, `/ d`...): shown next to the value and tolerance. Ratios have none.
pub fn unit(metric: &str) -> Option<&'static str> {
    let m = metric.to_ascii_lowercase();
    if m.contains("(deg") || m.contains("deg)") || m.contains("deg;") {
        Some("deg")
    } else if m.contains("(rad)") {
        Some("rad")
    } else if m.ends_with("(s)") {
        Some("s")
    } else if m.starts_with("output frames") {
        Some("frames")
    } else if m.starts_with("fdr points") {
        Some("points")
    } else if m.starts_with("gates that did not fail") || m.starts_with("the wrong physics passed")
    {
        Some("gates")
    } else {
        None
    }
}

/// Why a check has no value, in words.
fn missing(c: &Check) -> &'static str {
    match c.status {
        Status::Error => "n/a (the run failed)",
        Status::NotCompared => "n/a (not compared)",
        Status::Inconclusive => "n/a (no estimate)",
        Status::Pass | Status::Fail => "n/a (not a number)",
    }
}

/// The value column of a check: its number and unit, or "n/a (reason)".
pub fn value(c: &Check) -> String {
    if c.value.is_nan() {
        return missing(c).into();
    }
    with_unit(c.value, unit(&c.metric))
}

/// The tolerance column: "-" where the check has none to show (an error, a gate that
/// was not compared: the constructors put 0 there).
pub fn tolerance(c: &Check) -> String {
    if matches!(c.status, Status::Error | Status::NotCompared) || c.tolerance.is_nan() {
        return "-".into();
    }
    with_unit(c.tolerance, unit(&c.metric))
}

fn with_unit(x: f64, unit: Option<&str>) -> String {
    match unit {
        Some(u) => format!("{} {u}", number(x)),
        None => number(x),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare::Gate;

    #[test]
    fn values_carry_units_and_reasons() {
        let c = Check::at_least(
            "c",
            Gate::Coverage,
            "output frames after step 0",
            150.0,
            10.0,
            "",
        );
        assert_eq!(
            (value(&c), tolerance(&c)),
            ("150 frames".into(), "10 frames".into())
        );
        let e = Check::error("engine", "exit 1");
        assert_eq!(
            (value(&e), tolerance(&e)),
            ("n/a (the run failed)".into(), "-".into())
        );
        let n = Check::not_compared("k", Gate::KPhi, "one bed");
        assert_eq!(value(&n), "n/a (not compared)");
        let d = Check::at_most("p", Gate::Phi, "|phi_test - phi_ref| (deg)", 0.25, 1.0, "");
        assert_eq!(value(&d), "0.25 deg");
    }

    #[test]
    fn control_characters_become_visible() {
        assert_eq!(visible("a\u{1b}[31mb\0"), "a\\x1b[31mb\\x00");
        assert_eq!(
            xml("<a & \"b\">\n", true),
            "&lt;a &amp; &quot;b&quot;&gt;&#10;"
        );
        assert_eq!(md_cell("max |dx| / r_min"), "max \\|dx\\| / r_min");
        assert_eq!(md_cell("_a_ *b*"), "\\_a\\_ \\*b\\*");
    }
}
