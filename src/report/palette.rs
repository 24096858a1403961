//! The one set of colours every granval figure uses, so a reader learns them once:
//! each engine keeps its colour in every figure, sweeps are coloured along a sequential
//! scale, and field maps use a sequential scale for non-negative quantities and a
//! diverging one only around a meaningful zero.
//!
//! Engine colours are from the Okabe-Ito palette (Okabe & Ito 2008, "Color Universal
//! Design"), chosen to stay distinct under the common colour-vision deficiencies: native
//! blue, LIGGGHTS vermillion, LAMMPS bluish green; published (paper) values black. The
//! sequential scale samples viridis (van der Walt & Smith, matplotlib), perceptually
//! uniform and readable in grey; the diverging scale is ColorBrewer's RdBu.

use crate::rundata::provenance::EngineKind;
use plotters::style::RGBColor;

pub const NATIVE: RGBColor = RGBColor(0x00, 0x72, 0xB2);
pub const LIGGGHTS: RGBColor = RGBColor(0xD5, 0x5E, 0x00);
pub const LAMMPS: RGBColor = RGBColor(0x00, 0x9E, 0x73);
/// Published values (a paper's table or figure).
pub(crate) const PAPER: RGBColor = RGBColor(0, 0, 0);
/// Series that belong to no engine (an independently measured angle's band shares its
/// engine's colour; this is for anything else): Okabe-Ito reddish purple.
pub(crate) const OTHER: RGBColor = RGBColor(0xCC, 0x79, 0xA7);
/// Field-map cells without a value (masked, empty, undefined): a grey no scale below
/// contains, hatched with [`EMPTY_HATCH`].
pub(crate) const EMPTY: RGBColor = RGBColor(0xC8, 0xC8, 0xC8);
pub(crate) const EMPTY_HATCH: RGBColor = RGBColor(0x90, 0x90, 0x90);
/// The intruder's section on a field map: a solid body, not a cell without data, so it
/// is filled opaque in a dark neutral grey (no colour of either scale, and darker than
/// [`EMPTY`], which is also hatched) and outlined in [`INTRUDER_EDGE`].
pub(crate) const INTRUDER: RGBColor = RGBColor(0x60, 0x60, 0x60);
pub(crate) const INTRUDER_EDGE: RGBColor = RGBColor(0, 0, 0);
/// Zero lines and other guides.
pub(crate) const GUIDE: RGBColor = RGBColor(0x80, 0x80, 0x80);
/// The frame and stamp of a negative-control figure (Okabe-Ito orange).
pub(crate) const CONTROL: RGBColor = RGBColor(0xE6, 0x9F, 0x00);

/// Who produced a series. Every series carries its source as data, set where the
/// series is built (from the run's [`EngineKind`], or by the code that reads a paper's
/// values), so a figure's colours never depend on how its labels are worded: a label is
/// display text only, and renaming it cannot recolour a figure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Source {
    Native,
    Liggghts,
    Lammps,
    Paper,
    Other,
}

/// A run's engine is its series' source: callers holding a provenance (or the engine a
/// run was made with) pass it on instead of naming the engine in text.
impl From<EngineKind> for Source {
    fn from(e: EngineKind) -> Source {
        match e {
            EngineKind::Native => Source::Native,
            EngineKind::Liggghts => Source::Liggghts,
            EngineKind::Lammps => Source::Lammps,
        }
    }
}

impl Source {
    /// The source of a series keyed by an engine's lower-case key in a run summary
    /// ([`EngineKind::from_key`]); [`Source::Other`] for a key naming no engine, so an
    /// unknown producer never borrows an engine's colour.
    pub(crate) fn of_engine_key(key: &str) -> Source {
        EngineKind::from_key(key).map_or(Source::Other, Source::from)
    }

    pub fn colour(self) -> RGBColor {
        match self {
            Source::Native => NATIVE,
            Source::Liggghts => LIGGGHTS,
            Source::Lammps => LAMMPS,
            Source::Paper => PAPER,
            Source::Other => OTHER,
        }
    }

    /// In a sweep, engines are told apart by line style: the engine under test solid,
    /// the reference engines (and anything else) dashed.
    pub(crate) fn dashed(self) -> bool {
        self != Source::Native
    }

    /// The reference engines a native series is compared with.
    pub(crate) fn is_reference_engine(self) -> bool {
        matches!(self, Source::Liggghts | Source::Lammps)
    }

