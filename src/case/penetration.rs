//! Case kind `penetration`: quasi-static penetration of a flat-bottomed cylinder into a
//! poured and settled bed in a cylindrical container (Feng et al. Sec. 2, Tables 1-2,
//! Fig 1). Parsed and validated once; all SI.

use super::error::{CaseError, Ctx};
use super::validate::{finite, material_type, override_pairs, physics, positive};
use super::{ContactFamily, Gate, Material, NegativeControl, PairTable, RollingModel, schema};
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
    /// Pair values the intruder penetrates with, where they differ from those the bed
    /// was poured and settled with (Feng et al. Sec. 3 sweep one parameter at a fixed
    /// packing; here the packing is the very same bed).
    #[serde(default)]
    penetration_interactions: Vec<schema::Interaction>,
    container: Container,
    bed: Bed,
    preparation: Preparation,
    intruder: Intruder,
    analysis: Analysis,
    #[serde(default)]
    compare: Option<Tolerances>,
    #[serde(default)]
    ensemble: Option<Ensemble>,
    #[serde(default)]
    quasi_static: Option<QuasiStatic>,
    #[serde(default)]
    published: Option<Published>,
    #[serde(default)]
    published_phi: Option<PublishedPhi>,
    #[serde(default)]
    negative_control: Vec<super::control::RawControl>,
    /// Non-spherical grains (Feng et al. Sec. 3 (f), Fig 3(f)): the one rigid
    /// multisphere template `[bed] clump_template` names, as in micro cases.
    #[serde(default)]
    clump_templates: Vec<super::clumps::RawTemplate>,
}

/// Realisations: granular penetration is chaotic, so one bed gives K_phi only to about
/// +-15 % at CI scale (measured); the engines are compared on ensemble means.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Ensemble {
    /// Number of independent beds; bed k is drawn with seed `bed.seed + k`.
    beds: usize,
}

/// Sec. 3's quasi-static test: the native run repeated at a second speed.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct QuasiStatic {
    /// Second driving speed (m/s); K_phi at it must match K_phi at `intruder.speed`.
    speed: f64,
}

/// A published steady-state slope to check a run against (e.g. Table 3).
#[derive(Debug, Clone, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Published {
    pub k_phi: f64,
    /// Where the number comes from (table / figure / section).
    pub source: String,
}

