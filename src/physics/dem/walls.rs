//! Primitive walls with the geometry of LIGGGHTS `fix wall/gran ... primitive`
//! (primitive_wall_definitions.h): the contact vector points from the wall to the
//! particle centre and its length is the centre-wall distance.

use crate::case::{Axis, Wall};
use crate::numerics::vec3::V3;

/// Wall-to-particle vector and its length if the sphere of radius `r` touches the wall.
#[inline]
pub(crate) fn wall_contact(w: &Wall, x: V3, r: f64) -> Option<(V3, f64)> {
    match *w {
        Wall::Plane { axis, position, .. } => {
            let k = axis.index();
            let d = x[k] - position;
            let dist = d.abs();
            if dist - r > 0.0 {
                return None;
            }
            let mut delta = [0.0; 3];
            delta[k] = d;
            Some((delta, dist))
        }
        Wall::Cylinder {
            axis,
            radius,
            center,
            ..
        } => {
            debug_assert_eq!(axis, Axis::Z);
            let dy = x[0] - center[0];
            let dz = x[1] - center[1];
            let dist = (dy * dy + dz * dz).sqrt();
            if dist == 0.0 {
                return None;
            }
            // Inside the cylinder: gap R - dist; outside: dist - R (both sides repel).
            let (gap, sign) = if dist > radius {
                (dist - radius, 1.0)
            } else {
                (radius - dist, -1.0)
            };
            if gap - r > 0.0 {
                return None;
            }
            let fact = sign * gap / dist;
            Some(([dy * fact, dz * fact, 0.0], gap))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cylinder_pushes_inward_from_inside() {
        let w = Wall::Cylinder {
            axis: Axis::Z,
            radius: 0.05,
            center: [0.0, 0.0],
            type_: 0,
        };
        let (d, gap) = wall_contact(&w, [0.049, 0.0, 0.1], 0.002).expect("touching");
        approx::assert_relative_eq!(gap, 0.001, max_relative = 1e-12);
        assert!(d[0] < 0.0, "normal must point to the axis: {d:?}");
        assert!(wall_contact(&w, [0.03, 0.0, 0.1], 0.002).is_none());
    }

    #[test]
    fn plane_is_two_sided() {
        let w = Wall::Plane {
            axis: Axis::Z,
            position: 0.0,
            type_: 0,
        };
        assert!(
            wall_contact(&w, [0.0, 0.0, 0.0009], 0.001)
                .expect("above")
                .0[2]
                > 0.0
        );
        assert!(
            wall_contact(&w, [0.0, 0.0, -0.0009], 0.001)
                .expect("below")
                .0[2]
                < 0.0
        );
    }
}
