//! The in-process Rust solvers as engines: they take the same inputs as the reference
//! engines and leave the same run data (frames streamed to `particles.csv`, force
//! samples, impact series), each with its provenance.

mod lammps_penetration;

use crate::case::Perturbation;
use crate::case::penetration::PenetrationCase;
use crate::physics::dem::{self, Simulation, packing::Bed};
use crate::physics::dem2d::energy::EnergyModel;
use crate::physics::dem2d::impact::Scene;
use crate::physics::dem2d::impact::{NativeSeries, SnapshotSteps};
use crate::rundata::force::ForceSample;
use crate::rundata::frames::{FrameWriter, JsonlFrameWriter};
use crate::rundata::provenance::{EngineKind, Provenance, Sha256, now_utc};
use anyhow::Result;
use std::path::Path;
use std::time::Instant;

/// The note of a native run under a negative control's perturbation (none for the
/// paper's physics): what `--reuse` compares before it takes an earlier run as this one.
pub(crate) fn perturbation_note(pert: &Perturbation) -> Option<String> {
    (!pert.is_none()).then(|| format!("PERTURBED physics (negative control): {pert:?}"))
}

/// The note naming the granval build (its git commit) that computed a native run, when
/// the build knew it: `--reuse` takes an earlier run only from the same build.
pub(crate) fn build_note() -> Option<String> {
    crate::rundata::provenance::git_commit().map(|c| format!("computed by granval at commit {c}"))
}

/// Provenance of an in-process run that began at `start`.
pub fn provenance(
    input_hash: Sha256,
    case_file: &Path,
    start: Instant,
    what: &str,
    pert: &Perturbation,
    mut notes: Vec<String>,
) -> Provenance {
    if let Some(n) = perturbation_note(pert) {
        notes.insert(0, n);
    }
    notes.extend(build_note());
    Provenance {
        engine: EngineKind::Native,
        version: format!("granval {} native {what}", env!("CARGO_PKG_VERSION")),
        command: "in-process".into(),
        input_hash,
        date: now_utc(),
        wall_time_s: start.elapsed().as_secs_f64(),
        threads: rayon::current_num_threads(),
        case_file: case_file.display().to_string(),
        notes,
    }
}

/// A micro case, every output frame streamed to `csv` (memory does not grow with the
/// number of frames).
pub fn micro(
    case: &crate::case::Case,
    pert: &Perturbation,
    csv: &Path,
    on_step: impl FnMut(u64),
) -> Result<Provenance> {
    let start = Instant::now();
    if case.lammps().is_some() {
        let mut w = FrameWriter::create(csv)?;
        dem::lammps_micro::run(case, *pert, on_step, |f| w.write(&f))?;
        w.finish()?;
    } else if case.clumps.is_empty() {
        let mut w = FrameWriter::create(csv)?;
        dem::run(case, *pert, on_step, |f| w.write(&f))?;
        w.finish()?;
    } else {
        // Bodies do not fit particles.csv: the frames go to frames.jsonl next to it.
        let path = csv.with_file_name(crate::rundata::frames::JSONL_FILE);
        let mut w = JsonlFrameWriter::create(&path)?;
        dem::run(case, *pert, on_step, |f| w.write(&f))?;
        w.finish()?;
    }
    Ok(provenance(
        case.canonical_hash(),
        &case.source,
        start,
        if case.lammps().is_some() {
            "3D DEM, LAMMPS granular laws"
        } else {
            "3D DEM"
        },
        pert,
        vec![],
    ))
}

