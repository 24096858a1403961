//! Unit quaternions (w, x, y, z) as LIGGGHTS' math_extra.h writes them: the product the
//! rigid-body integrator composes rotations with, and the angle between two
//! orientations that the trajectory comparison measures.

/// A quaternion (w, x, y, z).
pub(crate) type Quat = [f64; 4];

/// math_extra.h:596-602, Hamilton product a b.
pub(crate) fn quatquat(a: Quat, b: Quat) -> Quat {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + b[0] * a[1] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] + b[0] * a[2] + a[3] * b[1] - a[1] * b[3],
        a[0] * b[3] + b[0] * a[3] + a[1] * b[2] - a[2] * b[1],
    ]
}

/// Rotation angle (rad) between two orientations, 2 atan2(|vec(a* b)|, |scalar(a* b)|):
/// well conditioned near 0, unlike acos, and q ~ -q.
pub(crate) fn rotation_angle(a: Quat, b: Quat) -> f64 {
    let d = quatquat([a[0], -a[1], -a[2], -a[3]], b);
    let s = (d[1] * d[1] + d[2] * d[2] + d[3] * d[3]).sqrt();
    2.0 * s.atan2(d[0].abs())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A turn by theta about z is 2 theta away from its inverse, and q ~ -q.
    #[test]
    fn the_angle_between_two_turns_about_one_axis() {
        let th: f64 = 0.3;
        let q = [(th / 2.0).cos(), 0.0, 0.0, (th / 2.0).sin()];
        let qi = [q[0], 0.0, 0.0, -q[3]];
        assert!((rotation_angle(qi, q) - 2.0 * th).abs() < 1e-15);
        assert_eq!(rotation_angle(q, q.map(|c| -c)), 0.0);
    }
}
