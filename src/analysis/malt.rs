//! Modified Archimedes's law theory (MALT) of Feng, Blumenfeld & Liu
//! (seed paper 003_7b2069b9a928ac9b, eqs 10-15), following the recipe in
//! `shared/MALT.md` for the function `A(eta, phi)` that eq 10 only calls
//! "a known function" (it is derived in Kang et al., Nat. Commun. 9, 1101).
//!
//! The steady-state gradient `K_phi` (eq 10) is the quantity that the DEM
//! runs are compared against, so it is computed by nested adaptive
//! quadrature with an error estimate that is propagated from the inner
//! integral into the outer one: a bare number without an error bound could
//! not be used to decide whether a simulated `(phi, K_phi)` point lies "on"
//! the theoretical curve.
//!
//! Conventions: angles are in radians unless a name says `deg`; depths and
//! heights are in units of the intruder radius `R` (the paper's tilde
//! variables, eq 5).

use crate::numerics::minimize::nelder_mead;
use crate::numerics::quadrature::{MAX_INTERVALS, Quad, adaptive, adaptive_mapped};
use crate::numerics::roots::brent;
use anyhow::{Result, ensure};
use serde::{Deserialize, Serialize};
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

// ---------------------------------------------------------------------------
// MALT curve, eq 10
// ---------------------------------------------------------------------------

/// Tolerances of the inner integral `Z(eta)`. The relative one sits just
/// above the GK round-off floor (`50 eps int|g|`, ~1e-14 of `|Z|`): asking
/// for less makes every inner integral exhaust its interval budget. Through
/// `A = ... exp(s tan(beta) Z)` it costs at most ~1e-13 relative in `K`.
const Z_ABS_TOL: f64 = 1e-15;
const Z_REL_TOL: f64 = 1e-13;
const Z_MAX_INTERVALS: usize = 500;

/// Angle-dependent constants of MALT.md's `A(eta, phi)`, computed once per
/// `phi` because the nested quadrature evaluates `A` thousands of times.
#[derive(Clone, Copy)]
struct Malt {
    s: f64,
    t: f64,
    tb: f64,
    beta: f64,
    sin_b: f64,
    cos_b: f64,
    cos_phi: f64,
    /// `E / tan(beta)` with `E = exp(pi tan(phi) / 2)`.
    e_over_tb: f64,
}

impl Malt {
    fn new(phi: f64) -> Result<Self> {
        ensure!(
            phi.is_finite() && (0.0..FRAC_PI_2).contains(&phi),
            "friction angle must be in [0, pi/2) rad, got {phi}"
        );
        // beta: half-angle of the Prandtl wedge, pi/4 - phi/2 (Mohr-Coulomb).
        let beta = FRAC_PI_4 - 0.5 * phi;
        let t = phi.tan();
        let tb = beta.tan();
        Ok(Self {
            s: phi.sin(),
            t,
            tb,
            beta,
            sin_b: beta.sin(),
            cos_b: beta.cos(),
            cos_phi: phi.cos(),
            e_over_tb: (0.5 * PI * t).exp() / tb,
        })
    }

    /// Integrand of `Z(eta)` over the log-spiral fan angle `psi`.
    ///
    /// The denominator `sin(beta) + (1-eta) sin(psi-beta) e^{psi t}` tends to
    /// `eta sin(beta)` at `psi = 0`, which is the (integrable) singularity of
    /// MALT.md. Evaluated literally it cancels catastrophically for small
    /// `eta`, so for `psi < beta` it is rewritten as a sum of two
    /// non-negative terms (sin(beta) + sin(psi-beta) e^{psi t} via expm1, plus
    /// `-eta sin(psi-beta) e^{psi t}`), each accurate to rounding.
    fn z_integrand(&self, eta: f64, psi: f64) -> f64 {
        let one_m = 1.0 - eta;
        let ept = (psi * self.t).exp();
        let den = if psi < self.beta {
            let half = (0.5 * psi).sin();
            let d0 = psi.sin() * self.cos_b * ept
                - self.sin_b * ((psi * self.t).exp_m1() * psi.cos() - 2.0 * half * half);
            d0 - eta * (psi - self.beta).sin() * ept
        } else {
            self.sin_b + one_m * (psi - self.beta).sin() * ept
        };
        -one_m * (psi + self.beta).cos() * ept / (self.cos_phi * den)
    }

