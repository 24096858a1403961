//! The estimator study of docs/stress.md ("Validating the estimator", rule 1, and "How
//! the pre-registration is read"): estimator v1 run unchanged on windows where its
//! answer is known or should not move.
//!
//! - **Null window**: the settled bed before the intruder touches it. Nothing yields
//!   there, so a sound estimator reads far below the material's phi; v1 is "unfit"
//!   when it reads within 5 deg of its own penetration phi.
//! - **Janssen**: sigma_zz near the axis of that same bed against the hydrostatic
//!   rho_g psi g (z_surface - z); wall friction carries part of the weight (Janssen), and
//!   eq 9's tensor is about 0.3 of the true stress by construction (docs/stress.md,
//!   Conventions), so both tensors are reported.
//! - **Convergence**: phi of the final state as the number of averaged snapshots (1-40)
//!   and the grid spacing (w / 2, w, 2 w) change, where gamma_max sits and how many
//!   grains the band's cells hold. A material constant does not move with either.
//!
//! Everything here is reported, never gated (rule 1).

use super::stress::TOP_FRACTION;
use super::stress_fields::{
    CONVERGENCE_COUNTS, Frame, N_THETA, NULL_LABEL, SnapshotPlan, WindowFields, convergence_label,
    window_fields_spaced,
};
use crate::rundata::snapshot::{self, Snapshot};
use anyhow::{Context, Result, bail};
use serde::Serialize;
use std::path::Path;

/// Grid spacings of the convergence study, in units of the kernel width w (rule 1).
pub(crate) const SPACINGS: [f64; 3] = [1.0, 0.5, 2.0];
/// v1 is "unfit" when its null-window phi is within this of its penetration phi (deg).
pub(crate) const UNFIT_MARGIN_DEG: f64 = 5.0;
/// Janssen slabs are this many mean grain diameters thick (rule 1).
pub(crate) const SLAB_D: f64 = 2.0;

/// v1 on one window of the study.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct StudyWindow {
    pub label: String,
    pub n_snapshots: usize,
    pub spacing_over_w: f64,
    pub phi_deg: Option<f64>,
    pub gamma_max: Option<f64>,
    /// gamma_max's cell: r / R and depth below the intruder's face / R.
    pub gamma_max_r: Option<f64>,
    pub gamma_max_depth: Option<f64>,
    /// Cells of the 0.995 band and masked cells.
    pub n_top: usize,
    pub n_cells: usize,
    /// Mean gamma over all masked cells.
    pub mean_gamma: Option<f64>,
    /// Eq 9's count of grains fully inside the basic sphere, at gamma_max's cell and
    /// averaged over the band.
    pub grains_in_basic_at_max: Option<f64>,
    pub grains_in_basic_band: Option<f64>,
    /// Grain centres within 1.5 d_g of the cell's 32 sample points (azimuthal and
    /// snapshot mean), at gamma_max's cell and averaged over the band.
    pub centres_at_max: Option<f64>,
    pub centres_band: Option<f64>,
    pub error: Option<String>,
}

/// One slab of the Janssen check.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct JanssenSlab {
    /// Ring-area weighted mean height of the slab's cells (m) and its depth below the
    /// surface (m).
    pub z: f64,
    pub depth: f64,
    pub cells: usize,
    /// sigma_zz of eq 9 and of the kernel contact stress (Pa), r-weighted.
    pub szz_basic: f64,
    pub szz_kernel: f64,
    /// rho_g psi g (z_surface - z) (Pa).
    pub hydrostatic: f64,
}

/// The study of one bed in one engine.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct BedStudy {
    pub engine: String,
    pub bed: usize,
    pub null: StudyWindow,
    pub janssen: Vec<JanssenSlab>,
    pub convergence: Vec<StudyWindow>,
}

