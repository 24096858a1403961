//! Registered expectations and the release gate (docs/statistics.md, "Registered
//! expectations and the release gate"). A documented finding (a claim of a paper the
//! simulations do not reproduce, or one the registered beds cannot decide) stays FAIL or
//! INCONCLUSIVE in every report; a suite file may pin it with an `[[expect]]` entry, and
//! the gate then passes when every verdict is what was registered and every pinned value
//! is where it was found. Any change, in either direction, fails the gate.

use super::{Check, Status};
use serde::{Deserialize, Serialize};

/// One `[[expect]]` of a suite file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Expectation {
    /// The check's name exactly as the report prints it.
    pub check: String,
    /// The verdict it was found with.
    pub verdict: Status,
    /// The value it was found at (the check's `value`), if pinned.
    #[serde(default)]
    pub value: Option<f64>,
    /// The interval the value must stay in (the 90 % interval it was found with).
    #[serde(default)]
    pub interval: Option<[f64; 2]>,
    /// Why it is expected (a finding of docs/release.md, an under-resolved gate).
    pub reason: String,
    /// When it was found (YYYY-MM-DD).
    pub found: String,
}

impl Expectation {
    /// What the suite file got wrong, if anything.
    pub(crate) fn validate(&self) -> Result<(), String> {
        if self.check.trim().is_empty() {
            return Err("check: empty; give the check's name as the report prints it".into());
        }
        if self.verdict == Status::Error {
            return Err(
                "verdict = \"error\": an error is never an expected outcome; fix the run".into(),
            );
        }
        if self.reason.trim().is_empty() {
            return Err("reason: empty; say why the verdict is expected".into());
        }
        if let Some([lo, hi]) = self.interval {
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(format!(
                    "interval = [{lo}, {hi}]: must be finite with lo <= hi"
                ));
            }
            if let Some(v) = self.value
                && !(lo <= v && v <= hi)
            {
                return Err(format!(
                    "value = {v}: outside its own interval [{lo}, {hi}]"
                ));
            }
        }
        Ok(())
    }
}

/// Checks a suite file's `[[expect]]` list as a whole: every entry on its own
/// ([`Expectation::validate`]) and no check named twice (two entries for one check would
/// make the gate's judgement depend on their order). The suite loader and the release
/// status table read the same list, so they refuse the same files with the same words.
pub(crate) fn check_list(file: &std::path::Path, list: &[Expectation]) -> anyhow::Result<()> {
    for (k, e) in list.iter().enumerate() {
        e.validate().map_err(|why| {
            anyhow::anyhow!("{}: expect[{k}] ({}): {why}", file.display(), e.check)
        })?;
        if let Some(j) = list[..k].iter().position(|o| o.check == e.check) {
            anyhow::bail!(
                "{}: expect[{k}] and expect[{j}] both name the check \"{}\"",
                file.display(),
                e.check
            );
        }
    }
    Ok(())
}

/// How one check stands against what was registered for it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GateRow {
    pub check: String,
    pub expected: Status,
    /// The verdict of this run (None: the check did not run).
    pub got: Option<Status>,
    /// Whether the row holds: verdict as expected and the pinned value inside its interval.
    pub holds: bool,
    pub why: String,
}

/// The release gate over one run's checks.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GateOutcome {
    /// Every registered expectation (held or not) and every check that broke the
    /// default expectation of a pass.
    pub rows: Vec<GateRow>,
    /// 0 every verdict as registered; 1 a verdict or pinned value changed; 2 an
    /// unexpected error, or an undecided verdict where a decision was registered.
    pub exit_code: i32,
}

impl GateOutcome {
    pub fn passed(&self) -> bool {
        self.exit_code == 0
    }
}

