//! Every number and switch of every case file either enters the case's seal (its
//! canonical hash, to which recorded references and run seals are bound) or is listed
//! below as not physics, with the reason.
//!
//! The canonical hashes are hand-written views of the case structures (`src/case/`), so
//! a physics field left out of a view would never be sealed: a record of other physics
//! would then pass as this case's. This test finds such a field without trusting the
//! views: for every `key = value` line of every case file under `cases/` it changes the
//! value (a float times 1.37, an integer plus one, a boolean flipped, each component of
//! an array in turn; a string to every other value that key takes in some case file:
//! another contact model, diameter distribution, shape), loads the case again and asks
//! whether the hash moved. A change
//! the loader refuses proves nothing and is skipped; one it accepts must move the hash,
//! unless its key is in [`NOT_SEALED`].

use granval::case::AnyCase;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

mod common;

/// Keys (`table.key`; `*` for every key of the table) a case may change without
/// changing its runs, with the reason. Anything else that loads must move the hash.
const NOT_SEALED: &[(&str, &str)] = &[
    ("case.name", "the case's name"),
    ("case.description", "words"),
    // What is computed from the runs, not the runs themselves.
    (
        "analysis.*",
        "reduction of the runs: fit ranges, bins, snapshot depths, windows",
    ),
    ("compare.*", "tolerances of the checks"),
    ("claim.*", "the paper's claim a run is judged by"),
    ("published.*", "a paper's value the runs are compared with"),
    (
        "published_phi.*",
        "a paper's value the runs are compared with",
    ),
    (
        "negative_control.*",
        "a control perturbs the native runs only; the reference record it is judged against is the case's own",
    ),
    (
        "quasi_static.*",
        "a second native run at another speed; no reference record depends on it",
    ),
];

/// Changes that do move the physics' inputs but not the physics, file by file.
const SAME_PHYSICS: &[(&str, &str, &str)] = &[
    (
        "cases/release/feng-fig3g-psi-dense.toml",
        "penetration_interactions.types",
        "[[penetration_interactions]] overrides pairs of [[interactions]]; its (1, 2) entry turned into (2, 2) overrides (2, 2) with the values it already has there, and (1, 2) keeps the [[interactions]] values, which are the same as the override's: the pair table is unchanged",
    ),
    (
        "cases/release/frictionless-ci-random.toml",
        "penetration_interactions.types",
        "as for feng-fig3g-psi-dense.toml: its (1, 2) override (frictionless) repeats the [[interactions]] (1, 2) and (2, 2) values, so turned into (2, 2) it leaves the pair table unchanged",
    ),
];

fn allowed(section: &str, key: &str) -> bool {
    let full = format!("{section}.{key}");
    NOT_SEALED
        .iter()
        .any(|(k, _)| *k == full || k.strip_suffix(".*").is_some_and(|t| t == section))
}

fn hash(text: &str, path: &Path) -> Option<String> {
    Some(match AnyCase::from_toml_str(text, path).ok()? {
        AnyCase::Micro(c) => c.canonical_hash().to_string(),
        AnyCase::Penetration(c) => c.canonical_hash().to_string(),
        AnyCase::Impact2d(c) => c.canonical_hash().to_string(),
        AnyCase::Triaxial(c) => c.canonical_hash().to_string(),
    })
}

fn case_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            if p.file_name().is_some_and(|n| n != "suites") {
                case_files(&p, out);
            }
        } else if p.extension().is_some_and(|x| x == "toml") {
            out.push(p);
        }
    }
}

/// Byte ranges of the numbers and booleans of a TOML value, outside strings.
fn tokens(value: &str) -> Vec<(usize, usize)> {
    let b = value.as_bytes();
    let mut out = Vec::new();
    let (mut i, mut in_str) = (0, false);
    while i < b.len() {
        let c = b[i] as char;
        if c == '"' {
            in_str = !in_str;
            i += 1;
            continue;
        }
        let prev_word = i > 0 && ((b[i - 1] as char).is_ascii_alphanumeric() || b[i - 1] == b'_');
        let starts_number = c.is_ascii_digit()
            || ((c == '-' || c == '+' || c == '.')
                && b.get(i + 1).is_some_and(|n| n.is_ascii_digit()));
        if !in_str && !prev_word && starts_number {
            let mut j = i + 1;
            while j < b.len() && ((b[j] as char).is_ascii_alphanumeric() || b"._+-".contains(&b[j]))
            {
                // A sign only right after an exponent.
                if (b[j] == b'+' || b[j] == b'-') && !matches!(b[j - 1], b'e' | b'E') {
                    break;
                }
                j += 1;
            }
            out.push((i, j));
            i = j;
            continue;
        }
        if !in_str && !prev_word {
            for w in ["true", "false"] {
                let end = i + w.len();
                if value[i..].starts_with(w)
                    && !b
                        .get(end)
                        .is_some_and(|n| n.is_ascii_alphanumeric() || *n == b'_')
                {
                    out.push((i, end));
                }
            }
        }
        i += 1;
    }
    out
}