fn read_window(
    dir: &Path,
    plan: &SnapshotPlan,
    label: &str,
) -> Result<(Vec<Snapshot>, Vec<usize>)> {
    let w = plan
        .windows
        .iter()
        .find(|w| w.label.as_deref() == Some(label))
        .with_context(|| format!("{}: no window `{label}` in the study plan", dir.display()))?;
    let mut snaps = Vec::new();
    let mut ks = Vec::new();
    for &step in &w.steps {
        let k = plan
            .index_of(step)
            .with_context(|| format!("{}: step {step} not in the plan", dir.display()))?;
        let s = snapshot::read(dir, k)?;
        if s.meta.step != step {
            bail!(
                "{}: snapshot {k} holds step {}, not {step}",
                dir.display(),
                s.meta.step
            );
        }
        snaps.push(s);
        ks.push(k);
    }
    Ok((snaps, ks))
}

/// Grain centres within 1.5 d of the 32 azimuthal sample points of the ring (r, z)
/// (reference frame), mean over azimuths and the window's snapshots (each shifted by
/// its dz).
fn centres_near(snaps: &[Snapshot], shifts: &[f64], r: f64, z: f64, d: f64) -> f64 {
    let reach2 = (1.5 * d) * (1.5 * d);
    let mut total = 0.0;
    for (s, &dz) in snaps.iter().zip(shifts) {
        let zc = z + dz;
        let near: Vec<&snapshot::Grain> = s
            .grains
            .iter()
            .filter(|g| (g.x[2] - zc).abs() <= 1.5 * d)
            .collect();
        for t in 0..N_THETA {
            let th = 2.0 * std::f64::consts::PI * (t as f64 + 0.5) / N_THETA as f64;
            let p = [r * th.cos(), r * th.sin(), zc];
            total += near
                .iter()
                .filter(|g| {
                    let dx = [g.x[0] - p[0], g.x[1] - p[1], g.x[2] - p[2]];
                    dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2] <= reach2
                })
                .count() as f64;
        }
    }
    total / (N_THETA * snaps.len()) as f64
}

fn summarise(label: &str, spacing: f64, snaps: &[Snapshot], w: &WindowFields) -> StudyWindow {
    let a = &w.avg.analysis;
    let rz = &w.avg.rz;
    let m = &w.avg.snap_meta;
    let masked: Vec<usize> = (0..a.mask.len())
        .filter(|&c| a.mask[c] && a.gamma_basic[c].is_some())
        .collect();
    let mean_gamma = (!masked.is_empty()).then(|| {
        masked.iter().filter_map(|&c| a.gamma_basic[c]).sum::<f64>() / masked.len() as f64
    });
    let mut out = StudyWindow {
        label: label.to_string(),
        n_snapshots: snaps.len(),
        spacing_over_w: spacing,
        phi_deg: None,
        gamma_max: None,
        gamma_max_r: None,
        gamma_max_depth: None,
        n_top: 0,
        n_cells: masked.len(),
        mean_gamma,
        grains_in_basic_at_max: None,
        grains_in_basic_band: None,
        centres_at_max: None,
        centres_band: None,
        error: None,
    };
    match &a.phi_basic {
        Ok(p) => {
            let gmax = p.gamma_max;
            let arg = masked
                .iter()
                .copied()
                .find(|&c| a.gamma_basic[c] == Some(gmax))
                .unwrap_or(masked[0]);
            let band: Vec<usize> = masked
                .iter()
                .copied()
                .filter(|&c| a.gamma_basic[c].is_some_and(|g| g >= TOP_FRACTION * gmax))
                .collect();
            let at = |c: usize| (rz.r(c % rz.nr), rz.z(c / rz.nr));
            let (r, z) = at(arg);
            let d = m.mean_diameter;
            out.phi_deg = Some(p.phi_deg);
            out.gamma_max = Some(gmax);
            out.gamma_max_r = Some(r / m.intruder_radius);
            out.gamma_max_depth = Some((m.intruder_bottom_z - z) / m.intruder_radius);
            out.n_top = p.n_top;
            out.grains_in_basic_at_max = Some(rz.grains_in_basic[arg]);
            out.grains_in_basic_band =
                Some(band.iter().map(|&c| rz.grains_in_basic[c]).sum::<f64>() / band.len() as f64);
            out.centres_at_max = Some(centres_near(snaps, &w.shifts, r, z, d));
            out.centres_band = Some(
                band.iter()
                    .map(|&c| {
                        let (r, z) = at(c);
                        centres_near(snaps, &w.shifts, r, z, d)
                    })
                    .sum::<f64>()
                    / band.len() as f64,
            );
        }
        Err(e) => out.error = Some(e.clone()),
    }
    out
}

