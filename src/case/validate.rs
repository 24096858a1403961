//! Turns the raw TOML into a [`Case`], refusing anything non-physical with a message
//! that names file, field, value and reason.

use super::ContactFamily;
use super::error::{CaseError, Ctx};
use super::schema;
use super::{
    Axis, Case, Material, Observation, PairTable, Particle, RollingModel, Tolerances, Wall,
};
use std::path::Path;

/// Gates a micro comparison produces (what its negative controls may name).
pub(crate) const MICRO_GATES: &[super::Gate] = &[
    super::Gate::Position,
    super::Gate::Velocity,
    super::Gate::AngularVelocity,
    super::Gate::Orientation,
];

/// More time steps than any run on one machine can take (1e12 steps of the fastest
/// micro case would take weeks): a duration that large is a typo.
pub(crate) const MAX_STEPS: f64 = 1e12;

/// The raw schema of a case file of one kind, and the context its errors are reported
/// in: a TOML error names the file, a header whose kind is not the loader's is refused
/// before any of its fields (so the message says which loader, not which field it
/// lacks), and the name must be a safe directory name.
pub(super) fn parse_kind<T: serde::de::DeserializeOwned>(
    text: &str,
    path: &Path,
    kind: &str,
    meta: impl Fn(&T) -> &schema::Meta,
) -> Result<(T, Ctx), CaseError> {
    let raw: T = super::parse::from_toml(text, path)?;
    let ctx = Ctx {
        file: path.to_path_buf(),
    };
    let m = meta(&raw);
    if m.kind != kind {
        return Err(ctx.bad(
            "case.kind",
            &m.kind,
            format!("this loader reads kind = \"{kind}\""),
        ));
    }
    case_name(&ctx, &m.name)?;
    Ok((raw, ctx))
}

/// Names of what granval writes beside the case directories of a report or deck
/// directory (the report files, the claim figures, the deck's README and case file, a
/// summary): a case may not be named like one, or its directory and that file would
/// clash ("Is a directory" at the end of a run). Compared without case, for file
/// systems that ignore it.
pub(crate) const RESERVED_NAMES: [&str; 8] = [
    "report.json",
    "report.md",
    "report.junit.xml",
    "claims",
    "malt_verdict.svg",
    "case.toml",
    "README.txt",
    "summary.json",
];

/// Case names become directory names under `--report` and `reference/`: only
/// `[A-Za-z0-9._-]`, not starting with a dot, so a name can never climb out of them,
/// and none of [`RESERVED_NAMES`].
pub(super) fn case_name(ctx: &Ctx, name: &str) -> Result<(), CaseError> {
    if let Some(r) = RESERVED_NAMES.iter().find(|r| r.eq_ignore_ascii_case(name)) {
        return Err(ctx.bad(
            "case.name",
            name,
            format!(
                "{r} is a file granval writes beside the case directories of a report; name the case otherwise"
            ),
        ));
    }
    let ok = !name.is_empty()
        && name.len() <= 100
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "._-".contains(c));
    if ok {
        Ok(())
    } else {
        Err(ctx.bad(
            "case.name",
            name,
            "must be 1-100 characters of [A-Za-z0-9._-], not starting with '.' (it names output directories)",
        ))
    }
}

pub(crate) use super::fields::{finite, positive, vec3};

fn axis(ctx: &Ctx, field: &str, s: &str) -> Result<Axis, CaseError> {
    match s {
        "x" => Ok(Axis::X),
        "y" => Ok(Axis::Y),
        "z" => Ok(Axis::Z),
        _ => Err(ctx.bad(field, s, "must be one of \"x\", \"y\", \"z\"")),
    }
}

