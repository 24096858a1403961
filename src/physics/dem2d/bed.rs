//! Bed preparation of K Sec. II, in the native engine only (the LAMMPS run reads the
//! finished bed through `read_data`, so both engines start from the very same grains).
//!
//! - random: polydisperse disks, diameters uniform in `d (1 +- r)`, on a square lattice
//!   of pitch `d (1 + r)` with uniformly random velocity components in `+- v0`
//!   (seeded), settled under gravity until the total kinetic energy
//!   (translation + rotation) is below `settle_ke` (K: 1e-10 m g d). The rough top is
//!   then smoothed: the bed is cut into columns 2 d wide, the lowest of the columns'
//!   highest grain tops is the cut height, and every grain whose centre lies above it
//!   is removed; the rest settles again to the same criterion.
//! - hexagonal: monodisperse disks of diameter d touching in a hexagonal lattice on a
//!   wall row of the same pitch, equilibrated under gravity to the same criterion.
//!
//! The bottom wall is one row of frozen disks (K: "rigid horizontal walls made up from
//! monodisperse particles"), pitch `L / n` with n = floor(L / wall_d).

use super::contact::Coeffs;
use super::neighbor::Box2;
use super::{Disk, Role, System, lammps_mass};
use anyhow::{Result, bail};
use rand::{Rng, SeedableRng};

pub use crate::case::impact2d::Packing;

/// Everything bed preparation needs, SI.
#[derive(Debug, Clone, serde::Serialize)]
pub struct BedSpec {
    pub packing: Packing,
    pub count: usize,
    /// Periodic length L (m).
    pub length: f64,
    /// Mean grain diameter d (m).
    pub d: f64,
    /// Polydispersity r: diameters uniform in d (1 +- r). Ignored (0) for hexagonal.
    pub polydispersity: f64,
    /// Mass per area (kg/m^2) so that a disk of diameter d has the mass scale m.
    pub areal_density: f64,
    pub wall_d: f64,
    pub seed: u64,
    /// Initial velocity components uniform in +- this (m/s).
    pub initial_speed: f64,
    /// Total kinetic energy threshold (J).
    pub settle_ke: f64,
    /// Give up (error) after this much simulated settling time (s).
    pub max_settle_time: f64,
    pub dt: f64,
    pub skin: f64,
    pub gravity: f64,
    /// Coefficients for types 0 (grain) and 1 (wall), 2x2 symmetric.
    pub coeffs: [Coeffs; 4],
}

/// A settled bed: grains (type 0, free) and the bottom wall (type 1, frozen).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Bed {
    pub grains: Vec<Disk>,
    pub wall: Vec<Disk>,
    /// Top of the bottom wall (y of the wall disks' tops).
    pub floor: f64,
    pub settle_time: f64,
    pub final_ke: f64,
    /// Grains removed by smoothing.
    pub removed: usize,
    /// Packing fraction (disk area / area) between 2 d above the floor and 2 d
    /// below the surface.
    pub packing_fraction: f64,
}

