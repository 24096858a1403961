//! Case kind `impact2d`: a disk or elliptical intruder hitting a 2D bed of disks
//! (Kondic et al., K Sec. II-III). Case files are written in K's units and converted
//! to SI once, here:
//!
//! - length `d` = mean grain diameter (`units.d`, m),
//! - mass `m` = mass of a grain of diameter d (`units.mass`, kg); grains are disks of
//!   uniform areal density `m / (pi d^2/4)`, so a grain of diameter d' has mass m (d'/d)^2,
//! - `g0` = the gravity that defines the stiffness scale (`units.g`, m/s^2),
//! - stiffness: the dimensionless `k_n` means `k = k_n m g0 / d` (N/m),
//! - time: `tau_c = pi sqrt(d / (2 g0 k_n))` (K's binary collision time, for the grains'
//!   k_n), velocities in d / tau_c,
//! - damping: `gamma_n = -2 ln(e_n) / tau_c(k_n of the pair)`, `gamma_t = gamma_n / 2`,
//! - friction models: `static` = K's model 1 (k_t = 0.8 k_n), `kinetic` = model 2 (k_t = 0).
//!
//! Gravity can differ from g0 (`simulation.gravity`, in units of g0): K Sec. III B
//! changes only the gravitational force, never the stiffness.
//!
//! Coefficients of a type pair come from the "more special" partner: a wall disk's
//! (K: mu 0.9, e_n 0.1) for anything touching a wall, else the intruder's for
//! grain-intruder contacts, else the grains'.
//!
//! A case may declare a one-parameter `[sweep]`; each value is one run (variant) from
//! the same prepared bed (the `packing` and `bed` sweeps prepare one bed per distinct
//! bed: packing, count, length and seed), and an optional `[claim]` turns the variants'
//! final depths into one of K's claims. `[bed] seeds` makes a seed ensemble: every
//! variant once per seed, the claims judged on the per-value means over the seeds.

use super::error::{CaseError, Ctx};
use super::validate::{finite, positive};
use serde::Deserialize;
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    case: super::schema::Meta,
    units: Units,
    simulation: Sim,
    grains: MaterialIn,
    walls: Walls,
    bed: BedIn,
    intruder: IntruderIn,
    analysis: AnalysisIn,
    #[serde(default)]
    sweep: Option<SweepIn>,
    /// `[claim]` (one) or `[[claim]]` (several).
    #[serde(default)]
    /// Kept as TOML until validation: serde's untagged one-or-many would hide which
    /// field of which claim is wrong behind "did not match any variant".
    claim: Option<toml::Value>,
    #[serde(default)]
    compare: Option<Tolerances>,
    #[serde(default)]
    fields: Option<FieldsIn>,
    #[serde(default)]
    negative_control: Vec<super::control::RawControl>,
}

