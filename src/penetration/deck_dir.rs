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

use super::{EngineRun, PenetrationRun, bed_hash, binner, liggghts_deck, prepare_bed};
use crate::case::penetration::PenetrationCase;
use crate::engines::liggghts::penetration::{self as lp, Units};
use crate::physics::dem::packing::{self, Bed};
use crate::rundata::provenance::{Provenance, read_provenance, write_provenance};
use anyhow::{Context, Result, bail, ensure};
use std::path::{Path, PathBuf};

pub const CASE_FILE: &str = "case.toml";

pub fn bed_dir_name(k: usize) -> String {
    format!("bed-{k}")
}

/// `force.csv` + `provenance.json` of a native run.
pub fn save_native(dir: &Path, run: &PenetrationRun) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    crate::rundata::force::write_force_csv(&dir.join("force.csv"), &run.samples)?;
    write_provenance(&dir.join("provenance.json"), &run.provenance)
}

/// Who prepares the beds of a deck directory.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BedBy {
    /// granval's native pour; `data.bed` holds the exact settled bed, so the native
    /// engine can penetrate the very same grains (the engine comparison).
    Native,
    /// LIGGGHTS pours and settles the same loose lattice with the same criterion
    /// (`data.lattice` in, `bed.dump` out): for full-size beds a native pour would take
    /// hours for.
    Liggghts,
}

/// Whether a bed directory settles its own bed in LIGGGHTS.
fn settles_in_liggghts(dir: &Path) -> bool {
    dir.join(lp::LATTICE_FILE).exists()
}

/// Prepares every bed of the case (or leaves that to LIGGGHTS) and writes the deck
/// directory `out`.
pub fn write(
    case: &PenetrationCase,
    out: &Path,
    bed_by: BedBy,
    progress: bool,
) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    std::fs::copy(&case.source, out.join(CASE_FILE)).with_context(|| {
        format!(
            "cannot copy {} to {}",
            case.source.display(),
            out.join(CASE_FILE).display()
        )
    })?;
    let mut dirs = Vec::new();
    let mut lines = Vec::new();
    for k in 0..case.ensemble_beds {
        let ck = case.realisation(k);
        let dir = out.join(bed_dir_name(k));
        let (deck, psi) = match bed_by {
            BedBy::Native => {
                let bed = prepare_bed(&ck, progress)?;
                (liggghts_deck(&ck, &bed)?, format!("{:.4}", bed.psi))
            }
            BedBy::Liggghts => (
                super::liggghts_settle_deck(&ck)?,
                "measured after settling".into(),
            ),
        };
        lp::write_deck_dir(&deck, &dir)?;
        lines.push(format!(
            "| {} | {} | {} | {psi} | {} |",
            bed_dir_name(k),
            ck.seed,
            deck.particles.len(),
            deck.n_steps
        ));
        dirs.push(dir);
    }
    std::fs::write(out.join("README.md"), readme(case, &lines, bed_by))
        .with_context(|| format!("cannot write {}", out.join("README.md").display()))?;
    Ok(dirs)
}

fn readme(case: &PenetrationCase, rows: &[String], bed_by: BedBy) -> String {
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
         with `--no-native`) and writes the same report as `granval compare`.\n",
        name = case.name,
        desc = case.description,
        n = case.ensemble_beds,
        rows = rows.join("\n"),
    )
}

/// The bed a deck directory starts from, read back from its `data.bed`.
pub fn read_bed(case: &PenetrationCase, dir: &Path) -> Result<Bed> {
    let particles = if settles_in_liggghts(dir) {
        lp::parse_bed_dump(&dir.join(lp::BED_DUMP_FILE), Units::Si, case.density)?
    } else {
        lp::parse_data_file(&dir.join(lp::DATA_FILE), Units::Si)?
    };
    let surface_z = packing::surface_height(case, &particles);
    let psi = packing::packing_fraction(case, &particles, surface_z);
    Ok(Bed {
        particles,
        surface_z,
        psi,
        ke_ratio: f64::NAN,
        settle_time: f64::NAN,
        ke_at_end_of_pour: f64::NAN,
    })
}