    /// `Z(eta)` with its quadrature error. Not converging to the (tight)
    /// inner tolerance is not fatal: the error is propagated into `K_phi`,
    /// which then fails its own tolerance if the loss matters.
    fn z(&self, eta: f64) -> Result<Quad> {
        if eta == 1.0 {
            return Ok(Quad {
                value: 0.0,
                abs_err: 0.0,
            });
        }
        let g = |psi: f64| (self.z_integrand(eta, psi), 0.0);
        Ok(adaptive_mapped(&g, 0.0, FRAC_PI_2, Z_ABS_TOL, Z_REL_TOL, Z_MAX_INTERVALS)?.0)
    }

    /// `A(eta, phi)` and its error from the inner integral. Assembled in
    /// logs because `eta^-s` (from `r_E = eta`) and `exp(s tb Z)` both
    /// diverge as `eta -> 0` while their product stays finite
    /// (`Z ~ ln(eta) / tb` there).
    fn a(&self, eta: f64) -> Result<Quad> {
        if self.s == 0.0 {
            return Ok(Quad {
                value: 1.0,
                abs_err: 0.0,
            });
        }
        let one_m = 1.0 - eta;
        let tb2 = self.tb * self.tb;
        let ln_rc = (2.0 * one_m * self.e_over_tb).ln_1p();
        let ln_rd = (one_m * self.e_over_tb).ln_1p();
        let z = self.z(eta)?;
        let ln_a =
            self.s * ((1.0 + tb2) * ln_rc - eta.ln() - tb2 * ln_rd) + self.s * self.tb * z.value;
        let a = ln_a.exp();
        Ok(Quad {
            value: a,
            abs_err: a * self.s * self.tb * z.abs_err,
        })
    }
}

/// A(eta, phi) per MALT.md; phi in radians.
///
/// The form is the one MALT.md documents for eq 10 (Prandtl wedge of
/// half-angle `beta = pi/4 - phi/2`, log-spiral fan, hoop-stress
/// correction); it satisfies `A(1, phi) = 1` and `A(eta, 0) = 1`, which is
/// what makes `K(0) = 1`. Domain: `0 < eta <= 1`, `0 <= phi < pi/2`.
#[cfg(test)]
pub(crate) fn a_function(eta: f64, phi: f64) -> Result<f64> {
    ensure!(
        eta.is_finite() && eta > 0.0 && eta <= 1.0,
        "eta must be in (0, 1], got {eta}"
    );
    Ok(Malt::new(phi)?.a(eta)?.value)
}

/// Relative tolerance of the outer (eta) integral of eq 10; far below the
/// 1e-8 accuracy of MALT.md's check values, and well above the ~1e-14
/// round-off floor of the GK error estimate (which also carries the
/// propagated inner error).
const K_REL_TOL: f64 = 1e-11;

/// K_phi(phi), eq 10, phi in radians, with the quadrature error estimate
/// propagated (outer and inner integrals).
///
/// Eq 10's prefactor `2 (1+sin phi)/(1-sin phi) e^{pi tan phi}` is `2 N_q`
/// (Prandtl-Reissner bearing capacity). At `phi = 0` exactly, `A = 1` and
/// `2 * int_0^1 eta d eta = 1`, so 1.0 is returned without quadrature: the
/// water limit the paper stresses (Archimedes) is then exact.
pub fn k_phi(phi: f64) -> Result<Quad> {
    let m = Malt::new(phi)?;
    if phi == 0.0 {
        return Ok(Quad {
            value: 1.0,
            abs_err: 0.0,
        });
    }
    let pref = 2.0 * (1.0 + m.s) / (1.0 - m.s) * (PI * m.t).exp();
    // The inner integral can only fail on a non-finite value, which the
    // outer quadrature reports as such; record the first failure.
    let failure = std::cell::RefCell::new(None::<anyhow::Error>);
    let g = |eta: f64| match m.a(eta) {
        Ok(a) => (eta * a.value, eta * a.abs_err),
        Err(e) => {
            failure.borrow_mut().get_or_insert(e);
            (f64::NAN, 0.0)
        }
    };
    let res = adaptive_mapped(&g, 0.0, 1.0, 0.0, K_REL_TOL, MAX_INTERVALS);
    if let Some(e) = failure.into_inner() {
        return Err(e.context(format!("A(eta, phi = {phi}) failed")));
    }
    let (q, ok) = res?;
    ensure!(
        ok,
        "K_phi({phi}) quadrature did not converge: {} +- {}",
        q.value,
        q.abs_err
    );
    Ok(Quad {
        value: pref * q.value,
        abs_err: pref * q.abs_err,
    })
}

