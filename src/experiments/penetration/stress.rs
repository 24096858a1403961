//! The stress option of the penetration experiment (Feng et al. Sec. 2, eqs 6-15): both
//! engines' contact snapshots of every bed, taken at the same steps, coarse-grained into
//! stress and velocity fields; phi per engine, (phi, K_phi) against MALT, the unified
//! FDR fit; the negative control (tangential forces dropped) must fail the phi gate.
//! Heavy outputs (CSV, VTK, SVG per window) go under each bed's run directory.

use super::{NativeRun, RefRun, SNAPSHOT_DIR, Unit, bed_dir_name};
use crate::analysis::malt;
use crate::analysis::stress;
use crate::analysis::stress_fields::{
    DEFAULT_WIDTH_OVER_D, EngineFields, Forces, SnapshotPlan, analyse_engine, snapshot_meta,
};
use crate::case::penetration::PenetrationCase;
use crate::compare::stress::{EnginePoint, engine_point, malt_checks, mean_fdr, phi_check};
use crate::compare::{Check, Gate, Status};
use crate::engines::liggghts::penetration::PenetrationDeck;
use crate::experiments::{Options, Verdict};
use crate::physics::dem::Simulation;
use crate::physics::dem::packing::Bed;
use crate::rundata::provenance::Provenance;
use crate::rundata::snapshot::{self, Snapshot};
use anyhow::{Context, Result};
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Writes the native snapshot of `sim` into `snap_dir` (its number from the plan).
pub fn write_native_snapshot(
    case: &PenetrationCase,
    bed: &Bed,
    plan: Option<&SnapshotPlan>,
    snap_dir: &Path,
    sim: &Simulation,
) -> Result<()> {
    let Some(plan) = plan else {
        return Ok(());
    };
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
}

