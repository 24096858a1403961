//! The native 3D DEM: Hertz-Mindlin spheres with tangential history, CDT/EPSD2 rolling
//! friction and primitive walls, integrated like LIGGGHTS `nve/sphere`.
//!
//! Layout is structure-of-arrays; the force pass runs over pairs in parallel and then
//! gathers per particle in a fixed order, so results are bit-identical for any number
//! of threads (and for a given case, run to run).

pub mod contact;
pub mod contacts;
pub mod intruder;
pub mod neighbor;
mod overlap;
pub mod packing;
pub mod penetration;
pub mod walls;

use crate::case::{Case, Perturbation, RollingModel, Wall};
use crate::numerics::vec3::*;
use crate::rundata::frames::{Frame, ParticleState};
use contact::{ContactForce, ContactGeom, History, PairCoeffs, hertz_history};
use neighbor::PairList;
use rayon::prelude::*;
use std::time::Instant;

/// Moment-of-inertia factor of a solid sphere, LIGGGHTS' `INERTIA` in fix_nve_sphere.
const INERTIA: f64 = 0.4;

/// Pairs below this count are handled by one thread: spawning costs more than it saves.
const PAR_MIN_LEN: usize = 2048;

/// Largest initial overlap accepted, as a fraction of the smaller radius.
pub const MAX_INITIAL_OVERLAP: f64 = 0.05;

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
    n_types: usize,
    coeffs: Vec<PairCoeffs>,
    rolling: RollingModel,
    walls: Vec<Wall>,
    /// Wall contact history, `walls_stride` entries per particle.
    wall_hist: Vec<History>,
    walls_stride: usize,
    pairs: PairList,
    pair_out: Vec<ContactForce>,
    /// Force each wall exerted on each particle in the last force pass (`walls_stride`
    /// per particle; zero when not touching), kept so [`Simulation::contacts`] reports
    /// exactly the forces that were integrated, not a re-evaluation.
    wall_out: Vec<V3>,
    /// Whether each pair touched this step; the gather reads `pair_out` only where set,
    /// so non-touching pairs cost one byte of memory traffic instead of a whole result.
    pair_touch: Vec<bool>,
    /// Bit k set: particle was within its radius + skin of wall k at the last rebuild,
    /// so it may touch it before the next one (the role of LIGGGHTS' primitive-wall
    /// neighbour lists). Walls beyond 64 are always checked.
    near_walls: Vec<u64>,
    intruder: Option<MovingIntruder>,
    gravity: V3,
    pub dt: f64,
    skin: f64,
    lo: V3,
    hi: V3,
    pub step: u64,
    times: StepTimes,
}

/// Wall time (s) spent in each phase of [`Simulation::step`] since the simulation was
/// made (or [`Simulation::reset_step_times`]), for profiling: a handful of clock reads per
/// step, negligible against the step itself.
#[derive(Debug, Clone, Copy, Default)]
pub struct StepTimes {
    /// Both half kicks and the drift.
    pub integrate: f64,
    /// Finite-state and domain checks, the skin/2 displacement check.
    pub checks: f64,
    /// Neighbour-list builds (cells, pairs, history merge, wall masks).
    pub neighbor: f64,
    /// The pair pass (contact law of every neighbour pair).
    pub pairs: f64,
    /// Per-particle gather of the pair results, primitive walls, gravity.
    pub gather_walls: f64,
    /// The moving intruder's contacts.
    pub intruder: f64,
    pub steps: u64,
}

impl StepTimes {
    pub fn total(&self) -> f64 {
        self.integrate
            + self.checks
            + self.neighbor
            + self.pairs
            + self.gather_walls
            + self.intruder
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
    hist: Vec<History>,
    /// Force each grain receives from the intruder this step (zero if not touching).
    on_grain: Vec<V3>,
}

impl Simulation {
    /// Adds the moving intruder; `type_` is its 0-based material type.
    pub fn set_intruder(&mut self, body: intruder::FlatCylinder, velocity: V3, type_: usize) {
        let n = self.x.len();
        self.intruder = Some(MovingIntruder {
            body,
            velocity,
            type_,
            hist: vec![History::default(); n],
            on_grain: vec![[0.0; 3]; n],
        });
    }

    pub fn intruder(&self) -> Option<&MovingIntruder> {
        self.intruder.as_ref()
    }

