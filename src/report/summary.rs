//! What granval prints on stdout after a comparison: for people, the verdict and the
//! checks that did not pass (the whole report is in `report.md`); for scripts, one line
//! of JSON (`--format json`) with the verdict, the tally and where the report is.

use super::Report;
use super::text::{tolerance, value, visible};
use crate::compare::{Check, Status};
use serde::Serialize;
use std::fmt::Write as _;

/// One line of JSON on stdout (`--format json`): enough for a CI step to decide and
/// point at the report without parsing it.
#[derive(Debug, Serialize)]
pub(crate) struct MachineSummary<'a> {
    pub title: &'a str,
    pub verdict: &'static str,
    pub exit_code: i32,
    pub checks: usize,
    pub pass: usize,
    pub fail: usize,
    pub inconclusive: usize,
    pub not_compared: usize,
    pub error: usize,
    /// Checks printed but not gated (docs/statistics.md, "Registration").
    #[serde(skip_serializing_if = "is_zero")]
    pub exploratory: usize,
    /// The release gate's verdict, when the suite has one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub release_gate: Option<&'static str>,
    /// The report directory (report.json, report.md, report.junit.xml).
    pub report: String,
    /// Every check that did not pass: name, case, verdict.
    pub not_passed: Vec<NotPassed<'a>>,
}

#[derive(Debug, Serialize)]
pub(crate) struct NotPassed<'a> {
    pub name: &'a str,
    pub case: &'a str,
    pub status: Status,
    /// Why the check is EXPLORATORY (not gated), when it is.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exploratory: Option<&'a str>,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl Report {
    /// What granval prints on stdout after a comparison: the verdict, the tally, the
    /// release gate, and every check that did not pass with its value and why (details
    /// other than an error's cut at `width` characters); the notes and passing checks
    /// are in `report.md`.
    pub fn summary(&self, title: &str, width: usize) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "{}: {}", visible(title), self.verdict());
        let _ = writeln!(s, "{}", self.tally());
        if let Some(g) = self.gate_line("") {
            let _ = writeln!(s, "{g}");
        }
        // Where the reference came from when not from a live engine: a pass against a
        // record must never read like a live one.
        for r in &self.runs {
            if let Some(root) = r.reference_source.strip_prefix("recorded ") {
                let _ = writeln!(
                    s,
                    "{}: compared against the RECORDED {} run in {root} (seal verified), not a live engine",
                    visible(&r.case),
                    visible(&r.reference_engine)
                );
            } else if r.reference_source != "live" {
                let _ = writeln!(
                    s,
                    "{}: {} reference from {}",
                    visible(&r.case),
                    visible(&r.reference_engine),
                    visible(&r.reference_source)
                );
            }
        }
        let bad: Vec<&Check> = self
            .checks
            .iter()
            .filter(|c| c.status != Status::Pass)
            .collect();
        if !bad.is_empty() {
            let _ = writeln!(s, "\nNot passed:");
        }
        for c in bad {
            let mut detail = visible(&c.detail).replace('\n', " ");
            if let Some(why) = &c.exploratory {
                detail = format!("EXPLORATORY, not gated: {}; {detail}", visible(why));
            }
            // An error's detail is why the run failed (an engine's own message, a
            // remedy): printed whole. Other details are cut; report.md has them all.
            if c.status != Status::Error && detail.chars().count() > width {
                detail = detail.chars().take(width).collect::<String>() + " ...";
            }
            let _ = writeln!(
                s,
                "  {:<12} {}\n               {} = {} (tolerance {}){}",
                c.status.label(),
                visible(&c.name),
                visible(&c.metric),
                value(c),
                tolerance(c),
                if detail.is_empty() {
                    String::new()
                } else {
                    format!("\n               {detail}")
                }
            );
        }
        if !self.notes.is_empty() {
            let _ = writeln!(
                s,
                "\n{} note(s) in report.md (where the reference came from, what a reader must know).",
                self.notes.len()
            );
        }
        s
    }

    /// The `--format json` line (no trailing newline).
    pub fn machine_summary(&self, title: &str, dir: &std::path::Path) -> String {
        let m = MachineSummary {
            title,
            verdict: self.verdict(),
            exit_code: self.exit_code(),
            checks: self.checks.len(),
            pass: self.count(Status::Pass),
            fail: self.count(Status::Fail),
            inconclusive: self.count(Status::Inconclusive),
            not_compared: self.count(Status::NotCompared),
            error: self.count(Status::Error),
            exploratory: self.exploratory(),
            release_gate: self
                .gate
                .as_ref()
                .map(|g| if g.passed() { "PASS" } else { "FAIL" }),
            report: dir.display().to_string(),
            not_passed: self
                .checks
                .iter()
                .filter(|c| c.status != Status::Pass)
                .map(|c| NotPassed {
                    name: &c.name,
                    case: &c.case,
                    status: c.status,
                    exploratory: c.exploratory.as_deref(),
                })
                .collect(),
        };
        serde_json::to_string(&m).expect("a summary of strings and numbers serialises")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare::Gate;
    use crate::report::CaseRun;

    /// Stdout names every check that did not pass, and no passing one, and every case
    /// compared against a record rather than a live engine.
    #[test]
    fn the_summary_lists_only_what_did_not_pass() {
        let r = Report::new(
            vec![
                Check::at_most(
                    "case: position",
                    Gate::Position,
                    "max |dx| / r_min",
                    1e-9,
                    1e-6,
                    "fine",
                ),
                Check::at_most(
                    "case: velocity",
                    Gate::Velocity,
                    "max |dv| / max|v_ref|",
                    2e-3,
                    1e-6,
                    "worst at step 10 particle 2",
                ),
                Check::error(
                    "case: reference run",
                    format!("LIGGGHTS exited with status 1: {}end", "x".repeat(400)),
                ),
                Check::at_most(
                    "case: angular velocity",
                    Gate::AngularVelocity,
                    "max |dw| / max|w_ref|",
                    1.0,
                    1e-6,
                    format!("{}end", "y".repeat(400)),
                ),
            ],
            ["live", "recorded reference/micro/b"]
                .iter()
                .enumerate()
                .map(|(k, src)| CaseRun {
                    case: format!("case{k}"),
                    case_file: String::new(),
                    test_engine: "native".into(),
                    reference_engine: "LIGGGHTS".into(),
                    reference_version: "3.8.0".into(),
                    reference_source: src.to_string(),
                    wall_time_test_s: 0.0,
                    wall_time_reference_s: 0.0,
                })
                .collect(),
            vec!["a note".into()],
        );
        let s = r.summary("granval compare x", 200);
        // A recorded reference is said on stdout; a live one needs no line.
        assert!(s.contains(
            "case1: compared against the RECORDED LIGGGHTS run in reference/micro/b (seal verified), not a live engine"
        ));
        assert!(!s.contains("case0"));
        assert!(s.starts_with("granval compare x: ERROR\n4 checks: 1 pass, 2 FAIL"));
        // An error's reason whole, a failure's detail cut.
        assert!(s.contains(&format!("{}end", "x".repeat(400))));
        assert!(s.contains(&format!("{} ...", "y".repeat(200))) && !s.contains("yend"));
        assert!(
            s.contains("FAIL         case: velocity") && s.contains("= 0.002 (tolerance 1.000e-6)")
        );
        assert!(
            s.contains("ERROR        case: reference run") && s.contains("n/a (the run failed)")
        );
        assert!(!s.contains("case: position"));
        assert!(s.contains("1 note(s) in report.md"));
    }
}