/// `[fields]`: snapshots of the bed during the impact (K Sec. IV), in tau_c after release.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FieldsIn {
    /// Contact-force snapshots for B0 of the force networks (K Figs 22-23).
    #[serde(default)]
    network_times: Vec<f64>,
    /// B0 thresholds from 0 to this, in units of the mean per-grain normal force.
    threshold_max: Option<f64>,
    threshold_step: Option<f64>,
    /// Affine field and D2_min (K Figs 24-27, eqs 3-4) at this time, from the positions
    /// at `affine_time - affine_dt` and `affine_time`, neighbours within `affine_radius` d.
    affine_time: Option<f64>,
    affine_dt: Option<f64>,
    affine_radius: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Units {
    /// Mean grain diameter d (m). K: 4 mm (photoelastic disks).
    d: f64,
    /// Mass of a grain of diameter d (kg).
    mass: f64,
    /// g0 (m/s^2) in k = k_n m g0 / d and tau_c.
    g: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Sim {
    /// Time step in tau_c.
    dt: f64,
    /// Simulated time after the release of the intruder, in tau_c.
    duration: f64,
    /// Intruder output every this many steps.
    output_every: u64,
    /// Energy output (full snapshot in LAMMPS) every this many steps.
    energy_every: u64,
    /// Gravity in units of units.g.
    gravity: f64,
    /// Verlet skin in d (cost only, not physics).
    skin: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Friction {
    /// K's model 1: k_t = 0.8 k_n, tangential spring with history.
    Static,
    /// K's model 2: k_t = 0, viscous tangential force capped at mu |F_n|.
    Kinetic,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialIn {
    k_n: f64,
    e_n: f64,
    mu: f64,
    friction: Friction,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Walls {
    e_n: f64,
    mu: f64,
    /// Default: the grains' model.
    friction: Option<Friction>,
    /// Default: the grains' k_n.
    k_n: Option<f64>,
    /// Wall disk diameter in d.
    diameter: f64,
    /// Height of the top wall above the release position of the intruder's top, in d.
    top_gap: f64,
    /// During the impact (not while the bed settles) the wall disks interact with the
    /// grains' coefficients: one LAMMPS pair style, which `compute pair/local` needs.
    #[serde(default)]
    impact_as_grains: bool,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BedIn {
    packing: Packing,
    count: usize,
    /// Periodic length L in d.
    length: f64,
    /// r: diameters uniform in d (1 +- r) (random packing only).
    #[serde(default)]
    polydispersity: f64,
    /// One bed: its seed. Or `seeds`, never both.
    #[serde(default)]
    seed: Option<u64>,
    /// A seed ensemble: every variant runs once on the bed of each seed (at least 2,
    /// all different); claims are judged on the per-value means (docs/impact2d.md).
    #[serde(default)]
    seeds: Option<Vec<toml::Value>>,
    /// Random initial velocity components uniform in +- this, in d / tau_c.
    #[serde(default)]
    initial_speed: f64,
    /// Settled when the total kinetic energy < this, in m g0 d (K: 1e-10).
    settle_ke: f64,
    /// ... and has stayed below it at every check for this long, in tau_c (default 0:
    /// one check, K's criterion as written; docs/impact2d.md).
    #[serde(default)]
    settle_hold: f64,
    /// Give up after this much settling time, in tau_c.
    max_settle_time: f64,
    /// Which grains settle a variant's bed: `"base"` (default: every variant of a sweep
    /// hits the base case's beds) or `"variant"` (each variant's own grains, so a
    /// friction sweep compares beds each settled with its own law; docs/impact2d.md).
    #[serde(default)]
    settled_with: Option<String>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum Shape {
    Disk,
    Ellipse,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct IntruderIn {
    shape: Shape,
    /// Disk diameter D_i in d.
    diameter: Option<f64>,
    /// Ellipse semi-axes in d: a horizontal, b vertical.
    a: Option<f64>,
    b: Option<f64>,
    /// Disks on the ellipse outline (K: 360).
    #[serde(default = "default_cluster")]
    cluster_count: usize,
    /// Areal density relative to the grains (disk). The ellipse's mass is that of a
    /// disk of diameter 2a times this (K Sec. III A).
    #[serde(default = "one")]
    density_ratio: f64,
    /// Impact speed in d / tau_c.
    speed: f64,
    /// Gap between the intruder's lowest point and the surface at release, in d (K: 5).
    release_height: f64,
    /// Material; each field defaults to the grains' (K Fig 2: "the same as the grains").
    k_n: Option<f64>,
    e_n: Option<f64>,
    mu: Option<f64>,
    friction: Option<Friction>,
}

fn default_cluster() -> usize {
    360
}
fn one() -> f64 {
    1.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct AnalysisIn {
    /// Final depth = mean of D(t) over the last `final_window` tau_c of the run.
    final_window: f64,
    /// Record the interface tracers' height at every intruder sample (K Fig 12) even
    /// without an `interface_steadies` claim (which implies it).
    #[serde(default)]
    track_interface: bool,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SweepIn {
    /// speed | e_n | mu | gravity | friction | friction_mu | packing | bed
    parameter: String,
    values: Vec<toml::Value>,
}

#[derive(Debug, Clone, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "snake_case")]
pub enum Claim {
    /// `of` strictly increases along the sweep, each step by at least `min_step` (d, or
    /// tau_c for a time) (K: static < kinetic friction, hexagonal < random, grows with
    /// e_n; Fig 9: deeper and later for smaller g).
    ///
    /// On a seed ensemble (`[bed] seeds`): per step the per-seed rises (the same seeds
    /// at every value), a one-sided test that they exceed `min_step` (docs/statistics.md,
    /// "Rises"): passes when every step passes, fails when one step falls short at the
    /// Bonferroni level of the steps, else INCONCLUSIVE. The detail lists mean +- SE per
    /// value and each seed's value.
    Increasing {
        #[serde(default)]
        min_step: f64,
        #[serde(default)]
        of: ClaimQuantity,
        /// The time (tau_c after release) `energy_lost` is read at.
        #[serde(default)]
        at: Option<f64>,
    },
    /// `of` follows a trend along a numeric sweep (docs/statistics.md, "Rises": the
    /// paper's sentence names a tendency over the sweep, not each step; K Fig 9:
    /// "significantly deeper penetration for smaller gravitational accelerations").
    /// Judged on a seed ensemble only: per seed the least-squares slope of `of` against
    /// the swept value (its natural log with `log_x`), then the one-sample t interval of
    /// those slopes over the seeds (the seeds are the beds; the same beds at every value,
    /// so the bed-to-bed offset drops out). `direction = "falls"` judges minus the slope.
    /// PASS when the interval's lower end exceeds `min_slope` (unit of `of` per unit of
    /// x), FAIL when its upper end lies below it, else INCONCLUSIVE.
    Trend {
        direction: TrendDirection,
        #[serde(default)]
        min_slope: f64,
        #[serde(default)]
        of: ClaimQuantity,
        /// The time (tau_c after release) `energy_lost` is read at.
        #[serde(default)]
        at: Option<f64>,
        /// Fit against ln x rather than x (a sweep over decades, e.g. gravity).
        #[serde(default)]
        log_x: bool,
    },
    /// In every variant the total energy (kinetic + potential + normal elastic, K Fig 28)
    /// never rises between two samples by more than `max_rise` of the intruder's impact
    /// energy M v^2 / 2 (K Sec. V: "The total energy ... shows a monotonous decrease").
    EnergyNonIncreasing { max_rise: f64 },
    /// Final depth vs sweep value is linear for values >= `from` (K Fig 8b: linear in v
    /// for v >= 0.4). On one bed: INCONCLUSIVE (a comparison between conditions). On a
    /// seed ensemble (docs/statistics.md, "Linearity"): the per-seed slopes must be
    /// resolved positive, and straightness needs a registered curvature margin, which no
    /// case registers yet, so the claim is at best INCONCLUSIVE; `r2_min` on the means is
    /// reported, never gated.
    Linear { from: f64, r2_min: f64 },
    /// K Appendix, Fig 29: at fixed depth the intruder's deceleration follows a power of
    /// its speed, a ~ u^k ("for the kinetic friction case we find k ~ 1"). k is fitted
    /// (ln a on ln u) over the first passages of every variant through the depth bins
    /// `depths +- half_width` (d); it must lie in [`min`, `max`] in each engine, and the
    /// two engines' k may differ by at most `engine_tol`. The sweep must be of the speed.
    VelocityExponent {
        depths: Vec<f64>,
        half_width: f64,
        min: f64,
        max: f64,
        engine_tol: f64,
    },
    /// K Appendix, Fig 29, read per depth ("find a(u) for fixed y"; "for fixed u, a does
    /// not appear to depend on y"), on a seed ensemble only (docs/impact2d.md, "Fig 29 per
    /// depth"): at each depth of `depths` (bins +- `half_width` d) and on each bed, k is
    /// the slope of ln a on ln u over that bed's first passages (at least
    /// `min_passages`); per depth the mean k over the beds (at least `min_seeds`) with
    /// its t interval must lie inside (`min`, `max`) for a pass, and fails when its
    /// Bonferroni interval over the depths lies wholly outside. Native vs LAMMPS: per bed
    /// and depth |k_native - k_ref| <= `engine_tol`. The sweep must be of the speed.
    VelocityExponentPerDepth {
        depths: Vec<f64>,
        half_width: f64,
        min: f64,
        max: f64,
        min_passages: usize,
        min_seeds: usize,
        engine_tol: f64,
    },
    /// K Fig 21: "this force is very large immediately after impact, and then decreases
    /// significantly on a very short time scale". In every variant, with F(t) the
    /// contact force on the intruder along y averaged over bins of `bin` tau_c from the
    /// first contact t_c: the largest bin starts at most `peak_within` tau_c after t_c,
    /// and the bin mean falls below half of it at most `half_within` tau_c after that.
    ForceImpulsive {
        bin: f64,
        peak_within: f64,
        half_within: f64,
    },
    /// K Fig 21: "how similar they are for the different systems ... the penetration
    /// depths differ significantly". Over the variants, the relative spreads
    /// (max - min) / mean of the peak force and of the impulse over [t_c, t_c + `window`]
    /// are each at most `max_spread_ratio` times that of the final depths, and the final
    /// depths span at least `min_depth_spread` d. Bins as the `force_impulsive` claim's
    /// (1 tau_c unless that claim sets another).
    ForceSimilar {
        window: f64,
        max_spread_ratio: f64,
        min_depth_spread: f64,
    },
    /// K Figs 22-27: a field summary of variant `larger` is at least `min_ratio` (and at
    /// most `max_ratio`, if given) times that of variant `smaller` (variant labels, e.g.
    /// `friction=static`); B0 claims hold at every `fields.network_times`.
    FieldOrder {
        quantity: FieldQuantity,
        larger: String,
        smaller: String,
        min_ratio: f64,
        #[serde(default)]
        max_ratio: Option<f64>,
    },
    /// K Sec. III, Fig 11 ("Effect of system size and initial configuration"): "the final
    /// penetration depth ... varies only very little (less than a particle diameter)
    /// between systems of different sizes. This variation is smaller than that due to
    /// different initial conditions". A `bed` sweep's variants are grouped by size
    /// (count, length); the realizations of a size are its seeds. Judged as docs/statistics.md
    /// judges a claim of no effect: every pair of sizes an equivalence test (Welch over
    /// the seeds) of the mean final depths within `max_spread` (d); the spread between
    /// realizations is reported beside it.
    SizeInsensitive { max_spread: f64 },
    /// K Sec. III, Fig 12: the long-time oscillations of D(t) are global oscillations of
    /// the bed; "Fig. 12 shows the depth of the intruder with respect to the
    /// time-dependent position of the interface, calculated at the same time as the
    /// intruder's position. The long-time oscillation are not visible anymore." Rule
    /// (docs/impact2d.md, fixed before any run tracked the interface): the interface
    /// tracers are the grains whose centre at release lies within 2 d of the surface D
    /// is measured from and at a periodic horizontal distance >= L/4 from the impact
    /// point (at least 10, ids fixed at release); s(t) = their centre of mass in y minus
    /// its value at release; D_rel = D + s. A[X] = max - min of X over the final window
    /// (the final depth's samples). A variant is tested when A[D] >= `min_amplitude` (d)
    /// and holds when A[D_rel] <= `max_ratio` x A[D]. The claim fails when a tested
    /// variant fails, else it is NOT COMPARED when a variant is untested, else it holds.
    InterfaceSteadies { max_ratio: f64, min_amplitude: f64 },
}

/// A field summary a `field_order` claim compares.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FieldQuantity {
    /// Integral of B0 / N of the normal force network over the thresholds (K Fig 22).
    B0Normal,
    /// The same for the tangential network (K Fig 23).
    B0Tangential,
    /// Mean |A_f| over the grains (K Figs 24, 26).
    Affine,
    /// Mean |A_f . j| (K Fig 24: "in particular for the y component").
    AffineY,
    /// Mean D2_min (K Figs 25, 27).
    D2min,
}

impl FieldQuantity {
    pub(crate) fn is_network(self) -> bool {
        matches!(self, FieldQuantity::B0Normal | FieldQuantity::B0Tangential)
    }
    pub(crate) fn describe(self) -> &'static str {
        match self {
            FieldQuantity::B0Normal => "integral of B0/N, normal force network",
            FieldQuantity::B0Tangential => "integral of B0/N, tangential force network",
            FieldQuantity::Affine => "mean |A_f| (d)",
            FieldQuantity::AffineY => "mean |A_f . j| (d)",
            FieldQuantity::D2min => "mean D2_min (d^2)",
        }
    }
}

/// `[fields]`, validated: snapshot steps and the analysis parameters (SI).
#[derive(Debug, Clone, serde::Serialize)]
pub struct Fields {
    /// Steps of the contact-force snapshots (B0).
    pub network_steps: Vec<u64>,
    /// Thresholds in units of the mean per-grain normal force.
    pub threshold_max: f64,
    pub threshold_step: f64,
    /// (step at t - dt, step at t, neighbourhood radius in m) of the affine analysis.
    pub affine: Option<(u64, u64, f64)>,
}

impl Fields {
    /// Every step at which the grains' positions are written (B0 and affine).
    pub fn position_steps(&self) -> Vec<u64> {
        let mut v = self.network_steps.clone();
        if let Some((a, b, _)) = self.affine {
            v.extend([a, b]);
        }
        v.sort_unstable();
        v.dedup();
        v
    }
}

/// What an `increasing` claim follows along the sweep.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ClaimQuantity {
    /// The final depth (d): mean over the final window.
    #[default]
    FinalDepth,
    /// When the maximum depth is reached (tau_c after release; K Fig 9: "the maximum
    /// penetration depth is reached at much later times as gravity is decreased").
    TimeOfMaxDepth,
    /// Total energy lost by the time `at` (m g d; K Fig 28: "faster loss of energy for
    /// the systems with friction").
    EnergyLost,
}

impl ClaimQuantity {
    pub(crate) fn describe(self) -> (&'static str, &'static str) {
        match self {
            ClaimQuantity::FinalDepth => ("final depth", "d"),
            ClaimQuantity::TimeOfMaxDepth => ("time of the maximum depth", "tau_c"),
            ClaimQuantity::EnergyLost => ("total energy lost", "m g d"),
        }
    }
}

/// Which way a `trend` claim's quantity goes as the swept value grows.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TrendDirection {
    Rises,
    Falls,
}

impl TrendDirection {
    /// +1 for `rises`, -1 for `falls`: the slope the claim judges is sign x slope.
    pub(crate) fn sign(self) -> f64 {
        match self {
            TrendDirection::Rises => 1.0,
            TrendDirection::Falls => -1.0,
        }
    }
}

/// Cross-check tolerances (native vs LAMMPS), in d.
#[derive(Debug, Clone, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Tolerances {
    /// |D_native - D_lammps| of the final depth (default 1.0 d: "about one grain").
    #[serde(default = "d_final")]
    pub final_depth_abs: f64,
    /// RMS of D_native(t) - D_lammps(t) over the run (default 1.0 d).
    #[serde(default = "d_rms")]
    pub depth_rms: f64,
    /// Force on the intruder: the largest relative difference of peak, impulse and the
    /// RMS of the binned F(t) over `force_window` tau_c after first contact (a
    /// `force_*` claim's case only; default 0.05).
    #[serde(default = "d_rel")]
    pub force_rel: f64,
    #[serde(default = "d_force_window")]
    pub force_window: f64,
    /// B0 curves: L1 distance over the reference integral (default 0.05).
    #[serde(default = "d_rel")]
    pub b0_distance: f64,
    /// Affine / D2_min summaries: relative difference (default 0.05).
    #[serde(default = "d_rel")]
    pub field_rel: f64,
    /// RMS of s_native(t) - s_lammps(t), the interface displacement (K Fig 12), over
    /// the run, in d (default 0.1; cases that track the interface only).
    #[serde(default = "d_interface_rms")]
    pub interface_rms: f64,
}

fn d_interface_rms() -> f64 {
    0.1
}

fn d_rel() -> f64 {
    0.05
}
fn d_force_window() -> f64 {
    50.0
}

fn d_final() -> f64 {
    1.0
}
fn d_rms() -> f64 {
    1.0
}

impl Default for Tolerances {
    fn default() -> Self {
        Tolerances {
            final_depth_abs: d_final(),
            depth_rms: d_rms(),
            force_rel: d_rel(),
            force_window: d_force_window(),
            b0_distance: d_rel(),
            field_rel: d_rel(),
            interface_rms: d_interface_rms(),
        }
    }
}

/// K's scales in SI.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Scales {
    pub d: f64,
    pub m: f64,
    pub g0: f64,
    /// N/m per unit of dimensionless k_n.
    pub k_unit: f64,
    /// tau_c of the grains' k_n (s).
    pub tau_c: f64,
}

impl Scales {
    pub fn velocity(&self) -> f64 {
        self.d / self.tau_c
    }
    pub(crate) fn tau_of(&self, k_n: f64) -> f64 {
        std::f64::consts::PI * (self.d / (2.0 * self.g0 * k_n)).sqrt()
    }
}

/// One material in K's terms.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Material2d {
    pub k_n: f64,
    pub e_n: f64,
    pub mu: f64,
    pub friction: Friction,
}

impl Material2d {
    /// The LAMMPS-style coefficients (SI) of this material.
    pub fn coeffs(&self, s: &Scales) -> Coeffs {
        let kn = self.k_n * s.k_unit;
        let gamma_n = gamma_n_from_restitution(self.e_n, s.tau_of(self.k_n));
        Coeffs {
            kn,
            kt: match self.friction {
                Friction::Static => 0.8 * kn,
                Friction::Kinetic => 0.0,
            },
            gamma_n,
            gamma_t: 0.5 * gamma_n,
            mu: self.mu,
        }
    }
}

#[derive(Debug, Clone, serde::Serialize)]
pub enum IntruderShape {
    /// Radius (m).
    Disk { radius: f64 },
    /// Semi-axes (m) and outline disk count.
    Ellipse { a: f64, b: f64, count: usize },
}

/// A bed of its own for one variant (the `bed` sweep, K Fig 11): grain count, periodic
/// length (m) and seed in place of `[bed]`'s; everything else of `[bed]` is kept.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BedSize {
    pub count: usize,
    pub length: f64,
    pub seed: u64,
}

/// Which prepared bed a variant runs on: the key of the bed map (one bed is prepared
/// per distinct key) and what the scene's geometry follows.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BedKey {
    pub packing: Packing,
    pub count: usize,
    /// Periodic length L (m).
    pub length: f64,
    pub seed: u64,
    /// The grain and wall materials the bed settles with when they are not the base
    /// case's (`[bed] settled_with = "variant"`: a friction sweep sets both); `None`: the
    /// base's, as every bed before.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) settled_with: Option<SettleMaterials>,
}

/// The materials a bed settles with (K Sec. II's pour and settling).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub(crate) struct SettleMaterials {
    pub(crate) grains: Material2d,
    pub(crate) walls: Material2d,
}

impl BedKey {
    /// The system size (count, L in m) K Fig 11 compares; the seed is the realization.
    pub fn size(&self) -> (usize, f64) {
        (self.count, self.length)
    }
}

