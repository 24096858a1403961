//! Registration that the records prove (docs/statistics.md, "Registration"): a rule is
//! registered when it was committed before the runs it judges. A record's seal says when
//! its runs were made and git says when each rule was committed, so whether a check's
//! rules came before its data is read from the repository, not from anyone's memory.
//!
//! The rules of a case are its case file parsed as TOML values without `[case]
//! description`; those of a claim its `[[claim]]` table without the keys that only
//! describe or draw it ([`DESCRIPTIVE_CLAIM_KEYS`]). Both are compared as parsed values,
//! so comments and layout never count, and hashed as canonical JSON (`rules_sha256`).
//! Nothing here runs an engine or a comparison: [`of_suite`] reads the case files, the
//! suite file, the seals and git only.

use super::suite::{RegistrationSource, Suite};
use crate::compare::Check;
use crate::rundata::provenance::sha256_hex;
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Keys of a `[[claim]]` table that describe or draw it and decide nothing: the paper's
/// sentence, the figure's axis and the published values drawn beside the engines.
pub const DESCRIPTIVE_CLAIM_KEYS: [&str; 4] = ["source", "x", "x_label", "paper_k_phi"];

/// Whether a case or a claim is a case's or a claim's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Holder {
    Case,
    Claim,
}

impl Holder {
    fn label(self) -> &'static str {
        match self {
            Holder::Case => "case",
            Holder::Claim => "claim",
        }
    }
}

/// The registration of one case or claim.
#[derive(Debug, Clone, PartialEq)]
pub struct Standing {
    pub holder: Holder,
    /// The case's `[case] name`, or the claim's name.
    pub name: String,
    /// The file that holds its rules (the case file, or the suite file).
    pub file: PathBuf,
    /// sha256 of its rules' canonical JSON; empty when the file does not parse.
    pub rules_sha256: String,
    /// Why it is EXPLORATORY; None: registered (or not checkable, see
    /// [`Registration::unavailable`]).
    pub exploratory: Option<String>,
    /// What registered it (the commit its rules were committed in, the seals it precedes).
    pub basis: String,
}

/// The registration of a suite's cases and claims.
#[derive(Debug, Clone, PartialEq)]
pub struct Registration {
    pub cases: Vec<Standing>,
    pub claims: Vec<Standing>,
    /// Why git history could not be read (not a git checkout, no `git`, a shallow
    /// clone): then nothing is marked EXPLORATORY, and the report says so once.
    pub unavailable: Option<String>,
}

impl Registration {
    /// Marks every check of a case (by its `case`) or of a claim (a check with no case,
    /// named after the claim) with its rules hash, and as EXPLORATORY where its case or
    /// claim is.
    pub fn apply(&self, checks: &mut [Check]) {
        for c in checks.iter_mut() {
            let standing = if c.case.is_empty() {
                // The longest claim name the check is named after: `<claim> (<engine>)`,
                // `<claim>: negative control "..."`, or `<claim>` itself.
                self.claims
                    .iter()
                    .filter(|s| {
                        c.name == s.name
                            || c.name.starts_with(&format!("{} (", s.name))
                            || c.name.starts_with(&format!("{}: ", s.name))
                    })
                    .max_by_key(|s| s.name.len())
            } else {
                self.cases.iter().find(|s| s.name == c.case)
            };
            let Some(s) = standing else { continue };
            if !s.rules_sha256.is_empty() {
                c.rules_sha256 = Some(s.rules_sha256.clone());
            }
            if let Some(why) = &s.exploratory {
                c.exploratory = Some(why.clone());
            }
        }
    }

    /// The notes a report carries: that registration could not be checked and why, or
    /// how many cases and claims are EXPLORATORY.
    pub fn notes(&self) -> Vec<String> {
        if let Some(why) = &self.unavailable {
            return vec![format!(
                "registration could not be checked ({why}): no check is marked EXPLORATORY; every verdict is gated as if its rules were registered (docs/statistics.md, \"Registration\")"
            )];
        }
        let count = |v: &[Standing]| v.iter().filter(|s| s.exploratory.is_some()).count();
        vec![format!(
            "registration (docs/statistics.md): {} of {} case(s) and {} of {} claim(s) EXPLORATORY (their rules were not committed before their records were sealed): their verdicts are printed, never gated; see the Registration section",
            count(&self.cases),
            self.cases.len(),
            count(&self.claims),
            self.claims.len()
        )]
    }

