//! Suites: named lists of case files, `cases/suites/<name>.toml`.
//!
//! ```toml
//! description = "what the suite verifies"
//! [[case]]
//! path = "micro/*.toml"        # relative to cases/; `dir/*.toml` takes every case there
//! [[case]]
//! path = "penetration/ci.toml"
//! stress = true                # also the stress fields, phi and MALT (penetration)
//! theory = false               # report the MALT comparison without gating it
//! ```

use anyhow::{Context, Result, bail, ensure};
use serde::Deserialize;
use std::path::{Path, PathBuf};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    description: String,
    #[serde(rename = "case")]
    cases: Vec<Entry>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Entry {
    path: String,
    #[serde(default)]
    stress: bool,
    /// Gate the comparisons with theory (MALT); default true.
    #[serde(default = "yes")]
    theory: bool,
}

fn yes() -> bool {
    true
}

/// One case of a suite and how it runs there.
#[derive(Debug, Clone, PartialEq)]
pub struct SuiteCase {
    pub path: PathBuf,
    pub stress: bool,
    /// Whether theory comparisons are gated here (else reported only).
    pub theory: bool,
}

#[derive(Debug, Clone)]
pub struct Suite {
    pub name: String,
    pub description: String,
    pub cases: Vec<SuiteCase>,
}

pub fn manifest(cases_root: &Path, name: &str) -> PathBuf {
    cases_root.join("suites").join(format!("{name}.toml"))
}

/// Names of the suites under `cases_root`.
pub fn names(cases_root: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(cases_root.join("suites"))
        .into_iter()
        .flatten()
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let p = e.path();
            (p.extension().is_some_and(|x| x == "toml"))
                .then(|| p.file_stem()?.to_str().map(str::to_string))
                .flatten()
        })
        .collect();
    v.sort();
    v
}

pub fn load(cases_root: &Path, name: &str) -> Result<Suite> {
    let path = manifest(cases_root, name);
    let text = std::fs::read_to_string(&path).with_context(|| {
        format!(
            "suite {name:?}: cannot read {} (suites here: {})",
            path.display(),
            names(cases_root).join(", ")
        )
    })?;
    let f: File = toml::from_str(&text).with_context(|| format!("{}", path.display()))?;
    let mut cases = Vec::new();
    for (k, e) in f.cases.iter().enumerate() {
        let expanded = if let Some(dir) = e.path.strip_suffix("/*.toml") {
            let d = cases_root.join(dir);
            let mut v: Vec<PathBuf> = std::fs::read_dir(&d)
                .with_context(|| {
                    format!(
                        "{}: case[{k}].path = {:?}: cannot list {}",
                        path.display(),
                        e.path,
                        d.display()
                    )
                })?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "toml"))
                .collect();
            v.sort();
            v
        } else {
            vec![cases_root.join(&e.path)]
        };
        ensure!(
            !expanded.is_empty(),
            "{}: case[{k}].path = {:?} names no case file",
            path.display(),
            e.path
        );
        for p in expanded {
            if !p.is_file() {
                bail!(
                    "{}: case[{k}].path = {:?}: {} does not exist",
                    path.display(),
                    e.path,
                    p.display()
                );
            }
            cases.push(SuiteCase {
                path: p,
                stress: e.stress,
                theory: e.theory,
            });
        }
    }
    ensure!(
        !cases.is_empty(),
        "{}: the suite has no cases",
        path.display()
    );
    Ok(Suite {
        name: name.to_string(),
        description: f.description,
        cases,
    })
}
