//! The triaxial test of docs/stress.md rule 5 in the native engine: a cuboid of six
//! plane walls (x_lo, y_lo, z_lo at 0; x_hi, y_hi, z_hi moving), a jittered cubic
//! lattice compacted isotropically by three stress servos (LIGGGHTS' mesh module servo,
//! [`super::servo`]), then axisymmetric compression: z_hi down at eps_dot H0, x_hi and
//! y_hi holding the confining pressure.
//!
//! Wall `k` of the box: 0 x_lo, 1 y_lo, 2 z_lo, 3 x_hi, 4 y_hi, 5 z_hi. A servo wall's
//! target force is sigma_c times its current face area, the product of the two other hi
//! walls' positions (the lo walls are at 0), evaluated after the step's wall moves, as
//! LIGGGHTS evaluates its equal-style target in `final_integrate`.

use super::Simulation;
use super::servo::Servo;
use crate::case::triaxial::TriaxialCase;
use crate::case::{Axis, Case, Particle, Perturbation, Tolerances, Wall};
use crate::rundata::triaxial::WallRecord;
use anyhow::{Result, bail};
use rand::{Rng, SeedableRng};

/// Index of the hi wall along axis `i` (0 x, 1 y, 2 z); the lo wall is `i`.
pub(crate) const fn hi_wall(i: usize) -> usize {
    3 + i
}

/// A compacted sample, ready for the shear in either engine.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Sample {
    pub seed: u64,
    /// Confining pressure it was compacted to (Pa).
    pub sigma_c: f64,
    /// Positions, velocities and spins at the end of the compaction.
    pub particles: Vec<Particle>,
    /// Positions of x_hi, y_hi, z_hi where the compaction left them.
    pub hi: [f64; 3],
    /// Side of the cubic box of the starting lattice (the simulation domain follows it).
    pub lattice_side: f64,
    /// Solid fraction: grain volume / box volume.
    pub psi: f64,
    pub compaction_time: f64,
    /// Translational kinetic energy / (sigma_c V) at the end.
    pub ke_ratio: f64,
    /// Wall stresses x, y, z / sigma_c at the end.
    pub stress_ratio: [f64; 3],
}

impl Sample {
    pub fn note(&self) -> String {
        format!(
            "sample seed {} at {} Pa: {} grains compacted in {:.3} s, psi = {:.4}, box {:.4} x {:.4} x {:.4} mm, wall stresses / sigma_c = {:.4} / {:.4} / {:.4}, KE / (sigma_c V) = {:.2e}",
            self.seed,
            self.sigma_c,
            self.particles.len(),
            self.compaction_time,
            self.psi,
            1e3 * self.hi[0],
            1e3 * self.hi[1],
            1e3 * self.hi[2],
            self.stress_ratio[0],
            self.stress_ratio[1],
            self.stress_ratio[2],
            self.ke_ratio
        )
    }
}

/// The square (centre, half side) in every wall's plane that the LIGGGHTS wall meshes
/// must cover: the starting cube of side `side` and 1.5 grain diameters beyond.
pub(crate) fn mesh_square(case: &TriaxialCase, side: f64) -> (f64, f64) {
    (0.5 * side, 0.5 * side + 1.5 * case.diameter)
}

/// Circumradius of the one triangle that makes a LIGGGHTS wall: an equilateral triangle
/// centred on the square of [`mesh_square`] whose inscribed circle (radius R / 2)
/// contains the square, so its edges stay a quarter of the square's side away from
/// any grain (a two-triangle rectangle has a diagonal across the face, where LIGGGHTS
/// 3.8 counted one grain's contact twice for a step in a test: measured).
pub(crate) fn mesh_circumradius(case: &TriaxialCase, side: f64) -> f64 {
    let (_, h) = mesh_square(case, side);
    2.0 * std::f64::consts::SQRT_2 * h
}

/// The simulation box around a sample whose lattice filled a cube of side `side`: a cube
/// about the sample's centre holding the wall meshes of [`mesh_circumradius`] (both
/// engines use it; only the meshes need it).
pub(crate) fn domain(case: &TriaxialCase, side: f64) -> ([f64; 3], [f64; 3]) {
    let (c, _) = mesh_square(case, side);
    let e = mesh_circumradius(case, side) + 2.0 * case.diameter;
    ([c - e; 3], [c + e; 3])
}

