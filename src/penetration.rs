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

/// The LIGGGHTS deck of a penetration case started from `bed` (identical grains,
/// container, intruder start and speed as the native run).
pub fn liggghts_deck(
    case: &PenetrationCase,
    bed: &Bed,
) -> Result<crate::engines::liggghts::penetration::PenetrationDeck> {
    use crate::engines::liggghts::penetration::{PenetrationDeck, Units};
    let (lo, hi) = packing::domain(case, dem::penetration::box_top(case, bed));
    // LIGGGHTS refuses E < 5e6 Pa (Table 2's G = 1 MPa gives E = 2.6 MPa) in SI *and* in
    // cgs (5e7 barye). Its own `soft_particles yes` lifts only that range check; the
    // material is written unchanged, never stiffened.
    let soft = case.materials.iter().any(|m| m.youngs_modulus < 5e6);
    let hard = case.materials.iter().any(|m| m.youngs_modulus > 1e9);
    Ok(PenetrationDeck {
        units: Units::Si,
        materials: case.materials.clone(),
        pairs: case.pairs.clone(),
        rolling: case.rolling,
        dt: case.dt,
        gravity: case.gravity,
        container_radius: case.container_radius,
        floor_z: 0.0,
        domain_lo: lo,
        domain_hi: hi,
        particles: bed.particles.clone(),
        intruder_radius: case.intruder_radius,
        intruder_length: case.intruder_length,
        intruder_type: case.intruder_type,
        intruder_bottom_z0: dem::penetration::start_z(case, bed),
        speed: case.speed,
        n_steps: dem::penetration::n_steps(case, bed),
        force_every: case.force_every,
        neighbor_skin: case.neighbor_skin,
        rim_error_frac: 0.01,
        wall_type: case.wall_type,
        soft_particles: soft,
        hard_particles: hard,
    })
}

/// Runs the case in LIGGGHTS from the natively prepared bed, in `dir`.
pub fn run_liggghts(
    case: &PenetrationCase,
    bed: &Bed,
    dir: &Path,
    mpi_procs: usize,
) -> Result<PenetrationRun> {
    let deck = liggghts_deck(case, bed)?;
    std::fs::create_dir_all(dir)?;
    let (samples, mut provenance) = crate::engines::liggghts::penetration::run(
        &deck,
        dir,
        mpi_procs,
        std::time::Duration::from_secs(3600),
    )?;
    provenance.notes.push(packing::bed_note(case, bed));
    Ok(PenetrationRun {
        samples: samples
            .iter()
            .map(|s| ForceSample {
                t: s.t,
                z_bottom: s.z_bottom,
                f: s.f,
            })
            .collect(),
        provenance,
    })
}

/// Reads a `force.csv` written by [`write_force_csv`].
pub fn read_force_csv(path: &Path) -> Result<Vec<ForceSample>> {
    let mut r =
        csv::Reader::from_path(path).with_context(|| format!("cannot open {}", path.display()))?;
    let mut out = Vec::new();
    for (k, rec) in r.records().enumerate() {
        let rec = rec.with_context(|| format!("{}: record {}", path.display(), k + 2))?;
        let v = |i: usize| -> Result<f64> {
            rec[i].parse::<f64>().with_context(|| {
                format!(
                    "{}: line {}: column {} = {:?}",
                    path.display(),
                    k + 2,
                    i + 1,
                    &rec[i]
                )
            })
        };
        out.push(ForceSample {
            t: v(0)?,
            z_bottom: v(1)?,
            f: [v(2)?, v(3)?, v(4)?],
        });
    }
    Ok(out)
}

