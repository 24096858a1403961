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
use crate::case::impact2d::{
    BedKey, Impact2dCase, IntruderShape, MIN_TRACERS, TRACER_DEPTH, TRACER_MIN_DISTANCE, Variant,
};
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
    /// Indices (into `sys.disks`) of the disks whose centre of mass in y is the
    /// interface height (K Fig 12), recorded at every intruder sample; empty when the
    /// case does not track the interface.
    pub tracers: Vec<usize>,
}

/// Bed preparation inputs for a bed key (packing, count, length, seed): the case's base
/// grain and wall materials, so every variant of a sweep (e_n, mu, friction, speed,
/// gravity) hits the very same bed and only the impact differs; a `bed` sweep's
/// variants differ only in count, length and seed. With `[bed] settled_with =
/// "variant"` the key carries the variant's own grain and wall materials, which then
/// settle its bed (K's "as in Fig. 2" for a system with static friction: prepared with
/// it).
pub fn bed_spec(case: &Impact2dCase, key: &BedKey) -> BedSpec {
    let s = &case.scales;
    let (g, w) = match &key.settled_with {
        Some(m) => (m.grains.coeffs(s), m.walls.coeffs(s)),
        None => (case.base.grains.coeffs(s), case.base.walls.coeffs(s)),
    };
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
        settle_hold: case.settle_hold,
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
    let tracers = if case.track_interface {
        interface_tracers(&sys, surface, s.d, x_imp, l)
            .map_err(|e| anyhow::anyhow!("{}: variant {}: {e}", case.source.display(), v.label))?
    } else {
        Vec::new()
    };
    Ok(Scene {
        sys,
        surface,
        bottom_offset,
        intruder_mass,
        tracers,
    })
}

/// The interface tracers of K Fig 12 (docs/impact2d.md, rule 1), as indices into
/// `sys.disks`: grains (type 0, free) whose centre lies at or above `surface -
/// TRACER_DEPTH d` and at a periodic horizontal distance of at least
/// `TRACER_MIN_DISTANCE L` from the impact point `x_imp`: the top of the bed on the side
/// opposite the impact, away from the crater, whose motion is the bed's own. Fewer than
/// `MIN_TRACERS` is an error.
pub(crate) fn interface_tracers(
    sys: &System,
    surface: f64,
    d: f64,
    x_imp: f64,
    length: f64,
) -> Result<Vec<usize>> {
    let level = surface - TRACER_DEPTH * d;
    let t: Vec<usize> = (0..sys.disks.len())
        .filter(|&k| {
            let g = &sys.disks[k];
            let dx = (g.x[0] - x_imp).rem_euclid(length);
            g.type_ == 0
                && g.role == Role::Free
                && !sys.intruder.contains(&k)
                && g.x[1] >= level
                && dx.min(length - dx) >= TRACER_MIN_DISTANCE * length
        })
        .collect();
    anyhow::ensure!(
        t.len() >= MIN_TRACERS,
        "{} interface tracer(s) (grains with their centre within {TRACER_DEPTH} d of the \
         surface and at least {TRACER_MIN_DISTANCE} L from the impact point); K Fig 12's \
         interface needs at least {MIN_TRACERS}",
        t.len()
    );
    Ok(t)
}

/// The bottom row of frozen wall disks (below `surface`): the tracers of the
/// `interface_frozen_floor` control, whose height never changes.
pub(crate) fn floor_tracers(sys: &System, surface: f64) -> Vec<usize> {
    (0..sys.disks.len())
        .filter(|&k| sys.disks[k].role == Role::Frozen && sys.disks[k].x[1] < surface)
        .collect()
}

