//! Outputs of the stress-field analysis: (r, z) CSV, 3D VTK/CSV grids and SVG maps of
//! each window's averaged fields.

use crate::analysis::coarse_grain::{Grid3, PointFields, RzField};
use crate::analysis::stress::{self, principal};
use crate::analysis::stress_fields::{SnapshotFields, WindowFields};
use crate::rundata::snapshot::SnapshotMeta;
use anyhow::{Context, Result};
use std::io::Write;
use std::path::Path;

fn rz_csv(path: &Path, f: &SnapshotFields) -> Result<()> {
    let mut w = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?,
    );
    let (rz, a, m) = (&f.rz, &f.analysis, &f.snap_meta);
    writeln!(
        w,
        "r,z,r_over_R,z_minus_surface_over_R,in_mask,solid_fraction,grains_in_basic,v_r,v_theta,v_z,\
         basic_rr,basic_tt,basic_zz,basic_rt,basic_rz,basic_tz,s1_basic,s2_basic,s3_basic,gamma_basic,\
         kernel_rr,kernel_tt,kernel_zz,kernel_rt,kernel_rz,kernel_tz,s1_kernel,s2_kernel,s3_kernel,gamma_kernel,\
         yield_basic,stagnant"
    )?;
    let opt = |g: Option<f64>| g.map_or("nan".to_string(), |g| format!("{g:e}"));
    for kz in 0..rz.nz {
        for i in 0..rz.nr {
            let c = rz.idx(i, kz);
            let v = rz.velocity[c];
            write!(
                w,
                "{:e},{:e},{:e},{:e},{},{:e},{:e},{:e},{:e},{:e}",
                rz.r(i),
                rz.z(kz),
                rz.r(i) / m.intruder_radius,
                (rz.z(kz) - m.surface_z) / m.intruder_radius,
                a.mask[c] as u8,
                rz.solid_fraction[c],
                rz.grains_in_basic[c],
                v[0],
                v[1],
                v[2]
            )?;
            for (s, g) in [
                (&rz.stress_basic[c], a.gamma_basic[c]),
                (&rz.stress_kernel[c], a.gamma_kernel[c]),
            ] {
                for x in s {
                    write!(w, ",{x:e}")?;
                }
                let p = principal(s);
                write!(w, ",{:e},{:e},{:e},{}", p.s1, p.s2, p.s3, opt(g))?;
            }
            writeln!(w, ",{},{}", a.yield_basic[c] as u8, a.stagnant[c] as u8)?;
        }
    }
    w.flush()?;
    Ok(())
}

/// VTK and CSV of the (window-averaged) 3D grid; `m` places the intruder.
fn grid3_outputs(
    dir: &Path,
    k: usize,
    grid: &Grid3,
    vals: &[PointFields],
    m: &SnapshotMeta,
) -> Result<()> {
    let pts = grid.points();
    let sf: Vec<f64> = vals.iter().map(|v| v.solid_fraction).collect();
    let vel: Vec<[f64; 3]> = vals.iter().map(|v| v.velocity).collect();
    let sb: Vec<[f64; 6]> = vals.iter().map(|v| v.stress_basic).collect();
    let sk: Vec<[f64; 6]> = vals.iter().map(|v| v.stress_kernel).collect();
    let gam = |s: &[[f64; 6]]| -> Vec<f64> {
        s.iter()
            .map(|t| stress::gamma(&principal(t)).unwrap_or(f64::NAN))
            .collect()
    };
    let (gb, gk) = (gam(&sb), gam(&sk));
    crate::report::vtk::write_structured_points(
        &dir.join(format!("fields_{k:02}.vtk")),
        &format!(
            "granval CG fields, {} h = {:.4} (window average), SI, compressive stress positive",
            m.engine, m.h
        ),
        grid,
        &crate::report::vtk::GridData {
            scalars: vec![
                ("solid_fraction", &sf),
                ("gamma_basic", &gb),
                ("gamma_kernel", &gk),
            ],
            vectors: vec![("velocity", &vel)],
            tensors: vec![("stress_basic", &sb), ("stress_kernel", &sk)],
        },
    )?;
    let p = dir.join(format!("fields_{k:02}_3d.csv"));
    let mut w = std::io::BufWriter::new(
        std::fs::File::create(&p).with_context(|| format!("cannot create {}", p.display()))?,
    );
    writeln!(
        w,
        "x,y,z,solid_fraction,vx,vy,vz,basic_xx,basic_yy,basic_zz,basic_xy,basic_xz,basic_yz,gamma_basic,\
         kernel_xx,kernel_yy,kernel_zz,kernel_xy,kernel_xz,kernel_yz,gamma_kernel"
    )?;
    for (c, x) in pts.iter().enumerate() {
        write!(w, "{:e},{:e},{:e},{:e}", x[0], x[1], x[2], sf[c])?;
        for v in vel[c] {
            write!(w, ",{v:e}")?;
        }
        for (s, g) in [(&sb[c], gb[c]), (&sk[c], gk[c])] {
            for v in s {
                write!(w, ",{v:e}")?;
            }
            write!(w, ",{g:e}")?;
        }
        writeln!(w)?;
    }
    w.flush()?;
    Ok(())
}

