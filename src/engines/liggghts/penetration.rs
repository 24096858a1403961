//! LIGGGHTS 3.8 deck for the penetration experiment (Feng et al., Sec. 2, Tables 1-2): a
//! flat-bottomed cylindrical intruder (closed STL mesh, [`super::stl`]) driven down at
//! constant speed into a settled granular bed inside a cylindrical container; the force on
//! the intruder and its measured position are written every `force_every` steps.
//!
//! All inputs are SI. [`Units::Cgs`] converts everything written (deck, data file, STL)
//! to LIGGGHTS' `units cgs` and [`parse_force_file`] converts the force file back to SI.
//!
//! Measured facts about Debian's LIGGGHTS 3.8.0 this module relies on:
//! - `youngsModulus >= 5e6 required for SI units` and `youngsModulus >= 5e7 required for
//!   CGS units`: 5e7 barye = 5e6 Pa, the *same* physical limit (likewise the upper limits
//!   1e9 Pa and 1e10 barye). Changing units therefore never makes a soft material
//!   acceptable; [`choose_units`] says so. The only way past the check is LIGGGHTS' own
//!   `soft_particles yes` / `hard_particles yes` switches, which disable the range check
//!   and do not change any material value; [`PenetrationDeck::soft_particles`] and
//!   [`PenetrationDeck::hard_particles`] write them, and only when asked.
//! - `${var}` substitution of an equal-style variable prints `%.15g`, but the immediate
//!   form `$(expr)` prints `%.20g` (round-trip exact for an f64). The force line is
//!   therefore built from `$(...)` expressions that reference `f_cad[i]` directly
//!   (a `v_name` reference would go through the 15-digit string form).
//! - `fix mesh/surface/stress` stores a 9-vector: total force exerted *by the particles
//!   on the mesh* (1-3), the torque about the reference point (4-6) and the current
//!   (moved) reference point (7-9). With `reference_point` at the bottom centre,
//!   `f_cad[9]` is the measured height of the intruder's bottom face.
//!
//! Force sign convention: `f` is the force the grains exert on the intruder, in the global
//! frame; pushing down into a bed gives `f[2] > 0` (the bed resists, pushing up).

pub use super::LOG_FILE;
use super::deck::{f, model_keywords, write_contact_model};
pub(crate) use super::units::{LIGGGHTS_MAX_E_PA, LIGGGHTS_MIN_E_PA};
pub use super::units::{Units, choose_units};
pub(crate) use super::{STDERR_FILE, STDOUT_FILE};
use super::{TRANSCRIPT, VERSION_PREFIX};
use crate::case::clumps::{Clump, ClumpTemplate};
use crate::case::{Material, PairTable, Particle, RollingModel};
use crate::engines::deck_text;
use crate::engines::process::{self, Transcript};
use crate::rundata::provenance::{EngineKind, Provenance, Sha256, now_utc};
use anyhow::{Context, Result, bail};
use std::fmt::Write as _;
use std::io::BufRead;
use std::path::{Path, PathBuf};

pub const DECK_FILE: &str = "in.penetration";
pub const DATA_FILE: &str = "data.bed";
pub const STL_FILE: &str = "intruder.stl";
pub const FORCE_FILE: &str = "force.txt";
pub(crate) const README_FILE: &str = "README.md";

/// One penetration run. ALL inputs in SI; the intruder's axis is the container's (x = y = 0).
#[derive(Debug, Clone)]
pub struct PenetrationDeck {
    pub units: Units,
    pub materials: Vec<Material>,
    pub pairs: PairTable,
    pub rolling: RollingModel,
    /// LAMMPS family: the case's `tangential mindlin` damping ratio xt; `None` (a
    /// LIGGGHTS-family case): the LAMMPS deck uses the xt that makes Mindlin's
    /// tangential damping LIGGGHTS' ([`crate::engines::lammps3d_penetration`]).
    pub tangential_damping: Option<f64>,
    pub dt: f64,
    /// m/s^2, along -z.
    pub gravity: f64,
    pub container_radius: f64,
    pub floor_z: f64,
    pub domain_lo: [f64; 3],
    pub domain_hi: [f64; 3],
    /// The settled bed, SI.
    pub particles: Vec<Particle>,
    /// A settled bed of clumps instead (`particles` empty): the template and the bodies,
    /// inserted exactly ([`super::clump_bed`]).
    pub clump: Option<ClumpTemplate>,
    pub bodies: Vec<Clump>,
    pub intruder_radius: f64,
    pub intruder_length: f64,
    /// 0-based material type of the intruder mesh.
    pub intruder_type: usize,
    /// Height of the intruder's bottom face at step 0.
    pub intruder_bottom_z0: f64,
    /// m/s, downward.
    pub speed: f64,
    pub n_steps: u64,
    pub force_every: u64,
    pub neighbor_skin: f64,
    /// Maximum rim error of the STL polygon as a fraction of the intruder radius.
    pub rim_error_frac: f64,
    /// 0-based material type of the floor and container walls (the grains' type, 0).
    pub wall_type: usize,
    /// Write `soft_particles yes`: lets LIGGGHTS accept E < 5e6 Pa (its range check only;
    /// the material is written unchanged). Refused otherwise.
    pub soft_particles: bool,
    /// Write `hard_particles yes`: lets LIGGGHTS accept E > 1e9 Pa.
    pub hard_particles: bool,
    /// Settle the bed in LIGGGHTS first (`particles` is then the loose lattice).
    pub settle: Option<Settle>,
    /// Title and leading paragraphs of the deck's header (the case, its description);
    /// the deck adds what it measures, its geometry and units.
    pub header: deck_text::Header,
    /// A visualisation dump every this many steps of the penetration (`granval deck
    /// --viz N`): the grains as `custom/vtk`, the intruder mesh as `mesh/vtk`, files
    /// ParaView opens directly. granval never reads them; the deck directory's
    /// `inputs.json` records N so that `analyze` accepts the deck as written.
    pub viz_every: Option<u64>,
}

/// LIGGGHTS-side bed preparation, for beds too large to pour natively (the paper's
/// full-size 2.9e6-grain bed): the deck reads the loose lattice granval's native pour
/// starts from, settles it with the same criterion (mean KE below `ke_ratio` times its
/// peak at the end of pouring, checked every `check_every` steps), writes the settled
/// bed to `bed.dump`, and starts the intruder `start_gap` above the highest grain top
/// within `footprint_radius` of the axis, as the native engine does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settle {
    pub ke_ratio: f64,
    pub check_every: u64,
    pub max_checks: u64,
    pub footprint_radius: f64,
    pub start_gap: f64,
}

/// Settled bed written by a [`Settle`] deck (id type radius x y z vx vy vz, %.17g).
pub(crate) const BED_DUMP_FILE: &str = "bed.dump";
/// The loose lattice a [`Settle`] deck starts from.
pub const LATTICE_FILE: &str = "data.lattice";

/// What [`write_deck_dir`] wrote.
#[derive(Debug, Clone)]
pub struct DeckFiles {
    pub deck: PathBuf,
    pub data: PathBuf,
    pub stl: PathBuf,
    pub readme: PathBuf,
    /// Azimuthal segments of the intruder STL (4n facets).
    pub stl_segments: usize,
    /// SHA-256 of deck + data file + STL text.
    pub input_hash: Sha256,
}

/// One line of `force.txt`, converted to SI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceSample {
    pub step: u64,
    pub t: f64,
    /// Measured height of the intruder's bottom face (LIGGGHTS' moved reference point).
    pub z_bottom: f64,
    /// Force of the grains on the intruder (N); `f[2] > 0` when the bed resists.
    pub f: [f64; 3],
}

fn positive(name: &str, x: f64) -> Result<()> {
    if !(x.is_finite() && x > 0.0) {
        bail!("penetration deck: `{name}` = {x:e} must be positive and finite");
    }
    Ok(())
}

/// Refuses inputs LIGGGHTS would refuse or that make no sense, naming field and value.
/// The checks run in the order of the calls below; the first failure is reported.
pub(crate) fn validate(d: &PenetrationDeck) -> Result<()> {
    if let Some(n) = d.viz_every
        && (n == 0 || n > d.n_steps)
    {
        bail!(
            "--viz: {n}: the visualisation dump interval must be a whole number of steps from 1 to the run's {} steps",
            d.n_steps
        );
    }
    let n = d.materials.len();
    if n == 0 {
        bail!("penetration deck: no materials");
    }
    validate_pairs(d, n)?;
    validate_materials(d)?;
    validate_scalars(d, n)?;
    validate_geometry(d)?;
    validate_clumps(d, n)?;
    validate_particles(d, n)
}

/// The pair table must be the materials' `n` types square, and every restitution
/// coefficient in LIGGGHTS' range.
fn validate_pairs(d: &PenetrationDeck, n: usize) -> Result<()> {
    if d.pairs.n_types != n
        || [
            &d.pairs.restitution,
            &d.pairs.friction,
            &d.pairs.rolling_friction,
        ]
        .iter()
        .any(|v| v.len() != n * n)
    {
        bail!(
            "penetration deck: pair table is for {} types with {}/{}/{} entries, the deck has {n} materials (needs {} entries each)",
            d.pairs.n_types,
            d.pairs.restitution.len(),
            d.pairs.friction.len(),
            d.pairs.rolling_friction.len(),
            n * n
        );
    }
    Ok(())
}

