//! Turns two runs (or a run and a published/theoretical value) into named metrics with
//! tolerances and a verdict each. Nothing here knows which engine produced what.

pub mod chaos;
pub(crate) mod coverage;
pub mod ensemble;
pub mod expect;
pub mod impact2d;
pub mod interface;
pub mod malt_points;
pub mod penetration;
pub mod stress;
pub mod sweep;
pub(crate) mod trajectory;
pub mod triaxial;

use crate::numerics::stats::{self, Decision, Estimate};
use serde::{Deserialize, Serialize};

/// The verdict of one check. Only `Pass` lets a run exit 0: a check that could not be
/// evaluated (`NotCompared`: too little data to mean anything), whose data decide
/// neither way (`Inconclusive`: the interval of docs/statistics.md straddles the margin)
/// or whose inputs failed (`Error`: a crashed engine, a corrupt reference) is never a
/// pass.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    Pass,
    Fail,
    NotCompared,
    Inconclusive,
    Error,
}

impl Status {
    /// How reports print it.
    pub fn label(self) -> &'static str {
        match self {
            Status::Pass => "pass",
            Status::Fail => "FAIL",
            Status::NotCompared => "NOT COMPARED",
            Status::Inconclusive => "INCONCLUSIVE",
            Status::Error => "ERROR",
        }
    }

    /// Neither a pass nor a physics failure: the run exits 2.
    pub(crate) fn undecided(self) -> bool {
        matches!(
            self,
            Status::NotCompared | Status::Inconclusive | Status::Error
        )
    }
}

/// The rule of a statistical gate (docs/statistics.md, "Decision rules").
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Rule {
    /// Equivalence by two one-sided tests within +-`margin`.
    Equivalence { margin: f64 },
    /// A one-sided test that the effect exceeds `delta`.
    Exceeds { delta: f64 },
}

/// One comparison of a statistical gate: what it is about, its estimate over beds
/// (None: fewer than two beds, or a value that is not finite) and the comparisons it
/// shares its claim with (`m`, for the Bonferroni level of a failure).
#[derive(Debug, Clone)]
pub(crate) struct Comparison {
    pub what: String,
    pub estimate: Option<Estimate>,
    pub rule: Rule,
    pub m: usize,
}

impl Comparison {
    pub(crate) fn decision(&self) -> Decision {
        match (&self.estimate, self.rule) {
            (None, _) => Decision::Inconclusive,
            (Some(e), Rule::Equivalence { margin }) => stats::equivalence(e, margin, self.m),
            (Some(e), Rule::Exceeds { delta }) => stats::exceeds(e, delta, self.m),
        }
    }

    /// `what: 0.0123 [90 % interval -0.010, 0.034] over 5 beds (sd 0.021), margin +-0.0953:
    /// INCONCLUSIVE, about 14 beds would decide it at this sd`.
    pub(crate) fn describe(&self) -> String {
        let d = self.decision();
        let rule = match self.rule {
            Rule::Equivalence { margin } if margin.is_nan() => "no registered margin".into(),
            Rule::Equivalence { margin } => format!("margin +-{margin:.4}"),
            Rule::Exceeds { delta } => format!("must exceed {delta:.4}"),
        };
        let Some(e) = &self.estimate else {
            return format!(
                "{}: {rule}: INCONCLUSIVE (no estimate: one bed, a value that is not finite, or nothing registered to judge it by)",
                self.what
            );
        };
        let (l, u) = e.decision_interval();
        let level = if self.m > 1 {
            let (fl, fu) = e.failure_interval(self.m);
            format!(
                "; failure decided on the Bonferroni interval [{fl:.4}, {fu:.4}] of {} comparisons",
                self.m
            )
        } else {
            String::new()
        };
        let need = match d {
            Decision::Inconclusive => {
                // At the measured difference and sd: the beds that would pass an
                // equivalence inside its margin or fail one outside it, or resolve a
                // one-sided test either way.
                let n = match self.rule {
                    Rule::Equivalence { margin } if e.value.abs() < margin => {
                        stats::beds_to_pass_equivalence(e.sd, e.value, margin)
                    }
                    Rule::Equivalence { margin } => {
                        stats::beds_to_resolve(e.sd, e.value.abs() - margin)
                    }
                    Rule::Exceeds { delta } => stats::beds_to_resolve(e.sd, e.value - delta),
                };
                match n {
                    Some(n) => {
                        format!(", about {n} beds would decide it at this difference and sd")
                    }
                    None => ", no bed count decides it at this difference and sd".to_string(),
                }
            }
            _ => String::new(),
        };
        format!(
            "{}: {:.4} [90 % interval {l:.4}, {u:.4}] over {} beds (sd {:.4}, {} degrees of freedom), {rule}{level}: {}{need}",
            self.what,
            e.value,
            e.n,
            e.sd,
            // Welch-Satterthwaite's are fractional: one decimal says all they mean.
            if e.df.fract() == 0.0 {
                format!("{}", e.df)
            } else {
                format!("{:.1}", e.df)
            },
            match d {
                Decision::Pass => "PASS",
                Decision::Fail => "FAIL",
                Decision::Inconclusive => "INCONCLUSIVE",
            }
        )
    }
}

