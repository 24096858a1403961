//! The granular contact law of LIGGGHTS 3.8 `model hertz tangential history
//! rolling_friction cdt|epsd2`, written from its documented semantics and the contact
//! model headers (normal_model_hertz.h, tangential_model_history.h,
//! rolling_model_cdt.h, rolling_model_epsd2.h, surface_model_default.h).
//!
//! Physics in Feng et al. terms (003_7b2069b9a928ac9b.txt): eq 2 (Hertz normal force
//! with damping), eq 3 (tangential spring with Coulomb cap, damping only while sticking),
//! eq 4 (CDT rolling torque), Table 1 (stiffness and damping from E, nu, e).
//! The law is split into LIGGGHTS' sub-models, each an `#[inline(always)]` function
//! mirroring one header: [`surface_default`], [`normal_hertz`], [`tangential_history`],
//! [`rolling_cdt`], [`rolling_epsd2`]; [`evaluate`] calls them in the order of
//! contact_models.h, so every floating-point operation happens in the same order as in
//! LIGGGHTS. One function serves particle-particle and particle-wall contacts, as in
//! LIGGGHTS, so the two cannot drift apart.
//!
//! The functions are generic over [`Real`]: `f64` for one contact, or
//! [`super::lanes::F4`] for four pair contacts at once in SIMD lanes. A lane performs
//! exactly the IEEE operations of the scalar law in the same order (no fused
//! multiply-add, no reassociation), and every branch of the law is evaluated on both
//! sides and selected per lane, so both give the same bits (tested).

use crate::case::RollingModel;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// sqrt(5/6) as LIGGGHTS spells it; Table 1's damping prefactor 2 sqrt(5/6) beta.
const SQRT_FIVE_OVER_SIX: f64 = 0.912_870_929_175_276_9;

/// A number the contact law computes with: `f64`, or several `f64` lanes processed
/// with the same IEEE operations.
pub(crate) trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// Per-lane condition.
    type Mask: Copy;
    fn splat(v: f64) -> Self;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    /// `self > o` (false if either is NaN).
    fn gt(self, o: Self) -> Self::Mask;
    /// `self != o` (true if either is NaN).
    fn ne(self, o: Self) -> Self::Mask;
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    fn uniform(b: bool) -> Self::Mask;
    /// Whether any lane is set (work only some lanes need can then be skipped for all).
    fn any(m: Self::Mask) -> bool;
    /// `a` where `m`, else `b`.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
}

impl Real for f64 {
    type Mask = bool;
    #[inline(always)]
    fn splat(v: f64) -> f64 {
        v
    }
    #[inline(always)]
    fn sqrt(self) -> f64 {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> f64 {
        f64::abs(self)
    }
    #[inline(always)]
    fn gt(self, o: f64) -> bool {
        self > o
    }
    #[inline(always)]
    fn ne(self, o: f64) -> bool {
        self != o
    }
    #[inline(always)]
    fn and(a: bool, b: bool) -> bool {
        a && b
    }
    #[inline(always)]
    fn uniform(b: bool) -> bool {
        b
    }
    #[inline(always)]
    fn any(m: bool) -> bool {
        m
    }
    #[inline(always)]
    fn select(m: bool, a: f64, b: f64) -> f64 {
        if m { a } else { b }
    }
}

/// A 3-vector of [`Real`]s; `V3<f64>` is [`crate::numerics::vec3::V3`].
pub(crate) type V3<T = f64> = [T; 3];

#[inline(always)]
fn add<T: Real>(a: V3<T>, b: V3<T>) -> V3<T> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline(always)]
fn sub<T: Real>(a: V3<T>, b: V3<T>) -> V3<T> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline(always)]
fn scale<T: Real>(a: V3<T>, s: T) -> V3<T> {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline(always)]
fn dot<T: Real>(a: V3<T>, b: V3<T>) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline(always)]
fn norm<T: Real>(a: V3<T>) -> T {
    dot(a, a).sqrt()
}
#[inline(always)]
fn select3<T: Real>(m: T::Mask, a: V3<T>, b: V3<T>) -> V3<T> {
    [
        T::select(m, a[0], b[0]),
        T::select(m, a[1], b[1]),
        T::select(m, a[2], b[2]),
    ]
}