fn svg_maps(dir: &Path, k: usize, f: &SnapshotFields) -> Result<()> {
    use crate::report::field_svg::{RzMap, rz_map};
    use crate::report::palette::{OTHER, Scale};
    use crate::report::plot::Caption;
    use plotters::style::RGBColor;
    let (rz, a, m) = (&f.rz, &f.analysis, &f.snap_meta);
    let rr = m.intruder_radius;
    let masked = |vals: Vec<f64>| -> Vec<f64> {
        vals.into_iter()
            .zip(&a.mask)
            .map(|(v, &ok)| if ok { v } else { f64::NAN })
            .collect()
    };
    let g = masked(
        a.gamma_basic
            .iter()
            .map(|g| g.unwrap_or(f64::NAN))
            .collect(),
    );
    let gmax = g
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    fn map<'a>(rz: &RzField, m: &SnapshotMeta, rr: f64, values: &'a [f64]) -> RzMap<'a> {
        RzMap {
            nr: rz.nr,
            nz: rz.nz,
            r0: 0.0,
            z0: (rz.z0 - m.surface_z) / rr,
            spacing: rz.spacing / rr,
            values,
        }
    }
    let intruder = Some((1.0, (m.intruder_bottom_z - m.surface_z) / rr));
    // Outlines in colours neither map scale holds: yield black, the stagnant zone
    // Okabe-Ito reddish purple.
    let yield_colour = RGBColor(0, 0, 0);
    let stagnant_colour = OTHER;
    let phi_txt = match &a.phi_basic {
        Ok(p) => format!("phi = {:.2} deg", p.phi_deg),
        Err(_) => "phi undefined".to_string(),
    };
    rz_map(
        &dir.join(format!("gamma_{k:02}.svg")),
        &Caption::new(format!(
            "{}: gamma (eq 8, eq 9 stress), h = {:.3}, {phi_txt}",
            m.engine, m.h
        )),
        "gamma",
        &map(rz, m, rr, &g),
        Scale::Sequential {
            lo: 0.0,
            hi: if gmax > 0.0 { gmax } else { 1.0 },
        },
        &[
            ("yield: gamma >= 0.85 sin phi", &a.yield_basic, yield_colour),
            ("stagnant zone", &a.stagnant, stagnant_colour),
        ],
        intruder,
    )?;
    let speed = m.intruder_vz.abs();
    let vz = masked(
        rz.velocity
            .iter()
            .zip(&rz.solid_fraction)
            .map(|(v, &sf)| {
                if sf >= f.mask.min_solid_fraction {
                    v[2] / speed
                } else {
                    f64::NAN
                }
            })
            .collect(),
    );
    let lo = vz
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(-1.0, f64::min);
    let hi = vz
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.1, f64::max);
    rz_map(
        &dir.join(format!("velocity_{k:02}.svg")),
        &Caption::new(format!(
            "{}: v_z / intruder speed (eq 7), h = {:.3}",
            m.engine, m.h
        )),
        "v_z / U",
        &map(rz, m, rr, &vz),
        // Signed, and 0 (at rest) means something: diverging, centred, symmetric.
        Scale::centred(lo, hi),
        &[("stagnant zone", &a.stagnant, stagnant_colour)],
        intruder,
    )?;
    Ok(())
}

pub fn write_outputs(dir: &Path, k: usize, w: &WindowFields) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    rz_csv(&dir.join(format!("fields_{k:02}_rz.csv")), &w.avg)?;
    if let Some((grid, vals)) = &w.grid3 {
        grid3_outputs(dir, k, grid, vals, &w.avg.snap_meta)?;
    }
    svg_maps(dir, k, &w.avg)?;
    Ok(())
}
