//! Every repository path the documentation names exists: README.md and docs/*.md are
//! scanned for relative Markdown link targets and for words that look like repository
//! paths (starting with `src/`, `tests/`, `cases/`, `docs/`, `reference/`, `benches/`,
//! `examples/` or `.ci/`, in prose, code spans or code blocks). A path with `*` must match
//! at least one file. Placeholders (`cases/suites/NAME.toml`, `reference/<kind>/<case>/`)
//! are not paths and are skipped. A file moved or renamed without its documentation
//! fails here, naming the page, the line and the path.

use std::path::{Path, PathBuf};

/// Where repository paths start; a word starting otherwise is not checked.
const PREFIXES: [&str; 8] = [
    "src/",
    "tests/",
    "cases/",
    "docs/",
    "reference/",
    "benches/",
    "examples/",
    ".ci/",
];

/// One path a page names: its line (1-based) and the path relative to the repository
/// root.
#[derive(Debug, Clone, PartialEq)]
struct Mention {
    line: usize,
    path: String,
}

/// The word as a path: leading Markdown punctuation removed, cut at the first character
/// no path here contains (`docs/stress.md's`, `src/main.rs:12`, `(docs/x.md),`), trailing
/// full stops dropped.
fn clean(word: &str) -> &str {
    let w = word.trim_start_matches(['(', '[', '`', '"', '\'', '*', '_', '|']);
    let end = w
        .find(['`', '"', '\'', ')', ']', ',', ';', ':', '|', '(', '['])
        .unwrap_or(w.len());
    w[..end].trim_end_matches('.')
}

/// A placeholder rather than a path: `<kind>`, `{a,b}`, `...`, or a component in capitals
/// (`NAME.toml`, `DIR`, `bed-K`, `snapshot_KK_seal.json`) other than `README`.
fn placeholder(path: &str) -> bool {
    if path.contains(['<', '>', '{', '}', '$']) || path.contains("...") {
        return true;
    }
    path.split('/').any(|component| {
        let stem = component.split('.').next().unwrap_or("");
        stem.split(['-', '_']).any(|part| {
            !part.is_empty() && part != "README" && part.chars().all(|c| c.is_ascii_uppercase())
        })
    })
}

/// Joins `base` (a directory relative to the root) and a relative link target, resolving
/// `.` and `..`.
fn join_relative(base: &Path, target: &str) -> String {
    let mut parts: Vec<String> = base
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    for part in target.split('/') {
        match part {
            "" | "." => {}
            ".." => {
                parts.pop();
            }
            p => parts.push(p.to_string()),
        }
    }
    let mut joined = parts.join("/");
    if target.ends_with('/') {
        joined.push('/');
    }
    joined
}

/// Every path `text` (the page at `page`, relative to the root) names, in order.
fn mentions(page: &Path, text: &str) -> Vec<Mention> {
    let dir = page.parent().unwrap_or(Path::new(""));
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line_no = i + 1;
        // Link targets: `](target)` or `](target "title")`.
        let mut rest = line;
        while let Some(at) = rest.find("](") {
            let after = &rest[at + 2..];
            let end = after.find(')').unwrap_or(after.len());
            let target = after[..end].split_whitespace().next().unwrap_or("");
            let target = target.split('#').next().unwrap_or("");
            let external = target.contains("://") || target.starts_with("mailto:");
            if !target.is_empty() && !external && !placeholder(target) {
                out.push(Mention {
                    line: line_no,
                    path: join_relative(dir, target),
                });
            }
            rest = &after[end..];
        }
        // Words that look like repository paths.
        for word in line.split_whitespace() {
            let path = clean(word);
            if PREFIXES.iter().any(|p| path.starts_with(p)) && !placeholder(path) {
                out.push(Mention {
                    line: line_no,
                    path: path.to_string(),
                });
            }
        }
    }
    out
}

/// Whether `name` matches the `*` pattern `pattern` (one path component).
fn wildcard(pattern: &str, name: &str) -> bool {
    let parts: Vec<&str> = pattern.split('*').collect();
    if parts.len() == 1 {
        return pattern == name;
    }
    let (first, last) = (parts[0], parts[parts.len() - 1]);
    if !name.starts_with(first) || name.len() < first.len() + last.len() {
        return false;
    }
    let mut rest = &name[first.len()..name.len() - last.len()];
    if !name.ends_with(last) {
        return false;
    }
    for middle in &parts[1..parts.len() - 1] {
        match rest.find(middle) {
            Some(at) => rest = &rest[at + middle.len()..],
            None => return false,
        }
    }
    true
}