pub use crate::case::Gate;

/// One gated comparison. The JSON shape `{name, gate, metric, value, tolerance, status,
/// passed, detail}` is the stable interface CI scripts read (`passed` is `status ==
/// pass`, kept for scripts written before `status` existed).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Check {
    pub name: String,
    pub gate: Gate,
    pub metric: String,
    /// NaN (a check that could not be evaluated) is written as JSON `null`, since JSON
    /// has no NaN, and read back as NaN.
    #[serde(deserialize_with = "nan_from_null")]
    pub value: f64,
    #[serde(deserialize_with = "nan_from_null")]
    pub tolerance: f64,
    pub status: Status,
    pub passed: bool,
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub detail: String,
    /// The case the check belongs to (empty: a claim across cases); JUnit's
    /// `classname`. Set by the runner, not by the comparisons.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub case: String,
    /// Wall time (s) of the work that produced this verdict and no other (a negative
    /// control's runs; a share of the comparison of the case's runs), when measured.
    /// JUnit's `time`. The engine runs a case's checks share are its `CaseRun` times.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_s: Option<f64>,
    /// The sha256 of the rules this check is judged by (its case's or its claim's), in a
    /// suite that registers them (docs/statistics.md, "Registration"). Set by the suite.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rules_sha256: Option<String>,
    /// Why the check is EXPLORATORY (its rules were not committed before the record it
    /// judges was sealed): its verdict is printed, never gated. Absent: gated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exploratory: Option<String>,
}

/// serde_json writes a non-finite f64 as `null`; read `null` back as NaN so that every
/// report.json granval writes can be read again.
pub(crate) fn nan_from_null<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

impl Check {
    pub(crate) fn with_status(
        name: impl Into<String>,
        gate: Gate,
        metric: impl Into<String>,
        value: f64,
        tolerance: f64,
        status: Status,
        detail: impl Into<String>,
    ) -> Check {
        Check {
            name: name.into(),
            gate,
            metric: metric.into(),
            value,
            tolerance,
            status,
            passed: status == Status::Pass,
            detail: detail.into(),
            case: String::new(),
            time_s: None,
            rules_sha256: None,
            exploratory: None,
        }
    }

    /// Whether the verdict counts toward the exit code and the release gate: it does
    /// unless the check is EXPLORATORY, and an ERROR always does (a run that failed is a
    /// failed run whatever its rules).
    pub(crate) fn counts(&self) -> bool {
        self.exploratory.is_none() || self.status == Status::Error
    }

    /// Marks the check EXPLORATORY for `why`.
    #[cfg(test)]
    pub(crate) fn mark_exploratory(mut self, why: impl Into<String>) -> Check {
        self.exploratory = Some(why.into());
        self
    }

