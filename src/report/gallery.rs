//! The figure gallery (docs/figures.md): one figure of each kind granval draws, from
//! small synthetic inputs, every one captioned "illustration" so nobody reads it as a
//! result. Regenerate with `cargo run --example gallery` (writes docs/figures/); the
//! tier-1 test `gallery_is_up_to_date` fails when a committed figure differs from what
//! the code draws now.
//!
//! The inputs are smooth closed forms with the shapes the papers report (a linear FDR
//! after a transient, eq 5; D(t) saturating with a small oscillation, K Fig 2; a
//! mobilised friction angle with a peak and a critical state), not measurements.

use super::field_svg::{KPhiPoint, PhiBand, RzMap, k_phi_plane, rz_map};
use super::overlay::Line;
use super::palette::{OTHER, Scale, Source};
use super::plot::Caption;
use super::svg::{FdrSeries, SweepSeries, fdr_overlay, sweep_with_error_bars};
use super::svg_impact::depth_overlay;
use super::svg_triaxial::phi_mob_overlay;
use crate::analysis::fdr::{Fdr, steady_state_fit};
use crate::analysis::malt;
use anyhow::{Context, Result};
use plotters::style::RGBColor;
use std::path::{Path, PathBuf};

/// The gallery's files, in the order docs/figures.md shows them.
pub(crate) const FILES: [&str; 9] = [
    "fdr.svg",
    "depth.svg",
    "depth-sweep.svg",
    "final-depth-sweep.svg",
    "field-gamma.svg",
    "field-vz.svg",
    "phi-mob.svg",
    "k-phi.svg",
    "control-depth.svg",
];

fn caption(title: &str) -> Caption {
    Caption::new(title).illustration()
}

/// D(t) / d of an impact at speed `v` (d / tau_c): saturating at 5.4 + 7.6 v with a
/// decaying oscillation; `scale` stands for an engine's small difference.
fn depth_series(v: f64, scale: f64, phase: f64) -> Vec<(f64, f64)> {
    let d_inf = (5.4 + 7.6 * v) * scale;
    (0..=400)
        .map(|i| {
            let t = 2.0 * i as f64;
            let osc = 0.15 * (-t / 250.0).exp() * (t / 18.0 + phase).sin();
            (t, d_inf * (1.0 - (-t * v.max(0.1) / 40.0).exp()) + osc)
        })
        .collect()
}

fn fdr_series(k: f64) -> Fdr {
    let h: Vec<f64> = (0..=150).map(|i| 0.02 * i as f64).collect();
    let p = h
        .iter()
        .map(|&x| k * x + 4.0 * (1.0 - (-3.0 * x).exp()) + 0.3 * (7.0 * x).sin())
        .collect();
    Fdr { h, p }
}

