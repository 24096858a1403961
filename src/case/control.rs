//! Negative controls as case files declare them: a deliberately wrong native run and
//! the gates it must make fail. A gate that no wrong physics can fail proves nothing, so
//! every kind of gated check has a control somewhere in the suites.
//!
//! ```toml
//! [[negative_control]]
//! name = "mu_gg = 0.3 instead of Table 2's 0.5"
//! must_fail = ["k_phi"]
//! perturbation = { pair_friction = { types = [1, 1], value = 0.3 } }
//! ```

use super::error::{CaseError, Ctx};
use serde::{Deserialize, Serialize};

/// What a check gates, as a stable identifier: case files name gates in their negative
/// controls and CI scripts may select on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Gate {
    /// Micro trajectories: positions, velocities, angular velocities.
    Position,
    Velocity,
    AngularVelocity,
    /// Micro clump cases: rotation angle between the engines' body orientations.
    Orientation,
    /// Penetration: steady-state slope, curve distance, regime boundaries, speed.
    KPhi,
    FdrDistance,
    RegimeBoundaries,
    QuasiStatic,
    /// A run against a published number (e.g. Feng et al. Table 3).
    Published,
    /// Impact: final depth and D(t) distance native vs reference, a paper's claim.
    FinalDepth,
    DepthSeries,
    Claim,
    /// Impact: the force on the intruder F(t) native vs reference (peak, impulse, series).
    IntruderForce,
    /// Impact: B0 curves of the force networks native vs reference (Kondic Figs 22-23).
    ForceNetwork,
    /// Impact: affine field and D2_min summaries native vs reference (Kondic Figs 24-27).
    DisplacementField,
    /// Impact: the interface displacement s(t) native vs reference (Kondic Fig 12).
    InterfaceSeries,
    /// Stress fields: phi native vs reference, (phi, K_phi) against MALT, unified fit.
    Phi,
    MaltK,
    MaltPhi,
    UnifiedFit,
    /// A negative control: passes only when the wrong physics made its gates fail.
    NegativeControl,
    /// Did the comparison see enough dynamics to mean anything (frames, contacts,
    /// points in a fitted range)?
    Coverage,
    /// A stage failed to produce a result (engine crash, bad reference, I/O).
    Run,
}

impl Gate {
    pub fn key(self) -> String {
        serde_json::to_value(self)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default()
    }
}

/// Deliberately wrong physics for the native engine. The default is the case as
/// written.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Perturbation {
    /// Every sliding friction coefficient multiplied by this.
    pub friction_factor: f64,
    /// Every rolling friction coefficient multiplied by this (3D).
    pub rolling_friction_factor: f64,
    /// Added to every restitution coefficient (capped at 1).
    pub restitution_shift: f64,
    /// Added to every Poisson ratio.
    pub poisson_shift: f64,
    /// Replaces the sliding friction of one type pair (0-based types), e.g. mu_gg.
    pub pair_friction: Option<(usize, usize, f64)>,
    /// 2D: static <-> kinetic friction model (k_t = 0.8 k_n <-> 0) in every contact.
    pub swap_friction_model: bool,
    /// 2D sweeps: every variant runs with the base case's parameters, i.e. the swept
    /// parameter is not applied; a claim over the sweep must then fail.
    pub sweep_ignored: bool,
    /// 2D `packing` sweeps: every variant runs the first variant's scene (its bed, i.e.
    /// its packing), so the preparation the sweep varies is ignored; a claim over the
    /// packings must then fail. (`sweep_ignored` cannot do this: a packing is a bed, and
    /// each variant keeps its own.)
    pub packing_ignored: bool,
    /// 2D `bed` sweeps (K Fig 11): the intruder's impact speed multiplied by this in
    /// every variant whose bed size (count, length) differs from the first variant's;
    /// the first size runs as written. A claim that the size does not matter must then
    /// fail.
    pub other_size_speed_factor: f64,
    /// 2D cases that track the interface (K Fig 12): the native engine tracks the bottom
    /// row of frozen wall disks instead of the interface tracers, so s(t) = 0 and the
    /// depth is taken relative to the container. A claim that the oscillations vanish
    /// relative to the interface must then fail.
    pub interface_frozen_floor: bool,
    /// Clumps: every principal moment of inertia multiplied by this.
    pub inertia_factor: f64,
    /// Clumps: members use their own sphere mass as contact mass instead of the body
    /// mass LIGGGHTS gives them (particleToInsert_multisphere.cpp:203).
    pub member_sphere_mass: bool,
    /// Not a control: the chaos baseline's replica (docs/statistics.md), every grain of
    /// the bed moved by one unit in the last place of its x coordinate. No case file can
    /// set it; `granval chaos` does.
    pub nudge_one_ulp: bool,
}

