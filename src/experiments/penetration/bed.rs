//! Beds of a penetration case: native preparation (pour and settle, Feng et al. Sec. 2),
//! their fingerprint, the LIGGGHTS deck that starts from them, and the streaming eq-5
//! reducer both engines' force series go through.

use crate::analysis::fdr::{Fdr, FdrBinner, Scales};
use crate::case::penetration::PenetrationCase;
use crate::engines::liggghts::penetration::PenetrationDeck;
use crate::physics::dem;
use crate::physics::dem::packing::{self, Bed};
use crate::rundata::provenance::{Provenance, Sha256};
use anyhow::Result;

/// One engine's run reduced to what the comparison needs: the binned FDR (eq 5).
#[derive(Debug, Clone)]
pub struct EngineRun {
    pub fdr: Fdr,
    pub samples: u64,
    pub provenance: Provenance,
    /// The force file the FDR was reduced from (what a run seal covers).
    pub force_file: Option<std::path::PathBuf>,
}

/// The two notes every reference-engine run of `bed` carries in its provenance: the bed
/// (grains, packing fraction, seed: what `--reuse` matches) and its sha256 (what the
/// summaries pair beds by).
pub(crate) fn push_bed_notes(provenance: &mut Provenance, case: &PenetrationCase, bed: &Bed) {
    provenance.notes.push(packing::bed_note(case, bed));
    provenance
        .notes
        .push(format!("bed sha256 {}", bed_hash(bed)));
}

/// The streaming eq-5 reducer of a run from `bed`: its own psi and surface.
pub(crate) fn binner(case: &PenetrationCase, bed: &Bed) -> Result<FdrBinner> {
    FdrBinner::new(
        &Scales {
            rho_g: case.density,
            psi: bed.psi,
            g: case.gravity,
            radius: case.intruder_radius,
        },
        bed.surface_z,
        case.h_bin,
    )
}

/// The name under which the bed of `case` (with its seed) is stored, in the bed cache
/// and in a reference record: the whole settling case is the key, safe if more than
/// the bed needs.
pub fn bed_file_name(case: &PenetrationCase) -> Option<String> {
    crate::experiments::bed_cache::name(
        "penetration",
        &crate::case::ValidatedCase::canonical_hash(&case.settling_case()).to_string(),
    )
}

/// The bed of `case` as stored with the recorded reference run of `unit` (`root`: the
/// record; the bed is in the unit's directory or, by its sealed hash, in the bed store).
/// Read before the seal is verified, which is safe: the comparison goes on only if the
/// deck built from it has the fingerprint the seal holds, i.e. the LIGGGHTS run started
/// from exactly this bed.
pub(crate) fn recorded_bed(
    case: &PenetrationCase,
    root: &std::path::Path,
    unit: &str,
) -> Option<Bed> {
    let file =
        crate::experiments::reference::store::recorded_bed_file(root, unit, &bed_file_name(case)?)?;
    crate::experiments::bed_cache::load::<Bed>(Some(&file))
}

/// LIGGGHTS' data file of a sphere bed (`data.bed`) as granval writes it for `case`
/// from `bed`: what a lean record leaves out and writes again on use. `None` for a bed
/// of clumps, whose bodies file is kept.
pub(crate) fn data_file(case: &PenetrationCase, bed: &Bed) -> Option<Result<Vec<u8>>> {
    bed.bodies.is_empty().then(|| {
        let deck = liggghts_deck(case, bed)?;
        Ok(crate::engines::liggghts::penetration::data_text(&deck)?.into_bytes())
    })
}

/// Prepares the bed natively (pour + settle to the case's KE criterion).
pub fn prepare_bed(case: &PenetrationCase, progress: bool) -> Result<Bed> {
    // With the pairs of [[interactions]]: the penetration's own act on the settled bed.
    let cache = bed_file_name(case).and_then(|n| crate::experiments::bed_cache::in_cache(&n));
    let case = &case.settling_case();
    let spec = crate::case::ValidatedCase::canonical_hash(case).to_string();
    let cached = crate::experiments::bed_cache::load_cached::<Bed>(cache.as_deref(), &spec, |b| {
        anyhow::ensure!(
            b.n_grains() == case.count && b.surface_z.is_finite() && b.psi > 0.0,
            "a bed of {} grains (surface z = {:e} m, psi = {}), the case pours {}",
            b.n_grains(),
            b.surface_z,
            b.psi,
            case.count
        );
        Ok(())
    })?;
    if let Some(b) = cached {
        return Ok(b);
    }
    let bar = crate::report::progress::status(progress, "settle");
    let bed = packing::prepare(case, |t, ratio| {
        bar.set_message(format!("t = {t:.3} s, KE ratio {ratio:.1e}"))
    })?;
    bar.finish_and_clear();
    crate::experiments::bed_cache::store(cache.as_deref(), &spec, &bed);
    Ok(bed)
}

/// The LIGGGHTS deck of a penetration case started from `bed` (identical grains,
/// container, intruder start and speed as the native run). A case of the LAMMPS family
/// is refused: LIGGGHTS 3.8 has no `tangential mindlin`, only LAMMPS 2025 can run it.
pub fn liggghts_deck(case: &PenetrationCase, bed: &Bed) -> Result<PenetrationDeck> {
    if case.family != crate::case::ContactFamily::Liggghts {
        anyhow::bail!(
            "{}: models.family = \"lammps\": LAMMPS' granular laws have no LIGGGHTS 3.8 deck; the reference of a LAMMPS-family penetration case is LAMMPS 2025 (`--engine lammps`)",
            case.source.display()
        );
    }
    penetration_deck(case, bed)
}

