//! LAMMPS' `pair_style granular` contact law (LAMMPS 22 Jul 2025, src/GRANULAR/) with
//! the sub-models granval uses: `hertz/material E e nu`, `damping coeff_restitution`,
//! `tangential mindlin NULL xt mu`, `rolling sds k_roll gamma_roll mu_roll`, twisting
//! none; for particle pairs (`pair_coeff`) and for plane walls (`fix wall/gran
//! granular`).
//!
//! Written from LAMMPS' sources so that every floating-point operation happens in the
//! same order, which is what makes round-off agreement with live LAMMPS possible:
//! `GranularModel::check_contact` and `calculate_forces` (granular_model.cpp), the
//! sub-models' `coeffs_to_local`/`init`/`calculate_forces` (gran_sub_mod_normal.cpp,
//! gran_sub_mod_damping.cpp, gran_sub_mod_tangential.cpp, gran_sub_mod_rolling.cpp), the
//! mixing rules of gran_sub_mod.cpp (`mix_stiffnessE`, `mix_stiffnessG` and their wall
//! forms, `mix_geom`) and `GranSubMod::rotate_rescale_vec`. The synchronized-Verlet
//! option of that version is off by default and not used here.
//!
//! How these laws relate to LIGGGHTS' ([`super::contact`]) is in docs/lammps-laws.md.

/// `FOURTHIRDS` of gran_sub_mod_normal.cpp.
const FOURTHIRDS: f64 = 4.0 / 3.0;
/// `TWOROOTFIVEBYSIX` and `ROOTTHREEBYTWO` of gran_sub_mod_damping.cpp (the literals
/// LAMMPS writes, so the rounded doubles are the same).
#[allow(clippy::excessive_precision)]
const TWOROOTFIVEBYSIX: f64 = 1.825_741_858_350_553_803_45;
#[allow(clippy::excessive_precision)]
const ROOTTHREEBYTWO: f64 = 1.224_744_871_391_588_940_67;
/// `EPSILON` of gran_sub_mod_tangential.cpp / gran_sub_mod_rolling.cpp: below this
/// fraction of the critical force the history is not rotated into the tangent plane.
const EPSILON: f64 = 1e-10;

type V3 = [f64; 3];

/// `GranSubMod::mix_stiffnessE`: 1 / ((1 - nu1^2)/E1 + (1 - nu2^2)/E2).
pub(crate) fn mix_stiffness_e(e1: f64, e2: f64, nu1: f64, nu2: f64) -> f64 {
    let factor1 = (1.0 - nu1 * nu1) / e1;
    let factor2 = (1.0 - nu2 * nu2) / e2;
    1.0 / (factor1 + factor2)
}

/// `GranSubMod::mix_stiffnessG`: 1 / (2(2 - nu1)(1 + nu1)/E1 + 2(2 - nu2)(1 + nu2)/E2).
pub(crate) fn mix_stiffness_g(e1: f64, e2: f64, nu1: f64, nu2: f64) -> f64 {
    let factor1 = 2.0 * (2.0 - nu1) * (1.0 + nu1) / e1;
    let factor2 = 2.0 * (2.0 - nu2) * (1.0 + nu2) / e2;
    1.0 / (factor1 + factor2)
}

/// `GranSubMod::mix_stiffnessE_wall`: E / (2 (1 - nu^2)).
pub(crate) fn mix_stiffness_e_wall(e: f64, nu: f64) -> f64 {
    let factor = 2.0 * (1.0 - nu * nu);
    e / factor
}

/// `GranSubMod::mix_stiffnessG_wall`: E / (4 (2 - nu)(1 + nu)).
pub(crate) fn mix_stiffness_g_wall(e: f64, nu: f64) -> f64 {
    let factor = 4.0 * (2.0 - nu) * (1.0 + nu);
    e / factor
}

/// `GranSubMod::mix_geom`.
pub(crate) fn mix_geom(a: f64, b: f64) -> f64 {
    (a * b).sqrt()
}