/// Every material within LIGGGHTS 3.8's ranges: Young's modulus from 5e6 to 1e9 Pa
/// unless the deck writes `soft_particles` / `hard_particles` (the module's header: the
/// same limit in cgs), 0 <= nu <= 0.5.
fn validate_materials(d: &PenetrationDeck) -> Result<()> {
    for (t, m) in d.materials.iter().enumerate() {
        let e = m.youngs_modulus;
        if !e.is_finite() || e <= 0.0 {
            bail!(
                "penetration deck: youngs_modulus of material type {} = {e:e} Pa",
                t + 1
            );
        }
        if e < LIGGGHTS_MIN_E_PA && !d.soft_particles {
            bail!(
                "penetration deck: youngs_modulus of material type {} = {e:e} Pa is below LIGGGHTS 3.8's limit of 5e6 Pa \
                 (5e7 barye in cgs: the same value, so units do not help); granval does not change materials — \
                 set soft_particles = true to make LIGGGHTS skip its check with the material unchanged",
                t + 1
            );
        }
        if e > LIGGGHTS_MAX_E_PA && !d.hard_particles {
            bail!(
                "penetration deck: youngs_modulus of material type {} = {e:e} Pa is above LIGGGHTS 3.8's limit of 1e9 Pa; \
                 set hard_particles = true to make LIGGGHTS skip its check with the material unchanged",
                t + 1
            );
        }
        if !(0.0..=0.5).contains(&m.poisson_ratio) {
            bail!(
                "penetration deck: poisson_ratio of material type {} = {:e}: LIGGGHTS requires 0 <= nu <= 0.5",
                t + 1,
                m.poisson_ratio
            );
        }
    }
    let n = d.materials.len();
    for a in 0..n {
        for b in 0..n {
            let e = d.pairs.restitution[d.pairs.idx(a, b)];
            if !(e > super::MIN_RESTITUTION_EXCLUSIVE && e <= 1.0) {
                bail!(
                    "penetration deck: restitution of types [{}, {}] = {e:e}: LIGGGHTS requires 0.05 < e <= 1",
                    a + 1,
                    b + 1
                );
            }
        }
    }
    Ok(())
}

/// The intruder's and walls' types among the `n` materials; positive sizes, step, speed
/// and skin; gravity >= 0 (it acts along -z); a positive step count and force interval.
fn validate_scalars(d: &PenetrationDeck, n: usize) -> Result<()> {
    for (name, t) in [
        ("intruder_type", d.intruder_type),
        ("wall_type", d.wall_type),
    ] {
        if t >= n {
            bail!("penetration deck: `{name}` = {t} (0-based) but there are only {n} materials");
        }
    }
    for (name, x) in [
        ("dt", d.dt),
        ("container_radius", d.container_radius),
        ("intruder_radius", d.intruder_radius),
        ("intruder_length", d.intruder_length),
        ("speed", d.speed),
        ("neighbor_skin", d.neighbor_skin),
        ("rim_error_frac", d.rim_error_frac),
    ] {
        positive(name, x)?;
    }
    if !(d.gravity.is_finite() && d.gravity >= 0.0) {
        bail!(
            "penetration deck: `gravity` = {:e} must be >= 0 (it acts along -z)",
            d.gravity
        );
    }
    if d.n_steps == 0 || d.force_every == 0 {
        bail!(
            "penetration deck: n_steps = {} and force_every = {} must be positive",
            d.n_steps,
            d.force_every
        );
    }
    Ok(())
}

/// The intruder inside the container, the container and the floor inside the domain, and
/// the whole intruder mesh inside the domain for the whole run, above the floor.
fn validate_geometry(d: &PenetrationDeck) -> Result<()> {
    if d.intruder_radius >= d.container_radius {
        bail!(
            "penetration deck: intruder_radius {:e} m must be smaller than container_radius {:e} m",
            d.intruder_radius,
            d.container_radius
        );
    }
    for k in 0..3 {
        if d.domain_lo[k] >= d.domain_hi[k] || d.domain_lo[k].is_nan() || d.domain_hi[k].is_nan() {
            bail!(
                "penetration deck: domain_lo[{k}] = {:e} must be below domain_hi[{k}] = {:e}",
                d.domain_lo[k],
                d.domain_hi[k]
            );
        }
    }
    let r = d.container_radius;
    if d.domain_lo[0] > -r || d.domain_hi[0] < r || d.domain_lo[1] > -r || d.domain_hi[1] < r {
        bail!(
            "penetration deck: the container (radius {r:e} m about x = y = 0) does not fit in the domain"
        );
    }
    if !(d.floor_z > d.domain_lo[2] && d.floor_z < d.domain_hi[2]) {
        bail!(
            "penetration deck: floor_z = {:e} is outside the domain z range",
            d.floor_z
        );
    }
    // LIGGGHTS errors when a mesh element's centre leaves the domain; keep the whole mesh in.
    let top = d.intruder_bottom_z0 + d.intruder_length;
    let bottom_end = d.intruder_bottom_z0 - d.speed * d.dt * d.n_steps as f64;
    if top >= d.domain_hi[2] {
        bail!(
            "penetration deck: the intruder's top at z = {top:e} m is not below domain_hi[2] = {:e} m",
            d.domain_hi[2]
        );
    }
    if bottom_end <= d.floor_z {
        bail!(
            "penetration deck: the intruder's bottom would reach z = {bottom_end:e} m after {} steps, at or below the floor {:e} m",
            d.n_steps,
            d.floor_z
        );
    }
    Ok(())
}

/// A bed of clumps: bodies only, with their template (of one of the `n` types), settled
/// by granval, every body inside the domain with its bounding radius.
fn validate_clumps(d: &PenetrationDeck, n: usize) -> Result<()> {
    if d.bodies.is_empty() {
        return Ok(());
    }
    let Some(t) = &d.clump else {
        bail!("penetration deck: clump bodies without their template");
    };
    if !d.particles.is_empty() || d.settle.is_some() {
        bail!(
            "penetration deck: a bed of clumps holds bodies only and is settled by granval (not in the deck)"
        );
    }
    if t.type_ >= n {
        bail!(
            "penetration deck: the clump template has type {} (0-based), only {n} materials",
            t.type_
        );
    }
    for b in &d.bodies {
        if (0..3).any(|k| {
            !(b.x[k] - t.bounding_radius > d.domain_lo[k]
                && b.x[k] + t.bounding_radius < d.domain_hi[k])
        }) {
            bail!(
                "penetration deck: clump {} at {:?} m does not fit in the domain with its bounding radius {:e} m",
                b.id,
                b.x,
                t.bounding_radius
            );
        }
    }
    Ok(())
}

/// Every sphere of the bed: a type among the `n` materials, positive radius and density,
/// its centre inside the domain.
fn validate_particles(d: &PenetrationDeck, n: usize) -> Result<()> {
    for p in &d.particles {
        if p.type_ >= n {
            bail!(
                "penetration deck: particle {} has type {} (0-based), only {n} materials",
                p.id,
                p.type_
            );
        }
        if !(p.radius > 0.0 && p.density > 0.0) {
            bail!(
                "penetration deck: particle {} has radius {:e} m, density {:e} kg/m^3",
                p.id,
                p.radius,
                p.density
            );
        }
        if (0..3).any(|k| !(p.x[k] > d.domain_lo[k] && p.x[k] < d.domain_hi[k])) {
            bail!(
                "penetration deck: particle {} at {:?} m is outside the domain",
                p.id,
                p.x
            );
        }
    }
    Ok(())
}

/// The `read_data` file of the bed in the deck's units (`atom-ID type diameter density x y z`,
/// then `Velocities`), every float in `{:e}`.
pub(crate) fn data_text(d: &PenetrationDeck) -> Result<String> {
    validate(d)?;
    if !d.bodies.is_empty() {
        return Ok(super::clump_bed::bodies_text(&d.bodies));
    }
    let u = d.units;
    Ok(super::deck::data_text(
        &format!("penetration bed ({} units)", u.keyword()),
        &d.particles,
        d.materials.len(),
        d.domain_lo,
        d.domain_hi,
        u.length(),
        u.velocity(),
        u.density(),
    ))
}

/// Thermo output interval: about 1 % of the run, so a progress bar can follow the log.
pub(crate) fn thermo_every(n_steps: u64) -> u64 {
    (n_steps / 100).max(1)
}

/// Number of lines `force.txt` holds after a complete run (fix print skips step 0).
pub fn expected_samples(d: &PenetrationDeck) -> usize {
    (d.n_steps / d.force_every) as usize
}

/// The deck text (reads `data.bed` and `intruder.stl` from the run directory).
pub fn deck_text(d: &PenetrationDeck) -> Result<String> {
    deck_text_with_snapshots(d, &[])
}

