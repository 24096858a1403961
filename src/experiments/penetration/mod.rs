//! Quasi-static penetration (Feng et al. Sec. 2-3): one unit per bed of the ensemble
//! (`[ensemble] beds`, seeds `seed + k`), each prepared natively and penetrated by both
//! engines from exactly the same grains. A single bed at CI scale gives K_phi only to
//! about +-15 % (two correct engines started from the same bed diverge grain by grain
//! within milliseconds), so the checks compare the ensemble-mean FDRs.
//!
//! With the stress option (`granval stress`, or a suite entry with `stress = true`)
//! both engines also take contact snapshots at the same steps; [`stress`] turns them
//! into the stress fields, phi and the MALT checks. Snapshots are never recorded under
//! `reference/` (several GB per run): against a record, only what the native snapshots
//! decide alone is checked (the native phi against a published value, the native MALT
//! distances); the phi gate native vs LIGGGHTS needs a live LIGGGHTS.
//!
//! Output layout of `compare`: `OUT/bed-K/liggghts/` (the LIGGGHTS deck directory of
//! bed K with its outputs), `OUT/bed-K/native/` (force.csv, provenance.json, snapshots),
//! `OUT/fdr_*.csv`, `OUT/fdr.svg`, and with stress the fields and `k_phi.svg`.

pub mod agreement;
pub mod bed;
mod chaos;
pub mod deck_dir;
pub(crate) mod inputs;
pub(crate) mod run_seal;
pub mod stress;

use super::reference::Verified;
use super::{DeckFiles, Derived, Estimate, Experiment, Options, Role, Run, Verdict};
use crate::analysis::stress_fields::{BedRun, SnapshotPlan};
use crate::case::penetration::PenetrationCase;
use crate::compare::{Check, penetration as cp};
use crate::engines::liggghts::penetration as lp;
use crate::physics::dem::packing::{self, Bed};
use crate::rundata::force::write_force_csv;
use crate::rundata::provenance::{
    EngineKind, Provenance, Sha256, read_provenance, write_provenance,
};
use anyhow::{Context, Result, ensure};
use bed::{EngineRun, binner, liggghts_deck, prepare_bed};
use std::path::{Path, PathBuf};

/// What the stress analysis needs of `bed` and of the native run of `case` from it
/// (the analysis layer knows no engine, so the run's start height and steps are given).
pub fn bed_run(case: &PenetrationCase, bed: &Bed) -> BedRun {
    BedRun {
        surface_z: bed.surface_z,
        psi: bed.psi,
        start_z: crate::physics::dem::penetration::start_z(case, bed),
        n_steps: crate::physics::dem::penetration::n_steps(case, bed),
    }
}

pub const PROVENANCE_FILE: &str = "provenance.json";
pub const FORCE_CSV: &str = "force.csv";
/// Where a run keeps its contact snapshots (stress option).
pub const SNAPSHOT_DIR: &str = "snapshots";

pub struct Penetration {
    pub case: PenetrationCase,
    /// Take contact snapshots and gate the stress fields too.
    pub stress: bool,
    /// The reference engine: LIGGGHTS (the papers' code), or LAMMPS 2025 on the same
    /// natively prepared beds (`granval compare --engine lammps`; docs/lammps-laws.md,
    /// "Penetration in LAMMPS 2025"), live only and without the stress option.
    pub reference: EngineKind,
}

/// One bed of the ensemble.
pub struct Unit {
    pub k: usize,
    /// The case with this bed's seed.
    pub case: PenetrationCase,
    pub bed: Bed,
    pub bed_hash: Sha256,
    /// The bed was read from the sealed record (stored there when the reference run was
    /// recorded) instead of being settled again.
    pub bed_from_record: bool,
    /// Snapshot steps (stress option).
    pub plan: Option<SnapshotPlan>,
    /// Snapshot steps of the estimator study's extra run (`granval stress --study`).
    pub study_plan: Option<SnapshotPlan>,
}

pub struct NativeRun {
    pub run: EngineRun,
    /// At `[quasi_static] speed` (main runs only).
    pub slow: Option<EngineRun>,
    pub snapshots: Option<PathBuf>,
    /// Snapshots of the estimator study's extra run (`DIR/study/snapshots`).
    pub study_snapshots: Option<PathBuf>,
}

pub struct RefRun {
    pub run: EngineRun,
    pub snapshots: Option<PathBuf>,
    /// Snapshots of the estimator study's extra run (`DIR/study/snapshots`).
    pub study_snapshots: Option<PathBuf>,
}

/// Where a unit's estimator-study run goes, inside the engine's run directory.
pub(crate) const STUDY_DIR: &str = "study";

impl Run for NativeRun {
    fn provenance(&self) -> &Provenance {
        &self.run.provenance
    }
}

impl Run for RefRun {
    fn provenance(&self) -> &Provenance {
        &self.run.provenance
    }
}

pub(crate) fn bed_dir_name(k: usize) -> String {
    format!("bed-{k}")
}

