//! The stress servo of LIGGGHTS' mesh module `servo` (mesh_module_stress_servo.cpp,
//! `ctrlPV force`, PID form without `mode auto`), operation by operation, for a plane
//! wall that moves along one axis.
//!
//! LIGGGHTS: in `initial_integrate` the wall moves by `dt * vcm`; in `final_integrate`,
//! after the force pass, with `pv` = the force of the grains on the wall along the axis
//! and `sp = -target_val`:
//!
//! ```text
//! err = sp - pv;  sum_err += err * dt;  dfdt = -(pv - old_pv) / dt
//! v = -vel_max * (err * kp + sum_err * ki + dfdt * kd) / |sp|
//! if |v| > vel_max: v *= vel_max / |v|;  if ki > 0: sum_err = (-sgn(v) * sp - err * kp) / ki
//! old_pv = pv
//! ```
//!
//! With the axis pointing out of the sample and a negative target (-sigma A), the wall
//! moves inward at up to `vel_max` until the grains push it with sigma A.

pub(crate) use crate::case::triaxial::ServoGains;

/// The controller state of one servo wall (`vcm`, `sum_err_`, `old_pv_mag_`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Servo {
    pub gains: ServoGains,
    /// Wall velocity along the axis (m/s), `vcm . axis`.
    pub velocity: f64,
    pub sum_err: f64,
    pub old_pv: f64,
    /// Last error `sp - pv` (N), for reports.
    pub err: f64,
}

impl Servo {
    /// A servo at rest with empty sums: LIGGGHTS' state after `post_create` (vcm = 0,
    /// sums 0), the state every new run of a sample starts from.
    pub fn new(gains: ServoGains) -> Servo {
        Servo {
            gains,
            velocity: 0.0,
            sum_err: 0.0,
            old_pv: 0.0,
            err: 0.0,
        }
    }

    /// `final_integrate` of the servo: `pv` the force of the grains on the wall along
    /// the axis (N), `target` LIGGGHTS' `target_val` (N; negative to push along -axis),
    /// `dt` the time step. Returns the new wall velocity along the axis.
    pub(crate) fn update(&mut self, pv: f64, target: f64, dt: f64) -> f64 {
        let g = self.gains;
        let sp = -target;
        let sp_inv = 1.0 / sp.abs();
        let err = sp - pv;
        self.err = err;
        self.sum_err += err * dt;
        let dfdt = -(pv - self.old_pv) / dt;
        let mut v = -g.vel_max * (err * g.kp + self.sum_err * g.ki + dfdt * g.kd) * sp_inv;
        self.old_pv = pv;
        // limit_vel(): the magnitude of the (axis-parallel) velocity vector.
        let vmag = (v * v).sqrt();
        if vmag > g.vel_max && vmag != 0.0 {
            let factor = g.vel_max / vmag;
            v *= factor;
            if g.ki > 0.0 {
                let sgn = f64::from(i8::from(0.0 < v) - i8::from(v < 0.0));
                self.sum_err = (-sgn * sp - err * g.kp) / g.ki;
            }
        }
        self.velocity = v;
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three steps of LIGGGHTS' formulas by hand (kp 2, ki 50, kd 1e-4, vel_max 0.05,
    /// target -10 N, dt 1e-4): unsaturated, then saturated with the anti-windup reset.
    #[test]
    fn the_servo_follows_liggghts_formulas() {
        let gains = ServoGains {
            kp: 2.0,
            ki: 50.0,
            kd: 1e-4,
            vel_max: 0.05,
        };
        let mut s = Servo::new(gains);
        let (target, dt) = (-10.0, 1e-4);
        // Step 1: pv = 9.9 N (close to the set point 10 N).
        let v1 = s.update(9.9, target, dt);
        let err1 = 10.0 - 9.9;
        let sum1 = err1 * dt;
        let dfdt1 = -(9.9 - 0.0) / dt;
        let want1 = -0.05 * (err1 * 2.0 + sum1 * 50.0 + dfdt1 * 1e-4) / 10.0;
        // -0.05 * (0.2 + 0.0005 - 9.9) / 10 = +0.0485: below vel_max, not limited.
        assert_eq!(v1, want1);
        assert!((v1 - 0.048_497_5).abs() < 1e-9, "{v1}");
        assert_eq!(s.sum_err, sum1);
        // Step 2: pv = 9.9 again: dfdt = 0, v = -0.05 (0.2 + 50 sum) / 10 = -0.00100.
        let v2 = s.update(9.9, target, dt);
        let sum2 = sum1 + err1 * dt;
        assert_eq!(v2, -0.05 * (err1 * 2.0 + sum2 * 50.0 + 0.0 * 1e-4) / 10.0);
        // Step 3: no contact (pv = 0): err = 10, the raw output -0.05 (20 + ...) / 10 is
        // far beyond vel_max: limited to -vel_max (inward), sum reset by the inverted
        // controller equation.
        let v3 = s.update(0.0, target, dt);
        let raw = -0.05 * (10.0 * 2.0 + (sum2 + 10.0 * dt) * 50.0 + (9.9 / dt) * 1e-4) / 10.0;
        assert!(raw < -0.05);
        assert_eq!(v3, raw * (0.05 / raw.abs()));
        assert!((v3 + 0.05).abs() < 1e-17);
        assert_eq!(s.sum_err, (-(-1.0) * 10.0 - 10.0 * 2.0) / 50.0);
        assert_eq!(s.old_pv, 0.0);
        // Without ki the sum is never reset.
        let mut p = Servo::new(ServoGains { ki: 0.0, ..gains });
        p.update(0.0, target, dt);
        assert_eq!(p.sum_err, 10.0 * dt);
    }
}