    /// Passes when `value <= tolerance`. NaN never passes.
    pub(crate) fn at_most(
        name: impl Into<String>,
        gate: Gate,
        metric: impl Into<String>,
        value: f64,
        tolerance: f64,
        detail: impl Into<String>,
    ) -> Check {
        let status = if value <= tolerance {
            Status::Pass
        } else {
            Status::Fail
        };
        Check::with_status(name, gate, metric, value, tolerance, status, detail)
    }

    /// Turns a pass into a fail when the rule has a condition its single metric cannot
    /// carry (an `increasing` claim with min_step 0 meets `value <= 0` on a flat step,
    /// which does not increase). Any other verdict is kept.
    pub(crate) fn fail_if(mut self, failed: bool, why: &str) -> Check {
        if failed && self.status == Status::Pass {
            self.status = Status::Fail;
            self.passed = false;
            self.detail = format!("{}; fails: {why}", self.detail);
        }
        self
    }

    /// Passes when `value >= minimum`. NaN never passes.
    pub(crate) fn at_least(
        name: impl Into<String>,
        gate: Gate,
        metric: impl Into<String>,
        value: f64,
        minimum: f64,
        detail: impl Into<String>,
    ) -> Check {
        let status = if value >= minimum {
            Status::Pass
        } else {
            Status::Fail
        };
        Check::with_status(name, gate, metric, value, minimum, status, detail)
    }

    /// A check that failed on its face (e.g. a regime present in one engine only).
    pub fn failed(
        name: impl Into<String>,
        gate: Gate,
        metric: impl Into<String>,
        value: f64,
        detail: impl Into<String>,
    ) -> Check {
        Check::with_status(name, gate, metric, value, 0.0, Status::Fail, detail)
    }

    /// The verdict of a negative control: it passes when nothing in `unbitten` (the
    /// gates or claims the wrong physics did not fail) is left.
    pub fn control(label: impl Into<String>, unbitten: &[String], detail: String) -> Check {
        if unbitten.is_empty() {
            Check::at_most(
                label,
                Gate::NegativeControl,
                "gates that did not fail",
                0.0,
                0.0,
                detail,
            )
        } else {
            Check::failed(
                label,
                Gate::NegativeControl,
                format!("the wrong physics passed {}", unbitten.join(", ")),
                unbitten.len() as f64,
                format!("the control did not bite: {detail}"),
            )
        }
    }

    /// A negative control whose unbitten gates the wrong physics left INCONCLUSIVE: the
    /// data resolve neither the control biting nor its failing to (one bed, too few
    /// beds). Never a pass.
    pub(crate) fn control_unresolved(
        label: impl Into<String>,
        unresolved: &[String],
        detail: String,
    ) -> Check {
        Check::with_status(
            label,
            Gate::NegativeControl,
            format!(
                "gates the wrong physics left unresolved: {}",
                unresolved.join(", ")
            ),
            unresolved.len() as f64,
            0.0,
            Status::Inconclusive,
            format!("the control cannot bite a gate the data do not resolve: {detail}"),
        )
    }

    /// A stage that produced nothing to compare: never a pass.
    pub fn error(name: impl Into<String>, message: impl Into<String>) -> Check {
        Check::error_in(name, Gate::Run, message)
    }

    /// A gate whose inputs could not be computed.
    pub(crate) fn error_in(
        name: impl Into<String>,
        gate: Gate,
        message: impl Into<String>,
    ) -> Check {
        Check::with_status(name, gate, "error", f64::NAN, 0.0, Status::Error, message)
    }

    /// Too little data for the gate to mean anything: not a pass, not a physics failure.
    pub(crate) fn not_compared(
        name: impl Into<String>,
        gate: Gate,
        reason: impl Into<String>,
    ) -> Check {
        Check::with_status(
            name,
            gate,
            "not compared",
            f64::NAN,
            0.0,
            Status::NotCompared,
            reason,
        )
    }