/// The realizations of one sweep value in a seed ensemble.
#[derive(Debug, Clone, PartialEq)]
pub struct EnsembleGroup {
    /// The value's label without the seed (e.g. `speed=0.7`, or `base` without a sweep).
    pub value: String,
    /// The swept value as a number (the variants' `x`).
    pub x: f64,
    /// Indices into `variants`, one per seed in `seeds` order.
    pub members: Vec<usize>,
}

/// One run: the base case with the sweep value applied.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Variant {
    /// e.g. `speed=0.7` or `base`.
    pub label: String,
    /// The swept value as a number (for claims; 0, 1, ... for text values).
    pub x: f64,
    pub packing: Packing,
    /// The variant's own bed size and seed (a `bed` sweep), else `[bed]`'s. Left out of
    /// the serialised variant when absent, so the canonical hash of cases without a `bed`
    /// sweep (and the seals of their records) stays as it was.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bed: Option<BedSize>,
    /// In a seed ensemble (`[bed] seeds`), the label of the sweep value this run is a
    /// realization of (the label without its `,seed=S`); `None` otherwise. Not hashed:
    /// the label and the bed carry it.
    #[serde(skip)]
    pub ensemble_value: Option<String>,
    pub grains: Material2d,
    pub walls: Material2d,
    pub intruder: Material2d,
    /// SI.
    pub gravity: f64,
    pub speed: f64,
}

/// A validated impact2d case, SI unless stated. Outside this crate it can only come
/// from [`Impact2dCase::load`] / `from_toml_str` (`non_exhaustive`), so every value a
/// run sees went through validation; the fields are public for reading.
#[derive(Debug, Clone, serde::Serialize)]
#[non_exhaustive]
pub struct Impact2dCase {
    /// `[bed] settled_with = "variant"`: a variant whose grains differ from the base's
    /// runs on beds settled with its own grains ([`Impact2dCase::bed_of`]).
    pub beds_per_variant: bool,
    pub name: String,
    pub description: String,
    pub source: PathBuf,
    pub scales: Scales,
    pub dt: f64,
    pub n_steps: u64,
    pub output_every: u64,
    pub energy_every: u64,
    pub skin: f64,
    pub base_packing: Packing,
    pub count: usize,
    pub length: f64,
    pub polydispersity: f64,
    /// `[bed] seed`, or the first of `seeds`.
    pub seed: u64,
    /// `[bed] seeds` of a seed ensemble; empty for one bed.
    pub seeds: Vec<u64>,
    pub initial_speed: f64,
    pub settle_ke: f64,
    /// `[bed] settle_hold` (s): how long the kinetic energy must stay below
    /// `settle_ke` (0: one check).
    pub settle_hold: f64,
    pub max_settle_time: f64,
    pub wall_d: f64,
    pub top_gap: f64,
    pub shape: IntruderShape,
    /// Intruder mass (kg).
    pub intruder_mass: f64,
    pub release_height: f64,
    pub final_window: f64,
    /// Wall disks take the grains' coefficients during the impact.
    pub walls_as_grains: bool,
    /// Bed snapshots during the impact (K Sec. IV), if any.
    pub fields: Option<Fields>,
    /// Both engines record the interface tracers' height (K Fig 12): an
    /// `interface_steadies` claim or `[analysis] track_interface`.
    pub track_interface: bool,
    pub sweep_parameter: Option<String>,
    /// The case without its sweep: beds are prepared with these materials.
    pub base: Variant,
    pub variants: Vec<Variant>,
    /// K's claims over the sweep, each evaluated in each engine.
    pub claims: Vec<Claim>,
    pub tolerances: Tolerances,
    pub negative_controls: Vec<super::NegativeControl>,
}

/// Gates an impact2d comparison produces (what its negative controls may name).
pub(crate) const IMPACT2D_GATES: &[super::Gate] = &[
    super::Gate::FinalDepth,
    super::Gate::DepthSeries,
    super::Gate::Claim,
    super::Gate::IntruderForce,
    super::Gate::ForceNetwork,
    super::Gate::DisplacementField,
    super::Gate::InterfaceSeries,
];

/// The interface tracers of K Fig 12 (docs/impact2d.md): grains whose centre at release
/// lies within this many d below the surface D is measured from ...
pub(crate) const TRACER_DEPTH: f64 = 2.0;
/// ... at a periodic horizontal distance from the impact point of at least this
/// fraction of L ...
pub(crate) const TRACER_MIN_DISTANCE: f64 = 0.25;
/// ... and at least this many of them.
pub(crate) const MIN_TRACERS: usize = 10;

/// `[claim]` (one table) or `[[claim]]` (several), each read on its own so that an
/// error names the claim and serde's own reason (a missing or unknown field, a bad kind).
fn parse_claims(ctx: &Ctx, raw: Option<&toml::Value>) -> Result<Vec<Claim>, CaseError> {
    let tables: Vec<(String, &toml::Value)> = match raw {
        None => return Ok(vec![]),
        Some(toml::Value::Array(v)) => v
            .iter()
            .enumerate()
            .map(|(k, c)| (format!("claim[{k}]"), c))
            .collect(),
        Some(c) => vec![("claim".to_string(), c)],
    };
    tables
        .into_iter()
        .map(|(field, c)| {
            let kind = c.get("kind").and_then(|k| k.as_str()).unwrap_or("(none)");
            Claim::deserialize(c.clone()).map_err(|e| {
                ctx.bad(
                    &field,
                    format!("kind = {kind}"),
                    format!("not a valid claim: {}", e.message()),
                )
            })
        })
        .collect()
}

fn unit_interval(ctx: &Ctx, field: &str, v: f64) -> Result<f64, CaseError> {
    if v.is_finite() && v > 0.0 && v <= 1.0 {
        Ok(v)
    } else {
        Err(ctx.bad(field, v, "must lie in (0, 1]"))
    }
}

/// A claim's `at`: required (and inside the run) for `energy_lost`, which is read at a
/// time, refused for every other quantity.
fn read_time(
    ctx: &Ctx,
    field: &str,
    of: ClaimQuantity,
    at: Option<f64>,
    duration: f64,
) -> Result<(), CaseError> {
    match (of, at) {
        (ClaimQuantity::EnergyLost, None) => Err(ctx.bad(
            field,
            "missing",
            "energy_lost is read at a time: give `at` (tau_c after release)",
        )),
        (ClaimQuantity::EnergyLost, Some(t)) => {
            positive(ctx, field, t)?;
            if t > duration {
                return Err(ctx.bad(field, t, "after the end of the run"));
            }
            Ok(())
        }
        (_, Some(t)) => Err(ctx.bad(field, t, "only energy_lost is read at a time")),
        (_, None) => Ok(()),
    }
}

fn non_negative(ctx: &Ctx, field: &str, v: f64) -> Result<f64, CaseError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(ctx.bad(field, v, "must be >= 0"))
    }
}

fn material(ctx: &Ctx, prefix: &str, m: &MaterialIn) -> Result<Material2d, CaseError> {
    Ok(Material2d {
        k_n: positive(ctx, &format!("{prefix}.k_n"), m.k_n)?,
        e_n: unit_interval(ctx, &format!("{prefix}.e_n"), m.e_n)?,
        mu: non_negative(ctx, &format!("{prefix}.mu"), m.mu)?,
        friction: m.friction,
    })
}

impl Impact2dCase {
    /// The bed variant `v` runs on.
    pub fn bed_of(&self, v: &Variant) -> BedKey {
        let b = v.bed.unwrap_or(BedSize {
            count: self.count,
            length: self.length,
            seed: self.seed,
        });
        BedKey {
            packing: v.packing,
            count: b.count,
            length: b.length,
            seed: b.seed,
            settled_with: (self.beds_per_variant
                && (v.grains, v.walls) != (self.base.grains, self.base.walls))
                .then_some(SettleMaterials {
                    grains: v.grains,
                    walls: v.walls,
                }),
        }
    }

    /// Whether the case is a seed ensemble (`[bed] seeds`).
    pub fn is_ensemble(&self) -> bool {
        !self.seeds.is_empty()
    }

    /// A seed ensemble's variants grouped by sweep value, in sweep order: each group the
    /// realizations (one per seed, in `seeds` order) of one value. Empty for one bed.
    pub fn ensemble_groups(&self) -> Vec<EnsembleGroup> {
        let mut out: Vec<EnsembleGroup> = Vec::new();
        for (k, v) in self.variants.iter().enumerate() {
            let Some(value) = &v.ensemble_value else {
                continue;
            };
            match out.iter_mut().find(|g| &g.value == value) {
                Some(g) => g.members.push(k),
                None => out.push(EnsembleGroup {
                    value: value.clone(),
                    x: v.x,
                    members: vec![k],
                }),
            }
        }
        out
    }

    /// The variants' indices grouped by system size (count, length), sizes in order of
    /// first appearance (K Fig 11: the realizations of each size).
    pub fn size_groups(&self) -> Vec<((usize, f64), Vec<usize>)> {
        size_groups(&self.variants, self.count, self.length)
    }

    /// Whether a control's `other_size_speed_factor` applies to variant `v`: its size
    /// (count, length) differs from the first variant's.
    pub fn is_other_size(&self, v: &Variant) -> bool {
        self.variants
            .first()
            .is_some_and(|f| self.bed_of(f).size() != self.bed_of(v).size())
    }

    /// What the runs depend on (scales, bed, intruder, protocol, every variant), not the
    /// name, description, analysis window, claim, tolerances or controls. A recorded
    /// reference is sealed to its sha256.
    ///
    /// The struct is destructured exhaustively: a new field does not compile until it is
    /// placed in the view or named below as not physics.
    pub fn canonical_hash(&self) -> crate::rundata::provenance::Sha256 {
        let Impact2dCase {
            scales,
            dt,
            n_steps,
            output_every,
            energy_every,
            skin,
            base_packing,
            count,
            length,
            polydispersity,
            seed,
            seeds,
            initial_speed,
            settle_ke,
            settle_hold,
            max_settle_time,
            wall_d,
            top_gap,
            shape,
            intruder_mass,
            release_height,
            walls_as_grains,
            beds_per_variant,
            fields,
            track_interface,
            base,
            variants,
            // Not physics: labels, the analysis window and claims, how the runs are
            // judged, and the name of the swept parameter (its values are in `variants`).
            name: _,
            description: _,
            source: _,
            final_window: _,
            sweep_parameter: _,
            claims: _,
            tolerances: _,
            negative_controls: _,
        } = self;
        let mut view = serde_json::json!({
            "kind": "impact2d",
            "scales": scales,
            "dt": dt,
            "n_steps": n_steps,
            "output_every": output_every,
            "energy_every": energy_every,
            "skin": skin,
            "bed": [*count as f64, length, polydispersity, *seed as f64, initial_speed, settle_ke, max_settle_time, wall_d, top_gap],
            "base_packing": base_packing,
            "shape": shape,
            "intruder": [intruder_mass, release_height],
            "base": base,
            "variants": variants,
        });
        // Added with the bed fields (K Sec. IV); absent from the view when unused, so the
        // hashes of cases written before them, and their seals, stay as they were.
        if *walls_as_grains {
            view["walls_as_grains"] = serde_json::json!(true);
        }
        if let Some(f) = fields {
            view["fields"] = serde_json::json!(f);
        }
        // Added with beds settled per variant; absent for the base's beds, as above.
        if *beds_per_variant {
            view["beds_settled_with"] = serde_json::json!("variant");
        }
        // Added with the settling hold; absent when 0, as above.
        if *settle_hold > 0.0 {
            view["settle_hold"] = serde_json::json!(settle_hold);
        }
        // Added with seed ensembles; absent for one bed, so the hashes (and seals) of
        // the cases written before stay as they were.
        if self.is_ensemble() {
            view["seeds"] = serde_json::json!(seeds);
        }
        // Added with the interface tracers (K Fig 12), the same way.
        if *track_interface {
            view["interface_tracers"] =
                serde_json::json!([TRACER_DEPTH, TRACER_MIN_DISTANCE, MIN_TRACERS]);
        }
        crate::rundata::provenance::Sha256::of(view.to_string().as_bytes())
    }

