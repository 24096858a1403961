//! Profiling driver for the native 3D engine (docs/performance.md): prepares the two
//! profiled workloads once, stores their state, and replays a chosen number of steps
//! from it, so a profiler (callgrind) sees only the steps.
//!
//! ```text
//! dem_profile bench-pack N FILE              settle the `granval bench` packing, store it
//! dem_profile bench-run N FILE STEPS THREADS time STEPS steps from it
//! dem_profile bench N FILE STEPS REPS        `granval bench` on the stored packing
//! dem_profile pen-bench CASE STEPS REPS      the penetration benchmark (bench.rs)
//! dem_profile bench-liggghts N FILE STEPS DIR  the same in LIGGGHTS (1 process)
//! dem_profile ci-prep CASE BED MID            prepare bed 0 of a penetration case (timed
//!                                            per phase), store the bed in BED, penetrate
//!                                            it fully (timed) and store the state at
//!                                            half depth in MID
//! dem_profile ci-pour CASE STEPS THREADS      time the first STEPS steps of the pour
//! dem_profile ci-run CASE STATE STEPS THREADS time STEPS penetration steps from a state
//! ```
//! Every mode prints the per-phase wall times of `Simulation::step`. With
//! `DEM_PROFILE_UNSORTED=1` the engine never sorts its particles in space (the engine
//! before spatial sorting), for before/after comparisons from one build.

use anyhow::{Context, Result, bail};
use granval::case::penetration::PenetrationCase;
use granval::physics::dem::intruder::FlatCylinder;
use granval::physics::dem::packing::{self, Bed};
use granval::physics::dem::{Simulation, StepTimes};
use std::io::{Read, Write};
use std::path::Path;
use std::time::Instant;