    /// Every case and claim, registered or EXPLORATORY and why, one line each.
    pub fn lines(&self) -> Vec<String> {
        self.cases
            .iter()
            .chain(&self.claims)
            .map(|s| match &s.exploratory {
                Some(why) => format!("{} {:?}: EXPLORATORY: {why}", s.holder.label(), s.name),
                None => format!("{} {:?}: registered: {}", s.holder.label(), s.name, s.basis),
            })
            .collect()
    }

    /// The report's "Registration" section: a table of every case and claim.
    pub fn section(&self) -> crate::report::Section {
        use crate::report::text::md_cell;
        let mut body = String::new();
        if let Some(why) = &self.unavailable {
            body.push_str(&format!(
                "Registration could not be checked ({}): no check is marked EXPLORATORY.\n\n",
                md_cell(why)
            ));
        }
        body.push_str(
            "A rule is registered when it was committed before the record it judges was sealed (docs/statistics.md). An EXPLORATORY check is printed with its verdict, never gated.\n\n| | name | rules sha256 | registration |\n|---|---|---|---|\n",
        );
        for s in self.cases.iter().chain(&self.claims) {
            let standing = match &s.exploratory {
                Some(why) => format!("**EXPLORATORY**: {}", md_cell(why)),
                None => md_cell(&format!("registered: {}", s.basis)),
            };
            body.push_str(&format!(
                "| {} | {} | {} | {standing} |\n",
                s.holder.label(),
                md_cell(&s.name),
                s.rules_sha256.get(..12).unwrap_or("-"),
            ));
        }
        crate::report::Section {
            title: "Registration".into(),
            body,
            figures: Vec::new(),
        }
    }
}

/// The registration of `suite` when it declares one (`registration = "git"`), its
/// records under `reference_root` (the suite's own reference directory). Reads case
/// files, the suite file, seals and git; runs nothing.
pub fn of_suite(suite: &Suite, reference_root: &Path) -> Result<Option<Registration>> {
    match suite.registration {
        None => Ok(None),
        Some(RegistrationSource::Git) => registration(suite, reference_root).map(Some),
    }
}

/// One commit of a file's history: its hash, committer time (Unix s) and the file's text.
#[derive(Debug, Clone)]
struct Revision {
    commit: String,
    time: i64,
    text: Option<String>,
}

/// A record as its seal and git tell it.
#[derive(Debug, Clone)]
struct Record {
    case: String,
    sealed: String,
    sealed_at: i64,
    /// The commit that first added its seal (None: not committed).
    first_commit: Option<String>,
}

