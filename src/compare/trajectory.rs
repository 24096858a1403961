//! Micro comparison: two trajectories of the same few grains must agree at every output
//! step (DESIGN.md "Same start, fair comparison").
//!
//! Metrics (worst over all output steps and particles):
//! - positions: |x_a - x_b| / r_min, with r_min the smallest radius in the case;
//! - velocities: |v_a - v_b| / V, with V the largest speed of the reference run;
//! - angular velocities: |w_a - w_b| / W, with W the largest |w| of the reference run,
//!   or V / r_min if the reference never rotates (so spurious spin still counts).
//!
//! Vector norms rather than components keep the metric frame-independent and avoid
//! dividing by a component that happens to cross zero.

use super::Check;
use crate::case::Case;
use crate::engines::Frame;
use crate::numerics::vec3::{norm, sub};

#[derive(Debug, Clone, Copy, Default)]
struct Worst {
    value: f64,
    step: u64,
    id: u64,
}

impl Worst {
    fn update(&mut self, value: f64, step: u64, id: u64) {
        if value > self.value || value.is_nan() {
            *self = Worst { value, step, id };
        }
    }
    fn detail(&self) -> String {
        format!("worst at step {} particle {}", self.step, self.id)
    }
}

/// Compares `test` against `reference`; returns the checks for this case.
pub fn compare(case: &Case, test: &[Frame], reference: &[Frame]) -> Vec<Check> {
    let name = |what: &str| format!("{}: {what}", case.name);
    if test.len() != reference.len() {
        return vec![Check::error(
            name("frames"),
            format!(
                "{} output frames vs {} in the reference",
                test.len(),
                reference.len()
            ),
        )];
    }
    let vscale = reference
        .iter()
        .flat_map(|f| f.particles.iter().map(|p| norm(p.v)))
        .fold(0.0, f64::max);
    let r_min = case.min_radius();
    let wmax = reference
        .iter()
        .flat_map(|f| f.particles.iter().map(|p| norm(p.omega)))
        .fold(0.0, f64::max);
    let wscale = if wmax > 0.0 { wmax } else { vscale / r_min };
    if vscale <= 0.0 {
        return vec![Check::error(
            name("frames"),
            "reference run never moves: nothing to compare",
        )];
    }
    let (mut wx, mut wv, mut ww) = (Worst::default(), Worst::default(), Worst::default());
    for (a, b) in test.iter().zip(reference) {
        if a.step != b.step || a.particles.len() != b.particles.len() {
            return vec![Check::error(
                name("frames"),
                format!(
                    "frame mismatch: step {} ({} particles) vs step {} ({} particles)",
                    a.step,
                    a.particles.len(),
                    b.step,
                    b.particles.len()
                ),
            )];
        }
        for (p, q) in a.particles.iter().zip(&b.particles) {
            if p.id != q.id {
                return vec![Check::error(
                    name("frames"),
                    format!(
                        "particle ids differ at step {}: {} vs {}",
                        a.step, p.id, q.id
                    ),
                )];
            }
            wx.update(norm(sub(p.x, q.x)) / r_min, a.step, p.id);
            wv.update(norm(sub(p.v, q.v)) / vscale, a.step, p.id);
            ww.update(norm(sub(p.omega, q.omega)) / wscale, a.step, p.id);
        }
    }
    let tol = &case.tolerances;
    vec![
        Check::at_most(
            name("position"),
            "max |dx| / r_min",
            wx.value,
            tol.position_frac_radius,
            wx.detail(),
        ),
        Check::at_most(
            name("velocity"),
            "max |dv| / max|v_ref|",
            wv.value,
            tol.velocity_rel,
            wv.detail(),
        ),
        Check::at_most(
            name("angular velocity"),
            "max |dw| / max|w_ref|",
            ww.value,
            tol.velocity_rel,
            ww.detail(),
        ),
    ]
}