    pub fn name(self) -> &'static str {
        match self {
            Source::Native => "native",
            Source::Liggghts => "LIGGGHTS",
            Source::Lammps => "LAMMPS",
            Source::Paper => "published",
            Source::Other => "other",
        }
    }
}

/// viridis at 9 evenly spaced points of [0, 1] (matplotlib's table).
const VIRIDIS: [(u8, u8, u8); 9] = [
    (0x44, 0x01, 0x54),
    (0x47, 0x2D, 0x7B),
    (0x3B, 0x52, 0x8B),
    (0x2C, 0x72, 0x8E),
    (0x21, 0x91, 0x8C),
    (0x28, 0xAE, 0x80),
    (0x5E, 0xC9, 0x62),
    (0xAD, 0xDC, 0x30),
    (0xFD, 0xE7, 0x25),
];

/// viridis at `t` in [0, 1] (clamped), linearly between its 9 tabulated points.
pub(crate) fn viridis(t: f64) -> RGBColor {
    interpolate(&VIRIDIS, t)
}

/// The colour at `t` in [0, 1] of a table of evenly spaced colours (its first entry at
/// 0, its last at 1), linear between neighbours in RGB and rounded to the nearest
/// integer; `t` outside [0, 1] is clamped and a `t` that is not finite is 0. One rule
/// for every scale, so viridis and RdBu cannot drift apart in how they are sampled.
pub(crate) fn interpolate(table: &[(u8, u8, u8)], t: f64) -> RGBColor {
    assert!(table.len() >= 2, "a colour table needs two entries");
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * (table.len() - 1) as f64;
    let i = (x.floor() as usize).min(table.len() - 2);
    let f = x - i as f64;
    let (a, b) = (table[i], table[i + 1]);
    let mix = |p: u8, q: u8| (p as f64 + f * (q as f64 - p as f64)).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// The colour of sweep value `i` of `n`: viridis from its dark end to 0.85 (its last
/// yellows are too pale for a line on white).
pub(crate) fn sweep_colour(i: usize, n: usize) -> RGBColor {
    if n <= 1 {
        return viridis(0.0);
    }
    viridis(0.85 * i as f64 / (n - 1) as f64)
}

/// ColorBrewer RdBu (11 classes, reversed: blue negative, red positive).
const RDBU: [(u8, u8, u8); 11] = [
    (0x05, 0x30, 0x61),
    (0x21, 0x66, 0xAC),
    (0x43, 0x93, 0xC3),
    (0x92, 0xC5, 0xDE),
    (0xD1, 0xE5, 0xF0),
    (0xF7, 0xF7, 0xF7),
    (0xFD, 0xDB, 0xC7),
    (0xF4, 0xA5, 0x82),
    (0xD6, 0x60, 0x4D),
    (0xB2, 0x18, 0x2B),
    (0x67, 0x00, 0x1F),
];

/// A colour scale of a field map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Scale {
    /// viridis from `lo` (dark) to `hi` (yellow): a non-negative quantity (gamma, |v|,
    /// pressure, log10 of a magnitude).
    Sequential { lo: f64, hi: f64 },
    /// RdBu from `-limit` (blue) through white at 0 to `+limit` (red): a signed quantity
    /// whose zero means something (v_z: at rest).
    Diverging { limit: f64 },
}

impl Scale {
    /// A diverging scale centred on 0 whose symmetric limit covers `lo..hi`.
    pub fn centred(lo: f64, hi: f64) -> Scale {
        let limit = lo.abs().max(hi.abs());
        Scale::Diverging {
            limit: if limit > 0.0 && limit.is_finite() {
                limit
            } else {
                1.0
            },
        }
    }

    pub fn range(&self) -> (f64, f64) {
        match *self {
            Scale::Sequential { lo, hi } => (lo, hi),
            Scale::Diverging { limit } => (-limit, limit),
        }
    }

    /// The colour of `v`; [`EMPTY`] for a value that is not finite (no data), a colour
    /// neither scale contains.
    pub fn colour(&self, v: f64) -> RGBColor {
        if !v.is_finite() {
            return EMPTY;
        }
        let (lo, hi) = self.range();
        let t = ((v - lo) / (hi - lo)).clamp(0.0, 1.0);
        match self {
            Scale::Sequential { .. } => viridis(t),
            Scale::Diverging { .. } => interpolate(&RDBU, t),
        }
    }