/// The `hertz/material` coefficients LAMMPS uses for a pair of types when it mixes them
/// itself (`GranSubModNormalHertzMaterial::mix_coeffs`): E_ij = mix_stiffnessE(E_i, E_j,
/// nu_i, nu_j), nu_ij = sqrt(nu_i nu_j). granval writes these into an explicit
/// `pair_coeff i j` (with the case's own e and mu for the pair), so both engines start
/// from the same doubles.
pub(crate) fn mixed_material(e_i: f64, nu_i: f64, e_j: f64, nu_j: f64) -> (f64, f64) {
    if e_i == e_j && nu_i == nu_j {
        (e_i, nu_i)
    } else {
        (mix_stiffness_e(e_i, e_j, nu_i, nu_j), mix_geom(nu_i, nu_j))
    }
}

/// The coefficients of one `pair_coeff` or `fix wall/gran` after LAMMPS' set-up
/// (`coeffs_to_local`, `init`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coeffs {
    /// `GranSubModNormalHertzMaterial::k`: 4/3 E* (E* by the pair or the wall rule).
    pub kn: f64,
    /// `GranSubModDampingCoeffRestitution::damp` (from e at `init`).
    pub damp: f64,
    /// `GranSubModTangentialMindlin::k` (NULL: 8 G*).
    pub kt: f64,
    /// Tangential damping ratio `xt`.
    pub xt: f64,
    pub mu: f64,
    /// `rolling sds`: (k_roll, gamma_roll, mu_roll).
    pub rolling: Option<(f64, f64, f64)>,
}

impl Coeffs {
    /// `hertz/material e_mod e nu damping coeff_restitution tangential mindlin NULL xt mu
    /// [rolling sds kr gr mur]` for a particle pair (`wall` false, contact type PAIR) or a
    /// wall (contact type WALL).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        e_mod: f64,
        restitution: f64,
        nu: f64,
        xt: f64,
        mu: f64,
        rolling: Option<(f64, f64, f64)>,
        wall: bool,
    ) -> Coeffs {
        // GranSubModNormalHertzMaterial::coeffs_to_local
        let kn = if wall {
            FOURTHIRDS * mix_stiffness_e_wall(e_mod, nu)
        } else {
            FOURTHIRDS * mix_stiffness_e(e_mod, e_mod, nu, nu)
        };
        // GranSubModTangentialMindlin::coeffs_to_local with k = NULL
        let kt = if wall {
            8.0 * mix_stiffness_g_wall(e_mod, nu)
        } else {
            8.0 * mix_stiffness_g(e_mod, e_mod, nu, nu)
        };
        // GranSubModDampingCoeffRestitution::init, Hertzian branch
        let logcor = restitution.ln();
        let mut damp = -ROOTTHREEBYTWO * TWOROOTFIVEBYSIX * logcor;
        damp /= (std::f64::consts::PI * std::f64::consts::PI + logcor * logcor).sqrt();
        Coeffs {
            kn,
            damp,
            kt,
            xt,
            mu,
            rolling,
        }
    }
}

/// One touching candidate, as `PairGranular::compute` / `FixWallGran::post_force` hand it
/// to the model. For a wall: `dx` is the wall-to-particle vector, `radj` 0, `vj` and
/// `omegaj` zero.
#[derive(Debug, Clone, Copy)]
pub struct Contact {
    pub dx: V3,
    pub radi: f64,
    pub radj: f64,
    pub wall: bool,
    pub meff: f64,
    pub vi: V3,
    pub vj: V3,
    pub omegai: V3,
    pub omegaj: V3,
}

/// Per-contact history: the tangential displacement (3, `tangential mindlin`) then the
/// rolling displacement (3, `rolling sds`), in LAMMPS' sub-model order.
pub(crate) type History = [f64; 6];

/// Force on i (j gets its negative) and the torques on i and j.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Output {
    pub forces: V3,
    pub torquesi: V3,
    pub torquesj: V3,
}

