//! `report.junit.xml` for CI dashboards (GitLab, Jenkins, GitHub test reporters): one
//! `<testsuite>` per case, each check a `<testcase>` whose `classname` is its case, so a
//! dashboard groups and tracks checks by case. Always well-formed XML 1.0, whatever an
//! engine printed into a detail ([`super::text::xml`]).

use super::Report;
use super::text::{tolerance, value, xml};
use crate::compare::{Check, Status};
use std::fmt::Write as _;

/// JUnit's `classname` of the checks that belong to no case (a suite's claims across
/// cases).
pub(crate) const CLAIMS_CLASS: &str = "claims across cases";

impl Report {
    pub fn junit(&self, title: &str) -> String {
        // Cases in report order, each with its checks.
        let mut cases: Vec<(&str, Vec<&Check>)> = Vec::new();
        for c in &self.checks {
            let class = if c.case.is_empty() {
                CLAIMS_CLASS
            } else {
                c.case.as_str()
            };
            match cases.iter_mut().find(|(k, _)| *k == class) {
                Some((_, v)) => v.push(c),
                None => cases.push((class, vec![c])),
            }
        }
        // An EXPLORATORY check is `<skipped>` (not gated), unless it is an error.
        let count = |cs: &[&Check], f: fn(Status) -> bool| {
            cs.iter().filter(|c| c.counts() && f(c.status)).count()
        };
        let skipped = |cs: &[&Check]| cs.iter().filter(|c| !c.counts()).count();
        let failure = |s: Status| s == Status::Fail;
        let error = |s: Status| s.undecided();
        let all: Vec<&Check> = self.checks.iter().collect();
        let total_time: f64 = self
            .runs
            .iter()
            .map(|r| r.wall_time_test_s + r.wall_time_reference_s)
            .sum::<f64>()
            + self.checks.iter().filter_map(|c| c.time_s).sum::<f64>();
        let mut s = format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites name=\"{}\" tests=\"{}\" failures=\"{}\" errors=\"{}\" skipped=\"{}\" time=\"{}\">\n",
            xml(title, true),
            all.len(),
            count(&all, failure),
            count(&all, error),
            skipped(&all),
            seconds(total_time)
        );
        for (class, checks) in &cases {
            // The case's engine runs (shared by its checks) and its checks' own times.
            let runs: f64 = self
                .runs
                .iter()
                .filter(|r| r.case == *class)
                .map(|r| r.wall_time_test_s + r.wall_time_reference_s)
                .sum();
            let own: f64 = checks.iter().filter_map(|c| c.time_s).sum();
            let _ = writeln!(
                s,
                "  <testsuite name=\"{}\" tests=\"{}\" failures=\"{}\" errors=\"{}\" skipped=\"{}\" time=\"{}\">",
                xml(class, true),
                checks.len(),
                count(checks, failure),
                count(checks, error),
                skipped(checks),
                seconds(runs + own)
            );
            if let Some(r) = self.runs.iter().find(|r| r.case == *class) {
                let _ = writeln!(
                    s,
                    "    <properties>\n      <property name=\"case_file\" value=\"{}\"/>\n      <property name=\"reference\" value=\"{} {} ({})\"/>\n      <property name=\"wall_time_test_s\" value=\"{}\"/>\n      <property name=\"wall_time_reference_s\" value=\"{}\"/>\n    </properties>",
                    xml(&r.case_file, true),
                    xml(&r.reference_engine, true),
                    xml(&r.reference_version, true),
                    xml(&r.reference_source, true),
                    seconds(r.wall_time_test_s),
                    seconds(r.wall_time_reference_s)
                );
            }
            for c in checks {
                testcase(&mut s, class, c);
            }
            s.push_str("  </testsuite>\n");
        }
        s.push_str("</testsuites>\n");
        s
    }
}

/// A duration in seconds as JUnit readers parse it (a plain decimal).
fn seconds(t: f64) -> String {
    if t.is_finite() && t >= 0.0 {
        format!("{t:.3}")
    } else {
        "0".into()
    }
}