/// [`deck_text`] plus contact/grain dumps at `snapshot_steps` ([`super::snapshot`]);
/// with no steps the two hold the same commands.
pub(crate) fn deck_text_with_snapshots(
    d: &PenetrationDeck,
    snapshot_steps: &[u64],
) -> Result<String> {
    validate(d)?;
    let snapshots = super::snapshot::deck_block(snapshot_steps, d.n_steps)?;
    let mut s = String::new();
    write_penetration_header(&mut s, d);
    write_atom_style(&mut s, d)?;
    write_grains(&mut s, d)?;
    let u = d.units;
    write_contact_model(
        &mut s,
        &d.materials,
        &d.pairs,
        d.rolling,
        u.pressure(),
        u.pressure_unit(),
    )?;
    write_gravity_and_container(&mut s, d)?;
    if let Some(st) = &d.settle {
        write_settle_block(&mut s, d, st)?;
    }
    write_intruder(&mut s, d)?;
    write_output(&mut s, d, &snapshots)?;
    write_run(&mut s, d)?;
    Ok(s)
}

/// The header: the case's title and paragraphs, then what the run measures (Feng et
/// al. eq 5), the geometry in SI, the deck's units and how to run it.
fn write_penetration_header(s: &mut String, d: &PenetrationDeck) {
    let u = d.units;
    let (lu, vu) = (u.length_unit(), u.velocity_unit());
    let travel = d.speed * d.dt * d.n_steps as f64;
    let mut paragraphs = d.header.paragraphs.clone();
    paragraphs.push(format!(
        "What the run measures: the force of the grains on a flat-bottomed cylindrical \
         intruder driven down at constant speed into a settled bed, and the height of the \
         intruder's bottom face, every {} steps ({FORCE_FILE}). granval reduces them to the \
         dimensionless force-depth relation p = F / (rho_g psi g S R) against h / R (Feng et al. \
         eq 5) and fits its steady-state slope K_phi (regime C, Table 3).",
        d.force_every
    ));
    paragraphs.push(format!(
        "Geometry (SI): {} grains {} in a cylindrical container of radius {} m about the z axis, \
         floor at z = {} m; intruder radius {} m, length {} m, {}; speed {} m/s down for {} steps \
         of {} s (travel {} m).",
        d.particles.len() + d.bodies.len(),
        if d.settle.is_some() {
            "poured as a loose lattice and settled by this deck"
        } else {
            "settled by granval's native engine"
        },
        f(d.container_radius),
        f(d.floor_z),
        f(d.intruder_radius),
        f(d.intruder_length),
        if d.settle.is_some() {
            "its bottom placed just above the settled bed".to_string()
        } else {
            format!("its bottom starting at z = {} m", f(d.intruder_bottom_z0))
        },
        f(d.speed),
        d.n_steps,
        f(d.dt),
        deck_text::approx(travel),
    ));
    paragraphs.push(format!(
        "Units of this deck: {}{}.",
        u.names(),
        if u == Units::Si {
            String::new()
        } else {
            format!(
                " (lengths {lu}, velocities {vu}, densities {}, pressures {}); granval converts \
                 every input from SI and the outputs back",
                u.density_unit(),
                u.pressure_unit()
            )
        }
    ));
    paragraphs.push(format!(
        "Run it in this directory: `liggghts -in {DECK_FILE} -log {LOG_FILE}`, or with N MPI \
         processes `mpirun -np N liggghts -in {DECK_FILE} -log {LOG_FILE}`; then `granval \
         analyze DIR --report OUT` (README.md)."
    ));
    deck_text::write_header(
        s,
        &deck_text::Header {
            title: if d.header.title.is_empty() {
                format!("granval penetration deck: LIGGGHTS 3.8 input ({DECK_FILE})")
            } else {
                d.header.title.clone()
            },
            paragraphs,
        },
    );
}

/// Units, atom style, atom map, boundaries and the parallel layout LIGGGHTS' granular
/// pair style needs, and the switches past its Young's modulus range check.
fn write_atom_style(s: &mut String, d: &PenetrationDeck) -> Result<()> {
    let u = d.units;
    let max_id = d.particles.iter().map(|p| p.id).max().unwrap_or(0);
    let map = if max_id > 10_000_000 { "hash" } else { "array" };
    deck_text::block(
        s,
        &format!(
            "---- Box, atoms, parallel layout ----\n\
             Units `{}`. `atom_style granular`: every atom is a sphere with a diameter, a density \
             (its mass follows) and an angular velocity; atoms are looked up by ID in an array \
             (`map array`; a hash above 10 million IDs). `boundary f f f`: a closed box; a grain \
             that leaves it stops the run (thermo_modify below).",
            u.keyword()
        ),
    );
    writeln!(s, "units {}", u.keyword())?;
    writeln!(s, "atom_style granular")?;
    if !d.bodies.is_empty() {
        // fix multisphere needs the map; no sorting keeps members in insertion order.
        writeln!(s, "atom_modify map array sort 0 0.0")?;
    } else {
        writeln!(s, "atom_modify map {map}")?;
    }
    writeln!(s, "boundary f f f")?;
    deck_text::comment(
        s,
        "`newton off`: LIGGGHTS' granular pair style with shear history requires it (a pair \
         split between two MPI processes is computed on both). `communicate single vel yes`: \
         ghost atoms carry velocities, which the damping and tangential forces need. \
         `processors * * 1`: the bed fills only the lower part of a tall box, and LIGGGHTS' \
         default grid would split z first and leave every grain on one process; so only x and \
         y are divided among the MPI processes.",
    );
    writeln!(s, "newton off")?;
    writeln!(s, "communicate single vel yes")?;
    writeln!(s, "processors * * 1")?;
    super::deck::write_hardness(s, &d.materials, d.soft_particles, d.hard_particles)?;
    Ok(())
}

/// The box and the grains: the data file of the bed (native or the lattice a settle
/// deck pours), or for clumps an empty box the bodies are inserted into later; then
/// the neighbour lists.
fn write_grains(s: &mut String, d: &PenetrationDeck) -> Result<()> {
    let u = d.units;
    let l = u.length();
    let (lu, vu) = (u.length_unit(), u.velocity_unit());
    let data = if d.settle.is_some() {
        LATTICE_FILE
    } else {
        DATA_FILE
    };
    if !d.bodies.is_empty() {
        deck_text::block(
            s,
            &format!(
                "The box ({lu}); the grains are rigid clumps, inserted body by body below after                  the walls ({}: the bodies granval settled natively).",
                super::clump_bed::BODIES_FILE
            ),
        );
        writeln!(
            s,
            "region domain block {} {} {} {} {} {} units box",
            f(d.domain_lo[0] * l),
            f(d.domain_hi[0] * l),
            f(d.domain_lo[1] * l),
            f(d.domain_hi[1] * l),
            f(d.domain_lo[2] * l),
            f(d.domain_hi[2] * l)
        )?;
        writeln!(s, "create_box {} domain", d.materials.len())?;
    } else {
        deck_text::block(
            s,
            &format!(
                "The grains: {data} holds the box ({lu}) and per grain its ID, type, diameter ({lu}), \
             density ({}), position ({lu}), velocity ({vu}) and angular velocity (rad/s){}.",
                u.density_unit(),
                if d.settle.is_some() {
                    ": the loose lattice granval's native pour also starts from"
                } else {
                    ": the bed granval's native engine poured and settled (Feng et al. Sec. 2), \
                 exactly, so both engines penetrate the very same grains"
                }
            ),
        );
        writeln!(s, "read_data {data}")?;
    }
    deck_text::block(
        s,
        &format!(
            "Neighbour lists: skin {} {lu} (the case's neighbor_skin), rebuilt whenever a grain \
             has moved more than half the skin since the last build. It changes the cost, not \
             the physics.",
            f(d.neighbor_skin * l)
        ),
    );
    writeln!(s, "neighbor {} bin", f(d.neighbor_skin * l))?;
    writeln!(s, "neigh_modify delay 0")?;
    Ok(())
}

/// Time step, gravity, the container (floor and cylinder with the grains' contact law,
/// as in the native engine) and the integration of the grains: spheres by
/// `nve/sphere`, clumps by their insertion and `fix multisphere`.
fn write_gravity_and_container(s: &mut String, d: &PenetrationDeck) -> Result<()> {
    let u = d.units;
    let (l, v) = (u.length(), u.velocity());
    let (lu, vu) = (u.length_unit(), u.velocity_unit());
    let models = model_keywords(d.rolling);
    deck_text::block(
        s,
        &format!(
            "---- Time integration, gravity, walls ----\n\
             Time step {} s (the case's dt; Feng et al. use about 20 % of the Rayleigh time, \
             Sec. 2).",
            f(d.dt)
        ),
    );
    writeln!(s, "timestep {}", f(d.dt))?;
    if d.gravity > 0.0 {
        deck_text::comment(s, &format!("Gravity {} {vu}/s along -z.", f(d.gravity * v)));
        writeln!(
            s,
            "fix gravi all gravity {} vector 0 0 -1",
            f(d.gravity * v)
        )?;
    }
    let wt = d.wall_type + 1;
    deck_text::comment(
        s,
        &format!(
            "The container: a floor at z = {} {lu} and a cylinder of radius {} {lu} about the z \
             axis, of material type {wt}, with the grains' contact law.",
            f(d.floor_z * l),
            f(d.container_radius * l)
        ),
    );
    writeln!(
        s,
        "fix floor all wall/gran {models} primitive type {wt} zplane {}",
        f(d.floor_z * l)
    )?;
    writeln!(
        s,
        "fix container all wall/gran {models} primitive type {wt} zcylinder {} 0 0",
        f(d.container_radius * l)
    )?;
    if let (true, Some(t)) = (!d.bodies.is_empty(), &d.clump) {
        super::clump_bed::write_insertion(s, t, &d.bodies, d.n_steps)?;
    } else {
        deck_text::comment(
            s,
            "Velocity Verlet for spheres (`nve/sphere`: half kick, drift, forces, half kick; \
             moment of inertia 0.4 m r^2).",
        );
        writeln!(s, "fix integr all nve/sphere")?;
    }
    Ok(())
}

