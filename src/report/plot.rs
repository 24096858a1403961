//! What every granval figure shares: one font, flattened plotters errors, the caption
//! (title, and the subtitle of a negative control or an illustration), and the legend
//! in a panel of its own beside the data, so no legend ever covers a curve or a window.
//! Colours are [`super::palette`]'s.
//!
//! Text: without the `ttf` feature plotters estimates text extents with a crude
//! fixed-width rule and emits plain `<text>` elements with a generic font family,
//! which every SVG viewer renders; no font files are needed.

use super::palette::{CONTROL, EMPTY, EMPTY_HATCH, INTRUDER, INTRUDER_EDGE};
use anyhow::anyhow;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

pub(crate) const FONT: &str = "sans-serif";

/// plotters' drawing errors carry a backend type parameter; flatten them.
pub fn err<E: std::fmt::Debug>(what: &'static str) -> impl FnOnce(E) -> anyhow::Error {
    move |e| anyhow!("{what}: {e:?}")
}

/// A figure's title and what kind of figure it is. A negative control (the native
/// engine with wrong physics on purpose) is titled "negative control: <what was
/// changed>, <title>", carries a subtitle saying it is expected to disagree, and an
/// orange dashed frame with a stamp, so it cannot be taken for an engine comparison. An
/// illustration (synthetic input, e.g. the figure gallery) says so under the title.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Caption {
    pub title: String,
    /// The perturbation in words (`Perturbation`'s Display), when a negative control.
    pub control: Option<String>,
    pub illustration: bool,
}

impl Caption {
    pub fn new(title: impl Into<String>) -> Caption {
        Caption {
            title: title.into(),
            ..Caption::default()
        }
    }

    /// This figure is of a negative control's runs (`None`: of the case itself).
    pub fn control(mut self, perturbation: Option<&str>) -> Caption {
        self.control = perturbation.map(str::to_string);
        self
    }

    pub(crate) fn illustration(mut self) -> Caption {
        self.illustration = true;
        self
    }

    pub(crate) fn heading(&self) -> String {
        match &self.control {
            Some(p) => format!("negative control: {p}, {}", self.title),
            None => self.title.clone(),
        }
    }

    pub(crate) fn subtitles(&self) -> Vec<String> {
        let mut s = Vec::new();
        if self.control.is_some() {
            s.push(
                "native run with wrong physics ON PURPOSE: it should disagree; not an engine comparison"
                    .to_string(),
            );
        }
        if self.illustration {
            s.push("illustration: synthetic input, not a measured result".to_string());
        }
        s
    }
}

impl From<&str> for Caption {
    fn from(t: &str) -> Caption {
        Caption::new(t)
    }
}

/// How a legend entry's key is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Key {
    Line {
        colour: RGBColor,
        dashed: bool,
        width: u32,
    },
    Marker {
        colour: RGBColor,
        filled: bool,
        shape: Shape,
    },
    /// A filled box (a band, a region).
    Patch { colour: RGBColor, opacity: f64 },
    /// The empty-cell swatch of field maps.
    Empty,
    /// The intruder's swatch of field maps: its fill with its outline.
    Intruder,
    /// No key: a heading over the entries below it.
    Heading,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    Circle,
    Square,
    Triangle,
    Diamond,
}

impl Shape {
    pub fn nth(i: usize) -> Shape {
        [
            Shape::Circle,
            Shape::Square,
            Shape::Triangle,
            Shape::Diamond,
        ][i % 4]
    }
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Entry {
    pub label: String,
    pub key: Key,
}

impl Entry {
    pub fn new(label: impl Into<String>, key: Key) -> Entry {
        Entry {
            label: label.into(),
            key,
        }
    }
}

pub(crate) type Area<'a> = DrawingArea<SVGBackend<'a>, Shift>;

const LEGEND_FONT: u32 = 13;
const LEGEND_ROW: i32 = 19;

/// Width in pixels the legend panel needs for `entries` (plotters' fixed-width text
/// estimate: about 0.6 em per character).
fn legend_width(entries: &[Entry]) -> u32 {
    let chars = entries
        .iter()
        .map(|e| e.label.chars().count())
        .max()
        .unwrap_or(0);
    (52.0 + 0.62 * LEGEND_FONT as f64 * chars as f64).clamp(150.0, 560.0) as u32
}

/// The canvas of a figure: the whole drawing, the area for the data (right of it the
/// legend panel, above it the caption) and the legend panel, with the legend and the
/// caption already drawn. `data` is the size of the data area (axes included).
pub(crate) fn canvas<'a>(
    path: &'a Path,
    data: (u32, u32),
    caption: &Caption,
    entries: &[Entry],
) -> anyhow::Result<(Area<'a>, Area<'a>, Area<'a>)> {
    let subs = caption.subtitles();
    let head = 38 + 20 * subs.len() as u32;
    let lw = legend_width(entries);
    let rows = (entries.len() as u32 + 1) * LEGEND_ROW as u32 + 20;
    let height = head + data.1.max(rows);
    let width = data.0 + lw;
    let root = SVGBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(err("fill"))?;
    let (top, body) = root.split_vertically(head);
    let heading = caption.heading();
    top.draw(&Text::new(
        heading,
        (14, 10),
        (FONT, 20).into_font().color(&BLACK),
    ))
    .map_err(err("title"))?;
    for (i, s) in subs.iter().enumerate() {
        let col = if caption.control.is_some() && i == 0 {
            CONTROL.mix(1.0)
        } else {
            BLACK.mix(0.75)
        };
        top.draw(&Text::new(
            s.clone(),
            (14, 36 + 20 * i as i32),
            (FONT, 14).into_font().color(&col),
        ))
        .map_err(err("subtitle"))?;
    }
    let (data_area, legend_area) = body.split_horizontally(data.0);
    draw_legend(&legend_area, entries)?;
    if caption.control.is_some() {
        let (w, h) = (width as i32, height as i32);
        let dash = |a: (i32, i32), b: (i32, i32)| {
            let n = (((b.0 - a.0).abs() + (b.1 - a.1).abs()) / 24).max(1);
            (0..n)
                .map(|k| {
                    let f0 = k as f64 / n as f64;
                    let f1 = (k as f64 + 0.55) / n as f64;
                    let p = |f: f64| {
                        (
                            a.0 + ((b.0 - a.0) as f64 * f) as i32,
                            a.1 + ((b.1 - a.1) as f64 * f) as i32,
                        )
                    };
                    PathElement::new(vec![p(f0), p(f1)], CONTROL.stroke_width(6))
                })
                .collect::<Vec<_>>()
        };
        for (a, b) in [
            ((3, 3), (w - 3, 3)),
            ((w - 3, 3), (w - 3, h - 3)),
            ((w - 3, h - 3), (3, h - 3)),
            ((3, h - 3), (3, 3)),
        ] {
            for e in dash(a, b) {
                root.draw(&e).map_err(err("control frame"))?;
            }
        }
        root.draw(&Text::new(
            "NEGATIVE CONTROL",
            (w - 200, h - 28),
            (FONT, 18).into_font().color(&CONTROL),
        ))
        .map_err(err("control stamp"))?;
    }
    Ok((root, data_area, legend_area))
}