/// Upper end of the bracket searched by [`phi_of_k`]; covers every friction
/// angle of practical granular media (K(60 deg) is in the thousands).
pub(crate) const PHI_MAX_DEG: f64 = 60.0;

/// [`k_phi`] of an angle in degrees, restricted to [0, [`PHI_MAX_DEG`]]: granular
/// internal friction angles lie well inside it, and beyond it eq 10's exp(pi tan phi)
/// growth (K(89 deg) ~ 1e122) is a number without meaning for a granular bed.
pub fn k_phi_deg(phi_deg: f64) -> Result<Quad> {
    ensure!(
        phi_deg.is_finite() && (0.0..=PHI_MAX_DEG).contains(&phi_deg),
        "phi = {phi_deg} deg: MALT's K_phi is evaluated for 0 <= phi <= {PHI_MAX_DEG} deg (internal friction angles of granular materials; K grows as exp(pi tan phi) toward 90 deg)"
    );
    k_phi(phi_deg.to_radians())
}

/// Inverse: phi (radians) with K(phi) = k, for k >= 1 (error for k < 1 or
/// non-finite), by a bracketing root finder (Brent) on [0, 60 deg] to 1e-12 rad.
///
/// This is how a measured steady-state gradient (Table 3, eq 10) is turned
/// into a friction angle. The root is sought in `ln K`, which is nearly
/// linear in `phi`, so Brent's interpolation steps are nearly exact.
pub fn phi_of_k(k: f64) -> Result<f64> {
    ensure!(
        k.is_finite() && k >= 1.0,
        "K_phi must be finite and >= 1 (K(0) = 1), got {k}"
    );
    if k == 1.0 {
        return Ok(0.0);
    }
    let target = k.ln();
    let hi = PHI_MAX_DEG.to_radians();
    let g = |phi: f64| -> Result<f64> { Ok(k_phi(phi)?.value.ln() - target) };
    let g_hi = g(hi)?;
    ensure!(
        g_hi >= 0.0,
        "K_phi = {k} exceeds K({PHI_MAX_DEG} deg) = {}",
        (g_hi + target).exp()
    );
    brent(g, 0.0, hi, -target, g_hi, 1e-12)
}

/// The MALT curve as rows (phi_deg, K) from 0 to max_deg inclusive in steps
/// of step_deg (eq 10; the solid line of the paper's Fig. 7).
pub fn table(max_deg: f64, step_deg: f64) -> Result<Vec<(f64, f64)>> {
    ensure!(
        max_deg.is_finite() && (0.0..90.0).contains(&max_deg),
        "max_deg must be in [0, 90), got {max_deg}"
    );
    ensure!(
        step_deg.is_finite() && step_deg > 0.0,
        "step_deg must be positive, got {step_deg}"
    );
    // Tolerate max_deg being a multiple of step_deg up to rounding, so that
    // e.g. (40, 0.1) includes 40.
    let n = (max_deg / step_deg * (1.0 + 1e-12)).floor();
    ensure!(n <= 1e6, "too many rows ({n})");
    (0..=n as usize)
        .map(|i| {
            let deg = (i as f64 * step_deg).min(max_deg);
            Ok((deg, k_phi(deg.to_radians())?.value))
        })
        .collect()
}

// ---------------------------------------------------------------------------
// Stagnant zone and unified force-depth relation, eqs 11-15
// ---------------------------------------------------------------------------

/// Steady-state cone height `H_ss = tan(pi/4 + phi/2)` (sec. 6): the
/// Mohr-Coulomb cone half-angle at the apex is `beta = pi/4 - phi/2`.
fn h_ss(phi: f64) -> f64 {
    (FRAC_PI_4 + 0.5 * phi).tan()
}

/// Stagnant-zone cone height in units of R, eqs 11-12: H_ss = tan(pi/4 + phi/2);
/// H(h) = H_ss (1 - exp(-((h-h_A)/(h_B-h_A))^2)) for h > h_A else 0.
///
/// The Gaussian form is the paper's choice to have `dH/dh = 0` at `h_A`
/// (no stagnant zone during compaction, regime A) and saturation beyond
/// `h_B`. Through eq 11 the stagnant-zone volume `pi R^3 H / 3` adds to the
/// intruded volume.
#[cfg(test)]
pub(crate) fn stagnant_cone_height(h: f64, h_a: f64, h_b: f64, phi: f64) -> f64 {
    if h <= h_a {
        return 0.0;
    }
    let x = (h - h_a) / (h_b - h_a);
    h_ss(phi) * (1.0 - (-x * x).exp())
}

