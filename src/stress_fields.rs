//! Issue 4 end to end: contact snapshots of a penetration case from both engines, the
//! coarse-grained stress and velocity fields, phi from gamma (eq 8), the (phi, K_phi)
//! points against the MALT curve (eq 10), the unified FDR fit with that phi (eqs
//! 13-15), gated checks, and the outputs (CSV, VTK, SVG).
//!
//! Both engines start from the same natively prepared bed and are snapshotted at the
//! same steps. Per requested depth of `analysis.snapshot_h` (and the final depth) the
//! run takes a *window* of `analysis.snapshot_window` snapshots spread over
//! `analysis.snapshot_window_h` of intruder travel (see
//! [`crate::case::penetration::snapshot_windows`]); each snapshot is the step at which
//! the intruder's bottom is nearest to its depth, the final window ends at the last step.
//!
//! **Time averaging (eq 8's gamma "recorded at each time step").** The fields of a
//! window's snapshots are averaged *before* principal stresses, gamma, phi, the yield
//! region and the stagnant zone are computed (see [`window_fields`]). The average is
//! taken in the frame moving with the intruder: snapshot j's (r, z) grid is shifted by
//! dz_j = z_bottom,j - mean(z_bottom), so a cell sits at the same position relative to
//! the intruder's face in every snapshot. Reason: the fields that matter for phi and
//! the stagnant zone (the stress concentration and the dead cone under the face, the
//! yield band from its rim) are carried along with the intruder; averaged in the lab
//! frame they would be smeared over the window's travel (one grain diameter by
//! default), while the bed far from the intruder is quasi-static in either frame.
//! Each snapshot's own (instantaneous) phi is computed on the same shifted grid and
//! reported alongside, so the only difference between the two estimates is the
//! averaging.

use crate::analysis::coarse_grain::{
    CgParams, CoarseGrainer, Grid3, PointFields, RzField, Sym, azimuthal_average,
};
use crate::analysis::malt;
use crate::analysis::stress::{self, FieldAnalysis, Mask, principal};
use crate::case::Perturbation;
use crate::case::penetration::{PenetrationCase, Tolerances};
use crate::compare::Check;
use crate::compare::penetration::Observables;
use crate::penetration::PenetrationRun;
use crate::physics::dem::packing::Bed;
use crate::rundata::force::ForceSample;
use crate::rundata::snapshot::{self, Snapshot, SnapshotMeta};
use anyhow::{Context, Result, bail, ensure};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Azimuths sampled per ring of the (r, z) average.
pub const N_THETA: usize = 32;

/// Gaussian range w of eq 6 in grain diameters (see `analysis::coarse_grain`: cutoff
/// 3 w = the basic sphere's radius). `granval stress --kernel-width` overrides it for
/// sensitivity studies; the checks are meant to be run with this value.
pub const DEFAULT_WIDTH_OVER_D: f64 = 0.5;

/// The snapshot window of one requested depth: its steps, ascending and distinct.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WindowPlan {
    /// Requested depth (units of R).
    pub h_target: f64,
    pub steps: Vec<u64>,
}

/// Every snapshot a run takes: the windows, and the union of their steps (ascending);
/// snapshot file `k` holds step `steps[k]`. Stored as [`PLAN_FILE`] next to the
/// snapshots.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SnapshotPlan {
    pub windows: Vec<WindowPlan>,
    pub steps: Vec<u64>,
}

/// Name of the stored [`SnapshotPlan`] in a snapshot directory.
pub const PLAN_FILE: &str = "windows.json";

impl SnapshotPlan {
    /// The snapshot file number of `step`.
    pub fn index_of(&self, step: u64) -> Option<usize> {
        self.steps.binary_search(&step).ok()
    }

    /// Writes the plan into `dir` (created if missing).
    pub fn write(&self, dir: &Path) -> Result<()> {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let p = dir.join(PLAN_FILE);
        std::fs::write(&p, serde_json::to_string_pretty(self)?)
            .with_context(|| format!("cannot write {}", p.display()))
    }

    /// The plan stored in `dir`; a directory written before windows existed (no
    /// [`PLAN_FILE`]) reads as one window per snapshot.
    pub fn read(dir: &Path) -> Result<SnapshotPlan> {
        let p = dir.join(PLAN_FILE);
        if p.exists() {
            let text = std::fs::read_to_string(&p)
                .with_context(|| format!("cannot read {}", p.display()))?;
            let plan: SnapshotPlan = serde_json::from_str(&text)
                .with_context(|| format!("{}: not a snapshot plan", p.display()))?;
            let mut all: Vec<u64> = plan.windows.iter().flat_map(|w| w.steps.clone()).collect();
            all.sort_unstable();
            all.dedup();
            ensure!(
                all == plan.steps && plan.windows.iter().all(|w| !w.steps.is_empty()),
                "{}: `steps` is not the union of the windows' steps",
                p.display()
            );
            return Ok(plan);
        }
        let mut windows = Vec::new();
        let mut steps = Vec::new();
        for k in snapshot::list(dir)? {
            let m = snapshot::read_meta(dir, k)?;
            windows.push(WindowPlan {
                h_target: m.h,
                steps: vec![m.step],
            });
            steps.push(m.step);
        }
        Ok(SnapshotPlan { windows, steps })
    }
}

/// The snapshot steps of `case` run from `bed`: per window of
/// [`PenetrationCase::snapshot_windows`] the steps nearest to its depths; the last
/// depth of the last window (the final depth) is the run's last step.
pub fn snapshot_plan(case: &PenetrationCase, bed: &Bed) -> SnapshotPlan {
    let n = crate::physics::dem::penetration::n_steps(case, bed);
    let z0 = crate::physics::dem::penetration::start_z(case, bed);
    let per_step = case.speed * case.dt;
    let windows = case.snapshot_windows();
    let last = windows.len().saturating_sub(1);
    let mut out: Vec<WindowPlan> = Vec::new();
    for (wi, w) in windows.iter().enumerate() {
        let mut steps: Vec<u64> = Vec::new();
        for (j, &h) in w.h.iter().enumerate() {
            let step = if wi == last && j + 1 == w.h.len() {
                n
            } else {
                (((z0 - (bed.surface_z - h * case.intruder_radius)) / per_step)
                    .round()
                    .max(0.0) as u64)
                    .min(n)
            };
            if steps.last().is_none_or(|&s| step > s) {
                steps.push(step);
            }
        }
        out.push(WindowPlan {
            h_target: w.h_target,
            steps,
        });
    }
    let mut all: Vec<u64> = out.iter().flat_map(|w| w.steps.clone()).collect();
    all.sort_unstable();
    all.dedup();
    SnapshotPlan {
        windows: out,
        steps: all,
    }
}

