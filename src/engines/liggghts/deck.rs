//! The LIGGGHTS 3.8 input deck and `read_data` file for a [`Case`]. Pure text
//! generation: nothing here runs LIGGGHTS, so `granval deck` and tests can use it.
//!
//! Every float is written with [`deck_text::num`] (shortest round-trip representation,
//! plain notation), so LIGGGHTS parses back exactly the f64 the case holds: the deck
//! carries no rounding. Every block is commented with what it does and its source.

use crate::case::{Case, Material, PairTable, Particle, RollingModel, Wall};
use crate::engines::deck_text;
use anyhow::{Result, bail};
use std::fmt::Write;

/// LIGGGHTS refuses `youngsModulus` below this in SI units (`global_properties.cpp`,
/// "youngsModulus >= 5e6 required for SI units"), unless `soft_particles yes`.
pub(crate) const MIN_YOUNGS_MODULUS_SI: f64 = 5e6;
/// ... and above this ("youngsModulus <= 1e9 required for SI units (use command
/// 'hard_particles yes' to override)").
pub(crate) const MAX_YOUNGS_MODULUS_SI: f64 = 1e9;
/// LIGGGHTS requires `0.05 < coefficientRestitution <= 1`.
pub(crate) const MIN_RESTITUTION_EXCLUSIVE: f64 = 0.05;

/// Dump columns, in the order the deck asks for them (the parser maps by name anyway).
pub(crate) const DUMP_COLUMNS: [&str; 13] = [
    "id", "x", "y", "z", "vx", "vy", "vz", "omegax", "omegay", "omegaz", "fx", "fy", "fz",
];

/// Above this largest atom ID an `atom_modify map array` would allocate a huge lookup
/// table, so the deck switches to `map hash` (same physics, slower lookups).
const MAP_ARRAY_MAX_ID: u64 = 10_000_000;

/// Full-precision (shortest round-trip) number for a deck or data file, in plain
/// notation where that is readable ([`deck_text::num`]).
pub(super) fn f(x: f64) -> String {
    deck_text::num(x)
}

pub(super) fn join(xs: impl IntoIterator<Item = f64>) -> String {
    deck_text::nums(xs)
}

/// `model hertz tangential history [rolling_friction K]`: pair_style and every
/// `fix wall/gran` must name the same models.
pub(super) fn model_keywords(rolling: RollingModel) -> String {
    let r = rolling
        .liggghts_keyword()
        .map(|k| format!(" rolling_friction {k}"))
        .unwrap_or_default();
    format!("model hertz tangential history{r}")
}

/// The order LIGGGHTS reads a `peratomtypepair` table in: `1-1 1-2 ... n-n`, row by row.
fn pair_order(n: usize) -> String {
    let mut v = Vec::new();
    for a in 1..=n {
        for b in 1..=n {
            v.push(format!("{a}-{b}"));
        }
    }
    v.join(" ")
}

/// What the contact law of `pair_style gran` computes, with its sources.
pub(super) fn contact_law_text(rolling: RollingModel) -> String {
    let rolling_text = match rolling {
        RollingModel::None => "no rolling resistance".to_string(),
        RollingModel::Cdt => {
            "rolling resistance `rolling_friction cdt`: a constant directional torque \
             mu_r k_n delta_n R* opposing the relative rotation, without torsion (Feng et al. eq 4)"
                .to_string()
        }
        RollingModel::Epsd2 => {
            "rolling resistance `rolling_friction epsd2`: an elastic-plastic spring \
             of stiffness k_t R*^2 on the relative rotation, its torque capped at mu_r |F_n| R*"
                .to_string()
        }
    };
    format!(
        "Contact law of every grain-grain and grain-wall contact (LIGGGHTS 3.8 `pair_style gran`; \
         Feng et al. eqs 2-4 and Table 1, as granval's native engine computes it): Hertz normal \
         force with damping, `model hertz` (eq 2: k_n = 4/3 E* sqrt(R* delta_n), damping \
         2 sqrt(5/6) beta sqrt(S_n m*) with beta = ln e / sqrt(ln^2 e + pi^2) from the \
         restitution e); Mindlin tangential spring 8 G* sqrt(R* delta_n) with shear history, \
         capped at Coulomb friction mu |F_n| and damped only while sticking, `tangential \
         history` (eq 3); {rolling_text}. E*, G*, R*, m*: the effective Young's and shear \
         moduli, radius and mass of the pair."
    )
}

