//! The layering of docs/architecture.md, enforced: every `crate::` path in src/ may only
//! point to its own layer or one below, and no two modules import each other (directly
//! or around a cycle).
//!
//! Layers, bottom to top: numerics, rundata, case, physics, engines, analysis, compare,
//! report, experiments (+ the top-level `bench`), and the binary (main.rs).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const LAYERS: [&str; 9] = [
    "numerics",
    "rundata",
    "case",
    "physics",
    "engines",
    "analysis",
    "compare",
    "report",
    "experiments",
];

fn rank(top: &str) -> Option<usize> {
    if top == "bench" {
        return Some(8);
    }
    LAYERS.iter().position(|l| *l == top)
}

fn src() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// Module path of a source file: src/a/b/mod.rs -> ["a", "b"], src/a/c.rs -> ["a", "c"].
fn module_of(p: &Path) -> Vec<String> {
    let rel = p.strip_prefix(src()).unwrap();
    let mut parts: Vec<String> = rel
        .iter()
        .map(|s| s.to_string_lossy().trim_end_matches(".rs").to_string())
        .collect();
    if parts
        .last()
        .is_some_and(|l| l == "mod" || l == "lib" || l == "main")
    {
        parts.pop();
    }
    parts
}

/// Code without comments and string literals (so doc links and messages do not count).
fn code(text: &str) -> String {
    let mut out = String::new();
    for line in text.lines() {
        let t = line.trim_start();
        if t.starts_with("//") {
            continue;
        }
        let mut in_str = false;
        let mut prev = ' ';
        for c in line.chars() {
            if c == '"' && prev != '\\' {
                in_str = !in_str;
            } else if !in_str {
                out.push(c);
            }
            prev = c;
        }
        out.push('\n');
    }
    out
}

/// `crate::a::b::...` and `super::...` references of a file, as module paths (the
/// longest prefix that is a module of the crate).
fn references(p: &Path, modules: &BTreeSet<Vec<String>>) -> BTreeSet<Vec<String>> {
    let text = code(&std::fs::read_to_string(p).unwrap());
    let me = module_of(p);
    let is_mod_file = p.file_name().is_some_and(|f| f == "mod.rs");
    let mut out = BTreeSet::new();
    let bytes: Vec<char> = text.chars().collect();
    let s: String = bytes.iter().collect();
    let mut resolve = |path: Vec<String>| {
        let mut best = None;
        for k in (1..=path.len()).rev() {
            if modules.contains(&path[..k].to_vec()) {
                best = Some(path[..k].to_vec());
                break;
            }
        }
        if let Some(b) = best
            && b != me
        {
            out.insert(b);
        }
    };
    let ident = |rest: &str| -> Vec<String> {
        let mut parts = Vec::new();
        for seg in rest.split("::") {
            let seg: String = seg
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            if seg.is_empty() {
                break;
            }
            parts.push(seg);
        }
        parts
    };
    for (i, _) in s.match_indices("crate::") {
        if i > 0 && s[..i].ends_with('$') {
            continue; // `$crate::` in macros
        }
        resolve(ident(&s[i + 7..]));
    }
    for (i, _) in s.match_indices("super::") {
        if i > 0 && s[..i].ends_with("super::") {
            continue;
        }
        let mut base = me.clone();
        let mut rest = &s[i..];
        while let Some(r) = rest.strip_prefix("super::") {
            if !is_mod_file || base.len() > me.len() - 1 {
                base.pop();
            }
            rest = r;
            if !rest.starts_with("super::") {
                break;
            }
        }
        // `use super::*` and friends inside `mod tests` refer to the file's own module.
        if rest.starts_with('*')
            || rest.starts_with('{') && base.len() + 1 == me.len() && !is_mod_file
        {
            continue;
        }
        let mut path = base;
        path.extend(ident(rest));
        resolve(path);
    }
    out
}

/// Every source file of src/ (lib.rs and main.rs excepted) with the modules it refers to.
fn import_graph() -> Vec<(PathBuf, Vec<String>, BTreeSet<Vec<String>>)> {
    let mut all = Vec::new();
    files(&src(), &mut all);
    let modules: BTreeSet<Vec<String>> = all.iter().map(|p| module_of(p)).collect();
    all.iter()
        .filter(|p| !module_of(p).is_empty())
        .map(|p| (p.clone(), module_of(p), references(p, &modules)))
        .collect()
}

