//! Suites: named lists of case files, `cases/suites/<name>.toml`.
//!
//! ```toml
//! description = "what the suite verifies"
//! reference = "release"        # optional: its recorded runs live under reference/release/
//! registration = "git"         # optional: checks whose rules changed after their record
//!                              # was sealed are EXPLORATORY (experiments::registration)
//! [[case]]
//! path = "micro/*.toml"        # relative to cases/; `dir/*.toml` takes every case there
//! [[case]]
//! path = "penetration/ci.toml"
//! stress = true                # also the stress fields, phi and MALT (penetration)
//! theory = false               # report the MALT comparison without gating it
//! quasi_static = false         # skip the case's `[quasi_static]` runs here (penetration)
//!
//! [[claim]]                    # a paper's claim over several of its cases, per engine
//! name = "K_phi rises with mu_gg"
//! source = "Feng et al. Sec. 3 (b): ..."
//! cases = ["release/a.toml", "release/b.toml"]   # in order along the claim
//! kind = "increasing"          # or ratio_at_least, independent (compare::sweep::SweepClaim)
//! quantity = "k_phi"
//! [[claim.negative_control]]   # the claim on wrong native physics must fail
//! name = "mu_gg ignored"
//! kind = "sweep_ignored"       # or case_control (compare::sweep::ClaimControl)
//!
//! [[expect]]                   # a registered finding the release gate expects
//! check = "K_phi rises with mu_gg (native)"
//! verdict = "fail"             # pass | fail | inconclusive | not_compared
//! value = 0.012                # optional: pinned value and interval
//! interval = [-0.01, 0.03]
//! reason = "..."
//! found = "2026-11-26"
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
    /// Registered expectations of the release gate (docs/statistics.md).
    #[serde(default, rename = "expect")]
    expectations: Vec<crate::compare::expect::Expectation>,
    /// Families of cases for the engine agreement against chaos (docs/statistics.md).
    #[serde(default, rename = "family")]
    families: Vec<FamilyEntry>,
    /// `registration = "git"`: its checks' rules are registered by git history.
    #[serde(default)]
    registration: Option<RegistrationSource>,
}

/// Where a suite's registration is read from (docs/statistics.md, "Registration"): the
/// git history of its case files and suite file against its records' seal times.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RegistrationSource {
    Git,
}

/// `[[family]]`: cases whose engine differences are pooled and judged against the chaos
/// spread of their chaos records (`granval chaos`), paths relative to the repository
/// (the parent of the cases directory).
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub(crate) struct FamilyEntry {
    pub name: String,
    pub cases: Vec<String>,
    pub chaos: Vec<String>,
}

#[derive(Debug, Deserialize)]
struct ClaimEntry {
    name: String,
    /// Paper, figure/table and the sentence the claim stands for.
    source: String,
    cases: Vec<String>,
    #[serde(default, rename = "negative_control")]
    controls: Vec<crate::compare::sweep::ClaimControl>,
    /// The swept parameter's value at each case and its name, for the claim's figure
    /// (default: the case index).
    #[serde(default)]
    x: Vec<f64>,
    #[serde(default)]
    x_label: Option<String>,
    /// The paper's K_phi at each case where it prints one (`nan` where it does not), drawn
    /// beside the engines' (Feng et al. Table 3).
    #[serde(default)]
    paper_k_phi: Vec<f64>,
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
    pub controls: Vec<ClaimControl>,
    /// Figure axis: the parameter per case and its name (empty: case index).
    pub x: Vec<f64>,
    pub x_label: String,
    /// Published K_phi per case (empty: none; NaN where the paper gives none).
    pub paper_k_phi: Vec<f64>,
}

/// A claim's negative control with what it substitutes, resolved when the suite is read.
#[derive(Debug, Clone, PartialEq)]
pub struct ClaimControl {
    pub control: crate::compare::sweep::ClaimControl,
    substitute: Substitute,
}

#[derive(Debug, Clone, PartialEq)]
enum Substitute {
    /// Every case's summary by the first case's.
    First,
    /// Case `case`'s summary by its control run's, `<case output>/<dir>/summary.json`.
    Control { case: usize, dir: String },
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
    /// Run the case's `[quasi_static]` test (Feng Sec. 3, a second native run per bed at
    /// the slower speed); default true.
    #[serde(default = "yes")]
    quasi_static: bool,
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
    /// Whether the case's `[quasi_static]` runs and check happen here (a suite may
    /// leave that test to another suite that runs it on its own beds).
    pub quasi_static: bool,
}

#[derive(Debug, Clone)]
pub struct Suite {
    pub name: String,
    pub description: String,
    pub cases: Vec<SuiteCase>,
    pub claims: Vec<SuiteClaim>,
    /// `[[expect]]`: the verdicts the release gate expects where they are not a pass.
    pub expectations: Vec<crate::compare::expect::Expectation>,
    /// `[[family]]`: the families of the engine agreement against chaos, with their case
    /// files and chaos records resolved to paths.
    pub families: Vec<Family>,
    /// `registration = "git"` (None: its checks are all gated, as before registration).
    pub registration: Option<RegistrationSource>,
    /// The suite file (`cases/suites/<name>.toml`).
    pub file: PathBuf,
    reference: Option<PathBuf>,
}

/// A resolved `[[family]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Family {
    pub name: String,
    pub cases: Vec<PathBuf>,
    pub chaos: Vec<PathBuf>,
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

/// Reads suite `name` of `cases_root` and resolves it: its reference directory, its case
/// files, its claims, expectations and families, each checked in the order of the calls
/// below; the first error found is the one reported.
pub fn load(cases_root: &Path, name: &str) -> Result<Suite> {
    // A suite is named, not a path: `--suite ../../x` must not read any TOML on disk.
    ensure!(
        !name.is_empty()
            && !name.starts_with('.')
            && name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "._-".contains(c)),
        "--suite {name:?}: a suite is a plain name of a file in {} (suites here: {})",
        cases_root.join("suites").display(),
        names(cases_root).join(", ")
    );
    let path = manifest(cases_root, name);
    let text = crate::rundata::fsio::read_to_string(
        &path,
        crate::rundata::fsio::MAX_CASE_FILE,
        "a suite file (TOML text)",
    )
    .with_context(|| {
        format!(
            "suite {name:?} (suites here: {})",
            names(cases_root).join(", ")
        )
    })?;
    let f: File = toml::from_str(&text).with_context(|| format!("{}", path.display()))?;
    let reference = reference_dir(&path, f.reference.as_deref())?;
    let cases = suite_cases(cases_root, &path, &f.cases)?;
    unique_names(&path, &cases)?;
    let claims = f
        .claims
        .into_iter()
        .enumerate()
        .map(|(k, c)| suite_claim(cases_root, &path, k, c, &cases))
        .collect::<Result<Vec<_>>>()?;
    crate::compare::expect::check_list(&path, &f.expectations)?;
    let families = families(cases_root, &path, f.families, &cases)?;
    Ok(Suite {
        name: name.to_string(),
        description: f.description,
        cases,
        claims,
        expectations: f.expectations,
        families,
        registration: f.registration,
        file: path,
        reference,
    })
}