/// Effective properties of a type pair, precomputed once per case
/// (LIGGGHTS global_properties: createYeff, createGeff, createBetaEff).
#[derive(Debug, Clone, Copy)]
pub(crate) struct PairCoeffs<T = f64> {
    /// 1/Y* = (1-nu_i^2)/E_i + (1-nu_j^2)/E_j (Table 1).
    pub yeff: T,
    /// 1/G* = 2(2-nu_i)(1+nu_i)/E_i + 2(2-nu_j)(1+nu_j)/E_j.
    pub geff: T,
    /// beta = ln e / sqrt(ln^2 e + pi^2) (Table 1).
    pub betaeff: T,
    pub mu: T,
    pub mu_r: T,
}

impl PairCoeffs {
    pub fn new(
        e_i: f64,
        nu_i: f64,
        e_j: f64,
        nu_j: f64,
        restitution: f64,
        mu: f64,
        mu_r: f64,
    ) -> Self {
        let yeff = 1.0 / ((1.0 - nu_i * nu_i) / e_i + (1.0 - nu_j * nu_j) / e_j);
        let geff = 1.0
            / (2.0 * (2.0 - nu_i) * (1.0 + nu_i) / e_i + 2.0 * (2.0 - nu_j) * (1.0 + nu_j) / e_j);
        let ln_e = restitution.ln();
        let betaeff = ln_e / (ln_e * ln_e + std::f64::consts::PI * std::f64::consts::PI).sqrt();
        PairCoeffs {
            yeff,
            geff,
            betaeff,
            mu,
            mu_r,
        }
    }
}

/// Geometry and kinematics of one touching contact, seen from particle i.
/// For walls `radj`, `omega_j` are unused and `vel_j` is the wall velocity.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ContactGeom<T = f64> {
    /// x_i - x_j (pair) or wall-to-particle vector (wall); |delta| = r.
    pub delta: V3<T>,
    pub r: T,
    pub radi: T,
    pub radj: T,
    pub is_wall: bool,
    pub meff: T,
    pub vel_i: V3<T>,
    pub vel_j: V3<T>,
    pub omega_i: V3<T>,
    pub omega_j: V3<T>,
}

/// Per-contact state carried between steps (LIGGGHTS' contact history).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg(test)]
pub(crate) struct History {
    /// Accumulated tangential displacement ("shearx/y/z").
    pub shear: V3,
    /// Previous rolling torque of EPSD2 ("r_torquex_old"...).
    pub roll: V3,
}

/// Force on i and torques on i and j (force on j is the negative; walls ignore torque_j).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct ContactForce<T = f64> {
    pub f_i: V3<T>,
    pub torque_i: V3<T>,
    pub torque_j: V3<T>,
}

/// What the surface model hands to the normal, tangential and rolling models: the
/// fields of LIGGGHTS' `SurfacesIntersectData` that surface_model_default.h sets
/// (plus `en`, set by the caller there and here).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Surface<T = f64> {
    /// Unit normal `delta / r`, pointing to particle i.
    pub en: V3<T>,
    /// Overlap `radsum - r` (radsum = r_i for a wall).
    pub deltan: T,
    /// Normal relative velocity `(v_i - v_j) . en`.
    pub vn: T,
    /// Contact rotation rate ("wr1..3"): `(c_i w_i + c_j w_j) / r`, `c = r - deltan / 2`.
    pub wr: V3<T>,
    /// Tangential relative velocity at the contact point ("vtr1..3").
    pub vtr: V3<T>,
    /// Lever arms `r_i - deltan / 2`, `r_j - deltan / 2` (0 for a wall).
    pub cri: T,
    pub crj: T,
}

/// Output of the normal model that the tangential and rolling models read
/// (LIGGGHTS' `sidata.Fn`, `kn`, `kt`, `gammat`), and the effective radius R*.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Normal<T = f64> {
    /// Total normal force `k_n delta_n - gamma_n v_n` (signed, not clamped).
    pub fn_total: T,
    pub kn: T,
    pub kt: T,
    pub gammat: T,
    pub reff: T,
}

/// Tangential force on i and the torques it exerts on i and j.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Tangential<T = f64> {
    pub ft: V3<T>,
    pub torque_i: V3<T>,
    pub torque_j: V3<T>,
}

