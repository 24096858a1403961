//! The native 3D DEM: Hertz-Mindlin spheres with tangential history, CDT/EPSD2 rolling
//! friction and primitive walls, integrated like LIGGGHTS `nve/sphere`.
//!
//! Layout is structure-of-arrays; the force pass runs over pairs in parallel and then
//! gathers per particle in a fixed order, so results are bit-identical for any number
//! of threads (and for a given case, run to run).

pub mod contact;
pub mod contacts;
pub mod intruder;
pub(crate) mod lammps_granular;
pub(crate) mod lammps_micro;
mod lanes;
mod moving_walls;
pub mod neighbor;
pub mod packing;
mod pairs;
mod par;
pub mod penetration;
pub mod reorder;
pub(crate) mod rigid;
pub(crate) mod servo;
pub mod triaxial;
pub mod walls;

use crate::case::{Case, Perturbation, RollingModel, Wall};
use crate::numerics::vec3::*;
use crate::rundata::frames::{BodyState, Frame, ParticleState};
use contact::{ContactGeom, PairCoeffs, evaluate};
use neighbor::PairList;
use pairs::RevForce;
use par::Shared;
use rayon::prelude::*;
use std::time::Instant;

/// Moment-of-inertia factor of a solid sphere, LIGGGHTS' `INERTIA` in fix_nve_sphere.
const INERTIA: f64 = 0.4;

/// Pairs below this count are handled by one thread: spawning costs more than it saves.
const PAR_MIN_LEN: usize = 2048;

/// Largest initial overlap accepted, as a fraction of the smaller radius.
pub(crate) const MAX_INITIAL_OVERLAP: f64 = 0.05;

/// The per-particle arrays (`id` .. `body`) are in *storage order*: case order at the
/// start (free spheres, then clump members), then, for beds of at least
/// [`Simulation::set_reorder`]'s size, the free spheres renumbered in space at some
/// neighbour-list builds (see [`reorder`]). `case_index` maps storage to case order; every
/// output that lists particles ([`Simulation::frame`], [`Simulation::contacts`],
/// snapshots) is in case or id order whatever the storage order.
#[derive(Clone)]
pub struct Simulation {
    pub id: Vec<u64>,
    pub type_: Vec<usize>,
    pub radius: Vec<f64>,
    pub mass: Vec<f64>,
    pub x: Vec<V3>,
    pub v: Vec<V3>,
    pub omega: Vec<V3>,
    pub f: Vec<V3>,
    pub torque: Vec<V3>,
    /// Index into `bodies` of the clump each sphere belongs to, -1 for a free sphere.
    /// Free spheres come first (case order), then the members of each body.
    pub body: Vec<i32>,
    /// Rigid multisphere clumps (fix multisphere), see [`rigid`].
    pub bodies: Vec<rigid::RigidBody>,
    /// Spheres `0..free` are free, `free..` clump members: the per-sphere kick, drift
    /// and gravity sweeps run over `0..free` only, without a per-sphere branch.
    free: usize,
    n_types: usize,
    coeffs: Vec<PairCoeffs>,
    rolling: RollingModel,
    walls: Vec<Wall>,
    /// Velocity of each wall (zero unless a driver sets it, see
    /// [`Simulation::set_wall_velocity`]): plane walls move along their normal by
    /// `dt * v` at the start of every step and grains feel `v` in the contact's relative
    /// velocity, as LIGGGHTS' moving meshes (`move/mesh`, mesh module servo).
    wall_vel: Vec<V3>,
    /// Plane positions at the last neighbour build: a wall that moved more than skin/2
    /// since then forces a rebuild (LIGGGHTS rebuilds when a mesh moved that far), so the
    /// `r + skin` near-wall masks stay valid.
    wall_pos_at_build: Vec<f64>,
    /// Whether any wall has a non-zero velocity (the step moves walls only then).
    walls_move: bool,
    /// Wall contact history, `walls_stride` entries per particle: shear, and the EPSD2
    /// rolling torque only when the rolling model is EPSD2 (empty otherwise).
    wall_shear: Vec<V3>,
    wall_roll: Vec<V3>,
    walls_stride: usize,
    pairs: PairList,
    /// Per reverse slot (see [`PairList::rev_pos`]): the force on the pair's first
    /// particle and the torque on its second, zero when the pair does not touch, so the
    /// gather adds them without a branch (adding +0.0 to a sum that started at +0.0
    /// changes no bit).
    rev_out: Vec<RevForce>,
    /// Force each wall exerted on each particle in the last force pass (`walls_stride`
    /// per particle; zero when not touching), kept so [`Simulation::contacts`] reports
    /// exactly the forces that were integrated, not a re-evaluation.
    wall_out: Vec<V3>,
    /// Whether each pair touched in the last force pass.
    pair_touch: Vec<bool>,
    /// Scratch of the pair pass: indices of the touching pairs, compacted within each
    /// block's pair range.
    touching: Vec<u32>,
    /// Bit k set: particle was within its radius + skin of wall k at the last rebuild,
    /// so it may touch it before the next one (the role of LIGGGHTS' primitive-wall
    /// neighbour lists). Walls beyond 63 share bit 63.
    near_walls: Vec<u64>,
    intruder: Option<MovingIntruder>,
    gravity: V3,
    pub dt: f64,
    skin: f64,
    lo: V3,
    hi: V3,
    pub step: u64,
    times: StepTimes,
    /// Per particle `(dtf / m, dtf / INERTIA / (r^2 m))` of `nve/sphere` with
    /// `dtf = dt / 2`, for the dt, masses and radii in `kick_for`: the same divisions
    /// the kicks would do, done once.
    kick: Vec<[f64; 2]>,
    kick_for: (f64, u64),
    /// Case index (position in the case's particle order) of each stored particle.
    case_index: Vec<u32>,
    /// Steps between spatial sorts (0: never) and the fewest free spheres to sort.
    reorder_every: u64,
    reorder_min: usize,
    /// Step of the last sort (`None`: not yet).
    sorted_at: Option<u64>,
}

/// Wall time (s) spent in each phase of [`Simulation::step`] since the simulation was
/// made, for profiling: a handful of clock reads per step, negligible against the step
/// itself.
#[derive(Debug, Clone, Copy, Default)]
pub struct StepTimes {
    /// First half kick and drift, fused with the finite-state, domain and skin/2
    /// displacement checks.
    pub integrate: f64,
    /// Neighbour-list builds (cells, pairs, history merge, wall masks, intruder
    /// candidates).
    pub neighbor: f64,
    /// The pair pass: contact law of every neighbour pair, own-pair sums.
    pub pairs: f64,
    /// Per-particle gather of the reverse pair results, primitive walls, gravity, the
    /// intruder and the second half kick.
    pub gather: f64,
    pub steps: u64,
}

impl StepTimes {
    pub fn total(&self) -> f64 {
        self.integrate + self.neighbor + self.pairs + self.gather
    }
}

/// A rigid body driven at constant velocity through the grains (the penetration
/// intruder). Grains see it as a moving wall with the wall contact law, like LIGGGHTS'
/// `fix move/mesh` + `fix wall/gran ... mesh`; the force on it is the sum of the
/// reactions, summed in particle order so it is deterministic.
#[derive(Clone)]
pub struct MovingIntruder {
    pub body: intruder::FlatCylinder,
    pub velocity: V3,
    pub type_: usize,
    shear: Vec<V3>,
    /// EPSD2 rolling history (empty for other rolling models).
    roll: Vec<V3>,
    /// Force each grain receives from the intruder this step (zero if not touching).
    on_grain: Vec<V3>,
    /// Grains that may touch the intruder before the candidates are listed again:
    /// within `INTRUDER_MARGIN_SKINS` skins of its surface when listed.
    candidate: Vec<bool>,
    /// Bottom z when the candidates were listed; `None`: not listed yet.
    listed_z: Option<f64>,
}