/// The Janssen profile of a (null-window) average: cells with r < R_c / 2 through the
/// v1 mask, r-weighted, in slabs of [`SLAB_D`] d_g from the floor up.
fn janssen(w: &WindowFields, gravity: f64) -> Vec<JanssenSlab> {
    let rz = &w.avg.rz;
    let m = &w.avg.snap_meta;
    let a = &w.avg.analysis;
    let slab = SLAB_D * m.mean_diameter;
    let n_slabs = ((m.surface_z - m.floor_z) / slab).ceil() as usize;
    let mut out = Vec::new();
    for s in 0..n_slabs {
        let (lo, hi) = (
            m.floor_z + s as f64 * slab,
            m.floor_z + (s + 1) as f64 * slab,
        );
        let (mut wsum, mut zs, mut sb, mut sk, mut n) = (0.0, 0.0, 0.0, 0.0, 0);
        for k in 0..rz.nz {
            let z = rz.z(k);
            if z < lo || z >= hi {
                continue;
            }
            for i in 0..rz.nr {
                let c = rz.idx(i, k);
                if rz.r(i) >= 0.5 * m.container_radius || !a.mask[c] {
                    continue;
                }
                let wt = rz.r(i);
                wsum += wt;
                zs += wt * z;
                sb += wt * rz.stress_basic[c][2];
                sk += wt * rz.stress_kernel[c][2];
                n += 1;
            }
        }
        if n == 0 {
            continue;
        }
        let z = zs / wsum;
        out.push(JanssenSlab {
            z,
            depth: m.surface_z - z,
            cells: n,
            szz_basic: sb / wsum,
            szz_kernel: sk / wsum,
            hydrostatic: m.density * m.psi * gravity * (m.surface_z - z),
        });
    }
    out
}

/// The study of one bed's extra run in one engine (`dir`: its snapshots with the study
/// plan), kernel width `width` (w / d_g).
pub(crate) fn study_bed(
    engine: &str,
    bed: usize,
    dir: &Path,
    gravity: f64,
    width: f64,
) -> Result<BedStudy> {
    let plan = SnapshotPlan::read(dir)?;
    let (snaps, ks) = read_window(dir, &plan, NULL_LABEL)?;
    let w = window_fields_spaced(&snaps, &ks, width, 1.0, Frame::Intruder, false)?;
    let null = summarise(NULL_LABEL, 1.0, &snaps, &w);
    let janssen = janssen(&w, gravity);
    let mut convergence = Vec::new();
    for n in CONVERGENCE_COUNTS {
        let label = convergence_label(n);
        let (snaps, ks) = read_window(dir, &plan, &label)?;
        for sp in SPACINGS {
            let w = window_fields_spaced(&snaps, &ks, width, sp, Frame::Intruder, false)
                .with_context(|| format!("{engine} bed {bed}: {label}, spacing {sp} w"))?;
            convergence.push(summarise(&label, sp, &snaps, &w));
        }
    }
    Ok(BedStudy {
        engine: engine.to_string(),
        bed,
        null,
        janssen,
        convergence,
    })
}

/// Rule 1's verdict on v1 for one engine: the mean over beds of the null-window phi
/// against the engine's pooled v1 phi of the penetration windows.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct NullVerdict {
    pub engine: String,
    pub phi_null_deg: f64,
    pub phi_penetration_deg: f64,
    pub mean_gamma_null: f64,
    /// phi_null > phi_penetration - 5 deg.
    pub unfit: bool,
}