/// Unified FDR of eqs 13-15: parameters of the fit.
///
/// `k_a`: gradient of the compaction regime A; `k_phi`: steady-state
/// gradient (eq 10); `h_a`, `h_b`: ends of regimes A and B; `delta`: width
/// of the tanh crossovers (eq 14); `p0`: resistance at `h = 0` (not the
/// intercept of the steady-state line of Table 3); `phi`: friction angle in
/// radians, entering only through `H_ss`.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct UnifiedFdr {
    pub k_a: f64,
    pub k_phi: f64,
    pub h_a: f64,
    pub h_b: f64,
    pub delta: f64,
    pub p0: f64,
    pub phi: f64,
}

/// Eq 14: tanh crossover from `a` (well below `h0`) to `b` (well above).
fn g14(a: f64, b: f64, h0: f64, delta: f64, h: f64) -> f64 {
    0.5 * (b + a) + 0.5 * (b - a) * ((h - h0) / delta).tanh()
}

impl UnifiedFdr {
    /// Regime-B gradient `f(h)` of eq 13, i.e. `(K_phi/3) dH/dh` with `H`
    /// from eq 12. Zero for `h <= h_A`, where eq 12 has no stagnant zone
    /// (the printed formula would turn negative there).
    ///
    /// Eq 13 is used as printed: it omits the `K_phi * 1` term that
    /// differentiating eq 11 would add. That matches the paper's account of
    /// regime B starting with a "very low gradient, much lower than either A
    /// or C", and it is the form fed into eq 15 for the fits of Fig. 8.
    fn f13(&self, h: f64) -> f64 {
        if h <= self.h_a {
            return 0.0;
        }
        let w = self.h_b - self.h_a;
        let x = (h - self.h_a) / w;
        2.0 * self.k_phi * h_ss(self.phi) * (h - self.h_a) * (-x * x).exp() / (3.0 * w * w)
    }

    /// Crossover depth between the two branches of eq 15; the slope has a
    /// jump of order `(K_A - K_phi) e^{-(h_B-h_A)/delta}` there.
    fn h_mid(&self) -> f64 {
        0.5 * (self.h_a + self.h_b)
    }

    /// slope dp/dh, eq 15 with the smoothing function G of eq 14, f(h) of eq 13.
    ///
    /// The two tanh crossovers are applied on either side of
    /// `(h_A + h_B)/2` so that each regime boundary is smoothed independently
    /// (eq 15). Parameters are assumed valid (`h_a < h_b`, `delta > 0`).
    pub(crate) fn slope(&self, h: f64) -> f64 {
        let f = self.f13(h);
        if h < self.h_mid() {
            g14(self.k_a, f, self.h_a, self.delta, h)
        } else {
            g14(f, self.k_phi, self.h_b, self.delta, h)
        }
    }

    /// Break points of the slope: the jump at the branch switch of eq 15 and
    /// the kinks/crossovers at `h_A` and `h_B`; quadrature panels must not
    /// straddle the jump.
    fn breaks(&self) -> [f64; 3] {
        [self.h_a, self.h_mid(), self.h_b]
    }

    /// p(h) = p0 + integral_0^h slope, integrated numerically (the paper
    /// gives no closed form for eq 15's integral).
    #[cfg(test)]
    pub fn p(&self, h: f64) -> f64 {
        self.p0 + integrate_pieces(&|x| self.slope(x), 0.0, h, &self.breaks())
    }
}

/// Integral of a piecewise-smooth `f` over [x0, x1], split at the break
/// points inside. The slope of eq 15 is smooth on each piece, so the
/// unmapped GK rule converges in a panel or two; a non-converged piece
/// still returns its best estimate because `p` has no error channel.
fn integrate_pieces<F: Fn(f64) -> f64>(f: &F, x0: f64, x1: f64, breaks: &[f64]) -> f64 {
    if x0 == x1 {
        return 0.0;
    }
    let (lo, hi, sign) = if x0 < x1 {
        (x0, x1, 1.0)
    } else {
        (x1, x0, -1.0)
    };
    let g = |x: f64| (f(x), 0.0);
    let mut total = 0.0;
    let mut a = lo;
    let inner = breaks.iter().copied().filter(|&c| c > lo && c < hi);
    for b in inner.chain(std::iter::once(hi)) {
        if b > a {
            total += match adaptive(&g, a, b, 1e-14, 1e-12, 200) {
                Ok((q, _)) => q.value,
                Err(_) => f64::NAN,
            };
            a = b;
        }
    }
    sign * total
}

