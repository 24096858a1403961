//! Text shared by every input deck granval writes (LIGGGHTS and LAMMPS): numbers that
//! read back exactly, wrapped comments, the deck header, and the canonical form a deck's
//! fingerprint is taken from.
//!
//! - **Numbers** ([`num`]) are Rust's shortest round-trip representation, in plain
//!   notation (`0.000005`, `2500`, `210000000000`) between 1e-7 and 1e16 and in
//!   exponent notation (`1e-9`) outside; either form parses back (Rust's `parse`, C's
//!   `strtod`/`atof`, both correctly rounded) to exactly the f64 it was printed from, so
//!   a deck carries no rounding (tested on random bit patterns).
//! - **Comments** are whole lines starting with `# `. LAMMPS and LIGGGHTS join a line
//!   ending in `&` with the next one *before* they strip comments, so no comment line may
//!   end in `&`; [`comment`] makes sure, and free text (case names, descriptions) goes
//!   through [`safe`].
//! - **Fingerprints** ([`canonical`]) ignore comments and blank lines and collapse
//!   whitespace: the date in a deck's header, or a better comment, never changes the
//!   fingerprint a recorded reference is sealed to; every command and number does.

use crate::rundata::provenance::{Sha256, now_utc};
use std::fmt::Write as _;

/// Width of wrapped comment lines.
const WIDTH: usize = 88;

