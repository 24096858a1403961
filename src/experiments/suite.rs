//! Suites: named lists of case files, `cases/suites/<name>.toml`.
//!
//! ```toml
//! description = "what the suite verifies"
//! reference = "release"        # optional: its recorded runs live under reference/release/
//! [[case]]
//! path = "micro/*.toml"        # relative to cases/; `dir/*.toml` takes every case there
//! [[case]]
//! path = "penetration/ci.toml"
//! stress = true                # also the stress fields, phi and MALT (penetration)
//! theory = false               # report the MALT comparison without gating it
//!
//! [[claim]]                    # a paper's claim over several of its cases, per engine
//! name = "K_phi rises with mu_gg"
//! source = "Feng et al. Sec. 3 (b): ..."
//! cases = ["release/a.toml", "release/b.toml"]   # in order along the claim
//! kind = "increasing"          # or ratio_at_least (compare::sweep::SweepClaim)
//! quantity = "k_phi"
//! min_step_se = 2.0
//! ```

use anyhow::{Context, Result, bail, ensure};
use serde::Deserialize;
use std::path::{Path, PathBuf};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    description: String,
    /// Sub-directory of the reference root holding this suite's recorded runs, so a
    /// tier's records stay together (the release suite: `reference/release/`).
    #[serde(default)]
    reference: Option<String>,
    #[serde(rename = "case")]
    cases: Vec<Entry>,
    #[serde(default, rename = "claim")]
    claims: Vec<ClaimEntry>,
}

#[derive(Debug, Deserialize)]
struct ClaimEntry {
    name: String,
    /// Paper, figure/table and the sentence the claim stands for.
    source: String,
    cases: Vec<String>,
    #[serde(flatten)]
    claim: crate::compare::sweep::SweepClaim,
}

/// A claim over several cases of the suite, evaluated from their summaries.
#[derive(Debug, Clone, PartialEq)]
pub struct SuiteClaim {
    pub name: String,
    pub source: String,
    /// Case files, in the claim's order; every one is a case of the suite.
    pub cases: Vec<PathBuf>,
    pub claim: crate::compare::sweep::SweepClaim,
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
    pub claims: Vec<SuiteClaim>,
    reference: Option<PathBuf>,
}

impl Suite {
    /// Where this suite's recorded reference runs live under `reference_root`.
    pub fn reference_root(&self, reference_root: &Path) -> PathBuf {
        match &self.reference {
            Some(d) => reference_root.join(d),
            None => reference_root.to_path_buf(),
        }
    }
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
    let reference = match &f.reference {
        None => None,
        Some(d) => {
            let p = PathBuf::from(d);
            ensure!(
                !d.is_empty()
                    && p.components()
                        .all(|c| matches!(c, std::path::Component::Normal(_))),
                "{}: reference = {d:?}: must be a plain relative directory (no `..`, no root)",
                path.display()
            );
            Some(p)
        }
    };
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
    let mut claims = Vec::new();
    for (k, c) in f.claims.into_iter().enumerate() {
        ensure!(
            c.cases.len() >= 2,
            "{}: claim[{k}] ({:?}).cases: a claim across cases needs at least 2, got {}",
            path.display(),
            c.name,
            c.cases.len()
        );
        let mut files = Vec::new();
        for rel in &c.cases {
            let p = cases_root.join(rel);
            ensure!(
                cases.iter().any(|e| e.path == p),
                "{}: claim[{k}] ({:?}).cases: {rel:?} is not a case of this suite (add a [[case]] for it)",
                path.display(),
                c.name
            );
            files.push(p);
        }
        claims.push(SuiteClaim {
            name: c.name,
            source: c.source,
            cases: files,
            claim: c.claim,
        });
    }
    Ok(Suite {
        name: name.to_string(),
        description: f.description,
        cases,
        claims,
        reference,
    })
}

