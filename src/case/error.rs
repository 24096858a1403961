//! Errors for bad case input. A researcher who mistypes a friction coefficient must
//! learn which file, which field, which value and why — never a panic, never a
//! silently substituted default.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum CaseError {
    /// The I/O error is part of the message, not a `source`: chained printing
    /// (`{:#}`) would otherwise say it twice.
    #[error("{file}: cannot read: {error}")]
    Io {
        file: PathBuf,
        error: std::io::Error,
    },
    #[error("{file}: {message}")]
    Parse { file: PathBuf, message: String },
    #[error("{file}: field `{field}` = {value}: {reason}")]
    Invalid {
        file: PathBuf,
        field: String,
        value: String,
        reason: String,
    },
}

impl CaseError {
    /// This error with the plausibility warnings of the same file appended: a value in
    /// the wrong unit is the likely cause of a refusal that names another field (a
    /// density in g/cm^3 shrinks the Rayleigh time, and the time step is refused).
    pub(crate) fn noting(self, warnings: &[String]) -> CaseError {
        match self {
            CaseError::Invalid {
                file,
                field,
                value,
                reason,
            } if !warnings.is_empty() => CaseError::Invalid {
                file,
                field,
                value,
                reason: format!(
                    "{reason} (likely cause, an implausible input: {})",
                    warnings.join("; ")
                ),
            },
            e => e,
        }
    }
}

/// Collects the location once so validation code can say `ctx.bad("field", v, "why")`.
#[derive(Debug, Clone)]
pub(crate) struct Ctx {
    pub file: PathBuf,
}

impl Ctx {
    pub fn bad(
        &self,
        field: impl Into<String>,
        value: impl std::fmt::Debug,
        reason: impl Into<String>,
    ) -> CaseError {
        CaseError::Invalid {
            file: self.file.clone(),
            field: field.into(),
            value: format!("{value:?}"),
            reason: reason.into(),
        }
    }
}
