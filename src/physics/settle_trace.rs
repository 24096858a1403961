//! What a bed's settling did, for the error when it does not settle: whether the kinetic
//! energy was still falling when the time allowed ran out (raise the time) or had
//! stopped falling (something keeps the bed moving: a creeping avalanche, an oscillating
//! column, a rattler; more time alone may not help, though a creeping 2D bed can still
//! settle after an avalanche). A bed of 20 000 disks that does not settle in an hour of
//! CPU is only diagnosable from this.

/// Every checked (time, energy) of one settling phase (kept in a settling checkpoint,
/// so a settling continued from one describes the whole phase).
#[derive(Debug, Default, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct SettleTrace {
    samples: Vec<(f64, f64)>,
}

impl SettleTrace {
    pub(crate) fn push(&mut self, t: f64, energy: f64) {
        self.samples.push((t, energy));
    }

    /// The energy at the last check at or before `t`.
    fn at(&self, t: f64) -> Option<(f64, f64)> {
        self.samples.iter().rev().find(|s| s.0 <= t).copied()
    }

    /// One sentence: `what` (the energy, or its ratio to a reference) at a quarter, half,
    /// three quarters and the end of the phase, its lowest value and when, and its change
    /// over the last half, in `unit` (`scale` divides the values: m g d, or 1).
    pub(crate) fn describe(&self, what: &str, scale: f64, unit: &str) -> String {
        let (Some(&(t0, _)), Some(&(t1, e1))) = (self.samples.first(), self.samples.last()) else {
            return "no check was reached".into();
        };
        let span = t1 - t0;
        let points: Vec<String> = [0.25, 0.5, 0.75]
            .iter()
            .filter_map(|f| self.at(t0 + f * span))
            .chain(std::iter::once((t1, e1)))
            .map(|(t, e)| format!("{:.3e}{unit} at t = {t:.4e} s", e / scale))
            .collect();
        let (tmin, emin) = self
            .samples
            .iter()
            .copied()
            .fold((t1, f64::INFINITY), |a, s| if s.1 < a.1 { s } else { a });
        let half = self.at(t0 + 0.5 * span).map_or(f64::NAN, |s| s.1);
        let comparable = half > 0.0 && e1 >= 0.0; // false for NaN too
        let trend = if !comparable {
            String::new()
        } else if e1 < 0.5 * half {
            format!(
                "; still falling: x{:.2e} over the last half, so more time may settle it",
                e1 / half
            )
        } else if e1 > 2.0 * half {
            format!(
                "; rising over the last half (x{:.2}): the grains are still falling from the pour, so more time is needed",
                e1 / half
            )
        } else {
            format!(
                "; not falling over the last half (x{:.2}): the bed keeps moving (creep, an oscillation, a rattler), and more time alone may not settle it",
                e1 / half
            )
        };
        format!(
            "{what} {}; lowest {:.3e}{unit} at t = {tmin:.4e} s{trend}",
            points.join(", "),
            emin / scale
        )
    }
}

#[cfg(test)]
mod tests {
    use super::SettleTrace;

    fn trace(f: impl Fn(f64) -> f64) -> SettleTrace {
        let mut t = SettleTrace::default();
        for k in 0..=100 {
            let x = k as f64 * 0.01;
            t.push(x, f(x));
        }
        t
    }

    /// A decaying energy is "still falling", a flat one "not falling", a growing one
    /// "rising"; each names the lowest value and the quarter points.
    #[test]
    fn a_decay_and_a_plateau_are_told_apart() {
        let decay = trace(|x| (-10.0 * x).exp()).describe("KE", 1.0, " J");
        assert!(decay.contains("still falling"), "{decay}");
        assert!(
            decay.contains("lowest 4.540e-5 J at t = 1.0000e0 s"),
            "{decay}"
        );
        let flat = trace(|x| 2.0 + (40.0 * x).sin()).describe("KE", 2.0, " m g d");
        assert!(flat.contains("not falling"), "{flat}");
        assert!(flat.contains("at t = 2.5000e-1 s"), "{flat}");
        let rising = trace(|x| 1.0 + 10.0 * x * x).describe("KE", 1.0, "");
        assert!(rising.contains("rising"), "{rising}");
        assert_eq!(
            SettleTrace::default().describe("KE", 1.0, ""),
            "no check was reached"
        );
    }
}
