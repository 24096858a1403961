//! K Fig 12's checks (docs/impact2d.md, "Depth below the moving interface"): the
//! `interface_steadies` claim in one engine, and native vs reference s(t).

use super::{Check, Gate, Status};
use crate::analysis::interface::Oscillation;
use crate::case::impact2d::Impact2dCase;

/// The interface observables of one run (lengths in d, times in tau_c).
#[derive(Debug, Clone, serde::Serialize)]
pub struct InterfaceObs {
    /// How many disks the interface height averages (the tracers, or the control's floor).
    pub tracers: usize,
    /// A[D] and its rough period over the final window.
    pub depth: Oscillation,
    /// A[D_rel] and its rough period over the final window.
    pub relative: Oscillation,
    /// (t, s) at every intruder sample.
    #[serde(skip)]
    pub shift: Vec<(f64, f64)>,
    /// (t, D_rel) at every intruder sample.
    #[serde(skip)]
    pub relative_series: Vec<(f64, f64)>,
}

fn period(o: &Oscillation) -> String {
    o.period
        .map_or(format!("- ({} crossing(s))", o.crossings), |p| {
            format!("{p:.1}")
        })
}

/// The `interface_steadies` claim in one engine over the variants `(label, interface
/// observables)`, in sweep order: a variant is tested when A[D] >= `min_amplitude` and
/// holds when A[D_rel] <= `max_ratio` A[D]; the claim fails when a tested variant
/// fails, else is NOT COMPARED when a variant is untested, else passes. A variant
/// without interface observables is an error.
pub(crate) fn steadies(
    case: &Impact2dCase,
    max_ratio: f64,
    min_amplitude: f64,
    engine: &str,
    variants: &[(&str, Option<&InterfaceObs>)],
) -> Check {
    let name = format!(
        "{}: claim ({engine}): the long-time oscillations of D vanish below the moving interface (K Fig 12)",
        case.name
    );
    let metric = "max over tested variants of A[D_rel] / A[D]";
    let mut rows = Vec::new();
    let (mut worst, mut failed, mut untested) = (f64::NEG_INFINITY, Vec::new(), Vec::new());
    for &(label, o) in variants {
        let Some(o) = o else {
            return Check::error_in(
                name,
                Gate::Claim,
                format!("variant {label} has no interface observables"),
            );
        };
        let (a, r) = (o.depth.amplitude, o.relative.amplitude);
        let ratio = r / a;
        rows.push(format!(
            "{label}: A[D] {a:.3} d, A[D_rel] {r:.3} d, ratio {ratio:.3}, periods {} / {} tau_c ({} tracers)",
            period(&o.depth),
            period(&o.relative),
            o.tracers
        ));
        // NaN amplitudes are neither tested nor holding.
        let tested = a >= min_amplitude;
        if !tested {
            untested.push(format!("{label} (A[D] {a:.3} d)"));
            continue;
        }
        worst = worst.max(ratio);
        let holds = r <= max_ratio * a;
        if !holds {
            failed.push(label.to_string());
        }
    }
    if rows.is_empty() {
        return Check::error_in(name, Gate::Claim, "no variants");
    }
    let rule = format!(
        "registered max_ratio {max_ratio}, min_amplitude {min_amplitude} d; over the final {:.0} tau_c",
        case.final_window / case.scales.tau_c
    );
    let detail = format!("{rule}; {}", rows.join("; "));
    if !failed.is_empty() {
        return Check::with_status(
            name,
            Gate::Claim,
            metric,
            worst,
            max_ratio,
            Status::Fail,
            format!(
                "the oscillation stays visible below the interface in {}; {detail}",
                failed.join(", ")
            ),
        );
    }
    if !untested.is_empty() {
        return Check::not_compared(
            name,
            Gate::Claim,
            format!(
                "D does not oscillate by min_amplitude in {}: those data cannot test the statement (the claim's premise); {detail}",
                untested.join(", ")
            ),
        );
    }
    Check::with_status(
        name,
        Gate::Claim,
        metric,
        worst,
        max_ratio,
        Status::Pass,
        detail,
    )
}

