//! SVG figures of the stress-field analysis (Feng et al. Fig 5-7): colour maps of gamma and of the
//! velocity in the (r, z) plane (the paper's Fig. 5) with the incipient-yield region and
//! the stagnant zone outlined, and the K-phi plane (Fig. 7) with error bars.

use super::palette::{EMPTY, EMPTY_HATCH, INTRUDER, INTRUDER_EDGE, Scale, Source};
use super::plot::{Area, Caption, Entry, FONT, Key, Shape, canvas, draw_key, draw_marker, err};
use anyhow::{Result, ensure};
use plotters::prelude::*;
use std::path::Path;

const SIZE: (u32, u32) = (720, 700);

/// A cell field on the (r, z) plane, r fastest, cell size `spacing`, in units the caller
/// chooses for the axes (we use intruder radii).
pub(crate) struct RzMap<'a> {
    pub nr: usize,
    pub nz: usize,
    pub r0: f64,
    pub z0: f64,
    pub spacing: f64,
    /// NaN = no data (masked, empty): drawn grey and hatched, never a scale colour.
    pub values: &'a [f64],
}

/// The colour bar of `scale` in `area` (its label above it); with `with_empty`, under
/// it the swatch of cells without data, so the reader never takes them for a value.
pub(crate) fn colour_bar(
    area: &Area<'_>,
    label: &str,
    scale: Scale,
    with_empty: bool,
) -> Result<()> {
    let (lo, hi) = scale.range();
    let (bar, foot) = area.split_vertically(area.dim_in_pixel().1.saturating_sub(70));
    let mut cb = ChartBuilder::on(&bar)
        .margin_top(30)
        .margin_bottom(10)
        .margin_right(10)
        .margin_left(8)
        .y_label_area_size(55)
        .caption(label, (FONT, 13))
        .build_cartesian_2d(0.0..1.0, lo..hi)
        .map_err(err("colour bar"))?;
    cb.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .label_style((FONT, 12))
        .draw()
        .map_err(err("colour bar axis"))?;
    let steps = 64;
    cb.draw_series((0..steps).map(|s| {
        let a = lo + (hi - lo) * s as f64 / steps as f64;
        let b = lo + (hi - lo) * (s + 1) as f64 / steps as f64;
        Rectangle::new([(0.0, a), (1.0, b)], scale.colour(0.5 * (a + b)).filled())
    }))
    .map_err(err("colour bar"))?;
    foot.draw(&Text::new(
        scale.describe(),
        (8, 4),
        (FONT, 12).into_font().color(&BLACK),
    ))
    .map_err(err("colour bar"))?;
    if with_empty {
        draw_key(&foot, Key::Empty, 8, 34)?;
        for (i, t) in ["no data", "(empty or masked)"].iter().enumerate() {
            foot.draw(&Text::new(
                *t,
                (44, 22 + 15 * i as i32),
                (FONT, 12).into_font().color(&BLACK),
            ))
            .map_err(err("colour bar"))?;
        }
    }
    Ok(())
}