/// The jittered cubic lattice of seed `seed`: `n^3` sites of spacing `side / n` in the
/// cube, the first `grains` filled, each grain displaced uniformly by up to a quarter of
/// the gap between neighbours along each axis (so none touch), at rest.
pub fn lattice(case: &TriaxialCase, seed: u64) -> Vec<Particle> {
    let (side, n) = case.lattice_box();
    let a = side / n as f64;
    let jitter = 0.25 * (a - case.diameter);
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut out = Vec::with_capacity(case.grains);
    'fill: for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                if out.len() == case.grains {
                    break 'fill;
                }
                let mut x = [0.0; 3];
                for (c, idx) in [i, j, k].into_iter().enumerate() {
                    x[c] = (idx as f64 + 0.5) * a + jitter * (2.0 * rng.random::<f64>() - 1.0);
                }
                out.push(Particle {
                    id: out.len() as u64 + 1,
                    type_: case.grain_type,
                    radius: 0.5 * case.diameter,
                    density: case.density,
                    x,
                    v: [0.0; 3],
                    omega: [0.0; 3],
                });
            }
        }
    }
    out
}

/// The native engine's case: the grains in the six-wall box with its hi walls at `hi`.
pub(crate) fn box_case(
    case: &TriaxialCase,
    particles: Vec<Particle>,
    hi: [f64; 3],
    side: f64,
) -> Case {
    let (lo, dhi) = domain(case, side);
    let plane = |axis, position| Wall::Plane {
        axis,
        position,
        type_: case.wall_type,
    };
    Case {
        name: format!("{}-box", case.name),
        kind: "triaxial".into(),
        description: case.description.clone(),
        source: case.source.clone(),
        dt: case.dt,
        n_steps: 0,
        output_every: 1,
        gravity: [0.0; 3],
        neighbor_skin: case.neighbor_skin,
        family: crate::case::ContactFamily::Liggghts,
        rolling: case.rolling,
        domain_lo: lo,
        domain_hi: dhi,
        materials: case.materials.clone(),
        pairs: case.pairs.clone(),
        particles,
        walls: vec![
            plane(Axis::X, 0.0),
            plane(Axis::Y, 0.0),
            plane(Axis::Z, 0.0),
            plane(Axis::X, hi[0]),
            plane(Axis::Y, hi[1]),
            plane(Axis::Z, hi[2]),
        ],
        tolerances: Tolerances {
            velocity_rel: 1e-6,
            position_frac_radius: 1e-6,
            orientation_rad: 1e-6,
        },
        clumps: Default::default(),
        rayleigh_time: case.rayleigh_time,
        negative_controls: vec![],
        expect: Vec::new(),
        warnings: Vec::new(),
    }
}

/// Positions of the three hi walls.
pub(crate) fn hi_positions(sim: &Simulation) -> [f64; 3] {
    [0, 1, 2].map(|i| sim.wall_position(hi_wall(i)))
}

/// LIGGGHTS' target of the servo on axis `i`: `-sigma_c * a * b` with a, b the other two
/// hi walls' positions in axis order (the deck's `variable ... equal -sigma*f_..*f_..`,
/// evaluated left to right).
pub(crate) fn servo_target(sigma_c: f64, hi: [f64; 3], i: usize) -> f64 {
    let (a, b) = match i {
        0 => (hi[1], hi[2]),
        1 => (hi[0], hi[2]),
        _ => (hi[0], hi[1]),
    };
    -sigma_c * a * b
}

/// Force of the grains on the hi wall along axis `i` (positive: pushed outward).
pub(crate) fn hi_force(sim: &Simulation, i: usize) -> f64 {
    sim.wall_force(hi_wall(i))[i]
}

/// The servos' `final_integrate` for the hi walls of `axes`: new velocities from this
/// step's forces and targets.
fn servo_step(
    sim: &mut Simulation,
    servos: &mut [Servo],
    axes: &[usize],
    sigma_c: f64,
) -> Result<()> {
    let hi = hi_positions(sim);
    for (s, &i) in servos.iter_mut().zip(axes) {
        let v = s.update(hi_force(sim, i), servo_target(sigma_c, hi, i), sim.dt);
        sim.set_wall_velocity(hi_wall(i), v)?;
    }
    Ok(())
}

/// Wall stresses along x, y, z from the hi walls' forces (Pa) and the box volume.
pub(crate) fn hi_stresses(sim: &Simulation) -> ([f64; 3], f64) {
    let h = hi_positions(sim);
    let area = [h[1] * h[2], h[0] * h[2], h[0] * h[1]];
    (
        [0, 1, 2].map(|i| hi_force(sim, i) / area[i]),
        h[0] * h[1] * h[2],
    )
}

