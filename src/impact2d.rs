//! The 2D impact experiment end to end (issue 5): bed preparation (native), one scene
//! per sweep variant, the native run and the LAMMPS run (live, or recorded under
//! `reference/impact2d/<case>/<variant>/` for this very scene), observables, checks.

use crate::analysis::impact::{self as obs, EnergyModel, EnergySample, IntruderSample};
use crate::case::impact2d::{Impact2dCase, Variant};
use crate::compare::Check;
use crate::compare::impact2d::{self as cmp, VariantObs};
use crate::engines::lammps::{self, Lammps};
use crate::physics::dem2d::bed::{self, Bed, Packing};
use crate::physics::dem2d::impact::{self as scene_mod, Scene};
use crate::rundata::provenance::{
    Provenance, now_utc, read_provenance, sha256_hex, write_provenance,
};
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// A deliberately wrong native engine for negative controls.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Tweak {
    #[default]
    None,
    /// Static <-> kinetic friction model (k_t = 0.8 k_n <-> 0) in every native contact.
    SwapFriction,
}

pub struct Run {
    pub samples: Vec<IntruderSample>,
    pub energy: Vec<EnergySample>,
    pub provenance: Provenance,
}

/// The beds a case needs, one per packing, in first-use order.
pub struct Beds {
    pub beds: Vec<(Packing, Bed)>,
}

impl Beds {
    pub fn get(&self, p: Packing) -> &Bed {
        &self
            .beds
            .iter()
            .find(|b| b.0 == p)
            .expect("bed prepared for every packing")
            .1
    }
}

pub fn bed_note(case: &Impact2dCase, p: Packing, b: &Bed) -> String {
    let s = &case.scales;
    format!(
        "{} bed ({:?}): {} grains ({} removed by smoothing), settled in {:.0} tau_c to total KE {:.2e} m g d, packing fraction {:.3}, surface at {:.2} d above the floor",
        case.name,
        p,
        b.grains.len(),
        b.removed,
        b.settle_time / s.tau_c,
        b.final_ke / (s.m * s.g0 * s.d),
        b.packing_fraction,
        (b.surface_at(0.5 * case.length, case.length) - b.floor) / s.d
    )
}

/// Beds already prepared in this process, by sha256 of their specification:
/// preparation is deterministic, so cases sharing a bed (a test binary running the
/// CI cases) settle it once.
type BedSlot = std::sync::Arc<std::sync::Mutex<Option<Bed>>>;
static BED_MEMO: std::sync::Mutex<std::collections::BTreeMap<String, BedSlot>> =
    std::sync::Mutex::new(std::collections::BTreeMap::new());

/// Opt-in cache of prepared beds (settling a 6000-disk bed to 1e-10 m g d takes
/// minutes): only when `GRANVAL_BED_CACHE=DIR` is set, one JSON file per bed
/// specification (sha256 of the spec and the crate version). Preparation is
/// deterministic, so a hit is the bed that would be prepared; tests never set it.
fn cache_file(spec: &bed::BedSpec) -> Option<PathBuf> {
    let dir = std::env::var_os("GRANVAL_BED_CACHE")?;
    let key = sha256_hex(
        format!(
            "{} {}",
            env!("CARGO_PKG_VERSION"),
            serde_json::to_string(spec).ok()?
        )
        .as_bytes(),
    );
    Some(PathBuf::from(dir).join(format!("impact2d-bed-{key}.json")))
}

