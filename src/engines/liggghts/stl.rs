//! ASCII STL of the penetration intruder for LIGGGHTS
//! (`fix mesh/surface/stress file intruder.stl ...`): a closed, flat-bottomed cylinder,
//! the mesh counterpart of [`crate::physics::dem::intruder::FlatCylinder`].
//!
//! The rim circles are regular n-gons inscribed in the circle of radius R, so the mesh
//! lies inside the true cylinder by at most the sagitta `R (1 - cos(pi/n))` (midpoints of
//! the rim chords). Facets (4n in total): n bottom fan triangles around the bottom centre
//! (normal -z), n top fan triangles (+z) and 2n side triangles (two per quad), all wound
//! counter-clockwise seen from outside so normals point out. Every ring vertex is computed
//! once and reused, and written with `{:e}` (shortest round-trip form), so shared vertices
//! are bit-identical in the file and the surface is closed exactly.

#[cfg(test)]
use anyhow::{Context, Result};
use std::f64::consts::PI;
use std::fmt::Write as _;
#[cfg(test)]
use std::path::Path;

/// Fewest segments ever used, whatever the requested rim error.
pub(crate) const MIN_SEGMENTS: usize = 24;

/// Maximum rim error of an inscribed regular n-gon as a fraction of R:
/// `1 - cos(pi/n)`, evaluated as `2 sin^2(pi/2n)` to avoid cancellation.
pub fn rim_error_frac(n: usize) -> f64 {
    let s = (PI / (2.0 * n as f64)).sin();
    2.0 * s * s
}

/// Smallest multiple of 4, at least [`MIN_SEGMENTS`], whose rim error is strictly below
/// `max_rim_error_frac` (24 for 1 %, 72 for 0.1 %).
pub fn segments_for_rim_error(max_rim_error_frac: f64) -> usize {
    assert!(
        max_rim_error_frac.is_finite() && max_rim_error_frac > 0.0,
        "rim error fraction must be positive and finite, got {max_rim_error_frac}"
    );
    // Continuous threshold n* = pi / (2 asin(sqrt(f/2))); start a little below it.
    let f = max_rim_error_frac.min(1.0);
    let n_star = PI / (2.0 * (f / 2.0).sqrt().asin());
    let mut n = ((n_star / 4.0).floor() as usize).saturating_sub(2) * 4;
    n = n.max(MIN_SEGMENTS);
    while rim_error_frac(n) >= max_rim_error_frac {
        n += 4;
    }
    n
}

fn facet(out: &mut String, a: [f64; 3], b: [f64; 3], c: [f64; 3]) {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    // Writing to a String cannot fail.
    let _ = writeln!(
        out,
        "facet normal {:e} {:e} {:e}\n outer loop",
        n[0] / l,
        n[1] / l,
        n[2] / l
    );
    for p in [a, b, c] {
        let _ = writeln!(out, "  vertex {:e} {:e} {:e}", p[0], p[1], p[2]);
    }
    out.push_str(" endloop\nendfacet\n");
}

/// ASCII STL of a closed cylinder of `radius` and `length`, axis +z, bottom disk centred
/// at `bottom_center`, with the segment count of [`segments_for_rim_error`].
/// Returns the file text and the number of azimuthal segments n (the mesh has 4n facets).
pub(crate) fn flat_cylinder_stl(
    radius: f64,
    length: f64,
    bottom_center: [f64; 3],
    max_rim_error_frac: f64,
) -> (String, usize) {
    assert!(
        radius > 0.0 && length > 0.0 && radius.is_finite() && length.is_finite(),
        "cylinder needs positive finite radius and length"
    );
    let n = segments_for_rim_error(max_rim_error_frac);
    let [cx, cy, z0] = bottom_center;
    let z1 = z0 + length;
    let ring: Vec<(f64, f64)> = (0..n)
        .map(|k| {
            let (s, c) = (2.0 * PI * k as f64 / n as f64).sin_cos();
            (cx + radius * c, cy + radius * s)
        })
        .collect();
    let c0 = [cx, cy, z0];
    let c1 = [cx, cy, z1];
    let mut out = String::with_capacity(4 * n * 260 + 64);
    out.push_str("solid granval_intruder\n");
    for k in 0..n {
        let (ax, ay) = ring[k];
        let (bx, by) = ring[(k + 1) % n];
        let (a0, b0) = ([ax, ay, z0], [bx, by, z0]);
        let (a1, b1) = ([ax, ay, z1], [bx, by, z1]);
        facet(&mut out, c0, b0, a0);
        facet(&mut out, c1, a1, b1);
        facet(&mut out, a0, b0, b1);
        facet(&mut out, a0, b1, a1);
    }
    out.push_str("endsolid granval_intruder\n");
    (out, n)
}

