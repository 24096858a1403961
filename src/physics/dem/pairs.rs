//! Pass 1 of a step, for one block of particles i over their own pairs (i, j > i) in
//! neighbour-list order.
//!
//! Phase A, without branches: which pairs touch (`touch`, and their indices compacted
//! into `list`), every reverse slot zeroed, the own sums zeroed. Phase B, over the
//! touching pairs only, four at a time in SIMD lanes ([`super::lanes`]): the contact
//! law; the force and torque on i added in pair order to `f[i]`, `torque[i]` (summed
//! from +0.0; the gather continues these sums); the force on i and the torque on j
//! stored in the pair's reverse slot for the gather of j. Separating the two phases
//! removes the unpredictable touch branch from the contact loop, and lanes make the
//! contact law itself about three times cheaper; neither changes a bit of the result.

use super::contact::{ContactGeom, PairCoeffs, evaluate};
use super::lanes::Lanes;
use super::par::Shared;
use crate::case::RollingModel;
use crate::numerics::vec3::{V3, add_assign, dot, sub};
use std::ops::Range;

/// What the pair pass leaves for the second member of a pair.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct RevForce {
    /// Force on the first member (the second gets its negative).
    pub f_i: V3,
    pub torque_j: V3,
}

/// The read-only inputs of the pair pass.
pub(super) struct PairCtx<'a> {
    pub x: &'a [V3],
    pub v: &'a [V3],
    pub omega: &'a [V3],
    pub radius: &'a [f64],
    pub mass: &'a [f64],
    pub type_: &'a [usize],
    pub coeffs: &'a [PairCoeffs],
    pub n_types: usize,
    pub rolling: RollingModel,
    pub dt: f64,
    pub update_history: bool,
    pub start: &'a [usize],
    pub pi: &'a [u32],
    pub pj: &'a [u32],
    pub rev_pos: &'a [u32],
    /// Index into `coeffs` when every particle has the same type (set by `check`).
    pub one_coeff: Option<usize>,
}

/// The outputs of one block: its pair range `k0..` and particle range `i0..`.
pub(super) struct BlockOut<'a> {
    pub k0: usize,
    pub i0: usize,
    pub shear: &'a mut [V3],
    /// Empty unless EPSD2.
    pub roll: &'a mut [V3],
    pub touch: &'a mut [bool],
    pub list: &'a mut [u32],
    pub f: &'a mut [V3],
    pub t: &'a mut [V3],
    /// Every reverse slot; each pair writes only its own.
    pub rev: Shared<RevForce>,
}

/// `s[i]` without a bounds check, for the indices the neighbour list stores.
///
/// SAFETY: `PairCtx::check` established that every particle index in the list is below
/// the length of every per-particle array and every pair index below the list's length.
#[inline(always)]
fn at<T: Copy>(s: &[T], i: usize) -> T {
    debug_assert!(i < s.len());
    unsafe { *s.get_unchecked(i) }
}

impl PairCtx<'_> {
    /// The invariants [`at`] relies on: per-particle arrays of one length `n`, the list
    /// built for `n` particles (its build stores indices below `n` only), per-pair arrays
    /// of one length.
    /// Also finds whether one coefficient set serves every pair (`one_coeff`).
    pub fn check(&mut self, n_at_build: usize, n_slots: usize) {
        let n = self.x.len();
        assert!(
            [
                self.v.len(),
                self.omega.len(),
                self.radius.len(),
                self.mass.len(),
                self.type_.len(),
                n_at_build,
                self.start.len() - 1
            ]
            .iter()
            .all(|&m| m == n),
            "per-particle arrays and neighbour list disagree on the particle count"
        );
        let np = self.pi.len();
        assert!(
            self.pj.len() == np && self.rev_pos.len() == np && n_slots == np,
            "per-pair arrays disagree on the pair count"
        );
        assert!(self.coeffs.len() == self.n_types * self.n_types);
        let t0 = self.type_.first().copied().unwrap_or(0);
        let (mut in_range, mut same) = (t0 < self.n_types, true);
        for &t in self.type_ {
            in_range &= t < self.n_types;
            same &= t == t0;
        }
        assert!(in_range, "particle type out of range");
        self.one_coeff = same.then_some(t0 * self.n_types + t0);
    }
}

/// Pass 1 for the particles `r` (module doc).
pub(super) fn block(ctx: &PairCtx, r: Range<usize>, mut out: BlockOut) {
    out.f.fill([0.0; 3]);
    out.t.fill([0.0; 3]);
    let (x, radius, pi, pj) = (ctx.x, ctx.radius, ctx.pi, ctx.pj);
    let kr = ctx.start[r.start]..ctx.start[r.end];
    let (k0, touch, list) = (out.k0, &mut *out.touch, &mut *out.list);
    assert!(kr.start == k0 && touch.len() == kr.len() && list.len() == kr.len());
    let mut cnt = 0;
    for k in kr {
        let (i, j) = (at(pi, k) as usize, at(pj, k) as usize);
        let delta = sub(at(x, i), at(x, j));
        let rsq = dot(delta, delta);
        let radsum = at(radius, i) + at(radius, j);
        let touching = rsq < radsum * radsum;
        // SAFETY: k - k0 < kr.len() (asserted above); cnt <= k - k0.
        unsafe {
            *touch.get_unchecked_mut(k - k0) = touching;
            *list.get_unchecked_mut(cnt) = k as u32;
        }
        cnt += touching as usize;
        // SAFETY: slot of pair k, written by no other pair.
        unsafe {
            out.rev
                .write(at(ctx.rev_pos, k) as usize, RevForce::default())
        };
    }
    // History of pairs that no longer touch is NOT cleared: LIGGGHTS 3.8 keeps a
    // separated pair's shear until the next neighbour rebuild (see neighbor.rs).
    contacts(ctx, &mut out, cnt);
}