/// Draws `key` with its left end at (x, y) (the row's middle), 30 px wide.
pub(crate) fn draw_key(area: &Area<'_>, key: Key, x: i32, y: i32) -> anyhow::Result<()> {
    match key {
        Key::Line {
            colour,
            dashed,
            width,
        } => {
            let style = colour.stroke_width(width);
            if dashed {
                for s in [(x, x + 8), (x + 12, x + 20), (x + 24, x + 30)] {
                    area.draw(&PathElement::new(vec![(s.0, y), (s.1, y)], style))
                        .map_err(err("legend key"))?;
                }
            } else {
                area.draw(&PathElement::new(vec![(x, y), (x + 30, y)], style))
                    .map_err(err("legend key"))?;
            }
        }
        Key::Marker {
            colour,
            filled,
            shape,
        } => draw_marker(area, (x + 15, y), 5, colour, filled, shape)?,
        Key::Patch { colour, opacity } => {
            area.draw(&Rectangle::new(
                [(x, y - 6), (x + 30, y + 6)],
                colour.mix(opacity).filled(),
            ))
            .map_err(err("legend key"))?;
        }
        Key::Empty => {
            area.draw(&Rectangle::new(
                [(x, y - 6), (x + 30, y + 6)],
                EMPTY.filled(),
            ))
            .map_err(err("legend key"))?;
            for k in 0..3 {
                let x0 = x + 10 * k;
                area.draw(&PathElement::new(
                    vec![(x0, y + 6), (x0 + 10, y - 6)],
                    EMPTY_HATCH.stroke_width(1),
                ))
                .map_err(err("legend key"))?;
            }
        }
        Key::Intruder => {
            area.draw(&Rectangle::new(
                [(x, y - 6), (x + 30, y + 6)],
                INTRUDER.filled(),
            ))
            .map_err(err("legend key"))?;
            area.draw(&Rectangle::new(
                [(x, y - 6), (x + 30, y + 6)],
                INTRUDER_EDGE.stroke_width(2),
            ))
            .map_err(err("legend key"))?;
        }
        Key::Heading => {}
    }
    Ok(())
}

/// A marker of `shape` centred at pixel `c` on any drawing area.
pub(crate) fn draw_marker(
    area: &Area<'_>,
    c: (i32, i32),
    r: i32,
    colour: RGBColor,
    filled: bool,
    shape: Shape,
) -> anyhow::Result<()> {
    let style = if filled {
        colour.filled()
    } else {
        colour.stroke_width(2)
    };
    match shape {
        Shape::Circle => area.draw(&Circle::new(c, r, style)),
        Shape::Square => area.draw(&Rectangle::new(
            [(c.0 - r, c.1 - r), (c.0 + r, c.1 + r)],
            style,
        )),
        Shape::Triangle => area.draw(&Polygon::new(
            vec![(c.0, c.1 - r - 1), (c.0 - r, c.1 + r), (c.0 + r, c.1 + r)],
            style,
        )),
        Shape::Diamond => area.draw(&Polygon::new(
            vec![
                (c.0, c.1 - r - 1),
                (c.0 + r + 1, c.1),
                (c.0, c.1 + r + 1),
                (c.0 - r - 1, c.1),
            ],
            style,
        )),
    }
    .map_err(err("marker"))
}

/// The legend: one row per entry in the legend panel (never over the data area).
pub(crate) fn draw_legend(area: &Area<'_>, entries: &[Entry]) -> anyhow::Result<()> {
    for (i, e) in entries.iter().enumerate() {
        let y = 24 + LEGEND_ROW * i as i32;
        let (tx, font) = if e.key == Key::Heading {
            (8, (FONT, LEGEND_FONT).into_font().style(FontStyle::Bold))
        } else {
            draw_key(area, e.key, 8, y)?;
            (46, (FONT, LEGEND_FONT).into_font())
        };
        area.draw(&Text::new(
            e.label.clone(),
            (tx, y - LEGEND_FONT as i32 / 2 - 1),
            font.color(&BLACK),
        ))
        .map_err(err("legend"))?;
    }
    Ok(())
}