/// `reference`: the sub-directory of the reference root holding the suite's records, a
/// plain relative directory so that it stays under that root.
fn reference_dir(path: &Path, reference: Option<&str>) -> Result<Option<PathBuf>> {
    let Some(d) = reference else {
        return Ok(None);
    };
    let p = PathBuf::from(d);
    ensure!(
        !d.is_empty()
            && p.components()
                .all(|c| matches!(c, std::path::Component::Normal(_))),
        "{}: reference = {d:?}: must be a plain relative directory (no `..`, no root)",
        path.display()
    );
    Ok(Some(p))
}

/// `[[case]]` entries resolved to case files (`dir/*.toml` expanded in name order): at
/// least one case, every file existing, and none listed twice, which would run twice
/// into one output directory.
fn suite_cases(cases_root: &Path, path: &Path, entries: &[Entry]) -> Result<Vec<SuiteCase>> {
    let mut cases = Vec::new();
    // (entry index, canonical path, entry's path) of every case file taken so far.
    let mut listed: Vec<(usize, PathBuf, String)> = Vec::new();
    for (k, e) in entries.iter().enumerate() {
        let expanded = entry_files(cases_root, path, k, e)?;
        for p in expanded {
            if !p.is_file() {
                bail!(
                    "{}: case[{k}].path = {:?}: {} does not exist",
                    path.display(),
                    e.path,
                    p.display()
                );
            }
            // One case file listed twice would run twice into one output directory.
            let real = std::fs::canonicalize(&p).unwrap_or_else(|_| p.clone());
            if let Some((j, first)) = listed
                .iter()
                .find(|(_, r, _)| *r == real)
                .map(|(j, _, f)| (*j, f))
            {
                bail!(
                    "{}: case[{j}].path = {:?} and case[{k}].path = {:?} both name {}: list each case file once",
                    path.display(),
                    first,
                    e.path,
                    p.display()
                );
            }
            listed.push((k, real, e.path.clone()));
            cases.push(SuiteCase {
                path: p,
                stress: e.stress,
                theory: e.theory,
                quasi_static: e.quasi_static,
            });
        }
    }
    ensure!(
        !cases.is_empty(),
        "{}: the suite has no cases",
        path.display()
    );
    Ok(cases)
}

/// The case files entry `k` names: one file, or every `.toml` of a directory for
/// `dir/*.toml`, sorted; at least one.
fn entry_files(cases_root: &Path, path: &Path, k: usize, e: &Entry) -> Result<Vec<PathBuf>> {
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
    Ok(expanded)
}

/// `[[claim]]` number `k`: over at least two cases of this suite, a valid claim, its
/// negative controls resolved to what they substitute, and figure values (`x`,
/// `paper_k_phi`) one per case when given, `x` finite.
fn suite_claim(
    cases_root: &Path,
    path: &Path,
    k: usize,
    c: ClaimEntry,
    cases: &[SuiteCase],
) -> Result<SuiteClaim> {
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
    let at = |what: String| format!("{}: claim[{k}] ({:?}): {what}", path.display(), c.name);
    c.claim.validate().map_err(|e| anyhow::anyhow!(at(e)))?;
    let mut controls = Vec::new();
    for (j, control) in c.controls.iter().enumerate() {
        let substitute = resolve_control(control, &c.cases, &files)
            .map_err(|e| anyhow::anyhow!(at(format!("negative_control[{j}]: {e}"))))?;
        controls.push(ClaimControl {
            control: control.clone(),
            substitute,
        });
    }
    for (field, v) in [("x", &c.x), ("paper_k_phi", &c.paper_k_phi)] {
        ensure!(
            v.is_empty() || v.len() == files.len(),
            "{}",
            at(format!(
                "{field} has {} values for {} cases (one per case, or leave it out)",
                v.len(),
                files.len()
            ))
        );
    }
    ensure!(
        c.x.iter().all(|v| v.is_finite()),
        "{}",
        at(format!("x = {:?}: every value must be finite", c.x))
    );
    Ok(SuiteClaim {
        name: c.name,
        source: c.source,
        cases: files,
        claim: c.claim,
        controls,
        x: c.x,
        x_label: c.x_label.unwrap_or_else(|| "case".into()),
        paper_k_phi: c.paper_k_phi,
    })
}

/// `[[family]]`s resolved: each case a case of this suite (relative to `cases_root`),
/// the chaos records relative to the repository, the parent of `cases_root`.
fn families(
    cases_root: &Path,
    path: &Path,
    entries: Vec<FamilyEntry>,
    cases: &[SuiteCase],
) -> Result<Vec<Family>> {
    let repo = cases_root.parent().unwrap_or(Path::new("."));
    let mut families = Vec::new();
    for (k, fam) in entries.into_iter().enumerate() {
        let mut fcases = Vec::new();
        for c in &fam.cases {
            let p = cases_root.join(c);
            ensure!(
                cases.iter().any(|e| e.path == p),
                "{}: family[{k}] ({}): {c} is not a case of this suite",
                path.display(),
                fam.name
            );
            fcases.push(p);
        }
        let chaos = fam.chaos.iter().map(|c| repo.join(c)).collect();
        families.push(Family {
            name: fam.name,
            cases: fcases,
            chaos,
        });
    }
    Ok(families)
}

/// A case's outputs go to `OUT/<case name>/` and its record to
/// `reference/<kind>/<case name>/`: two case files of one suite with the same `[case]
/// name` would overwrite each other's outputs and give two indistinguishable rows, and a
/// file listed twice would run twice. Both are refused, naming the files. The name is
/// read alone (a case file that does not parse is left to its own loader's error).
fn unique_names(suite_file: &Path, cases: &[SuiteCase]) -> Result<()> {
    let mut seen: Vec<(String, &Path)> = Vec::new();
    for (k, c) in cases.iter().enumerate() {
        if let Some(j) = cases[..k].iter().position(|d| d.path == c.path) {
            bail!(
                "{}: {} is listed twice (cases {j} and {k} after expanding the globs): it would run twice",
                suite_file.display(),
                c.path.display()
            );
        }
        let Some(name) = std::fs::read_to_string(&c.path)
            .ok()
            .and_then(|t| t.parse::<toml::Table>().ok())
            .and_then(|t| Some(t.get("case")?.get("name")?.as_str()?.to_string()))
        else {
            continue;
        };
        if let Some((_, first)) = seen.iter().find(|(n, _)| *n == name) {
            bail!(
                "{}: {} and {} both declare [case] name = {name:?}: their outputs (OUT/{name}/) and records would overwrite each other; rename one",
                suite_file.display(),
                first.display(),
                c.path.display()
            );
        }
        seen.push((name, &c.path));
    }
    Ok(())
}

