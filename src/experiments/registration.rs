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
pub(crate) const DESCRIPTIVE_CLAIM_KEYS: [&str; 4] = ["source", "x", "x_label", "paper_k_phi"];

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
pub(crate) fn claim_rules(text: &str) -> std::result::Result<Vec<(String, String)>, String> {
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
pub(crate) fn rules_hash(v: &toml::Value) -> String {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare::{Gate, Status};

    /// A git repository in a temporary directory with a suite `s` of cases `a` and `b`
    /// and a claim over both; commits are made at given times (Unix s).
    struct Repo {
        dir: tempfile::TempDir,
    }

    const T0: i64 = 1_764_000_000;

    const CASE: &str = "[case]\nname = \"NAME\"\nkind = \"penetration\"\ndescription = \"d\"\n\n[compare]\ntolerance = 3e-5\nwindow = [1, 2]\n";

    const SUITE: &str = "description = \"s\"\nreference = \"release\"\nregistration = \"git\"\n[[case]]\npath = \"release/a.toml\"\n[[case]]\npath = \"release/b.toml\"\n\n[[claim]]\nname = \"c\"\nsource = \"a paper\"\ncases = [\"release/a.toml\", \"release/b.toml\"]\nx = [1.0, 2.0]\nkind = \"ratio_at_least\"\nquantity = \"k_phi\"\nratio = 2.0\n";

    impl Repo {
        fn new() -> Repo {
            let r = Repo {
                dir: tempfile::tempdir().unwrap(),
            };
            r.git(&["init", "-q"], T0);
            r
        }

        fn path(&self, rel: &str) -> PathBuf {
            self.dir.path().join(rel)
        }

        fn write(&self, rel: &str, text: &str) {
            let p = self.path(rel);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, text).unwrap();
        }

        fn case(&self, name: &str) {
            self.write(
                &format!("cases/release/{name}.toml"),
                &CASE.replace("NAME", name),
            );
        }

        /// A record of case `name` sealed at `sealed`.
        fn record(&self, name: &str, sealed: i64) {
            self.write(
                &format!("reference/release/penetration/{name}/seal.json"),
                &format!(
                    "{{\"case_name\": \"{name}\", \"sealed\": \"{}\"}}",
                    date(sealed)
                ),
            );
        }

        fn git(&self, args: &[&str], at: i64) {
            let when = format!("@{at} +0000");
            let out = Command::new("git")
                .arg("-C")
                .arg(self.dir.path())
                .args([
                    "-c",
                    "user.name=t",
                    "-c",
                    "user.email=t@t",
                    "-c",
                    "commit.gpgsign=false",
                ])
                .args(args)
                .env("GIT_AUTHOR_DATE", &when)
                .env("GIT_COMMITTER_DATE", &when)
                .output()
                .unwrap();
            assert!(out.status.success(), "git {args:?}: {out:?}");
        }

        fn commit(&self, at: i64) {
            self.git(&["add", "-A"], at);
            self.git(&["commit", "-q", "-m", "m"], at);
        }

        fn registration(&self) -> Registration {
            let cases = self.path("cases");
            let s = super::super::suite::load(&cases, "s").unwrap();
            of_suite(&s, &s.reference_root(&self.path("reference")))
                .unwrap()
                .expect("the suite registers")
        }
    }

    fn case<'a>(r: &'a Registration, name: &str) -> &'a Standing {
        r.cases.iter().find(|s| s.name == name).unwrap()
    }

    /// Cases and the suite committed at T0, both records sealed at T0 + 100 and
    /// committed at T0 + 200.
    fn registered() -> Repo {
        let r = Repo::new();
        r.case("a");
        r.case("b");
        r.write("cases/suites/s.toml", SUITE);
        r.commit(T0);
        r.record("a", T0 + 100);
        r.record("b", T0 + 100);
        r.commit(T0 + 200);
        r
    }

    /// (a) A case committed before its record was sealed and unchanged since is
    /// registered, and so is the claim over it.
    #[test]
    fn a_case_committed_before_its_seal_is_registered() {
        let r = registered();
        let g = r.registration();
        assert_eq!(g.unavailable, None);
        for s in g.cases.iter().chain(&g.claims) {
            assert_eq!(s.exploratory, None, "{s:?}");
            assert_eq!(s.rules_sha256.len(), 64);
        }
        assert!(
            case(&g, "a")
                .basis
                .contains("before its record was sealed on"),
            "{:?}",
            case(&g, "a")
        );
    }

    /// (b) A rule changed after the seal makes the case EXPLORATORY, naming the seal's
    /// date and the commit; the claim over it follows. An uncommitted change does too.
    #[test]
    fn a_case_changed_after_its_seal_is_exploratory() {
        let r = registered();
        r.write(
            "cases/release/a.toml",
            &CASE.replace("NAME", "a").replace("3e-5", "4e-5"),
        );
        let g = r.registration();
        let why = case(&g, "a").exploratory.clone().unwrap();
        assert!(
            why.contains("case file changed after its record was sealed on")
                && why.contains(&date(T0 + 100))
                && why.contains("uncommitted change"),
            "{why}"
        );
        r.commit(T0 + 300);
        let g = r.registration();
        let why = case(&g, "a").exploratory.clone().unwrap();
        assert!(
            why.contains(&date(T0 + 300)) && why.contains("commit "),
            "{why}"
        );
        assert_eq!(case(&g, "b").exploratory, None);
        let claim = g.claims[0].exploratory.clone().unwrap();
        assert!(
            claim.contains("reads case a, which is EXPLORATORY"),
            "{claim}"
        );
    }

    /// (c) A case and its record first committed in one commit were not registered
    /// before the run, even when that commit's date is before the seal's.
    #[test]
    fn a_case_committed_with_its_record_is_exploratory() {
        let r = registered();
        r.case("c");
        r.record("c", T0 + 400);
        r.write(
            "cases/suites/s.toml",
            &SUITE.replace(
                "[[claim]]",
                "[[case]]\npath = \"release/c.toml\"\n\n[[claim]]",
            ),
        );
        // Committed with a date before the seal: only the shared commit tells.
        r.commit(T0 + 300);
        let g = r.registration();
        let why = case(&g, "c").exploratory.clone().unwrap();
        assert!(
            why.contains("case file and its record first committed together in commit"),
            "{why}"
        );
        assert_eq!(case(&g, "a").exploratory, None);
    }

    /// (d) Comments, key order, blank lines, number notation and the description are
    /// not rules: a case edited only in those after its seal stays registered.
    #[test]
    fn a_layout_only_edit_after_the_seal_keeps_a_case_registered() {
        let r = registered();
        let before = registered().registration();
        r.write(
            "cases/release/a.toml",
            "# a comment\n[compare]\nwindow = [ 1, 2 ]   # same\ntolerance = 3.0e-5\n\n[case]\nkind = \"penetration\"\nname = \"a\"\ndescription = \"another description\"\n",
        );
        r.commit(T0 + 300);
        let g = r.registration();
        assert_eq!(case(&g, "a").exploratory, None, "{:?}", case(&g, "a"));
        assert_eq!(case(&g, "a").rules_sha256, case(&before, "a").rules_sha256);
        // The negative control: an integer where a float was is another value.
        r.write(
            "cases/release/a.toml",
            &CASE.replace("NAME", "a").replace("[1, 2]", "[1.0, 2]"),
        );
        assert!(case(&r.registration(), "a").exploratory.is_some());
    }

    /// (e) A claim table changed after a record it reads is EXPLORATORY; its
    /// descriptive keys (source, x) are not rules.
    #[test]
    fn a_claim_changed_after_a_record_it_reads_is_exploratory() {
        let r = registered();
        r.write(
            "cases/suites/s.toml",
            &SUITE
                .replace("a paper", "another citation")
                .replace("x = [1.0, 2.0]", "x = [0.5, 2.0]\nx_label = \"v\""),
        );
        r.commit(T0 + 300);
        assert_eq!(r.registration().claims[0].exploratory, None);
        r.write(
            "cases/suites/s.toml",
            &SUITE.replace("ratio = 2.0", "ratio = 1.5"),
        );
        r.commit(T0 + 400);
        let g = r.registration();
        let why = g.claims[0].exploratory.clone().unwrap();
        assert!(
            why.contains("claim table changed after the record of a was sealed on")
                && why.contains(&date(T0 + 400)),
            "{why}"
        );
        assert!(g.cases.iter().all(|s| s.exploratory.is_none()));
        // A claim added after the records it reads were sealed was never registered.
        let renamed = SUITE.replace("name = \"c\"", "name = \"d\"");
        r.write("cases/suites/s.toml", &renamed);
        r.commit(T0 + 500);
        let why = r.registration().claims[0].exploratory.clone().unwrap();
        assert!(why.contains("was not in the suite file"), "{why}");
    }

    /// A case without a record is registered when its rules are committed, EXPLORATORY
    /// while they are not.
    #[test]
    fn a_case_without_a_record_needs_committed_rules() {
        let r = Repo::new();
        r.case("a");
        r.case("b");
        r.write("cases/suites/s.toml", SUITE);
        r.commit(T0);
        let g = r.registration();
        assert!(case(&g, "a").basis.contains("no record yet"), "{g:?}");
        assert_eq!(g.claims[0].exploratory, None);
        r.write(
            "cases/release/b.toml",
            &CASE.replace("NAME", "b").replace("[1, 2]", "[1, 3]"),
        );
        let why = case(&r.registration(), "b").exploratory.clone().unwrap();
        assert!(why.contains("uncommitted changes"), "{why}");
    }

    /// (f) Without git history (here: not a git checkout) nothing is EXPLORATORY, the
    /// rules are still hashed, and one note says why registration was not checked.
    #[test]
    fn without_git_nothing_is_exploratory_and_a_note_says_why() {
        let r = registered();
        std::fs::remove_dir_all(r.path(".git")).unwrap();
        // Changed after the seal: with history this would be EXPLORATORY.
        r.write(
            "cases/release/a.toml",
            &CASE.replace("NAME", "a").replace("3e-5", "4e-5"),
        );
        let g = r.registration();
        let why = g.unavailable.clone().expect("no checkout");
        assert!(why.contains("git"), "{why}");
        assert!(
            g.cases
                .iter()
                .chain(&g.claims)
                .all(|s| s.exploratory.is_none() && s.rules_sha256.len() == 64)
        );
        let notes = g.notes();
        assert_eq!(notes.len(), 1);
        assert!(
            notes[0].contains("registration could not be checked"),
            "{notes:?}"
        );
        let mut checks = vec![Check::failed("a: k", Gate::KPhi, "m", 1.0, "")];
        checks[0].case = "a".into();
        g.apply(&mut checks);
        assert!(checks[0].exploratory.is_none() && checks[0].rules_sha256.is_some());
    }

    /// Checks are matched to their case by `case` and to their claim by name.
    #[test]
    fn checks_take_the_standing_of_their_case_or_claim() {
        let r = registered();
        r.write(
            "cases/suites/s.toml",
            &SUITE.replace("ratio = 2.0", "ratio = 1.5"),
        );
        r.commit(T0 + 300);
        let g = r.registration();
        let mut of_a = Check::failed("a: K_phi", Gate::KPhi, "m", 1.0, "");
        of_a.case = "a".into();
        let mut checks = vec![
            of_a,
            Check::failed("c (native)", Gate::Claim, "m", 1.0, ""),
            Check::failed(
                "c: negative control \"x\"",
                Gate::NegativeControl,
                "m",
                1.0,
                "",
            ),
            Check::failed("cc (native)", Gate::Claim, "m", 1.0, ""),
        ];
        g.apply(&mut checks);
        assert!(checks[0].exploratory.is_none());
        assert_eq!(
            checks[0].rules_sha256.as_deref(),
            Some(case(&g, "a").rules_sha256.as_str())
        );
        assert!(checks[1].exploratory.is_some() && checks[2].exploratory.is_some());
        assert!(checks[3].exploratory.is_none() && checks[3].rules_sha256.is_none());
        assert_eq!(checks[1].status, Status::Fail, "the verdict is kept");
    }

    /// Canonical rules: key order and float notation do not change the hash; values do.
    #[test]
    fn rules_hash_values_not_text() {
        let a = case_rules("x = 3e-5\ny = \"s\"\n").unwrap();
        assert_eq!(a, case_rules("y = 's'   # c\nx = 0.00003\n").unwrap());
        assert_ne!(a, case_rules("x = 3e-5\ny = \"t\"\n").unwrap());
    }
}
