//! Issue 4 end to end: contact snapshots of a penetration case from both engines, the
//! coarse-grained stress and velocity fields, phi from gamma (eq 8), the (phi, K_phi)
//! points against the MALT curve (eq 10), the unified FDR fit with that phi (eqs
//! 13-15), gated checks, and the outputs (CSV, VTK, SVG).
//!
//! Both engines start from the same natively prepared bed and are snapshotted at the
//! same steps: the steps at which the intruder's bottom reaches the case's
//! `analysis.snapshot_h` depths (nearest step) and the final step (steady state).

use crate::analysis::coarse_grain::{
    CgParams, CoarseGrainer, Grid3, PointFields, RzField, azimuthal_average,
};
use crate::analysis::malt;
use crate::analysis::stress::{self, FieldAnalysis, Mask, principal};
use crate::case::penetration::{PenetrationCase, Tolerances};
use crate::compare::Check;
use crate::dem::Perturbation;
use crate::dem::packing::Bed;
use crate::engines::output::{ForceSample, Provenance, now_utc, sha256_hex};
use crate::engines::snapshot::{self, Snapshot, SnapshotMeta};
use crate::penetration::PenetrationRun;
use anyhow::{Context, Result, bail};
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Azimuths sampled per ring of the (r, z) average.
pub const N_THETA: usize = 32;

/// Gaussian range w of eq 6 in grain diameters (see `analysis::coarse_grain`: cutoff
/// 3 w = the basic sphere's radius). `granval stress --kernel-width` overrides it for
/// sensitivity studies; the checks are meant to be run with this value.
pub const DEFAULT_WIDTH_OVER_D: f64 = 0.5;

/// One requested snapshot: target depth (units of R) and the step that reaches it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SnapshotPlan {
    pub h_target: f64,
    pub step: u64,
}

/// Steps at which the intruder's bottom is nearest to each depth of
/// `case.snapshot_h` (the last entry, the final depth, is the run's last step).
pub fn snapshot_plan(case: &PenetrationCase, bed: &Bed) -> Vec<SnapshotPlan> {
    let n = crate::dem::penetration::n_steps(case, bed);
    let z0 = crate::dem::penetration::start_z(case, bed);
    let per_step = case.speed * case.dt;
    let mut out: Vec<SnapshotPlan> = Vec::new();
    for (k, &h) in case.snapshot_h.iter().enumerate() {
        let step = if k + 1 == case.snapshot_h.len() {
            n
        } else {
            (((z0 - (bed.surface_z - h * case.intruder_radius)) / per_step).round() as u64).min(n)
        };
        if out.last().is_none_or(|p| step > p.step) {
            out.push(SnapshotPlan { h_target: h, step });
        }
    }
    out
}

fn meta(case: &PenetrationCase, bed: &Bed, engine: &str, step: u64, z_bottom: f64) -> SnapshotMeta {
    SnapshotMeta {
        engine: engine.to_string(),
        step,
        t: step as f64 * case.dt,
        h: (bed.surface_z - z_bottom) / case.intruder_radius,
        intruder_bottom_z: z_bottom,
        intruder_radius: case.intruder_radius,
        intruder_vz: -case.speed,
        surface_z: bed.surface_z,
        container_radius: case.container_radius,
        floor_z: 0.0,
        density: case.density,
        psi: bed.psi,
        mean_diameter: case.diameter.mean(),
    }
}