/// A native run of `case` from `bed` (force series reduced while kept for force.csv),
/// with snapshots into `dir/snapshots` when a plan is given.
fn native_run(
    case: &PenetrationCase,
    bed: &Bed,
    role: Role,
    plan: Option<&SnapshotPlan>,
    dir: &Path,
    progress: bool,
    reuse: bool,
) -> Result<EngineRun> {
    let nudged;
    let bed = if role.perturbation().nudge_one_ulp {
        nudged = bed.nudged_one_ulp();
        &nudged
    } else {
        bed
    };
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    if reuse && let Some(run) = reuse_native(case, bed, &role.perturbation(), plan, dir)? {
        return Ok(run);
    }
    let n = crate::physics::dem::penetration::n_steps(case, bed);
    let bar = crate::report::progress::bar(progress, n, "native");
    if case.lammps().is_some() {
        // LAMMPS' laws: the LAMMPS deck of this bed, stepped natively.
        ensure!(
            plan.is_none(),
            "{}: models.family = \"lammps\": contact snapshots (stress fields) are not written by the native engine with LAMMPS' laws",
            case.source.display()
        );
        let deck = deck_dir::lammps_deck(case, bed)?;
        let (samples, mut provenance) = crate::engines::native::penetration_lammps_laws(
            case,
            &deck,
            &role.perturbation(),
            |s, _| bar.set_position(s),
        )?;
        bar.finish_and_clear();
        provenance.notes.push(packing::bed_note(case, bed));
        write_force_csv(&dir.join(FORCE_CSV), &samples)?;
        write_provenance(&dir.join(PROVENANCE_FILE), &provenance)?;
        let mut b = binner(case, bed)?;
        for s in &samples {
            b.push(s.z_bottom, s.f[2])?;
        }
        return Ok(EngineRun {
            fdr: b.fdr(),
            samples: b.samples(),
            provenance,
            force_file: Some(dir.join(FORCE_CSV)),
        });
    }
    let snap_dir = dir.join(SNAPSHOT_DIR);
    let steps = plan.map(|p| p.steps.clone()).unwrap_or_default();
    let (samples, provenance) = crate::engines::native::penetration(
        case,
        bed,
        &role.perturbation(),
        &steps,
        |sim| stress::write_native_snapshot(case, bed, plan, &snap_dir, sim),
        |s, _| bar.set_position(s),
    )?;
    bar.finish_and_clear();
    if let Some(p) = plan {
        p.write(&snap_dir)?;
    }
    write_force_csv(&dir.join(FORCE_CSV), &samples)?;
    write_provenance(&dir.join(PROVENANCE_FILE), &provenance)?;
    let mut b = binner(case, bed)?;
    for s in &samples {
        b.push(s.z_bottom, s.f[2])?;
    }
    Ok(EngineRun {
        fdr: b.fdr(),
        samples: b.samples(),
        provenance,
        force_file: Some(dir.join(FORCE_CSV)),
    })
}

/// `--reuse` of a run whose snapshots followed another plan (other depths or windows)
/// would analyse different fields: refused.
fn check_reused_plan(plan: &SnapshotPlan, snap_dir: &Path) -> Result<()> {
    let stored = SnapshotPlan::read(snap_dir).with_context(|| {
        format!(
            "{}: --reuse found no snapshot plan; run without --reuse",
            snap_dir.display()
        )
    })?;
    ensure!(
        &stored == plan,
        "{}: --reuse: these snapshots were taken in windows {:?} (depth: snapshots), the case asks for {:?}; run without --reuse",
        snap_dir.display(),
        stored
            .windows
            .iter()
            .map(|w| (w.h_target, w.steps.len()))
            .collect::<Vec<_>>(),
        plan.windows
            .iter()
            .map(|w| (w.h_target, w.steps.len()))
            .collect::<Vec<_>>()
    );
    Ok(())
}

/// `--reuse`: an earlier native run of this very case and bed in `dir` (its provenance
/// names the case's canonical hash and the bed; its snapshots follow the same plan), or
/// `None` when there is nothing complete to reuse.
fn reuse_native(
    case: &PenetrationCase,
    bed: &Bed,
    pert: &crate::case::Perturbation,
    plan: Option<&SnapshotPlan>,
    dir: &Path,
) -> Result<Option<EngineRun>> {
    let (force, prov) = (dir.join(FORCE_CSV), dir.join(PROVENANCE_FILE));
    if !force.exists() || !prov.exists() {
        return Ok(None);
    }
    if let Some(p) = plan {
        check_reused_plan(p, &dir.join(SNAPSHOT_DIR))?;
    }
    let mut provenance = read_provenance(&prov)?;
    // The same physics (a control's perturbation, or none) and the same build, or the
    // run is not this one.
    let perturbed = provenance.notes.iter().find(|n| n.starts_with("PERTURBED"));
    let wanted = crate::engines::native::perturbation_note(pert);
    ensure!(
        perturbed == wanted.as_ref(),
        "{}: --reuse found a run under other physics ({}; this run is {}); run without --reuse",
        dir.display(),
        perturbed.map_or("the case's own physics", |s| s.as_str()),
        wanted.as_deref().unwrap_or("the case's own physics")
    );
    let build = crate::engines::native::build_note().with_context(|| {
        format!(
            "{}: --reuse: this granval was built without its git commit, so it cannot tell its own runs from another build's; run without --reuse",
            dir.display()
        )
    })?;
    ensure!(
        provenance.notes.contains(&build),
        "{}: --reuse found a run computed by another granval build ({}; this is {build}); run without --reuse",
        dir.display(),
        provenance
            .notes
            .iter()
            .find(|n| n.starts_with("computed by granval"))
            .map_or("no commit recorded", |s| s.as_str())
    );
    let bed_note = packing::bed_note(case, bed);
    ensure!(
        provenance.input_hash == case.canonical_hash()
            && provenance
                .notes
                .iter()
                .any(|n| packing::same_bed_note(n, &bed_note)),
        "{}: --reuse found a run of another case or bed; run without --reuse",
        dir.display()
    );
    let mut b = binner(case, bed)?;
    for s in crate::rundata::force::read_force_csv(&force)? {
        b.push(s.z_bottom, s.f[2])?;
    }
    provenance
        .notes
        .push(format!("reused from {}", dir.display()));
    Ok(Some(EngineRun {
        fdr: b.fdr(),
        samples: b.samples(),
        provenance,
        force_file: Some(force),
    }))
}

/// Reduces a finished LIGGGHTS run in `dir` (made here, recorded, or brought back from
/// a cluster) while reading its force file.
pub fn reduce_liggghts_dir(case: &PenetrationCase, bed: &Bed, dir: &Path) -> Result<EngineRun> {
    let deck = if deck_dir::settles_in_liggghts(dir) {
        bed::liggghts_settle_deck(case)?
    } else {
        liggghts_deck(case, bed)?
    };
    let mut b = binner(case, bed)?;
    let mut provenance = lp::read_outputs(&deck, dir, |s| b.push(s.z_bottom, s.f[2]))
        .with_context(|| format!("LIGGGHTS run in {}", dir.display()))?;
    bed::push_bed_notes(&mut provenance, case, bed);
    Ok(EngineRun {
        fdr: b.fdr(),
        samples: b.samples(),
        provenance,
        force_file: Some(dir.join(lp::FORCE_FILE)),
    })
}

