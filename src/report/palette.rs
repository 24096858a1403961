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

use plotters::style::RGBColor;

pub const NATIVE: RGBColor = RGBColor(0x00, 0x72, 0xB2);
pub const LIGGGHTS: RGBColor = RGBColor(0xD5, 0x5E, 0x00);
pub const LAMMPS: RGBColor = RGBColor(0x00, 0x9E, 0x73);
/// Published values (a paper's table or figure).
pub const PAPER: RGBColor = RGBColor(0, 0, 0);
/// Series that belong to no engine (an independently measured angle's band shares its
/// engine's colour; this is for anything else): Okabe-Ito reddish purple.
pub const OTHER: RGBColor = RGBColor(0xCC, 0x79, 0xA7);
/// Field-map cells without a value (masked, empty, undefined): a grey no scale below
/// contains, hatched with [`EMPTY_HATCH`].
pub const EMPTY: RGBColor = RGBColor(0xC8, 0xC8, 0xC8);
pub const EMPTY_HATCH: RGBColor = RGBColor(0x90, 0x90, 0x90);
/// Zero lines and other guides.
pub const GUIDE: RGBColor = RGBColor(0x80, 0x80, 0x80);
/// The frame and stamp of a negative-control figure (Okabe-Ito orange).
pub const CONTROL: RGBColor = RGBColor(0xE6, 0x9F, 0x00);

/// Who produced a series. Figures are told by the series' label, which in granval always
/// names its engine ("native", "LIGGGHTS", "LAMMPS") or the paper ("published", "Feng
/// et al.", "Kondic et al.", "paper").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Source {
    Native,
    Liggghts,
    Lammps,
    Paper,
    Other,
}

impl Source {
    /// The source a label names (case-insensitive); [`Source::Other`] if none.
    pub fn of_label(label: &str) -> Source {
        let l = label.to_ascii_lowercase();
        if l.contains("native") {
            Source::Native
        } else if l.contains("liggghts") {
            Source::Liggghts
        } else if l.contains("lammps") {
            Source::Lammps
        } else if ["published", "paper", "feng et al", "kondic et al"]
            .iter()
            .any(|w| l.contains(w))
        {
            Source::Paper
        } else {
            Source::Other
        }
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
    pub fn dashed(self) -> bool {
        self != Source::Native
    }

    /// The reference engines a native series is compared with.
    pub fn is_reference_engine(self) -> bool {
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

/// The label with its engine's word removed: what distinguishes series of one engine
/// (a sweep value, a case), e.g. "native v=0.4" -> "v=0.4".
pub fn variant_of(label: &str) -> String {
    let words: Vec<&str> = label
        .split_whitespace()
        .filter(|w| {
            let w = w.trim_matches(|c: char| !c.is_ascii_alphanumeric());
            !["native", "liggghts", "lammps"].contains(&w.to_ascii_lowercase().as_str())
        })
        .collect();
    words
        .join(" ")
        .trim_matches(|c: char| c == ',' || c == ':' || c.is_whitespace())
        .to_string()
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
pub fn viridis(t: f64) -> RGBColor {
    interpolate(&VIRIDIS, t)
}

/// The colour at `t` in [0, 1] of a table of evenly spaced colours (its first entry at
/// 0, its last at 1), linear between neighbours in RGB and rounded to the nearest
/// integer; `t` outside [0, 1] is clamped and a `t` that is not finite is 0. One rule
/// for every scale, so viridis and RdBu cannot drift apart in how they are sampled.
pub fn interpolate(table: &[(u8, u8, u8)], t: f64) -> RGBColor {
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
pub fn sweep_colour(i: usize, n: usize) -> RGBColor {
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
pub enum Scale {
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
    pub fn describe(&self) -> &'static str {
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

    /// The label rule: an engine's word anywhere in a label picks its colour; a label
    /// naming none is Other (so a new engine cannot silently borrow native blue).
    #[test]
    fn labels_name_their_source() {
        assert_eq!(Source::of_label("native v=0.4"), Source::Native);
        assert_eq!(Source::of_label("fig2 LAMMPS"), Source::Lammps);
        assert_eq!(Source::of_label("case liggghts"), Source::Liggghts);
        assert_eq!(Source::of_label("published values"), Source::Paper);
        assert_eq!(Source::of_label("Feng et al. Table 3"), Source::Paper);
        assert_eq!(Source::of_label("yield region"), Source::Other);
        assert_eq!(variant_of("native v=0.4"), "v=0.4");
        assert_eq!(variant_of("fig2-v0.7 LAMMPS"), "fig2-v0.7");
        assert_eq!(variant_of("native"), "");
        let all = [NATIVE, LIGGGHTS, LAMMPS, PAPER, OTHER, EMPTY];
        for (i, a) in all.iter().enumerate() {
            for b in &all[i + 1..] {
                assert_ne!(a, b);
            }
        }
    }

    /// The empty colour is no colour of either scale (checked at 1001 points), and a
    /// diverging scale maps 0 to white.
    #[test]
    fn empty_is_outside_both_scales() {
        let seq = Scale::Sequential { lo: 0.0, hi: 1.0 };
        let div = Scale::centred(-0.3, 1.0);
        assert_eq!(div.range(), (-1.0, 1.0));
        assert_eq!(div.colour(0.0), RGBColor(0xF7, 0xF7, 0xF7));
        for k in 0..=1000 {
            let v = k as f64 / 1000.0;
            assert_ne!(seq.colour(v), EMPTY);
            assert_ne!(div.colour(2.0 * v - 1.0), EMPTY);
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