/// The native penetration run with snapshots written to `snap_dir`.
pub fn run_native(
    case: &PenetrationCase,
    bed: &Bed,
    pert: Perturbation,
    snap_dir: &Path,
    progress: bool,
) -> Result<PenetrationRun> {
    let plan = snapshot_plan(case, bed);
    let steps: Vec<u64> = plan.iter().map(|p| p.step).collect();
    let start = std::time::Instant::now();
    let total = crate::dem::penetration::n_steps(case, bed);
    let bar = crate::report::progress::bar(progress, total, "native");
    let samples = crate::dem::penetration::run_with_snapshots(
        case,
        bed,
        pert,
        &steps,
        |sim| {
            let k = steps
                .iter()
                .position(|&s| s == sim.step)
                .context("snapshot at an unplanned step")?;
            let zb = sim
                .intruder()
                .context("penetration run without intruder")?
                .body
                .bottom_z();
            let snap = Snapshot::from_native(sim, meta(case, bed, "native", sim.step, zb));
            snapshot::write(snap_dir, k, &snap)
        },
        |s, _| bar.set_position(s),
    )?;
    bar.finish_and_clear();
    Ok(PenetrationRun {
        samples,
        provenance: Provenance {
            engine: "native".into(),
            version: format!("granval {} native DEM", env!("CARGO_PKG_VERSION")),
            command: "in-process".into(),
            input_hash: sha256_hex(&std::fs::read(&case.source).unwrap_or_default()),
            date: now_utc(),
            wall_time_s: start.elapsed().as_secs_f64(),
            threads: rayon::current_num_threads(),
            case_file: case.source.display().to_string(),
            notes: vec![
                crate::dem::packing::bed_note(case, bed),
                format!("snapshots at steps {steps:?}"),
            ],
        },
    })
}

/// The LIGGGHTS run (from the same bed) with snapshots converted into `snap_dir`.
pub fn run_liggghts(
    case: &PenetrationCase,
    bed: &Bed,
    run_dir: &Path,
    snap_dir: &Path,
    mpi_procs: usize,
) -> Result<PenetrationRun> {
    let plan = snapshot_plan(case, bed);
    let steps: Vec<u64> = plan.iter().map(|p| p.step).collect();
    let deck = crate::penetration::liggghts_deck(case, bed)?;
    std::fs::create_dir_all(run_dir)?;
    let (samples, mut provenance) = crate::engines::liggghts::penetration::run_with_snapshots(
        &deck,
        run_dir,
        mpi_procs,
        std::time::Duration::from_secs(3600),
        &steps,
    )?;
    provenance
        .notes
        .push(crate::dem::packing::bed_note(case, bed));
    let z0 = crate::dem::penetration::start_z(case, bed);
    for (k, &step) in steps.iter().enumerate() {
        let (grains, contacts, dropped) =
            crate::engines::liggghts::snapshot::read_snapshot(run_dir, step, deck.units)?;
        if dropped > 0 {
            provenance.notes.push(format!(
                "snapshot step {step}: {dropped} grain-grain contacts reported twice (MPI ranks) kept once"
            ));
        }
        let zb = z0 - case.speed * case.dt * step as f64;
        let snap = Snapshot {
            meta: meta(case, bed, "liggghts", step, zb),
            grains,
            contacts,
        };
        snapshot::write(snap_dir, k, &snap)?;
    }
    Ok(PenetrationRun {
        samples: samples
            .iter()
            .map(|s| ForceSample {
                t: s.t,
                z_bottom: s.z_bottom,
                f: s.f,
            })
            .collect(),
        provenance,
    })
}

/// What one snapshot's fields gave.
#[derive(Debug, Clone, Serialize)]
pub struct SnapshotSummary {
    pub k: usize,
    pub step: u64,
    pub h: f64,
    pub n_grains: usize,
    pub n_contacts_used: usize,
    pub phi_basic: Option<stress::PhiEstimate>,
    pub phi_kernel: Option<stress::PhiEstimate>,
    pub stagnant_height: f64,
    pub yield_cells: usize,
    pub error: Option<String>,
}

/// An engine's phi over its snapshots (mean and sample standard deviation).
#[derive(Debug, Clone, Serialize)]
pub struct EngineFields {
    pub engine: String,
    pub snapshots: Vec<SnapshotSummary>,
    pub phi_deg: f64,
    pub phi_std_deg: f64,
    pub phi_kernel_deg: f64,
    pub phi_kernel_std_deg: f64,
    pub mask: Option<Mask>,
    pub params: Option<CgParams>,
}

fn mean_std(v: &[f64]) -> (f64, f64) {
    if v.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let m = v.iter().sum::<f64>() / v.len() as f64;
    let s = if v.len() > 1 {
        (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
    } else {
        0.0
    };
    (m, s)
}

/// How the contact forces enter the stress.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Forces {
    Full,
    /// Negative control: tangential contact forces dropped.
    NormalOnly,
}