/// A published internal friction angle to check the stress-field phi against (e.g.
/// Feng et al.'s frictionless spheres, phi = 9 +- 1 deg): |phi - phi_deg| <= abs_deg for
/// both engines and both estimators (docs/stress.md, rule 1).
#[derive(Debug, Clone, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct PublishedPhi {
    pub phi_deg: f64,
    /// Tolerance in degrees.
    pub abs_deg: f64,
    /// Where the number comes from (table / figure / section).
    pub source: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Sim {
    /// Time step (s); must not exceed the Rayleigh time (Feng uses 20% of it).
    dt: f64,
    /// |g| in m/s^2, acting along -z.
    gravity: f64,
    neighbor_skin: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Container {
    diameter: f64,
    height: f64,
    /// Material type of floor and side wall (1-based).
    #[serde(rename = "type")]
    type_: usize,
}

/// Grain diameter distributions of the paper: constant (Table 2), Gaussian with
/// cut-offs (Table 4), uniform +- half width.
#[derive(Debug, Clone, Copy, Deserialize, serde::Serialize, PartialEq)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "snake_case")]
pub enum Diameter {
    Constant {
        value: f64,
    },
    Gaussian {
        mean: f64,
        std: f64,
        min: f64,
        max: f64,
    },
    Uniform {
        mean: f64,
        half_width: f64,
    },
}

impl Diameter {
    pub fn mean(&self) -> f64 {
        match *self {
            Diameter::Constant { value } => value,
            Diameter::Gaussian { mean, .. } | Diameter::Uniform { mean, .. } => mean,
        }
    }
    pub fn max(&self) -> f64 {
        match *self {
            Diameter::Constant { value } => value,
            Diameter::Gaussian { max, .. } => max,
            Diameter::Uniform { mean, half_width } => mean + half_width,
        }
    }
    pub fn min(&self) -> f64 {
        match *self {
            Diameter::Constant { value } => value,
            Diameter::Gaussian { min, .. } => min,
            Diameter::Uniform { mean, half_width } => mean - half_width,
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Bed {
    #[serde(rename = "type")]
    type_: usize,
    density: f64,
    diameter: Diameter,
    /// Number of grains (give `count` or `fill_height`).
    count: Option<usize>,
    /// Target settled bed height in m, converted to a count with `packing_guess`.
    fill_height: Option<f64>,
    #[serde(default = "default_packing_guess")]
    packing_guess: f64,
    seed: u64,
    /// Grains are rigid clumps of this `[[clump_templates]]` entry instead of spheres;
    /// `diameter` is then the members' diameter and `count` counts bodies.
    #[serde(default)]
    clump_template: Option<String>,
}

fn default_packing_guess() -> f64 {
    0.6
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Preparation {
    /// Settle until mean KE < this fraction of its value at the end of pouring (Sec. 2: 1e-7).
    settle_ke_ratio: f64,
    /// Give up (error) if not settled after this much simulated time (s).
    max_settle_time: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Intruder {
    diameter: f64,
    length: f64,
    #[serde(rename = "type")]
    type_: usize,
    /// Driving speed (m/s), downward.
    speed: f64,
    /// Gap between the intruder bottom and the bed surface at the start (m).
    start_gap: f64,
    /// Final depth of the bottom below the bed surface (m).
    final_depth: f64,
    /// Force output every this many steps.
    force_every: u64,
    /// LIGGGHTS' STL intruder: largest rim error of its inscribed polygon as a fraction
    /// of R (default 0.01, 24 segments). The native intruder is an exact cylinder.
    #[serde(default = "default_stl_rim_error")]
    stl_rim_error: f64,
}

fn default_stl_rim_error() -> f64 {
    0.01
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Analysis {
    /// Regime C, where p = K_phi h + p0 is fitted, starts here (h = depth / R).
    fit_h_min: f64,
    /// Width in h of the bins the force series is averaged into while it is read
    /// (default 0.01): memory stays bounded however many samples a run writes.
    h_bin: Option<f64>,
    /// Depths h = depth / R of the contact snapshots for the stress fields (Feng et al. Fig 5);
    /// the final depth (steady state) is always added. Default: Fig. 5's
    /// [0.24, 0.373, 0.61, 1.0], those shallower than the final depth. An empty list
    /// keeps only the final depth.
    #[serde(default)]
    snapshot_h: Option<Vec<f64>>,
    /// Snapshots per requested depth, averaged in the intruder's frame (default 5; 1 =
    /// one instantaneous snapshot per depth).
    #[serde(default)]
    snapshot_window: Option<usize>,
    /// Intruder travel (in h = depth / R) each window spans, centred on its depth
    /// (default one mean grain diameter, d_mean / R).
    #[serde(default)]
    snapshot_window_h: Option<f64>,
    /// Where the K_phi fit ends: "open" (default: the final depth) or "rule3" (where
    /// the stagnant cone's tip comes within 3 d_g of the floor, docs/stress.md rule 3,
    /// with the bed-by-bed NOT COMPARED rule).
    #[serde(default)]
    k_phi_range: Option<String>,
    /// The gated phi estimator: "v1" (default: window-averaged, eqs 8-9) or "v2"
    /// (pooled regime C with bootstrap admission, docs/stress.md rule 2); the other one
    /// is reported beside it.
    #[serde(default)]
    phi_estimator: Option<String>,
}

/// Where the K_phi fit of regime C ends (docs/stress.md rule 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum KPhiRange {
    /// h >= fit_h_min to the end of the FDR; the gate without a standard-error rule.
    Open,
    /// Rule 3's self-consistent floor clearance, with the bed-by-bed NOT COMPARED rule.
    Rule3,
}

/// The phi estimator a case gates (docs/stress.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum PhiEstimator {
    V1,
    V2,
}

/// Default number of snapshots per time-averaging window.
pub(crate) const DEFAULT_SNAPSHOT_WINDOW: usize = 5;

/// One time-averaging window of contact snapshots around a requested depth.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SnapshotWindow {
    /// The requested depth (h = depth / R) the window belongs to.
    pub h_target: f64,
    /// Depths of the window's snapshots, ascending.
    pub h: Vec<f64>,
}

/// The windows of `n` snapshots spanning `span` (in h) around each of `centres`,
/// clipped to (0, `h_final`]: a window reaching past the final depth ends at `h_final`
/// (so the last window ends with the run's last step); a window reaching h <= 0 is cut
/// there and its snapshots spread evenly over (0, upper end]. Otherwise the snapshots
/// are evenly spaced from `h - span / 2` to `h + span / 2`, both ends included, so an
/// odd `n` has one at the requested depth itself. `n = 1` gives the requested depths.
pub fn snapshot_windows(centres: &[f64], h_final: f64, n: usize, span: f64) -> Vec<SnapshotWindow> {
    centres
        .iter()
        .map(|&c| {
            let h = if n <= 1 {
                vec![c]
            } else {
                let hi = (c + 0.5 * span).min(h_final);
                let lo = c - 0.5 * span;
                if lo > 0.0 {
                    (0..n)
                        .map(|j| {
                            if j + 1 == n {
                                hi
                            } else {
                                lo + (hi - lo) * j as f64 / (n - 1) as f64
                            }
                        })
                        .collect()
                } else {
                    (0..n).map(|j| hi * (j + 1) as f64 / n as f64).collect()
                }
            };
            SnapshotWindow { h_target: c, h }
        })
        .collect()
}

/// Fig. 5 of Feng et al.: the depths at which the paper shows velocity and gamma fields.
pub(crate) const DEFAULT_SNAPSHOT_H: [f64; 4] = [0.24, 0.373, 0.61, 1.0];

#[derive(Debug, Deserialize, Clone, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Tolerances {
    /// |K_native / K_ref - 1| (default 0.10).
    #[serde(default = "d_k")]
    pub k_phi_rel: f64,
    /// RMS(p_a - p_b) / mean p over regime C (default 0.15).
    #[serde(default = "d_fdr")]
    pub fdr_distance: f64,
    /// |h_A,a - h_A,b| and |h_B,a - h_B,b| (defaults 0.1 and 0.25, in units of R).
    #[serde(default = "d_ha")]
    pub h_a_abs: f64,
    #[serde(default = "d_hb")]
    pub h_b_abs: f64,
    /// |K(v2) / K(v1) - 1| of the native quasi-static test (default 0.10).
    #[serde(default = "d_k")]
    pub quasi_static_k_rel: f64,
    /// |K / K_published - 1| (default 0.10).
    #[serde(default = "d_k")]
    pub published_k_rel: f64,
    /// |phi_test - phi_ref| in degrees, phi from the stress fields (default 1.5).
    #[serde(default = "d_phi")]
    pub phi_abs_deg: f64,
    /// |K_phi / K(phi) - 1| of an engine's (phi, K_phi) point against the MALT curve
    /// (default 0.25).
    #[serde(default = "d_malt_k")]
    pub malt_k_rel: f64,
    /// |phi(K_phi) - phi| in degrees, the same distance measured along phi (default 1.5).
    #[serde(default = "d_phi")]
    pub malt_phi_abs_deg: f64,
    /// Minimum R^2 of the unified FDR fit, eqs 13-15 (default 0.98).
    #[serde(default = "d_r2")]
    pub unified_r2_min: f64,
}

fn d_phi() -> f64 {
    1.5
}
fn d_malt_k() -> f64 {
    0.25
}
fn d_r2() -> f64 {
    0.98
}

fn d_k() -> f64 {
    0.10
}
fn d_fdr() -> f64 {
    0.15
}
fn d_ha() -> f64 {
    0.1
}
fn d_hb() -> f64 {
    0.25
}

impl Default for Tolerances {
    fn default() -> Self {
        Tolerances {
            k_phi_rel: d_k(),
            fdr_distance: d_fdr(),
            h_a_abs: d_ha(),
            h_b_abs: d_hb(),
            quasi_static_k_rel: d_k(),
            published_k_rel: d_k(),
            phi_abs_deg: d_phi(),
            malt_k_rel: d_malt_k(),
            malt_phi_abs_deg: d_phi(),
            unified_r2_min: d_r2(),
        }
    }
}

/// A validated penetration case. Outside this crate it can only come from
/// [`PenetrationCase::load`] / `from_toml_str` (`non_exhaustive`), so every value a run
/// sees went through validation; the fields are public for reading.
#[derive(Debug, Clone, serde::Serialize)]
#[non_exhaustive]
pub struct PenetrationCase {
    pub name: String,
    pub description: String,
    pub source: PathBuf,
    pub dt: f64,
    pub gravity: f64,
    pub neighbor_skin: f64,
    pub rolling: RollingModel,
    /// `[models] family`: LIGGGHTS' laws (the default), or LAMMPS' `pair_style granular`
    /// laws, which the native engine runs as LAMMPS' deck does
    /// ([`crate::engines::native::lammps_penetration`]) and only LAMMPS can be the
    /// reference of (docs/lammps-laws.md, "The native engine with LAMMPS' laws in
    /// penetration").
    pub family: ContactFamily,
    pub materials: Vec<Material>,
    /// The pairs of the penetration (both engines).
    pub pairs: PairTable,
    /// The pairs the bed is prepared with, when `[[penetration_interactions]]` makes the
    /// penetration's differ; `None`: the same as `pairs`.
    pub settle_pairs: Option<PairTable>,
    pub container_radius: f64,
    pub container_height: f64,
    /// 0-based material types.
    pub wall_type: usize,
    pub grain_type: usize,
    pub intruder_type: usize,
    pub density: f64,
    /// Sphere diameter; for clump grains, the diameter of every member sphere.
    pub diameter: Diameter,
    /// Grains (spheres or clump bodies).
    pub count: usize,
    /// The clump template every grain is made of (Feng et al. Fig 3(f)); `None`: spheres.
    pub clump: Option<Box<super::clumps::ClumpTemplate>>,
    pub seed: u64,
    pub settle_ke_ratio: f64,
    pub max_settle_time: f64,
    pub intruder_radius: f64,
    pub intruder_length: f64,
    pub speed: f64,
    pub start_gap: f64,
    pub final_depth: f64,
    pub force_every: u64,
    /// Rim error of LIGGGHTS' STL polygon as a fraction of R.
    pub stl_rim_error: f64,
    pub fit_h_min: f64,
    pub h_bin: f64,
    /// Snapshot depths in units of R, ascending, the final depth last.
    pub snapshot_h: Vec<f64>,
    /// Snapshots per depth (time-averaging window), >= 1.
    pub snapshot_window: usize,
    /// Intruder travel (units of R) each window spans.
    pub snapshot_window_h: f64,
    pub tolerances: Tolerances,
    /// Independent beds (seeds `seed`, `seed + 1`, ...), at least 1.
    pub ensemble_beds: usize,
    pub quasi_static_speed: Option<f64>,
    pub published: Option<Published>,
    pub published_phi: Option<PublishedPhi>,
    pub rayleigh_time: f64,
    pub negative_controls: Vec<NegativeControl>,
    pub k_phi_range: KPhiRange,
    pub phi_estimator: PhiEstimator,
    /// Plausibility warnings of the file as written ([`super::plausible`]); not physics.
    #[serde(skip)]
    pub warnings: Vec<String>,
}

/// Gates a penetration comparison produces (what its negative controls may name).
pub(crate) const PENETRATION_GATES: &[Gate] = &[
    Gate::KPhi,
    Gate::FdrDistance,
    Gate::QuasiStatic,
    Gate::Published,
    Gate::Phi,
    Gate::MaltK,
    Gate::MaltPhi,
    Gate::UnifiedFit,
];

impl PenetrationCase {
    /// The time-averaging windows of the contact snapshots, one per `snapshot_h` entry.
    pub fn snapshot_windows(&self) -> Vec<SnapshotWindow> {
        snapshot_windows(
            &self.snapshot_h,
            self.final_depth / self.intruder_radius,
            self.snapshot_window,
            self.snapshot_window_h,
        )
    }

    /// What the runs of this case depend on, in a fixed form: the physics, bed and
    /// intruder protocol, not the name, description, analysis ranges, tolerances,
    /// published values or controls. A recorded reference is sealed to its sha256.
    ///
    /// The struct is destructured exhaustively: a new field does not compile until it is
    /// placed in the view or named below as not physics.
    pub fn canonical_hash(&self) -> crate::rundata::provenance::Sha256 {
        let PenetrationCase {
            dt,
            gravity,
            neighbor_skin,
            rolling,
            family,
            materials,
            pairs,
            settle_pairs,
            container_radius,
            container_height,
            wall_type,
            grain_type,
            intruder_type,
            density,
            diameter,
            count,
            clump,
            seed,
            settle_ke_ratio,
            max_settle_time,
            intruder_radius,
            intruder_length,
            speed,
            start_gap,
            final_depth,
            force_every,
            stl_rim_error,
            ensemble_beds,
            // Not physics: labels; the fit and binning of the force-depth relation; the
            // contact snapshots' depths and windows (what is written, not what is
            // computed); the quasi-static rerun's speed (a control of its own, judged
            // by its own gate); tolerances, published values and controls; the
            // estimator choices; and a time derived from the sealed materials.
            name: _,
            description: _,
            source: _,
            fit_h_min: _,
            h_bin: _,
            snapshot_h: _,
            snapshot_window: _,
            snapshot_window_h: _,
            tolerances: _,
            quasi_static_speed: _,
            published: _,
            published_phi: _,
            rayleigh_time: _,
            negative_controls: _,
            k_phi_range: _,
            phi_estimator: _,
            warnings: _,
        } = self;
        let mut view = serde_json::json!({
            "kind": "penetration",
            "dt": dt,
            "gravity": gravity,
            "neighbor_skin": neighbor_skin,
            "rolling": rolling,
            "materials": materials,
            "pairs": pairs,
            "container": [container_radius, container_height, wall_type],
            "grains": [grain_type, density, serde_json::to_value(diameter).unwrap_or_default(), count, seed],
            "preparation": [settle_ke_ratio, max_settle_time],
            "intruder": [intruder_type, intruder_radius, intruder_length, speed, start_gap, final_depth, *force_every as f64, stl_rim_error],
            "beds": ensemble_beds,
        });
        // Only when present, so the hashes (and seals) of cases without it are unchanged.
        if let (ContactFamily::Lammps(m), Some(o)) = (family, view.as_object_mut()) {
            o.insert("lammps".into(), serde_json::json!(m));
        }
        if let (Some(p), Some(o)) = (settle_pairs, view.as_object_mut()) {
            o.insert("settle_pairs".into(), serde_json::json!(p));
        }
        if let (Some(t), Some(o)) = (clump, view.as_object_mut()) {
            o.insert("clump".into(), serde_json::json!(t));
        }
        crate::rundata::provenance::Sha256::of(view.to_string().as_bytes())
    }

    /// LAMMPS' sub-model coefficients when the case is of the LAMMPS family.
    pub(crate) fn lammps(&self) -> Option<&super::LammpsModels> {
        match &self.family {
            ContactFamily::Lammps(m) => Some(m),
            ContactFamily::Liggghts => None,
        }
    }

    /// The case the bed is prepared with: the pairs of `[[interactions]]`, without the
    /// penetration's own.
    pub fn settling_case(&self) -> PenetrationCase {
        match &self.settle_pairs {
            Some(p) => PenetrationCase {
                pairs: p.clone(),
                settle_pairs: None,
                ..self.clone()
            },
            None => self.clone(),
        }
    }

    /// Bed `k` of the ensemble: the same case with seed `seed + k`.
    pub fn realisation(&self, k: usize) -> PenetrationCase {
        PenetrationCase {
            seed: self.seed.wrapping_add(k as u64),
            ..self.clone()
        }
    }

    pub fn load(path: &Path) -> Result<PenetrationCase, CaseError> {
        let text = super::read_case_file(path)?;
        Self::from_toml_str(&text, path)
    }

    pub fn from_toml_str(text: &str, path: &Path) -> Result<PenetrationCase, CaseError> {
        let (raw, ctx) =
            super::validate::parse_kind(text, path, "penetration", |r: &File| &r.case)?;
        let warnings = plausibility(&raw);
        let mut case = Self::validated(raw, ctx, path).map_err(|e| e.noting(&warnings))?;
        case.warnings = warnings;
        Ok(case)
    }

    /// Validates a parsed file one section at a time, in the order of the calls below;
    /// the first error found is the one reported.
    fn validated(raw: File, ctx: Ctx, path: &Path) -> Result<PenetrationCase, CaseError> {
        let (rolling, materials, bed_pairs) =
            physics(&ctx, &raw.models, &raw.materials, &raw.interactions, true)?;
        let n_types = materials.len();
        let family = penetration_family(&ctx, &raw, n_types)?;
        let (pairs, settle_pairs) = penetration_pairs(&ctx, &raw, bed_pairs)?;
        let wall_type = material_type(&ctx, "container.type", raw.container.type_, n_types)?;
        let grain_type = material_type(&ctx, "bed.type", raw.bed.type_, n_types)?;
        let intruder_type = material_type(&ctx, "intruder.type", raw.intruder.type_, n_types)?;
        let container_radius = 0.5 * positive(&ctx, "container.diameter", raw.container.diameter)?;
        let container_height = positive(&ctx, "container.height", raw.container.height)?;
        let grains = bed_grains(&ctx, &raw, n_types, &family)?;
        let count = bed_count(&ctx, &raw.bed, &grains, container_radius, container_height)?;
        let (settle_ke_ratio, max_settle_time) = preparation(&ctx, &raw.preparation)?;
        let intruder = intruder_params(&ctx, &raw.intruder, container_radius, grains.diameter)?;
        let time = timing(&ctx, &raw.simulation, &materials[grain_type], &grains)?;
        let fit_h_min = positive(&ctx, "analysis.fit_h_min", raw.analysis.fit_h_min)?;
        let tolerances = tolerances(&ctx, raw.compare)?;
        let fit = fit_options(&ctx, &raw.analysis, fit_h_min, &intruder)?;
        let ensemble_beds = ensemble_beds(&ctx, raw.ensemble)?;
        let quasi_static_speed = quasi_static_speed(&ctx, raw.quasi_static, intruder.speed)?;
        published(&ctx, raw.published.as_ref(), raw.published_phi.as_ref())?;
        if !(tolerances.unified_r2_min > 0.0 && tolerances.unified_r2_min < 1.0) {
            return Err(ctx.bad(
                "compare.unified_r2_min",
                tolerances.unified_r2_min,
                "must lie in (0, 1)",
            ));
        }
        let h_final = intruder.final_depth / intruder.radius;
        let snapshot_h = snapshot_depths(&ctx, raw.analysis.snapshot_h.as_deref(), h_final)?;
        let (snapshot_window, snapshot_window_h) = snapshot_spans(
            &ctx,
            &raw.analysis,
            &snapshot_h,
            grains.diameter.mean(),
            &intruder,
            time.dt,
        )?;
        let negative_controls =
            super::control::controls(&ctx, &raw.negative_control, n_types, PENETRATION_GATES)?;
        super::control::check_applicable(
            &ctx,
            &negative_controls,
            &super::control::Targets {
                spheres: Some((&pairs, &materials, rolling != super::RollingModel::None)),
                clumps: grains.clump.is_some(),
            },
        )?;
        Ok(PenetrationCase {
            negative_controls,
            family,
            name: raw.case.name,
            description: raw.case.description,
            source: path.to_path_buf(),
            dt: time.dt,
            gravity: time.gravity,
            neighbor_skin: time.neighbor_skin,
            rolling,
            materials,
            pairs,
            settle_pairs,
            container_radius,
            container_height,
            wall_type,
            grain_type,
            intruder_type,
            density: grains.density,
            diameter: grains.diameter,
            count,
            clump: grains.clump,
            seed: raw.bed.seed,
            settle_ke_ratio,
            max_settle_time,
            intruder_radius: intruder.radius,
            intruder_length: intruder.length,
            speed: intruder.speed,
            start_gap: intruder.start_gap,
            final_depth: intruder.final_depth,
            force_every: raw.intruder.force_every,
            stl_rim_error: intruder.stl_rim_error,
            fit_h_min,
            h_bin: fit.h_bin,
            snapshot_h,
            snapshot_window,
            snapshot_window_h,
            tolerances,
            ensemble_beds,
            quasi_static_speed,
            published: raw.published,
            published_phi: raw.published_phi,
            rayleigh_time: time.rayleigh,
            k_phi_range: fit.k_phi_range,
            phi_estimator: fit.phi_estimator,
            warnings: Vec::new(),
        })
    }
}

/// The pair table the intruder penetrates with and, when `[[penetration_interactions]]`
/// overrides some pairs, the table the bed was poured and settled with (Feng et al.
/// Sec. 3 sweep one parameter at a fixed packing; here the packing is the very same bed).
fn penetration_pairs(
    ctx: &Ctx,
    raw: &File,
    bed_pairs: PairTable,
) -> Result<(PairTable, Option<PairTable>), CaseError> {
    if raw.penetration_interactions.is_empty() {
        return Ok((bed_pairs, None));
    }
    let p = override_pairs(
        ctx,
        &bed_pairs,
        &raw.penetration_interactions,
        "penetration_interactions",
    )?;
    Ok((p, Some(bed_pairs)))
}

/// `[bed]`'s grains, validated: density, diameter distribution and, for a bed of
/// non-spherical grains, its clump template.
struct BedGrains {
    density: f64,
    diameter: Diameter,
    clump: Option<Box<super::clumps::ClumpTemplate>>,
}

/// `[bed]` density and diameter distribution (each of its parameters positive, the
/// Gaussian's mean between its cut-offs, the uniform one's half width below its mean),
/// and the clump template of a bed of non-spherical grains, which only LIGGGHTS' fix
/// multisphere runs.
fn bed_grains(
    ctx: &Ctx,
    raw: &File,
    n_types: usize,
    family: &ContactFamily,
) -> Result<BedGrains, CaseError> {
    let density = positive(ctx, "bed.density", raw.bed.density)?;
    let diameter = raw.bed.diameter;
    match diameter {
        Diameter::Constant { value } => {
            positive(ctx, "bed.diameter.value", value)?;
        }
        Diameter::Gaussian {
            mean,
            std,
            min,
            max,
        } => {
            positive(ctx, "bed.diameter.mean", mean)?;
            positive(ctx, "bed.diameter.std", std)?;
            positive(ctx, "bed.diameter.min", min)?;
            if !(min <= mean && mean <= max) {
                return Err(ctx.bad("bed.diameter", (min, mean, max), "need min <= mean <= max"));
            }
        }
        Diameter::Uniform { mean, half_width } => {
            positive(ctx, "bed.diameter.mean", mean)?;
            let hw = finite(ctx, "bed.diameter.half_width", half_width)?;
            if !(0.0..mean).contains(&hw) {
                return Err(ctx.bad("bed.diameter.half_width", hw, "must lie in [0, mean)"));
            }
        }
    }
    let clump = bed_clump(
        ctx,
        &raw.clump_templates,
        &raw.bed,
        n_types,
        density,
        diameter,
    )?;
    if clump.is_some() && *family != ContactFamily::Liggghts {
        return Err(ctx.bad(
            "models.family",
            "lammps",
            "a clump bed is LIGGGHTS' fix multisphere; the LAMMPS penetration deck takes sphere beds only",
        ));
    }
    Ok(BedGrains {
        density,
        diameter,
        clump,
    })
}

/// `[bed]` count, or the count that fills the container to `fill_height` at the solid
/// fraction `packing_guess` (spheres of the mean diameter, or clumps), a height below
/// the container's.
fn bed_count(
    ctx: &Ctx,
    bed: &Bed,
    grains: &BedGrains,
    container_radius: f64,
    container_height: f64,
) -> Result<usize, CaseError> {
    let packing_guess = bed.packing_guess;
    if !(packing_guess > 0.0 && packing_guess < 0.75) {
        return Err(ctx.bad("bed.packing_guess", packing_guess, "must lie in (0, 0.75)"));
    }
    match (bed.count, bed.fill_height) {
        (Some(n), None) if n > 0 => Ok(n),
        (Some(n), None) => Err(ctx.bad("bed.count", n, "must be >= 1")),
        (None, Some(h)) => {
            let h = positive(ctx, "bed.fill_height", h)?;
            if h >= container_height {
                return Err(ctx.bad(
                    "bed.fill_height",
                    h,
                    format!("the bed would overflow the container (container.height = {container_height:e} m)"),
                ));
            }
            let v_grain = match &grains.clump {
                Some(t) => t.volume,
                None => std::f64::consts::PI / 6.0 * grains.diameter.mean().powi(3),
            };
            Ok(
                (packing_guess * std::f64::consts::PI * container_radius.powi(2) * h / v_grain)
                    .round() as usize,
            )
        }
        (Some(_), Some(_)) => Err(ctx.bad(
            "bed.count",
            "both given",
            "give count or fill_height, not both",
        )),
        (None, None) => Err(ctx.bad("bed.count", "missing", "give count or fill_height")),
    }
}

/// `[preparation]`: the settling criterion (Sec. 2: mean KE below 1e-7 of its value at
/// the end of pouring) and the time after which settling gives up.
fn preparation(ctx: &Ctx, p: &Preparation) -> Result<(f64, f64), CaseError> {
    let settle_ke_ratio = positive(ctx, "preparation.settle_ke_ratio", p.settle_ke_ratio)?;
    let max_settle_time = positive(ctx, "preparation.max_settle_time", p.max_settle_time)?;
    Ok((settle_ke_ratio, max_settle_time))
}

/// `[intruder]`, validated (SI); its type and `force_every` are the file's.
struct IntruderParams {
    radius: f64,
    length: f64,
    speed: f64,
    start_gap: f64,
    final_depth: f64,
    stl_rim_error: f64,
}

/// `[intruder]`: its size, speed, start and final depth, force interval and the STL's
/// rim error; it must leave grains room to flow past it in the container (`diameter`
/// is the grains') and must not be buried at the final depth.
fn intruder_params(
    ctx: &Ctx,
    i: &Intruder,
    container_radius: f64,
    diameter: Diameter,
) -> Result<IntruderParams, CaseError> {
    let radius = 0.5 * positive(ctx, "intruder.diameter", i.diameter)?;
    let length = positive(ctx, "intruder.length", i.length)?;
    let speed = positive(ctx, "intruder.speed", i.speed)?;
    let start_gap = finite(ctx, "intruder.start_gap", i.start_gap)?;
    if start_gap < 0.0 {
        return Err(ctx.bad(
            "intruder.start_gap",
            start_gap,
            "must be >= 0 (the intruder starts above the bed)",
        ));
    }
    let final_depth = positive(ctx, "intruder.final_depth", i.final_depth)?;
    if i.force_every == 0 {
        return Err(ctx.bad("intruder.force_every", 0, "must be >= 1"));
    }
    let stl_rim_error = positive(ctx, "intruder.stl_rim_error", i.stl_rim_error)?;
    if stl_rim_error >= 0.1 {
        return Err(ctx.bad(
            "intruder.stl_rim_error",
            stl_rim_error,
            "must be below 0.1 (an STL that far inside the cylinder is not the same intruder)",
        ));
    }
    if radius >= container_radius {
        return Err(ctx.bad(
            "intruder.diameter",
            i.diameter,
            "must be smaller than the container diameter",
        ));
    }
    let gap = container_radius - radius;
    if gap < 2.0 * diameter.max() {
        return Err(ctx.bad(
            "intruder.diameter",
            i.diameter,
            format!(
                "leaves a gap of {gap:e} m to the container wall, less than two grain diameters ({:e} m): grains could not flow past the intruder",
                2.0 * diameter.max()
            ),
        ));
    }
    if final_depth >= length {
        return Err(ctx.bad(
            "intruder.final_depth",
            final_depth,
            "the intruder would be buried: must be < intruder.length",
        ));
    }
    Ok(IntruderParams {
        radius,
        length,
        speed,
        start_gap,
        final_depth,
        stl_rim_error,
    })
}

/// `[simulation]`, validated (SI), with the Rayleigh time of the smallest grain.
struct Timing {
    dt: f64,
    rayleigh: f64,
    gravity: f64,
    neighbor_skin: f64,
}

/// `[simulation]`: the time step against the Rayleigh time of the smallest grain of
/// material `mat` (Feng uses 20% of it), gravity, and the skin (default a quarter of the
/// smallest diameter).
fn timing(ctx: &Ctx, s: &Sim, mat: &Material, grains: &BedGrains) -> Result<Timing, CaseError> {
    let diameter = grains.diameter;
    let rayleigh = super::rayleigh_time(
        0.5 * diameter.min(),
        grains.density,
        mat.shear_modulus,
        mat.poisson_ratio,
    );
    let dt = positive(ctx, "simulation.dt", s.dt)?;
    if dt > rayleigh {
        return Err(ctx.bad("simulation.dt", dt, format!("exceeds the Rayleigh time {rayleigh:.3e} s of the smallest grain; use <= 20% of it ({:.3e} s)", 0.2 * rayleigh)));
    }
    let gravity = positive(ctx, "simulation.gravity", s.gravity)?;
    let neighbor_skin = match s.neighbor_skin {
        Some(skin) => positive(ctx, "simulation.neighbor_skin", skin)?,
        None => 0.25 * diameter.min(),
    };
    Ok(Timing {
        dt,
        rayleigh,
        gravity,
        neighbor_skin,
    })
}

/// `[compare]` (defaults where absent): every tolerance positive. The unified fit's
/// R^2 floor, a fraction in (0, 1), is checked after the published values.
fn tolerances(ctx: &Ctx, compare: Option<Tolerances>) -> Result<Tolerances, CaseError> {
    let tolerances = compare.unwrap_or_default();
    for (f, v) in [
        ("compare.k_phi_rel", tolerances.k_phi_rel),
        ("compare.fdr_distance", tolerances.fdr_distance),
        ("compare.h_a_abs", tolerances.h_a_abs),
        ("compare.h_b_abs", tolerances.h_b_abs),
        ("compare.quasi_static_k_rel", tolerances.quasi_static_k_rel),
        ("compare.published_k_rel", tolerances.published_k_rel),
        ("compare.phi_abs_deg", tolerances.phi_abs_deg),
        ("compare.malt_k_rel", tolerances.malt_k_rel),
        ("compare.malt_phi_abs_deg", tolerances.malt_phi_abs_deg),
    ] {
        positive(ctx, f, v)?;
    }
    Ok(tolerances)
}

/// `[analysis]`'s choices of fit, validated.
struct FitOptions {
    k_phi_range: KPhiRange,
    phi_estimator: PhiEstimator,
    h_bin: f64,
}

/// `[analysis]`: where the K_phi fit ends (docs/stress.md rule 3), the gated phi
/// estimator (rule 2), and the width of the force bins, fine enough that regime C (from
/// `fit_h_min` to the final depth) holds at least 10 of them.
fn fit_options(
    ctx: &Ctx,
    a: &Analysis,
    fit_h_min: f64,
    intruder: &IntruderParams,
) -> Result<FitOptions, CaseError> {
    let k_phi_range = match a.k_phi_range.as_deref() {
        None | Some("open") => KPhiRange::Open,
        Some("rule3") => KPhiRange::Rule3,
        Some(o) => {
            return Err(ctx.bad("analysis.k_phi_range", o, "must be \"open\" or \"rule3\""));
        }
    };
    let phi_estimator = match a.phi_estimator.as_deref() {
        None | Some("v1") => PhiEstimator::V1,
        Some("v2") => PhiEstimator::V2,
        Some(o) => {
            return Err(ctx.bad("analysis.phi_estimator", o, "must be \"v1\" or \"v2\""));
        }
    };
    let h_bin = match a.h_bin {
        Some(b) => positive(ctx, "analysis.h_bin", b)?,
        None => 0.01,
    };
    if h_bin > 0.1 * fit_h_min.max(intruder.final_depth / intruder.radius - fit_h_min) {
        return Err(ctx.bad(
            "analysis.h_bin",
            h_bin,
            "too coarse: regime C would hold fewer than 10 bins",
        ));
    }
    Ok(FitOptions {
        k_phi_range,
        phi_estimator,
        h_bin,
    })
}

/// `[ensemble] beds` (default 1): granular penetration is chaotic, so the engines are
/// compared on ensemble means of at least one bed.
fn ensemble_beds(ctx: &Ctx, e: Option<Ensemble>) -> Result<usize, CaseError> {
    match e {
        Some(Ensemble { beds: 0 }) => Err(ctx.bad("ensemble.beds", 0, "must be >= 1")),
        Some(e) => Ok(e.beds),
        None => Ok(1),
    }
}

/// `[quasi_static] speed`: Sec. 3's quasi-static test needs a second speed, other than
/// the intruder's `speed`.
fn quasi_static_speed(
    ctx: &Ctx,
    q: Option<QuasiStatic>,
    speed: f64,
) -> Result<Option<f64>, CaseError> {
    let Some(q) = q else {
        return Ok(None);
    };
    let v = positive(ctx, "quasi_static.speed", q.speed)?;
    if v == speed {
        return Err(ctx.bad(
            "quasi_static.speed",
            v,
            "equals intruder.speed: the test needs a second speed",
        ));
    }
    Ok(Some(v))
}

/// `[published]` and `[published_phi]`: a published K_phi (e.g. Table 3) and phi, each
/// citing its table or figure; phi within the MALT domain (0, 60) deg.
fn published(
    ctx: &Ctx,
    published: Option<&Published>,
    published_phi: Option<&PublishedPhi>,
) -> Result<(), CaseError> {
    if let Some(p) = published {
        positive(ctx, "published.k_phi", p.k_phi)?;
        if p.source.trim().is_empty() {
            return Err(ctx.bad("published.source", &p.source, "cite the table or figure"));
        }
    }
    if let Some(p) = published_phi {
        if !(p.phi_deg.is_finite() && p.phi_deg > 0.0 && p.phi_deg < 60.0) {
            return Err(ctx.bad(
                "published_phi.phi_deg",
                p.phi_deg,
                "must lie in (0, 60) deg (the MALT domain)",
            ));
        }
        positive(ctx, "published_phi.abs_deg", p.abs_deg)?;
        if p.source.trim().is_empty() {
            return Err(ctx.bad(
                "published_phi.source",
                &p.source,
                "cite the table or figure",
            ));
        }
    }
    Ok(())
}

/// `[analysis] snapshot_h`, ending with the final depth `h_final`: the requested depths
/// of the contact snapshots (Feng et al. Fig 5), each inside the travel and strictly
/// ascending.
fn snapshot_depths(ctx: &Ctx, list: Option<&[f64]>, h_final: f64) -> Result<Vec<f64>, CaseError> {
    // The default list is cut at the final depth (a shallow case keeps loading); an
    // explicit list is validated entry by entry.
    let requested: Vec<f64> = match list {
        Some(list) => list.to_vec(),
        None => DEFAULT_SNAPSHOT_H
            .iter()
            .copied()
            .filter(|&h| h < h_final)
            .collect(),
    };
    let mut snapshot_h = Vec::new();
    for (k, &h) in requested.iter().enumerate() {
        let field = format!("analysis.snapshot_h[{k}]");
        if !(h.is_finite() && h > 0.0 && h < h_final) {
            return Err(ctx.bad(
                &field,
                h,
                format!(
                    "must lie in (0, {h_final:.4}) (depth / R; the final depth {h_final:.4} is always added)"
                ),
            ));
        }
        if snapshot_h.last().is_some_and(|&p| h <= p) {
            return Err(ctx.bad(&field, h, "snapshot depths must be strictly ascending"));
        }
        snapshot_h.push(h);
    }
    snapshot_h.push(h_final);
    Ok(snapshot_h)
}

/// `[analysis] snapshot_window` and `snapshot_window_h`: snapshots per depth and the
/// travel each window spans (default one mean grain diameter `d_mean`), shorter than the
/// whole travel, with at least one time step `dt` of travel between its snapshots.
fn snapshot_spans(
    ctx: &Ctx,
    a: &Analysis,
    snapshot_h: &[f64],
    d_mean: f64,
    intruder: &IntruderParams,
    dt: f64,
) -> Result<(usize, f64), CaseError> {
    let h_final = intruder.final_depth / intruder.radius;
    let snapshot_window = match a.snapshot_window {
        Some(0) => {
            return Err(ctx.bad(
                "analysis.snapshot_window",
                0,
                "must be >= 1 (snapshots per depth; 1 = no time averaging)",
            ));
        }
        Some(n) => n,
        None => DEFAULT_SNAPSHOT_WINDOW,
    };
    let (snapshot_window_h, span_origin) = match a.snapshot_window_h {
        Some(w) => (positive(ctx, "analysis.snapshot_window_h", w)?, ""),
        None => (d_mean / intruder.radius, " (the default, d_mean / R)"),
    };
    if snapshot_window_h >= h_final {
        return Err(ctx.bad(
            "analysis.snapshot_window_h",
            snapshot_window_h,
            format!(
                "must be shorter than the whole travel h_final = {h_final:.4}{span_origin}: a window would average over the entire penetration"
            ),
        ));
    }
    // Distinct snapshots need at least one time step of travel between them.
    let travel_per_step = intruder.speed * dt / intruder.radius;
    for w in snapshot_windows(snapshot_h, h_final, snapshot_window, snapshot_window_h) {
        let gap =
            w.h.windows(2)
                .map(|p| p[1] - p[0])
                .fold(f64::INFINITY, f64::min);
        if gap < travel_per_step {
            return Err(ctx.bad(
                "analysis.snapshot_window",
                snapshot_window,
                format!(
                    "the window around h = {:.4} spaces its snapshots {gap:.3e} R apart, less than one time step of travel ({travel_per_step:.3e} R); use fewer snapshots or a wider analysis.snapshot_window_h (now {snapshot_window_h:.4}{span_origin})",
                    w.h_target
                ),
            ));
        }
    }
    Ok((snapshot_window, snapshot_window_h))
}

/// Plausibility warnings of a penetration case as written ([`super::plausible`]).
fn plausibility(raw: &File) -> Vec<String> {
    use super::plausible::{density, materials, size, templates};
    let mut w = materials(&raw.materials);
    w.extend(density("bed.density", raw.bed.density));
    let d = match raw.bed.diameter {
        Diameter::Constant { value } => ("bed.diameter.value", value),
        Diameter::Gaussian { mean, .. } | Diameter::Uniform { mean, .. } => {
            ("bed.diameter.mean", mean)
        }
    };
    w.extend(size(d.0, d.1));
    w.extend(size("intruder.diameter", raw.intruder.diameter));
    w.extend(templates(&raw.clump_templates));
    w
}

/// `[models] family` of a penetration case. The LAMMPS family takes the micro cases'
/// keywords (`hertz/material`, `mindlin` with `tangential_damping` xt), without rolling
/// resistance: the LAMMPS penetration deck writes none (`rolling sds` would need a
/// per-pair stiffness and damping that deck does not carry).
fn penetration_family(ctx: &Ctx, raw: &File, n_types: usize) -> Result<ContactFamily, CaseError> {
    if !super::family::is_lammps(ctx, &raw.models)? {
        return Ok(ContactFamily::Liggghts);
    }
    if raw.models.rolling != "none" {
        return Err(ctx.bad(
            "models.rolling",
            &raw.models.rolling,
            "a LAMMPS-family penetration case has no rolling resistance (\"none\"): the LAMMPS penetration deck writes none",
        ));
    }
    let m = super::family::lammps_models(
        ctx,
        &raw.models,
        &raw.interactions,
        n_types,
        &[],
        &[],
        false,
    )?;
    Ok(ContactFamily::Lammps(m))
}

/// The clump template of a bed of non-spherical grains, checked against `[bed]`: the
/// template is the grain, so its material type and density must be the bed's and its
/// members must all have the bed's (constant) diameter, which the case uses for the
/// Rayleigh time, the skin and the scales of the analysis.
fn bed_clump(
    ctx: &Ctx,
    raw: &[super::clumps::RawTemplate],
    bed: &Bed,
    n_types: usize,
    density: f64,
    diameter: Diameter,
) -> Result<Option<Box<super::clumps::ClumpTemplate>>, CaseError> {
    let Some(name) = &bed.clump_template else {
        if !raw.is_empty() {
            return Err(ctx.bad(
                "clump_templates",
                raw.len(),
                "templates are defined but [bed] clump_template names none: the grains would be spheres",
            ));
        }
        return Ok(None);
    };
    let templates = super::clumps::templates(ctx, raw, n_types)?;
    if templates.len() != 1 || &templates[0].name != name {
        return Err(ctx.bad(
            "bed.clump_template",
            name,
            format!(
                "must name the one [[clump_templates]] entry of the case; defined: {:?}",
                templates.iter().map(|t| &t.name).collect::<Vec<_>>()
            ),
        ));
    }
    let t = templates.into_iter().next().expect("one template");
    if t.type_ != bed.type_.wrapping_sub(1) {
        return Err(ctx.bad(
            "clump_templates[0].type",
            t.type_ + 1,
            format!("must be the bed's material type {}", bed.type_),
        ));
    }
    if t.density != density {
        return Err(ctx.bad(
            "clump_templates[0].density",
            t.density,
            format!("must be the bed's density {density:e} kg/m^3"),
        ));
    }
    let Diameter::Constant { value } = diameter else {
        return Err(ctx.bad(
            "bed.diameter",
            "a distribution",
            "a bed of clumps takes a constant diameter (that of every member sphere)",
        ));
    };
    if let Some(k) = t.radii.iter().position(|&r| r != 0.5 * value) {
        return Err(ctx.bad(
            format!("clump_templates[0].spheres[{k}].radius"),
            t.radii[k],
            format!(
                "must be half the bed's diameter ({:e} m): every member is one grain sphere",
                0.5 * value
            ),
        ));
    }
    Ok(Some(Box::new(t)))
}

super::validated_case!(PenetrationCase);