/// One LIGGGHTS run of unit `u` in `dir`, with contact snapshots at the steps of `plan`
/// (converted into `dir/snapshots`); with `--reuse`, an earlier run of the same deck and
/// plan in `dir` is read instead.
fn liggghts_run(
    case: &PenetrationCase,
    u: &Unit,
    plan: Option<&SnapshotPlan>,
    dir: &Path,
    opts: &Options,
    limits: &crate::engines::process::Limits,
) -> Result<RefRun> {
    let deck = liggghts_deck(&u.case, &u.bed)?;
    std::fs::create_dir_all(dir)?;
    // A run counts as done only when its snapshots were converted (the plan file is
    // written last): a run killed midway leaves a partial force file and is run again.
    if opts.reuse
        && let Some(plan) = plan
        && dir.join(lp::FORCE_FILE).exists()
        && dir
            .join(SNAPSHOT_DIR)
            .join(crate::analysis::stress_fields::PLAN_FILE)
            .exists()
    {
        check_reused_plan(plan, &dir.join(SNAPSHOT_DIR)).with_context(|| format!("bed {}", u.k))?;
        let on_disk = crate::rundata::fsio::read_to_string(
            &dir.join(lp::DECK_FILE),
            crate::rundata::fsio::max_engine_output(),
            "a LIGGGHTS deck",
        )
        .unwrap_or_default();
        ensure!(
            crate::engines::deck_text::same_input(
                &on_disk,
                &lp::deck_text_with_snapshots(&deck, &plan.steps)?
            ),
            "{}: --reuse found a LIGGGHTS run of another case or bed (its deck differs); run without --reuse",
            dir.display()
        );
        let mut run = reduce_liggghts_dir(&u.case, &u.bed, dir)?;
        run.provenance
            .notes
            .push(format!("reused from {}", dir.display()));
        return Ok(RefRun {
            run,
            snapshots: Some(dir.join(SNAPSHOT_DIR)),
            study_snapshots: None,
        });
    }
    let np = opts.mpi_procs.max(2);
    let bar = crate::report::progress::bar(opts.progress, deck.n_steps, "LIGGGHTS");
    let mut b = binner(&u.case, &u.bed)?;
    let mut provenance = match plan {
        None => lp::run_streaming(
            &deck,
            dir,
            np,
            limits,
            |step| bar.set_position(step),
            |s| b.push(s.z_bottom, s.f[2]),
        )?,
        Some(plan) => {
            let (samples, prov) = lp::run_with_snapshots(&deck, dir, np, limits, &plan.steps)?;
            for s in &samples {
                b.push(s.z_bottom, s.f[2])?;
            }
            prov
        }
    };
    bar.finish_and_clear();
    inputs::InputManifest::of_dir(dir, case, u.k, u.case.seed, Some(u.bed_hash.clone()))?
        .write(dir)?;
    bed::push_bed_notes(&mut provenance, &u.case, &u.bed);
    if !u.bed.bodies.is_empty() {
        provenance
            .notes
            .push(clump_start_note(&u.case, &u.bed, dir, np)?);
    }
    let snapshots = match plan {
        Some(plan) => Some(stress::convert_liggghts_snapshots(
            &u.case,
            &u.bed,
            plan,
            &deck,
            dir,
            &mut provenance,
        )?),
        None => None,
    };
    write_provenance(&dir.join(PROVENANCE_FILE), &provenance)?;
    Ok(RefRun {
        run: EngineRun {
            fdr: b.fdr(),
            samples: b.samples(),
            provenance,
            force_file: Some(dir.join(lp::FORCE_FILE)),
        },
        snapshots,
        study_snapshots: None,
    })
}

/// One LAMMPS 2025 run of unit `u` in `dir` from the deck `granval deck --engine lammps`
/// writes for the same bed, its force file reduced by the same binner as LIGGGHTS'.
fn lammps_run(
    case: &PenetrationCase,
    u: &Unit,
    dir: &Path,
    limits: crate::engines::process::Limits,
) -> Result<RefRun> {
    use crate::engines::lammps3d;
    let binary = lammps3d::binary().with_context(|| {
        format!(
            "{}=none: LAMMPS 2025 is switched off, but the comparison runs it",
            lammps3d::ENV_VAR
        )
    })?;
    let lmp = lammps3d::Lammps3d { binary, limits };
    let deck = deck_dir::lammps_deck(&u.case, &u.bed)?;
    let (lines, mut provenance) =
        crate::engines::lammps3d_penetration::run(&lmp, &deck, dir, &case.source)?;
    let mut b = binner(&u.case, &u.bed)?;
    for l in &lines {
        b.push(l.z_bottom, l.f[2])?;
    }
    inputs::InputManifest::of_dir(dir, case, u.k, u.case.seed, Some(u.bed_hash.clone()))?
        .write(dir)?;
    bed::push_bed_notes(&mut provenance, &u.case, &u.bed);
    write_provenance(&dir.join(PROVENANCE_FILE), &provenance)?;
    Ok(RefRun {
        run: EngineRun {
            fdr: b.fdr(),
            samples: b.samples(),
            provenance,
            force_file: Some(dir.join(crate::engines::lammps3d_penetration::FORCE_FILE)),
        },
        snapshots: None,
        study_snapshots: None,
    })
}