fn penetration_case(p: &Path) -> Result<crate::case::penetration::PenetrationCase, String> {
    match crate::case::AnyCase::load(p).map_err(|e| format!("{e:#}"))? {
        crate::case::AnyCase::Penetration(c) => Ok(c),
        _ => Err(format!(
            "{}: claims across cases take penetration cases",
            p.display()
        )),
    }
}

/// What a claim control substitutes, checked against the claim's case files: a sweep
/// may be ignored only among cases on the same seeds and bed count; a case control
/// names a case of the claim and one of that case's own negative controls.
fn resolve_control(
    control: &crate::compare::sweep::ClaimControl,
    rels: &[String],
    files: &[PathBuf],
) -> Result<Substitute, String> {
    use crate::compare::sweep::ClaimControl as C;
    match control {
        C::SweepIgnored { .. } => {
            let first = penetration_case(&files[0])?;
            for (rel, f) in rels.iter().zip(files).skip(1) {
                let c = penetration_case(f)?;
                if (c.seed, c.ensemble_beds) != (first.seed, first.ensemble_beds) {
                    return Err(format!(
                        "kind = \"sweep_ignored\" stands for re-running every case with the first one's parameters, which needs the same beds: {rel} has seed {} and {} bed(s), {} has seed {} and {}",
                        c.seed, c.ensemble_beds, rels[0], first.seed, first.ensemble_beds
                    ));
                }
            }
            Ok(Substitute::First)
        }
        C::CaseControl { case, control, .. } => {
            let i = rels.iter().position(|r| r == case).ok_or_else(|| {
                format!("case = {case:?} is not one of the claim's cases {rels:?}")
            })?;
            let c = penetration_case(&files[i])?;
            let k = c
                .negative_controls
                .iter()
                .position(|n| n.name == *control)
                .ok_or_else(|| {
                    format!(
                        "control = {control:?}: {case} has no negative control of that name (it has {:?})",
                        c.negative_controls.iter().map(|n| &n.name).collect::<Vec<_>>()
                    )
                })?;
            Ok(Substitute::Control {
                case: i,
                dir: format!("control-{k}"),
            })
        }
    }
}

/// The directory holding the summary of the case `name` in one of `dirs`
/// (`DIR/<name>/summary.json`, as `check` writes, or `DIR/summary.json` naming the case,
/// as `compare` / `stress --out DIR` write). Found is not accepted: [`gather`] verifies
/// its run seal.
pub(crate) fn find_summary(dirs: &[PathBuf], name: &str) -> Option<PathBuf> {
    use crate::compare::sweep::SUMMARY_FILE;
    dirs.iter().find_map(|d| {
        let own = d.join(name);
        if own.join(SUMMARY_FILE).is_file() {
            return Some(own);
        }
        let names_it = std::fs::read_to_string(d.join(SUMMARY_FILE))
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .is_some_and(|v| v.get("case").and_then(|c| c.as_str()) == Some(name));
        names_it.then(|| d.to_path_buf())
    })
}

/// The summaries of a claim's cases found in `dirs` (in the claim's order, with the
/// directory each came from), the names of the cases without one, and for the report
/// where each came from; `Err` when a case cannot take part or a summary found is not
/// accepted: its run seal does not verify ([`super::penetration::run_seal::verify`]:
/// hand-written, edited, of another version of the case, or not following from the
/// run's sealed outputs).
type Gathered = (
    Vec<(String, PathBuf, crate::compare::sweep::CaseSummary)>,
    Vec<String>,
    Vec<String>,
);

fn gather(claim: &SuiteClaim, dirs: &[PathBuf]) -> Result<Gathered, String> {
    let (mut found, mut missing, mut sources) = (Vec::new(), Vec::new(), Vec::new());
    for p in &claim.cases {
        let pc = penetration_case(p)?;
        let name = pc.name.clone();
        match find_summary(dirs, &name) {
            None => missing.push(name),
            Some(d) => match super::penetration::run_seal::verify(&d, &pc) {
                Ok(v) => {
                    sources.push(v.describe());
                    found.push((name, d, v.summary));
                }
                Err(e) => return Err(format!("{e:#}")),
            },
        }
    }
    Ok((found, missing, sources))
}

/// One claim control's check: the claim on the native summaries with the control's
/// substitution.
fn control_check(
    c: &SuiteClaim,
    control: &ClaimControl,
    found: &[(String, PathBuf, crate::compare::sweep::CaseSummary)],
) -> crate::compare::Check {
    use crate::compare::{Check, Gate, sweep};
    let mut cases: Vec<(String, sweep::CaseSummary)> = found
        .iter()
        .map(|(l, _, s)| (l.clone(), s.clone()))
        .collect();
    match &control.substitute {
        Substitute::First => {
            for x in cases.iter_mut().skip(1) {
                x.1 = found[0].2.clone();
            }
        }
        Substitute::Control { case, dir } => {
            let (l, d, s) = &found[*case];
            let read = penetration_case(&c.cases[*case]).and_then(|pc| {
                super::penetration::run_seal::verify(&d.join(dir), &pc)
                    .map(|v| v.summary)
                    .map_err(|e| format!("{e:#}"))
            });
            match read.and_then(|w| {
                (w.case == s.case && w.canonical_hash == s.canonical_hash)
                    .then_some(w)
                    .ok_or_else(|| {
                        format!(
                            "{}: the control's summary is of another case or version",
                            d.join(dir).display()
                        )
                    })
            }) {
                Ok(w) => cases[*case] = (format!("{l} ({})", control.control.name()), w),
                Err(e) => {
                    return Check::error_in(
                        format!(
                            "{}: negative control \"{}\"",
                            c.name,
                            control.control.name()
                        ),
                        Gate::NegativeControl,
                        e,
                    );
                }
            }
        }
    }
    let substituted = sweep::evaluate(&c.name, &c.claim, &cases, "native");
    sweep::control_check(&c.name, &control.control, &substituted)
}

