//! A case file's TOML read into its schema, with type errors said in words. serde's
//! "invalid type: floating point `1.5`, expected u64" names a Rust type; a physicist
//! who typed `output_every = 1.5` needs "simulation.output_every: expected a whole
//! number, got 1.5". The mapping is generic (field path from the error's position in
//! the file, expected kind from serde's wording), never per field, so a new field is
//! covered the day it is added. Errors that are not type errors (syntax, unknown or
//! missing fields) keep toml's own message, which already says what is wrong.

use super::error::CaseError;
use std::path::Path;

/// `text` (the file `path`) as `T`, or an error naming the file, the field path, the
/// value as written and, for a type error, the expected kind in words.
pub(crate) fn from_toml<T: serde::de::DeserializeOwned>(
    text: &str,
    path: &Path,
) -> Result<T, CaseError> {
    toml::from_str(text).map_err(|e| CaseError::Parse {
        file: path.to_path_buf(),
        message: in_words(&e, text).unwrap_or_else(|| e.to_string()),
    })
}

/// The plain-language form of a type error (`None`: not a type error, or no position).
fn in_words(e: &toml::de::Error, text: &str) -> Option<String> {
    let msg = e.message();
    let rest = msg
        .strip_prefix("invalid type: ")
        .or_else(|| msg.strip_prefix("invalid value: "))
        .or_else(|| msg.strip_prefix("invalid length "))?;
    let (got, expected) = rest.split_once(", expected ")?;
    let span = e.span()?;
    let written = text.get(span.clone())?.trim();
    let line = text[..span.start].matches('\n').count() + 1;
    let field = field_path(text, span.start).unwrap_or_else(|| "a value".into());
    let shown = if written.contains('\n') || written.len() > 60 {
        kind_of_got(got)
    } else {
        written.to_string()
    };
    let length_note = if msg.starts_with("invalid length ") {
        format!(" ({} entries)", got.trim())
    } else {
        String::new()
    };
    Some(format!(
        "line {line}: {field}: expected {}, got {shown}{length_note}",
        expected_in_words(expected.trim())
    ))
}

/// serde's name of the expected type, in words.
fn expected_in_words(expected: &str) -> String {
    let e = expected.trim_end_matches('.');
    match e {
        "u8" | "u16" | "u32" | "u64" | "u128" | "usize" => {
            "a whole number (0 or more, no decimal point)".into()
        }
        "i8" | "i16" | "i32" | "i64" | "i128" | "isize" => {
            "a whole number (no decimal point)".into()
        }
        "f32" | "f64" => "a number".into(),
        "a boolean" => "true or false".into(),
        "a string" | "a borrowed string" | "a character" => "text in quotes".into(),
        "a sequence" => "a list [..]".into(),
        "a map" => "a table".into(),
        _ => {
            if let Some(n) = e
                .strip_prefix("an array of length ")
                .or_else(|| e.strip_prefix("a tuple of size "))
            {
                format!("a list of {n} values [..]")
            } else if let Some(s) = e.strip_prefix("struct ") {
                format!("a table ({s})")
            } else if e.starts_with("enum ") || e.starts_with("variant ") {
                format!("one of the names the documentation lists ({e})")
            } else {
                e.to_string()
            }
        }
    }
}

/// What serde says it got, in words, when the value as written is too long to show.
fn kind_of_got(got: &str) -> String {
    if got.starts_with("sequence") {
        "a list".into()
    } else if got.starts_with("map") {
        "a table".into()
    } else {
        got.replace('`', "")
    }
}

/// The dotted path (`particles[1].radius`) of the value whose text starts at `pos`, from
/// the spans of the parsed document.
fn field_path(text: &str, pos: usize) -> Option<String> {
    let doc = toml::de::DeTable::parse(text).ok()?;
    let mut path = Vec::new();
    if find_in_table(doc.get_ref(), pos, &mut path) {
        Some(join(&path))
    } else {
        None
    }
}