    /// Total force the grains exert on the intruder (N).
    pub fn intruder_force(&self) -> V3 {
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
                    case.pairs.rolling_friction[k],
                ));
            }
        }
        let n = case.particles.len();
        let stride = case.walls.len().max(1);
        Simulation {
            id: case.particles.iter().map(|p| p.id).collect(),
            type_: case.particles.iter().map(|p| p.type_).collect(),
            radius: case.particles.iter().map(|p| p.radius).collect(),
            mass: case.particles.iter().map(|p| p.mass()).collect(),
            x: case.particles.iter().map(|p| p.x).collect(),
            v: case.particles.iter().map(|p| p.v).collect(),
            omega: case.particles.iter().map(|p| p.omega).collect(),
            f: vec![[0.0; 3]; n],
            torque: vec![[0.0; 3]; n],
            n_types,
            coeffs,
            rolling: case.rolling,
            walls: case.walls.clone(),
            wall_hist: vec![History::default(); n * stride],
            walls_stride: stride,
            pairs: PairList::default(),
            pair_out: Vec::new(),
            wall_out: vec![[0.0; 3]; n * stride],
            pair_touch: Vec::new(),
            near_walls: vec![u64::MAX; n],
            intruder: None,
            gravity: case.gravity,
            dt: case.dt,
            skin: case.neighbor_skin,
            lo: case.domain_lo,
            hi: case.domain_hi,
            step: 0,
            times: StepTimes::default(),
        }
    }

    /// Builds the neighbour list and evaluates forces without advancing history, as
    /// LIGGGHTS' `Verlet::setup` does before step 1 (and before the step-0 dump).
    pub fn setup(&mut self) -> anyhow::Result<()> {
        self.check_domain()?;
        self.check_initial_overlaps()?;
        self.rebuild();
        self.compute_forces(false);
        Ok(())
    }

    /// [`Simulation::setup`] for a state the DEM itself settled (a prepared bed, native or
    /// LIGGGHTS): its overlaps are the equilibrium of its own contact law (a soft G = 1 MPa
    /// bed carries up to ~5 % of a radius at the bottom), not input errors, so the
    /// initial-overlap refusal is skipped; the domain and finiteness checks remain.
    pub fn setup_settled(&mut self) -> anyhow::Result<()> {
        self.check_domain()?;
        self.rebuild();
        self.compute_forces(false);
        Ok(())
    }

    /// One velocity-Verlet step in `nve/sphere` order: half kick + drift, re-neighbour
    /// if needed, forces, half kick.
    pub fn step(&mut self) -> anyhow::Result<()> {
        let t0 = Instant::now();
        self.kick_drift();
        self.step += 1;
        if let Some(it) = &mut self.intruder {
            it.body.translate(it.velocity[2] * self.dt);
        }
        let t1 = Instant::now();
        self.check_domain()?;
        let rebuild = self.pairs.needs_rebuild(&self.x, self.skin);
        let t2 = Instant::now();
        if rebuild {
            self.rebuild();
        }
        let t3 = Instant::now();
        self.compute_forces(true);
        let t4 = Instant::now();
        self.kick();
        let t5 = Instant::now();
        let tm = &mut self.times;
        tm.integrate += (t1 - t0).as_secs_f64() + (t5 - t4).as_secs_f64();
        tm.checks += (t2 - t1).as_secs_f64();
        tm.neighbor += (t3 - t2).as_secs_f64();
        tm.steps += 1;
        Ok(())
    }

    /// First half kick and drift of `nve/sphere`.
    #[inline(never)]
    fn kick_drift(&mut self) {
        let dt = self.dt;
        let dtf = 0.5 * dt;
        (&mut self.x, &mut self.v, &mut self.omega)
            .into_par_iter()
            .zip((&self.f, &self.torque, &self.mass, &self.radius).into_par_iter())
            .with_min_len(PAR_MIN_LEN)
            .for_each(|((x, v, w), (f, t, m, r))| {
                let dtfm = dtf / m;
                add_assign(v, scale(*f, dtfm));
                add_assign(x, scale(*v, dt));
                let dtirotate = dtf / INERTIA / (r * r * m);
                add_assign(w, scale(*t, dtirotate));
            });
    }

    /// Second half kick of `nve/sphere`.
    #[inline(never)]
    fn kick(&mut self) {
        let dtf = 0.5 * self.dt;
        (&mut self.v, &mut self.omega)
            .into_par_iter()
            .zip((&self.f, &self.torque, &self.mass, &self.radius).into_par_iter())
            .with_min_len(PAR_MIN_LEN)
            .for_each(|((v, w), (f, t, m, r))| {
                let dtfm = dtf / m;
                add_assign(v, scale(*f, dtfm));
                let dtirotate = dtf / INERTIA / (r * r * m);
                add_assign(w, scale(*t, dtirotate));
            });
    }

    /// Wall time per phase of [`Simulation::step`] so far (see [`StepTimes`]).
    pub fn step_times(&self) -> StepTimes {
        self.times
    }

    pub fn reset_step_times(&mut self) {
        self.times = StepTimes::default();
    }

    fn rebuild(&mut self) {
        self.pairs
            .build(&self.x, &self.radius, self.skin, self.lo, self.hi);
        let (walls, skin) = (&self.walls, self.skin);
        (&mut self.near_walls, &self.x, &self.radius)
            .into_par_iter()
            .with_min_len(PAR_MIN_LEN)
            .for_each(|(mask, x, r)| {
                *mask = 0;
                for (k, w) in walls.iter().enumerate() {
                    if k >= 64 || walls::wall_contact(w, *x, r + skin).is_some() {
                        *mask |= 1u64 << k.min(63);
                    }
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
    fn check_initial_overlaps(&self) -> anyhow::Result<()> {
        if let Some((i, j, overlap)) =
            overlap::first_overlap(&self.x, &self.radius, MAX_INITIAL_OVERLAP)
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
        if let Some(k) = (0..self.x.len()).find(|&k| {
            !(self.x[k].iter().chain(&self.v[k]).chain(&self.omega[k])).all(|c| c.is_finite())
        }) {
            anyhow::bail!(
                "particle id {} has a non-finite state at step {} (x = {:?}, v = {:?}): the integration blew up; likely causes are a time step too large for the contact stiffness or grains started deep inside each other",
                self.id[k],
                self.step,
                self.x[k],
                self.v[k]
            );
        }
        if let Some(k) = self
            .x
            .iter()
            .position(|p| (0..3).any(|c| !(p[c] >= self.lo[c] && p[c] <= self.hi[c])))
        {
            anyhow::bail!(
                "particle id {} left the domain box at step {} (x = {:?})",
                self.id[k],
                self.step,
                self.x[k]
            );
        }
        Ok(())
    }

    fn compute_forces(&mut self, update_history: bool) {
        let t0 = Instant::now();
        self.pair_pass(update_history);
        let t1 = Instant::now();
        self.gather_pass(update_history);
        let t2 = Instant::now();
        self.intruder_pass(update_history);
        let t3 = Instant::now();
        let tm = &mut self.times;
        tm.pairs += (t1 - t0).as_secs_f64();
        tm.gather_walls += (t2 - t1).as_secs_f64();
        tm.intruder += (t3 - t2).as_secs_f64();
    }

    /// Pass 1: every neighbour pair independently.
    #[inline(never)]
    fn pair_pass(&mut self, update_history: bool) {
        let dt = self.dt;
        let (x, v, omega, radius, mass, type_) = (
            &self.x,
            &self.v,
            &self.omega,
            &self.radius,
            &self.mass,
            &self.type_,
        );
        let (coeffs, n_types, rolling) = (&self.coeffs, self.n_types, self.rolling);
        let np = self.pairs.len();
        self.pair_out.resize(np, ContactForce::default());
        self.pair_touch.resize(np, false);
        (
            &self.pairs.i,
            &self.pairs.j,
            &mut self.pairs.hist,
            &mut self.pair_out,
            &mut self.pair_touch,
        )
            .into_par_iter()
            .with_min_len(PAR_MIN_LEN)
            .for_each(|(&i, &j, hist, out, touch)| {
                let (i, j) = (i as usize, j as usize);
                let delta = sub(x[i], x[j]);
                let rsq = dot(delta, delta);
                let radsum = radius[i] + radius[j];
                if rsq < radsum * radsum {
                    let (mi, mj) = (mass[i], mass[j]);
                    let g = ContactGeom {
                        delta,
                        r: rsq.sqrt(),
                        radi: radius[i],
                        radj: radius[j],
                        is_wall: false,
                        meff: mi * mj / (mi + mj),
                        vel_i: v[i],
                        vel_j: v[j],
                        omega_i: omega[i],
                        omega_j: omega[j],
                    };
                    let c = &coeffs[type_[i] * n_types + type_[j]];
                    *out = hertz_history(&g, c, rolling, dt, hist, update_history);
                    *touch = true;
                } else {
                    // History is NOT cleared here: LIGGGHTS 3.8 keeps a separated pair's
                    // shear until the next neighbour rebuild (see neighbor.rs).
                    *touch = false;
                }
            });
    }

    /// Pass 2: per particle, gather pair results in a fixed order, then walls, gravity.
    #[inline(never)]
    fn gather_pass(&mut self, update_history: bool) {
        let dt = self.dt;
        let (x, v, omega, radius, mass, type_) = (
            &self.x,
            &self.v,
            &self.omega,
            &self.radius,
            &self.mass,
            &self.type_,
        );
        let (coeffs, n_types, rolling) = (&self.coeffs, self.n_types, self.rolling);
        let pairs = &self.pairs;
        let (pair_out, pair_touch) = (&self.pair_out, &self.pair_touch);
        let (walls, gravity) = (&self.walls, self.gravity);
        (
            &mut self.f,
            &mut self.torque,
            self.wall_hist.par_chunks_mut(self.walls_stride),
            self.wall_out.par_chunks_mut(self.walls_stride),
            &self.near_walls,
        )
            .into_par_iter()
            .enumerate()
            .with_min_len(PAR_MIN_LEN)
            .for_each(|(i, (f, t, whist, wout, &near))| {
                let mut fi = [0.0; 3];
                let mut ti = [0.0; 3];
                for k in pairs.start[i]..pairs.start[i + 1] {
                    if pair_touch[k] {
                        add_assign(&mut fi, pair_out[k].f_i);
                        add_assign(&mut ti, pair_out[k].torque_i);
                    }
                }
                for &k in &pairs.rev_pair[pairs.rev_start[i]..pairs.rev_start[i + 1]] {
                    if pair_touch[k as usize] {
                        let o = &pair_out[k as usize];
                        sub_assign(&mut fi, o.f_i);
                        add_assign(&mut ti, o.torque_j);
                    }
                }
                for (k, ((w, hist), wo)) in walls
                    .iter()
                    .zip(whist.iter_mut())
                    .zip(wout.iter_mut())
                    .enumerate()
                {
                    *wo = [0.0; 3];
                    if near & (1u64 << k.min(63)) == 0 {
                        continue;
                    }
                    match walls::wall_contact(w, x[i], radius[i]) {
                        Some((delta, r)) => {
                            let g = ContactGeom {
                                delta,
                                r,
                                radi: radius[i],
                                radj: 0.0,
                                is_wall: true,
                                meff: mass[i],
                                vel_i: v[i],
                                vel_j: [0.0; 3],
                                omega_i: omega[i],
                                omega_j: [0.0; 3],
                            };
                            let c = &coeffs[type_[i] * n_types + w.type_()];
                            let o = hertz_history(&g, c, rolling, dt, hist, update_history);
                            add_assign(&mut fi, o.f_i);
                            add_assign(&mut ti, o.torque_i);
                            *wo = o.f_i;
                        }
                        None => *hist = History::default(),
                    }
                }
                add_assign(&mut fi, scale(gravity, mass[i]));
                *f = fi;
                *t = ti;
            });
    }

    /// Pass 3: the moving intruder, a wall with velocity (grain-intruder law).
    #[inline(never)]
    fn intruder_pass(&mut self, update_history: bool) {
        let dt = self.dt;
        let (x, v, omega, radius, mass, type_) = (
            &self.x,
            &self.v,
            &self.omega,
            &self.radius,
            &self.mass,
            &self.type_,
        );
        let (coeffs, n_types, rolling) = (&self.coeffs, self.n_types, self.rolling);
        if let Some(it) = &mut self.intruder {
            let (body, vel, ity) = (&it.body, it.velocity, it.type_);
            (
                &mut self.f,
                &mut self.torque,
                &mut it.hist,
                &mut it.on_grain,
            )
                .into_par_iter()
                .enumerate()
                .with_min_len(PAR_MIN_LEN)
                .for_each(|(i, (f, t, hist, on))| {
                    match body.closest_contact(x[i], radius[i]) {
                        Some((delta, r)) => {
                            let g = ContactGeom {
                                delta,
                                r,
                                radi: radius[i],
                                radj: 0.0,
                                is_wall: true,
                                meff: mass[i],
                                vel_i: v[i],
                                vel_j: vel,
                                omega_i: omega[i],
                                omega_j: [0.0; 3],
                            };
                            let c = &coeffs[type_[i] * n_types + ity];
                            let o = hertz_history(&g, c, rolling, dt, hist, update_history);
                            add_assign(f, o.f_i);
                            add_assign(t, o.torque_i);
                            *on = o.f_i;
                        }
                        None => {
                            *hist = History::default();
                            *on = [0.0; 3];
                        }
                    }
                });
        }
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
            .map(|k| ParticleState {
                id: self.id[k],
                x: self.x[k],
                v: self.v[k],
                omega: self.omega[k],
                f: self.f[k],
            })
            .collect();
        particles.sort_by_key(|p| p.id);
        Frame {
            step: self.step,
            t: self.step as f64 * self.dt,
            particles,
        }
    }

    /// Translational kinetic energy, what LIGGGHTS' `compute ke` reports. Bed
    /// preparation uses it: CDT rolling friction makes resting grains flip their spin
    /// every step (the torque follows the sign of w), a numerical floor in the
    /// rotational energy that no amount of settling removes.
    pub fn translational_kinetic_energy(&self) -> f64 {
        (0..self.x.len())
            .map(|k| 0.5 * self.mass[k] * dot(self.v[k], self.v[k]))
            .sum()
    }

    pub fn kinetic_energy(&self) -> f64 {
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