/// The suite's claims, one check per claim and engine, from the case summaries found in
/// `dirs`. A summary is read only through its run seal, which must verify for the case
/// as it is now (its canonical hash) and reproduce the summary from the run's sealed
/// force files; otherwise the claim is an error naming the file. The notes name the
/// directory each summary came from and the run's own verdict. `partial`: a claim some
/// or all of whose cases have no summary is left out (with a note naming them) instead
/// of NOT COMPARED, for runs of a subset (`check --only`).
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
            Ok((found, missing, sources)) if missing.is_empty() => {
                notes.push(format!("claim {:?}: {}", c.name, c.source));
                for s in sources {
                    notes.push(format!("claim {:?}: case {s}", c.name));
                }
                let summaries: Vec<_> = found
                    .iter()
                    .map(|(l, _, s)| (l.clone(), s.clone()))
                    .collect();
                for engine in ["native", "liggghts"] {
                    checks.push(sweep::evaluate(&c.name, &c.claim, &summaries, engine));
                }
                for control in &c.controls {
                    checks.push(control_check(c, control, &found));
                }
            }
            Ok((found, _, _)) if partial && found.is_empty() => notes.push(format!(
                "claim {:?}: none of its cases ran here; not evaluated",
                c.name
            )),
            // A subset that ran only some of a claim's cases has not judged it either: the
            // release gate then counts it as not run, not as a verdict that changed.
            Ok((_, missing, _)) if partial => notes.push(format!(
                "claim {:?}: not evaluated: case(s) {} did not run here (pass their output with --runs)",
                c.name,
                missing.join(", ")
            )),
            Ok((_, missing, _)) => checks.push(Check::not_compared(
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

/// A report section per claim whose cases all have summaries in `dirs`: the cases'
/// ensemble-mean FDRs overlaid (both engines) and K_phi along the sweep with its
/// standard errors, single beds and the paper's values, written under `out/claims/`.
pub fn claim_sections(
    suite: &Suite,
    dirs: &[PathBuf],
    out: &Path,
) -> (Vec<String>, Vec<crate::report::Section>) {
    let (mut notes, mut sections) = (Vec::new(), Vec::new());
    for c in &suite.claims {
        let Ok((found, missing, _)) = gather(c, dirs) else {
            continue;
        };
        if !missing.is_empty() {
            continue;
        }
        match claim_figures(c, &found, out) {
            Ok(figures) => sections.push(crate::report::Section {
                title: format!("Claim: {}", c.name),
                body: format!(
                    "{}\n\ncases: {}",
                    c.source,
                    found
                        .iter()
                        .map(|f| f.0.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
                figures,
            }),
            Err(e) => notes.push(format!("claim {:?}: figures not written: {e:#}", c.name)),
        }
    }
    (notes, sections)
}

/// The two figures of one claim; paths relative to `out`.
fn claim_figures(
    c: &SuiteClaim,
    found: &[(String, PathBuf, crate::compare::sweep::CaseSummary)],
    out: &Path,
) -> Result<Vec<String>> {
    use crate::report::svg::{FdrSeries, SweepSeries, fdr_overlay, k_phi_sweep};
    use crate::rundata::provenance::EngineKind;
    let slug: String = c
        .name
        .chars()
        .map(|ch| {
            if ch.is_ascii_alphanumeric() {
                ch.to_ascii_lowercase()
            } else {
                '-'
            }
        })
        .collect::<String>()
        .split('-')
        .filter(|w| !w.is_empty())
        .collect::<Vec<_>>()
        .join("-");
    std::fs::create_dir_all(out.join("claims"))?;
    let fdr_rel = format!("claims/{slug}-fdr.svg");
    let k_rel = format!("claims/{slug}-k_phi.svg");
    // Summaries keep each engine under its key; the case name is the variant.
    let engines = [EngineKind::Native, EngineKind::Liggghts];
    let labels: Vec<String> = found
        .iter()
        .flat_map(|(name, _, _)| engines.map(|e| format!("{name} {}", e.key())))
        .collect();
    let mut series = Vec::new();
    for (i, (name, _, s)) in found.iter().enumerate() {
        for (j, e) in engines.iter().enumerate() {
            if let Some(es) = s.engines.get(e.key()) {
                series.push(FdrSeries {
                    variant: name,
                    ..FdrSeries::new(&labels[2 * i + j], (*e).into(), &es.h, &es.p, None)
                });
            }
        }
    }
    fdr_overlay(
        &out.join(&fdr_rel),
        &series,
        &format!("{}: ensemble-mean FDRs", c.name).as_str().into(),
    )?;
    let x: Vec<f64> = if c.x.is_empty() {
        (0..found.len()).map(|i| i as f64).collect()
    } else {
        c.x.clone()
    };
    // Per engine along the sweep: K_phi, its standard error, and each case's per-bed values.
    type EngineSweep = (EngineKind, Vec<f64>, Vec<f64>, Vec<Vec<f64>>);
    let per_engine: Vec<EngineSweep> = engines
        .iter()
        .filter_map(|e| {
            let v: Option<Vec<_>> = found
                .iter()
                .map(|(_, _, s)| s.engines.get(e.key()))
                .collect();
            v.map(|v| {
                (
                    *e,
                    v.iter().map(|s| s.k_phi).collect(),
                    v.iter().map(|s| s.k_phi_se()).collect(),
                    v.iter().map(|s| s.k_phi_beds.clone()).collect(),
                )
            })
        })
        .collect();
    let sweep: Vec<SweepSeries> = per_engine
        .iter()
        .map(|(e, k, se, beds)| SweepSeries {
            label: e.key(),
            source: (*e).into(),
            k,
            se,
            beds,
        })
        .collect();
    k_phi_sweep(
        &out.join(&k_rel),
        &format!("{}: K_phi", c.name).as_str().into(),
        &c.x_label,
        &x,
        &sweep,
        (!c.paper_k_phi.is_empty()).then_some(&c.paper_k_phi[..]),
    )?;
    Ok(vec![fdr_rel, k_rel])
}

/// "Engine agreement against chaos" (docs/statistics.md): per family, the per-bed
/// ln(K_native / K_liggghts) of every bed pair in the summaries found in `dirs` (each
/// case version and bed once) against the family's chaos records; for a family of
/// Kondic (2D) cases, the per-variant (D_native - D_lammps) / d of the runs' final
/// depths against the 2D records' (D - D') / d. Reporting only.
pub fn chaos_section(
    suite: &Suite,
    dirs: &[PathBuf],
) -> (Vec<String>, Option<crate::report::Section>) {
    use crate::compare::chaos::family_agreement;
    use crate::experiments::chaos::{ChaosRecord, IMPACT2D, PENETRATION};
    let (mut notes, mut rows) = (Vec::new(), Vec::new());
    for fam in &suite.families {
        let mut chaos = Vec::new();
        let mut kinds = std::collections::BTreeSet::new();
        for c in &fam.chaos {
            match ChaosRecord::read(c) {
                Ok(r) => {
                    chaos.extend_from_slice(r.values());
                    kinds.insert(r.kind);
                }
                Err(e) => notes.push(format!("family {:?}: {e:#}", fam.name)),
            }
        }
        if kinds.len() > 1 {
            notes.push(format!(
                "family {:?}: chaos records of different kinds ({}); their c_k are not one quantity, not in the chaos section",
                fam.name,
                kinds.into_iter().collect::<Vec<_>>().join(", ")
            ));
            continue;
        }
        let kind = kinds.pop_first().unwrap_or_else(|| PENETRATION.to_string());
        let (logs, quantity) = if kind == IMPACT2D {
            (
                impact2d_engine_differences(fam, dirs, &mut notes),
                "(D_n - D_L) / d",
            )
        } else {
            (
                penetration_engine_logs(fam, dirs, &mut notes),
                "ln(K_n / K_L)",
            )
        };
        if logs.is_empty() {
            notes.push(format!(
                "family {:?}: no summary of its cases here; not in the chaos section",
                fam.name
            ));
            continue;
        }
        rows.push((quantity, family_agreement(&fam.name, &logs, &chaos)));
    }
    if rows.is_empty() {
        return (notes, None);
    }
    let mut body = String::from(
        "Per family, every bed pair native / reference engine of the cases that ran (each case version and bed once; LIGGGHTS for penetration, LAMMPS per variant for the 2D cases), against the chaos spread s_c of one engine against itself (two native runs of one bed, one ulp apart; `granval chaos`).\n\n| family | per bed | bed pairs | mean | 95 % interval | sd per bed | chaos s_c (df) | F (p) | z vs chaos | verdict |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for (q, r) in &rows {
        body.push_str(&format!(
            "| {} | {q} | {} | {:+.4} | [{:+.4}, {:+.4}] | {:.4} | {:.4} ({}) | {:.2} ({:.3}) | {:+.2} | {} |\n",
            r.family,
            r.n_pairs,
            r.mean_log,
            r.interval95.0,
            r.interval95.1,
            r.sd_engines,
            r.chaos_sd,
            r.chaos_df,
            r.f_ratio,
            r.f_p,
            r.z_chaos,
            r.verdict
        ));
    }
    (
        notes,
        Some(crate::report::Section {
            title: "Engine agreement against chaos".into(),
            body,
            figures: Vec::new(),
        }),
    )
}

/// ln(K_native / K_liggghts) of every bed pair of the family's penetration cases in the
/// sealed run summaries found in `dirs`, each case version and bed once.
fn penetration_engine_logs(fam: &Family, dirs: &[PathBuf], notes: &mut Vec<String>) -> Vec<f64> {
    let mut seen = std::collections::BTreeSet::new();
    let mut logs = Vec::new();
    for p in &fam.cases {
        let Ok(pc) = penetration_case(p) else {
            continue;
        };
        let Some(d) = find_summary(dirs, &pc.name) else {
            continue;
        };
        let s = match super::penetration::run_seal::verify(&d, &pc) {
            Ok(v) => v.summary,
            Err(e) => {
                notes.push(format!(
                    "{}: left out of the chaos comparison: {e:#}",
                    pc.name
                ));
                continue;
            }
        };
        let (Some(n), Some(r)) = (s.engines.get("native"), s.engines.get("liggghts")) else {
            continue;
        };
        for (k, (a, b)) in n.k_phi_beds.iter().zip(&r.k_phi_beds).enumerate() {
            let bed = s
                .bed_hashes
                .get(k)
                .cloned()
                .unwrap_or_else(|| k.to_string());
            if seen.insert((s.canonical_hash.clone(), bed)) {
                logs.push((a / b).ln());
            }
        }
    }
    logs
}

/// (D_native - D_lammps) / d of every variant of the family's 2D cases, from the
/// `final_depths.json` of their runs found in `dirs` (`DIR/<case name>/`), each case
/// version and variant once. A file written by another version of the case (its
/// canonical hash) is named in a note and left out.
fn impact2d_engine_differences(
    fam: &Family,
    dirs: &[PathBuf],
    notes: &mut Vec<String>,
) -> Vec<f64> {
    let mut seen = std::collections::BTreeSet::new();
    let mut diffs = Vec::new();
    for p in &fam.cases {
        let Ok(crate::case::AnyCase::Impact2d(ic)) = crate::case::AnyCase::load(p) else {
            notes.push(format!(
                "{}: not an impact2d case, left out of a 2D family's chaos comparison",
                p.display()
            ));
            continue;
        };
        let hash = ic.canonical_hash().to_string();
        let Some(file) = dirs
            .iter()
            .map(|d| d.join(&ic.name).join(super::impact2d::FINAL_DEPTHS_FILE))
            .find(|f| f.is_file())
        else {
            continue;
        };
        match super::impact2d::read_final_depths(&file, &hash) {
            Ok(pairs) => {
                for (label, a, b) in pairs {
                    if seen.insert((hash.clone(), label)) {
                        diffs.push(a - b);
                    }
                }
            }
            Err(e) => notes.push(format!(
                "{}: left out of the chaos comparison: {e:#}",
                ic.name
            )),
        }
    }
    diffs
}

/// The cross-scale MALT verdict (docs/stress.md rule 6) of the suite's stress cases whose
/// `malt_points.json` is found in `dirs`: a report section with the table and, when any
/// point exists, the figure `malt_verdict.svg` written into `out`. A run of another
/// version of a case (canonical hash) is named in a note and left out. Reporting only:
/// every gate stays in its case.
pub fn malt_verdict(
    suite: &Suite,
    dirs: &[PathBuf],
    out: &Path,
) -> (Vec<String>, Option<crate::report::Section>) {
    use crate::compare::malt_points::{MaltPoints, table};
    let mut notes = Vec::new();
    let mut points = Vec::new();
    for e in suite.cases.iter().filter(|e| e.stress) {
        let Ok(pc) = penetration_case(&e.path) else {
            continue;
        };
        let hash = crate::case::ValidatedCase::canonical_hash(&pc).to_string();
        let mut unreadable = Vec::new();
        let found = dirs.iter().find_map(|d| {
            [d.join(&pc.name), d.to_path_buf()]
                .into_iter()
                .find_map(|c| match MaltPoints::read(&c) {
                    Ok(m) => Some(m).filter(|m| m.case == pc.name),
                    Err(e) => {
                        if c.join(crate::compare::malt_points::MALT_POINTS_FILE)
                            .exists()
                        {
                            unreadable.push(format!("{e:#}"));
                        }
                        None
                    }
                })
        });
        if found.is_none() {
            for e in unreadable {
                notes.push(format!("MALT verdict: {e}; left out"));
            }
        }
        match found {
            Some(m) if m.canonical_hash == hash => points.push(m),
            Some(_) => notes.push(format!(
                "MALT verdict: the points of {} are of another version of the case (canonical hash); left out",
                pc.name
            )),
            None => {}
        }
    }
    // Independent angles (rule 5's triaxial test) of the suite's other cases.
    let mut angles = Vec::new();
    for e in &suite.cases {
        let Ok(c) = crate::case::AnyCase::load(&e.path) else {
            continue;
        };
        let crate::case::AnyCase::Triaxial(tc) = &c else {
            continue;
        };
        let hash = crate::case::ValidatedCase::canonical_hash(tc).to_string();
        let name = c.name().to_string();
        let found = dirs.iter().find_map(|d| {
            [d.join(&name), d.to_path_buf()]
                .into_iter()
                .find_map(|dir| {
                    crate::compare::malt_points::IndependentAngles::read(&dir)
                        .ok()
                        .filter(|a| a.case == name)
                })
        });
        match found {
            Some(a) if a.canonical_hash == hash => angles.extend(a.angles),
            Some(_) => notes.push(format!(
                "MALT verdict: the angles of {name} are of another version of the case (canonical hash); left out"
            )),
            None => {}
        }
    }
    if points.is_empty() && angles.is_empty() {
        return (notes, None);
    }
    let mut section = crate::report::Section {
        title: "MALT across scales (docs/stress.md rule 6)".into(),
        body: format!(
            "Reported, not gated: each case keeps its own engine and MALT gates. phi(K_phi) is eq 10 inverted at the measured K_phi; 'v2 - phi(K)' is how far the stress-field angle sits from the MALT curve in phi.\n\n{}",
            table(&points, &angles)
        ),
        figures: Vec::new(),
    };
    const FIGURE: &str = "malt_verdict.svg";
    match draw_malt_verdict(&out.join(FIGURE), &points, &angles) {
        Ok(()) => section.figures.push(FIGURE.into()),
        Err(e) => notes.push(format!("MALT verdict figure not written: {e:#}")),
    }
    (notes, Some(section))
}

fn draw_malt_verdict(
    path: &Path,
    points: &[crate::compare::malt_points::MaltPoints],
    angles: &[crate::compare::malt_points::IndependentAngle],
) -> Result<()> {
    use crate::report::field_svg::{KPhiPoint, PhiBand, k_phi_plane};
    use crate::report::palette::Source;
    let curve: Vec<(f64, f64)> = crate::analysis::malt::table(45.0, 0.5)?
        .into_iter()
        .filter(|(_, k)| *k <= 2e3)
        .collect();
    // (label, engine key, group: one marker shape per case and scale, point)
    type Labelled<'a> = (
        String,
        &'a str,
        String,
        &'a crate::compare::malt_points::MaltPoint,
    );
    let labels: Vec<Labelled> = points
        .iter()
        .flat_map(|m| {
            m.engines.iter().map(move |(engine, e)| {
                (
                    format!("{} {engine}, phi v2 (R/d {:.1})", m.case, m.scale.r_over_d),
                    engine.as_str(),
                    format!("{} (R/d {:.1})", m.case, m.scale.r_over_d),
                    e,
                )
            })
        })
        .collect();
    let kp: Vec<KPhiPoint> = labels
        .iter()
        .map(|(l, engine, group, e)| KPhiPoint {
            label: l,
            source: Source::of_engine_key(engine),
            group,
            reported: false,
            phi_deg: e.phi_v2_deg,
            phi_err: e.phi_v2_sd_deg,
            k: e.k_phi,
            k_err: e.k_phi_se,
        })
        .collect();
    let bands: Vec<PhiBand> = angles
        .iter()
        .map(|a| PhiBand {
            label: &a.label,
            source: a.engine.map_or(Source::Other, Source::from),
            phi_deg: a.phi_deg,
            half_width_deg: a.se_deg,
        })
        .collect();
    k_phi_plane(
        path,
        &"MALT across scales: K_phi vs phi (eq 10)".into(),
        &curve,
        &kp,
        &bands,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2D family: each variant's D_native - D_lammps from the run's final-depth file
    /// (of this case version only) against the 2D chaos record's (D - D') / d, in a row
    /// that says what it compares; a family that mixes record kinds gets a note, no row.
    #[test]
    fn a_2d_family_pairs_final_depths_per_variant_against_its_chaos_record() {
        use crate::experiments::chaos::{ChaosRecord, IMPACT2D, PENETRATION};
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
        let suite = load(&root, "release").unwrap();
        let path = root.join("release/kondic-fig11-size.toml");
        let Ok(crate::case::AnyCase::Impact2d(ic)) = crate::case::AnyCase::load(&path) else {
            panic!("kondic-fig11-size.toml is an impact2d case");
        };
        let d = tempfile::tempdir().unwrap();
        let record = |kind: &str, name: &str| {
            let r = ChaosRecord {
                case: ic.name.clone(),
                canonical_hash: ic.canonical_hash().to_string(),
                family: "k".into(),
                kind: kind.into(),
                bed_hashes: vec!["x".into(); 3],
                variants: vec!["a".into(), "b".into(), "c".into()],
                fit_h: None,
                k_phi: Vec::new(),
                k_phi_nudged: Vec::new(),
                log_ratio: vec![0.1, -0.1, 0.05],
                final_depth: vec![13.0; 3],
                final_depth_nudged: vec![12.8, 13.3, 13.1],
                depth_difference: vec![0.2, -0.3, -0.1],
                granval: "0".into(),
            };
            let dir = d.path().join(name);
            std::fs::create_dir_all(&dir).unwrap();
            r.write(&dir).unwrap();
            dir.join(crate::experiments::chaos::CHAOS_FILE)
        };
        let runs = d.path().join("runs");
        std::fs::create_dir_all(runs.join(&ic.name)).unwrap();
        let obs = |l: &str, x: f64| serde_json::json!({"label": l, "final_depth": x});
        std::fs::write(
            runs.join(&ic.name)
                .join(super::super::impact2d::FINAL_DEPTHS_FILE),
            serde_json::json!({
                "canonical_hash": ic.canonical_hash().to_string(),
                "native": [obs("a", 13.0), obs("b", 13.2), obs("c", 12.9)],
                "lammps": [obs("a", 13.1), obs("b", 13.0), obs("c", 12.9)],
            })
            .to_string(),
        )
        .unwrap();
        let family = |chaos: Vec<PathBuf>| Suite {
            families: vec![Family {
                name: "kondic-size".into(),
                cases: vec![path.clone()],
                chaos,
            }],
            ..suite.clone()
        };
        let dirs = vec![runs.clone()];
        let (notes, section) = chaos_section(&family(vec![record(IMPACT2D, "2d")]), &dirs);
        let body = section.expect("a 2D family row").body;
        // Pairs -0.1, +0.2, 0.0 (mean +0.0333); chaos s_c = sqrt((0.04 + 0.09 + 0.01) / 3).
        assert!(notes.is_empty(), "{notes:?}");
        assert!(
            body.contains("| kondic-size | (D_n - D_L) / d | 3 | +0.0333 |")
                && body.contains("| 0.2160 (3) |"),
            "{body}"
        );
        let (notes, section) = chaos_section(
            &family(vec![record(IMPACT2D, "2d"), record(PENETRATION, "p")]),
            &dirs,
        );
        assert!(section.is_none(), "{section:?}");
        assert!(
            notes.iter().any(|n| n.contains("different kinds")),
            "{notes:?}"
        );
        // Another version of the case: left out, named.
        let other = d.path().join("other");
        std::fs::create_dir_all(other.join(&ic.name)).unwrap();
        std::fs::write(
            other
                .join(&ic.name)
                .join(super::super::impact2d::FINAL_DEPTHS_FILE),
            serde_json::json!({"canonical_hash": "0", "native": [], "lammps": []}).to_string(),
        )
        .unwrap();
        let (notes, section) = chaos_section(&family(vec![record(IMPACT2D, "2d")]), &[other]);
        assert!(section.is_none(), "{section:?}");
        assert!(
            notes.iter().any(|n| n.contains("another version")),
            "{notes:?}"
        );
    }

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
            "{HEAD}[[claim]]\nname = \"n\"\nsource = \"s\"\ncases = [\"release/a.toml\", \"release/b.toml\"]\nkind = \"ratio_at_least\"\nquantity = \"k_phi\"\nratio = 2.0\n"
        );
        write(d.path(), &ok);
        let s = load(d.path(), "s").unwrap();
        assert_eq!(s.claims.len(), 1);
        assert_eq!(s.reference_root(Path::new("r")), Path::new("r/release"));
        // A misspelt field is an error, not a silently defaulted one.
        write(d.path(), &ok.replace("ratio = ", "ration = "));
        assert!(load(d.path(), "s").is_err());
        // The retired standard-error multiple is refused with its reason.
        write(
            d.path(),
            &ok.replace("ratio_at_least", "increasing")
                .replace("ratio = 2.0", "min_step_se = 2.0"),
        );
        let e = format!("{:#}", load(d.path(), "s").unwrap_err());
        assert!(e.contains("retired"), "{e}");
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

    /// Two case files with one `[case] name`, or one file listed twice, are refused
    /// naming both; distinct names load (the negative control).
    /// A suite entry may leave the case's quasi-static test out (`quasi_static = false`);
    /// by default it runs, as does theory gating; any other value is refused.
    #[test]
    fn entries_say_whether_the_quasi_static_test_runs() {
        let d = tempfile::tempdir().unwrap();
        let named = |n: &str| format!("[case]\nname = \"{n}\"\nkind = \"micro\"\n");
        write(
            d.path(),
            "description = \"d\"\n[[case]]\npath = \"release/a.toml\"\nquasi_static = false\n[[case]]\npath = \"release/b.toml\"\n",
        );
        std::fs::write(d.path().join("release/a.toml"), named("x")).unwrap();
        std::fs::write(d.path().join("release/b.toml"), named("y")).unwrap();
        let s = load(d.path(), "s").unwrap();
        assert_eq!(
            s.cases
                .iter()
                .map(|c| (c.quasi_static, c.theory))
                .collect::<Vec<_>>(),
            [(false, true), (true, true)]
        );
        write(
            d.path(),
            "description = \"d\"\n[[case]]\npath = \"release/a.toml\"\nquasi_static = \"no\"\n",
        );
        let e = format!("{:#}", load(d.path(), "s").unwrap_err());
        assert!(e.contains("quasi_static"), "{e}");
    }

    #[test]
    fn case_names_are_unique_within_a_suite() {
        let d = tempfile::tempdir().unwrap();
        write(d.path(), HEAD);
        let named = |n: &str| format!("[case]\nname = \"{n}\"\nkind = \"micro\"\n");
        std::fs::write(d.path().join("release/a.toml"), named("x")).unwrap();
        std::fs::write(d.path().join("release/b.toml"), named("y")).unwrap();
        assert!(load(d.path(), "s").is_ok());
        std::fs::write(d.path().join("release/b.toml"), named("x")).unwrap();
        let e = format!("{:#}", load(d.path(), "s").unwrap_err());
        assert!(
            e.contains("release/a.toml and")
                && e.contains("release/b.toml both declare [case] name = \"x\""),
            "{e}"
        );
        std::fs::write(d.path().join("release/b.toml"), named("y")).unwrap();
        write(
            d.path(),
            &format!("{HEAD}[[case]]\npath = \"release/*.toml\"\n"),
        );
        std::fs::write(d.path().join("release/a.toml"), named("x")).unwrap();
        std::fs::write(d.path().join("release/b.toml"), named("y")).unwrap();
        let e = format!("{:#}", load(d.path(), "s").unwrap_err());
        assert!(
            e.contains("release/a.toml") && e.contains("list each case file once"),
            "{e}"
        );
    }

    /// Claims read the cases' sealed summaries: all present gives one check per engine;
    /// a summary of another version of the case (its run sealed for another canonical
    /// hash) is an error; a missing one NOT COMPARED, or only a note (naming what did
    /// not run) when a subset ran.
    #[test]
    fn claims_are_evaluated_from_current_summaries_only() {
        use crate::case::AnyCase;
        use crate::compare::Status;
        use crate::experiments::penetration::run_seal;
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
        let case = |p: &Path| match AnyCase::load(p).unwrap() {
            AnyCase::Penetration(c) => c,
            _ => panic!(),
        };
        let write = |p: &Path, p_level: f64| {
            let c = case(p);
            run_seal::sealed_test_run(&c, &d.path().join(&c.name), |_, h| {
                p_level * (20.0 * h + 3.0)
            })
            .unwrap();
        };
        let dirs = vec![d.path().to_path_buf()];
        let (checks, notes) = evaluate_claims(&one, &dirs, true);
        assert!(
            checks.is_empty() && notes.len() == 1,
            "{checks:?} {notes:?}"
        );
        write(&claim.cases[0], 1.0);
        // A subset that ran one of the two cases has not judged the claim: a note names
        // the case that did not run (the release gate counts the claim as not run).
        let (checks, notes) = evaluate_claims(&one, &dirs, true);
        assert!(checks.is_empty(), "{checks:?}");
        assert!(
            notes.len() == 1 && notes[0].contains("did not run here"),
            "{notes:?}"
        );
        // The whole suite without it: NOT COMPARED, naming it.
        let (checks, _) = evaluate_claims(&one, &dirs, false);
        assert_eq!(checks.len(), 1);
        assert_eq!(checks[0].status, Status::NotCompared);
        write(&claim.cases[1], 12.0);
        let (checks, notes) = evaluate_claims(&one, &dirs, false);
        assert_eq!(
            checks.len(),
            3,
            "native, liggghts and the sweep-ignored control"
        );
        assert!(checks.iter().all(|c| c.passed), "{checks:?}");
        // The report names where each summary came from.
        let name = case(&claim.cases[1]).name;
        assert!(
            notes.iter().any(|n| n
                .contains(&format!("{name} from {}", d.path().join(&name).display()))
                && n.contains("run seal verified")),
            "{notes:?}"
        );
        // Both summaries present: the claim gets its section and two figures.
        let (fig_notes, sections) = claim_sections(&one, &dirs, d.path());
        assert!(fig_notes.is_empty(), "{fig_notes:?}");
        assert_eq!(sections.len(), 1);
        assert_eq!(sections[0].figures.len(), 2, "{:?}", sections[0]);
        for f in &sections[0].figures {
            let svg = std::fs::read_to_string(d.path().join(f)).unwrap();
            assert!(svg.contains("<svg"), "{f}");
        }
        // A run of another version of the case: the seal names another canonical hash.
        let seal = d.path().join(&name).join(run_seal::RUN_SEAL_FILE);
        let text = std::fs::read_to_string(&seal).unwrap();
        let other = crate::case::ValidatedCase::canonical_hash(&case(&claim.cases[0]));
        let hash = crate::case::ValidatedCase::canonical_hash(&case(&claim.cases[1]));
        std::fs::write(&seal, text.replace(hash.hex(), other.hex())).unwrap();
        assert!(
            claim_sections(&one, &dirs, d.path()).1.is_empty(),
            "a stale case has no figures"
        );
        let (checks, _) = evaluate_claims(&one, &dirs, false);
        assert_eq!(checks[0].status, Status::Error, "{checks:?}");
        assert!(checks[0].detail.contains("another version"), "{checks:?}");
    }

    /// Claim controls are checked against the case files when the suite is read, and a
    /// case control reads the case's own sealed control run: it bites when the claim
    /// then fails, and is an error when that run is missing.
    #[test]
    fn claim_controls_name_real_runs() {
        use crate::compare::Status;
        use crate::experiments::penetration::run_seal;
        let real = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/release");
        let d = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(d.path().join("suites")).unwrap();
        std::fs::create_dir_all(d.path().join("release")).unwrap();
        for n in [
            "feng-table3-speed-1",
            "feng-fig3b-mugg-0.5",
            "ci-seeds-20261200",
        ] {
            std::fs::copy(
                real.join(format!("{n}.toml")),
                d.path().join(format!("release/{n}.toml")),
            )
            .unwrap();
        }
        let suite = |a: &str, b: &str, control: &str| {
            let text = format!(
                "description = \"d\"\n[[case]]\npath = \"release/{a}.toml\"\n[[case]]\npath = \"release/{b}.toml\"\n[[claim]]\nname = \"n\"\nsource = \"s\"\ncases = [\"release/{a}.toml\", \"release/{b}.toml\"]\nkind = \"independent\"\nquantity = \"k_phi\"\nmax_rel = 0.1\n[[claim.negative_control]]\nname = \"c\"\n{control}\n"
            );
            std::fs::write(d.path().join("suites/s.toml"), text).unwrap();
            load(d.path(), "s")
        };
        let case_control = |c: &str| {
            format!(
                "kind = \"case_control\"\ncase = \"release/feng-table3-speed-1.toml\"\ncontrol = \"{c}\""
            )
        };
        let (a, b) = ("feng-table3-speed-1", "feng-fig3b-mugg-0.5");
        let e = format!("{:#}", suite(a, b, &case_control("no such")).unwrap_err());
        assert!(e.contains("no negative control of that name"), "{e}");
        let e = format!(
            "{:#}",
            suite(a, "ci-seeds-20261200", "kind = \"sweep_ignored\"").unwrap_err()
        );
        assert!(e.contains("needs the same beds"), "{e}");
        assert!(suite(a, b, "kind = \"sweep_ignored\"").is_ok());
        let s = suite(a, b, &case_control("mu_gg = 0.3 instead of 0.5")).unwrap();

        let out = tempfile::tempdir().unwrap();
        // Bed k's force rises with slope k_bed = k - 3, k, k + 3.
        let write = |case: &Path, sub: &str, k: f64| {
            let AnyCase::Penetration(c) = AnyCase::load(case).unwrap() else {
                panic!()
            };
            run_seal::sealed_test_run(&c, &out.path().join(&c.name).join(sub), |b, h| {
                (k + 3.0 * (b as f64 - 1.0)) * h + 3.0
            })
            .unwrap();
        };
        use crate::case::AnyCase;
        write(&s.cases[0].path, "", 30.0);
        write(&s.cases[1].path, "", 31.0);
        let dirs = vec![out.path().to_path_buf()];
        let (checks, _) = evaluate_claims(&s, &dirs, false);
        assert_eq!(checks.len(), 3, "{checks:?}");
        assert!(checks[..2].iter().all(|c| c.passed), "{checks:?}");
        assert_eq!(
            checks[2].status,
            Status::Error,
            "no control run: {checks:?}"
        );
        write(&s.cases[0].path, "control-0", 22.0);
        let (checks, _) = evaluate_claims(&s, &dirs, false);
        assert!(checks[2].passed, "the control bites: {checks:?}");
    }
}
