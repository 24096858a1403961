//! The LIGGGHTS 3.8 input deck and `read_data` file for a [`Case`]. Pure text
//! generation: nothing here runs LIGGGHTS, so `granval deck` and tests can use it.
//!
//! Every float is written with Rust's `{:e}` (shortest round-trip representation), so
//! LIGGGHTS parses back exactly the f64 the case holds: the deck carries no rounding.

use crate::case::{Case, Material, PairTable, Particle, RollingModel, Wall};
use anyhow::{Result, bail};
use std::fmt::Write;

/// LIGGGHTS refuses `youngsModulus` below this in SI units (`global_properties.cpp`,
/// "youngsModulus >= 5e6 required for SI units"), unless `soft_particles yes`.
pub const MIN_YOUNGS_MODULUS_SI: f64 = 5e6;
/// ... and above this ("youngsModulus <= 1e9 required for SI units (use command
/// 'hard_particles yes' to override)").
pub const MAX_YOUNGS_MODULUS_SI: f64 = 1e9;
/// LIGGGHTS requires `0.05 < coefficientRestitution <= 1`.
pub const MIN_RESTITUTION_EXCLUSIVE: f64 = 0.05;

/// Dump columns, in the order the deck asks for them (the parser maps by name anyway).
pub const DUMP_COLUMNS: [&str; 13] = [
    "id", "x", "y", "z", "vx", "vy", "vz", "omegax", "omegay", "omegaz", "fx", "fy", "fz",
];

/// Above this largest atom ID an `atom_modify map array` would allocate a huge lookup
/// table, so the deck switches to `map hash` (same physics, slower lookups).
const MAP_ARRAY_MAX_ID: u64 = 10_000_000;

/// Full-precision (shortest round-trip) number for a deck or data file.
pub(super) fn f(x: f64) -> String {
    format!("{x:e}")
}

