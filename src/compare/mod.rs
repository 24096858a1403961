//! Turns two runs (or a run and a published/theoretical value) into named metrics with
//! tolerances and a verdict each. Nothing here knows which engine produced what.

pub mod coverage;
pub mod ensemble;
pub mod impact2d;
pub mod interface;
pub mod malt_points;
pub mod penetration;
pub mod stress;
pub mod sweep;
pub mod trajectory;
pub mod triaxial;

use serde::{Deserialize, Serialize};

/// The verdict of one check. Only `Pass` lets a run exit 0: a check that could not be
/// evaluated (`NotCompared`: too little data to mean anything) or whose inputs failed
/// (`Error`: a crashed engine, a corrupt reference) is never a pass.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    Pass,
    Fail,
    NotCompared,
    Error,
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
}

/// serde_json writes a non-finite f64 as `null`; read `null` back as NaN so that every
/// report.json granval writes can be read again.
pub(crate) fn nan_from_null<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

impl Check {
    fn with_status(
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
        }
    }

    /// Passes when `value <= tolerance`. NaN never passes.
    pub fn at_most(
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
    pub fn fail_if(mut self, failed: bool, why: &str) -> Check {
        if failed && self.status == Status::Pass {
            self.status = Status::Fail;
            self.passed = false;
            self.detail = format!("{}; fails: {why}", self.detail);
        }
        self
    }

    /// Passes when `value >= minimum`. NaN never passes.
    pub fn at_least(
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

    /// A stage that produced nothing to compare: never a pass.
    pub fn error(name: impl Into<String>, message: impl Into<String>) -> Check {
        Check::error_in(name, Gate::Run, message)
    }

    /// A gate whose inputs could not be computed.
    pub fn error_in(name: impl Into<String>, gate: Gate, message: impl Into<String>) -> Check {
        Check::with_status(name, gate, "error", f64::NAN, 0.0, Status::Error, message)
    }

    /// Too little data for the gate to mean anything: not a pass, not a physics failure.
    pub fn not_compared(name: impl Into<String>, gate: Gate, reason: impl Into<String>) -> Check {
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
    pub fn at_most_resolved(
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