/// The CG fields of one snapshot on the (r, z) plane, with its analysis.
pub struct SnapshotFields {
    pub snap_meta: SnapshotMeta,
    pub params: CgParams,
    pub mask: Mask,
    pub rz: RzField,
    pub analysis: FieldAnalysis,
    pub n_contacts: usize,
    pub n_grains: usize,
}

/// Coarse-grains one snapshot (common contact set) and analyses its (r, z) field.
pub fn snapshot_fields(
    snap: &Snapshot,
    width_over_d: f64,
) -> Result<(CoarseGrainer, SnapshotFields)> {
    let m = &snap.meta;
    let params = CgParams::with_width(m.mean_diameter, width_over_d * m.mean_diameter)?;
    let d_max = snap
        .grains
        .iter()
        .map(|g| 2.0 * g.radius)
        .fold(0.0, f64::max);
    let cg = CoarseGrainer::new(snap, snap.common_contacts(), params)?;
    let spacing = params.w;
    let nr = (m.container_radius / spacing).ceil() as usize;
    let nz = ((m.surface_z + m.mean_diameter - m.floor_z) / spacing).ceil() as usize;
    if nr == 0 || nz == 0 {
        bail!("snapshot step {}: empty (r, z) grid", m.step);
    }
    let rz = azimuthal_average(&cg, spacing, nr, nz, m.floor_z, N_THETA);
    let mask = Mask::for_bed(&params, m.psi, m.container_radius, m.floor_z, d_max);
    let analysis = stress::analyse(
        &rz,
        &mask,
        m.intruder_bottom_z,
        m.intruder_radius,
        m.intruder_vz,
    );
    let f = SnapshotFields {
        snap_meta: m.clone(),
        params,
        mask,
        rz,
        analysis,
        n_contacts: cg.n_contacts(),
        n_grains: snap.grains.len(),
    };
    Ok((cg, f))
}

/// Analyses every snapshot in `snap_dir`, one at a time; writes the field outputs
/// into `out_dir` when given.
pub fn analyse_engine(
    engine: &str,
    snap_dir: &Path,
    out_dir: Option<&Path>,
    forces: Forces,
    width_over_d: f64,
) -> Result<EngineFields> {
    let ks = snapshot::list(snap_dir)?;
    if ks.is_empty() {
        bail!("{}: no snapshots (snapshot_KK.json)", snap_dir.display());
    }
    let mut out = EngineFields {
        engine: engine.to_string(),
        snapshots: Vec::new(),
        phi_deg: f64::NAN,
        phi_std_deg: f64::NAN,
        phi_kernel_deg: f64::NAN,
        phi_kernel_std_deg: f64::NAN,
        mask: None,
        params: None,
    };
    for k in ks {
        let mut snap = snapshot::read(snap_dir, k)?;
        if forces == Forces::NormalOnly {
            snap.drop_tangential();
        }
        let (cg, f) = snapshot_fields(&snap, width_over_d)?;
        drop(snap);
        if let Some(dir) = out_dir {
            write_outputs(dir, k, &cg, &f)?;
        }
        out.mask = Some(f.mask);
        out.params = Some(f.params);
        let a = &f.analysis;
        out.snapshots.push(SnapshotSummary {
            k,
            step: f.snap_meta.step,
            h: f.snap_meta.h,
            n_grains: f.n_grains,
            n_contacts_used: f.n_contacts,
            phi_basic: a.phi_basic.as_ref().ok().copied(),
            phi_kernel: a.phi_kernel.as_ref().ok().copied(),
            stagnant_height: a.stagnant_height,
            yield_cells: a.yield_basic.iter().filter(|&&y| y).count(),
            error: a
                .phi_basic
                .as_ref()
                .err()
                .or(a.phi_kernel.as_ref().err())
                .cloned(),
        });
    }
    let b: Vec<f64> = out
        .snapshots
        .iter()
        .filter_map(|s| s.phi_basic.map(|p| p.phi_deg))
        .collect();
    let kk: Vec<f64> = out
        .snapshots
        .iter()
        .filter_map(|s| s.phi_kernel.map(|p| p.phi_deg))
        .collect();
    (out.phi_deg, out.phi_std_deg) = mean_std(&b);
    (out.phi_kernel_deg, out.phi_kernel_std_deg) = mean_std(&kk);
    Ok(out)
}

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

