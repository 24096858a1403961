//! Turns two runs (or a run and a published/theoretical value) into named metrics with
//! tolerances and a verdict each. Nothing here knows which engine produced what.

pub mod impact2d;
pub mod penetration;
pub mod trajectory;

use serde::{Deserialize, Serialize};

/// One gated comparison. The JSON shape `{name, metric, value, tolerance, passed}` is
/// the stable interface CI scripts read; `detail` says where the worst value occurred.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Check {
    pub name: String,
    pub metric: String,
    pub value: f64,
    pub tolerance: f64,
    pub passed: bool,
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub detail: String,
}

impl Check {
    /// A check that passes when `value <= tolerance`. NaN never passes.
    pub fn at_most(
        name: impl Into<String>,
        metric: impl Into<String>,
        value: f64,
        tolerance: f64,
        detail: impl Into<String>,
    ) -> Check {
        Check {
            name: name.into(),
            metric: metric.into(),
            value,
            tolerance,
            passed: value <= tolerance,
            detail: detail.into(),
        }
    }

    /// A reference engine that crashed or produced nothing: a failed check, never a pass.
    pub fn error(name: impl Into<String>, message: impl Into<String>) -> Check {
        Check {
            name: name.into(),
            metric: "error".into(),
            value: f64::NAN,
            tolerance: 0.0,
            passed: false,
            detail: message.into(),
        }
    }
}
