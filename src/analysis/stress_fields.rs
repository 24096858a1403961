//! Contact snapshots of a penetration case from both engines, the
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
use crate::analysis::stress::{self, FieldAnalysis, Mask};
use crate::case::penetration::PenetrationCase;
use crate::rundata::snapshot::{self, Snapshot, SnapshotMeta};
use anyhow::{Context, Result, bail, ensure};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Azimuths sampled per ring of the (r, z) average.
pub(crate) const N_THETA: usize = 32;

/// Gaussian range w of eq 6 in grain diameters (see `analysis::coarse_grain`: cutoff
/// 3 w = the basic sphere's radius). `granval stress --kernel-width` overrides it for
/// sensitivity studies; the checks are meant to be run with this value.
pub(crate) const DEFAULT_WIDTH_OVER_D: f64 = 0.5;

/// The snapshot window of one requested depth: its steps, ascending and distinct.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WindowPlan {
    /// Requested depth (units of R).
    pub h_target: f64,
    pub steps: Vec<u64>,
    /// What the window is for, when it is not a depth window of the case (the estimator
    /// study: `null`, `convergence-N`); absent in the case's own plans.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
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
pub(crate) const PLAN_FILE: &str = "windows.json";

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
            let text = crate::rundata::fsio::read_to_string(
                &p,
                crate::rundata::fsio::MAX_RECORD_JSON,
                "a snapshot plan (JSON)",
            )?;
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
                label: None,
            });
            steps.push(m.step);
        }
        Ok(SnapshotPlan { windows, steps })
    }
}

/// What the snapshot plans and metadata need of a settled bed and of the penetration run
/// from it. The experiment layer fills it from the bed and the engine's run
/// (`experiments::penetration::bed_run`): the analysis knows no engine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BedRun {
    /// Height of the settled surface (m).
    pub surface_z: f64,
    /// The bed's solid fraction.
    pub psi: f64,
    /// Height of the intruder's bottom at step 0 (m).
    pub start_z: f64,
    /// Steps of the penetration to the final depth.
    pub n_steps: u64,
}

/// The snapshot steps of `case` run from `bed`: per window of
/// [`PenetrationCase::snapshot_windows`] the steps nearest to its depths; the last
/// depth of the last window (the final depth) is the run's last step.
pub fn snapshot_plan(case: &PenetrationCase, bed: &BedRun) -> SnapshotPlan {
    let (n, z0) = (bed.n_steps, bed.start_z);
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
            label: None,
        });
    }
    SnapshotPlan::of_windows(out)
}

impl SnapshotPlan {
    /// The plan of `windows`: the union of their steps, ascending.
    pub(crate) fn of_windows(windows: Vec<WindowPlan>) -> SnapshotPlan {
        let mut all: Vec<u64> = windows.iter().flat_map(|w| w.steps.clone()).collect();
        all.sort_unstable();
        all.dedup();
        SnapshotPlan {
            windows,
            steps: all,
        }
    }
}

/// Snapshots of the null window (docs/stress.md, "Validating the estimator", rule 1).
pub(crate) const NULL_WINDOW_SNAPSHOTS: usize = 5;
/// Snapshot counts of the convergence windows (rule 1).
pub(crate) const CONVERGENCE_COUNTS: [usize; 6] = [1, 2, 5, 10, 20, 40];
/// Intruder travel (units of R) the convergence windows spread over, ending at the
/// final depth (rule 1).
pub(crate) const CONVERGENCE_SPAN_R: f64 = 0.5;
/// Label of the null window in a study plan.
pub(crate) const NULL_LABEL: &str = "null";

/// Label of the convergence window of `n` snapshots in a study plan.
pub(crate) fn convergence_label(n: usize) -> String {
    format!("convergence-{n}")
}