/// `ln cosh(y)` without overflow.
fn ln_cosh(y: f64) -> f64 {
    let ay = y.abs();
    ay + (-2.0 * ay).exp().ln_1p() - std::f64::consts::LN_2
}

/// Data prepared once for the fit objective.
struct FitData {
    /// Depths sorted ascending, and the matching resistances.
    h: Vec<f64>,
    p: Vec<f64>,
    h_max: f64,
    k_phi: f64,
    phi: f64,
}

/// Bounds of the crossover width relative to the deepest data point.
const DELTA_MIN_REL: f64 = 1e-4;
const DELTA_MAX_REL: f64 = 0.5;

/// Logistic map kept strictly inside (0, 1), so a saturated search
/// coordinate still yields the strict bounds `0 < h_a < h_b < h_max`.
fn sigmoid(u: f64) -> f64 {
    (1.0 / (1.0 + (-u).exp())).clamp(1e-12, 1.0 - 1e-12)
}

fn logit(x: f64) -> f64 {
    (x / (1.0 - x)).ln()
}

impl FitData {
    /// Unconstrained coordinates -> `(h_a, h_b, delta)` obeying
    /// `0 < h_a < h_b < h_max` and `delta > 0`, so Nelder-Mead can roam freely.
    fn decode(&self, u: &[f64; 3]) -> (f64, f64, f64) {
        let h_a = self.h_max * sigmoid(u[0]);
        let h_b = h_a + (self.h_max - h_a) * sigmoid(u[1]);
        let (dmin, dmax) = (DELTA_MIN_REL * self.h_max, DELTA_MAX_REL * self.h_max);
        let delta = dmin * (dmax / dmin).powf(sigmoid(u[2]));
        (h_a, h_b, delta)
    }

    fn encode(&self, h_a: f64, h_b: f64, delta: f64) -> [f64; 3] {
        let (dmin, dmax) = (DELTA_MIN_REL * self.h_max, DELTA_MAX_REL * self.h_max);
        [
            logit(h_a / self.h_max),
            logit((h_b - h_a) / (self.h_max - h_a)),
            logit((delta / dmin).ln() / (dmax / dmin).ln()),
        ]
    }

    /// Variable projection: `p(h)` is affine in `(p0, k_a)` for fixed
    /// `(h_a, h_b, delta)`, so those two are solved by linear least squares
    /// inside the objective and only three nonlinear parameters are searched.
    /// The `k_a` weight `(1 - tanh((h-h_a)/delta))/2` of eq 14 (below the
    /// branch switch of eq 15) integrates in closed form.
    fn solve(&self, h_a: f64, h_b: f64, delta: f64) -> (f64, UnifiedFdr) {
        let base = UnifiedFdr {
            k_a: 0.0,
            k_phi: self.k_phi,
            h_a,
            h_b,
            delta,
            p0: 0.0,
            phi: self.phi,
        };
        let breaks = base.breaks();
        let h_mid = base.h_mid();
        let slope = |x: f64| base.slope(x);
        let ka_weight_int = |x: f64| {
            let x = x.min(h_mid);
            0.5 * x - 0.5 * delta * (ln_cosh((x - h_a) / delta) - ln_cosh(-h_a / delta))
        };
        let n = self.h.len();
        let mut c = Vec::with_capacity(n);
        let mut d = Vec::with_capacity(n);
        let (mut acc, mut prev) = (0.0, 0.0);
        for &x in &self.h {
            acc += integrate_pieces(&slope, prev, x, &breaks);
            prev = x;
            c.push(acc);
            d.push(ka_weight_int(x));
        }
        let nf = n as f64;
        let r: Vec<f64> = self.p.iter().zip(&c).map(|(p, c)| p - c).collect();
        let r_mean = r.iter().sum::<f64>() / nf;
        let d_mean = d.iter().sum::<f64>() / nf;
        let sdd: f64 = d.iter().map(|d| (d - d_mean).powi(2)).sum();
        let sdr: f64 = d
            .iter()
            .zip(&r)
            .map(|(d, r)| (d - d_mean) * (r - r_mean))
            .sum();
        // All data beyond the branch switch: k_a and p0 are confounded;
        // pick k_a = k_phi (no regime A) and let p0 absorb the offset.
        let k_a = if sdd > 1e-14 * d_mean.abs().max(1e-300).powi(2) * nf {
            sdr / sdd
        } else {
            self.k_phi
        };
        let p0 = r_mean - k_a * d_mean;
        let sse: f64 = r
            .iter()
            .zip(&d)
            .map(|(r, d)| (r - p0 - k_a * d).powi(2))
            .sum();
        let fdr = UnifiedFdr { k_a, p0, ..base };
        (if sse.is_finite() { sse } else { f64::INFINITY }, fdr)
    }
}