/// Centre of mass in y of the disks `idx`, summed as LAMMPS' `Group::xcm` sums (mass
/// times position, then over the group mass); NaN for an empty set.
pub(crate) fn tracer_height(sys: &System, idx: &[usize]) -> f64 {
    let (mut my, mut m) = (0.0, 0.0);
    for &k in idx {
        let g = &sys.disks[k];
        my += g.x[1] * g.mass;
        m += g.mass;
    }
    my / m
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
pub(crate) fn field_snapshot(
    sys: &System,
    contacts: bool,
) -> crate::rundata::impact::FieldSnapshot {
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
pub(crate) type NativeSeries = (
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
                interface_y: (!scene.tracers.is_empty())
                    .then(|| tracer_height(&sys, &scene.tracers)),
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
pub(crate) fn with_intruder_speed(scene: &Scene, factor: f64) -> Scene {
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
/// friction coefficients scaled; the interface tracked on the frozen floor instead of
/// the tracers (K Fig 12's control). Not a control: the chaos baseline's replica
/// (docs/statistics.md, "The chaos baseline") moves every free disk of the bed by one
/// ulp in x (not a wall disk, not the intruder, which a disk intruder also is).
pub(crate) fn perturbed(scene: &Scene, pert: &crate::case::Perturbation) -> Scene {
    let mut s = scene.clone();
    if pert.interface_frozen_floor {
        s.tracers = floor_tracers(&s.sys, s.surface);
    }
    if pert.nudge_one_ulp {
        let intruder = s.sys.intruder.clone();
        for (k, g) in s.sys.disks.iter_mut().enumerate() {
            if g.role == Role::Free && !intruder.contains(&k) {
                g.x[0] = g.x[0].next_up();
            }
        }
    }
    for c in &mut s.sys.coeffs {
        if pert.swap_friction_model {
            c.kt = if c.kt > 0.0 { 0.0 } else { 0.8 * c.kn };
        }
        c.mu *= pert.friction_factor;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::impact2d::Coeffs;

    fn disk(id: u64, type_: usize, x: [f64; 2], role: Role) -> Disk {
        Disk {
            id,
            type_,
            radius: 0.5,
            mass: 1.0 + id as f64,
            x,
            v: [0.0; 2],
            omega: 0.0,
            role,
        }
    }

    /// L = 40, d = 1, impact at x = 20, surface at 10: tracers are the grains with
    /// their centre at y >= 8 and |x - 20| >= 10 across the periodic side.
    fn system(extra: Vec<Disk>) -> System {
        let mut disks = vec![
            disk(1, 1, [5.0, 0.5], Role::Frozen),
            disk(2, 1, [25.0, 0.5], Role::Frozen),
            disk(3, 1, [5.0, 30.0], Role::Frozen),
        ];
        disks.extend(extra);
        let c = Coeffs {
            kn: 1e3,
            kt: 0.0,
            gamma_n: 10.0,
            gamma_t: 5.0,
            mu: 0.5,
        };
        let intruder = disks
            .iter()
            .position(|g| g.type_ == 2)
            .into_iter()
            .collect();
        System::new(
            disks,
            None,
            vec![c; 9],
            3,
            Box2 {
                lo: [0.0, 0.0],
                hi: [40.0, 31.0],
                periodic_x: true,
            },
            9.81,
            1e-4,
            0.1,
            intruder,
        )
    }

    /// The rule of docs/impact2d.md on a hand-made bed: depth (y >= surface - 2 d, the
    /// boundary included), periodic distance >= L/4 on both sides of the impact and
    /// across x = 0 = L, grains only (no wall disk, not the intruder), at least 10.
    #[test]
    fn tracers_are_the_top_grains_opposite_the_impact() {
        let mut grains = Vec::new();
        let mut id = 10;
        let mut push = |x: f64, y: f64, type_: usize, grains: &mut Vec<Disk>| {
            grains.push(disk(id, type_, [x, y], Role::Free));
            id += 1;
        };
        // Counted: x in [0, 10] or [30, 40), y >= 8.
        let want = [
            (0.2, 9.5),
            (39.9, 9.5),
            (10.0, 8.0),
            (30.0, 8.7),
            (2.0, 9.0),
            (4.0, 9.0),
            (6.0, 9.0),
            (8.0, 9.0),
            (33.0, 9.0),
            (36.0, 9.0),
        ];
        for &(x, y) in &want {
            push(x, y, 0, &mut grains);
        }
        // Not counted: too deep, too close to the impact, or the intruder.
        for &(x, y) in &[
            (2.0, 7.99),
            (10.01, 9.0),
            (29.99, 9.0),
            (20.0, 9.5),
            (15.0, 9.0),
        ] {
            push(x, y, 0, &mut grains);
        }
        push(2.0, 12.0, 2, &mut grains);
        let sys = system(grains.clone());
        let t = interface_tracers(&sys, 10.0, 1.0, 20.0, 40.0).unwrap();
        let got: Vec<[f64; 2]> = t.iter().map(|&k| sys.disks[k].x).collect();
        let want: Vec<[f64; 2]> = want.iter().map(|&(x, y)| [x, y]).collect();
        assert_eq!(got, want);
        // The weighted mean y is LAMMPS' xcm: sum m y / sum m.
        let (my, m) = t.iter().fold((0.0, 0.0), |(a, b), &k| {
            let g = &sys.disks[k];
            (a + g.mass * g.x[1], b + g.mass)
        });
        assert!((tracer_height(&sys, &t) - my / m).abs() < 1e-12);
        // The floor: the bottom wall row only, at a constant height.
        assert_eq!(floor_tracers(&sys, 10.0), vec![0, 1]);
        assert_eq!(tracer_height(&sys, &floor_tracers(&sys, 10.0)), 0.5);
        // One grain fewer: 9 tracers are refused, with the count and the rule.
        grains.remove(0);
        let e = interface_tracers(&system(grains), 10.0, 1.0, 20.0, 40.0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("9 interface tracer(s)") && e.contains("at least 10"),
            "{e}"
        );
    }

    /// The chaos replica (docs/statistics.md) moves every free bed disk by exactly one
    /// ulp in x and nothing else: not y, not a wall disk, not the (free) disk intruder;
    /// without it the scene is the scene.
    #[test]
    fn the_chaos_replica_moves_every_bed_grain_one_ulp_in_x() {
        let mut grains: Vec<Disk> = (0..5)
            .map(|k| disk(10 + k, 0, [3.0 + 7.0 * k as f64, 2.0], Role::Free))
            .collect();
        grains.push(disk(20, 2, [20.0, 12.0], Role::Free));
        let scene = Scene {
            sys: system(grains),
            surface: 10.0,
            bottom_offset: 0.5,
            intruder_mass: 21.0,
            tracers: Vec::new(),
        };
        assert_eq!(scene.sys.intruder, vec![8]);
        let same = perturbed(&scene, &crate::case::Perturbation::default());
        let nudged = perturbed(
            &scene,
            &crate::case::Perturbation {
                nudge_one_ulp: true,
                ..Default::default()
            },
        );
        let mut moved = 0;
        for (k, ((a, s), b)) in scene
            .sys
            .disks
            .iter()
            .zip(&same.sys.disks)
            .zip(&nudged.sys.disks)
            .enumerate()
        {
            assert_eq!(s.x, a.x, "disk {k}");
            assert_eq!(b.x[1], a.x[1], "disk {k}");
            if a.role == Role::Free && k != 8 {
                assert_eq!(b.x[0], a.x[0].next_up(), "disk {k}");
                assert_ne!(b.x[0], a.x[0], "disk {k}");
                moved += 1;
            } else {
                assert_eq!(b.x[0], a.x[0], "disk {k}");
            }
        }
        assert_eq!(moved, 5);
    }
}