/// Reduces the LIGGGHTS outputs in `dir` (a finished run of the deck granval writes for
/// `case` and `bed`) while reading them.
pub fn reduce_liggghts_dir(case: &PenetrationCase, bed: &Bed, dir: &Path) -> Result<EngineRun> {
    let deck = if settles_in_liggghts(dir) {
        super::liggghts_settle_deck(case)?
    } else {
        liggghts_deck(case, bed)?
    };
    let mut b = binner(case, bed)?;
    let mut provenance = lp::read_outputs(&deck, dir, |s| b.push(s.z_bottom, s.f[2]))
        .with_context(|| format!("LIGGGHTS run in {}", dir.display()))?;
    if let Ok(on_disk) = std::fs::read_to_string(dir.join(lp::DECK_FILE))
        && on_disk != lp::deck_text(&deck)?
    {
        provenance.notes.push(format!(
            "{} differs from the deck granval writes for this case and bed (edited by hand?)",
            dir.join(lp::DECK_FILE).display()
        ));
    }
    provenance.notes.push(packing::bed_note(case, bed));
    provenance
        .notes
        .push(format!("bed sha256 {}", bed_hash(bed)));
    Ok(EngineRun {
        fdr: b.fdr(),
        samples: b.samples(),
        provenance,
    })
}

/// A recorded LIGGGHTS run under `reference/`: used only for the very bed it was
/// recorded from (its provenance names the bed's sha256), never as a silent stand-in.
pub fn reduce_recorded(
    case: &PenetrationCase,
    bed: &Bed,
    dir: &Path,
    hash: &str,
) -> Result<EngineRun> {
    let recorded: Provenance = read_provenance(&dir.join("provenance.json"))?;
    ensure!(
        recorded.engine == "liggghts",
        "{}: not a LIGGGHTS record (engine {:?})",
        dir.display(),
        recorded.engine
    );
    ensure!(
        recorded.notes.iter().any(|n| n.contains(hash)),
        "{}: recorded from a different bed than the one prepared now (sha256 {hash}); run `granval reference refresh --suite penetration --only CASE`",
        dir.display()
    );
    let mut run = reduce_liggghts_dir(case, bed, dir)?;
    run.provenance = recorded;
    Ok(run)
}

/// The `bed-K` directories of a deck directory, in K order.
pub fn bed_dirs(dir: &Path) -> Result<Vec<PathBuf>> {
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

/// `granval analyze DIR`: the deck directory after LIGGGHTS ran in it (here or on a
/// cluster), reduced to the same checks as `granval compare`. With `native`, the
/// native engine penetrates each `data.bed` as `compare` does.
pub fn analyze(
    dir: &Path,
    native: bool,
    opts: &crate::pipeline::Options,
    out_dir: &Path,
) -> Result<crate::pipeline::CaseResult> {
    let case = PenetrationCase::load(&dir.join(CASE_FILE))?;
    let beds = bed_dirs(dir)?;
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
            dir.join(CASE_FILE).display(),
            case.ensemble_beds
        );
    }
    let mut runs = super::ensemble::EnsembleRuns {
        reference_source: format!("run directory {}", dir.display()),
        ..Default::default()
    };
    for (k, bdir) in beds.iter().enumerate() {
        let ck = case.realisation(k);
        let bed = read_bed(&ck, bdir)?;
        runs.notes.push(format!(
            "bed {k}: {} grains read from {} (sha256 {}), surface z = {:.6e} m, psi = {:.4}",
            bed.particles.len(),
            bdir.join(lp::DATA_FILE).display(),
            bed_hash(&bed),
            bed.surface_z,
            bed.psi
        ));
        runs.reference.push(reduce_liggghts_dir(&ck, &bed, bdir)?);
        if native {
            super::ensemble::run_native_bed(
                &ck,
                &bed,
                opts,
                &out_dir.join(bed_dir_name(k)),
                &mut runs,
            )?;
        }
    }
    Ok(super::ensemble::case_result(
        &case,
        &dir.join(CASE_FILE),
        if native { "native" } else { "none" },
        runs,
        out_dir,
    ))
}