/// Compacts the lattice of `seed` to `sigma_c` with the three servo walls and the
/// material's own friction until every wall stress is within the case's tolerance of
/// sigma_c and the translational kinetic energy is below ke_factor sigma_c V (checked
/// every `check_every` steps). `progress(t, stress ratios, KE ratio)` at each check.
pub fn compact(
    case: &TriaxialCase,
    seed: u64,
    sigma_c: f64,
    mut progress: impl FnMut(f64, [f64; 3], f64),
) -> Result<Sample> {
    let (side, _) = case.lattice_box();
    let c = box_case(case, lattice(case, seed), [side; 3], side);
    let mut sim = Simulation::from_case(&c);
    sim.setup()?;
    let mut servos = [Servo::new(case.servo); 3];
    let max_steps = (case.max_compaction_time / case.dt).ceil() as u64;
    let (ratio, ke_ratio) = loop {
        sim.step()?;
        servo_step(&mut sim, &mut servos, &[0, 1, 2], sigma_c)?;
        if !sim.step.is_multiple_of(case.check_every) {
            continue;
        }
        let (s, volume) = hi_stresses(&sim);
        let ratio = s.map(|x| x / sigma_c);
        let ke_ratio = sim.translational_kinetic_energy() / (sigma_c * volume);
        let t = sim.step as f64 * case.dt;
        progress(t, ratio, ke_ratio);
        if ratio
            .iter()
            .all(|r| (r - 1.0).abs() <= case.stress_tolerance)
            && ke_ratio < case.ke_factor
        {
            break (ratio, ke_ratio);
        }
        if sim.step >= max_steps {
            bail!(
                "{}: sample seed {seed} at sigma_c = {sigma_c} Pa not compacted after max_time = {} s: wall stresses / sigma_c = {:.4} / {:.4} / {:.4} (tolerance {}), KE / (sigma_c V) = {ke_ratio:.2e} (target {:.1e})",
                case.source.display(),
                case.max_compaction_time,
                ratio[0],
                ratio[1],
                ratio[2],
                case.stress_tolerance,
                case.ke_factor
            );
        }
    };
    let particles = super::packing::particles_now(&c.particles, &sim);
    let hi = hi_positions(&sim);
    let v_grains = particles.len() as f64 * std::f64::consts::PI / 6.0 * case.diameter.powi(3);
    Ok(Sample {
        seed,
        sigma_c,
        particles,
        hi,
        lattice_side: side,
        psi: v_grains / (hi[0] * hi[1] * hi[2]),
        compaction_time: sim.step as f64 * case.dt,
        ke_ratio,
        stress_ratio: ratio,
    })
}

/// The record of the walls at the simulation's current step.
pub fn record(sim: &Simulation) -> WallRecord {
    WallRecord {
        step: sim.step,
        hi: hi_positions(sim),
        f_lo: [0, 1, 2].map(|i| sim.wall_force(i)[i]),
        f_hi: [0, 1, 2].map(|i| hi_force(sim, i)),
    }
}

/// The shear of a compacted sample (with `pert`'s physics): contact history and servo
/// state reset (vcm = 0, sums 0), z_hi moving down at strain_rate H0 from step 1, x_hi and
/// y_hi holding sample.sigma_c, for `steps` steps; every `output_every` steps the walls
/// go to `on_record`.
pub fn shear(
    case: &TriaxialCase,
    sample: &Sample,
    pert: Perturbation,
    steps: u64,
    mut on_record: impl FnMut(&WallRecord) -> Result<()>,
) -> Result<()> {
    let c = box_case(
        case,
        sample.particles.clone(),
        sample.hi,
        sample.lattice_side,
    );
    let mut sim = Simulation::from_case_perturbed(&c, pert);
    sim.setup_settled()?;
    let mut servos = [Servo::new(case.servo); 2];
    sim.set_wall_velocity(hi_wall(2), -case.strain_rate * sample.hi[2])?;
    for _ in 0..steps {
        sim.step()?;
        servo_step(&mut sim, &mut servos, &[0, 1], sample.sigma_c)?;
        if sim.step.is_multiple_of(case.output_every) {
            on_record(&record(&sim))?;
        }
    }
    Ok(())
}
