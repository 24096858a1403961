//! Bed preparation of Feng et al. Sec. 2: grains are released from a loose jittered
//! lattice inside the container (the "pour"), fall under gravity, and the system is
//! relaxed until the mean kinetic energy is below `settle_ke_ratio` times its value at
//! the end of pouring (translational energy, as LIGGGHTS' `compute ke`; see
//! `Simulation::translational_kinetic_energy`). "End of pouring" is taken as the kinetic-energy maximum: until
//! then grains are still gaining energy in free fall; afterwards the heap only dissipates.

use super::{Simulation, rigid};
use crate::case::clumps::{Clump, Clumps};
use crate::case::penetration::{Diameter, PenetrationCase};
use crate::case::{Axis, Case, Material, PairTable, Particle, RollingModel, Tolerances, Wall};
use crate::physics::settle_trace::SettleTrace;
use anyhow::{Result, bail};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use std::path::PathBuf;

/// A settled bed, ready for penetration by either engine.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Bed {
    pub particles: Vec<Particle>,
    /// The grains of a bed of clumps (the case's `clump` template; `particles` is then
    /// empty): centre of mass, orientation, velocity and angular velocity of each body.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub bodies: Vec<Clump>,
    /// Bed surface height (m): mean over a 2 d_mean grid of the highest grain top
    /// `z + r` in each cell, for cells within R_container - d_mean of the axis.
    pub surface_z: f64,
    /// Packing fraction in the coaxial cylinder r < R_c - 2 d_mean, 2 d_mean < z <
    /// surface - 2 d_mean: volume of grains whose centres lie inside / region volume.
    pub psi: f64,
    pub ke_ratio: f64,
    pub settle_time: f64,
    pub ke_at_end_of_pour: f64,
}

impl Bed {
    /// The same bed with every grain (every body of a clump bed) moved by one unit in the
    /// last place of its x coordinate: the chaos baseline's replica of docs/statistics.md,
    /// round-off everywhere, as two engines' summation orders differ everywhere. (One
    /// grain is not enough: a bottom-layer grain's one ulp is rounded away in the static
    /// bed and the intruder's force history stays bit-identical.)
    pub(crate) fn nudged_one_ulp(&self) -> Bed {
        let mut b = self.clone();
        for p in &mut b.particles {
            p.x[0] = p.x[0].next_up();
        }
        for c in &mut b.bodies {
            c.x[0] = c.x[0].next_up();
        }
        b
    }
}

fn draw_diameters(d: &Diameter, n: usize, seed: u64) -> Result<Vec<f64>> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut out = Vec::with_capacity(n);
    match *d {
        Diameter::Constant { value } => out.resize(n, value),
        Diameter::Uniform { mean, half_width } => {
            for _ in 0..n {
                out.push(mean + half_width * (2.0 * rng.random::<f64>() - 1.0));
            }
        }
        Diameter::Gaussian {
            mean,
            std,
            min,
            max,
        } => {
            let normal = Normal::new(mean, std)?;
            while out.len() < n {
                // Truncated Gaussian (Table 4's cut-offs) by rejection.
                let v = normal.sample(&mut rng);
                if (min..=max).contains(&v) {
                    out.push(v);
                }
            }
        }
    }
    Ok(out)
}

/// The simulation box for a penetration case: container plus the intruder's travel.
pub(crate) fn domain(case: &PenetrationCase, top: f64) -> ([f64; 3], [f64; 3]) {
    let m = case.diameter.max();
    let r = case.container_radius + m;
    ([-r, -r, -m], [r, r, top.max(case.container_height) + m])
}

/// A `Case` the native engine can run: the given grains in the container.
pub fn container_case(case: &PenetrationCase, particles: Vec<Particle>, top: f64) -> Case {
    container_case_with(case, particles, Vec::new(), top)
}