/// The summary of the case `name` in one of `dirs` (`DIR/<name>/summary.json`, as
/// `check` writes, or `DIR/summary.json`, as `compare` / `stress --out DIR` write), with
/// the directory it came from.
fn find_summary(
    dirs: &[PathBuf],
    name: &str,
) -> Option<(PathBuf, crate::compare::sweep::CaseSummary)> {
    dirs.iter().find_map(|d| {
        [d.join(name), d.to_path_buf()].into_iter().find_map(|c| {
            crate::compare::sweep::CaseSummary::read(&c)
                .ok()
                .filter(|s| s.case == name)
                .map(|s| (c, s))
        })
    })
}

/// The summaries of a claim's cases found in `dirs` (in the claim's order) and the names
/// of the cases without one; `Err` when a case cannot take part or its summary is of
/// another version of the case (canonical hash).
type Gathered = (
    Vec<(String, crate::compare::sweep::CaseSummary)>,
    Vec<String>,
);

fn gather(claim: &SuiteClaim, dirs: &[PathBuf]) -> Result<Gathered, String> {
    use crate::case::AnyCase;
    let (mut found, mut missing) = (Vec::new(), Vec::new());
    for p in &claim.cases {
        let case = AnyCase::load(p).map_err(|e| e.to_string())?;
        let AnyCase::Penetration(pc) = &case else {
            return Err(format!(
                "{}: claims across cases take penetration cases",
                p.display()
            ));
        };
        let hash = crate::case::ValidatedCase::canonical_hash(pc).to_string();
        let name = case.name().to_string();
        match find_summary(dirs, &name) {
            None => missing.push(name),
            Some((_, s)) if s.canonical_hash == hash => found.push((name, s)),
            Some((d, _)) => {
                return Err(format!(
                    "{}: the summary is of another version of case {name} (canonical hash differs): re-run it",
                    d.display()
                ));
            }
        }
    }
    Ok((found, missing))
}

