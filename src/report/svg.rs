//! SVG figures of the penetration observables: FDR overlays (the paper's Figs. 2-3 and
//! 8) with their fits and the difference panel of [`super::overlay`], and a quantity
//! along a sweep with error bars (K_phi of Table 3, a seed ensemble's final depth).
//! The K-phi plane of the stress analysis is drawn in `field_svg`.

use super::overlay::{Axes, FitLine, Line, overlay};
use super::palette::{PAPER, Source};
use super::plot::{Caption, Entry, FONT, Key, Shape, canvas, err};
use crate::analysis::fdr::LinearFit;
use anyhow::{Result, ensure};
use plotters::prelude::*;
use std::path::Path;

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

/// One FDR series: its legend text, who produced it and its variant (see
/// [`Line`]), h, p and the optional steady-state fit.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FdrSeries<'a> {
    pub label: &'a str,
    pub source: Source,
    pub variant: &'a str,
    pub h: &'a [f64],
    pub p: &'a [f64],
    pub fit: Option<&'a LinearFit>,
}

impl<'a> FdrSeries<'a> {
    /// A series of `source` with no variant.
    pub fn new(
        label: &'a str,
        source: Source,
        h: &'a [f64],
        p: &'a [f64],
        fit: Option<&'a LinearFit>,
    ) -> FdrSeries<'a> {
        FdrSeries {
            label,
            source,
            variant: "",
            h,
            p,
            fit,
        }
    }
}

/// Overlay of FDRs, each fit a dashed line in its engine's colour over the fit's own h
/// range (`h_lo..h_hi`), labelled with the fitted law and its values. Axis labels
/// follow eq 5; the difference panel is p_reference - p_native.
pub(crate) fn fdr_overlay(path: &Path, series: &[FdrSeries<'_>], caption: &Caption) -> Result<()> {
    ensure!(!series.is_empty(), "fdr_overlay: no series to plot");
    for s in series {
        ensure!(
            s.h.len() == s.p.len(),
            "series '{}': h and p differ in length ({} vs {})",
            s.label,
            s.h.len(),
            s.p.len()
        );
    }
    let pts: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|s| s.h.iter().copied().zip(s.p.iter().copied()).collect())
        .collect();
    let lines: Vec<Line> = series
        .iter()
        .zip(&pts)
        .map(|(s, p)| Line::new(s.label, s.source, p).variant(s.variant))
        .collect();
    let fits: Vec<FitLine> = series
        .iter()
        .filter_map(|s| {
            s.fit.map(|f| FitLine {
                label: format!(
                    "{} fit p = K_phi h + p0: K_phi = {:.2} +- {:.2}, p0 = {:.2}, R^2 = {:.4}",
                    s.label, f.k_phi, f.se_k, f.p0, f.r2
                ),
                source: s.source,
                points: (0..=50)
                    .map(|k| {
                        let x = f.h_lo + (f.h_hi - f.h_lo) * k as f64 / 50.0;
                        (x, f.p(x))
                    })
                    .collect(),
            })
        })
        .collect();
    overlay(
        path,
        caption,
        &Axes {
            x: "h = depth / R",
            y: "p = F / (rho_g psi g S R)",
            unit: "dimensionless p",
            y_down: false,
        },
        &lines,
        &fits,
    )
}

/// One engine's quantity along a sweep (K_phi of Feng et al., a seed ensemble's final
/// depth of Kondic et al.): per point the value, its standard error and the single
/// beds' values (drawn small, so the scatter a claim must beat is visible).
pub(crate) struct SweepSeries<'a> {
    pub label: &'a str,
    /// Who produced the values: the series' colour.
    pub source: Source,
    pub k: &'a [f64],
    pub se: &'a [f64],
    pub beds: &'a [Vec<f64>],
}

