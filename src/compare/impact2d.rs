//! Impact checks (Kondic et al.): native vs LAMMPS per variant (final depth, D(t) RMS
//! distance), and K's claims over a sweep, evaluated separately in each engine.

use super::Check;
use crate::case::impact2d::{Claim, ClaimQuantity, Impact2dCase};

/// What one run of one variant reduces to (lengths in d).
#[derive(Debug, Clone, serde::Serialize)]
pub struct VariantObs {
    pub label: String,
    pub x: f64,
    pub final_depth: f64,
    pub max_depth: f64,
    /// When the maximum depth was reached (tau_c after release).
    pub t_max_depth: f64,
    /// Total energy (kinetic + potential relative to the first sample + normal elastic)
    /// at each energy sample: (t in tau_c after release, E in m g d).
    pub energy: Vec<(f64, f64)>,
    /// The intruder's impact energy M v^2 / 2 (m g d).
    pub impact_energy: f64,
    /// Largest |v| of the intruder in the final window (d / tau_c): is it at rest?
    pub final_speed: f64,
    /// Samples the final depth was averaged over.
    pub final_samples: usize,
    /// (t in tau_c, D in d, downward speed in d / tau_c) at every intruder sample, for
    /// claims on the force law (K Fig 29).
    #[serde(skip)]
    pub trajectory: Vec<(f64, f64, f64)>,
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

/// K's claims of the case over its variants (in sweep order), for one engine.
pub fn claim_checks(case: &Impact2dCase, engine: &str, obs: &[VariantObs]) -> Vec<Check> {
    case.claims
        .iter()
        .map(|c| claim_check(case, c, engine, obs))
        .collect()
}

fn claim_check(case: &Impact2dCase, claim: &Claim, engine: &str, obs: &[VariantObs]) -> Check {
    let param = case.sweep_parameter.clone().unwrap_or_default();
    let listing = |f: &dyn Fn(&VariantObs) -> f64| {
        obs.iter()
            .map(|o| format!("{}: {:.3}", o.label, f(o)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    match claim {
        Claim::Increasing { min_step, of, at } => {
            let (what, unit) = of.describe();
            if obs.len() < 2 {
                return Check::not_compared(
                    format!("{}: claim ({engine}): {what}", case.name),
                    crate::compare::Gate::Claim,
                    "a trend needs at least 2 variants",
                );
            }
            let value = |o: &VariantObs| match of {
                ClaimQuantity::FinalDepth => o.final_depth,
                ClaimQuantity::TimeOfMaxDepth => o.t_max_depth,
                ClaimQuantity::EnergyLost => energy_lost(o, at.unwrap_or(f64::NAN)),
            };
            if let Some(o) = obs.iter().find(|o| !value(o).is_finite()) {
                return Check::error_in(
                    format!("{}: claim ({engine}): {what}", case.name),
                    crate::compare::Gate::Claim,
                    format!(
                        "variant {}: no {what} (no energy sample at or after the time read)",
                        o.label
                    ),
                );
            }
            // Largest y_k + min_step - y_{k+1}: <= 0 iff every step rises by min_step.
            let worst = obs
                .windows(2)
                .map(|w| value(&w[0]) + min_step - value(&w[1]))
                .fold(f64::NEG_INFINITY, f64::max);
            Check::at_most(
                format!(
                    "{}: claim ({engine}): {what} increases along {param}",
                    case.name
                ),
                crate::compare::Gate::Claim,
                format!("max_k (y_k + min_step - y_k+1) / {unit}"),
                worst,
                0.0,
                format!(
                    "min_step {min_step} {unit}; {what} ({unit}): {}",
                    listing(&value)
                ),
            )
        }
        Claim::EnergyNonIncreasing { max_rise } => {
            // Largest rise of E between consecutive samples, over the impact energy.
            let rise = |o: &VariantObs| {
                o.energy
                    .windows(2)
                    .map(|w| (w[1].1 - w[0].1) / o.impact_energy)
                    .fold(f64::NEG_INFINITY, f64::max)
            };
            let worst = obs.iter().map(rise).fold(f64::NEG_INFINITY, f64::max);
            let per: Vec<String> = obs
                .iter()
                .map(|o| format!("{}: {:.2e}", o.label, rise(o)))
                .collect();
            if obs.iter().any(|o| o.energy.len() < 2) {
                return Check::error_in(
                    format!("{}: claim ({engine}): total energy never rises", case.name),
                    crate::compare::Gate::Claim,
                    "a variant has fewer than 2 energy samples",
                );
            }
            Check::at_most(
                format!("{}: claim ({engine}): total energy never rises", case.name),
                crate::compare::Gate::Claim,
                "max over samples of (E_k+1 - E_k) / (M v^2 / 2)",
                worst,
                *max_rise,
                format!(
                    "largest rise per variant: {}; M v^2 / 2 = {:.4e} m g d",
                    per.join(", "),
                    obs.first().map_or(f64::NAN, |o| o.impact_energy)
                ),
            )
        }
        Claim::VelocityExponent {
            depths,
            half_width,
            min,
            max,
            ..
        } => {
            let name = format!(
                "{}: claim ({engine}): deceleration ~ u^k at depths {depths:?} +- {half_width} d",
                case.name
            );
            match velocity_exponent(obs, depths, *half_width) {
                Ok((k, detail)) if (*min..=*max).contains(&k) => Check::at_least(
                    name,
                    crate::compare::Gate::Claim,
                    format!("k, must lie in [{min}, {max}]"),
                    k,
                    *min,
                    detail,
                ),
                Ok((k, detail)) => Check::failed(
                    name,
                    crate::compare::Gate::Claim,
                    format!("k, must lie in [{min}, {max}]"),
                    k,
                    detail,
                ),
                Err(e) => Check::not_compared(name, crate::compare::Gate::Claim, e),
            }
        }
        Claim::Linear { from, r2_min } => {
            let pts: Vec<&VariantObs> = obs.iter().filter(|o| o.x >= *from).collect();
            if pts.len() < 3 {
                return Check::not_compared(
                    format!("{}: claim ({engine})", case.name),
                    crate::compare::Gate::Claim,
                    format!(
                        "a line through {} point(s) tests nothing: at least 3 variants with {param} >= {from} are needed",
                        pts.len()
                    ),
                );
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
                        "D = {a:.3} + {b:.3} x (R^2 {r2:.4}; the slope must be > 0); final depths (d): {}",
                        listing(&|o| o.final_depth)
                    ),
                ),
                Err(e) => {
                    Check::error(format!("{}: claim ({engine})", case.name), format!("{e:#}"))
                }
            }
        }
    }
}

/// k of a ~ u^k (K Fig 29) over the passages of every variant through the bins, with
/// the fit's description; an error when fewer than 4 passages with a > 0 from at least 3
/// variants remain (a power through fewer tests nothing).
pub fn velocity_exponent(
    obs: &[VariantObs],
    depths: &[f64],
    half_width: f64,
) -> Result<(f64, String), String> {
    use crate::analysis::impact::{passages, power_law};
    let mut all = Vec::new();
    let mut variants = 0;
    let mut dropped = 0;
    for o in obs {
        let p = passages(&o.trajectory, depths, half_width);
        let positive = p.iter().filter(|q| q.decel > 0.0).count();
        dropped += p.len() - positive;
        if positive > 0 {
            variants += 1;
        }
        all.extend(p);
    }
    let used = all.iter().filter(|q| q.decel > 0.0).count();
    if used < 4 || variants < 3 {
        return Err(format!(
            "{used} passage(s) with a > 0 from {variants} variant(s): a power law needs at least 4 from 3 variants"
        ));
    }
    let (k, c, r2, n) = power_law(&all).map_err(|e| format!("{e:#}"))?;
    let pts = all
        .iter()
        .map(|q| format!("(y {:.1}: u {:.3}, a {:.4})", q.y, q.u, q.decel))
        .collect::<Vec<_>>()
        .join(" ");
    Ok((
        k,
        format!(
            "a = {c:.4} u^{k:.3} (R^2 {r2:.3}) over {n} passages ({dropped} with a <= 0 left out); d, tau_c units: {pts}"
        ),
    ))
}

/// Native vs reference k of every velocity-exponent claim of the case.
pub fn exponent_cross_checks(
    case: &Impact2dCase,
    native: &[VariantObs],
    reference: &[VariantObs],
    engine: &str,
) -> Vec<Check> {
    case.claims
        .iter()
        .filter_map(|c| match c {
            Claim::VelocityExponent {
                depths,
                half_width,
                engine_tol,
                ..
            } => Some((depths, *half_width, *engine_tol)),
            _ => None,
        })
        .map(|(depths, half, tol)| {
            let name = format!("{}: velocity exponent k native vs {engine}", case.name);
            match (
                velocity_exponent(native, depths, half),
                velocity_exponent(reference, depths, half),
            ) {
                (Ok((a, da)), Ok((b, db))) => Check::at_most(
                    name,
                    crate::compare::Gate::Claim,
                    "|k_native - k_ref|",
                    (a - b).abs(),
                    tol,
                    format!("native {da}; {engine} {db}"),
                ),
                (a, b) => Check::not_compared(
                    name,
                    crate::compare::Gate::Claim,
                    format!("native: {:?}; {engine}: {:?}", a.err(), b.err()),
                ),
            }
        })
        .collect()
}

/// E(0) - E(t) at the first energy sample at or after `t` (tau_c); NaN if none.
fn energy_lost(o: &VariantObs, t: f64) -> f64 {
    let Some(first) = o.energy.first() else {
        return f64::NAN;
    };
    o.energy
        .iter()
        .find(|(s, _)| *s >= t)
        .map_or(f64::NAN, |(_, e)| first.1 - e)
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
                t_max_depth: d,
                energy: vec![],
                impact_energy: 1.0,
                final_speed: 0.0,
                final_samples: 100,
                trajectory: Vec::new(),
            })
            .collect()
    }

    /// The velocity exponent claim reads k off the passages of every variant: in range
    /// it passes, out of range it fails, and native vs reference compares the two k.
    #[test]
    fn velocity_exponent_claim_fits_the_force_law() {
        let c = case(
            "[claim]\nkind = \"velocity_exponent\"\ndepths = [1.0, 2.0, 3.0]\nhalf_width = 0.5\nmin = 0.7\nmax = 1.3\nengine_tol = 0.2",
            "[sweep]\nparameter = \"speed\"\nvalues = [0.2, 0.4, 0.7, 1.0]",
        );
        let speeds = [0.2, 0.4, 0.7, 1.0];
        let with = |k: f64| {
            let mut o = obs(&speeds, &[1.0; 4]);
            for (x, v) in o.iter_mut().zip(speeds) {
                x.trajectory = crate::analysis::impact::power_law_trajectory(v, 0.02, k, 0.01);
            }
            o
        };
        let k = one(&c, &with(1.0)).unwrap();
        assert!(k.passed && (k.value - 1.0).abs() < 0.05, "{k:?}");
        assert!(!one(&c, &with(1.8)).unwrap().passed);
        let x = exponent_cross_checks(&c, &with(1.0), &with(1.1), "lammps");
        assert!(x.len() == 1 && x[0].passed, "{x:?}");
        let x = exponent_cross_checks(&c, &with(1.0), &with(1.5), "lammps");
        assert!(!x[0].passed, "{x:?}");
        // Two variants cannot pin a power law down.
        let few = with(1.0)[..2].to_vec();
        let k = one(&c, &few).unwrap();
        assert_eq!(k.status, crate::compare::Status::NotCompared, "{k:?}");
    }

    fn one(c: &Impact2dCase, obs: &[VariantObs]) -> Option<Check> {
        let mut v = claim_checks(c, "x", obs);
        assert!(v.len() <= 1);
        v.pop()
    }

    #[test]
    fn increasing_claim_passes_rising_and_fails_falling_or_too_flat() {
        let c = case(
            "[claim]\nkind = \"increasing\"\nmin_step = 0.5",
            "[sweep]\nparameter = \"e_n\"\nvalues = [0.1, 0.5, 0.9]",
        );
        assert!(
            one(&c, &obs(&[0.1, 0.5, 0.9], &[1.0, 2.0, 3.0]))
                .unwrap()
                .passed
        );
        assert!(
            !one(&c, &obs(&[0.1, 0.5, 0.9], &[3.0, 2.0, 1.0]))
                .unwrap()
                .passed
        );
        assert!(
            !one(&c, &obs(&[0.1, 0.5, 0.9], &[1.0, 1.3, 3.0]))
                .unwrap()
                .passed
        );
    }

    /// Two claims give two checks; the time claim reads t_max_depth, not the depth.
    #[test]
    fn time_of_max_claim_follows_its_own_quantity() {
        let c = case(
            "[[claim]]\nkind = \"increasing\"\nmin_step = 1.0\n[[claim]]\nkind = \"increasing\"\nof = \"time_of_max_depth\"\nmin_step = 5.0",
            "[sweep]\nparameter = \"gravity\"\nvalues = [2.0, 1.0, 0.5]",
        );
        let mut o = obs(&[2.0, 1.0, 0.5], &[5.0, 7.0, 9.0]);
        for (k, t) in [40.0, 60.0, 62.0].into_iter().enumerate() {
            o[k].t_max_depth = t;
        }
        let v = claim_checks(&c, "x", &o);
        assert_eq!(v.len(), 2);
        assert!(v[0].passed, "depths rise by 2 d per step");
        assert!(!v[1].passed, "the last delay is 2 tau_c < 5");
        assert!((v[1].value - 3.0).abs() < 1e-12, "{}", v[1].value);
        o[2].t_max_depth = 70.0;
        assert!(claim_checks(&c, "x", &o).iter().all(|k| k.passed));
    }

    /// Energy claims: the loss at a time rises with friction; a rise of E fails.
    #[test]
    fn energy_claims_read_the_total_energy_series() {
        let c = case(
            "[[claim]]\nkind = \"increasing\"\nof = \"energy_lost\"\nat = 100.0\n[[claim]]\nkind = \"energy_non_increasing\"\nmax_rise = 0.01",
            "[sweep]\nparameter = \"mu\"\nvalues = [0.0, 0.5]",
        );
        let mut o = obs(&[0.0, 0.5], &[5.0, 4.0]);
        o[0].energy = vec![(0.0, 10.0), (50.0, 8.0), (100.0, 7.0)];
        o[1].energy = vec![(0.0, 10.0), (50.0, 5.0), (100.0, 4.0)];
        let v = claim_checks(&c, "x", &o);
        assert!(v[0].passed && v[1].passed, "{v:?}");
        // E rises from 5 to 7.5 (2.5 impact energies); the loss by t = 100 drops to 2.5.
        o[1].energy[2].1 = 7.5;
        let v = claim_checks(&c, "x", &o);
        assert!(!v[0].passed, "loss 2.5 < 3 with friction");
        assert!(
            !v[1].passed && (v[1].value - 2.5).abs() < 1e-12,
            "{:?}",
            v[1]
        );
    }

    #[test]
    fn linear_claim_fails_curved_and_falling_data() {
        let c = case(
            "[claim]\nkind = \"linear\"\nfrom = 0.4\nr2_min = 0.9",
            "[sweep]\nparameter = \"speed\"\nvalues = [0.1, 0.4, 0.7, 1.0]",
        );
        let x = [0.1, 0.4, 0.7, 1.0];
        assert!(one(&c, &obs(&x, &[0.0, 2.0, 3.5, 5.0])).unwrap().passed);
        assert!(!one(&c, &obs(&x, &[0.0, 1.0, 1.0, 9.0])).unwrap().passed);
        assert!(!one(&c, &obs(&x, &[0.0, 5.0, 3.5, 2.0])).unwrap().passed);
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