/// The intruder: the closed STL mesh whose `mesh/surface/stress` gives the measured
/// force and bottom height (see the module doc), its contacts and its constant-speed
/// drive (Feng et al.: quasi-static, constant speed).
fn write_intruder(s: &mut String, d: &PenetrationDeck) -> Result<()> {
    let u = d.units;
    let (l, v) = (u.length(), u.velocity());
    let (lu, vu) = (u.length_unit(), u.velocity_unit());
    let models = model_keywords(d.rolling);
    deck_text::block(
        s,
        &format!(
            "---- The intruder ----\n\
             {STL_FILE}: a closed triangle mesh of the flat-bottomed cylinder (radius {} {lu}, \
             length {} {lu}), material type {}. `mesh/surface/stress` sums the force the grains \
             exert on it; with the reference point at the bottom centre, f_cad[1..3] is that \
             force, f_cad[4..6] its torque about that point and f_cad[9] the measured height of \
             the bottom face. {}",
            f(d.intruder_radius * l),
            f(d.intruder_length * l),
            d.intruder_type + 1,
            if d.settle.is_some() {
                "The mesh is written with its bottom at z = 0 and moved up to z0 (above)."
            } else {
                "The mesh is written at its start position, so nothing moves it before the run."
            }
        ),
    );
    if d.settle.is_some() {
        writeln!(
            s,
            "fix cad all mesh/surface/stress file {STL_FILE} type {} move 0 0 ${{z0}} stress on reference_point 0 0 ${{z0}}",
            d.intruder_type + 1
        )?;
    } else {
        writeln!(
            s,
            "fix cad all mesh/surface/stress file {STL_FILE} type {} stress on reference_point 0 0 {}",
            d.intruder_type + 1,
            f(d.intruder_bottom_z0 * l)
        )?;
    }
    deck_text::comment(
        s,
        &format!(
            "Grain-intruder contacts use the same contact law; the mesh moves down at constant \
             speed {} {vu}, whatever the force (Feng et al.: quasi-static, constant speed).",
            f(d.speed * v)
        ),
    );
    writeln!(
        s,
        "fix wallint all wall/gran {models} mesh n_meshes 1 meshes cad"
    )?;
    writeln!(
        s,
        "fix mv all move/mesh mesh cad linear 0 0 {}",
        f(-d.speed * v)
    )?;
    Ok(())
}

/// The measurement ([`FORCE_FILE`], at full precision, the columns [`parse_force_file`]
/// reads), the thermo line granval's progress bar follows, and the optional snapshot
/// and visualisation dumps.
fn write_output(s: &mut String, d: &PenetrationDeck, snapshots: &str) -> Result<()> {
    let u = d.units;
    let lu = u.length_unit();
    deck_text::block(
        s,
        &format!(
            "---- Output ----\n\
             The measurement: every {} steps one line of {FORCE_FILE}, `step t z_bottom fx fy fz` \
             (s, {lu}, {}; f = force of the grains on the intruder, fz > 0 when the bed pushes \
             back). `$(...)` prints %.20g, so every double reads back exactly (`${{name}}` would \
             print only 15 digits).",
            d.force_every,
            u.force_unit()
        ),
    );
    writeln!(
        s,
        "fix fout all print {} \"$(step) $(step*dt) $(f_cad[9]) $(f_cad[1]) $(f_cad[2]) $(f_cad[3])\" file {FORCE_FILE} screen no title \"{}\"",
        d.force_every,
        force_title(d)
    )?;
    deck_text::comment(
        s,
        &format!(
            "Thermo line every {} steps (about 1 % of the run; granval's progress bar follows \
             it). `thermo_modify lost error`: LIGGGHTS 3.8 would silently drop a grain that \
             leaves the closed box; granval makes that an error. It must follow thermo_style, \
             which resets thermo_modify.",
            thermo_every(d.n_steps)
        ),
    );
    writeln!(s, "thermo_style custom step atoms ke cpu")?;
    writeln!(s, "thermo_modify lost error")?;
    writeln!(s, "thermo {}", thermo_every(d.n_steps))?;
    if !snapshots.is_empty() {
        s.push('\n');
        s.push_str(snapshots);
    }
    if let Some(n) = d.viz_every {
        viz_block(s, n, d)?;
    }
    Ok(())
}

/// The penetration run; a settle deck takes its length from an `index` variable so
/// that start-up tests can shorten it.
fn write_run(s: &mut String, d: &PenetrationDeck) -> Result<()> {
    deck_text::block(
        s,
        &format!(
            "{} steps of penetration ({} s).{}",
            d.n_steps,
            deck_text::approx(d.dt * d.n_steps as f64),
            if d.settle.is_some() {
                " `-var pen_steps N` shortens it (start-up tests)."
            } else {
                ""
            }
        ),
    );
    if d.settle.is_some() {
        writeln!(s, "variable pen_steps index {}", d.n_steps)?;
        writeln!(s, "run ${{pen_steps}}")?;
    } else {
        writeln!(s, "run {}", d.n_steps)?;
    }
    Ok(())
}

/// File name patterns of the visualisation dump (`*` is the step).
pub(crate) const VIZ_GRAINS: &str = "viz-grains-*.vtk";
pub(crate) const VIZ_INTRUDER: &str = "viz-intruder-*.vtk";

/// The visualisation dump of `granval deck --viz N`: what ParaView opens, written beside
/// the measurement and never read by granval.
fn viz_block(s: &mut String, n: u64, d: &PenetrationDeck) -> Result<()> {
    let u = d.units;
    deck_text::block(
        s,
        &format!(
            "---- Visualisation (granval deck --viz {n}) ----\n\
             Every {n} steps of the penetration: the grains as legacy VTK ({VIZ_GRAINS}: id, \
             type, radius, position, velocity, force, angular velocity; {lu}, {vu}, {fu}) and the \
             intruder mesh with the stress the grains put on each facet ({VIZ_INTRUDER}); LIGGGHTS \
             adds the domain's box as viz-grains-boundingBox_*.vtk. Open \
             either series in ParaView (File > Open, the `..` group) and draw the grains with \
             the Point Gaussian representation scaled by `radius`. The container is a \
             `wall/gran` primitive, not a mesh, so it is not in these files: a cylinder of \
             radius {} m about the z axis, floor at z = {} m. granval never reads these files; \
             `inputs.json` records --viz so `granval analyze` accepts this deck.",
            f(d.container_radius),
            f(d.floor_z),
            lu = u.length_unit(),
            vu = u.velocity_unit(),
            fu = u.force_unit(),
        ),
    );
    writeln!(
        s,
        "dump viz all custom/vtk {n} {VIZ_GRAINS} id type radius x y z vx vy vz fx fy fz omegax omegay omegaz"
    )?;
    writeln!(s, "dump vizmesh all mesh/vtk {n} {VIZ_INTRUDER} stress cad")?;
    Ok(())
}

/// The settling loop and intruder placement of a [`Settle`] deck. `settle_checks` is an
/// `index` variable, so `-var settle_checks N` caps a smoke run at N * check_every steps.
fn write_settle_block(s: &mut String, d: &PenetrationDeck, st: &Settle) -> Result<()> {
    let every = st.check_every;
    deck_text::block(
        s,
        &format!(
            "---- Bed preparation (Feng et al. Sec. 2, granval's native protocol) ----\n\
             The lattice falls under gravity; every {every} steps the mean kinetic energy per \
             grain is checked. Its peak while pouring is tracked until it drops below half the \
             peak (the pour is over); the bed is settled when it is below {} of that peak \
             (the case's settle_ke_ratio; Feng et al.: 1e-7), after at most {} checks (the \
             case's max_settle_time). `-var settle_checks N` caps the checks, `-var smoke 1` \
             skips the settling test (start-up tests of decks too big to run here).",
            f(st.ke_ratio),
            st.max_checks
        ),
    );
    writeln!(s, "thermo_style custom step atoms ke cpu")?;
    writeln!(s, "thermo_modify lost error")?;
    writeln!(s, "thermo {}", every * 20)?;
    writeln!(s, "variable settle_checks index {}", st.max_checks)?;
    writeln!(s, "variable smoke index 0")?;
    writeln!(s, "variable kepeak equal 0")?;
    writeln!(s, "variable poured equal 0")?;
    writeln!(s, "variable ratio equal 1")?;
    writeln!(s, "variable nchk loop ${{settle_checks}}")?;
    writeln!(s, "label settle_loop")?;
    writeln!(s, "run {every} post no")?;
    writeln!(s, "variable kenow equal $(ke/atoms)")?;
    writeln!(s, "variable half equal $(0.5*v_kepeak)")?;
    // `elif` takes its commands directly, without `then` (LIGGGHTS' if command).
    writeln!(
        s,
        "if \"${{poured}} == 0 && ${{kenow}} >= ${{kepeak}}\" then \"variable kepeak equal ${{kenow}}\" elif \"${{poured}} == 0 && ${{kenow}} < ${{half}}\" \"variable poured equal 1\""
    )?;
    writeln!(
        s,
        "if \"${{poured}} == 1\" then \"variable ratio equal $(v_kenow/v_kepeak)\""
    )?;
    writeln!(
        s,
        "if \"${{poured}} == 1 && ${{ratio}} < {}\" then \"jump SELF settled\"",
        f(st.ke_ratio)
    )?;
    writeln!(s, "next nchk")?;
    writeln!(s, "jump SELF settle_loop")?;
    writeln!(s, "if \"${{smoke}} == 1\" then \"jump SELF settled\"")?;
    writeln!(
        s,
        "print \"granval: bed not settled after $(step) steps (KE ratio ${{ratio}}, target {})\"",
        f(st.ke_ratio)
    )?;
    writeln!(s, "quit")?;
    writeln!(s, "label settled")?;
    writeln!(
        s,
        "print \"granval: bed settled at step $(step), KE ratio ${{ratio}}\""
    )?;
    write_intruder_start(s, d, st)
}

