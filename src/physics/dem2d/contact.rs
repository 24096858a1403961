//! One disk-disk contact, exactly as LAMMPS `pair_style gran/hooke/history` (k_t > 0)
//! and `pair_style gran/hooke` (k_t = 0) compute it, restricted to the plane.
//!
//! Kondic et al. (K) Sec. II, eq 2: `F_n = [k_n x - gamma_n m_eff v_n] n`, a
//! Cundall-Strack tangential spring `xi = int v_t dt` whose part along `n` is projected
//! out (`xi' = xi - n (n . xi)`), the test force `F_t* = -k_t xi' - gamma_t v_t` and the
//! Coulomb cap `|F_t| <= mu |F_n|` with `xi'` shortened to match. The arithmetic is
//! written in the order of LAMMPS' C++ (src/GRANULAR/pair_gran_hooke_history.cpp and
//! pair_gran_hooke.cpp, version 7Jan2022) with every z term dropped — each dropped term
//! is an exact zero under `fix enforce2d`, so two-disk runs agree with LAMMPS to
//! round-off. LAMMPS-specific semantics reproduced here (and listed in docs/impact2d.md):
//! - `x` and the damping use the *centre distance* vector `del`, not a unit vector:
//!   `ccel = k_n (R_i + R_j - r)/r - m_eff gamma_n (v . del)/r^2`, force `del * ccel`.
//! - `m_eff = m_i m_j/(m_i + m_j)`; a frozen partner (`fix freeze`) makes m_eff the
//!   mobile mass; a rigid-cluster member counts with the whole cluster's mass.
//! - The Coulomb limit is `mu |F_n|` with the *damped* normal force (not `k_n x`).
//! - history: the shear is incremented with `v_t,rel dt` *before* the projection, the
//!   projection is applied to the stored shear, and on sliding the stored shear is reset
//!   to `(F_c/F_t) (xi + m_eff gamma_t v_t/k_t) - m_eff gamma_t v_t/k_t`.
//! - no history (`gran/hooke`, K's "kinetic friction only", k_t = 0): the tangential
//!   force is `-min(mu |F_n|, m_eff gamma_t |v_t|) v_t/|v_t|`.
//! - neither style clamps the normal force at zero (`limit_damping` is off by default
//!   in LAMMPS 29Sep2021; older `gran/hooke` clamped unconditionally), so a fast
//!   separating contact is briefly attractive, as in K's eq for F_n. `gran/hooke/history` with k_t = 0
//!   divides by k_t on sliding, so LAMMPS' k_t = 0 model must be `gran/hooke`.

pub use crate::case::impact2d::{Coeffs, gamma_n_from_restitution};

/// The two disks of a contact as the force law sees them; `del = x_i - x_j`
/// (minimum image across the periodic boundary).
#[derive(Debug, Clone, Copy)]
pub(crate) struct PairIn {
    pub del: [f64; 2],
    pub ri: f64,
    pub rj: f64,
    pub vi: [f64; 2],
    pub vj: [f64; 2],
    pub wi: f64,
    pub wj: f64,
    /// Mass used for m_eff (the cluster mass for a cluster member).
    pub mi: f64,
    pub mj: f64,
    pub frozen_i: bool,
    pub frozen_j: bool,
}

/// Force on i (j gets the negative) and the torques on i and j.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PairOut {
    pub f: [f64; 2],
    pub torque_i: f64,
    pub torque_j: f64,
    /// Normal overlap `R_i + R_j - r`.
    pub overlap: f64,
}