/// Models, materials and pair coefficients: shared by every case kind.
pub(super) fn physics(
    ctx: &Ctx,
    models: &schema::Models,
    raw_materials: &[schema::Material],
    interactions: &[schema::Interaction],
    lammps_allowed: bool,
) -> Result<(RollingModel, Vec<Material>, PairTable), CaseError> {
    let raw = Raw {
        models,
        materials: raw_materials,
        interactions,
    };
    // The LAMMPS family names its own sub-models (micro cases only; see super::family).
    let rolling = if super::family::is_lammps(ctx, models)? {
        if !lammps_allowed {
            return Err(ctx.bad(
                "models.family",
                "lammps",
                "only micro cases can use the LAMMPS family",
            ));
        }
        super::family::check_lammps_names(ctx, models)?;
        RollingModel::None
    } else {
        super::family::refuse_lammps_fields(ctx, models, interactions)?;
        liggghts_models(ctx, &raw)?
    };
    physics_tables(ctx, &raw).map(|(m, p)| (rolling, m, p))
}

/// Models: only the LIGGGHTS 3.8 combination the native engine reproduces exactly.
fn liggghts_models(ctx: &Ctx, raw: &Raw) -> Result<RollingModel, CaseError> {
    if raw.models.normal != "hertz" {
        return Err(ctx.bad("models.normal", &raw.models.normal, "supported: \"hertz\""));
    }
    if raw.models.tangential != "history" {
        return Err(ctx.bad(
            "models.tangential",
            &raw.models.tangential,
            "supported: \"history\"",
        ));
    }
    let rolling = match raw.models.rolling.as_str() {
        "none" => RollingModel::None,
        "cdt" => RollingModel::Cdt,
        "epsd2" => RollingModel::Epsd2,
        other => {
            return Err(ctx.bad(
                "models.rolling",
                other,
                "supported: \"none\", \"cdt\", \"epsd2\"",
            ));
        }
    };
    Ok(rolling)
}

/// Materials and pair coefficients, shared by both families.
fn physics_tables(ctx: &Ctx, raw: &Raw) -> Result<(Vec<Material>, PairTable), CaseError> {
    // Materials: types 1..n, each exactly once.
    let n_types = raw.materials.len();
    if n_types == 0 {
        return Err(ctx.bad(
            "materials",
            "[]",
            "at least one material (atom type) is required",
        ));
    }
    let mut materials: Vec<Option<Material>> = vec![None; n_types];
    for (k, m) in raw.materials.iter().enumerate() {
        let f = |name: &str| format!("materials[{k}].{name}");
        if m.type_ < 1 || m.type_ > n_types {
            return Err(ctx.bad(
                f("type"),
                m.type_,
                format!("types must be 1..={n_types} (one material per type)"),
            ));
        }
        if materials[m.type_ - 1].is_some() {
            return Err(ctx.bad(f("type"), m.type_, "type defined twice"));
        }
        let nu = finite(ctx, &f("poisson_ratio"), m.poisson_ratio)?;
        // Isotropic elasticity: positive bulk and shear moduli need -1 < nu <= 1/2
        // (1/2: incompressible). The reference engines may take less (LIGGGHTS: nu >= 0),
        // which every command that compares checks ([`crate::experiments::Experiment::preflight`]).
        if !(nu > -1.0 && nu <= 0.5) {
            return Err(ctx.bad(f("poisson_ratio"), nu, "must lie in (-1, 0.5]"));
        }
        let (e, g) = match (m.youngs_modulus, m.shear_modulus) {
            (Some(e), None) => {
                let e = positive(ctx, &f("youngs_modulus"), e)?;
                (e, e / (2.0 * (1.0 + nu)))
            }
            (None, Some(g)) => {
                let g = positive(ctx, &f("shear_modulus"), g)?;
                (2.0 * g * (1.0 + nu), g)
            }
            (Some(_), Some(_)) => {
                return Err(ctx.bad(
                    f("youngs_modulus"),
                    "both given",
                    "give youngs_modulus or shear_modulus, not both",
                ));
            }
            (None, None) => {
                return Err(ctx.bad(
                    f("youngs_modulus"),
                    "missing",
                    "give youngs_modulus or shear_modulus",
                ));
            }
        };
        materials[m.type_ - 1] = Some(Material {
            youngs_modulus: e,
            shear_modulus: g,
            poisson_ratio: nu,
        });
    }
    let materials: Vec<Material> = materials
        .into_iter()
        .map(|m| m.expect("every type checked above"))
        .collect();

    // Interactions: every unordered type pair exactly once.
    let nn = n_types * n_types;
    let mut pairs = PairTable {
        n_types,
        restitution: vec![f64::NAN; nn],
        friction: vec![f64::NAN; nn],
        rolling_friction: vec![f64::NAN; nn],
    };
    for (k, it) in raw.interactions.iter().enumerate() {
        set_pair(
            ctx,
            &format!("interactions[{k}]"),
            it,
            &mut pairs,
            |p, a, b| !p.restitution[p.idx(a, b)].is_nan(),
        )?;
    }
    for a in 0..n_types {
        for b in a..n_types {
            if pairs.restitution[pairs.idx(a, b)].is_nan() {
                return Err(ctx.bad(
                    "interactions",
                    format!("types [{}, {}]", a + 1, b + 1),
                    "missing: every type pair needs restitution, friction and rolling_friction",
                ));
            }
        }
    }

    Ok((materials, pairs))
}