/// Shortest round-trip representation of `x`: plain notation for 1e-7 <= |x| < 1e16
/// (and 0), exponent notation outside. Parses back to exactly `x`.
pub fn num(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 || (1e-7..1e16).contains(&a) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// Space-separated [`num`]s.
pub(crate) fn nums(xs: impl IntoIterator<Item = f64>) -> String {
    xs.into_iter().map(num).collect::<Vec<_>>().join(" ")
}

/// `x` in plain notation with 4 significant digits (for comments only, never for a
/// value the engine reads); exponent notation outside 1e-9..1e12.
pub fn approx(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let digits = (3 - x.abs().log10().floor() as i32).max(0) as usize;
    let a = x.abs();
    if (1e-9..1e12).contains(&a) {
        let s = format!("{x:.digits$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{x:.3e}")
    }
}

/// Free text made harmless in a comment: no line breaks, no `&` (line continuation in
/// LIGGGHTS and LAMMPS), no `$` (variable substitution), no quotes.
pub(crate) fn safe(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_alphanumeric() || " _-.:,;/()[]+=<>*%'`^~|!?@".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Appends `text` as comment lines (`# ...`), wrapped at 88 columns; `\n` in `text`
/// starts a new line, an empty paragraph gives a bare `#`.
pub fn comment(s: &mut String, text: &str) {
    for para in text.split('\n') {
        let mut line = String::from("#");
        for word in para.split_whitespace() {
            if line.len() > 1 && line.len() + 1 + word.len() > WIDTH {
                push_line(s, &line);
                line = String::from("#  ");
            }
            line.push(' ');
            line.push_str(word);
        }
        push_line(s, &line);
    }
}

fn push_line(s: &mut String, line: &str) {
    let line = line.trim_end();
    // A trailing `&` would continue the comment into the next (command) line.
    let line = if line.ends_with('&') {
        format!("{line} .")
    } else {
        line.to_string()
    };
    s.push_str(&line);
    s.push('\n');
}

/// A block of the deck: a blank line, then the comment saying what follows and where
/// it comes from.
pub(crate) fn block(s: &mut String, text: &str) {
    s.push('\n');
    comment(s, text);
}

/// What the header of a deck says.
#[derive(Debug, Clone, Default)]
pub struct Header {
    /// First line, e.g. "granval micro case `head-on`: LIGGGHTS 3.8 input deck".
    pub title: String,
    /// Paragraphs: the case's description, what the run measures, units, how to run it.
    pub paragraphs: Vec<String>,
}

/// The header: title, `written by granval VERSION on DATE`, the paragraphs. The date
/// makes every deck text different, which is why fingerprints ignore comments.
pub(crate) fn write_header(s: &mut String, h: &Header) {
    comment(s, &h.title);
    let _ = writeln!(
        s,
        "# written by granval {} on {}",
        env!("CARGO_PKG_VERSION"),
        now_utc()
    );
    for p in &h.paragraphs {
        s.push_str("#\n");
        comment(s, p);
    }
}

/// The part of a line LAMMPS/LIGGGHTS execute: up to a `#` outside quotes.
fn uncommented(line: &str) -> &str {
    let mut quote: Option<char> = None;
    for (i, c) in line.char_indices() {
        match (quote, c) {
            (None, '"' | '\'') => quote = Some(c),
            (Some(q), c) if c == q => quote = None,
            (None, '#') => return &line[..i],
            _ => {}
        }
    }
    line
}

/// What an engine reads from an input text: lines ending in `&` joined with the next
/// (LAMMPS and LIGGGHTS do this before they strip comments), comments and blank lines
/// dropped, whitespace collapsed, one command per line. A deck that splits a long
/// command over `&` lines has the canonical form of the one-line command.
pub fn canonical(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut pending = String::new();
    for line in text.lines() {
        let trimmed = line.trim_end();
        if let Some(head) = trimmed.strip_suffix('&') {
            pending.push_str(head);
            pending.push(' ');
            continue;
        }
        pending.push_str(line);
        let words: Vec<&str> = uncommented(&pending).split_whitespace().collect();
        if !words.is_empty() {
            out.push_str(&words.join(" "));
            out.push('\n');
        }
        pending.clear();
    }
    let words: Vec<&str> = uncommented(&pending).split_whitespace().collect();
    if !words.is_empty() {
        out.push_str(&words.join(" "));
        out.push('\n');
    }
    out
}

/// sha256 of the canonical form of input texts (deck, data file, mesh), in order: the
/// fingerprint of a reference engine's input.
pub fn fingerprint(texts: &[&str]) -> Sha256 {
    let mut all = String::new();
    for t in texts {
        all.push_str(&canonical(t));
        // Keeps ("a", "b c") and ("a b", "c") apart.
        all.push('\u{1e}');
    }
    Sha256::of(all.as_bytes())
}

/// Whether two input texts give the engine the same commands: [`canonical`] forms equal
/// token by token, numbers compared as f64 (`5e-1` and `0.5` are the same input).
pub fn same_input(a: &str, b: &str) -> bool {
    let (a, b) = (canonical(a), canonical(b));
    let (la, lb): (Vec<&str>, Vec<&str>) = (a.lines().collect(), b.lines().collect());
    la.len() == lb.len()
        && la.iter().zip(&lb).all(|(x, y)| {
            let (tx, ty): (Vec<&str>, Vec<&str>) = (
                x.split_whitespace().collect(),
                y.split_whitespace().collect(),
            );
            tx.len() == ty.len()
                && tx.iter().zip(&ty).all(|(p, q)| {
                    p == q
                        || matches!((p.parse::<f64>(), q.parse::<f64>()),
                            (Ok(u), Ok(v)) if u.to_bits() == v.to_bits())
                })
        })
}

/// Errors unless the input file `name` in `dir` gives the engine the same commands as
/// `expected` ([`same_input`]): a run brought back for `granval analyze` must be of the
/// deck granval writes for the case today, or its numbers would be compared against
/// another experiment. `skip_first`: the first line is a title the engine skips (a
/// `read_data` file). The error names the file and the first command that differs.
pub fn check_same_input(
    dir: &std::path::Path,
    name: &str,
    expected: &str,
    skip_first: bool,
) -> anyhow::Result<()> {
    let path = dir.join(name);
    // What the file should hold is `expected` up to comments and number notation: four
    // times its size (and 1 MiB for a small one) is generous, and bounds the read.
    let max = 4 * expected.len() as u64 + crate::rundata::fsio::MIB;
    let text = crate::rundata::fsio::read_to_string(&path, max, &format!("the input {name}"))
        .map_err(|e| {
            anyhow::anyhow!("{e} (a deck directory holds every input `granval deck` wrote)")
        })?;
    let body = |t: &str| -> String {
        if skip_first {
            t.split_once('\n').map(|(_, b)| b).unwrap_or("").to_string()
        } else {
            t.to_string()
        }
    };
    let (now, want) = (body(&text), body(expected));
    if same_input(&now, &want) {
        return Ok(());
    }
    let (a, b) = (canonical(&now), canonical(&want));
    let (la, lb): (Vec<&str>, Vec<&str>) = (a.lines().collect(), b.lines().collect());
    let k = (0..la.len().max(lb.len()))
        .find(|&k| match (la.get(k), lb.get(k)) {
            (Some(x), Some(y)) => !same_input(x, y),
            _ => true,
        })
        .unwrap_or(0);
    anyhow::bail!(
        "{}: not the input granval writes for this case: command {} is `{}`, expected `{}` (comments and number notation aside). Analyse only runs of unedited `granval deck` directories; to run changed physics, change the case file and write the deck again",
        path.display(),
        k + 1,
        la.get(k).unwrap_or(&"<end of file>"),
        lb.get(k).unwrap_or(&"<end of file>")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every number a deck prints parses back to the very same f64 (bit for bit), in
    /// plain and in exponent notation, over random bit patterns and the edge cases.
    #[test]
    fn numbers_round_trip_exactly() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            // splitmix64
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        };
        let mut xs: Vec<f64> = vec![
            0.0,
            -0.0,
            1.0,
            0.1,
            0.2,
            0.3,
            9.81,
            5e-6,
            1e-7,
            f64::from_bits(1e-7f64.to_bits() - 1),
            1e16,
            9999999999999998.0,
            2.1e11,
            981.0000000000001,
            2.837006706885775e-5,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            -f64::MAX,
        ];
        for _ in 0..200_000 {
            let x = f64::from_bits(next());
            if x.is_finite() {
                xs.push(x);
            }
        }
        // Values of the size decks hold (lengths, times, moduli), uniformly in log.
        for _ in 0..200_000 {
            let u = (next() >> 11) as f64 / (1u64 << 53) as f64;
            let x = 10f64.powf(-9.0 + 22.0 * u);
            xs.push(x);
            xs.push(-x);
        }
        for x in xs {
            let s = num(x);
            let back: f64 = s.parse().unwrap();
            assert_eq!(back.to_bits(), x.to_bits(), "{x:e} printed as {s}");
            let a = x.abs();
            if a != 0.0 && (1e-7..1e16).contains(&a) {
                assert!(!s.contains('e'), "{x:e} printed as {s}");
            }
        }
        assert_eq!(num(5e-6), "0.000005");
        assert_eq!(num(2500.0), "2500");
        assert_eq!(num(-9.81), "-9.81");
        assert_eq!(num(0.0), "0");
        assert_eq!(num(2.1e11), "210000000000");
        assert_eq!(num(1e-9), "1e-9");
        assert_eq!(num(1e20), "1e20");
    }

    #[test]
    fn comments_wrap_and_never_continue_a_line() {
        let mut s = String::new();
        comment(&mut s, &"word ".repeat(40));
        assert!(s.lines().all(|l| l.starts_with('#') && l.len() <= WIDTH));
        assert!(s.lines().count() > 1);
        let mut s = String::new();
        comment(&mut s, "a & b &");
        assert!(!s.trim_end().ends_with('&'), "{s}");
        assert_eq!(safe("a$b&c\"d\ne"), "a_b_c_d_e");
        assert_eq!(approx(0.04283), "0.04283");
        assert_eq!(approx(1234.5678), "1235");
        assert_eq!(approx(1.0), "1");
        assert_eq!(approx(5.0e-6), "0.000005");
        assert_eq!(approx(2.7366e-5), "0.00002737");
    }

    #[test]
    fn fingerprints_ignore_comments_and_layout_only() {
        let a = "# header written on 2026-01-01\nunits si\n\n# block\nfix a all print \"x # y\" file f # note\n";
        let b = "# other date\nunits   si\nfix a all print \"x # y\" file f\n";
        assert_eq!(canonical(a), canonical(b));
        assert_eq!(fingerprint(&[a]), fingerprint(&[b]));
        assert_ne!(fingerprint(&[a]), fingerprint(&["units cgs\n"]));
        assert_ne!(fingerprint(&["a", "b c"]), fingerprint(&["a b", "c"]));
        assert!(same_input("timestep 5e-6\n", "# x\ntimestep 0.000005\n"));
        assert!(!same_input("timestep 5e-6\n", "timestep 0.0000051\n"));
        assert!(!same_input("run 5\n", "run 5\nrun 6\n"));
        // A command split over `&` lines is the one-line command.
        assert_eq!(
            canonical("pair_style hybrid &\n  gran/hooke 1e3 1 &\n  gran/hooke 2e3 1\nrun 1\n"),
            "pair_style hybrid gran/hooke 1e3 1 gran/hooke 2e3 1\nrun 1\n"
        );
        assert!(same_input(
            "pair_style hybrid gran/hooke 1000 1\n",
            "pair_style hybrid &\n gran/hooke 1e3 1\n"
        ));
    }
}
