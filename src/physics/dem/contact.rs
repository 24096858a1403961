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

use crate::case::RollingModel;
use crate::numerics::vec3::*;

/// sqrt(5/6) as LIGGGHTS spells it; Table 1's damping prefactor 2 sqrt(5/6) beta.
const SQRT_FIVE_OVER_SIX: f64 = 0.912_870_929_175_276_9;

/// Effective properties of a type pair, precomputed once per case
/// (LIGGGHTS global_properties: createYeff, createGeff, createBetaEff).
#[derive(Debug, Clone, Copy)]
pub struct PairCoeffs {
    /// 1/Y* = (1-nu_i^2)/E_i + (1-nu_j^2)/E_j (Table 1).
    pub yeff: f64,
    /// 1/G* = 2(2-nu_i)(1+nu_i)/E_i + 2(2-nu_j)(1+nu_j)/E_j.
    pub geff: f64,
    /// beta = ln e / sqrt(ln^2 e + pi^2) (Table 1).
    pub betaeff: f64,
    pub mu: f64,
    pub mu_r: f64,
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
pub struct ContactGeom {
    /// x_i - x_j (pair) or wall-to-particle vector (wall); |delta| = r.
    pub delta: V3,
    pub r: f64,
    pub radi: f64,
    pub radj: f64,
    pub is_wall: bool,
    pub meff: f64,
    pub vel_i: V3,
    pub vel_j: V3,
    pub omega_i: V3,
    pub omega_j: V3,
}

/// Per-contact state carried between steps (LIGGGHTS' contact history).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct History {
    /// Accumulated tangential displacement ("shearx/y/z").
    pub shear: V3,
    /// Previous rolling torque of EPSD2 ("r_torquex_old"...).
    pub roll: V3,
}

/// Force on i and torques on i and j (force on j is the negative; walls ignore torque_j).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ContactForce {
    pub f_i: V3,
    pub torque_i: V3,
    pub torque_j: V3,
}

/// What the surface model hands to the normal, tangential and rolling models: the
/// fields of LIGGGHTS' `SurfacesIntersectData` that surface_model_default.h sets
/// (plus `en` and `rinv`, set by the caller there and here).
#[derive(Debug, Clone, Copy)]
pub struct Surface {
    /// Unit normal `delta / r`, pointing to particle i.
    pub en: V3,
    pub rinv: f64,
    /// Overlap `radsum - r` (radsum = r_i for a wall).
    pub deltan: f64,
    /// Normal relative velocity `(v_i - v_j) . en`.
    pub vn: f64,
    /// Contact rotation rate ("wr1..3"): `(c_i w_i + c_j w_j) / r`, `c = r - deltan / 2`.
    pub wr: V3,
    /// Tangential relative velocity at the contact point ("vtr1..3").
    pub vtr: V3,
    /// Lever arms `r_i - deltan / 2`, `r_j - deltan / 2` (0 for a wall).
    pub cri: f64,
    pub crj: f64,
}

/// Output of the normal model that the tangential and rolling models read
/// (LIGGGHTS' `sidata.Fn`, `kn`, `kt`, `gammat`), and the effective radius R*.
#[derive(Debug, Clone, Copy)]
pub struct Normal {
    /// Total normal force `k_n delta_n - gamma_n v_n` (signed, not clamped).
    pub fn_total: f64,
    pub kn: f64,
    pub kt: f64,
    pub gammat: f64,
    pub reff: f64,
}

/// Tangential force on i and the torques it exerts on i and j.
#[derive(Debug, Clone, Copy)]
pub struct Tangential {
    pub ft: V3,
    pub torque_i: V3,
    pub torque_j: V3,
}

