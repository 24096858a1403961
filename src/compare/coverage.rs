//! Coverage before verdict: a comparison must show that it compared the dynamics, or
//! its gates are NOT COMPARED (and the run exits 2). Two engines that agree on a run in
//! which nothing happened have shown nothing.
//!
//! Rules (fixed here, each with a test that fails without it):
//! - micro: at least [`MIN_FRAMES_AFTER_START`] output frames after step 0, and either a
//!   frame with a contact force (some |f_i - m_i g| above [`CONTACT_FORCE_FRAC`] of the
//!   case's force scale m max(|g|, V^2 / r_min)) or, for a contact-free case, measurable
//!   motion (some grain displaced by at least [`MIN_MOTION_FRAC`] of r_min); and, when
//!   the case expects a contact (`[compare] expect = ["contact"]`, the default for two
//!   bodies approaching each other at t = 0), a frame with a contact force in each run,
//!   the native one and the reference: free flight of a collision case that misses
//!   moves the grains but compares no contact law;
//! - fitted ranges (penetration, impact): at least [`MIN_FIT_POINTS`] points in every
//!   fitted range ([`fit_points`]).

use super::{Check, Gate};
use crate::case::{Case, Observation};
use crate::numerics::vec3::{norm, scale, sub};
use crate::rundata::frames::Frame;

pub(crate) const MIN_FRAMES_AFTER_START: usize = 10;
pub(crate) const CONTACT_FORCE_FRAC: f64 = 1e-6;
pub(crate) const MIN_MOTION_FRAC: f64 = 0.01;
pub(crate) const MIN_FIT_POINTS: usize = 10;

/// (id, position, velocity, force) of a sphere or a body.
type State = (u64, [f64; 3], [f64; 3], [f64; 3]);

/// What the reference frames of a micro case covered.
pub(crate) struct MicroCoverage<'a> {
    case: &'a Case,
    frames: usize,
    contact_frames: usize,
    first_x: Vec<[f64; 3]>,
    max_displacement: f64,
    max_speed: f64,
    max_residual: f64,
    mass_by_id: std::collections::HashMap<u64, f64>,
}

impl<'a> MicroCoverage<'a> {
    pub fn new(case: &'a Case) -> MicroCoverage<'a> {
        MicroCoverage {
            case,
            frames: 0,
            contact_frames: 0,
            first_x: Vec::new(),
            max_displacement: 0.0,
            max_speed: 0.0,
            max_residual: 0.0,
            mass_by_id: case.mass_by_id(),
        }
    }

    /// Adds one reference frame (particles sorted by id, as every reader returns them).
    /// NaN residuals (an unknown id) never count as contact.
    pub fn push(&mut self, f: &Frame) {
        // Free spheres and clump bodies alike (bodies: the total force incl. gravity,
        // the body mass, the centre of mass).
        let states: Vec<State> = f
            .particles
            .iter()
            .map(|p| (p.id, p.x, p.v, p.f))
            .chain(f.bodies.iter().map(|b| (b.id, b.x, b.v, b.f)))
            .collect();
        if self.frames == 0 {
            self.first_x = states.iter().map(|p| p.1).collect();
        }
        self.frames += 1;
        let mut residual: f64 = 0.0;
        for (k, &(id, x, v, force)) in states.iter().enumerate() {
            let m = self.mass_by_id.get(&id).copied().unwrap_or(f64::NAN);
            // Contact acceleration: the force beyond gravity, per unit mass.
            residual = residual.max(norm(sub(force, scale(self.case.gravity, m))) / m);
            self.max_speed = self.max_speed.max(norm(v));
            if let Some(x0) = self.first_x.get(k) {
                self.max_displacement = self.max_displacement.max(norm(sub(x, *x0)));
            }
        }
        self.max_residual = self.max_residual.max(residual);
        self.contact_frames += usize::from(self.residual_is_contact(residual));
    }

    /// Acceleration scale of the case: max(|g|, V^2 / r_min), V the largest speed seen.
    fn accel_scale(&self) -> f64 {
        norm(self.case.gravity).max(self.max_speed * self.max_speed / self.case.min_radius())
    }

    fn residual_is_contact(&self, residual: f64) -> bool {
        let a = self.accel_scale();
        a > 0.0 && residual > CONTACT_FORCE_FRAC * a
    }

    /// The coverage check of a comparison: `self` fed the reference frames, `native` the
    /// native run's (for the contact a case expects, which both runs must show).
    pub fn check(&self, name: &str, native: &MicroCoverage) -> Check {
        let after_start = self.frames.saturating_sub(1);
        let r_min = self.case.min_radius();
        let moved = self.max_displacement >= MIN_MOTION_FRAC * r_min;
        let detail = format!(
            "{after_start} frames after step 0 (need >= {MIN_FRAMES_AFTER_START}); {} with a contact force; largest displacement {:.3e} r_min (need a contact or >= {MIN_MOTION_FRAC})",
            self.contact_frames,
            self.max_displacement / r_min
        );
        if self.case.expect.contains(&Observation::Contact) {
            let missing: Vec<&str> = [("the native run", native), ("the reference run", self)]
                .into_iter()
                .filter(|(_, c)| c.frames > 0 && c.contact_frames == 0)
                .map(|(what, _)| what)
                .collect();
            if !missing.is_empty() {
                let grains = if self.case.clumps.is_empty() {
                    "spheres"
                } else {
                    "bodies"
                };
                return Check::not_compared(
                    name,
                    Gate::Coverage,
                    format!(
                        "the {grains} never touch: the case expects a contact ([compare] expect; by default for two bodies approaching at t = 0), and no output frame of {} carries a contact force; {detail}",
                        missing.join(" or ")
                    ),
                );
            }
        }
        let ok = after_start >= MIN_FRAMES_AFTER_START && (self.contact_frames > 0 || moved);
        if ok {
            Check::at_least(
                name,
                Gate::Coverage,
                "output frames after step 0",
                after_start as f64,
                MIN_FRAMES_AFTER_START as f64,
                detail,
            )
        } else {
            Check::not_compared(name, Gate::Coverage, detail)
        }
    }
}

/// Coverage of one fitted range: `n` points where at least [`MIN_FIT_POINTS`] are needed.
pub(crate) fn fit_points(name: &str, what: &str, n: usize) -> Option<Check> {
    (n < MIN_FIT_POINTS).then(|| {
        Check::not_compared(
            name,
            Gate::Coverage,
            format!(
                "{what}: {n} points, fewer than the {MIN_FIT_POINTS} a fit needs to mean anything"
            ),
        )
    })
}