/// Stored state: step, intruder bottom z (NaN: none), then x, v, omega per particle in
/// case order (whatever order the engine stores them in).
fn save(path: &Path, step: u64, z: f64, sim: &Simulation) -> Result<()> {
    let mut b = Vec::new();
    b.extend_from_slice(&(sim.x.len() as u64).to_le_bytes());
    b.extend_from_slice(&step.to_le_bytes());
    b.extend_from_slice(&z.to_le_bytes());
    for k in sim.case_order() {
        for v in sim.x[k].iter().chain(&sim.v[k]).chain(&sim.omega[k]) {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::File::create(path)?.write_all(&b)?;
    Ok(())
}

struct State {
    step: u64,
    z: f64,
    xvw: Vec<[f64; 9]>,
}

fn load(path: &Path) -> Result<State> {
    let mut b = Vec::new();
    std::fs::File::open(path)
        .with_context(|| path.display().to_string())?
        .read_to_end(&mut b)?;
    let word = |k: usize| <[u8; 8]>::try_from(&b[8 * k..8 * k + 8]).unwrap();
    let n = u64::from_le_bytes(word(0)) as usize;
    let step = u64::from_le_bytes(word(1));
    let z = f64::from_le_bytes(word(2));
    let xvw = (0..n)
        .map(|p| std::array::from_fn(|c| f64::from_le_bytes(word(3 + 9 * p + c))))
        .collect();
    Ok(State { step, z, xvw })
}

fn print_times(label: &str, t: &StepTimes, n: usize) {
    let tot = t.total();
    let ps = n as f64 * t.steps as f64;
    println!(
        "{label}: {} steps, {:.3} s in step(), {:.3e} particle-steps/s, {:.1} ns per particle-step",
        t.steps,
        tot,
        ps / tot,
        1e9 * tot / ps
    );
    for (name, v) in [
        ("integrate", t.integrate),
        ("neighbor", t.neighbor),
        ("pairs", t.pairs),
        ("gather", t.gather),
    ] {
        println!("  {name:<13} {v:>9.3} s  {:>5.1} %", 100.0 * v / tot);
    }
}

/// CPU time of the calling thread (s), from the scheduler's own accounting: on a shared
/// machine a single-threaded pass is timed by the CPU it got, not the wall clock.
fn thread_cpu() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(f64::NAN, |ns| ns * 1e-9)
}

/// CPU time of every thread of the process (s).
fn all_threads_cpu() -> f64 {
    let mut total = 0.0;
    if let Ok(dir) = std::fs::read_dir("/proc/self/task") {
        for e in dir.flatten() {
            if let Ok(s) = std::fs::read_to_string(e.path().join("schedstat"))
                && let Some(ns) = s
                    .split_whitespace()
                    .next()
                    .and_then(|v| v.parse::<f64>().ok())
            {
                total += ns * 1e-9;
            }
        }
    }
    total
}

fn pool(threads: usize) -> Result<rayon::ThreadPool> {
    Ok(rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?)
}

/// The penetration simulation of `case` started from a stored state.
/// Spatial sorting (off by default in the engine) on, unless `DEM_PROFILE_UNSORTED=1`.
fn sort_policy(sim: &mut Simulation) {
    if !std::env::var("DEM_PROFILE_UNSORTED").is_ok_and(|v| v == "1") {
        sim.set_reorder(
            granval::physics::dem::reorder::DEFAULT_EVERY,
            granval::physics::dem::reorder::DEFAULT_MIN_PARTICLES,
        );
    }
}

fn pen_sim(case: &PenetrationCase, st: &State) -> Result<Simulation> {
    let mut particles = packing::lattice(case)?;
    for (p, s) in particles.iter_mut().zip(&st.xvw) {
        p.x = [s[0], s[1], s[2]];
        p.v = [s[3], s[4], s[5]];
        p.omega = [s[6], s[7], s[8]];
    }
    let bed = bed_of(case, particles);
    let top = granval::physics::dem::penetration::box_top(case, &bed);
    let sim_case = packing::container_case(case, bed.particles, top);
    let mut sim = Simulation::from_case(&sim_case);
    sort_policy(&mut sim);
    let z = if st.z.is_nan() {
        granval::physics::dem::penetration::start_z(case, &bed_of(case, sim_case.particles))
    } else {
        st.z
    };
    sim.set_intruder(
        FlatCylinder::new(case.intruder_radius, case.intruder_length, [0.0, 0.0, z]),
        [0.0, 0.0, -case.speed],
        case.intruder_type,
    );
    sim.setup_settled()?;
    sim.step = st.step;
    Ok(sim)
}

fn bed_of(case: &PenetrationCase, particles: Vec<granval::case::Particle>) -> Bed {
    let surface_z = packing::surface_height(case, &packing::grain_spheres(case, &particles, &[]));
    Bed {
        psi: packing::packing_fraction(case, &particles, &[], surface_z),
        particles,
        bodies: Vec::new(),
        surface_z,
        ke_ratio: f64::NAN,
        settle_time: f64::NAN,
        ke_at_end_of_pour: f64::NAN,
    }
}

fn main() -> Result<()> {
    let a: Vec<String> = std::env::args().collect();
    let arg = |k: usize| -> Result<&str> {
        a.get(k)
            .map(|s| s.as_str())
            .context("missing argument (see the module doc)")
    };
    match arg(1)? {
        "bench-pack" => {
            let n: usize = arg(2)?.parse()?;
            let t = Instant::now();
            let (case, ratio) = granval::bench::settled_packing(n, 1, 0.15)?;
            println!(
                "settled {n} in {:.1} s, KE ratio {ratio:.1e}",
                t.elapsed().as_secs_f64()
            );
            let mut sim = Simulation::from_case(&case);
            sort_policy(&mut sim);
            sim.setup()?;
            save(Path::new(arg(3)?), 0, f64::NAN, &sim)?;
        }
        "bench-run" => {
            let n: usize = arg(2)?.parse()?;
            let st = load(Path::new(arg(3)?))?;
            let steps: u64 = arg(4)?.parse()?;
            let threads: usize = arg(5)?.parse()?;
            let mut case = granval::bench::lattice_case(n, 1);
            for (p, s) in case.particles.iter_mut().zip(&st.xvw) {
                p.x = [s[0], s[1], s[2]];
            }
            pool(threads)?.install(|| -> Result<()> {
                let mut sim = Simulation::from_case(&case);
                sort_policy(&mut sim);
                sim.setup()?;
                let (t, c, ca) = (Instant::now(), thread_cpu(), all_threads_cpu());
                for _ in 0..steps {
                    sim.step()?;
                }
                println!(
                    "wall {:.3} s, cpu of this thread {:.3} s, of all threads {:.3} s, {} pairs, {} neighbour builds",
                    t.elapsed().as_secs_f64(),
                    thread_cpu() - c,
                    all_threads_cpu() - ca,
                    sim.n_pairs(),
                    sim.neighbor_builds()
                );
                print_times("bench", &sim.step_times(), n);
                println!(
                    "  memory {:.0} bytes per particle",
                    sim.memory_bytes() as f64 / n as f64
                );
                Ok(())
            })?;
        }
        "bench" => {
            // `granval bench` on the stored packing (skips the 15 s settle).
            let n: usize = arg(2)?.parse()?;
            let st = load(Path::new(arg(3)?))?;
            let steps: u64 = arg(4)?.parse()?;
            let reps: usize = arg(5)?.parse()?;
            let mut case = granval::bench::lattice_case(n, 1);
            for (p, s) in case.particles.iter_mut().zip(&st.xvw) {
                p.x = [s[0], s[1], s[2]];
            }
            granval::bench::measure_packing(&case, steps, reps)?.print();
        }
        "pen-bench" => {
            let steps: u64 = arg(3)?.parse()?;
            let reps: usize = arg(4)?.parse()?;
            granval::bench::run_penetration(Path::new(arg(2)?), steps, reps)?;
        }
        "bench-liggghts" => {
            // The same packing in LIGGGHTS (1 process), as `granval bench` runs it.
            let n: usize = arg(2)?.parse()?;
            let st = load(Path::new(arg(3)?))?;
            let steps: u64 = arg(4)?.parse()?;
            let dir = Path::new(arg(5)?);
            let mut case = granval::bench::lattice_case(n, 1);
            for (p, s) in case.particles.iter_mut().zip(&st.xvw) {
                p.x = [s[0], s[1], s[2]];
            }
            case.n_steps = steps;
            case.output_every = steps;
            granval::engines::liggghts::micro(
                &granval::engines::liggghts::Liggghts::default(),
                &case,
                dir,
            )?;
            let log = std::fs::read_to_string(dir.join("log.liggghts"))?;
            println!("LIGGGHTS loop time {:?} s", granval::bench::loop_time(&log));
        }
        "ci-prep" => {
            let case = PenetrationCase::load(Path::new(arg(2)?))?;
            // packing::prepare, step for step, with the phase times kept.
            let sim_case = packing::pour_case(&case)?;
            let mut sim = Simulation::from_case(&sim_case);
            sort_policy(&mut sim);
            let t = Instant::now();
            sim.setup()?;
            let (ratio, _) = packing::settle(&mut sim, &case, |_, _| {})?;
            println!(
                "prepared in {:.1} s wall ({} steps, KE ratio {ratio:.2e}, {} pairs at the end, {} builds)",
                t.elapsed().as_secs_f64(),
                sim.step,
                sim.n_pairs(),
                sim.neighbor_builds()
            );
            print_times("preparation", &sim.step_times(), sim.x.len());
            // Stored in case (id) order, as packing::prepare returns the bed.
            save(Path::new(arg(3)?), 0, f64::NAN, &sim)?;
            let st = load(Path::new(arg(3)?))?;
            let mut pen = pen_sim(&case, &st)?;
            let bed = bed_of(&case, {
                let mut ps = packing::lattice(&case)?;
                for (p, s) in ps.iter_mut().zip(&st.xvw) {
                    p.x = [s[0], s[1], s[2]];
                }
                ps
            });
            let total = granval::physics::dem::penetration::n_steps(&case, &bed);
            let t = Instant::now();
            for _ in 0..total {
                pen.step()?;
                if pen.step == total / 2 {
                    let z = pen.intruder().unwrap().body.bottom_z();
                    save(Path::new(arg(4)?), pen.step, z, &pen)?;
                }
            }
            println!(
                "penetrated in {:.1} s wall ({total} steps, {} pairs at the end, {} builds)",
                t.elapsed().as_secs_f64(),
                pen.n_pairs(),
                pen.neighbor_builds()
            );
            print_times("penetration", &pen.step_times(), pen.x.len());
        }
        "ci-pour" => {
            // The first STEPS steps of bed preparation (pouring from the lattice).
            let case = PenetrationCase::load(Path::new(arg(2)?))?;
            let steps: u64 = arg(3)?.parse()?;
            let threads: usize = arg(4)?.parse()?;
            pool(threads)?.install(|| -> Result<()> {
                let sim_case = packing::pour_case(&case)?;
                let mut sim = Simulation::from_case(&sim_case);
                sort_policy(&mut sim);
                sim.setup()?;
                let (t, c) = (Instant::now(), thread_cpu());
                for _ in 0..steps {
                    sim.step()?;
                }
                println!(
                    "wall {:.3} s, cpu of this thread {:.3} s, {} pairs, {} neighbour builds",
                    t.elapsed().as_secs_f64(),
                    thread_cpu() - c,
                    sim.n_pairs(),
                    sim.neighbor_builds()
                );
                print_times("pour", &sim.step_times(), sim.x.len());
                Ok(())
            })?;
        }
        "ci-run" => {
            let case = PenetrationCase::load(Path::new(arg(2)?))?;
            let st = load(Path::new(arg(3)?))?;
            let steps: u64 = arg(4)?.parse()?;
            let threads: usize = arg(5)?.parse()?;
            pool(threads)?.install(|| -> Result<()> {
                let mut sim = pen_sim(&case, &st)?;
                let (t, c) = (Instant::now(), thread_cpu());
                for _ in 0..steps {
                    sim.step()?;
                }
                println!(
                    "wall {:.3} s, cpu of this thread {:.3} s, {} pairs, {} neighbour builds",
                    t.elapsed().as_secs_f64(),
                    thread_cpu() - c,
                    sim.n_pairs(),
                    sim.neighbor_builds()
                );
                print_times("penetration", &sim.step_times(), sim.x.len());
                println!(
                    "  memory {:.0} bytes per particle",
                    sim.memory_bytes() as f64 / sim.x.len() as f64
                );
                Ok(())
            })?;
        }
        m => bail!("unknown mode {m} (see the module doc)"),
    }
    Ok(())
}