/// Judges `checks` against `expectations` (a check without one is expected to pass).
/// `complete`: the whole suite ran, so a registered check that did not run is a change;
/// with a subset (`--only`), it is listed and does not count. An EXPLORATORY check
/// (docs/statistics.md, "Registration") is not judged: it needs no expectation, and one
/// it has is listed as not counted; its ERROR still counts ([`Check::counts`]).
pub(crate) fn release_gate(
    checks: &[Check],
    expectations: &[Expectation],
    complete: bool,
) -> GateOutcome {
    let mut rows = Vec::new();
    let mut exit = 0;
    let mut raise = |code: i32| exit = exit.max(code);
    for c in checks.iter().filter(|c| !c.counts()) {
        if let Some(e) = expectations.iter().find(|e| e.check == c.name) {
            rows.push(GateRow {
                check: c.name.clone(),
                expected: e.verdict,
                got: Some(c.status),
                holds: true,
                why: format!(
                    "EXPLORATORY, not gated ({}); the expectation is not counted",
                    c.exploratory.as_deref().unwrap_or_default()
                ),
            });
        }
    }
    for c in checks.iter().filter(|c| c.counts()) {
        let e = expectations.iter().find(|e| e.check == c.name);
        let expected = e.map_or(Status::Pass, |e| e.verdict);
        let mut why = Vec::new();
        let mut holds = true;
        if c.status != expected {
            holds = false;
            why.push(format!(
                "verdict {} where {} was registered",
                c.status.label(),
                expected.label()
            ));
            raise(mismatch_code(c.status, expected));
        }
        if let Some(e) = e {
            if let Some([lo, hi]) = e.interval
                && !(lo <= c.value && c.value <= hi)
            {
                holds = false;
                why.push(format!(
                    "value {:.4} outside the pinned interval [{lo:.4}, {hi:.4}] (found {} at {})",
                    c.value,
                    e.value.map_or("n/a".to_string(), |v| format!("{v:.4}")),
                    e.found
                ));
                raise(1);
            }
            if holds {
                why.push(format!("as registered on {}: {}", e.found, e.reason));
            }
        }
        if e.is_some() || !holds {
            rows.push(GateRow {
                check: c.name.clone(),
                expected,
                got: Some(c.status),
                holds,
                why: why.join("; "),
            });
        }
    }
    for e in expectations {
        if !checks.iter().any(|c| c.name == e.check) {
            rows.push(GateRow {
                check: e.check.clone(),
                expected: e.verdict,
                got: None,
                holds: !complete,
                why: if complete {
                    "registered, but no check of this name ran".into()
                } else {
                    "not run (a subset of the suite)".into()
                },
            });
            if complete {
                raise(1);
            }
        }
    }
    if checks.is_empty() {
        // A gate over nothing gated nothing: exit 1, as a report without checks does.
        raise(1);
    } else if checks.iter().all(|c| c.exploratory.is_some()) {
        // Checks ran, every one EXPLORATORY: nothing was gated (NO GATED CHECKS).
        raise(2);
    }
    GateOutcome {
        rows,
        exit_code: exit,
    }
}

