//! Lanes for the contact law ([`super::contact::Real`]): several contacts computed with
//! the same IEEE operations as the scalar law (`+ - * /`, `sqrt`, `abs`, sign flip,
//! ordered comparisons, bitwise selection), never fused or reordered, so a lane's result
//! is bit for bit the scalar result.
//!
//! [`F4`] holds four `f64` in an AVX register. Its operations are AVX intrinsics, so an
//! `F4` may only be created where the CPU has AVX2 (the pair pass checks at run time
//! and otherwise uses `f64`, one lane).

use super::contact::Real;

/// A [`Real`] of `N` lanes that contacts can be loaded into and read back from.
pub(crate) trait Lanes: Real {
    const N: usize;
    /// Lane `l` is `f(l)`, for `l < N`.
    fn load(f: impl FnMut(usize) -> f64) -> Self;
    /// The lanes, in order.
    fn lanes(self) -> [f64; 4];
}

impl Lanes for f64 {
    const N: usize = 1;
    #[inline(always)]
    fn load(mut f: impl FnMut(usize) -> f64) -> f64 {
        f(0)
    }
    #[inline(always)]
    fn lanes(self) -> [f64; 4] {
        [self, 0.0, 0.0, 0.0]
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use avx::F4;

#[cfg(target_arch = "x86_64")]
mod avx {
    use super::{Lanes, Real};
    use std::arch::x86_64::*;
    use std::ops::{Add, Div, Mul, Neg, Sub};

    /// Four `f64` lanes in an AVX register. Only for code running on a CPU with AVX2
    /// (module doc): every operation is an AVX instruction.
    #[derive(Clone, Copy)]
    pub(crate) struct F4(__m256d);

    /// Per-lane condition: all bits set or none.
    #[derive(Clone, Copy)]
    pub(crate) struct M4(__m256d);

    // SAFETY (every `unsafe` below): the intrinsics need AVX, which the only users of
    // `F4` (the pair pass behind `is_x86_feature_detected!("avx2")`, and tests behind
    // the same check) guarantee.
    macro_rules! binop {
        ($tr:ident, $f:ident, $intr:ident) => {
            impl $tr for F4 {
                type Output = F4;
                #[inline(always)]
                fn $f(self, o: F4) -> F4 {
                    F4(unsafe { $intr(self.0, o.0) })
                }
            }
        };
    }
    binop!(Add, add, _mm256_add_pd);
    binop!(Sub, sub, _mm256_sub_pd);
    binop!(Mul, mul, _mm256_mul_pd);
    binop!(Div, div, _mm256_div_pd);

    impl Neg for F4 {
        type Output = F4;
        /// Flips the sign bit, as scalar negation does.
        #[inline(always)]
        fn neg(self) -> F4 {
            F4(unsafe { _mm256_xor_pd(self.0, _mm256_set1_pd(-0.0)) })
        }
    }

    impl Real for F4 {
        type Mask = M4;
        #[inline(always)]
        fn splat(v: f64) -> F4 {
            F4(unsafe { _mm256_set1_pd(v) })
        }
        #[inline(always)]
        fn sqrt(self) -> F4 {
            F4(unsafe { _mm256_sqrt_pd(self.0) })
        }
        /// Clears the sign bit, as `f64::abs` does.
        #[inline(always)]
        fn abs(self) -> F4 {
            F4(unsafe { _mm256_andnot_pd(_mm256_set1_pd(-0.0), self.0) })
        }
        /// Ordered, quiet: false if either lane is NaN, as scalar `>`.
        #[inline(always)]
        fn gt(self, o: F4) -> M4 {
            M4(unsafe { _mm256_cmp_pd::<_CMP_GT_OQ>(self.0, o.0) })
        }
        /// Unordered or not equal: true if either lane is NaN, as scalar `!=`.
        #[inline(always)]
        fn ne(self, o: F4) -> M4 {
            M4(unsafe { _mm256_cmp_pd::<_CMP_NEQ_UQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn and(a: M4, b: M4) -> M4 {
            M4(unsafe { _mm256_and_pd(a.0, b.0) })
        }
        #[inline(always)]
        fn uniform(b: bool) -> M4 {
            let bits = if b { -1i64 } else { 0 };
            M4(unsafe { _mm256_castsi256_pd(_mm256_set1_epi64x(bits)) })
        }
        #[inline(always)]
        fn any(m: M4) -> bool {
            unsafe { _mm256_movemask_pd(m.0) != 0 }
        }
        #[inline(always)]
        fn select(m: M4, a: F4, b: F4) -> F4 {
            F4(unsafe { _mm256_blendv_pd(b.0, a.0, m.0) })
        }
    }

    impl Lanes for F4 {
        const N: usize = 4;
        #[inline(always)]
        fn load(mut f: impl FnMut(usize) -> f64) -> F4 {
            let (a, b, c, d) = (f(0), f(1), f(2), f(3));
            F4(unsafe { _mm256_set_pd(d, c, b, a) })
        }
        #[inline(always)]
        fn lanes(self) -> [f64; 4] {
            let mut out = [0.0; 4];
            unsafe { _mm256_storeu_pd(out.as_mut_ptr(), self.0) };
            out
        }
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use crate::case::RollingModel;
    use crate::physics::dem::contact::{ContactForce, ContactGeom, PairCoeffs, evaluate};

    /// Random touching contacts (sticking and sliding, spinning and not, with and without
    /// shear and rolling history, setup and step), four at a time in `F4` lanes, against
    /// the scalar law one by one: every output bit must agree.
    #[test]
    fn four_lanes_give_the_scalar_bits() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            eprintln!("no AVX2: F4 is never used here");
            return;
        }
        struct Rng(u64);
        impl Rng {
            fn f(&mut self) -> f64 {
                self.0 ^= self.0 << 13;
                self.0 ^= self.0 >> 7;
                self.0 ^= self.0 << 17;
                (self.0 >> 11) as f64 / (1u64 << 53) as f64
            }
            fn v(&mut self, sc: f64) -> [f64; 3] {
                [
                    sc * (self.f() - 0.5),
                    sc * (self.f() - 0.5),
                    sc * (self.f() - 0.5),
                ]
            }
        }
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        let coeffs = [
            PairCoeffs::new(1e7, 0.3, 1e7, 0.3, 0.5, 0.5, 0.01),
            PairCoeffs::new(2.6e6, 0.3, 5e7, 0.25, 0.8, 0.3, 0.1),
        ];
        let mut checked = 0;
        for case in 0..4000 {
            let mut geoms = Vec::new();
            let mut cs = Vec::new();
            let mut hists = Vec::new();
            for _ in 0..4 {
                let (radi, radj) = (1e-3 * (0.8 + 0.4 * rng.f()), 1e-3 * (0.8 + 0.4 * rng.f()));
                let dir = {
                    let d = rng.v(1.0);
                    let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                    [d[0] / n, d[1] / n, d[2] / n]
                };
                let r = (radi + radj) * (1.0 - 0.05 * rng.f());
                let spin = if case % 5 != 0 { 300.0 } else { 0.0 };
                let omega_i = rng.v(spin);
                let omega_j = if case % 7 == 0 { omega_i } else { rng.v(spin) };
                geoms.push(ContactGeom {
                    delta: [dir[0] * r, dir[1] * r, dir[2] * r],
                    r,
                    radi,
                    radj,
                    is_wall: false,
                    meff: 1e-5 * (0.5 + rng.f()),
                    vel_i: rng.v(1.0),
                    vel_j: rng.v(1.0),
                    omega_i,
                    omega_j,
                });
                cs.push(coeffs[(rng.f() * 2.0) as usize]);
                // Shear from none to far beyond the cap (sliding), roll likewise.
                let big = [0.0, 1e-7, 1e-5, 1e-3][case % 4];
                hists.push((rng.v(big), rng.v(big * 1e-3)));
            }
            let rolling = [RollingModel::None, RollingModel::Cdt, RollingModel::Epsd2][case % 3];
            let update = case % 6 != 0;
            let dt = 1e-6;
            let ld = |f: &dyn Fn(usize) -> f64| F4::load(f);
            let l3 = |f: &dyn Fn(usize) -> [f64; 3]| {
                [ld(&|l| f(l)[0]), ld(&|l| f(l)[1]), ld(&|l| f(l)[2])]
            };
            let g4 = ContactGeom {
                delta: l3(&|l| geoms[l].delta),
                r: ld(&|l| geoms[l].r),
                radi: ld(&|l| geoms[l].radi),
                radj: ld(&|l| geoms[l].radj),
                is_wall: false,
                meff: ld(&|l| geoms[l].meff),
                vel_i: l3(&|l| geoms[l].vel_i),
                vel_j: l3(&|l| geoms[l].vel_j),
                omega_i: l3(&|l| geoms[l].omega_i),
                omega_j: l3(&|l| geoms[l].omega_j),
            };
            let c4 = PairCoeffs {
                yeff: ld(&|l| cs[l].yeff),
                geff: ld(&|l| cs[l].geff),
                betaeff: ld(&|l| cs[l].betaeff),
                mu: ld(&|l| cs[l].mu),
                mu_r: ld(&|l| cs[l].mu_r),
            };
            let mut sh4 = l3(&|l| hists[l].0);
            let mut rl4 = l3(&|l| hists[l].1);
            let o4: ContactForce<F4> = evaluate(&g4, &c4, rolling, dt, &mut sh4, &mut rl4, update);
            let get = |a: &[F4; 3], l: usize| [a[0].lanes()[l], a[1].lanes()[l], a[2].lanes()[l]];
            for l in 0..4 {
                let (mut sh, mut rl) = hists[l];
                let o = evaluate(&geoms[l], &cs[l], rolling, dt, &mut sh, &mut rl, update);
                let bits = |v: [f64; 3]| v.map(f64::to_bits);
                assert_eq!(
                    bits(o.f_i),
                    bits(get(&o4.f_i, l)),
                    "f_i, case {case} lane {l}"
                );
                assert_eq!(
                    bits(o.torque_i),
                    bits(get(&o4.torque_i, l)),
                    "torque_i {case}"
                );
                assert_eq!(
                    bits(o.torque_j),
                    bits(get(&o4.torque_j, l)),
                    "torque_j {case}"
                );
                assert_eq!(bits(sh), bits(get(&sh4, l)), "shear {case}");
                assert_eq!(bits(rl), bits(get(&rl4, l)), "roll {case}");
                checked += 1;
            }
        }
        assert_eq!(checked, 16000);
    }
}