/// After settling: the settled bed written for `granval analyze`, and the intruder's
/// start height from the highest grain top under its footprint, where the native
/// engine places it.
fn write_intruder_start(s: &mut String, d: &PenetrationDeck, st: &Settle) -> Result<()> {
    let l = d.units.length();
    deck_text::comment(
        s,
        &format!(
            "The settled bed, written to {BED_DUMP_FILE} (id type radius x y z vx vy vz, %.17g): \
             `granval analyze` reads it back to know the grains the intruder met."
        ),
    );
    writeln!(
        s,
        "write_dump all custom {BED_DUMP_FILE} id type radius x y z vx vy vz modify format \"%d %d %.17g %.17g %.17g %.17g %.17g %.17g %.17g\""
    )?;
    deck_text::comment(
        s,
        &format!(
            "The intruder starts {} {} above the highest grain top within {} {} of the axis \
             (as in granval's native engine): z0 = max(z + r) over that footprint + the gap. \
             LIGGGHTS 3.8's atom-style variables know no `radius`, compute property/atom does; \
             the gap is written in plain decimals because its formula parser would read `1e-3` \
             as a thermo keyword.",
            st.start_gap * l,
            d.units.length_unit(),
            f(st.footprint_radius * l),
            d.units.length_unit()
        ),
    );
    writeln!(
        s,
        "region foot cylinder z 0 0 {} {} {} units box",
        f(st.footprint_radius * l),
        f(d.domain_lo[2] * l),
        f(d.domain_hi[2] * l)
    )?;
    writeln!(s, "compute rad all property/atom radius")?;
    writeln!(s, "variable top atom z+c_rad")?;
    writeln!(s, "compute ztop all reduce/region foot max v_top")?;
    writeln!(s, "thermo_style custom step atoms ke c_ztop")?;
    writeln!(s, "run 0")?;
    writeln!(s, "variable z0 equal $(c_ztop+{})", st.start_gap * l)?;
    writeln!(
        s,
        "print \"granval: intruder bottom starts at z0 = ${{z0}}\""
    )?;
    deck_text::comment(s, "Penetration starts at step 0.");
    writeln!(s, "reset_timestep 0")?;
    Ok(())
}

fn readme_text(d: &PenetrationDeck, segments: usize) -> String {
    let u = d.units;
    let force_unit = match u {
        Units::Si => "N",
        Units::Cgs => "dyn",
    };
    let len_unit = match u {
        Units::Si => "m",
        Units::Cgs => "cm",
    };
    format!(
        "# LIGGGHTS penetration run (written by granval)\n\n\
         Flat-bottomed cylindrical intruder (R = {r:e} m, L = {len:e} m, {segments}-segment STL) driven down at \
         {speed:e} m/s into a bed of {np} grains in a cylinder of radius {cr:e} m; {steps} steps of {dt:e} s.\n\
         Deck units: `{kw}` ({names}); granval converts back to SI when it reads the results.\n\n\
         ## Run\n\n\
         One core, in this directory:\n\n    liggghts -in {DECK_FILE}\n\n\
         N MPI ranks (add `--allow-run-as-root` when running as root):\n\n    mpirun -np N liggghts -in {DECK_FILE}\n\n\
         granval itself runs `liggghts -in {DECK_FILE} -log {LOG_FILE}` with stdout/stderr in \
         `{STDOUT_FILE}` / `{STDERR_FILE}`.\n\n\
         ## Files\n\n\
         - `{DECK_FILE}`: the LIGGGHTS deck.\n\
         {grains_line}\
         - `{STL_FILE}`: the intruder, closed ASCII STL in {len_unit}, already at its start position.\n\
         - `{FORCE_FILE}` (output): every {every} steps, `step t z_bottom fx fy fz`: time (s), measured height of the \
           intruder's bottom face ({len_unit}) and the force of the grains on the intruder ({force_unit}; fz > 0 = the bed \
           pushes the intruder up), printed with 17+ significant digits.\n\
         - `{LOG_FILE}` (output): LIGGGHTS log, thermo line every {thermo} steps (~1 % of the run).\n\n\
         ## Analysis\n\n    granval analyze DIR --report OUT\n\n\
         with DIR the deck directory that holds this run directory and `case.toml` (a run \
         directory of `granval compare` is read the same way): reads `{FORCE_FILE}` (converted \
         to SI) from here and writes the report to OUT.\n",
        r = d.intruder_radius,
        len = d.intruder_length,
        speed = d.speed,
        np = d.particles.len() + d.bodies.len(),
        grains_line = if d.bodies.is_empty() {
            format!(
                "- `{DATA_FILE}`: the settled bed (`read_data`): box, `atom-ID type diameter density x y z`, velocities; {len_unit}, {}, {len_unit}/s.\n",
                if u == Units::Si { "kg/m^3" } else { "g/cm^3" }
            )
        } else {
            format!(
                "- `{}`: the settled rigid clumps (not read by LIGGGHTS: the deck inserts each body itself), `id x y z qw qx qy qz vx vy vz wx wy wz`, SI.\n\
                 - `{}` (output): the bodies at step 0 of the penetration, for granval's start-state check.\n",
                super::clump_bed::BODIES_FILE,
                super::clump_bed::START_DUMP_FILE
            )
        },
        cr = d.container_radius,
        steps = d.n_steps,
        dt = d.dt,
        kw = u.keyword(),
        names = u.names(),
        every = d.force_every,
        thermo = thermo_every(d.n_steps),
    )
}

/// The grains' file of a deck directory: the lattice a settling deck pours, the bodies
/// of a clump bed, else the bed LIGGGHTS reads.
pub(crate) fn data_file_name(d: &PenetrationDeck) -> &'static str {
    if d.settle.is_some() {
        LATTICE_FILE
    } else if !d.bodies.is_empty() {
        super::clump_bed::BODIES_FILE
    } else {
        DATA_FILE
    }
}

/// Writes `in.penetration`, `data.bed`, `intruder.stl` and `README.md` into `dir`
/// (created if missing). Nothing is written unless the deck validates.
pub fn write_deck_dir(d: &PenetrationDeck, dir: &Path) -> Result<DeckFiles> {
    write_deck_dir_with_snapshots(d, dir, &[])
}

/// [`write_deck_dir`] with contact snapshots at `snapshot_steps`.
pub(crate) fn write_deck_dir_with_snapshots(
    d: &PenetrationDeck,
    dir: &Path,
    snapshot_steps: &[u64],
) -> Result<DeckFiles> {
    let deck = deck_text_with_snapshots(d, snapshot_steps)?;
    let data = data_text(d)?;
    let (stl, segments) = stl_text(d);
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create run directory {}", dir.display()))?;
    let readme = readme_text(d, segments);
    let files = DeckFiles {
        deck: dir.join(DECK_FILE),
        data: dir.join(data_file_name(d)),
        stl: dir.join(STL_FILE),
        readme: dir.join(README_FILE),
        stl_segments: segments,
        input_hash: deck_text::fingerprint(&[&deck, &data, &stl]),
    };
    for (p, text) in [
        (&files.deck, &deck),
        (&files.data, &data),
        (&files.stl, &stl),
        (&files.readme, &readme),
    ] {
        std::fs::write(p, text).with_context(|| format!("cannot write {}", p.display()))?;
    }
    Ok(files)
}

/// Reads `force.txt` into memory (small files, tests); see [`for_each_force_sample`].
pub fn parse_force_file(path: &Path, units: Units) -> Result<Vec<ForceSample>> {
    let mut out = Vec::new();
    for_each_force_sample(path, units, |s| {
        out.push(*s);
        Ok(())
    })?;
    Ok(out)
}