/// How far LIGGGHTS' bodies at step 0 of the penetration (its start dump) are from the
/// native engine's start from the same bed: zero when the insertion was exact and the
/// native start reproduces LIGGGHTS' insertion step and run boundary.
pub fn clump_start_difference(
    case: &PenetrationCase,
    bed: &Bed,
    dir: &Path,
) -> Result<crate::engines::liggghts::clump_bed::StartDifference> {
    use crate::engines::liggghts::clump_bed;
    let lig = clump_bed::read_start(dir, &bed.bodies)?;
    let sim = crate::physics::dem::penetration::simulation(
        case,
        bed,
        crate::case::Perturbation::default(),
    )?;
    clump_bed::StartDifference::between(&sim.frame().bodies, &lig)
}

fn clump_start_note(case: &PenetrationCase, bed: &Bed, dir: &Path, np: usize) -> Result<String> {
    let d = clump_start_difference(case, bed, dir)
        .with_context(|| format!("start state of the clump bed in {}", dir.display()))?;
    Ok(format!(
        "clump bed start, LIGGGHTS ({np} process(es)) vs native, {} bodies: {}",
        bed.bodies.len(),
        d.text()
    ))
}

impl Penetration {
    /// The experiment of `case` against LIGGGHTS, the reference engine of penetration
    /// cases unless `compare --engine lammps` names LAMMPS, with stress fields or not.
    pub fn against_liggghts(case: PenetrationCase, stress: bool) -> Penetration {
        Penetration {
            case,
            stress,
            reference: EngineKind::Liggghts,
        }
    }

    /// The paths that exist for LIGGGHTS as the reference only: with LAMMPS, `what` is
    /// refused by name rather than read as if it were LIGGGHTS'.
    fn liggghts_only(&self, what: &str) -> Result<()> {
        ensure!(
            self.reference == EngineKind::Liggghts,
            "{}: {what} exists for LIGGGHTS as the reference only, not for {}; compare with LAMMPS live (`granval compare --engine lammps`)",
            self.case.source.display(),
            self.reference
        );
        Ok(())
    }

    /// A negative control whose gates include a stress gate (phi, published phi, MALT)
    /// needs the snapshots too: its native run takes them (stress option only).
    fn control_takes_snapshots(&self, role: Role) -> bool {
        let Role::Control(p) = role else {
            return false;
        };
        self.stress
            && self.case.negative_controls.iter().any(|c| {
                c.perturbation == *p
                    && c.must_fail.iter().any(|g| {
                        matches!(
                            g,
                            crate::compare::Gate::Phi
                                | crate::compare::Gate::MaltK
                                | crate::compare::Gate::MaltPhi
                                | crate::compare::Gate::UnifiedFit
                        ) || (*g == crate::compare::Gate::Published
                            && self.case.published_phi.is_some())
                    })
            })
    }
}

impl Experiment for Penetration {
    type Unit = Unit;
    type NativeRun = NativeRun;
    type RefRun = RefRun;
    type Case = PenetrationCase;

