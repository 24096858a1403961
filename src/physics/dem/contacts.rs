//! Enumeration of the contacts, for contact snapshots (stress fields, Feng et al. eqs 6-9).
//!
//! Two readings of "the contact force at step n" exist, and they differ for sliding
//! contacts:
//! - [`Simulation::contacts`]: the forces of the last force pass, exactly what moved the
//!   grains (velocities at the half step, history advanced, Coulomb cap applied).
//! - [`Simulation::contacts_as_dumped`]: what LIGGGHTS' `compute pair/gran/local` and
//!   `compute wall/gran/local` report at a dump. They loop over the neighbour list at the
//!   end of the step and evaluate the contact law again, with the end-of-step velocities
//!   and without advancing the shear history (doc: "if the current pairwise distance is
//!   less than the force cutoff"). For a sliding contact the stored shear sits exactly
//!   at the old cap mu |F_n|; if the re-evaluated |F_n| is larger, the contact falls into
//!   the sticking branch of tangential_model_history.h and gets the tangential damping
//!   `gamma_t v_t` of its full sliding velocity on top, so |F_t| exceeds mu |F_n|.
//!   Measured on the CI case: 29 % of LIGGGHTS' grain-intruder contacts (about half of
//!   the 60 % that slide) and 12 % of the grain-grain contacts below the intruder are
//!   above the cap, against 0.1 % in the native last-pass forces. The snapshots compare
//!   the engines, so the native engine reports contacts the LIGGGHTS way.
//!
//! Contact points follow LIGGGHTS 3.8 (checked against `compute pair/gran/local` and
//! `compute wall/gran/local ... contactPoint` in tests/stress_fields.rs):
//! - grain-grain: `x_i + (x_j - x_i) r_i / (r_i + r_j)`, the centre line divided in the
//!   ratio of the radii (measured; for unequal radii this is not the `r_i - delta_n / 2`
//!   lever arm the contact law uses for the tangential torque);
//! - grain-wall / grain-intruder: `x_i - delta`, the closest point of the wall surface
//!   (fix_wall_gran_base.h: `vectorSubtract3D(x, sidata.delta, contactPoint)`).

use super::Simulation;
use crate::numerics::vec3::*;
use crate::rundata::snapshot::{Contact, ContactKind, Grain, Snapshot, SnapshotMeta};

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
    /// The contacts as LIGGGHTS dumps them (module doc): the contact law evaluated again
    /// on a copy of the current state, history not advanced. The simulation itself is
    /// untouched, so the run continues bit for bit as without the snapshot.
    pub fn contacts_as_dumped(&self) -> Vec<ContactRecord> {
        let mut copy = self.clone();
        copy.compute_forces(false, false);
        copy.contacts()
    }

    /// Every contact that carried a force in the last force evaluation (`setup` or
    /// `step`), grain-grain pairs once each (i < j in neighbour-list order), then walls
    /// and the intruder in particle order. Deterministic for a given state.
    ///
    /// "Particle order" and "i < j" are case order (`i`, `j` stay storage indices): after
    /// a spatial sort ([`Simulation::set_reorder`]) the records are put back into the
    /// order, and each pair into the orientation, an unsorted run lists them in.
    pub fn contacts(&self) -> Vec<ContactRecord> {
        let mut out = Vec::new();
        let case = &self.case_index;
        let reordered = self.reordered();
        for k in 0..self.pairs.len().min(self.pair_touch.len()) {
            if !self.pair_touch[k] {
                continue;
            }
            let (mut i, mut j) = (self.pairs.i[k] as usize, self.pairs.j[k] as usize);
            let mut force_on_i = self.rev_out[self.pairs.rev_pos[k] as usize].f_i;
            if case[i] > case[j] {
                (i, j) = (j, i);
                force_on_i = scale(force_on_i, -1.0);
            }
            let frac = self.radius[i] / (self.radius[i] + self.radius[j]);
            out.push(ContactRecord {
                i,
                other: Touching::Grain(j),
                point: add(self.x[i], scale(sub(self.x[j], self.x[i]), frac)),
                force_on_i,
            });
        }
        if reordered {
            out.sort_by_key(|c| match c.other {
                Touching::Grain(j) => (case[c.i], case[j]),
                _ => unreachable!("only pairs so far"),
            });
        }
        let n_pairs = out.len();
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
        if reordered {
            // Stable: a grain's walls stay in wall order, and the intruder after them.
            out[n_pairs..].sort_by_key(|c| (matches!(c.other, Touching::Intruder), case[c.i]));
        }
        out
    }
}

