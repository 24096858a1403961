//! Self-contained LIGGGHTS deck directories — what a researcher takes to a cluster — and
//! their analysis after LIGGGHTS ran there (`granval deck` / `granval analyze`).
//!
//! Layout (also what `granval compare` leaves behind, so `analyze` can re-read it):
//! ```text
//! DIR/case.toml            the case, copied verbatim
//! DIR/README.md            how to run every bed, on one core or with mpirun
//! DIR/bed-K/in.penetration deck of bed K (read_data data.bed, intruder.stl)
//! DIR/bed-K/data.bed       the natively prepared bed K (seed bed.seed + K), exact
//! DIR/bed-K/intruder.stl   the intruder mesh at its start position
//! DIR/bed-K/README.md      what each input and output file holds
//! ```

use super::bed::{bed_hash, liggghts_deck, liggghts_settle_deck, prepare_bed};
use super::inputs::InputManifest;
use super::{Unit, bed_dir_name, fdr_checks, reduce_liggghts_dir};
use crate::case::penetration::PenetrationCase;
use crate::engines::liggghts::penetration::{self as lp, Units};
use crate::experiments::Options;
use crate::experiments::runner::CaseOutcome;
use crate::physics::dem::packing::{self, Bed};
use crate::report::CaseRun;
use anyhow::{Context, Result, bail, ensure};
use std::path::{Path, PathBuf};

pub(crate) const CASE_FILE: &str = "case.toml";

use crate::experiments::BedBy;

/// Whether a bed directory settles its own bed in LIGGGHTS.
pub(crate) fn settles_in_liggghts(dir: &Path) -> bool {
    dir.join(lp::LATTICE_FILE).exists()
}

/// Checks the case as a run would (`preflight`) and starts the deck directory `out` with a
/// verbatim copy of the case file: the first step of every penetration deck writer.
fn start_deck_dir(case: &PenetrationCase, out: &Path) -> Result<()> {
    use crate::experiments::Experiment;
    super::Penetration::against_liggghts(case.clone(), false).preflight()?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    std::fs::copy(&case.source, out.join(CASE_FILE)).with_context(|| {
        format!(
            "cannot copy {} to {}",
            case.source.display(),
            out.join(CASE_FILE).display()
        )
    })?;
    Ok(())
}

/// Prepares every bed of the case (or leaves that to LIGGGHTS) and writes the deck
/// directory `out`, each deck with a visualisation dump every `viz_every` steps when
/// given (`granval deck --viz N`; recorded in `inputs.json`, so `analyze` accepts it).
pub fn write(
    case: &PenetrationCase,
    out: &Path,
    bed_by: BedBy,
    progress: bool,
    viz_every: Option<u64>,
) -> Result<Vec<PathBuf>> {
    start_deck_dir(case, out)?;
    let mut dirs = Vec::new();
    let mut lines = Vec::new();
    for k in 0..case.ensemble_beds {
        let ck = case.realisation(k);
        let dir = out.join(bed_dir_name(k));
        let (mut deck, psi, hash) = match bed_by {
            BedBy::Native => {
                let bed = prepare_bed(&ck, progress)?;
                (
                    liggghts_deck(&ck, &bed)?,
                    format!("{:.4}", bed.psi),
                    Some(bed_hash(&bed)),
                )
            }
            BedBy::Liggghts => (
                liggghts_settle_deck(&ck)?,
                "measured after settling".into(),
                None,
            ),
        };
        deck.viz_every = viz_every;
        lp::write_deck_dir(&deck, &dir)?;
        let mut manifest = InputManifest::of_dir(&dir, case, k, ck.seed, hash)?;
        manifest.viz_every = viz_every;
        manifest.write(&dir)?;
        lines.push(format!(
            "| {} | {} | {} | {psi} | {} |",
            bed_dir_name(k),
            ck.seed,
            deck.particles.len() + deck.bodies.len(),
            deck.n_steps
        ));
        dirs.push(dir);
    }
    std::fs::write(
        out.join("README.md"),
        readme(case, &lines, bed_by, viz_every),
    )
    .with_context(|| format!("cannot write {}", out.join("README.md").display()))?;
    Ok(dirs)
}