/// [`container_case`] with clump grains (bodies of the case's template) besides spheres.
pub(crate) fn container_case_with(
    case: &PenetrationCase,
    particles: Vec<Particle>,
    bodies: Vec<Clump>,
    top: f64,
) -> Case {
    let (lo, hi) = domain(case, top);
    Case {
        name: format!("{}-bed", case.name),
        kind: "penetration".into(),
        description: case.description.clone(),
        source: case.source.clone(),
        dt: case.dt,
        n_steps: 0,
        output_every: 1,
        gravity: [0.0, 0.0, -case.gravity],
        neighbor_skin: case.neighbor_skin,
        family: crate::case::ContactFamily::Liggghts,
        rolling: case.rolling,
        domain_lo: lo,
        domain_hi: hi,
        materials: case.materials.clone(),
        pairs: case.pairs.clone(),
        particles,
        walls: vec![
            Wall::Plane {
                axis: Axis::Z,
                position: 0.0,
                type_: case.wall_type,
            },
            Wall::Cylinder {
                axis: Axis::Z,
                radius: case.container_radius,
                center: [0.0, 0.0],
                type_: case.wall_type,
            },
        ],
        tolerances: Tolerances {
            velocity_rel: 1e-6,
            position_frac_radius: 1e-6,
            orientation_rad: 1e-6,
        },
        clumps: match &case.clump {
            Some(t) if !bodies.is_empty() => Clumps {
                templates: vec![(**t).clone()],
                bodies,
            },
            _ => Clumps::default(),
        },
        rayleigh_time: case.rayleigh_time,
        negative_controls: vec![],
        expect: Vec::new(),
        warnings: Vec::new(),
    }
}

/// The (x, y) sites of a square lattice of spacing `a` whose cells lie inside the circle
/// of radius `rin`: one layer of a loose pour.
fn lattice_sites(rin: f64, a: f64) -> Vec<(f64, f64)> {
    let n1 = (2.0 * rin / a).floor() as i64;
    let mut sites = Vec::new();
    for j in 0..=n1 {
        for i in 0..=n1 {
            let (x, y) = (-rin + i as f64 * a, -rin + j as f64 * a);
            if (x * x + y * y).sqrt() <= rin - 0.5 * a {
                sites.push((x, y));
            }
        }
    }
    sites
}

/// Loose lattice: spacing 1.05 d_max, inside R_c - d_max/2, layers from d_max up.
pub fn lattice(case: &PenetrationCase) -> Result<Vec<Particle>> {
    let d = draw_diameters(&case.diameter, case.count, case.seed)?;
    let dmax = case.diameter.max();
    let a = 1.05 * dmax;
    let rin = case.container_radius - 0.5 * dmax;
    let sites = lattice_sites(rin, a);
    if sites.is_empty() {
        bail!(
            "{}: container too narrow for the grains",
            case.source.display()
        );
    }
    let mut rng = rand::rngs::StdRng::seed_from_u64(case.seed ^ 0x5EED);
    let mut particles = Vec::with_capacity(case.count);
    for (k, diam) in d.into_iter().enumerate() {
        let layer = k / sites.len();
        let (x, y) = sites[k % sites.len()];
        let jitter = 0.02 * dmax;
        particles.push(Particle {
            id: k as u64 + 1,
            type_: case.grain_type,
            radius: 0.5 * diam,
            density: case.density,
            x: [
                x + jitter * (rng.random::<f64>() - 0.5),
                y + jitter * (rng.random::<f64>() - 0.5),
                dmax + layer as f64 * a,
            ],
            v: [0.0; 3],
            omega: [0.0; 3],
        });
    }
    Ok(particles)
}

/// Loose lattice of clump bodies (a bed of the case's clump template): sites 1.05 times
/// the body's bounding diameter apart, so no two bodies touch whatever their orientation,
/// inside R_c minus the bounding radius, layers from one bounding diameter up; each body
/// jittered and turned to a uniformly random orientation (a normalised Gaussian
/// quaternion), at rest.
pub(crate) fn lattice_bodies(case: &PenetrationCase) -> Result<Vec<Clump>> {
    let Some(t) = &case.clump else {
        bail!("{}: not a bed of clumps", case.source.display());
    };
    let rb = t.bounding_radius;
    let a = 1.05 * 2.0 * rb;
    let rin = case.container_radius - rb;
    let sites = lattice_sites(rin, a);
    if sites.is_empty() {
        bail!(
            "{}: container too narrow for the clumps (bounding radius {rb:e} m)",
            case.source.display()
        );
    }
    let mut rng = rand::rngs::StdRng::seed_from_u64(case.seed ^ 0x5EED);
    let normal = Normal::new(0.0, 1.0)?;
    let jitter = 0.02 * a;
    let mut bodies = Vec::with_capacity(case.count);
    for k in 0..case.count {
        let layer = k / sites.len();
        let (x, y) = sites[k % sites.len()];
        let x = [
            x + jitter * (rng.random::<f64>() - 0.5),
            y + jitter * (rng.random::<f64>() - 0.5),
            2.0 * rb + layer as f64 * a,
        ];
        let q = rigid::qnormalize(std::array::from_fn(|_| normal.sample(&mut rng)));
        bodies.push(Clump {
            id: k as u64 + 1,
            template: 0,
            x,
            orientation: q,
            v: [0.0; 3],
            omega: [0.0; 3],
        });
    }
    Ok(bodies)
}