#[inline(always)]
fn dot3(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline(always)]
fn len3(a: V3) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}
#[inline(always)]
fn scale3(s: f64, a: V3) -> V3 {
    [s * a[0], s * a[1], s * a[2]]
}
#[inline(always)]
fn add3(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline(always)]
fn sub3(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline(always)]
fn cross3(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `GranSubMod::rotate_rescale_vec`: project onto the plane normal to `n`, keep the
/// magnitude.
fn rotate_rescale_vec(v: &mut V3, n: V3) {
    let rsht = dot3(*v, n);
    let shrmag = len3(*v);
    *v = sub3(*v, scale3(rsht, n));
    let prjmag = len3(*v);
    let scale = if prjmag > 0.0 { shrmag / prjmag } else { 0.0 };
    *v = scale3(scale, *v);
}

/// `GranularModel::check_contact`: squared distance, radius sum, effective radius, and
/// whether they touch (`GranSubModNormal::touch`).
pub(crate) fn check_contact(c: &Contact) -> (bool, f64, f64, f64) {
    let rsq = dot3(c.dx, c.dx);
    let (radsum, reff) = if c.wall {
        // radj == 0: a flat wall
        (c.radi, c.radi)
    } else {
        let radsum = c.radi + c.radj;
        (radsum, c.radi * c.radj / radsum)
    };
    (rsq < radsum * radsum, rsq, radsum, reff)
}

/// `GranularModel::calculate_forces` for a touching contact, sub-models called in
/// LAMMPS' order: normal, damping, (Fncrit), tangential, torques, rolling. `hist` is
/// advanced only when `history_update` (off during LAMMPS' setup), except that the
/// Coulomb rescale writes it as LAMMPS does.
pub(crate) fn calculate_forces(
    c: &Contact,
    k: &Coeffs,
    dt: f64,
    hist: &mut History,
    history_update: bool,
) -> Output {
    let (_, rsq, radsum, reff) = check_contact(c);
    forces_at(c, k, dt, hist, history_update, rsq.sqrt(), radsum, reff)
}

/// `GranularModel::check_contact` for contact type WALLREGION (`fix wall/gran/region`):
/// the distance `r` to the region's surface is given (`Region::surface`), rsq = r r,
/// radsum = radi, and the effective radius is radi when the surface is flat (`radj` =
/// the region contact's `radius` = 0) and radi radj / (radi + radj) otherwise (radj =
/// -2 R on the inside of a cylinder's mantle, 2 R on its outside: region_cylinder.cpp).
/// Returns (touch, radsum, reff).
pub(crate) fn check_region_contact(radi: f64, radj: f64, r: f64) -> (bool, f64, f64) {
    let rsq = r * r;
    let radsum = radi;
    let reff = if radj == 0.0 {
        radi
    } else {
        radi * radj / (radi + radj)
    };
    (rsq < radsum * radsum, radsum, reff)
}

/// `GranularModel::calculate_forces` for contact type WALLREGION: as
/// [`calculate_forces`], but with the region's own surface distance `r` (LAMMPS does not
/// recompute it from `dx` there) and the effective radius of [`check_region_contact`]
/// (`c.radj` is the region contact's `radius`; `c.omegaj` zero). Torque on the grain:
/// radi (n x fs), as for every wall.
pub(crate) fn calculate_region_forces(
    c: &Contact,
    r: f64,
    k: &Coeffs,
    dt: f64,
    hist: &mut History,
    history_update: bool,
) -> Output {
    debug_assert!(c.wall, "a region contact is a wall contact");
    let (_, radsum, reff) = check_region_contact(c.radi, c.radj, r);
    forces_at(c, k, dt, hist, history_update, r, radsum, reff)
}

/// The body of `GranularModel::calculate_forces` once r, radsum and Reff are known.
#[allow(clippy::too_many_arguments)]
fn forces_at(
    c: &Contact,
    k: &Coeffs,
    dt: f64,
    hist: &mut History,
    history_update: bool,
    r: f64,
    radsum: f64,
    reff: f64,
) -> Output {
    let rinv = 1.0 / r;
    let delta = radsum - r;
    let d_r = delta * reff;
    let nx = scale3(rinv, c.dx);

    // relative translational velocity, normal and tangential parts
    let vr = sub3(c.vi, c.vj);
    let vnnr = dot3(vr, nx);
    let vn = scale3(vnnr, nx);
    let vt = sub3(vr, vn);
    // relative rotational velocity, tangential velocity at the contact
    let wr = add3(scale3(c.radi, c.omegai), scale3(c.radj, c.omegaj));
    let vtr = sub3(vt, cross3(wr, nx));

    // normal: GranSubModNormal::calculate_contact_radius, GranSubModNormalHertz
    let contact_radius = d_r.sqrt();
    let fnormal = k.kn * contact_radius * delta;
    // damping: GranSubModDampingTsuji::calculate_forces (coeff_restitution inherits it)
    let sqrt1 = if delta > 0.0 {
        (c.meff * fnormal / delta).max(0.0)
    } else {
        0.0
    };
    let damp_prefactor = k.damp * sqrt1.sqrt();
    let fdamp = -damp_prefactor * vnnr;
    let fntot = fnormal + fdamp;
    // GranSubModNormal::set_fncrit
    let fncrit = fntot.abs();

    // tangential: GranSubModTangentialMindlin::calculate_forces (not rescale, not force)
    let fs = {
        let damp = k.xt * damp_prefactor;
        let fscrit = fncrit * k.mu;
        let k_scaled = k.kt * contact_radius;
        let mut h: V3 = [hist[0], hist[1], hist[2]];
        if history_update {
            let rsht = dot3(h, nx);
            if rsht.abs() * k_scaled > EPSILON * fscrit {
                rotate_rescale_vec(&mut h, nx);
            }
            h = add3(h, scale3(dt, vtr));
        }
        let mut fs = scale3(-k_scaled, h);
        let fdamp_t = scale3(-damp, vtr);
        fs = add3(fs, fdamp_t);
        let magfs = len3(fs);
        if magfs > fscrit {
            if len3(h) != 0.0 {
                fs = scale3(fscrit / magfs, fs);
                h = sub3(fs, fdamp_t);
                h = scale3(-1.0 / k_scaled, h);
            } else {
                fs = [0.0; 3];
            }
        }
        hist[..3].copy_from_slice(&h);
        fs
    };

    let forces = add3(scale3(fntot, nx), fs);
    let t = scale3(-1.0, cross3(nx, fs));
    let (mut torquesi, mut torquesj) = if c.wall {
        (scale3(c.radi, t), [0.0; 3])
    } else {
        (
            scale3(c.radi - 0.5 * delta, t),
            scale3(c.radj - 0.5 * delta, t),
        )
    };

    if let Some((kr, gamma, mur)) = k.rolling {
        let relrot = sub3(c.omegai, c.omegaj);
        // rolling velocity, Wang et al. eq 31 as granular_model.cpp writes it
        let vrl = [
            reff * (relrot[1] * nx[2] - relrot[2] * nx[1]),
            reff * (relrot[2] * nx[0] - relrot[0] * nx[2]),
            reff * (relrot[0] * nx[1] - relrot[1] * nx[0]),
        ];
        // GranSubModRollingSDS::calculate_forces
        let frcrit = mur * fncrit;
        let mut h: V3 = [hist[3], hist[4], hist[5]];
        if history_update {
            let rolldotn = dot3(h, nx);
            if rolldotn.abs() * kr > EPSILON * frcrit {
                rotate_rescale_vec(&mut h, nx);
            }
            h = add3(h, scale3(dt, vrl));
        }
        let mut fr = add3(scale3(-kr, h), scale3(-gamma, vrl));
        let magfr = len3(fr);
        if magfr > frcrit {
            if len3(h) != 0.0 {
                let k_inv = 1.0 / kr;
                let magfr_inv = 1.0 / magfr;
                h = scale3(-frcrit * k_inv * magfr_inv, fr);
                h = add3(h, scale3(-gamma * k_inv, vrl));
                fr = scale3(frcrit * magfr_inv, fr);
            } else {
                fr = [0.0; 3];
            }
        }
        if history_update {
            hist[3..].copy_from_slice(&h);
        }
        let torroll = scale3(reff, cross3(nx, fr));
        torquesi = add3(torquesi, torroll);
        if !c.wall {
            torquesj = sub3(torquesj, torroll);
        }
    }
    Output {
        forces,
        torquesi,
        torquesj,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pair(delta: f64, vn: f64) -> Contact {
        let r = 2e-3 - delta;
        Contact {
            dx: [r, 0.0, 0.0],
            radi: 1e-3,
            radj: 1e-3,
            wall: false,
            meff: 1e-5,
            vi: [-vn, 0.0, 0.0],
            vj: [0.0; 3],
            omegai: [0.0; 3],
            omegaj: [0.0; 3],
        }
    }

    #[test]
    fn elastic_normal_force_is_hertz_with_e_star() {
        // e = 1: no damping; F = 4/3 E* sqrt(R* d) d with E* = E / (2 (1 - nu^2)).
        let k = Coeffs::new(1e7, 1.0, 0.3, 1.0, 0.5, None, false);
        let d = 1e-5;
        let mut h = [0.0; 6];
        let o = calculate_forces(&pair(d, 0.1), &k, 1e-7, &mut h, true);
        let e_star = 1e7 / (2.0 * (1.0 - 0.09));
        let expect = 4.0 / 3.0 * e_star * (0.5e-3 * d).sqrt() * d;
        approx::assert_relative_eq!(o.forces[0], expect, max_relative = 1e-12);
    }

    /// coeff_restitution damping for Hertz equals LIGGGHTS' -2 sqrt(5/6) beta
    /// sqrt(S_n m*) (S_n = 2 E* a): damp sqrt(m* F_n / d) = the same number.
    #[test]
    fn restitution_damping_equals_liggghts_form() {
        let e = 0.5f64;
        let k = Coeffs::new(1e7, e, 0.3, 1.0, 0.5, None, false);
        let (d, m, reff): (f64, f64, f64) = (1e-5, 1e-5, 0.5e-3);
        let e_star = 1e7 / (2.0 * (1.0 - 0.09));
        let a = (reff * d).sqrt();
        let lammps = k.damp * (m * k.kn * a * d / d).sqrt();
        let ln_e = e.ln();
        let beta = ln_e / (ln_e * ln_e + std::f64::consts::PI.powi(2)).sqrt();
        let liggghts = -2.0 * (5.0f64 / 6.0).sqrt() * beta * (2.0 * e_star * a * m).sqrt();
        approx::assert_relative_eq!(lammps, liggghts, max_relative = 1e-12);
    }

    #[test]
    fn sliding_force_is_capped_at_mu_fn() {
        let k = Coeffs::new(1e7, 0.9, 0.3, 1.0, 0.3, None, false);
        let mut c = pair(1e-5, 0.0);
        c.vi = [0.0, 5.0, 0.0];
        let mut h = [0.0; 6];
        let mut o = Output::default();
        for _ in 0..1000 {
            o = calculate_forces(&c, &k, 1e-7, &mut h, true);
        }
        approx::assert_relative_eq!(
            o.forces[1].abs(),
            0.3 * o.forces[0].abs(),
            max_relative = 1e-12
        );
    }

    #[test]
    fn sds_rolling_torque_is_capped() {
        let k = Coeffs::new(1e7, 0.9, 0.3, 1.0, 0.3, Some((1e3, 0.0, 0.01)), false);
        let mut c = pair(1e-5, 0.0);
        c.omegai = [0.0, 0.0, 50.0];
        let mut h = [0.0; 6];
        let (mut with, mut without) = (Output::default(), Output::default());
        for _ in 0..2000 {
            with = calculate_forces(&c, &k, 1e-6, &mut h, true);
        }
        let k0 = Coeffs { rolling: None, ..k };
        let mut h0 = [0.0; 6];
        for _ in 0..2000 {
            without = calculate_forces(&c, &k0, 1e-6, &mut h0, true);
        }
        // |torque_roll| = R* mu_r |F_n| once the rolling spring slides
        let tr = sub3(with.torquesi, without.torquesi);
        let expect = 0.5e-3 * 0.01 * with.forces[0].abs();
        approx::assert_relative_eq!(len3(tr), expect, max_relative = 1e-9);
    }
}
