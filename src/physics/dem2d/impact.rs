//! The impact scene (K Sec. II, Fig 1): a settled bed, a bottom and a top wall of
//! frozen disks, and the intruder released with its lowest point `release_height`
//! above the bed surface at the impact point (the middle of L), moving down at the
//! impact speed. Both engines start from the [`System`] built here.
//!
//! Types: 0 grains, 1 wall disks, 2 intruder. The bed comes from bed preparation with
//! its velocities; contact histories start empty in both engines (LAMMPS' `read_data`
//! cannot carry them), which lets a static-friction bed relax by a tiny amount before
//! the intruder arrives, identically in both.

use super::bed::{Bed, BedSpec, wall_row};
use super::neighbor::Box2;
use super::{Cluster, Disk, Role, System, lammps_mass};
use crate::case::impact2d::{BedKey, Impact2dCase, IntruderShape, Variant};
use anyhow::Result;

/// A scene ready to run, plus what the analysis needs to turn the intruder's centre
/// of mass into a depth.
#[derive(Debug, Clone)]
pub struct Scene {
    pub sys: System,
    /// Bed surface height at the impact point (m).
    pub surface: f64,
    /// Intruder centre of mass minus its lowest point (m).
    pub bottom_offset: f64,
    pub intruder_mass: f64,
}

/// Bed preparation inputs for a bed key (packing, count, length, seed): always the
/// case's base grain and wall materials, so every variant of a sweep (e_n, mu,
/// friction, speed, gravity) hits the very same bed and only the impact differs; a
/// `bed` sweep's variants differ only in count, length and seed.
pub fn bed_spec(case: &Impact2dCase, key: &BedKey) -> BedSpec {
    let s = &case.scales;
    let g = case.base.grains.coeffs(s);
    let w = case.base.walls.coeffs(s);
    let v = Variant {
        packing: key.packing,
        ..case.base.clone()
    };
    BedSpec {
        packing: v.packing,
        count: key.count,
        length: key.length,
        d: s.d,
        polydispersity: match v.packing {
            super::bed::Packing::Random => case.polydispersity,
            super::bed::Packing::Hexagonal => 0.0,
        },
        areal_density: s.m / (std::f64::consts::PI * 0.25 * s.d * s.d),
        wall_d: match v.packing {
            super::bed::Packing::Random => case.wall_d,
            // The lattice sits in the pockets of a wall row of the same pitch.
            super::bed::Packing::Hexagonal => s.d,
        },
        seed: key.seed,
        initial_speed: match v.packing {
            super::bed::Packing::Random => case.initial_speed,
            super::bed::Packing::Hexagonal => 0.0,
        },
        settle_ke: case.settle_ke,
        max_settle_time: case.max_settle_time,
        dt: case.dt,
        skin: case.skin,
        // Beds are always prepared under g0 (K Sec. III B: "prepared under Earth's
        // gravity"), whatever gravity the impact uses.
        gravity: case.scales.g0,
        coeffs: [g, w, w, w],
    }
}

/// Points on an ellipse with semi-axes (a, b) at equal arc-length spacing.
fn ellipse_outline(a: f64, b: f64, n: usize) -> Vec<[f64; 2]> {
    let fine = 200 * n.max(1);
    let mut pts = Vec::with_capacity(fine + 1);
    let mut len = vec![0.0];
    for k in 0..=fine {
        let t = 2.0 * std::f64::consts::PI * k as f64 / fine as f64;
        pts.push([a * t.cos(), b * t.sin()]);
        if k > 0 {
            let (p, q) = (pts[k - 1], pts[k]);
            len.push(len[k - 1] + ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt());
        }
    }
    let total = len[fine];
    let mut out = Vec::with_capacity(n);
    let mut j = 0;
    for k in 0..n {
        let target = total * k as f64 / n as f64;
        while len[j] < target {
            j += 1;
        }
        out.push(pts[j]);
    }
    out
}

