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

/// Collects the location once so validation code can say `ctx.bad("field", v, "why")`.
#[derive(Debug, Clone)]
pub struct Ctx {
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