/// Validates one `[[interactions]]`-shaped entry (`field` names it in errors) and writes
/// it into `pairs` for both orders; `taken(pairs, a, b)` says whether the pair was
/// already given in this list.
fn set_pair(
    ctx: &Ctx,
    field: &str,
    it: &schema::Interaction,
    pairs: &mut PairTable,
    taken: impl Fn(&PairTable, usize, usize) -> bool,
) -> Result<(), CaseError> {
    let n_types = pairs.n_types;
    let f = |name: &str| format!("{field}.{name}");
    let [a, b] = it.types;
    if a < 1 || a > n_types || b < 1 || b > n_types {
        return Err(ctx.bad(
            f("types"),
            it.types,
            format!("types must be in 1..={n_types}"),
        ));
    }
    let (a, b) = (a - 1, b - 1);
    if taken(pairs, a, b) {
        return Err(ctx.bad(f("types"), it.types, "pair defined twice"));
    }
    let e = finite(ctx, &f("restitution"), it.restitution)?;
    if !(e > 0.0 && e <= 1.0) {
        return Err(ctx.bad(f("restitution"), e, "must lie in (0, 1]"));
    }
    let mu = finite(ctx, &f("friction"), it.friction)?;
    if mu < 0.0 {
        return Err(ctx.bad(f("friction"), mu, "must be >= 0"));
    }
    let mur = finite(ctx, &f("rolling_friction"), it.rolling_friction)?;
    if mur < 0.0 {
        return Err(ctx.bad(f("rolling_friction"), mur, "must be >= 0"));
    }
    for (i, j) in [(a, b), (b, a)] {
        let ix = pairs.idx(i, j);
        pairs.restitution[ix] = e;
        pairs.friction[ix] = mu;
        pairs.rolling_friction[ix] = mur;
    }
    Ok(())
}

/// `base` with the pairs of `overrides` (entries `field[k]`, each a complete
/// `[[interactions]]` entry) replaced; each pair at most once.
pub(super) fn override_pairs(
    ctx: &Ctx,
    base: &PairTable,
    overrides: &[schema::Interaction],
    field: &str,
) -> Result<PairTable, CaseError> {
    let mut pairs = base.clone();
    let mut given = Vec::new();
    for (k, it) in overrides.iter().enumerate() {
        set_pair(ctx, &format!("{field}[{k}]"), it, &mut pairs, |p, a, b| {
            given.contains(&p.idx(a.min(b), a.max(b)))
        })?;
        let [a, b] = it.types;
        given.push(pairs.idx((a.min(b)) - 1, a.max(b) - 1));
    }
    Ok(pairs)
}

/// A 1-based material type `t` of `field`, as a 0-based index into the case's
/// `n_types` materials (penetration and triaxial cases name their grains', walls' and
/// intruder's types so).
pub(super) fn material_type(
    ctx: &Ctx,
    field: &str,
    t: usize,
    n_types: usize,
) -> Result<usize, CaseError> {
    if t < 1 || t > n_types {
        Err(ctx.bad(
            field,
            t,
            format!("must be a material type in 1..={n_types}"),
        ))
    } else {
        Ok(t - 1)
    }
}

/// Borrowed view so the shared validation reads like the original field accesses.
struct Raw<'a> {
    models: &'a schema::Models,
    materials: &'a [schema::Material],
    interactions: &'a [schema::Interaction],
}