fn testcase(s: &mut String, class: &str, c: &Check) {
    let _ = write!(
        s,
        "    <testcase name=\"{}\" classname=\"{}\" time=\"{}\">",
        xml(&c.name, true),
        xml(class, true),
        seconds(c.time_s.unwrap_or(0.0))
    );
    let message = format!(
        "{}: {} = {}, tolerance {}",
        c.status.label(),
        c.metric,
        value(c),
        tolerance(c)
    );
    match c.status {
        _ if !c.counts() => {
            let why = c.exploratory.as_deref().unwrap_or_default();
            let _ = write!(
                s,
                "<skipped message=\"{}\">{}</skipped>",
                xml(&format!("EXPLORATORY, not gated ({why}); {message}"), true),
                xml(&c.detail, false)
            );
        }
        Status::Pass => {}
        Status::Fail => {
            let _ = write!(
                s,
                "<failure message=\"{}\" type=\"FAIL\">{}</failure>",
                xml(&message, true),
                xml(&c.detail, false)
            );
        }
        Status::Error | Status::NotCompared | Status::Inconclusive => {
            let _ = write!(
                s,
                "<error message=\"{}\" type=\"{}\">{}</error>",
                xml(&message, true),
                xml(c.status.label(), true),
                xml(&c.detail, false)
            );
        }
    }
    if c.status == Status::Pass && !c.detail.is_empty() {
        let _ = write!(
            s,
            "<system-out>{} = {}; {}</system-out>",
            xml(&c.metric, false),
            xml(&value(c), false),
            xml(&c.detail, false)
        );
    }
    s.push_str("</testcase>\n");
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare::Gate;
    use crate::report::CaseRun;
    use crate::report::text::visible;

    /// What a crashed LIGGGHTS may leave in a detail: terminal colour codes, NUL, a
    /// bell, a form feed, a byte-order mark's non-character, and XML's own specials.
    const CRASH: &str =
        "ERROR: Lost atoms \u{1b}[31m<3 & \"x\"]]>\u{1b}[0m\0\u{7}\u{c}\u{fffe} done";

    fn run(case: &str) -> CaseRun {
        CaseRun {
            case: case.into(),
            case_file: format!("cases/micro/{case}.toml"),
            test_engine: "native".into(),
            reference_engine: "LIGGGHTS".into(),
            reference_version: "3.8.0 <\u{1b}>".into(),
            reference_source: "live".into(),
            wall_time_test_s: 1.25,
            wall_time_reference_s: 2.5,
        }
    }

    fn report() -> Report {
        let mut pass = Check::at_most(
            "a: position",
            Gate::Position,
            "max |dx| / r_min",
            1e-9,
            1e-6,
            "worst at step 5",
        );
        pass.case = "a".into();
        pass.time_s = Some(0.5);
        let mut crash = Check::error("b: reference run", format!("LIGGGHTS crashed:\n{CRASH}"));
        crash.case = "b".into();
        let mut fail = Check::at_most(
            "b: velocity",
            Gate::Velocity,
            "max |dv| / max|v_ref|",
            2e-3,
            1e-6,
            CRASH,
        );
        fail.case = "b".into();
        fail.time_s = Some(0.25);
        let claim = Check::not_compared("sweep: trend", Gate::KPhi, "one case");
        Report::new(
            vec![pass, crash, fail, claim],
            vec![run("a"), run("b")],
            Vec::new(),
        )
    }

    /// report.junit.xml is well-formed XML 1.0 after a reference engine's crash output
    /// landed in a detail (a strict parser reads it), each check's `classname` is its
    /// case, the claims across cases have their own, every testcase has a time, and
    /// the details read back as what the engine printed (control bytes shown as
    /// `\xNN`). Before, control bytes were copied raw and every check was
    /// `classname="granval"` without a time.
    #[test]
    fn junit_parses_after_an_engine_crash_with_a_class_per_case() {
        let r = report();
        let text = r.junit("granval check \u{1b}[1m--suite micro");
        let doc = roxmltree::Document::parse(&text)
            .unwrap_or_else(|e| panic!("report.junit.xml does not parse: {e}\n{text}"));
        let root = doc.root_element();
        assert_eq!(root.tag_name().name(), "testsuites");
        assert_eq!(
            root.attribute("name"),
            Some("granval check \\x1b[1m--suite micro")
        );
        assert_eq!(
            (
                root.attribute("tests"),
                root.attribute("failures"),
                root.attribute("errors")
            ),
            (Some("4"), Some("1"), Some("2"))
        );
        let suites: Vec<_> = root
            .children()
            .filter(|n| n.has_tag_name("testsuite"))
            .collect();
        let names: Vec<_> = suites
            .iter()
            .map(|s| s.attribute("name").unwrap())
            .collect();
        assert_eq!(names, ["a", "b", CLAIMS_CLASS]);
        // Suite b: its engine runs (1.25 + 2.5 s) and its checks' own time (0.25 s).
        let b = suites[1];
        assert_eq!(b.attribute("time"), Some("4.000"));
        assert_eq!(
            (
                b.attribute("tests"),
                b.attribute("failures"),
                b.attribute("errors")
            ),
            (Some("2"), Some("1"), Some("1"))
        );
        let mut seen = 0;
        for (suite, class) in suites.iter().zip(["a", "b", CLAIMS_CLASS]) {
            for tc in suite.children().filter(|n| n.has_tag_name("testcase")) {
                seen += 1;
                assert_eq!(tc.attribute("classname"), Some(class));
                let t: f64 = tc.attribute("time").unwrap().parse().unwrap();
                assert!(t >= 0.0);
                let c = r
                    .checks
                    .iter()
                    .find(|c| c.name == tc.attribute("name").unwrap())
                    .unwrap();
                let body = tc.children().find(|n| n.is_element());
                match c.status {
                    Status::Pass => assert!(body.unwrap().has_tag_name("system-out")),
                    Status::Fail => {
                        let f = body.unwrap();
                        assert!(f.has_tag_name("failure"));
                        assert_eq!(f.text(), Some(visible(&c.detail).as_str()));
                    }
                    _ => {
                        let e = body.unwrap();
                        assert!(e.has_tag_name("error"));
                        assert_eq!(e.attribute("type"), Some(c.status.label()));
                        assert_eq!(e.text(), Some(visible(&c.detail).as_str()));
                    }
                }
            }
        }
        assert_eq!(seen, 4);
        let a = suites[0]
            .children()
            .find(|n| n.has_tag_name("testcase"))
            .unwrap();
        assert_eq!(a.attribute("time"), Some("0.500"));
        let props = suites[1]
            .descendants()
            .filter(|n| n.has_tag_name("property"));
        let reference = props
            .filter(|p| p.attribute("name") == Some("reference"))
            .map(|p| p.attribute("value").unwrap())
            .next();
        assert_eq!(reference, Some("LIGGGHTS 3.8.0 <\\x1b> (live)"));
    }

    /// The negative control: the same crash text copied raw, as before, is not XML
    /// the parser accepts (so the test above can fail).
    #[test]
    fn raw_control_bytes_do_not_parse() {
        let raw = format!(
            "<testsuite><testcase name=\"x\"><error>{CRASH}</error></testcase></testsuite>"
        )
        .replace('&', "&amp;")
        .replace('<', "&lt;");
        let raw = format!("<r>{raw}</r>");
        assert!(roxmltree::Document::parse(&raw).is_err());
    }
}
