//! Micro comparison: two trajectories of the same few grains must agree at every output
//! step (the deterministic kind of comparison: a contact-law bug shows at once).
//!
//! Metrics (worst over all output steps and particles):
//! - positions: |x_a - x_b| / r_min, with r_min the smallest radius in the case;
//! - velocities: |v_a - v_b| / V, with V the largest speed of the reference run;
//! - angular velocities: |w_a - w_b| / W, with W the largest |w| of the reference run,
//!   or V / r_min if the reference never rotates (so spurious spin still counts).
//!
//! Vector norms rather than components keep the metric frame-independent and avoid
//! dividing by a component that happens to cross zero. The frames are fed one pair at
//! a time ([`Trajectory::push`]): V and W are only known at the end, and since dividing
//! by a positive constant preserves order, max(|dv|) / V is the worst |dv| / V exactly.

use super::coverage::MicroCoverage;
use super::{Check, Gate};
use crate::case::Case;
use crate::numerics::quat::rotation_angle;
use crate::numerics::vec3::{norm, sub};
use crate::rundata::frames::Frame;

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
        if self.value == 0.0 {
            "identical at every output step".into()
        } else {
            format!("worst at step {} particle {}", self.step, self.id)
        }
    }
}

/// The comparison of one micro case, fed frame pair by frame pair.
pub(crate) struct Trajectory<'a> {
    case: &'a Case,
    dx: Worst,
    dv: Worst,
    dw: Worst,
    /// Clump cases: rotation angle between body orientations (rad).
    dq: Worst,
    vmax_ref: f64,
    wmax_ref: f64,
    frames: usize,
    coverage: MicroCoverage<'a>,
    /// The native run's frames, for the contact a case expects.
    native_coverage: MicroCoverage<'a>,
    mismatch: Option<String>,
}

impl<'a> Trajectory<'a> {
    pub fn new(case: &'a Case) -> Trajectory<'a> {
        Trajectory {
            case,
            dx: Worst::default(),
            dv: Worst::default(),
            dw: Worst::default(),
            dq: Worst::default(),
            vmax_ref: 0.0,
            wmax_ref: 0.0,
            frames: 0,
            coverage: MicroCoverage::new(case),
            native_coverage: MicroCoverage::new(case),
            mismatch: None,
        }
    }

    /// Adds the frames of one output step; a structural mismatch (different steps,
    /// particle sets) stops the comparison and becomes an error check.
    pub fn push(&mut self, a: &Frame, b: &Frame) {
        if self.mismatch.is_some() {
            return;
        }
        if a.step != b.step
            || a.particles.len() != b.particles.len()
            || a.bodies.len() != b.bodies.len()
        {
            self.mismatch = Some(format!(
                "frame mismatch: step {} ({} particles) vs step {} ({} particles)",
                a.step,
                a.particles.len(),
                b.step,
                b.particles.len()
            ));
            return;
        }
        let r_min = self.case.min_radius();
        for (p, q) in a.particles.iter().zip(&b.particles) {
            if p.id != q.id {
                self.mismatch = Some(format!(
                    "particle ids differ at step {}: {} vs {}",
                    a.step, p.id, q.id
                ));
                return;
            }
            self.dx.update(norm(sub(p.x, q.x)) / r_min, a.step, p.id);
            self.dv.update(norm(sub(p.v, q.v)), a.step, p.id);
            self.dw.update(norm(sub(p.omega, q.omega)), a.step, p.id);
            self.vmax_ref = self.vmax_ref.max(norm(q.v));
            self.wmax_ref = self.wmax_ref.max(norm(q.omega));
        }
        // Clumps: the same metrics on the body state, plus the orientation angle.
        for (p, q) in a.bodies.iter().zip(&b.bodies) {
            if p.id != q.id {
                self.mismatch = Some(format!(
                    "clump ids differ at step {}: {} vs {}",
                    a.step, p.id, q.id
                ));
                return;
            }
            self.dx.update(norm(sub(p.x, q.x)) / r_min, a.step, p.id);
            self.dv.update(norm(sub(p.v, q.v)), a.step, p.id);
            self.dw.update(norm(sub(p.omega, q.omega)), a.step, p.id);
            self.dq.update(rotation_angle(p.q, q.q), a.step, p.id);
            self.vmax_ref = self.vmax_ref.max(norm(q.v));
            self.wmax_ref = self.wmax_ref.max(norm(q.omega));
        }
        self.coverage.push(b);
        self.native_coverage.push(a);
        self.frames += 1;
    }

    /// A run ended with a different number of frames than the other.
    pub(crate) fn length_mismatch(&mut self, test: usize, reference: usize) {
        if self.mismatch.is_none() {
            self.mismatch = Some(format!(
                "{test} output frames vs {reference} in the reference"
            ));
        }
    }

    /// The scales the gates divide by: (smallest radius, largest reference speed V,
    /// largest reference angular speed, or V / r_min if the reference never rotates);
    /// `None` while the reference has not moved.
    pub fn scales(&self) -> Option<(f64, f64, f64)> {
        let r_min = self.case.min_radius();
        let v = self.vmax_ref;
        (v > 0.0).then(|| {
            let w = if self.wmax_ref > 0.0 {
                self.wmax_ref
            } else {
                v / r_min
            };
            (r_min, v, w)
        })
    }

    /// The checks of the case: coverage first, then position, velocity and angular
    /// velocity. Without coverage the trajectory gates are NOT COMPARED.
    pub fn finish(self) -> Vec<Check> {
        let name = |what: &str| format!("{}: {what}", self.case.name);
        if let Some(m) = self.mismatch {
            return vec![Check::error(name("frames"), m)];
        }
        let coverage = self
            .coverage
            .check(&name("coverage"), &self.native_coverage);
        let gates = [
            (Gate::Position, "position", "max |dx| / r_min"),
            (Gate::Velocity, "velocity", "max |dv| / max|v_ref|"),
            (
                Gate::AngularVelocity,
                "angular velocity",
                "max |dw| / max|w_ref|",
            ),
        ];
        if !coverage.passed {
            let mut out = vec![coverage];
            out.extend(gates.iter().map(|(g, n, _)| {
                Check::not_compared(
                    name(n),
                    *g,
                    "the comparison did not cover enough dynamics (see the coverage check)",
                )
            }));
            return out;
        }
        let Some((_, vscale, wscale)) = self.scales() else {
            return vec![Check::error(
                name("frames"),
                "reference run never moves: nothing to compare",
            )];
        };
        let tol = &self.case.tolerances;
        let orientation = (!self.case.clumps.is_empty()).then(|| {
            Check::at_most(
                name("orientation"),
                Gate::Orientation,
                "max rotation angle between body orientations (rad)",
                self.dq.value,
                tol.orientation_rad,
                self.dq.detail(),
            )
        });
        let mut checks = vec![
            coverage,
            Check::at_most(
                name("position"),
                Gate::Position,
                gates[0].2,
                self.dx.value,
                tol.position_frac_radius,
                self.dx.detail(),
            ),
            Check::at_most(
                name("velocity"),
                Gate::Velocity,
                gates[1].2,
                self.dv.value / vscale,
                tol.velocity_rel,
                self.dv.detail(),
            ),
            Check::at_most(
                name("angular velocity"),
                Gate::AngularVelocity,
                gates[2].2,
                self.dw.value / wscale,
                tol.velocity_rel,
                self.dw.detail(),
            ),
        ];
        checks.extend(orientation);
        checks
    }
}