/// Candidate margin of the intruder, in skins. A grain moves at most skin/2 from its
/// position at the last neighbour build, so at most one skin from where it was when the
/// candidates were listed; the intruder moves at most skin/2 before they are listed
/// again. The signed distance to a convex body is 1-Lipschitz in both, so a grain farther
/// than r + 1.5 skin cannot touch before the next listing; 2 leaves room for round-off.
const INTRUDER_MARGIN_SKINS: f64 = 2.0;

impl Simulation {
    /// Adds the moving intruder; `type_` is its 0-based material type.
    pub fn set_intruder(&mut self, body: intruder::FlatCylinder, velocity: V3, type_: usize) {
        let n = self.x.len();
        let epsd2 = self.rolling == RollingModel::Epsd2;
        self.intruder = Some(MovingIntruder {
            body,
            velocity,
            type_,
            shear: vec![[0.0; 3]; n],
            roll: vec![[0.0; 3]; if epsd2 { n } else { 0 }],
            on_grain: vec![[0.0; 3]; n],
            candidate: vec![false; n],
            listed_z: None,
        });
    }

    pub fn intruder(&self) -> Option<&MovingIntruder> {
        self.intruder.as_ref()
    }

    /// Total force the grains exert on the intruder (N).
    pub(crate) fn intruder_force(&self) -> V3 {
        let mut f = [0.0; 3];
        if let Some(it) = &self.intruder {
            for g in &it.on_grain {
                sub_assign(&mut f, *g);
            }
        }
        f
    }

    pub fn from_case(case: &Case) -> Simulation {
        Simulation::from_case_perturbed(case, Perturbation::default())
    }

    pub fn from_case_perturbed(case: &Case, pert: Perturbation) -> Simulation {
        let n_types = case.n_types();
        let mut coeffs = Vec::with_capacity(n_types * n_types);
        for a in 0..n_types {
            for b in 0..n_types {
                let (ma, mb) = (&case.materials[a], &case.materials[b]);
                let k = case.pairs.idx(a, b);
                coeffs.push(PairCoeffs::new(
                    ma.youngs_modulus,
                    ma.poisson_ratio + pert.poisson_shift,
                    mb.youngs_modulus,
                    mb.poisson_ratio + pert.poisson_shift,
                    (case.pairs.restitution[k] + pert.restitution_shift).min(1.0),
                    match pert.pair_friction {
                        Some((i, j, mu)) if (i, j) == (a, b) || (j, i) == (a, b) => mu,
                        _ => case.pairs.friction[k] * pert.friction_factor,
                    },
                    case.pairs.rolling_friction[k] * pert.rolling_friction_factor,
                ));
            }
        }
        // Free spheres, then every clump's members (the LIGGGHTS atom order: spheres
        // created at step 0, bodies inserted at step 1 in case order).
        let mut id: Vec<u64> = case.particles.iter().map(|p| p.id).collect();
        let mut type_: Vec<usize> = case.particles.iter().map(|p| p.type_).collect();
        let mut radius: Vec<f64> = case.particles.iter().map(|p| p.radius).collect();
        let mut mass: Vec<f64> = case.particles.iter().map(|p| p.mass()).collect();
        let mut x: Vec<V3> = case.particles.iter().map(|p| p.x).collect();
        let mut v: Vec<V3> = case.particles.iter().map(|p| p.v).collect();
        let mut omega: Vec<V3> = case.particles.iter().map(|p| p.omega).collect();
        let mut body = vec![-1i32; case.particles.len()];
        let mut bodies = Vec::with_capacity(case.clumps.bodies.len());
        for (b, c) in case.clumps.bodies.iter().enumerate() {
            let t = case.clumps.template_of(c);
            let first = id.len();
            for (k, r) in t.radii.iter().enumerate() {
                id.push(c.id);
                type_.push(t.type_);
                radius.push(*r);
                // Every member carries the whole body's mass as its contact mass
                // (particleToInsert_multisphere.cpp:203, `rmass = mass_ins`).
                mass.push(if pert.member_sphere_mass {
                    4.0 * std::f64::consts::PI / 3.0 * r * r * r * t.density
                } else {
                    t.mass
                });
                x.push(t.offsets[k]);
                v.push([0.0; 3]);
                omega.push([0.0; 3]);
                body.push(b as i32);
            }
            let rb = rigid::RigidBody::new(
                c.id,
                t.mass,
                t.inertia.map(|i| i * pert.inertia_factor),
                t.offsets.clone(),
                (first..id.len()).collect(),
                c.x,
                c.orientation,
                c.v,
                c.omega,
            );
            rb.set_xv(&mut x, &mut v, &mut omega);
            bodies.push(rb);
        }
        let n = id.len();
        let stride = case.walls.len().max(1);
        let epsd2 = case.rolling == RollingModel::Epsd2;
        Simulation {
            id,
            type_,
            radius,
            mass,
            x,
            v,
            omega,
            body,
            bodies,
            free: case.particles.len(),
            f: vec![[0.0; 3]; n],
            torque: vec![[0.0; 3]; n],
            n_types,
            coeffs,
            rolling: case.rolling,
            walls: case.walls.clone(),
            wall_vel: vec![[0.0; 3]; case.walls.len()],
            wall_pos_at_build: vec![f64::NAN; case.walls.len()],
            walls_move: false,
            wall_shear: vec![[0.0; 3]; n * stride],
            wall_roll: vec![[0.0; 3]; if epsd2 { n * stride } else { 0 }],
            walls_stride: stride,
            pairs: PairList::with_roll(epsd2),
            rev_out: Vec::new(),
            wall_out: vec![[0.0; 3]; n * stride],
            pair_touch: Vec::new(),
            touching: Vec::new(),
            near_walls: vec![u64::MAX; n],
            intruder: None,
            gravity: case.gravity,
            dt: case.dt,
            skin: case.neighbor_skin,
            lo: case.domain_lo,
            hi: case.domain_hi,
            step: 0,
            times: StepTimes::default(),
            kick: Vec::new(),
            kick_for: (f64::NAN, 0),
            case_index: (0..n as u32).collect(),
            // Off unless asked for: no speed-up is measured yet (docs/performance.md,
            // "Spatial sorting"), and a sort changes every run of 4096 grains or more
            // by rounding, so the engine's results stay those it was validated with.
            reorder_every: 0,
            reorder_min: reorder::DEFAULT_MIN_PARTICLES,
            sorted_at: None,
        }
    }

    /// Spatial sorting of the free spheres (see [`reorder`]): at the first neighbour-list
    /// build at least `every` steps after the last sort (and at the first build), when
    /// there are at least `min_particles` free spheres. `every = 0` never sorts, the
    /// default; LAMMPS' own default is [`reorder::DEFAULT_EVERY`] steps, used here with
    /// [`reorder::DEFAULT_MIN_PARTICLES`] spheres when sorting is asked for
    /// (`granval bench --scaling`).
    pub fn set_reorder(&mut self, every: u64, min_particles: usize) {
        self.reorder_every = every;
        self.reorder_min = min_particles;
    }

    /// Storage indices in case order: `case_order()[c]` is where the case's particle `c`
    /// (free spheres in case order, then clump members) is stored now.
    pub fn case_order(&self) -> Vec<usize> {
        let mut order = vec![0; self.case_index.len()];
        for (k, &c) in self.case_index.iter().enumerate() {
            order[c as usize] = k;
        }
        order
    }

