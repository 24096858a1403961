//! Enumeration of the contacts of the last force pass, for contact snapshots (stress
//! fields, issue 4). The forces are the ones stored while integrating — never a
//! re-evaluation of the contact law — so a snapshot is exactly what moved the grains.
//!
//! Contact points follow LIGGGHTS 3.8 (checked against `compute pair/gran/local` and
//! `compute wall/gran/local ... contactPoint` in tests/stress_fields.rs):
//! - grain-grain: `x_i + (x_j - x_i) r_i / (r_i + r_j)`, the centre line divided in the
//!   ratio of the radii (measured; for unequal radii this is not the `r_i - delta_n / 2`
//!   lever arm the contact law uses for the tangential torque);
//! - grain-wall / grain-intruder: `x_i - delta`, the closest point of the wall surface
//!   (fix_wall_gran_base.h: `vectorSubtract3D(x, sidata.delta, contactPoint)`).

use super::Simulation;
use super::vec3::*;

/// What a grain touches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Touching {
    /// Another grain (index into the simulation arrays).
    Grain(usize),
    /// Primitive wall number k of the case (floor, container side...).
    Wall(usize),
    /// The moving intruder.
    Intruder,
}

/// One touching contact of grain `i` (array index), with the force it exerts on `i`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactRecord {
    pub i: usize,
    pub other: Touching,
    pub point: V3,
    /// Force on grain i (on j it is the negative; on a wall/intruder the reaction).
    pub force_on_i: V3,
}

impl Simulation {
    /// Every contact that carried a force in the last force evaluation (`setup` or
    /// `step`), grain-grain pairs once each (i < j in neighbour-list order), then walls
    /// and the intruder in particle order. Deterministic for a given state.
    pub fn contacts(&self) -> Vec<ContactRecord> {
        let mut out = Vec::new();
        for k in 0..self.pairs.len().min(self.pair_touch.len()) {
            if !self.pair_touch[k] {
                continue;
            }
            let (i, j) = (self.pairs.i[k] as usize, self.pairs.j[k] as usize);
            let frac = self.radius[i] / (self.radius[i] + self.radius[j]);
            out.push(ContactRecord {
                i,
                other: Touching::Grain(j),
                point: add(self.x[i], scale(sub(self.x[j], self.x[i]), frac)),
                force_on_i: self.pair_out[k].f_i,
            });
        }
        let stride = self.walls_stride;
        for i in 0..self.x.len() {
            for k in 0..self.walls.len() {
                let f = self.wall_out[i * stride + k];
                if f == [0.0; 3] {
                    continue;
                }
                if let Some((delta, _)) =
                    super::walls::wall_contact(&self.walls[k], self.x[i], self.radius[i])
                {
                    out.push(ContactRecord {
                        i,
                        other: Touching::Wall(k),
                        point: sub(self.x[i], delta),
                        force_on_i: f,
                    });
                }
            }
        }
        if let Some(it) = &self.intruder {
            for (i, f) in it.on_grain.iter().enumerate() {
                if *f == [0.0; 3] {
                    continue;
                }
                if let Some((delta, _)) = it.body.closest_contact(self.x[i], self.radius[i]) {
                    out.push(ContactRecord {
                        i,
                        other: Touching::Intruder,
                        point: sub(self.x[i], delta),
                        force_on_i: *f,
                    });
                }
            }
        }
        out
    }
}