    pub fn load(path: &Path) -> Result<Impact2dCase, CaseError> {
        let text = super::read_case_file(path)?;
        Self::from_toml_str(&text, path)
    }

    /// Reads a case file's text and validates it one section at a time, in the order of
    /// the calls below; the first error found is the one reported.
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Impact2dCase, CaseError> {
        let (raw, ctx) = super::validate::parse_kind(text, path, "impact2d", |r: &File| &r.case)?;
        let (scales, grains) = units_and_grains(&ctx, &raw.units, &raw.grains)?;
        let walls = wall_params(&ctx, &raw.walls, &grains, scales.d)?;
        let time = timing(
            &ctx,
            &raw.simulation,
            &scales,
            &grains,
            &walls.material,
            raw.intruder.k_n,
        )?;
        let swept = raw.sweep.as_ref().map(|w| w.parameter.as_str());
        let bed = bed_params(&ctx, &raw.bed, swept, &scales)?;
        let intruder = intruder_params(&ctx, &raw.intruder, &scales, bed.length)?;
        let final_window = final_window(&ctx, &raw.analysis, scales.tau_c, time.duration)?;

        let base = Variant {
            label: "base".into(),
            x: 0.0,
            packing: raw.bed.packing,
            bed: None,
            ensemble_value: None,
            grains,
            walls: walls.material,
            intruder: intruder_material(&ctx, &raw.intruder, &grains)?,
            gravity: time.gravity,
            speed: intruder.speed,
        };
        let sweep_parameter = raw.sweep.as_ref().map(|s| s.parameter.clone());
        let variants = sweep_variants(&ctx, &raw, &base, &scales, intruder.width)?;
        let variants = seed_ensemble(variants, &raw, &bed);
        let claims = validated_claims(&ClaimScope {
            ctx: &ctx,
            raw: &raw,
            variants: &variants,
            seeds: &bed.seeds,
            dt_tau: time.dt_tau,
            length: bed.length,
            d: scales.d,
        })?;
        hexagonal_lengths(&ctx, &variants, raw.bed.length, scales.d)?;
        let tolerances = tolerances(&ctx, raw.compare.as_ref())?;
        let track_interface = raw.analysis.track_interface
            || claims
                .iter()
                .any(|c| matches!(c, Claim::InterfaceSteadies { .. }));
        let fields = match &raw.fields {
            None => None,
            Some(f) => Some(fields(&ctx, f, time.dt_tau, time.n_steps, scales.d)?),
        };
        let negative_controls =
            negative_controls(&ctx, &raw, &variants, track_interface, bed.length)?;
        let beds_per_variant = settled_with(&ctx, &raw, &base, &variants, &negative_controls)?;
        Ok(Impact2dCase {
            beds_per_variant,
            negative_controls,
            name: raw.case.name,
            description: raw.case.description,
            source: path.to_path_buf(),
            scales,
            dt: time.dt,
            n_steps: time.n_steps,
            output_every: raw.simulation.output_every,
            energy_every: raw.simulation.energy_every,
            skin: time.skin,
            base_packing: raw.bed.packing,
            count: raw.bed.count,
            length: bed.length,
            polydispersity: bed.polydispersity,
            seed: bed.seed,
            seeds: bed.seeds,
            initial_speed: bed.initial_speed,
            settle_ke: bed.settle_ke,
            settle_hold: bed.settle_hold,
            max_settle_time: bed.max_settle_time,
            wall_d: walls.wall_d,
            top_gap: walls.top_gap,
            shape: intruder.shape,
            intruder_mass: intruder.mass,
            release_height: intruder.release_height,
            final_window,
            walls_as_grains: raw.walls.impact_as_grains,
            fields,
            track_interface,
            sweep_parameter,
            base,
            variants,
            claims,
            tolerances,
        })
    }
}

/// `[bed] settled_with`: true for `"variant"` (each variant's bed settled with its own
/// grains), false for `"base"` or absent. Only a sweep of a grain property changes the
/// grains; with a `sweep_ignored` control some value must keep the base's grains, whose
/// beds that control runs every value on.
fn settled_with(
    ctx: &Ctx,
    raw: &File,
    base: &Variant,
    variants: &[Variant],
    controls: &[super::NegativeControl],
) -> Result<bool, CaseError> {
    let Some(v) = raw.bed.settled_with.as_deref() else {
        return Ok(false);
    };
    match v {
        "base" => return Ok(false),
        "variant" => {}
        _ => {
            return Err(ctx.bad(
                "bed.settled_with",
                v,
                "must be \"base\" (every variant on the base case's beds) or \"variant\" (each variant's bed settled with its own grains)",
            ));
        }
    }
    let swept = raw.sweep.as_ref().map(|w| w.parameter.as_str());
    if !matches!(swept, Some("friction" | "mu" | "e_n")) {
        return Err(ctx.bad(
            "bed.settled_with",
            v,
            format!(
                "needs a sweep of a grain property (friction, mu or e_n), not {}: otherwise every variant settles the same grains",
                swept.map_or("no sweep".to_string(), |p| format!("a {p} sweep"))
            ),
        ));
    }
    if controls.iter().any(|c| c.perturbation.sweep_ignored)
        && !variants
            .iter()
            .any(|x| (x.grains, x.walls) == (base.grains, base.walls))
    {
        return Err(ctx.bad(
            "bed.settled_with",
            v,
            "a sweep_ignored control runs every value on the base grains' beds, so one sweep value must keep the base case's grains",
        ));
    }
    Ok(true)
}

/// `[units]` and `[grains]`: K's scales in SI. The grains' k_n sets tau_c, the time unit
/// of every other section (K Sec. II).
fn units_and_grains(
    ctx: &Ctx,
    u: &Units,
    g: &MaterialIn,
) -> Result<(Scales, Material2d), CaseError> {
    let d = positive(ctx, "units.d", u.d)?;
    let m = positive(ctx, "units.mass", u.mass)?;
    let g0 = positive(ctx, "units.g", u.g)?;
    let grains = material(ctx, "grains", g)?;
    let scales = Scales {
        d,
        m,
        g0,
        k_unit: m * g0 / d,
        tau_c: std::f64::consts::PI * (d / (2.0 * g0 * grains.k_n)).sqrt(),
    };
    Ok((scales, grains))
}

/// `[walls]`, validated: the wall disks' material and the geometry they set (SI).
struct WallParams {
    material: Material2d,
    wall_d: f64,
    top_gap: f64,
}

/// `[walls]`: the wall disks' material (k_n and friction default to the grains') and
/// their diameter and top gap.
fn wall_params(ctx: &Ctx, w: &Walls, grains: &Material2d, d: f64) -> Result<WallParams, CaseError> {
    let material = Material2d {
        k_n: match w.k_n {
            Some(k) => positive(ctx, "walls.k_n", k)?,
            None => grains.k_n,
        },
        e_n: unit_interval(ctx, "walls.e_n", w.e_n)?,
        mu: non_negative(ctx, "walls.mu", w.mu)?,
        friction: w.friction.unwrap_or(grains.friction),
    };
    let wall_d = positive(ctx, "walls.diameter", w.diameter)? * d;
    let top_gap = positive(ctx, "walls.top_gap", w.top_gap)? * d;
    Ok(WallParams {
        material,
        wall_d,
        top_gap,
    })
}

/// `[simulation]`, validated (SI; `dt_tau` is the step in tau_c, which `[fields]` and the
/// claims count in).
struct Timing {
    dt_tau: f64,
    dt: f64,
    duration: f64,
    n_steps: u64,
    gravity: f64,
    skin: f64,
}

/// `[simulation]`: the time step against the stiffest contact of grains, walls and
/// intruder (`intruder_k_n`, not yet validated, defaults to the grains'), the duration
/// and step count, the output intervals, gravity (in g0: K Sec. III B changes only the
/// gravitational force) and the Verlet skin.
fn timing(
    ctx: &Ctx,
    s: &Sim,
    scales: &Scales,
    grains: &Material2d,
    walls: &Material2d,
    intruder_k_n: Option<f64>,
) -> Result<Timing, CaseError> {
    let tau = scales.tau_c;
    let dt_tau = positive(ctx, "simulation.dt", s.dt)?;
    // Stiffest pair sets the limit: tau_c scales as k_n^-1/2.
    let k_max = [grains.k_n, walls.k_n, intruder_k_n.unwrap_or(grains.k_n)]
        .into_iter()
        .fold(0.0, f64::max);
    let tau_min = scales.tau_of(k_max) / tau;
    if dt_tau > 0.1 * tau_min {
        return Err(ctx.bad(
            "simulation.dt",
            dt_tau,
            format!("exceeds tau_c/10 of the stiffest contact ({:.4} tau_c); a linear spring needs >= 10 steps per collision (use ~1/50)", 0.1 * tau_min),
        ));
    }
    let dt = dt_tau * tau;
    let duration = positive(ctx, "simulation.duration", s.duration)? * tau;
    let n_steps = (duration / dt).round() as u64;
    if s.output_every == 0 {
        return Err(ctx.bad("simulation.output_every", 0, "must be >= 1"));
    }
    if s.energy_every == 0 || !s.energy_every.is_multiple_of(s.output_every) {
        return Err(ctx.bad(
            "simulation.energy_every",
            s.energy_every,
            "must be a positive multiple of simulation.output_every",
        ));
    }
    let gravity = positive(ctx, "simulation.gravity", s.gravity)? * scales.g0;
    let skin = positive(ctx, "simulation.skin", s.skin)? * scales.d;
    Ok(Timing {
        dt_tau,
        dt,
        duration,
        n_steps,
        gravity,
        skin,
    })
}

/// `[bed]`, validated (SI); packing and count are taken from `[bed]` as written.
struct BedParams {
    length: f64,
    polydispersity: f64,
    initial_speed: f64,
    settle_ke: f64,
    settle_hold: f64,
    max_settle_time: f64,
    seed: u64,
    seeds: Vec<u64>,
}

/// `[bed]`: grain count, periodic length, polydispersity (K Sec. II), the settling
/// protocol, and the seed or seed ensemble (`sweep` is the swept parameter, if any).
fn bed_params(
    ctx: &Ctx,
    b: &BedIn,
    sweep: Option<&str>,
    scales: &Scales,
) -> Result<BedParams, CaseError> {
    let (d, m, g0) = (scales.d, scales.m, scales.g0);
    if b.count == 0 {
        return Err(ctx.bad("bed.count", 0, "must be >= 1"));
    }
    let length = period_length(ctx, "bed.length", b.length, d)?;
    let poly = finite(ctx, "bed.polydispersity", b.polydispersity)?;
    if !(0.0..0.5).contains(&poly) {
        return Err(ctx.bad(
            "bed.polydispersity",
            poly,
            "must lie in [0, 0.5) (K uses 0 to 0.4)",
        ));
    }
    let initial_speed =
        non_negative(ctx, "bed.initial_speed", b.initial_speed)? * scales.velocity();
    let settle_ke = positive(ctx, "bed.settle_ke", b.settle_ke)? * m * g0 * d;
    let max_settle_time = positive(ctx, "bed.max_settle_time", b.max_settle_time)? * scales.tau_c;
    let settle_hold = non_negative(ctx, "bed.settle_hold", b.settle_hold)? * scales.tau_c;
    if settle_hold >= max_settle_time {
        return Err(ctx.bad(
            "bed.settle_hold",
            b.settle_hold,
            "must be shorter than bed.max_settle_time: the bed could never be found settled",
        ));
    }
    let (seed, seeds) = bed_seeds(ctx, b, sweep)?;
    Ok(BedParams {
        length,
        polydispersity: poly,
        initial_speed,
        settle_ke,
        settle_hold,
        max_settle_time,
        seed,
        seeds,
    })
}