/// Validates a micro case file one section at a time, in the order of the calls below;
/// the first error found is the one reported.
pub(super) fn validate(raw: schema::CaseFile, path: &Path) -> Result<Case, CaseError> {
    let ctx = Ctx {
        file: path.to_path_buf(),
    };

    if raw.case.kind != "micro" {
        // Other kinds have their own loaders (e.g. `PenetrationCase::load`).

        return Err(ctx.bad("case.kind", &raw.case.kind, "supported kinds: \"micro\""));
    }
    case_name(&ctx, &raw.case.name)?;

    let (rolling, materials, pairs) =
        physics(&ctx, &raw.models, &raw.materials, &raw.interactions, true)?;
    let n_types = materials.len();
    let (lo, hi) = domain(&ctx, &raw.domain)?;
    let (particles, ids) = particles(&ctx, &raw, n_types, lo, hi)?;
    let clumps = clumps(&ctx, &raw, n_types, lo, hi, &ids)?;
    let walls = walls(&ctx, &raw.walls, n_types)?;
    let time = timing(&ctx, &raw.simulation, &particles, &clumps, &materials)?;
    clumps_start_still(&ctx, &particles, &clumps, time.gravity)?;
    let neighbor_skin = neighbor_skin(&ctx, &raw.simulation, &particles, &clumps)?;
    let tolerances = tolerances(&ctx, raw.compare.as_ref())?;
    let expect = match raw.compare.as_ref().and_then(|c| c.expect.as_ref()) {
        Some(list) => observations(&ctx, list)?,
        None => default_expect(&particles, &clumps.bodies),
    };
    let negative_controls = micro_controls(&ctx, &raw, &pairs, &materials, rolling, &clumps)?;
    let family = if super::family::is_lammps(&ctx, &raw.models)? {
        ContactFamily::Lammps(super::family::lammps_models(
            &ctx,
            &raw.models,
            &raw.interactions,
            n_types,
            &particles,
            &walls,
            !clumps.is_empty(),
        )?)
    } else {
        ContactFamily::Liggghts
    };

    Ok(Case {
        family,
        negative_controls,
        name: raw.case.name,
        kind: raw.case.kind,
        description: raw.case.description,
        source: path.to_path_buf(),
        dt: time.dt,
        n_steps: time.n_steps as u64,
        output_every: raw.simulation.output_every,
        gravity: time.gravity,
        neighbor_skin,
        rolling,
        domain_lo: lo,
        domain_hi: hi,
        materials,
        pairs,
        particles,
        walls,
        clumps,
        tolerances,
        rayleigh_time: time.rayleigh,
        expect,
        warnings: Vec::new(),
    })
}

/// `[domain]`: the box's corners, `hi` above `lo` on every axis.
fn domain(ctx: &Ctx, d: &schema::Domain) -> Result<([f64; 3], [f64; 3]), CaseError> {
    let lo = vec3(ctx, "domain.lo", d.lo)?;
    let hi = vec3(ctx, "domain.hi", d.hi)?;
    for k in 0..3 {
        if hi[k] <= lo[k] {
            return Err(ctx.bad(
                format!("domain.hi[{k}]"),
                hi[k],
                format!("must exceed domain.lo[{k}] = {}", lo[k]),
            ));
        }
    }
    Ok((lo, hi))
}