/// Prepares every bed of the case natively and writes LAMMPS 2025 decks for them
/// (`granval deck --engine lammps`; [`crate::engines::lammps3d_penetration`]): per bed
/// `bed-K/in.penetration.lammps` and `bed-K/data.bed.lammps`, the bed exactly as the
/// LIGGGHTS deck would read it.
/// `viz_every`: each deck also writes a visualisation dump every that many steps
/// (`granval deck --engine lammps --viz N`, [`crate::engines::viz_dump`]).
pub(crate) fn write_lammps(
    case: &PenetrationCase,
    out: &Path,
    progress: bool,
    viz_every: Option<u64>,
) -> Result<Vec<PathBuf>> {
    use crate::engines::lammps3d_penetration as lmp;
    use crate::engines::viz_dump::{self, VizEngine};
    start_deck_dir(case, out)?;
    let mut dirs = Vec::new();
    let mut lines = Vec::new();
    for k in 0..case.ensemble_beds {
        let ck = case.realisation(k);
        let dir = out.join(bed_dir_name(k));
        let bed = prepare_bed(&ck, progress)?;
        let deck = lammps_deck(&ck, &bed)?;
        lmp::write_inputs(&deck, &dir)
            .with_context(|| format!("{}: no LAMMPS penetration deck", case.source.display()))?;
        if let Some(n) = viz_every {
            let p = dir.join(lmp::DECK_FILE);
            let text = std::fs::read_to_string(&p)
                .with_context(|| format!("cannot read {}", p.display()))?;
            std::fs::write(
                &p,
                viz_dump::add(&text, VizEngine::Lammps3d, n, deck.n_steps)?,
            )
            .with_context(|| format!("cannot write {}", p.display()))?;
        }
        InputManifest::of_dir(&dir, case, k, ck.seed, Some(bed_hash(&bed)))?.write(&dir)?;
        lines.push(format!(
            "| {} | {} | {} | {:.4} | {} |",
            bed_dir_name(k),
            ck.seed,
            deck.particles.len(),
            bed.psi,
            deck.n_steps
        ));
        dirs.push(dir);
    }
    let mut readme = lammps_readme(case, &lines);
    if let Some(n) = viz_every {
        readme += &format!(
            "\n## Visualisation\n\n{}\n",
            viz_dump::readme_line(VizEngine::Lammps3d, n)
        );
    }
    std::fs::write(out.join("README.md"), readme)
        .with_context(|| format!("cannot write {}", out.join("README.md").display()))?;
    Ok(dirs)
}

/// The README of a LAMMPS 2025 deck directory: what it holds, how to run it, how to
/// bring it back.
fn lammps_readme(case: &PenetrationCase, rows: &[String]) -> String {
    use crate::engines::lammps3d_penetration as lmp;
    let log = crate::engines::lammps3d::LOG_FILE;
    format!(
        "# LAMMPS 2025 penetration decks for `{name}` (written by granval)\n\n\
         {desc}\n\n\
         {n} independent bed(s), each prepared by granval's native engine (pour and settle, \
         Feng et al. Sec. 2) and written exactly (`{data}`); LAMMPS only penetrates. The laws \
         are LAMMPS' `pair_style granular` counterparts of the case's (docs/lammps-laws.md in \
         the granval repository: Hertz with restitution damping, Mindlin tangential with \
         LIGGGHTS' damping ratio, **no rolling resistance**; the intruder is an exact moving \
         cylinder region). The case file is copied as `{CASE_FILE}`.\n\n\
         | directory | seed | grains | packing fraction | steps |\n|---|---|---|---|---|\n{rows}\n\n\
         ## Run\n\n\
         Each `bed-K` directory is self-contained and needs LAMMPS 22 Jul 2025 with the \
         GRANULAR package. One core:\n\n\
         \x20   for d in bed-*; do (cd $d && lmp -in {deck} -log {log}); done\n\n\
         N MPI ranks:\n\n\
         \x20   for d in bed-*; do (cd $d && mpirun -np N lmp -in {deck} -log {log}); done\n\n\
         The beds are independent jobs: on a cluster submit one job per directory.\n\n\
         ## Analyse\n\n\
         Bring the directory back (at least `{CASE_FILE}` and every `bed-K` with its inputs, \
         `inputs.json`, `{force}` and `{log}`) and run\n\n\
         \x20   granval analyze DIR --report OUT\n\n\
         It checks that every run is complete and that its inputs are the ones granval wrote \
         (`inputs.json`), reduces each `{force}` (`step t z_bottom fx fy fz`, SI, f = force of \
         the grains on the intruder) to the force-depth relation, re-runs the native engine \
         from the same bed (skip with `--no-native`) and writes the same report as \
         `granval compare CASE --engine lammps`.\n",
        name = case.name,
        desc = case.description,
        n = case.ensemble_beds,
        rows = rows.join("\n"),
        data = lmp::DATA_FILE,
        deck = lmp::DECK_FILE,
        force = lmp::FORCE_FILE,
    )
}