/// Contact geometry and relative kinematics, LIGGGHTS surface_model_default.h
/// (`SurfaceModel<SURFACE_DEFAULT>::surfacesIntersect`): normal, overlap, normal
/// velocity, the contact rotation rate and the tangential velocity at the contact
/// point that Feng et al. eq 3 integrates into the shear displacement.
///
/// Walls: `wr = w_i (c_i / r)` here, where the header has `(c_i w_i) / r`; the two can
/// differ in the last bit. Kept as it was, so results stay identical to earlier runs.
#[inline(always)]
pub(crate) fn surface_default<T: Real>(g: &ContactGeom<T>) -> Surface<T> {
    let rinv = T::splat(1.0) / g.r;
    let en = scale(g.delta, rinv);
    let radsum = if g.is_wall { g.radi } else { g.radi + g.radj };
    let deltan = radsum - g.r;

    // Relative velocities at the contact point.
    let vr = sub(g.vel_i, g.vel_j);
    let vn = dot(vr, en);
    let vt = sub(vr, scale(en, vn));
    let half = T::splat(0.5);
    let (wr, cri, crj) = if g.is_wall {
        let cr = g.radi - half * deltan;
        (scale(g.omega_i, cr * rinv), cr, T::splat(0.0))
    } else {
        let cri = g.radi - half * deltan;
        let crj = g.radj - half * deltan;
        (
            scale(add(scale(g.omega_i, cri), scale(g.omega_j, crj)), rinv),
            cri,
            crj,
        )
    };
    let d = g.delta;
    let vtr = [
        vt[0] - (d[2] * wr[1] - d[1] * wr[2]),
        vt[1] - (d[0] * wr[2] - d[2] * wr[0]),
        vt[2] - (d[1] * wr[0] - d[0] * wr[1]),
    ];
    Surface {
        en,
        deltan,
        vn,
        wr,
        vtr,
        cri,
        crj,
    }
}

/// Hertz normal force with viscous damping, Feng et al. eq 2 with Table 1's
/// coefficients: `k_n = 4/3 Y* sqrt(R* d)`, `gamma_n = -2 sqrt(5/6) beta sqrt(S_n m*)`,
/// `S_n = 2 Y* sqrt(R* d)`; also the tangential stiffness `k_t = S_t = 8 G* sqrt(R* d)`
/// and damping the tangential model uses. Mirrors LIGGGHTS normal_model_hertz.h
/// (`NormalModel<HERTZ>::surfacesIntersect`, `tangential_damping on`, `limitForce off`).
/// The force on i is `fn_total * en`.
#[inline(always)]
pub(crate) fn normal_hertz<T: Real>(
    g: &ContactGeom<T>,
    s: &Surface<T>,
    c: &PairCoeffs<T>,
) -> Normal<T> {
    let reff = if g.is_wall {
        g.radi
    } else {
        g.radi * g.radj / (g.radi + g.radj)
    };
    let sqrtval = (reff * s.deltan).sqrt();
    let sn = T::splat(2.0) * c.yeff * sqrtval;
    let st = T::splat(8.0) * c.geff * sqrtval;
    let kn = T::splat(4.0 / 3.0) * c.yeff * sqrtval;
    let kt = st;
    let damp = T::splat(-2.0 * SQRT_FIVE_OVER_SIX) * c.betaeff;
    let gamman = damp * (sn * g.meff).sqrt();
    let gammat = damp * (st * g.meff).sqrt();
    let fn_total = -gamman * s.vn + kn * s.deltan;
    Normal {
        fn_total,
        kn,
        kt,
        gammat,
        reff,
    }
}

/// Tangential spring with history, Coulomb cap and damping only while sticking, Feng et
/// al. eq 3. Mirrors LIGGGHTS tangential_model_history.h
/// (`TangentialModel<TANGENTIAL_HISTORY>::surfacesIntersect`): the shear displacement is
/// advanced by `vtr dt` and projected onto the tangent plane (only when
/// `update_history`), `F_t = -k_t shear`, capped at `mu |F_n|` with the shear rescaled to
/// the cap, else `- gamma_t vtr` is added; torques `-c_i en x F_t`, `-c_j en x F_t`.
#[inline(always)]
pub(crate) fn tangential_history<T: Real>(
    s: &Surface<T>,
    n: &Normal<T>,
    c: &PairCoeffs<T>,
    dt: f64,
    shear: &mut V3<T>,
    update_history: bool,
) -> Tangential<T> {
    let (en, vtr, kt) = (s.en, s.vtr, n.kt);
    if update_history {
        *shear = add(*shear, scale(vtr, T::splat(dt)));
        let rsht = dot(*shear, en);
        *shear = sub(*shear, scale(en, rsht));
    }
    let shrmag = norm(*shear);
    let ft_ela = scale(*shear, -kt);
    let ft_shear = kt * shrmag;
    let ft_friction = c.mu * n.fn_total.abs();
    // Sticking: the damping -gamma_t vtr added. Sliding: F_t rescaled onto the cap
    // (zero if there is no shear to rescale) and the shear set to -F_t / k_t
    // component-wise, the same division LIGGGHTS performs. Lanes compute both and keep
    // one; the sliding side only when some lane slides.
    let slide = ft_shear.gt(ft_friction);
    let ft_stick = sub(ft_ela, scale(vtr, n.gammat));
    let ft = if T::any(slide) {
        let nonzero = shrmag.ne(T::splat(0.0));
        let ft_cap = scale(ft_ela, ft_friction / ft_shear);
        if update_history {
            let rescaled = [-ft_cap[0] / kt, -ft_cap[1] / kt, -ft_cap[2] / kt];
            *shear = select3(T::and(slide, nonzero), rescaled, *shear);
        }
        select3(
            slide,
            select3(nonzero, ft_cap, [T::splat(0.0); 3]),
            ft_stick,
        )
    } else {
        ft_stick
    };
    let tor = [
        en[1] * ft[2] - en[2] * ft[1],
        en[2] * ft[0] - en[0] * ft[2],
        en[0] * ft[1] - en[1] * ft[0],
    ];
    Tangential {
        ft,
        torque_i: scale(tor, -s.cri),
        torque_j: scale(tor, -s.crj),
    }
}