/// A penetration run from `bed`: the force samples, and `on_snapshot` called after each
/// step listed in `snapshot_steps` (contact snapshots for the stress fields).
pub fn penetration(
    case: &PenetrationCase,
    bed: &Bed,
    pert: &Perturbation,
    snapshot_steps: &[u64],
    on_snapshot: impl FnMut(&Simulation) -> Result<()>,
    on_step: impl FnMut(u64, u64),
) -> Result<(Vec<ForceSample>, Provenance)> {
    anyhow::ensure!(
        case.family == crate::case::family::ContactFamily::Liggghts,
        "{}: models.family = \"lammps\": this is the native engine with LIGGGHTS' laws; a LAMMPS-family case runs in `penetration_lammps_laws`",
        case.source.display()
    );
    let start = Instant::now();
    let samples = dem::penetration::run_with_snapshots(
        case,
        bed,
        *pert,
        snapshot_steps,
        on_snapshot,
        on_step,
    )?;
    let mut notes = vec![dem::packing::bed_note(case, bed)];
    if !snapshot_steps.is_empty() {
        notes.push(format!("snapshots at steps {snapshot_steps:?}"));
    }
    Ok((
        samples,
        provenance(
            case.canonical_hash(),
            &case.source,
            start,
            "3D DEM",
            pert,
            notes,
        ),
    ))
}

/// A penetration run with LAMMPS' laws: `deck`, the LAMMPS 2025 deck of one bed (what
/// `granval deck --engine lammps` writes, [`crate::experiments::penetration::deck_dir::lammps_deck`]),
/// stepped by the native engine with LAMMPS' contact laws, walls and order of operations
/// ([`lammps_penetration`]) under the control `pert`. The force samples are those
/// the deck's `fix print` writes (step 0, then every `force_every` steps).
pub fn penetration_lammps_laws(
    case: &PenetrationCase,
    deck: &crate::engines::liggghts::penetration::PenetrationDeck,
    pert: &Perturbation,
    on_step: impl FnMut(u64, u64),
) -> Result<(Vec<ForceSample>, Provenance)> {
    let start = Instant::now();
    let samples = lammps_penetration::run(deck, pert, on_step)?;
    let notes = vec![format!(
        "the LAMMPS 2025 deck of {} grains (input {}), stepped natively with LAMMPS' laws",
        deck.particles.len(),
        crate::engines::lammps3d_penetration::input_hash(deck)?
    )];
    Ok((
        samples,
        provenance(
            case.canonical_hash(),
            &case.source,
            start,
            "3D DEM, LAMMPS granular laws",
            pert,
            notes,
        ),
    ))
}

/// A 2D impact scene.
#[allow(clippy::too_many_arguments)]
pub fn impact2d(
    scene: &Scene,
    n_steps: u64,
    output_every: u64,
    energy_every: u64,
    energy: &EnergyModel,
    snaps: &SnapshotSteps,
    input_hash: Sha256,
    case_file: &Path,
    pert: &Perturbation,
    on_step: impl FnMut(u64),
) -> Result<(NativeSeries, Provenance)> {
    let start = Instant::now();
    let scene = crate::physics::dem2d::impact::perturbed(scene, pert);
    let (samples, energies, fields) = crate::physics::dem2d::impact::run_native(
        &scene,
        n_steps,
        output_every,
        energy_every,
        energy,
        snaps,
        on_step,
    )?;
    Ok((
        (samples, energies, fields),
        provenance(input_hash, case_file, start, "2D DEM", pert, vec![]),
    ))
}

/// The shear of a compacted triaxial sample (docs/stress.md rule 5) for `steps` steps;
/// the wall records every `output_every` steps, `on_step(step)` every 1000 steps.
pub fn triaxial(
    case: &crate::case::triaxial::TriaxialCase,
    sample: &dem::triaxial::Sample,
    pert: &Perturbation,
    steps: u64,
    mut on_step: impl FnMut(u64),
) -> Result<(Vec<crate::rundata::triaxial::WallRecord>, Provenance)> {
    let start = Instant::now();
    let mut records = Vec::with_capacity((steps / case.output_every) as usize);
    dem::triaxial::shear(case, sample, *pert, steps, |r| {
        if r.step.is_multiple_of(1000) {
            on_step(r.step);
        }
        records.push(*r);
        Ok(())
    })?;
    let p = provenance(
        case.canonical_hash(),
        &case.source,
        start,
        "triaxial",
        pert,
        vec![],
    );
    Ok((records, p))
}