/// The engine-neutral description of one penetration run (the LIGGGHTS deck's inputs,
/// all SI), in SI units for LAMMPS.
pub fn lammps_deck(case: &PenetrationCase, bed: &Bed) -> Result<lp::PenetrationDeck> {
    let mut deck = super::bed::penetration_deck(case, bed)?;
    deck.units = Units::Si;
    Ok(deck)
}

fn readme(
    case: &PenetrationCase,
    rows: &[String],
    bed_by: BedBy,
    viz_every: Option<u64>,
) -> String {
    let prep = match bed_by {
        BedBy::Native => {
            "each prepared by granval's native engine (pour and settle, Feng et al. Sec. 2) and written exactly (`data.bed`); LIGGGHTS only penetrates"
        }
        BedBy::Liggghts => {
            "each poured and settled by LIGGGHTS itself from the loose lattice in `data.lattice` with the protocol of Feng et al. Sec. 2 (mean KE below the case's ratio of its peak); the settled bed is written to `bed.dump`, then the intruder starts above the highest grain under it"
        }
    };
    format!(
        "# LIGGGHTS penetration decks for `{name}` (written by granval)\n\n\
         {desc}\n\n\
         {n} independent bed(s), {prep}. The case file is copied as `{CASE_FILE}`.\n\n\
         | directory | seed | grains | packing fraction | steps |\n|---|---|---|---|---|\n{rows}\n\n\
         ## Run\n\n\
         Each `bed-K` directory is self-contained. One core:\n\n\
         \x20   for d in bed-*; do (cd $d && liggghts -in in.penetration -log log.liggghts); done\n\n\
         N MPI ranks (add `--allow-run-as-root` when running as root):\n\n\
         \x20   for d in bed-*; do (cd $d && mpirun -np N liggghts -in in.penetration -log log.liggghts); done\n\n\
         The beds are independent jobs: on a cluster submit one job per directory.\n\n\
         ## Analyse\n\n\
         Bring the directory back (at least `{CASE_FILE}` and every `bed-K` with its inputs, \
         `force.txt`, `log.liggghts` and, for LIGGGHTS-settled beds, `bed.dump`) and run\n\n\
         \x20   granval analyze DIR --report OUT\n\n\
         It checks that every run is complete, reduces each `force.txt` to the force-depth \
         relation while reading it, re-runs the native engine from the same `data.bed` (skip \
         with `--no-native`) and writes the same report as `granval compare`.\n{viz}",
        name = case.name,
        desc = case.description,
        n = case.ensemble_beds,
        rows = rows.join("\n"),
        viz = match viz_every {
            None => String::new(),
            Some(n) => format!(
                "\n## Look at it\n\n\
                 Written with `--viz {n}`: every {n} steps of the penetration each run also writes \
                 `{}` (the grains: id, type, radius, position, velocity, force, angular velocity) \
                 and `{}` (the intruder mesh with the stress on each facet), legacy VTK that \
                 ParaView opens as a time series (LIGGGHTS adds the domain's box as \
                 `viz-grains-boundingBox_*.vtk`); open them in ParaView (File > Open). Draw the grains as Point Gaussian \
                 scaled by `radius`. These files are not needed by `analyze`; `inputs.json` \
                 records `--viz`, so the deck is still the one granval wrote.\n",
                lp::VIZ_GRAINS,
                lp::VIZ_INTRUDER
            ),
        },
    )
}

/// The bed a deck directory starts from, read back from its `data.bed`.
pub fn read_bed(case: &PenetrationCase, dir: &Path) -> Result<Bed> {
    read_bed_as(case, dir, settles_in_liggghts(dir))
}

/// [`read_bed`] with who settled the bed given (`settled_by_liggghts`: from its
/// `bed.dump`), as the directory's manifest says, not guessed from the files present.
fn read_bed_as(case: &PenetrationCase, dir: &Path, settled_by_liggghts: bool) -> Result<Bed> {
    let (particles, bodies) = if case.clump.is_some() {
        (
            Vec::new(),
            crate::engines::liggghts::clump_bed::parse_bodies(
                &dir.join(crate::engines::liggghts::clump_bed::BODIES_FILE),
            )?,
        )
    } else if settled_by_liggghts {
        (
            lp::parse_bed_dump(&dir.join(lp::BED_DUMP_FILE), Units::Si, case.density)?,
            Vec::new(),
        )
    } else {
        (
            lp::parse_data_file(&dir.join(lp::DATA_FILE), Units::Si)?,
            Vec::new(),
        )
    };
    Ok(bed_of(case, particles, bodies))
}