/// Constant directional torque (CDT) rolling resistance, Feng et al. eq 4:
/// magnitude `mu_r k_n delta_n R*` along the relative rotation, without its torsional
/// (normal) part. Mirrors LIGGGHTS rolling_model_cdt.h
/// (`RollingModel<ROLLING_CDT>::surfacesIntersect`, `torsionTorque off`): pairs use
/// `w_i - w_j`, walls the contact rotation rate `wr` (same direction as `w_i`). Returns
/// the torque subtracted from i and added to j, and where it applies (not where
/// nothing rotates).
#[inline(always)]
pub(crate) fn rolling_cdt<T: Real>(
    g: &ContactGeom<T>,
    s: &Surface<T>,
    n: &Normal<T>,
    c: &PairCoeffs<T>,
) -> (T::Mask, V3<T>) {
    let w = if g.is_wall {
        s.wr
    } else {
        sub(g.omega_i, g.omega_j)
    };
    let wmag = norm(w);
    let (en, reff) = (s.en, n.reff);
    let t = if g.is_wall {
        let fnel = s.deltan * n.kn;
        [
            c.mu_r * fnel * w[0] / wmag * reff,
            c.mu_r * fnel * w[1] / wmag * reff,
            c.mu_r * fnel * w[2] / wmag * reff,
        ]
    } else {
        scale(w, c.mu_r * n.kn * s.deltan * reff / wmag)
    };
    // No torsional component (torsionTorque off).
    let tn = dot(t, en);
    (wmag.gt(T::splat(0.0)), sub(t, scale(en, tn)))
}

/// Elastic-plastic spring-dashpot rolling resistance (EPSD2, no dashpot): a rolling
/// spring `k_r = k_t R*^2` on the tangential part of the relative rotation, accumulated
/// in `roll` and capped at `mu_r |F_n| R*` (the torque form of Feng et al. eq 4's
/// limit). Mirrors LIGGGHTS rolling_model_epsd2.h (`calcRollTorque`, `torsionTorque
/// off`); `roll` is its `r_torque_old` history, stored only when `update_history`.
/// Returns the torque subtracted from i and added to j.
#[inline(always)]
pub(crate) fn rolling_epsd2<T: Real>(
    g: &ContactGeom<T>,
    s: &Surface<T>,
    n: &Normal<T>,
    c: &PairCoeffs<T>,
    dt: f64,
    roll: &mut V3<T>,
    update_history: bool,
) -> V3<T> {
    let w = if g.is_wall {
        s.wr
    } else {
        sub(g.omega_i, g.omega_j)
    };
    let en = s.en;
    let wn = dot(w, en);
    let w_t = sub(w, scale(en, wn));
    let kr = n.kt * n.reff * n.reff;
    let t = add(*roll, scale(w_t, T::splat(dt) * kr));
    let tmag = norm(t);
    let tmax = n.fn_total.abs() * n.reff * c.mu_r;
    let capped = tmag.gt(tmax);
    let t = if T::any(capped) {
        select3(capped, scale(t, tmax / tmag), t)
    } else {
        t
    };
    if update_history {
        *roll = t;
    }
    t
}

