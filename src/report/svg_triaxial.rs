//! phi_mob(eps_a) of triaxial runs (docs/stress.md rule 5): the mobilised friction angle
//! of the wall stresses against the axial strain, one line per engine and unit.

use super::plot::{FONT, err, legend};
use anyhow::{Result, ensure};
use plotters::prelude::*;
use std::path::Path;

/// `(label, [(eps_a, phi_mob in degrees)])`.
pub type PhiSeries<'a> = (&'a str, &'a [(f64, f64)]);

pub fn phi_mob_overlay(path: &Path, series: &[PhiSeries<'_>], title: &str) -> Result<()> {
    ensure!(!series.is_empty(), "phi_mob_overlay: no series to plot");
    let (mut x1, mut y1) = (0.0f64, 0.0f64);
    for &(x, y) in series.iter().flat_map(|s| s.1.iter()) {
        if x.is_finite() && y.is_finite() {
            x1 = x1.max(x);
            y1 = y1.max(y);
        }
    }
    ensure!(x1 > 0.0, "phi_mob_overlay: no finite points");
    let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(err("fill"))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, (FONT, 22))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..x1, 0.0..(y1 * 1.1 + 1.0))
        .map_err(err("layout"))?;
    chart
        .configure_mesh()
        .x_desc("axial strain eps_a")
        .y_desc("phi_mob (deg)")
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
