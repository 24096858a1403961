//! Renders verdicts: `report.json` (the stable machine interface), `report.md` (for
//! people) and `report.junit.xml` (for CI dashboards). The exit code follows from
//! [`Report::exit_code`].

pub mod console;
pub mod field_svg;
pub mod gallery;
pub mod junit;
pub mod markdown;
pub mod overlay;
pub mod palette;
pub mod plot;
pub mod progress;
pub mod stress;
pub mod summary;
pub mod svg;
pub mod svg_impact;
pub mod svg_triaxial;
pub mod text;
pub mod vtk;

use crate::compare::expect::{Expectation, GateOutcome, release_gate};
use crate::compare::{Check, Status};
use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The report files of a report directory.
pub(crate) const JSON_FILE: &str = "report.json";
pub(crate) const MARKDOWN_FILE: &str = "report.md";
pub(crate) const JUNIT_FILE: &str = "report.junit.xml";

/// How one case was run: which engines, and whether the reference was live or recorded.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CaseRun {
    pub case: String,
    pub case_file: String,
    pub test_engine: String,
    pub reference_engine: String,
    pub reference_version: String,
    /// "live" or "recorded <dir>".
    pub reference_source: String,
    pub wall_time_test_s: f64,
    pub wall_time_reference_s: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Report {
    pub passed: bool,
    pub checks: Vec<Check>,
    #[serde(default)]
    pub runs: Vec<CaseRun>,
    /// Anything a reader must know to trust the verdict (e.g. recorded fallback).
    #[serde(default)]
    pub notes: Vec<String>,
    /// True if some stage failed to produce a result (engine crash, bad input, a
    /// corrupt reference) or a gate could not be evaluated (not compared).
    #[serde(default)]
    pub errored: bool,
    /// Views across cases that are not checks (a suite's claim figures, the cross-scale
    /// MALT verdict): each a titled Markdown body and its figures, paths relative to the
    /// report directory.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sections: Vec<Section>,
    /// The release gate of a suite with registered expectations (docs/statistics.md):
    /// when present, it decides the exit code; the checks' verdicts are unchanged.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gate: Option<GateOutcome>,
    /// The git commit granval was built from (absent: not built from a git work tree,
    /// or a report written before the field existed): what judged these runs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub granval_commit: Option<String>,
    /// When the verdicts were decided (UTC, RFC 3339, seconds).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub made_utc: Option<String>,
}

/// A titled part of `report.md` after the checks.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Section {
    pub title: String,
    /// Markdown (tables allowed).
    pub body: String,
    /// Figures shown under the body, relative to the report directory.
    #[serde(default)]
    pub figures: Vec<String>,
}

impl Report {
    /// `passed` and `errored` are of the checks that count ([`Check::counts`]): an
    /// EXPLORATORY verdict is printed, never gated (docs/statistics.md, "Registration").
    pub fn new(checks: Vec<Check>, runs: Vec<CaseRun>, notes: Vec<String>) -> Report {
        let counted: Vec<&Check> = checks.iter().filter(|c| c.counts()).collect();
        let errored = counted.iter().any(|c| c.status.undecided());
        let passed =
            !errored && !counted.is_empty() && counted.iter().all(|c| c.status == Status::Pass);
        Report {
            passed,
            checks,
            runs,
            notes,
            errored,
            sections: Vec::new(),
            gate: None,
            granval_commit: crate::rundata::provenance::git_commit(),
            made_utc: Some(chrono::Utc::now().to_rfc3339_opts(chrono::SecondsFormat::Secs, true)),
        }
    }

    /// Judges the checks against a suite's registered expectations (`complete`: the
    /// whole suite ran) and lets that gate decide the exit code.
    pub fn apply_gate(&mut self, expectations: &[Expectation], complete: bool) {
        self.gate = Some(release_gate(&self.checks, expectations, complete));
    }

    /// Checks ran and every one is EXPLORATORY: nothing was gated.
    pub(crate) fn nothing_gated(&self) -> bool {
        !self.checks.is_empty() && self.checks.iter().all(|c| c.exploratory.is_some())
    }