/// The case the native engine pours: the loose lattice in the container, the domain up
/// to the lattice's top.
pub fn pour_case(case: &PenetrationCase) -> Result<Case> {
    if let Some(t) = &case.clump {
        let bodies = lattice_bodies(case)?;
        let top = bodies
            .iter()
            .map(|b| b.x[2] + t.bounding_radius)
            .fold(0.0, f64::max);
        return Ok(container_case_with(case, Vec::new(), bodies, top));
    }
    let particles = lattice(case)?;
    let top = particles
        .iter()
        .map(|p| p.x[2] + p.radius)
        .fold(0.0, f64::max);
    Ok(container_case(case, particles, top))
}

/// Steps `sim` until the bed has poured (mean KE past its peak and below half of it) and
/// settled (mean KE / KE at the end of pouring < `settle_ke_ratio`), or until
/// `max_settle_time`; checked every 50 steps. Returns (last KE ratio, mean KE at the end
/// of pouring); the ratio is infinite if the pour never ended. `progress(t, ratio)` after
/// each check once poured.
pub fn settle(
    sim: &mut Simulation,
    case: &PenetrationCase,
    progress: impl FnMut(f64, f64),
) -> Result<(f64, f64)> {
    settle_traced(sim, case, progress).map(|(r, k, _)| (r, k))
}

/// [`settle`], with the trace of the ratio after pouring (for the error when the bed
/// does not settle).
fn settle_traced(
    sim: &mut Simulation,
    case: &PenetrationCase,
    mut progress: impl FnMut(f64, f64),
) -> Result<(f64, f64, SettleTrace)> {
    let mut trace = SettleTrace::default();
    let n = sim.n_grains() as f64;
    let check_every = 50u64;
    let max_steps = (case.max_settle_time / case.dt).ceil() as u64;
    let (mut ke_peak, mut ratio) = (0.0f64, f64::INFINITY);
    let mut poured = false;
    while sim.step < max_steps {
        sim.step()?;
        if !sim.step.is_multiple_of(check_every) {
            continue;
        }
        let ke = sim.translational_kinetic_energy() / n;
        if !poured {
            if ke >= ke_peak {
                ke_peak = ke;
            } else if ke < 0.5 * ke_peak {
                poured = true;
            }
        } else {
            ratio = ke / ke_peak;
            progress(sim.step as f64 * case.dt, ratio);
            trace.push(sim.step as f64 * case.dt, ratio);
            if ratio < case.settle_ke_ratio {
                break;
            }
        }
    }
    Ok((ratio, ke_peak, trace))
}

/// Pours and settles the bed with the native engine.
pub fn prepare(case: &PenetrationCase, progress: impl FnMut(f64, f64)) -> Result<Bed> {
    let sim_case = pour_case(case)?;
    let mut sim = Simulation::from_case(&sim_case);
    sim.setup()?;
    let (ratio, ke_peak, trace) = settle_traced(&mut sim, case, progress)?;
    if ratio >= case.settle_ke_ratio {
        bail!(
            "{}: bed not settled after max_settle_time = {} s (mean KE / KE at end of pouring = {ratio:.2e}, target {:.1e}); {}",
            case.source.display(),
            case.max_settle_time,
            case.settle_ke_ratio,
            trace.describe("the ratio", 1.0, "")
        );
    }
    let frame = sim.frame();
    let settled = particles_now(&sim_case.particles, &sim);
    // Bodies: the state both engines insert them with (LIGGGHTS' `fix insert` takes
    // centre of mass, orientation, velocity and angular velocity).
    let bodies: Vec<Clump> = sim_case
        .clumps
        .bodies
        .iter()
        .zip(&frame.bodies)
        .map(|(c, s)| Clump {
            x: s.x,
            orientation: s.q,
            v: s.v,
            omega: s.omega,
            ..c.clone()
        })
        .collect();
    let spheres = grain_spheres(case, &settled, &bodies);
    let surface_z = surface_height(case, &spheres);
    let psi = packing_fraction(case, &settled, &bodies, surface_z);
    Ok(Bed {
        particles: settled,
        bodies,
        surface_z,
        psi,
        ke_ratio: ratio,
        settle_time: sim.step as f64 * case.dt,
        ke_at_end_of_pour: ke_peak,
    })
}

/// The case's free spheres (in id order, as `Simulation::frame` gives them) with the
/// positions, velocities and spins the simulation has now: a prepared state to start
/// both engines from.
pub(crate) fn particles_now(particles: &[Particle], sim: &Simulation) -> Vec<Particle> {
    particles
        .iter()
        .zip(&sim.frame().particles)
        .map(|(p, s)| {
            debug_assert_eq!(p.id, s.id, "particles must be in id order");
            Particle {
                x: s.x,
                v: s.v,
                omega: s.omega,
                ..p.clone()
            }
        })
        .collect()
}