    /// What the colour bar says about the scale.
    pub(crate) fn describe(&self) -> &'static str {
        match self {
            Scale::Sequential { .. } => "viridis (sequential)",
            Scale::Diverging { .. } => "RdBu, white = 0",
        }
    }
}

/// `#RRGGBB`, as plotters' SVG backend writes a colour.
pub fn hex(c: RGBColor) -> String {
    format!("#{:02X}{:02X}{:02X}", c.0, c.1, c.2)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each engine is its own source, and a summary's engine key maps exactly (a key
    /// naming no engine, or an engine's display name in other case, is Other: keys are
    /// matched, never searched for words).
    #[test]
    fn engines_are_their_sources() {
        assert_eq!(Source::from(EngineKind::Native), Source::Native);
        assert_eq!(Source::from(EngineKind::Liggghts), Source::Liggghts);
        assert_eq!(Source::from(EngineKind::Lammps), Source::Lammps);
        for e in [EngineKind::Native, EngineKind::Liggghts, EngineKind::Lammps] {
            assert_eq!(Source::from(e), Source::of_engine_key(e.key()));
            // The key is the engine's serde form, the key summaries are written with.
            assert_eq!(
                serde_json::to_string(&e).unwrap(),
                format!("\"{}\"", e.key())
            );
        }
        assert_eq!(Source::of_engine_key("liggghts"), Source::Liggghts);
        assert_eq!(Source::of_engine_key("lammps native"), Source::Other);
        assert_eq!(Source::of_engine_key("paper"), Source::Other);
        let all = [NATIVE, LIGGGHTS, LAMMPS, PAPER, OTHER, EMPTY, INTRUDER];
        for (i, a) in all.iter().enumerate() {
            for b in &all[i + 1..] {
                assert_ne!(a, b);
            }
        }
    }

    /// The empty and intruder colours are no colour of either scale (checked at 1001
    /// points), and a
    /// diverging scale maps 0 to white.
    #[test]
    fn empty_is_outside_both_scales() {
        let seq = Scale::Sequential { lo: 0.0, hi: 1.0 };
        let div = Scale::centred(-0.3, 1.0);
        assert_eq!(div.range(), (-1.0, 1.0));
        assert_eq!(div.colour(0.0), RGBColor(0xF7, 0xF7, 0xF7));
        for k in 0..=1000 {
            let v = k as f64 / 1000.0;
            for c in [EMPTY, INTRUDER] {
                assert_ne!(seq.colour(v), c);
                assert_ne!(div.colour(2.0 * v - 1.0), c);
            }
        }
        assert_eq!(seq.colour(f64::NAN), EMPTY);
        assert_eq!(viridis(0.0), RGBColor(0x44, 0x01, 0x54));
        assert_eq!(viridis(1.0), RGBColor(0xFD, 0xE7, 0x25));
    }

    /// The shared interpolation: the table's ends at 0 and 1 (and beyond, clamped), the
    /// rounded mean of two neighbours halfway between them, the middle entry of an odd
    /// table at 0.5, and 0 for a value that is not finite.
    #[test]
    fn interpolation_hits_ends_and_midpoints() {
        let t = [(0, 10, 200), (100, 11, 0), (255, 255, 255)];
        assert_eq!(interpolate(&t, 0.0), RGBColor(0, 10, 200));
        assert_eq!(interpolate(&t, 1.0), RGBColor(255, 255, 255));
        assert_eq!(interpolate(&t, -3.0), RGBColor(0, 10, 200));
        assert_eq!(interpolate(&t, 7.0), RGBColor(255, 255, 255));
        assert_eq!(interpolate(&t, f64::NAN), RGBColor(0, 10, 200));
        assert_eq!(interpolate(&t, 0.5), RGBColor(100, 11, 0));
        // Halfway between entries 0 and 1: (50, 10.5 -> 11, 100).
        assert_eq!(interpolate(&t, 0.25), RGBColor(50, 11, 100));
        assert_eq!(interpolate(&RDBU, 0.0), RGBColor(0x05, 0x30, 0x61));
        assert_eq!(interpolate(&RDBU, 0.5), RGBColor(0xF7, 0xF7, 0xF7));
        assert_eq!(interpolate(&RDBU, 1.0), RGBColor(0x67, 0x00, 0x1F));
        assert_eq!(interpolate(&VIRIDIS, 0.5), RGBColor(0x21, 0x91, 0x8C));
    }
}