/// The scene of variant `v` on `bed` (the bed of `case.bed_of(v)`; its period is the
/// scene's).
pub fn build(case: &Impact2dCase, v: &Variant, bed: &Bed) -> Result<Scene> {
    let s = &case.scales;
    let l = case.bed_of(v).length;
    let x_imp = 0.5 * l;
    let surface = bed.surface_at(x_imp, l);
    anyhow::ensure!(
        surface.is_finite(),
        "no grain under the impact point x = {x_imp} m"
    );
    let mut disks: Vec<Disk> = bed.grains.clone();
    for g in &mut disks {
        g.type_ = 0;
    }
    let mut next_id = disks.iter().map(|d| d.id).max().unwrap_or(0) + 1;
    for w in &bed.wall {
        disks.push(Disk {
            id: next_id,
            ..w.clone()
        });
        next_id += 1;
    }
    let m = case.intruder_mass;
    let bottom = surface + case.release_height;
    let vel = [0.0, -v.speed];
    let mut intruder = Vec::new();
    let (cluster, height, bottom_offset, intruder_mass) = match case.shape {
        IntruderShape::Disk { radius } => {
            let mass = lammps_mass(m, radius);
            intruder.push(disks.len());
            disks.push(Disk {
                id: next_id,
                type_: 2,
                radius,
                mass,
                x: [x_imp, bottom + radius],
                v: vel,
                omega: 0.0,
                role: Role::Free,
            });
            next_id += 1;
            (None, 2.0 * radius, radius, mass)
        }
        IntruderShape::Ellipse { a, b, count } => {
            // Outline disks of diameter d whose outer envelope is the ellipse (a, b).
            let r = 0.5 * s.d;
            let pts = ellipse_outline(a - r, b - r, count);
            let centre = [x_imp, bottom + b];
            let mass_each = lammps_mass(m / count as f64, r);
            let mut members = Vec::new();
            for p in &pts {
                members.push(disks.len());
                intruder.push(disks.len());
                disks.push(Disk {
                    id: next_id,
                    type_: 2,
                    radius: r,
                    mass: mass_each,
                    x: [centre[0] + p[0], centre[1] + p[1]],
                    v: vel,
                    omega: 0.0,
                    role: Role::Cluster,
                });
                next_id += 1;
            }
            let c = Cluster::new(&mut disks, members, vel);
            let (total, xcm) = (c.mass, c.xcm);
            let bottom_offset = xcm[1] - bottom;
            (Some(c), 2.0 * b, bottom_offset, total)
        }
    };
    let top_y = bottom + height + case.top_gap + 0.5 * case.wall_d;
    let top = wall_row(l, case.wall_d, top_y, next_id);
    disks.extend(top);
    let g = v.grains.coeffs(s);
    let w = if case.walls_as_grains {
        g
    } else {
        v.walls.coeffs(s)
    };
    let i = v.intruder.coeffs(s);
    // Row-major 3x3: grain, wall, intruder.
    let coeffs = vec![g, w, i, w, w, w, i, w, i];
    let bx = Box2 {
        lo: [0.0, 0.0],
        hi: [l, top_y + case.wall_d],
        periodic_x: true,
    };
    let sys = System::new(
        disks, cluster, coeffs, 3, bx, v.gravity, case.dt, case.skin, intruder,
    );
    Ok(Scene {
        sys,
        surface,
        bottom_offset,
        intruder_mass,
    })
}

/// Which bed snapshots a run writes (K Sec. IV): the grains' positions at
/// `position_steps`, and every contact's forces at `contact_steps` (a subset).
#[derive(Debug, Clone, Default)]
pub struct SnapshotSteps {
    pub position_steps: Vec<u64>,
    pub contact_steps: Vec<u64>,
}

/// The bed at the current step of `sys`: grains (type 0) sorted by id, and the touching
/// pairs by atom id if `contacts`.
pub fn field_snapshot(sys: &System, contacts: bool) -> crate::rundata::impact::FieldSnapshot {
    use crate::rundata::impact::{ContactForce, FieldSnapshot, GrainPos};
    let mut grains: Vec<GrainPos> = sys
        .disks
        .iter()
        .filter(|d| d.type_ == 0)
        .map(|d| GrainPos { id: d.id, x: d.x })
        .collect();
    grains.sort_by_key(|g| g.id);
    FieldSnapshot {
        step: sys.step,
        grains,
        contacts: contacts.then(|| {
            sys.contact_forces()
                .into_iter()
                .map(|(i, j, f_n, ft)| ContactForce {
                    i: sys.disks[i].id,
                    j: sys.disks[j].id,
                    f_n,
                    ft,
                })
                .collect()
        }),
    }
}

