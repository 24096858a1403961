//! Case kind `triaxial`: axisymmetric-stress compression of a cuboid sample between six
//! frictionless plane walls (docs/stress.md, "Reading of rule 5: the triaxial test"). A
//! sample is a jittered cubic lattice at a low solid fraction, compacted isotropically
//! by three servo walls to the confining pressure, then sheared by the z_hi wall moving
//! down at constant speed while x_hi and y_hi hold the confining pressure. Parsed and
//! validated once; all SI.

use super::error::CaseError;
use super::validate::{material_type, physics, positive};
use super::{Gate, Material, NegativeControl, PairTable, RollingModel, schema};
use serde::Deserialize;
use std::path::{Path, PathBuf};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    case: schema::Meta,
    simulation: Sim,
    models: schema::Models,
    materials: Vec<schema::Material>,
    interactions: Vec<schema::Interaction>,
    sample: RawSample,
    servo: ServoGains,
    compaction: RawCompaction,
    shear: RawShear,
    analysis: Analysis,
    #[serde(default)]
    compare: Option<Tolerances>,
    #[serde(default)]
    negative_control: Vec<super::control::RawControl>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Sim {
    dt: f64,
    neighbor_skin: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSample {
    /// Material type of the grains (1-based).
    #[serde(rename = "type")]
    type_: usize,
    /// Material type of the six walls (1-based).
    wall_type: usize,
    grains: usize,
    diameter: f64,
    density: f64,
    /// Solid fraction of the jittered cubic lattice the compaction starts from.
    solid_fraction: f64,
    /// One sample per seed (and per confining pressure).
    seeds: Vec<u64>,
}

/// Gains and speed limit of LIGGGHTS' mesh module servo (`kp`, `ki`, `kd`, `vel_max`),
/// used by the three compaction walls and the two lateral walls of the shear.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct ServoGains {
    pub kp: f64,
    pub ki: f64,
    pub kd: f64,
    /// m/s; LIGGGHTS requires vel_max < skin / (2 dt).
    pub vel_max: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCompaction {
    /// Every wall stress within this fraction of the confining pressure.
    stress_tolerance: f64,
    /// Translational kinetic energy below this times sigma_c V (V the box volume).
    ke_factor: f64,
    /// Error if the criterion is not met after this much simulated time (s).
    max_time: f64,
    /// The criterion is checked every this many steps.
    check_every: u64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawShear {
    /// sigma_c (Pa), one unit per pressure and seed.
    confining_pressures: Vec<f64>,
    /// eps_dot (1/s): the z_hi wall moves down at eps_dot H0.
    strain_rate: f64,
    /// Axial strain eps_a = (H0 - H) / H0 at the end.
    final_strain: f64,
    /// Wall positions and forces every this many steps.
    output_every: u64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Analysis {
    /// Width in eps_a of the consecutive windows phi_peak is the largest of.
    peak_window: f64,
    /// [from, to] in eps_a of the critical-state window.
    critical_state: [f64; 2],
    /// Width in eps_a of the blocks whose phi gives the critical state's block sd.
    block: f64,
}

#[derive(Debug, Clone, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Tolerances {
    /// |mean phi_cs,native - mean phi_cs,reference| in degrees (default 1.5, the phi
    /// gate's tolerance).
    #[serde(default = "d_phi")]
    pub phi_abs_deg: f64,
}

fn d_phi() -> f64 {
    1.5
}

impl Default for Tolerances {
    fn default() -> Self {
        Tolerances {
            phi_abs_deg: d_phi(),
        }
    }
}

/// Gates a triaxial comparison produces (what its negative controls may name).
pub(crate) const TRIAXIAL_GATES: &[Gate] = &[Gate::Phi];

/// A validated triaxial case; the fields are public for reading (`non_exhaustive`: only
/// the loader builds one).
#[derive(Debug, Clone, serde::Serialize)]
#[non_exhaustive]
pub struct TriaxialCase {
    pub name: String,
    pub description: String,
    pub source: PathBuf,
    pub dt: f64,
    pub neighbor_skin: f64,
    pub rolling: RollingModel,
    pub materials: Vec<Material>,
    pub pairs: PairTable,
    /// 0-based material types.
    pub grain_type: usize,
    pub wall_type: usize,
    pub grains: usize,
    pub diameter: f64,
    pub density: f64,
    pub solid_fraction: f64,
    pub seeds: Vec<u64>,
    pub servo: ServoGains,
    pub stress_tolerance: f64,
    pub ke_factor: f64,
    pub max_compaction_time: f64,
    pub check_every: u64,
    pub confining_pressures: Vec<f64>,
    pub strain_rate: f64,
    pub final_strain: f64,
    pub output_every: u64,
    pub peak_window: f64,
    pub critical_state: [f64; 2],
    pub block: f64,
    pub tolerances: Tolerances,
    pub rayleigh_time: f64,
    pub negative_controls: Vec<NegativeControl>,
    /// Plausibility warnings of the file as written ([`super::plausible`]); not physics.
    #[serde(skip)]
    pub warnings: Vec<String>,
}

impl TriaxialCase {
    pub fn load(path: &Path) -> Result<TriaxialCase, CaseError> {
        let text = super::read_case_file(path)?;
        Self::from_toml_str(&text, path)
    }

    /// What the runs depend on: physics, sample, servo, compaction and shear protocol;
    /// not the name, description, analysis windows, tolerances or controls.
    ///
    /// The struct is destructured exhaustively: a new field does not compile until it is
    /// placed in the view or named below as not physics.
    pub fn canonical_hash(&self) -> crate::rundata::provenance::Sha256 {
        let TriaxialCase {
            dt,
            neighbor_skin,
            rolling,
            materials,
            pairs,
            grain_type,
            wall_type,
            grains,
            diameter,
            density,
            solid_fraction,
            seeds,
            servo,
            stress_tolerance,
            ke_factor,
            max_compaction_time,
            check_every,
            confining_pressures,
            strain_rate,
            final_strain,
            output_every,
            // Not physics: labels, the analysis windows (peak, critical state, blocks),
            // how the runs are judged, and a time derived from the sealed materials.
            name: _,
            description: _,
            source: _,
            peak_window: _,
            critical_state: _,
            block: _,
            tolerances: _,
            rayleigh_time: _,
            negative_controls: _,
            warnings: _,
        } = self;
        let view = serde_json::json!({
            "kind": "triaxial",
            "dt": dt,
            "neighbor_skin": neighbor_skin,
            "rolling": rolling,
            "materials": materials,
            "pairs": pairs,
            "sample": [*grain_type as f64, *wall_type as f64, *grains as f64, diameter, density, solid_fraction],
            "seeds": seeds,
            "servo": servo,
            "compaction": [stress_tolerance, ke_factor, max_compaction_time, *check_every as f64],
            "shear": [strain_rate, final_strain, *output_every as f64],
            "pressures": confining_pressures,
        });
        crate::rundata::provenance::Sha256::of(view.to_string().as_bytes())
    }

    /// Steps of the shear: the final strain at eps_dot, rounded up to whole outputs.
    pub(crate) fn shear_steps(&self) -> u64 {
        let n = (self.final_strain / (self.strain_rate * self.dt)).ceil() as u64;
        n.div_ceil(self.output_every) * self.output_every
    }

    /// Side of the cubic box the lattice fills at the starting solid fraction, and the
    /// lattice sites per side.
    pub fn lattice_box(&self) -> (f64, usize) {
        let v = std::f64::consts::PI / 6.0 * self.diameter.powi(3);
        let side = (self.grains as f64 * v / self.solid_fraction).cbrt();
        let n = (self.grains as f64).cbrt().round() as usize;
        let n = if n * n * n < self.grains { n + 1 } else { n };
        (side, n)
    }

    pub fn from_toml_str(text: &str, path: &Path) -> Result<TriaxialCase, CaseError> {
        let (raw, ctx) = super::validate::parse_kind(text, path, "triaxial", |r: &File| &r.case)?;
        let mut warnings = super::plausible::materials(&raw.materials);
        warnings.extend(super::plausible::density(
            "sample.density",
            raw.sample.density,
        ));
        warnings.extend(super::plausible::size(
            "sample.diameter",
            raw.sample.diameter,
        ));
        let mut case = Self::validated(raw, ctx, path).map_err(|e| e.noting(&warnings))?;
        case.warnings = warnings;
        Ok(case)
    }

    /// Validates a parsed file one section at a time, in the order of the calls below;
    /// the first error found is the one reported.
    fn validated(
        raw: File,
        ctx: super::error::Ctx,
        path: &Path,
    ) -> Result<TriaxialCase, CaseError> {
        let (rolling, materials, pairs) =
            physics(&ctx, &raw.models, &raw.materials, &raw.interactions, false)?;
        let n_types = materials.len();
        let sample = sample(&ctx, &raw.sample, n_types)?;
        let g = servo(&ctx, raw.servo)?;
        let compaction = compaction(&ctx, &raw.compaction)?;
        let (strain_rate, final_strain) = shear(&ctx, &raw.shear)?;
        let (peak_window, block) = analysis_windows(&ctx, &raw.analysis, final_strain)?;
        let tolerances = raw.compare.unwrap_or_default();
        positive(&ctx, "compare.phi_abs_deg", tolerances.phi_abs_deg)?;
        let (dt, rayleigh, neighbor_skin) = timing(
            &ctx,
            &raw.simulation,
            &materials[sample.grain_type],
            &sample,
            g.vel_max,
        )?;
        let (s, c, sh, a) = (&raw.sample, &raw.compaction, &raw.shear, &raw.analysis);
        let case = TriaxialCase {
            name: raw.case.name,
            description: raw.case.description,
            source: path.to_path_buf(),
            dt,
            neighbor_skin,
            rolling,
            materials,
            pairs,
            grain_type: sample.grain_type,
            wall_type: sample.wall_type,
            grains: s.grains,
            diameter: sample.diameter,
            density: sample.density,
            solid_fraction: sample.solid_fraction,
            seeds: s.seeds.clone(),
            servo: g,
            stress_tolerance: compaction.stress_tolerance,
            ke_factor: compaction.ke_factor,
            max_compaction_time: compaction.max_time,
            check_every: c.check_every,
            confining_pressures: sh.confining_pressures.clone(),
            strain_rate,
            final_strain,
            output_every: sh.output_every,
            peak_window,
            critical_state: a.critical_state,
            block,
            tolerances,
            rayleigh_time: rayleigh,
            negative_controls: super::control::controls(
                &ctx,
                &raw.negative_control,
                n_types,
                TRIAXIAL_GATES,
            )?,
            warnings: Vec::new(),
        };
        super::control::check_applicable(
            &ctx,
            &case.negative_controls,
            &super::control::Targets {
                spheres: Some((
                    &case.pairs,
                    &case.materials,
                    case.rolling != super::RollingModel::None,
                )),
                clumps: false,
            },
        )?;
        lattice_fits(&ctx, &case)?;
        Ok(case)
    }
}

/// `[sample]`, validated: 0-based material types and the grains (SI).
struct Sample {
    grain_type: usize,
    wall_type: usize,
    diameter: f64,
    density: f64,
    solid_fraction: f64,
}

/// `[sample]`: the grains' and the walls' material types (distinct: the walls are
/// frictionless against the grains, docs/stress.md rule 5), at least a 2^3 lattice of
/// grains, their size, density and starting solid fraction, and distinct seeds.
fn sample(ctx: &super::error::Ctx, s: &RawSample, n_types: usize) -> Result<Sample, CaseError> {
    let grain_type = material_type(ctx, "sample.type", s.type_, n_types)?;
    let wall_type = material_type(ctx, "sample.wall_type", s.wall_type, n_types)?;
    if grain_type == wall_type {
        return Err(ctx.bad(
            "sample.wall_type",
            s.wall_type,
            "the walls need their own type (frictionless against the grains, docs/stress.md rule 5)",
        ));
    }
    if s.grains < 8 {
        return Err(ctx.bad("sample.grains", s.grains, "must be >= 8"));
    }
    let diameter = positive(ctx, "sample.diameter", s.diameter)?;
    let density = positive(ctx, "sample.density", s.density)?;
    let solid_fraction = positive(ctx, "sample.solid_fraction", s.solid_fraction)?;
    if s.seeds.is_empty() {
        return Err(ctx.bad("sample.seeds", "[]", "give at least one seed"));
    }
    for (k, a) in s.seeds.iter().enumerate() {
        if s.seeds[..k].contains(a) {
            return Err(ctx.bad(format!("sample.seeds[{k}]"), a, "seeds must differ"));
        }
    }
    Ok(Sample {
        grain_type,
        wall_type,
        diameter,
        density,
        solid_fraction,
    })
}

/// `[servo]`: LIGGGHTS' gains must be >= 0 and not all zero (a servo that does not
/// move), and a positive speed limit (checked against the skin with the time step).
fn servo(ctx: &super::error::Ctx, g: ServoGains) -> Result<ServoGains, CaseError> {
    for (f, v) in [("servo.kp", g.kp), ("servo.ki", g.ki), ("servo.kd", g.kd)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(ctx.bad(f, v, "must be >= 0 (LIGGGHTS: kp, ki, kd >= 0)"));
        }
    }
    if g.kp == 0.0 && g.ki == 0.0 && g.kd == 0.0 {
        return Err(ctx.bad(
            "servo.kp",
            0.0,
            "kp, ki and kd are all zero: the servo would not move",
        ));
    }
    positive(ctx, "servo.vel_max", g.vel_max)?;
    Ok(g)
}

/// `[compaction]`, validated (the check interval is taken as written).
struct Compaction {
    stress_tolerance: f64,
    ke_factor: f64,
    max_time: f64,
}

/// `[compaction]`: the criterion (wall stresses within a fraction below 1 of sigma_c,
/// kinetic energy), its time limit and check interval.
fn compaction(ctx: &super::error::Ctx, c: &RawCompaction) -> Result<Compaction, CaseError> {
    let stress_tolerance = positive(ctx, "compaction.stress_tolerance", c.stress_tolerance)?;
    if stress_tolerance >= 1.0 {
        return Err(ctx.bad(
            "compaction.stress_tolerance",
            stress_tolerance,
            "must be below 1 (a fraction of sigma_c)",
        ));
    }
    let ke_factor = positive(ctx, "compaction.ke_factor", c.ke_factor)?;
    let max_time = positive(ctx, "compaction.max_time", c.max_time)?;
    if c.check_every == 0 {
        return Err(ctx.bad("compaction.check_every", 0, "must be >= 1"));
    }
    Ok(Compaction {
        stress_tolerance,
        ke_factor,
        max_time,
    })
}

/// `[shear]`: distinct positive confining pressures, the strain rate, a final strain
/// that keeps the z_hi wall off the floor's grains, and the output interval. Returns
/// (strain rate, final strain).
fn shear(ctx: &super::error::Ctx, sh: &RawShear) -> Result<(f64, f64), CaseError> {
    if sh.confining_pressures.is_empty() {
        return Err(ctx.bad(
            "shear.confining_pressures",
            "[]",
            "give at least one pressure",
        ));
    }
    for (k, p) in sh.confining_pressures.iter().enumerate() {
        positive(ctx, &format!("shear.confining_pressures[{k}]"), *p)?;
        if sh.confining_pressures[..k].contains(p) {
            return Err(ctx.bad(
                format!("shear.confining_pressures[{k}]"),
                p,
                "pressures must differ",
            ));
        }
    }
    let strain_rate = positive(ctx, "shear.strain_rate", sh.strain_rate)?;
    let final_strain = positive(ctx, "shear.final_strain", sh.final_strain)?;
    if final_strain >= 0.9 {
        return Err(ctx.bad(
            "shear.final_strain",
            final_strain,
            "must be below 0.9 (the z_hi wall would reach the grains of the floor)",
        ));
    }
    if sh.output_every == 0 {
        return Err(ctx.bad("shear.output_every", 0, "must be >= 1"));
    }
    Ok((strain_rate, final_strain))
}

/// `[analysis]`: the peak window and the critical-state window within the shear (up to
/// `final_strain`), the blocks no wider than the latter. Returns (peak window, block).
fn analysis_windows(
    ctx: &super::error::Ctx,
    a: &Analysis,
    final_strain: f64,
) -> Result<(f64, f64), CaseError> {
    let peak_window = positive(ctx, "analysis.peak_window", a.peak_window)?;
    let block = positive(ctx, "analysis.block", a.block)?;
    let [c0, c1] = a.critical_state;
    if !(c0.is_finite() && c0 >= 0.0 && c1 > c0 && c1 <= final_strain + 1e-12) {
        return Err(ctx.bad(
            "analysis.critical_state",
            a.critical_state,
            format!("need 0 <= from < to <= shear.final_strain ({final_strain})"),
        ));
    }
    if block > c1 - c0 {
        return Err(ctx.bad(
            "analysis.block",
            block,
            "wider than the critical-state window",
        ));
    }
    if peak_window > final_strain {
        return Err(ctx.bad(
            "analysis.peak_window",
            peak_window,
            "wider than the whole shear",
        ));
    }
    Ok((peak_window, block))
}

/// `[simulation]`: the time step against the grains' Rayleigh time (material `mat`), the
/// skin (default a quarter diameter), and the servo's speed limit `vel_max` below what
/// LIGGGHTS accepts for them. Returns (dt, Rayleigh time, skin).
fn timing(
    ctx: &super::error::Ctx,
    s: &Sim,
    mat: &Material,
    sample: &Sample,
    vel_max: f64,
) -> Result<(f64, f64, f64), CaseError> {
    let diameter = sample.diameter;
    let rayleigh = super::rayleigh_time(
        0.5 * diameter,
        sample.density,
        mat.shear_modulus,
        mat.poisson_ratio,
    );
    let dt = positive(ctx, "simulation.dt", s.dt)?;
    if dt > rayleigh {
        return Err(ctx.bad("simulation.dt", dt, format!("exceeds the Rayleigh time {rayleigh:.3e} s of the grains; use <= 20% of it ({:.3e} s)", 0.2 * rayleigh)));
    }
    let neighbor_skin = match s.neighbor_skin {
        Some(v) => positive(ctx, "simulation.neighbor_skin", v)?,
        None => 0.25 * diameter,
    };
    if vel_max >= neighbor_skin / (2.0 * dt) {
        return Err(ctx.bad(
            "servo.vel_max",
            vel_max,
            format!("must be below skin / (2 dt) = {:.4e} m/s (LIGGGHTS refuses it otherwise: a wall may not cross half the skin in one step)", neighbor_skin / (2.0 * dt)),
        ));
    }
    Ok((dt, rayleigh, neighbor_skin))
}

/// The starting lattice must hold its grains apart: a cubic lattice of the case's box at
/// its solid fraction, spaced wider than a grain.
fn lattice_fits(ctx: &super::error::Ctx, case: &TriaxialCase) -> Result<(), CaseError> {
    let (side, n) = case.lattice_box();
    let spacing = side / n as f64;
    if spacing <= case.diameter {
        return Err(ctx.bad(
            "sample.solid_fraction",
            case.solid_fraction,
            format!(
                "too dense for a cubic lattice of {n}^3 sites: spacing {spacing:.4e} m <= diameter"
            ),
        ));
    }
    Ok(())
}

super::validated_case!(TriaxialCase);

#[cfg(test)]
mod tests {
    use super::*;

    /// Rule 5 measures the CI case's Table 2 material: the grains' material, their pair
    /// values, density, diameter, time step and rolling model must stay equal to
    /// cases/penetration/ci.toml's.
    #[test]
    fn the_release_case_has_the_ci_grain_material() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let t = TriaxialCase::load(&root.join("cases/release/triaxial-table2.toml")).unwrap();
        let c = crate::case::penetration::PenetrationCase::load(
            &root.join("cases/penetration/ci.toml"),
        )
        .unwrap();
        let (mt, mc) = (&t.materials[t.grain_type], &c.materials[c.grain_type]);
        assert_eq!(mt.youngs_modulus, mc.youngs_modulus);
        assert_eq!(mt.shear_modulus, mc.shear_modulus);
        assert_eq!(mt.poisson_ratio, mc.poisson_ratio);
        let (kt, kc) = (
            t.pairs.idx(t.grain_type, t.grain_type),
            c.pairs.idx(c.grain_type, c.grain_type),
        );
        assert_eq!(t.pairs.restitution[kt], c.pairs.restitution[kc]);
        assert_eq!(t.pairs.friction[kt], c.pairs.friction[kc]);
        assert_eq!(t.pairs.rolling_friction[kt], c.pairs.rolling_friction[kc]);
        assert_eq!(t.density, c.density);
        assert_eq!(t.diameter, c.diameter.mean());
        assert_eq!(t.diameter, c.diameter.max());
        assert_eq!(t.dt, c.dt);
        assert_eq!(t.rolling, c.rolling);
        // The walls: frictionless, no rolling friction, e = 0.8, the grains' G and nu.
        let kw = t.pairs.idx(t.grain_type, t.wall_type);
        assert_eq!(t.pairs.friction[kw], 0.0);
        assert_eq!(t.pairs.rolling_friction[kw], 0.0);
        assert_eq!(t.pairs.restitution[kw], 0.8);
        let mw = &t.materials[t.wall_type];
        assert_eq!(
            (mw.shear_modulus, mw.poisson_ratio),
            (mc.shear_modulus, mc.poisson_ratio)
        );
        // The registered protocol.
        assert_eq!(t.grains, 8000);
        assert_eq!(t.solid_fraction, 0.30);
        assert_eq!(t.seeds, vec![20261500, 20261501]);
        assert_eq!(t.confining_pressures, vec![1000.0, 4000.0]);
        assert_eq!((t.strain_rate, t.final_strain), (0.158, 0.30));
        assert_eq!(t.critical_state, [0.20, 0.30]);
        assert_eq!((t.peak_window, t.block), (0.01, 0.01));
        assert_eq!((t.stress_tolerance, t.ke_factor), (0.01, 1e-8));
        assert_eq!(t.tolerances.phi_abs_deg, 1.5);
        assert_eq!(t.output_every, 100);
    }

    #[test]
    fn bad_fields_are_named() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let p = root.join("cases/release/triaxial-table2.toml");
        let text = std::fs::read_to_string(&p).unwrap();
        for (from, to, field) in [
            ("vel_max = 0.05", "vel_max = 9.0", "servo.vel_max"),
            (
                "solid_fraction = 0.30",
                "solid_fraction = 0.6",
                "sample.solid_fraction",
            ),
            (
                "confining_pressures = [1000.0, 4000.0]",
                "confining_pressures = [1000.0, -4.0]",
                "shear.confining_pressures[1]",
            ),
            (
                "critical_state = [0.20, 0.30]",
                "critical_state = [0.30, 0.20]",
                "analysis.critical_state",
            ),
        ] {
            assert!(text.contains(from), "{from}");
            let e = TriaxialCase::from_toml_str(&text.replace(from, to), &p)
                .unwrap_err()
                .to_string();
            assert!(
                e.contains(field) && e.contains("triaxial-table2.toml"),
                "{e}"
            );
        }
        let e = TriaxialCase::from_toml_str(&text.replace("[shear]", "[shear]\nspeed = 1.0"), &p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("speed"), "{e}");
    }
}