/// `[intruder]`, validated (SI); its material is [`intruder_material`]'s.
struct IntruderParams {
    shape: IntruderShape,
    mass: f64,
    /// Horizontal extent (m), for the fit in the period.
    width: f64,
    speed: f64,
    release_height: f64,
}

/// `[intruder]` without its material: density, shape and size (a disk, or an ellipse of
/// disks, K Sec. III A), which must fit in the period of length `length` (m), the impact
/// speed and the release height.
fn intruder_params(
    ctx: &Ctx,
    i: &IntruderIn,
    scales: &Scales,
    length: f64,
) -> Result<IntruderParams, CaseError> {
    let (d, m) = (scales.d, scales.m);
    let areal = m / (std::f64::consts::PI * 0.25 * d * d);
    let density_ratio = positive(ctx, "intruder.density_ratio", i.density_ratio)?;
    let (shape, mass, width) = match i.shape {
        Shape::Disk => disk_intruder(ctx, i, d, density_ratio, areal)?,
        Shape::Ellipse => ellipse_intruder(ctx, i, d, density_ratio, areal)?,
    };
    if !fits_period(width, length) {
        return Err(ctx.bad("intruder", width / d, NARROWER));
    }
    let speed = non_negative(ctx, "intruder.speed", i.speed)? * scales.velocity();
    let release_height = positive(ctx, "intruder.release_height", i.release_height)? * d;
    Ok(IntruderParams {
        shape,
        mass,
        width,
        speed,
        release_height,
    })
}

/// `shape = "disk"`: its diameter, and no semi-axes. Returns (shape, mass, width), SI;
/// the mass is `density_ratio` times that of grain material of areal density `areal`.
fn disk_intruder(
    ctx: &Ctx,
    i: &IntruderIn,
    d: f64,
    density_ratio: f64,
    areal: f64,
) -> Result<(IntruderShape, f64, f64), CaseError> {
    let dia = positive(
        ctx,
        "intruder.diameter",
        i.diameter.ok_or_else(|| {
            ctx.bad(
                "intruder.diameter",
                "missing",
                "a disk intruder needs its diameter (in d)",
            )
        })?,
    )?;
    if i.a.is_some() || i.b.is_some() {
        return Err(ctx.bad("intruder.a", i.a, "a and b belong to shape = \"ellipse\""));
    }
    let r = 0.5 * dia * d;
    Ok((
        IntruderShape::Disk { radius: r },
        density_ratio * areal * std::f64::consts::PI * r * r,
        2.0 * r,
    ))
}

/// `shape = "ellipse"`: semi-axes a, b of at least 1 d, no diameter, and at least 8
/// outline disks. Returns (shape, mass, width), SI; the mass is that of a disk of
/// diameter 2a (K Sec. III A) times `density_ratio`.
fn ellipse_intruder(
    ctx: &Ctx,
    i: &IntruderIn,
    d: f64,
    density_ratio: f64,
    areal: f64,
) -> Result<(IntruderShape, f64, f64), CaseError> {
    let a = positive(
        ctx,
        "intruder.a",
        i.a.ok_or_else(|| {
            ctx.bad(
                "intruder.a",
                "missing",
                "an ellipse needs semi-axes a and b (in d)",
            )
        })?,
    )?;
    let bb = positive(
        ctx,
        "intruder.b",
        i.b.ok_or_else(|| {
            ctx.bad(
                "intruder.b",
                "missing",
                "an ellipse needs semi-axes a and b (in d)",
            )
        })?,
    )?;
    if i.diameter.is_some() {
        return Err(ctx.bad(
            "intruder.diameter",
            i.diameter,
            "diameter belongs to shape = \"disk\"",
        ));
    }
    if a < 1.0 || bb < 1.0 {
        return Err(ctx.bad(
            "intruder.a",
            (a, bb),
            "semi-axes must be >= 1 d (the outline disks are d wide)",
        ));
    }
    if i.cluster_count < 8 {
        return Err(ctx.bad("intruder.cluster_count", i.cluster_count, "must be >= 8"));
    }
    let (a, bb) = (a * d, bb * d);
    Ok((
        IntruderShape::Ellipse {
            a,
            b: bb,
            count: i.cluster_count,
        },
        density_ratio * areal * std::f64::consts::PI * a * a,
        2.0 * a,
    ))
}

/// The intruder's material over grains `g`: each field of `[intruder]` given, or the
/// grains' (K Fig 2: "the same as the grains"). Applied again to each variant's grains.
fn intruder_material(ctx: &Ctx, i: &IntruderIn, g: &Material2d) -> Result<Material2d, CaseError> {
    Ok(Material2d {
        k_n: match i.k_n {
            Some(k) => positive(ctx, "intruder.k_n", k)?,
            None => g.k_n,
        },
        e_n: match i.e_n {
            Some(e) => unit_interval(ctx, "intruder.e_n", e)?,
            None => g.e_n,
        },
        mu: match i.mu {
            Some(v) => non_negative(ctx, "intruder.mu", v)?,
            None => g.mu,
        },
        friction: i.friction.unwrap_or(g.friction),
    })
}

/// `[analysis] final_window` (s): positive and shorter than the run (`duration`, s).
fn final_window(ctx: &Ctx, a: &AnalysisIn, tau: f64, duration: f64) -> Result<f64, CaseError> {
    let final_window = positive(ctx, "analysis.final_window", a.final_window)? * tau;
    if final_window >= duration {
        return Err(ctx.bad(
            "analysis.final_window",
            a.final_window,
            "must be shorter than simulation.duration",
        ));
    }
    Ok(final_window)
}

/// What a sweep value is applied to: the base case and what its parameters are checked
/// and converted with.
struct SweepBase<'a> {
    ctx: &'a Ctx,
    parameter: &'a str,
    base: &'a Variant,
    scales: &'a Scales,
    intruder: &'a IntruderIn,
    /// `[walls] friction` as written: without it the walls follow the grains' model.
    walls_friction: Option<Friction>,
    /// The intruder's width (m), which a `bed` value's period must leave room for.
    width: f64,
}

/// `[sweep]`: one variant per value, the base case with the swept parameter set (at
/// least two values, no two alike); without a sweep the base case alone.
fn sweep_variants(
    ctx: &Ctx,
    raw: &File,
    base: &Variant,
    scales: &Scales,
    width: f64,
) -> Result<Vec<Variant>, CaseError> {
    let Some(sw) = &raw.sweep else {
        return Ok(vec![base.clone()]);
    };
    if sw.values.len() < 2 {
        return Err(ctx.bad(
            "sweep.values",
            sw.values.len(),
            "a sweep needs at least two values",
        ));
    }
    let sb = SweepBase {
        ctx,
        parameter: &sw.parameter,
        base,
        scales,
        intruder: &raw.intruder,
        walls_friction: raw.walls.friction,
        width,
    };
    let mut variants: Vec<Variant> = Vec::new();
    for (k, v) in sw.values.iter().enumerate() {
        let field = format!("sweep.values[{k}]");
        let var = sweep_value(&sb, &field, k, v)?;
        if variants.iter().any(|o| o.label == var.label) {
            return Err(ctx.bad(&field, v.to_string(), "repeated sweep value"));
        }
        variants.push(var);
    }
    Ok(variants)
}

/// A sweep value as a number (a float or an integer).
fn sweep_number(sb: &SweepBase, field: &str, v: &toml::Value) -> Result<f64, CaseError> {
    v.as_float()
        .or_else(|| v.as_integer().map(|n| n as f64))
        .ok_or_else(|| {
            sb.ctx.bad(
                field,
                v.to_string(),
                format!("sweep over `{}` takes numbers", sb.parameter),
            )
        })
}

/// A sweep value as a string.
fn sweep_text(sb: &SweepBase, field: &str, v: &toml::Value) -> Result<String, CaseError> {
    v.as_str().map(str::to_string).ok_or_else(|| {
        sb.ctx.bad(
            field,
            v.to_string(),
            format!("sweep over `{}` takes strings", sb.parameter),
        )
    })
}

/// Sweep value `k` (`v`, at `field`) applied to the base case: the variant it runs,
/// labelled. A numeric value is in the units of the section it replaces and is the
/// variant's x; text and table values count 0, 1, ... as x.
fn sweep_value(
    sb: &SweepBase,
    field: &str,
    k: usize,
    v: &toml::Value,
) -> Result<Variant, CaseError> {
    let ctx = sb.ctx;
    let mut var = sb.base.clone();
    let label;
    match sb.parameter {
        "speed" => {
            let x = non_negative(ctx, field, sweep_number(sb, field, v)?)?;
            var.speed = x * sb.scales.velocity();
            var.x = x;
            label = format!("speed={x}");
        }
        "gravity" => {
            let x = positive(ctx, field, sweep_number(sb, field, v)?)?;
            var.gravity = x * sb.scales.g0;
            var.x = x;
            label = format!("gravity={x}");
        }
        "e_n" => {
            let x = unit_interval(ctx, field, sweep_number(sb, field, v)?)?;
            var.grains.e_n = x;
            var.intruder = intruder_material(ctx, sb.intruder, &var.grains)?;
            var.x = x;
            label = format!("e_n={x}");
        }
        "mu" => {
            let x = non_negative(ctx, field, sweep_number(sb, field, v)?)?;
            var.grains.mu = x;
            var.intruder = intruder_material(ctx, sb.intruder, &var.grains)?;
            var.x = x;
            label = format!("mu={x}");
        }
        "friction" => {
            let t = sweep_text(sb, field, v)?;
            var.grains.friction = match t.as_str() {
                "static" => Friction::Static,
                "kinetic" => Friction::Kinetic,
                _ => {
                    return Err(ctx.bad(field, t, "friction is \"static\" or \"kinetic\""));
                }
            };
            if sb.walls_friction.is_none() {
                var.walls.friction = var.grains.friction;
            }
            var.intruder = intruder_material(ctx, sb.intruder, &var.grains)?;
            var.x = k as f64;
            label = format!("friction={t}");
        }
        "friction_mu" => {
            label = sweep_friction_mu(sb, field, v, &mut var)?;
            var.x = k as f64;
        }
        "packing" => {
            let t = sweep_text(sb, field, v)?;
            var.packing = match t.as_str() {
                "random" => Packing::Random,
                "hexagonal" => Packing::Hexagonal,
                _ => {
                    return Err(ctx.bad(field, t, "packing is \"random\" or \"hexagonal\""));
                }
            };
            var.x = k as f64;
            label = format!("packing={t}");
        }
        "bed" => {
            // K Fig 11: a bed of another size and/or seed per variant.
            let (bed, l) = bed_value(ctx, field, v, sb.scales.d, sb.width)?;
            label = format!("count={},length={l},seed={}", bed.count, bed.seed);
            var.bed = Some(bed);
            var.x = k as f64;
        }
        other => {
            return Err(ctx.bad(
                "sweep.parameter",
                other,
                "one of speed, gravity, e_n, mu, friction, friction_mu, packing, bed",
            ));
        }
    }
    var.label = label;
    Ok(var)
}