/// Fit of the unified FDR (eqs 13-15) to measured (h, p) points: least
/// squares over (k_a, h_a, h_b, delta, p0) with k_phi and phi given (K_phi
/// from the steady-state fit, phi from stress or [`phi_of_k`]). Returns the
/// parameters and R^2.
///
/// `k_phi` and `phi` are held fixed because the paper reads them off
/// independently (steady-state slope, Mohr-Coulomb stress analysis); only the
/// transient is fitted. `(p0, k_a)` enter linearly and are solved exactly for
/// each trial `(h_a, h_b, delta)`, which a bounded Nelder-Mead search (from the
/// best few points of a coarse grid) minimises.
pub(crate) fn fit_unified_fdr(
    h: &[f64],
    p: &[f64],
    k_phi: f64,
    phi: f64,
) -> Result<(UnifiedFdr, f64)> {
    ensure!(
        h.len() == p.len(),
        "h and p differ in length ({} vs {})",
        h.len(),
        p.len()
    );
    ensure!(
        h.len() >= 6,
        "need at least 6 points for 5 parameters, got {}",
        h.len()
    );
    ensure!(
        h.iter().chain(p).all(|v| v.is_finite()),
        "data contain non-finite values"
    );
    ensure!(h.iter().all(|&v| v >= 0.0), "depths must be >= 0");
    ensure!(
        k_phi.is_finite() && k_phi > 0.0,
        "k_phi must be positive, got {k_phi}"
    );
    ensure!(
        phi.is_finite() && (0.0..FRAC_PI_2).contains(&phi),
        "phi must be in [0, pi/2) rad, got {phi}"
    );
    let mut idx: Vec<usize> = (0..h.len()).collect();
    idx.sort_by(|&i, &j| h[i].total_cmp(&h[j]));
    let data = FitData {
        h: idx.iter().map(|&i| h[i]).collect(),
        p: idx.iter().map(|&i| p[i]).collect(),
        h_max: h.iter().copied().fold(0.0, f64::max),
        k_phi,
        phi,
    };
    ensure!(data.h_max > 0.0, "all depths are zero");
    let p_mean = p.iter().sum::<f64>() / p.len() as f64;
    let sst: f64 = p.iter().map(|v| (v - p_mean).powi(2)).sum();
    ensure!(sst > 0.0, "resistance data are constant; R^2 undefined");

    let objective = |u: &[f64; 3]| {
        let (h_a, h_b, delta) = data.decode(u);
        data.solve(h_a, h_b, delta).0
    };

    // Coarse grid over regime boundaries, crossover width a fraction of the
    // shorter regime (the paper's "Delta much shorter than h_A, h_B - h_A").
    let mut starts: Vec<([f64; 3], f64)> = Vec::new();
    for fa in [0.03, 0.08, 0.15, 0.25, 0.4] {
        for fb in [0.1, 0.25, 0.45, 0.7] {
            let h_a = fa * data.h_max;
            let h_b = h_a + fb * (data.h_max - h_a);
            let delta = (0.2 * h_a.min(h_b - h_a)).clamp(
                2.0 * DELTA_MIN_REL * data.h_max,
                0.5 * DELTA_MAX_REL * data.h_max,
            );
            let u = data.encode(h_a, h_b, delta);
            starts.push((u, objective(&u)));
        }
    }
    starts.sort_by(|a, b| a.1.total_cmp(&b.1));
    let f_tol = 1e-16 * sst;
    let mut best = ([0.0; 3], f64::INFINITY);
    for (u0, _) in starts.iter().take(3) {
        let (u1, _) = nelder_mead(&objective, *u0, 0.5, f_tol, 600);
        // Restart from the optimum: a simplex that collapsed prematurely
        // in one direction gets a fresh, full-size one.
        let r = nelder_mead(&objective, u1, 0.1, f_tol, 600);
        if r.1 < best.1 {
            best = r;
        }
    }
    ensure!(
        best.1.is_finite(),
        "unified FDR fit failed (non-finite residuals)"
    );
    let (h_a, h_b, delta) = data.decode(&best.0);
    let (sse, fdr) = data.solve(h_a, h_b, delta);
    Ok((fdr, 1.0 - sse / sst))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// MALT.md check values (independent quadrature, rel. error < 1e-8).
    const CHECK: [(f64, f64); 9] = [
        (0.0, 1.0),
        (5.0, 1.725515),
        (10.0, 3.034241),
        (15.0, 5.480783),
        (20.0, 10.261851),
        (25.0, 20.131526),
        (30.0, 41.936972),
        (35.0, 94.378753),
        (40.0, 234.833365),
    ];

    #[test]
    fn k_matches_malt_md_table() {
        for (deg, want) in CHECK {
            let q = k_phi(deg.to_radians()).unwrap();
            let rel = (q.value - want).abs() / want;
            assert!(rel < 1e-6, "K({deg}) = {} vs {want}", q.value);
            assert!(q.abs_err <= 1e-8 * q.value, "K({deg}) error {q:?}");
        }
        assert_eq!(k_phi(0.0).unwrap().value, 1.0);
        let rows = table(40.0, 5.0).unwrap();
        assert_eq!(rows.len(), 9);
        for ((deg, k), (d0, k0)) in rows.iter().zip(CHECK) {
            assert_eq!(*deg, d0);
            assert!((k - k0).abs() / k0 < 1e-6);
        }
    }

    #[test]
    fn a_function_limits() {
        for deg in [5.0_f64, 20.0, 40.0] {
            assert_eq!(a_function(1.0, deg.to_radians()).unwrap(), 1.0);
        }
        for eta in [1e-9, 0.3, 0.9] {
            assert_eq!(a_function(eta, 0.0).unwrap(), 1.0);
        }
        // Finite as eta -> 0: the eta^-s and exp(s tb Z) divergences cancel.
        let small = a_function(1e-12, 30f64.to_radians()).unwrap();
        let less_small = a_function(1e-9, 30f64.to_radians()).unwrap();
        assert!(small.is_finite() && (small - less_small).abs() < 1e-3 * less_small);
        assert!(a_function(0.0, 0.3).is_err());
        assert!(a_function(1.1, 0.3).is_err());
        assert!(a_function(0.5, -0.1).is_err());
    }

    #[test]
    fn k_increasing() {
        let mut last = k_phi(0.0).unwrap().value;
        for i in 1..=30 {
            let k = k_phi((2.0 * i as f64).to_radians()).unwrap().value;
            assert!(k > last, "K not increasing at {} deg", 2 * i);
            last = k;
        }
    }

    #[test]
    fn inverse() {
        let phi = phi_of_k(23.00).unwrap().to_degrees();
        assert!((phi - 25.94).abs() < 0.01, "phi(23) = {phi}");
        let phi = phi_of_k(2.71).unwrap().to_degrees();
        assert!((phi - 9.0).abs() < 0.25, "phi(2.71) = {phi}");
        for deg in [0.5_f64, 12.3, 33.3, 55.0] {
            let phi = deg.to_radians();
            let back = phi_of_k(k_phi(phi).unwrap().value).unwrap();
            assert!((back - phi).abs() < 1e-9, "round trip {deg}: {back}");
        }
        assert_eq!(phi_of_k(1.0).unwrap(), 0.0);
        assert!(phi_of_k(0.99).is_err());
        assert!(phi_of_k(f64::NAN).is_err());
        assert!(phi_of_k(1e9).is_err());
    }

    #[test]
    fn cone_height() {
        let phi = 30f64.to_radians();
        let hss = (FRAC_PI_4 + phi / 2.0).tan();
        assert_eq!(stagnant_cone_height(0.1, 0.16, 0.61, phi), 0.0);
        let at_b = stagnant_cone_height(0.61, 0.16, 0.61, phi);
        assert!((at_b - hss * (1.0 - (-1.0f64).exp())).abs() < 1e-14);
        assert!((stagnant_cone_height(50.0, 0.16, 0.61, phi) - hss).abs() < 1e-12);
    }

    fn truth() -> UnifiedFdr {
        UnifiedFdr {
            k_a: 60.0,
            k_phi: 23.0,
            h_a: 0.16,
            h_b: 0.61,
            delta: 0.03,
            p0: 0.5,
            phi: 25.94f64.to_radians(),
        }
    }

    #[test]
    fn unified_slope_and_p() {
        let m = truth();
        // Far from crossovers the slope is K_A, f(h) of eq 13, and K_phi.
        assert!((m.slope(0.0) - m.k_a).abs() < 1e-2);
        assert!((m.slope(0.35) - m.f13(0.35)).abs() < 1e-3);
        assert!((m.slope(2.0) - m.k_phi).abs() < 1e-9);
        assert_eq!(m.p(0.0), m.p0);
        // Regime C: p grows at K_phi.
        assert!(((m.p(2.0) - m.p(1.5)) / 0.5 - m.k_phi).abs() < 1e-9);
        // p is the integral of the slope: central difference check.
        let h = 0.4;
        let d = (m.p(h + 1e-4) - m.p(h - 1e-4)) / 2e-4;
        assert!((d - m.slope(h)).abs() < 1e-5 * m.slope(h));
        // Eq 12/13 consistency: f = (K_phi/3) dH/dh.
        let dh = 1e-6;
        let dhdh = (stagnant_cone_height(h + dh, m.h_a, m.h_b, m.phi)
            - stagnant_cone_height(h - dh, m.h_a, m.h_b, m.phi))
            / (2.0 * dh);
        assert!((m.f13(h) - m.k_phi * dhdh / 3.0).abs() < 1e-6);
    }

    #[test]
    fn unified_fit_recovers_parameters() {
        let m = truth();
        let h: Vec<f64> = (0..=160).map(|i| i as f64 * 0.0125).collect();
        let p: Vec<f64> = h.iter().map(|&x| m.p(x)).collect();
        let (fit, r2) = fit_unified_fdr(&h, &p, m.k_phi, m.phi).unwrap();
        assert!(r2 > 0.999_999, "R^2 = {r2}");
        for (got, want, name) in [
            (fit.k_a, m.k_a, "k_a"),
            (fit.h_a, m.h_a, "h_a"),
            (fit.h_b, m.h_b, "h_b"),
            (fit.delta, m.delta, "delta"),
            (fit.p0, m.p0, "p0"),
        ] {
            assert!(
                (got - want).abs() < 1e-4 * want.abs(),
                "{name}: {got} vs {want}"
            );
        }
        // With deterministic noise (1% of the range) the fit stays good.
        let amp = 0.01 * (p[p.len() - 1] - p[0]);
        let mut state = 12345u64;
        let noisy: Vec<f64> = p
            .iter()
            .map(|v| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                v + amp * ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5)
            })
            .collect();
        let (fit, r2) = fit_unified_fdr(&h, &noisy, m.k_phi, m.phi).unwrap();
        assert!(r2 > 0.999, "noisy R^2 = {r2}");
        assert!(
            (fit.h_a - m.h_a).abs() < 0.03 && (fit.h_b - m.h_b).abs() < 0.05,
            "{fit:?}"
        );
    }

    #[test]
    fn unified_fit_negative_control() {
        // A saturating curve with no steady linear regime: the unified FDR,
        // whose final gradient is pinned to K_phi, must not fit it well.
        let h: Vec<f64> = (0..=160).map(|i| i as f64 * 0.0125).collect();
        let p: Vec<f64> = h.iter().map(|&x| 30.0 * (1.0 - (-x / 0.5).exp())).collect();
        let (_, r2) = fit_unified_fdr(&h, &p, 23.0, 25.94f64.to_radians()).unwrap();
        assert!(r2 < 0.99, "negative control R^2 = {r2}");
    }

    #[test]
    fn fit_rejects_bad_input() {
        assert!(fit_unified_fdr(&[0.0, 1.0], &[1.0, 2.0], 23.0, 0.4).is_err());
        let h = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5];
        assert!(fit_unified_fdr(&h, &[1.0; 5], 23.0, 0.4).is_err());
        assert!(fit_unified_fdr(&h, &[1.0; 6], 23.0, 0.4).is_err());
        assert!(fit_unified_fdr(&h, &h, -1.0, 0.4).is_err());
    }
}