fn registration(suite: &Suite, reference_root: &Path) -> Result<Registration> {
    let git = Git::open(suite.file.parent().unwrap_or(Path::new(".")));
    let suite_now = std::fs::read_to_string(&suite.file)
        .with_context(|| format!("{}: cannot read the suite file", suite.file.display()))?;
    let claims_now = claim_rules(&suite_now)
        .map_err(|e| anyhow::anyhow!("{}: not a suite file: {e}", suite.file.display()))?;
    let (unavailable, git) = match git {
        Ok(g) => (None, Some(g)),
        Err(why) => (Some(why), None),
    };
    let mut cases = Vec::new();
    let mut records: Vec<(PathBuf, Option<Record>)> = Vec::new();
    for e in &suite.cases {
        let text = std::fs::read_to_string(&e.path)
            .with_context(|| format!("{}: cannot read the case file", e.path.display()))?;
        let (name, kind) = case_identity(&text).unwrap_or_default();
        let name = if name.is_empty() {
            e.path.display().to_string()
        } else {
            name
        };
        let now = case_rules(&text);
        let record = match &git {
            Some(g) => record(g, reference_root, &kind, &name)?,
            None => None,
        };
        let standing = match (&now, &git) {
            (Err(why), _) => Standing {
                holder: Holder::Case,
                name: name.clone(),
                file: e.path.clone(),
                rules_sha256: String::new(),
                exploratory: None,
                basis: format!("its rules could not be read ({why}); the case itself will say"),
            },
            (Ok(rules), None) => Standing {
                holder: Holder::Case,
                name: name.clone(),
                file: e.path.clone(),
                rules_sha256: rules.clone(),
                exploratory: None,
                basis: "not checked".into(),
            },
            (Ok(rules), Some(g)) => {
                let history = g.history(&e.path)?;
                let judged = judge(
                    "case file",
                    rules,
                    &history,
                    |t| case_rules(t).ok(),
                    record.as_slice(),
                );
                Standing {
                    holder: Holder::Case,
                    name: name.clone(),
                    file: e.path.clone(),
                    rules_sha256: rules.clone(),
                    exploratory: judged.as_ref().err().cloned(),
                    basis: judged.unwrap_or_default(),
                }
            }
        };
        cases.push(standing);
        records.push((e.path.clone(), record));
    }
    let suite_history = match &git {
        Some(g) => g.history(&suite.file)?,
        None => Vec::new(),
    };
    let mut claims = Vec::new();
    for c in &suite.claims {
        let rules = claims_now
            .iter()
            .find(|(n, _)| *n == c.name)
            .map(|(_, r)| r.clone())
            .unwrap_or_default();
        let mut standing = Standing {
            holder: Holder::Claim,
            name: c.name.clone(),
            file: suite.file.clone(),
            rules_sha256: rules.clone(),
            exploratory: None,
            basis: "not checked".into(),
        };
        if git.is_some() {
            let of_cases: Vec<(&Standing, Option<&Record>)> = c
                .cases
                .iter()
                .filter_map(|p| {
                    let k = suite.cases.iter().position(|e| e.path == *p)?;
                    Some((&cases[k], records[k].1.as_ref()))
                })
                .collect();
            let judged = match of_cases.iter().find(|(s, _)| s.exploratory.is_some()) {
                Some((s, _)) => Err(format!(
                    "reads case {}, which is EXPLORATORY ({})",
                    s.name,
                    s.exploratory.as_deref().unwrap_or_default()
                )),
                None => {
                    let recs: Vec<Record> =
                        of_cases.iter().filter_map(|(_, r)| r.cloned()).collect();
                    let name = c.name.clone();
                    judge(
                        "claim table",
                        &rules,
                        &suite_history,
                        move |t| {
                            claim_rules(t)
                                .ok()?
                                .into_iter()
                                .find(|(n, _)| *n == name)
                                .map(|(_, r)| r)
                        },
                        &recs,
                    )
                }
            };
            standing.exploratory = judged.as_ref().err().cloned();
            standing.basis = judged.unwrap_or_default();
        }
        claims.push(standing);
    }
    Ok(Registration {
        cases,
        claims,
        unavailable,
    })
}

/// Whether rules `now` (a hash) were registered before every record in `records`, from
/// the `history` of the file that holds them (`rules_at`: the rules hash of one version
/// of its text, None where it holds none). Ok(what registered them) or Err(why the
/// check is EXPLORATORY). `what`: "case file" or "claim table", for the reasons.
fn judge(
    what: &str,
    now: &str,
    history: &[Revision],
    rules_at: impl Fn(&str) -> Option<String>,
    records: &[Record],
) -> std::result::Result<String, String> {
    let versions: Vec<(&Revision, Option<String>)> = history
        .iter()
        .map(|r| (r, r.text.as_deref().and_then(&rules_at)))
        .collect();
    let first = versions.iter().find(|(_, r)| r.is_some()).map(|(v, _)| *v);
    let Some(first) = first else {
        return Err(format!(
            "{what} is not committed: its rules were never registered"
        ));
    };
    if records.is_empty() {
        // No record: no run of it has been seen; its rules must be those committed.
        let (last, rules) = versions.last().expect("a first version exists");
        return match rules.as_deref() {
            Some(r) if r == now => Ok(format!(
                "no record yet; rules as committed in {} on {}",
                short(&last.commit),
                date(last.time)
            )),
            _ => Err(format!(
                "{what} has uncommitted changes to its rules (last commit {} on {}), and no record yet",
                short(&last.commit),
                date(last.time)
            )),
        };
    }
    let mut sorted: Vec<&Record> = records.iter().collect();
    sorted.sort_by_key(|r| r.sealed_at);
    for rec in &sorted {
        let of = if what == "case file" {
            "its record".to_string()
        } else {
            format!("the record of {}", rec.case)
        };
        if rec.first_commit.as_deref() == Some(first.commit.as_str()) {
            return Err(format!(
                "{what} and {of} first committed together in commit {} ({}): the rule was not committed before the run",
                short(&first.commit),
                date(first.time)
            ));
        }
        let at = versions.iter().rev().find(|(v, _)| v.time < rec.sealed_at);
        let Some((at, rules)) = at else {
            return Err(format!(
                "{what} first committed in {} on {}, after {of} was sealed on {}",
                short(&first.commit),
                date(first.time),
                rec.sealed
            ));
        };
        let Some(rules) = rules else {
            return Err(format!(
                "{what} {} at commit {}, the last before {of} was sealed on {} (first committed in {} on {})",
                if what == "case file" {
                    "did not parse"
                } else {
                    "was not in the suite file"
                },
                short(&at.commit),
                rec.sealed,
                short(&first.commit),
                date(first.time)
            ));
        };
        if rules != now {
            let later = versions
                .iter()
                .filter(|(v, _)| v.time >= rec.sealed_at)
                .find(|(_, r)| r.as_deref() != Some(rules.as_str()));
            return Err(match later {
                Some((v, _)) => format!(
                    "{what} changed after {of} was sealed on {}: commit {} on {}",
                    rec.sealed,
                    short(&v.commit),
                    date(v.time)
                ),
                None => format!(
                    "{what} changed after {of} was sealed on {}: an uncommitted change in the working copy",
                    rec.sealed
                ),
            });
        }
    }
    let earliest = sorted[0];
    let (at, _) = versions
        .iter()
        .rev()
        .find(|(v, _)| v.time < earliest.sealed_at)
        .expect("checked above");
    Ok(format!(
        "rules as committed in {} on {}, before {} sealed {}",
        short(&at.commit),
        date(at.time),
        if sorted.len() == 1 {
            "its record was".to_string()
        } else {
            format!("its {} records were", sorted.len())
        },
        if sorted.len() == 1 {
            format!("on {}", earliest.sealed)
        } else {
            format!("from {}", earliest.sealed)
        }
    ))
}

