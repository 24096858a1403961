//! Engine-vs-engine line overlays (FDR, D(t), F(t), B0, phi_mob) with a difference
//! panel under them: the same x axis, y = reference - native.
//!
//! Styles: with one variant, each line is its engine's colour, the native line wide
//! and the reference thin on top of it, so two curves that coincide still show both
//! colours. With several variants (a sweep) the variant picks the colour (viridis) and
//! the engine the line style (native solid, reference dashed), and the legend says so.
//!
//! The difference is drawn only where it is honest: both series' x strictly increasing;
//! on a shared x grid (the same output steps or bins, the usual case: both engines write
//! the same times) it is taken point by point, otherwise the native series is
//! interpolated linearly at the reference's x inside the native x range (never
//! extrapolated), and the panel's legend says which.

use super::palette::{self, GUIDE, Source};
use super::plot::{Area, Caption, Entry, FONT, Key, canvas, err};
use anyhow::{Result, ensure};
use plotters::prelude::*;
use std::path::Path;

/// One line of an overlay. Its style comes from `source` and `variant`, set by the code
/// that builds the line; `label` is the legend's text only.
#[derive(Debug, Clone, Copy)]
pub struct Line<'a> {
    pub label: &'a str,
    pub source: Source,
    /// What tells lines of one source apart (a sweep value, a case); "" when there is
    /// one of each source. Several variants make the figure a sweep: colour = variant.
    pub variant: &'a str,
    pub points: &'a [(f64, f64)],
}

impl<'a> Line<'a> {
    /// A line of `source` with no variant.
    pub(crate) fn new(label: &'a str, source: Source, points: &'a [(f64, f64)]) -> Line<'a> {
        Line {
            label,
            source,
            variant: "",
            points,
        }
    }

    /// The same line as variant `variant` of a sweep.
    pub(crate) fn variant(self, variant: &'a str) -> Line<'a> {
        Line { variant, ..self }
    }
}

/// A fitted law drawn as a dashed line in its engine's colour with its legend entry
/// (the law and its fitted values).
#[derive(Debug, Clone)]
pub(crate) struct FitLine {
    pub label: String,
    pub source: Source,
    pub points: Vec<(f64, f64)>,
}

/// Axis text of an overlay; `unit` is the unit of y in the difference panel.
pub(crate) struct Axes<'a> {
    pub x: &'a str,
    pub y: &'a str,
    pub unit: &'a str,
    /// y grows downwards (depth below the surface, as in Kondic's figures of the bed).
    pub y_down: bool,
}

/// How a difference was taken.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Grid {
    Shared,
    Interpolated,
}

/// reference - native at the reference's x (see the module comment); `None` when an x
/// is not strictly increasing or the ranges do not overlap.
pub fn difference(
    native: &[(f64, f64)],
    reference: &[(f64, f64)],
) -> Option<(Vec<(f64, f64)>, Grid)> {
    let clean = |s: &[(f64, f64)]| -> Vec<(f64, f64)> {
        s.iter()
            .copied()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .collect()
    };
    let (n, r) = (clean(native), clean(reference));
    let increasing = |s: &[(f64, f64)]| s.len() >= 2 && s.windows(2).all(|w| w[1].0 > w[0].0);
    if !increasing(&n) || !increasing(&r) {
        return None;
    }
    if n.len() == r.len() && n.iter().zip(&r).all(|(a, b)| a.0 == b.0) {
        return Some((
            n.iter().zip(&r).map(|(a, b)| (a.0, b.1 - a.1)).collect(),
            Grid::Shared,
        ));
    }
    let (lo, hi) = (n[0].0, n[n.len() - 1].0);
    let mut out = Vec::new();
    let mut j = 0;
    for &(x, y) in r.iter().filter(|p| p.0 >= lo && p.0 <= hi) {
        while j + 2 < n.len() && n[j + 1].0 < x {
            j += 1;
        }
        let (a, b) = (n[j], n[j + 1]);
        let f = ((x - a.0) / (b.0 - a.0)).clamp(0.0, 1.0);
        out.push((x, y - (a.1 + f * (b.1 - a.1))));
    }
    (out.len() >= 2).then_some((out, Grid::Interpolated))
}