/// Material property/global fixes, pair style and pair_coeff, shared by every granval
/// deck, each block commented. `pressure` converts Pa into the deck's units (1 for SI),
/// `pressure_unit` names that unit.
pub(super) fn write_contact_model(
    s: &mut String,
    materials: &[Material],
    pairs: &PairTable,
    rolling: RollingModel,
    pressure: f64,
    pressure_unit: &str,
) -> std::fmt::Result {
    let n = materials.len();
    deck_text::block(
        s,
        &format!(
            "---- Materials (the case's [[materials]] and [[interactions]]) ----\n\
             Young's modulus E ({pressure_unit}) and Poisson's ratio nu of atom types 1..{n}, then per \
             type pair ({}) the coefficient of restitution e, the sliding friction mu{}. \
             Written exactly as the case file gives them; never rescaled.",
            pair_order(n),
            if rolling.liggghts_keyword().is_some() {
                " and the rolling friction mu_r"
            } else {
                ""
            }
        ),
    );
    writeln!(
        s,
        "fix m1 all property/global youngsModulus peratomtype {}",
        join(materials.iter().map(|m| m.youngs_modulus * pressure))
    )?;
    writeln!(
        s,
        "fix m2 all property/global poissonsRatio peratomtype {}",
        join(materials.iter().map(|m| m.poisson_ratio))
    )?;
    writeln!(
        s,
        "fix m3 all property/global coefficientRestitution peratomtypepair {n} {}",
        join(pairs.restitution.iter().copied())
    )?;
    writeln!(
        s,
        "fix m4 all property/global coefficientFriction peratomtypepair {n} {}",
        join(pairs.friction.iter().copied())
    )?;
    if rolling.liggghts_keyword().is_some() {
        writeln!(
            s,
            "fix m5 all property/global coefficientRollingFriction peratomtypepair {n} {}",
            join(pairs.rolling_friction.iter().copied())
        )?;
    }
    deck_text::block(s, &contact_law_text(rolling));
    writeln!(s, "pair_style gran {}", model_keywords(rolling))?;
    writeln!(s, "pair_coeff * *")
}

/// Whether the materials need LIGGGHTS' `soft_particles yes` / `hard_particles yes`.
/// Both switches only lift LIGGGHTS' range check of Young's modulus (5e6-1e9 Pa in SI,
/// 5e7-1e10 barye in cgs: the same pressures); the material is written unchanged, so
/// glass, steel and alumina run as they are.
pub(crate) fn hardness(materials: &[Material]) -> (bool, bool) {
    let soft = materials
        .iter()
        .any(|m| m.youngs_modulus < MIN_YOUNGS_MODULUS_SI);
    let hard = materials
        .iter()
        .any(|m| m.youngs_modulus > MAX_YOUNGS_MODULUS_SI);
    (soft, hard)
}

/// The switch lines of [`hardness`], each with the comment that says why: which types'
/// Young's modulus lies outside LIGGGHTS' accepted range. `pressure`/`unit`: the deck's
/// pressure unit (1, "Pa" in SI).
pub(super) fn write_hardness(
    s: &mut String,
    materials: &[Material],
    soft: bool,
    hard: bool,
) -> std::fmt::Result {
    let which = |pick: &dyn Fn(f64) -> bool| {
        let v: Vec<String> = materials
            .iter()
            .enumerate()
            .filter(|(_, m)| pick(m.youngs_modulus))
            .map(|(t, m)| format!("type {} has E = {} Pa", t + 1, f(m.youngs_modulus)))
            .collect();
        if v.is_empty() {
            "set on request (no type needs it)".to_string()
        } else {
            v.join(", ")
        }
    };
    if soft {
        deck_text::block(
            s,
            &format!(
                "soft_particles yes: {}, below the 5e6 Pa LIGGGHTS 3.8 accepts by default (in SI \
                 and cgs alike). The switch only disables that range check: the material is \
                 written unchanged, and so is the contact law.",
                which(&|e| e < MIN_YOUNGS_MODULUS_SI)
            ),
        );
        writeln!(s, "soft_particles yes")?;
    }
    if hard {
        deck_text::block(
            s,
            &format!(
                "hard_particles yes: {}, above the 1e9 Pa LIGGGHTS 3.8 accepts by default. The \
                 switch only disables that range check: the material is written unchanged, and \
                 so is the contact law.",
                which(&|e| e > MAX_YOUNGS_MODULUS_SI)
            ),
        );
        writeln!(s, "hard_particles yes")?;
    }
    Ok(())
}

