//! The penetration intruder of Feng et al. (003_7b2069b9a928ac9b.txt, Sec. 2): a solid,
//! flat-bottomed cylinder with its axis along +z, driven down the container axis.
//!
//! Contacts follow the convention of [`super::walls::wall_contact`]: `delta` points from
//! the closest point of the solid's surface to the sphere centre and `r` is its length,
//! so `hertz_history` sees the overlap `r_i - r` along `delta / r`.
//!
//! Outside the solid the closest point is exact in all three regions:
//! - flat faces (radial distance `rho <= R`, below the bottom or above the top): the face
//!   normal, `delta = (0, 0, dz)`;
//! - the side (`0 <= z - z_bottom <= L`, `rho > R`): radial, `delta = (rho - R) e_rho`;
//! - the rim edges (`rho > R` and beyond a face): the nearest point of the rim circle,
//!   `delta = (rho - R) e_rho + dz e_z`.
//!
//! One formula covers all three (`dr = max(rho - R, 0)`, `dz` = distance beyond the
//! nearer face or 0), so the distance is continuous (indeed 1-Lipschitz) in `x`.
//!
//! **Centre inside the solid** (or exactly on its surface). A rigid intruder must push the
//! grain out, never ignore it (LIGGGHTS' mesh contact treats a surface as a two-sided shell
//! and would push such a grain further in). We push it out along the outward normal of the
//! nearest face (smallest depth; ties go bottom, then top, then side; the side is not a
//! candidate for a centre exactly on the axis, where its normal is undefined). The
//! returned `r` is clamped to `INSIDE_FLOOR_FRAC * r_i` and `delta` is that length along
//! the outward normal, so the overlap `r_i - r` saturates at `(1 - 1e-6) r_i` instead of
//! growing with the true depth `r_i + depth`. A negative `r` (true overlap) would flip the
//! sign of the wall rolling terms in `hertz_history`, which divide by `r`; the clamp keeps
//! the contact law valid, and the force stays continuous and monotone as the centre moves
//! in. Use [`FlatCylinder::signed_distance`] to detect such (unphysical) deep penetrations.

use crate::numerics::vec3::V3;

/// Floor of the returned centre-surface distance, as a fraction of the sphere radius, once
/// the centre reaches the surface or enters the solid.
pub(crate) const INSIDE_FLOOR_FRAC: f64 = 1e-6;

/// A solid cylinder with its axis along +z; bottom disk centred at `axis_point`, top disk
/// at `axis_point.z + length`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlatCylinder {
    pub radius: f64,
    pub length: f64,
    /// Centre of the bottom disk.
    pub axis_point: [f64; 3],
}

/// Closest point of the solid's surface to a point, with the outward direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SurfaceQuery {
    /// Closest point on the surface (inside: the projection onto the nearest face).
    pub point: V3,
    /// Unit outward direction: `(x - point) / distance` outside, the nearest face's
    /// outward normal on the surface or inside.
    pub normal: V3,
    /// Signed distance: positive outside, negative inside, 0 on the surface.
    pub distance: f64,
    /// `x - point`, computed without cancellation against the absolute coordinates.
    pub delta: V3,
}

impl FlatCylinder {
    pub fn new(radius: f64, length: f64, axis_point: [f64; 3]) -> Self {
        assert!(
            radius > 0.0 && length > 0.0,
            "intruder needs positive radius and length"
        );
        FlatCylinder {
            radius,
            length,
            axis_point,
        }
    }

    /// Moves the intruder along its axis (negative `dz` drives it into the bed).
    pub(crate) fn translate(&mut self, dz: f64) {
        self.axis_point[2] += dz;
    }

    pub fn bottom_z(&self) -> f64 {
        self.axis_point[2]
    }

    #[cfg(test)]
    pub(crate) fn top_z(&self) -> f64 {
        self.axis_point[2] + self.length
    }

