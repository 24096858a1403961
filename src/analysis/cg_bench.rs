//! Throughput of the coarse graining (target: 1e6 contacts onto a 50^3 grid must take
//! seconds): a jittered simple-cubic packing with its nearest-neighbour contacts, shared
//! by `granval cg-bench` and `benches/coarse_grain.rs`.

use super::coarse_grain::{CgParams, CoarseGrainer, Grid3};
use crate::rundata::snapshot::{Contact, ContactKind, Grain, Snapshot, SnapshotMeta};
use anyhow::Result;
use rand::{Rng, SeedableRng};

/// About `n_contacts` contacts (3 per grain: +x, +y, +z neighbours) among grains of
/// diameter `d` on a jittered cubic lattice; forces random but deterministic (seeded).
pub fn synthetic_snapshot(n_contacts: usize, d: f64) -> Snapshot {
    let side = ((n_contacts as f64 / 3.0).cbrt().ceil() as usize).max(2);
    let mut rng = rand::rngs::StdRng::seed_from_u64(4);
    let a = 0.98 * d;
    let idx = |i: usize, j: usize, k: usize| (k * side + j) * side + i;
    let mut grains = Vec::with_capacity(side * side * side);
    for k in 0..side {
        for j in 0..side {
            for i in 0..side {
                let jit = |rng: &mut rand::rngs::StdRng| rng.random_range(-0.005..0.005) * d;
                grains.push(Grain {
                    id: idx(i, j, k) as u64 + 1,
                    x: [
                        i as f64 * a + jit(&mut rng),
                        j as f64 * a + jit(&mut rng),
                        k as f64 * a + jit(&mut rng),
                    ],
                    v: [0.0, 0.0, -0.01],
                    radius: 0.5 * d,
                });
            }
        }
    }
    let mut contacts = Vec::with_capacity(n_contacts);
    'outer: for k in 0..side {
        for j in 0..side {
            for i in 0..side {
                for (di, dj, dk) in [(1, 0, 0), (0, 1, 0), (0, 0, 1)] {
                    if contacts.len() == n_contacts {
                        break 'outer;
                    }
                    let (ni, nj, nk) = (i + di, j + dj, k + dk);
                    if ni >= side || nj >= side || nk >= side {
                        continue;
                    }
                    let (gi, gj) = (&grains[idx(i, j, k)], &grains[idx(ni, nj, nk)]);
                    let b = [gj.x[0] - gi.x[0], gj.x[1] - gi.x[1], gj.x[2] - gi.x[2]];
                    let f = [
                        -b[0] * 1e3 + rng.random_range(-0.1..0.1),
                        -b[1] * 1e3 + rng.random_range(-0.1..0.1),
                        -b[2] * 1e3 + rng.random_range(-0.1..0.1),
                    ];
                    contacts.push(Contact {
                        kind: ContactKind::Pair,
                        i: gi.id,
                        j: gj.id,
                        xi: gi.x,
                        point: [
                            gi.x[0] + 0.5 * b[0],
                            gi.x[1] + 0.5 * b[1],
                            gi.x[2] + 0.5 * b[2],
                        ],
                        branch: b,
                        force: f,
                    });
                }
            }
        }
    }
    Snapshot {
        meta: SnapshotMeta {
            engine: "synthetic".into(),
            step: 0,
            t: 0.0,
            h: 0.0,
            intruder_bottom_z: 1.0,
            intruder_radius: 1.0,
            intruder_vz: 0.0,
            surface_z: side as f64 * a,
            container_radius: side as f64 * a,
            floor_z: 0.0,
            density: 2500.0,
            psi: 0.5,
            mean_diameter: d,
        },
        grains,
        contacts,
    }
}

/// A `n`^3 grid spanning the snapshot's lattice.
pub fn grid_over(snap: &Snapshot, n: usize) -> Grid3 {
    let hi = snap.meta.surface_z;
    Grid3 {
        lo: [0.0; 3],
        spacing: hi / n as f64,
        n: [n; 3],
    }
}

/// Timings (s) of binning + moments and of evaluating every field on the grid.
pub struct CgTiming {
    pub n_contacts: usize,
    pub n_grains: usize,
    pub grid_points: usize,
    pub setup_s: f64,
    pub eval_s: f64,
}

pub fn time_cg(n_contacts: usize, n_grid: usize) -> Result<CgTiming> {
    let d = 2e-3;
    let snap = synthetic_snapshot(n_contacts, d);
    let grid = grid_over(&snap, n_grid);
    let pts = grid.points();
    let t0 = std::time::Instant::now();
    let cg = CoarseGrainer::new(&snap, &snap.contacts, CgParams::from_grain_diameter(d)?)?;
    let setup_s = t0.elapsed().as_secs_f64();
    let t1 = std::time::Instant::now();
    let vals = cg.eval(&pts);
    let eval_s = t1.elapsed().as_secs_f64();
    anyhow::ensure!(
        vals.iter()
            .all(|v| v.stress_kernel.iter().all(|x| x.is_finite())),
        "non-finite stress in the benchmark"
    );
    Ok(CgTiming {
        n_contacts: cg.n_contacts(),
        n_grains: snap.grains.len(),
        grid_points: pts.len(),
        setup_s,
        eval_s,
    })
}
