//! The registered native vs reference gate of docs/stress.md rule 5, judged as
//! docs/statistics.md judges an agreement: an equivalence test (two one-sided tests) on
//! the paired per-unit differences of phi_cs, margin +-tolerance; one unit has no
//! unit-to-unit variance and is INCONCLUSIVE.

use super::{Check, Comparison, Gate, Rule};
use crate::numerics::stats::Estimate;

/// The gate from the paired per-unit phi_cs (degrees), in unit order.
pub(crate) fn phi_cs_gate(
    name: &str,
    native: &[f64],
    reference: &[f64],
    tolerance_deg: f64,
) -> Check {
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
    Check::decided(
        label,
        Gate::Phi,
        "phi_cs native - liggghts (deg), mean over units",
        &[Comparison {
            what: "paired phi_cs difference (deg)".into(),
            estimate: Estimate::mean(&d),
            rule: Rule::Equivalence {
                margin: tolerance_deg,
            },
            m: 1,
        }],
        format!(
            "mean phi_cs native {mn:.3} deg, liggghts {mr:.3} deg over {} unit(s); paired differences {:?} deg",
            d.len(),
            d.iter().map(|x| format!("{x:+.3}")).collect::<Vec<_>>()
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare::Status;

    #[test]
    fn the_gate_is_an_equivalence_test_on_paired_units() {
        // Differences +0.3, +0.5, +0.1, +0.3: mean 0.3, SE 0.082, 90 % interval
        // [0.11, 0.49] inside +-1.5: a pass.
        let c = phi_cs_gate(
            "t",
            &[30.3, 31.5, 29.1, 30.3],
            &[30.0, 31.0, 29.0, 30.0],
            1.5,
        );
        assert_eq!(c.status, Status::Pass);
        assert!((c.value - 0.3).abs() < 1e-12);
        // Differences 3 +- 0.2: the interval lies wholly above the margin.
        let c = phi_cs_gate("t", &[33.0, 33.2, 32.8, 33.0], &[30.0; 4], 1.5);
        assert_eq!(c.status, Status::Fail);
        // Scattered differences (-2, +4, -1, +3): mean 1, SE 1.47: inconclusive.
        let c = phi_cs_gate("t", &[28.0, 34.0, 29.0, 33.0], &[30.0; 4], 1.5);
        assert_eq!(c.status, Status::Inconclusive);
        assert!(c.detail.contains("beds would decide"), "{}", c.detail);
        // Scattered but far beyond: 6 +- (SE 1.47), interval [2.5, 9.5]: a failure.
        let c = phi_cs_gate("t", &[33.0, 39.0, 34.0, 38.0], &[30.0; 4], 1.5);
        assert_eq!(c.status, Status::Fail);
        // One unit: no unit-to-unit variance.
        let c = phi_cs_gate("t", &[30.0], &[30.1], 1.5);
        assert_eq!(c.status, Status::Inconclusive);
        assert!(phi_cs_gate("t", &[30.0], &[], 1.5).is_error());
    }
}
