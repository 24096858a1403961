//! The native engine for micro cases of the LAMMPS family: spheres, plane walls and
//! gravity stepped the way LAMMPS 22 Jul 2025 steps the deck
//! [`crate::engines::lammps3d`] writes (`fix nve/sphere`, `pair_style granular`,
//! `fix gravity`, `fix wall/gran granular`), with the contact law of
//! [`super::lammps_granular`].
//!
//! A micro case has a handful of grains, so this is a plain scalar loop rather than the
//! LIGGGHTS-family engine's SIMD pair pass; what matters here is LAMMPS' order of
//! operations:
//! - `Verlet::setup`: forces without advancing history (`update->setupflag`), pair
//!   first, then the fixes' `post_force` in deck order (gravity, then walls).
//! - a step: `FixNVESphere::initial_integrate` (v, x, omega with I = 0.4 m r^2), forces
//!   (pair, gravity, walls), `final_integrate`.
//! - pair forces in neighbour-list order: for i ascending, each j > i; `f[i] += F`,
//!   `f[j] -= F` (`newton off`, one process). LAMMPS orders j by bin; with two grains, or
//!   grains in one bin, that is ascending index too; otherwise the per-particle force
//!   sums may differ in the last bit.
//! - history is cleared whenever a neighbour pair (or a particle and a wall) does not
//!   touch (`PairGranular::compute`, `FixWallGran::post_force`), not at neighbour-list
//!   rebuilds as in LIGGGHTS.
//! - gravity is `fix gravity g vector gx gy gz` with g = |(gx, gy, gz)|: the
//!   acceleration is g (gx / |..|), as `FixGravity::set_acceleration` computes it.

use super::lammps_granular::{Coeffs, Contact, History, calculate_forces, check_contact};
use crate::case::{Case, LammpsModels, Perturbation, Wall};
use crate::rundata::frames::{Frame, ParticleState};
use anyhow::{Result, bail};

type V3 = [f64; 3];

/// `INERTIA` of fix_nve_sphere.cpp (solid sphere).
const INERTIA: f64 = 0.4;

/// The coefficients the deck gives LAMMPS, as LAMMPS sets them up: one per type pair
/// (`pair_coeff i j`, E and nu mixed by LAMMPS' rule) and one per wall (`fix
/// wall/gran`: the wall's material, the interaction of the particles' type with it).
pub(crate) struct LammpsCoeffs {
    pub n_types: usize,
    pub pair: Vec<Coeffs>,
    pub wall: Vec<Coeffs>,
}

/// The `hertz/material` E, e, nu and the `tangential` xt, mu and `rolling sds`
/// coefficients of type pair (a, b) (0-based), or of a wall (`wall`): what the deck
/// prints and what [`LammpsCoeffs`] is built from.
pub(crate) struct LawValues {
    pub e_mod: f64,
    pub restitution: f64,
    pub nu: f64,
    pub xt: f64,
    pub mu: f64,
    pub rolling: Option<(f64, f64, f64)>,
}

/// The values of type pair (a, b) or, with `wall = Some(w)`, of wall `w` touched by type
/// `a`, under the negative-control perturbation `pert`.
pub(crate) fn law_values(
    case: &Case,
    m: &LammpsModels,
    a: usize,
    b: usize,
    wall: bool,
    pert: &Perturbation,
) -> LawValues {
    let (ma, mb) = (&case.materials[a], &case.materials[b]);
    let nu_a = ma.poisson_ratio + pert.poisson_shift;
    let nu_b = mb.poisson_ratio + pert.poisson_shift;
    let (e_mod, nu) = if wall {
        // fix wall/gran: the wall's material (type b) for every particle
        (mb.youngs_modulus, nu_b)
    } else {
        super::lammps_granular::mixed_material(ma.youngs_modulus, nu_a, mb.youngs_modulus, nu_b)
    };
    let k = case.pairs.idx(a, b);
    let mu = match pert.pair_friction {
        Some((i, j, mu)) if (i, j) == (a, b) || (j, i) == (a, b) => mu,
        _ => case.pairs.friction[k] * pert.friction_factor,
    };
    let rolling = match m.rolling {
        crate::case::LammpsRolling::None => None,
        crate::case::LammpsRolling::Sds => Some((
            m.rolling_stiffness[k],
            m.rolling_damping[k],
            case.pairs.rolling_friction[k] * pert.rolling_friction_factor,
        )),
    };
    LawValues {
        e_mod,
        restitution: (case.pairs.restitution[k] + pert.restitution_shift).min(1.0),
        nu,
        xt: m.tangential_damping,
        mu,
        rolling,
    }
}

impl LawValues {
    pub fn coeffs(&self, wall: bool) -> Coeffs {
        Coeffs::new(
            self.e_mod,
            self.restitution,
            self.nu,
            self.xt,
            self.mu,
            self.rolling,
            wall,
        )
    }
}