/// Converts the LIGGGHTS contact dumps of a finished run in `run_dir` into snapshots in
/// `run_dir/snapshots` (the same format as the native ones).
pub fn convert_liggghts_snapshots(
    case: &PenetrationCase,
    bed: &Bed,
    plan: &SnapshotPlan,
    deck: &PenetrationDeck,
    run_dir: &Path,
    provenance: &mut Provenance,
) -> Result<PathBuf> {
    let snap_dir = run_dir.join(SNAPSHOT_DIR);
    if snap_dir.exists() {
        std::fs::remove_dir_all(&snap_dir)
            .with_context(|| format!("cannot clear {}", snap_dir.display()))?;
    }
    let z0 = crate::physics::dem::penetration::start_z(case, bed);
    for (k, &step) in plan.steps.iter().enumerate() {
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
        snapshot::write(&snap_dir, k, &snap)?;
    }
    plan.write(&snap_dir)?;
    Ok(snap_dir)
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

/// Analyses one bed's snapshots of both engines (and the negative control).
fn analyse_bed(
    u: &Unit,
    native: &Path,
    liggghts: &Path,
    fields_out: &Path,
    width: f64,
) -> Result<BedStress> {
    let t = std::time::Instant::now();
    let plan = SnapshotPlan::read(native)?;
    let lplan = SnapshotPlan::read(liggghts)?;
    anyhow::ensure!(
        plan == lplan,
        "{} and {}: the engines' snapshot plans differ",
        native.display(),
        liggghts.display()
    );
    let writer = |dir: PathBuf| {
        move |wi: usize, w: &crate::analysis::stress_fields::WindowFields| {
            crate::report::stress::write_outputs(&dir, wi, w)
        }
    };
    let mut wn = writer(fields_out.join("native"));
    let mut wl = writer(fields_out.join("liggghts"));
    let mut bed = BedStress {
        bed: u.k,
        seed: u.case.seed,
        native: analyse_engine("native", native, Forces::Full, width, Some(&mut wn))?,
        liggghts: analyse_engine("liggghts", liggghts, Forces::Full, width, Some(&mut wl))?,
        native_normal_only: analyse_engine(
            "native (tangential forces dropped)",
            native,
            Forces::NormalOnly,
            width,
            None,
        )?,
        surface_z: u.bed.surface_z,
        psi: u.bed.psi,
        n_windows: plan.windows.len(),
        n_snapshots: plan.steps.len(),
        analysis_wall_s: 0.0,
    };
    bed.analysis_wall_s = t.elapsed().as_secs_f64();
    Ok(bed)
}

/// Every stress check of the case from both engines' snapshots of every bed, pooled
/// over the beds: at CI scale one bed's phi differs between the engines by about 1.5
/// deg (sd over 10 beds, measured), chaos alone, so a single bed cannot resolve a 1.5
/// deg tolerance. K_phi and the unified fit come from the same runs' mean FDRs.
pub fn checks(
    case: &PenetrationCase,
    units: &[Unit],
    native: &[NativeRun],
    reference: &[RefRun],
    out: &Path,
    opts: &Options,
) -> Verdict {
    match run_checks(case, units, native, reference, out, opts) {
        Ok(v) => v,
        Err(e) => Verdict {
            checks: vec![Check::error_in(
                format!("{}: stress fields", case.name),
                Gate::Phi,
                format!("{e:#}"),
            )],
            notes: vec![],
        },
    }
}

fn run_checks(
    case: &PenetrationCase,
    units: &[Unit],
    native: &[NativeRun],
    reference: &[RefRun],
    out: &Path,
    opts: &Options,
) -> Result<Verdict> {
    let width = opts.kernel_width.unwrap_or(DEFAULT_WIDTH_OVER_D);
    let mut beds = Vec::with_capacity(units.len());
    for ((u, n), r) in units.iter().zip(native).zip(reference) {
        let (Some(ns), Some(ls)) = (&n.snapshots, &r.snapshots) else {
            return Ok(Verdict {
                checks: vec![Check::not_compared(
                    format!("{}: phi", case.name),
                    Gate::Phi,
                    "the stress fields need contact snapshots of both engines; recorded LIGGGHTS references hold none (run with a live LIGGGHTS)",
                )],
                notes: vec![],
            });
        };
        let fields = out.join(bed_dir_name(u.k)).join("fields");
        beds.push(analyse_bed(u, ns, ls, &fields, width).with_context(|| format!("bed {}", u.k))?);
    }
    let b0 = &beds[0];
    let mut notes = vec![format!(
        "phi per engine: mean +- sd over {} beds x {} depths of the phi of {}-snapshot windows averaged in the intruder's frame (span {:.4} R of travel); kernel width w = {width} d",
        beds.len(),
        b0.n_windows,
        case.snapshot_window,
        case.snapshot_window_h,
    )];
    for b in &beds {
        notes.push(format!(
            "bed {} (seed {}): phi native {:.2} +- {:.2} deg, LIGGGHTS {:.2} +- {:.2} deg (over depths); instantaneous phi over all {} snapshots: native {:.2} +- {:.2}, LIGGGHTS {:.2} +- {:.2}; kernel method (not gated) native {:.2}, LIGGGHTS {:.2}",
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
            b.liggghts.phi_instant_std_deg,
            b.native.phi_kernel_deg,
            b.liggghts.phi_kernel_deg,
        ));
    }
    let origin = format!("mean FDR of the {} bed(s) of this run", beds.len());
    let nfdr = mean_fdr(
        case,
        &native.iter().map(|r| r.run.fdr.clone()).collect::<Vec<_>>(),
        &origin,
    )?;
    let lfdr = mean_fdr(
        case,
        &reference
            .iter()
            .map(|r| r.run.fdr.clone())
            .collect::<Vec<_>>(),
        &origin,
    )?;
    let pick = |f: fn(&BedStress) -> &EngineFields| beds.iter().map(f).collect::<Vec<_>>();
    let np = engine_point(&pick(|b| &b.native), &nfdr);
    let lp = engine_point(&pick(|b| &b.liggghts), &lfdr);
    let mut checks = vec![phi_check(&case.name, &case.tolerances, &np, &lp)];
    for c in malt_checks(&case.name, &case.tolerances, &np)
        .into_iter()
        .chain(malt_checks(&case.name, &case.tolerances, &lp))
    {
        if opts.gate_theory || !matches!(c.gate, Gate::MaltK | Gate::MaltPhi) {
            checks.push(c);
        } else {
            notes.push(format!(
                "REPORTED, not gated in this suite (theory is gated in the release suite): {} = {:.4} against {} -> would {}; {}",
                c.name,
                c.value,
                c.tolerance,
                if c.passed { "pass" } else { "FAIL" },
                c.detail
            ));
        }
    }
    let negp = EnginePoint {
        unified: Err("not fitted (negative control)".into()),
        unified_malt: None,
        ..engine_point(&pick(|b| &b.native_normal_only), &nfdr)
    };
    let neg = phi_check(&case.name, &case.tolerances, &negp, &lp);
    let bit = neg.status == Status::Fail;
    checks.push(if bit {
        Check::at_most(
            format!(
                "{}: negative control \"tangential forces dropped\"",
                case.name
            ),
            Gate::NegativeControl,
            "gates that did not fail",
            0.0,
            0.0,
            format!(
                "phi: {:.3} deg > {} deg, as it must; {}",
                neg.value, neg.tolerance, neg.detail
            ),
        )
    } else {
        Check::failed(
            format!(
                "{}: negative control \"tangential forces dropped\"",
                case.name
            ),
            Gate::NegativeControl,
            "the wrong physics passed phi",
            1.0,
            format!(
                "the control did not bite ({:?}): {}",
                neg.status, neg.detail
            ),
        )
    });
    let curve: Vec<(f64, f64)> = malt::table(45.0, 0.5)?
        .into_iter()
        .filter(|(_, k)| *k <= 2e3)
        .collect();
    use crate::report::field_svg::{KPhiPoint, k_phi_plane};
    k_phi_plane(
        &out.join("k_phi.svg"),
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
    write_phi_csv(&out.join("phi_snapshots.csv"), &beds)?;
    let analysis_wall_s: f64 = beds.iter().map(|b| b.analysis_wall_s).sum();
    notes.push(format!("wall time: field analysis {analysis_wall_s:.1} s"));
    let report = StressReport {
        case: case.name.clone(),
        beds,
        native_point: np,
        liggghts_point: lp,
        negative_control_check: neg,
        checks: checks.clone(),
        notes: notes.clone(),
        analysis_wall_s,
    };
    std::fs::write(
        out.join("stress.json"),
        serde_json::to_string_pretty(&report)?,
    )?;
    Ok(Verdict { checks, notes })
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