fn grid3_outputs(dir: &Path, k: usize, cg: &CoarseGrainer, m: &SnapshotMeta) -> Result<()> {
    let d = m.mean_diameter;
    let rc = m.container_radius;
    let n_xy = (2.0 * rc / d).ceil() as usize;
    let nz = ((m.surface_z + d - m.floor_z) / d).ceil() as usize;
    let grid = Grid3 {
        lo: [-0.5 * n_xy as f64 * d, -0.5 * n_xy as f64 * d, m.floor_z],
        spacing: d,
        n: [n_xy, n_xy, nz],
    };
    let pts = grid.points();
    let vals: Vec<PointFields> = cg.eval(&pts);
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
            "granval CG fields, {} step {} h = {:.4}, SI, compressive stress positive",
            m.engine, m.step, m.h
        ),
        &grid,
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
    let yellow = RGBColor(230, 170, 0);
    let green = RGBColor(0, 150, 60);
    let phi_txt = match &a.phi_basic {
        Ok(p) => format!("phi = {:.2} deg", p.phi_deg),
        Err(_) => "phi undefined".to_string(),
    };
    rz_map(
        &dir.join(format!("gamma_{k:02}.svg")),
        &format!(
            "{}: gamma (eq 8, eq 9 stress), h = {:.3}, {phi_txt}",
            m.engine, m.h
        ),
        "gamma",
        &map(rz, m, rr, &g),
        (0.0, if gmax > 0.0 { gmax } else { 1.0 }),
        &[
            ("yield: gamma >= 0.85 sin phi", &a.yield_basic, yellow),
            ("stagnant zone", &a.stagnant, green),
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
        &format!("{}: v_z / intruder speed (eq 7), h = {:.3}", m.engine, m.h),
        "v_z / U",
        &map(rz, m, rr, &vz),
        (lo, hi),
        &[("stagnant zone", &a.stagnant, green)],
        intruder,
    )?;
    Ok(())
}

fn write_outputs(dir: &Path, k: usize, cg: &CoarseGrainer, f: &SnapshotFields) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    rz_csv(&dir.join(format!("fields_{k:02}_rz.csv")), f)?;
    grid3_outputs(dir, k, cg, &f.snap_meta)?;
    svg_maps(dir, k, f)?;
    Ok(())
}

/// An engine's (phi, K_phi) point with the FDR it came from.
#[derive(Debug, Clone, Serialize)]
pub struct EnginePoint {
    pub engine: String,
    pub phi_deg: f64,
    pub phi_std_deg: f64,
    pub k_phi: f64,
    pub k_phi_se: f64,
    /// Unified fit (eqs 13-15) with phi from the stress field: (h_A, h_B, R^2) or why not.
    pub unified: Result<(f64, f64, f64), String>,
    /// The same fit with the MALT-consistent phi(K_phi) (issue 3's regime boundaries),
    /// reported alongside, not gated here.
    #[serde(default)]
    pub unified_malt: Option<(f64, f64, f64)>,
}

/// |phi_test - phi_ref| <= `tol.phi_abs_deg`.
pub fn phi_check(
    case: &str,
    tol: &Tolerances,
    test: &EnginePoint,
    reference: &EnginePoint,
) -> Check {
    Check::at_most(
        format!("{case}: phi {} vs {}", test.engine, reference.engine),
        "|phi_test - phi_ref| (deg); sin phi = mean gamma over 0.995 gamma_max <= gamma (eqs 8-9)",
        (test.phi_deg - reference.phi_deg).abs(),
        tol.phi_abs_deg,
        format!(
            "phi: {} {:.2} +- {:.2} deg, {} {:.2} +- {:.2} deg (mean +- sd over snapshots)",
            test.engine,
            test.phi_deg,
            test.phi_std_deg,
            reference.engine,
            reference.phi_deg,
            reference.phi_std_deg
        ),
    )
}