/// The token changed: float x 1.37, integer + 1, boolean flipped; `None` if not a value.
fn changed(tok: &str) -> Option<String> {
    match tok {
        "true" => return Some("false".into()),
        "false" => return Some("true".into()),
        _ => {}
    }
    let clean = tok.replace('_', "");
    if clean.contains(['.', 'e', 'E']) {
        let x: f64 = clean.parse().ok()?;
        Some(format!("{:e}", if x == 0.0 { 0.37 } else { x * 1.37 }))
    } else {
        let n: i64 = clean.parse().ok()?;
        Some((n + 1).to_string())
    }
}

/// The one quoted string of a value (`"cdt"`), if the value is just that.
fn string_value(value: &str) -> Option<&str> {
    let v = value.trim();
    let inner = v.strip_prefix('"')?.strip_suffix('"')?;
    (!inner.contains('"')).then_some(inner)
}

/// Every value line of `text` (with the table it is in) and every variant of the file
/// with one token of that line changed, or its string replaced by another value the
/// same key has in some case file (`vocabulary`: `table.key` -> values).
fn variants(
    text: &str,
    vocabulary: &BTreeMap<String, BTreeSet<String>>,
) -> Vec<(String, String, String)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut section = String::new();
    let mut out = Vec::new();
    for (n, line) in lines.iter().enumerate() {
        let t = line.trim_start();
        if t.starts_with('[') {
            section = t.trim_matches(|c| c == '[' || c == ']').trim().to_string();
            continue;
        }
        if t.starts_with('#') {
            continue;
        }
        let Some((key, value)) = line.split_once(" = ") else {
            continue;
        };
        let value = value.split(" #").next().unwrap_or(value);
        let edit = |new_value: String| {
            let mut edited: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
            edited[n] = format!("{key} = {new_value}");
            edited.join("\n") + "\n"
        };
        if let Some(own) = string_value(value) {
            // Names and words of the listed keys would only add listed changes.
            if allowed(&section, key.trim()) {
                continue;
            }
            let full = format!("{section}.{}", key.trim());
            for other in vocabulary.get(&full).into_iter().flatten() {
                if other != own {
                    out.push((
                        section.clone(),
                        key.trim().to_string(),
                        edit(format!("\"{other}\"")),
                    ));
                }
            }
            continue;
        }
        for (a, b) in tokens(value) {
            let Some(new) = changed(&value[a..b]) else {
                continue;
            };
            let mut edited: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
            edited[n] = format!("{key} = {}{new}{}", &value[..a], &value[b..]);
            out.push((
                section.clone(),
                key.trim().to_string(),
                edited.join("\n") + "\n",
            ));
        }
    }
    out
}

/// What a scan of every case file under `cases/` found.
struct Scan {
    files: usize,
    kinds: BTreeSet<&'static str>,
    tried: usize,
    moved: usize,
    refused: usize,
    listed: usize,
    /// `table.key` -> the files where an accepted change left the seal unchanged.
    unsealed: BTreeMap<String, BTreeSet<String>>,
}