/// The whole contact law for a touching pair (overlap > 0), with the shear and rolling
/// histories passed separately (`roll` is read and written only by EPSD2). The models
/// run in LIGGGHTS' order (contact_models.h `ContactModel::surfacesIntersect`: surface,
/// normal, cohesion (none), tangential, rolling) and accumulate into the force and
/// torques in that order, so the floating-point result is LIGGGHTS'.
#[inline(always)]
pub(crate) fn evaluate<T: Real>(
    g: &ContactGeom<T>,
    c: &PairCoeffs<T>,
    rolling: RollingModel,
    dt: f64,
    shear: &mut V3<T>,
    roll: &mut V3<T>,
    update_history: bool,
) -> ContactForce<T> {
    let s = surface_default(g);
    let n = normal_hertz(g, &s, c);
    let f_n = scale(s.en, n.fn_total);
    let t = tangential_history(&s, &n, c, dt, shear, update_history);
    let f_i = add(f_n, t.ft);
    let (mut torque_i, mut torque_j) = (t.torque_i, t.torque_j);
    let rolled = match rolling {
        RollingModel::None => None,
        RollingModel::Cdt => Some(rolling_cdt(g, &s, &n, c)),
        RollingModel::Epsd2 => Some((
            T::uniform(true),
            rolling_epsd2(g, &s, &n, c, dt, roll, update_history),
        )),
    };
    if let Some((applies, r_torque)) = rolled {
        torque_i = select3(applies, sub(torque_i, r_torque), torque_i);
        torque_j = select3(applies, add(torque_j, r_torque), torque_j);
    }
    ContactForce {
        f_i,
        torque_i,
        torque_j,
    }
}

/// Evaluates the contact law for a touching pair (overlap > 0). `update_history` is
/// false during setup force evaluation, as LIGGGHTS' `shearupdate` is.
#[inline]
#[cfg(test)]
pub(crate) fn hertz_history(
    g: &ContactGeom,
    c: &PairCoeffs,
    rolling: RollingModel,
    dt: f64,
    hist: &mut History,
    update_history: bool,
) -> ContactForce {
    evaluate(
        g,
        c,
        rolling,
        dt,
        &mut hist.shear,
        &mut hist.roll,
        update_history,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn geom(deltan: f64, vn: f64) -> ContactGeom {
        let r = 2.0e-3 - deltan;
        ContactGeom {
            delta: [r, 0.0, 0.0],
            r,
            radi: 1e-3,
            radj: 1e-3,
            is_wall: false,
            meff: 0.5,
            vel_i: [vn, 0.0, 0.0],
            vel_j: [0.0; 3],
            omega_i: [0.0; 3],
            omega_j: [0.0; 3],
        }
    }

    #[test]
    fn elastic_normal_force_is_hertz() {
        // e = 1 => beta = 0: F = 4/3 Y* sqrt(R*) delta^1.5 exactly.
        let c = PairCoeffs::new(1e7, 0.3, 1e7, 0.3, 1.0, 0.5, 0.0);
        let d = 1e-5;
        let mut h = History::default();
        let f = hertz_history(&geom(d, -0.1), &c, RollingModel::None, 1e-6, &mut h, true);
        let expect = 4.0 / 3.0 * c.yeff * (0.5e-3f64).sqrt() * d.powf(1.5);
        approx::assert_relative_eq!(f.f_i[0], expect, max_relative = 1e-12);
    }

    #[test]
    fn damping_opposes_approach() {
        let c = PairCoeffs::new(1e7, 0.3, 1e7, 0.3, 0.5, 0.5, 0.0);
        let mut h = History::default();
        let approaching = hertz_history(
            &geom(1e-5, -0.1),
            &c,
            RollingModel::None,
            1e-6,
            &mut h,
            true,
        );
        let separating =
            hertz_history(&geom(1e-5, 0.1), &c, RollingModel::None, 1e-6, &mut h, true);
        assert!(approaching.f_i[0] > separating.f_i[0]);
    }

    #[test]
    fn coulomb_cap_limits_tangential_force() {
        let c = PairCoeffs::new(1e7, 0.3, 1e7, 0.3, 0.9, 0.3, 0.0);
        let mut g = geom(1e-5, 0.0);
        g.vel_i = [0.0, 5.0, 0.0];
        let mut h = History::default();
        let mut f = ContactForce::default();
        for _ in 0..1000 {
            f = hertz_history(&g, &c, RollingModel::None, 1e-6, &mut h, true);
        }
        let ft = f.f_i[1].abs();
        approx::assert_relative_eq!(ft, 0.3 * f.f_i[0].abs(), max_relative = 1e-12);
    }
}
