//! `granval bench --scaling`: throughput against the bed size, from a few thousand
//! grains to paper scale, native (1 and 2 threads) and LIGGGHTS (1 process and
//! `mpirun -np 2`) on the same settled packing in the same run.
//!
//! The packings of large N take minutes to settle, so each is settled once and kept
//! outside the repository (`$GRANVAL_BED_CACHE`, else `<temp>/granval-bench-<uid>`),
//! keyed by N, seed, settling time and granval's version, with the sha256 of the file
//! beside it: a file whose bytes do not hash to it is an error naming the file, never
//! a silently different packing. Steps per N keep the particle-steps per timing about
//! equal, so the sweep runs in minutes.

use super::{best, fmt_times, liggghts_memory_mb, loop_time, pool, round_ratios, time_native};
use crate::case::Case;
use crate::engines::liggghts::{self, Liggghts};
use crate::rundata::provenance::{EngineKind, Sha256};
use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The sizes of the sweep by default: the `granval bench` bed, 4x, 16x and 64x it.
pub const DEFAULT_NS: [usize; 4] = [2_500, 10_000, 40_000, 160_000];

/// Particle-steps per timed run by default: about 1.5 s of one native thread.
pub const DEFAULT_BUDGET: f64 = 2.0e7;

/// Settling time of the packings (s), as `granval bench`.
const SETTLE_TIME: f64 = 0.15;

/// Steps timed at `n` grains: `budget / n`, at least 50 (so the set-up is amortised)
/// and at most 4000.
pub(crate) fn steps_for(n: usize, budget: f64) -> u64 {
    ((budget / n.max(1) as f64).round() as u64).clamp(50, 4000)
}

/// The settled positions of one packing, as cached.
#[derive(Serialize, Deserialize)]
struct CachedPacking {
    granval: String,
    n: usize,
    seed: u64,
    settle_time: f64,
    /// Wall time the settling took when the packing was made (s).
    preparation: f64,
    ke_ratio: f64,
    x: Vec<[f64; 3]>,
}

/// Where packings are cached: `$GRANVAL_BED_CACHE`, else the system temp directory.
pub fn cache_dir() -> PathBuf {
    match std::env::var_os("GRANVAL_BED_CACHE") {
        Some(d) if !d.is_empty() => PathBuf::from(d),
        _ => std::env::temp_dir().join(format!("granval-bench-{}", uid())),
    }
}

/// The user id, so two users of one machine do not share a cache directory.
fn uid() -> String {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("Uid:"))
                .and_then(|l| l.split_whitespace().next().map(String::from))
        })
        .unwrap_or_else(|| "user".into())
}

fn cache_file(dir: &Path, n: usize, seed: u64) -> PathBuf {
    dir.join(format!(
        "bench-packing-{}-n{n}-seed{seed}-settle{SETTLE_TIME}.json",
        env!("CARGO_PKG_VERSION")
    ))
}

/// A settled packing of `n` spheres (seed `seed`): read from `dir` when cached there
/// (its sha256 checked), else settled natively on two threads and stored. Returns the
/// case, the preparation time when it was made, and whether it came from the cache.
pub fn packing(dir: &Path, n: usize, seed: u64) -> Result<(Case, f64, bool)> {
    let file = cache_file(dir, n, seed);
    let seal = file.with_extension("json.sha256");
    let mut case = super::lattice_case(n, seed);
    if file.exists() {
        let what = "a cached bench packing";
        let bytes = crate::rundata::fsio::read(&file, crate::rundata::fsio::MAX_RECORD_JSON, what)?;
        let want = crate::rundata::fsio::read_to_string(&seal, 1024, "its sha256")
            .with_context(|| format!("{}: no readable seal beside it", file.display()))?;
        let got = Sha256::of(&bytes);
        if got.hex() != want.trim() {
            bail!(
                "{}: sha256 {} differs from its seal {} ({}): the cached packing was changed; remove both files and granval settles it again",
                file.display(),
                got.hex(),
                want.trim(),
                seal.display()
            );
        }
        let c: CachedPacking = serde_json::from_slice(&bytes)
            .with_context(|| format!("{}: not a bench packing", file.display()))?;
        if c.n != n || c.seed != seed || c.x.len() != case.particles.len() {
            bail!(
                "{}: holds {} grains of seed {}, {} of seed {seed} expected",
                file.display(),
                c.x.len(),
                c.seed,
                n
            );
        }
        for (p, x) in case.particles.iter_mut().zip(&c.x) {
            p.x = *x;
        }
        return Ok((case, c.preparation, true));
    }
    let t0 = Instant::now();
    let (settled, ke_ratio) = pool(2)?.install(|| super::settled_packing(n, seed, SETTLE_TIME))?;
    let preparation = t0.elapsed().as_secs_f64();
    case = settled;
    let c = CachedPacking {
        granval: env!("CARGO_PKG_VERSION").into(),
        n,
        seed,
        settle_time: SETTLE_TIME,
        preparation,
        ke_ratio,
        x: case.particles.iter().map(|p| p.x).collect(),
    };
    let bytes = serde_json::to_vec(&c)?;
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    crate::rundata::fsio::write_atomic(&file, &bytes)?;
    crate::rundata::fsio::write_atomic(&seal, Sha256::of(&bytes).hex().as_bytes())?;
    Ok((case, preparation, false))
}