/// Contact geometry and relative kinematics, LIGGGHTS surface_model_default.h
/// (`SurfaceModel<SURFACE_DEFAULT>::surfacesIntersect`): normal, overlap, normal
/// velocity, the contact rotation rate and the tangential velocity at the contact
/// point that Feng et al. eq 3 integrates into the shear displacement.
///
/// Walls: `wr = w_i (c_i / r)` here, where the header has `(c_i w_i) / r`; the two can
/// differ in the last bit. Kept as it was, so results stay identical to earlier runs.
#[inline(always)]
pub fn surface_default(g: &ContactGeom) -> Surface {
    let rinv = 1.0 / g.r;
    let en = scale(g.delta, rinv);
    let radsum = if g.is_wall { g.radi } else { g.radi + g.radj };
    let deltan = radsum - g.r;

    // Relative velocities at the contact point.
    let vr = sub(g.vel_i, g.vel_j);
    let vn = dot(vr, en);
    let vt = sub(vr, scale(en, vn));
    let (wr, cri, crj) = if g.is_wall {
        let cr = g.radi - 0.5 * deltan;
        (scale(g.omega_i, cr * rinv), cr, 0.0)
    } else {
        let cri = g.radi - 0.5 * deltan;
        let crj = g.radj - 0.5 * deltan;
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
        rinv,
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
pub fn normal_hertz(g: &ContactGeom, s: &Surface, c: &PairCoeffs) -> Normal {
    let reff = if g.is_wall {
        g.radi
    } else {
        g.radi * g.radj / (g.radi + g.radj)
    };
    let sqrtval = (reff * s.deltan).sqrt();
    let sn = 2.0 * c.yeff * sqrtval;
    let st = 8.0 * c.geff * sqrtval;
    let kn = 4.0 / 3.0 * c.yeff * sqrtval;
    let kt = st;
    let gamman = -2.0 * SQRT_FIVE_OVER_SIX * c.betaeff * (sn * g.meff).sqrt();
    let gammat = -2.0 * SQRT_FIVE_OVER_SIX * c.betaeff * (st * g.meff).sqrt();
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
pub fn tangential_history(
    s: &Surface,
    n: &Normal,
    c: &PairCoeffs,
    dt: f64,
    shear: &mut V3,
    update_history: bool,
) -> Tangential {
    let (en, vtr, kt) = (s.en, s.vtr, n.kt);
    if update_history {
        add_assign(shear, scale(vtr, dt));
        let rsht = dot(*shear, en);
        sub_assign(shear, scale(en, rsht));
    }
    let shrmag = norm(*shear);
    let mut ft = scale(*shear, -kt);
    let ft_shear = kt * shrmag;
    let ft_friction = c.mu * n.fn_total.abs();
    if ft_shear > ft_friction {
        if shrmag != 0.0 {
            ft = scale(ft, ft_friction / ft_shear);
            if update_history {
                // -Ft/kt component-wise, the same division LIGGGHTS performs.
                shear[0] = -ft[0] / kt;
                shear[1] = -ft[1] / kt;
                shear[2] = -ft[2] / kt;
            }
        } else {
            ft = [0.0; 3];
        }
    } else {
        sub_assign(&mut ft, scale(vtr, n.gammat));
    }
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
/// the torque subtracted from i and added to j, `None` when nothing rotates.
#[inline(always)]
pub fn rolling_cdt(g: &ContactGeom, s: &Surface, n: &Normal, c: &PairCoeffs) -> Option<V3> {
    let w = if g.is_wall {
        s.wr
    } else {
        sub(g.omega_i, g.omega_j)
    };
    let wmag = norm(w);
    if wmag > 0.0 {
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
        Some(sub(t, scale(en, tn)))
    } else {
        None
    }
}

/// Elastic-plastic spring-dashpot rolling resistance (EPSD2, no dashpot): a rolling
/// spring `k_r = k_t R*^2` on the tangential part of the relative rotation, accumulated
/// in `roll` and capped at `mu_r |F_n| R*` (the torque form of Feng et al. eq 4's
/// limit). Mirrors LIGGGHTS rolling_model_epsd2.h (`calcRollTorque`, `torsionTorque
/// off`); `roll` is its `r_torque_old` history, stored only when `update_history`.
/// Returns the torque subtracted from i and added to j.
#[inline(always)]
pub fn rolling_epsd2(
    g: &ContactGeom,
    s: &Surface,
    n: &Normal,
    c: &PairCoeffs,
    dt: f64,
    roll: &mut V3,
    update_history: bool,
) -> V3 {
    let w = if g.is_wall {
        s.wr
    } else {
        sub(g.omega_i, g.omega_j)
    };
    let en = s.en;
    let wn = dot(w, en);
    let w_t = sub(w, scale(en, wn));
    let kr = n.kt * n.reff * n.reff;
    let mut t = add(*roll, scale(w_t, dt * kr));
    let tmag = norm(t);
    let tmax = n.fn_total.abs() * n.reff * c.mu_r;
    if tmag > tmax {
        t = scale(t, tmax / tmag);
    }
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
pub fn evaluate(
    g: &ContactGeom,
    c: &PairCoeffs,
    rolling: RollingModel,
    dt: f64,
    shear: &mut V3,
    roll: &mut V3,
    update_history: bool,
) -> ContactForce {
    let s = surface_default(g);
    let n = normal_hertz(g, &s, c);
    let mut f_i = scale(s.en, n.fn_total);
    let t = tangential_history(&s, &n, c, dt, shear, update_history);
    add_assign(&mut f_i, t.ft);
    let (mut torque_i, mut torque_j) = (t.torque_i, t.torque_j);
    let r_torque = match rolling {
        RollingModel::None => None,
        RollingModel::Cdt => rolling_cdt(g, &s, &n, c),
        RollingModel::Epsd2 => Some(rolling_epsd2(g, &s, &n, c, dt, roll, update_history)),
    };
    if let Some(t) = r_torque {
        sub_assign(&mut torque_i, t);
        add_assign(&mut torque_j, t);
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
pub fn hertz_history(
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