/// Evaluates one pair; `None` when not touching (the shear history is then cleared,
/// as LAMMPS does for a neighbour that is not in contact). `shear_update` is false
/// during LAMMPS' setup force pass (`update->setupflag`).
#[inline]
pub(crate) fn hooke(
    c: &Coeffs,
    p: &PairIn,
    shear: &mut [f64; 2],
    shear_update: bool,
    dt: f64,
) -> Option<PairOut> {
    let [delx, dely] = p.del;
    let rsq = delx * delx + dely * dely;
    let radsum = p.ri + p.rj;
    if rsq >= radsum * radsum {
        *shear = [0.0, 0.0];
        return None;
    }
    let r = rsq.sqrt();
    let rinv = 1.0 / r;
    let rsqinv = 1.0 / rsq;
    let vr1 = p.vi[0] - p.vj[0];
    let vr2 = p.vi[1] - p.vj[1];
    let vnnr = vr1 * delx + vr2 * dely;
    let vn1 = delx * vnnr * rsqinv;
    let vn2 = dely * vnnr * rsqinv;
    let vt1 = vr1 - vn1;
    let vt2 = vr2 - vn2;
    let wr3 = (p.ri * p.wi + p.rj * p.wj) * rinv;
    let mut meff = p.mi * p.mj / (p.mi + p.mj);
    if p.frozen_i {
        meff = p.mj;
    }
    if p.frozen_j {
        meff = p.mi;
    }
    let damp = meff * c.gamma_n * vnnr * rsqinv;
    let ccel = c.kn * (radsum - r) * rinv - damp;
    // vtr = vt - del x wr with del_z = 0 and wr = (0, 0, wr3).
    let vtr1 = vt1 + dely * wr3;
    let vtr2 = vt2 - delx * wr3;
    let (fs1, fs2) = if c.history() {
        if shear_update {
            shear[0] += vtr1 * dt;
            shear[1] += vtr2 * dt;
        }
        let shrmag = (shear[0] * shear[0] + shear[1] * shear[1]).sqrt();
        let rsht = (shear[0] * delx + shear[1] * dely) * rsqinv;
        if shear_update {
            shear[0] -= rsht * delx;
            shear[1] -= rsht * dely;
        }
        let mut fs1 = -(c.kt * shear[0] + meff * c.gamma_t * vtr1);
        let mut fs2 = -(c.kt * shear[1] + meff * c.gamma_t * vtr2);
        let fs = (fs1 * fs1 + fs2 * fs2).sqrt();
        let fn_ = c.mu * (ccel * r).abs();
        if fs > fn_ {
            if shrmag != 0.0 {
                let g1 = meff * c.gamma_t * vtr1 / c.kt;
                let g2 = meff * c.gamma_t * vtr2 / c.kt;
                shear[0] = (fn_ / fs) * (shear[0] + g1) - g1;
                shear[1] = (fn_ / fs) * (shear[1] + g2) - g2;
                fs1 *= fn_ / fs;
                fs2 *= fn_ / fs;
            } else {
                fs1 = 0.0;
                fs2 = 0.0;
            }
        }
        (fs1, fs2)
    } else {
        let vrel = (vtr1 * vtr1 + vtr2 * vtr2).sqrt();
        let fn_ = c.mu * (ccel * r).abs();
        let fs = meff * c.gamma_t * vrel;
        let ft = if vrel != 0.0 { fn_.min(fs) / vrel } else { 0.0 };
        (-ft * vtr1, -ft * vtr2)
    };
    let fx = delx * ccel + fs1;
    let fy = dely * ccel + fs2;
    let tor3 = rinv * (delx * fs2 - dely * fs1);
    Some(PairOut {
        f: [fx, fy],
        torque_i: -p.ri * tor3,
        torque_j: -p.rj * tor3,
        overlap: radsum - r,
    })
}

/// Restitution of a linear spring-dashpot `x'' + gamma x' + omega_0^2 x = 0`:
/// `exp(-gamma/2 * pi / sqrt(omega_0^2 - gamma^2/4))`.
pub fn restitution_of(gamma: f64, omega0: f64) -> f64 {
    let wd = (omega0 * omega0 - 0.25 * gamma * gamma).sqrt();
    (-0.5 * gamma * std::f64::consts::PI / wd).exp()
}

/// Contact duration of the same oscillator, `pi / sqrt(omega_0^2 - gamma^2/4)`.
pub fn contact_time_of(gamma: f64, omega0: f64) -> f64 {
    std::f64::consts::PI / (omega0 * omega0 - 0.25 * gamma * gamma).sqrt()
}