/// What the sweep runs.
#[derive(Debug, Clone)]
pub struct ScalingOptions {
    pub ns: Vec<usize>,
    pub budget: f64,
    pub reps: usize,
    pub seed: u64,
    /// Also time the native engine with spatial sorting off (the engine before it),
    /// interleaved with the sorted runs.
    pub unsorted: bool,
    /// Run LIGGGHTS too (when installed).
    pub liggghts: bool,
    pub cache: PathBuf,
}

/// Timings (s) of one N; the figure reported is the best of each list.
#[derive(Debug, Clone)]
pub struct ScalingRow {
    pub n: usize,
    pub steps: u64,
    pub preparation: f64,
    pub cached: bool,
    pub native_1: Vec<f64>,
    pub native_2: Vec<f64>,
    /// Sorting off (only with [`ScalingOptions::unsorted`]).
    pub unsorted_1: Vec<f64>,
    pub unsorted_2: Vec<f64>,
    pub liggghts_1: Vec<f64>,
    pub liggghts_2: Vec<f64>,
    pub native_bytes: f64,
    pub unsorted_bytes: f64,
    pub liggghts_bytes_1: Option<f64>,
    pub liggghts_bytes_2: Option<f64>,
}

fn time_liggghts(case: &Case, procs: usize) -> Result<(f64, Option<f64>)> {
    let dir = tempfile::tempdir()?;
    let lig = Liggghts {
        mpi_procs: procs,
        ..Liggghts::default()
    };
    liggghts::micro(&lig, case, dir.path())
        .with_context(|| format!("LIGGGHTS bench run, {procs} process(es)"))?;
    let log = std::fs::read_to_string(dir.path().join("log.liggghts"))?;
    let n = case.particles.len() as f64;
    let bytes = liggghts_memory_mb(&log).map(|mb| procs as f64 * mb * 1048576.0 / n);
    Ok((
        loop_time(&log).context("no 'Loop time' line in the LIGGGHTS log")?,
        bytes,
    ))
}

/// Runs the sweep, printing each N's table as soon as it is measured.
pub fn run(opts: &ScalingOptions) -> Result<Vec<ScalingRow>> {
    let version = if opts.liggghts {
        crate::experiments::reference::probe(EngineKind::Liggghts)?
    } else {
        None
    };
    crate::outln!(
        "scaling sweep: N = {:?}, {} rounds (native 1 thread, 2 threads{}{} in turn), best reported; packings cached in {}",
        opts.ns,
        opts.reps,
        if opts.unsorted {
            ", the same unsorted"
        } else {
            ""
        },
        match &version {
            Some(v) => format!(", LIGGGHTS 1 process, mpirun -np 2; {v}"),
            None => ", no LIGGGHTS".into(),
        },
        opts.cache.display()
    );
    let mut rows = Vec::new();
    for &n in &opts.ns {
        let (mut case, preparation, cached) = packing(&opts.cache, n, opts.seed)?;
        let steps = steps_for(n, opts.budget);
        case.n_steps = steps;
        case.output_every = steps;
        let mut r = ScalingRow {
            n,
            steps,
            preparation,
            cached,
            native_1: Vec::new(),
            native_2: Vec::new(),
            unsorted_1: Vec::new(),
            unsorted_2: Vec::new(),
            liggghts_1: Vec::new(),
            liggghts_2: Vec::new(),
            native_bytes: f64::NAN,
            unsorted_bytes: f64::NAN,
            liggghts_bytes_1: None,
            liggghts_bytes_2: None,
        };
        for _ in 0..opts.reps {
            let (t, b) = time_native(&case, steps, 1, true)?;
            r.native_1.push(t);
            r.native_bytes = b;
            if opts.unsorted {
                let (t, b) = time_native(&case, steps, 1, false)?;
                r.unsorted_1.push(t);
                r.unsorted_bytes = b;
            }
            r.native_2.push(time_native(&case, steps, 2, true)?.0);
            if opts.unsorted {
                r.unsorted_2.push(time_native(&case, steps, 2, false)?.0);
            }
            if version.is_some() {
                let (t, b) = time_liggghts(&case, 1)?;
                r.liggghts_1.push(t);
                r.liggghts_bytes_1 = b;
                let (t, b) = time_liggghts(&case, 2)?;
                r.liggghts_2.push(t);
                r.liggghts_bytes_2 = b;
            }
        }
        r.print();
        rows.push(r);
    }
    Ok(rows)
}

