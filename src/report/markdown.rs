//! `report.md` (every check, for people, rendering the same on GitHub, GitLab and any
//! CommonMark + GFM viewer) and the short text summary granval prints on stdout (the
//! verdict and the checks that did not pass; the whole report is in the file).

use super::text::{md_cell, tolerance, value, visible};
use super::{Report, Section};
use crate::compare::Status;
use std::fmt::Write as _;

/// The verdict column of a check: `pass`, or the label in bold.
pub(crate) fn verdict_cell(status: Status) -> String {
    match status {
        Status::Pass => "pass".to_string(),
        st => format!("**{}**", st.label()),
    }
}

impl Report {
    /// Checks with verdict `st`, EXPLORATORY ones included (the tally shows every verdict).
    pub(super) fn count(&self, st: Status) -> usize {
        self.checks.iter().filter(|c| c.status == st).count()
    }

    /// Checks with verdict `st` that count ([`crate::compare::Check::counts`]).
    fn count_counted(&self, st: Status) -> usize {
        self.checks
            .iter()
            .filter(|c| c.status == st && c.counts())
            .count()
    }

    /// EXPLORATORY checks: printed, not gated.
    pub(super) fn exploratory(&self) -> usize {
        self.checks
            .iter()
            .filter(|c| c.exploratory.is_some())
            .count()
    }

    /// The report's one-word verdict. An undecidable gate (NOT COMPARED) exits 2 like an
    /// error, but a reader should not take a suite that ran to the end for a crash: the
    /// heading says which.
    pub fn verdict(&self) -> &'static str {
        if self.count(Status::Error) > 0 {
            "ERROR"
        } else if self.nothing_gated() {
            // Every check EXPLORATORY: their verdicts are printed, none decides (exit 2).
            "NO GATED CHECKS"
        } else if self.errored
            && self.count_counted(Status::NotCompared) == 0
            && self.count_counted(Status::Inconclusive) > 0
        {
            // Every gate was decided or under-resolved: the data could not tell.
            "INCONCLUSIVE"
        } else if self.errored {
            "INCOMPLETE"
        } else if self.passed {
            "PASS"
        } else if self.checks.is_empty() {
            // Still exit 1 for compare/check: a comparison that checked nothing failed.
            "NO GATED CHECKS"
        } else {
            "FAIL"
        }
    }

    /// "N checks: a pass, b FAIL, ... (exit c).", with "; k EXPLORATORY, not gated" before
    /// the exit code when there are any.
    pub(crate) fn tally(&self) -> String {
        let exploratory = match self.exploratory() {
            0 => String::new(),
            k => format!("; {k} of them EXPLORATORY, not gated"),
        };
        format!(
            "{} checks: {} pass, {} FAIL, {} INCONCLUSIVE, {} NOT COMPARED, {} ERROR{exploratory} (exit {}).",
            self.checks.len(),
            self.count(Status::Pass),
            self.count(Status::Fail),
            self.count(Status::Inconclusive),
            self.count(Status::NotCompared),
            self.count(Status::Error),
            self.exit_code()
        )
    }

    /// The release gate's line; `strong`: its verdict in Markdown bold.
    pub(super) fn gate_line(&self, strong: &str) -> Option<String> {
        self.gate.as_ref().map(|g| {
            let expected = g.rows.iter().filter(|r| r.holds && r.got.is_some()).count();
            let not_run = g.rows.iter().filter(|r| r.holds && r.got.is_none()).count();
            let changed = g.rows.len() - expected - not_run;
            // A subset (`--only`) lists the findings it did not run; they are not counted
            // as seen.
            let not_run = if not_run > 0 {
                format!(", {not_run} not run (a subset of the suite)")
            } else {
                String::new()
            };
            format!(
                "Release gate: {strong}{}{strong} ({expected} registered finding(s) as expected{not_run}, {changed} change(s); docs/statistics.md). Every verdict below is the check's own.",
                if g.passed() { "PASS" } else { "FAIL" }
            )
        })
    }

    pub fn markdown(&self, title: &str) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "# {}: {}\n", visible(title), self.verdict());
        let _ = writeln!(s, "{}\n", self.tally());
        if let Some(g) = self.gate_line("**") {
            let _ = writeln!(s, "{g}\n");
        }
        if !self.notes.is_empty() {
            for n in &self.notes {
                let _ = writeln!(s, "> {}\n>", visible(n).replace('\n', "\n> "));
            }
            s.push('\n');
        }
        let _ = writeln!(
            s,
            "| check | metric | value | tolerance | verdict | where |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|");
        for c in &self.checks {
            let (verdict, detail) = match &c.exploratory {
                None => (verdict_cell(c.status), md_cell(&c.detail)),
                Some(why) => (
                    format!("{} (EXPLORATORY, not gated)", verdict_cell(c.status)),
                    md_cell(&format!("EXPLORATORY: {why}; {}", c.detail)),
                ),
            };
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {verdict} | {detail} |",
                md_cell(&c.name),
                md_cell(&c.metric),
                md_cell(&value(c)),
                md_cell(&tolerance(c)),
            );
        }
        if let Some(g) = &self.gate
            && !g.rows.is_empty()
        {
            let _ = writeln!(
                s,
                "\n## Release gate\n\n| check | registered | this run | as registered | why |\n|---|---|---|---|---|"
            );
            for r in &g.rows {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} | {} |",
                    md_cell(&r.check),
                    r.expected.label(),
                    r.got.map_or("not run", |st| st.label()),
                    if r.holds { "yes" } else { "**NO**" },
                    md_cell(&r.why)
                );
            }
        }
        for sec in &self.sections {
            section(&mut s, sec);
        }
        if !self.runs.is_empty() {
            let _ = writeln!(
                s,
                "\n## Runs\n\n| case | test | reference | reference source | version | wall time test / ref (s) |\n|---|---|---|---|---|---|"
            );
            for r in &self.runs {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} | {} | {:.2} / {:.2} |",
                    md_cell(&r.case),
                    md_cell(&r.test_engine),
                    md_cell(&r.reference_engine),
                    md_cell(&r.reference_source),
                    md_cell(&r.reference_version),
                    r.wall_time_test_s,
                    r.wall_time_reference_s
                );
            }
        }
        s
    }
}