/// Every change of every case file, judged by the seal `seal` (the real canonical hash,
/// or a deliberately blind one in the negative control).
fn scan(seal: impl Fn(&str, &Path) -> Option<String>) -> Scan {
    let mut files = Vec::new();
    case_files(&common::root().join("cases"), &mut files);
    files.sort();
    let mut vocabulary: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for f in &files {
        let mut section = String::new();
        for line in std::fs::read_to_string(f).unwrap().lines() {
            let t = line.trim_start();
            if t.starts_with('[') {
                section = t.trim_matches(|c| c == '[' || c == ']').trim().to_string();
            } else if let Some((key, value)) = line.split_once(" = ")
                && !t.starts_with('#')
                && let Some(v) = string_value(value.split(" #").next().unwrap_or(value))
            {
                vocabulary
                    .entry(format!("{section}.{}", key.trim()))
                    .or_default()
                    .insert(v.to_string());
            }
        }
    }
    let mut s = Scan {
        files: files.len(),
        kinds: BTreeSet::new(),
        tried: 0,
        moved: 0,
        refused: 0,
        listed: 0,
        unsealed: BTreeMap::new(),
    };
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        let Some(base) = seal(&text, f) else {
            continue; // not a case file (an exploratory draft that no longer loads)
        };
        s.kinds
            .insert(match AnyCase::from_toml_str(&text, f).unwrap() {
                AnyCase::Micro(_) => "micro",
                AnyCase::Penetration(_) => "penetration",
                AnyCase::Impact2d(_) => "impact2d",
                AnyCase::Triaxial(_) => "triaxial",
            });
        for (section, key, edited) in variants(&text, &vocabulary) {
            s.tried += 1;
            let full = format!("{section}.{key}");
            match seal(&edited, f) {
                None => s.refused += 1,
                Some(h) if h != base => s.moved += 1,
                Some(_)
                    if allowed(&section, &key)
                        || SAME_PHYSICS
                            .iter()
                            .any(|(file, k, _)| f.ends_with(file) && *k == full) =>
                {
                    s.listed += 1
                }
                Some(_) => {
                    let rel = f.strip_prefix(common::root()).unwrap();
                    s.unsealed
                        .entry(full)
                        .or_default()
                        .insert(rel.display().to_string());
                }
            }
        }
    }
    s
}

#[test]
fn every_accepted_change_of_a_case_moves_its_seal_or_is_listed_as_not_physics() {
    let s = scan(hash);
    eprintln!(
        "{} case files ({:?}): {} changes, {} moved the seal, {} refused by the loader, {} of keys listed as not physics",
        s.files, s.kinds, s.tried, s.moved, s.refused, s.listed
    );
    // The test must have something to judge: every kind, and most changes moving a seal.
    assert_eq!(s.kinds.len(), 4, "{:?}", s.kinds);
    assert!(
        s.moved > 1000 && s.moved > s.listed,
        "{} moved, {} listed",
        s.moved,
        s.listed
    );
    assert!(
        s.unsealed.is_empty(),
        "values the loader accepts that leave the seal unchanged (a physics field missing from a canonical_hash view, or a key to list in NOT_SEALED with its reason):\n{}",
        s.unsealed
            .iter()
            .map(|(k, fs)| format!(
                "  {k}: {} file(s), e.g. {}",
                fs.len(),
                fs.iter().next().unwrap()
            ))
            .collect::<Vec<_>>()
            .join("\n")
    );
}

/// The test's own negative control: a seal that is blind to sliding friction (the hash
/// of the case with every `friction` set to one value) is caught, friction named in the
/// files that set it; and the tokeniser finds the numbers of inline tables and arrays,
/// not those inside strings.
#[test]
fn a_seal_blind_to_friction_is_caught() {
    let blind = |text: &str, path: &Path| {
        let same: String = text
            .lines()
            .map(|l| match l.split_once(" = ") {
                Some((k, _)) if k.trim() == "friction" => format!("{k} = 0.5\n"),
                _ => format!("{l}\n"),
            })
            .collect();
        hash(&same, path)
    };
    let s = scan(blind);
    for key in ["interactions.friction", "penetration_interactions.friction"] {
        assert!(
            s.unsealed.get(key).is_some_and(|f| !f.is_empty()),
            "{key} not caught: {:?}",
            s.unsealed.keys().collect::<Vec<_>>()
        );
    }
    // Nothing outside the pair tables (a `types` change there may now give equal pairs).
    assert!(
        s.unsealed.keys().all(|k| k.contains("interactions.")),
        "{:?}",
        s.unsealed.keys().collect::<Vec<_>>()
    );
    let v = r#"{ kind = "constant", value = 2.0e-3 }"#;
    let t: Vec<&str> = tokens(v).into_iter().map(|(a, b)| &v[a..b]).collect();
    assert_eq!(t, ["2.0e-3"]);
    let v = r#"[1, 2] "x1" true -3.5e+2"#;
    let t: Vec<&str> = tokens(v).into_iter().map(|(a, b)| &v[a..b]).collect();
    assert_eq!(t, ["1", "2", "true", "-3.5e+2"]);
}