/// A bed read back from a deck directory, with its surface height and packing fraction
/// computed as the native preparation computes them.
fn bed_of(
    case: &PenetrationCase,
    particles: Vec<crate::case::Particle>,
    bodies: Vec<crate::case::clumps::Clump>,
) -> Bed {
    let spheres = packing::grain_spheres(case, &particles, &bodies);
    let surface_z = packing::surface_height(case, &spheres);
    let psi = packing::packing_fraction(case, &particles, &bodies, surface_z);
    Bed {
        particles,
        bodies,
        surface_z,
        psi,
        ke_ratio: f64::NAN,
        settle_time: f64::NAN,
        ke_at_end_of_pour: f64::NAN,
    }
}

/// The `bed-K` directories of a deck directory, in K order.
pub(crate) fn bed_dirs(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut found = Vec::new();
    for e in std::fs::read_dir(dir).with_context(|| format!("cannot read {}", dir.display()))? {
        let e = e?;
        if let Some(k) = e
            .file_name()
            .to_str()
            .and_then(|n| n.strip_prefix("bed-"))
            .and_then(|k| k.parse::<usize>().ok())
            && e.path().is_dir()
        {
            found.push((k, e.path()));
        }
    }
    found.sort();
    for (i, (k, _)) in found.iter().enumerate() {
        if *k != i {
            bail!(
                "{}: bed directories must be bed-0, bed-1, ... without gaps; found bed-{k} where bed-{i} belongs",
                dir.display()
            );
        }
    }
    Ok(found.into_iter().map(|(_, p)| p).collect())
}

/// Bed `k`'s realisation of `case` and the manifest of its directory `dir`, checked
/// against them: exactly the inputs it lists, of this case (canonical hash), bed number
/// and seed.
fn checked_manifest(
    case: &PenetrationCase,
    case_file: &Path,
    k: usize,
    dir: &Path,
) -> Result<(PenetrationCase, InputManifest)> {
    let ck = case.realisation(k);
    let manifest = InputManifest::read(dir)?;
    manifest.check(dir, case, case_file, k, ck.seed)?;
    Ok((ck, manifest))
}

/// The bed read from `dir` is the one its manifest names (manifests of beds the
/// reference engine settles name none).
fn check_bed_hash(manifest: &InputManifest, bed: &Bed, dir: &Path) -> Result<()> {
    if let Some(want) = &manifest.bed_sha256 {
        let got = bed_hash(bed);
        ensure!(
            &got == want,
            "{}: the bed read from it has sha256 {got}, {} names {want}",
            dir.display(),
            dir.join(super::inputs::MANIFEST_FILE).display()
        );
    }
    Ok(())
}

/// A LIGGGHTS run directory of bed `k` of `case` (`ck`: its realisation), checked and
/// reduced: the directory holds exactly the inputs its manifest lists, of this case and
/// bed ([`InputManifest::check`]); the inputs are the ones granval writes for this case
/// on the bed they hold ([`check_case_inputs`]); the outputs are of this deck (its
/// log echoes it, its force file follows its intruder; [`reduce_liggghts_dir`]). Any
/// mismatch is an error naming the file: never a physics verdict on inputs or outputs
/// granval did not write for this case.
pub(crate) fn read_run(
    case: &PenetrationCase,
    case_file: &Path,
    k: usize,
    dir: &Path,
) -> Result<(Bed, super::bed::EngineRun)> {
    let (ck, manifest) = checked_manifest(case, case_file, k, dir)?;
    let settled_by_liggghts = manifest.settles_in_liggghts();
    let bed = read_bed_as(&ck, dir, settled_by_liggghts)?;
    check_bed_hash(&manifest, &bed, dir)?;
    check_case_inputs(&ck, &bed, dir, settled_by_liggghts, manifest.viz_every)?;
    let run = reduce_liggghts_dir(&ck, &bed, dir)?;
    Ok((bed, run))
}