/// Fingerprint of a bed (positions, radii, velocities), so a recorded LIGGGHTS run is
/// only ever compared with a native run from the very same grains.
pub fn bed_hash(bed: &Bed) -> String {
    let mut bytes = Vec::with_capacity(bed.particles.len() * 80);
    for p in &bed.particles {
        for v in
            p.x.iter()
                .chain(&p.v)
                .chain(&p.omega)
                .chain(std::iter::once(&p.radius))
        {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    sha256_hex(&bytes)
}

/// Native vs LIGGGHTS (live, or recorded under `reference/penetration/<name>/` for this
/// very bed) for one penetration case; outputs under `out_dir`.
pub fn compare_case(
    case: &PenetrationCase,
    opts: &crate::pipeline::Options,
    out_dir: &Path,
) -> crate::pipeline::CaseResult {
    use crate::compare::{Check, penetration as cp};
    let fail = |what: &str, e: anyhow::Error| crate::pipeline::CaseResult {
        checks: vec![Check::error(
            format!("{}: {what}", case.name),
            format!("{e:#}"),
        )],
        run: None,
        notes: vec![],
        errored: true,
    };
    let bed = match prepare_bed(case, opts.progress) {
        Ok(b) => b,
        Err(e) => return fail("bed preparation", e),
    };
    let hash = bed_hash(&bed);
    let mut notes = vec![format!(
        "{} (bed sha256 {hash})",
        packing::bed_note(case, &bed)
    )];
    let native = match run_native(case, &bed, opts.native.perturbation, opts.progress) {
        Ok(r) => r,
        Err(e) => return fail("native run", e),
    };
    let rec_dir = opts.reference_root.join("penetration").join(&case.name);
    let reference = if crate::engines::liggghts::installed_version("liggghts").is_some() {
        run_liggghts(case, &bed, &out_dir.join("liggghts"), opts.mpi_procs.max(2))
            .map(|r| (r, "live".to_string()))
    } else if opts.require_live {
        Err(anyhow::anyhow!(
            "LIGGGHTS is not installed but live engines are required"
        ))
    } else {
        (|| {
            let provenance =
                crate::engines::output::read_provenance(&rec_dir.join("provenance.json"))?;
            anyhow::ensure!(
                provenance.engine == "liggghts",
                "{}: not a LIGGGHTS record",
                rec_dir.display()
            );
            anyhow::ensure!(
                provenance.notes.iter().any(|n| n.contains(&hash)),
                "{}: recorded from a different bed than the one prepared now (sha256 {hash}); run `granval reference refresh --suite penetration`",
                rec_dir.display()
            );
            let samples = read_force_csv(&rec_dir.join("force.csv"))?;
            notes.push(format!("LIGGGHTS is not installed here: {} was compared against the RECORDED LIGGGHTS run in {} ({})", case.name, rec_dir.display(), provenance.version));
            Ok((
                PenetrationRun {
                    samples,
                    provenance,
                },
                format!("recorded {}", rec_dir.display()),
            ))
        })()
    };
    let (reference, source) = match reference {
        Ok(r) => r,
        Err(e) => return fail("reference run", e),
    };
    let mut checks = Vec::new();
    let mut errored = false;
    let obs = |run: &PenetrationRun| cp::observables(case, &run.samples, bed.surface_z, bed.psi);
    match (obs(&native), obs(&reference)) {
        (Ok(a), Ok(b)) => {
            checks.extend(cp::compare(case, &a, &b));
            let _ = std::fs::create_dir_all(out_dir);
            let _ = crate::analysis::fdr::write_csv(
                &out_dir.join("fdr_native.csv"),
                &a.fdr,
                Some(&a.fit),
            );
            let _ = crate::analysis::fdr::write_csv(
                &out_dir.join("fdr_liggghts.csv"),
                &b.fdr,
                Some(&b.fit),
            );
            if let Err(e) = crate::report::svg::fdr_overlay(
                &out_dir.join("fdr.svg"),
                &[
                    ("native", &a.fdr.h, &a.fdr.p, Some(&a.fit)),
                    ("LIGGGHTS", &b.fdr.h, &b.fdr.p, Some(&b.fit)),
                ],
                &format!("{}: force-depth relation", case.name),
            ) {
                notes.push(format!("SVG not written: {e:#}"));
            }
        }
        (a, b) => {
            errored = true;
            checks.push(Check::error(
                format!("{}: observables", case.name),
                format!("native: {:?}; reference: {:?}", a.err(), b.err()),
            ));
        }
    }
    for (name, run) in [("native", &native), ("liggghts", &reference)] {
        let d = out_dir.join(name);
        let _ = std::fs::create_dir_all(&d);
        if write_force_csv(&d.join("force.csv"), &run.samples)
            .and_then(|_| {
                crate::engines::output::write_provenance(
                    &d.join("provenance.json"),
                    &run.provenance,
                )
            })
            .is_err()
        {
            errored = true;
        }
    }
    errored |= checks.iter().any(|c| c.metric == "error");
    crate::pipeline::CaseResult {
        checks,
        run: Some(crate::report::CaseRun {
            case: case.name.clone(),
            case_file: case.source.display().to_string(),
            test_engine: "native".into(),
            reference_engine: reference.provenance.engine.clone(),
            reference_version: reference.provenance.version.clone(),
            reference_source: source,
            wall_time_test_s: native.provenance.wall_time_s,
            wall_time_reference_s: reference.provenance.wall_time_s,
        }),
        notes,
        errored,
    }
}
