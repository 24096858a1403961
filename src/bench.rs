//! `granval bench`: throughput of the native engine and of LIGGGHTS on the same dense
//! settled packing, measured in the same run so machine noise hits both alike.
//!
//! The packing is poured (lattice with jitter, under gravity, into a walled box) and
//! settled by the native engine; both engines then start from exactly that packing.
//! LIGGGHTS' time is its own "Loop time" from the log, so its start-up and file
//! output are not charged to it.

use crate::case::Case;
use crate::case::Perturbation;
use crate::engines::liggghts::{self, Liggghts};
use crate::physics::dem::Simulation;
use crate::rundata::provenance::EngineKind;
use anyhow::{Context, Result};
use std::path::Path;
use std::time::Instant;

pub mod scaling;

/// The bench packing's starting lattice; it lives in the physics layer so the engine's
/// own tests can use it without importing from `bench` (tests/architecture.rs).
pub use crate::physics::dem::packing::lattice_case;

/// Pours and settles the lattice; returns the case with the settled positions and zero
/// velocities, plus the mean kinetic energy ratio reached.
pub fn settled_packing(n: usize, seed: u64, settle_time: f64) -> Result<(Case, f64)> {
    let mut case = lattice_case(n, seed);
    let mut sim = Simulation::from_case(&case);
    sim.setup()?;
    let steps = (settle_time / case.dt).ceil() as u64;
    let mut ke_peak: f64 = 0.0;
    for _ in 0..steps {
        sim.step()?;
        if sim.step.is_multiple_of(100) {
            ke_peak = ke_peak.max(sim.kinetic_energy());
        }
    }
    let ratio = sim.kinetic_energy() / ke_peak.max(f64::MIN_POSITIVE);
    for (p, k) in case.particles.iter_mut().zip(sim.case_order()) {
        p.x = sim.x[k];
    }
    Ok((case, ratio))
}

fn pool(threads: usize) -> Result<rayon::ThreadPool> {
    Ok(rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?)
}

/// Wall time of `steps` steps from `case` (set-up excluded), and the engine's bytes per
/// particle then; `sort`: with the spatial sorting `bench --scaling` measures
/// (off in the engine by default).
fn time_native(case: &Case, steps: u64, threads: usize, sort: bool) -> Result<(f64, f64)> {
    pool(threads)?.install(|| -> Result<(f64, f64)> {
        let mut sim = Simulation::from_case_perturbed(case, Perturbation::default());
        if sort {
            sim.set_reorder(
                crate::physics::dem::reorder::DEFAULT_EVERY,
                crate::physics::dem::reorder::DEFAULT_MIN_PARTICLES,
            );
        }
        sim.setup()?;
        let t = Instant::now();
        for _ in 0..steps {
            sim.step()?;
        }
        let el = t.elapsed().as_secs_f64();
        Ok((el, sim.memory_bytes() as f64 / sim.x.len() as f64))
    })
}

/// "Memory usage per processor = 16.4864 Mbytes" from a LIGGGHTS log (its own estimate
/// of its arrays, not the process's resident size).
pub(crate) fn liggghts_memory_mb(log: &str) -> Option<f64> {
    log.lines().rev().find_map(|l| {
        l.trim()
            .strip_prefix("Memory usage per processor =")?
            .split_whitespace()
            .next()?
            .parse()
            .ok()
    })
}

/// Peak resident size of this process (VmHWM, bytes), if the system reports it.
pub(crate) fn peak_rss_bytes() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let kb: f64 = s
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))?
        .split_whitespace()
        .next()?
        .parse()
        .ok()?;
    Some(kb * 1024.0)
}

/// Minimum, median and maximum of a few timings.
fn spread(v: &[f64]) -> (f64, f64, f64) {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    (s[0], s[s.len() / 2], s[s.len() - 1])
}