/// Streams `force.txt` line by line, converting each sample to SI and handing it to
/// `visit`; nothing is kept, so memory does not grow with the number of output steps.
/// Lines starting with `#` and blank lines are skipped; errors name file and line.
pub(crate) fn for_each_force_sample(
    path: &Path,
    units: Units,
    mut visit: impl FnMut(&ForceSample) -> Result<()>,
) -> Result<()> {
    let file = crate::rundata::fsio::open_engine_output(path, "a LIGGGHTS log (thermo lines)")?;
    let mut reader = std::io::BufReader::new(file);
    let (l, fo) = (units.length(), units.force());
    let mut line = String::new();
    let mut lineno = 0usize;
    loop {
        line.clear();
        let n = reader
            .read_line(&mut line)
            .with_context(|| format!("{}:{}: read error", path.display(), lineno + 1))?;
        if n == 0 {
            break;
        }
        lineno += 1;
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let mut it = t.split_whitespace();
        let bad = |what: &str| {
            anyhow::anyhow!(
                "{}:{lineno}: {what} in force line {t:?} (expected `step t z_bottom fx fy fz`)",
                path.display()
            )
        };
        let step_tok = it.next().ok_or_else(|| bad("missing step"))?;
        // %.20g prints an integer step as an integer, but accept "1000.0"-like forms too.
        let step = match step_tok.parse::<u64>() {
            Ok(s) => s,
            Err(_) => {
                let x: f64 = step_tok.parse().map_err(|_| bad("unparsable step"))?;
                if !(x >= 0.0 && x.fract() == 0.0) {
                    return Err(bad("non-integer step"));
                }
                x as u64
            }
        };
        let mut v = [0.0f64; 5];
        for (k, name) in ["t", "z_bottom", "fx", "fy", "fz"].iter().enumerate() {
            let tok = it
                .next()
                .ok_or_else(|| bad(&format!("missing column {name}")))?;
            v[k] = tok
                .parse()
                .map_err(|_| bad(&format!("unparsable {name} {tok:?}")))?;
            if !v[k].is_finite() {
                return Err(bad(&format!("non-finite {name}")));
            }
        }
        if it.next().is_some() {
            return Err(bad("extra columns"));
        }
        visit(&ForceSample {
            step,
            t: v[0],
            z_bottom: v[1] / l,
            f: [v[2] / fo, v[3] / fo, v[4] / fo],
        })?;
    }
    Ok(())
}

/// Whether coreutils' `stdbuf` runs here (checked once).
fn have_stdbuf() -> bool {
    static HAVE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *HAVE.get_or_init(|| process::succeeds(&["stdbuf".into(), "--version".into()]))
}

/// `liggghts -in in.penetration -log log.liggghts`, under `mpirun` when `mpi_procs > 1`,
/// and behind `stdbuf -oL` when available: LIGGGHTS' per-rank errors (`error->one`, e.g.
/// "Cannot open mesh file") end in `MPI_Abort`, which discards a fully buffered stdout and
/// log, so without line buffering the `ERROR` line is lost (measured on 3.8.0).
pub fn argv(mpi_procs: usize) -> Vec<String> {
    let mut argv = process::mpi_prefix(mpi_procs);
    if have_stdbuf() {
        argv.extend(["stdbuf", "-oL"].map(String::from));
    }
    argv.push(super::binary());
    argv.extend(["-in", DECK_FILE, "-log", LOG_FILE].map(String::from));
    argv
}

/// Writes the deck directory ([`write_deck_dir`]) and runs it ([`run_existing`]).
pub fn run(
    d: &PenetrationDeck,
    dir: &Path,
    mpi_procs: usize,
    limits: &process::Limits,
) -> Result<(Vec<ForceSample>, Provenance)> {
    run_with_snapshots(d, dir, mpi_procs, limits, &[])
}

/// [`run`] with contact snapshots at `snapshot_steps`, left in `dir` for
/// [`super::snapshot::read_snapshot`] (stale snapshot files are removed first).
pub fn run_with_snapshots(
    d: &PenetrationDeck,
    dir: &Path,
    mpi_procs: usize,
    limits: &process::Limits,
    snapshot_steps: &[u64],
) -> Result<(Vec<ForceSample>, Provenance)> {
    if dir.exists() {
        for e in std::fs::read_dir(dir)? {
            let name = e?.file_name().to_string_lossy().to_string();
            if super::snapshot::is_dump_name(&name) {
                std::fs::remove_file(dir.join(&name))
                    .with_context(|| format!("cannot remove stale {name}"))?;
            }
        }
    }
    let files = write_deck_dir_with_snapshots(d, dir, snapshot_steps)?;
    let (samples, mut prov) = run_existing(d, dir, mpi_procs, limits)?;
    prov.notes
        .insert(2, format!("intruder STL: {} segments", files.stl_segments));
    if !snapshot_steps.is_empty() {
        let (before, after) = super::snapshot::compress_dumps(dir)?;
        prov.notes.push(format!(
            "contact dumps kept zstd-compressed: {:.1} MB -> {:.1} MB",
            before as f64 / 1e6,
            after as f64 / 1e6
        ));
    }
    Ok((samples, prov))
}

/// [`write_deck_dir`], then LIGGGHTS on it; `progress(step)` follows the thermo lines of
/// its log while it runs and `visit` receives every force sample (SI) afterwards.
pub(crate) fn run_streaming(
    d: &PenetrationDeck,
    dir: &Path,
    mpi_procs: usize,
    limits: &process::Limits,
    progress: impl FnMut(u64),
    visit: impl FnMut(&ForceSample) -> Result<()>,
) -> Result<Provenance> {
    let files = write_deck_dir(d, dir)?;
    let mut prov = execute(d, dir, mpi_procs, limits, progress, visit)?;
    prov.notes
        .insert(2, format!("intruder STL: {} segments", files.stl_segments));
    Ok(prov)
}

/// Runs LIGGGHTS on the deck directory `dir` as it is on disk (written by
/// [`write_deck_dir`] for `d`, possibly edited by hand), ended at its `limits`; the
/// samples are collected in memory (see [`execute`] for the streaming form).
pub fn run_existing(
    d: &PenetrationDeck,
    dir: &Path,
    mpi_procs: usize,
    limits: &process::Limits,
) -> Result<(Vec<ForceSample>, Provenance)> {
    let mut out = Vec::new();
    let prov = execute(
        d,
        dir,
        mpi_procs,
        limits,
        |_| {},
        |s| {
            out.push(*s);
            Ok(())
        },
    )?;
    Ok((out, prov))
}

/// sha256 of what LIGGGHTS is given for `d` without snapshot dumps (deck, data file,
/// STL): the fingerprint of a penetration bed's reference run. Equal to the
/// `input_hash` of [`write_deck_dir`].
pub(crate) fn input_hash_of(d: &PenetrationDeck) -> Result<Sha256> {
    let files = input_files(d)?;
    Ok(deck_text::fingerprint(
        &files.iter().map(|(_, t)| t.as_str()).collect::<Vec<_>>(),
    ))
}

/// The input files of `d` without snapshot dumps (name, text), in fingerprint order:
/// deck, grains (`data.bed`, `bodies.bed` or `data.lattice`), intruder mesh.
pub(crate) fn input_files(d: &PenetrationDeck) -> Result<Vec<(&'static str, String)>> {
    Ok(vec![
        (DECK_FILE, deck_text(d)?),
        (data_file_name(d), data_text(d)?),
        (STL_FILE, stl_text(d).0),
    ])
}

/// The intruder mesh of `d` at its start position, and its number of rim segments.
fn stl_text(d: &PenetrationDeck) -> (String, usize) {
    let l = d.units.length();
    let z_stl = if d.settle.is_some() {
        0.0
    } else {
        d.intruder_bottom_z0 * l
    };
    super::stl::flat_cylinder_stl(
        d.intruder_radius * l,
        d.intruder_length * l,
        [0.0, 0.0, z_stl],
        d.rim_error_frac,
    )
}

fn input_hash(dir: &Path) -> Sha256 {
    // A missing input is left for LIGGGHTS to report (its error is the useful one).
    let texts: Vec<String> = [
        DECK_FILE,
        DATA_FILE,
        LATTICE_FILE,
        super::clump_bed::BODIES_FILE,
        STL_FILE,
    ]
    .iter()
    .filter_map(|name| {
        let p = dir.join(name);
        crate::rundata::fsio::read_to_string(
            &p,
            crate::rundata::fsio::max_engine_output(),
            "a LIGGGHTS input",
        )
        .ok()
    })
    .collect();
    deck_text::fingerprint(&texts.iter().map(String::as_str).collect::<Vec<_>>())
}

/// Follows LIGGGHTS' log while it grows: the step of the newest thermo line.
struct LogFollower {
    path: PathBuf,
    offset: u64,
    partial: String,
}

impl LogFollower {
    fn poll(&mut self) -> Option<u64> {
        use std::io::{Read, Seek, SeekFrom};
        let mut f = std::fs::File::open(&self.path).ok()?;
        let len = f.metadata().ok()?.len();
        if len <= self.offset {
            return None;
        }
        f.seek(SeekFrom::Start(self.offset)).ok()?;
        let mut buf = Vec::new();
        f.take(len - self.offset).read_to_end(&mut buf).ok()?;
        self.offset = len;
        self.partial.push_str(&String::from_utf8_lossy(&buf));
        let mut last = None;
        let complete = self.partial.rfind('\n').map(|i| i + 1).unwrap_or(0);
        for line in self.partial[..complete].lines() {
            let mut it = line.split_whitespace();
            // Thermo lines are `step atoms ke cpu` (thermo_style custom step atoms ke cpu).
            if let (Some(a), Some(b), Some(_), Some(_), None) =
                (it.next(), it.next(), it.next(), it.next(), it.next())
                && let (Ok(step), Ok(_)) = (a.parse::<u64>(), b.parse::<u64>())
            {
                last = Some(step);
            }
        }
        self.partial.drain(..complete);
        last
    }
}