enum Step {
    Key(String),
    Index(usize),
}

fn join(path: &[Step]) -> String {
    let mut s = String::new();
    for p in path {
        match p {
            Step::Key(k) => {
                if !s.is_empty() {
                    s.push('.');
                }
                s.push_str(k);
            }
            Step::Index(i) => s.push_str(&format!("[{i}]")),
        }
    }
    s
}

fn find_in_table(t: &toml::de::DeTable<'_>, pos: usize, path: &mut Vec<Step>) -> bool {
    for (k, v) in t.iter() {
        path.push(Step::Key(k.get_ref().to_string()));
        if find_in_value(v.get_ref(), v.span(), pos, path) {
            return true;
        }
        path.pop();
    }
    false
}

/// Leaves are matched by their span; containers are searched whatever their span says
/// (a `[table]` header's span does not cover its keys).
fn find_in_value(
    v: &toml::de::DeValue<'_>,
    span: std::ops::Range<usize>,
    pos: usize,
    path: &mut Vec<Step>,
) -> bool {
    match v {
        toml::de::DeValue::Table(t) => find_in_table(t, pos, path) || span.start == pos,
        toml::de::DeValue::Array(a) => {
            for (i, item) in a.iter().enumerate() {
                path.push(Step::Index(i));
                if find_in_value(item.get_ref(), item.span(), pos, path) {
                    return true;
                }
                path.pop();
            }
            span.contains(&pos)
        }
        _ => span.contains(&pos),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    #[allow(dead_code)]
    struct Doc {
        sim: Sim,
        #[serde(default)]
        items: Vec<Item>,
    }
    #[derive(Debug, serde::Deserialize)]
    #[allow(dead_code)]
    struct Sim {
        every: u64,
        dt: f64,
        #[serde(default)]
        flag: bool,
        #[serde(default)]
        name: String,
        #[serde(default)]
        g: [f64; 3],
    }
    #[derive(Debug, serde::Deserialize)]
    #[allow(dead_code)]
    struct Item {
        r: f64,
    }

    fn err(text: &str) -> String {
        from_toml::<Doc>(text, Path::new("c.toml"))
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn a_fraction_where_a_whole_number_belongs_is_named_in_words() {
        let m = err("[sim]\nevery = 1.5\ndt = 1e-6\n");
        assert_eq!(
            m,
            "c.toml: line 2: sim.every: expected a whole number (0 or more, no decimal point), got 1.5"
        );
    }

    #[test]
    fn kinds_in_words_with_path_and_value() {
        assert!(
            err("[sim]\nevery = 1\ndt = \"fast\"\n")
                .contains("sim.dt: expected a number, got \"fast\"")
        );
        assert!(
            err("[sim]\nevery = 1\ndt = 1.0\nflag = 1\n")
                .contains("sim.flag: expected true or false, got 1")
        );
        assert!(
            err("[sim]\nevery = 1\ndt = 1.0\nname = 3\n")
                .contains("sim.name: expected text in quotes, got 3")
        );
        assert!(
            err("[sim]\nevery = -2\ndt = 1.0\n")
                .contains("sim.every: expected a whole number (0 or more")
        );
        let m = err("[sim]\nevery = 1\ndt = 1.0\ng = [1.0, 2.0]\n");
        assert!(m.contains("sim.g: expected a list of 3 values"), "{m}");
        let m = err("[sim]\nevery = 1\ndt = 1.0\n[[items]]\nr = 1.0\n[[items]]\nr = true\n");
        assert!(
            m.contains("line 7: items[1].r: expected a number, got true"),
            "{m}"
        );
    }

    #[test]
    fn other_errors_keep_tomls_message() {
        let m = err("[sim]\nevery = 1\n");
        assert!(m.contains("missing field `dt`"), "{m}");
        let m = err("[sim\n");
        assert!(m.contains("TOML parse error"), "{m}");
    }
}