/// Provenance lines for the switches a deck of these materials sets.
pub fn hardness_note(materials: &[Material]) -> Vec<String> {
    let (soft, hard) = hardness(materials);
    let mut v = Vec::new();
    if soft {
        v.push(
            "soft_particles yes (LIGGGHTS' E >= 5e6 Pa check disabled; materials unchanged)".into(),
        );
    }
    if hard {
        v.push(
            "hard_particles yes (LIGGGHTS' E <= 1e9 Pa check disabled; materials unchanged)".into(),
        );
    }
    v
}

/// The `read_data` file of a granular atom set: box, atom types, `Atoms` (sphere style
/// `atom-ID atom-type diameter density x y z`, types 1-based) and `Velocities`
/// (`atom-ID vx vy vz omegax omegay omegaz`). `l`, `v`, `rho` convert SI lengths,
/// velocities and densities into the deck's units (1 for SI); rad/s is the same in
/// both. The one data-file writer of every LIGGGHTS deck granval writes.
#[allow(clippy::too_many_arguments)]
pub(super) fn data_text(
    title: &str,
    particles: &[Particle],
    n_types: usize,
    lo: [f64; 3],
    hi: [f64; 3],
    l: f64,
    v: f64,
    rho: f64,
) -> String {
    let mut s = String::new();
    // The first line of a data file is always skipped by read_data.
    let _ = writeln!(
        s,
        "LIGGGHTS data file written by granval: {}; Atoms: atom-ID type diameter density x y z, Velocities: atom-ID vx vy vz omegax omegay omegaz",
        comment_safe(title)
    );
    let _ = writeln!(s);
    let _ = writeln!(s, "{} atoms", particles.len());
    let _ = writeln!(s, "{n_types} atom types");
    let _ = writeln!(s);
    for (k, ax) in ["x", "y", "z"].iter().enumerate() {
        let _ = writeln!(s, "{} {} {ax}lo {ax}hi", f(lo[k] * l), f(hi[k] * l));
    }
    let _ = writeln!(s);
    let _ = writeln!(s, "Atoms");
    let _ = writeln!(s);
    for p in particles {
        // 2*r is exact in binary floating point; LIGGGHTS halves it back exactly.
        let _ = writeln!(
            s,
            "{} {} {} {} {}",
            p.id,
            p.type_ + 1,
            f(2.0 * p.radius * l),
            f(p.density * rho),
            join(p.x.map(|x| x * l))
        );
    }
    let _ = writeln!(s);
    let _ = writeln!(s, "Velocities");
    let _ = writeln!(s);
    for p in particles {
        let _ = writeln!(s, "{} {} {}", p.id, join(p.v.map(|x| x * v)), join(p.omega));
    }
    s
}