    /// Closest surface point, outward direction and signed distance of `x`.
    pub(crate) fn query(&self, x: V3) -> SurfaceQuery {
        let a = self.axis_point;
        let (rad, len) = (self.radius, self.length);
        let px = x[0] - a[0];
        let py = x[1] - a[1];
        let pz = x[2] - a[2];
        let rho = (px * px + py * py).sqrt();
        let dr = if rho > rad { rho - rad } else { 0.0 };
        let dz = if pz < 0.0 {
            pz
        } else if pz > len {
            pz - len
        } else {
            0.0
        };
        if dr > 0.0 || dz != 0.0 {
            // Outside: face (dr = 0), side (dz = 0) or rim (both).
            let (ex, ey) = if dr > 0.0 {
                (px / rho, py / rho)
            } else {
                (0.0, 0.0)
            };
            let delta = [ex * dr, ey * dr, dz];
            let distance = (dr * dr + dz * dz).sqrt();
            let point = [
                if dr > 0.0 { a[0] + ex * rad } else { x[0] },
                if dr > 0.0 { a[1] + ey * rad } else { x[1] },
                if dz < 0.0 {
                    a[2]
                } else if dz > 0.0 {
                    a[2] + len
                } else {
                    x[2]
                },
            ];
            let normal = [delta[0] / distance, delta[1] / distance, dz / distance];
            return SurfaceQuery {
                point,
                normal,
                distance,
                delta,
            };
        }
        // On the surface or inside: nearest face, ties bottom < top < side.
        let d_bottom = pz;
        let d_top = len - pz;
        let d_side = rad - rho;
        let mut depth = d_bottom;
        let mut face = 0;
        if d_top < depth {
            depth = d_top;
            face = 1;
        }
        if rho > 0.0 && d_side < depth {
            depth = d_side;
            face = 2;
        }
        let (point, normal, delta) = match face {
            0 => ([x[0], x[1], a[2]], [0.0, 0.0, -1.0], [0.0, 0.0, pz]),
            1 => (
                [x[0], x[1], a[2] + len],
                [0.0, 0.0, 1.0],
                [0.0, 0.0, pz - len],
            ),
            _ => {
                let (ex, ey) = (px / rho, py / rho);
                (
                    [a[0] + ex * rad, a[1] + ey * rad, x[2]],
                    [ex, ey, 0.0],
                    [-ex * depth, -ey * depth, 0.0],
                )
            }
        };
        SurfaceQuery {
            point,
            normal,
            distance: -depth,
            delta,
        }
    }

    /// Signed distance from `x` to the surface (negative inside).
    pub(crate) fn signed_distance(&self, x: V3) -> f64 {
        self.query(x).distance
    }

    /// Whether `x` lies inside the solid or on its surface.
    pub fn contains(&self, x: V3) -> bool {
        self.signed_distance(x) <= 0.0
    }

    /// Surface-to-centre vector and its length if the sphere (centre `x`, radius `r > 0`)
    /// touches the solid; see the module docs for centres on the surface or inside.
    #[inline]
    pub(crate) fn closest_contact(&self, x: V3, r: f64) -> Option<(V3, f64)> {
        debug_assert!(r > 0.0, "sphere radius must be positive");
        let q = self.query(x);
        if q.distance - r > 0.0 {
            return None;
        }
        let floor = INSIDE_FLOOR_FRAC * r;
        if q.distance >= floor {
            Some((q.delta, q.distance))
        } else {
            let n = q.normal;
            Some(([n[0] * floor, n[1] * floor, n[2] * floor], floor))
        }
    }

