//! The penetration experiment end to end (issue 3): bed preparation, runs, FDR.
//! Engine-agnostic pieces live in `analysis::fdr`; this module wires them.

use crate::case::penetration::PenetrationCase;
use crate::dem::packing::{self, Bed};
use crate::dem::{self, Perturbation};
use crate::engines::output::{ForceSample, Provenance, now_utc, sha256_hex};
use anyhow::{Context, Result};
use std::io::Write;
use std::path::Path;

pub struct PenetrationRun {
    pub samples: Vec<ForceSample>,
    pub provenance: Provenance,
}

/// Writes `force.csv` (t, z_bottom, fx, fy, fz; SI, full precision).
pub fn write_force_csv(path: &Path, samples: &[ForceSample]) -> Result<()> {
    let mut w = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?,
    );
    writeln!(w, "t,z_bottom,fx,fy,fz")?;
    for s in samples {
        writeln!(
            w,
            "{:e},{:e},{:e},{:e},{:e}",
            s.t, s.z_bottom, s.f[0], s.f[1], s.f[2]
        )?;
    }
    Ok(())
}

/// Prepares the bed natively (pour + settle to the case's KE criterion).
pub fn prepare_bed(case: &PenetrationCase, progress: bool) -> Result<Bed> {
    let bar = crate::report::progress::bar(progress, 1, "settle");
    let bed = packing::prepare(case, |t, ratio| {
        bar.set_message(format!("t = {t:.3} s, KE ratio {ratio:.1e}"))
    })?;
    bar.finish_and_clear();
    Ok(bed)
}

pub fn run_native(
    case: &PenetrationCase,
    bed: &Bed,
    pert: Perturbation,
    progress: bool,
) -> Result<PenetrationRun> {
    let start = std::time::Instant::now();
    let bar =
        crate::report::progress::bar(progress, dem::penetration::n_steps(case, bed), "native");
    let samples = dem::penetration::run(case, bed, pert, |s, _| bar.set_position(s))?;
    bar.finish_and_clear();
    Ok(PenetrationRun {
        samples,
        provenance: Provenance {
            engine: "native".into(),
            version: format!("granval {} native DEM", env!("CARGO_PKG_VERSION")),
            command: "in-process".into(),
            input_hash: sha256_hex(&std::fs::read(&case.source).unwrap_or_default()),
            date: now_utc(),
            wall_time_s: start.elapsed().as_secs_f64(),
            threads: rayon::current_num_threads(),
            case_file: case.source.display().to_string(),
            notes: vec![packing::bed_note(case, bed)],
        },
    })
}