    /// A gate whose value carries a standard error `se` (rules 2 and 3 with amendment A,
    /// docs/stress.md): decided as [`Check::at_most`] when 2 se <= tolerance; otherwise
    /// it fails when value - 2 se > tolerance (a failure the data resolve) and is NOT
    /// COMPARED (`unresolved` says why) when neither holds. It can never pass on data
    /// that cannot resolve the tolerance.
    #[allow(clippy::too_many_arguments)]
    #[cfg(test)]
    pub(crate) fn at_most_resolved(
        name: impl Into<String>,
        gate: Gate,
        metric: impl Into<String>,
        value: f64,
        se: f64,
        tolerance: f64,
        detail: impl Into<String>,
        unresolved: impl Into<String>,
    ) -> Check {
        let detail = detail.into();
        if se.is_finite() && 2.0 * se <= tolerance {
            Check::at_most(name, gate, metric, value, tolerance, detail)
        } else if se.is_finite() && value - 2.0 * se > tolerance {
            Check::at_most(
                name,
                gate,
                metric,
                value,
                tolerance,
                format!(
                    "a resolved failure (amendment A): value - 2 x standard error = {:.4} > tolerance {tolerance} although 2 x standard error {:.4} > tolerance; {detail}",
                    value - 2.0 * se,
                    2.0 * se
                ),
            )
        } else {
            Check::not_compared(name, gate, format!("{}; {detail}", unresolved.into()))
        }
    }

    /// A statistical gate (docs/statistics.md): the comparisons the claim needs, combined
    /// as [`stats::all_of`] (PASS when each passes, FAIL when one fails at its Bonferroni
    /// level, INCONCLUSIVE otherwise). `value` and `tolerance` of the check are those of
    /// the comparison that decided it (the first failing one, else the first undecided,
    /// else the one closest to its threshold).
    pub(crate) fn decided(
        name: impl Into<String>,
        gate: Gate,
        metric: impl Into<String>,
        parts: &[Comparison],
        detail: impl Into<String>,
    ) -> Check {
        let decisions: Vec<Decision> = parts.iter().map(Comparison::decision).collect();
        let verdict = stats::all_of(&decisions);
        let status = match verdict {
            Decision::Pass => Status::Pass,
            Decision::Fail => Status::Fail,
            Decision::Inconclusive => Status::Inconclusive,
        };
        let key = decisions
            .iter()
            .position(|d| *d == Decision::Fail)
            .or_else(|| decisions.iter().position(|d| *d != Decision::Pass))
            .unwrap_or(0);
        let (value, tolerance) = parts
            .get(key)
            .map(|c| {
                let t = match c.rule {
                    Rule::Equivalence { margin } => margin,
                    Rule::Exceeds { delta } => delta,
                };
                (c.estimate.map_or(f64::NAN, |e| e.value), t)
            })
            .unwrap_or((f64::NAN, f64::NAN));
        let parts_text = parts
            .iter()
            .map(Comparison::describe)
            .collect::<Vec<_>>()
            .join("; ");
        let detail = detail.into();
        let detail = if detail.is_empty() {
            parts_text
        } else {
            format!("{parts_text}; {detail}")
        };
        Check::with_status(name, gate, metric, value, tolerance, status, detail)
    }

    pub fn is_error(&self) -> bool {
        self.status == Status::Error
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(value: f64, se: f64) -> Status {
        Check::at_most_resolved("g", Gate::KPhi, "m", value, se, 0.10, "", "why").status
    }

    /// Amendment A (docs/stress.md): resolved errors decide as registered, a failure
    /// beyond two standard errors fails, nothing unresolved passes.
    #[test]
    fn a_gate_with_a_standard_error() {
        assert_eq!(status(0.075, 0.044), Status::Pass);
        assert_eq!(status(0.12, 0.04), Status::Fail);
        // The new-seed mu_gg control: 0.309 with SE 0.0585.
        assert_eq!(status(0.309, 0.0585), Status::Fail);
        assert_eq!(status(0.15, 0.06), Status::NotCompared);
        assert_eq!(status(0.01, 0.06), Status::NotCompared);
        assert_eq!(status(0.5, f64::NAN), Status::NotCompared);
        assert_eq!(status(f64::NAN, 0.01), Status::Fail);
    }
}