/// Whether something under `dir` matches the components `pattern` (`**`: any depth).
fn matches(dir: &Path, pattern: &[&str]) -> bool {
    let Some((first, rest)) = pattern.split_first() else {
        return dir.exists();
    };
    if *first == "**" {
        if matches(dir, rest) {
            return true;
        }
        return children(dir)
            .iter()
            .any(|c| c.is_dir() && matches(c, pattern));
    }
    if !first.contains('*') {
        return matches(&dir.join(first), rest);
    }
    children(dir).iter().any(|c| {
        c.file_name()
            .is_some_and(|n| wildcard(first, &n.to_string_lossy()))
            && matches(c, rest)
    })
}

fn children(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .map(|entries| entries.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default()
}

/// Whether `path` (relative to `root`) exists, or with `*` matches at least one file.
fn exists(root: &Path, path: &str) -> bool {
    let components: Vec<&str> = path.split('/').filter(|c| !c.is_empty()).collect();
    if path.ends_with('/') {
        return matches(root, &components) && {
            // A trailing slash promises a directory (checked when there is no wildcard).
            path.contains('*') || root.join(path).is_dir()
        };
    }
    matches(root, &components)
}

/// `page:line: path` for every path of `text` (the page `page`) that does not exist.
fn missing(root: &Path, page: &Path, text: &str) -> Vec<String> {
    mentions(page, text)
        .into_iter()
        .filter(|m| !exists(root, &m.path))
        .map(|m| format!("{}:{}: {}", page.display(), m.line, m.path))
        .collect()
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// README.md and every docs/*.md.
fn pages() -> Vec<PathBuf> {
    let mut pages = vec![PathBuf::from("README.md")];
    let mut docs: Vec<PathBuf> = children(&root().join("docs"))
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .map(|p| Path::new("docs").join(p.file_name().unwrap()))
        .collect();
    docs.sort();
    pages.extend(docs);
    pages
}

#[test]
fn every_path_in_readme_and_docs_exists() {
    let root = root();
    let pages = pages();
    assert!(pages.len() > 5, "too few pages found: {pages:?}");
    let mut checked = 0;
    let mut stale = Vec::new();
    for page in &pages {
        let text = std::fs::read_to_string(root.join(page)).unwrap();
        checked += mentions(page, &text).len();
        stale.extend(missing(&root, page, &text));
    }
    // The extractor must have found the pages' paths at all (README alone names dozens).
    assert!(checked > 100, "only {checked} paths found in {pages:?}");
    assert!(
        stale.is_empty(),
        "{} of {checked} repository paths in the documentation do not exist:\n{}",
        stale.len(),
        stale.join("\n")
    );
}

/// Negative control: a page naming files that do not exist (a moved module, a dead
/// link, a glob that matches nothing) is reported, line by line.
#[test]
fn a_page_with_stale_paths_is_reported() {
    let page = "# Sample\n\
                The engine is in `src/dem/contact.rs` (moved).\n\
                See [the cases](no-such-page.md) and [stress](stress.md#rule-5).\n\
                Run `granval compare cases/micro/no-such-case.toml` or tests/impact2d_fig2.rs.\n\
                Every `cases/micro/*.nope` file.\n";
    let got = missing(&root(), Path::new("docs/sample.md"), page);
    let want = [
        "docs/sample.md:2: src/dem/contact.rs",
        "docs/sample.md:3: docs/no-such-page.md",
        "docs/sample.md:4: cases/micro/no-such-case.toml",
        "docs/sample.md:4: tests/impact2d_fig2.rs",
        "docs/sample.md:5: cases/micro/*.nope",
    ];
    assert_eq!(got, want);
}

/// Positive control: existing files, links relative to the page, globs that match,
/// placeholders and user output are not reported.
#[test]
fn a_page_with_only_existing_paths_reports_nothing() {
    let page = "See [architecture](architecture.md#layers), [the README](../README.md),\n\
                `src/lib.rs`, (docs/stress.md), `cases/micro/*.toml`, `reference/**/seal.json`.\n\
                Write to `out/micro`, `cases/suites/NAME.toml`, `reference/<kind>/<case>/`,\n\
                `DIR/bed-K/force.csv` and [the web](https://example.org/x.md).\n";
    let root = root();
    let got = missing(&root, Path::new("docs/sample.md"), page);
    assert!(got.is_empty(), "{got:?}");
    // ...and it did look at them.
    let seen: Vec<String> = mentions(Path::new("docs/sample.md"), page)
        .into_iter()
        .map(|m| m.path)
        .collect();
    for p in [
        "docs/architecture.md",
        "README.md",
        "src/lib.rs",
        "docs/stress.md",
        "cases/micro/*.toml",
        "reference/**/seal.json",
    ] {
        assert!(seen.iter().any(|s| s == p), "{p} not extracted: {seen:?}");
    }
}