/// What a native run leaves: intruder samples, energies, bed snapshots.
pub type NativeSeries = (
    Vec<crate::rundata::impact::IntruderSample>,
    Vec<crate::rundata::impact::EnergySample>,
    Vec<crate::rundata::impact::FieldSnapshot>,
);

/// Native run of a scene: intruder samples every `output_every` steps, energies (from
/// the same snapshot function the LAMMPS dumps go through) every `energy_every`, bed
/// snapshots at the steps `snaps` lists.
pub fn run_native(
    scene: &Scene,
    n_steps: u64,
    output_every: u64,
    energy_every: u64,
    model: &super::energy::EnergyModel,
    snaps: &SnapshotSteps,
    mut progress: impl FnMut(u64),
) -> Result<NativeSeries> {
    use super::energy::{SnapDisk, energies};
    use crate::rundata::impact::IntruderSample;
    let mut sys = scene.sys.clone();
    sys.setup();
    let mut samples = Vec::new();
    let mut energy = Vec::new();
    let mut fields = Vec::new();
    loop {
        if snaps.position_steps.contains(&sys.step) {
            fields.push(field_snapshot(
                &sys,
                snaps.contact_steps.contains(&sys.step),
            ));
        }
        if sys.step.is_multiple_of(output_every) {
            let (x, v) = intruder_cm(&sys);
            anyhow::ensure!(x[1].is_finite(), "native run diverged at step {}", sys.step);
            samples.push(IntruderSample {
                step: sys.step,
                t: sys.time(),
                x,
                v,
                f: sys.intruder_contact_force(),
            });
            progress(sys.step);
        }
        if sys.step.is_multiple_of(energy_every) {
            let snap: Vec<SnapDisk> = sys
                .disks
                .iter()
                .map(|d| SnapDisk {
                    type_: d.type_,
                    radius: d.radius,
                    mass: d.mass,
                    x: d.x,
                    v: d.v,
                    omega: d.omega,
                })
                .collect();
            energy.push(energies(sys.step, sys.time(), &snap, model));
        }
        if sys.step >= n_steps {
            break;
        }
        sys.step();
    }
    Ok((samples, energy, fields))
}

/// Intruder centre of mass and velocity (unwrapped in x relative to its first disk).
pub fn intruder_cm(sys: &System) -> ([f64; 2], [f64; 2]) {
    if let Some(c) = &sys.cluster {
        return (c.xcm, c.vcm);
    }
    let k = sys.intruder[0];
    (sys.disks[k].x, sys.disks[k].v)
}

/// The scene with the intruder's velocity multiplied by `factor` (every intruder disk,
/// and a cluster's centre-of-mass velocity): a negative control's wrong impact speed.
pub fn with_intruder_speed(scene: &Scene, factor: f64) -> Scene {
    let mut s = scene.clone();
    for &k in &s.sys.intruder {
        let v = &mut s.sys.disks[k].v;
        *v = [v[0] * factor, v[1] * factor];
    }
    if let Some(c) = &mut s.sys.cluster {
        c.vcm = [c.vcm[0] * factor, c.vcm[1] * factor];
    }
    s
}

/// The scene made wrong on purpose for a negative control (the reference engine always
/// gets the untouched scene): friction model swapped (k_t = 0.8 k_n <-> 0) and/or
/// friction coefficients scaled.
pub fn perturbed(scene: &Scene, pert: &crate::case::Perturbation) -> Scene {
    let mut s = scene.clone();
    for c in &mut s.sys.coeffs {
        if pert.swap_friction_model {
            c.kt = if c.kt > 0.0 { 0.0 } else { 0.8 * c.kn };
        }
        c.mu *= pert.friction_factor;
    }
    s
}