/// Writes [`flat_cylinder_stl`] to `path`; returns the number of segments.
#[cfg(test)]
pub(crate) fn write_flat_cylinder_stl(
    path: &Path,
    radius: f64,
    length: f64,
    bottom_center: [f64; 3],
    max_rim_error_frac: f64,
) -> Result<usize> {
    let (text, n) = flat_cylinder_stl(radius, length, bottom_center, max_rim_error_frac);
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
    Ok(n)
}

/// ASCII STL of one equilateral triangle in the plane `x[axis] = position`, centred at
/// `centre` (the other two coordinates, in axis order `axis + 1`, `axis + 2` mod 3) with
/// circumradius `r`: the mesh of a plane wall whose edges must stay away from the grains
/// (the triaxial box's walls).
pub(crate) fn triangle_stl(
    name: &str,
    axis: usize,
    position: f64,
    centre: [f64; 2],
    r: f64,
) -> String {
    let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
    let vertex = |deg: f64| {
        let (s, c) = deg.to_radians().sin_cos();
        let mut p = [0.0; 3];
        p[axis] = position;
        p[a] = centre[0] + r * c;
        p[b] = centre[1] + r * s;
        p
    };
    let mut out = format!("solid {name}\n");
    facet(&mut out, vertex(90.0), vertex(210.0), vertex(330.0));
    out.push_str(&format!("endsolid {name}\n"));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    type V = [f64; 3];

    const R: f64 = 0.015;
    const L: f64 = 0.05;
    const C: V = [0.1, -0.2, 0.3];

    /// Parses our own ASCII STL into (normal, vertices) facets, checking the grammar.
    fn parse(text: &str) -> Vec<(V, [V; 3])> {
        let mut lines = text.lines().map(str::trim);
        assert!(lines.next().unwrap().starts_with("solid "));
        let nums = |l: &str, key: &str| -> V {
            let rest = l.strip_prefix(key).unwrap_or_else(|| panic!("{key}: {l}"));
            let v: Vec<f64> = rest
                .split_whitespace()
                .map(|t| t.parse().unwrap())
                .collect();
            assert_eq!(v.len(), 3);
            [v[0], v[1], v[2]]
        };
        let mut out = Vec::new();
        loop {
            let l = lines.next().expect("endsolid");
            if l.starts_with("endsolid") {
                break;
            }
            let normal = nums(l, "facet normal");
            assert_eq!(lines.next(), Some("outer loop"));
            let vs = [0, 1, 2].map(|_| nums(lines.next().unwrap(), "vertex"));
            assert_eq!(lines.next(), Some("endloop"));
            assert_eq!(lines.next(), Some("endfacet"));
            out.push((normal, vs));
        }
        assert!(lines.next().is_none());
        out
    }

    fn sub(a: V, b: V) -> V {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
    }
    fn cross(u: V, v: V) -> V {
        [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ]
    }
    fn dot(a: V, b: V) -> f64 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }
    fn key(p: V) -> [u64; 3] {
        p.map(f64::to_bits)
    }

    fn mesh(frac: f64) -> (Vec<(V, [V; 3])>, usize) {
        let (text, n) = flat_cylinder_stl(R, L, C, frac);
        (parse(&text), n)
    }

    #[test]
    fn segment_counts() {
        assert_eq!(segments_for_rim_error(0.01), 24);
        assert_eq!(segments_for_rim_error(0.5), 24);
        assert_eq!(segments_for_rim_error(0.001), 72);
        assert_eq!(segments_for_rim_error(1e-4), 224);
        for f in [0.01, 3e-3, 1e-3, 2.5e-4, 1e-4, 1e-6] {
            let n = segments_for_rim_error(f);
            assert_eq!(n % 4, 0);
            assert!(rim_error_frac(n) < f);
            assert!(n == MIN_SEGMENTS || rim_error_frac(n - 4) >= f, "{f}: {n}");
        }
        // The cancellation-free form agrees with the textbook one.
        approx::assert_relative_eq!(
            rim_error_frac(24),
            1.0 - (PI / 24.0).cos(),
            max_relative = 1e-12
        );
    }

    #[test]
    fn facet_count_is_4n() {
        for f in [0.01, 1e-3] {
            let (m, n) = mesh(f);
            assert_eq!(m.len(), 4 * n);
        }
    }

    #[test]
    fn closed_and_consistently_oriented() {
        for f in [0.01, 1e-3] {
            let (m, _) = mesh(f);
            let mut undirected: HashMap<([u64; 3], [u64; 3]), usize> = HashMap::new();
            let mut directed: HashMap<([u64; 3], [u64; 3]), usize> = HashMap::new();
            for (_, v) in &m {
                for i in 0..3 {
                    let (a, b) = (key(v[i]), key(v[(i + 1) % 3]));
                    *directed.entry((a, b)).or_default() += 1;
                    *undirected
                        .entry(if a < b { (a, b) } else { (b, a) })
                        .or_default() += 1;
                }
            }
            assert!(
                undirected.values().all(|&c| c == 2),
                "open or non-manifold edge"
            );
            // Each edge is traversed once in each direction: consistent winding.
            assert!(directed.values().all(|&c| c == 1));
            // Euler characteristic of a sphere: V - E + F = 2.
            let nv = m
                .iter()
                .flat_map(|(_, v)| v.iter().map(|&p| key(p)))
                .collect::<std::collections::HashSet<_>>()
                .len();
            assert_eq!(nv as i64 - undirected.len() as i64 + m.len() as i64, 2);
        }
    }

    #[test]
    fn normals_point_outward() {
        let (m, n) = mesh(0.01);
        let (mut bottom, mut top, mut side) = (0, 0, 0);
        for (normal, v) in &m {
            // The stated normal is the unit right-hand normal of the vertex order.
            let rh = cross(sub(v[1], v[0]), sub(v[2], v[0]));
            let l = dot(rh, rh).sqrt();
            assert!(l > 0.0, "degenerate facet");
            for k in 0..3 {
                approx::assert_abs_diff_eq!(normal[k], rh[k] / l, epsilon = 1e-12);
            }
            approx::assert_abs_diff_eq!(dot(*normal, *normal), 1.0, epsilon = 1e-12);
            let zs = v.map(|p| p[2]);
            if zs.iter().all(|&z| z == C[2]) {
                assert_eq!(*normal, [0.0, 0.0, -1.0]);
                bottom += 1;
            } else if zs.iter().all(|&z| z == C[2] + L) {
                assert_eq!(*normal, [0.0, 0.0, 1.0]);
                top += 1;
            } else {
                let g = [0, 1, 2].map(|k| (v[0][k] + v[1][k] + v[2][k]) / 3.0);
                let radial = [g[0] - C[0], g[1] - C[1], 0.0];
                let cos = dot(*normal, radial) / dot(radial, radial).sqrt();
                assert!(cos > (PI / n as f64).cos() - 1e-9, "{cos}");
                approx::assert_abs_diff_eq!(normal[2], 0.0, epsilon = 1e-12);
                side += 1;
            }
        }
        assert_eq!((bottom, top, side), (n, n, 2 * n));
    }

    #[test]
    fn volume_by_divergence_theorem() {
        for f in [0.01, 1e-3, 1e-4] {
            let (m, n) = mesh(f);
            // V = 1/6 sum a . (b x c), about the bottom centre to avoid cancellation.
            let vol: f64 = m
                .iter()
                .map(|(_, v)| {
                    let [a, b, c] = v.map(|p| sub(p, C));
                    dot(a, cross(b, c))
                })
                .sum::<f64>()
                / 6.0;
            let nf = n as f64;
            let prism = 0.5 * nf * R * R * (2.0 * PI / nf).sin() * L;
            approx::assert_relative_eq!(vol, prism, max_relative = 1e-12);
            // Between the cylinders of the inscribed circle R cos(pi/n) and the true one.
            let cyl = PI * R * R * L;
            let rin = R * (PI / nf).cos();
            assert!(vol < cyl && vol > PI * rin * rin * L, "{f}: {vol} vs {cyl}");
            assert!((cyl - vol) / cyl < 2.0 * f);
        }
    }

    #[test]
    fn rim_error_below_request() {
        for f in [0.01, 1e-3] {
            let (m, n) = mesh(f);
            let rho = |p: V| ((p[0] - C[0]).powi(2) + (p[1] - C[1]).powi(2)).sqrt();
            let mut worst: f64 = 0.0;
            for (_, v) in &m {
                for i in 0..3 {
                    let (a, b) = (v[i], v[(i + 1) % 3]);
                    if rho(a) > 0.5 * R {
                        approx::assert_relative_eq!(rho(a), R, max_relative = 1e-12);
                    }
                    // Rim chords: both ends on the ring at the same height.
                    if a[2] == b[2] && rho(a) > 0.5 * R && rho(b) > 0.5 * R {
                        let mid = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), a[2]];
                        worst = worst.max(R - rho(mid));
                    }
                }
            }
            approx::assert_relative_eq!(worst / R, rim_error_frac(n), max_relative = 1e-6);
            assert!(worst < f * R, "{f}: {}", worst / R);
        }
    }

    #[test]
    fn writes_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("intruder.stl");
        let n = write_flat_cylinder_stl(&path, R, L, C, 0.01).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(parse(&text).len(), 4 * n);
    }
}