/// A value of a `friction_mu` sweep set in `var`: mu and the friction model together
/// (K Figs 6, 21); returns the label.
fn sweep_friction_mu(
    sb: &SweepBase,
    field: &str,
    v: &toml::Value,
    var: &mut Variant,
) -> Result<String, CaseError> {
    let ctx = sb.ctx;
    let bad = || {
        ctx.bad(
            field,
            v.to_string(),
            "friction_mu takes tables { mu = NUMBER, friction = \"static\" | \"kinetic\" }",
        )
    };
    let t = v.as_table().ok_or_else(bad)?;
    if t.len() != 2 {
        return Err(bad());
    }
    let mu = t
        .get("mu")
        .and_then(|m| m.as_float().or_else(|| m.as_integer().map(|n| n as f64)))
        .ok_or_else(bad)?;
    let fr = t.get("friction").and_then(|f| f.as_str()).ok_or_else(bad)?;
    var.grains.mu = non_negative(ctx, &format!("{field}.mu"), mu)?;
    var.grains.friction = match fr {
        "static" => Friction::Static,
        "kinetic" => Friction::Kinetic,
        _ => return Err(bad()),
    };
    if sb.walls_friction.is_none() {
        var.walls.friction = var.grains.friction;
    }
    var.intruder = intruder_material(ctx, sb.intruder, &var.grains)?;
    Ok(format!("mu={mu},{fr}"))
}

/// A seed ensemble (`[bed] seeds`): every value once per seed, on that seed's bed (the
/// bed machinery of the `bed` sweep: one bed per BedKey), value-major. One bed: the
/// variants as they are.
fn seed_ensemble(variants: Vec<Variant>, raw: &File, bed: &BedParams) -> Vec<Variant> {
    if bed.seeds.is_empty() {
        return variants;
    }
    let mut out = Vec::new();
    for v in variants {
        for &s in &bed.seeds {
            let mut r = v.clone();
            r.label = if raw.sweep.is_some() {
                format!("{},seed={s}", v.label)
            } else {
                format!("seed={s}")
            };
            r.bed = Some(BedSize {
                count: raw.bed.count,
                length: bed.length,
                seed: s,
            });
            r.ensemble_value = Some(v.label.clone());
            out.push(r);
        }
    }
    out
}

/// What the claims are checked against: the case as validated so far.
struct ClaimScope<'a> {
    ctx: &'a Ctx,
    raw: &'a File,
    variants: &'a [Variant],
    /// `[bed] seeds`; empty for one bed.
    seeds: &'a [u64],
    /// The time step in tau_c.
    dt_tau: f64,
    /// `[bed]`'s periodic length (m).
    length: f64,
    d: f64,
}

/// `[claim]` / `[[claim]]`: each claim read, then checked against the sweep it compares
/// the variants of and, on a seed ensemble, against the rules registered for one.
fn validated_claims(sc: &ClaimScope) -> Result<Vec<Claim>, CaseError> {
    let ctx = sc.ctx;
    let claims = parse_claims(ctx, sc.raw.claim.as_ref())?;
    if !claims.is_empty() && sc.raw.sweep.is_none() {
        return Err(ctx.bad(
            "claim",
            "given",
            "a claim compares the variants of a [sweep]; add one",
        ));
    }
    for (k, claim) in claims.iter().enumerate() {
        let at = |f: &str| {
            if claims.len() == 1 {
                format!("claim.{f}")
            } else {
                format!("claim[{k}].{f}")
            }
        };
        claim_on_beds(sc, &at, claim)?;
        check_claim(sc, &at, claim)?;
    }
    Ok(claims)
}

/// Whether a claim is defined for one bed or a seed ensemble: `trend` and
/// `velocity_exponent_per_depth` are judged over beds, and on an ensemble only the
/// claims with a registered ensemble rule are (docs/impact2d.md). `at` names a field of
/// the claim.
fn claim_on_beds(
    sc: &ClaimScope,
    at: &impl Fn(&str) -> String,
    claim: &Claim,
) -> Result<(), CaseError> {
    if sc.seeds.is_empty() {
        let over_beds = match claim {
            Claim::VelocityExponentPerDepth { .. } => Some("velocity_exponent_per_depth"),
            Claim::Trend { .. } => Some("trend"),
            _ => None,
        };
        if let Some(kind) = over_beds {
            return Err(sc.ctx.bad(
                at("kind"),
                kind,
                "judged over beds: needs a seed ensemble ([bed] seeds)",
            ));
        }
    }
    if !sc.seeds.is_empty()
        && !matches!(
            claim,
            Claim::Increasing { .. }
                | Claim::Trend { .. }
                | Claim::Linear { .. }
                | Claim::VelocityExponentPerDepth { .. }
                | Claim::FieldOrder { .. }
        )
    {
        let kind = serde_json::to_value(claim)
            .ok()
            .and_then(|v| v["kind"].as_str().map(str::to_string))
            .unwrap_or_default();
        return Err(sc.ctx.bad(
            at("kind"),
            kind,
            "not defined on a seed ensemble ([bed] seeds): only `increasing`, `trend`, `linear`, `velocity_exponent_per_depth` and `field_order` have a registered ensemble rule (docs/impact2d.md)",
        ));
    }
    Ok(())
}

/// One claim's own fields, and what it needs of the sweep, the run and `[fields]`.
fn check_claim(
    sc: &ClaimScope,
    at: &impl Fn(&str) -> String,
    claim: &Claim,
) -> Result<(), CaseError> {
    let ctx = sc.ctx;
    match claim {
        Claim::Trend {
            min_slope,
            of,
            at: t,
            log_x,
            ..
        } => check_trend(sc, at, *min_slope, *of, *t, *log_x),
        Claim::Increasing {
            min_step,
            of,
            at: t,
        } => {
            non_negative(ctx, &at("min_step"), *min_step)?;
            read_time(ctx, &at("at"), *of, *t, sc.raw.simulation.duration)
        }
        Claim::EnergyNonIncreasing { max_rise } => {
            non_negative(ctx, &at("max_rise"), *max_rise).map(|_| ())
        }
        Claim::VelocityExponent {
            depths,
            half_width,
            min,
            max,
            engine_tol,
        } => {
            depth_bins(ctx, at, depths, *half_width, *min, *max, *engine_tol)?;
            velocity_exponent_sweep(sc, at)
        }
        Claim::VelocityExponentPerDepth {
            depths,
            half_width,
            min,
            max,
            min_passages,
            min_seeds,
            engine_tol,
        } => {
            depth_bins(ctx, at, depths, *half_width, *min, *max, *engine_tol)?;
            per_depth_samples(sc, at, *min_passages, *min_seeds)
        }
        Claim::ForceImpulsive {
            bin,
            peak_within,
            half_within,
        } => check_force_impulsive(sc, at, *bin, *peak_within, *half_within),
        Claim::ForceSimilar {
            window,
            max_spread_ratio,
            min_depth_spread,
        } => check_force_similar(sc, at, *window, *max_spread_ratio, *min_depth_spread),
        Claim::FieldOrder {
            quantity,
            larger,
            smaller,
            min_ratio,
            max_ratio,
        } => check_field_order(sc, at, *quantity, larger, smaller, *min_ratio, *max_ratio),
        Claim::SizeInsensitive { max_spread } => check_size_insensitive(sc, at, *max_spread),
        Claim::InterfaceSteadies {
            max_ratio,
            min_amplitude,
        } => check_interface_steadies(ctx, at, *max_ratio, *min_amplitude),
        Claim::Linear { from, r2_min } => check_linear(sc, at, *from, *r2_min),
    }
}

/// A `trend` claim: a slope over a numeric sweep of at least 3 values (docs/statistics.md,
/// "Rises"), positive values for a fit against ln x.
fn check_trend(
    sc: &ClaimScope,
    at: &impl Fn(&str) -> String,
    min_slope: f64,
    of: ClaimQuantity,
    t: Option<f64>,
    log_x: bool,
) -> Result<(), CaseError> {
    let ctx = sc.ctx;
    non_negative(ctx, &at("min_slope"), min_slope)?;
    read_time(ctx, &at("at"), of, t, sc.raw.simulation.duration)?;
    let param = sc
        .raw
        .sweep
        .as_ref()
        .map(|w| w.parameter.as_str())
        .unwrap_or("");
    if !["speed", "gravity", "e_n", "mu"].contains(&param) {
        return Err(ctx.bad(
            at("kind"),
            "trend",
            format!("a slope needs a numeric sweep (speed, gravity, e_n or mu), not `{param}`"),
        ));
    }
    let groups = sc.variants.iter().filter(|v| v.ensemble_value.is_some());
    let mut xs: Vec<f64> = groups.map(|v| v.x).collect();
    xs.sort_by(f64::total_cmp);
    xs.dedup();
    if xs.len() < 3 {
        return Err(ctx.bad(
            "sweep.values",
            xs.len(),
            "a trend is fitted over at least 3 values (2 are one step: use `increasing`)",
        ));
    }
    if log_x && xs.iter().any(|x| *x <= 0.0) {
        return Err(ctx.bad(at("log_x"), "true", "ln x needs every swept value > 0"));
    }
    Ok(())
}

/// The depth bins and exponent range of a Fig 29 claim (K Appendix): a positive half
/// width and engine tolerance, at least one bin, each inside the bed, and min < max.
fn depth_bins(
    ctx: &Ctx,
    at: &impl Fn(&str) -> String,
    depths: &[f64],
    half_width: f64,
    min: f64,
    max: f64,
    engine_tol: f64,
) -> Result<(), CaseError> {
    positive(ctx, &at("half_width"), half_width)?;
    positive(ctx, &at("engine_tol"), engine_tol)?;
    if depths.is_empty() {
        return Err(ctx.bad(at("depths"), "[]", "at least one depth bin"));
    }
    for (j, y) in depths.iter().enumerate() {
        if !(y.is_finite() && *y > half_width) {
            return Err(ctx.bad(
                format!("{}[{j}]", at("depths")),
                y,
                "a bin must lie inside the bed: centre > half_width",
            ));
        }
    }
    if !(min.is_finite() && max.is_finite() && min < max) {
        return Err(ctx.bad(at("max"), max, format!("must exceed min = {min}")));
    }
    Ok(())
}

/// A `velocity_exponent` claim's sweep (K Appendix, Fig 29): of the speed, with at
/// least 3 values.
fn velocity_exponent_sweep(sc: &ClaimScope, at: &impl Fn(&str) -> String) -> Result<(), CaseError> {
    let param = sc.raw.sweep.as_ref().map(|w| w.parameter.as_str());
    if param != Some("speed") || sc.variants.len() < 3 {
        return Err(sc.ctx.bad(
            at("kind"),
            "velocity_exponent",
            "a(u) needs a [sweep] of the speed with at least 3 values",
        ));
    }
    Ok(())
}

