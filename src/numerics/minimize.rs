//! Derivative-free minimisation.

/// Compact Nelder-Mead simplex minimiser (standard coefficients 1, 2, 1/2,
/// 1/2). Stops when the simplex has collapsed in both position and value.
pub(crate) fn nelder_mead<const N: usize, F: Fn(&[f64; N]) -> f64>(
    f: &F,
    x0: [f64; N],
    step: f64,
    f_abs_tol: f64,
    max_iter: usize,
) -> ([f64; N], f64) {
    let mut pts: Vec<([f64; N], f64)> = Vec::with_capacity(N + 1);
    pts.push((x0, f(&x0)));
    for i in 0..N {
        let mut x = x0;
        x[i] += step;
        pts.push((x, f(&x)));
    }
    for _ in 0..max_iter {
        pts.sort_by(|a, b| a.1.total_cmp(&b.1));
        let (best, worst) = (pts[0].1, pts[N].1);
        let size = pts[1..]
            .iter()
            .flat_map(|(x, _)| x.iter().zip(&pts[0].0).map(|(a, b)| (a - b).abs()))
            .fold(0.0, f64::max);
        if size < 1e-10 && worst - best <= f_abs_tol + 1e-13 * best.abs() {
            break;
        }
        let mut cen = [0.0; N];
        for (x, _) in &pts[..N] {
            for (c, xj) in cen.iter_mut().zip(x) {
                *c += xj / N as f64;
            }
        }
        let along =
            |t: f64| -> [f64; N] { std::array::from_fn(|j| cen[j] + t * (pts[N].0[j] - cen[j])) };
        let xr = along(-1.0);
        let fr = f(&xr);
        if fr < pts[0].1 {
            let xe = along(-2.0);
            let fe = f(&xe);
            pts[N] = if fe < fr { (xe, fe) } else { (xr, fr) };
        } else if fr < pts[N - 1].1 {
            pts[N] = (xr, fr);
        } else {
            let (xc, fc) = if fr < pts[N].1 {
                let x = along(-0.5);
                (x, f(&x))
            } else {
                let x = along(0.5);
                (x, f(&x))
            };
            if fc < fr.min(pts[N].1) {
                pts[N] = (xc, fc);
            } else {
                let x_best = pts[0].0;
                for p in pts.iter_mut().skip(1) {
                    for (xj, bj) in p.0.iter_mut().zip(&x_best) {
                        *xj = bj + 0.5 * (*xj - bj);
                    }
                    p.1 = f(&p.0);
                }
            }
        }
    }
    pts.sort_by(|a, b| a.1.total_cmp(&b.1));
    pts[0]
}