impl Simulation {
    /// Builds a native snapshot with the contacts as LIGGGHTS would dump them at this
    /// step ([`crate::physics::dem::Simulation::contacts_as_dumped`]), so both engines' stress
    /// fields are measured the same way.
    pub fn snapshot(&self, meta: SnapshotMeta) -> Snapshot {
        let sim = self;
        let grains = sim
            .case_order()
            .into_iter()
            .map(|k| Grain {
                id: sim.id[k],
                x: sim.x[k],
                v: sim.v[k],
                radius: sim.radius[k],
            })
            .collect();
        let contacts = sim
            .contacts_as_dumped()
            .into_iter()
            .map(|c| {
                let xi = sim.x[c.i];
                let (kind, j, branch) = match c.other {
                    Touching::Grain(j) => (ContactKind::Pair, sim.id[j], sub(sim.x[j], xi)),
                    Touching::Wall(_) => (ContactKind::Wall, 0, sub(c.point, xi)),
                    Touching::Intruder => (ContactKind::Intruder, 0, sub(c.point, xi)),
                };
                Contact {
                    kind,
                    i: sim.id[c.i],
                    j,
                    xi,
                    point: c.point,
                    branch,
                    force: c.force_on_i,
                }
            })
            .collect();
        Snapshot {
            meta,
            grains,
            contacts,
        }
    }
}

#[cfg(test)]
#[allow(clippy::items_after_test_module)] // the snapshot writer below came later
mod tests {
    use super::*;
    use crate::case::Case;
    use std::path::Path;

    /// `(|F_t|, F_n)` of a contact, with the normal from the contact point to the grain.
    fn split(sim: &Simulation, c: &ContactRecord) -> (f64, f64) {
        let d = sub(sim.x[c.i], c.point);
        let n = scale(d, 1.0 / norm(d));
        let fnorm = dot(c.force_on_i, n);
        (norm(sub(c.force_on_i, scale(n, fnorm))), fnorm)
    }

    /// A sphere dropped sliding (no spin) onto a plane under gravity, mu = 0.5: while it
    /// slides, the last-pass force sits on the Coulomb cap, and the dumped one exceeds it
    /// in the steps where the end-of-step normal force is larger than the integrated one
    /// (the module doc's LIGGGHTS effect). Taking the dumped contacts every step must not
    /// change the trajectory by a single bit.
    #[test]
    fn dumped_contacts_exceed_the_cap_while_sliding_and_leave_the_run_untouched() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut case = Case::load(&root.join("cases/micro/rolling-cdt.toml")).unwrap();
        let p = &mut case.particles[0];
        p.omega = [0.0; 3];
        p.x[2] = 1.0e-3 - 1.04e-7; // resting overlap m g = 4/3 E* sqrt(R) delta^1.5
        let mu = 0.5;
        let steps = 1000; // sliding lasts 2 v0 / (7 mu g) = 5.8 ms = 1166 steps
        let run = |dump: bool| {
            let mut sim = Simulation::from_case(&case);
            sim.setup().unwrap();
            let (mut last_over, mut dumped_over, mut touching) = (0, 0, 0);
            for _ in 0..steps {
                sim.step().unwrap();
                if !dump {
                    continue;
                }
                let (last, dumped) = (sim.contacts(), sim.contacts_as_dumped());
                assert_eq!(last.len(), dumped.len());
                if let (Some(l), Some(d)) = (last.first(), dumped.first()) {
                    assert_eq!(l.point, d.point, "same geometry, same contact point");
                    touching += 1;
                    let (lt, ln) = split(&sim, l);
                    let (dt, dn) = split(&sim, d);
                    last_over += (lt > mu * ln * (1.0 + 1e-9)) as usize;
                    dumped_over += (dt > mu * dn * (1.0 + 1e-9)) as usize;
                }
            }
            (
                sim.x.clone(),
                sim.v.clone(),
                sim.omega.clone(),
                touching,
                last_over,
                dumped_over,
            )
        };
        let plain = run(false);
        let dumped = run(true);
        assert_eq!(
            (&plain.0, &plain.1, &plain.2),
            (&dumped.0, &dumped.1, &dumped.2)
        );
        let (touching, last_over, dumped_over) = (dumped.3, dumped.4, dumped.5);
        eprintln!(
            "{touching} touching steps: above the cap {last_over} (last pass), {dumped_over} (dumped)"
        );
        assert!(touching > steps / 2, "the sphere must rest on the plane");
        assert_eq!(last_over, 0, "the integrated force obeys Coulomb");
        assert!(
            dumped_over > touching / 4,
            "the dumped force must show the LIGGGHTS effect"
        );
    }
}
