//! SVG figures of the penetration observables, drawn with plotters' SVG
//! backend: FDR overlays (the paper's Figs. 2-3 and 8).
//! The K-phi plane of the stress analysis is drawn in `field_svg`.

use super::plot::{FONT, err, legend};
use crate::analysis::fdr::LinearFit;
use anyhow::{Result, ensure};
use plotters::prelude::*;
use std::path::Path;

const SIZE: (u32, u32) = (900, 600);

/// `(lo, hi)` padded by 5% of the span (or by 1 if the span is zero).
fn padded(lo: f64, hi: f64) -> (f64, f64) {
    let span = hi - lo;
    let pad = if span > 0.0 { 0.05 * span } else { 1.0 };
    (lo - pad, hi + pad)
}

/// Finite min/max over values; error if there are none.
fn range<'a>(vals: impl Iterator<Item = &'a f64>, what: &str) -> Result<(f64, f64)> {
    let (lo, hi) = vals
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    ensure!(lo <= hi, "no finite {what} values to plot");
    Ok((lo, hi))
}

/// One FDR series: label, h, p, optional steady-state fit.
pub type FdrSeries<'a> = (&'a str, &'a [f64], &'a [f64], Option<&'a LinearFit>);

/// Overlay of FDRs, each as a solid line, and each fit as a thinner dashed
/// line of the same colour over the fit's own h range (`h_lo..h_hi`),
/// labelled "<label> fit K_phi = .., R^2 = ..". Axis labels follow eq 5.
pub fn fdr_overlay(path: &Path, series: &[FdrSeries<'_>], title: &str) -> Result<()> {
    ensure!(!series.is_empty(), "fdr_overlay: no series to plot");
    for (label, h, p, _) in series {
        ensure!(
            h.len() == p.len(),
            "series '{label}': h and p differ in length ({} vs {})",
            h.len(),
            p.len()
        );
    }
    let (x0, x1) = range(series.iter().flat_map(|s| s.1.iter()), "h")?;
    let mut ys: Vec<f64> = series.iter().flat_map(|s| s.2.iter().copied()).collect();
    for (_, _, _, fit) in series {
        if let Some(f) = fit {
            ys.extend([f.p(f.h_lo), f.p(f.h_hi)]);
        }
    }
    let (y0, y1) = range(ys.iter(), "p")?;
    let (x0, x1) = padded(x0, x1);
    let (y0, y1) = padded(y0, y1);

    let root = SVGBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(err("fill"))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, (FONT, 22))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err("chart layout"))?;
    chart
        .configure_mesh()
        .x_desc("h = depth / R")
        .y_desc("p = F / (rho_g psi g S R)")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .draw()
        .map_err(err("axes"))?;

    for (i, (label, h, p, fit)) in series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let pts: Vec<(f64, f64)> = h
            .iter()
            .zip(p.iter())
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .map(|(a, b)| (*a, *b))
            .collect();
        chart
            .draw_series(LineSeries::new(pts, color.stroke_width(2)))
            .map_err(err("series"))?
            .label(*label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        if let Some(f) = fit {
            let n = 50;
            let line: Vec<(f64, f64)> = (0..=n)
                .map(|k| {
                    let x = f.h_lo + (f.h_hi - f.h_lo) * k as f64 / n as f64;
                    (x, f.p(x))
                })
                .collect();
            let style = BLACK.mix(0.8).stroke_width(1);
            chart
                .draw_series(DashedLineSeries::new(line, 8, 5, style))
                .map_err(err("fit"))?
                .label(format!(
                    "{label} fit: K_phi = {:.2} +- {:.2}, R^2 = {:.4}",
                    f.k_phi, f.se_k, f.r2
                ))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
        }
    }
    legend(&mut chart, SeriesLabelPosition::UpperLeft, 14)?;
    root.present().map_err(err("write svg"))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fdr_overlay_writes_svg() {
        let dir = tempfile::tempdir().unwrap();
        let h: Vec<f64> = (0..=100).map(|i| 0.02 * i as f64).collect();
        let pa: Vec<f64> = h
            .iter()
            .map(|x| 23.0 * x + 3.0 * (1.0 - (-x).exp()))
            .collect();
        let pb: Vec<f64> = pa.iter().map(|v| 1.05 * v).collect();
        let fit = LinearFit {
            k_phi: 23.0,
            p0: 3.0,
            r2: 0.999,
            se_k: 0.1,
            se_p0: 0.05,
            n: 70,
            h_lo: 0.6,
            h_hi: 2.0,
        };
        let path = dir.path().join("fdr.svg");
        fdr_overlay(
            &path,
            &[("native", &h, &pa, Some(&fit)), ("liggghts", &h, &pb, None)],
            "FDR overlay",
        )
        .unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        assert!(!svg.is_empty() && svg.contains("<svg"));
        for needle in [
            "h = depth / R",
            "p = F / (rho_g psi g S R)",
            "native",
            "liggghts",
            "K_phi = 23.00",
        ] {
            assert!(svg.contains(needle), "missing {needle}");
        }
        assert!(fdr_overlay(&path, &[], "x").is_err());
        assert!(fdr_overlay(&path, &[("bad", &h, &pa[..3], None)], "x").is_err());
    }
}