/// Native vs reference s(t) of one variant: RMS of the difference over every sample
/// of the run, at most `[compare] interface_rms` (d).
pub fn cross_check(
    case: &Impact2dCase,
    label: &str,
    a: Option<&InterfaceObs>,
    b: Option<&InterfaceObs>,
    reference: &str,
) -> Check {
    let name = format!(
        "{} [{label}]: interface s(t) native vs {reference}",
        case.name
    );
    let (Some(a), Some(b)) = (a, b) else {
        return Check::error_in(
            name,
            Gate::InterfaceSeries,
            "a run has no interface observables",
        );
    };
    match crate::analysis::impact::rms_distance(&a.shift, &b.shift) {
        Ok(rms) => {
            let last = |o: &InterfaceObs| o.shift.last().map_or(f64::NAN, |p| p.1);
            let span = |o: &InterfaceObs| {
                o.shift
                    .iter()
                    .map(|p| p.1)
                    .fold(f64::NEG_INFINITY, f64::max)
                    - o.shift.iter().map(|p| p.1).fold(f64::INFINITY, f64::min)
            };
            Check::at_most(
                name,
                Gate::InterfaceSeries,
                "RMS(s_native - s_ref) / d over the run",
                rms,
                case.tolerances.interface_rms,
                format!(
                    "s at the end {:.3} vs {:.3} d, range over the run {:.3} vs {:.3} d; A[D_rel] {:.3} vs {:.3} d; tracers {} / {}",
                    last(a),
                    last(b),
                    span(a),
                    span(b),
                    a.relative.amplitude,
                    b.relative.amplitude,
                    a.tracers,
                    b.tracers
                ),
            )
        }
        Err(e) => Check::error_in(name, Gate::InterfaceSeries, format!("{e:#}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::interface::oscillation;
    use std::path::Path;

    fn case() -> Impact2dCase {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/cases/impact2d/ci.toml"
        ))
        .unwrap();
        Impact2dCase::from_toml_str(
            &format!(
                "{text}\n[sweep]\nparameter = \"speed\"\nvalues = [0.7, 1.0]\n[claim]\nkind = \"interface_steadies\"\nmax_ratio = 0.5\nmin_amplitude = 0.05\n"
            ),
            Path::new("t.toml"),
        )
        .unwrap()
    }

    /// Observables of a bed oscillating by `bed` (d, peak) with the intruder riding
    /// along, plus an oscillation `own` of the intruder relative to the bed; 1000 tau_c
    /// sampled every 2 tau_c, period 40 tau_c.
    fn obs(bed: f64, own: f64, frozen_floor: bool) -> InterfaceObs {
        let w = 2.0 * std::f64::consts::PI / 40.0;
        let t: Vec<f64> = (0..=500).map(|k| k as f64 * 2.0).collect();
        let s: Vec<(f64, f64)> = t
            .iter()
            .map(|&t| {
                (
                    t,
                    if frozen_floor {
                        0.0
                    } else {
                        bed * (w * t).sin()
                    },
                )
            })
            .collect();
        let depth: Vec<(f64, f64)> = t
            .iter()
            .map(|&t| (t, 8.0 - bed * (w * t).sin() + own * (3.0 * w * t).cos()))
            .collect();
        let rel = crate::analysis::interface::relative_depth(&depth, &s).unwrap();
        InterfaceObs {
            tracers: 40,
            depth: oscillation(&depth, 200.0).unwrap(),
            relative: oscillation(&rel, 200.0).unwrap(),
            shift: s,
            relative_series: rel,
        }
    }

    fn verdict(v: &[InterfaceObs]) -> Check {
        let labels = ["speed=0.7", "speed=1"];
        let pairs: Vec<(&str, Option<&InterfaceObs>)> =
            labels.iter().copied().zip(v.iter().map(Some)).collect();
        steadies(&case(), 0.5, 0.05, "x", &pairs)
    }

    /// K Fig 12 on synthetic runs: global oscillations that vanish below the interface
    /// pass; an intruder oscillating within the bed fails; a bed that does not
    /// oscillate cannot test the claim (NOT COMPARED), unless another variant fails.
    #[test]
    fn interface_steadies_passes_fails_and_needs_an_oscillation() {
        let k = verdict(&[obs(0.4, 0.0, false), obs(0.3, 0.02, false)]);
        assert_eq!(k.status, Status::Pass, "{k:?}");
        assert!(k.value < 0.1 && k.detail.contains("ratio"), "{k:?}");
        // The intruder oscillates relative to the bed by as much as the bed moves.
        let k = verdict(&[obs(0.4, 0.0, false), obs(0.3, 0.3, false)]);
        assert_eq!(k.status, Status::Fail, "{k:?}");
        assert!(k.detail.contains("speed=1"), "{k:?}");
        // No oscillation in D in one variant: the premise fails there.
        let k = verdict(&[obs(0.4, 0.0, false), obs(0.01, 0.0, false)]);
        assert_eq!(k.status, Status::NotCompared, "{k:?}");
        assert!(k.detail.contains("speed=1 (A[D] 0.0"), "{k:?}");
        let k = verdict(&[obs(0.4, 0.4, false), obs(0.01, 0.0, false)]);
        assert_eq!(k.status, Status::Fail, "a tested failure decides: {k:?}");
        // A variant without observables is an error.
        let a = obs(0.4, 0.0, false);
        let k = steadies(&case(), 0.5, 0.05, "x", &[("a", Some(&a)), ("b", None)]);
        assert!(k.is_error(), "{k:?}");
    }

    /// The negative control: the interface taken as the frozen floor (s = 0) leaves
    /// D_rel = D, ratio 1, and the claim fails; against a moving reference interface the
    /// s(t) cross-check fails too, while equal series pass it.
    #[test]
    fn the_frozen_floor_fails_the_claim_and_the_cross_check() {
        let k = verdict(&[obs(0.4, 0.0, true), obs(0.3, 0.0, true)]);
        assert_eq!(k.status, Status::Fail, "{k:?}");
        assert!((k.value - 1.0).abs() < 1e-12, "{k:?}");
        let c = case();
        let (real, floor) = (obs(0.4, 0.0, false), obs(0.4, 0.0, true));
        let x = cross_check(&c, "v", Some(&real), Some(&real), "lammps");
        assert!(x.passed && x.value == 0.0, "{x:?}");
        let x = cross_check(&c, "v", Some(&floor), Some(&real), "lammps");
        assert_eq!(x.status, Status::Fail, "{x:?}");
        assert!((x.value - 0.4 / 2f64.sqrt()).abs() < 0.01, "{x:?}");
        assert!(cross_check(&c, "v", None, Some(&real), "lammps").is_error());
    }
}