/// Keeps free text (case names) harmless inside a LIGGGHTS comment: no `$` variable
/// expansion, no `&` continuation, no line breaks.
pub(super) fn comment_safe(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_alphanumeric() || " _-.:,/()[]+=".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Largest atom ID LIGGGHTS 3.8 takes: its `tagint` is a signed 32-bit int (LAMMPS'
/// default `LAMMPS_SMALLBIG`, `MAXTAGINT` = 2^31 - 1); a larger ID in a data file aborts
/// the run with an empty log.
pub(crate) const MAX_ATOM_ID: u64 = i32::MAX as u64;

/// Refuses what LIGGGHTS 3.8 itself would refuse of a micro case, before anything runs,
/// naming the case file, the field and the value: its materials and pairs
/// ([`check_materials`]) and, where the case's particle IDs go into the data file (no
/// clumps: a clump deck numbers its atoms itself), IDs above [`MAX_ATOM_ID`].
pub(crate) fn check_liggghts_limits(case: &Case) -> Result<()> {
    check_materials(&case.source, &case.materials, &case.pairs)?;
    if case.clumps.is_empty()
        && let Some((k, p)) = case
            .particles
            .iter()
            .enumerate()
            .find(|(_, p)| p.id > MAX_ATOM_ID)
    {
        bail!(
            "{}: field `particles[{k}].id` = {}: LIGGGHTS 3.8 atom IDs are signed 32-bit integers (at most {MAX_ATOM_ID}); renumber the particles",
            case.source.display(),
            p.id
        );
    }
    Ok(())
}

/// Refuses material and pair values LIGGGHTS 3.8 refuses in every deck granval writes
/// (its `global_properties.cpp`: `0 <= poissonsRatio <= 0.5`, `0.05 <
/// coefficientRestitution <= 1`), naming the case file, field and value. The case
/// loader takes the physical ranges (-1 < nu <= 0.5, 0 < e <= 1), which the native
/// engine runs; a comparison needs what both engines take. Young's modulus is not
/// refused here: `soft_particles` / `hard_particles` lift LIGGGHTS' range check with the
/// material unchanged. Materials are never changed silently.
pub(crate) fn check_materials(
    file: &std::path::Path,
    materials: &[crate::case::Material],
    pairs: &crate::case::PairTable,
) -> Result<()> {
    let file = file.display();
    for (t, m) in materials.iter().enumerate() {
        let ty = t + 1;
        if !(m.youngs_modulus.is_finite() && m.youngs_modulus > 0.0) {
            bail!(
                "{file}: field `youngs_modulus` of material type {ty} = {:e} Pa cannot be written into a LIGGGHTS deck",
                m.youngs_modulus
            );
        }
        if !(0.0..=0.5).contains(&m.poisson_ratio) {
            bail!(
                "{file}: field `poisson_ratio` of material type {ty} = {:e}: LIGGGHTS 3.8 requires 0 <= poissonsRatio <= 0.5; \
                 granval does not change materials — run this case with the native engine only",
                m.poisson_ratio
            );
        }
    }
    let n = materials.len();
    for a in 0..n {
        for b in a..n {
            let e = pairs.restitution[pairs.idx(a, b)];
            if !(e > MIN_RESTITUTION_EXCLUSIVE && e <= 1.0) {
                bail!(
                    "{file}: field `restitution` of interaction types [{}, {}] = {e:e}: LIGGGHTS 3.8 requires \
                     0.05 < coefficientRestitution <= 1; granval does not change materials — run this case with the native engine only",
                    a + 1,
                    b + 1
                );
            }
        }
    }
    Ok(())
}

/// Number of dump frames a complete run writes: step 0 plus every `output_every` steps.
pub fn expected_frames(case: &Case) -> usize {
    (case.n_steps / case.output_every) as usize + 1
}

/// The `read_data` file: box, atom types, `Atoms` (granular = sphere style:
/// `atom-ID atom-type diameter density x y z`) and `Velocities`
/// (`atom-ID vx vy vz omegax omegay omegaz`). Types are written 1-based.
pub fn write_data_file(case: &Case) -> Result<String> {
    check_liggghts_limits(case)?;
    Ok(data_text(
        &format!("case {}", case.name),
        &case.particles,
        case.n_types(),
        case.domain_lo,
        case.domain_hi,
        1.0,
        1.0,
        1.0,
    ))
}

/// The input deck, commented block by block. `dump_file` and `data_file` are written
/// into the deck verbatim (relative names resolve against the directory LIGGGHTS runs
/// in). The header carries the date; [`crate::engines::deck_text::fingerprint`] ignores
/// it.
pub fn write_deck(case: &Case, dump_file: &str, data_file: &str) -> Result<String> {
    check_liggghts_limits(case)?;
    check_file_names(dump_file, data_file)?;
    let mut s = String::new();
    write_micro_header(&mut s, case, dump_file);
    write_box_and_atoms(&mut s, case, data_file)?;
    write_contact_model(
        &mut s,
        &case.materials,
        &case.pairs,
        case.rolling,
        1.0,
        "Pa",
    )?;
    write_time_step_and_gravity(&mut s, case)?;
    write_walls(&mut s, case)?;
    deck_text::comment(
        &mut s,
        "Velocity Verlet for spheres (`nve/sphere`: half kick, drift, forces, half kick; \
         moment of inertia 0.4 m r^2).",
    );
    writeln!(s, "fix integr all nve/sphere")?;
    write_output_and_run(&mut s, case, dump_file)?;
    Ok(s)
}

/// Refuses file names LIGGGHTS' input parser would split or expand (whitespace,
/// variables, comments, continuation, quotes): they go into the deck verbatim.
fn check_file_names(dump_file: &str, data_file: &str) -> Result<()> {
    for (what, name) in [("dump file", dump_file), ("data file", data_file)] {
        if name.is_empty()
            || name
                .chars()
                .any(|c| c.is_whitespace() || "$#&\"'".contains(c))
        {
            bail!(
                "{what} name {name:?} cannot be written into a LIGGGHTS deck (no whitespace, $, #, &, quotes)"
            );
        }
    }
    Ok(())
}

/// The header: the case, what the run measures and the tolerances granval compares it
/// with, the units and time step (Feng et al. Sec. 2), and how to run it.
fn write_micro_header(s: &mut String, case: &Case, dump_file: &str) {
    let duration = case.dt * case.n_steps as f64;
    let every_s = case.dt * case.output_every as f64;
    deck_text::write_header(
        s,
        &deck_text::Header {
            title: format!(
                "granval micro case `{}`: LIGGGHTS 3.8 input deck ({})",
                deck_text::safe(&case.name),
                super::DECK_FILE
            ),
            paragraphs: vec![
                deck_text::safe(&case.description),
                format!(
                    "What the run measures: the trajectory of every particle ({} particle(s), {} \
                     wall(s)), written to {dump_file} every {} steps ({} s): position, velocity, \
                     angular velocity and force. granval runs the same case in its native engine \
                     and compares the two frame by frame: position to {} r_min, velocity and \
                     angular velocity to {} of their largest reference value.",
                    case.particles.len(),
                    case.walls.len(),
                    case.output_every,
                    deck_text::approx(every_s),
                    f(case.tolerances.position_frac_radius),
                    f(case.tolerances.velocity_rel),
                ),
                format!(
                    "Units: SI throughout (m, kg, s, N, Pa; rad/s). {} steps of {} s = {} s; the \
                     time step is {} % of the Rayleigh time {} s of the most critical particle \
                     (Feng et al. Sec. 2).",
                    case.n_steps,
                    f(case.dt),
                    deck_text::approx(duration),
                    deck_text::approx(100.0 * case.dt / case.rayleigh_time),
                    deck_text::approx(case.rayleigh_time),
                ),
                format!(
                    "Run it in this directory: `liggghts -in {} -log log.liggghts`, or with N MPI \
                     processes `mpirun -np N liggghts -in {} -log log.liggghts`; then \
                     `granval analyze DIR --report OUT` (README.txt).",
                    super::DECK_FILE,
                    super::DECK_FILE
                ),
            ],
        },
    );
}

/// Units, atom style and map, the closed box, the parallel layout LIGGGHTS' granular
/// pair style needs, the Young's modulus switches, the particles of the data file and
/// the neighbour lists.
fn write_box_and_atoms(s: &mut String, case: &Case, data_file: &str) -> std::fmt::Result {
    let max_id = case.particles.iter().map(|p| p.id).max().unwrap_or(0);
    let map = if max_id > MAP_ARRAY_MAX_ID {
        "hash"
    } else {
        "array"
    };
    deck_text::block(
        s,
        "---- Box, atoms, parallel layout ----\n\
         SI units. `atom_style granular`: every atom is a sphere with a diameter, a density \
         (its mass follows) and an angular velocity. Atoms are looked up by ID in an array \
         (`map array`; a hash above 10 million IDs). `boundary f f f`: a closed box, the \
         case's [domain]; a particle that leaves it stops the run (thermo_modify below).",
    );
    writeln!(s, "units si")?;
    writeln!(s, "atom_style granular")?;
    writeln!(s, "atom_modify map {map}")?;
    writeln!(s, "boundary f f f")?;
    deck_text::comment(
        s,
        "`newton off`: LIGGGHTS' granular pair style with shear history requires it (a pair \
         split between two MPI processes is computed on both). `communicate single vel yes`: \
         ghost atoms carry velocities, which the damping and tangential forces need. \
         `processors * * *`: LIGGGHTS chooses the MPI grid (matters only under mpirun; the \
         results do not depend on it beyond round-off).",
    );
    writeln!(s, "newton off")?;
    writeln!(s, "communicate single vel yes")?;
    writeln!(s, "processors * * *")?;
    let (soft, hard) = hardness(&case.materials);
    write_hardness(s, &case.materials, soft, hard)?;
    deck_text::block(
        s,
        &format!(
            "The particles, exactly as the case's [[particles]] give them: {data_file} holds the \
             box (m), and per atom its ID, type, diameter (m), density (kg/m^3), position (m), \
             velocity (m/s) and angular velocity (rad/s)."
        ),
    );
    writeln!(s, "read_data {data_file}")?;
    deck_text::block(
        s,
        &format!(
            "Neighbour lists: skin {} m (the case's neighbor_skin; default half the smallest \
             radius), rebuilt whenever a particle has moved more than half the skin since the \
             last build. It changes the cost, not the physics.",
            f(case.neighbor_skin)
        ),
    );
    writeln!(s, "neighbor {} bin", f(case.neighbor_skin))?;
    writeln!(s, "neigh_modify delay 0")
}

/// The case's time step and gravity, exactly as the native engine integrates them.
fn write_time_step_and_gravity(s: &mut String, case: &Case) -> std::fmt::Result {
    deck_text::block(
        s,
        &format!(
            "---- Time integration ----\n\
             Time step {} s (the case's dt).",
            f(case.dt)
        ),
    );
    writeln!(s, "timestep {}", f(case.dt))?;
    let g = case.gravity;
    let gmag = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    if gmag > 0.0 {
        deck_text::comment(
            s,
            &format!(
                "Gravity: {} m/s^2 along ({}) (the case's simulation.gravity).",
                f(gmag),
                join(g)
            ),
        );
        writeln!(s, "fix gravi all gravity {} vector {}", f(gmag), join(g))?;
    }
    Ok(())
}

/// The case's [[walls]] as `wall/gran` primitives with the particles' contact law
/// ([`model_keywords`] must name the pair style's models).
fn write_walls(s: &mut String, case: &Case) -> std::fmt::Result {
    let models = model_keywords(case.rolling);
    for (k, w) in case.walls.iter().enumerate() {
        let (prim, what) = match w {
            Wall::Plane { axis, position, .. } => (
                format!("{}plane {}", axis.name(), f(*position)),
                format!("the plane {} = {} m", axis.name(), f(*position)),
            ),
            Wall::Cylinder {
                axis,
                radius,
                center,
                ..
            } => (
                format!(
                    "{}cylinder {} {} {}",
                    axis.name(),
                    f(*radius),
                    f(center[0]),
                    f(center[1])
                ),
                format!(
                    "the inside of a cylinder of radius {} m about the {} axis through ({}, {}) m",
                    f(*radius),
                    axis.name(),
                    f(center[0]),
                    f(center[1])
                ),
            ),
        };
        deck_text::comment(
            s,
            &format!(
                "Wall {} ([[walls]] {}): {what}, material type {}, the same contact law as \
                 between particles.",
                k + 1,
                k + 1,
                w.type_() + 1
            ),
        );
        writeln!(
            s,
            "fix w{} all wall/gran {models} primitive type {} {prim}",
            k + 1,
            w.type_() + 1
        )?;
    }
    Ok(())
}

/// Thermo (with lost atoms an error, as in the native engine), the measured trajectory
/// in the columns of [`DUMP_COLUMNS`] at full precision (what granval's dump parser
/// reads), and the run.
fn write_output_and_run(s: &mut String, case: &Case, dump_file: &str) -> std::fmt::Result {
    let duration = case.dt * case.n_steps as f64;
    deck_text::block(
        s,
        &format!(
            "---- Output ----\n\
             Thermo line every {} steps (step, atoms, kinetic energy, CPU time). `thermo_modify \
             lost error`: LIGGGHTS 3.8 would silently drop an atom that leaves the closed box; \
             the case (and granval's native engine) makes that an error. The check runs at \
             thermo output, and the last step always has one; it must follow thermo_style, \
             which resets thermo_modify.",
            (case.n_steps / 20).max(1)
        ),
    );
    writeln!(s, "thermo_style custom step atoms ke cpu")?;
    writeln!(s, "thermo_modify lost error")?;
    writeln!(s, "thermo {}", (case.n_steps / 20).max(1))?;
    deck_text::comment(
        s,
        &format!(
            "The measured trajectory: every {} steps (from step 0) each particle's id, position \
             (m), velocity (m/s), angular velocity (rad/s) and force (N), sorted by id, with 17 \
             significant digits (%.17g: every double reads back exactly). One C format for the \
             whole line: LIGGGHTS 3.8 has no per-column form.",
            case.output_every
        ),
    );
    writeln!(
        s,
        "dump d all custom {} {dump_file} {}",
        case.output_every,
        DUMP_COLUMNS.join(" ")
    )?;
    let fmt = std::iter::once("%d")
        .chain(std::iter::repeat_n("%.17g", DUMP_COLUMNS.len() - 1))
        .collect::<Vec<_>>()
        .join(" ");
    writeln!(s, "dump_modify d sort id format \"{fmt}\"")?;
    deck_text::block(
        s,
        &format!(
            "{} steps: {} s of simulated time.",
            case.n_steps,
            deck_text::approx(duration)
        ),
    );
    writeln!(s, "run {}", case.n_steps)
}