/// The record of case `name` of `kind` under `reference_root`, when it has one.
fn record(g: &Git, reference_root: &Path, kind: &str, name: &str) -> Result<Option<Record>> {
    let seal =
        super::reference::record_root(reference_root, kind, name).join(super::reference::SEAL_FILE);
    let Ok(text) = std::fs::read_to_string(&seal) else {
        return Ok(None);
    };
    // Only its time is read here: a seal that is otherwise wrong is the record's own
    // error, which `check` reports when it verifies the record.
    let sealed = serde_json::from_str::<serde_json::Value>(&text)
        .ok()
        .and_then(|v| Some(v.get("sealed")?.as_str()?.to_string()))
        .with_context(|| format!("{}: no `sealed` time", seal.display()))?;
    let sealed_at = chrono::DateTime::parse_from_rfc3339(&sealed)
        .with_context(|| {
            format!(
                "{}: sealed = {sealed:?}: not an RFC 3339 time",
                seal.display()
            )
        })?
        .timestamp();
    let first_commit = g
        .log(&seal, &["--diff-filter=A"])?
        .into_iter()
        .min_by_key(|(_, t)| *t)
        .map(|(c, _)| c);
    Ok(Some(Record {
        case: name.to_string(),
        sealed,
        sealed_at,
        first_commit,
    }))
}

/// `[case] name` and `[case] kind` of a case file's text.
fn case_identity(text: &str) -> Option<(String, String)> {
    let t: toml::Table = text.parse().ok()?;
    let case = t.get("case")?;
    Some((
        case.get("name")?.as_str()?.to_string(),
        case.get("kind")?.as_str()?.to_string(),
    ))
}

/// The rules hash of a case file's text: its values without `[case] description`.
pub fn case_rules(text: &str) -> std::result::Result<String, String> {
    let mut t: toml::Table = text.parse().map_err(|e| format!("{e}"))?;
    if let Some(toml::Value::Table(case)) = t.get_mut("case") {
        case.remove("description");
    }
    Ok(rules_hash(&toml::Value::Table(t)))
}

/// Every `[[claim]]` of a suite file's text: its name and the hash of its rules (the
/// table without [`DESCRIPTIVE_CLAIM_KEYS`]).
pub fn claim_rules(text: &str) -> std::result::Result<Vec<(String, String)>, String> {
    let t: toml::Table = text.parse().map_err(|e| format!("{e}"))?;
    let Some(claims) = t.get("claim").and_then(|c| c.as_array()) else {
        return Ok(Vec::new());
    };
    Ok(claims
        .iter()
        .filter_map(|c| {
            let mut c = c.as_table()?.clone();
            let name = c.get("name")?.as_str()?.to_string();
            for k in DESCRIPTIVE_CLAIM_KEYS {
                c.remove(k);
            }
            Some((name, rules_hash(&toml::Value::Table(c))))
        })
        .collect())
}

/// sha256 of the canonical JSON of `v`: keys sorted, no whitespace, floats in their
/// shortest round-trip form (so `3e-5` and `3.0e-5` are one value).
pub fn rules_hash(v: &toml::Value) -> String {
    let mut s = String::new();
    canonical(v, &mut s);
    sha256_hex(s.as_bytes())
}