/// A LAMMPS 2025 run directory of bed `k` of `case`, checked and reduced as
/// [`read_run`] checks a LIGGGHTS one: exactly the inputs its manifest lists, of this case
/// and bed; the deck and data file those granval writes for this case on the bed the
/// data file holds; a finished LAMMPS 2025 run with every force line
/// ([`crate::engines::lammps3d_penetration::read_finished`]).
pub(crate) fn read_lammps_run(
    case: &PenetrationCase,
    case_file: &Path,
    k: usize,
    dir: &Path,
) -> Result<(Bed, super::bed::EngineRun)> {
    use crate::engines::lammps3d_penetration as lmp;
    let (ck, manifest) = checked_manifest(case, case_file, k, dir)?;
    ensure!(
        manifest.is_lammps(),
        "{}: not a LAMMPS deck (its inputs.json lists {:?})",
        dir.display(),
        manifest.inputs.keys().collect::<Vec<_>>()
    );
    let particles = lp::parse_data_file(&dir.join(lmp::DATA_FILE), Units::Si)?;
    let bed = bed_of(&ck, particles, Vec::new());
    check_bed_hash(&manifest, &bed, dir)?;
    let deck = lammps_deck(&ck, &bed)?;
    let (lines, mut provenance) = lmp::read_finished(&deck, dir, case_file)?;
    super::bed::push_bed_notes(&mut provenance, &ck, &bed);
    let mut b = super::bed::binner(&ck, &bed)?;
    for l in &lines {
        b.push(l.z_bottom, l.f[2])?;
    }
    let run = super::bed::EngineRun {
        fdr: b.fdr(),
        samples: b.samples(),
        provenance,
        force_file: Some(dir.join(lmp::FORCE_FILE)),
    };
    Ok((bed, run))
}

/// Errors unless every input in `dir` is the one granval writes for bed `ck` on `bed`
/// (comments and number notation aside), as `read_run_dir` checks a micro or impact2d
/// deck directory; a deck with contact snapshot dumps (a `stress` run) is compared with
/// the deck of the case's snapshot plan on that bed.
pub(crate) fn check_case_inputs(
    ck: &PenetrationCase,
    bed: &Bed,
    dir: &Path,
    settled_by_liggghts: bool,
    viz_every: Option<u64>,
) -> Result<()> {
    let mut deck = if settled_by_liggghts {
        liggghts_settle_deck(ck)?
    } else {
        liggghts_deck(ck, bed)?
    };
    deck.viz_every = viz_every;
    for (name, mut text) in lp::input_files(&deck)? {
        if name == lp::DECK_FILE
            && std::fs::read_to_string(dir.join(name))
                .is_ok_and(|t| t.contains(crate::engines::liggghts::snapshot::PAIR_PREFIX))
        {
            let plan = crate::analysis::stress_fields::snapshot_plan(ck, &super::bed_run(ck, bed));
            text = lp::deck_text_with_snapshots(&deck, &plan.steps)?;
        }
        let data = name != lp::DECK_FILE && name != lp::STL_FILE;
        crate::engines::deck_text::check_same_input(dir, name, &text, data)?;
    }
    Ok(())
}