    /// Closest point of the solid's surface to the centre if the sphere touches the solid
    /// (inside: its projection onto the face it is pushed out of). This is where the
    /// grain's force acts on the intruder.
    #[cfg(test)]
    pub(crate) fn contact_point(&self, x: V3, r: f64) -> Option<V3> {
        let q = self.query(x);
        (q.distance - r <= 0.0).then_some(q.point)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::RollingModel;
    use crate::numerics::vec3::{dot, norm, sub};
    use crate::physics::dem::contact::{ContactGeom, History, PairCoeffs, hertz_history};
    use approx::assert_abs_diff_eq;

    const R: f64 = 0.015;
    const L: f64 = 0.05;
    const A: V3 = [0.1, -0.2, 0.3];

    fn cyl() -> FlatCylinder {
        FlatCylinder::new(R, L, A)
    }

    fn at(d: V3) -> V3 {
        [A[0] + d[0], A[1] + d[1], A[2] + d[2]]
    }

    fn check(x: V3, r: f64, delta: V3, dist: f64) {
        let c = cyl();
        let (d, g) = c.closest_contact(x, r).expect("touching");
        assert_abs_diff_eq!(g, dist, epsilon = 1e-15);
        for k in 0..3 {
            assert_abs_diff_eq!(d[k], delta[k], epsilon = 1e-15);
        }
        approx::assert_relative_eq!(norm(d), g, max_relative = 1e-12);
        // Contact point + delta is the centre.
        let p = c.contact_point(x, r).expect("touching");
        for k in 0..3 {
            assert_abs_diff_eq!(p[k] + d[k], x[k], epsilon = 1e-15);
        }
    }

    #[test]
    fn bottom_face_region() {
        check(at([0.005, 0.003, -0.001]), 0.002, [0.0, 0.0, -0.001], 0.001);
        // Straight below the axis, too.
        check(at([0.0, 0.0, -0.0015]), 0.002, [0.0, 0.0, -0.0015], 0.0015);
    }

    #[test]
    fn top_face_region() {
        check(
            at([-0.01, 0.0, L + 0.0015]),
            0.002,
            [0.0, 0.0, 0.0015],
            0.0015,
        );
    }

    #[test]
    fn side_region() {
        check(
            at([0.0, R + 0.0015, 0.02]),
            0.002,
            [0.0, 0.0015, 0.0],
            0.0015,
        );
        // 45 degrees: (rho - R) e_rho.
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let rho = R + 0.001;
        check(
            at([-rho * s, rho * s, 0.01]),
            0.002,
            [-0.001 * s, 0.001 * s, 0.0],
            0.001,
        );
    }

    #[test]
    fn rim_regions() {
        // 3-4-5 triangles to the bottom and top rim circles.
        check(
            at([R + 0.0006, 0.0, -0.0008]),
            0.002,
            [0.0006, 0.0, -0.0008],
            0.001,
        );
        check(
            at([0.0, -(R + 0.0003), L + 0.0004]),
            0.001,
            [0.0, -0.0003, 0.0004],
            0.0005,
        );
        let p = cyl()
            .contact_point(at([R + 0.0006, 0.0, -0.0008]), 0.002)
            .unwrap();
        assert_abs_diff_eq!(p[0], A[0] + R, epsilon = 1e-15);
        assert_abs_diff_eq!(p[2], A[2], epsilon = 1e-15);
    }

    #[test]
    fn no_contact_when_clear() {
        let c = cyl();
        // Rim at distance 1e-3: radius 0.9e-3 is clear, 1.1e-3 touches.
        let x = at([R + 0.0006, 0.0, -0.0008]);
        assert!(c.closest_contact(x, 0.0009).is_none());
        assert!(c.contact_point(x, 0.0009).is_none());
        assert!(c.closest_contact(x, 0.0011).is_some());
        // Inside the bounding box of the rim but clear of the rounded edge:
        // dr = dz = 8e-4, distance 1.13e-3 > 1e-3.
        assert!(
            c.closest_contact(at([R + 0.0008, 0.0, -0.0008]), 0.001)
                .is_none()
        );
        assert!(c.closest_contact(at([0.0, 0.0, -0.0021]), 0.002).is_none());
        assert!(
            c.closest_contact(at([0.0, 0.0, L + 0.0021]), 0.002)
                .is_none()
        );
        assert!(
            c.closest_contact(at([R + 0.0021, 0.0, 0.02]), 0.002)
                .is_none()
        );
        assert!(c.closest_contact([10.0, 10.0, 10.0], 0.002).is_none());
    }

    #[test]
    fn continuous_from_face_through_rim_to_side() {
        let c = cyl();
        let r = 0.01; // large, so the whole path is in contact
        // Straight line: bottom-face region -> bottom rim -> side region.
        let x0 = at([0.5 * R, 0.2 * R, -0.008]);
        let x1 = at([R + 0.004, 0.3 * R, 0.002]);
        let n = 20_000;
        let mut prev: Option<(V3, V3, f64)> = None;
        let mut regions = Vec::new();
        for i in 0..=n {
            let t = i as f64 / n as f64;
            let x = [
                x0[0] + t * (x1[0] - x0[0]),
                x0[1] + t * (x1[1] - x0[1]),
                x0[2] + t * (x1[2] - x0[2]),
            ];
            let (d, g) = c.closest_contact(x, r).expect("in contact");
            let q = c.query(x);
            let region = match (q.delta[0] != 0.0 || q.delta[1] != 0.0, q.delta[2] != 0.0) {
                (false, true) => "face",
                (true, true) => "rim",
                (true, false) => "side",
                _ => "surface",
            };
            if regions.last() != Some(&region) {
                regions.push(region);
            }
            if let Some((xp, dp, gp)) = prev {
                let step = norm(sub(x, xp));
                // The distance to a convex body is 1-Lipschitz.
                assert!((g - gp).abs() <= step * (1.0 + 1e-9), "jump at t = {t}");
                // The direction turns smoothly (no jump between regions).
                let cos = dot(d, dp) / (g * gp);
                assert!(cos > 1.0 - 1e-4, "direction jump at t = {t}: {cos}");
            }
            prev = Some((x, d, g));
        }
        assert_eq!(regions, ["face", "rim", "side"]);
    }

    #[test]
    fn continuous_over_top_rim() {
        let c = cyl();
        let rho0 = 0.5 * R;
        let n = 10_000;
        let mut prev: Option<(V3, f64)> = None;
        // Arc of radius 2e-3 around the top rim, from above the top face to the side.
        for i in 0..=n {
            let t = -0.3 + 2.1 * i as f64 / n as f64; // angle from +z towards +rho
            let x = if t < 0.0 {
                at([R + rho0 * t, 0.0, L + 0.002])
            } else {
                at([
                    R + 0.002 * t.min(std::f64::consts::FRAC_PI_2).sin(),
                    0.0,
                    L + 0.002 * t.cos(),
                ])
            };
            let g = c.signed_distance(x);
            if let Some((xp, gp)) = prev {
                assert!((g - gp).abs() <= norm(sub(x, xp)) * (1.0 + 1e-9) + 1e-15);
            }
            prev = Some((x, g));
        }
    }

    #[test]
    fn symmetric_under_rotation_about_axis() {
        let c = cyl();
        let offsets = [
            [0.004, 0.001, -0.001],     // face
            [R + 0.0006, 0.0, -0.0008], // rim
            [R + 0.001, 0.0, 0.02],     // side
            [0.006, 0.0, L + 0.0007],   // top face
            [0.013, 0.0, 0.02],         // inside, nearest the side
        ];
        for off in offsets {
            let (d0, g0) = c.closest_contact(at(off), 0.002).unwrap();
            for k in 1..12 {
                let th = 0.53 * k as f64 + 0.1;
                let (s, co) = th.sin_cos();
                let rot = |v: V3| [co * v[0] - s * v[1], s * v[0] + co * v[1], v[2]];
                let (d, g) = c.closest_contact(at(rot(off)), 0.002).unwrap();
                approx::assert_relative_eq!(g, g0, max_relative = 1e-9);
                let e = rot(d0);
                for m in 0..3 {
                    assert_abs_diff_eq!(d[m], e[m], epsilon = 1e-12);
                }
            }
        }
    }

    #[test]
    fn inside_pushes_out_along_nearest_face() {
        let c = cyl();
        let r = 0.002;
        let floor = INSIDE_FLOOR_FRAC * r;
        let cases: [(V3, V3, f64); 4] = [
            ([0.001, 0.0, 0.002], [0.0, 0.0, -1.0], -0.002), // near bottom
            ([0.0, 0.001, L - 0.003], [0.0, 0.0, 1.0], -0.003), // near top
            ([0.0, -(R - 0.001), 0.025], [0.0, -1.0, 0.0], -0.001), // near side
            // On the axis the side (depth R = 0.015) is no candidate: bottom (0.02).
            ([0.0, 0.0, 0.02], [0.0, 0.0, -1.0], -0.02),
        ];
        for (off, n, sd) in cases {
            let x = at(off);
            assert!(c.contains(x));
            assert_abs_diff_eq!(c.signed_distance(x), sd, epsilon = 1e-15);
            let (d, g) = c.closest_contact(x, r).expect("inside is a contact");
            assert_eq!(g, floor);
            for k in 0..3 {
                assert_abs_diff_eq!(d[k] / g, n[k], epsilon = 1e-12);
            }
            // The contact point is the projection onto that face.
            let p = c.contact_point(x, r).unwrap();
            assert_abs_diff_eq!(norm(sub(x, p)), -sd, epsilon = 1e-15);
        }
        // Exactly on the bottom face: pushed down, no NaN.
        let (d, g) = c.closest_contact([A[0], A[1], A[2]], r).unwrap();
        assert_eq!(g, floor);
        assert!(d[2] < 0.0 && d[0] == 0.0 && d[1] == 0.0);
    }

    #[test]
    fn overlap_grows_monotonically_through_the_bottom_face() {
        let c = cyl();
        let r = 0.002;
        let mut last = f64::NEG_INFINITY;
        for i in 0..=400 {
            let z = -0.0025 + 1e-5 * i as f64; // from clear to 1.5 mm inside
            if let Some((d, g)) = c.closest_contact(at([0.003, 0.0, z]), r) {
                let overlap = r - g;
                assert!(overlap >= last);
                assert!(overlap <= r && d[2] < 0.0);
                last = overlap;
            }
        }
        approx::assert_relative_eq!(last, r * (1.0 - INSIDE_FLOOR_FRAC), max_relative = 1e-12);
    }

    #[test]
    fn contact_law_pushes_inside_grain_out_and_resists_rolling() {
        let c = cyl();
        let coeffs = PairCoeffs::new(5.2e6, 0.3, 5.2e6, 0.3, 0.8, 0.3, 0.1);
        let radi = 0.002;
        let x = at([0.0, R - 0.0005, 0.02]); // centre inside, nearest the side (+y)
        let (delta, r) = c.closest_contact(x, radi).unwrap();
        let omega = [0.0, 0.0, 3.0];
        let g = ContactGeom {
            delta,
            r,
            radi,
            radj: 0.0,
            is_wall: true,
            meff: 1e-4,
            vel_i: [0.0; 3],
            vel_j: [0.0; 3],
            omega_i: omega,
            omega_j: [0.0; 3],
        };
        let mut h = History::default();
        let o = hertz_history(&g, &coeffs, RollingModel::Cdt, 1e-6, &mut h, true);
        assert!(o.f_i.iter().all(|v| v.is_finite()));
        assert!(o.f_i[1] > 0.0, "pushed out along +y: {:?}", o.f_i);
        // The CDT rolling torque opposes the spin (z, tangential to the contact).
        assert!(dot(o.torque_i, omega) < 0.0, "{:?}", o.torque_i);
    }

    #[test]
    fn translate_moves_the_solid() {
        let mut c = cyl();
        let x = at([0.0, 0.0, -0.003]);
        assert!(c.closest_contact(x, 0.002).is_none());
        c.translate(-0.0015);
        assert_abs_diff_eq!(c.bottom_z(), A[2] - 0.0015, epsilon = 1e-15);
        assert_abs_diff_eq!(c.top_z(), A[2] - 0.0015 + L, epsilon = 1e-15);
        let (d, g) = c.closest_contact(x, 0.002).unwrap();
        assert_abs_diff_eq!(g, 0.0015, epsilon = 1e-15);
        assert!(d[2] < 0.0);
    }
}