/// One difference series: its colour, the reference engine, the points, the grid.
type Diff = (RGBColor, Source, Vec<(f64, f64)>, Grid);

struct Styled<'a> {
    source: Source,
    variant: &'a str,
    points: &'a [(f64, f64)],
    colour: RGBColor,
    dashed: bool,
    width: u32,
}

fn bounds<'a>(pts: impl Iterator<Item = &'a (f64, f64)>) -> Option<(f64, f64, f64, f64)> {
    let mut b = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in pts.filter(|p| p.0.is_finite() && p.1.is_finite()) {
        b = (b.0.min(x), b.1.max(x), b.2.min(y), b.3.max(y));
    }
    (b.0 < b.1).then_some(b)
}

/// The overlay of `lines` and `fits` with the difference panel under it (when some
/// variant has a native and a reference-engine line), written to `path`.
pub(crate) fn overlay(
    path: &Path,
    caption: &Caption,
    axes: &Axes<'_>,
    lines: &[Line<'_>],
    fits: &[FitLine],
) -> Result<()> {
    ensure!(!lines.is_empty(), "overlay: no series to plot");
    let mut variants: Vec<&str> = Vec::new();
    for l in lines {
        if !variants.contains(&l.variant) {
            variants.push(l.variant);
        }
    }
    let sweep = variants.len() > 1;
    let styled: Vec<Styled> = lines
        .iter()
        .map(|l| {
            let (source, variant) = (l.source, l.variant);
            let vi = variants.iter().position(|v| *v == variant).unwrap_or(0);
            let native = source == Source::Native;
            Styled {
                source,
                colour: if sweep {
                    palette::sweep_colour(vi, variants.len())
                } else {
                    source.colour()
                },
                dashed: sweep && source.dashed(),
                width: if sweep || !native { 2 } else { 4 },
                variant,
                points: l.points,
            }
        })
        .collect();
    // Difference per variant: the first native line against each reference-engine line.
    let mut diffs: Vec<Diff> = Vec::new();
    let mut undrawn: Vec<String> = Vec::new();
    for v in &variants {
        let Some(n) = styled
            .iter()
            .find(|s| s.variant == *v && s.source == Source::Native)
        else {
            continue;
        };
        for r in styled
            .iter()
            .filter(|s| s.variant == *v && s.source.is_reference_engine())
        {
            match difference(n.points, r.points) {
                Some((d, g)) => diffs.push((
                    if sweep { r.colour } else { r.source.colour() },
                    r.source,
                    d,
                    g,
                )),
                None => undrawn.push(if v.is_empty() {
                    r.source.name().to_string()
                } else {
                    format!("{v} {}", r.source.name())
                }),
            }
        }
    }

    let mut entries = Vec::new();
    if sweep {
        let mut sources: Vec<Source> = styled.iter().map(|s| s.source).collect();
        sources.sort();
        sources.dedup();
        entries.push(Entry::new("line style = engine", Key::Heading));
        for s in &sources {
            entries.push(Entry::new(
                s.name(),
                Key::Line {
                    colour: BLACK,
                    dashed: s.dashed(),
                    width: 2,
                },
            ));
        }
        entries.push(Entry::new("colour = value", Key::Heading));
        for (i, v) in variants.iter().enumerate() {
            entries.push(Entry::new(
                *v,
                Key::Line {
                    colour: palette::sweep_colour(i, variants.len()),
                    dashed: false,
                    width: 3,
                },
            ));
        }
    } else {
        for (s, l) in styled.iter().zip(lines) {
            entries.push(Entry::new(
                l.label,
                Key::Line {
                    colour: s.colour,
                    dashed: s.dashed,
                    width: s.width,
                },
            ));
        }
    }
    for f in fits {
        entries.push(Entry::new(
            f.label.clone(),
            Key::Line {
                colour: f.source.colour(),
                dashed: true,
                width: 2,
            },
        ));
    }
    if !diffs.is_empty() {
        let refs: Vec<&str> = {
            let mut r: Vec<&str> = diffs.iter().map(|d| d.1.name()).collect();
            r.dedup();
            r
        };
        entries.push(Entry::new(
            format!("lower panel: {} - native", refs.join(", ")),
            Key::Heading,
        ));
        let grid = if diffs.iter().all(|d| d.3 == Grid::Shared) {
            "point by point on the shared x grid"
        } else {
            "native interpolated linearly at the reference's x"
        };
        entries.push(Entry::new(grid, Key::Heading));
    }
    if !undrawn.is_empty() {
        entries.push(Entry::new(
            format!(
                "no difference for {} (x not increasing)",
                undrawn.join(", ")
            ),
            Key::Heading,
        ));
    }

    let (x0, x1, mut y0, mut y1) = bounds(
        lines
            .iter()
            .flat_map(|l| l.points.iter())
            .chain(fits.iter().flat_map(|f| f.points.iter())),
    )
    .ok_or_else(|| anyhow::anyhow!("overlay: no finite points"))?;
    let pad = 0.05 * (y1 - y0).max(1e-12);
    (y0, y1) = (y0 - pad, y1 + pad);
    let height = if diffs.is_empty() { 600 } else { 760 };
    let (root, data, _legend) = canvas(path, (800, height), caption, &entries)?;
    let (top, bottom) = if diffs.is_empty() {
        (data.clone(), None)
    } else {
        let (t, b) = data.split_vertically(height * 62 / 100);
        (t, Some(b))
    };
    let yr = if axes.y_down { y1..y0 } else { y0..y1 };
    let mut chart = ChartBuilder::on(&top)
        .margin(12)
        .x_label_area_size(if bottom.is_some() { 20 } else { 50 })
        .y_label_area_size(75)
        .build_cartesian_2d(x0..x1, yr)
        .map_err(err("layout"))?;
    let mut mesh = chart.configure_mesh();
    mesh.y_desc(axes.y)
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 15));
    if bottom.is_none() {
        mesh.x_desc(axes.x);
    } else {
        mesh.x_label_formatter(&|_| String::new());
    }
    mesh.draw().map_err(err("axes"))?;
    // Native first, references over it.
    let mut order: Vec<&Styled> = styled.iter().collect();
    order.sort_by_key(|s| s.source != Source::Native);
    for s in order {
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .collect();
        let style = s.colour.stroke_width(s.width);
        if s.dashed {
            chart
                .draw_series(DashedLineSeries::new(pts, 9, 6, style))
                .map_err(err("series"))?;
        } else {
            chart
                .draw_series(LineSeries::new(pts, style))
                .map_err(err("series"))?;
        }
    }
    for f in fits {
        chart
            .draw_series(DashedLineSeries::new(
                f.points.clone(),
                10,
                6,
                f.source.colour().stroke_width(2),
            ))
            .map_err(err("fit"))?;
    }
    if let Some(bottom) = bottom {
        difference_panel(&bottom, axes, (x0, x1), &diffs)?;
    }
    root.present().map_err(err("write svg"))?;
    Ok(())
}