/// The suite's claims, one check per claim and engine, from the case summaries found in
/// `dirs`. A summary must come from the case as it is now (its canonical hash), else the
/// claim is an error. `partial`: a claim none of whose cases has a summary is left out
/// (with a note) instead of NOT COMPARED, for runs of a subset (`check --only`).
pub fn evaluate_claims(
    suite: &Suite,
    dirs: &[PathBuf],
    partial: bool,
) -> (Vec<crate::compare::Check>, Vec<String>) {
    use crate::compare::{Check, Gate, sweep};
    let (mut checks, mut notes) = (Vec::new(), Vec::new());
    for c in &suite.claims {
        match gather(c, dirs) {
            Err(e) => checks.push(Check::error_in(&c.name, Gate::Claim, e)),
            Ok((found, missing)) if missing.is_empty() => {
                notes.push(format!("claim {:?}: {}", c.name, c.source));
                for engine in ["native", "liggghts"] {
                    checks.push(sweep::evaluate(&c.name, &c.claim, &found, engine));
                }
            }
            Ok((found, _)) if partial && found.is_empty() => notes.push(format!(
                "claim {:?}: none of its cases ran here; not evaluated",
                c.name
            )),
            Ok((_, missing)) => checks.push(Check::not_compared(
                &c.name,
                Gate::Claim,
                format!(
                    "no summary of case(s) {} (run them, or pass their output with --runs)",
                    missing.join(", ")
                ),
            )),
        }
    }
    (checks, notes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, suite: &str) {
        std::fs::create_dir_all(dir.join("suites")).unwrap();
        std::fs::create_dir_all(dir.join("release")).unwrap();
        for n in ["a", "b"] {
            std::fs::write(dir.join(format!("release/{n}.toml")), "").unwrap();
        }
        std::fs::write(dir.join("suites/s.toml"), suite).unwrap();
    }

    const HEAD: &str = "description = \"d\"\nreference = \"release\"\n[[case]]\npath = \"release/a.toml\"\n[[case]]\npath = \"release/b.toml\"\n";

    #[test]
    fn claims_parse_and_name_their_mistakes() {
        let d = tempfile::tempdir().unwrap();
        let ok = format!(
            "{HEAD}[[claim]]\nname = \"n\"\nsource = \"s\"\ncases = [\"release/a.toml\", \"release/b.toml\"]\nkind = \"increasing\"\nquantity = \"k_phi\"\nmin_step_se = 2.0\n"
        );
        write(d.path(), &ok);
        let s = load(d.path(), "s").unwrap();
        assert_eq!(s.claims.len(), 1);
        assert_eq!(s.reference_root(Path::new("r")), Path::new("r/release"));
        // A misspelt field is an error, not a silently defaulted one.
        write(d.path(), &ok.replace("min_step_se", "min_step_sd"));
        assert!(load(d.path(), "s").is_err());
        // A claim over a case the suite does not run cannot be evaluated: refused.
        write(
            d.path(),
            &ok.replace("release/b.toml\"]", "release/c.toml\"]"),
        );
        let e = format!("{:#}", load(d.path(), "s").unwrap_err());
        assert!(e.contains("not a case of this suite"), "{e}");
        write(d.path(), &HEAD.replace("\"release\"", "\"../x\""));
        let e = format!("{:#}", load(d.path(), "s").unwrap_err());
        assert!(e.contains("plain relative directory"), "{e}");
    }

    /// Claims read the cases' summaries: all present gives one check per engine; a
    /// stale summary (another canonical hash) is an error; a missing one NOT COMPARED,
    /// or only a note when a subset ran and none of the claim's cases was in it.
    #[test]
    fn claims_are_evaluated_from_current_summaries_only() {
        use crate::case::AnyCase;
        use crate::compare::Status;
        use crate::compare::sweep::{CaseSummary, EngineSummary};
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
        let suite = load(&root, "release").unwrap();
        let claim = suite
            .claims
            .iter()
            .find(|c| c.name.contains("x10"))
            .expect("the registered force-ratio claim");
        let one = Suite {
            claims: vec![claim.clone()],
            ..suite.clone()
        };
        let d = tempfile::tempdir().unwrap();
        let write = |p: &Path, hash: Option<&str>, p_level: f64| {
            let AnyCase::Penetration(c) = AnyCase::load(p).unwrap() else {
                panic!()
            };
            let h: Vec<f64> = (0..300).map(|i| i as f64 * 0.01).collect();
            let e = EngineSummary {
                k_phi: p_level,
                k_phi_se_regression: 0.1,
                k_phi_beds: vec![p_level; 3],
                p: h.iter().map(|x| p_level * x).collect(),
                h,
                psi: 0.6,
            };
            let s = CaseSummary {
                case: c.name.clone(),
                canonical_hash: hash.map_or(c.canonical_hash().to_string(), str::to_string),
                engines: [
                    ("native".to_string(), e.clone()),
                    ("liggghts".to_string(), e),
                ]
                .into(),
            };
            let dir = d.path().join(&c.name);
            std::fs::create_dir_all(&dir).unwrap();
            s.write(&dir).unwrap();
        };
        let dirs = vec![d.path().to_path_buf()];
        let (checks, notes) = evaluate_claims(&one, &dirs, true);
        assert!(
            checks.is_empty() && notes.len() == 1,
            "{checks:?} {notes:?}"
        );
        write(&claim.cases[0], None, 1.0);
        let (checks, _) = evaluate_claims(&one, &dirs, true);
        assert_eq!(checks.len(), 1);
        assert_eq!(checks[0].status, Status::NotCompared);
        write(&claim.cases[1], None, 12.0);
        let (checks, _) = evaluate_claims(&one, &dirs, false);
        assert_eq!(checks.len(), 2, "native and liggghts");
        assert!(checks.iter().all(|c| c.passed), "{checks:?}");
        write(&claim.cases[1], Some("stale"), 12.0);
        let (checks, _) = evaluate_claims(&one, &dirs, false);
        assert_eq!(checks[0].status, Status::Error, "{checks:?}");
    }
}