    fn case(&self) -> &PenetrationCase {
        &self.case
    }
    fn kind(&self) -> &'static str {
        "penetration"
    }
    fn reference_engine(&self) -> EngineKind {
        self.reference
    }
    fn probe_reference(&self) -> Result<Option<String>> {
        match self.reference {
            EngineKind::Lammps => crate::engines::lammps3d::probe_reference(),
            e => super::reference::probe(e),
        }
    }

    fn estimate(&self) -> Estimate {
        let c = &self.case;
        // Spheres the engines integrate: clump members count one by one.
        let n = (c.count * c.clump.as_ref().map_or(1, |t| t.radii.len())) as f64;
        let travel = c.start_gap + c.final_depth + c.diameter.max();
        let steps = travel / c.speed / c.dt;
        let slow = c.quasi_static_speed.map_or(0.0, |v| travel / v / c.dt);
        let controls = c.negative_controls.len() as f64;
        let beds = c.ensemble_beds as f64;
        Estimate {
            // Penetration runs plus settling (of the order of max_settle_time).
            particle_steps: beds * n * (steps * (1.0 + controls) + slow + c.max_settle_time / c.dt),
            particles: n,
            output_bytes: beds * (3.0 + controls) * 100.0 * steps / c.force_every as f64
                + if self.stress {
                    beds * 2.0 * 60.0 * 300.0 * n * 4.0
                } else {
                    0.0
                },
            memory_bytes: 3e3 * n + 2e8,
        }
    }

    fn preflight(&self) -> Result<()> {
        if self.reference == EngineKind::Lammps {
            let src = self.case.source.display();
            ensure!(
                !self.stress,
                "{src}: the stress option with LAMMPS as the reference is not built (LAMMPS writes no contact snapshots here); compare it without the stress option"
            );
            ensure!(
                self.case.clump.is_none(),
                "{src}: [clump]: the LAMMPS penetration deck takes sphere beds only"
            );
        }
        ensure!(
            !(self.stress && self.case.clump.is_some()),
            "{}: the stress fields of a bed of clumps are not built (contact snapshots and coarse graining are per sphere); run it without the stress option",
            self.case.source.display()
        );
        crate::engines::liggghts::check_materials(
            &self.case.source,
            &self.case.materials,
            &self.case.pairs,
        )
    }

    fn derived(&self) -> Vec<Derived> {
        let c = &self.case;
        let travel = c.start_gap + c.final_depth + c.diameter.max();
        let steps = (travel / c.speed / c.dt).ceil();
        vec![
            Derived::new(
                "grains",
                c.count.to_string(),
                match &c.clump {
                    None => format!(
                        "per bed; {} independent bed(s); diameter {:e} to {:e} m",
                        c.ensemble_beds,
                        c.diameter.min(),
                        c.diameter.max()
                    ),
                    Some(t) => format!(
                        "rigid clumps `{}` of {} spheres of diameter {:e} m (volume {:.4e} m^3 each), per bed; {} independent bed(s)",
                        t.name,
                        t.radii.len(),
                        c.diameter.max(),
                        t.volume,
                        c.ensemble_beds
                    ),
                },
            ),
            Derived::new(
                "Rayleigh time",
                format!("{:.4e} s", c.rayleigh_time),
                "of the smallest grain (Feng et al. Sec. 2)",
            ),
            Derived::new(
                "time step",
                format!("{:e} s", c.dt),
                format!(
                    "{:.2} % of the Rayleigh time (validation refuses > 100 %; Feng et al. use about 20 %)",
                    100.0 * c.dt / c.rayleigh_time
                ),
            ),
            Derived::new(
                "penetration",
                format!("{steps:.0} steps"),
                format!(
                    "{:.4e} m of travel at {:e} m/s ({:.4e} s simulated), after settling of up to {:e} s",
                    travel,
                    c.speed,
                    travel / c.speed,
                    c.max_settle_time
                ),
            ),
        ]
    }

    fn units(&self, opts: &Options) -> Result<Vec<Unit>> {
        ensure!(
            !(self.stress && self.case.clump.is_some()),
            "{}: the stress fields of a bed of clumps are not built (contact snapshots and coarse graining are per sphere); run it without the stress option",
            self.case.source.display()
        );
        (0..self.case.ensemble_beds)
            .map(|k| {
                let ck = self.case.realisation(k);
                let recorded = opts
                    .recorded_inputs
                    .as_ref()
                    .and_then(|r| bed::recorded_bed(&ck, r, &bed_dir_name(k)));
                let bed_from_record = recorded.is_some();
                let bed = match recorded {
                    Some(b) => b,
                    None => prepare_bed(&ck, opts.progress)
                        .with_context(|| format!("preparing bed {k} (seed {})", ck.seed))?,
                };
                let run = self.stress.then(|| bed_run(&ck, &bed));
                let plan = run
                    .as_ref()
                    .map(|r| crate::analysis::stress_fields::snapshot_plan(&ck, r));
                let study_plan = run
                    .as_ref()
                    .filter(|_| opts.study)
                    .map(|r| crate::analysis::stress_fields::study_plan(&ck, r));
                Ok(Unit {
                    k,
                    bed_from_record,
                    bed_hash: bed::bed_hash(&bed),
                    case: ck,
                    bed,
                    plan,
                    study_plan,
                })
            })
            .collect()
    }

    fn unit_name(&self, u: &Unit) -> String {
        bed_dir_name(u.k)
    }

    fn fingerprint(&self, u: &Unit) -> Result<Sha256> {
        match self.reference {
            EngineKind::Lammps => crate::engines::lammps3d_penetration::input_hash(
                &deck_dir::lammps_deck(&u.case, &u.bed)?,
            ),
            _ => lp::input_hash_of(&liggghts_deck(&u.case, &u.bed)?),
        }
    }
    fn engine_input(&self, u: &Unit) -> Result<Vec<(&'static str, String)>> {
        match self.reference {
            EngineKind::Lammps => crate::engines::lammps3d_penetration::inputs(
                &deck_dir::lammps_deck(&u.case, &u.bed)?,
            ),
            _ => lp::input_files(&liggghts_deck(&u.case, &u.bed)?),
        }
    }

    fn run_native(&self, u: &Unit, role: Role, dir: &Path, opts: &Options) -> Result<NativeRun> {
        let main = role == Role::Main;
        let plan = if main || self.control_takes_snapshots(role) {
            u.plan.as_ref()
        } else {
            None
        };
        let run = native_run(&u.case, &u.bed, role, plan, dir, opts.progress, opts.reuse)?;
        let study_snapshots = match (&u.study_plan, main) {
            (Some(sp), true) => {
                let sdir = dir.join(STUDY_DIR);
                native_run(
                    &u.case,
                    &u.bed,
                    role,
                    Some(sp),
                    &sdir,
                    opts.progress,
                    opts.reuse,
                )?;
                Some(sdir.join(SNAPSHOT_DIR))
            }
            _ => None,
        };
        let slow = match (main, u.case.quasi_static_speed) {
            (true, Some(v2)) => {
                let slow_case = PenetrationCase {
                    speed: v2,
                    ..u.case.clone()
                };
                Some(native_run(
                    &slow_case,
                    &u.bed,
                    role,
                    None,
                    &dir.join(format!("v{v2}")),
                    opts.progress,
                    opts.reuse,
                )?)
            }
            _ => None,
        };
        Ok(NativeRun {
            run,
            slow,
            snapshots: plan.map(|_| dir.join(SNAPSHOT_DIR)),
            study_snapshots,
        })
    }

    fn write_deck(&self, u: &Unit, dir: &Path, _opts: &Options) -> Result<()> {
        lp::write_deck_dir(&liggghts_deck(&u.case, &u.bed)?, dir).map(|_| ())
    }

    fn run_reference(&self, u: &Unit, dir: &Path, opts: &Options) -> Result<RefRun> {
        let limits = super::engine_limits(self, opts);
        if self.reference == EngineKind::Lammps {
            return lammps_run(&self.case, u, dir, limits);
        }
        let mut main = liggghts_run(&self.case, u, u.plan.as_ref(), dir, opts, &limits)?;
        if let Some(sp) = &u.study_plan {
            let sdir = dir.join(STUDY_DIR);
            let study = liggghts_run(&self.case, u, Some(sp), &sdir, opts, &limits)
                .with_context(|| format!("bed {}: estimator-study run", u.k))?;
            main.study_snapshots = study.snapshots;
        }
        Ok(main)
    }

    fn record(&self, u: &Unit, run: &RefRun, run_dir: &Path, rec: &Path) -> Result<()> {
        self.liggghts_only("a record under reference/")?;
        std::fs::create_dir_all(rec).with_context(|| format!("cannot create {}", rec.display()))?;
        let grains: &[&str] = if u.bed.bodies.is_empty() {
            &[lp::DATA_FILE]
        } else {
            use crate::engines::liggghts::clump_bed;
            &[clump_bed::BODIES_FILE, clump_bed::START_DUMP_FILE]
        };
        for f in [
            lp::DECK_FILE,
            lp::STL_FILE,
            lp::FORCE_FILE,
            lp::LOG_FILE,
            crate::engines::liggghts::STDOUT_FILE,
        ]
        .iter()
        .chain(grains)
        {
            std::fs::copy(run_dir.join(f), rec.join(f))
                .with_context(|| format!("copying {f} into {}", rec.display()))?;
        }
        // The bed as granval prepared it, so a recorded comparison need not settle it
        // again (the deck's fingerprint in the seal covers it).
        if let Some(bed) = self.bed_file(u) {
            let (name, bytes) = bed?;
            let path = rec.join(name);
            std::fs::write(&path, bytes)
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
        let mut p = run.run.provenance.clone();
        p.notes.retain(|n| !n.starts_with("run directory"));
        write_provenance(&rec.join(PROVENANCE_FILE), &p)
    }

    fn bed_file(&self, u: &Unit) -> Option<Result<(String, Vec<u8>)>> {
        let name = bed::bed_file_name(&u.case)?;
        Some(
            serde_json::to_vec(&u.bed)
                .map(|bytes| (name, bytes))
                .map_err(Into::into),
        )
    }

    fn regenerate(&self, u: &Unit, file: &str) -> Option<Result<Vec<u8>>> {
        (file == lp::DATA_FILE)
            .then(|| bed::data_file(&u.case, &u.bed))
            .flatten()
    }

    fn read_record(&self, u: &Unit, name: &str, seal: &Verified) -> Result<RefRun> {
        self.liggghts_only("a recorded reference (--reference-mode recorded)")?;
        // Every file the reduction reads must be sealed.
        for f in [lp::FORCE_FILE, lp::LOG_FILE, lp::DECK_FILE, PROVENANCE_FILE] {
            seal.file(name, f)?;
        }
        let recorded = read_provenance(&seal.file(name, PROVENANCE_FILE)?)?;
        ensure!(
            recorded.engine == EngineKind::Liggghts,
            "{}: not a LIGGGHTS record (engine {})",
            seal.root.display(),
            recorded.engine
        );
        let dir = seal.unit_files(name)?;
        let mut run = reduce_liggghts_dir(&u.case, &u.bed, &dir)?;
        run.provenance = recorded;
        Ok(RefRun {
            run,
            snapshots: None,
            study_snapshots: None,
        })
    }

    fn read_run_dir(&self, u: &Unit, dir: &Path) -> Result<RefRun> {
        // `granval analyze` of penetration deck directories goes through
        // [`deck_dir::analyze`], which reads LAMMPS directories too; this path is LIGGGHTS'.
        self.liggghts_only("reading a run directory through the runner")?;
        // The bed is this unit's (granval prepared it): the deck on disk must be the one
        // written from it, as the directory's manifest must list it.
        let manifest = inputs::InputManifest::read(dir)?;
        manifest.check(dir, &self.case, &self.case.source, u.k, u.case.seed)?;
        deck_dir::check_case_inputs(
            &u.case,
            &u.bed,
            dir,
            manifest.settles_in_liggghts(),
            manifest.viz_every,
        )?;
        Ok(RefRun {
            run: reduce_liggghts_dir(&u.case, &u.bed, dir)?,
            snapshots: None,
            study_snapshots: None,
        })
    }

    fn deck_files(&self) -> DeckFiles {
        DeckFiles {
            binary: "liggghts",
            deck: lp::DECK_FILE,
            log: lp::LOG_FILE,
            inputs: &[
                (lp::DATA_FILE, "the settled bed (read_data), exact"),
                (lp::STL_FILE, "the intruder mesh at its start position"),
            ],
            outputs: &[
                (
                    lp::FORCE_FILE,
                    "every force_every steps: step, time, intruder bottom height, force of the grains on the intruder",
                ),
                (
                    lp::LOG_FILE,
                    "LIGGGHTS' log (version, warnings, thermo lines)",
                ),
            ],
        }
    }

    fn drift(&self, previous: &RefRun, now: &RefRun) -> String {
        match (
            cp::observables(&self.case, &previous.run.fdr),
            cp::observables(&self.case, &now.run.fdr),
        ) {
            (Ok(a), Ok(b)) => format!(
                "K_phi {:.4} -> {:.4} ({:+.2e})",
                a.fit.k_phi,
                b.fit.k_phi,
                b.fit.k_phi - a.fit.k_phi
            ),
            (a, b) => format!(
                "not comparable ({:?} / {:?})",
                a.err().map(|e| e.to_string()),
                b.err().map(|e| e.to_string())
            ),
        }
    }

    fn write_decks(
        &self,
        bed_by: super::BedBy,
        opts: &Options,
        out: &Path,
    ) -> Result<Vec<std::path::PathBuf>> {
        match self.reference {
            EngineKind::Lammps if bed_by != super::BedBy::Native => anyhow::bail!(
                "--engine lammps --bed liggghts: the LAMMPS penetration deck reads beds granval prepared natively (--bed native)"
            ),
            EngineKind::Lammps => {
                deck_dir::write_lammps(&self.case, out, opts.progress, opts.viz_every)
            }
            _ => deck_dir::write(&self.case, out, bed_by, opts.progress, opts.viz_every),
        }
    }

    fn analyze_decks(
        &self,
        dir: &Path,
        native: bool,
        opts: &Options,
        out: &Path,
    ) -> Result<super::runner::CaseOutcome> {
        deck_dir::analyze(dir, native, opts, out)
    }

    fn has_chaos_baseline(&self) -> bool {
        true
    }

    fn has_stress_fields(&self) -> bool {
        true
    }

    fn chaos(&self, family: &str, opts: &Options, out: &Path) -> Result<super::chaos::ChaosRecord> {
        chaos::replicas(self, family, opts, out)
    }

    fn checks(
        &self,
        units: &[Unit],
        native: &[NativeRun],
        reference: &[RefRun],
        out: &Path,
        opts: &Options,
    ) -> Verdict {
        let runs = FdrRuns {
            native: native.iter().map(|r| &r.run).collect(),
            native_slow: native.iter().filter_map(|r| r.slow.as_ref()).collect(),
            reference: reference.iter().map(|r| &r.run).collect(),
            reference_engine: self.reference,
        };
        let (mut v, summary) = fdr_checks(&self.case, units, &runs, out, opts.control.as_deref());
        let main_run = native.iter().all(|r| r.snapshots.is_some());
        if self.stress && main_run {
            let s = stress::checks(&self.case, units, native, reference, out, opts);
            v.checks.extend(s.checks);
            v.notes.extend(s.notes);
            v.unevaluated.extend(s.unevaluated);
        }
        let runs = |k: usize| -> Result<run_seal::BedRuns> {
            let u = &units[k];
            Ok(run_seal::BedRuns {
                unit: u,
                engine_input: self.fingerprint(u)?,
                native_force: native.get(k).and_then(|r| r.run.force_file.clone()),
                reference_force: reference[k]
                    .run
                    .force_file
                    .clone()
                    .context("the reference run names no force file")?,
            })
        };
        seal_summary(
            &self.case,
            (0..units.len()).map(runs),
            &summary,
            self.reference,
            out,
            &mut v,
        );
        v
    }
}

