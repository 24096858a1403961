//! Adaptive Gauss-Kronrod (G7-K15) quadrature with propagated error estimates, so
//! nested integrals (MALT's eq 10) carry an honest error bound.

#[cfg(test)]
use anyhow::ensure;
use anyhow::{Result, bail};

/// Result of an adaptive quadrature: value and an estimate of its absolute error.
#[derive(Debug, Clone, Copy)]
pub struct Quad {
    pub value: f64,
    pub abs_err: f64,
}

// ---------------------------------------------------------------------------
// Adaptive Gauss-Kronrod quadrature
// ---------------------------------------------------------------------------

/// Kronrod abscissae (QUADPACK `qk15`); odd indices are the 7 Gauss nodes.
const XGK: [f64; 8] = [
    0.9914553711208126,
    0.9491079123427585,
    0.8648644233597691,
    0.7415311855993945,
    0.5860872354676911,
    0.4058451513773972,
    0.20778495500789848,
    0.0,
];
const WGK: [f64; 8] = [
    0.022935322010529224,
    0.06309209262997856,
    0.10479001032225019,
    0.14065325971552592,
    0.1690047266392679,
    0.19035057806478542,
    0.20443294007529889,
    0.20948214108472782,
];
const WG: [f64; 4] = [
    0.1294849661688697,
    0.27970539148927664,
    0.3818300505051189,
    0.4179591836734694,
];

/// Interval budget of one adaptive integration; generous because endpoint
/// singularities are resolved by bisection towards the endpoint.
pub(crate) const MAX_INTERVALS: usize = 2000;

#[derive(Clone, Copy)]
struct Piece {
    a: f64,
    b: f64,
    value: f64,
    err: f64,
    splittable: bool,
}

/// One G7-K15 panel. The integrand returns `(value, abs_err_of_value)`; the
/// second component lets nested quadratures (eq 10 has an integral inside
/// `A`) carry the inner error into the outer estimate, weighted like the
/// value itself.
fn gk15<F: Fn(f64) -> (f64, f64)>(f: &F, a: f64, b: f64) -> Result<(f64, f64)> {
    let centr = 0.5 * (a + b);
    let hlgth = 0.5 * (b - a);
    let dhlgth = hlgth.abs();
    let mut fv1 = [0.0; 7];
    let mut fv2 = [0.0; 7];
    let (fc, ec) = f(centr);
    let mut resg = fc * WG[3];
    let mut resk = fc * WGK[7];
    let mut resabs = resk.abs();
    let mut prop = WGK[7] * ec.abs();
    for j in 0..7 {
        let absc = hlgth * XGK[j];
        let (f1, e1) = f(centr - absc);
        let (f2, e2) = f(centr + absc);
        fv1[j] = f1;
        fv2[j] = f2;
        resk += WGK[j] * (f1 + f2);
        resabs += WGK[j] * (f1.abs() + f2.abs());
        prop += WGK[j] * (e1.abs() + e2.abs());
        if j % 2 == 1 {
            resg += WG[j / 2] * (f1 + f2);
        }
    }
    if !resk.is_finite() || !prop.is_finite() {
        bail!("non-finite integrand value on [{a}, {b}]");
    }
    let reskh = 0.5 * resk;
    let mut resasc = WGK[7] * (fc - reskh).abs();
    for j in 0..7 {
        resasc += WGK[j] * ((fv1[j] - reskh).abs() + (fv2[j] - reskh).abs());
    }
    let result = resk * hlgth;
    resabs *= dhlgth;
    resasc *= dhlgth;
    // QUADPACK's calibration of |K15 - G7|: deliberately pessimistic for
    // smooth integrands, with a round-off floor, so the estimate is a bound in
    // practice rather than a guess.
    let mut abserr = ((resk - resg) * hlgth).abs();
    if resasc != 0.0 && abserr != 0.0 {
        abserr = resasc * (200.0 * abserr / resasc).powf(1.5).min(1.0);
    }
    if resabs > f64::MIN_POSITIVE / (50.0 * f64::EPSILON) {
        abserr = abserr.max(50.0 * f64::EPSILON * resabs);
    }
    Ok((result, abserr + prop * dhlgth))
}

/// Globally adaptive bisection (always split the panel with the largest
/// error). Returns the estimate and whether the tolerance was met, so that
/// callers that can live with a looser result (inner integrals whose error
/// is propagated anyway) need not fail.
pub(crate) fn adaptive<F: Fn(f64) -> (f64, f64)>(
    f: &F,
    a: f64,
    b: f64,
    abs_tol: f64,
    rel_tol: f64,
    max_intervals: usize,
) -> Result<(Quad, bool)> {
    let (v, e) = gk15(f, a, b)?;
    let mut pieces = vec![Piece {
        a,
        b,
        value: v,
        err: e,
        splittable: true,
    }];
    loop {
        let value: f64 = pieces.iter().map(|p| p.value).sum();
        let err: f64 = pieces.iter().map(|p| p.err).sum();
        let q = Quad {
            value,
            abs_err: err,
        };
        if err <= abs_tol.max(rel_tol * value.abs()) {
            return Ok((q, true));
        }
        if pieces.len() >= max_intervals {
            return Ok((q, false));
        }
        let worst = pieces
            .iter()
            .enumerate()
            .filter(|(_, p)| p.splittable)
            .max_by(|x, y| x.1.err.total_cmp(&y.1.err))
            .map(|(i, _)| i);
        let Some(i) = worst else {
            return Ok((q, false));
        };
        let p = pieces[i];
        let m = 0.5 * (p.a + p.b);
        // A panel at the resolution of f64 cannot be refined further; keep
        // its (large) error so the caller learns the tolerance was not met.
        if !(m > p.a.min(p.b) && m < p.a.max(p.b))
            || (p.b - p.a).abs() <= 8.0 * f64::EPSILON * p.a.abs().max(p.b.abs())
        {
            pieces[i].splittable = false;
            continue;
        }
        let (v1, e1) = gk15(f, p.a, m)?;
        let (v2, e2) = gk15(f, m, p.b)?;
        pieces[i] = Piece {
            a: p.a,
            b: m,
            value: v1,
            err: e1,
            splittable: true,
        };
        pieces.push(Piece {
            a: m,
            b: p.b,
            value: v2,
            err: e2,
            splittable: true,
        });
    }
}