fn section(s: &mut String, sec: &Section) {
    let _ = writeln!(s, "\n## {}\n\n{}", visible(&sec.title), sec.body.trim_end());
    for f in &sec.figures {
        let _ = writeln!(s, "\n![{}]({})", md_cell(f), f.replace(' ', "%20"));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare::expect::{GateOutcome, GateRow};
    use crate::compare::{Check, Gate};
    use crate::report::CaseRun;
    use pulldown_cmark::{Event, Options, Parser, Tag, TagEnd};

    /// A subset run (`--only`) counts as seen only the findings it ran; the others are
    /// listed as not run, and a broken row is a change.
    #[test]
    fn gate_line_counts_seen_not_run_and_changed_findings_apart() {
        let row = |got: Option<Status>, holds: bool| GateRow {
            check: "c".into(),
            expected: Status::Inconclusive,
            got,
            holds,
            why: String::new(),
        };
        let mut r = Report::new(Vec::new(), Vec::new(), Vec::new());
        r.gate = Some(GateOutcome {
            rows: vec![
                row(Some(Status::Inconclusive), true),
                row(None, true),
                row(None, true),
            ],
            exit_code: 0,
        });
        assert_eq!(
            r.gate_line("").unwrap(),
            "Release gate: PASS (1 registered finding(s) as expected, 2 not run (a subset of the suite), 0 change(s); docs/statistics.md). Every verdict below is the check's own."
        );
        r.gate = Some(GateOutcome {
            rows: vec![row(Some(Status::Pass), false)],
            exit_code: 1,
        });
        assert_eq!(
            r.gate_line("").unwrap(),
            "Release gate: FAIL (0 registered finding(s) as expected, 1 change(s); docs/statistics.md). Every verdict below is the check's own."
        );
    }

    /// Every table of `md` as GFM renders it: rows of cell texts (header first), and
    /// whether any cell held raw HTML.
    fn tables(md: &str) -> (Vec<Vec<Vec<String>>>, bool) {
        let (mut out, mut html) = (Vec::new(), false);
        let (mut table, mut row, mut cell): (Vec<Vec<String>>, Vec<String>, Option<String>) =
            (Vec::new(), Vec::new(), None);
        for ev in Parser::new_ext(md, Options::ENABLE_TABLES | Options::ENABLE_STRIKETHROUGH) {
            match ev {
                Event::Start(Tag::TableCell) => cell = Some(String::new()),
                Event::End(TagEnd::TableCell) => row.push(cell.take().unwrap()),
                Event::End(TagEnd::TableHead) | Event::End(TagEnd::TableRow) => {
                    table.push(std::mem::take(&mut row))
                }
                Event::End(TagEnd::Table) => out.push(std::mem::take(&mut table)),
                Event::Text(t) | Event::Code(t) => {
                    if let Some(c) = cell.as_mut() {
                        c.push_str(&t)
                    }
                }
                Event::Html(_) | Event::InlineHtml(_) if cell.is_some() => html = true,
                _ => {}
            }
        }
        (out, html)
    }

    /// What a cell must read as: the text with line breaks as spaces, control
    /// characters visible, outer spaces trimmed.
    fn shown(s: &str) -> String {
        visible(s)
            .replace(['\n', '\r', '\t'], " ")
            .trim()
            .to_string()
    }

    /// report.md is valid GFM: every row of every table has its header's cell count,
    /// each check's name, metric and verdict land in their own columns whatever the
    /// text holds (pipes, emphasis, code, HTML, link brackets, escapes, line breaks,
    /// terminal escape codes), and no cell turns into HTML. Before cells were escaped,
    /// `max |dx| / r_min` split its row into 8 cells and the verdict moved columns.
    #[test]
    fn report_md_parses_as_gfm_with_every_verdict_in_its_column() {
        let nasty = "a|b *c* _d_ `e` <b>f</b> [g](h) \\ ~~i~~ &amp; \u{1b}[31mred\0";
        let mut checks = vec![
            Check::at_most(
                "micro: position",
                Gate::Position,
                "max |dx| / r_min",
                2.5e-9,
                1e-6,
                "worst at step 5 particle 2",
            ),
            Check::at_most(
                format!("case {nasty}: velocity"),
                Gate::Velocity,
                "max |dv| / max|v_ref|",
                2.0,
                1e-6,
                format!("line one | x\nline two {nasty}"),
            ),
            Check::at_least(
                "micro: coverage",
                Gate::Coverage,
                "output frames after step 0",
                150.0,
                10.0,
                "150 frames",
            ),
            Check::error(
                "micro: reference run",
                format!("LIGGGHTS exited with status 1:\n{nasty}\n|||"),
            ),
            Check::not_compared("pen: K_phi", Gate::KPhi, "one bed | too few"),
        ];
        checks.push(Check::decided(
            "pen: K_phi vs published",
            Gate::Published,
            "ln(K / K_pub) | mean",
            &[crate::compare::Comparison {
                what: "bed by bed | ln".into(),
                estimate: None,
                rule: crate::compare::Rule::Equivalence { margin: 0.095 },
                m: 1,
            }],
            "one bed",
        ));
        let mut r = Report::new(
            checks,
            vec![CaseRun {
                case: format!("micro {nasty}"),
                case_file: "cases/micro/x|y.toml".into(),
                test_engine: "native".into(),
                reference_engine: "LIGGGHTS".into(),
                reference_version: "LIGGGHTS (Version 3.8.0 | x)".into(),
                reference_source: "live".into(),
                wall_time_test_s: 1.0,
                wall_time_reference_s: 2.0,
            }],
            vec![format!("note with | pipe\nand a second line {nasty}")],
        );
        r.gate = Some(GateOutcome {
            rows: vec![GateRow {
                check: format!("case {nasty}: velocity"),
                expected: Status::Fail,
                got: Some(Status::Fail),
                holds: true,
                why: format!("as registered | {nasty}"),
            }],
            exit_code: 0,
        });
        let md = r.markdown("granval check --suite a|b");
        let (tables, html) = tables(&md);
        assert!(!html, "a cell rendered as HTML:\n{md}");
        assert_eq!(tables.len(), 3, "checks, release gate, runs:\n{md}");
        let widths = [6, 5, 6];
        for (t, w) in tables.iter().zip(widths) {
            for row in t {
                assert_eq!(row.len(), w, "row {row:?} of a {w}-column table:\n{md}");
            }
        }
        let main = &tables[0];
        assert_eq!(
            main[0],
            ["check", "metric", "value", "tolerance", "verdict", "where"]
        );
        assert_eq!(main.len(), 1 + r.checks.len());
        for (row, c) in main[1..].iter().zip(&r.checks) {
            assert_eq!(row[0], shown(&c.name));
            assert_eq!(row[1], shown(&c.metric));
            assert_eq!(row[4], c.status.label());
            assert_eq!(row[5], shown(&c.detail));
        }
        // Counts as integers with their unit; no NaN, no 0.0e0 tolerance of an error.
        assert_eq!(
            (main[3][2].as_str(), main[3][3].as_str()),
            ("150 frames", "10 frames")
        );
        assert_eq!(
            (main[4][2].as_str(), main[4][3].as_str()),
            ("n/a (the run failed)", "-")
        );
        assert_eq!(main[5][2], "n/a (not compared)");
        assert!(!md.contains("NaN") && !md.contains("0.0e0"));
        assert_eq!(tables[1][1][0], shown(&format!("case {nasty}: velocity")));
        assert_eq!(tables[1][1][3], "yes");
        assert_eq!(tables[2][1][0], shown(&format!("micro {nasty}")));
    }

    /// The negative control: unescaped, the same report does not parse into its columns
    /// (so the test above can fail).
    #[test]
    fn an_unescaped_pipe_breaks_the_row() {
        let (t, _) = tables("| a | b |\n|---|---|\n| max |dx| / r | pass |\n");
        assert_ne!(t[0][1], ["max |dx| / r", "pass"]);
    }
}