impl Default for Perturbation {
    fn default() -> Self {
        Perturbation {
            friction_factor: 1.0,
            rolling_friction_factor: 1.0,
            restitution_shift: 0.0,
            poisson_shift: 0.0,
            pair_friction: None,
            swap_friction_model: false,
            sweep_ignored: false,
            packing_ignored: false,
            other_size_speed_factor: 1.0,
            interface_frozen_floor: false,
            inertia_factor: 1.0,
            member_sphere_mass: false,
            nudge_one_ulp: false,
        }
    }
}

impl Perturbation {
    pub fn is_none(&self) -> bool {
        *self == Perturbation::default()
    }
}

/// One control of a case.
#[derive(Debug, Clone, Serialize)]
pub struct NegativeControl {
    pub name: String,
    pub perturbation: Perturbation,
    pub must_fail: Vec<Gate>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawControl {
    name: String,
    must_fail: Vec<Gate>,
    perturbation: RawPerturbation,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPerturbation {
    friction_factor: Option<f64>,
    rolling_friction_factor: Option<f64>,
    restitution_shift: Option<f64>,
    poisson_shift: Option<f64>,
    pair_friction: Option<RawPairFriction>,
    #[serde(default)]
    swap_friction_model: bool,
    #[serde(default)]
    sweep_ignored: bool,
    #[serde(default)]
    packing_ignored: bool,
    other_size_speed_factor: Option<f64>,
    #[serde(default)]
    interface_frozen_floor: bool,
    inertia_factor: Option<f64>,
    #[serde(default)]
    member_sphere_mass: bool,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPairFriction {
    types: [usize; 2],
    value: f64,
}

/// Validates the `[[negative_control]]` tables of a case with `n_types` atom types;
/// `gates` are the gates this case kind produces.
pub(crate) fn controls(
    ctx: &Ctx,
    raw: &[RawControl],
    n_types: usize,
    gates: &[Gate],
) -> Result<Vec<NegativeControl>, CaseError> {
    let mut out = Vec::with_capacity(raw.len());
    for (k, c) in raw.iter().enumerate() {
        let at = ControlAt { ctx, k, gates };
        at.name_and_gates(c)?;
        let pert = at.perturbation(&c.perturbation, n_types)?;
        out.push(NegativeControl {
            name: c.name.clone(),
            perturbation: pert,
            must_fail: c.must_fail.clone(),
        });
    }
    Ok(out)
}

/// Control number `k` of a case whose kind produces `gates`: where its errors point.
struct ControlAt<'a> {
    ctx: &'a Ctx,
    k: usize,
    gates: &'a [Gate],
}

impl ControlAt<'_> {
    /// The field `negative_control[k].<n>`.
    fn field(&self, n: &str) -> String {
        format!("negative_control[{}].{n}", self.k)
    }

    /// `perturbation.<n>`'s value `v`, if finite.
    fn finite(&self, n: &str, v: f64) -> Result<f64, CaseError> {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.ctx.bad(
                self.field(&format!("perturbation.{n}")),
                v,
                "must be a finite number",
            ))
        }
    }

    /// A switch set on a case kind without the gate `needs` it perturbs is refused.
    fn switch(&self, name: &str, set: bool, needs: Gate, why: &str) -> Result<bool, CaseError> {
        if set && !self.gates.contains(&needs) {
            Err(self
                .ctx
                .bad(self.field(&format!("perturbation.{name}")), true, why))
        } else {
            Ok(set)
        }
    }

    /// A control has a name and must fail at least one gate, each one this case kind
    /// produces (a gate it never runs could not fail).
    fn name_and_gates(&self, c: &RawControl) -> Result<(), CaseError> {
        let (ctx, gates) = (self.ctx, self.gates);
        if c.name.trim().is_empty() {
            return Err(ctx.bad(self.field("name"), &c.name, "must not be empty"));
        }
        if c.must_fail.is_empty() {
            return Err(ctx.bad(
                self.field("must_fail"),
                "[]",
                "name at least one gate the control must fail",
            ));
        }
        for g in &c.must_fail {
            if !gates.contains(g) {
                return Err(ctx.bad(
                    self.field("must_fail"),
                    g.key(),
                    format!(
                        "this case kind has no such gate; its gates: {}",
                        gates.iter().map(|g| g.key()).collect::<Vec<_>>().join(", ")
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The perturbation: the coefficients' changes ([`Self::coefficients`]), then the
    /// switches and factors of one case kind ([`Self::kind_specific`]); one that changes
    /// nothing is refused.
    fn perturbation(&self, p: &RawPerturbation, n_types: usize) -> Result<Perturbation, CaseError> {
        let mut pert = Perturbation::default();
        self.coefficients(p, n_types, &mut pert)?;
        self.kind_specific(p, &mut pert)?;
        if pert.is_none() {
            return Err(self.ctx.bad(
                self.field("perturbation"),
                "{}",
                "changes nothing: a control must perturb the physics",
            ));
        }
        Ok(pert)
    }

    /// Friction and rolling friction factors (>= 0; 2D disks have no rolling friction),
    /// restitution and Poisson shifts, and one pair's friction (types in 1..=`n_types`,
    /// value >= 0), written into `pert`.
    fn coefficients(
        &self,
        p: &RawPerturbation,
        n_types: usize,
        pert: &mut Perturbation,
    ) -> Result<(), CaseError> {
        let ctx = self.ctx;
        let f = |n: &str| self.field(n);
        if let Some(v) = p.friction_factor {
            let v = self.finite("friction_factor", v)?;
            if v < 0.0 {
                return Err(ctx.bad(f("perturbation.friction_factor"), v, "must be >= 0"));
            }
            pert.friction_factor = v;
        }
        if let Some(v) = p.rolling_friction_factor {
            if self.gates.contains(&Gate::Claim) {
                return Err(ctx.bad(
                    f("perturbation.rolling_friction_factor"),
                    v,
                    "2D disks have no rolling friction to change",
                ));
            }
            let v = self.finite("rolling_friction_factor", v)?;
            if v < 0.0 {
                return Err(ctx.bad(f("perturbation.rolling_friction_factor"), v, "must be >= 0"));
            }
            pert.rolling_friction_factor = v;
        }
        if let Some(v) = p.restitution_shift {
            pert.restitution_shift = self.finite("restitution_shift", v)?;
        }
        if let Some(v) = p.poisson_shift {
            pert.poisson_shift = self.finite("poisson_shift", v)?;
        }
        if let Some(pf) = &p.pair_friction {
            let [a, b] = pf.types;
            if a < 1 || b < 1 || a > n_types || b > n_types {
                return Err(ctx.bad(
                    f("perturbation.pair_friction.types"),
                    pf.types,
                    format!("types must be in 1..={n_types}"),
                ));
            }
            let v = self.finite("pair_friction.value", pf.value)?;
            if v < 0.0 {
                return Err(ctx.bad(f("perturbation.pair_friction.value"), v, "must be >= 0"));
            }
            pert.pair_friction = Some((a - 1, b - 1, v));
        }
        Ok(())
    }

    /// The friction model swap, the impact2d switches (sweep, packing, interface) and
    /// other-size speed factor (> 0, not 1), each only where its gate is produced, and
    /// the clumps' inertia factor (> 0) and member-sphere mass, written into `pert`.
    fn kind_specific(&self, p: &RawPerturbation, pert: &mut Perturbation) -> Result<(), CaseError> {
        let ctx = self.ctx;
        let f = |n: &str| self.field(n);
        pert.swap_friction_model = p.swap_friction_model;
        pert.sweep_ignored = self.switch(
            "sweep_ignored",
            p.sweep_ignored,
            Gate::Claim,
            "only impact2d cases have a sweep to ignore",
        )?;
        pert.packing_ignored = self.switch(
            "packing_ignored",
            p.packing_ignored,
            Gate::Claim,
            "only impact2d cases have a packing sweep to ignore",
        )?;
        if let Some(v) = p.other_size_speed_factor {
            if !self.gates.contains(&Gate::Claim) {
                return Err(ctx.bad(
                    f("perturbation.other_size_speed_factor"),
                    v,
                    "only impact2d cases have an intruder speed and beds of several sizes",
                ));
            }
            let v = self.finite("other_size_speed_factor", v)?;
            if v <= 0.0 || v == 1.0 {
                return Err(ctx.bad(
                    f("perturbation.other_size_speed_factor"),
                    v,
                    "must be > 0 and not 1 (1 changes nothing)",
                ));
            }
            pert.other_size_speed_factor = v;
        }
        pert.interface_frozen_floor = self.switch(
            "interface_frozen_floor",
            p.interface_frozen_floor,
            Gate::InterfaceSeries,
            "only impact2d cases track an interface",
        )?;
        if let Some(v) = p.inertia_factor {
            let v = self.finite("inertia_factor", v)?;
            if v <= 0.0 {
                return Err(ctx.bad(f("perturbation.inertia_factor"), v, "must be > 0"));
            }
            pert.inertia_factor = v;
        }
        pert.member_sphere_mass = p.member_sphere_mass;
        Ok(())
    }
}

/// What a case gives a perturbation to act on, so a control that would change nothing
/// (restitution 1.0 shifted up and capped at 1; friction scaled where every friction is
/// 0; inertia of clumps where there are none) is refused as "not applicable" when the
/// case is read, instead of running the case's own physics and reporting that "the
/// control did not bite".
pub(crate) struct Targets<'a> {
    /// Pair coefficients the 3D native engine perturbs (`Simulation::from_case_perturbed`),
    /// with the materials' Poisson ratios and whether a rolling model is on; `None`: the
    /// 2D engine, which perturbs friction and the friction model only
    /// (`physics::dem2d::impact::perturbed`).
    pub spheres: Option<(&'a super::PairTable, &'a [super::Material], bool)>,
    /// The case has rigid clumps (inertia and contact-mass perturbations need them).
    pub clumps: bool,
}

/// Refuses every perturbation field of `controls` that would leave the native physics
/// of the case unchanged or outside its physical range, naming the field and why.
pub(crate) fn check_applicable(
    ctx: &Ctx,
    controls: &[NegativeControl],
    t: &Targets,
) -> Result<(), CaseError> {
    for (k, c) in controls.iter().enumerate() {
        let p = &c.perturbation;
        let at = Applicable { ctx, k, t };
        at.restitution_and_poisson(p)?;
        at.friction(p)?;
        at.model_and_clumps(p)?;
    }
    Ok(())
}

/// The perturbation of control number `k`, judged against what the case gives it to act
/// on.
struct Applicable<'a> {
    ctx: &'a Ctx,
    k: usize,
    t: &'a Targets<'a>,
}

/// Why a 3D-only perturbation is refused on a 2D case.
const TWO_D: &str = "the 2D engine perturbs only friction (friction_factor, pair_friction, swap_friction_model) and the sweep, packing, size and interface switches";

impl Applicable<'_> {
    /// The field `negative_control[k].perturbation.<n>`.
    fn field(&self, n: &str) -> String {
        format!("negative_control[{}].perturbation.{n}", self.k)
    }

    /// `field`'s `value` is not applicable to this case, because `why`.
    fn na(&self, field: &str, value: f64, why: String) -> CaseError {
        self.ctx
            .bad(self.field(field), value, format!("not applicable: {why}"))
    }

    /// Restitution and Poisson shifts need the 3D engine; a shifted restitution must
    /// change some pair (it is capped at 1) and stay in (0, 1], a shifted Poisson ratio
    /// stay in (-1, 0.5).
    fn restitution_and_poisson(&self, p: &Perturbation) -> Result<(), CaseError> {
        if p.restitution_shift != 0.0 {
            let Some((pairs, _, _)) = self.t.spheres else {
                return Err(self.na("restitution_shift", p.restitution_shift, TWO_D.into()));
            };
            let shifted: Vec<f64> = pairs
                .restitution
                .iter()
                .map(|e| (e + p.restitution_shift).min(1.0))
                .collect();
            if shifted.iter().zip(&pairs.restitution).all(|(s, e)| s == e) {
                return Err(self.na(
                    "restitution_shift",
                    p.restitution_shift,
                    format!(
                        "every restitution coefficient of the case ({:?}) is already 1 and a shifted one is capped at 1, so the control would run the case's own physics; shift down or perturb something else",
                        pairs.restitution
                    ),
                ));
            }
            if let Some(s) = shifted.iter().find(|s| **s <= 0.0) {
                return Err(self.na(
                    "restitution_shift",
                    p.restitution_shift,
                    format!("a shifted restitution coefficient would be {s}, not in (0, 1]"),
                ));
            }
        }
        if p.poisson_shift != 0.0 {
            let Some((_, materials, _)) = self.t.spheres else {
                return Err(self.na("poisson_shift", p.poisson_shift, TWO_D.into()));
            };
            if let Some(m) = materials.iter().find(|m| {
                let nu = m.poisson_ratio + p.poisson_shift;
                !(nu > -1.0 && nu < 0.5)
            }) {
                return Err(self.na(
                    "poisson_shift",
                    p.poisson_shift,
                    format!(
                        "a Poisson ratio of {} would become {}, outside (-1, 0.5)",
                        m.poisson_ratio,
                        m.poisson_ratio + p.poisson_shift
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Sliding and rolling friction of the 3D engine: scaling needs a nonzero
    /// coefficient (and a rolling model for rolling friction), a pair's new value must
    /// differ from its own.
    fn friction(&self, p: &Perturbation) -> Result<(), CaseError> {
        if p.friction_factor != 1.0
            && let Some((pairs, _, _)) = self.t.spheres
            && pairs.friction.iter().all(|m| *m == 0.0)
        {
            return Err(self.na(
                "friction_factor",
                p.friction_factor,
                "every sliding friction coefficient of the case is 0, so scaling it changes nothing".into(),
            ));
        }
        if let Some((a, b, v)) = p.pair_friction
            && let Some((pairs, _, _)) = self.t.spheres
            && pairs.friction[pairs.idx(a, b)] == v
        {
            return Err(self.na(
                "pair_friction.value",
                v,
                format!(
                    "types [{}, {}] already have sliding friction {v}",
                    a + 1,
                    b + 1
                ),
            ));
        }
        if p.rolling_friction_factor != 1.0
            && let Some((pairs, _, rolling)) = self.t.spheres
        {
            if !rolling {
                return Err(self.na(
                    "rolling_friction_factor",
                    p.rolling_friction_factor,
                    "the case has no rolling friction model (models.rolling = \"none\")".into(),
                ));
            }
            if pairs.rolling_friction.iter().all(|m| *m == 0.0) {
                return Err(self.na(
                    "rolling_friction_factor",
                    p.rolling_friction_factor,
                    "every rolling friction coefficient of the case is 0, so scaling it changes nothing".into(),
                ));
            }
        }
        Ok(())
    }

    /// The friction model swap exists only in the 2D engine; inertia and member-sphere
    /// mass perturbations need rigid clumps.
    fn model_and_clumps(&self, p: &Perturbation) -> Result<(), CaseError> {
        if p.swap_friction_model && self.t.spheres.is_some() {
            return Err(self.ctx.bad(
                self.field("swap_friction_model"),
                true,
                "not applicable: only the 2D engine has a static and a kinetic friction model to swap",
            ));
        }
        if (p.inertia_factor != 1.0 || p.member_sphere_mass) && !self.t.clumps {
            let (field, value) = if p.inertia_factor != 1.0 {
                ("inertia_factor", p.inertia_factor)
            } else {
                ("member_sphere_mass", 1.0)
            };
            return Err(self.na(
                field,
                value,
                "the case has no rigid clumps, whose inertia and contact mass this perturbs".into(),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod applicable_tests {
    use super::*;
    use crate::case::{Material, PairTable};

    fn pairs(e: f64, mu: f64) -> PairTable {
        PairTable {
            n_types: 1,
            restitution: vec![e],
            friction: vec![mu],
            rolling_friction: vec![0.0],
        }
    }

    fn control(p: Perturbation) -> NegativeControl {
        NegativeControl {
            name: "c".into(),
            perturbation: p,
            must_fail: vec![Gate::Velocity],
        }
    }

    fn check(p: Perturbation, table: &PairTable) -> Result<(), String> {
        let m = [Material {
            youngs_modulus: 1e7,
            shear_modulus: 1e7 / 2.6,
            poisson_ratio: 0.3,
        }];
        check_applicable(
            &Ctx {
                file: "c.toml".into(),
            },
            &[control(p)],
            &Targets {
                spheres: Some((table, &m, false)),
                clumps: false,
            },
        )
        .map_err(|e| e.to_string())
    }

    /// e = 1.0 + 0.05 is capped back to 1: the control is not applicable, said when the
    /// case is read; e = 0.9 + 0.05 changes the physics and is accepted.
    #[test]
    fn a_clamped_restitution_shift_is_not_applicable() {
        let up = Perturbation {
            restitution_shift: 0.05,
            ..Perturbation::default()
        };
        let e = check(up, &pairs(1.0, 0.5)).unwrap_err();
        assert!(
            e.contains("negative_control[0].perturbation.restitution_shift")
                && e.contains("not applicable")
                && e.contains("capped at 1"),
            "{e}"
        );
        assert!(check(up, &pairs(0.9, 0.5)).is_ok());
        let down = Perturbation {
            restitution_shift: -0.95,
            ..Perturbation::default()
        };
        assert!(
            check(down, &pairs(0.9, 0.5))
                .unwrap_err()
                .contains("not in (0, 1]")
        );
    }

    #[test]
    fn perturbations_of_absent_physics_are_not_applicable() {
        let fric = Perturbation {
            friction_factor: 2.0,
            ..Perturbation::default()
        };
        assert!(
            check(fric, &pairs(0.5, 0.0))
                .unwrap_err()
                .contains("not applicable")
        );
        assert!(check(fric, &pairs(0.5, 0.3)).is_ok());
        let roll = Perturbation {
            rolling_friction_factor: 2.0,
            ..Perturbation::default()
        };
        assert!(
            check(roll, &pairs(0.5, 0.3))
                .unwrap_err()
                .contains("no rolling")
        );
        let inertia = Perturbation {
            inertia_factor: 2.0,
            ..Perturbation::default()
        };
        assert!(
            check(inertia, &pairs(0.5, 0.3))
                .unwrap_err()
                .contains("no rigid clumps")
        );
        let nu = Perturbation {
            poisson_shift: 0.3,
            ..Perturbation::default()
        };
        assert!(
            check(nu, &pairs(0.5, 0.3))
                .unwrap_err()
                .contains("outside (-1, 0.5)")
        );
    }
}

/// In words, as reports print it: only what differs from the case as written, e.g.
/// "friction x 0.8, restitution + 0.05" (never the struct's field dump).
impl std::fmt::Display for Perturbation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let d = Perturbation::default();
        let mut parts: Vec<String> = Vec::new();
        if self.friction_factor != d.friction_factor {
            parts.push(format!("friction x {}", self.friction_factor));
        }
        if self.rolling_friction_factor != d.rolling_friction_factor {
            parts.push(format!(
                "rolling friction x {}",
                self.rolling_friction_factor
            ));
        }
        if self.restitution_shift != d.restitution_shift {
            parts.push(format!(
                "restitution {:+} (at most 1)",
                self.restitution_shift
            ));
        }
        if self.poisson_shift != d.poisson_shift {
            parts.push(format!("Poisson ratio {:+}", self.poisson_shift));
        }
        if let Some((a, b, v)) = self.pair_friction {
            parts.push(format!("friction of types {}-{} = {v}", a + 1, b + 1));
        }
        if self.swap_friction_model {
            parts.push("static and kinetic friction models swapped".into());
        }
        if self.sweep_ignored {
            parts.push("the swept parameter not applied".into());
        }
        if self.packing_ignored {
            parts.push("every variant on the first variant's packing".into());
        }
        if self.other_size_speed_factor != d.other_size_speed_factor {
            parts.push(format!(
                "impact speed x {} on beds of another size",
                self.other_size_speed_factor
            ));
        }
        if self.interface_frozen_floor {
            parts.push("the frozen floor tracked instead of the interface".into());
        }
        if self.inertia_factor != d.inertia_factor {
            parts.push(format!("moments of inertia x {}", self.inertia_factor));
        }
        if self.member_sphere_mass {
            parts.push("clump members with their own sphere mass as contact mass".into());
        }
        if self.nudge_one_ulp {
            parts.push("every grain moved by one ulp in x".into());
        }
        if parts.is_empty() {
            f.write_str("none (the case as written)")
        } else {
            f.write_str(&parts.join(", "))
        }
    }
}

#[cfg(test)]
mod display_tests {
    use super::*;

    /// Reports describe a control in words, never as a Rust field dump.
    #[test]
    fn a_perturbation_reads_as_words() {
        let p = Perturbation {
            friction_factor: 0.8,
            pair_friction: Some((0, 1, 0.3)),
            restitution_shift: 0.05,
            ..Perturbation::default()
        };
        assert_eq!(
            p.to_string(),
            "friction x 0.8, restitution +0.05 (at most 1), friction of types 1-2 = 0.3"
        );
        assert_eq!(
            Perturbation::default().to_string(),
            "none (the case as written)"
        );
        assert!(!p.to_string().contains("Perturbation"));
    }
}