/// The engine-neutral inputs of one penetration run from `bed` (the LIGGGHTS deck's
/// fields, SI), whatever the case's family.
pub(crate) fn penetration_deck(case: &PenetrationCase, bed: &Bed) -> Result<PenetrationDeck> {
    use crate::engines::liggghts::penetration::Units;
    let (lo, hi) = packing::domain(case, dem::penetration::box_top(case, bed));
    // LIGGGHTS refuses E < 5e6 Pa (Table 2's G = 1 MPa gives E = 2.6 MPa) in SI *and* in
    // cgs (5e7 barye). Its own `soft_particles yes` lifts only that range check; the
    // material is written unchanged, never stiffened.
    let (soft, hard) = crate::engines::liggghts::hardness(&case.materials);
    Ok(PenetrationDeck {
        units: Units::Si,
        materials: case.materials.clone(),
        pairs: case.pairs.clone(),
        rolling: case.rolling,
        tangential_damping: case.lammps().map(|m| m.tangential_damping),
        dt: case.dt,
        gravity: case.gravity,
        container_radius: case.container_radius,
        floor_z: 0.0,
        domain_lo: lo,
        domain_hi: hi,
        particles: bed.particles.clone(),
        clump: case.clump.as_deref().cloned(),
        bodies: bed.bodies.clone(),
        intruder_radius: case.intruder_radius,
        intruder_length: case.intruder_length,
        intruder_type: case.intruder_type,
        intruder_bottom_z0: dem::penetration::start_z(case, bed),
        speed: case.speed,
        n_steps: dem::penetration::n_steps(case, bed),
        force_every: case.force_every,
        neighbor_skin: case.neighbor_skin,
        rim_error_frac: case.stl_rim_error,
        wall_type: case.wall_type,
        soft_particles: soft,
        hard_particles: hard,
        settle: None,
        viz_every: None,
        header: crate::engines::deck_text::Header {
            title: format!(
                "granval penetration case `{}`, bed seed {}: LIGGGHTS 3.8 input deck ({})",
                crate::engines::deck_text::safe(&case.name),
                case.seed,
                crate::engines::liggghts::penetration::DECK_FILE
            ),
            paragraphs: vec![crate::engines::deck_text::safe(&case.description)],
        },
    })
}

/// Fingerprint of a bed (positions, radii, velocities), so a recorded LIGGGHTS run is
/// only ever compared with a native run from the very same grains.
pub fn bed_hash(bed: &Bed) -> Sha256 {
    let mut bytes = Vec::with_capacity(bed.particles.len() * 80 + bed.bodies.len() * 112);
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
    // Bodies after the spheres (none in a sphere bed, whose hash is unchanged).
    for b in &bed.bodies {
        bytes.extend_from_slice(&b.id.to_le_bytes());
        for v in b.x.iter().chain(&b.orientation).chain(&b.v).chain(&b.omega) {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    Sha256::of(&bytes)
}

/// The LIGGGHTS deck of bed `k` of a case whose bed LIGGGHTS prepares itself (see
/// [`crate::engines::liggghts::penetration::Settle`]): the same loose lattice as the
/// native pour, settled with the same criterion, then penetrated.
pub fn liggghts_settle_deck(case: &PenetrationCase) -> Result<PenetrationDeck> {
    use crate::engines::liggghts::penetration::Settle;
    anyhow::ensure!(
        case.clump.is_none(),
        "{}: a bed of clumps is poured and settled natively and inserted into LIGGGHTS body by body; prepare the beds natively (`--bed native`)",
        case.source.display()
    );
    anyhow::ensure!(
        case.settle_pairs.is_none(),
        "{}: [[penetration_interactions]]: the bed and the penetration use different pair values, which one LIGGGHTS deck that settles and penetrates cannot switch; prepare the beds natively (`--bed native`)",
        case.source.display()
    );
    let lattice = packing::lattice(case)?;
    let lattice_top = lattice
        .iter()
        .map(|p| p.x[2] + p.radius)
        .fold(0.0, f64::max);
    let dmax = case.diameter.max();
    // Upper bound of the start height (the settled bed is lower than the lattice).
    let z0_bound = lattice_top + case.start_gap;
    let fill_guess = lattice_top;
    let bed = Bed {
        particles: lattice,
        bodies: Vec::new(),
        surface_z: fill_guess,
        psi: f64::NAN,
        ke_ratio: f64::NAN,
        settle_time: f64::NAN,
        ke_at_end_of_pour: f64::NAN,
    };
    let mut d = liggghts_deck(case, &bed)?;
    let (lo, hi) = packing::domain(case, z0_bound + case.intruder_length + dmax);
    d.domain_lo = lo;
    d.domain_hi = hi;
    d.intruder_bottom_z0 = z0_bound;
    // Travel: gap + final depth + one grain (the highest top is at most ~d_max above
    // the mean surface), so the tip reaches at least `final_depth`.
    d.n_steps = ((case.start_gap + case.final_depth + dmax) / case.speed / case.dt).ceil() as u64;
    let check_every = 50;
    d.settle = Some(Settle {
        ke_ratio: case.settle_ke_ratio,
        check_every,
        max_checks: (case.max_settle_time / case.dt / check_every as f64).ceil() as u64,
        footprint_radius: case.intruder_radius + dmax,
        start_gap: case.start_gap,
    });
    Ok(d)
}