    /// Whether the storage order differs from case order (a sort moved something).
    pub(crate) fn reordered(&self) -> bool {
        self.case_index
            .iter()
            .enumerate()
            .any(|(k, &c)| c as usize != k)
    }

    /// The new storage order if a sort is due at this build (see [`Simulation::set_reorder`]).
    fn due_order(&mut self) -> Option<Vec<u32>> {
        let every = self.reorder_every;
        if every == 0
            || self.free < self.reorder_min
            || self.sorted_at.is_some_and(|s| self.step < s + every)
        {
            return None;
        }
        self.sorted_at = Some(self.step);
        let rmax = self.radius.iter().cloned().fold(0.0, f64::max);
        reorder::morton_order(&self.x, self.free, 2.0 * rmax + self.skin, self.lo, self.hi)
    }

    /// Renumbers every per-particle array: new particle k is old `old_of_new[k]`. Clump
    /// members are never moved (their bodies hold their indices), so `body` and
    /// `bodies` stay valid. The pair list is renumbered by its next build.
    fn permute(&mut self, old_of_new: &[u32]) {
        use reorder::{gather, gather_strided};
        debug_assert!(
            old_of_new[self.free..]
                .iter()
                .enumerate()
                .all(|(k, &o)| o as usize == self.free + k)
        );
        gather(&mut self.id, old_of_new);
        gather(&mut self.type_, old_of_new);
        gather(&mut self.radius, old_of_new);
        gather(&mut self.mass, old_of_new);
        gather(&mut self.x, old_of_new);
        gather(&mut self.v, old_of_new);
        gather(&mut self.omega, old_of_new);
        gather(&mut self.f, old_of_new);
        gather(&mut self.torque, old_of_new);
        gather(&mut self.body, old_of_new);
        gather(&mut self.near_walls, old_of_new);
        gather(&mut self.case_index, old_of_new);
        let stride = self.walls_stride;
        gather_strided(&mut self.wall_shear, old_of_new, stride);
        gather_strided(&mut self.wall_roll, old_of_new, stride);
        gather_strided(&mut self.wall_out, old_of_new, stride);
        if let Some(it) = &mut self.intruder {
            gather(&mut it.shear, old_of_new);
            gather(&mut it.roll, old_of_new);
            gather(&mut it.on_grain, old_of_new);
            gather(&mut it.candidate, old_of_new);
        }
        if self.kick.len() == old_of_new.len() {
            gather(&mut self.kick, old_of_new);
            self.kick_for.1 = self.mass_radius_print();
        }
    }

    /// Builds the neighbour list and evaluates forces without advancing history, as
    /// LIGGGHTS' `Verlet::setup` does before step 1 (and before the step-0 dump).
    pub fn setup(&mut self) -> anyhow::Result<()> {
        self.check_start()?;
        self.refresh_kick();
        self.rebuild();
        if self.bodies.is_empty() {
            self.compute_forces(false, false);
        } else {
            // LIGGGHTS inserts bodies in pre_exchange of step 1 (fix_insert.cpp:407,
            // 652-660): the body sits at x0 and then gets that step's forces (history
            // updated, an ordinary step) and only the final half kick
            // (fix_multisphere.cpp:721-784). Native step 0 is that state, LIGGGHTS step 1;
            // free spheres start at rest and force-free (case validation), so their step
            // 0 -> 1 in LIGGGHTS is the same final half kick.
            self.compute_forces(true, true);
        }
        Ok(())
    }

    /// [`Simulation::setup`] for a state the DEM itself settled (a prepared bed, native or
    /// LIGGGHTS): its overlaps are the equilibrium of its own contact law (a soft G = 1 MPa
    /// bed carries up to ~5 % of a radius at the bottom), not input errors, so the
    /// initial-overlap refusal is skipped; the domain and finiteness checks remain.
    ///
    /// With clumps, the start is LIGGGHTS' with the bodies inserted into the settled
    /// state: the insertion step (see [`Simulation::setup`]: forces with history, final
    /// half kick) and then the boundary of the next `run` command, where LIGGGHTS builds
    /// the neighbour list again and recomputes every force without advancing history
    /// (`Verlet::setup`), and `fix multisphere` gathers the bodies' force and torque from
    /// them (fix_multisphere.cpp `setup` -> `calc_force(true)`) without moving anything.
    /// The first step's half kick uses those.
    pub fn setup_settled(&mut self) -> anyhow::Result<()> {
        self.check_domain()?;
        self.refresh_kick();
        self.rebuild();
        if self.bodies.is_empty() {
            self.compute_forces(false, false);
        } else {
            self.compute_forces(true, true);
            self.rebuild();
            self.compute_forces(false, false);
            for b in &mut self.bodies {
                b.gather(&self.x, &self.f, &self.torque, self.gravity);
            }
        }
        Ok(())
    }

    /// One velocity-Verlet step in `nve/sphere` order: half kick + drift, re-neighbour
    /// if needed, forces, half kick. The checks after the drift (finite state, domain,
    /// displacement since the last build) run in the drift's sweep, and the second half
    /// kick in the force gather's, so a step reads the particle arrays three times.
    /// Clumps follow `fix multisphere`: their first half (kick, drift, rotation, member
    /// positions) after the free spheres' sweep, their second after the gather.
    pub fn step(&mut self) -> anyhow::Result<()> {
        let t0 = Instant::now();
        self.refresh_kick();
        let (mut non_finite, mut outside, mut moved) = self.kick_drift_check();
        if !self.bodies.is_empty() {
            for b in &mut self.bodies {
                b.initial_integrate(self.dt);
                b.set_xv(&mut self.x, &mut self.v, &mut self.omega);
            }
            // The sweep saw the free spheres only; members (indices above every free
            // one, so `min` keeps "first in array order") are checked where they are now.
            let (nf, out, mv) = self.check_members();
            non_finite = non_finite.min(nf);
            outside = outside.min(out);
            moved |= mv;
        }
        self.step += 1;
        if let Some(it) = &mut self.intruder {
            it.body.translate(it.velocity[2] * self.dt);
        }
        if self.walls_move {
            moved |= self.move_walls();
        }
        self.domain_error(non_finite, outside)?;
        let t1 = Instant::now();
        if moved {
            self.rebuild();
        }
        self.list_intruder_candidates(false);
        let t2 = Instant::now();
        self.compute_forces(true, true);
        let tm = &mut self.times;
        tm.integrate += (t1 - t0).as_secs_f64();
        tm.neighbor += (t2 - t1).as_secs_f64();
        tm.steps += 1;
        Ok(())
    }

