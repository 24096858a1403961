//! Figures of the 2D impact runs (Kondic et al.): the D(t) overlay (K Fig 2 style,
//! depth increasing downwards), other engine-vs-engine curves (F(t), B0), each with the
//! difference panel of [`super::overlay`], and grain maps (K Figs 24-27).

use super::field_svg::colour_bar;
use super::overlay::{Axes, Line, overlay};
use super::palette::Scale;
use super::plot::{Caption, FONT, canvas, err};
use anyhow::{Result, ensure};
use plotters::prelude::*;
use std::path::Path;

/// A line of (t / tau_c, D / d).
pub type DepthSeries<'a> = Line<'a>;

/// D / d against t / tau_c, one line per engine and variant.
pub(crate) fn depth_overlay(
    path: &Path,
    series: &[DepthSeries<'_>],
    caption: &Caption,
) -> Result<()> {
    overlay(
        path,
        caption,
        &Axes {
            x: "t / tau_c",
            y: "D / d (below the initial surface)",
            unit: "d",
            y_down: true,
        },
        series,
        &[],
    )
}

/// A line of a line plot.
pub(crate) type Curve<'a> = Line<'a>;

/// Lines on ordinary axes (K Figs 21-23: F(t), B0 against the force threshold); `unit`
/// is y's unit in the difference panel.
pub fn curves(
    path: &Path,
    series: &[Curve<'_>],
    caption: &Caption,
    x_desc: &str,
    y_desc: &str,
    unit: &str,
) -> Result<()> {
    overlay(
        path,
        caption,
        &Axes {
            x: x_desc,
            y: y_desc,
            unit,
            y_down: false,
        },
        series,
        &[],
    )
}

/// Every grain as a dot at (x, y) (in d) coloured by `value` on `scale` (K Figs 24-27's
/// maps), with its colour bar labelled `value_label`.
pub(crate) fn grain_map(
    path: &Path,
    points: &[(f64, f64, f64)],
    scale: Scale,
    value_label: &str,
    caption: &Caption,
) -> Result<()> {
    ensure!(!points.is_empty(), "grain_map: no grains");
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y, _) in points {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    let w = 1000u32;
    let h = ((w as f64) * (y1 - y0 + 2.0) / (x1 - x0 + 2.0)).clamp(200.0, 1200.0) as u32 + 80;
    let (root, main, bar) = canvas(path, (w, h.max(320)), caption, &[])?;
    colour_bar(&bar, value_label, scale, false)?;
    let mut chart = ChartBuilder::on(&main)
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d((x0 - 1.0)..(x1 + 1.0), (y0 - 1.0)..(y1 + 1.0))
        .map_err(err("layout"))?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x / d")
        .y_desc("y / d")
        .label_style((FONT, 12))
        .draw()
        .map_err(err("axes"))?;
    chart
        .draw_series(
            points
                .iter()
                .map(|&(x, y, v)| Circle::new((x, y), 3, scale.colour(v).filled())),
        )
        .map_err(err("grains"))?;
    root.present().map_err(err("write"))?;
    Ok(())
}