/// K_phi against the swept parameter `x` (Feng et al. Fig 3, Table 3): each series with
/// +- 1 SE bars and its single beds, and the paper's published values where it gives
/// them (`paper`, NaN where it does not). Series are offset slightly along x so their
/// bars do not hide each other.
pub(crate) fn k_phi_sweep(
    path: &Path,
    caption: &Caption,
    x_label: &str,
    x: &[f64],
    series: &[SweepSeries<'_>],
    paper: Option<&[f64]>,
) -> Result<()> {
    sweep_with_error_bars(path, caption, x_label, "K_phi", x, series, paper)
}

/// A quantity (`y_label`) against the swept parameter `x`: each series with +- 1 SE bars
/// and its single beds, and published values where given (`paper`, NaN where none).
/// Series are offset slightly along x so their bars do not hide each other. The sweep
/// is the x axis, so each series is its engine's colour (published values black).
pub(crate) fn sweep_with_error_bars(
    path: &Path,
    caption: &Caption,
    x_label: &str,
    y_label: &str,
    x: &[f64],
    series: &[SweepSeries<'_>],
    paper: Option<&[f64]>,
) -> Result<()> {
    ensure!(!x.is_empty(), "sweep_with_error_bars: no points");
    for s in series {
        ensure!(
            s.k.len() == x.len() && s.se.len() == x.len() && s.beds.len() == x.len(),
            "sweep_with_error_bars: series '{}' has {} points for {} x values",
            s.label,
            s.k.len(),
            x.len()
        );
    }
    if let Some(p) = paper {
        ensure!(
            p.len() == x.len(),
            "sweep_with_error_bars: {} paper values for {} x values",
            p.len(),
            x.len()
        );
    }
    let (x0, x1) = range(x.iter(), "x")?;
    let span = if x1 > x0 { x1 - x0 } else { 1.0 };
    let dx = 0.015 * span;
    let ys: Vec<f64> = series
        .iter()
        .flat_map(|s| {
            s.k.iter()
                .zip(s.se)
                .flat_map(|(k, e)| [k - e, k + e])
                .chain(s.beds.iter().flatten().copied())
        })
        .chain(paper.into_iter().flatten().copied())
        .collect();
    let (y0, y1) = range(ys.iter(), y_label)?;
    let (x0, x1) = padded(x0 - dx * series.len() as f64, x1 + dx * series.len() as f64);
    let (y0, y1) = padded(y0.min(0.0), y1);
    let mut entries: Vec<Entry> = Vec::new();
    for s in series {
        let col = s.source.colour();
        entries.push(Entry::new(
            format!("{} mean +- 1 SE", s.label),
            Key::Marker {
                colour: col,
                filled: true,
                shape: Shape::Circle,
            },
        ));
        entries.push(Entry::new(
            format!("{} single beds/seeds", s.label),
            Key::Marker {
                colour: col,
                filled: false,
                shape: Shape::Circle,
            },
        ));
    }
    if paper.is_some() {
        entries.push(Entry::new(
            "published values",
            Key::Marker {
                colour: PAPER,
                filled: true,
                shape: Shape::Square,
            },
        ));
    }
    let (root, main, _) = canvas(path, (800, 600), caption, &entries)?;
    let mut chart = ChartBuilder::on(&main)
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err("chart layout"))?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .draw()
        .map_err(err("axes"))?;
    for (i, s) in series.iter().enumerate() {
        let col = s.source.colour();
        let off = (i as f64 - 0.5 * (series.len() as f64 - 1.0)) * dx;
        let pts: Vec<(f64, f64)> = x.iter().zip(s.k).map(|(a, k)| (a + off, *k)).collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), col.stroke_width(2)))
            .map_err(err("series"))?;
        chart
            .draw_series(pts.iter().map(|p| Circle::new(*p, 5, col.filled())))
            .map_err(err("points"))?;
        chart
            .draw_series(x.iter().zip(s.k).zip(s.se).map(|((a, k), e)| {
                PathElement::new(
                    vec![(a + off, k - e), (a + off, k + e)],
                    col.stroke_width(2),
                )
            }))
            .map_err(err("error bars"))?;
        chart
            .draw_series(x.iter().zip(s.beds).flat_map(|(a, b)| {
                b.iter()
                    .map(move |k| Circle::new((a + off, *k), 2, col.stroke_width(1)))
            }))
            .map_err(err("beds"))?;
    }
    if let Some(p) = paper {
        let pts: Vec<(f64, f64)> = x
            .iter()
            .zip(p)
            .filter(|(_, k)| k.is_finite())
            .map(|(a, k)| (*a, *k))
            .collect();
        chart
            .draw_series(pts.iter().map(|p| {
                Rectangle::new(
                    [
                        (p.0 - dx, p.1 - 0.01 * (y1 - y0)),
                        (p.0 + dx, p.1 + 0.01 * (y1 - y0)),
                    ],
                    PAPER.filled(),
                )
            }))
            .map_err(err("paper"))?;
    }
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
            &[
                FdrSeries::new("native", Source::Native, &h, &pa, Some(&fit)),
                FdrSeries::new("liggghts", Source::Liggghts, &h, &pb, None),
            ],
            &"FDR overlay".into(),
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
        assert!(fdr_overlay(&path, &[], &"x".into()).is_err());
        let q = dir.path().join("sweep.svg");
        let beds = vec![vec![22.0, 24.0], vec![23.0, 23.5], vec![22.5, 24.5]];
        k_phi_sweep(
            &q,
            &"Table 3".into(),
            "v (cm/s)",
            &[0.5, 1.0, 2.0],
            &[SweepSeries {
                label: "native",
                source: Source::Native,
                k: &[23.0, 23.2, 23.5],
                se: &[0.5, 0.4, 0.6],
                beds: &beds,
            }],
            Some(&[23.05, 22.86, 23.14]),
        )
        .unwrap();
        let svg = std::fs::read_to_string(&q).unwrap();
        assert!(
            svg.contains("v (cm/s)") && svg.contains("published values") && svg.contains("native")
        );
        assert!(k_phi_sweep(&q, &"t".into(), "x", &[1.0], &[], Some(&[1.0, 2.0])).is_err());
        let bad = FdrSeries::new("bad", Source::Native, &h, &pa[..3], None);
        assert!(fdr_overlay(&path, &[bad], &"x".into()).is_err());
    }
}