    /// First half kick and drift of `nve/sphere` for the free spheres, and in the same
    /// sweep the first of them with a non-finite state, the first outside the box
    /// (`usize::MAX`: none) and whether any moved more than skin/2 since the last
    /// neighbour build (LIGGGHTS `neigh_modify delay 0 every 1 check yes`).
    #[inline(never)]
    fn kick_drift_check(&mut self) -> (usize, usize, bool) {
        let dt = self.dt;
        let built = self.pairs.x_at_build.len() == self.x.len();
        // Clump members (`free..`) are moved by their bodies, not here.
        let n = self.free;
        let (lo, hi) = (self.lo, self.hi);
        let lim = 0.25 * self.skin * self.skin;
        let x_at_build = &self.pairs.x_at_build;
        let (f, torque, kick) = (&self.f, &self.torque, &self.kick);
        let (xs, vs, ws) = (
            Shared::new(&mut self.x),
            Shared::new(&mut self.v),
            Shared::new(&mut self.omega),
        );
        let (non_finite, outside, moved) = par::map_reduce_blocks(
            n,
            (usize::MAX, usize::MAX, !built),
            |r| {
                // SAFETY: blocks are disjoint particle ranges.
                let (x, v, w) = unsafe {
                    (
                        xs.slice(r.clone()),
                        vs.slice(r.clone()),
                        ws.slice(r.clone()),
                    )
                };
                let (f, t) = (&f[r.clone()], &torque[r.clone()]);
                let kick = &kick[r.clone()];
                let xb = if built { &x_at_build[r.clone()] } else { &[] };
                let len = r.len();
                assert!(x.len() == len && f.len() == len && kick.len() == len);
                // Simple loops the compiler vectorises: the sweep, then each check over
                // the block (still in cache); the index of a failure is searched for only
                // when there is one.
                for l in 0..len {
                    let [dtfm, dtirotate] = kick[l];
                    add_assign(&mut v[l], scale(f[l], dtfm));
                    add_assign(&mut x[l], scale(v[l], dt));
                    add_assign(&mut w[l], scale(t[l], dtirotate));
                }
                let all_finite = |a: &[V3]| {
                    a.as_flattened()
                        .iter()
                        .fold(true, |ok, c| ok & c.is_finite())
                };
                let finite =
                    |l: usize| x[l].iter().chain(&v[l]).chain(&w[l]).all(|c| c.is_finite());
                let inside = |p: &V3| {
                    (p[0] >= lo[0])
                        & (p[0] <= hi[0])
                        & (p[1] >= lo[1])
                        & (p[1] <= hi[1])
                        & (p[2] >= lo[2])
                        & (p[2] <= hi[2])
                };
                let nf = if all_finite(x) & all_finite(v) & all_finite(w) {
                    usize::MAX
                } else {
                    r.start + (0..len).find(|&l| !finite(l)).unwrap_or(0)
                };
                let out = if x.iter().fold(true, |ok, p| ok & inside(p)) {
                    usize::MAX
                } else {
                    r.start + x.iter().position(|p| !inside(p)).unwrap_or(0)
                };
                let mv = built
                    && x.iter().zip(xb).fold(false, |mv, (p, b)| {
                        let d = [p[0] - b[0], p[1] - b[1], p[2] - b[2]];
                        mv | (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] > lim)
                    });
                (nf, out, mv)
            },
            |a, b| (a.0.min(b.0), a.1.min(b.1), a.2 || b.2),
        );
        (non_finite, outside, moved)
    }

    /// The checks of [`Simulation::kick_drift_check`] for the clump members, after their
    /// bodies placed them: a serial loop, members being few.
    fn check_members(&self) -> (usize, usize, bool) {
        let (lo, hi) = (self.lo, self.hi);
        let lim = 0.25 * self.skin * self.skin;
        let xb = &self.pairs.x_at_build;
        let built = xb.len() == self.x.len();
        let (mut nf, mut out, mut mv) = (usize::MAX, usize::MAX, !built);
        for k in (self.free..self.x.len()).rev() {
            let (p, v, w) = (self.x[k], self.v[k], self.omega[k]);
            if !p.iter().chain(&v).chain(&w).all(|c| c.is_finite()) {
                nf = k;
            }
            if !(0..3).all(|c| p[c] >= lo[c] && p[c] <= hi[c]) {
                out = k;
            }
            if built {
                let b = xb[k];
                let d = [p[0] - b[0], p[1] - b[1], p[2] - b[2]];
                mv |= d[0] * d[0] + d[1] * d[1] + d[2] * d[2] > lim;
            }
        }
        (nf, out, mv)
    }

    /// Computes the kick factors for the current dt, masses and radii: at setup, and
    /// again when `dt` changed (masses and radii are fixed after setup; debug builds
    /// check that on every step).
    fn refresh_kick(&mut self) {
        debug_assert!(
            self.kick.len() != self.x.len() || self.kick_for.1 == self.mass_radius_print(),
            "masses or radii changed after setup"
        );
        if self.kick_for.0 == self.dt && self.kick.len() == self.x.len() {
            return;
        }
        let dtf = 0.5 * self.dt;
        self.kick.clear();
        self.kick.extend(
            self.mass
                .iter()
                .zip(&self.radius)
                .map(|(&m, &r)| [dtf / m, dtf / INERTIA / (r * r * m)]),
        );
        self.kick_for = (self.dt, self.mass_radius_print());
    }

    fn mass_radius_print(&self) -> u64 {
        self.mass
            .iter()
            .chain(&self.radius)
            .fold(0xcbf2_9ce4_8422_2325u64, |h, v| {
                (h ^ v.to_bits()).wrapping_mul(0x0100_0000_01b3)
            })
    }

    /// Wall time per phase of [`Simulation::step`] so far (see [`StepTimes`]).
    pub fn step_times(&self) -> StepTimes {
        self.times
    }

    fn rebuild(&mut self) {
        let order = self.due_order();
        if let Some(o) = &order {
            self.permute(o);
        }
        self.pairs.build(
            &self.x,
            &self.radius,
            &self.body,
            self.skin,
            self.lo,
            self.hi,
            order.as_deref(),
        );
        for (p, w) in self.wall_pos_at_build.iter_mut().zip(&self.walls) {
            if let Wall::Plane { position, .. } = w {
                *p = *position;
            }
        }
        let (walls, skin, stride) = (&self.walls, self.skin, self.walls_stride);
        (
            &mut self.near_walls,
            self.wall_out.par_chunks_mut(stride),
            &self.x,
            &self.radius,
        )
            .into_par_iter()
            .with_min_len(PAR_MIN_LEN)
            .for_each(|(mask, wout, x, r)| {
                *mask = 0;
                for (k, w) in walls.iter().enumerate() {
                    if k >= 64 || walls::wall_contact(w, *x, r + skin).is_some() {
                        *mask |= 1u64 << k.min(63);
                    }
                }
                // Walls the particle cannot reach before the next build are not evaluated:
                // their last force is zero from now on (it was not touching them).
                for (k, o) in wout.iter_mut().enumerate() {
                    if *mask & (1u64 << k.min(63)) == 0 {
                        *o = [0.0; 3];
                    }
                }
            });
        self.list_intruder_candidates(true);
    }

    /// Lists the grains that may touch the intruder (see [`INTRUDER_MARGIN_SKINS`]):
    /// always when `force`, else when never listed or the intruder moved more than skin/2
    /// since. A grain leaving the list is not touching: its history and force are
    /// cleared exactly as evaluating it would.
    fn list_intruder_candidates(&mut self, force: bool) {
        let skin = self.skin;
        let Some(it) = &mut self.intruder else {
            return;
        };
        let z = it.body.bottom_z();
        if !force && it.listed_z.is_some_and(|z0| (z - z0).abs() <= 0.5 * skin) {
            return;
        }
        it.listed_z = Some(z);
        let margin = INTRUDER_MARGIN_SKINS * skin;
        let (body, epsd2) = (&it.body, !it.roll.is_empty());
        let (shear, roll, on) = (
            Shared::new(&mut it.shear),
            Shared::new(&mut it.roll),
            Shared::new(&mut it.on_grain),
        );
        let (x, radius) = (&self.x, &self.radius);
        let cand = Shared::new(&mut it.candidate);
        par::for_blocks(x.len(), |r| {
            // SAFETY: blocks are disjoint particle ranges.
            let (cand, shear, on) = unsafe {
                (
                    cand.slice(r.clone()),
                    shear.slice(r.clone()),
                    on.slice(r.clone()),
                )
            };
            let roll: &mut [V3] = if epsd2 {
                unsafe { roll.slice(r.clone()) }
            } else {
                &mut []
            };
            for (l, k) in r.enumerate() {
                let near = body.query(x[k]).distance <= radius[k] + margin;
                if cand[l] && !near {
                    shear[l] = [0.0; 3];
                    on[l] = [0.0; 3];
                    if epsd2 {
                        roll[l] = [0.0; 3];
                    }
                }
                cand[l] = near;
            }
        });
    }

    /// LIGGGHTS runs with `boundary f f f`: an atom leaving the box is lost and the run
    /// stops with an error. Do the same instead of silently integrating it.
    /// Refuses a start with grains (or a grain and a wall) overlapping by more than
    /// [`MAX_INITIAL_OVERLAP`] of the smaller radius: Hertz forces at such overlaps fling
    /// grains out at once and the run would end with a meaningless "left the domain"
    /// error. Checked with a hash grid, so a case with 1e6 coincident grains fails fast
    /// in O(N) memory instead of building an N^2 neighbour list.
    /// The start checks [`Simulation::setup`] makes (every state finite and inside the
    /// box, no start overlap), without computing anything: `granval validate` and `deck`
    /// make exactly the checks a run makes.
    pub(crate) fn check_start(&self) -> anyhow::Result<()> {
        self.check_domain()?;
        self.check_initial_overlaps()
    }

    fn check_initial_overlaps(&self) -> anyhow::Result<()> {
        if !self.bodies.is_empty() {
            // Clump cases: LIGGGHTS' insertion (overlapcheck yes) refuses a body touching
            // anything, so the start must be contact-free; members of one body overlap
            // by design and never interact (fix_multisphere.cpp:178-186).
            if let Some((i, j, gap)) = crate::numerics::overlap::first_contact_across_bodies(
                &self.x,
                &self.radius,
                &self.body,
            ) {
                let kind = |k: usize| {
                    if self.body[k] >= 0 {
                        "clump"
                    } else {
                        "particle"
                    }
                };
                anyhow::bail!(
                    "{} id {} and {} id {} touch at the start (gap {gap:.3e} m): a case with clumps must start without contacts (LIGGGHTS' insertion refuses overlapping bodies)",
                    kind(i),
                    self.id[i],
                    kind(j),
                    self.id[j],
                );
            }
        }
        if let Some((i, j, overlap)) = self
            .bodies
            .is_empty()
            .then(|| {
                crate::numerics::overlap::first_overlap(&self.x, &self.radius, MAX_INITIAL_OVERLAP)
            })
            .flatten()
        {
            anyhow::bail!(
                "particles id {} and id {} overlap by {overlap:.3e} m ({:.1} % of the smaller radius {:.3e} m) at the start; more than {:.0} % is refused: move them apart",
                self.id[i],
                self.id[j],
                100.0 * overlap / self.radius[i].min(self.radius[j]),
                self.radius[i].min(self.radius[j]),
                100.0 * MAX_INITIAL_OVERLAP
            );
        }
        for (k, x) in self.x.iter().enumerate() {
            for (w, wall) in self.walls.iter().enumerate() {
                if let Some((delta, _)) = walls::wall_contact(wall, *x, self.radius[k]) {
                    let overlap = self.radius[k] - norm(delta);
                    if overlap > MAX_INITIAL_OVERLAP * self.radius[k] {
                        anyhow::bail!(
                            "particle id {} overlaps wall {w} by {overlap:.3e} m ({:.1} % of its radius) at the start; more than {:.0} % is refused",
                            self.id[k],
                            100.0 * overlap / self.radius[k],
                            100.0 * MAX_INITIAL_OVERLAP
                        );
                    }
                }
            }
        }
        Ok(())
    }

    fn check_domain(&self) -> anyhow::Result<()> {
        let non_finite = (0..self.x.len())
            .find(|&k| {
                !(self.x[k].iter().chain(&self.v[k]).chain(&self.omega[k])).all(|c| c.is_finite())
            })
            .unwrap_or(usize::MAX);
        let outside = self
            .x
            .iter()
            .position(|p| (0..3).any(|c| !(p[c] >= self.lo[c] && p[c] <= self.hi[c])))
            .unwrap_or(usize::MAX);
        self.domain_error(non_finite, outside)
    }

    /// The error for the first particle with a non-finite state, else the first outside
    /// the box (`usize::MAX`: none).
    fn domain_error(&self, non_finite: usize, outside: usize) -> anyhow::Result<()> {
        if non_finite != usize::MAX {
            let k = non_finite;
            anyhow::bail!(
                "particle id {} has a non-finite state at step {} (x = {:?}, v = {:?}): the integration blew up; likely causes are a time step too large for the contact stiffness or grains started deep inside each other",
                self.id[k],
                self.step,
                self.x[k],
                self.v[k]
            );
        }
        if outside != usize::MAX {
            let k = outside;
            anyhow::bail!(
                "particle id {} left the domain box at step {} (x = {:?})",
                self.id[k],
                self.step,
                self.x[k]
            );
        }
        Ok(())
    }

    /// Forces and torques on every particle; with `kick`, also the second half kick of
    /// `nve/sphere` (in the gather's sweep: a particle's kick needs only its own force)
    /// and then that of `fix multisphere` (force gathering, kick, member velocities).
    fn compute_forces(&mut self, update_history: bool, kick: bool) {
        let t0 = Instant::now();
        self.pair_pass(update_history);
        let t1 = Instant::now();
        self.gather_pass(update_history, kick);
        if kick {
            for b in &mut self.bodies {
                b.gather(&self.x, &self.f, &self.torque, self.gravity);
                b.final_integrate(self.dt);
                b.set_v(&mut self.v, &mut self.omega);
            }
        }
        let t2 = Instant::now();
        let tm = &mut self.times;
        tm.pairs += (t1 - t0).as_secs_f64();
        tm.gather += (t2 - t1).as_secs_f64();
    }

    /// Pass 1, per block of particles over their own pairs: see [`pairs`].
    #[inline(never)]
    fn pair_pass(&mut self, update_history: bool) {
        let np = self.pairs.len();
        self.rev_out.resize(np, RevForce::default());
        self.pair_touch.resize(np, false);
        self.touching.resize(np, 0);
        let pl = &mut self.pairs;
        let mut ctx = pairs::PairCtx {
            x: &self.x,
            v: &self.v,
            omega: &self.omega,
            radius: &self.radius,
            mass: &self.mass,
            type_: &self.type_,
            coeffs: &self.coeffs,
            n_types: self.n_types,
            rolling: self.rolling,
            dt: self.dt,
            update_history,
            start: &pl.start,
            pi: &pl.i,
            pj: &pl.j,
            rev_pos: &pl.rev_pos,
            one_coeff: None,
        };
        ctx.check(pl.x_at_build.len(), self.rev_out.len());
        let track_roll = pl.track_roll;
        let (shear, roll) = (Shared::new(&mut pl.shear), Shared::new(&mut pl.roll));
        let touch = Shared::new(&mut self.pair_touch);
        let list = Shared::new(&mut self.touching);
        let rev = Shared::new(&mut self.rev_out);
        let (fs, ts) = (Shared::new(&mut self.f), Shared::new(&mut self.torque));
        par::for_blocks(self.x.len(), |r| {
            let kr = ctx.start[r.start]..ctx.start[r.end];
            // SAFETY: blocks are disjoint particle ranges, hence disjoint pair ranges.
            let out = unsafe {
                pairs::BlockOut {
                    k0: kr.start,
                    i0: r.start,
                    shear: shear.slice(kr.clone()),
                    roll: if track_roll {
                        roll.slice(kr.clone())
                    } else {
                        &mut []
                    },
                    touch: touch.slice(kr.clone()),
                    list: list.slice(kr.clone()),
                    f: fs.slice(r.clone()),
                    t: ts.slice(r.clone()),
                    rev,
                }
            };
            pairs::block(&ctx, r, out);
        });
    }

    /// Pass 2, per particle: the own-pair sums of pass 1 continued with the reverse pair
    /// results in pair order, then the primitive walls in wall order, gravity and the
    /// moving intruder (a wall with velocity, grain-intruder law); with `kick` the
    /// second half kick. Clump members get neither gravity (fix_gravity.cpp:333: the
    /// body gets m g once in its force gathering) nor a kick (their body moves them).
    #[inline(never)]
    fn gather_pass(&mut self, update_history: bool, kick: bool) {
        let dt = self.dt;
        let (x, radius, mass, type_) = (&self.x, &self.radius, &self.mass, &self.type_);
        let kicks = &self.kick;
        let (coeffs, n_types, rolling) = (&self.coeffs, self.n_types, self.rolling);
        let (rev_start, rev_out) = (&self.pairs.rev_start, &self.rev_out);
        let (walls, gravity, stride) = (&self.walls, self.gravity, self.walls_stride);
        let wall_vel = &self.wall_vel;
        let near_walls = &self.near_walls;
        let free = self.free;
        let epsd2 = !self.wall_roll.is_empty();
        let (wshear, wroll, wout) = (
            Shared::new(&mut self.wall_shear),
            Shared::new(&mut self.wall_roll),
            Shared::new(&mut self.wall_out),
        );
        let it = self.intruder.as_mut().map(|it| {
            (
                &it.body,
                it.velocity,
                it.type_,
                &it.candidate,
                Shared::new(&mut it.shear),
                Shared::new(&mut it.roll),
                Shared::new(&mut it.on_grain),
                !it.roll.is_empty(),
            )
        });
        let (fs, ts) = (Shared::new(&mut self.f), Shared::new(&mut self.torque));
        // Velocities are read by the wall and intruder laws and written by the kick, of
        // the block's own particles only.
        let (vs, ws) = (Shared::new(&mut self.v), Shared::new(&mut self.omega));
        par::for_blocks(x.len(), |r| {
            // SAFETY: blocks are disjoint particle ranges.
            let (f, t) = unsafe { (fs.slice(r.clone()), ts.slice(r.clone())) };
            let (vb, wb) = unsafe { (vs.slice(r.clone()), ws.slice(r.clone())) };
            let wr = r.start * stride..r.end * stride;
            let (wshear, wout) = unsafe { (wshear.slice(wr.clone()), wout.slice(wr.clone())) };
            let wroll: &mut [V3] = if epsd2 {
                unsafe { wroll.slice(wr.clone()) }
            } else {
                &mut []
            };
            let (x, radius, mass) = (&x[r.clone()], &radius[r.clone()], &mass[r.clone()]);
            let (type_, near_walls) = (&type_[r.clone()], &near_walls[r.clone()]);
            let kb: &[[f64; 2]] = if kick { &kicks[r.clone()] } else { &[] };
            let rev_start = &rev_start[r.start..r.end + 1];
            let len = r.len();
            // The block's free spheres are its first `n_free` (members come last).
            let n_free = free.saturating_sub(r.start).min(len);
            assert!(
                x.len() == len && vb.len() == len && f.len() == len && rev_start.len() == len + 1
            );
            let mut no_roll = [0.0; 3];
            let mut itb = it.map(|(body, vel, ity, cand, sh, rl, on, iepsd2)| {
                // SAFETY: the block's own particles.
                let rl: &mut [V3] = if iepsd2 {
                    unsafe { rl.slice(r.clone()) }
                } else {
                    &mut []
                };
                (
                    body,
                    vel,
                    ity,
                    &cand[r.clone()],
                    unsafe { sh.slice(r.clone()) },
                    rl,
                    unsafe { on.slice(r.clone()) },
                    iepsd2,
                )
            });
            // Per particle in this order (the order of the sums): the reverse pair
            // results, the near walls, gravity, the intruder, then the kick. Each stage
            // is its own loop over the block (still in cache), so the common ones stay
            // simple and the sparse ones (walls, intruder) skip what they need not touch.
            for l in 0..len {
                let (mut fi, mut ti) = (f[l], t[l]);
                for o in &rev_out[rev_start[l]..rev_start[l + 1]] {
                    sub_assign(&mut fi, o.f_i);
                    add_assign(&mut ti, o.torque_j);
                }
                f[l] = fi;
                t[l] = ti;
            }
            for l in 0..len {
                // Near walls in ascending order: bits 0..62, then every wall from 63 on
                // when bit 63 is set.
                let near = near_walls[l];
                if near == 0 {
                    continue;
                }
                let mut bits = near & !(1u64 << 63);
                let mut high = if near >> 63 != 0 { 63 } else { walls.len() };
                loop {
                    let k = if bits != 0 {
                        let k = bits.trailing_zeros() as usize;
                        bits &= bits - 1;
                        k
                    } else if high < walls.len() {
                        high += 1;
                        high - 1
                    } else {
                        break;
                    };
                    let w = &walls[k];
                    let h = l * stride + k;
                    match walls::wall_contact(w, x[l], radius[l]) {
                        Some((delta, r)) => {
                            let g = ContactGeom {
                                delta,
                                r,
                                radi: radius[l],
                                radj: 0.0,
                                is_wall: true,
                                meff: mass[l],
                                vel_i: vb[l],
                                vel_j: wall_vel[k],
                                omega_i: wb[l],
                                omega_j: [0.0; 3],
                            };
                            let c = &coeffs[type_[l] * n_types + w.type_()];
                            let rl = if epsd2 { &mut wroll[h] } else { &mut no_roll };
                            let o =
                                evaluate(&g, c, rolling, dt, &mut wshear[h], rl, update_history);
                            add_assign(&mut f[l], o.f_i);
                            add_assign(&mut t[l], o.torque_i);
                            wout[h] = o.f_i;
                        }
                        None => {
                            wshear[h] = [0.0; 3];
                            if epsd2 {
                                wroll[h] = [0.0; 3];
                            }
                            wout[h] = [0.0; 3];
                        }
                    }
                }
            }
            for l in 0..n_free {
                add_assign(&mut f[l], scale(gravity, mass[l]));
            }
            if let Some((body, vel, ity, cand, ishear, iroll, ion, iepsd2)) = &mut itb {
                for l in 0..len {
                    if !cand[l] {
                        continue;
                    }
                    match body.closest_contact(x[l], radius[l]) {
                        Some((delta, r)) => {
                            let g = ContactGeom {
                                delta,
                                r,
                                radi: radius[l],
                                radj: 0.0,
                                is_wall: true,
                                meff: mass[l],
                                vel_i: vb[l],
                                vel_j: *vel,
                                omega_i: wb[l],
                                omega_j: [0.0; 3],
                            };
                            let c = &coeffs[type_[l] * n_types + *ity];
                            let rl = if *iepsd2 { &mut iroll[l] } else { &mut no_roll };
                            let o =
                                evaluate(&g, c, rolling, dt, &mut ishear[l], rl, update_history);
                            add_assign(&mut f[l], o.f_i);
                            add_assign(&mut t[l], o.torque_i);
                            ion[l] = o.f_i;
                        }
                        None => {
                            ishear[l] = [0.0; 3];
                            if *iepsd2 {
                                iroll[l] = [0.0; 3];
                            }
                            ion[l] = [0.0; 3];
                        }
                    }
                }
            }
            if kick {
                for l in 0..n_free {
                    let [dtfm, dtirotate] = kb[l];
                    add_assign(&mut vb[l], scale(f[l], dtfm));
                    add_assign(&mut wb[l], scale(t[l], dtirotate));
                }
            }
        });
    }

    /// Bytes the engine's state occupies (every per-particle, per-pair and per-wall
    /// array at its allocated capacity, scratch included), for memory per particle.
    pub fn memory_bytes(&self) -> usize {
        fn b<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        let particles = b(&self.id)
            + b(&self.type_)
            + b(&self.radius)
            + b(&self.mass)
            + b(&self.x)
            + b(&self.v)
            + b(&self.omega)
            + b(&self.f)
            + b(&self.torque)
            + b(&self.body)
            + b(&self.near_walls)
            + b(&self.kick)
            + b(&self.case_index);
        let walls = b(&self.wall_shear) + b(&self.wall_roll) + b(&self.wall_out);
        let pairs = b(&self.rev_out) + b(&self.pair_touch) + b(&self.touching);
        let intruder = self.intruder.as_ref().map_or(0, |it| {
            b(&it.shear) + b(&it.roll) + b(&it.on_grain) + b(&it.candidate)
        });
        particles + walls + pairs + intruder + self.pairs.memory_bytes()
    }

    pub fn n_pairs(&self) -> usize {
        self.pairs.len()
    }

    pub fn neighbor_builds(&self) -> u64 {
        self.pairs.builds
    }

    /// Snapshot in output order (sorted by id).
    pub fn frame(&self) -> Frame {
        let mut particles: Vec<ParticleState> = (0..self.x.len())
            .filter(|&k| self.body[k] < 0)
            .map(|k| ParticleState {
                id: self.id[k],
                x: self.x[k],
                v: self.v[k],
                omega: self.omega[k],
                f: self.f[k],
            })
            .collect();
        particles.sort_by_key(|p| p.id);
        let mut bodies: Vec<BodyState> = self
            .bodies
            .iter()
            .map(|b| BodyState {
                id: b.id,
                x: b.xcm,
                q: b.quat,
                v: b.vcm,
                omega: b.omega,
                f: b.fcm,
            })
            .collect();
        bodies.sort_by_key(|b| b.id);
        Frame {
            bodies,
            step: self.step,
            t: self.step as f64 * self.dt,
            particles,
        }
    }

    /// Translational kinetic energy, what LIGGGHTS' `compute ke` reports. Bed
    /// preparation uses it: CDT rolling friction makes resting grains flip their spin
    /// every step (the torque follows the sign of w), a numerical floor in the
    /// rotational energy that no amount of settling removes.
    ///
    /// A clump counts once, with its body mass and centre-of-mass velocity (its members
    /// carry the whole body's mass as contact mass, so summing them would count it once
    /// per member and add the rotation).
    pub(crate) fn translational_kinetic_energy(&self) -> f64 {
        let free: f64 = (0..self.free)
            .map(|k| 0.5 * self.mass[k] * dot(self.v[k], self.v[k]))
            .sum();
        free + self
            .bodies
            .iter()
            .map(|b| 0.5 * b.mass * dot(b.vcm, b.vcm))
            .sum::<f64>()
    }

    /// Grains: free spheres and clump bodies.
    pub fn n_grains(&self) -> usize {
        self.free + self.bodies.len()
    }

    pub(crate) fn kinetic_energy(&self) -> f64 {
        (0..self.x.len())
            .map(|k| {
                let m = self.mass[k];
                let r = self.radius[k];
                0.5 * m * dot(self.v[k], self.v[k])
                    + 0.5 * INERTIA * m * r * r * dot(self.omega[k], self.omega[k])
            })
            .sum()
    }
}