/// The one particle type that touches walls (the case validation requires a single
/// particle type when there are walls).
pub(crate) fn wall_particle_type(case: &Case) -> usize {
    case.particles.first().map(|p| p.type_).unwrap_or(0)
}

impl LammpsCoeffs {
    pub fn new(case: &Case, m: &LammpsModels, pert: &Perturbation) -> LammpsCoeffs {
        let n = case.n_types();
        let mut pair = Vec::with_capacity(n * n);
        for a in 0..n {
            for b in 0..n {
                pair.push(law_values(case, m, a.min(b), a.max(b), false, pert).coeffs(false));
            }
        }
        let pt = wall_particle_type(case);
        let wall = case
            .walls
            .iter()
            .map(|w| law_values(case, m, pt, w.type_(), true, pert).coeffs(true))
            .collect();
        LammpsCoeffs {
            n_types: n,
            pair,
            wall,
        }
    }
}

struct State {
    id: Vec<u64>,
    type_: Vec<usize>,
    radius: Vec<f64>,
    rmass: Vec<f64>,
    x: Vec<V3>,
    v: Vec<V3>,
    omega: Vec<V3>,
    f: Vec<V3>,
    torque: Vec<V3>,
    /// History of pair (i, j > i) at `i * n + j`.
    pair_hist: Vec<History>,
    /// History of particle i and wall w at `i * n_walls + w`.
    wall_hist: Vec<History>,
}

/// Runs a LAMMPS-family micro case: `on_frame` gets step 0 and every `output_every`-th
/// step (particles sorted by id), `on_step` every step.
pub fn run(
    case: &Case,
    pert: Perturbation,
    mut on_step: impl FnMut(u64),
    mut on_frame: impl FnMut(Frame) -> Result<()>,
) -> Result<()> {
    let Some(m) = case.lammps() else {
        bail!(
            "{}: not a LAMMPS-family case (models.family)",
            case.source.display()
        );
    };
    let coeffs = LammpsCoeffs::new(case, m, &pert);
    let n = case.particles.len();
    let nw = case.walls.len();
    let mut s = State {
        id: case.particles.iter().map(|p| p.id).collect(),
        type_: case.particles.iter().map(|p| p.type_).collect(),
        radius: case.particles.iter().map(|p| p.radius).collect(),
        // AtomVecSphere::data_atom_post: rmass = density * 4 pi / 3 r^3
        rmass: case.particles.iter().map(|p| p.mass()).collect(),
        x: case.particles.iter().map(|p| p.x).collect(),
        v: case.particles.iter().map(|p| p.v).collect(),
        omega: case.particles.iter().map(|p| p.omega).collect(),
        f: vec![[0.0; 3]; n],
        torque: vec![[0.0; 3]; n],
        pair_hist: vec![[0.0; 6]; n * n],
        wall_hist: vec![[0.0; 6]; n * nw],
    };
    let gacc = gravity_acceleration(case.gravity);
    let dt = case.dt;
    forces(&mut s, case, &coeffs, gacc, dt, false);
    on_frame(frame(&s, 0, dt))?;
    // FixNVESphere::init: dtv = dt, dtf = 0.5 dt ftm2v (ftm2v = 1 in SI units)
    let dtv = dt;
    let dtf = 0.5 * dt;
    for step in 1..=case.n_steps {
        let dtfrotate = dtf / INERTIA;
        for i in 0..n {
            let dtfm = dtf / s.rmass[i];
            for c in 0..3 {
                s.v[i][c] += dtfm * s.f[i][c];
            }
            for c in 0..3 {
                s.x[i][c] += dtv * s.v[i][c];
            }
            let dtirotate = dtfrotate / (s.radius[i] * s.radius[i] * s.rmass[i]);
            for c in 0..3 {
                s.omega[i][c] += dtirotate * s.torque[i][c];
            }
        }
        check_state(&s, case, step)?;
        forces(&mut s, case, &coeffs, gacc, dt, true);
        for i in 0..n {
            let dtfm = dtf / s.rmass[i];
            for c in 0..3 {
                s.v[i][c] += dtfm * s.f[i][c];
            }
            let dtirotate = dtfrotate / (s.radius[i] * s.radius[i] * s.rmass[i]);
            for c in 0..3 {
                s.omega[i][c] += dtirotate * s.torque[i][c];
            }
        }
        if step.is_multiple_of(case.output_every) {
            on_frame(frame(&s, step, dt))?;
        }
        on_step(step);
    }
    Ok(())
}

/// `FixGravity::set_acceleration` (VECTOR style, 3D): magnitude times the unit
/// direction, with the magnitude the deck writes (|g|).
pub(crate) fn gravity_acceleration(g: V3) -> V3 {
    let magnitude = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    if magnitude == 0.0 {
        return [0.0; 3];
    }
    let length = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    [
        magnitude * (g[0] / length),
        magnitude * (g[1] / length),
        magnitude * (g[2] / length),
    ]
}

