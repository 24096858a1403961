//! Impact checks (issue 5): native vs LAMMPS per variant (final depth, D(t) RMS
//! distance), and K's claims over a sweep, evaluated separately in each engine.

use super::Check;
use crate::case::impact2d::{Claim, Impact2dCase};

/// What one run of one variant reduces to (lengths in d).
#[derive(Debug, Clone, serde::Serialize)]
pub struct VariantObs {
    pub label: String,
    pub x: f64,
    pub final_depth: f64,
    pub max_depth: f64,
}

/// Native vs reference for one variant. `rms` is the D(t) RMS distance in d, or the
/// reason it could not be computed.
pub fn cross_check(
    case: &Impact2dCase,
    a: &VariantObs,
    b: &VariantObs,
    rms: Result<f64, String>,
    reference: &str,
) -> Vec<Check> {
    let tol = &case.tolerances;
    let name = |w: &str| format!("{} [{}]: {w}", case.name, a.label);
    let mut out = vec![Check::at_most(
        name(&format!("final depth native vs {reference}")),
        "|D_native - D_ref| / d",
        (a.final_depth - b.final_depth).abs(),
        tol.final_depth_abs,
        format!(
            "D_native = {:.3} d, D_{reference} = {:.3} d (mean over the last {:.0} tau_c)",
            a.final_depth,
            b.final_depth,
            case.final_window / case.scales.tau_c
        ),
    )];
    out.push(match rms {
        Ok(r) => Check::at_most(
            name("D(t) distance"),
            "RMS(D_native - D_ref) / d",
            r,
            tol.depth_rms,
            format!("max depth {:.3} d vs {:.3} d", a.max_depth, b.max_depth),
        ),
        Err(e) => Check::error(name("D(t) distance"), e),
    });
    out
}

/// K's claim of the case over its variants (in sweep order), for one engine.
pub fn claim_check(case: &Impact2dCase, engine: &str, obs: &[VariantObs]) -> Option<Check> {
    let claim = case.claim.as_ref()?;
    let param = case.sweep_parameter.clone().unwrap_or_default();
    let listing = obs
        .iter()
        .map(|o| format!("{}: {:.3}", o.label, o.final_depth))
        .collect::<Vec<_>>()
        .join(", ");
    Some(match claim {
        Claim::Increasing { min_step } => {
            // Largest D_k + min_step - D_{k+1}: <= 0 iff every step rises by min_step.
            let worst = obs
                .windows(2)
                .map(|w| w[0].final_depth + min_step - w[1].final_depth)
                .fold(f64::NEG_INFINITY, f64::max);
            Check::at_most(
                format!(
                    "{}: claim ({engine}): final depth increases along {param}",
                    case.name
                ),
                "max_k (D_k + min_step - D_k+1) / d",
                worst,
                0.0,
                format!("min_step {min_step} d; final depths (d): {listing}"),
            )
        }
        Claim::Linear { from, r2_min } => {
            let pts: Vec<&VariantObs> = obs.iter().filter(|o| o.x >= *from).collect();
            let x: Vec<f64> = pts.iter().map(|o| o.x).collect();
            let y: Vec<f64> = pts.iter().map(|o| o.final_depth).collect();
            match crate::analysis::impact::linear_r2(&x, &y) {
                Ok((a, b, r2)) => Check::at_most(
                    format!(
                        "{}: claim ({engine}): final depth linear in {param} for {param} >= {from}",
                        case.name
                    ),
                    "1 - R^2 of the least-squares line",
                    // A falling line is no support for "grows linearly".
                    if b > 0.0 { 1.0 - r2 } else { f64::INFINITY },
                    1.0 - r2_min,
                    format!(
                        "D = {a:.3} + {b:.3} x (R^2 {r2:.4}; the slope must be > 0); final depths (d): {listing}"
                    ),
                ),
                Err(e) => {
                    Check::error(format!("{}: claim ({engine})", case.name), format!("{e:#}"))
                }
            }
        }
    })
}
