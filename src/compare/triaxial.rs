//! The registered native vs reference gate of docs/stress.md rule 5: the absolute
//! difference of the engines' mean phi_cs over the units, with the standard error of the paired
//! differences (sd / sqrt(n): sd / 2 for four units), decided as amendment A decides
//! ([`Check::at_most_resolved`]): NOT COMPARED when 2 SE > tolerance and the difference
//! is not beyond the tolerance by 2 SE; one unit has no SE and is NOT COMPARED.

use super::{Check, Gate};
use crate::analysis::triaxial::sample_sd;

/// The gate from the paired per-unit phi_cs (degrees), in unit order.
pub fn phi_cs_gate(name: &str, native: &[f64], reference: &[f64], tolerance_deg: f64) -> Check {
    let label = format!("{name}: phi_cs native vs liggghts");
    if native.len() != reference.len() || native.is_empty() {
        return Check::error_in(
            label,
            Gate::Phi,
            format!(
                "{} native and {} reference unit(s): the gate pairs units",
                native.len(),
                reference.len()
            ),
        );
    }
    let n = native.len() as f64;
    let d: Vec<f64> = native.iter().zip(reference).map(|(a, b)| a - b).collect();
    let (mn, mr) = (
        native.iter().sum::<f64>() / n,
        reference.iter().sum::<f64>() / n,
    );
    let value = (mn - mr).abs();
    let se = if d.len() > 1 {
        sample_sd(&d) / n.sqrt()
    } else {
        f64::NAN
    };
    Check::at_most_resolved(
        label,
        Gate::Phi,
        "|mean phi_cs native - mean phi_cs liggghts| (deg)",
        value,
        se,
        tolerance_deg,
        format!(
            "mean phi_cs native {mn:.3} deg, liggghts {mr:.3} deg over {} unit(s); paired differences {:?} deg, SE {se:.3} deg",
            d.len(),
            d.iter().map(|x| format!("{x:+.3}")).collect::<Vec<_>>()
        ),
        format!(
            "not resolved: 2 SE = {:.3} deg > {tolerance_deg} deg and the difference is not beyond it by 2 SE",
            2.0 * se
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare::Status;

    #[test]
    fn the_gate_pairs_units_and_decides_as_amendment_a() {
        // Differences +0.3, +0.5, +0.1, +0.3: mean 0.3, sd 0.163, SE 0.082: a pass.
        let c = phi_cs_gate(
            "t",
            &[30.3, 31.5, 29.1, 30.3],
            &[30.0, 31.0, 29.0, 30.0],
            1.5,
        );
        assert_eq!(c.status, Status::Pass);
        assert!((c.value - 0.3).abs() < 1e-12);
        // Differences 3 +- 0.2: resolved failure.
        let c = phi_cs_gate("t", &[33.0, 33.2, 32.8, 33.0], &[30.0; 4], 1.5);
        assert_eq!(c.status, Status::Fail);
        // Scattered differences (-2, +4, -1, +3): mean 1, SE 1.47: not compared.
        let c = phi_cs_gate("t", &[28.0, 34.0, 29.0, 33.0], &[30.0; 4], 1.5);
        assert_eq!(c.status, Status::NotCompared);
        // Scattered but far beyond: 6 +- (SE 1.47): a resolved failure.
        let c = phi_cs_gate("t", &[33.0, 39.0, 34.0, 38.0], &[30.0; 4], 1.5);
        assert_eq!(c.status, Status::Fail);
        // One unit: no SE.
        let c = phi_cs_gate("t", &[30.0], &[30.1], 1.5);
        assert_eq!(c.status, Status::NotCompared);
        assert!(phi_cs_gate("t", &[30.0], &[], 1.5).is_error());
    }
}