/// What a `velocity_exponent_per_depth` claim (K Appendix, Fig 29 read per depth) needs
/// beyond its bins: at least 3 passages for a slope with an error, between 2 and the
/// ensemble's seeds for an interval over beds, and a speed sweep with at least
/// `min_passages` values.
fn per_depth_samples(
    sc: &ClaimScope,
    at: &impl Fn(&str) -> String,
    min_passages: usize,
    min_seeds: usize,
) -> Result<(), CaseError> {
    let ctx = sc.ctx;
    if min_passages < 3 {
        return Err(ctx.bad(
            at("min_passages"),
            min_passages,
            "a slope with an error needs at least 3 passages",
        ));
    }
    if min_seeds < 2 || min_seeds > sc.seeds.len() {
        return Err(ctx.bad(
            at("min_seeds"),
            min_seeds,
            format!(
                "an interval over beds needs at least 2, and the ensemble has {} seeds",
                sc.seeds.len()
            ),
        ));
    }
    let param = sc.raw.sweep.as_ref().map(|w| w.parameter.as_str());
    let values = sc.raw.sweep.as_ref().map_or(0, |w| w.values.len());
    if param != Some("speed") || values < min_passages {
        return Err(ctx.bad(
            at("kind"),
            "velocity_exponent_per_depth",
            format!(
                "a(u) needs a [sweep] of the speed with at least min_passages = {min_passages} values"
            ),
        ));
    }
    Ok(())
}

/// A `force_impulsive` claim (K Fig 21): positive times, and bins that hold at least 2
/// intruder samples.
fn check_force_impulsive(
    sc: &ClaimScope,
    at: &impl Fn(&str) -> String,
    bin: f64,
    peak_within: f64,
    half_within: f64,
) -> Result<(), CaseError> {
    let ctx = sc.ctx;
    positive(ctx, &at("bin"), bin)?;
    positive(ctx, &at("peak_within"), peak_within)?;
    positive(ctx, &at("half_within"), half_within)?;
    if bin < 2.0 * sc.dt_tau * sc.raw.simulation.output_every as f64 {
        return Err(ctx.bad(
            at("bin"),
            bin,
            "a bin must hold at least 2 intruder samples (output_every * dt)",
        ));
    }
    Ok(())
}

/// A `force_similar` claim (K Fig 21): its window and margins, and at least 2 variants
/// to compare.
fn check_force_similar(
    sc: &ClaimScope,
    at: &impl Fn(&str) -> String,
    window: f64,
    max_spread_ratio: f64,
    min_depth_spread: f64,
) -> Result<(), CaseError> {
    let ctx = sc.ctx;
    positive(ctx, &at("window"), window)?;
    positive(ctx, &at("max_spread_ratio"), max_spread_ratio)?;
    non_negative(ctx, &at("min_depth_spread"), min_depth_spread)?;
    if sc.variants.len() < 2 {
        return Err(ctx.bad(at("kind"), "force_similar", "needs at least 2 variants"));
    }
    Ok(())
}

/// A `field_order` claim (K Figs 22-27): its ratios, two different variants by label,
/// and the `[fields]` snapshot its quantity is read from.
fn check_field_order(
    sc: &ClaimScope,
    at: &impl Fn(&str) -> String,
    quantity: FieldQuantity,
    larger: &str,
    smaller: &str,
    min_ratio: f64,
    max_ratio: Option<f64>,
) -> Result<(), CaseError> {
    let ctx = sc.ctx;
    positive(ctx, &at("min_ratio"), min_ratio)?;
    if let Some(m) = max_ratio
        && !(m.is_finite() && m > min_ratio)
    {
        return Err(ctx.bad(
            at("max_ratio"),
            m,
            format!("must exceed min_ratio = {min_ratio}"),
        ));
    }
    // On a seed ensemble the claim names sweep values (the labels without the seed).
    let name_of =
        |v: &Variant| -> String { v.ensemble_value.clone().unwrap_or_else(|| v.label.clone()) };
    for (f, l) in [("larger", larger), ("smaller", smaller)] {
        if !sc.variants.iter().any(|v| name_of(v) == l) {
            let mut names: Vec<String> = sc.variants.iter().map(name_of).collect();
            names.dedup();
            return Err(ctx.bad(
                at(f),
                l,
                format!("no such variant; the variants: {}", names.join(", ")),
            ));
        }
    }
    if larger == smaller {
        return Err(ctx.bad(at("smaller"), smaller, "must differ from `larger`"));
    }
    let f = sc.raw.fields.as_ref();
    let has = if quantity.is_network() {
        f.is_some_and(|f| !f.network_times.is_empty())
    } else {
        f.is_some_and(|f| f.affine_time.is_some())
    };
    if !has {
        return Err(ctx.bad(
            at("quantity"),
            format!("{quantity:?}"),
            if quantity.is_network() {
                "a B0 claim needs [fields] network_times"
            } else {
                "an affine or D2_min claim needs [fields] affine_time"
            },
        ));
    }
    Ok(())
}

/// A `size_insensitive` claim (K Sec. III, Fig 11): a `bed` sweep with at least 2 sizes
/// (count, length), each with at least 2 realizations.
fn check_size_insensitive(
    sc: &ClaimScope,
    at: &impl Fn(&str) -> String,
    max_spread: f64,
) -> Result<(), CaseError> {
    let ctx = sc.ctx;
    positive(ctx, &at("max_spread"), max_spread)?;
    let param = sc.raw.sweep.as_ref().map(|w| w.parameter.as_str());
    if param != Some("bed") {
        return Err(ctx.bad(
            at("kind"),
            "size_insensitive",
            "compares beds of different sizes: needs a [sweep] of `bed`",
        ));
    }
    let groups = size_groups(sc.variants, sc.raw.bed.count, sc.length);
    if groups.len() < 2 {
        return Err(ctx.bad(
            at("kind"),
            "size_insensitive",
            "needs at least 2 sizes (count, length) among the sweep's beds",
        ));
    }
    if let Some(((n, l), g)) = groups.iter().find(|g| g.1.len() < 2) {
        return Err(ctx.bad(
            at("kind"),
            "size_insensitive",
            format!(
                "the size count = {n}, length = {} has {} realization(s); every size needs at least 2 (seeds)",
                l / sc.d,
                g.len()
            ),
        ));
    }
    Ok(())
}

/// An `interface_steadies` claim (K Sec. III, Fig 12): positive margins, the ratio
/// below 1.
fn check_interface_steadies(
    ctx: &Ctx,
    at: &impl Fn(&str) -> String,
    max_ratio: f64,
    min_amplitude: f64,
) -> Result<(), CaseError> {
    positive(ctx, &at("max_ratio"), max_ratio)?;
    positive(ctx, &at("min_amplitude"), min_amplitude)?;
    if max_ratio >= 1.0 {
        return Err(ctx.bad(
            at("max_ratio"),
            max_ratio,
            "must be < 1: the depth below the interface would be allowed to oscillate as much as D",
        ));
    }
    Ok(())
}

/// A `linear` claim (K Fig 8b): r2_min in [0, 1], and at least 3 distinct sweep values
/// from `from` on.
fn check_linear(
    sc: &ClaimScope,
    at: &impl Fn(&str) -> String,
    from: f64,
    r2_min: f64,
) -> Result<(), CaseError> {
    let ctx = sc.ctx;
    finite(ctx, &at("from"), from)?;
    if !(0.0..=1.0).contains(&r2_min) {
        return Err(ctx.bad(at("r2_min"), r2_min, "must lie in [0, 1]"));
    }
    // Distinct values (a seed ensemble has one variant per seed of each).
    let mut xs: Vec<f64> = sc
        .variants
        .iter()
        .filter(|v| v.x >= from)
        .map(|v| v.x)
        .collect();
    xs.dedup();
    let n = xs.len();
    if n < 3 {
        return Err(ctx.bad(
            at("from"),
            from,
            format!(
                "only {n} sweep values are >= it; a line through fewer than 3 points always fits"
            ),
        ));
    }
    Ok(())
}

/// Every hexagonal bed's period L is a whole number of d, which its rows of touching
/// disks of diameter d fill: `[bed] length` (`bed_length`, in d), or a `bed` sweep
/// value's own.
fn hexagonal_lengths(
    ctx: &Ctx,
    variants: &[Variant],
    bed_length: f64,
    d: f64,
) -> Result<(), CaseError> {
    for (k, v) in variants.iter().enumerate() {
        if v.packing != Packing::Hexagonal {
            continue;
        }
        let (field, l) = match v.bed {
            Some(bed) if v.ensemble_value.is_none() => {
                (format!("sweep.values[{k}].length"), bed.length / d)
            }
            _ => ("bed.length".to_string(), bed_length),
        };
        if (l - l.round()).abs() > 1e-9 {
            return Err(ctx.bad(
                field,
                l,
                "a hexagonal bed needs L to be a whole number of d",
            ));
        }
    }
    Ok(())
}

/// `[compare]`: the native vs LAMMPS tolerances (defaults where absent), each positive.
fn tolerances(ctx: &Ctx, compare: Option<&Tolerances>) -> Result<Tolerances, CaseError> {
    let tolerances = compare.cloned().unwrap_or_default();
    positive(ctx, "compare.interface_rms", tolerances.interface_rms)?;
    positive(ctx, "compare.final_depth_abs", tolerances.final_depth_abs)?;
    positive(ctx, "compare.depth_rms", tolerances.depth_rms)?;
    positive(ctx, "compare.force_rel", tolerances.force_rel)?;
    positive(ctx, "compare.force_window", tolerances.force_window)?;
    positive(ctx, "compare.b0_distance", tolerances.b0_distance)?;
    positive(ctx, "compare.field_rel", tolerances.field_rel)?;
    Ok(tolerances)
}

/// `[[negative_control]]`: the controls an impact2d comparison can run, and what each
/// perturbation needs of the case (a sweep, a packing or `bed` sweep, the interface
/// tracers). `length` is `[bed]`'s period (m).
fn negative_controls(
    ctx: &Ctx,
    raw: &File,
    variants: &[Variant],
    track_interface: bool,
    length: f64,
) -> Result<Vec<super::NegativeControl>, CaseError> {
    // Wall disks are type 2, the intruder type 3 (a pair_friction control names them).
    let negative_controls =
        super::control::controls(ctx, &raw.negative_control, 3, IMPACT2D_GATES)?;
    super::control::check_applicable(
        ctx,
        &negative_controls,
        &super::control::Targets {
            spheres: None,
            clumps: false,
        },
    )?;
    if raw.sweep.is_none()
        && let Some(k) = negative_controls
            .iter()
            .position(|c| c.perturbation.sweep_ignored)
    {
        return Err(ctx.bad(
            format!("negative_control[{k}].perturbation.sweep_ignored"),
            true,
            "ignores a [sweep] the case does not have",
        ));
    }
    let bed_sweep = raw.sweep.as_ref().is_some_and(|w| w.parameter == "bed");
    for (k, c) in negative_controls.iter().enumerate() {
        let p = &c.perturbation;
        if p.sweep_ignored && bed_sweep {
            return Err(ctx.bad(
                format!("negative_control[{k}].perturbation.sweep_ignored"),
                true,
                "a bed sweep changes the beds themselves: each variant keeps its own bed, so ignoring the sweep would rerun it unchanged (use other_size_speed_factor)",
            ));
        }
        if p.packing_ignored && raw.sweep.as_ref().is_none_or(|w| w.parameter != "packing") {
            return Err(ctx.bad(
                format!("negative_control[{k}].perturbation.packing_ignored"),
                true,
                "runs every variant on the first variant's bed: needs a [sweep] of `packing`",
            ));
        }
        if p.interface_frozen_floor && !track_interface {
            return Err(ctx.bad(
                format!("negative_control[{k}].perturbation.interface_frozen_floor"),
                true,
                "replaces the interface tracers, which this case does not track (an interface_steadies claim or [analysis] track_interface = true)",
            ));
        }
        if p.other_size_speed_factor != 1.0
            && (!bed_sweep || size_groups(variants, raw.bed.count, length).len() < 2)
        {
            return Err(ctx.bad(
                format!("negative_control[{k}].perturbation.other_size_speed_factor"),
                p.other_size_speed_factor,
                "slows the variants of other sizes than the first: needs a [sweep] of `bed` with at least 2 sizes",
            ));
        }
    }
    Ok(negative_controls)
}