pub fn prepare_beds(case: &Impact2dCase, progress: bool) -> Result<Beds> {
    let mut beds: Vec<(Packing, Bed)> = Vec::new();
    for v in &case.variants {
        if beds.iter().any(|b| b.0 == v.packing) {
            continue;
        }
        let spec = scene_mod::bed_spec(case, v.packing);
        let key = sha256_hex(serde_json::to_string(&spec).unwrap_or_default().as_bytes());
        let slot = {
            let mut memo = BED_MEMO.lock().unwrap_or_else(|p| p.into_inner());
            memo.entry(key).or_default().clone()
        };
        // Held while preparing, so a second case needing this bed waits for it.
        let mut slot = slot.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(b) = slot.as_ref() {
            beds.push((v.packing, b.clone()));
            continue;
        }
        let cache = cache_file(&spec);
        let cached = cache
            .as_ref()
            .and_then(|p| std::fs::read(p).ok())
            .and_then(|t| serde_json::from_slice::<Bed>(&t).ok());
        let b = match cached {
            Some(b) => b,
            None => {
                let bar = crate::report::progress::bar(progress, 1, "settle");
                let scale = case.scales.m * case.scales.g0 * case.scales.d;
                let tau = case.scales.tau_c;
                let b = bed::prepare(&spec, |t, ke| {
                    bar.set_message(format!(
                        "t = {:.0} tau_c, KE = {:.1e} m g d",
                        t / tau,
                        ke / scale
                    ))
                })
                .with_context(|| {
                    format!(
                        "{}: preparing the {:?} bed",
                        case.source.display(),
                        v.packing
                    )
                })?;
                bar.finish_and_clear();
                if let Some(path) = &cache {
                    let _ = std::fs::create_dir_all(path.parent().unwrap_or(Path::new(".")));
                    let _ = std::fs::write(path, serde_json::to_vec(&b).unwrap_or_default());
                }
                b
            }
        };
        *slot = Some(b.clone());
        beds.push((v.packing, b));
    }
    Ok(Beds { beds })
}

pub fn scene(case: &Impact2dCase, v: &Variant, beds: &Beds) -> Result<Scene> {
    scene_mod::build(case, v, beds.get(v.packing))
}

/// The scene the native engine runs: the shared scene, made wrong on purpose for a
/// negative control (the reference engine always gets the untouched scene).
pub fn native_scene(scene: &Scene, tweak: Tweak) -> Scene {
    let mut s = scene.clone();
    if tweak == Tweak::SwapFriction {
        for c in &mut s.sys.coeffs {
            c.kt = if c.kt > 0.0 { 0.0 } else { 0.8 * c.kn };
        }
    }
    s
}

/// Energies: walls frozen; wall-wall and (cluster) intruder-intruder pairs excluded.
pub fn energy_model(scene: &Scene) -> EnergyModel {
    let n = scene.sys.n_types;
    let cluster = scene.sys.cluster.is_some();
    let mut kn = Vec::with_capacity(n * n);
    for a in 0..n {
        for b in 0..n {
            let off = (a == 1 && b == 1) || (cluster && a == 2 && b == 2);
            kn.push((!off).then_some(scene.sys.coeffs[a * n + b].kn));
        }
    }
    EnergyModel {
        n_types: n,
        kn,
        frozen_type: vec![false, true, false],
        gravity: scene.sys.gravity,
        bx: scene.sys.bx,
    }
}

/// The scene's fingerprint: sha256 of its LAMMPS data file (every disk, mass,
/// position and velocity, full precision) and coefficients.
pub fn scene_hash(scene: &Scene) -> String {
    let mut text = lammps::deck::write_data(&scene.sys);
    for c in &scene.sys.coeffs {
        text += &format!("{c:?}\n");
    }
    text += &format!("g {:e} dt {:e}\n", scene.sys.gravity, scene.sys.dt);
    sha256_hex(text.as_bytes())
}

pub fn run_native(case: &Impact2dCase, scene: &Scene, progress: bool) -> Result<Run> {
    let t0 = std::time::Instant::now();
    let bar = crate::report::progress::bar(progress, case.n_steps, "native");
    let (samples, energy) = scene_mod::run_native(
        scene,
        case.n_steps,
        case.output_every,
        case.energy_every,
        &energy_model(scene),
        |s| bar.set_position(s),
    )?;
    bar.finish_and_clear();
    Ok(Run {
        samples,
        energy,
        provenance: Provenance {
            engine: "native".into(),
            version: format!("granval {} native 2D DEM", env!("CARGO_PKG_VERSION")),
            command: "in-process".into(),
            input_hash: scene_hash(scene),
            date: now_utc(),
            wall_time_s: t0.elapsed().as_secs_f64(),
            threads: rayon::current_num_threads(),
            case_file: case.source.display().to_string(),
            notes: vec![],
        },
    })
}