impl Bed {
    /// Height of the bed's surface at horizontal position `x`: the highest point of
    /// any grain above `x` (K Sec. III: "the initial upper boundary of the granular bed
    /// at the point of impact").
    pub fn surface_at(&self, x: f64, length: f64) -> f64 {
        self.grains
            .iter()
            .filter_map(|g| {
                let mut dx = (g.x[0] - x).abs();
                dx = dx.min(length - dx);
                (dx < g.radius).then(|| g.x[1] + (g.radius * g.radius - dx * dx).sqrt())
            })
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// Highest grain top anywhere.
    pub fn top(&self) -> f64 {
        self.grains
            .iter()
            .map(|g| g.x[1] + g.radius)
            .fold(f64::NEG_INFINITY, f64::max)
    }
}

pub(crate) fn wall_row(length: f64, wall_d: f64, y: f64, first_id: u64) -> Vec<Disk> {
    let n = ((length / wall_d).floor() as usize).max(1);
    let pitch = length / n as f64;
    (0..n)
        .map(|k| Disk {
            id: first_id + k as u64,
            type_: 1,
            radius: 0.5 * wall_d,
            // Walls are frozen: their mass never enters m_eff (LAMMPS uses the mobile
            // partner's mass), any positive value will do.
            mass: 1.0,
            x: [(k as f64 + 0.5) * pitch, y],
            v: [0.0; 2],
            omega: 0.0,
            role: Role::Frozen,
        })
        .collect()
}

fn disk_mass(spec: &BedSpec, r: f64) -> f64 {
    lammps_mass(spec.areal_density * std::f64::consts::PI * r * r, r)
}

fn initial_grains(spec: &BedSpec, floor: f64) -> Result<Vec<Disk>> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(spec.seed);
    let mut out = Vec::with_capacity(spec.count);
    match spec.packing {
        Packing::Random => {
            let pitch = spec.d * (1.0 + spec.polydispersity) * 1.02;
            let ncols = (spec.length / pitch).floor() as usize;
            if ncols == 0 {
                bail!(
                    "bed length {} m is shorter than one lattice pitch {pitch} m",
                    spec.length
                );
            }
            let px = spec.length / ncols as f64;
            for k in 0..spec.count {
                let (c, row) = (k % ncols, k / ncols);
                let dia = spec.d * (1.0 + spec.polydispersity * (2.0 * rng.random::<f64>() - 1.0));
                let r = 0.5 * dia;
                let v = [
                    spec.initial_speed * (2.0 * rng.random::<f64>() - 1.0),
                    spec.initial_speed * (2.0 * rng.random::<f64>() - 1.0),
                ];
                out.push(Disk {
                    id: k as u64 + 1,
                    type_: 0,
                    radius: r,
                    mass: disk_mass(spec, r),
                    x: [(c as f64 + 0.5) * px, floor + (row as f64 + 0.5) * pitch],
                    v,
                    omega: 0.0,
                    role: Role::Free,
                });
            }
        }
        Packing::Hexagonal => {
            let ncols = (spec.length / spec.d).round() as usize;
            let pitch = spec.length / ncols as f64;
            if pitch < spec.d * (1.0 - 1e-12) {
                bail!("hexagonal bed: L / round(L/d) = {pitch} m < d; choose L a multiple of d");
            }
            let dy = pitch * 3f64.sqrt() / 2.0;
            let r = 0.5 * spec.d;
            for k in 0..spec.count {
                let (c, row) = (k % ncols, k / ncols);
                // Row 0 sits in the pockets of the wall row (wall disks at (k + 1/2) pitch).
                let shift = if row % 2 == 0 { 0.0 } else { 0.5 };
                let x = ((c as f64 + shift) * pitch).rem_euclid(spec.length);
                out.push(Disk {
                    id: k as u64 + 1,
                    type_: 0,
                    radius: r,
                    mass: disk_mass(spec, r),
                    x: [x, floor - 0.5 * spec.wall_d + (row as f64 + 1.0) * dy],
                    v: [0.0; 2],
                    omega: 0.0,
                    role: Role::Free,
                });
            }
        }
    }
    Ok(out)
}

fn system(spec: &BedSpec, grains: Vec<Disk>, wall: &[Disk], top: f64) -> System {
    let mut disks = grains;
    disks.extend_from_slice(wall);
    let bx = Box2 {
        lo: [0.0, 0.0],
        hi: [spec.length, top],
        periodic_x: true,
    };
    System::new(
        disks,
        None,
        spec.coeffs.to_vec(),
        2,
        bx,
        spec.gravity,
        spec.dt,
        spec.skin,
        vec![],
    )
}