pub(super) fn join(xs: impl IntoIterator<Item = f64>) -> String {
    xs.into_iter().map(f).collect::<Vec<_>>().join(" ")
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

/// Material property/global fixes, pair style and pair_coeff, shared by every granval
/// deck. `pressure` converts Pa into the deck's units (1 for SI).
pub(super) fn write_contact_model(
    s: &mut String,
    materials: &[Material],
    pairs: &PairTable,
    rolling: RollingModel,
    pressure: f64,
) -> std::fmt::Result {
    let n = materials.len();
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
    writeln!(s, "pair_style gran {}", model_keywords(rolling))?;
    writeln!(s, "pair_coeff * *")
}

/// Whether the materials need LIGGGHTS' `soft_particles yes` / `hard_particles yes`.
/// Both switches only lift LIGGGHTS' range check of Young's modulus (5e6-1e9 Pa in SI,
/// 5e7-1e10 barye in cgs: the same pressures); the material is written unchanged, so
/// glass, steel and alumina run as they are.
pub fn hardness(materials: &[Material]) -> (bool, bool) {
    let soft = materials
        .iter()
        .any(|m| m.youngs_modulus < MIN_YOUNGS_MODULUS_SI);
    let hard = materials
        .iter()
        .any(|m| m.youngs_modulus > MAX_YOUNGS_MODULUS_SI);
    (soft, hard)
}

/// The switch lines of [`hardness`], each with the comment that says why.
pub(super) fn write_hardness(s: &mut String, soft: bool, hard: bool) -> std::fmt::Result {
    if soft {
        writeln!(
            s,
            "# disables LIGGGHTS' youngsModulus >= 5e6 Pa range check; materials are unchanged"
        )?;
        writeln!(s, "soft_particles yes")?;
    }
    if hard {
        writeln!(
            s,
            "# disables LIGGGHTS' youngsModulus <= 1e9 Pa range check; materials are unchanged"
        )?;
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
        "LIGGGHTS data file written by granval: {}",
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

/// Refuses material values LIGGGHTS 3.8 itself would refuse, before anything runs, naming
/// the case file, the field and the value. Materials are never changed silently.
pub fn check_liggghts_limits(case: &Case) -> Result<()> {
    let file = case.source.display();
    for (t, m) in case.materials.iter().enumerate() {
        let ty = t + 1;
        if !(m.youngs_modulus.is_finite() && m.youngs_modulus > 0.0) {
            bail!(
                "{file}: field `youngs_modulus` of material type {ty} = {:e} Pa cannot be written into a LIGGGHTS deck",
                m.youngs_modulus
            );
        }
        if m.poisson_ratio.is_nan() || m.poisson_ratio < 0.0 {
            bail!(
                "{file}: field `poisson_ratio` of material type {ty} = {:e}: LIGGGHTS 3.8 requires 0 <= poissonsRatio <= 0.5; \
                 granval does not change materials — run this case with the native engine only",
                m.poisson_ratio
            );
        }
    }
    let n = case.n_types();
    for a in 0..n {
        for b in a..n {
            let e = case.pairs.restitution[case.pairs.idx(a, b)];
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

/// The input deck. `dump_file` and `data_file` are written into the deck verbatim
/// (relative names resolve against the directory LIGGGHTS runs in).
pub fn write_deck(case: &Case, dump_file: &str, data_file: &str) -> Result<String> {
    check_liggghts_limits(case)?;
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
    let n = case.n_types();
    let models = model_keywords(case.rolling);
    let max_id = case.particles.iter().map(|p| p.id).max().unwrap_or(0);
    let map = if max_id > MAP_ARRAY_MAX_ID {
        "hash"
    } else {
        "array"
    };

    let mut s = String::new();
    writeln!(
        s,
        "# LIGGGHTS 3.8 input written by granval for case {}",
        comment_safe(&case.name)
    )?;
    writeln!(
        s,
        "# {} particles, {} atom types, {} steps of {} s, output every {} steps",
        case.particles.len(),
        n,
        case.n_steps,
        f(case.dt),
        case.output_every
    )?;
    writeln!(s, "units si")?;
    writeln!(s, "atom_style granular")?;
    writeln!(s, "atom_modify map {map}")?;
    writeln!(s, "boundary f f f")?;
    writeln!(s, "newton off")?;
    writeln!(s, "communicate single vel yes")?;
    writeln!(s, "processors * * *")?;
    let (soft, hard) = hardness(&case.materials);
    write_hardness(&mut s, soft, hard)?;
    writeln!(s, "read_data {data_file}")?;
    writeln!(s, "neighbor {} bin", f(case.neighbor_skin))?;
    writeln!(s, "neigh_modify delay 0")?;

    write_contact_model(&mut s, &case.materials, &case.pairs, case.rolling, 1.0)?;
    writeln!(s, "timestep {}", f(case.dt))?;

    let g = case.gravity;
    let gmag = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    if gmag > 0.0 {
        writeln!(s, "fix gravi all gravity {} vector {}", f(gmag), join(g))?;
    }

    for (k, w) in case.walls.iter().enumerate() {
        let prim = match w {
            Wall::Plane { axis, position, .. } => format!("{}plane {}", axis.name(), f(*position)),
            Wall::Cylinder {
                axis,
                radius,
                center,
                ..
            } => format!(
                "{}cylinder {} {} {}",
                axis.name(),
                f(*radius),
                f(center[0]),
                f(center[1])
            ),
        };
        writeln!(
            s,
            "fix w{} all wall/gran {models} primitive type {} {prim}",
            k + 1,
            w.type_() + 1
        )?;
    }

    writeln!(s, "fix integr all nve/sphere")?;
    writeln!(s, "thermo_style custom step atoms ke cpu")?;
    // LIGGGHTS 3.8 silently drops atoms that leave a fixed box unless told otherwise;
    // the case semantics (and the native engine) make leaving the domain an error. The
    // check runs at thermo output, and the last step of a run always has one. Must come
    // after thermo_style, which resets thermo_modify settings.
    writeln!(s, "thermo_modify lost error")?;
    writeln!(s, "thermo {}", (case.n_steps / 20).max(1))?;
    writeln!(
        s,
        "dump d all custom {} {dump_file} {}",
        case.output_every,
        DUMP_COLUMNS.join(" ")
    )?;
    // LIGGGHTS 3.8 takes one C format string for the whole line (no per-column form).
    let fmt = std::iter::once("%d")
        .chain(std::iter::repeat_n("%.17g", DUMP_COLUMNS.len() - 1))
        .collect::<Vec<_>>()
        .join(" ");
    writeln!(s, "dump_modify d sort id format \"{fmt}\"")?;
    writeln!(s, "run {}", case.n_steps)?;
    Ok(s)
}
