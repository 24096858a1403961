//! Throughput of the native 2D engine on a Kondic impact scene, and of LAMMPS on the
//! very same scene and number of steps in the same run (docs/performance.md, "The 2D
//! engine"), so machine load hits both alike.
//!
//! ```sh
//! cargo build --release --example impact2d_bench
//! target/release/examples/impact2d_bench cases/release/kondic-fig9-gravity.toml \
//!     reference/release/impact2d/kondic-fig9-gravity 4000 3 --variant 1 --lammps
//! ```
//!
//! The bed is read from the sealed record given (preparing a 6000-disk bed takes
//! minutes). The native engine runs on one thread (as LAMMPS on one process; `--threads
//! T` for more); its time is the CPU time of the stepping thread
//! (`/proc/thread-self/schedstat`, steady under load where wall time is not; with more
//! threads only the wall time counts) and its wall time; LAMMPS' is its own "Loop time"
//! (set-up and start-up not charged). `--warmup W` first runs W native steps and starts
//! both engines from that state. Native and LAMMPS alternate, best of `REPS`.
//! The native end state is printed as a hash of the bits of every disk's position,
//! velocity and spin and of the stored shear, so two builds of the engine can be shown
//! to compute the same run bit for bit.

use anyhow::{Context, Result, bail};
use granval::Impact2dCase;
use granval::engines::lammps::{self, Lammps, Outputs};
use granval::physics::dem2d::impact;
use std::path::{Path, PathBuf};
use std::time::Instant;

fn thread_cpu_s() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .map(|ns| ns * 1e-9)
        .unwrap_or(f64::NAN)
}

/// FNV-1a over the bits of the end state.
fn state_hash(sys: &granval::physics::dem2d::System) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |x: f64| {
        for b in x.to_bits().to_le_bytes() {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    for d in &sys.disks {
        eat(d.x[0]);
        eat(d.x[1]);
        eat(d.v[0]);
        eat(d.v[1]);
        eat(d.omega);
    }
    for s in &sys.list.shear {
        eat(s[0]);
        eat(s[1]);
    }
    h
}

struct Native {
    cpu_s: f64,
    wall_s: f64,
    hash: u64,
    builds: u64,
    pairs: usize,
    touching: usize,
    depth_d: f64,
}

fn run_native(scene: &impact::Scene, steps: u64, d: f64, threads: usize) -> Result<Native> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    pool.install(|| {
        let mut sys = scene.sys.clone();
        sys.setup();
        let (c0, w0) = (thread_cpu_s(), Instant::now());
        for _ in 0..steps {
            sys.step();
        }
        let (cpu_s, wall_s) = (thread_cpu_s() - c0, w0.elapsed().as_secs_f64());
        let (x, _) = impact::intruder_cm(&sys);
        Ok(Native {
            cpu_s,
            wall_s,
            hash: state_hash(&sys),
            builds: sys.list.builds,
            pairs: sys.list.pairs.len(),
            touching: sys.last.iter().filter(|r| r.is_some()).count(),
            depth_d: (scene.surface - (x[1] - scene.bottom_offset)) / d,
        })
    })
}