/// The (phi, K_phi) point against the MALT curve: in K and in phi, and the unified fit.
pub fn malt_checks(case: &str, tol: &Tolerances, p: &EnginePoint) -> Vec<Check> {
    let name = |w: &str| format!("{case}: {} {w}", p.engine);
    let mut out = Vec::new();
    match malt::k_phi(p.phi_deg.to_radians()) {
        Ok(q) if p.phi_deg.is_finite() => out.push(Check::at_most(
            name("MALT distance in K"),
            "|K_phi / K(phi) - 1| (eq 10)",
            (p.k_phi / q.value - 1.0).abs(),
            tol.malt_k_rel,
            format!(
                "K_phi = {:.3} +- {:.3} (FDR), K(phi = {:.2} deg) = {:.3}; K_phi / K(phi) - 1 = {:+.3}",
                p.k_phi,
                p.k_phi_se,
                p.phi_deg,
                q.value,
                p.k_phi / q.value - 1.0
            ),
        )),
        Ok(_) => out.push(Check::error(name("MALT distance in K"), "phi undefined")),
        Err(e) => out.push(Check::error(name("MALT distance in K"), format!("{e:#}"))),
    }
    match malt::phi_of_k(p.k_phi) {
        Ok(phi_k) if p.phi_deg.is_finite() => out.push(Check::at_most(
            name("MALT distance in phi"),
            "|phi(K_phi) - phi| (deg), eq 10 inverted",
            (phi_k.to_degrees() - p.phi_deg).abs(),
            tol.malt_phi_abs_deg,
            format!(
                "phi(K_phi = {:.3}) = {:.2} deg, phi from stress = {:.2} deg; difference {:+.2} deg",
                p.k_phi,
                phi_k.to_degrees(),
                p.phi_deg,
                phi_k.to_degrees() - p.phi_deg
            ),
        )),
        Ok(_) => out.push(Check::error(name("MALT distance in phi"), "phi undefined")),
        Err(e) => out.push(Check::error(name("MALT distance in phi"), format!("{e:#}"))),
    }
    out.push(match &p.unified {
        Ok((ha, hb, r2)) => Check::at_most(
            name("unified FDR fit"),
            "1 - R^2 of the unified fit, eqs 13-15 (phi from stress)",
            1.0 - r2,
            1.0 - tol.unified_r2_min,
            match p.unified_malt {
                Some((ma, mb, mr2)) => format!(
                    "R^2 = {r2:.4}, h_A = {ha:.3}, h_B = {hb:.3}; with phi(K_phi) instead: R^2 = {mr2:.4}, h_A = {ma:.3}, h_B = {mb:.3}"
                ),
                None => format!("R^2 = {r2:.4}, h_A = {ha:.3}, h_B = {hb:.3}"),
            },
        ),
        Err(e) => Check::error(name("unified FDR fit"), e.clone()),
    });
    out
}

/// Reduces an engine's FDR and phi to its (phi, K_phi) point.
pub fn engine_point(
    case: &PenetrationCase,
    fields: &EngineFields,
    samples: &[ForceSample],
    surface_z: f64,
    psi: f64,
) -> Result<EnginePoint> {
    let mut binner = crate::analysis::fdr::FdrBinner::new(
        &crate::analysis::fdr::Scales {
            rho_g: case.density,
            psi,
            g: case.gravity,
            radius: case.intruder_radius,
        },
        surface_z,
        case.h_bin,
    )?;
    for s in samples {
        binner.push(s.z_bottom, s.f[2])?;
    }
    let obs = crate::compare::penetration::observables(case, &binner.fdr())?;
    let unified = if fields.phi_deg.is_finite() {
        let c = obs.fdr.contact_only();
        malt::fit_unified_fdr(&c.h, &c.p, obs.fit.k_phi, fields.phi_deg.to_radians())
            .map(|(u, r2)| (u.h_a, u.h_b, r2))
            .map_err(|e| format!("{e:#}"))
    } else {
        Err("phi undefined".to_string())
    };
    Ok(EnginePoint {
        engine: fields.engine.clone(),
        phi_deg: fields.phi_deg,
        phi_std_deg: fields.phi_std_deg,
        k_phi: obs.fit.k_phi,
        k_phi_se: obs.fit.se_k,
        unified,
        unified_malt: obs.boundaries.as_ref().map(|b| (b.h_a, b.h_b, b.r2)),
    })
}

