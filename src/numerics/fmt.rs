//! Numbers as reports and messages print them for people (not for machines: report.json
//! and the CSV files keep every digit).

/// A number as a person reads it: integers without a fraction, 4 significant digits in
/// plain notation between 1e-3 and 1e5, scientific notation outside; NaN as "n/a".
pub fn number(x: f64) -> String {
    if x.is_nan() {
        return "n/a".into();
    }
    if x.is_infinite() {
        return if x > 0.0 { "inf".into() } else { "-inf".into() };
    }
    if x == x.trunc() && x.abs() < 1e15 {
        return format!("{}", x as i64);
    }
    let a = x.abs();
    if (1e-3..1e5).contains(&a) {
        let digits = (3 - a.log10().floor() as i32).max(0) as usize;
        let s = format!("{x:.digits$}");
        // 0.1230 -> 0.123: trailing zeros say nothing here.
        let s = if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        };
        return s;
    }
    format!("{x:.3e}")
}

/// A number as it would be typed into a case file: plain for moderate magnitudes (up to
/// 6 decimals, trailing zeros dropped), else the shortest scientific form (`6.3e10`).
pub(crate) fn typed(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 || (1e-3..1e5).contains(&a) {
        let s = format!("{x:.6}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{x:e}")
    }
}

/// An interval `[lo, hi]` with `decimals` decimals; an empty one (hi < lo, or either end
/// not a number) says so, "empty (from 0.500 to 0.323)", instead of printing its ends as
/// if they bounded something.
pub(crate) fn interval(lo: f64, hi: f64, decimals: usize) -> String {
    if lo <= hi {
        format!("[{lo:.decimals$}, {hi:.decimals$}]")
    } else {
        format!("empty (from {lo:.decimals$} to {hi:.decimals$})")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_inverted_interval_is_empty() {
        assert_eq!(interval(0.1, 0.5, 3), "[0.100, 0.500]");
        assert_eq!(interval(0.5, 0.323, 3), "empty (from 0.500 to 0.323)");
        assert_eq!(interval(f64::NAN, 0.3, 3), "empty (from NaN to 0.300)");
        assert_eq!(interval(0.3, 0.3, 1), "[0.3, 0.3]");
    }

    #[test]
    fn numbers_read_as_typed() {
        assert_eq!(typed(63.0), "63");
        assert_eq!(typed(6.3e10), "6.3e10");
        assert_eq!(typed(0.002), "0.002");
        assert_eq!(typed(2500.0), "2500");
        assert_eq!(typed(1e-6), "1e-6");
    }

    #[test]
    fn numbers_read_as_a_person_expects() {
        assert_eq!(number(150.0), "150");
        assert_eq!(number(-3.0), "-3");
        assert_eq!(number(0.12345), "0.1235");
        assert_eq!(number(0.5), "0.5");
        assert_eq!(number(23.456), "23.46");
        assert_eq!(number(2.5e-7), "2.500e-7");
        assert_eq!(number(f64::NAN), "n/a");
        assert_eq!(number(1e20), "1.000e20");
    }
}
