//! Penetration comparison (issue 3): two force-depth relations from the same bed,
//! reduced to K_phi, the FDR distance and the regime boundaries, each a gated check.

use super::Check;
use crate::analysis::fdr::{self, Fdr, FdrInput, LinearFit, RegimeBoundaries, Scales};
use crate::case::penetration::PenetrationCase;
use crate::engines::output::ForceSample;
use anyhow::Result;
use serde::Serialize;

/// What one engine's run reduces to.
#[derive(Debug, Clone, Serialize)]
pub struct Observables {
    pub fdr: Fdr,
    pub fit: LinearFit,
    pub boundaries: Option<RegimeBoundaries>,
    /// Why the boundaries could not be located, if they could not.
    pub boundaries_error: Option<String>,
}

/// Eq 5 with the bed's own psi and surface; only samples at or below the surface.
pub fn observables(
    case: &PenetrationCase,
    samples: &[ForceSample],
    surface_z: f64,
    psi: f64,
) -> Result<Observables> {
    let input = FdrInput {
        depth: samples.iter().map(|s| surface_z - s.z_bottom).collect(),
        // +z force on the intruder resists the downward push.
        force: samples.iter().map(|s| s.f[2]).collect(),
    };
    let scales = Scales {
        rho_g: case.density,
        psi,
        g: case.gravity,
        radius: case.intruder_radius,
    };
    let full = fdr::nondimensionalise(&input, &scales)?;
    let fdr = full.contact_only();
    let fit = fdr::steady_state_fit(&fdr, case.fit_h_min, f64::INFINITY)?;
    let (boundaries, boundaries_error) = match fdr::regime_boundaries(&fdr, &fit) {
        Ok(b) => (Some(b), None),
        Err(e) => (None, Some(format!("{e:#}"))),
    };
    Ok(Observables {
        fdr,
        fit,
        boundaries,
        boundaries_error,
    })
}

/// Checks of `test` against `reference`, tolerances from the case file.
pub fn compare(case: &PenetrationCase, test: &Observables, reference: &Observables) -> Vec<Check> {
    let tol = &case.tolerances;
    let name = |w: &str| format!("{}: {w}", case.name);
    let mut checks = vec![Check::at_most(
        name("K_phi"),
        "|K_test / K_ref - 1|",
        (test.fit.k_phi / reference.fit.k_phi - 1.0).abs(),
        tol.k_phi_rel,
        format!(
            "K_test = {:.3} +- {:.3} (R^2 {:.3}), K_ref = {:.3} +- {:.3} (R^2 {:.3}), fitted on h >= {}",
            test.fit.k_phi,
            test.fit.se_k,
            test.fit.r2,
            reference.fit.k_phi,
            reference.fit.se_k,
            reference.fit.r2,
            case.fit_h_min
        ),
    )];
    let h_hi = test
        .fdr
        .h
        .last()
        .copied()
        .unwrap_or(0.0)
        .min(reference.fdr.h.last().copied().unwrap_or(0.0));
    checks.push(
        match fdr::rms_distance_over_mean(&test.fdr, &reference.fdr, case.fit_h_min, h_hi, 200) {
            Ok(d) => Check::at_most(
                name("FDR distance"),
                "RMS(p_test - p_ref) / mean p, regime C",
                d,
                tol.fdr_distance,
                format!("h in [{}, {h_hi:.3}]", case.fit_h_min),
            ),
            Err(e) => Check::error(name("FDR distance"), format!("{e:#}")),
        },
    );
    match (&test.boundaries, &reference.boundaries) {
        (Some(a), Some(b)) => {
            checks.push(Check::at_most(
                name("h_A"),
                "|h_A,test - h_A,ref|",
                (a.h_a - b.h_a).abs(),
                tol.h_a_abs,
                format!("h_A: {:.3} vs {:.3} (unified fit, eqs 13-15)", a.h_a, b.h_a),
            ));
            checks.push(Check::at_most(
                name("h_B"),
                "|h_B,test - h_B,ref|",
                (a.h_b - b.h_b).abs(),
                tol.h_b_abs,
                format!("h_B: {:.3} vs {:.3}", a.h_b, b.h_b),
            ));
        }
        _ => checks.push(Check::error(
            name("regime boundaries"),
            format!(
                "could not locate h_A/h_B: test {:?}, reference {:?}",
                test.boundaries_error, reference.boundaries_error
            ),
        )),
    }
    checks
}
