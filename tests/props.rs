//! Property: whatever is done to a valid case file — a number turned into NaN, inf, 0, a
//! negative or a huge value, a field removed or duplicated, a type swapped — `granval
//! compare` against the case's sealed recorded reference ends with exit 0, 1 or 2,
//! never a panic, an abort or unreadable output, and never reports `passed: true` for
//! a case whose physics differs from the recorded one.
//!
//! Bounded: 40 mutations of two small micro cases, each a subprocess of about 0.2 s.

mod common;

use granval::case::AnyCase;
use proptest::prelude::*;
use std::path::Path;

const CASES: [&str; 2] = [
    "cases/micro/head-on-e05.toml",
    "cases/micro/plane-normal.toml",
];

#[derive(Debug, Clone)]
enum Mutation {
    Number(f64),
    Remove,
    Duplicate,
    Retype(&'static str),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        prop::sample::select(vec![
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.0,
            -1.0,
            -1e-3,
            1e300,
            1e-300,
            1e12,
        ])
        .prop_map(Mutation::Number),
        Just(Mutation::Remove),
        Just(Mutation::Duplicate),
        prop::sample::select(vec!["\"text\"", "true", "[1, 2]", "{ a = 1 }"])
            .prop_map(Mutation::Retype),
    ]
}

/// Lines of the file that hold `key = value` (not comments, not table headers).
fn value_lines(text: &str) -> Vec<usize> {
    text.lines()
        .enumerate()
        .filter(|(_, l)| {
            let t = l.trim_start();
            !t.starts_with('#') && !t.starts_with('[') && t.contains(" = ")
        })
        .map(|(i, _)| i)
        .collect()
}

fn apply(text: &str, line: usize, m: &Mutation) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let l = lines[line];
    let (key, value) = l.split_once(" = ").unwrap();
    let new: Vec<String> = match m {
        Mutation::Remove => vec![],
        Mutation::Duplicate => vec![l.to_string(), l.to_string()],
        Mutation::Retype(v) => vec![format!("{key} = {v}")],
        Mutation::Number(x) => {
            let lit = if x.is_nan() {
                "nan".to_string()
            } else if x.is_infinite() {
                if *x > 0.0 {
                    "inf".into()
                } else {
                    "-inf".into()
                }
            } else {
                format!("{x:e}")
            };
            // Replace the first number of the value (a scalar, or one vector component).
            let v = value.trim();
            let start = v.find(|c: char| c.is_ascii_digit() || c == '-' || c == '.');
            match start {
                Some(s) => {
                    let end = v[s..]
                        .find(|c: char| !(c.is_ascii_alphanumeric() || "+-._".contains(c)))
                        .map_or(v.len(), |e| s + e);
                    vec![format!("{key} = {}{lit}{}", &v[..s], &v[end..])]
                }
                None => vec![format!("{key} = {lit}")],
            }
        }
    };
    let mut out: Vec<String> = lines[..line].iter().map(|s| s.to_string()).collect();
    out.extend(new);
    out.extend(lines[line + 1..].iter().map(|s| s.to_string()));
    out.join("\n") + "\n"
}

fn canonical(text: &str, path: &Path) -> Option<String> {
    match AnyCase::from_toml_str(text, path).ok()? {
        AnyCase::Micro(c) => Some(c.canonical_hash().to_string()),
        _ => None,
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 40, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn mutated_cases_never_pass_against_the_unmutated_reference(
        which in 0usize..CASES.len(),
        pick in any::<prop::sample::Index>(),
        m in mutation(),
    ) {
        let rel = CASES[which];
        let original = std::fs::read_to_string(common::root().join(rel)).unwrap();
        let lines = value_lines(&original);
        let line = lines[pick.index(lines.len())];
        let mutated = apply(&original, line, &m);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(Path::new(rel).file_name().unwrap());
        std::fs::write(&path, &mutated).unwrap();
        let out = dir.path().join("report");
        let o = common::granval()
            .env_remove("GRANVAL_REQUIRE_LIVE")
            .args(["compare"])
            .arg(&path)
            .args(["--reference-mode", "recorded", "--report"])
            .arg(&out)
            .output()
            .unwrap();
        let code = o.status.code();
        let stdout = String::from_utf8(o.stdout.clone());
        let stderr = String::from_utf8(o.stderr.clone());
        prop_assert!(stdout.is_ok() && stderr.is_ok(), "non-UTF-8 output for {m:?} on line {line}");
        let stderr = stderr.unwrap();
        prop_assert!(matches!(code, Some(0..=2)), "exit {code:?} for {m:?} on line {line} of {rel}:\n{stderr}");
        prop_assert!(!stderr.contains("panicked"), "panic for {m:?} on line {line} of {rel}:\n{stderr}");
        if let Ok(report) = std::fs::read_to_string(out.join("report.json")) {
            let v: serde_json::Value = serde_json::from_str(&report).unwrap();
            if v["passed"] == true {
                let a = canonical(&original, Path::new(rel));
                let b = canonical(&mutated, &path);
                prop_assert!(a.is_some() && a == b,
                    "PASSED with changed physics: {m:?} on line {line} of {rel}: {:?}",
                    mutated.lines().nth(line));
            }
        }
    }
}