    /// 0 all passed, 1 some check failed, 2 something errored or could not be decided
    /// (or every check was EXPLORATORY: nothing was gated); with a release gate, the
    /// gate's code (every verdict as registered: 0). EXPLORATORY verdicts other than an
    /// ERROR do not count.
    pub fn exit_code(&self) -> i32 {
        if self.nothing_gated() {
            return 2;
        }
        if let Some(g) = &self.gate {
            return g.exit_code;
        }
        if self.errored {
            2
        } else if self.passed {
            0
        } else {
            1
        }
    }

    /// Writes the three report files, each whole or not at all (a temporary file renamed
    /// into place: a full disk or a crash leaves no truncated report); `report.json`, the
    /// machine interface, last, so its presence means the others are complete. An error
    /// names the file that could not be written.
    pub fn write(&self, dir: &Path, title: &str) -> Result<()> {
        use crate::rundata::fsio::write_atomic;
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        write_atomic(&dir.join(MARKDOWN_FILE), self.markdown(title).as_bytes())?;
        write_atomic(&dir.join(JUNIT_FILE), self.junit(title).as_bytes())?;
        write_atomic(
            &dir.join(JSON_FILE),
            (serde_json::to_string_pretty(self)? + "\n").as_bytes(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare::Gate;

    /// A report with an error and a not-compared check (NaN values, written as JSON
    /// null) reads back with the same verdicts and NaN values.
    #[test]
    fn report_json_with_nan_round_trips() {
        let checks = vec![
            Check::error("engine", "LIGGGHTS exited with status 1"),
            Check::not_compared("k", Gate::KPhi, "one bed"),
            Check::at_most("d", Gate::KPhi, "|x|", 0.5, 1.0, ""),
        ];
        let r = Report::new(checks, Vec::new(), vec!["n".into()]);
        let text = serde_json::to_string_pretty(&r).unwrap();
        assert!(text.contains("\"value\": null"));
        let back: Report = serde_json::from_str(&text).unwrap();
        assert_eq!(back.exit_code(), 2);
        assert!(back.checks[0].value.is_nan() && back.checks[1].value.is_nan());
        assert_eq!(back.checks[1].status, Status::NotCompared);
        assert_eq!(back.checks[2].value, 0.5);
        assert_eq!(serde_json::to_string_pretty(&back).unwrap(), text);
    }

    /// An EXPLORATORY verdict (docs/statistics.md, "Registration") is printed with its
    /// reason in every report file and never gated: a FAIL that exits 1 when registered
    /// exits 0 when EXPLORATORY; a run of EXPLORATORY checks only gated nothing (exit 2);
    /// an EXPLORATORY ERROR still exits 2.
    #[test]
    fn exploratory_verdicts_are_printed_never_gated() {
        let pass = || Check::at_most("p", Gate::KPhi, "|x|", 0.5, 1.0, "");
        let fail = || Check::at_most("f", Gate::KPhi, "|x|", 2.0, 1.0, "off by two");
        let why = "case file changed after its record was sealed on 2026-11-24T19:48:27Z";
        let registered = Report::new(vec![pass(), fail()], Vec::new(), Vec::new());
        assert_eq!(registered.exit_code(), 1);
        let mut f = fail().mark_exploratory(why);
        f.rules_sha256 = Some("ab".repeat(32));
        let r = Report::new(vec![pass(), f], Vec::new(), Vec::new());
        assert_eq!((r.exit_code(), r.verdict()), (0, "PASS"));
        assert!(r.passed && !r.errored);
        let md = r.markdown("t");
        assert!(
            md.contains("**FAIL** (EXPLORATORY, not gated)")
                && md.contains(&format!("EXPLORATORY: {why}; off by two"))
                && md.contains("2 checks: 1 pass, 1 FAIL, 0 INCONCLUSIVE, 0 NOT COMPARED, 0 ERROR; 1 of them EXPLORATORY, not gated (exit 0)."),
            "{md}"
        );
        let json = serde_json::to_string(&r).unwrap();
        assert!(
            json.contains(&format!("\"exploratory\":\"{why}\"")),
            "{json}"
        );
        assert!(json.contains(&format!("\"rules_sha256\":\"{}\"", "ab".repeat(32))));
        let back: Report = serde_json::from_str(&json).unwrap();
        assert_eq!(back.checks[1].exploratory.as_deref(), Some(why));
        assert_eq!(back.exit_code(), 0);
        let xml = r.junit("t");
        let doc = roxmltree::Document::parse(&xml).unwrap();
        let skipped = doc
            .descendants()
            .find(|n| n.has_tag_name("skipped"))
            .expect("an EXPLORATORY check is <skipped>");
        assert!(skipped.attribute("message").unwrap().contains(why), "{xml}");
        let root = doc.root_element();
        assert_eq!(
            (root.attribute("failures"), root.attribute("skipped")),
            (Some("0"), Some("1"))
        );
        assert!(!xml.contains("<failure"), "{xml}");
        assert!(
            r.summary("t", 200)
                .contains(&format!("EXPLORATORY, not gated: {why}"))
        );
        // Every check EXPLORATORY: nothing gated, exit 2, whatever the verdicts.
        let none = Report::new(
            vec![pass().mark_exploratory(why), fail().mark_exploratory(why)],
            Vec::new(),
            Vec::new(),
        );
        assert_eq!((none.exit_code(), none.verdict()), (2, "NO GATED CHECKS"));
        // An ERROR counts whatever its rules.
        let crashed = Report::new(
            vec![
                pass(),
                Check::error("engine", "exit 1").mark_exploratory(why),
            ],
            Vec::new(),
            Vec::new(),
        );
        assert_eq!((crashed.exit_code(), crashed.verdict()), (2, "ERROR"));
        let xml = crashed.junit("t");
        assert!(
            xml.contains("<error ") && !xml.contains("<skipped"),
            "{xml}"
        );
    }

    /// The heading tells an engine error from a gate the data could not decide (both
    /// exit 2), and the tally under it counts every verdict.
    #[test]
    fn heading_separates_errors_from_undecided_gates() {
        let pass = || Check::at_most("d", Gate::KPhi, "|x|", 0.5, 1.0, "");
        let fail = || Check::at_most("f", Gate::KPhi, "|x|", 2.0, 1.0, "");
        let undecided = || Check::not_compared("k", Gate::KPhi, "one bed");
        let heading = |checks: Vec<Check>| {
            let r = Report::new(checks, Vec::new(), Vec::new());
            let md = r.markdown("t");
            (md.lines().next().unwrap().to_string(), md, r.exit_code())
        };
        let (h, md, code) = heading(vec![pass(), fail(), undecided()]);
        assert_eq!((h.as_str(), code), ("# t: INCOMPLETE", 2));
        assert!(md.contains(
            "3 checks: 1 pass, 1 FAIL, 0 INCONCLUSIVE, 1 NOT COMPARED, 0 ERROR (exit 2)."
        ));
        let unresolved = || {
            Check::with_status(
                "u",
                Gate::KPhi,
                "x",
                0.1,
                0.2,
                Status::Inconclusive,
                "one bed",
            )
        };
        let (h, _, code) = heading(vec![pass(), unresolved()]);
        assert_eq!((h.as_str(), code), ("# t: INCONCLUSIVE", 2));
        let (h, _, code) = heading(vec![unresolved(), undecided()]);
        assert_eq!((h.as_str(), code), ("# t: INCOMPLETE", 2));
        let (h, _, code) = heading(vec![undecided(), Check::error("engine", "exit 1")]);
        assert_eq!((h.as_str(), code), ("# t: ERROR", 2));
        let (h, _, code) = heading(vec![pass(), fail()]);
        assert_eq!((h.as_str(), code), ("# t: FAIL", 1));
        let (h, md, code) = heading(vec![pass()]);
        assert_eq!((h.as_str(), code), ("# t: PASS", 0));
        assert!(md.contains(
            "1 checks: 1 pass, 0 FAIL, 0 INCONCLUSIVE, 0 NOT COMPARED, 0 ERROR (exit 0)."
        ));
    }
}