/// Runs until the total kinetic energy is below the threshold; returns the settled
/// grains and the time it took.
fn settle(
    spec: &BedSpec,
    grains: Vec<Disk>,
    wall: &[Disk],
    mut progress: impl FnMut(f64, f64),
) -> Result<(Vec<Disk>, f64, f64)> {
    let n = grains.len();
    let top = grains.iter().map(|g| g.x[1] + g.radius).fold(0.0, f64::max) + spec.d;
    let mut sys = system(spec, grains, wall, top);
    sys.setup();
    let check_every = 50u64;
    let max_steps = (spec.max_settle_time / spec.dt).ceil() as u64;
    let mut ke = sys.kinetic_energy();
    let mut trace = crate::physics::settle_trace::SettleTrace::default();
    while sys.step < max_steps {
        for _ in 0..check_every {
            sys.step();
        }
        ke = sys.kinetic_energy();
        if !ke.is_finite() {
            bail!(
                "bed settling diverged at t = {:.4e} s (kinetic energy {ke})",
                sys.time()
            );
        }
        progress(sys.time(), ke);
        trace.push(sys.time(), ke);
        if ke < spec.settle_ke && sys.step >= 2 * check_every {
            let t = sys.time();
            let grains = sys.disks.into_iter().take(n).collect();
            return Ok((grains, t, ke));
        }
    }
    // K's criterion is in m g d: the weight of a grain of diameter d lifted by d.
    let mgd = spec.areal_density * std::f64::consts::FRAC_PI_4 * spec.d.powi(3) * spec.gravity;
    bail!(
        "bed did not settle: total kinetic energy {ke:.3e} J still above {:.3e} J after {:.4e} s (bed.max_settle_time); m g d = {mgd:.3e} J, {}",
        spec.settle_ke,
        spec.max_settle_time,
        trace.describe("total KE", mgd, " m g d")
    )
}

/// Prepares the bed; `progress(t, ke)` is called during settling.
pub fn prepare(spec: &BedSpec, mut progress: impl FnMut(f64, f64)) -> Result<Bed> {
    let wall_y = 0.5 * spec.wall_d;
    let wall = wall_row(spec.length, spec.wall_d, wall_y, spec.count as u64 + 1);
    let floor = spec.wall_d;
    let grains = initial_grains(spec, floor)?;
    let (grains, t1, ke1) = settle(spec, grains, &wall, &mut progress)?;
    let (grains, removed, t2, ke) = match spec.packing {
        Packing::Hexagonal => (grains, 0, 0.0, ke1),
        Packing::Random => {
            let width = 2.0 * spec.d;
            let ncol = ((spec.length / width).floor() as usize).max(1);
            let mut col_top = vec![f64::NEG_INFINITY; ncol];
            for g in &grains {
                let c = ((g.x[0] / spec.length * ncol as f64) as usize).min(ncol - 1);
                col_top[c] = col_top[c].max(g.x[1] + g.radius);
            }
            let cut = col_top.iter().copied().fold(f64::INFINITY, f64::min);
            let before = grains.len();
            let kept: Vec<Disk> = grains.into_iter().filter(|g| g.x[1] <= cut).collect();
            let removed = before - kept.len();
            let (kept, t2, ke2) = settle(spec, kept, &wall, &mut progress)?;
            (kept, removed, t2, ke2)
        }
    };
    let mut bed = Bed {
        grains,
        wall,
        floor,
        settle_time: t1 + t2,
        final_ke: ke,
        removed,
        packing_fraction: 0.0,
    };
    bed.packing_fraction = packing_fraction(&bed, spec);
    Ok(bed)
}

fn packing_fraction(bed: &Bed, spec: &BedSpec) -> f64 {
    let lo = bed.floor + 2.0 * spec.d;
    let hi = bed.top() - 2.0 * spec.d;
    if hi <= lo {
        return f64::NAN;
    }
    let area: f64 = bed
        .grains
        .iter()
        .filter(|g| g.x[1] > lo && g.x[1] < hi)
        .map(|g| std::f64::consts::PI * g.radius * g.radius)
        .sum();
    area / (spec.length * (hi - lo))
}