/// Writes every gallery figure into `dir` (created if missing); returns their paths.
pub fn write_all(dir: &Path) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let path = |f: &str| dir.join(f);

    // FDR with steady-state fits (Feng et al. eq 5, Figs 2-3).
    let (fa, fb) = (fdr_series(23.0), fdr_series(24.0));
    let (ka, kb) = (
        steady_state_fit(&fa, 1.0, 3.0)?,
        steady_state_fit(&fb, 1.0, 3.0)?,
    );
    fdr_overlay(
        &path(FILES[0]),
        &[
            FdrSeries::new("native", Source::Native, &fa.h, &fa.p, Some(&ka)),
            FdrSeries::new("LIGGGHTS", Source::Liggghts, &fb.h, &fb.p, Some(&kb)),
        ],
        &caption("FDR, native vs LIGGGHTS (mean of beds)"),
    )?;

    // D(t), one variant, both engines.
    let (da, db) = (depth_series(0.7, 1.0, 0.0), depth_series(0.7, 1.004, 0.3));
    depth_overlay(
        &path(FILES[1]),
        &[
            Line::new("native", Source::Native, &da),
            Line::new("LAMMPS", Source::Lammps, &db),
        ],
        &caption("D(t), native vs LAMMPS, v = 0.7 d/tau_c"),
    )?;

    // D(t) of a speed sweep: colour = speed, line style = engine.
    let speeds = [0.2, 0.4, 0.7, 1.0];
    type Run = (String, Source, String, Vec<(f64, f64)>);
    // (label, source, variant, points)
    let runs: Vec<Run> = speeds
        .iter()
        .flat_map(|&v| {
            [
                (Source::Native, depth_series(v, 1.0, 0.0)),
                (Source::Lammps, depth_series(v, 1.003, 0.2)),
            ]
            .map(|(e, s)| (format!("{} v={v}", e.name()), e, format!("v={v}"), s))
        })
        .collect();
    let refs: Vec<Line> = runs
        .iter()
        .map(|(l, e, v, s)| Line::new(l, *e, s).variant(v))
        .collect();
    depth_overlay(
        &path(FILES[2]),
        &refs,
        &caption("D(t) of a speed sweep (K Fig 8b's runs), native vs LAMMPS"),
    )?;

    // Final depth along the sweep with error bars over seeds.
    let seeds = |scale: f64, j: usize| -> Vec<Vec<f64>> {
        speeds
            .iter()
            .map(|&v| {
                (0..5)
                    .map(|s| scale * (5.4 + 7.6 * v) + 0.12 * (((s + j) * 7 % 5) as f64 - 2.0))
                    .collect()
            })
            .collect()
    };
    let stats = |b: &[Vec<f64>]| -> (Vec<f64>, Vec<f64>) {
        b.iter()
            .map(|s| {
                let n = s.len() as f64;
                let m = s.iter().sum::<f64>() / n;
                let var = s.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
                (m, (var / n).sqrt())
            })
            .unzip()
    };
    let (ba, bb) = (seeds(1.0, 0), seeds(1.01, 2));
    let ((ma, sa), (mb, sb)) = (stats(&ba), stats(&bb));
    sweep_with_error_bars(
        &path(FILES[3]),
        &caption("final depth along a speed sweep, mean of 5 seeds +- 1 SE"),
        "v (d / tau_c)",
        "final depth / d",
        &speeds,
        &[
            SweepSeries {
                label: "native",
                source: Source::Native,
                k: &ma,
                se: &sa,
                beds: &ba,
            },
            SweepSeries {
                label: "LAMMPS",
                source: Source::Lammps,
                k: &mb,
                se: &sb,
                beds: &bb,
            },
        ],
        None,
    )?;

    // Field maps on the (r, z) plane (Feng et al. Fig 5): gamma sequential, v_z
    // diverging about 0; above the surface and inside the intruder there is no data.
    let (nr, nz, h) = (24usize, 28usize, 0.125);
    let (z0, zb) = (-2.5, -1.0);
    let centre = |i: usize, k: usize| (h * (i as f64 + 0.5), z0 + h * (k as f64 + 0.5));
    let empty = |r: f64, z: f64| z > 0.0 || (r < 1.0 && z > zb);
    let mut gamma = Vec::with_capacity(nr * nz);
    let mut vz = Vec::with_capacity(nr * nz);
    for k in 0..nz {
        for i in 0..nr {
            let (r, z) = centre(i, k);
            if empty(r, z) {
                gamma.push(f64::NAN);
                vz.push(f64::NAN);
                continue;
            }
            let d2 = r * r + (z - zb) * (z - zb);
            gamma.push(0.55 * (-0.35 * d2).exp() + 0.05);
            vz.push(
                -(-0.8 * (r * r + 1.5 * (z - zb + 0.3).powi(2))).exp()
                    + 0.25 * (-(r - 1.6).powi(2)).exp() * (-(z.powi(2))).exp(),
            );
        }
    }
    let yielded: Vec<bool> = gamma.iter().map(|g| *g >= 0.45).collect();
    let stagnant: Vec<bool> = (0..nr * nz)
        .map(|c| {
            let (r, z) = centre(c % nr, c / nr);
            r < 0.7 - 0.8 * (zb - z) && z < zb
        })
        .collect();
    let map = |values| RzMap {
        nr,
        nz,
        r0: 0.0,
        z0,
        spacing: h,
        values,
    };
    let gmax = gamma
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    rz_map(
        &path(FILES[4]),
        &caption("gamma (eq 8), one window"),
        "gamma",
        &map(&gamma),
        Scale::Sequential { lo: 0.0, hi: gmax },
        &[
            ("yield: gamma >= 0.85 sin phi", &yielded, RGBColor(0, 0, 0)),
            ("stagnant zone", &stagnant, OTHER),
        ],
        Some((1.0, zb)),
    )?;
    let (lo, hi) = vz
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold((0.0f64, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    rz_map(
        &path(FILES[5]),
        &caption("v_z / intruder speed (eq 7), one window"),
        "v_z / U",
        &map(&vz),
        Scale::centred(lo, hi),
        &[("stagnant zone", &stagnant, OTHER)],
        Some((1.0, zb)),
    )?;

    // phi_mob(eps_a) of a triaxial test (docs/stress.md rule 5), on different output
    // grids in the two engines (the difference panel interpolates, and says so).
    let phi = |eps: f64, peak: f64| {
        24.0 + peak * (eps / 0.03) * (-eps / 0.03).exp() * 2.7 - 24.0 * (-eps / 0.004).exp()
    };
    let pa: Vec<(f64, f64)> = (0..=150)
        .map(|i| 0.002 * i as f64)
        .map(|e| (e, phi(e, 6.0)))
        .collect();
    let pb: Vec<(f64, f64)> = (0..=120)
        .map(|i| 0.0025 * i as f64)
        .map(|e| (e, phi(e, 6.4) + 0.2))
        .collect();
    phi_mob_overlay(
        &path(FILES[6]),
        &[
            Line::new("native", Source::Native, &pa),
            Line::new("LIGGGHTS", Source::Liggghts, &pb),
        ],
        &caption("phi_mob(eps_a), sigma_c = 10 kPa, native vs LIGGGHTS"),
    )?;

    // The K_phi - phi plane with the MALT curve (Feng et al. eq 10, Fig 7).
    let curve: Vec<(f64, f64)> = malt::table(45.0, 0.5)?
        .into_iter()
        .filter(|(_, k)| *k <= 2e3)
        .collect();
    let at = |k: f64| -> Result<f64> { Ok(malt::phi_of_k(k)?.to_degrees()) };
    let points = [
        KPhiPoint {
            label: "native, phi v2 (gated)",
            source: Source::Native,
            group: "phi v2",
            reported: false,
            phi_deg: at(23.0)? + 0.8,
            phi_err: 1.1,
            k: 23.0,
            k_err: 0.4,
        },
        KPhiPoint {
            label: "LIGGGHTS, phi v2 (gated)",
            source: Source::Liggghts,
            group: "phi v2",
            reported: false,
            phi_deg: at(24.0)? - 0.5,
            phi_err: 1.0,
            k: 24.0,
            k_err: 0.5,
        },
        KPhiPoint {
            label: "native, phi v1 (reported)",
            source: Source::Native,
            group: "phi v1",
            reported: true,
            phi_deg: at(23.0)? - 2.0,
            phi_err: 1.5,
            k: 23.0,
            k_err: 0.4,
        },
        KPhiPoint {
            label: "LIGGGHTS, phi v1 (reported)",
            source: Source::Liggghts,
            group: "phi v1",
            reported: true,
            phi_deg: at(24.0)? - 2.4,
            phi_err: 1.4,
            k: 24.0,
            k_err: 0.5,
        },
        KPhiPoint {
            label: "Feng et al. Table 3",
            source: Source::Paper,
            group: "Feng et al. Table 3",
            reported: false,
            phi_deg: at(23.0)?,
            phi_err: 0.0,
            k: 23.0,
            k_err: 0.15,
        },
    ];
    k_phi_plane(
        &path(FILES[7]),
        &caption("K_phi vs internal friction angle (MALT, eq 10)"),
        &curve,
        &points,
        &[PhiBand {
            label: "triaxial phi_cs, native",
            source: Source::Native,
            phi_deg: 24.1,
            half_width_deg: 0.4,
        }],
    )?;

    // A negative control: the native run with friction x 0.8 against the same LAMMPS
    // run; it must disagree, and the figure says so.
    let dc = depth_series(0.7, 1.12, 0.0);
    depth_overlay(
        &path(FILES[8]),
        &[
            Line::new("native", Source::Native, &dc),
            Line::new("LAMMPS", Source::Lammps, &db),
        ],
        &caption("D(t), native vs LAMMPS").control(Some("friction x 0.8")),
    )?;
    Ok(FILES.iter().map(|f| dir.join(f)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::field_svg::{RzMap, rz_map};
    use crate::report::palette::{self, EMPTY, LAMMPS, LIGGGHTS, NATIVE, hex};
    use crate::report::svg_impact::curves;

    fn read(p: &Path) -> String {
        std::fs::read_to_string(p).unwrap()
    }

    /// `(stroke or fill colour, points)` of every polyline of an SVG.
    fn polylines(svg: &str) -> Vec<(String, Vec<(f64, f64)>)> {
        let doc = roxmltree::Document::parse(svg).unwrap();
        doc.descendants()
            .filter(|n| n.has_tag_name("polyline"))
            .map(|n| {
                let pts = n
                    .attribute("points")
                    .unwrap_or("")
                    .split_whitespace()
                    .filter_map(|p| {
                        let (x, y) = p.split_once(',')?;
                        Some((x.parse().ok()?, y.parse().ok()?))
                    })
                    .collect();
                (n.attribute("stroke").unwrap_or("").to_string(), pts)
            })
            .collect()
    }

    /// `(x, text)` of every text element.
    fn texts(svg: &str) -> Vec<(f64, String)> {
        let doc = roxmltree::Document::parse(svg).unwrap();
        doc.descendants()
            .filter(|n| n.has_tag_name("text"))
            .map(|n| {
                (
                    n.attribute("x").and_then(|x| x.parse().ok()).unwrap_or(0.0),
                    n.text().unwrap_or("").trim().to_string(),
                )
            })
            .collect()
    }

    /// The colours of the data lines (polylines of at least `min_points` points).
    fn line_colours(svg: &str, min_points: usize) -> std::collections::BTreeSet<String> {
        polylines(svg)
            .into_iter()
            .filter(|(_, p)| p.len() >= min_points)
            .map(|(c, _)| c)
            .collect()
    }

    /// Every figure kind drawn with two engines: each engine's data lines are its one
    /// colour (native #0072B2, LIGGGHTS #D55E00, LAMMPS #009E73) in every kind, and no
    /// other colour draws data. Negative case: the former per-figure palette (plotters'
    /// Palette99, series i -> colour i) gave the first series #E6194B in every figure
    /// and would fail the membership; swapping two engines' colours fails the presence.
    #[test]
    fn engine_colours_are_the_same_in_every_figure() {
        let dir = tempfile::tempdir().unwrap();
        let p = |f: &str| dir.path().join(f);
        let line: Vec<(f64, f64)> = (0..50).map(|i| (i as f64, (i as f64).sqrt())).collect();
        let other: Vec<(f64, f64)> = line.iter().map(|q| (q.0, q.1 + 0.1)).collect();
        let c = Caption::new("t");
        let (nat, lam, lig) = (Source::Native, Source::Lammps, Source::Liggghts);
        depth_overlay(
            &p("d.svg"),
            &[
                Line::new("native", nat, &line),
                Line::new("LAMMPS", lam, &other),
            ],
            &c,
        )
        .unwrap();
        curves(
            &p("c.svg"),
            &[
                Line::new("LIGGGHTS", lig, &other),
                Line::new("native", nat, &line),
            ],
            &c,
            "x",
            "y",
            "u",
        )
        .unwrap();
        phi_mob_overlay(
            &p("m.svg"),
            &[
                Line::new("native", nat, &line),
                Line::new("LIGGGHTS", lig, &other),
            ],
            &c,
        )
        .unwrap();
        let h: Vec<f64> = line.iter().map(|q| q.0).collect();
        let (ya, yb): (Vec<f64>, Vec<f64>) =
            line.iter().zip(&other).map(|(a, b)| (a.1, b.1)).unzip();
        fdr_overlay(
            &p("f.svg"),
            &[
                FdrSeries::new("native", nat, &h, &ya, None),
                FdrSeries::new("LIGGGHTS", lig, &h, &yb, None),
            ],
            &c,
        )
        .unwrap();
        let (n, l, g) = (hex(NATIVE), hex(LAMMPS), hex(LIGGGHTS));
        for (f, reference) in [("d.svg", &l), ("c.svg", &g), ("m.svg", &g), ("f.svg", &g)] {
            let svg = read(&p(f));
            let cols = line_colours(&svg, 10);
            let want: std::collections::BTreeSet<String> =
                [n.clone(), reference.clone()].into_iter().collect();
            // The main panel's lines, and the difference panel's line in the reference's
            // colour.
            assert_eq!(cols, want, "{f}");
        }
        // The sweep figure and the K-phi plane: markers and bars in the engines' colours.
        let beds = vec![vec![1.0, 1.2]; 3];
        sweep_with_error_bars(
            &p("s.svg"),
            &c,
            "x",
            "y",
            &[1.0, 2.0, 3.0],
            &[
                SweepSeries {
                    label: "native",
                    source: nat,
                    k: &[1.0, 2.0, 3.0],
                    se: &[0.1; 3],
                    beds: &beds,
                },
                SweepSeries {
                    label: "LAMMPS",
                    source: lam,
                    k: &[1.1, 2.1, 3.1],
                    se: &[0.1; 3],
                    beds: &beds,
                },
            ],
            None,
        )
        .unwrap();
        assert_eq!(
            line_colours(&read(&p("s.svg")), 3),
            [n.clone(), l.clone()].into_iter().collect()
        );
        let svg = {
            let curve = vec![(0.0, 1.0), (40.0, 100.0)];
            k_phi_plane(
                &p("k.svg"),
                &c,
                &curve,
                &[
                    KPhiPoint {
                        label: "native",
                        source: nat,
                        group: "",
                        reported: false,
                        phi_deg: 20.0,
                        phi_err: 1.0,
                        k: 20.0,
                        k_err: 1.0,
                    },
                    KPhiPoint {
                        label: "LIGGGHTS",
                        source: lig,
                        group: "",
                        reported: false,
                        phi_deg: 22.0,
                        phi_err: 1.0,
                        k: 22.0,
                        k_err: 1.0,
                    },
                ],
                &[],
            )
            .unwrap();
            read(&p("k.svg"))
        };
        let bars = line_colours(&svg, 2);
        assert!(
            bars.contains(&n) && bars.contains(&g) && !bars.contains(&l),
            "{bars:?}"
        );
    }

    /// No legend text lies left of the rightmost data point: the legend is its own
    /// panel. Negative case: the former legend inside the plot (upper left or lower
    /// right of the data area) put its labels at x inside the data's x range.
    #[test]
    fn legends_do_not_overlap_the_data() {
        let dir = tempfile::tempdir().unwrap();
        write_all(dir.path()).unwrap();
        for (f, labels) in [
            ("depth.svg", vec!["native", "LAMMPS"]),
            ("depth-sweep.svg", vec!["native", "LAMMPS", "v=0.2", "v=1"]),
            ("fdr.svg", vec!["native", "LIGGGHTS"]),
            ("phi-mob.svg", vec!["native", "LIGGGHTS"]),
            ("control-depth.svg", vec!["native", "LAMMPS"]),
        ] {
            let svg = read(&dir.path().join(f));
            let data_right = polylines(&svg)
                .iter()
                .filter(|(_, p)| p.len() >= 10)
                .flat_map(|(_, p)| p.iter().map(|q| q.0))
                .fold(f64::NEG_INFINITY, f64::max);
            assert!(data_right.is_finite(), "{f}: no data lines");
            let t = texts(&svg);
            for l in labels {
                let (x, _) = t
                    .iter()
                    .find(|(_, s)| s == l)
                    .unwrap_or_else(|| panic!("{f}: legend entry {l} missing"));
                assert!(
                    *x > data_right,
                    "{f}: legend '{l}' at x {x} over data up to {data_right}"
                );
            }
        }
    }

    /// A control's figure is titled "negative control: <perturbation>, ..." and framed in
    /// the control colour; the same figure of the case itself is neither (so the test
    /// fails if the caption ignored the control, or marked every figure).
    #[test]
    fn control_figures_say_negative_control() {
        let dir = tempfile::tempdir().unwrap();
        let line: Vec<(f64, f64)> = (0..20).map(|i| (i as f64, i as f64)).collect();
        let title = "fig2: D(t), native vs LAMMPS";
        let (a, b) = (dir.path().join("a.svg"), dir.path().join("b.svg"));
        let series = [
            Line::new("native", Source::Native, &line),
            Line::new("LAMMPS", Source::Lammps, &line),
        ];
        depth_overlay(
            &a,
            &series,
            &Caption::new(title).control(Some("friction x 0.8")),
        )
        .unwrap();
        depth_overlay(&b, &series, &Caption::new(title).control(None)).unwrap();
        let ctl = hex(palette::CONTROL);
        let (sa, sb) = (read(&a), read(&b));
        let ta = texts(&sa);
        assert_eq!(
            ta[0].1,
            format!("negative control: friction x 0.8, {title}")
        );
        assert!(ta.iter().any(|t| t.1.contains("not an engine comparison")));
        assert!(sa.contains(&ctl));
        assert!(!sb.contains("negative control") && !sb.contains(&ctl));
    }

    /// Cells without a value are filled with the empty grey, one rect per such cell
    /// plus the colour bar's swatch; a map without empty cells has only the swatch. A
    /// map that drew NaN with a scale colour (or skipped it, leaving white) fails.
    #[test]
    fn empty_field_cells_get_the_empty_colour() {
        let dir = tempfile::tempdir().unwrap();
        let count = |vals: &[f64], f: &str| {
            let p = dir.path().join(f);
            let map = RzMap {
                nr: 5,
                nz: 4,
                r0: 0.0,
                z0: 0.0,
                spacing: 0.5,
                values: vals,
            };
            rz_map(
                &p,
                &Caption::new("g"),
                "g",
                &map,
                Scale::Sequential { lo: 0.0, hi: 1.0 },
                &[],
                None,
            )
            .unwrap();
            let svg = read(&p);
            let doc = roxmltree::Document::parse(&svg).unwrap();
            doc.descendants()
                .filter(|n| {
                    n.has_tag_name("rect") && n.attribute("fill") == Some(hex(EMPTY).as_str())
                })
                .count()
        };
        let mut vals: Vec<f64> = (0..20).map(|i| i as f64 / 20.0).collect();
        assert_eq!(count(&vals, "full.svg"), 1);
        for i in [0, 7, 19] {
            vals[i] = f64::NAN;
        }
        assert_eq!(count(&vals, "holes.svg"), 4);
    }

    /// The committed gallery (docs/figures/) is what the code draws now, every file is
    /// well-formed XML under 200 kB, and docs/figures.md shows each. Regenerate with
    /// `cargo run --example gallery`.
    #[test]
    fn gallery_is_up_to_date() {
        let dir = tempfile::tempdir().unwrap();
        let written = write_all(dir.path()).unwrap();
        let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/figures");
        let md =
            std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/figures.md"))
                .unwrap();
        for p in written {
            let name = p.file_name().unwrap().to_str().unwrap();
            let now = read(&p);
            roxmltree::Document::parse(&now).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(now.len() < 200_000, "{name}: {} bytes", now.len());
            let old = std::fs::read_to_string(committed.join(name)).unwrap_or_else(|e| {
                panic!("docs/figures/{name}: {e}; run `cargo run --example gallery`")
            });
            assert!(
                old == now,
                "docs/figures/{name} is stale: run `cargo run --example gallery`"
            );
            assert!(
                md.contains(&format!("figures/{name}")),
                "docs/figures.md does not show {name}"
            );
        }
    }
}