/// `[[particles]]`, the free spheres (a clump case may have none), and their ids, which
/// the clump bodies must not reuse: unique positive ids, material types of the case, and
/// spheres that fit inside the box `lo`..`hi`.
fn particles(
    ctx: &Ctx,
    raw: &schema::CaseFile,
    n_types: usize,
    lo: [f64; 3],
    hi: [f64; 3],
) -> Result<(Vec<Particle>, std::collections::HashSet<u64>), CaseError> {
    if raw.particles.is_empty() && raw.clumps.is_empty() {
        return Err(ctx.bad(
            "particles",
            "[]",
            "at least one particle (or one [[clumps]] body) is required",
        ));
    }
    let mut particles = Vec::with_capacity(raw.particles.len());
    let mut seen = std::collections::HashSet::new();
    for (k, p) in raw.particles.iter().enumerate() {
        let f = |name: &str| format!("particles[{k}].{name}");
        if p.id == 0 || !seen.insert(p.id) {
            return Err(ctx.bad(f("id"), p.id, "ids must be positive and unique"));
        }
        if p.type_ < 1 || p.type_ > n_types {
            return Err(ctx.bad(f("type"), p.type_, format!("must be in 1..={n_types}")));
        }
        let radius = positive(ctx, &f("radius"), p.radius)?;
        let smallest_side = (0..3).map(|c| hi[c] - lo[c]).fold(f64::INFINITY, f64::min);
        if 2.0 * radius > smallest_side {
            return Err(ctx.bad(
                f("radius"),
                radius,
                format!(
                    "the sphere is wider than the domain box (smallest side {smallest_side:e} m)"
                ),
            ));
        }
        let density = positive(ctx, &f("density"), p.density)?;
        let x = vec3(ctx, &f("x"), p.x)?;
        for c in 0..3 {
            if x[c] - radius < lo[c] || x[c] + radius > hi[c] {
                return Err(ctx.bad(
                    f("x"),
                    x,
                    "particle (with its radius) must lie inside the domain box",
                ));
            }
        }
        particles.push(Particle {
            id: p.id,
            type_: p.type_ - 1,
            radius,
            density,
            x,
            v: vec3(ctx, &f("v"), p.v)?,
            omega: vec3(ctx, &f("omega"), p.omega)?,
        });
    }
    Ok((particles, seen))
}

/// `[[clump_templates]]` and `[[clumps]]`: the bodies, whose ids must differ from the
/// free spheres' `ids`; a template no body uses is refused.
fn clumps(
    ctx: &Ctx,
    raw: &schema::CaseFile,
    n_types: usize,
    lo: [f64; 3],
    hi: [f64; 3],
    ids: &std::collections::HashSet<u64>,
) -> Result<super::clumps::Clumps, CaseError> {
    let templates = super::clumps::templates(ctx, &raw.clump_templates, n_types)?;
    let bodies = super::clumps::bodies(ctx, &raw.clumps, &templates, lo, hi, ids)?;
    if bodies.is_empty() && !templates.is_empty() {
        return Err(ctx.bad(
            "clump_templates",
            templates.len(),
            "templates are defined but no [[clumps]] body uses them",
        ));
    }
    Ok(super::clumps::Clumps { templates, bodies })
}

/// `[[walls]]`: planes along any axis, cylinders along z only, each of a material type
/// of the case (0-based once validated).
fn walls(ctx: &Ctx, raw: &[schema::Wall], n_types: usize) -> Result<Vec<Wall>, CaseError> {
    let mut walls = Vec::with_capacity(raw.len());
    for (k, w) in raw.iter().enumerate() {
        let f = |name: &str| format!("walls[{k}].{name}");
        let wall = match w {
            schema::Wall::Plane {
                axis: a,
                position,
                type_,
            } => Wall::Plane {
                axis: axis(ctx, &f("axis"), a)?,
                position: finite(ctx, &f("position"), *position)?,
                type_: *type_,
            },
            schema::Wall::Cylinder {
                axis: a,
                radius,
                center,
                type_,
            } => {
                let ax = axis(ctx, &f("axis"), a)?;
                if ax != Axis::Z {
                    return Err(ctx.bad(f("axis"), a, "only \"z\" cylinders are supported"));
                }
                Wall::Cylinder {
                    axis: ax,
                    radius: positive(ctx, &f("radius"), *radius)?,
                    center: [
                        finite(ctx, &f("center[0]"), center[0])?,
                        finite(ctx, &f("center[1]"), center[1])?,
                    ],
                    type_: *type_,
                }
            }
        };
        let t = wall.type_();
        if t < 1 || t > n_types {
            return Err(ctx.bad(
                f("type"),
                t,
                format!("wall material type must be in 1..={n_types}"),
            ));
        }
        walls.push(match wall {
            Wall::Plane { axis, position, .. } => Wall::Plane {
                axis,
                position,
                type_: t - 1,
            },
            Wall::Cylinder {
                axis,
                radius,
                center,
                ..
            } => Wall::Cylinder {
                axis,
                radius,
                center,
                type_: t - 1,
            },
        });
    }
    Ok(walls)
}