/// Writes the case's `summary.json` and its run seal into `out` (claims across cases
/// read only sealed summaries, [`run_seal`]); a run whose summary cannot be sealed gets
/// an error check, as a summary without a seal would be refused later anyway.
pub(crate) fn seal_summary<'a>(
    case: &PenetrationCase,
    beds: impl Iterator<Item = Result<run_seal::BedRuns<'a>>>,
    summary: &crate::compare::sweep::CaseSummary,
    reference_engine: EngineKind,
    out: &Path,
    v: &mut Verdict,
) {
    let sealed = beds
        .collect::<Result<Vec<_>>>()
        .and_then(|beds| run_seal::write(out, case, &beds, summary, reference_engine, &v.checks));
    if let Err(e) = sealed {
        v.checks.push(Check::error(
            format!("{}: run seal", case.name),
            format!(
                "{} and {} not written: {e:#}",
                crate::compare::sweep::SUMMARY_FILE,
                run_seal::RUN_SEAL_FILE
            ),
        ));
    }
}

/// Rule 3's K_phi fit range (docs/stress.md) of the runs of both engines: each engine's
/// self-consistent end on its ensemble-mean FDR, the bed height the lowest of the beds'.
pub(crate) fn fit_range_of(
    case: &PenetrationCase,
    units: &[Unit],
    native: &[&EngineRun],
    reference: &[&EngineRun],
    reference_engine: EngineKind,
) -> cp::FitRange {
    let bed_height = units
        .iter()
        .map(|u| u.bed.surface_z)
        .fold(f64::INFINITY, f64::min);
    let mut engines = Vec::new();
    let mean = |r: &[&EngineRun]| {
        crate::analysis::fdr::ensemble_mean(
            &r.iter().map(|r| &r.fdr).collect::<Vec<_>>(),
            case.h_bin,
        )
    };
    let mut failed = Vec::new();
    for (label, runs) in [("native", native), (reference_engine.key(), reference)] {
        if runs.is_empty() {
            continue;
        }
        match mean(runs) {
            Ok(m) => engines.push((label, m)),
            Err(e) => failed.push(format!("{label}: {e:#}")),
        }
    }
    let mut r = cp::fit_range(
        case,
        bed_height,
        &engines.iter().map(|(l, m)| (*l, m)).collect::<Vec<_>>(),
    );
    if !failed.is_empty() {
        r.not_compared = Some(format!("no mean FDR: {}", failed.join("; ")));
    }
    r
}