/// The metadata of a snapshot of `case` from `bed` at `step`, the intruder's bottom at
/// `z_bottom`.
pub fn snapshot_meta(
    case: &PenetrationCase,
    bed: &Bed,
    engine: &str,
    step: u64,
    z_bottom: f64,
) -> SnapshotMeta {
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

/// The native penetration run with snapshots (and the plan) written to `snap_dir`.
pub fn run_native(
    case: &PenetrationCase,
    bed: &Bed,
    pert: Perturbation,
    snap_dir: &Path,
    progress: bool,
) -> Result<PenetrationRun> {
    let plan = snapshot_plan(case, bed);
    let steps = plan.steps.clone();
    let start = std::time::Instant::now();
    let total = crate::physics::dem::penetration::n_steps(case, bed);
    let bar = crate::report::progress::bar(progress, total, "native");
    let samples = crate::physics::dem::penetration::run_with_snapshots(
        case,
        bed,
        pert,
        &steps,
        |sim| {
            let k = plan
                .index_of(sim.step)
                .context("snapshot at an unplanned step")?;
            let zb = sim
                .intruder()
                .context("penetration run without intruder")?
                .body
                .bottom_z();
            let snap = sim.snapshot(snapshot_meta(case, bed, "native", sim.step, zb));
            snapshot::write(snap_dir, k, &snap)
        },
        |s, _| bar.set_position(s),
    )?;
    bar.finish_and_clear();
    plan.write(snap_dir)?;
    Ok(PenetrationRun {
        samples,
        provenance: crate::penetration::native_provenance(
            case,
            bed,
            start,
            vec![format!("snapshots at steps {steps:?}")],
        ),
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
    let steps = plan.steps.clone();
    let deck = crate::penetration::liggghts_deck(case, bed)?;
    std::fs::create_dir_all(run_dir)?;
    let (samples, mut provenance) = crate::engines::liggghts::penetration::run_with_snapshots(
        &deck,
        run_dir,
        mpi_procs,
        std::time::Duration::from_secs(4 * 3600),
        &steps,
    )?;
    provenance
        .notes
        .push(crate::physics::dem::packing::bed_note(case, bed));
    let z0 = crate::physics::dem::penetration::start_z(case, bed);
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
            meta: snapshot_meta(case, bed, "liggghts", step, zb),
            grains,
            contacts,
        };
        snapshot::write(snap_dir, k, &snap)?;
    }
    plan.write(snap_dir)?;
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

/// What one snapshot's own (instantaneous) fields gave.
#[derive(Debug, Clone, Serialize)]
pub struct SnapshotSummary {
    /// Snapshot file number.
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

/// What one window's averaged fields gave, with its snapshots' instantaneous results.
#[derive(Debug, Clone, Serialize)]
pub struct WindowSummary {
    pub window: usize,
    /// Requested depth (units of R).
    pub h_target: f64,
    /// Depth of the averaged field: the intruder at its mean bottom over the window.
    pub h: f64,
    pub steps: Vec<u64>,
    /// Window-averaged phi (gated: method `basic`, eq 9).
    pub phi_basic: Option<stress::PhiEstimate>,
    pub phi_kernel: Option<stress::PhiEstimate>,
    pub stagnant_height: f64,
    pub yield_cells: usize,
    pub error: Option<String>,
    pub instantaneous: Vec<SnapshotSummary>,
}

/// An engine's phi over its requested depths (mean and sample standard deviation):
/// window-averaged (gated) and, for comparison, over every instantaneous snapshot.
#[derive(Debug, Clone, Serialize)]
pub struct EngineFields {
    pub engine: String,
    pub windows: Vec<WindowSummary>,
    pub phi_deg: f64,
    pub phi_std_deg: f64,
    pub phi_kernel_deg: f64,
    pub phi_kernel_std_deg: f64,
    /// Mean +- sd of the instantaneous phi (eq 9) over all snapshots of all windows.
    pub phi_instant_deg: f64,
    pub phi_instant_std_deg: f64,
    pub phi_instant_kernel_deg: f64,
    pub phi_instant_kernel_std_deg: f64,
    pub mask: Option<Mask>,
    pub params: Option<CgParams>,
}

impl EngineFields {
    /// The window-averaged phi of each requested depth, NaN where it is undefined.
    pub fn phi_by_window(&self) -> Vec<f64> {
        self.windows
            .iter()
            .map(|w| w.phi_basic.as_ref().map_or(f64::NAN, |p| p.phi_deg))
            .collect()
    }
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

/// The frame a window's snapshots are averaged in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Frame {
    /// Moving with the intruder (the analysis' choice, see the module docs).
    Intruder,
    /// Fixed in the lab (diagnostics and tests only).
    Lab,
}

/// CG fields on the (r, z) plane with their analysis: one snapshot's, or a window's
/// average (then `snap_meta` places the intruder at its mean bottom over the window).
pub struct SnapshotFields {
    pub snap_meta: SnapshotMeta,
    pub params: CgParams,
    pub mask: Mask,
    pub rz: RzField,
    pub analysis: FieldAnalysis,
    pub n_contacts: usize,
    pub n_grains: usize,
}

/// A window's averaged fields, its instantaneous results and (if asked for) the
/// averaged 3D grid for the VTK/CSV outputs.
pub struct WindowFields {
    pub avg: SnapshotFields,
    pub steps: Vec<u64>,
    /// dz_j = z_bottom,j - mean z_bottom by which snapshot j's grid was shifted (0 in
    /// the lab frame).
    pub shifts: Vec<f64>,
    pub instantaneous: Vec<SnapshotSummary>,
    pub grid3: Option<(Grid3, Vec<PointFields>)>,
}

/// Running mean that is exact for identical inputs: m_j = m_{j-1} + (x_j - m_{j-1}) / j.
#[inline]
fn running(m: &mut f64, x: f64, j: usize) {
    *m += (x - *m) / j as f64;
}

fn running_sym(m: &mut Sym, x: &Sym, j: usize) {
    for q in 0..6 {
        running(&mut m[q], x[q], j);
    }
}

/// Velocity mean over the samples where it is defined (a kernel without grains has
/// none); NaN where no sample has one. `count` holds the samples averaged so far.
fn running_velocity(m: &mut [f64; 3], count: &mut usize, x: &[f64; 3]) {
    if x.iter().all(|v| v.is_finite()) {
        *count += 1;
        if *count == 1 {
            *m = *x;
        } else {
            for q in 0..3 {
                running(&mut m[q], x[q], *count);
            }
        }
    }
}

/// Cell-by-cell mean of (r, z) fields on the same cells (their own positions may be
/// shifted); the result is placed at `z0`.
// One cell index runs over six parallel arrays; iterators would hide that.
#[allow(clippy::needless_range_loop)]
fn mean_rz(fields: &[RzField], z0: f64) -> RzField {
    let first = &fields[0];
    let n = first.nr * first.nz;
    let mut out = RzField {
        spacing: first.spacing,
        nr: first.nr,
        nz: first.nz,
        z0,
        solid_fraction: vec![0.0; n],
        velocity: vec![[f64::NAN; 3]; n],
        stress_basic: vec![[0.0; 6]; n],
        stress_kernel: vec![[0.0; 6]; n],
        grains_in_basic: vec![0.0; n],
    };
    let mut vcount = vec![0usize; n];
    for (j, f) in fields.iter().enumerate() {
        for c in 0..n {
            running(&mut out.solid_fraction[c], f.solid_fraction[c], j + 1);
            running(&mut out.grains_in_basic[c], f.grains_in_basic[c], j + 1);
            running_sym(&mut out.stress_basic[c], &f.stress_basic[c], j + 1);
            running_sym(&mut out.stress_kernel[c], &f.stress_kernel[c], j + 1);
            running_velocity(&mut out.velocity[c], &mut vcount[c], &f.velocity[c]);
        }
    }
    out
}

fn mean_points(sets: &[Vec<PointFields>]) -> Vec<PointFields> {
    let n = sets[0].len();
    let mut out: Vec<PointFields> = (0..n)
        .map(|_| PointFields {
            solid_fraction: 0.0,
            velocity: [f64::NAN; 3],
            stress_basic: [0.0; 6],
            stress_kernel: [0.0; 6],
            grains_in_basic: 0,
        })
        .collect();
    let mut vcount = vec![0usize; n];
    let mut gib = vec![0.0; n];
    for (j, s) in sets.iter().enumerate() {
        for (c, p) in s.iter().enumerate() {
            let o = &mut out[c];
            running(&mut o.solid_fraction, p.solid_fraction, j + 1);
            running(&mut gib[c], p.grains_in_basic as f64, j + 1);
            running_sym(&mut o.stress_basic, &p.stress_basic, j + 1);
            running_sym(&mut o.stress_kernel, &p.stress_kernel, j + 1);
            running_velocity(&mut o.velocity, &mut vcount[c], &p.velocity);
        }
    }
    for (o, g) in out.iter_mut().zip(gib) {
        o.grains_in_basic = g.round() as u32;
    }
    out
}

/// The 3D output grid of a snapshot (spacing d_g over the container), its z shifted by
/// `dz`.
fn output_grid(m: &SnapshotMeta, dz: f64) -> Grid3 {
    let d = m.mean_diameter;
    let rc = m.container_radius;
    let n_xy = (2.0 * rc / d).ceil() as usize;
    let nz = ((m.surface_z + d - m.floor_z) / d).ceil() as usize;
    Grid3 {
        lo: [
            -0.5 * n_xy as f64 * d,
            -0.5 * n_xy as f64 * d,
            m.floor_z + dz,
        ],
        spacing: d,
        n: [n_xy, n_xy, nz],
    }
}

fn summary(k: usize, f: &SnapshotFields) -> SnapshotSummary {
    let a = &f.analysis;
    SnapshotSummary {
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
    }
}

/// Coarse-grains the snapshots of one window (common contact set) in `frame`, analyses
/// each snapshot's own field (instantaneous phi, on its shifted grid, masked in its own
/// lab position) and the window average: solid fraction, velocity (mean over the
/// snapshots where it is defined) and both stress tensors (cylindrical components)
/// averaged cell by cell, then principal stresses, gamma, phi, yield region and
/// stagnant zone from the averages. The average's mask keeps a cell only if the
/// geometric mask (floor, container wall) holds for it in every snapshot, plus the
/// solid-fraction threshold on the averaged solid fraction. `ks` are the snapshot file
/// numbers (for the summaries); `with_grid3` also averages the 3D output grid.
pub fn window_fields(
    snaps: &[Snapshot],
    ks: &[usize],
    width_over_d: f64,
    frame: Frame,
    with_grid3: bool,
) -> Result<WindowFields> {
    ensure!(!snaps.is_empty(), "a window needs at least one snapshot");
    ensure!(
        ks.len() == snaps.len(),
        "{} snapshots but {} numbers",
        snaps.len(),
        ks.len()
    );
    let m0 = &snaps[0].meta;
    for s in &snaps[1..] {
        let m = &s.meta;
        for (what, a, b) in [
            ("mean grain diameter", m.mean_diameter, m0.mean_diameter),
            ("container radius", m.container_radius, m0.container_radius),
            ("floor", m.floor_z, m0.floor_z),
            ("bed surface", m.surface_z, m0.surface_z),
            ("packing fraction", m.psi, m0.psi),
            ("intruder radius", m.intruder_radius, m0.intruder_radius),
            ("intruder velocity", m.intruder_vz, m0.intruder_vz),
        ] {
            ensure!(
                a == b,
                "snapshot steps {} and {} of one window differ in {what}: {b:e} vs {a:e}",
                m0.step,
                m.step
            );
        }
    }
    let mut zb_ref = 0.0;
    let mut t_ref = 0.0;
    for (j, s) in snaps.iter().enumerate() {
        running(&mut zb_ref, s.meta.intruder_bottom_z, j + 1);
        running(&mut t_ref, s.meta.t, j + 1);
    }
    let shifts: Vec<f64> = snaps
        .iter()
        .map(|s| match frame {
            Frame::Intruder => s.meta.intruder_bottom_z - zb_ref,
            Frame::Lab => 0.0,
        })
        .collect();
    let params = CgParams::with_width(m0.mean_diameter, width_over_d * m0.mean_diameter)?;
    let spacing = params.w;
    let max_shift = shifts.iter().fold(0.0, |a: f64, s| a.max(s.abs()));
    let nr = (m0.container_radius / spacing).ceil() as usize;
    let nz = ((m0.surface_z + m0.mean_diameter + max_shift - m0.floor_z) / spacing).ceil() as usize;
    if nr == 0 || nz == 0 {
        bail!("snapshot step {}: empty (r, z) grid", m0.step);
    }
    let mut rzs = Vec::with_capacity(snaps.len());
    let mut grids = Vec::new();
    let mut instantaneous = Vec::with_capacity(snaps.len());
    let mut d_max: f64 = 0.0;
    let (mut n_contacts, mut n_grains) = (0, 0);
    for ((s, &dz), &k) in snaps.iter().zip(&shifts).zip(ks) {
        let m = &s.meta;
        let dm = s.grains.iter().map(|g| 2.0 * g.radius).fold(0.0, f64::max);
        d_max = d_max.max(dm);
        let cg = CoarseGrainer::new(s, s.common_contacts(), params)?;
        let rz = azimuthal_average(&cg, spacing, nr, nz, m.floor_z + dz, N_THETA);
        let mask = Mask::for_bed(&params, m.psi, m.container_radius, m.floor_z, dm);
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
            n_grains: s.grains.len(),
        };
        instantaneous.push(summary(k, &f));
        n_contacts = n_contacts.max(f.n_contacts);
        n_grains = n_grains.max(f.n_grains);
        if with_grid3 {
            grids.push(cg.eval(&output_grid(m, dz).points()));
        }
        rzs.push(f.rz);
    }
    let rz = mean_rz(&rzs, m0.floor_z);
    drop(rzs);
    let base = Mask::for_bed(&params, m0.psi, m0.container_radius, m0.floor_z, d_max);
    // Cell z (reference frame) is at z + dz_j in snapshot j: above the floor limit in
    // every snapshot iff z >= z_min - min_j dz_j.
    let lowest = shifts.iter().fold(0.0, |a: f64, &s| a.min(s));
    let mask = Mask {
        z_min: base.z_min - lowest,
        ..base
    };
    let analysis = stress::analyse(&rz, &mask, zb_ref, m0.intruder_radius, m0.intruder_vz);
    let mid = snaps.len() / 2;
    let snap_meta = SnapshotMeta {
        step: snaps[mid].meta.step,
        t: t_ref,
        h: (m0.surface_z - zb_ref) / m0.intruder_radius,
        intruder_bottom_z: zb_ref,
        ..m0.clone()
    };
    let grid3 = with_grid3.then(|| (output_grid(&snap_meta, 0.0), mean_points(&grids)));
    Ok(WindowFields {
        avg: SnapshotFields {
            snap_meta,
            params,
            mask,
            rz,
            analysis,
            n_contacts,
            n_grains,
        },
        steps: snaps.iter().map(|s| s.meta.step).collect(),
        shifts,
        instantaneous,
        grid3,
    })
}

/// Analyses every window of the snapshots in `snap_dir` (one window in memory at a
/// time; the plan from [`PLAN_FILE`]); writes the window-averaged field outputs into
/// `out_dir` when given (files numbered by window).
pub fn analyse_engine(
    engine: &str,
    snap_dir: &Path,
    out_dir: Option<&Path>,
    forces: Forces,
    width_over_d: f64,
) -> Result<EngineFields> {
    let plan = SnapshotPlan::read(snap_dir)?;
    if plan.steps.is_empty() {
        bail!("{}: no snapshots (snapshot_KK.json)", snap_dir.display());
    }
    let mut out = EngineFields {
        engine: engine.to_string(),
        windows: Vec::new(),
        phi_deg: f64::NAN,
        phi_std_deg: f64::NAN,
        phi_kernel_deg: f64::NAN,
        phi_kernel_std_deg: f64::NAN,
        phi_instant_deg: f64::NAN,
        phi_instant_std_deg: f64::NAN,
        phi_instant_kernel_deg: f64::NAN,
        phi_instant_kernel_std_deg: f64::NAN,
        mask: None,
        params: None,
    };
    for (wi, w) in plan.windows.iter().enumerate() {
        let mut snaps = Vec::with_capacity(w.steps.len());
        let mut ks = Vec::with_capacity(w.steps.len());
        for &step in &w.steps {
            let k = plan.index_of(step).with_context(|| {
                format!(
                    "{}: window {wi} names step {step}, not a snapshot of the plan",
                    snap_dir.join(PLAN_FILE).display()
                )
            })?;
            let mut snap = snapshot::read(snap_dir, k)?;
            if snap.meta.step != step {
                bail!(
                    "{}: snapshot {k} holds step {}, the plan says {step}",
                    snap_dir.display(),
                    snap.meta.step
                );
            }
            if forces == Forces::NormalOnly {
                snap.drop_tangential();
            }
            snaps.push(snap);
            ks.push(k);
        }
        let wf = window_fields(
            &snaps,
            &ks,
            width_over_d,
            Frame::Intruder,
            out_dir.is_some(),
        )?;
        drop(snaps);
        if let Some(dir) = out_dir {
            write_outputs(dir, wi, &wf)?;
        }
        let a = summary(wi, &wf.avg);
        out.mask = Some(wf.avg.mask);
        out.params = Some(wf.avg.params);
        out.windows.push(WindowSummary {
            window: wi,
            h_target: w.h_target,
            h: wf.avg.snap_meta.h,
            steps: wf.steps,
            phi_basic: a.phi_basic,
            phi_kernel: a.phi_kernel,
            stagnant_height: a.stagnant_height,
            yield_cells: a.yield_cells,
            error: a.error,
            instantaneous: wf.instantaneous,
        });
    }
    let collect = |f: &dyn Fn(&WindowSummary) -> Vec<Option<stress::PhiEstimate>>| -> Vec<f64> {
        out.windows
            .iter()
            .flat_map(f)
            .flatten()
            .map(|p| p.phi_deg)
            .collect()
    };
    let b = collect(&|w| vec![w.phi_basic]);
    let kk = collect(&|w| vec![w.phi_kernel]);
    let ib = collect(&|w| w.instantaneous.iter().map(|s| s.phi_basic).collect());
    let ik = collect(&|w| w.instantaneous.iter().map(|s| s.phi_kernel).collect());
    (out.phi_deg, out.phi_std_deg) = mean_std(&b);
    (out.phi_kernel_deg, out.phi_kernel_std_deg) = mean_std(&kk);
    (out.phi_instant_deg, out.phi_instant_std_deg) = mean_std(&ib);
    (out.phi_instant_kernel_deg, out.phi_instant_kernel_std_deg) = mean_std(&ik);
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

fn write_outputs(dir: &Path, k: usize, w: &WindowFields) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    rz_csv(&dir.join(format!("fields_{k:02}_rz.csv")), &w.avg)?;
    if let Some((grid, vals)) = &w.grid3 {
        grid3_outputs(dir, k, grid, vals, &w.avg.snap_meta)?;
    }
    svg_maps(dir, k, &w.avg)?;
    Ok(())
}

/// An engine's (phi, K_phi) point with the FDR it came from.
#[derive(Debug, Clone, Serialize)]
pub struct EnginePoint {
    pub engine: String,
    /// Mean and sample sd of the window-averaged phi over every depth of every bed.
    pub phi_deg: f64,
    pub phi_std_deg: f64,
    /// The window-averaged phi of each requested depth of each bed, bed by bed (NaN
    /// where undefined): both engines snapshot the same steps of the same beds, so their
    /// difference can be taken window by window, which removes the depth-to-depth
    /// variation both share.
    pub phi_by_window: Vec<f64>,
    /// Each bed's phi (mean over its depths). The bed-by-bed difference is the honest
    /// measure of the engines' agreement: windows of one bed share its history and are
    /// not independent.
    pub phi_by_bed: Vec<f64>,
    pub k_phi: f64,
    pub k_phi_se: f64,
    /// Unified fit (eqs 13-15) with phi from the stress field: (h_A, h_B, R^2) or why not.
    pub unified: Result<(f64, f64, f64), String>,
    /// The same fit with the MALT-consistent phi(K_phi) (issue 3's regime boundaries),
    /// reported alongside, not gated here.
    #[serde(default)]
    pub unified_malt: Option<(f64, f64, f64)>,
    /// Which force-depth relation K_phi and the unified fit come from.
    pub fdr_source: String,
}

/// |phi_test - phi_ref| <= `tol.phi_abs_deg`, phi pooled over all beds' windows; the
/// detail gives the bed-by-bed and window-by-window paired differences.
pub fn phi_check(
    case: &str,
    tol: &Tolerances,
    test: &EnginePoint,
    reference: &EnginePoint,
) -> Check {
    let beds = test.phi_by_bed.len();
    let paired = |what: &str, a: &[f64], b: &[f64]| match paired_difference(a, b) {
        Some((m, se, n)) => format!(
            "; {what} by {what} over {n}: difference {m:+.2} +- {se:.2} deg (mean +- standard error)"
        ),
        None => String::new(),
    };
    let per_bed = test
        .phi_by_bed
        .iter()
        .zip(&reference.phi_by_bed)
        .map(|(a, b)| format!("{:+.2}", a - b))
        .collect::<Vec<_>>()
        .join(", ");
    Check::at_most(
        format!("{case}: phi {} vs {}", test.engine, reference.engine),
        "|phi_test - phi_ref| (deg); sin phi = mean gamma over 0.995 gamma_max <= gamma (eqs 8-9)",
        (test.phi_deg - reference.phi_deg).abs(),
        tol.phi_abs_deg,
        format!(
            "phi: {} {:.2} +- {:.2} deg, {} {:.2} +- {:.2} deg (mean +- sd over {beds} bed(s) x depths of the window-averaged phi); per bed difference [{per_bed}]{}{}",
            test.engine,
            test.phi_deg,
            test.phi_std_deg,
            reference.engine,
            reference.phi_deg,
            reference.phi_std_deg,
            paired("bed", &test.phi_by_bed, &reference.phi_by_bed),
            paired("window", &test.phi_by_window, &reference.phi_by_window),
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

/// One engine's FDR reduced to its observables, with where it came from.
pub struct FdrObservables {
    pub obs: Observables,
    pub source: String,
}

/// The observables of a single run's force samples (the stress run's own bed).
pub fn single_bed_fdr(
    case: &PenetrationCase,
    samples: &[ForceSample],
    surface_z: f64,
    psi: f64,
) -> Result<FdrObservables> {
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
    Ok(FdrObservables {
        obs: crate::compare::penetration::observables(case, &binner.fdr())?,
        source: "bed 0 only (the stress run's own FDR)".into(),
    })
}

/// Fields of a case that do not change what the engines ran (analysis settings,
/// tolerances, metadata); everything else must agree for runs to be reused.
const ANALYSIS_ONLY: [&str; 12] = [
    "name",
    "description",
    "source",
    "fit_h_min",
    "h_bin",
    "snapshot_h",
    "snapshot_window",
    "snapshot_window_h",
    "tolerances",
    "quasi_static_speed",
    "published",
    "ensemble_beds",
];

/// Errors unless `stored` describes the same runs as `case` (up to [`ANALYSIS_ONLY`]).
fn same_runs(case: &PenetrationCase, stored: &PenetrationCase, stored_path: &Path) -> Result<()> {
    let strip = |c: &PenetrationCase| -> Result<serde_json::Map<String, serde_json::Value>> {
        let mut v = match serde_json::to_value(c)? {
            serde_json::Value::Object(m) => m,
            _ => bail!("a case serialises to an object"),
        };
        for k in ANALYSIS_ONLY {
            v.remove(k);
        }
        Ok(v)
    };
    let (a, b) = (strip(case)?, strip(stored)?);
    let differ: Vec<&String> = a.keys().filter(|k| a.get(*k) != b.get(*k)).collect();
    if !differ.is_empty() {
        bail!(
            "{}: ran a different experiment than {} (fields {:?} differ)",
            stored_path.display(),
            case.source.display(),
            differ
        );
    }
    Ok(())
}

/// Both engines' ensemble-mean FDRs from the per-bed outputs `granval compare` left in
/// `dir` (the deck-directory layout: `dir/case.toml`, `dir/bed-K/` with the LIGGGHTS
/// outputs, `dir/bed-K/native/force.csv`). Every bed is reduced as `granval compare`
/// reduces it (its own surface and psi from `data.bed`); bed 0 must be the bed the
/// stress run used (`surface_z`, `psi`). Returns (native, LIGGGHTS, notes).
pub fn ensemble_fdr(
    case: &PenetrationCase,
    dir: &Path,
    surface_z: f64,
    psi: f64,
) -> Result<(FdrObservables, FdrObservables, Vec<String>)> {
    use crate::penetration::deck_dir;
    let stored_path = dir.join(deck_dir::CASE_FILE);
    let stored = PenetrationCase::load(&stored_path)
        .with_context(|| format!("--fdr-from {}", dir.display()))?;
    same_runs(case, &stored, &stored_path)?;
    let beds = deck_dir::bed_dirs(dir)?;
    ensure!(
        beds.len() == stored.ensemble_beds,
        "--fdr-from {}: {} bed directories, {} declares ensemble.beds = {}",
        dir.display(),
        beds.len(),
        stored_path.display(),
        stored.ensemble_beds
    );
    let (mut nat, mut lig, mut notes) = (Vec::new(), Vec::new(), Vec::new());
    for (k, bdir) in beds.iter().enumerate() {
        let ck = case.realisation(k);
        let bed = deck_dir::read_bed(&ck, bdir)?;
        if k == 0 {
            ensure!(
                (bed.surface_z - surface_z).abs() <= 1e-12 * surface_z.abs()
                    && (bed.psi - psi).abs() <= 1e-12,
                "--fdr-from {}: bed 0 (surface {:e} m, psi {:.6}) is not the bed of the stress run (surface {surface_z:e} m, psi {psi:.6})",
                bdir.display(),
                bed.surface_z,
                bed.psi
            );
        }
        lig.push(
            deck_dir::reduce_liggghts_dir(&ck, &bed, bdir)
                .with_context(|| format!("--fdr-from: bed {k}"))?
                .fdr,
        );
        let np = bdir.join("native").join("force.csv");
        let samples = crate::rundata::force::read_force_csv(&np)
            .with_context(|| format!("--fdr-from: native run of bed {k}"))?;
        ensure!(!samples.is_empty(), "{}: no force samples", np.display());
        let mut b = crate::penetration::binner(&ck, &bed)?;
        for s in &samples {
            b.push(s.z_bottom, s.f[2])?;
        }
        nat.push(b.fdr());
        notes.push(format!(
            "FDR bed {k}: {} (psi {:.4}), LIGGGHTS outputs and {}",
            bdir.display(),
            bed.psi,
            np.display()
        ));
    }
    let origin = format!("mean FDR of {} beds in {}", nat.len(), dir.display());
    Ok((
        mean_fdr(case, &nat, &origin)?,
        mean_fdr(case, &lig, &origin)?,
        notes,
    ))
}

/// The observables of the ensemble-mean FDR of `fdrs`, its source named `origin`.
fn mean_fdr(
    case: &PenetrationCase,
    fdrs: &[crate::analysis::fdr::Fdr],
    origin: &str,
) -> Result<FdrObservables> {
    let o = crate::compare::penetration::ensemble(case, &fdrs.iter().collect::<Vec<_>>())?;
    let source = format!(
        "{origin} (single beds K_phi {:?})",
        o.members
            .iter()
            .map(|m| (m.0 * 100.0).round() / 100.0)
            .collect::<Vec<_>>()
    );
    Ok(FdrObservables { obs: o, source })
}

/// Mean and standard error of `test - reference` over the windows where both are
/// defined; None with fewer than two such windows or different window counts.
pub fn paired_difference(test: &[f64], reference: &[f64]) -> Option<(f64, f64, usize)> {
    if test.len() != reference.len() {
        return None;
    }
    let d: Vec<f64> = test
        .iter()
        .zip(reference)
        .map(|(a, b)| a - b)
        .filter(|x| x.is_finite())
        .collect();
    (d.len() >= 2).then(|| {
        let (m, s) = mean_std(&d);
        (m, s / (d.len() as f64).sqrt(), d.len())
    })
}

/// An engine's (phi, K_phi) point: phi pooled over the stress fields of its beds, K_phi
/// and the unified fit (eqs 13-15, with that phi) from the given FDR.
pub fn engine_point(beds: &[&EngineFields], fdr: &FdrObservables) -> EnginePoint {
    let phi_by_window: Vec<f64> = beds.iter().flat_map(|f| f.phi_by_window()).collect();
    let finite: Vec<f64> = phi_by_window
        .iter()
        .copied()
        .filter(|x| x.is_finite())
        .collect();
    let (phi_deg, phi_std_deg) = mean_std(&finite);
    let obs = &fdr.obs;
    let unified = if phi_deg.is_finite() {
        let c = obs.fdr.contact_only();
        malt::fit_unified_fdr(&c.h, &c.p, obs.fit.k_phi, phi_deg.to_radians())
            .map(|(u, r2)| (u.h_a, u.h_b, r2))
            .map_err(|e| format!("{e:#}"))
    } else {
        Err("phi undefined".to_string())
    };
    EnginePoint {
        engine: beds.first().map_or(String::new(), |f| f.engine.clone()),
        phi_deg,
        phi_std_deg,
        phi_by_window,
        phi_by_bed: beds.iter().map(|f| f.phi_deg).collect(),
        k_phi: obs.fit.k_phi,
        k_phi_se: obs.fit.se_k,
        unified,
        unified_malt: obs.boundaries.as_ref().map(|b| (b.h_a, b.h_b, b.r2)),
        fdr_source: fdr.source.clone(),
    }
}

/// Everything `granval stress` produced, also written as `stress.json`.
#[derive(Debug, Serialize)]
pub struct StressReport {
    pub case: String,
    /// Every bed's fields, bed 0 first.
    pub beds: Vec<BedStress>,
    /// The engines' points, phi pooled over all beds' windows.
    pub native_point: EnginePoint,
    pub liggghts_point: EnginePoint,
    /// Negative control: native stress with tangential forces dropped, all beds.
    pub negative_control_check: Check,
    pub checks: Vec<Check>,
    pub notes: Vec<String>,
    /// Wall time of the field analysis of both engines and the negative control, all
    /// beds (s).
    pub analysis_wall_s: f64,
}

/// How `granval stress` runs.
#[derive(Debug, Clone)]
pub struct StressOptions {
    /// Re-analyse the snapshots of an earlier run in the output directory.
    pub reuse: bool,
    /// Gaussian range w of eq 6 in grain diameters.
    pub width_over_d: f64,
    /// A `granval compare` output directory of the same case: K_phi and the unified fit
    /// on its ensemble-mean FDR instead of the mean FDR of the stress run's own beds.
    pub fdr_from: Option<PathBuf>,
}

impl Default for StressOptions {
    fn default() -> Self {
        StressOptions {
            reuse: false,
            width_over_d: DEFAULT_WIDTH_OVER_D,
            fdr_from: None,
        }
    }
}

/// One bed of a stress run: both engines' fields and the negative control.
#[derive(Debug, Clone, Serialize)]
pub struct BedStress {
    /// Bed number K (seed `bed.seed + K`, directory `OUT/bed-K/`).
    pub bed: usize,
    pub seed: u64,
    pub native: EngineFields,
    pub liggghts: EngineFields,
    /// Negative control: native stress with tangential forces dropped.
    pub native_normal_only: EngineFields,
    /// The bed's surface and packing fraction, for its force-depth relation.
    pub surface_z: f64,
    pub psi: f64,
    pub n_windows: usize,
    pub n_snapshots: usize,
    /// Wall time of this bed's field analysis (both engines and the control), s.
    pub analysis_wall_s: f64,
}

/// Runs (or with `--reuse` re-reads) bed `k` of `case` into `dir` and analyses it.
fn run_bed(
    case: &PenetrationCase,
    k: usize,
    opts: &crate::pipeline::Options,
    dir: &Path,
    so: &StressOptions,
) -> Result<BedStress> {
    let nd = dir.join("native");
    let ld = dir.join("liggghts");
    let (nsnap, lsnap) = (nd.join("snapshots"), ld.join("snapshots"));
    let have = |d: &Path| {
        d.join("force.csv").exists()
            && snapshot::list(&d.join("snapshots")).is_ok_and(|v| !v.is_empty())
    };
    if !(so.reuse && have(&nd) && have(&ld)) {
        if so.reuse {
            eprintln!(
                "--reuse: no complete earlier run in {}; running both engines",
                dir.display()
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
            crate::rundata::force::write_force_csv(&d.join("force.csv"), &r.samples)?;
            crate::rundata::provenance::write_provenance(
                &d.join("provenance.json"),
                &r.provenance,
            )?;
        }
    }
    let m0 = snapshot::read_meta(&nsnap, snapshot::list(&nsnap)?[0])?;
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
    // ... and with this case's windows, identical in both engines.
    let want = case.snapshot_windows();
    let nplan = SnapshotPlan::read(&nsnap)?;
    let lplan = SnapshotPlan::read(&lsnap)?;
    if nplan != lplan {
        bail!(
            "{} and {}: the engines' snapshot plans differ; run without --reuse",
            nsnap.join(PLAN_FILE).display(),
            lsnap.join(PLAN_FILE).display()
        );
    }
    let same_windows = nplan.windows.len() == want.len()
        && nplan
            .windows
            .iter()
            .zip(&want)
            .all(|(p, w)| (p.h_target - w.h_target).abs() < 1e-9 && p.steps.len() == w.h.len());
    if !same_windows {
        bail!(
            "{}: snapshots were taken in windows {:?} (depth: steps), the case {} asks for depths {:?} with {} snapshots each; run without --reuse",
            nsnap.display(),
            nplan
                .windows
                .iter()
                .map(|w| (w.h_target, w.steps.len()))
                .collect::<Vec<_>>(),
            case.source.display(),
            want.iter().map(|w| w.h_target).collect::<Vec<_>>(),
            case.snapshot_window
        );
    }
    // Fresh field outputs: a stale file of an earlier run with more snapshots must not
    // survive next to the new ones.
    for d in [nd.join("fields"), ld.join("fields")] {
        if d.exists() {
            std::fs::remove_dir_all(&d).with_context(|| format!("cannot clear {}", d.display()))?;
        }
    }
    let w = so.width_over_d;
    let t_analysis = std::time::Instant::now();
    let mut bed = BedStress {
        bed: k,
        seed: case.seed,
        native: analyse_engine("native", &nsnap, Some(&nd.join("fields")), Forces::Full, w)?,
        liggghts: analyse_engine(
            "liggghts",
            &lsnap,
            Some(&ld.join("fields")),
            Forces::Full,
            w,
        )?,
        native_normal_only: analyse_engine(
            "native (tangential forces dropped)",
            &nsnap,
            None,
            Forces::NormalOnly,
            w,
        )?,
        surface_z: m0.surface_z,
        psi: m0.psi,
        n_windows: nplan.windows.len(),
        n_snapshots: nplan.steps.len(),
        analysis_wall_s: 0.0,
    };
    bed.analysis_wall_s = t_analysis.elapsed().as_secs_f64();
    Ok(bed)
}

/// Directory of bed `k` in a stress run's output directory.
pub fn bed_dir(out_dir: &Path, k: usize) -> PathBuf {
    out_dir.join(format!("bed-{k}"))
}

/// Both engines' mean FDR over the stress run's own beds (each reduced with its own
/// surface and psi, as `granval compare` does).
fn own_fdr(
    case: &PenetrationCase,
    out_dir: &Path,
    beds: &[BedStress],
) -> Result<(FdrObservables, FdrObservables)> {
    let mut fdrs = [Vec::new(), Vec::new()];
    for b in beds {
        for (e, fdr) in ["native", "liggghts"].iter().zip(&mut fdrs) {
            let path = bed_dir(out_dir, b.bed).join(e).join("force.csv");
            let samples = crate::rundata::force::read_force_csv(&path)?;
            ensure!(!samples.is_empty(), "{}: no force samples", path.display());
            fdr.push(single_bed_fdr(case, &samples, b.surface_z, b.psi)?.obs.fdr);
        }
    }
    let origin = format!("mean FDR of the stress run's {} bed(s)", beds.len());
    Ok((
        mean_fdr(case, &fdrs[0], &origin)?,
        mean_fdr(case, &fdrs[1], &origin)?,
    ))
}

/// Runs every bed of the case's ensemble (`[ensemble] beds`) in both engines, analyses
/// each, and checks phi pooled over the beds: at CI scale one bed's phi differs between
/// the engines by about 1.5 deg (sd over 10 beds, measured), chaos alone, so a single
/// bed cannot resolve a 1.5 deg tolerance.
pub fn run_case(
    case: &PenetrationCase,
    opts: &crate::pipeline::Options,
    out_dir: &Path,
    so: &StressOptions,
) -> Result<StressReport> {
    let beds = (0..case.ensemble_beds.max(1))
        .map(|k| {
            run_bed(&case.realisation(k), k, opts, &bed_dir(out_dir, k), so)
                .with_context(|| format!("bed {k}"))
        })
        .collect::<Result<Vec<_>>>()?;
    let b0 = &beds[0];
    let mut notes = vec![format!(
        "phi per engine: mean +- sd over {} beds x {} depths of the phi of {}-snapshot windows averaged in the intruder's frame (span {:.4} R of travel)",
        beds.len(),
        b0.n_windows,
        case.snapshot_window,
        case.snapshot_window_h,
    )];
    for b in &beds {
        notes.push(format!(
            "bed {} (seed {}): phi native {:.2} +- {:.2} deg, LIGGGHTS {:.2} +- {:.2} deg (over depths); instantaneous phi over all {} snapshots: native {:.2} +- {:.2}, LIGGGHTS {:.2} +- {:.2}",
            b.bed,
            b.seed,
            b.native.phi_deg,
            b.native.phi_std_deg,
            b.liggghts.phi_deg,
            b.liggghts.phi_std_deg,
            b.n_snapshots,
            b.native.phi_instant_deg,
            b.native.phi_instant_std_deg,
            b.liggghts.phi_instant_deg,
            b.liggghts.phi_instant_std_deg
        ));
    }
    let (nfdr, lfdr) = match &so.fdr_from {
        Some(dir) => {
            let (a, b, n) = ensemble_fdr(case, dir, b0.surface_z, b0.psi)?;
            notes.extend(n);
            (a, b)
        }
        None => {
            notes.push(
                "K_phi and the unified fit (eqs 13-15) on the mean FDR of the stress run's own beds (no --fdr-from COMPARE_DIR given)"
                    .into(),
            );
            own_fdr(case, out_dir, &beds)?
        }
    };
    let pick = |f: fn(&BedStress) -> &EngineFields| beds.iter().map(f).collect::<Vec<_>>();
    let np = engine_point(&pick(|b| &b.native), &nfdr);
    let lp = engine_point(&pick(|b| &b.liggghts), &lfdr);
    let mut checks = vec![phi_check(&case.name, &case.tolerances, &np, &lp)];
    checks.extend(malt_checks(&case.name, &case.tolerances, &np));
    checks.extend(malt_checks(&case.name, &case.tolerances, &lp));
    let negp = EnginePoint {
        unified: Err("not fitted (negative control)".into()),
        unified_malt: None,
        ..engine_point(&pick(|b| &b.native_normal_only), &nfdr)
    };
    let negative_control_check = phi_check(&case.name, &case.tolerances, &negp, &lp);
    let curve: Vec<(f64, f64)> = malt::table(45.0, 0.5)?
        .into_iter()
        .filter(|(_, k)| *k <= 2e3)
        .collect();
    use crate::report::field_svg::{KPhiPoint, k_phi_plane};
    k_phi_plane(
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
    write_phi_csv(&out_dir.join("phi_snapshots.csv"), &beds)?;
    let beds_wall: f64 = beds.iter().map(|b| b.analysis_wall_s).sum();
    let report = StressReport {
        case: case.name.clone(),
        beds,
        native_point: np,
        liggghts_point: lp,
        negative_control_check,
        checks,
        notes,
        analysis_wall_s: beds_wall,
    };
    std::fs::write(
        out_dir.join("stress.json"),
        serde_json::to_string_pretty(&report)?,
    )?;
    Ok(report)
}

/// `phi_snapshots.csv`: one row per instantaneous snapshot (`kind` = instantaneous) and
/// one per window average (`kind` = window, `k` empty, `step` the middle snapshot's).
fn write_phi_csv(path: &Path, beds: &[BedStress]) -> Result<()> {
    let mut w = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?,
    );
    writeln!(
        w,
        "bed,engine,window,h_target,kind,k,step,h,phi_basic_deg,gamma_max_basic,n_top_basic,n_cells,phi_kernel_deg,stagnant_height_over_R,yield_cells"
    )?;
    let row = |w: &mut std::io::BufWriter<std::fs::File>,
               prefix: &str,
               step: u64,
               h: f64,
               pb: Option<stress::PhiEstimate>,
               pk: Option<stress::PhiEstimate>,
               sh: f64,
               yc: usize|
     -> Result<()> {
        writeln!(
            w,
            "{prefix},{step},{h:e},{:e},{:e},{},{},{:e},{sh:e},{yc}",
            pb.map_or(f64::NAN, |p| p.phi_deg),
            pb.map_or(f64::NAN, |p| p.gamma_max),
            pb.map_or(0, |p| p.n_top),
            pb.map_or(0, |p| p.n_cells),
            pk.map_or(f64::NAN, |p| p.phi_deg),
        )?;
        Ok(())
    };
    let engines = beds
        .iter()
        .flat_map(|b| [&b.native, &b.liggghts, &b.native_normal_only].map(|e| (b.bed, e)));
    for (bed, e) in engines {
        for win in &e.windows {
            for s in &win.instantaneous {
                row(
                    &mut w,
                    &format!(
                        "{bed},{},{},{:e},instantaneous,{}",
                        e.engine, win.window, win.h_target, s.k
                    ),
                    s.step,
                    s.h,
                    s.phi_basic,
                    s.phi_kernel,
                    s.stagnant_height,
                    s.yield_cells,
                )?;
            }
            row(
                &mut w,
                &format!(
                    "{bed},{},{},{:e},window,",
                    e.engine, win.window, win.h_target
                ),
                win.steps[win.steps.len() / 2],
                win.h,
                win.phi_basic,
                win.phi_kernel,
                win.stagnant_height,
                win.yield_cells,
            )?;
        }
    }
    w.flush()?;
    Ok(())
}

/// Output paths of [`run_case`] with `beds` beds (for the CLI's summary).
pub fn output_files(out_dir: &Path, beds: usize) -> Vec<PathBuf> {
    let mut out = vec![
        out_dir.join("report.md"),
        out_dir.join("stress.json"),
        out_dir.join("phi_snapshots.csv"),
        out_dir.join("k_phi.svg"),
    ];
    for k in 0..beds {
        for e in ["native", "liggghts"] {
            out.push(bed_dir(out_dir, k).join(e).join("fields"));
        }
    }
    out
}