fn canonical(v: &toml::Value, out: &mut String) {
    use toml::Value as V;
    let string = |s: &str| serde_json::to_string(s).expect("a string serialises");
    match v {
        V::String(s) => out.push_str(&string(s)),
        V::Integer(i) => out.push_str(&i.to_string()),
        V::Float(f) if f.is_finite() => {
            out.push_str(&serde_json::to_string(f).expect("a finite float serialises"))
        }
        V::Float(f) => out.push_str(&string(&format!("{f}"))),
        V::Boolean(b) => out.push_str(if *b { "true" } else { "false" }),
        V::Datetime(d) => out.push_str(&string(&d.to_string())),
        V::Array(a) => {
            out.push('[');
            for (k, x) in a.iter().enumerate() {
                if k > 0 {
                    out.push(',');
                }
                canonical(x, out);
            }
            out.push(']');
        }
        V::Table(t) => {
            let mut keys: Vec<&String> = t.keys().collect();
            keys.sort();
            out.push('{');
            for (k, key) in keys.into_iter().enumerate() {
                if k > 0 {
                    out.push(',');
                }
                out.push_str(&string(key));
                out.push(':');
                canonical(&t[key], out);
            }
            out.push('}');
        }
    }
}

fn short(commit: &str) -> &str {
    commit.get(..10).unwrap_or(commit)
}

fn date(t: i64) -> String {
    chrono::DateTime::from_timestamp(t, 0)
        .map(|d| d.format("%Y-%m-%dT%H:%M:%SZ").to_string())
        .unwrap_or_else(|| t.to_string())
}

/// The git checkout the files live in, read with the `git` command line.
struct Git {
    top: PathBuf,
}

impl Git {
    /// The checkout holding `dir`, or why its history cannot be read.
    fn open(dir: &Path) -> std::result::Result<Git, String> {
        let top = run_git(dir, &["rev-parse", "--show-toplevel"])?;
        let top = PathBuf::from(top.trim());
        let shallow = run_git(&top, &["rev-parse", "--is-shallow-repository"])?;
        if shallow.trim() == "true" {
            return Err(format!(
                "{} is a shallow clone: the history before its first commit is missing (git fetch --unshallow)",
                top.display()
            ));
        }
        Ok(Git { top })
    }

    /// `path` relative to the checkout (both resolved, so symbolic links agree).
    fn relative(&self, path: &Path) -> Result<String> {
        let real = std::fs::canonicalize(path)
            .with_context(|| format!("{}: cannot resolve", path.display()))?;
        let top = std::fs::canonicalize(&self.top).unwrap_or_else(|_| self.top.clone());
        let rel = real.strip_prefix(&top).with_context(|| {
            format!(
                "{} is outside the git checkout {}",
                path.display(),
                top.display()
            )
        })?;
        Ok(rel.to_string_lossy().replace('\\', "/"))
    }

    /// (commit, committer time) of every commit touching `path`, with `extra` options.
    fn log(&self, path: &Path, extra: &[&str]) -> Result<Vec<(String, i64)>> {
        let rel = self.relative(path)?;
        let mut args = vec!["log", "--format=%H %ct"];
        args.extend_from_slice(extra);
        args.extend(["--", rel.as_str()]);
        let out = run_git(&self.top, &args).map_err(anyhow::Error::msg)?;
        Ok(out
            .lines()
            .filter_map(|l| {
                let (c, t) = l.split_once(' ')?;
                Some((c.to_string(), t.trim().parse().ok()?))
            })
            .collect())
    }

    /// Every committed version of `path`, oldest first (by committer time).
    fn history(&self, path: &Path) -> Result<Vec<Revision>> {
        let rel = self.relative(path)?;
        let mut v: Vec<Revision> = self
            .log(path, &[])?
            .into_iter()
            .map(|(commit, time)| {
                let text = run_git(&self.top, &["show", &format!("{commit}:{rel}")]).ok();
                Revision { commit, time, text }
            })
            .collect();
        v.reverse();
        v.sort_by_key(|r| r.time);
        Ok(v)
    }
}

/// `git -C dir args...`'s stdout, or why it failed (no `git`, not a checkout).
fn run_git(dir: &Path, args: &[&str]) -> std::result::Result<String, String> {
    let out = Command::new("git")
        .arg("-C")
        .arg(dir)
        .args(args)
        .output()
        .map_err(|e| format!("`git` could not be run: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "git {} in {}: {}",
            args.join(" "),
            dir.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}