/// Phase B on the first `cnt` entries of `out.list`, four pairs at a time where the CPU
/// has AVX2, else one at a time (same bits either way).
fn contacts(ctx: &PairCtx, out: &mut BlockOut, cnt: usize) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2.
        unsafe { contacts_avx2(ctx, out, cnt) };
        return;
    }
    contacts_lanes::<f64>(ctx, out, cnt);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn contacts_avx2(ctx: &PairCtx, out: &mut BlockOut, cnt: usize) {
    contacts_lanes::<super::lanes::F4>(ctx, out, cnt);
}

/// Phase B in lanes of `L`: pairs `list[c..c + L::N]`, the last group padded with copies
/// of its last pair whose results are dropped.
#[inline(always)]
pub(super) fn contacts_lanes<L: Lanes>(ctx: &PairCtx, out: &mut BlockOut, cnt: usize) {
    let track_roll = !out.roll.is_empty();
    let (k0, i0) = (out.k0, out.i0);
    let mut c = 0;
    while c < cnt {
        let nv = (cnt - c).min(L::N);
        let mut ks = [0usize; 4];
        let (mut ii, mut jj) = ([0usize; 4], [0usize; 4]);
        for l in 0..L::N {
            let k = out.list[c + l.min(nv - 1)] as usize;
            ks[l] = k;
            ii[l] = at(ctx.pi, k) as usize;
            jj[l] = at(ctx.pj, k) as usize;
        }
        let v3 = |a: &[V3], idx: &[usize; 4]| -> [L; 3] {
            [
                L::load(|l| at(a, idx[l])[0]),
                L::load(|l| at(a, idx[l])[1]),
                L::load(|l| at(a, idx[l])[2]),
            ]
        };
        let s1 = |a: &[f64], idx: &[usize; 4]| L::load(|l| at(a, idx[l]));
        let (xi, xj) = (v3(ctx.x, &ii), v3(ctx.x, &jj));
        let delta = [xi[0] - xj[0], xi[1] - xj[1], xi[2] - xj[2]];
        let rsq = delta[0] * delta[0] + delta[1] * delta[1] + delta[2] * delta[2];
        let (mi, mj) = (s1(ctx.mass, &ii), s1(ctx.mass, &jj));
        let g = ContactGeom {
            delta,
            r: rsq.sqrt(),
            radi: s1(ctx.radius, &ii),
            radj: s1(ctx.radius, &jj),
            is_wall: false,
            meff: mi * mj / (mi + mj),
            vel_i: v3(ctx.v, &ii),
            vel_j: v3(ctx.v, &jj),
            omega_i: v3(ctx.omega, &ii),
            omega_j: v3(ctx.omega, &jj),
        };
        let coeffs = if let Some(one) = ctx.one_coeff {
            let c = &ctx.coeffs[one];
            PairCoeffs {
                yeff: L::splat(c.yeff),
                geff: L::splat(c.geff),
                betaeff: L::splat(c.betaeff),
                mu: L::splat(c.mu),
                mu_r: L::splat(c.mu_r),
            }
        } else {
            let coeff = |l: usize| {
                at(
                    ctx.coeffs,
                    at(ctx.type_, ii[l]) * ctx.n_types + at(ctx.type_, jj[l]),
                )
            };
            let cs = [coeff(0), coeff(1), coeff(2), coeff(3)];
            PairCoeffs {
                yeff: L::load(|l| cs[l].yeff),
                geff: L::load(|l| cs[l].geff),
                betaeff: L::load(|l| cs[l].betaeff),
                mu: L::load(|l| cs[l].mu),
                mu_r: L::load(|l| cs[l].mu_r),
            }
        };
        let local = ks.map(|k| k.wrapping_sub(k0));
        let mut shear = v3(out.shear, &local);
        let mut roll = if track_roll {
            v3(out.roll, &local)
        } else {
            [L::splat(0.0); 3]
        };
        let o = evaluate(
            &g,
            &coeffs,
            ctx.rolling,
            ctx.dt,
            &mut shear,
            &mut roll,
            ctx.update_history,
        );
        let lanes3 = |a: &[L; 3]| [a[0].lanes(), a[1].lanes(), a[2].lanes()];
        let (sh, rl) = (lanes3(&shear), lanes3(&roll));
        let (f_i, t_i, t_j) = (lanes3(&o.f_i), lanes3(&o.torque_i), lanes3(&o.torque_j));
        let lane = |a: &[[f64; 4]; 3], l: usize| [a[0][l], a[1][l], a[2][l]];
        for l in 0..nv {
            out.shear[local[l]] = lane(&sh, l);
            if track_roll {
                out.roll[local[l]] = lane(&rl, l);
            }
            let f = lane(&f_i, l);
            add_assign(&mut out.f[ii[l] - i0], f);
            add_assign(&mut out.t[ii[l] - i0], lane(&t_i, l));
            let rf = RevForce {
                f_i: f,
                torque_j: lane(&t_j, l),
            };
            // SAFETY: slot of pair ks[l], written by no other pair.
            unsafe { out.rev.write(at(ctx.rev_pos, ks[l]) as usize, rf) };
        }
        c += L::N;
    }
}