fn fmt_times(v: &[f64]) -> String {
    v.iter()
        .map(|t| format!("{t:.2}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Ratios a[k] / b[k] of the rounds, in round order: rounds interleave the engines, so
/// their spread shows how much the load moved a ratio between rounds.
fn round_ratios(a: &[f64], b: &[f64]) -> String {
    a.iter()
        .zip(b)
        .map(|(x, y)| format!("{:.2}", x / y))
        .collect::<Vec<_>>()
        .join(", ")
}

/// "Loop time of 12.3 on 1 procs for 2000 steps with 10000 atoms" from a LIGGGHTS log.
pub fn loop_time(log: &str) -> Option<f64> {
    log.lines().rev().find_map(|l| {
        l.strip_prefix("Loop time of ")?
            .split_whitespace()
            .next()?
            .parse()
            .ok()
    })
}

/// Every timing of one `granval bench` run (seconds for `steps` steps; the figure
/// reported is the best of each list) and the memory per particle.
#[derive(Debug, Clone)]
pub struct BenchResult {
    pub n: usize,
    pub steps: u64,
    pub native_1: Vec<f64>,
    pub native_2: Vec<f64>,
    /// LIGGGHTS' own "Loop time", 1 process (None: LIGGGHTS not installed).
    pub liggghts_1: Option<Vec<f64>>,
    pub liggghts_version: Option<String>,
    /// Bytes per particle of the native engine's arrays.
    pub native_bytes: f64,
    /// LIGGGHTS' own "Memory usage per processor" estimate per particle.
    pub liggghts_bytes: Option<f64>,
}

fn best(v: &[f64]) -> f64 {
    spread(v).0
}

impl BenchResult {
    /// Native 2 threads / native 1 thread.
    pub(crate) fn scaling_2(&self) -> f64 {
        best(&self.native_1) / best(&self.native_2)
    }

    pub fn print(&self) {
        let ps = self.n as f64 * self.steps as f64;
        let (t1, t2) = (best(&self.native_1), best(&self.native_2));
        crate::outln!(
            "native 1 thread : {:>10.3e} particle-steps/s ({t1:.2} s; all: {})",
            ps / t1,
            fmt_times(&self.native_1)
        );
        crate::outln!(
            "native 2 threads: {:>10.3e} particle-steps/s ({t2:.2} s; all: {})",
            ps / t2,
            fmt_times(&self.native_2),
        );
        crate::outln!(
            "ratio native(2 threads) / native(1 thread) = {:.2} (per round: {})",
            self.scaling_2(),
            round_ratios(&self.native_1, &self.native_2)
        );
        crate::outln!(
            "native memory   : {:.0} bytes per particle in the engine's arrays; process peak RSS {:.1} MB",
            self.native_bytes,
            peak_rss_bytes().unwrap_or(f64::NAN) / 1e6
        );
        match (&self.liggghts_1, &self.liggghts_version) {
            (Some(vl), Some(v)) => {
                let tl = best(vl);
                crate::outln!(
                    "liggghts 1 proc : {:>10.3e} particle-steps/s ({tl:.2} s loop time; all: {}; {v})",
                    ps / tl,
                    fmt_times(vl)
                );
                if let Some(b) = self.liggghts_bytes {
                    crate::outln!(
                        "liggghts memory : {b:.0} bytes per particle (its own 'Memory usage per processor' estimate)"
                    );
                }
                crate::outln!(
                    "ratio native(1 thread) / liggghts(1 proc) = {:.2} (per round: {})",
                    tl / t1,
                    round_ratios(vl, &self.native_1)
                );
                crate::outln!(
                    "ratio native(2 threads) / liggghts(1 proc) = {:.2}",
                    tl / t2
                );
            }
            _ => crate::outln!("LIGGGHTS not installed: no ratio measured"),
        }
    }
}

/// `granval bench`: the `n`-sphere packing settled natively, then [`measure_packing`]
/// with `reps` rounds, printed.
pub fn run(n: usize, steps: u64, reps: usize) -> Result<()> {
    let t0 = Instant::now();
    let (case, ke_ratio) = settled_packing(n, 1, 0.15)?;
    crate::outln!(
        "packing: {n} spheres settled natively in {:.1} s (KE now / peak KE = {ke_ratio:.1e}), dt = {:.3e} s",
        t0.elapsed().as_secs_f64(),
        case.dt
    );
    crate::outln!(
        "timing {steps} steps per engine, {reps} repetitions (native 1 thread, 2 threads, LIGGGHTS in turn), best reported"
    );
    measure_packing(&case, steps, reps)?.print();
    Ok(())
}

/// Times `steps` steps from the packing `case` in both engines, `reps` rounds of native 1
/// thread, native 2 threads and LIGGGHTS (1 process) in turn, so noise hits all alike.
pub fn measure_packing(case: &Case, steps: u64, reps: usize) -> Result<BenchResult> {
    let mut case = case.clone();
    case.n_steps = steps;
    case.output_every = steps;
    let version = crate::experiments::reference::probe(EngineKind::Liggghts)?;
    let mut r = BenchResult {
        n: case.particles.len(),
        steps,
        native_1: Vec::new(),
        native_2: Vec::new(),
        liggghts_1: version.as_ref().map(|_| Vec::new()),
        liggghts_version: version,
        native_bytes: f64::NAN,
        liggghts_bytes: None,
    };
    for _ in 0..reps {
        let (t, bytes) = time_native(&case, steps, 1, false)?;
        r.native_1.push(t);
        r.native_bytes = bytes;
        r.native_2.push(time_native(&case, steps, 2, false)?.0);
        if let Some(vl) = &mut r.liggghts_1 {
            let dir = tempfile::tempdir()?;
            liggghts::micro(&Liggghts::default(), &case, dir.path())
                .context("LIGGGHTS bench run")?;
            let log = std::fs::read_to_string(dir.path().join("log.liggghts"))?;
            r.liggghts_bytes = liggghts_memory_mb(&log).map(|mb| mb * 1048576.0 / r.n as f64);
            vl.push(loop_time(&log).context("no 'Loop time' line in the LIGGGHTS log")?);
        }
    }
    Ok(r)
}

/// The case of `granval bench --clumps`: the CI geometry with rigid dimers.
pub const CLUMP_BENCH_CASE: &str = "cases/penetration/ci-dimers.toml";

/// Every timing of one penetration benchmark ([`run_penetration`]; seconds for `steps`
/// steps; the figure reported is the best of each list).
#[derive(Debug, Clone)]
pub struct PenetrationBench {
    /// Spheres the engines integrate (clump members one by one): the particle-steps.
    pub grains: usize,
    pub steps: u64,
    /// Native bed preparation (pour and settle, 2 threads), seconds.
    pub preparation: f64,
    pub native_2: Vec<f64>,
    /// LIGGGHTS `mpirun -np 2`, its own "Loop time".
    pub liggghts_np2: Option<Vec<f64>>,
    pub native_bytes: f64,
    /// LIGGGHTS' own "Memory usage per processor" estimate, per particle, both ranks.
    pub liggghts_bytes: Option<f64>,
}

impl PenetrationBench {
    /// Native 2 threads / LIGGGHTS np 2 (throughput ratio of the best timings).
    pub fn ratio(&self) -> Option<f64> {
        Some(best(self.liggghts_np2.as_ref()?) / best(&self.native_2))
    }

    pub fn print(&self) {
        let ps = self.grains as f64 * self.steps as f64;
        let t2 = best(&self.native_2);
        crate::outln!(
            "native 2 threads : {:>10.3e} particle-steps/s ({t2:.2} s; all: {})",
            ps / t2,
            fmt_times(&self.native_2)
        );
        crate::outln!(
            "native memory    : {:.0} bytes per particle in the engine's arrays; process peak RSS {:.1} MB",
            self.native_bytes,
            peak_rss_bytes().unwrap_or(f64::NAN) / 1e6
        );
        match &self.liggghts_np2 {
            Some(vl) => {
                let tl = best(vl);
                crate::outln!(
                    "liggghts np 2    : {:>10.3e} particle-steps/s ({tl:.2} s loop time; all: {})",
                    ps / tl,
                    fmt_times(vl)
                );
                if let Some(b) = self.liggghts_bytes {
                    crate::outln!(
                        "liggghts memory  : {b:.0} bytes per particle (its own 'Memory usage per processor' estimate, both ranks)"
                    );
                }
                crate::outln!(
                    "ratio native(2 threads) / liggghts(np 2) = {:.2} (per round: {})",
                    tl / t2,
                    round_ratios(vl, &self.native_2)
                );
            }
            None => crate::outln!("LIGGGHTS not installed: no ratio measured"),
        }
    }
}

/// The penetration benchmark: bed 0 of the penetration case `case_path` prepared natively
/// (pour and settle, timed, 2 threads), then the first `steps` steps of its penetration
/// (the whole run if `steps` is larger; the intruder reaches the grains after
/// `start_gap / speed`) timed `reps` times in turn in the native engine (2 threads) and
/// in LIGGGHTS under `mpirun -np 2` (the deck of `granval compare`: same bed, intruder
/// start and speed, force output; LIGGGHTS' own "Loop time", so start-up and reading the
/// bed are not charged to it, as native setup is not). Prints the table and returns the
/// timings.
pub fn run_penetration(case_path: &Path, steps: u64, reps: usize) -> Result<PenetrationBench> {
    use crate::case::penetration::PenetrationCase;
    use crate::physics::dem;
    let case = PenetrationCase::load(case_path)?;
    let t0 = Instant::now();
    let bed =
        pool(2)?.install(|| crate::experiments::penetration::bed::prepare_bed(&case, false))?;
    let preparation = t0.elapsed().as_secs_f64();
    let steps = steps.min(dem::penetration::n_steps(&case, &bed));
    let grains = bed.spheres(&case).len();
    crate::outln!(
        "{} (prepared in {preparation:.1} s, 2 threads){}",
        dem::packing::bed_note(&case, &bed),
        if bed.bodies.is_empty() {
            String::new()
        } else {
            format!(
                "; {} rigid clumps of {} spheres: particle-steps count the spheres",
                bed.bodies.len(),
                grains
            )
        }
    );
    crate::outln!(
        "timing {steps} penetration steps, {reps} repetitions (native 2 threads, LIGGGHTS np 2 in turn), best reported"
    );
    let mut deck = crate::experiments::penetration::bed::liggghts_deck(&case, &bed)?;
    deck.n_steps = steps;
    let have_liggghts = crate::experiments::reference::probe(EngineKind::Liggghts)?.is_some();
    let mut r = PenetrationBench {
        grains,
        steps,
        preparation,
        native_2: Vec::new(),
        liggghts_np2: have_liggghts.then(Vec::new),
        native_bytes: f64::NAN,
        liggghts_bytes: None,
    };
    for _ in 0..reps {
        let (t, bytes) = pool(2)?.install(|| -> Result<(f64, f64)> {
            let mut sim = dem::penetration::simulation(&case, &bed, Perturbation::default())?;
            let mut f = [0.0; 3];
            let t = Instant::now();
            for _ in 0..steps {
                sim.step()?;
                if sim.step.is_multiple_of(case.force_every) {
                    f = sim.intruder_force();
                }
            }
            let el = t.elapsed().as_secs_f64();
            std::hint::black_box(f);
            Ok((el, sim.memory_bytes() as f64 / grains as f64))
        })?;
        r.native_2.push(t);
        r.native_bytes = bytes;
        if let Some(vl) = &mut r.liggghts_np2 {
            let dir = tempfile::tempdir()?;
            liggghts::penetration::run(
                &deck,
                dir.path(),
                2,
                &crate::engines::process::Limits::derived(grains as f64 * steps as f64, None, None),
            )
            .context("LIGGGHTS penetration bench run")?;
            let log = std::fs::read_to_string(dir.path().join("log.liggghts"))?;
            r.liggghts_bytes =
                liggghts_memory_mb(&log).map(|mb| 2.0 * mb * 1048576.0 / grains as f64);
            vl.push(loop_time(&log).context("no 'Loop time' line in the LIGGGHTS log")?);
        }
    }
    r.print();
    Ok(r)
}

#[cfg(test)]
mod tests {
    #[test]
    fn parses_loop_time() {
        let log = "Step Atoms KinEng CPU\nLoop time of 12.75 on 1 procs for 2000 steps with 10000 atoms\n";
        assert_eq!(super::loop_time(log), Some(12.75));
    }

    #[test]
    fn parses_liggghts_memory() {
        let log = "Setting up run ...\nMemory usage per processor = 16.4864 Mbytes\n";
        assert_eq!(super::liggghts_memory_mb(log), Some(16.4864));
    }

    /// The penetration benchmark on the CI bed (several minutes; run with
    /// `cargo test --release --lib bench_penetration_ci -- --ignored --nocapture`).
    #[test]
    #[ignore]
    fn bench_penetration_ci() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let steps = std::env::var("GRANVAL_BENCH_STEPS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(10_000);
        let r = super::run_penetration(&root.join("cases/penetration/ci.toml"), steps, 3).unwrap();
        assert_eq!(r.native_2.len(), 3);
    }
}