pub fn run_lammps(case: &Impact2dCase, scene: &Scene, dir: &Path, mpi_procs: usize) -> Result<Run> {
    let lmp = Lammps {
        mpi_procs,
        ..Lammps::default()
    };
    let r = lammps::impact::run(
        &lmp,
        scene,
        case.n_steps,
        case.output_every,
        case.energy_every,
        &energy_model(scene),
        dir,
    )?;
    let mut notes = vec![
        format!("scene sha256 {}", scene_hash(scene)),
        format!("run directory: {}", dir.display()),
    ];
    notes.extend(r.finished.warnings.iter().cloned());
    Ok(Run {
        samples: r.samples,
        energy: r.energy,
        provenance: Provenance {
            engine: "lammps".into(),
            version: r.finished.version.clone(),
            command: r.finished.command.clone(),
            input_hash: r.finished.input_hash.clone(),
            date: now_utc(),
            wall_time_s: r.finished.wall_time_s,
            threads: mpi_procs.max(1),
            case_file: case.source.display().to_string(),
            notes,
        },
    })
}

/// `reference/impact2d/<case>/<label>` (label with `=` kept, other odd characters `_`).
pub fn record_dir(root: &Path, case: &Impact2dCase, v: &Variant) -> PathBuf {
    let label: String = v
        .label
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "=.-".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    root.join("impact2d").join(&case.name).join(label)
}

/// Stores a live LAMMPS run (its deck, data, log and parsed series) as the reference.
pub fn store_reference(run: &Run, run_dir: &Path, rec: &Path, scene: &Scene) -> Result<()> {
    std::fs::create_dir_all(rec).with_context(|| format!("cannot create {}", rec.display()))?;
    for f in [lammps::DECK_FILE, lammps::DATA_FILE, lammps::LOG_FILE] {
        std::fs::copy(run_dir.join(f), rec.join(f))
            .with_context(|| format!("copying {f} to {}", rec.display()))?;
    }
    obs::write_intruder_csv(
        &rec.join("intruder.csv"),
        &run.samples,
        scene.surface,
        scene.bottom_offset,
    )?;
    obs::write_energy_csv(&rec.join("energy.csv"), &run.energy)?;
    write_provenance(&rec.join("provenance.json"), &run.provenance)
}

/// A recorded LAMMPS run, only if it was recorded from this very scene.
pub fn recorded(rec: &Path, scene: &Scene) -> Result<Run> {
    let provenance = read_provenance(&rec.join("provenance.json"))?;
    anyhow::ensure!(
        provenance.engine == "lammps",
        "{}: not a LAMMPS record",
        rec.display()
    );
    let hash = scene_hash(scene);
    anyhow::ensure!(
        provenance.notes.iter().any(|n| n.contains(&hash)),
        "{}: recorded from a different scene than the one prepared now (sha256 {hash}); run `granval reference refresh --suite impact2d` where LAMMPS is installed",
        rec.display()
    );
    Ok(Run {
        samples: obs::read_intruder_csv(&rec.join("intruder.csv"))?,
        energy: obs::read_energy_csv(&rec.join("energy.csv"))?,
        provenance,
    })
}