/// The upper end of every K_phi fit of `case`: rule 3's common end where the case asks
/// for it (`analysis.k_phi_range = "rule3"`), else the end of the FDR.
pub(crate) fn k_phi_fit_end(case: &PenetrationCase, range: &cp::FitRange) -> f64 {
    match case.k_phi_range {
        crate::case::penetration::KPhiRange::Rule3 => range.fit_end(),
        crate::case::penetration::KPhiRange::Open => f64::INFINITY,
    }
}

/// The runs one penetration report is made from, per bed in bed order: the native
/// engine's at the case's speed and at its quasi-static speed (empty when the case has
/// none), and the reference engine's (empty for `analyze --no-native`'s other side).
pub(crate) struct FdrRuns<'a> {
    pub native: Vec<&'a EngineRun>,
    pub native_slow: Vec<&'a EngineRun>,
    pub reference: Vec<&'a EngineRun>,
    pub reference_engine: EngineKind,
}

/// Every FDR check of the experiment from the runs of both engines, with the FDR CSVs
/// and the overlay SVG written to `out`, and the case's summary. Shared by `compare` and
/// `analyze`, so both give the same report from the same runs.
pub(crate) fn fdr_checks(
    case: &PenetrationCase,
    units: &[Unit],
    runs: &FdrRuns,
    out: &Path,
    control: Option<&str>,
) -> (Verdict, crate::compare::sweep::CaseSummary) {
    let FdrRuns {
        native,
        native_slow,
        reference,
        reference_engine,
    } = runs;
    let reference_engine = *reference_engine;
    let name = |w: &str| format!("{}: {w}", case.name);
    let mut notes: Vec<String> = units
        .iter()
        .map(|u| {
            format!(
                "bed {}: {} (sha256 {}){}",
                u.k,
                packing::bed_note(&u.case, &u.bed),
                u.bed_hash,
                if u.bed_from_record {
                    crate::experiments::bed_cache::FROM_RECORD_NOTE
                } else {
                    ""
                }
            )
        })
        .collect();
    let mut checks = Vec::new();
    let Summarized {
        range,
        h_max,
        native: native_o,
        reference,
        summary,
    } = summarize(case, units, native, reference, reference_engine);
    notes.push(range.text());
    let obs = |r: &[&EngineRun]| {
        let f: Vec<&crate::analysis::fdr::Fdr> = r.iter().map(|r| &r.fdr).collect();
        cp::ensemble_in(case, &f, h_max)
    };
    let _ = std::fs::create_dir_all(out);
    let mut curves = Vec::new();
    for (label, o) in [("native", &native_o), (reference_engine.key(), &reference)] {
        match o {
            Some(Ok(o)) => {
                checks.extend(cp::fit_coverage(case, o, label));
                if let Err(e) = crate::analysis::fdr::write_csv(
                    &out.join(format!("fdr_{label}.csv")),
                    &o.fdr,
                    Some(&o.fit),
                ) {
                    notes.push(format!("fdr_{label}.csv not written: {e:#}"));
                }
                notes.push(format!(
                    "{label}: K_phi = {:.3} +- {:.3} (R^2 {:.4}) on the mean FDR of {} bed(s); single beds {:?}",
                    o.fit.k_phi,
                    o.fit.se_k,
                    o.fit.r2,
                    o.members.len(),
                    o.members
                        .iter()
                        .map(|m| format!("K {:.2} R^2 {:.3}", m.0, m.1))
                        .collect::<Vec<_>>()
                ));
                notes.push(format!("{label}: {}", cp::shape_text(o)));
                if let Some(c) = cp::published(case, o, label) {
                    checks.push(c);
                }
                let engine = if label == "native" {
                    EngineKind::Native
                } else {
                    reference_engine
                };
                curves.push((engine, o));
            }
            Some(Err(e)) => checks.push(Check::error(
                name(&format!("{label} observables")),
                format!("{e:#}"),
            )),
            None => {}
        }
    }
    if let (Some(Ok(a)), Some(Ok(b))) = (&native_o, &reference) {
        checks.extend(cp::compare(case, &range, a, b));
        notes.extend(cp::boundary_notes(case, a, b));
    }
    if let (Some(v2), Some(Ok(a)), false) =
        (case.quasi_static_speed, &native_o, native_slow.is_empty())
    {
        match obs(native_slow) {
            Ok(slow) => checks.push(cp::quasi_static(case, a, &slow, v2)),
            Err(e) => checks.push(Check::error(name("quasi-static K_phi"), format!("{e:#}"))),
        }
    }
    let series: Vec<_> = curves
        .iter()
        .map(|(e, o)| {
            crate::report::svg::FdrSeries::new(
                e.label(),
                (*e).into(),
                &o.fdr.h,
                &o.fdr.p,
                Some(&o.fit),
            )
        })
        .collect();
    if !series.is_empty()
        && let Err(e) = crate::report::svg::fdr_overlay(
            &out.join("fdr.svg"),
            &series,
            &crate::report::plot::Caption::new(format!(
                "{}: force-depth relation (mean of beds)",
                case.name
            ))
            .control(control),
        )
    {
        notes.push(format!("SVG not written: {e:#}"));
    }
    (
        Verdict {
            checks,
            notes,
            ..Verdict::default()
        },
        summary,
    )
}