impl ScalingRow {
    pub fn print(&self) {
        let ps = self.n as f64 * self.steps as f64;
        crate::outln!(
            "\nN = {} ({} steps; packing {} {:.1} s)",
            self.n,
            self.steps,
            if self.cached {
                "from the cache, settled in"
            } else {
                "settled now in"
            },
            self.preparation
        );
        let line = |name: &str, v: &[f64]| {
            if !v.is_empty() {
                crate::outln!(
                    "  {name:<22}: {:>10.3e} particle-steps/s ({:.2} s; all: {})",
                    ps / best(v),
                    best(v),
                    fmt_times(v)
                );
            }
        };
        line("native 1 thread", &self.native_1);
        line("native 2 threads", &self.native_2);
        line("unsorted 1 thread", &self.unsorted_1);
        line("unsorted 2 threads", &self.unsorted_2);
        line("liggghts 1 process", &self.liggghts_1);
        line("liggghts mpirun -np 2", &self.liggghts_2);
        let ratio = |name: &str, a: &[f64], b: &[f64]| {
            if !a.is_empty() && !b.is_empty() {
                crate::outln!(
                    "  {name:<42} = {:.2} (per round: {})",
                    best(b) / best(a),
                    round_ratios(b, a)
                );
            }
        };
        ratio(
            "native 2 threads / native 1 thread",
            &self.native_2,
            &self.native_1,
        );
        ratio(
            "native 1 thread / liggghts 1 process",
            &self.native_1,
            &self.liggghts_1,
        );
        ratio(
            "native 2 threads / liggghts np 2",
            &self.native_2,
            &self.liggghts_2,
        );
        ratio(
            "liggghts np 2 / liggghts 1 process",
            &self.liggghts_2,
            &self.liggghts_1,
        );
        ratio(
            "sorted / unsorted, 1 thread",
            &self.native_1,
            &self.unsorted_1,
        );
        ratio(
            "sorted / unsorted, 2 threads",
            &self.native_2,
            &self.unsorted_2,
        );
        ratio(
            "unsorted 2 threads / unsorted 1 thread",
            &self.unsorted_2,
            &self.unsorted_1,
        );
        ratio(
            "unsorted 1 thread / liggghts 1 process",
            &self.unsorted_1,
            &self.liggghts_1,
        );
        crate::outln!(
            "  memory per particle: native {:.0} B{}{}{}",
            self.native_bytes,
            if self.unsorted_bytes.is_nan() {
                String::new()
            } else {
                format!(" (unsorted {:.0} B)", self.unsorted_bytes)
            },
            self.liggghts_bytes_1
                .map(|b| format!(", liggghts 1 process {b:.0} B"))
                .unwrap_or_default(),
            self.liggghts_bytes_2
                .map(|b| format!(", liggghts np 2 {b:.0} B (both ranks)"))
                .unwrap_or_default()
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_keep_the_particle_steps_and_their_bounds() {
        assert_eq!(steps_for(10_000, 2.0e7), 2000);
        assert_eq!(steps_for(160_000, 2.0e7), 125);
        assert_eq!(steps_for(10_000_000, 2.0e7), 50);
        assert_eq!(steps_for(100, 2.0e7), 4000);
    }

    /// The sweep's plumbing on tiny beds, native only: one row per N with every
    /// timing, the packing settled once and then read from the cache bit for bit, and
    /// a cached file changed behind its seal refused with its name.
    #[test]
    fn sweep_caches_packings_and_refuses_a_changed_one() {
        let dir = tempfile::tempdir().unwrap();
        let opts = ScalingOptions {
            ns: vec![60, 90],
            budget: 3000.0,
            reps: 2,
            seed: 3,
            unsorted: true,
            liggghts: false,
            cache: dir.path().to_path_buf(),
        };
        let rows = run(&opts).unwrap();
        assert_eq!(rows.len(), 2);
        for (r, n) in rows.iter().zip([60, 90]) {
            assert_eq!(r.n, n);
            assert!(!r.cached);
            assert_eq!(r.steps, 50);
            for v in [&r.native_1, &r.native_2, &r.unsorted_1, &r.unsorted_2] {
                assert_eq!(v.len(), 2);
            }
            assert!(r.liggghts_1.is_empty() && r.native_bytes > 0.0);
        }
        let (fresh, _, cached) = packing(dir.path(), 60, 3).unwrap();
        assert!(cached);
        let (settled, _) = super::super::settled_packing(60, 3, SETTLE_TIME).unwrap();
        for (a, b) in fresh.particles.iter().zip(&settled.particles) {
            assert_eq!(a.x, b.x);
        }
        let file = cache_file(dir.path(), 60, 3);
        let mut bytes = std::fs::read(&file).unwrap();
        let k = bytes.iter().position(|b| b.is_ascii_digit()).unwrap();
        bytes[k] = if bytes[k] == b'1' { b'2' } else { b'1' };
        std::fs::write(&file, bytes).unwrap();
        let err = packing(dir.path(), 60, 3).unwrap_err().to_string();
        assert!(
            err.contains(&file.display().to_string()) && err.contains("differs from its seal"),
            "{err}"
        );
    }
}
