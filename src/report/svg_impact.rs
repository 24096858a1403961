//! D(t) overlay of impact runs (K Fig 2 style): penetration depth in grain diameters
//! against time in tau_c, one line per engine/variant, depth increasing downwards.

use super::plot::{FONT, err, legend};
use anyhow::{Result, ensure};
use plotters::prelude::*;
use std::path::Path;

/// `(label, [(t / tau_c, D / d)])`.
pub type DepthSeries<'a> = (&'a str, &'a [(f64, f64)]);

pub fn depth_overlay(path: &Path, series: &[DepthSeries<'_>], title: &str) -> Result<()> {
    ensure!(!series.is_empty(), "depth_overlay: no series to plot");
    let pts = || {
        series
            .iter()
            .flat_map(|s| s.1.iter())
            .filter(|p| p.0.is_finite() && p.1.is_finite())
    };
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in pts() {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    ensure!(x0 < x1, "depth_overlay: no finite points");
    let pad = 0.05 * (y1 - y0).max(1.0);
    let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(err("fill"))?;
    // Depth grows downwards, as in K's figures of the bed.
    let mut chart = ChartBuilder::on(&root)
        .caption(title, (FONT, 22))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, (y1 + pad)..(y0 - pad))
        .map_err(err("layout"))?;
    chart
        .configure_mesh()
        .x_desc("t / tau_c")
        .y_desc("D / d (below the initial surface)")
        .label_style((FONT, 14))
        .draw()
        .map_err(err("axes"))?;
    for (i, (label, s)) in series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        chart
            .draw_series(LineSeries::new(s.iter().copied(), color.stroke_width(2)))
            .map_err(err("series"))?
            .label(*label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    legend(&mut chart, SeriesLabelPosition::LowerRight, 14)?;
    root.present().map_err(err("write"))?;
    Ok(())
}

/// `(label, [(x, y)])` of a line plot.
pub type Curve<'a> = (&'a str, &'a [(f64, f64)]);

/// Lines on ordinary axes (K Figs 21-23: F(t), B0 against the force threshold).
pub fn curves(
    path: &Path,
    series: &[Curve<'_>],
    title: &str,
    x_desc: &str,
    y_desc: &str,
) -> Result<()> {
    ensure!(!series.is_empty(), "curves: no series to plot");
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in series
        .iter()
        .flat_map(|s| s.1.iter())
        .filter(|p| p.0.is_finite() && p.1.is_finite())
    {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    ensure!(x0 < x1, "curves: no finite points");
    let pad = 0.05 * (y1 - y0).max(1e-12);
    let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(err("fill"))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, (FONT, 20))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
        .map_err(err("layout"))?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .label_style((FONT, 14))
        .draw()
        .map_err(err("axes"))?;
    for (i, (label, s)) in series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        chart
            .draw_series(LineSeries::new(s.iter().copied(), color.stroke_width(2)))
            .map_err(err("series"))?
            .label(*label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    legend(&mut chart, SeriesLabelPosition::UpperRight, 14)?;
    root.present().map_err(err("write"))?;
    Ok(())
}

/// Every grain as a dot at (x, y) (in d) coloured by `value` on [lo, hi] (blue to red;
/// K Figs 24-27's maps), with the colour range in the title.
pub fn grain_map(
    path: &Path,
    points: &[(f64, f64, f64)],
    range: (f64, f64),
    title: &str,
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
    let root = SVGBackend::new(path, (w, h)).into_drawing_area();
    root.fill(&WHITE).map_err(err("fill"))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, (FONT, 16))
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
        .draw_series(points.iter().map(|&(x, y, v)| {
            Circle::new(
                (x, y),
                3,
                super::field_svg::colour(v, range.0, range.1).filled(),
            )
        }))
        .map_err(err("grains"))?;
    root.present().map_err(err("write"))?;
    Ok(())
}