/// The reference run of one variant: live LAMMPS if installed, else the record.
pub fn reference_run(
    case: &Impact2dCase,
    v: &Variant,
    scene: &Scene,
    opts: &crate::pipeline::Options,
    run_dir: &Path,
) -> Result<(Run, String)> {
    if lammps::installed_version(&lammps::binary()).is_some() {
        return Ok((
            run_lammps(case, scene, run_dir, opts.mpi_procs)?,
            "live".into(),
        ));
    }
    if opts.require_live {
        anyhow::bail!(
            "LAMMPS (`lmp`) is not installed but live engines are required (GRANVAL_REQUIRE_LIVE=1 / --require-live)"
        );
    }
    let rec = record_dir(&opts.reference_root, case, v);
    Ok((
        recorded(&rec, scene)?,
        format!("recorded {}", rec.display()),
    ))
}

/// Final and maximum depth (in d) of one run.
pub fn observe(
    case: &Impact2dCase,
    v: &Variant,
    scene: &Scene,
    run: &Run,
) -> Result<(VariantObs, Vec<(f64, f64)>)> {
    let d = case.scales.d;
    let series = obs::depth(&run.samples, scene.surface, scene.bottom_offset);
    let fin = obs::final_depth(&series, case.final_window)?;
    let max = series.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    let t_end = run.samples.last().map(|s| s.t).unwrap_or(0.0);
    let final_speed = run
        .samples
        .iter()
        .filter(|s| s.t >= t_end - case.final_window)
        .map(|s| s.v[0].hypot(s.v[1]))
        .fold(0.0, f64::max)
        / case.scales.velocity();
    Ok((
        VariantObs {
            label: v.label.clone(),
            x: v.x,
            final_depth: fin / d,
            max_depth: max / d,
            final_speed,
        },
        series,
    ))
}

fn write_series(dir: &Path, run: &Run, scene: &Scene) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    obs::write_intruder_csv(
        &dir.join("intruder.csv"),
        &run.samples,
        scene.surface,
        scene.bottom_offset,
    )?;
    obs::write_energy_csv(&dir.join("energy.csv"), &run.energy)?;
    write_provenance(&dir.join("provenance.json"), &run.provenance)
}

/// Native vs LAMMPS for every variant of an impact2d case, plus the case's claim in
/// each engine; outputs under `out_dir`.
pub fn compare_case(
    case: &Impact2dCase,
    opts: &crate::pipeline::Options,
    out_dir: &Path,
) -> crate::pipeline::CaseResult {
    compare_case_with(case, opts, out_dir, Tweak::None)
}

