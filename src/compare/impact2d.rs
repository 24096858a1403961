//! Impact checks (Kondic et al.): native vs LAMMPS per variant (final depth, D(t) RMS
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
    /// Largest |v| of the intruder in the final window (d / tau_c): is it at rest?
    pub final_speed: f64,
    /// Samples the final depth was averaged over.
    pub final_samples: usize,
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
    let n = a.final_samples.min(b.final_samples);
    if let Some(c) = super::coverage::fit_points(
        &name("coverage of the final-depth window"),
        "intruder samples in the final window (final_window / output_every)",
        n,
    ) {
        return vec![
            c,
            Check::not_compared(
                name(&format!("final depth native vs {reference}")),
                crate::compare::Gate::FinalDepth,
                "too few samples in the final window",
            ),
        ];
    }
    let mut out = vec![Check::at_most(
        name(&format!("final depth native vs {reference}")),
        crate::compare::Gate::FinalDepth,
        "|D_native - D_ref| / d",
        (a.final_depth - b.final_depth).abs(),
        tol.final_depth_abs,
        format!(
            "D_native = {:.3} d, D_{reference} = {:.3} d (mean over the last {:.0} tau_c; max intruder speed there {:.1e} / {:.1e} d/tau_c)",
            a.final_depth,
            b.final_depth,
            case.final_window / case.scales.tau_c,
            a.final_speed,
            b.final_speed
        ),
    )];
    out.push(match rms {
        Ok(r) => Check::at_most(
            name("D(t) distance"),
            crate::compare::Gate::DepthSeries,
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
            if obs.len() < 2 {
                return Some(Check::not_compared(
                    format!("{}: claim ({engine})", case.name),
                    crate::compare::Gate::Claim,
                    "a trend needs at least 2 variants",
                ));
            }
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
                crate::compare::Gate::Claim,
                "max_k (D_k + min_step - D_k+1) / d",
                worst,
                0.0,
                format!("min_step {min_step} d; final depths (d): {listing}"),
            )
        }
        Claim::Linear { from, r2_min } => {
            let pts: Vec<&VariantObs> = obs.iter().filter(|o| o.x >= *from).collect();
            if pts.len() < 3 {
                return Some(Check::not_compared(
                    format!("{}: claim ({engine})", case.name),
                    crate::compare::Gate::Claim,
                    format!(
                        "a line through {} point(s) tests nothing: at least 3 variants with {param} >= {from} are needed",
                        pts.len()
                    ),
                ));
            }
            let x: Vec<f64> = pts.iter().map(|o| o.x).collect();
            let y: Vec<f64> = pts.iter().map(|o| o.final_depth).collect();
            match crate::analysis::impact::linear_r2(&x, &y) {
                Ok((a, b, r2)) => Check::at_most(
                    format!(
                        "{}: claim ({engine}): final depth linear in {param} for {param} >= {from}",
                        case.name
                    ),
                    crate::compare::Gate::Claim,
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn case(claim: &str, sweep: &str) -> Impact2dCase {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/cases/impact2d/ci.toml"
        ))
        .unwrap();
        Impact2dCase::from_toml_str(&format!("{text}\n{sweep}\n{claim}\n"), Path::new("t.toml"))
            .unwrap()
    }

    fn obs(xs: &[f64], ds: &[f64]) -> Vec<VariantObs> {
        xs.iter()
            .zip(ds)
            .map(|(&x, &d)| VariantObs {
                label: format!("{x}"),
                x,
                final_depth: d,
                max_depth: d,
                final_speed: 0.0,
                final_samples: 100,
            })
            .collect()
    }

    #[test]
    fn increasing_claim_passes_rising_and_fails_falling_or_too_flat() {
        let c = case(
            "[claim]\nkind = \"increasing\"\nmin_step = 0.5",
            "[sweep]\nparameter = \"e_n\"\nvalues = [0.1, 0.5, 0.9]",
        );
        assert!(
            claim_check(&c, "x", &obs(&[0.1, 0.5, 0.9], &[1.0, 2.0, 3.0]))
                .unwrap()
                .passed
        );
        assert!(
            !claim_check(&c, "x", &obs(&[0.1, 0.5, 0.9], &[3.0, 2.0, 1.0]))
                .unwrap()
                .passed
        );
        assert!(
            !claim_check(&c, "x", &obs(&[0.1, 0.5, 0.9], &[1.0, 1.3, 3.0]))
                .unwrap()
                .passed
        );
    }

    #[test]
    fn linear_claim_fails_curved_and_falling_data() {
        let c = case(
            "[claim]\nkind = \"linear\"\nfrom = 0.4\nr2_min = 0.9",
            "[sweep]\nparameter = \"speed\"\nvalues = [0.1, 0.4, 0.7, 1.0]",
        );
        let x = [0.1, 0.4, 0.7, 1.0];
        assert!(
            claim_check(&c, "x", &obs(&x, &[0.0, 2.0, 3.5, 5.0]))
                .unwrap()
                .passed
        );
        assert!(
            !claim_check(&c, "x", &obs(&x, &[0.0, 1.0, 1.0, 9.0]))
                .unwrap()
                .passed
        );
        assert!(
            !claim_check(&c, "x", &obs(&x, &[0.0, 5.0, 3.5, 2.0]))
                .unwrap()
                .passed
        );
    }

    #[test]
    fn cross_check_fails_beyond_a_grain() {
        let c = case("", "");
        let a = &obs(&[0.0], &[5.0])[0];
        let b = &obs(&[0.0], &[6.5])[0];
        let checks = cross_check(&c, a, b, Ok(1.2), "lammps");
        assert!(checks.iter().all(|k| !k.passed));
        let checks = cross_check(&c, a, a, Ok(0.1), "lammps");
        assert!(checks.iter().all(|k| k.passed));
    }
}