/// `granval analyze DIR`: the deck directory after LIGGGHTS ran in it (here or on a
/// cluster), reduced to the same checks as `granval compare`. With `native`, the native
/// engine penetrates each `data.bed` and the case's negative controls run against the
/// same LIGGGHTS runs, through the runner as `compare` does ([`crate::experiments::runner::judge`]), so
/// the report is `check`'s; without, the LIGGGHTS side alone is reduced (its
/// published-value checks). The LIGGGHTS outputs of bed K
/// are read from `DIR/bed-K/` (a `granval deck` directory) or `DIR/bed-K/liggghts/` (a
/// `granval compare` output directory). Every bed's inputs and outputs are checked
/// ([`read_run`]) before anything runs; with `--no-native` too.
pub fn analyze(dir: &Path, native: bool, opts: &Options, out_dir: &Path) -> Result<CaseOutcome> {
    use crate::experiments::Experiment;
    let case_file = dir.join(CASE_FILE);
    let case = PenetrationCase::load(&case_file)?;
    let beds = bed_dirs(dir)?;
    // A LAMMPS deck directory (`deck --engine lammps`) or a `compare --engine lammps`
    // output: its first bed says which; every bed is then read as that engine's.
    let lammps = beds.first().is_some_and(|b| {
        let deck = crate::engines::lammps3d_penetration::DECK_FILE;
        b.join(deck).exists() || b.join("lammps").join(deck).exists()
    });
    let engine = if lammps {
        crate::rundata::provenance::EngineKind::Lammps
    } else {
        crate::rundata::provenance::EngineKind::Liggghts
    };
    let exp = super::Penetration {
        case: case.clone(),
        stress: false,
        reference: engine,
    };
    exp.preflight()?;
    ensure!(
        !beds.is_empty(),
        "{}: no bed-0, bed-1, ... directories (written by `granval deck`)",
        dir.display()
    );
    if beds.len() != case.ensemble_beds {
        bail!(
            "{}: {} bed directories but {} declares ensemble.beds = {}",
            dir.display(),
            beds.len(),
            case_file.display(),
            case.ensemble_beds
        );
    }
    let mut units = Vec::new();
    let mut reference = Vec::new();
    let mut notes = Vec::new();
    for (k, bdir) in beds.iter().enumerate() {
        let deck = if lammps {
            crate::engines::lammps3d_penetration::DECK_FILE
        } else {
            lp::DECK_FILE
        };
        let bdir = if bdir.join(engine.key()).join(deck).exists() {
            bdir.join(engine.key())
        } else {
            bdir.clone()
        };
        let read = if lammps { read_lammps_run } else { read_run };
        let (bed, run) = read(&case, &case_file, k, &bdir)
            .with_context(|| format!("bed {k}: run directory {}", bdir.display()))?;
        notes.push(format!(
            "bed {k}: {} grains read from {} (sha256 {}), surface z = {:.6e} m, psi = {:.4}; its inputs are the ones granval wrote for this case (inputs.json) and its outputs are of that deck",
            bed.n_grains(),
            bdir.display(),
            bed_hash(&bed),
            bed.surface_z,
            bed.psi
        ));
        reference.push(run);
        units.push(Unit {
            k,
            bed_from_record: false,
            bed_hash: bed_hash(&bed),
            case: case.realisation(k),
            bed,
            plan: None,
            study_plan: None,
        });
    }
    if native {
        // The native runs, checks and negative controls of `check`, against these runs.
        let names: Vec<String> = units.iter().map(|u| bed_dir_name(u.k)).collect();
        let refs: Vec<super::RefRun> = reference
            .into_iter()
            .map(|run| super::RefRun {
                run,
                snapshots: None,
                study_snapshots: None,
            })
            .collect();
        std::fs::create_dir_all(out_dir)
            .with_context(|| format!("cannot create {}", out_dir.display()))?;
        return Ok(crate::experiments::runner::judge(
            &exp,
            opts,
            out_dir,
            crate::experiments::runner::Inputs {
                units: &units,
                names: &names,
                refs: &refs,
            },
            &crate::experiments::reference::Source::RunDir {
                dir: dir.to_path_buf(),
            },
            notes,
        ));
    }
    // `--no-native`: the reference side alone (its published-value checks).
    let runs = super::FdrRuns {
        native: Vec::new(),
        native_slow: Vec::new(),
        reference: reference.iter().collect(),
        reference_engine: engine,
    };
    let (mut v, summary) = fdr_checks(&case, &units, &runs, out_dir, None);
    let bed_runs = |k: usize| -> Result<super::run_seal::BedRuns> {
        let u = &units[k];
        Ok(super::run_seal::BedRuns {
            unit: u,
            engine_input: exp.fingerprint(u)?,
            native_force: None,
            reference_force: reference[k]
                .force_file
                .clone()
                .with_context(|| format!("the {engine} run names no force file"))?,
        })
    };
    super::seal_summary(
        &case,
        (0..units.len()).map(bed_runs),
        &summary,
        engine,
        out_dir,
        &mut v,
    );
    notes.extend(v.notes);
    let wall = |it: &mut dyn Iterator<Item = f64>| it.sum::<f64>();
    Ok(CaseOutcome {
        checks: v.checks,
        run: Some(CaseRun {
            case: case.name.clone(),
            case_file: dir.join(CASE_FILE).display().to_string(),
            test_engine: "none".into(),
            reference_engine: engine.to_string(),
            reference_version: reference
                .first()
                .map(|r| r.provenance.version.clone())
                .unwrap_or_default(),
            reference_source: format!("run directory {}", dir.display()),
            wall_time_test_s: 0.0,
            wall_time_reference_s: wall(&mut reference.iter().map(|r| r.provenance.wall_time_s)),
        }),
        notes,
        sections: v.sections,
    })
}