/// A particle that left the box or became non-finite ends the run (LAMMPS: `thermo_modify
/// lost error` with `boundary f f f`).
fn check_state(s: &State, case: &Case, step: u64) -> Result<()> {
    check_lost(
        &s.id,
        [&s.x, &s.v, &s.omega],
        (case.domain_lo, case.domain_hi),
        ("particle", "domain"),
        step,
    )
}

/// `thermo_modify lost error` in a closed box `(lo, hi)`: the first of the atoms `id`
/// (positions, velocities, angular velocities in `xvw`) that is non-finite or outside
/// the box ends the run, named as `(atom, box)` (the micro cases' particles and domain,
/// the penetration bed's grains and box).
pub(crate) fn check_lost(
    id: &[u64],
    [x, v, w]: [&[V3]; 3],
    (lo, hi): (V3, V3),
    (what, region): (&str, &str),
    step: u64,
) -> Result<()> {
    for (i, xi) in x.iter().enumerate() {
        if !xi.iter().chain(&v[i]).chain(&w[i]).all(|c| c.is_finite()) {
            bail!("{what} {} is no longer finite at step {step}", id[i]);
        }
        if (0..3).any(|c| xi[c] < lo[c] || xi[c] > hi[c]) {
            bail!("{what} {} left the {region} at step {step}", id[i]);
        }
    }
    Ok(())
}

fn forces(s: &mut State, case: &Case, k: &LammpsCoeffs, gacc: V3, dt: f64, history_update: bool) {
    let n = s.x.len();
    s.f.iter_mut().for_each(|f| *f = [0.0; 3]);
    s.torque.iter_mut().for_each(|t| *t = [0.0; 3]);
    // PairGranular::compute
    for i in 0..n {
        for j in i + 1..n {
            let mi = s.rmass[i];
            let mj = s.rmass[j];
            let c = Contact {
                dx: [
                    s.x[i][0] - s.x[j][0],
                    s.x[i][1] - s.x[j][1],
                    s.x[i][2] - s.x[j][2],
                ],
                radi: s.radius[i],
                radj: s.radius[j],
                wall: false,
                meff: mi * mj / (mi + mj),
                vi: s.v[i],
                vj: s.v[j],
                omegai: s.omega[i],
                omegaj: s.omega[j],
            };
            let h = &mut s.pair_hist[i * n + j];
            if !check_contact(&c).0 {
                *h = [0.0; 6];
                continue;
            }
            let o = calculate_forces(
                &c,
                &k.pair[s.type_[i] * k.n_types + s.type_[j]],
                dt,
                h,
                history_update,
            );
            for a in 0..3 {
                s.f[i][a] += o.forces[a];
                s.torque[i][a] += o.torquesi[a];
                s.f[j][a] -= o.forces[a];
                s.torque[j][a] += o.torquesj[a];
            }
        }
    }
    // FixGravity::post_force
    if gacc != [0.0; 3] {
        for i in 0..n {
            let massone = s.rmass[i];
            for (f, acc) in s.f[i].iter_mut().zip(gacc) {
                *f += massone * acc;
            }
        }
    }
    // FixWallGran::post_force, one fix per wall in deck order
    let nw = case.walls.len();
    for (w, wall) in case.walls.iter().enumerate() {
        let Wall::Plane { axis, position, .. } = wall else {
            unreachable!("the LAMMPS family has plane walls only (case validation)");
        };
        let ax = axis.index();
        for i in 0..n {
            // `{x,y,z}plane lo NULL`: del1 = x - lo is below del2 = BIG - x
            let mut dx = [0.0; 3];
            dx[ax] = s.x[i][ax] - position;
            let c = Contact {
                dx,
                radi: s.radius[i],
                radj: 0.0,
                wall: true,
                meff: s.rmass[i],
                vi: s.v[i],
                vj: [0.0; 3],
                omegai: s.omega[i],
                omegaj: [0.0; 3],
            };
            let h = &mut s.wall_hist[i * nw + w];
            if !check_contact(&c).0 {
                *h = [0.0; 6];
                continue;
            }
            let o = calculate_forces(&c, &k.wall[w], dt, h, history_update);
            for a in 0..3 {
                s.f[i][a] += o.forces[a];
                s.torque[i][a] += o.torquesi[a];
            }
        }
    }
}

fn frame(s: &State, step: u64, dt: f64) -> Frame {
    let mut particles: Vec<ParticleState> = (0..s.x.len())
        .map(|i| ParticleState {
            id: s.id[i],
            x: s.x[i],
            v: s.v[i],
            omega: s.omega[i],
            f: s.f[i],
        })
        .collect();
    particles.sort_by_key(|p| p.id);
    Frame {
        step,
        t: step as f64 * dt,
        particles,
        bodies: Vec::new(),
    }
}