/// Adaptive quadrature after the change of variable
/// `x = a + (b-a) u^2 (3 - 2u)`, whose Jacobian `6u(1-u)` vanishes at both
/// ends. This turns `x^-1/2` into a smooth function and `ln x` into
/// `u ln u`, which is why GK bisection then converges quickly at integrable
/// endpoint singularities (eq 10's integrands are singular at `eta -> 0`).
pub(crate) fn adaptive_mapped<F: Fn(f64) -> (f64, f64)>(
    f: &F,
    a: f64,
    b: f64,
    abs_tol: f64,
    rel_tol: f64,
    max_intervals: usize,
) -> Result<(Quad, bool)> {
    let w = b - a;
    let g = |u: f64| {
        // Evaluate from the nearer end so points close to `b` keep their
        // distance to `b` instead of rounding onto it.
        let x = if u <= 0.5 {
            a + w * u * u * (3.0 - 2.0 * u)
        } else {
            let v = 1.0 - u;
            b - w * v * v * (3.0 - 2.0 * v)
        };
        // A node that collapses onto an endpoint lies inside a sub-ulp
        // sliver whose contribution to an integrable singularity is below
        // round-off; skipping it avoids evaluating f at the singular point.
        if x == a || x == b {
            return (0.0, 0.0);
        }
        let jac = 6.0 * w * u * (1.0 - u);
        let (fv, fe) = f(x);
        (fv * jac, fe * jac.abs())
    };
    adaptive(&g, 0.0, 1.0, abs_tol, rel_tol, max_intervals)
}

/// Adaptive Gauss-Kronrod (G7-K15) quadrature on [a,b] with bisection until
/// the error estimate is below max(abs_tol, rel_tol*|value|).
///
/// Integrable end-point singularities (e.g. `1/sqrt(x)`, `ln x`) are handled
/// by a polynomial change of variable whose Jacobian vanishes at both ends,
/// so the integrand is never evaluated at `a` or `b`. Fails if the bounds or
/// tolerances are invalid, if the integrand returns a non-finite value, or if
/// the tolerance cannot be met within the interval budget.
#[cfg(test)]
pub fn integrate<F: Fn(f64) -> f64>(
    f: F,
    a: f64,
    b: f64,
    abs_tol: f64,
    rel_tol: f64,
) -> Result<Quad> {
    ensure!(
        a.is_finite() && b.is_finite(),
        "integration bounds must be finite (got [{a}, {b}])"
    );
    ensure!(
        abs_tol >= 0.0 && rel_tol >= 0.0 && (abs_tol > 0.0 || rel_tol > 0.0),
        "tolerances must be non-negative and not both zero (abs {abs_tol}, rel {rel_tol})"
    );
    if a == b {
        return Ok(Quad {
            value: 0.0,
            abs_err: 0.0,
        });
    }
    let (lo, hi, sign) = if a < b { (a, b, 1.0) } else { (b, a, -1.0) };
    let (q, ok) = adaptive_mapped(&|x| (f(x), 0.0), lo, hi, abs_tol, rel_tol, MAX_INTERVALS)?;
    ensure!(
        ok,
        "quadrature on [{a}, {b}] did not reach tolerance: value {} +- {}",
        sign * q.value,
        q.abs_err
    );
    Ok(Quad {
        value: sign * q.value,
        abs_err: q.abs_err,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn integrate_endpoint_singularities() {
        let q = integrate(|x: f64| x.powf(-0.5), 0.0, 1.0, 1e-12, 1e-12).unwrap();
        let err = (q.value - 2.0).abs();
        assert!(err <= q.abs_err.max(1e-15), "x^-1/2: {q:?}");
        assert!(q.abs_err < 1e-11, "x^-1/2: {q:?}");
        let q = integrate(f64::ln, 0.0, 1.0, 1e-12, 1e-12).unwrap();
        let err = (q.value + 1.0).abs();
        assert!(err <= q.abs_err, "ln x: {q:?} actual {err:e}");
        assert!(q.abs_err < 1e-11, "ln x: {q:?}");
        // Singularity at the upper end, reversed bounds, and a smooth case.
        let q = integrate(|x: f64| (1.0 - x).ln(), 1.0, 0.0, 1e-12, 1e-12).unwrap();
        assert!(
            (q.value - 1.0).abs() <= q.abs_err,
            "ln(1-x) reversed: {q:?}"
        );
        let q = integrate(f64::sin, 0.0, PI, 1e-13, 0.0).unwrap();
        assert!((q.value - 2.0).abs() <= q.abs_err && q.abs_err < 1e-13);
        // A tolerance that cannot be met is an error, not a silent result.
        assert!(integrate(|x: f64| 1.0 / x, 0.0, 1.0, 1e-10, 1e-10).is_err());
    }
}