/// The plan of the estimator study's extra run of a bed (docs/stress.md, rule 1):
/// - the **null window**: [`NULL_WINDOW_SNAPSHOTS`] snapshots at steps
///   round(j N / 4), j = 0..4, N = round(start_gap / 2 / (speed dt)): the first half of
///   the intruder's approach, when it touches no grain;
/// - one **convergence window** per n of [`CONVERGENCE_COUNTS`]: n snapshots evenly
///   spaced in depth over the last [`CONVERGENCE_SPAN_R`] R of travel, the last one at
///   the run's last step (n = 1: the last step alone), each at the step nearest to its
///   depth as in [`snapshot_plan`].
pub fn study_plan(case: &PenetrationCase, bed: &BedRun) -> SnapshotPlan {
    let (n, z0) = (bed.n_steps, bed.start_z);
    let per_step = case.speed * case.dt;
    let half = (case.start_gap / 2.0 / per_step).round();
    let mut null: Vec<u64> = (0..NULL_WINDOW_SNAPSHOTS)
        .map(|j| ((j as f64 * half / (NULL_WINDOW_SNAPSHOTS - 1) as f64).round() as u64).min(n))
        .collect();
    null.dedup();
    let h_of = |step: u64| (bed.surface_z - (z0 - per_step * step as f64)) / case.intruder_radius;
    let null_h = null.iter().map(|&s| h_of(s)).sum::<f64>() / null.len() as f64;
    let mut windows = vec![WindowPlan {
        h_target: null_h,
        steps: null,
        label: Some(NULL_LABEL.to_string()),
    }];
    let h_final = case.final_depth / case.intruder_radius;
    for count in CONVERGENCE_COUNTS {
        let mut steps: Vec<u64> = Vec::with_capacity(count);
        for j in 0..count {
            let step = if j + 1 == count {
                n
            } else {
                let h = h_final - CONVERGENCE_SPAN_R
                    + CONVERGENCE_SPAN_R * j as f64 / (count - 1) as f64;
                (((z0 - (bed.surface_z - h * case.intruder_radius)) / per_step)
                    .round()
                    .max(0.0) as u64)
                    .min(n)
            };
            if steps.last().is_none_or(|&s| step > s) {
                steps.push(step);
            }
        }
        windows.push(WindowPlan {
            h_target: h_final,
            steps,
            label: Some(convergence_label(count)),
        });
    }
    SnapshotPlan::of_windows(windows)
}

/// The metadata of a snapshot of `case` from `bed` at `step`, the intruder's bottom at
/// `z_bottom`.
pub fn snapshot_meta(
    case: &PenetrationCase,
    bed: &BedRun,
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

pub(crate) fn mean_std(v: &[f64]) -> (f64, f64) {
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
pub(crate) fn mean_rz(fields: &[RzField], z0: f64) -> RzField {
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
pub(crate) fn output_grid(m: &SnapshotMeta, dz: f64) -> Grid3 {
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
    window_fields_spaced(snaps, ks, width_over_d, 1.0, frame, with_grid3)
}

/// [`window_fields`] on an (r, z) grid of spacing `spacing_over_w` times the kernel
/// width w (the estimator study's grid-spacing convergence; 1 everywhere else).
pub(crate) fn window_fields_spaced(
    snaps: &[Snapshot],
    ks: &[usize],
    width_over_d: f64,
    spacing_over_w: f64,
    frame: Frame,
    with_grid3: bool,
) -> Result<WindowFields> {
    ensure!(
        spacing_over_w > 0.0 && spacing_over_w.is_finite(),
        "grid spacing factor {spacing_over_w} must be positive"
    );
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
    let spacing = params.w * spacing_over_w;
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
#[allow(clippy::type_complexity)]
pub fn analyse_engine(
    engine: &str,
    snap_dir: &Path,
    forces: Forces,
    width_over_d: f64,
    mut on_window: Option<&mut dyn FnMut(usize, &WindowFields) -> Result<()>>,
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
            on_window.is_some(),
        )?;
        drop(snaps);
        if let Some(f) = on_window.as_mut() {
            f(wi, &wf)?;
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