/// The top-level modules each layer may import (docs/architecture.md, "knows nothing
/// of"): a layer below it is not enough. Analysis computes observables from run data
/// and knows no engine and no physics; comparisons judge observables and know neither;
/// reports render checks and know no engine, physics or experiment.
const ALLOWED: &[(&str, &[&str])] = &[
    ("numerics", &[]),
    ("rundata", &["numerics"]),
    ("case", &["numerics", "rundata"]),
    ("physics", &["numerics", "rundata", "case"]),
    ("engines", &["numerics", "rundata", "case", "physics"]),
    ("analysis", &["numerics", "rundata", "case"]),
    ("compare", &["numerics", "rundata", "case", "analysis"]),
    (
        "report",
        &["numerics", "rundata", "case", "analysis", "compare"],
    ),
    (
        "experiments",
        &[
            "numerics", "rundata", "case", "physics", "engines", "analysis", "compare", "report",
            "bench",
        ],
    ),
    (
        "bench",
        &[
            "numerics",
            "rundata",
            "case",
            "physics",
            "engines",
            "experiments",
        ],
    ),
];

/// The edges of `graph` (module -> the modules it refers to) between top-level modules
/// that [`ALLOWED`] does not list, one line each.
fn forbidden_edges<'a>(
    graph: impl IntoIterator<Item = (&'a [String], &'a BTreeSet<Vec<String>>)>,
) -> Vec<String> {
    let mut out = Vec::new();
    for (me, refs) in graph {
        let allowed = ALLOWED
            .iter()
            .find(|(m, _)| *m == me[0])
            .unwrap_or_else(|| panic!("top-level module {} is not in ALLOWED", me[0]))
            .1;
        for r in refs {
            if r[0] != me[0] && !allowed.contains(&r[0].as_str()) {
                out.push(format!("{} -> {}", me.join("::"), r.join("::")));
            }
        }
    }
    out
}

#[test]
fn every_layer_imports_only_what_it_may_know() {
    let graph = import_graph();
    let bad = forbidden_edges(graph.iter().map(|(_, m, r)| (m.as_slice(), r)));
    assert!(
        bad.is_empty(),
        "imports of a layer it must know nothing of:\n{}",
        bad.join("\n")
    );
}

/// Negative control: an analysis module that imports the physics, and a comparison
/// that imports an engine, are caught; a comparison importing the analysis is not.
#[test]
fn a_forbidden_edge_is_caught() {
    let v = |s: &str| s.split("::").map(str::to_string).collect::<Vec<String>>();
    let (a, c) = (v("analysis::stress_fields"), v("compare::trajectory"));
    let ra: BTreeSet<Vec<String>> = [v("physics::dem::packing"), v("rundata::snapshot")].into();
    let rc: BTreeSet<Vec<String>> = [v("engines::liggghts"), v("analysis::stress")].into();
    assert_eq!(
        forbidden_edges([(a.as_slice(), &ra), (c.as_slice(), &rc)]),
        [
            "analysis::stress_fields -> physics::dem::packing",
            "compare::trajectory -> engines::liggghts"
        ]
    );
}

#[test]
fn imports_only_point_down_and_modules_form_no_cycle() {
    let mut graph: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
    let mut upward = Vec::new();
    for (p, me, refs) in import_graph() {
        let p = &p;
        let my_rank = rank(&me[0]).unwrap_or_else(|| {
            panic!(
                "{}: top-level module {} is in no layer of docs/architecture.md",
                p.display(),
                me[0]
            )
        });
        for r in &refs {
            let their = rank(&r[0])
                .unwrap_or_else(|| panic!("{} imports {:?}, in no layer", p.display(), r));
            if their > my_rank {
                upward.push(format!(
                    "{} ({}) -> {} ({})",
                    me.join("::"),
                    LAYERS[my_rank.min(8)],
                    r.join("::"),
                    LAYERS[their.min(8)]
                ));
            }
        }
        graph.insert(me, refs);
    }
    assert!(
        upward.is_empty(),
        "imports that point up:\n{}",
        upward.join("\n")
    );

    // Cycles between modules (a parent mod.rs declaring and re-exporting its children is
    // not a dependency of the child on the parent, so parent -> child edges are dropped).
    let edges: BTreeMap<&Vec<String>, Vec<&Vec<String>>> = graph
        .iter()
        .map(|(m, rs)| {
            (
                m,
                rs.iter()
                    .filter(|r| !(r.len() > m.len() && r[..m.len()] == m[..]))
                    .filter(|r| graph.contains_key(*r))
                    .collect(),
            )
        })
        .collect();
    let mut cycles = Vec::new();
    for start in edges.keys() {
        // Depth-first search for a path back to `start`.
        let mut stack = vec![(*start, vec![*start])];
        let mut seen = BTreeSet::new();
        while let Some((node, path)) = stack.pop() {
            for next in edges.get(node).into_iter().flatten() {
                if *next == *start {
                    let mut c: Vec<String> = path.iter().map(|m| m.join("::")).collect();
                    c.push(start.join("::"));
                    cycles.push(c.join(" -> "));
                } else if seen.insert(*next) {
                    let mut p = path.clone();
                    p.push(*next);
                    stack.push((*next, p));
                }
            }
        }
    }
    cycles.sort();
    cycles.dedup();
    assert!(cycles.is_empty(), "module cycles:\n{}", cycles.join("\n"));
}