/// The exit code of a verdict that differs from the registered one: an error, or an
/// undecided verdict where a decision (pass or fail) was registered, exits 2 as it does
/// without expectations; every other change exits 1.
fn mismatch_code(got: Status, expected: Status) -> i32 {
    let decided = matches!(expected, Status::Pass | Status::Fail);
    if got == Status::Error || (got.undecided() && decided) {
        2
    } else {
        1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare::Gate;

    fn fail(name: &str, v: f64) -> Check {
        Check::at_most(name, Gate::Claim, "m", v, 0.0, "")
    }
    fn pass(name: &str) -> Check {
        Check::at_most(name, Gate::Claim, "m", 0.0, 1.0, "")
    }
    fn expect(name: &str, verdict: Status, interval: Option<[f64; 2]>) -> Expectation {
        Expectation {
            check: name.into(),
            verdict,
            value: interval.map(|[a, b]| (a + b) / 2.0),
            interval,
            reason: "a finding".into(),
            found: "2026-11-26".into(),
        }
    }

    #[test]
    fn the_gate_passes_when_every_verdict_is_as_registered() {
        let checks = [pass("a"), fail("b", 2.0)];
        let e = [expect("b", Status::Fail, Some([1.5, 2.5]))];
        let g = release_gate(&checks, &e, true);
        assert_eq!(g.exit_code, 0, "{g:?}");
        assert_eq!(g.rows.len(), 1);
        assert!(g.rows[0].holds && g.rows[0].why.contains("a finding"));
        // Without the expectation the same run fails, as a report would.
        assert_eq!(release_gate(&checks, &[], true).exit_code, 1);
    }

    #[test]
    fn any_change_fails_the_gate() {
        let e = [expect("b", Status::Fail, Some([1.5, 2.5]))];
        // The pinned value moved.
        let g = release_gate(&[pass("a"), fail("b", 3.0)], &e, true);
        assert_eq!(g.exit_code, 1);
        assert!(
            g.rows[0].why.contains("outside the pinned interval"),
            "{g:?}"
        );
        // The finding now passes.
        let g = release_gate(
            &[pass("a"), pass("b")],
            &[expect("b", Status::Fail, None)],
            true,
        );
        assert_eq!(g.exit_code, 1);
        // A new failure.
        let g = release_gate(&[fail("a", 1.0), fail("b", 2.0)], &e, true);
        assert_eq!(g.exit_code, 1);
        // The registered check did not run in a full run.
        let g = release_gate(&[pass("a")], &e, true);
        assert_eq!(g.exit_code, 1);
        // ... but may be absent from a subset.
        assert_eq!(release_gate(&[pass("a")], &e, false).exit_code, 0);
        // A run that checked nothing passes no gate.
        assert_eq!(release_gate(&[], &e, false).exit_code, 1);
        // An error is never expected and always exits 2.
        let g = release_gate(&[Check::error("b", "crash")], &e, true);
        assert_eq!(g.exit_code, 2);
        // An undecided verdict where a decision was registered exits 2.
        let g = release_gate(
            &[Check::not_compared("a", Gate::Claim, "one bed")],
            &[],
            true,
        );
        assert_eq!(g.exit_code, 2);
    }

    /// An EXPLORATORY check is not judged by the gate: its FAIL needs no expectation, an
    /// expectation it has is listed and not counted, and a run of nothing else exits 2.
    #[test]
    fn the_gate_ignores_exploratory_checks() {
        let why = "claim table changed after the record of a was sealed";
        let checks = [pass("a"), fail("b", 2.0)];
        assert_eq!(release_gate(&checks, &[], true).exit_code, 1);
        let checks = [pass("a"), fail("b", 2.0).mark_exploratory(why)];
        let g = release_gate(&checks, &[], true);
        assert_eq!(g.exit_code, 0, "{g:?}");
        assert!(g.rows.is_empty(), "{g:?}");
        // A pinned finding that moved would fail the gate; EXPLORATORY, it is not counted.
        let e = [expect("b", Status::Fail, Some([1.5, 1.8]))];
        assert_eq!(
            release_gate(&[pass("a"), fail("b", 2.0)], &e, true).exit_code,
            1
        );
        let g = release_gate(&checks, &e, true);
        assert_eq!(g.exit_code, 0, "{g:?}");
        assert!(g.rows[0].why.contains("EXPLORATORY") && g.rows[0].why.contains(why));
        let g = release_gate(&[fail("b", 2.0).mark_exploratory(why)], &[], true);
        assert_eq!(g.exit_code, 2, "nothing gated");
        let g = release_gate(
            &[pass("a"), Check::error("b", "crash").mark_exploratory(why)],
            &[],
            true,
        );
        assert_eq!(g.exit_code, 2, "an error counts: {g:?}");
    }

    #[test]
    fn expectations_name_their_mistakes() {
        let mut e = expect("b", Status::Error, None);
        assert!(
            e.validate()
                .unwrap_err()
                .contains("never an expected outcome")
        );
        e.verdict = Status::Fail;
        e.interval = Some([2.0, 1.0]);
        assert!(e.validate().unwrap_err().contains("lo <= hi"));
        e.interval = Some([1.0, 2.0]);
        e.value = Some(3.0);
        assert!(
            e.validate()
                .unwrap_err()
                .contains("outside its own interval")
        );
    }

    #[test]
    fn a_list_naming_one_check_twice_is_refused_with_both_places() {
        let file = std::path::Path::new("cases/suites/x.toml");
        let a = expect("a", Status::Fail, Some([0.0, 1.0]));
        let b = expect("b", Status::Inconclusive, None);
        assert!(check_list(file, &[a.clone(), b.clone()]).is_ok());
        let msg = check_list(file, &[a.clone(), b, a])
            .unwrap_err()
            .to_string();
        assert!(msg.contains("cases/suites/x.toml"), "{msg}");
        assert!(msg.contains("expect[2] and expect[0]"), "{msg}");
        let bad = expect("c", Status::Error, None);
        let msg = check_list(file, &[bad]).unwrap_err().to_string();
        assert!(
            msg.contains("expect[0] (c)") && msg.contains("never an expected outcome"),
            "{msg}"
        );
    }
}