/// Colour map with outlines: each outline is a cell set whose boundary edges are drawn;
/// `intruder` = (radius, bottom z) in axis units draws the intruder's section. Cells
/// without a value are light grey and hatched, and the colour bar says so; the intruder
/// is a solid body, not missing data, so it is drawn opaque over its cells in a darker
/// grey with a black outline and has its own legend entry: a reader can tell it from
/// empty cells and from the scale's lowest values.
#[allow(clippy::too_many_arguments)]
pub(crate) fn rz_map(
    path: &Path,
    caption: &Caption,
    value_label: &str,
    map: &RzMap<'_>,
    scale: Scale,
    outlines: &[(&str, &[bool], RGBColor)],
    intruder: Option<(f64, f64)>,
) -> Result<()> {
    ensure!(
        map.values.len() == map.nr * map.nz && map.nr > 0 && map.nz > 0,
        "rz_map: {} values for {} x {} cells",
        map.values.len(),
        map.nr,
        map.nz
    );
    for (name, cells, _) in outlines {
        ensure!(
            cells.len() == map.values.len(),
            "rz_map: outline {name} has {} cells, the map {}",
            cells.len(),
            map.values.len()
        );
    }
    let (lo, hi) = scale.range();
    ensure!(
        lo < hi && lo.is_finite() && hi.is_finite(),
        "rz_map: bad colour range {:?}",
        (lo, hi)
    );
    let mut entries: Vec<Entry> = outlines
        .iter()
        .map(|(n, _, c)| {
            Entry::new(
                *n,
                Key::Line {
                    colour: *c,
                    dashed: false,
                    width: 3,
                },
            )
        })
        .collect();
    if intruder.is_some() {
        entries.push(Entry::new(
            "intruder (solid body, no grains)",
            Key::Intruder,
        ));
    }
    let r1 = map.r0 + map.nr as f64 * map.spacing;
    let z1 = map.z0 + map.nz as f64 * map.spacing;
    let (root, main, side) = canvas(path, SIZE, caption, &entries)?;
    let rows = 30 + 19 * entries.len() as u32;
    let (_, bar) = side.split_vertically(rows);
    colour_bar(&bar, value_label, scale, true)?;
    let mut chart = ChartBuilder::on(&main)
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(map.r0..r1, map.z0..z1)
        .map_err(err("chart layout"))?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("r / R")
        .y_desc("z / R")
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 15))
        .draw()
        .map_err(err("axes"))?;
    let cell = |i: usize, k: usize| {
        let (x, y) = (
            map.r0 + i as f64 * map.spacing,
            map.z0 + k as f64 * map.spacing,
        );
        [(x, y), (x + map.spacing, y + map.spacing)]
    };
    let mut rects = Vec::new();
    let mut hatch = Vec::new();
    for k in 0..map.nz {
        for i in 0..map.nr {
            let v = map.values[k * map.nr + i];
            let c = cell(i, k);
            if v.is_finite() {
                rects.push(Rectangle::new(c, scale.colour(v).filled()));
            } else {
                rects.push(Rectangle::new(c, EMPTY.filled()));
                hatch.push(PathElement::new(
                    vec![(c[0].0, c[0].1), (c[1].0, c[1].1)],
                    EMPTY_HATCH.stroke_width(1),
                ));
            }
        }
    }
    chart.draw_series(rects).map_err(err("cells"))?;
    chart.draw_series(hatch).map_err(err("empty cells"))?;
    for (_, cells, col) in outlines {
        let mut segs: Vec<Vec<(f64, f64)>> = Vec::new();
        let inside = |i: isize, k: isize| {
            i >= 0
                && k >= 0
                && (i as usize) < map.nr
                && (k as usize) < map.nz
                && cells[k as usize * map.nr + i as usize]
        };
        for k in 0..map.nz as isize {
            for i in 0..map.nr as isize {
                if !inside(i, k) {
                    continue;
                }
                let [(x0, y0), (x1, y1)] = cell(i as usize, k as usize);
                if !inside(i - 1, k) {
                    segs.push(vec![(x0, y0), (x0, y1)]);
                }
                if !inside(i + 1, k) {
                    segs.push(vec![(x1, y0), (x1, y1)]);
                }
                if !inside(i, k - 1) {
                    segs.push(vec![(x0, y0), (x1, y0)]);
                }
                if !inside(i, k + 1) {
                    segs.push(vec![(x0, y1), (x1, y1)]);
                }
            }
        }
        let style = col.stroke_width(3);
        chart
            .draw_series(segs.into_iter().map(|s| PathElement::new(s, style)))
            .map_err(err("outline"))?;
    }
    if let Some((rad, zb)) = intruder {
        let section = [(map.r0, zb), (rad, z1)];
        chart
            .draw_series([
                Rectangle::new(section, INTRUDER.filled()),
                Rectangle::new(section, INTRUDER_EDGE.stroke_width(2)),
            ])
            .map_err(err("intruder"))?;
    }
    root.present().map_err(err("write svg"))?;
    Ok(())
}

/// A (phi, K_phi) point with its spreads (one standard deviation; 0 = none). Its style
/// is data set by the code that measures it; `label` is the legend's text only.
pub(crate) struct KPhiPoint<'a> {
    pub label: &'a str,
    /// Who produced the point: its colour.
    pub source: Source,
    /// What points share a marker shape (a case, an estimator): one shape per group,
    /// in order of first appearance.
    pub group: &'a str,
    /// A reported, not gated, value: drawn hollow.
    pub reported: bool,
    pub phi_deg: f64,
    pub phi_err: f64,
    pub k: f64,
    pub k_err: f64,
}

/// An angle measured independently of K_phi (rule 5's triaxial test): a vertical band
/// `phi_deg +- half_width_deg` across the whole K axis.
pub(crate) struct PhiBand<'a> {
    pub label: &'a str,
    /// Who measured the angle: the band's colour.
    pub source: Source,
    pub phi_deg: f64,
    pub half_width_deg: f64,
}