/// The ensemble observables of a run and the summary claims across cases read from it.
pub(crate) struct Summarized {
    pub range: cp::FitRange,
    /// Upper end of every K_phi fit ([`k_phi_fit_end`]).
    pub h_max: f64,
    /// Each engine's ensemble observables (None: that engine did not run).
    pub native: Option<Result<cp::Observables>>,
    pub reference: Option<Result<cp::Observables>>,
    pub summary: crate::compare::sweep::CaseSummary,
}

/// Rule 3's range, each engine's ensemble observables on it and the case summary, from
/// the runs of both engines: what [`fdr_checks`] gates and what a run seal recomputes
/// from the sealed force files ([`run_seal::verify`]), with this one function.
pub(crate) fn summarize(
    case: &PenetrationCase,
    units: &[Unit],
    native: &[&EngineRun],
    reference: &[&EngineRun],
    reference_engine: EngineKind,
) -> Summarized {
    let range = fit_range_of(case, units, native, reference, reference_engine);
    let h_max = k_phi_fit_end(case, &range);
    let obs = |r: &[&EngineRun]| {
        let f: Vec<&crate::analysis::fdr::Fdr> = r.iter().map(|r| &r.fdr).collect();
        cp::ensemble_in(case, &f, h_max)
    };
    let reference = (!reference.is_empty()).then(|| obs(reference));
    let native = (!native.is_empty()).then(|| obs(native));
    let summary = summary(case, units, &native, &reference, reference_engine);
    Summarized {
        range,
        h_max,
        native,
        reference,
        summary,
    }
}

/// What claims spanning several cases read from this case (`summary.json`).
fn summary(
    case: &PenetrationCase,
    units: &[Unit],
    native: &Option<Result<cp::Observables>>,
    reference: &Option<Result<cp::Observables>>,
    reference_engine: EngineKind,
) -> crate::compare::sweep::CaseSummary {
    use crate::compare::sweep::{CaseSummary, EngineSummary};
    let psi = units.iter().map(|u| u.bed.psi).sum::<f64>() / units.len().max(1) as f64;
    let mut engines = std::collections::BTreeMap::new();
    for (label, o) in [("native", native), (reference_engine.key(), reference)] {
        if let Some(Ok(o)) = o {
            engines.insert(
                label.to_string(),
                EngineSummary {
                    k_phi: o.fit.k_phi,
                    k_phi_se_regression: o.fit.se_k,
                    k_phi_beds: o.members.iter().map(|m| m.0).collect(),
                    h: o.fdr.h.clone(),
                    p: o.fdr.p.clone(),
                    bed_fdrs: o
                        .member_fdrs
                        .iter()
                        .map(|f| (f.h.clone(), f.p.clone()))
                        .collect(),
                    psi,
                },
            );
        }
    }
    CaseSummary {
        case: case.name.clone(),
        canonical_hash: case.canonical_hash().to_string(),
        bed_hashes: units.iter().map(|u| u.bed_hash.to_string()).collect(),
        engines,
    }
}