/// Runs LIGGGHTS in `dir` and hands the checked outputs to [`read_outputs`]. Refuses
/// failed runs (non-zero exit, any `ERROR` line, a limit reached, missing/short force file) with
/// the log tail.
pub(crate) fn execute(
    d: &PenetrationDeck,
    dir: &Path,
    mpi_procs: usize,
    limits: &process::Limits,
    mut progress: impl FnMut(u64),
    visit: impl FnMut(&ForceSample) -> Result<()>,
) -> Result<Provenance> {
    process::remove_stale(dir, &[FORCE_FILE, LOG_FILE, STDOUT_FILE, STDERR_FILE])?;
    let argv = argv(mpi_procs);
    let command = process::command_line(&argv);
    let mut follower = LogFollower {
        path: dir.join(LOG_FILE),
        offset: 0,
        partial: String::new(),
    };
    let fin = process::run_with(
        &argv,
        dir,
        &dir.join(STDOUT_FILE),
        &dir.join(STDERR_FILE),
        limits,
        || {
            if let Some(step) = follower.poll() {
                progress(step)
            }
        },
    )
    .context("LIGGGHTS penetration run failed to start")?;
    let what = "LIGGGHTS penetration run";
    let tr = Transcript::read(TRANSCRIPT, dir);
    tr.check_exit(&fin, limits, what, &command, dir)?;
    let fail = |reason: String| tr.failure(what, &command, dir, &reason);
    let mut prov = read_outputs(d, dir, visit).map_err(|e| fail(format!("{e:#}")))?;
    prov.command = command;
    prov.wall_time_s = fin.wall_time_s;
    prov.threads = mpi_procs.max(1);
    Ok(prov)
}

/// LIGGGHTS' own "Total wall time: h:mm:ss" (for runs made outside granval).
/// LIGGGHTS prints "Total wall time" to stdout at exit, after the log file is closed;
/// a log alone (a run brought back from a cluster) yields the sum of its "Loop time"s,
/// which leaves out only setup.
pub(crate) fn log_wall_time(log: &str) -> Option<f64> {
    let Some(l) = log
        .lines()
        .rev()
        .find(|l| l.starts_with("Total wall time:"))
    else {
        let loops: Vec<f64> = log
            .lines()
            .filter_map(|l| {
                l.strip_prefix("Loop time of ")?
                    .split_whitespace()
                    .next()?
                    .parse()
                    .ok()
            })
            .collect();
        return (!loops.is_empty()).then(|| loops.iter().sum());
    };
    let t = l.trim_start_matches("Total wall time:").trim();
    let parts: Vec<f64> = t
        .split(':')
        .map(|x| x.parse().ok())
        .collect::<Option<_>>()?;
    Some(parts.iter().fold(0.0, |acc, v| acc * 60.0 + v))
}

/// Checks the outputs of a finished run of `d` in `dir` — made by granval or by hand
/// (e.g. on a cluster) — and streams its force samples (SI) to `visit`: no `ERROR` in
/// the log or stdout, every expected sample present at the expected step. The returned
/// provenance's command and wall time are those the log tells (`execute` overwrites them
/// with what it measured).
pub(crate) fn read_outputs(
    d: &PenetrationDeck,
    dir: &Path,
    mut visit: impl FnMut(&ForceSample) -> Result<()>,
) -> Result<Provenance> {
    let tr = Transcript::read(TRANSCRIPT, dir);
    let (log, stdout, errors) = (&tr.log, &tr.stdout, &tr.errors);
    if log.is_empty() && stdout.is_empty() {
        bail!(
            "{}: neither {LOG_FILE} nor {STDOUT_FILE} exists or has content: LIGGGHTS did not run here (run `liggghts -in {DECK_FILE}` in it first)",
            dir.display()
        );
    }
    if !errors.is_empty() {
        bail!("ERROR in the LIGGGHTS output: {}", errors.join(" | "));
    }
    check_log_echoes_deck(dir, log)?;
    let force_path = dir.join(FORCE_FILE);
    if !force_path.exists() {
        bail!("no {} was written", force_path.display());
    }
    check_force_title(d, &force_path)?;
    let mut n = 0usize;
    let mut track = IntruderTrack::new(d);
    for_each_force_sample(&force_path, d.units, |s| {
        let step = (n as u64 + 1) * d.force_every;
        if s.step != step {
            bail!(
                "sample {n} of {} is step {}, expected {step}",
                force_path.display(),
                s.step
            );
        }
        track
            .check(s)
            .map_err(|e| anyhow::anyhow!("{}: {e}", force_path.display()))?;
        n += 1;
        visit(s)
    })?;
    let expected = expected_samples(d);
    if n != expected {
        bail!(
            "{} has {n} samples, expected {expected} (n_steps {} / force_every {}): the run is incomplete",
            force_path.display(),
            d.n_steps,
            d.force_every
        );
    }
    let version = tr.version(VERSION_PREFIX);
    let mut notes = vec![
        format!("run directory: {}", dir.display()),
        format!(
            "deck units: {}; force samples converted to SI",
            d.units.keyword()
        ),
    ];
    if d.soft_particles {
        notes.push(
            "soft_particles yes (LIGGGHTS' E >= 5e6 Pa check disabled; materials unchanged)"
                .to_string(),
        );
    }
    if d.hard_particles {
        notes.push(
            "hard_particles yes (LIGGGHTS' E <= 1e9 Pa check disabled; materials unchanged)"
                .to_string(),
        );
    }
    notes.extend(tr.warnings());
    let procs = log
        .lines()
        .find_map(|l| {
            l.trim()
                .strip_prefix("Loop time of")
                .and_then(|r| r.split(" on ").nth(1))
                .and_then(|r| r.split_whitespace().next())
                .and_then(|p| p.parse::<usize>().ok())
        })
        .unwrap_or(1);
    Ok(Provenance {
        engine: EngineKind::Liggghts,
        version,
        command: format!("run outside granval (log says {procs} procs)"),
        input_hash: input_hash(dir),
        date: now_utc(),
        wall_time_s: if stdout.contains("Total wall time:") {
            log_wall_time(stdout)
        } else {
            log_wall_time(log)
        }
        .unwrap_or(f64::NAN),
        threads: procs,
        case_file: dir.join(DECK_FILE).display().to_string(),
        notes,
    })
}

/// The title line `fix print` writes at the top of [`FORCE_FILE`] for `d`.
fn force_title(d: &PenetrationDeck) -> String {
    format!(
        "# step t z_bottom fx fy fz (units {}; f = force of the grains on the intruder)",
        d.units.names()
    )
}

/// The force file of a run of `d` starts with the title `d`'s deck gives it: a force
/// file of another deck (other units) is refused, not reduced.
fn check_force_title(d: &PenetrationDeck, path: &Path) -> Result<()> {
    use std::io::Read as _;
    let file =
        std::fs::File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let mut first = String::new();
    std::io::BufReader::new(file)
        .take(4096)
        .read_line(&mut first)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let want = force_title(d);
    if first.trim_end() != want {
        bail!(
            "{}: starts with {:?}, not the title its deck writes ({want:?}): not this run's force file",
            path.display(),
            first.trim_end()
        );
    }
    Ok(())
}

/// The intruder's bottom height in a force file must follow the deck's motion: from
/// `z0` (where the deck's mesh starts) down at the deck's speed, step by step. A force
/// file of another bed (another surface, so another `z0`), speed or time step is
/// refused. A deck that settles its own bed places the intruder itself: only the motion
/// from its first sample on is checked. LIGGGHTS moves the mesh by `v dt` per step; the
/// rounding this accumulates stays below 2e-11 of `z0` over the recorded runs (4e5
/// steps), so 1e-7 leaves room for 1e10 steps while a bed's surface moves `z0` by
/// millimetres.
struct IntruderTrack {
    z0: Option<f64>,
    speed: f64,
    dt: f64,
    tol: f64,
    first: Option<(u64, f64)>,
}

impl IntruderTrack {
    fn new(d: &PenetrationDeck) -> IntruderTrack {
        IntruderTrack {
            z0: d.settle.is_none().then_some(d.intruder_bottom_z0),
            speed: d.speed,
            dt: d.dt,
            tol: 1e-7 * d.intruder_bottom_z0.abs().max(d.intruder_length),
            first: None,
        }
    }

    fn check(&mut self, s: &ForceSample) -> Result<()> {
        let (from_step, from_z) = match (self.z0, self.first) {
            (Some(z0), _) => (0, z0),
            (None, Some(f)) => f,
            (None, None) => {
                self.first = Some((s.step, s.z_bottom));
                return Ok(());
            }
        };
        let want = from_z - self.speed * self.dt * (s.step - from_step) as f64;
        if (s.z_bottom - want).abs() > self.tol {
            bail!(
                "step {}: the intruder's bottom is at z = {:e} m, but this deck moves it to {want:e} m (from z = {from_z:e} m at step {from_step}, {:e} m/s): the force file is of another bed, case or run",
                s.step,
                s.z_bottom,
                self.speed
            );
        }
        Ok(())
    }
}

