//! Plane walls that move along their normal, the native counterpart of LIGGGHTS' moving
//! meshes (`fix move/mesh ... linear`, `mesh/surface/stress/servo`): a driver sets each
//! wall's velocity, [`Simulation::step`] advances the plane by `dt * v` before the force
//! pass (LIGGGHTS moves meshes in `initial_integrate`), the grains feel `v` in the
//! contact's relative velocity (damping and tangential spring), and
//! [`Simulation::wall_force`] returns what the grains pushed on a wall in the last force
//! pass, summed in particle order so it is the same for any thread count.

use super::Simulation;
use crate::case::Wall;
use crate::numerics::vec3::V3;

impl Simulation {
    /// Sets the velocity of plane wall `k` along its axis (m/s): it moves by `dt * v`
    /// at the start of each following step. Only plane walls move.
    pub(crate) fn set_wall_velocity(&mut self, k: usize, v: f64) -> anyhow::Result<()> {
        let Some(Wall::Plane { axis, .. }) = self.walls.get(k) else {
            anyhow::bail!("wall {k} is not a plane wall: only plane walls move");
        };
        let mut vel = [0.0; 3];
        vel[axis.index()] = v;
        self.wall_vel[k] = vel;
        self.walls_move = self.wall_vel.iter().any(|v| *v != [0.0; 3]);
        Ok(())
    }

    /// Velocity of wall `k` along its axis (0 for walls that do not move).
    #[cfg(test)]
    pub(crate) fn wall_velocity(&self, k: usize) -> f64 {
        match self.walls[k] {
            Wall::Plane { axis, .. } => self.wall_vel[k][axis.index()],
            Wall::Cylinder { .. } => 0.0,
        }
    }

    /// Position of plane wall `k` along its axis (NaN for other walls).
    pub(crate) fn wall_position(&self, k: usize) -> f64 {
        match self.walls[k] {
            Wall::Plane { position, .. } => position,
            Wall::Cylinder { .. } => f64::NAN,
        }
    }

    pub fn walls(&self) -> &[Wall] {
        &self.walls
    }

    /// Force the grains exerted on wall `k` in the last force pass (N, global frame): the
    /// negative of the wall forces on the grains, summed in particle order.
    pub(crate) fn wall_force(&self, k: usize) -> V3 {
        let stride = self.walls_stride;
        let mut f = [0.0; 3];
        for p in 0..self.x.len() {
            let o = self.wall_out[p * stride + k];
            f[0] -= o[0];
            f[1] -= o[1];
            f[2] -= o[2];
        }
        f
    }

    /// Advances every moving plane by `dt * v` (LIGGGHTS: `xcm += dtv * vcm` of the servo,
    /// `nodes += vel * dt` of `move/mesh linear`); true when one has moved more than
    /// skin/2 since the last neighbour build, which then must be rebuilt.
    pub(super) fn move_walls(&mut self) -> bool {
        let (dt, half_skin) = (self.dt, 0.5 * self.skin);
        let mut rebuild = false;
        for (k, w) in self.walls.iter_mut().enumerate() {
            if let Wall::Plane { axis, position, .. } = w {
                let v = self.wall_vel[k][axis.index()];
                if v != 0.0 {
                    *position += dt * v;
                }
                // NaN (never built) counts as moved.
                let d = (*position - self.wall_pos_at_build[k]).abs();
                rebuild |= d > half_skin || d.is_nan();
            }
        }
        rebuild
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::{Axis, Case, Material, PairTable, Particle, RollingModel, Tolerances};

    /// A grain overlapping the plane z = `plane` by 1 % of its radius, sliding along x.
    fn one_grain(plane: f64, grain_vz: f64) -> Case {
        let r = 1e-3;
        Case {
            name: "moving-wall".into(),
            kind: "micro".into(),
            description: String::new(),
            source: "<test>".into(),
            dt: 1e-6,
            n_steps: 0,
            output_every: 1,
            gravity: [0.0; 3],
            neighbor_skin: 0.5e-3,
            family: crate::case::ContactFamily::Liggghts,
            rolling: RollingModel::Cdt,
            domain_lo: [-0.01; 3],
            domain_hi: [0.01; 3],
            materials: vec![Material {
                youngs_modulus: 2.6e6,
                shear_modulus: 1e6,
                poisson_ratio: 0.3,
            }],
            pairs: PairTable {
                n_types: 1,
                restitution: vec![0.8],
                friction: vec![0.5],
                rolling_friction: vec![0.01],
            },
            particles: vec![Particle {
                id: 1,
                type_: 0,
                radius: r,
                density: 2500.0,
                x: [0.0, 0.0, plane + 0.99 * r],
                v: [0.3, 0.0, grain_vz],
                omega: [0.0, 50.0, 0.0],
            }],
            walls: vec![Wall::Plane {
                axis: Axis::Z,
                position: plane,
                type_: 0,
            }],
            tolerances: Tolerances {
                velocity_rel: 1e-6,
                position_frac_radius: 1e-6,
                orientation_rad: 1e-6,
            },
            clumps: Default::default(),
            rayleigh_time: 1.0,
            negative_controls: vec![],
            expect: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// The contact with a wall moving at u into a grain at rest is the contact with a
    /// wall at rest and a grain moving at -u (the law sees only the relative velocity):
    /// the same bits, and a damping force that a wall at rest against a grain at rest
    /// does not have.
    #[test]
    fn a_moving_plane_enters_the_contact_through_its_velocity() {
        let u = 0.05;
        let force = |wall_v: f64, grain_vz: f64| {
            let mut sim = Simulation::from_case(&one_grain(0.0, grain_vz));
            sim.set_wall_velocity(0, wall_v).unwrap();
            sim.setup_settled().unwrap();
            (sim.f[0], sim.torque[0], sim.wall_force(0))
        };
        let moving_wall = force(u, 0.0);
        let moving_grain = force(0.0, -u);
        let at_rest = force(0.0, 0.0);
        assert_eq!(moving_wall, moving_grain);
        // Damping: approaching raises the repulsion.
        assert!(
            moving_wall.0[2] > at_rest.0[2] * 1.01,
            "{moving_wall:?} vs {at_rest:?}"
        );
        // The force on the wall is the reaction on the grain, exactly.
        assert_eq!(moving_wall.2, moving_wall.0.map(|c| -c));
        // Tangential (sliding along x): present, and the same whatever moves.
        assert!(moving_wall.0[0] < 0.0);
        assert_eq!(moving_wall.0[0], at_rest.0[0]);
    }

    /// A wall advances by dt v each step, and past skin/2 since the last build the
    /// neighbour lists are rebuilt (so the near-wall masks cannot miss a contact).
    #[test]
    fn a_moving_plane_advances_and_triggers_rebuilds() {
        let case = one_grain(-2e-3, 0.0);
        let mut sim = Simulation::from_case(&case);
        sim.setup_settled().unwrap();
        // Away from the grain, so nothing else happens.
        let v = -1.0;
        sim.set_wall_velocity(0, v).unwrap();
        let builds = sim.neighbor_builds();
        let mut pos = -2e-3;
        // skin/2 = 0.25 mm at 1 um per step: a rebuild within 251 steps.
        for _ in 0..260 {
            sim.step().unwrap();
            pos += case.dt * v;
            assert_eq!(sim.wall_position(0), pos);
        }
        assert!(
            sim.neighbor_builds() > builds,
            "no rebuild after the wall moved 0.26 mm"
        );
        assert_eq!(sim.wall_velocity(0), v);
        assert!(sim.set_wall_velocity(1, 0.0).is_err());
    }
}