fn difference_panel(
    area: &Area<'_>,
    axes: &Axes<'_>,
    (x0, x1): (f64, f64),
    diffs: &[Diff],
) -> Result<()> {
    let (_, _, mut d0, mut d1) =
        bounds(diffs.iter().flat_map(|d| d.2.iter())).unwrap_or((0.0, 1.0, -1.0, 1.0));
    d0 = d0.min(0.0);
    d1 = d1.max(0.0);
    let span = (d1 - d0).max(1e-12);
    let (d0, d1) = (d0 - 0.08 * span, d1 + 0.08 * span);
    let mut chart = ChartBuilder::on(area)
        .margin(12)
        .margin_top(4)
        .x_label_area_size(50)
        .y_label_area_size(75)
        .build_cartesian_2d(x0..x1, d0..d1)
        .map_err(err("difference layout"))?;
    chart
        .configure_mesh()
        .x_desc(axes.x)
        .y_desc(format!("reference - native ({})", axes.unit))
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .y_labels(5)
        .draw()
        .map_err(err("difference axes"))?;
    chart
        .draw_series(LineSeries::new(
            vec![(x0, 0.0), (x1, 0.0)],
            GUIDE.stroke_width(1),
        ))
        .map_err(err("zero line"))?;
    for (c, _, d, _) in diffs {
        chart
            .draw_series(LineSeries::new(d.clone(), c.stroke_width(2)))
            .map_err(err("difference"))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a shared grid the difference is exact point by point; on another grid the
    /// native series is interpolated and never extrapolated; a series whose x goes back
    /// gets none (so a wrong difference cannot be drawn silently).
    #[test]
    fn differences_are_taken_honestly() {
        let n: Vec<(f64, f64)> = (0..11).map(|i| (i as f64, 2.0 * i as f64)).collect();
        let r: Vec<(f64, f64)> = n.iter().map(|p| (p.0, p.1 + 0.5)).collect();
        let (d, g) = difference(&n, &r).unwrap();
        assert_eq!(g, Grid::Shared);
        assert!(d.iter().all(|p| (p.1 - 0.5).abs() < 1e-12) && d.len() == 11);
        let r2: Vec<(f64, f64)> = (0..30)
            .map(|i| {
                let x = -1.0 + 0.5 * i as f64;
                (x, 2.0 * x + 1.0)
            })
            .collect();
        let (d, g) = difference(&n, &r2).unwrap();
        assert_eq!(g, Grid::Interpolated);
        assert!(d.iter().all(|p| p.0 >= 0.0 && p.0 <= 10.0));
        assert_eq!(d.len(), 21);
        assert!(d.iter().all(|p| (p.1 - 1.0).abs() < 1e-12), "{d:?}");
        let back = vec![(0.0, 0.0), (1.0, 1.0), (0.5, 2.0)];
        assert!(difference(&back, &r).is_none());
    }

    /// A line's colour is its typed source, whatever its label says: a native line
    /// labelled with every engine's name is native blue, and a LIGGGHTS line labelled
    /// "native run" is vermillion. Negative control of the former label rule, which
    /// coloured the second line native blue (its label contains "native") and left no
    /// LIGGGHTS colour in the figure.
    #[test]
    fn colour_follows_the_source_not_the_label() {
        use super::super::palette::{LAMMPS, LIGGGHTS, NATIVE, OTHER, hex};
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("o.svg");
        let a: Vec<(f64, f64)> = (0..20).map(|i| (i as f64, i as f64)).collect();
        let b: Vec<(f64, f64)> = a.iter().map(|q| (q.0, q.1 + 1.0)).collect();
        overlay(
            &p,
            &"t".into(),
            &Axes {
                x: "x",
                y: "y",
                unit: "u",
                y_down: false,
            },
            &[
                Line::new("lammps native liggghts", Source::Native, &a),
                Line::new("native run", Source::Liggghts, &b),
            ],
            &[],
        )
        .unwrap();
        let svg = std::fs::read_to_string(&p).unwrap();
        let doc = roxmltree::Document::parse(&svg).unwrap();
        let strokes: std::collections::BTreeSet<String> = doc
            .descendants()
            .filter(|n| {
                n.has_tag_name("polyline")
                    && n.attribute("points")
                        .is_some_and(|t| t.split_whitespace().count() >= 10)
            })
            .filter_map(|n| n.attribute("stroke").map(str::to_string))
            .collect();
        // Both lines, and the difference panel's line in the reference's colour.
        let want: std::collections::BTreeSet<String> =
            [hex(NATIVE), hex(LIGGGHTS)].into_iter().collect();
        assert_eq!(strokes, want);
        assert!(!svg.contains(&hex(LAMMPS)) && !svg.contains(&hex(OTHER)));
        assert!(svg.contains("lammps native liggghts") && svg.contains("native run"));
    }
}