/// Runs a case start to finish, handing every output frame (step 0 included) to
/// `on_frame` as soon as it exists: a long run never holds its trajectory in memory.
pub fn run(
    case: &Case,
    pert: Perturbation,
    mut on_step: impl FnMut(u64),
    mut on_frame: impl FnMut(Frame) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let mut sim = Simulation::from_case_perturbed(case, pert);
    sim.setup()?;
    on_frame(sim.frame())?;
    for _ in 0..case.n_steps {
        sim.step()?;
        if sim.step.is_multiple_of(case.output_every) {
            on_frame(sim.frame())?;
        }
        on_step(sim.step);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 3000 spheres thrown at each other (random velocities and spins, so most pairs
    /// touch within the run), walls on five sides (two of them closing in) and the
    /// intruder driven into them: every state array, the intruder force, every wall's
    /// force and every contact must be bit-identical
    /// for 1, 2 and 3 threads, with CDT and with EPSD2 rolling friction (which carries
    /// per-pair, per-wall and per-intruder rolling history). Then again with 900 of the
    /// spheres replaced by dimer clumps, so the free/member boundary (index 2100) falls
    /// inside a block and the body state joins the comparison.
    #[test]
    fn any_thread_count_gives_identical_bits() {
        for (rolling, with_clumps) in [
            (RollingModel::Cdt, false),
            (RollingModel::Epsd2, false),
            (RollingModel::Cdt, true),
            (RollingModel::Epsd2, true),
        ] {
            let mut case = packing::lattice_case(3000, 11);
            case.rolling = rolling;
            if with_clumps {
                add_dimers(&mut case, 900);
            }
            let mut s = 0x2545_F491_4F6C_DD1Du64;
            let mut rnd = move || {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            };
            for p in &mut case.particles {
                p.v = [3.0 * rnd(), 3.0 * rnd(), 3.0 * rnd()];
                p.omega = [400.0 * rnd(), 400.0 * rnd(), 400.0 * rnd()];
            }
            for c in &mut case.clumps.bodies {
                c.v = [3.0 * rnd(), 3.0 * rnd(), 3.0 * rnd()];
                c.omega = [400.0 * rnd(), 400.0 * rnd(), 400.0 * rnd()];
                c.orientation = rigid::qnormalize([rnd(), rnd(), rnd(), rnd()]);
            }
            let top = case
                .particles
                .iter()
                .map(|p| p.x[2] + p.radius)
                .chain(case.clumps.bodies.iter().map(|c| c.x[2] + 1e-3))
                .fold(0.0, f64::max);
            let centre = 0.5 * case.domain_hi[0];
            case.domain_hi[2] = top + 0.03;
            let run = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| {
                    let mut sim = Simulation::from_case(&case);
                    // Sort every 50 steps (the bed is below the default minimum), so
                    // the renumbering's history transfer runs under every thread count.
                    sim.set_reorder(50, 0);
                    sim.set_intruder(
                        intruder::FlatCylinder::new(4e-3, 0.02, [centre, centre, top + 2e-4]),
                        [0.0, 0.0, -1.0],
                        0,
                    );
                    sim.setup().unwrap();
                    // The x_hi and y_hi walls close in (moving planes): their velocity
                    // enters the contacts, and every wall's force is summed in particle
                    // order.
                    sim.set_wall_velocity(2, -0.5).unwrap();
                    sim.set_wall_velocity(4, -0.3).unwrap();
                    let mut touching = 0;
                    let mut f_int = Vec::new();
                    let mut f_walls = Vec::new();
                    for _ in 0..300 {
                        sim.step().unwrap();
                        touching = touching.max(sim.pair_touch.iter().filter(|&&t| t).count());
                        f_int.push(sim.intruder_force());
                        f_walls.push((0..5).map(|k| sim.wall_force(k)).collect::<Vec<_>>());
                    }
                    assert!(
                        f_walls.last().unwrap()[2] != [0.0; 3],
                        "the moving wall never touched"
                    );
                    assert!(touching > 1000, "too few contacts: {touching}");
                    assert!(f_int.iter().any(|f| f[2] != 0.0), "intruder never touched");
                    assert!(sim.reordered(), "the sort moved nothing");
                    let contacts: Vec<_> = sim
                        .contacts()
                        .into_iter()
                        .map(|c| (c.i, c.other, c.point, c.force_on_i))
                        .collect();
                    if with_clumps {
                        let members = contacts.iter().filter(|c| sim.body[c.0] >= 0).count();
                        // 62 member contacts at the last step when written (CDT).
                        assert!(members > 20, "too few member contacts: {members}");
                    }
                    let bodies: Vec<_> = sim
                        .bodies
                        .iter()
                        .map(|b| (b.xcm, b.vcm, b.quat, b.angmom, b.omega, b.fcm, b.torque))
                        .collect();
                    (
                        (sim.x.clone(), sim.v.clone(), sim.omega.clone()),
                        (sim.f.clone(), sim.torque.clone()),
                        (f_int, f_walls, sim.wall_position(2)),
                        contacts,
                        bodies,
                    )
                })
            };
            let one = run(1);
            for threads in [2, 3] {
                assert!(
                    run(threads) == one,
                    "{rolling:?}, clumps {with_clumps}: {threads} threads differ from 1"
                );
            }
        }
    }

    /// Spatial sorting renumbers the particles but changes nothing else. 3000 spheres
    /// thrown at each other (case order scrambled, CDT and EPSD2, walls, the intruder)
    /// for 100 steps, then rebuilt with and without a sort: the state is the same bit
    /// for bit, and the contact forces (evaluated from the renumbered shear and rolling
    /// history) agree to rounding, listed in the same order. Then 200 more steps sorting
    /// every 20: states and the intruder force stay within rounding and its growth of
    /// the unsorted run.
    #[test]
    fn sorting_changes_only_rounding() {
        for rolling in [RollingModel::Cdt, RollingModel::Epsd2] {
            let mut case = packing::lattice_case(3000, 5);
            case.rolling = rolling;
            let mut s = 0x9E37_79B9_7F4A_7C15u64;
            let mut rnd = move || {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            };
            for p in &mut case.particles {
                p.v = [3.0 * rnd(), 3.0 * rnd(), 3.0 * rnd()];
                p.omega = [400.0 * rnd(), 400.0 * rnd(), 400.0 * rnd()];
            }
            // Scramble the case order, as a pour does, so the sort has work to do.
            let n = case.particles.len();
            for k in (1..n).rev() {
                let j = ((rnd() + 0.5) * (k + 1) as f64) as usize % (k + 1);
                case.particles.swap(k, j);
            }
            let top = case
                .particles
                .iter()
                .map(|p| p.x[2] + p.radius)
                .fold(0.0, f64::max);
            let centre = 0.5 * case.domain_hi[0];
            case.domain_hi[2] = top + 0.03;
            let mut plain = Simulation::from_case(&case);
            plain.set_reorder(0, 0);
            plain.set_intruder(
                intruder::FlatCylinder::new(4e-3, 0.02, [centre, centre, top + 2e-4]),
                [0.0, 0.0, -1.0],
                0,
            );
            plain.setup().unwrap();
            for _ in 0..100 {
                plain.step().unwrap();
            }
            // The same state rebuilt with and without a sort, forces evaluated without
            // advancing history: the renumbered history must give the same forces.
            let mut sorted = plain.clone();
            sorted.set_reorder(20, 0);
            let mut same = plain.clone();
            sorted.rebuild();
            sorted.compute_forces(false, false);
            same.rebuild();
            same.compute_forces(false, false);
            assert!(sorted.reordered() && !same.reordered());
            let state = |sim: &Simulation| {
                let f = sim.frame();
                f.particles
                    .iter()
                    .map(|p| (p.id, p.x, p.v, p.omega))
                    .collect::<Vec<_>>()
            };
            assert!(state(&same) == state(&sorted), "{rolling:?}: state");
            let key = |sim: &Simulation, c: &contacts::ContactRecord| {
                let other = match c.other {
                    contacts::Touching::Grain(j) => sim.id[j],
                    contacts::Touching::Wall(k) => u64::MAX - k as u64,
                    contacts::Touching::Intruder => 0,
                };
                (sim.id[c.i], other)
            };
            let (ca, cb) = (same.contacts(), sorted.contacts());
            assert!(ca.len() > 500, "too few contacts: {}", ca.len());
            assert_eq!(ca.len(), cb.len());
            for (a, b) in ca.iter().zip(&cb) {
                assert_eq!(key(&same, a), key(&sorted, b), "contact order");
                let tol = 1e-9 * norm(a.force_on_i);
                for c in 0..3 {
                    assert!(
                        (a.force_on_i[c] - b.force_on_i[c]).abs() <= tol,
                        "{rolling:?}: contact {:?} force {:?} against {:?}",
                        key(&same, a),
                        b.force_on_i,
                        a.force_on_i
                    );
                }
            }
            let steps = 200;
            let mut sorted = plain.clone();
            sorted.set_reorder(20, 0);
            let builds = plain.neighbor_builds();
            let mut touching = 0;
            for _ in 0..steps {
                plain.step().unwrap();
                sorted.step().unwrap();
                touching += plain.pair_touch.iter().filter(|&&t| t).count();
            }
            let (fa, fb) = (plain.intruder_force(), sorted.intruder_force());
            assert!(sorted.reordered());
            assert!(plain.neighbor_builds() > builds + 2, "too few rebuilds");
            assert!(touching > 500 * steps, "too few contacts: {touching}");
            let (a, b) = (plain.frame(), sorted.frame());
            let mut worst: f64 = 0.0;
            for (p, q) in a.particles.iter().zip(&b.particles) {
                assert_eq!(p.id, q.id);
                for c in 0..3 {
                    worst = worst.max((p.x[c] - q.x[c]).abs() / 1e-3);
                    worst = worst.max((p.v[c] - q.v[c]).abs());
                }
            }
            // Rounding grown over 200 steps of collisions. (A history transfer that
            // forgets to negate a swapped pair fails already at the force check above:
            // forces off by their own size.)
            assert!(worst < 1e-8, "{rolling:?}: sorted run departs by {worst:e}");
            assert!((fa[2] - fb[2]).abs() <= 1e-8 * fa[2].abs().max(1e-12));
        }
    }

    /// Replaces the last `n` spheres of a lattice case by dimers (two overlapping
    /// spheres of 0.45 mm, centres 0.9 mm apart) centred where the spheres were: the
    /// dimer fits inside the sphere it replaces, so the start stays contact-free.
    fn add_dimers(case: &mut Case, n: usize) {
        use crate::case::clumps::{Clump, ClumpTemplate, union_mass_properties};
        let (a, r, rho) = (0.45e-3, 0.45e-3, 2500.0);
        let (volume, mass, inertia, _) = union_mass_properties(&[-a, a], &[r, r], rho);
        case.clumps.templates = vec![ClumpTemplate {
            name: "dimer".into(),
            type_: 0,
            density: rho,
            offsets: vec![[-a, 0.0, 0.0], [a, 0.0, 0.0]],
            radii: vec![r, r],
            volume,
            mass,
            inertia,
            bounding_radius: a + r,
        }];
        let keep = case.particles.len() - n;
        let next_id = case.particles.len() as u64 + 1;
        case.clumps.bodies = case.particles[keep..]
            .iter()
            .enumerate()
            .map(|(k, p)| Clump {
                id: next_id + k as u64,
                template: 0,
                x: p.x,
                orientation: [1.0, 0.0, 0.0, 0.0],
                v: [0.0; 3],
                omega: [0.0; 3],
            })
            .collect();
        case.particles.truncate(keep);
    }
}