fn run_lammps(scene: &impact::Scene, case: &Impact2dCase, steps: u64, dir: &Path) -> Result<f64> {
    let out = Outputs {
        n_steps: steps,
        intruder_every: case.output_every,
        snapshot_every: 0,
        header: granval::engines::deck_text::Header {
            title: "granval impact2d_bench: LAMMPS throughput".into(),
            paragraphs: vec![],
        },
        fields: Default::default(),
        tracers: Vec::new(),
    };
    let fin = Lammps::default().run(&scene.sys, &out, dir)?;
    let log = std::fs::read_to_string(dir.join(lammps::LOG_FILE))?;
    granval::bench::loop_time(&log)
        .with_context(|| format!("no Loop time in {}", fin.dir.display()))
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let pos: Vec<&String> = {
        let mut v = Vec::new();
        let mut k = 0;
        while k < args.len() {
            if ["--variant", "--warmup", "--threads"].contains(&args[k].as_str()) {
                k += 2;
                continue;
            }
            if !args[k].starts_with("--") {
                v.push(&args[k]);
            }
            k += 1;
        }
        v
    };
    if pos.len() < 3 {
        bail!(
            "usage: impact2d_bench CASE RECORD_DIR STEPS [REPS] [--variant K] [--warmup W] [--threads T] [--lammps]"
        );
    }
    let variant: usize = match args.iter().position(|a| a == "--variant") {
        Some(k) => args
            .get(k + 1)
            .context("--variant needs a number")?
            .parse()?,
        None => 0,
    };
    let warmup: u64 = match args.iter().position(|a| a == "--warmup") {
        Some(k) => args
            .get(k + 1)
            .context("--warmup needs a number")?
            .parse()?,
        None => 0,
    };
    let threads: usize = match args.iter().position(|a| a == "--threads") {
        Some(k) => args
            .get(k + 1)
            .context("--threads needs a number")?
            .parse()?,
        None => 1,
    };
    let with_lammps = args.iter().any(|a| a == "--lammps");
    let case = Impact2dCase::load(Path::new(pos[0]))?;
    let record = PathBuf::from(pos[1]);
    let steps: u64 = pos[2].parse().context("STEPS")?;
    let reps: usize = pos.get(3).map(|s| s.parse()).transpose()?.unwrap_or(1);
    let v = case
        .variants
        .get(variant)
        .with_context(|| format!("no variant {variant}"))?
        .clone();
    let key = case.bed_of(&v);
    let beds = granval::experiments::impact2d::prepare_beds(&case, false, Some(&record), None)?;
    if !beds.from_record(&key) {
        eprintln!(
            "note: bed not in {}; it was prepared here",
            record.display()
        );
    }
    let mut scene = impact::build(&case, &v, beds.get(&key))?;
    if warmup > 0 {
        // Past the impact, into the long penetration and relaxation that make up most
        // of a run: both engines then start from this state (LAMMPS without the shear
        // history, which `read_data` cannot carry; this changes nothing of the cost).
        let mut sys = scene.sys.clone();
        sys.setup();
        for _ in 0..warmup {
            sys.step();
        }
        println!(
            "warm-up: {warmup} native steps ({:.0} tau_c) before the timed steps",
            warmup as f64 * case.dt / case.scales.tau_c
        );
        scene.sys = sys;
    }
    let n = scene.sys.disks.len();
    let d = case.scales.d;
    println!(
        "case {} variant {} ({} disks), {steps} steps ({:.0} tau_c), best of {reps}",
        case.name,
        v.label,
        n,
        steps as f64 * case.dt / case.scales.tau_c
    );
    let lmp = with_lammps
        .then(|| lammps::installed_version(&lammps::binary()))
        .flatten();
    if with_lammps && lmp.is_none() {
        println!("LAMMPS: not installed (`lmp`), native only");
    }
    let tmp = tempfile::tempdir()?;
    let (mut cpu, mut wall, mut lt) = (Vec::new(), Vec::new(), Vec::new());
    let mut last = None;
    for r in 0..reps {
        let nat = run_native(&scene, steps, d, threads)?;
        println!(
            "  rep {r}: native {:.3} s CPU, {:.3} s wall; hash {:016x}, {} list builds, {} pairs ({} touching), intruder depth {:.3} d",
            nat.cpu_s, nat.wall_s, nat.hash, nat.builds, nat.pairs, nat.touching, nat.depth_d
        );
        cpu.push(nat.cpu_s);
        wall.push(nat.wall_s);
        if let Some(h) = last {
            anyhow::ensure!(h == nat.hash, "native run not reproducible");
        }
        last = Some(nat.hash);
        if lmp.is_some() {
            let t = run_lammps(&scene, &case, steps, &tmp.path().join(format!("lmp{r}")))?;
            println!("  rep {r}: LAMMPS loop time {t:.3} s");
            lt.push(t);
        }
    }
    let best = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    let per = |t: f64| t / (steps as f64 * n as f64) * 1e9;
    println!(
        "native ({threads} thread(s)): {:.3} s CPU ({:.0} steps/s, {:.0} ns per disk-step), {:.3} s wall",
        best(&cpu),
        steps as f64 / best(&cpu),
        per(best(&cpu)),
        best(&wall)
    );
    if let Some(ver) = &lmp {
        println!(
            "LAMMPS {ver} (1 proc): {:.3} s loop ({:.0} steps/s, {:.0} ns per disk-step)",
            best(&lt),
            steps as f64 / best(&lt),
            per(best(&lt))
        );
        println!(
            "native CPU / LAMMPS loop: {:.2}; native wall / LAMMPS loop: {:.2}",
            best(&cpu) / best(&lt),
            best(&wall) / best(&lt)
        );
    }
    println!("end-state hash {:016x}", last.unwrap_or(0));
    Ok(())
}