/// `[simulation]`, validated (SI): `n_steps` is the duration in whole steps.
struct Timing {
    dt: f64,
    rayleigh: f64,
    n_steps: f64,
    gravity: [f64; 3],
}

/// `[simulation]`: the time step, refused above the Rayleigh time of the most critical
/// grain (free spheres and clump members); a duration of a whole number of at most
/// [`MAX_STEPS`] steps; the output interval; gravity.
fn timing(
    ctx: &Ctx,
    s: &schema::Simulation,
    particles: &[Particle],
    clumps: &super::clumps::Clumps,
    materials: &[Material],
) -> Result<Timing, CaseError> {
    let dt = positive(ctx, "simulation.dt", s.dt)?;
    let rayleigh = particles
        .iter()
        .map(|p| (p.radius, p.density, p.type_))
        .chain(
            clumps
                .templates
                .iter()
                .flat_map(|t| t.radii.iter().map(|r| (*r, t.density, t.type_))),
        )
        .map(|(r, rho, ty)| {
            let m = &materials[ty];
            super::rayleigh_time(r, rho, m.shear_modulus, m.poisson_ratio)
        })
        .fold(f64::INFINITY, f64::min);
    if dt > rayleigh {
        return Err(ctx.bad(
            "simulation.dt",
            dt,
            format!(
                "exceeds the Rayleigh time {rayleigh:.3e} s; use <= 20% of it ({:.3e} s)",
                0.2 * rayleigh
            ),
        ));
    }
    let duration = positive(ctx, "simulation.duration", s.duration)?;
    let n_steps = (duration / dt).round();
    if n_steps > MAX_STEPS {
        return Err(ctx.bad(
            "simulation.duration",
            duration,
            format!(
                "is {n_steps:.3e} time steps of {dt:e} s; more than {MAX_STEPS:.0e} cannot finish"
            ),
        ));
    }
    if (n_steps * dt - duration).abs() > 1e-9 * duration {
        return Err(ctx.bad(
            "simulation.duration",
            duration,
            format!("must be a whole number of time steps of {dt} s"),
        ));
    }
    if s.output_every == 0 {
        return Err(ctx.bad("simulation.output_every", 0, "must be >= 1"));
    }
    let gravity = vec3(ctx, "simulation.gravity", s.gravity)?;
    Ok(Timing {
        dt,
        rayleigh,
        n_steps,
        gravity,
    })
}

/// A case with clumps: its free spheres must not move before the bodies exist.
fn clumps_start_still(
    ctx: &Ctx,
    particles: &[Particle],
    clumps: &super::clumps::Clumps,
    gravity: [f64; 3],
) -> Result<(), CaseError> {
    if clumps.is_empty() {
        return Ok(());
    }
    // LIGGGHTS creates free spheres at step 0 but inserts bodies at step 1 (fix
    // insert/pack, pre_exchange of step 1); the comparison starts at step 1 (t = 0).
    // A free sphere must therefore not move during step 0 -> 1: at rest, force-free.
    for (k, p) in particles.iter().enumerate() {
        if p.v != [0.0; 3] || p.omega != [0.0; 3] {
            return Err(ctx.bad(
                format!("particles[{k}].v"),
                (p.v, p.omega),
                "in a case with clumps, free spheres must start at rest (v = omega = 0): LIGGGHTS inserts the bodies one step after creating the spheres",
            ));
        }
    }
    if !particles.is_empty() && gravity != [0.0; 3] {
        return Err(ctx.bad(
            "simulation.gravity",
            gravity,
            "a case with clumps and free spheres must have zero gravity: the free spheres would fall during the step before the bodies are inserted",
        ));
    }
    Ok(())
}