/// Everything `granval stress` produced, also written as `stress.json`.
#[derive(Debug, Serialize)]
pub struct StressReport {
    pub case: String,
    pub native: EngineFields,
    pub liggghts: EngineFields,
    pub native_point: EnginePoint,
    pub liggghts_point: EnginePoint,
    /// Negative control: native stress with tangential forces dropped.
    pub native_normal_only: EngineFields,
    pub negative_control_check: Check,
    pub checks: Vec<Check>,
}

/// Runs (or, with `reuse`, re-reads from `out_dir`) both engines with snapshots and
/// produces the stress/MALT checks and outputs under `out_dir`.
pub fn run_case(
    case: &PenetrationCase,
    opts: &crate::pipeline::Options,
    out_dir: &Path,
    reuse: bool,
    width_over_d: f64,
) -> Result<StressReport> {
    let nd = out_dir.join("native");
    let ld = out_dir.join("liggghts");
    let (nsnap, lsnap) = (nd.join("snapshots"), ld.join("snapshots"));
    let have = |d: &Path| {
        d.join("force.csv").exists()
            && snapshot::list(&d.join("snapshots")).is_ok_and(|v| !v.is_empty())
    };
    if !(reuse && have(&nd) && have(&ld)) {
        if reuse {
            eprintln!(
                "--reuse: no complete earlier run in {}; running both engines",
                out_dir.display()
            );
        }
        if crate::engines::liggghts::installed_version("liggghts").is_none() {
            bail!(
                "LIGGGHTS is not installed: contact snapshots need a live LIGGGHTS run (no recorded snapshots exist)"
            );
        }
        for d in [&nsnap, &lsnap] {
            if d.exists() {
                std::fs::remove_dir_all(d)
                    .with_context(|| format!("cannot clear {}", d.display()))?;
            }
        }
        let bed = crate::penetration::prepare_bed(case, opts.progress)?;
        let native = run_native(case, &bed, opts.native.perturbation, &nsnap, opts.progress)?;
        let lig = run_liggghts(case, &bed, &ld, &lsnap, opts.mpi_procs.max(2))?;
        for (d, r) in [(&nd, &native), (&ld, &lig)] {
            crate::penetration::write_force_csv(&d.join("force.csv"), &r.samples)?;
            crate::engines::output::write_provenance(&d.join("provenance.json"), &r.provenance)?;
        }
    }
    let m0 = snapshot::read(&nsnap, snapshot::list(&nsnap)?[0])?.meta;
    // A reused directory must hold a run of this case, not of another one.
    for (what, stored, now) in [
        ("intruder radius", m0.intruder_radius, case.intruder_radius),
        (
            "container radius",
            m0.container_radius,
            case.container_radius,
        ),
        ("grain density", m0.density, case.density),
        (
            "mean grain diameter",
            m0.mean_diameter,
            case.diameter.mean(),
        ),
        ("intruder speed", -m0.intruder_vz, case.speed),
    ] {
        if (stored - now).abs() > 1e-12 * now.abs() {
            bail!(
                "{}: snapshots were taken with {what} = {stored:e}, the case {} has {now:e}; run without --reuse",
                nsnap.display(),
                case.source.display()
            );
        }
    }
    // Fresh field outputs: a stale file of an earlier run with more snapshots must not
    // survive next to the new ones.
    for d in [nd.join("fields"), ld.join("fields")] {
        if d.exists() {
            std::fs::remove_dir_all(&d).with_context(|| format!("cannot clear {}", d.display()))?;
        }
    }
    let w = width_over_d;
    let nf = analyse_engine("native", &nsnap, Some(&nd.join("fields")), Forces::Full, w)?;
    let lf = analyse_engine(
        "liggghts",
        &lsnap,
        Some(&ld.join("fields")),
        Forces::Full,
        w,
    )?;
    let neg = analyse_engine(
        "native (tangential forces dropped)",
        &nsnap,
        None,
        Forces::NormalOnly,
        w,
    )?;
    let read = |d: &Path| crate::penetration::read_force_csv(&d.join("force.csv"));
    let np = engine_point(case, &nf, &read(&nd)?, m0.surface_z, m0.psi)?;
    let lp = engine_point(case, &lf, &read(&ld)?, m0.surface_z, m0.psi)?;
    let mut checks = vec![phi_check(&case.name, &case.tolerances, &np, &lp)];
    checks.extend(malt_checks(&case.name, &case.tolerances, &np));
    checks.extend(malt_checks(&case.name, &case.tolerances, &lp));
    let negp = EnginePoint {
        engine: neg.engine.clone(),
        phi_deg: neg.phi_deg,
        phi_std_deg: neg.phi_std_deg,
        k_phi: np.k_phi,
        k_phi_se: np.k_phi_se,
        unified: Err("not fitted (negative control)".into()),
        unified_malt: None,
    };
    let negative_control_check = phi_check(&case.name, &case.tolerances, &negp, &lp);
    let curve: Vec<(f64, f64)> = malt::table(45.0, 0.5)?
        .into_iter()
        .filter(|(_, k)| *k <= 2e3)
        .collect();
    use crate::report::field_svg::{KPhiPoint, k_phi_plane_with_errors};
    k_phi_plane_with_errors(
        &out_dir.join("k_phi.svg"),
        &curve,
        &[
            KPhiPoint {
                label: "native",
                phi_deg: np.phi_deg,
                phi_err: np.phi_std_deg,
                k: np.k_phi,
                k_err: np.k_phi_se,
            },
            KPhiPoint {
                label: "LIGGGHTS",
                phi_deg: lp.phi_deg,
                phi_err: lp.phi_std_deg,
                k: lp.k_phi,
                k_err: lp.k_phi_se,
            },
            KPhiPoint {
                label: "Feng et al. Table 3",
                phi_deg: malt::phi_of_k(23.00)?.to_degrees(),
                phi_err: 0.0,
                k: 23.00,
                k_err: 0.15,
            },
        ],
    )?;
    let mut w = std::io::BufWriter::new(std::fs::File::create(out_dir.join("phi_snapshots.csv"))?);
    writeln!(
        w,
        "engine,k,step,h,phi_basic_deg,gamma_max_basic,n_top_basic,n_cells,phi_kernel_deg,stagnant_height_over_R,yield_cells"
    )?;
    for e in [&nf, &lf, &neg] {
        for s in &e.snapshots {
            let pb = s.phi_basic.map_or(f64::NAN, |p| p.phi_deg);
            let gm = s.phi_basic.map_or(f64::NAN, |p| p.gamma_max);
            let nt = s.phi_basic.map_or(0, |p| p.n_top);
            let nc = s.phi_basic.map_or(0, |p| p.n_cells);
            let pk = s.phi_kernel.map_or(f64::NAN, |p| p.phi_deg);
            writeln!(
                w,
                "{},{},{},{:e},{:e},{:e},{},{},{:e},{:e},{}",
                e.engine, s.k, s.step, s.h, pb, gm, nt, nc, pk, s.stagnant_height, s.yield_cells
            )?;
        }
    }
    w.flush()?;
    let report = StressReport {
        case: case.name.clone(),
        native: nf,
        liggghts: lf,
        native_point: np,
        liggghts_point: lp,
        native_normal_only: neg,
        negative_control_check,
        checks,
    };
    std::fs::write(
        out_dir.join("stress.json"),
        serde_json::to_string_pretty(&report)?,
    )?;
    Ok(report)
}

/// Output paths of [`run_case`] (for the CLI's summary).
pub fn output_files(out_dir: &Path) -> Vec<PathBuf> {
    vec![
        out_dir.join("report.md"),
        out_dir.join("stress.json"),
        out_dir.join("phi_snapshots.csv"),
        out_dir.join("k_phi.svg"),
        out_dir.join("native/fields"),
        out_dir.join("liggghts/fields"),
    ]
}