/// The phi - K_phi plane with the MALT curve `(phi_deg, K)` on a log K axis, points
/// with error bars (Fig. 7) and vertical bands of independently measured angles. Each
/// point and band is its source's colour (published values black); points of one
/// group (case or estimator) share a marker shape; a reported point is hollow.
pub(crate) fn k_phi_plane(
    path: &Path,
    caption: &Caption,
    curve: &[(f64, f64)],
    points: &[KPhiPoint<'_>],
    bands: &[PhiBand<'_>],
) -> Result<()> {
    ensure!(!curve.is_empty(), "k_phi_plane: empty MALT curve");
    let pts: Vec<&KPhiPoint> = points
        .iter()
        .filter(|p| p.phi_deg.is_finite() && p.k > 0.0 && p.k.is_finite())
        .collect();
    let x1 = pts
        .iter()
        .map(|p| p.phi_deg + p.phi_err + 3.0)
        .chain(bands.iter().map(|b| b.phi_deg + b.half_width_deg + 3.0))
        .fold(curve.last().map(|c| c.0).unwrap_or(40.0), f64::max);
    let k_hi = curve
        .iter()
        .map(|c| c.1)
        .chain(pts.iter().map(|p| p.k + p.k_err))
        .fold(1.0, f64::max)
        * 1.3;
    let mut groups: Vec<&str> = Vec::new();
    let styled: Vec<(&KPhiPoint, RGBColor, bool, Shape)> = pts
        .iter()
        .map(|p| {
            let i = groups
                .iter()
                .position(|g| *g == p.group)
                .unwrap_or_else(|| {
                    groups.push(p.group);
                    groups.len() - 1
                });
            (*p, p.source.colour(), !p.reported, Shape::nth(i))
        })
        .collect();
    let mut entries = vec![Entry::new(
        "MALT, eq 10",
        Key::Line {
            colour: BLACK,
            dashed: false,
            width: 2,
        },
    )];
    for b in bands {
        entries.push(Entry::new(
            format!(
                "{} ({:.2} +- {:.2} deg)",
                b.label, b.phi_deg, b.half_width_deg
            ),
            Key::Patch {
                colour: b.source.colour(),
                opacity: 0.3,
            },
        ));
    }
    for (p, c, filled, shape) in &styled {
        entries.push(Entry::new(
            format!("{} ({:.2} deg, {:.2})", p.label, p.phi_deg, p.k),
            Key::Marker {
                colour: *c,
                filled: *filled,
                shape: *shape,
            },
        ));
    }
    let (root, main, _) = canvas(path, (800, 600), caption, &entries)?;
    let mut chart = ChartBuilder::on(&main)
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..x1, (0.8..k_hi).log_scale())
        .map_err(err("chart layout"))?;
    chart
        .configure_mesh()
        .x_desc("phi (deg)")
        .y_desc("K_phi")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .draw()
        .map_err(err("axes"))?;
    for b in bands {
        let col = b.source.colour();
        let w = b.half_width_deg.max(0.05);
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(b.phi_deg - w, 0.8), (b.phi_deg + w, k_hi)],
                col.mix(0.3).filled(),
            )))
            .map_err(err("band"))?;
    }
    chart
        .draw_series(LineSeries::new(curve.to_vec(), BLACK.stroke_width(2)))
        .map_err(err("curve"))?;
    for (p, col, filled, shape) in &styled {
        let style = col.stroke_width(2);
        let mut bars = Vec::new();
        if p.phi_err > 0.0 {
            bars.push(PathElement::new(
                vec![(p.phi_deg - p.phi_err, p.k), (p.phi_deg + p.phi_err, p.k)],
                style,
            ));
        }
        if p.k_err > 0.0 && p.k - p.k_err > 0.0 {
            bars.push(PathElement::new(
                vec![(p.phi_deg, p.k - p.k_err), (p.phi_deg, p.k + p.k_err)],
                style,
            ));
        }
        chart.draw_series(bars).map_err(err("error bars"))?;
        let px = chart.backend_coord(&(p.phi_deg, p.k));
        let area = chart.plotting_area().strip_coord_spec();
        let (ox, oy) = area.get_base_pixel();
        draw_marker(&area, (px.0 - ox, px.1 - oy), 6, *col, *filled, *shape)?;
    }
    root.present().map_err(err("write svg"))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maps_and_plane_write_svg() {
        let dir = tempfile::tempdir().unwrap();
        let (nr, nz) = (6, 5);
        let vals: Vec<f64> = (0..nr * nz)
            .map(|c| if c == 3 { f64::NAN } else { c as f64 / 30.0 })
            .collect();
        let yield_: Vec<bool> = (0..nr * nz).map(|c| c % 7 == 0).collect();
        let p = dir.path().join("g.svg");
        let map = RzMap {
            nr,
            nz,
            r0: 0.0,
            z0: 0.0,
            spacing: 0.25,
            values: &vals,
        };
        rz_map(
            &p,
            &"gamma".into(),
            "gamma",
            &map,
            Scale::Sequential { lo: 0.0, hi: 1.0 },
            &[("yield", &yield_, RED)],
            Some((1.0, 0.9)),
        )
        .unwrap();
        let svg = std::fs::read_to_string(&p).unwrap();
        assert!(svg.contains("<svg") && svg.contains("yield") && svg.contains("r / R"));
        assert!(
            rz_map(
                &p,
                &"x".into(),
                "x",
                &map,
                Scale::Sequential { lo: 1.0, hi: 0.0 },
                &[],
                None
            )
            .is_err()
        );
        let curve: Vec<(f64, f64)> = (0..=40)
            .map(|d| (d as f64, (0.08 * d as f64).exp()))
            .collect();
        let q = dir.path().join("k.svg");
        k_phi_plane(
            &q,
            &"MALT".into(),
            &curve,
            &[KPhiPoint {
                label: "native",
                source: Source::Native,
                group: "",
                reported: false,
                phi_deg: 25.0,
                phi_err: 1.0,
                k: 20.0,
                k_err: 0.5,
            }],
            &[PhiBand {
                label: "triaxial",
                source: Source::Other,
                phi_deg: 28.0,
                half_width_deg: 0.5,
            }],
        )
        .unwrap();
        let svg = std::fs::read_to_string(&q).unwrap();
        assert!(svg.contains("native (25.00 deg, 20.00)") && svg.contains("MALT"));
        assert!(svg.contains("triaxial (28.00 +- 0.50 deg)"));
    }

    /// The intruder is drawn apart from cells without data and from the scale's lowest
    /// value: in a map whose intruder covers empty cells and cells at the scale's
    /// minimum, the intruder's rect has its own fill (not the empty grey, not the
    /// scale's colour at 0) and a dark outline, and the legend names it. Negative case:
    /// the former translucent black over the hatched empty grey had no rect of its own
    /// fill and no outline.
    #[test]
    fn intruder_is_not_an_empty_or_low_cell() {
        use super::super::palette::hex;
        let dir = tempfile::tempdir().unwrap();
        let (nr, nz) = (8, 8);
        // Empty cells at the top right, zeros (the scale's minimum) under the intruder.
        let vals: Vec<f64> = (0..nr * nz)
            .map(|c| match (c % nr, c / nr) {
                (i, k) if k >= 6 && i >= 4 => f64::NAN,
                (i, _) if i < 4 => 0.0,
                (i, k) => (i + k) as f64 / 16.0,
            })
            .collect();
        let map = RzMap {
            nr,
            nz,
            r0: 0.0,
            z0: -1.0,
            spacing: 0.25,
            values: &vals,
        };
        let scale = Scale::Sequential { lo: 0.0, hi: 1.0 };
        let p = dir.path().join("gamma.svg");
        rz_map(
            &p,
            &"gamma".into(),
            "gamma",
            &map,
            scale,
            &[],
            Some((0.5, -0.5)),
        )
        .unwrap();
        let svg = std::fs::read_to_string(&p).unwrap();
        let doc = roxmltree::Document::parse(&svg).unwrap();
        let rects: Vec<roxmltree::Node> = doc
            .descendants()
            .filter(|n| n.has_tag_name("rect"))
            .collect();
        let filled = |c: &str| {
            rects
                .iter()
                .filter(|n| n.attribute("fill") == Some(c))
                .count()
        };
        let (empty, intruder, low) = (hex(EMPTY), hex(INTRUDER), hex(scale.colour(0.0)));
        assert!(intruder != empty && intruder != low);
        // Eight empty cells and the colour bar's swatch.
        assert_eq!(filled(&empty), 9, "{svg}");
        // The section and the legend's swatch.
        assert_eq!(filled(&intruder), 2);
        assert!(filled(&low) >= 32);
        let outlined = rects
            .iter()
            .filter(|n| n.attribute("stroke") == Some(hex(INTRUDER_EDGE).as_str()))
            .count();
        assert!(outlined >= 2, "no intruder outline");
        assert!(svg.contains("intruder (solid body, no grains)"));
    }
}