pub fn compare_case_with(
    case: &Impact2dCase,
    opts: &crate::pipeline::Options,
    out_dir: &Path,
    tweak: Tweak,
) -> crate::pipeline::CaseResult {
    let fail = |what: &str, e: anyhow::Error, notes: Vec<String>| crate::pipeline::CaseResult {
        checks: vec![Check::error(
            format!("{}: {what}", case.name),
            format!("{e:#}"),
        )],
        run: None,
        notes,
        errored: true,
    };
    let beds = match prepare_beds(case, opts.progress) {
        Ok(b) => b,
        Err(e) => return fail("bed preparation", e, vec![]),
    };
    let mut notes: Vec<String> = beds
        .beds
        .iter()
        .map(|(p, b)| bed_note(case, *p, b))
        .collect();
    if tweak != Tweak::None {
        notes.push(format!(
            "NEGATIVE CONTROL: native engine run with {tweak:?}"
        ));
    }
    let tau = case.scales.tau_c;
    let d = case.scales.d;
    let (mut checks, mut errored) = (Vec::new(), false);
    let (mut native_obs, mut ref_obs) = (Vec::new(), Vec::new());
    let mut series_svg: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    let (mut wall_native, mut wall_ref) = (0.0, 0.0);
    let mut reference_meta: Option<(String, String)> = None;
    for v in &case.variants {
        let vdir = out_dir.join(
            record_dir(Path::new(""), case, v)
                .file_name()
                .unwrap_or_default(),
        );
        let scene = match scene(case, v, &beds) {
            Ok(s) => s,
            Err(e) => return fail(&format!("[{}] scene", v.label), e, notes),
        };
        let native = match run_native(case, &native_scene(&scene, tweak), opts.progress) {
            Ok(r) => r,
            Err(e) => return fail(&format!("[{}] native run", v.label), e, notes),
        };
        let (reference, source) =
            match reference_run(case, v, &scene, opts, &vdir.join("lammps-run")) {
                Ok(r) => r,
                Err(e) => {
                    notes.push(format!(
                        "the LAMMPS reference failed for {} [{}]: this is an error, not a pass",
                        case.name, v.label
                    ));
                    return fail(&format!("[{}] LAMMPS reference", v.label), e, notes);
                }
            };
        if source != "live" {
            notes.push(format!(
                "LAMMPS is not installed here: {} [{}] was compared against the RECORDED LAMMPS run in {} ({}, recorded {})",
                case.name, v.label, source.trim_start_matches("recorded "), reference.provenance.version, reference.provenance.date
            ));
        }
        wall_native += native.provenance.wall_time_s;
        wall_ref += reference.provenance.wall_time_s;
        reference_meta = Some((reference.provenance.version.clone(), source.clone()));
        for (name, run) in [("native", &native), ("lammps", &reference)] {
            if let Err(e) = write_series(&vdir.join(name), run, &scene) {
                checks.push(Check::error(
                    format!("{} [{}]: writing {name} outputs", case.name, v.label),
                    format!("{e:#}"),
                ));
                errored = true;
            }
        }
        match (
            observe(case, v, &scene, &native),
            observe(case, v, &scene, &reference),
        ) {
            (Ok((a, sa)), Ok((b, sb))) => {
                let rms = obs::rms_distance(&sa, &sb)
                    .map(|r| r / d)
                    .map_err(|e| format!("{e:#}"));
                checks.extend(cmp::cross_check(case, &a, &b, rms, "lammps"));
                let scaled =
                    |s: &[(f64, f64)]| s.iter().map(|p| (p.0 / tau, p.1 / d)).collect::<Vec<_>>();
                series_svg.push((format!("native {}", v.label), scaled(&sa)));
                series_svg.push((format!("LAMMPS {}", v.label), scaled(&sb)));
                native_obs.push(a);
                ref_obs.push(b);
            }
            (a, b) => {
                errored = true;
                checks.push(Check::error(
                    format!("{} [{}]: observables", case.name, v.label),
                    format!("native: {:?}; lammps: {:?}", a.err(), b.err()),
                ));
            }
        }
    }
    if !errored {
        checks.extend(cmp::claim_check(case, "native", &native_obs));
        checks.extend(cmp::claim_check(case, "lammps", &ref_obs));
        let refs: Vec<(&str, &[(f64, f64)])> = series_svg
            .iter()
            .map(|(l, s)| (l.as_str(), s.as_slice()))
            .collect();
        if let Err(e) = crate::report::svg_impact::depth_overlay(
            &out_dir.join("depth.svg"),
            &refs,
            &format!("{}: D(t), native vs LAMMPS", case.name),
        ) {
            notes.push(format!("SVG not written: {e:#}"));
        }
        let _ = std::fs::write(
            out_dir.join("final_depths.json"),
            serde_json::to_string_pretty(
                &serde_json::json!({"native": native_obs, "lammps": ref_obs}),
            )
            .unwrap_or_default(),
        );
    }
    errored |= checks.iter().any(|c| c.metric == "error");
    let (ref_version, source) = reference_meta.unwrap_or_default();
    crate::pipeline::CaseResult {
        checks,
        run: Some(crate::report::CaseRun {
            case: case.name.clone(),
            case_file: case.source.display().to_string(),
            test_engine: "native".into(),
            reference_engine: "lammps".into(),
            reference_version: ref_version,
            reference_source: source,
            wall_time_test_s: wall_native,
            wall_time_reference_s: wall_ref,
        }),
        notes,
        errored,
    }
}
