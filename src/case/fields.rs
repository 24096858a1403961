//! Checks of single fields, shared by every case kind's validation (and by the clump
//! templates, which `validate` itself calls: kept apart so neither imports the other).

use super::error::{CaseError, Ctx};

pub(crate) fn finite(ctx: &Ctx, field: &str, v: f64) -> Result<f64, CaseError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ctx.bad(field, v, "must be a finite number"))
    }
}

pub(crate) fn positive(ctx: &Ctx, field: &str, v: f64) -> Result<f64, CaseError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(ctx.bad(field, v, "must be > 0"))
    }
}

pub(crate) fn vec3(ctx: &Ctx, field: &str, v: [f64; 3]) -> Result<[f64; 3], CaseError> {
    for (k, c) in v.iter().enumerate() {
        finite(ctx, &format!("{field}[{k}]"), *c)?;
    }
    Ok(v)
}