/// The log of a run echoes its input (LIGGGHTS' default `echo log`): every command of
/// the deck in `dir`, in order, and the deck's title comment (which names the case and
/// the bed's seed). A log of another deck, another bed or another case is refused. A
/// deck with jumps (the settling loop) runs some lines never and others repeatedly, so
/// only its title is checked.
fn check_log_echoes_deck(dir: &Path, log: &str) -> Result<()> {
    let deck_path = dir.join(DECK_FILE);
    let deck = std::fs::read_to_string(&deck_path)
        .with_context(|| format!("cannot read {}", deck_path.display()))?;
    let log_path = dir.join(LOG_FILE);
    let lines: Vec<String> = log
        .lines()
        .map(|l| l.split_whitespace().collect::<Vec<_>>().join(" "))
        .collect();
    let title: Vec<String> = deck
        .lines()
        .take_while(|l| l.starts_with('#') && !l.starts_with("# written by granval"))
        .map(|l| l.split_whitespace().collect::<Vec<_>>().join(" "))
        .collect();
    if let Some(t) = title.iter().find(|t| !lines.contains(t)) {
        bail!(
            "{}: does not echo the title of {} ({t:?}): the log is of another deck (another case or bed), or LIGGGHTS ran with `-echo none` (run it as the README says)",
            log_path.display(),
            deck_path.display()
        );
    }
    let canonical = deck_text::canonical(&deck);
    if canonical.lines().any(|c| {
        let w = c.split_whitespace().next().unwrap_or("");
        w == "jump" || w == "label"
    }) {
        return Ok(());
    }
    let mut at = 0usize;
    for (k, cmd) in canonical.lines().enumerate() {
        match lines[at..].iter().position(|l| l == cmd) {
            Some(i) => at += i + 1,
            None => bail!(
                "{}: command {} of {} (`{cmd}`) is not echoed in order: the log is of another deck",
                log_path.display(),
                k + 1,
                deck_path.display()
            ),
        }
    }
    Ok(())
}

/// Reads a bed back from a `read_data` file written by [`data_text`] (SI out), so
/// `granval analyze` knows the exact grains a deck directory started from. Errors name
/// the file, line and what is wrong; every atom needs a `Velocities` line.
pub(crate) fn parse_data_file(path: &Path, units: Units) -> Result<Vec<Particle>> {
    let file = crate::rundata::fsio::open_engine_output(path, "a LIGGGHTS data file")?;
    let (l, v, rho) = (units.length(), units.velocity(), units.density());
    let mut particles: Vec<Particle> = Vec::new();
    let mut index = std::collections::HashMap::new();
    let mut section = "";
    let mut declared = None;
    let mut with_velocity = 0usize;
    for (k, line) in std::io::BufReader::new(file).lines().enumerate() {
        let lineno = k + 1;
        let line = line.with_context(|| format!("{}:{lineno}: read error", path.display()))?;
        let t = line.split('#').next().unwrap_or("").trim();
        if k == 0 || t.is_empty() {
            continue;
        }
        let bad = |what: &str| anyhow::anyhow!("{}:{lineno}: {what}: {t:?}", path.display());
        match t {
            "Atoms" | "Velocities" => {
                section = if t == "Atoms" { "atoms" } else { "velocities" };
                continue;
            }
            _ => {}
        }
        let tok: Vec<&str> = t.split_whitespace().collect();
        let num = |i: usize, name: &str| -> Result<f64> {
            let x: f64 = tok
                .get(i)
                .ok_or_else(|| bad(&format!("missing {name}")))?
                .parse()
                .map_err(|_| bad(&format!("unparsable {name}")))?;
            if x.is_finite() {
                Ok(x)
            } else {
                Err(bad(&format!("non-finite {name}")))
            }
        };
        match section {
            "" => {
                if tok.len() == 2 && tok[1] == "atoms" {
                    declared = Some(tok[0].parse::<usize>().map_err(|_| bad("atom count"))?);
                }
            }
            "atoms" => {
                if tok.len() != 7 {
                    bail!(bad("expected `atom-ID type diameter density x y z`"));
                }
                let id: u64 = tok[0].parse().map_err(|_| bad("unparsable atom-ID"))?;
                let ty: usize = tok[1].parse().map_err(|_| bad("unparsable type"))?;
                if ty == 0 {
                    bail!(bad("atom type 0"));
                }
                if index.insert(id, particles.len()).is_some() {
                    bail!(bad("duplicate atom-ID"));
                }
                particles.push(Particle {
                    id,
                    type_: ty - 1,
                    radius: 0.5 * num(2, "diameter")? / l,
                    density: num(3, "density")? / rho,
                    x: [num(4, "x")? / l, num(5, "y")? / l, num(6, "z")? / l],
                    v: [0.0; 3],
                    omega: [0.0; 3],
                });
            }
            _ => {
                if tok.len() != 7 {
                    bail!(bad("expected `atom-ID vx vy vz wx wy wz`"));
                }
                let id: u64 = tok[0].parse().map_err(|_| bad("unparsable atom-ID"))?;
                let &i = index
                    .get(&id)
                    .ok_or_else(|| bad("velocity of an atom not in `Atoms`"))?;
                let p = &mut particles[i];
                p.v = [num(1, "vx")? / v, num(2, "vy")? / v, num(3, "vz")? / v];
                p.omega = [num(4, "wx")?, num(5, "wy")?, num(6, "wz")?];
                with_velocity += 1;
            }
        }
    }
    match declared {
        Some(n) if n == particles.len() && n == with_velocity => Ok(particles),
        Some(n) => bail!(
            "{}: header declares {n} atoms, found {} in `Atoms` and {with_velocity} in `Velocities`",
            path.display(),
            particles.len()
        ),
        None => bail!("{}: no `N atoms` header line", path.display()),
    }
}

/// Reads the settled bed a [`Settle`] deck wrote (`write_dump ... id type radius x y z vx
/// vy vz`), SI out; angular velocities are not needed by the analysis and set to zero.
pub fn parse_bed_dump(path: &Path, units: Units, density: f64) -> Result<Vec<Particle>> {
    let file = crate::rundata::fsio::open_engine_output(path, "a settled-bed dump").with_context(
        || {
            format!(
                "the settled bed {}: did the deck reach `label settled`?",
                path.display()
            )
        },
    )?;
    let (l, v) = (units.length(), units.velocity());
    let mut out = Vec::new();
    let mut in_atoms = false;
    let mut expected = None;
    let mut after_number = false;
    for (k, line) in std::io::BufReader::new(file).lines().enumerate() {
        let lineno = k + 1;
        let line = line.with_context(|| format!("{}:{lineno}: read error", path.display()))?;
        let t = line.trim();
        if after_number {
            expected =
                Some(t.parse::<usize>().with_context(|| {
                    format!("{}:{lineno}: bad atom count {t:?}", path.display())
                })?);
            after_number = false;
            continue;
        }
        if t.starts_with("ITEM: NUMBER OF ATOMS") {
            after_number = true;
            continue;
        }
        if let Some(cols) = t.strip_prefix("ITEM: ATOMS") {
            if cols.split_whitespace().collect::<Vec<_>>()
                != ["id", "type", "radius", "x", "y", "z", "vx", "vy", "vz"]
            {
                bail!("{}:{lineno}: unexpected columns {cols:?}", path.display());
            }
            in_atoms = true;
            continue;
        }
        if t.starts_with("ITEM:") {
            in_atoms = false;
            continue;
        }
        if !in_atoms || t.is_empty() {
            continue;
        }
        let tok: Vec<&str> = t.split_whitespace().collect();
        let bad = |w: &str| anyhow::anyhow!("{}:{lineno}: {w}: {t:?}", path.display());
        if tok.len() != 9 {
            bail!(bad("expected 9 columns"));
        }
        let x: Vec<f64> = tok[2..]
            .iter()
            .map(|s| s.parse::<f64>().ok().filter(|x| x.is_finite()))
            .collect::<Option<_>>()
            .ok_or_else(|| bad("unparsable number"))?;
        let ty: usize = tok[1].parse().map_err(|_| bad("unparsable type"))?;
        out.push(Particle {
            id: tok[0].parse().map_err(|_| bad("unparsable id"))?,
            type_: ty.checked_sub(1).ok_or_else(|| bad("type 0"))?,
            radius: x[0] / l,
            density,
            x: [x[1] / l, x[2] / l, x[3] / l],
            v: [x[4] / v, x[5] / v, x[6] / v],
            omega: [0.0; 3],
        });
    }
    match expected {
        Some(n) if n == out.len() => {
            out.sort_by_key(|p| p.id);
            Ok(out)
        }
        Some(n) => bail!(
            "{}: header says {n} atoms, read {}",
            path.display(),
            out.len()
        ),
        None => bail!("{}: no `ITEM: NUMBER OF ATOMS`", path.display()),
    }
}

#[cfg(test)]
mod tests {
    use super::log_wall_time;

    #[test]
    fn wall_time_from_total_or_from_loop_times() {
        let total = "Loop time of 12.5 on 2 procs for 100 steps\nTotal wall time: 0:01:31\n";
        assert_eq!(log_wall_time(total), Some(91.0));
        let loops = "Loop time of 12.5 on 2 procs for 100 steps with 5 atoms\n\
                     text\nLoop time of 70.25 on 2 procs for 3500 steps with 5 atoms\n";
        assert_eq!(log_wall_time(loops), Some(82.75));
        assert_eq!(log_wall_time("no timing here\n"), None);
    }
}