pub(crate) fn null_verdict(
    engine: &str,
    beds: &[&BedStudy],
    phi_penetration_deg: f64,
) -> NullVerdict {
    let phis: Vec<f64> = beds.iter().filter_map(|b| b.null.phi_deg).collect();
    let gs: Vec<f64> = beds.iter().filter_map(|b| b.null.mean_gamma).collect();
    let mean = |v: &[f64]| {
        if v.is_empty() {
            f64::NAN
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    };
    let phi_null_deg = mean(&phis);
    NullVerdict {
        engine: engine.to_string(),
        phi_null_deg,
        phi_penetration_deg,
        mean_gamma_null: mean(&gs),
        // NaN (no null phi) counts as unfit: the test could not be passed.
        unfit: phi_null_deg.is_nan() || phi_null_deg > phi_penetration_deg - UNFIT_MARGIN_DEG,
    }
}

/// `study_convergence.csv` and `study_janssen.csv` of all beds and engines.
pub(crate) fn write_csvs(out: &Path, studies: &[BedStudy]) -> Result<()> {
    let mut w = csv::Writer::from_path(out.join("study_convergence.csv"))?;
    w.write_record([
        "engine",
        "bed",
        "window",
        "snapshots",
        "spacing_over_w",
        "phi_deg",
        "gamma_max",
        "gamma_max_r_over_R",
        "gamma_max_depth_over_R",
        "n_top",
        "n_cells",
        "mean_gamma",
        "grains_in_basic_at_max",
        "grains_in_basic_band",
        "centres_at_max",
        "centres_band",
    ])?;
    let o = |x: Option<f64>| x.map_or(String::new(), |v| format!("{v:.6}"));
    for s in studies {
        for c in std::iter::once(&s.null).chain(&s.convergence) {
            w.write_record([
                s.engine.clone(),
                s.bed.to_string(),
                c.label.clone(),
                c.n_snapshots.to_string(),
                c.spacing_over_w.to_string(),
                o(c.phi_deg),
                o(c.gamma_max),
                o(c.gamma_max_r),
                o(c.gamma_max_depth),
                c.n_top.to_string(),
                c.n_cells.to_string(),
                o(c.mean_gamma),
                o(c.grains_in_basic_at_max),
                o(c.grains_in_basic_band),
                o(c.centres_at_max),
                o(c.centres_band),
            ])?;
        }
    }
    w.flush()?;
    let mut w = csv::Writer::from_path(out.join("study_janssen.csv"))?;
    w.write_record([
        "engine",
        "bed",
        "z_m",
        "depth_m",
        "cells",
        "szz_basic_pa",
        "szz_kernel_pa",
        "hydrostatic_pa",
        "basic_over_hydrostatic",
        "kernel_over_hydrostatic",
    ])?;
    for s in studies {
        for j in &s.janssen {
            w.write_record([
                s.engine.clone(),
                s.bed.to_string(),
                format!("{:.6e}", j.z),
                format!("{:.6e}", j.depth),
                j.cells.to_string(),
                format!("{:.6e}", j.szz_basic),
                format!("{:.6e}", j.szz_kernel),
                format!("{:.6e}", j.hydrostatic),
                format!("{:.4}", j.szz_basic / j.hydrostatic),
                format!("{:.4}", j.szz_kernel / j.hydrostatic),
            ])?;
        }
    }
    w.flush()?;
    Ok(())
}

/// The study's one-line summary per engine for the report.
pub fn text(v: &NullVerdict, beds: &[&BedStudy]) -> String {
    let conv: Vec<String> = crate::analysis::stress_fields::CONVERGENCE_COUNTS
        .iter()
        .map(|&n| {
            let l = convergence_label(n);
            let phis: Vec<f64> = beds
                .iter()
                .flat_map(|b| b.convergence.iter())
                .filter(|c| c.label == l && c.spacing_over_w == 1.0)
                .filter_map(|c| c.phi_deg)
                .collect();
            if phis.is_empty() {
                format!("{n}: undefined")
            } else {
                format!("{n}: {:.1}", phis.iter().sum::<f64>() / phis.len() as f64)
            }
        })
        .collect();
    format!(
        "estimator study ({}, v1, reported): null-window phi {:.2} deg (mean over {} beds; mean gamma {:.3}) vs penetration phi {:.2} deg -> v1 {}; final-state phi vs snapshots averaged (mean over beds, spacing w) [{}]",
        v.engine,
        v.phi_null_deg,
        beds.len(),
        v.mean_gamma_null,
        v.phi_penetration_deg,
        if v.unfit {
            "UNFIT (reads within 5 deg of its penetration phi where nothing yields)"
        } else {
            "passes the null test"
        },
        conv.join(", ")
    )
}