/// Every sphere of the grains, `(centre, radius)`: the free spheres and the members of
/// the bodies where both engines place them at the start (`RigidBody::new`, `set_xv`).
pub fn grain_spheres(
    case: &PenetrationCase,
    particles: &[Particle],
    bodies: &[Clump],
) -> Vec<([f64; 3], f64)> {
    let mut out: Vec<([f64; 3], f64)> = particles.iter().map(|p| (p.x, p.radius)).collect();
    if let Some(t) = &case.clump {
        for b in bodies {
            let xs = rigid::member_positions(b.x, b.orientation, &t.offsets);
            out.extend(xs.into_iter().zip(t.radii.iter().copied()));
        }
    }
    out
}

impl Bed {
    /// [`grain_spheres`] of this bed.
    pub fn spheres(&self, case: &PenetrationCase) -> Vec<([f64; 3], f64)> {
        grain_spheres(case, &self.particles, &self.bodies)
    }

    /// Grains: spheres or clump bodies.
    pub fn n_grains(&self) -> usize {
        self.particles.len() + self.bodies.len()
    }
}

pub fn surface_height(case: &PenetrationCase, ps: &[([f64; 3], f64)]) -> f64 {
    let d = case.diameter.mean();
    let cell = 2.0 * d;
    let rmax = case.container_radius - d;
    let n = (2.0 * rmax / cell).ceil() as usize + 1;
    let mut top = vec![f64::NEG_INFINITY; n * n];
    for (p, r) in ps {
        let (x, y) = (p[0], p[1]);
        if (x * x + y * y).sqrt() > rmax {
            continue;
        }
        let (i, j) = (((x + rmax) / cell) as usize, ((y + rmax) / cell) as usize);
        let c = &mut top[j.min(n - 1) * n + i.min(n - 1)];
        *c = c.max(p[2] + r);
    }
    let filled: Vec<f64> = top.into_iter().filter(|v| v.is_finite()).collect();
    filled.iter().sum::<f64>() / filled.len() as f64
}

/// Solid fraction of the grains whose centre (a body's: its centre of mass) lies in the
/// region; a clump counts with the volume of the union of its members.
pub fn packing_fraction(
    case: &PenetrationCase,
    ps: &[Particle],
    bodies: &[Clump],
    surface_z: f64,
) -> f64 {
    let d = case.diameter.mean();
    let (rr, z0, z1) = (
        case.container_radius - 2.0 * d,
        2.0 * d,
        surface_z - 2.0 * d,
    );
    let inside = |x: &[f64; 3]| (x[0].powi(2) + x[1].powi(2)).sqrt() < rr && x[2] > z0 && x[2] < z1;
    let vol: f64 = ps
        .iter()
        .filter(|p| inside(&p.x))
        .map(|p| 4.0 / 3.0 * std::f64::consts::PI * p.radius.powi(3))
        .sum();
    let body_vol = case.clump.as_ref().map_or(0.0, |t| t.volume);
    let vol = vol + bodies.iter().filter(|b| inside(&b.x)).count() as f64 * body_vol;
    vol / (std::f64::consts::PI * rr * rr * (z1 - z0))
}

/// For `Bed` files written next to a run: where the bed came from. A bed read back from
/// files (a deck directory's data file or bed dump, a sealed record) carries no settle
/// time or KE ratio: the note says so instead of printing NaN as a time.
pub fn bed_note(case: &PenetrationCase, bed: &Bed) -> String {
    if bed.settle_time.is_finite() {
        format!(
            "bed of {} grains prepared natively from {} (seed {}): settled after {:.3} s, KE ratio {:.2e}, surface z = {:.6e} m, psi = {:.4}",
            bed.n_grains(),
            PathBuf::from(&case.source).display(),
            case.seed,
            bed.settle_time,
            bed.ke_ratio,
            bed.surface_z,
            bed.psi
        )
    } else {
        format!(
            "bed of {} grains for {} (seed {}), read from files: settled: n/a (the files keep no settle time or KE ratio), surface z = {:.6e} m, psi = {}",
            bed.n_grains(),
            PathBuf::from(&case.source).display(),
            case.seed,
            bed.surface_z,
            if bed.psi.is_finite() {
                format!("{:.4}", bed.psi)
            } else {
                "n/a".into()
            }
        )
    }
}