/// Variant indices grouped by size (count, length in m), in order of first appearance;
/// a variant without its own bed has `[bed]`'s.
fn size_groups(variants: &[Variant], count: usize, length: f64) -> Vec<((usize, f64), Vec<usize>)> {
    let mut out: Vec<((usize, f64), Vec<usize>)> = Vec::new();
    for (k, v) in variants.iter().enumerate() {
        let size = v.bed.map_or((count, length), |b| (b.count, b.length));
        match out.iter_mut().find(|g| g.0 == size) {
            Some(g) => g.1.push(k),
            None => out.push((size, vec![k])),
        }
    }
    out
}

/// `[bed] seed` (one bed) or `seeds` (an ensemble): (the seed of `[bed]`, the
/// ensemble's seeds or none). Exactly one of the two; an ensemble has at least 2
/// different seeds, each a whole number >= 0, and no `bed` sweep (which sets each
/// variant's seed itself).
fn bed_seeds(ctx: &Ctx, b: &BedIn, sweep: Option<&str>) -> Result<(u64, Vec<u64>), CaseError> {
    const EITHER: &str = "give `seed = S` (one bed) or `seeds = [S1, S2, ...]` (a seed ensemble)";
    let list = |v: &[toml::Value]| {
        format!(
            "[{}]",
            v.iter()
                .map(|x| x.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    match (b.seed, &b.seeds) {
        (Some(s), None) => Ok((s, Vec::new())),
        (None, None) => Err(ctx.bad("bed.seed", "missing", EITHER)),
        (Some(_), Some(v)) => Err(ctx.bad(
            "bed.seeds",
            list(v),
            format!("given together with bed.seed: {EITHER}, not both"),
        )),
        (None, Some(v)) => {
            if v.len() < 2 {
                return Err(ctx.bad(
                    "bed.seeds",
                    list(v),
                    "a seed ensemble needs at least 2 seeds (one bed is `seed = S`)",
                ));
            }
            if sweep == Some("bed") {
                return Err(ctx.bad(
                    "bed.seeds",
                    list(v),
                    "a `bed` sweep sets each variant's seed itself: give the realizations there, not as a seed ensemble",
                ));
            }
            let mut seeds: Vec<u64> = Vec::with_capacity(v.len());
            for (k, x) in v.iter().enumerate() {
                let field = format!("bed.seeds[{k}]");
                let s = match x.as_integer() {
                    Some(n) if n >= 0 => n as u64,
                    _ => return Err(ctx.bad(field, x.to_string(), "must be a whole number >= 0")),
                };
                if seeds.contains(&s) {
                    return Err(ctx.bad(
                        field,
                        s,
                        "repeated seed: each realization needs a bed of its own",
                    ));
                }
                seeds.push(s);
            }
            Ok((seeds[0], seeds))
        }
    }
}

/// The periodic length L of a bed, given in d, in m: positive and at least 5 d (fewer
/// grains across than that is no bed), for `[bed]` and every `bed` sweep value alike.
fn period_length(ctx: &Ctx, field: &str, l_d: f64, d: f64) -> Result<f64, CaseError> {
    let l_d = positive(ctx, field, l_d)?;
    if l_d < 5.0 {
        return Err(ctx.bad(field, l_d, "must be >= 5 d"));
    }
    Ok(l_d * d)
}

const NARROWER: &str = "the intruder must be narrower than 0.8 L";

/// Whether an intruder of this width (m) leaves room in a period of length L (m): its
/// periodic images must not meet across the boundary.
fn fits_period(width: f64, length: f64) -> bool {
    width <= 0.8 * length
}

/// One value of a `bed` sweep: `{ count = N, length = L, seed = S }` (L in d), checked
/// as `[bed]`'s own count, length and seed are; `width` is the intruder's (m). Also
/// returns L in d as written (for the variant's label).
fn bed_value(
    ctx: &Ctx,
    field: &str,
    v: &toml::Value,
    d: f64,
    width: f64,
) -> Result<(BedSize, f64), CaseError> {
    const FORM: &str = "a bed sweep takes tables { count = N, length = L (d), seed = S }";
    let t = v
        .as_table()
        .ok_or_else(|| ctx.bad(field, v.to_string(), FORM))?;
    if let Some(k) = t
        .keys()
        .find(|k| !["count", "length", "seed"].contains(&k.as_str()))
    {
        return Err(ctx.bad(
            format!("{field}.{k}"),
            &t[k],
            format!("unknown field; {FORM}"),
        ));
    }
    let get = |k: &str| {
        t.get(k)
            .ok_or_else(|| ctx.bad(format!("{field}.{k}"), "missing", FORM))
    };
    let whole = |k: &str, min: i64| -> Result<i64, CaseError> {
        let x = get(k)?;
        match x.as_integer() {
            Some(n) if n >= min => Ok(n),
            _ => Err(ctx.bad(
                format!("{field}.{k}"),
                x.to_string(),
                format!("must be a whole number >= {min}"),
            )),
        }
    };
    let count = whole("count", 1)? as usize;
    let seed = whole("seed", 0)? as u64;
    let lf = format!("{field}.length");
    let x = get("length")?;
    let l = x
        .as_float()
        .or_else(|| x.as_integer().map(|n| n as f64))
        .ok_or_else(|| ctx.bad(&lf, x.to_string(), "must be a number (d)"))?;
    let length = period_length(ctx, &lf, l, d)?;
    if !fits_period(width, length) {
        return Err(ctx.bad(&lf, l, NARROWER));
    }
    Ok((
        BedSize {
            count,
            length,
            seed,
        },
        l,
    ))
}

/// `[fields]` as steps: every time a whole number of steps inside the run.
fn fields(ctx: &Ctx, f: &FieldsIn, dt_tau: f64, n_steps: u64, d: f64) -> Result<Fields, CaseError> {
    let step = |field: &str, t: f64| -> Result<u64, CaseError> {
        let t = positive(ctx, field, t)?;
        let k = (t / dt_tau).round();
        if (t / dt_tau - k).abs() > 1e-6 {
            return Err(ctx.bad(
                field,
                t,
                format!("must be a whole number of time steps ({dt_tau} tau_c)"),
            ));
        }
        if k as u64 > n_steps {
            return Err(ctx.bad(field, t, "after the end of the run (simulation.duration)"));
        }
        Ok(k as u64)
    };
    let mut network_steps = Vec::new();
    for (k, t) in f.network_times.iter().enumerate() {
        network_steps.push(step(&format!("fields.network_times[{k}]"), *t)?);
    }
    if network_steps.windows(2).any(|w| w[0] >= w[1]) {
        return Err(ctx.bad(
            "fields.network_times",
            format!("{:?}", f.network_times),
            "must rise",
        ));
    }
    let threshold_max = positive(ctx, "fields.threshold_max", f.threshold_max.unwrap_or(6.0))?;
    let threshold_step = positive(
        ctx,
        "fields.threshold_step",
        f.threshold_step.unwrap_or(0.05),
    )?;
    if threshold_max / threshold_step > 1e5 || threshold_step >= threshold_max {
        return Err(ctx.bad(
            "fields.threshold_step",
            threshold_step,
            "must be below threshold_max, with at most 1e5 thresholds",
        ));
    }
    let affine = match (f.affine_time, f.affine_dt, f.affine_radius) {
        (None, None, None) => None,
        (Some(t), Some(dt), Some(r)) => {
            let b = step("fields.affine_time", t)?;
            let a_dt = step("fields.affine_dt", dt)?;
            if a_dt > b {
                return Err(ctx.bad(
                    "fields.affine_dt",
                    dt,
                    "reaches before the release (affine_time - affine_dt < 0)",
                ));
            }
            Some((b - a_dt, b, positive(ctx, "fields.affine_radius", r)? * d))
        }
        _ => {
            return Err(ctx.bad(
                "fields",
                "affine_time / affine_dt / affine_radius",
                "the affine analysis needs all three",
            ));
        }
    };
    if network_steps.is_empty() && affine.is_none() {
        return Err(ctx.bad(
            "fields",
            "{}",
            "asks for nothing: give network_times or affine_time",
        ));
    }
    Ok(Fields {
        network_steps,
        threshold_max,
        threshold_step,
        affine,
    })
}

/// How a bed is built: random polydisperse (K Sec. II) or a hexagonal lattice.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Packing {
    Random,
    Hexagonal,
}

/// Coefficients of one type pair in the units LAMMPS takes them: `k_n`, `k_t` in N/m,
/// `gamma_n`, `gamma_t` in 1/s (multiplied by m_eff inside the force law).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Coeffs {
    pub kn: f64,
    pub kt: f64,
    pub gamma_n: f64,
    pub gamma_t: f64,
    pub mu: f64,
}

impl Coeffs {
    /// The line this pair adds to a 2D scene's fingerprint
    /// (`experiments::impact2d::scene_hash`): every field by name, each number in Rust's
    /// shortest round-trip form. Written out field by field (the struct is destructured
    /// exhaustively, so a new field does not compile until it is placed here) instead of
    /// taken from `Debug`, whose output is not a format anything may be sealed by; the
    /// text is the one the sealed 2D records were fingerprinted with.
    pub(crate) fn fingerprint_line(&self) -> String {
        let Coeffs {
            kn,
            kt,
            gamma_n,
            gamma_t,
            mu,
        } = *self;
        format!(
            "Coeffs {{ kn: {}, kt: {}, gamma_n: {}, gamma_t: {}, mu: {} }}\n",
            shortest(kn),
            shortest(kt),
            shortest(gamma_n),
            shortest(gamma_t),
            shortest(mu)
        )
    }

    /// Tangential spring with history (K's model 1, "static friction") or not (model 2).
    pub(crate) fn history(&self) -> bool {
        self.kt > 0.0
    }
}

/// A number in Rust's shortest round-trip form (`1.0`, `0.5`, `1e-7`, `981.0000000000001`):
/// the exact value, read back to the same f64.
fn shortest(x: f64) -> String {
    format!("{x:?}")
}

/// `gamma_n = -2 ln(e_n) / tau_c` (K Sec. II), with `tau_c = pi sqrt(m_eff / k)` the
/// undamped binary collision time. The restitution that results is
/// [`restitution_of`]`(gamma_n, omega_0)`, slightly below e_n (K's relation neglects
/// the damping's shift of the collision time).
pub fn gamma_n_from_restitution(e_n: f64, tau_c: f64) -> f64 {
    -2.0 * e_n.ln() / tau_c
}

super::validated_case!(Impact2dCase);

#[cfg(test)]
mod tests {
    use super::Coeffs;

    /// The canonical line is the text the sealed 2D records were fingerprinted with
    /// (the struct's derived `Debug` of today), for the numbers the cases produce:
    /// round-off tails, zeros, exponents.
    #[test]
    fn the_fingerprint_line_is_the_sealed_text() {
        let c = Coeffs {
            kn: 981.0000000000001,
            kt: 0.0,
            gamma_n: 1954.587358225384,
            gamma_t: 1e-7,
            mu: 0.5,
        };
        assert_eq!(
            c.fingerprint_line(),
            "Coeffs { kn: 981.0000000000001, kt: 0.0, gamma_n: 1954.587358225384, gamma_t: 1e-7, mu: 0.5 }\n"
        );
        assert_eq!(c.fingerprint_line(), format!("{c:?}\n"));
    }
}