/// `[simulation] neighbor_skin`: it changes cost, not physics (default: half the smallest
/// radius of a free sphere or clump member).
fn neighbor_skin(
    ctx: &Ctx,
    s: &schema::Simulation,
    particles: &[Particle],
    clumps: &super::clumps::Clumps,
) -> Result<f64, CaseError> {
    let min_r = particles
        .iter()
        .map(|p| p.radius)
        .chain(
            clumps
                .templates
                .iter()
                .flat_map(|t| t.radii.iter().copied()),
        )
        .fold(f64::INFINITY, f64::min);
    match s.neighbor_skin {
        Some(skin) => positive(ctx, "simulation.neighbor_skin", skin),
        None => Ok(0.5 * min_r),
    }
}

/// `[compare]` tolerances, each positive (default 1e-6: the engines agree to round-off).
fn tolerances(ctx: &Ctx, compare: Option<&schema::Compare>) -> Result<Tolerances, CaseError> {
    Ok(match compare {
        None => Tolerances {
            velocity_rel: 1e-6,
            position_frac_radius: 1e-6,
            orientation_rad: 1e-6,
        },
        Some(c) => Tolerances {
            velocity_rel: positive(ctx, "compare.velocity_rel", c.velocity_rel.unwrap_or(1e-6))?,
            position_frac_radius: positive(
                ctx,
                "compare.position_frac_radius",
                c.position_frac_radius.unwrap_or(1e-6),
            )?,
            orientation_rad: positive(
                ctx,
                "compare.orientation_rad",
                c.orientation_rad.unwrap_or(1e-6),
            )?,
        },
    })
}

/// `[[negative_control]]` of a micro case, refused where it would not change the
/// physics of these pairs, materials and clumps.
fn micro_controls(
    ctx: &Ctx,
    raw: &schema::CaseFile,
    pairs: &PairTable,
    materials: &[Material],
    rolling: RollingModel,
    clumps: &super::clumps::Clumps,
) -> Result<Vec<super::NegativeControl>, CaseError> {
    let negative_controls = super::control::controls(
        ctx,
        &raw.negative_control,
        materials.len(),
        // Orientation is gated only where there are bodies to orient.
        if clumps.is_empty() {
            &MICRO_GATES[..3]
        } else {
            MICRO_GATES
        },
    )?;
    super::control::check_applicable(
        ctx,
        &negative_controls,
        &super::control::Targets {
            spheres: Some((
                pairs,
                materials,
                rolling != RollingModel::None || raw.models.rolling == "sds",
            )),
            clumps: !clumps.is_empty(),
        },
    )?;
    Ok(negative_controls)
}

/// `[compare] expect` as written: known names, each once.
fn observations(ctx: &Ctx, list: &[String]) -> Result<Vec<Observation>, CaseError> {
    let mut out = Vec::new();
    for (k, name) in list.iter().enumerate() {
        let o = match name.as_str() {
            "contact" => Observation::Contact,
            other => {
                return Err(ctx.bad(
                    format!("compare.expect[{k}]"),
                    other,
                    "supported: \"contact\" (or an empty list: nothing is required)",
                ));
            }
        };
        if out.contains(&o) {
            return Err(ctx.bad(format!("compare.expect[{k}]"), name, "listed twice"));
        }
        out.push(o);
    }
    Ok(out)
}

/// What a case that does not say tests: a contact, for exactly two bodies (free spheres
/// or clumps) whose centres approach at t = 0 ((v_b - v_a) . (x_b - x_a) < 0): a
/// collision case. Anything else (one grain on a wall, a cluster, bodies at rest)
/// expects nothing beyond the coverage rule's motion.
pub(crate) fn default_expect(
    particles: &[Particle],
    bodies: &[super::clumps::Clump],
) -> Vec<Observation> {
    let states: Vec<([f64; 3], [f64; 3])> = particles
        .iter()
        .map(|p| (p.x, p.v))
        .chain(bodies.iter().map(|b| (b.x, b.v)))
        .collect();
    match states.as_slice() {
        [(xa, va), (xb, vb)] => {
            use crate::numerics::vec3::{dot, sub};
            if dot(sub(*vb, *va), sub(*xb, *xa)) < 0.0 {
                vec![Observation::Contact]
            } else {
                Vec::new()
            }
        }
        _ => Vec::new(),
    }
}