/// Whether two [`bed_note`]s describe the same bed: the same text except the case file's
/// path, which names the same file however it was typed (relative, absolute).
pub(crate) fn same_bed_note(a: &str, b: &str) -> bool {
    let key = |n: &str| -> Option<(String, String)> {
        let (head, rest) = n
            .split_once(" prepared natively from ")
            .or_else(|| n.split_once(" grains for "))?;
        let (_, tail) = rest.split_once(" (seed ")?;
        Some((head.to_string(), tail.to_string()))
    };
    match (key(a), key(b)) {
        (Some(x), Some(y)) => x == y,
        _ => a == b,
    }
}

/// A loose jittered lattice of `n` spheres (d = 2 mm +-5%) in a walled box, with the
/// material of Feng's Table 2 scaled to a LIGGGHTS-legal modulus (E = 1e7 Pa).
pub fn lattice_case(n: usize, seed: u64) -> Case {
    let r = 1.0e-3;
    let spacing = 2.25 * r;
    let side = ((n as f64 / 2.0).cbrt().ceil() as usize).max(2);
    let (nx, ny) = (side, side);
    let nz = n.div_ceil(nx * ny);
    let lx = nx as f64 * spacing;
    let mut s = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut rnd = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut particles = Vec::with_capacity(n);
    'fill: for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                if particles.len() == n {
                    break 'fill;
                }
                let jitter = 0.05 * r;
                particles.push(Particle {
                    id: particles.len() as u64 + 1,
                    type_: 0,
                    radius: r * (0.95 + 0.1 * rnd()) * 0.98,
                    density: 2500.0,
                    x: [
                        (i as f64 + 0.5) * spacing + jitter * (rnd() - 0.5),
                        (j as f64 + 0.5) * spacing + jitter * (rnd() - 0.5),
                        (k as f64 + 0.5) * spacing + jitter * (rnd() - 0.5),
                    ],
                    v: [0.0; 3],
                    omega: [0.0; 3],
                });
            }
        }
    }
    let height = (nz as f64 + 2.0) * spacing;
    let mat = Material {
        youngs_modulus: 1.0e7,
        shear_modulus: 1.0e7 / 2.6,
        poisson_ratio: 0.3,
    };
    let rayleigh = crate::case::rayleigh_time(
        0.95 * 0.98 * r,
        2500.0,
        mat.shear_modulus,
        mat.poisson_ratio,
    );
    let dt = 0.2 * rayleigh;
    let walls = vec![
        Wall::Plane {
            axis: Axis::Z,
            position: 0.0,
            type_: 0,
        },
        Wall::Plane {
            axis: Axis::X,
            position: 0.0,
            type_: 0,
        },
        Wall::Plane {
            axis: Axis::X,
            position: lx,
            type_: 0,
        },
        Wall::Plane {
            axis: Axis::Y,
            position: 0.0,
            type_: 0,
        },
        Wall::Plane {
            axis: Axis::Y,
            position: lx,
            type_: 0,
        },
    ];
    Case {
        name: format!("bench-{n}"),
        kind: "bench".into(),
        description: "dense settled packing for throughput measurements".into(),
        source: PathBuf::from("<generated by granval bench>"),
        dt,
        n_steps: 0,
        output_every: 1,
        gravity: [0.0, 0.0, -9.81],
        neighbor_skin: 0.4 * r,
        family: crate::case::ContactFamily::Liggghts,
        rolling: RollingModel::Cdt,
        domain_lo: [-0.5 * r, -0.5 * r, -0.5 * r],
        domain_hi: [lx + 0.5 * r, lx + 0.5 * r, height],
        materials: vec![mat],
        pairs: PairTable {
            n_types: 1,
            restitution: vec![0.5],
            friction: vec![0.5],
            rolling_friction: vec![0.01],
        },
        particles,
        walls,
        tolerances: Tolerances {
            velocity_rel: 1e-6,
            position_frac_radius: 1e-6,
            orientation_rad: 1e-6,
        },
        clumps: Default::default(),
        rayleigh_time: rayleigh,
        negative_controls: vec![],
        expect: Vec::new(),
        warnings: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::same_bed_note;

    /// `--reuse` finds a run whatever way the case path was typed, and only that bed.
    #[test]
    fn bed_notes_compare_without_the_path() {
        let a = "bed of 10 grains prepared natively from cases/x.toml (seed 7): settled after 0.300 s, KE ratio 1.00e-7, surface z = 4.0e-2 m, psi = 0.5940";
        let b = a.replace("cases/x.toml", "/work/main/cases/x.toml");
        assert!(same_bed_note(a, &b));
        assert!(!same_bed_note(a, &a.replace("seed 7", "seed 8")));
        assert!(!same_bed_note(a, &a.replace("0.5940", "0.5941")));
    }
}
