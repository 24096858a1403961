//! The 2D impact experiment (Kondic et al.): beds prepared natively, one unit per sweep
//! variant (once per seed of a seed ensemble; a scene: the bed, the walls and the
//! intruder with its speed), each run natively and in LAMMPS from the same scene; final
//! depth and D(t) per variant, the paper's claim over the sweep in each engine.

use super::chaos;
use super::reference::Verified;
use super::{DeckFiles, Derived, Estimate, Experiment, Options, Role, Run, Verdict};
use crate::analysis::impact as obs;
use crate::case::Perturbation;
use crate::case::impact2d::IntruderShape;
use crate::case::impact2d::{BedKey, Impact2dCase, Packing, Variant};
use crate::compare::Check;
use crate::compare::ensemble::ValueStats;
use crate::compare::impact2d::{self as cmp, FieldObs, VariantObs};
use crate::engines::deck_text::{Header, approx, num, safe};
use crate::engines::lammps::{self, Lammps};
use crate::physics::dem2d::bed::{self, Bed};
use crate::physics::dem2d::energy::EnergyModel;
use crate::physics::dem2d::impact::SnapshotSteps;
use crate::physics::dem2d::impact::{self as scene_mod, Scene};
use crate::rundata::impact::{
    EnergySample, FieldSnapshot, IntruderSample, read_energy_csv, read_fields_csv,
    read_intruder_csv, write_energy_csv, write_fields_csv, write_intruder_csv,
};
use crate::rundata::provenance::{
    EngineKind, Provenance, Sha256, now_utc, read_provenance, write_provenance,
};
use anyhow::{Context, Result};
use std::path::Path;

pub struct Impact2d {
    pub case: Impact2dCase,
}

/// One variant and the scene both engines start from.
pub struct Unit {
    pub variant: Variant,
    pub scene: Scene,
    /// The base case on the same bed, for a `sweep_ignored` negative control.
    pub base_scene: Option<Scene>,
    /// The first variant's scene, for a `packing_ignored` negative control.
    pub first_scene: Option<std::sync::Arc<Scene>>,
    /// How its bed was prepared (for the report).
    pub bed_note: String,
    /// On the first unit of each bed: the bed and its file name, recorded with the
    /// reference run so a recorded comparison need not settle it again.
    pub bed_record: Option<(String, std::sync::Arc<Bed>)>,
}

/// The series of one run.
pub struct ImpactRun {
    pub samples: Vec<IntruderSample>,
    pub energy: Vec<EnergySample>,
    /// Bed snapshots at the case's `[fields]` steps (empty without).
    pub fields: Vec<FieldSnapshot>,
    pub provenance: Provenance,
}

impl Run for ImpactRun {
    fn provenance(&self) -> &Provenance {
        &self.provenance
    }
}

const PROVENANCE_FILE: &str = "provenance.json";
const INTRUDER_CSV: &str = "intruder.csv";
const ENERGY_CSV: &str = "energy.csv";
const GRAINS_CSV: &str = "grains.csv";
const CONTACTS_CSV: &str = "contacts.csv";

fn write_series(dir: &Path, run: &ImpactRun, scene: &Scene) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    write_intruder_csv(
        &dir.join(INTRUDER_CSV),
        &run.samples,
        scene.surface,
        scene.bottom_offset,
    )?;
    write_energy_csv(&dir.join(ENERGY_CSV), &run.energy)?;
    if !run.fields.is_empty() {
        write_fields_csv(&dir.join(GRAINS_CSV), &dir.join(CONTACTS_CSV), &run.fields)?;
    }
    write_provenance(&dir.join(PROVENANCE_FILE), &run.provenance)
}

impl Experiment for Impact2d {
    type Unit = Unit;
    type NativeRun = ImpactRun;
    type RefRun = ImpactRun;
    type Case = Impact2dCase;

    fn case(&self) -> &Impact2dCase {
        &self.case
    }
    fn kind(&self) -> &'static str {
        "impact2d"
    }
    fn reference_engine(&self) -> EngineKind {
        EngineKind::Lammps
    }

    fn estimate(&self) -> Estimate {
        let c = &self.case;
        // Disks of a variant's scene: its bed plus about three wall rows.
        let disks = |v: &Variant| {
            let b = c.bed_of(v);
            b.count as f64 + b.length / c.wall_d.max(1e-300) * 3.0
        };
        let n = c.variants.iter().map(disks).fold(0.0, f64::max);
        let all: f64 = c.variants.iter().map(disks).sum();
        let runs = (c.variants.len() * (1 + c.negative_controls.len())) as f64;
        let steps = c.n_steps as f64;
        // Field snapshots (Figs 22-27): each position dump is about 200 bytes per grain
        // at full precision; each contact dump about 2 contacts per grain (coordination
        // near 4 in 2D) of about 350 bytes.
        let snapshot_bytes = c.fields.as_ref().map_or(0.0, |f| {
            n * (200.0 * f.position_steps().len() as f64 + 700.0 * f.network_steps.len() as f64)
        });
        Estimate {
            particle_steps: all * steps * (1 + c.negative_controls.len()) as f64,
            particles: n,
            output_bytes: runs
                * (200.0 * (steps / c.output_every as f64 + steps / c.energy_every as f64)
                    + snapshot_bytes),
            memory_bytes: 2e3 * n + 1e8,
        }
    }

    fn derived(&self) -> Vec<Derived> {
        let c = &self.case;
        let tau = c.scales.tau_c;
        vec![
            Derived::new(
                "grains",
                {
                    let mut counts: Vec<usize> =
                        c.variants.iter().map(|v| c.bed_of(v).count).collect();
                    counts.dedup();
                    counts
                        .iter()
                        .map(|n| n.to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                },
                if c.is_ensemble() {
                    format!(
                        "per bed, plus the frozen wall disks; {} run(s): {} value(s) x {} seeds {:?}",
                        c.variants.len(),
                        c.ensemble_groups().len(),
                        c.seeds.len(),
                        c.seeds
                    )
                } else {
                    format!(
                        "per bed, plus the frozen wall disks; {} variant(s)",
                        c.variants.len()
                    )
                },
            ),
            Derived::new(
                "collision time tau_c",
                format!("{tau:.4e} s"),
                "binary collision time of the grains (Kondic et al. Sec. II); the 2D analogue of the Rayleigh time",
            ),
            Derived::new(
                "time step",
                format!("{:e} s", c.dt),
                format!("tau_c / {:.1}: steps per binary collision", tau / c.dt),
            ),
            Derived::new(
                "run",
                format!("{} steps", c.n_steps),
                format!(
                    "{:.4e} s = {:.1} tau_c simulated per variant",
                    c.dt * c.n_steps as f64,
                    c.dt * c.n_steps as f64 / tau
                ),
            ),
        ]
    }

    fn units(&self, opts: &Options) -> Result<Vec<Unit>> {
        let beds = prepare_beds(
            &self.case,
            opts.progress,
            opts.recorded_inputs.as_deref(),
            Some(&opts.reference_root),
        )?;
        let wants_base = self
            .case
            .negative_controls
            .iter()
            .any(|c| c.perturbation.sweep_ignored);
        let first_scene = match self.case.variants.first() {
            Some(v0)
                if self
                    .case
                    .negative_controls
                    .iter()
                    .any(|c| c.perturbation.packing_ignored) =>
            {
                let key = self.case.bed_of(v0);
                Some(std::sync::Arc::new(scene_mod::build(
                    &self.case,
                    v0,
                    beds.get(&key),
                )?))
            }
            _ => None,
        };
        let mut recorded_keys: Vec<BedKey> = Vec::new();
        self.case
            .variants
            .iter()
            .map(|v| {
                let key = self.case.bed_of(v);
                let bed_record = if recorded_keys.contains(&key) {
                    None
                } else {
                    recorded_keys.push(key);
                    bed_file_name(&self.case, &key)
                        .map(|n| (n, std::sync::Arc::new(beds.get(&key).clone())))
                };
                Ok(Unit {
                    variant: v.clone(),
                    scene: scene_mod::build(&self.case, v, beds.get(&key))?,
                    // On this variant's bed (a packing or bed sweep's base keeps its own
                    // bed); with beds settled per variant, on the base grains' bed of the
                    // same seed (the case refuses a sweep none of whose values has it).
                    base_scene: if wants_base {
                        let base = Variant {
                            packing: v.packing,
                            bed: v.bed,
                            ..self.case.base.clone()
                        };
                        Some(scene_mod::build(
                            &self.case,
                            &base,
                            beds.get(&self.case.bed_of(&base)),
                        )?)
                    } else {
                        None
                    },
                    first_scene: first_scene.clone(),
                    bed_note: bed_note(&self.case, &key, beds.get(&key)) + &beds.origin_note(&key),
                    bed_record,
                })
            })
            .collect()
    }

    fn unit_name(&self, u: &Unit) -> String {
        label_dir(&u.variant)
    }

    fn fingerprint(&self, u: &Unit) -> Result<Sha256> {
        Ok(scene_hash(&u.scene))
    }
    fn engine_input(&self, u: &Unit) -> Result<Vec<(&'static str, String)>> {
        Ok(vec![
            (
                lammps::DECK_FILE,
                lammps::deck::write_deck(&u.scene.sys, &self.outputs(u))?,
            ),
            (lammps::DATA_FILE, lammps::deck::write_data(&u.scene.sys)),
        ])
    }

    fn run_native(&self, u: &Unit, role: Role, dir: &Path, opts: &Options) -> Result<ImpactRun> {
        let c = &self.case;
        let pert = role.perturbation();
        let scene = &*control_scene(c, u, &pert)?;
        let bar = crate::report::progress::bar(opts.progress, c.n_steps, "native");
        let ((samples, energy, fields), provenance) = crate::engines::native::impact2d(
            scene,
            c.n_steps,
            c.output_every,
            c.energy_every,
            &energy_model(scene),
            &snapshot_steps(c),
            scene_hash(scene),
            &c.source,
            &pert,
            |s| bar.set_position(s),
        )?;
        bar.finish_and_clear();
        let run = ImpactRun {
            samples: in_unit_frame(samples, scene, &u.scene),
            energy,
            fields,
            provenance,
        };
        write_series(dir, &run, &u.scene)?;
        Ok(run)
    }

    fn write_deck(&self, u: &Unit, dir: &Path, opts: &Options) -> Result<()> {
        lammps::write_inputs(&u.scene.sys, &self.outputs(u), dir, opts.viz_every)
    }

    fn run_reference(&self, u: &Unit, dir: &Path, opts: &Options) -> Result<ImpactRun> {
        let lmp = Lammps {
            mpi_procs: opts.mpi_procs,
            limits: super::engine_limits(self, opts),
            ..Lammps::default()
        };
        let r = lammps::impact::run(
            &lmp,
            &u.scene,
            &self.outputs(u),
            &energy_model(&u.scene),
            dir,
        )?;
        let run = self.lammps_run(
            u,
            (r.samples, r.energy, r.fields),
            &r.finished,
            opts.mpi_procs,
        );
        write_series(dir, &run, &u.scene)?;
        Ok(run)
    }

    fn read_run_dir(&self, u: &Unit, dir: &Path) -> Result<ImpactRun> {
        let out = self.outputs(u);
        let fin = lammps::finished(&u.scene.sys, &out, dir)?;
        let series = lammps::impact::read(&u.scene, &out, &energy_model(&u.scene), dir)?;
        let procs = lammps_procs(&crate::rundata::fsio::read_to_string(
            &dir.join(lammps::LOG_FILE),
            crate::rundata::fsio::max_engine_output(),
            "a LAMMPS log",
        )?);
        Ok(self.lammps_run(u, series, &fin, procs))
    }

    fn deck_files(&self) -> DeckFiles {
        DeckFiles {
            binary: "lmp",
            deck: lammps::DECK_FILE,
            log: lammps::LOG_FILE,
            inputs: &[(
                lammps::DATA_FILE,
                "the disks (read_data): box, per disk id, type, diameter, density (= mass / (4/3 pi r^3), LAMMPS' convention), position; velocities",
            )],
            outputs: &[
                (
                    lammps::INTRUDER_FILE,
                    "every output_every steps the intruder's centre of mass, velocity and total force (%.17g); in cases that track the interface (Kondic et al. Fig 12) an eighth column, the interface tracers' centre of mass in y",
                ),
                (
                    lammps::SNAP_FILE,
                    "every energy_every steps every disk (for the energies)",
                ),
                (
                    lammps::deck::GRAINS_FILE,
                    "only with [fields]: every grain's position at the field steps (%.17g)",
                ),
                (
                    lammps::deck::CONTACTS_FILE,
                    "only with [fields] network_times: every touching pair's atom ids, distance, |F_n| and |F_t| at those steps",
                ),
                (
                    lammps::LOG_FILE,
                    "LAMMPS' log (version, warnings, thermo lines)",
                ),
            ],
        }
    }

    fn record(&self, u: &Unit, run: &ImpactRun, run_dir: &Path, rec: &Path) -> Result<()> {
        std::fs::create_dir_all(rec).with_context(|| format!("cannot create {}", rec.display()))?;
        for f in [lammps::DECK_FILE, lammps::DATA_FILE, lammps::LOG_FILE] {
            std::fs::copy(run_dir.join(f), rec.join(f))
                .with_context(|| format!("copying {f} to {}", rec.display()))?;
        }
        if let Some(bed) = self.bed_file(u) {
            let (name, bytes) = bed?;
            let path = rec.join(name);
            std::fs::write(&path, bytes)
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
        write_series(rec, run, &u.scene)
    }

    /// The first unit on each bed keeps it (the others find it there by its key).
    fn bed_file(&self, u: &Unit) -> Option<Result<(String, Vec<u8>)>> {
        let (name, b) = u.bed_record.as_ref()?;
        Some(
            serde_json::to_vec(&**b)
                .map(|bytes| (name.clone(), bytes))
                .map_err(Into::into),
        )
    }

    /// LAMMPS' data file is the scene's disks as granval writes them (the scene is the
    /// fingerprint), so a lean record leaves it out.
    fn regenerate(&self, u: &Unit, file: &str) -> Option<Result<Vec<u8>>> {
        (file == lammps::DATA_FILE).then(|| Ok(lammps::deck::write_data(&u.scene.sys).into_bytes()))
    }

    fn read_record(&self, _u: &Unit, name: &str, seal: &Verified) -> Result<ImpactRun> {
        let snaps = snapshot_steps(&self.case);
        Ok(ImpactRun {
            samples: read_intruder_csv(&seal.file(name, INTRUDER_CSV)?)?,
            energy: read_energy_csv(&seal.file(name, ENERGY_CSV)?)?,
            fields: if snaps.position_steps.is_empty() {
                Vec::new()
            } else {
                read_fields_csv(
                    &seal.file(name, GRAINS_CSV)?,
                    &seal.file(name, CONTACTS_CSV)?,
                    &snaps.contact_steps,
                )?
            },
            provenance: read_provenance(&seal.file(name, PROVENANCE_FILE)?)?,
        })
    }

    fn drift(&self, previous: &ImpactRun, now: &ImpactRun) -> String {
        let last = |r: &ImpactRun| r.samples.last().map(|s| s.x[1]).unwrap_or(f64::NAN);
        format!(
            "final intruder height {:+.2e} d",
            (last(now) - last(previous)) / self.case.scales.d
        )
    }

    fn has_chaos_baseline(&self) -> bool {
        true
    }

    fn chaos(&self, family: &str, opts: &Options, out: &Path) -> Result<super::chaos::ChaosRecord> {
        chaos_replicas(self, family, &chaos::one_ulp(), opts, out)
    }

    fn checks(
        &self,
        units: &[Unit],
        native: &[ImpactRun],
        reference: &[ImpactRun],
        out: &Path,
        opts: &Options,
    ) -> Verdict {
        let case = &self.case;
        let control = opts.control.as_deref();
        let caption = |t: String| crate::report::plot::Caption::new(t).control(control);
        let (tau, d) = (case.scales.tau_c, case.scales.d);
        let mut checks = Vec::new();
        let mut notes: Vec<String> = Vec::new();
        let mut sections = Vec::new();
        for u in units {
            if !notes.contains(&u.bed_note) {
                notes.push(u.bed_note.clone());
            }
        }
        let (mut native_obs, mut ref_obs) = (Vec::new(), Vec::new());
        let mut series_svg: Vec<SvgLine> = Vec::new();
        let mut relative_svg: Vec<SvgLine> = Vec::new();
        let mut complete = true;
        for ((u, a), b) in units.iter().zip(native).zip(reference) {
            let v = &u.variant;
            match (observe(case, v, &u.scene, a), observe(case, v, &u.scene, b)) {
                (Ok((oa, sa)), Ok((ob, sb))) => {
                    let rms = obs::rms_distance(&sa, &sb)
                        .map(|r| r / d)
                        .map_err(|e| format!("{e:#}"));
                    checks.extend(cmp::cross_check(case, &oa, &ob, rms, "lammps"));
                    checks.extend(cmp::force_cross_check(case, &oa, &ob, "lammps"));
                    checks.extend(cmp::field_cross_checks(case, &oa, &ob, "lammps"));
                    if case.track_interface {
                        checks.push(crate::compare::interface::cross_check(
                            case,
                            &v.label,
                            oa.interface.as_ref(),
                            ob.interface.as_ref(),
                            "lammps",
                        ));
                        for (e, o) in [(EngineKind::Native, &oa), (self.reference_engine(), &ob)] {
                            if let Some(i) = &o.interface {
                                relative_svg.push((
                                    format!("{e} {}", v.label),
                                    e,
                                    v.label.clone(),
                                    i.relative_series.clone(),
                                ));
                            }
                        }
                    }
                    let scaled = |s: &[(f64, f64)]| {
                        s.iter().map(|p| (p.0 / tau, p.1 / d)).collect::<Vec<_>>()
                    };
                    for (e, s) in [(EngineKind::Native, &sa), (self.reference_engine(), &sb)] {
                        series_svg.push((
                            format!("{e} {}", v.label),
                            e,
                            v.label.clone(),
                            scaled(s),
                        ));
                    }
                    native_obs.push(oa);
                    ref_obs.push(ob);
                }
                (a, b) => {
                    complete = false;
                    checks.push(Check::error(
                        format!("{} [{}]: observables", case.name, v.label),
                        format!(
                            "native: {:?}; lammps: {:?}",
                            a.err().map(|e| format!("{e:#}")),
                            b.err().map(|e| format!("{e:#}"))
                        ),
                    ));
                }
            }
        }
        if complete {
            checks.extend(cmp::claim_checks(case, "native", &native_obs));
            checks.extend(cmp::claim_checks(case, "lammps", &ref_obs));
            checks.extend(cmp::exponent_cross_checks(
                case,
                &native_obs,
                &ref_obs,
                "lammps",
            ));
            let refs = svg_lines(&series_svg);
            if let Err(e) = crate::report::svg_impact::depth_overlay(
                &out.join("depth.svg"),
                &refs,
                &caption(format!("{}: D(t), native vs LAMMPS", case.name)),
            ) {
                notes.push(format!("SVG not written: {e:#}"));
            }
            if !relative_svg.is_empty() {
                let refs = svg_lines(&relative_svg);
                if let Err(e) = crate::report::svg_impact::depth_overlay(
                    &out.join("depth-interface.svg"),
                    &refs,
                    &caption(format!(
                        "{}: D_rel(t), depth below the moving interface (K Fig 12)",
                        case.name
                    )),
                ) {
                    notes.push(format!("SVG not written: {e:#}"));
                }
            }
            if let Err(e) = field_plots(case, &native_obs, &ref_obs, out, control) {
                notes.push(format!("field plots not written: {e:#}"));
            }
            let mut depths = serde_json::json!({
                "case": case.name,
                "canonical_hash": crate::case::ValidatedCase::canonical_hash(case).to_string(),
                "native": native_obs,
                "lammps": ref_obs,
            });
            if case.is_ensemble() {
                let fd = |o: &VariantObs| o.final_depth;
                match (
                    cmp::ensemble_stats(case, &native_obs, &fd),
                    cmp::ensemble_stats(case, &ref_obs, &fd),
                ) {
                    (Ok(a), Ok(b)) => {
                        depths["ensemble"] = serde_json::json!({"native": a, "lammps": b});
                        match ensemble_section(case, &a, &b, out, control) {
                            Ok(s) => sections.push(s),
                            Err(e) => notes.push(format!("ensemble figure not written: {e:#}")),
                        }
                    }
                    (a, b) => notes.push(format!(
                        "no ensemble figure: native {:?}, lammps {:?}",
                        a.err(),
                        b.err()
                    )),
                }
            }
            if let Err(e) = std::fs::write(
                out.join(FINAL_DEPTHS_FILE),
                serde_json::to_string_pretty(&depths).unwrap_or_default(),
            ) {
                notes.push(format!("final_depths.json not written: {e}"));
            }
        }
        Verdict {
            checks,
            notes,
            sections,
            ..Verdict::default()
        }
    }
}

/// Every variant's observables in both engines, as the comparison found them.
pub(crate) const FINAL_DEPTHS_FILE: &str = "final_depths.json";

/// (label, D_native, D_lammps), final depths in d, of every variant in a
/// [`FINAL_DEPTHS_FILE`] written by the version `canonical_hash` of its case; another
/// version's file (or one written before the file named its version) is refused.
pub(crate) fn read_final_depths(
    path: &Path,
    canonical_hash: &str,
) -> Result<Vec<(String, f64, f64)>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let v: serde_json::Value = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a final-depth file", path.display()))?;
    let written = v.get("canonical_hash").and_then(|h| h.as_str());
    anyhow::ensure!(
        written == Some(canonical_hash),
        "{}: written by another version of the case (canonical hash {}, the case file's is {canonical_hash})",
        path.display(),
        written.unwrap_or("not recorded")
    );
    let depths = |engine: &str| -> Result<Vec<(String, f64)>> {
        v.get(engine)
            .and_then(|a| a.as_array())
            .with_context(|| format!("{}: no {engine} variants", path.display()))?
            .iter()
            .map(|o| {
                let label = o.get("label").and_then(|l| l.as_str());
                let d = o.get("final_depth").and_then(|d| d.as_f64());
                label
                    .zip(d)
                    .map(|(l, d)| (l.to_string(), d))
                    .with_context(|| {
                        format!(
                            "{}: a {engine} variant without label or final depth",
                            path.display()
                        )
                    })
            })
            .collect()
    };
    let lammps = depths("lammps")?;
    depths("native")?
        .into_iter()
        .map(|(label, a)| {
            let b = lammps
                .iter()
                .find(|(l, _)| *l == label)
                .map(|p| p.1)
                .with_context(|| {
                    format!("{}: variant {label} has no LAMMPS run", path.display())
                })?;
            Ok((label, a, b))
        })
        .collect()
}

/// The figure file of a seed ensemble's final depths.
pub const ENSEMBLE_FIGURE: &str = "final_depth.svg";

/// A seed ensemble's final depth against the swept value (K Fig 8b's axes): per engine
/// the mean over the seeds with +- 1 SE bars and every seed's bed as a small dot, written
/// as [`ENSEMBLE_FIGURE`] into `out`, and a report section with the same numbers as a
/// table. Reporting only: the claims judge the same means in their own checks.
fn ensemble_section(
    case: &Impact2dCase,
    native: &[ValueStats],
    lammps: &[ValueStats],
    out: &Path,
    control: Option<&str>,
) -> Result<crate::report::Section> {
    use crate::report::palette::Source;
    use crate::report::svg::{SweepSeries, sweep_with_error_bars};
    let x: Vec<f64> = native.iter().map(|s| s.x).collect();
    // A text-valued sweep (friction, packing) is drawn at 0, 1, ...: say which is which.
    let numeric = native.iter().all(|s| {
        s.value
            .split_once('=')
            .and_then(|(_, t)| t.parse::<f64>().ok())
            .is_some_and(|v| v == s.x)
    });
    let param = case.sweep_parameter.as_deref().unwrap_or("variant");
    let x_label = if numeric {
        param.to_string()
    } else {
        format!(
            "{param}: {}",
            native
                .iter()
                .map(|s| format!("{} = {}", s.x, s.value))
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    let columns = |st: &[ValueStats]| {
        (
            st.iter().map(|s| s.mean).collect::<Vec<f64>>(),
            st.iter().map(|s| s.se).collect::<Vec<f64>>(),
            st.iter()
                .map(|s| s.seeds.iter().map(|p| p.1).collect())
                .collect::<Vec<Vec<f64>>>(),
        )
    };
    let (na, nb) = (columns(native), columns(lammps));
    let series = [
        SweepSeries {
            label: "native",
            source: Source::Native,
            k: &na.0,
            se: &na.1,
            beds: &na.2,
        },
        SweepSeries {
            label: "LAMMPS",
            source: Source::Lammps,
            k: &nb.0,
            se: &nb.1,
            beds: &nb.2,
        },
    ];
    sweep_with_error_bars(
        &out.join(ENSEMBLE_FIGURE),
        &crate::report::plot::Caption::new(format!(
            "{}: final depth, mean of {} seeds +- 1 SE",
            case.name,
            case.seeds.len()
        ))
        .control(control),
        &x_label,
        "final depth / d",
        &x,
        &series,
        None,
    )?;
    let seeds = |s: &ValueStats| {
        s.seeds
            .iter()
            .map(|(k, y)| format!("{k}: {y:.3}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut body = format!(
        "Final depth (d) per {param} value: mean over the seeds {:?} +- its standard error (sample sd / sqrt(n)), and each seed's bed.\n\n| value | native | LAMMPS | native per seed | LAMMPS per seed |\n|---|---|---|---|---|\n",
        case.seeds
    );
    for (a, b) in native.iter().zip(lammps) {
        body += &format!(
            "| {} | {:.3} +- {:.3} | {:.3} +- {:.3} | {} | {} |\n",
            a.value,
            a.mean,
            a.se,
            b.mean,
            b.se,
            seeds(a),
            seeds(b)
        );
    }
    Ok(crate::report::Section {
        title: format!("Seed ensemble: {}", case.name),
        body,
        figures: vec![ENSEMBLE_FIGURE.to_string()],
    })
}

/// (label, engine, variant, points) of a line figure, kept until it is drawn: the
/// engine and the variant style the line, the label is its legend text.
type SvgLine = (String, EngineKind, String, Vec<(f64, f64)>);

/// The overlay lines of `v`, each styled by its engine and variant.
fn svg_lines(v: &[SvgLine]) -> Vec<crate::report::overlay::Line<'_>> {
    v.iter()
        .map(|(l, e, variant, s)| {
            crate::report::overlay::Line::new(l, (*e).into(), s).variant(variant)
        })
        .collect()
}

/// Plots where a person would rather look (K Figs 21-27): F(t) of every variant in both
/// engines, the B0 curves of both networks at each field time, and maps of D2_min and
/// |A_f| per variant and engine (log10, one colour range for all maps of a quantity).
fn field_plots(
    case: &Impact2dCase,
    native: &[VariantObs],
    reference: &[VariantObs],
    out: &Path,
    control: Option<&str>,
) -> Result<()> {
    use crate::report::palette::Scale;
    use crate::report::plot::Caption;
    use crate::report::svg_impact::{curves, grain_map};
    let engines = [
        (EngineKind::Native, native),
        (EngineKind::Lammps, reference),
    ];
    if cmp::has_force_claims(case) {
        let bin = cmp::force_bin(case);
        let mut series: Vec<SvgLine> = Vec::new();
        for (e, obs) in engines {
            for o in obs {
                let f = crate::analysis::impact::force_summary(&o.force, bin, bin)?;
                let early: Vec<(f64, f64)> = f
                    .bins
                    .iter()
                    .copied()
                    .filter(|b| b.0 <= f.t_contact + case.tolerances.force_window)
                    .collect();
                series.push((format!("{e} {}", o.label), e, o.label.clone(), early));
            }
        }
        let refs = svg_lines(&series);
        curves(
            &out.join("force.svg"),
            &refs,
            &Caption::new(format!(
                "{}: force on the intruder ({bin} tau_c bins)",
                case.name
            ))
            .control(control),
            "t / tau_c (after release)",
            "F_y / m g",
            "m g",
        )?;
    }
    let Some(first) = native.first().and_then(|o| o.fields.as_ref()) else {
        return Ok(());
    };
    for (k, (t, _)) in first.networks.iter().enumerate() {
        for net in ["normal", "tangential"] {
            let mut series: Vec<SvgLine> = Vec::new();
            for (e, obs) in engines {
                for o in obs {
                    if let Some((_, c)) = o.fields.as_ref().and_then(|f| f.networks.get(k)) {
                        let y = if net == "normal" {
                            &c.normal
                        } else {
                            &c.tangential
                        };
                        series.push((
                            format!("{e} {}", o.label),
                            e,
                            o.label.clone(),
                            c.thresholds
                                .iter()
                                .copied()
                                .zip(y.iter().copied())
                                .collect(),
                        ));
                    }
                }
            }
            let refs = svg_lines(&series);
            curves(
                &out.join(format!("b0-{net}-t{t}.svg")),
                &refs,
                &Caption::new(format!(
                    "{}: B0 of the {net} force network, t = {t} tau_c",
                    case.name
                ))
                .control(control),
                "force threshold / mean normal force per grain",
                "B0 / N",
                "fraction of N",
            )?;
        }
    }
    type Pick = fn(&crate::analysis::affine::AffineGrain) -> f64;
    let maps: [(&str, &str, Pick); 2] = [
        ("d2min", "log10(D2_min / d^2)", |g| {
            g.d2min.max(1e-30).log10()
        }),
        ("affine", "log10(|A_f| / d)", |g| {
            g.af[0].hypot(g.af[1]).max(1e-30).log10()
        }),
    ];
    for (file, what, pick) in maps {
        let mut all: Vec<f64> = engines
            .iter()
            .flat_map(|(_, obs)| obs.iter())
            .filter_map(|o| o.fields.as_ref())
            .flat_map(|f| f.affine_map.iter().map(pick))
            .collect();
        if all.is_empty() {
            continue;
        }
        all.sort_by(f64::total_cmp);
        let range = (all[all.len() / 100], all[all.len() * 99 / 100]);
        for (e, obs) in engines {
            for o in obs {
                let Some(f) = &o.fields else { continue };
                let pts: Vec<(f64, f64, f64)> = f
                    .affine_map
                    .iter()
                    .map(|g| (g.x[0], g.x[1], pick(g)))
                    .collect();
                grain_map(
                    &out.join(format!(
                        "{file}-{}-{}.svg",
                        label_dir_str(&o.label),
                        e.key()
                    )),
                    &pts,
                    Scale::Sequential {
                        lo: range.0,
                        hi: range.1,
                    },
                    what,
                    &Caption::new(format!(
                        "{} {e} {}: {what} at t = {} tau_c",
                        case.name, o.label, f.affine_t
                    ))
                    .control(control),
                )?;
            }
        }
    }
    Ok(())
}

/// MPI processes a LAMMPS log says it ran on (`Loop time of T on N procs ...`), 1 if
/// it does not say.
fn lammps_procs(log: &str) -> usize {
    log.lines()
        .find_map(|l| {
            l.trim()
                .strip_prefix("Loop time of")
                .and_then(|r| r.split(" on ").nth(1))
                .and_then(|r| r.split_whitespace().next())
                .and_then(|p| p.parse::<usize>().ok())
        })
        .unwrap_or(1)
}

impl Impact2d {
    /// A LAMMPS run of `u` as the checks take it, whether granval ran LAMMPS or a
    /// person did in a deck directory.
    fn lammps_run(
        &self,
        u: &Unit,
        (samples, energy, fields): (Vec<IntruderSample>, Vec<EnergySample>, Vec<FieldSnapshot>),
        fin: &lammps::Finished,
        procs: usize,
    ) -> ImpactRun {
        let mut notes = vec![format!("scene sha256 {}", scene_hash(&u.scene))];
        notes.extend(fin.notes.iter().cloned());
        ImpactRun {
            samples,
            energy,
            fields,
            provenance: Provenance {
                engine: EngineKind::Lammps,
                version: fin.version.clone(),
                command: fin.command.clone(),
                input_hash: fin.input_hash.clone(),
                date: now_utc(),
                wall_time_s: fin.wall_time_s,
                threads: procs.max(1),
                case_file: self.case.source.display().to_string(),
                notes,
            },
        }
    }

    /// What the LAMMPS deck of a unit runs and writes, with its header.
    pub fn outputs(&self, u: &Unit) -> lammps::Outputs {
        let c = &self.case;
        lammps::Outputs {
            n_steps: c.n_steps,
            intruder_every: c.output_every,
            snapshot_every: c.energy_every,
            header: self.header(u),
            fields: snapshot_steps(c),
            tracers: u
                .scene
                .tracers
                .iter()
                .map(|&k| u.scene.sys.disks[k].id)
                .collect(),
        }
    }

    fn header(&self, u: &Unit) -> Header {
        let c = &self.case;
        let s = &c.scales;
        let v = &u.variant;
        let shape = match c.shape {
            IntruderShape::Disk { radius } => {
                format!("a disk of diameter {} d", approx(2.0 * radius / s.d))
            }
            IntruderShape::Ellipse { a, b, count } => format!(
                "an ellipse of semi-axes {} d and {} d (a rigid cluster of {count} disks on its \
                 outline, Kondic et al. Sec. III A)",
                approx(a / s.d),
                approx(b / s.d)
            ),
        };
        let friction = |m: &crate::case::impact2d::Material2d| match m.friction {
            crate::case::impact2d::Friction::Static => "static (model 1, k_t = 0.8 k_n)",
            crate::case::impact2d::Friction::Kinetic => "kinetic (model 2, k_t = 0)",
        };
        Header {
            title: format!(
                "granval impact2d case `{}`, variant `{}`: LAMMPS input deck ({})",
                safe(&c.name),
                safe(&v.label),
                lammps::DECK_FILE
            ),
            paragraphs: vec![
                safe(&c.description),
                format!(
                    "Kondic et al. (PRE 85, 011305) Sec. II: {} grains of mean diameter d = {} m \
                     (polydispersity +-{}), {} bed, {} d long with periodic sides, between rows \
                     of frozen wall disks; {shape} hits the middle of the surface at v = {} \
                     d/tau_c from {} d above it.",
                    c.bed_of(v).count,
                    num(s.d),
                    approx(c.polydispersity),
                    match v.packing {
                        Packing::Random => "random",
                        Packing::Hexagonal => "hexagonal",
                    },
                    approx(c.bed_of(v).length / s.d),
                    approx(v.speed / s.velocity()),
                    approx(c.release_height / s.d),
                ),
                format!(
                    "Kondic et al.'s units, converted once to SI: length d = {} m, mass m = {} \
                     kg (a grain of diameter d), time tau_c = pi sqrt(d / (2 g0 k_n)) = {} s \
                     (binary collision time, g0 = {} m/s^2); a spring constant k_n stands for \
                     k = k_n m g0 / d N/m. Grains: k_n = {}, e_n = {}, mu = {}, {} friction; \
                     walls: k_n = {}, e_n = {}, mu = {}; intruder: k_n = {}, e_n = {}, mu = {}; \
                     gravity {} g0.",
                    num(s.d),
                    num(s.m),
                    approx(s.tau_c),
                    num(s.g0),
                    approx(v.grains.k_n),
                    approx(v.grains.e_n),
                    approx(v.grains.mu),
                    friction(&v.grains),
                    approx(v.walls.k_n),
                    approx(v.walls.e_n),
                    approx(v.walls.mu),
                    approx(v.intruder.k_n),
                    approx(v.intruder.e_n),
                    approx(v.intruder.mu),
                    approx(v.gravity / s.g0),
                ),
                format!(
                    "Measured: the penetration depth D(t) of the intruder's lowest point below \
                     the surface and the final depth, the mean over the last {} tau_c (Kondic \
                     et al. Figs 2, 8); granval compares both with its native engine.{}",
                    approx(c.final_window / s.tau_c),
                    if c.track_interface {
                        " Also the height of the interface (Kondic et al. Fig 12): the centre \
                         of mass in y of the grains within 2 d of the surface and at least L/4 \
                         from the impact point, for the depth below the moving interface."
                    } else {
                        ""
                    }
                ),
            ],
        }
    }
}

/// The scene the native engine starts from for unit `u` under `pert` (before
/// [`scene_mod::perturbed`] changes the coefficients): the base case's for
/// `sweep_ignored`, the intruder slowed by `other_size_speed_factor` in the variants of
/// another size than the first (K Fig 11's control), the first variant's for
/// `packing_ignored`, else the unit's own.
pub fn control_scene<'a>(
    case: &Impact2dCase,
    u: &'a Unit,
    pert: &crate::case::Perturbation,
) -> Result<std::borrow::Cow<'a, Scene>> {
    use std::borrow::Cow;
    if pert.sweep_ignored {
        return Ok(Cow::Borrowed(
            u.base_scene
                .as_ref()
                .context("a sweep_ignored control needs the base scene")?,
        ));
    }
    if pert.packing_ignored {
        return Ok(Cow::Borrowed(u.first_scene.as_deref().context(
            "a packing_ignored control needs the first variant's scene",
        )?));
    }
    if pert.other_size_speed_factor != 1.0 && case.is_other_size(&u.variant) {
        return Ok(Cow::Owned(scene_mod::with_intruder_speed(
            &u.scene,
            pert.other_size_speed_factor,
        )));
    }
    Ok(Cow::Borrowed(&u.scene))
}

/// Heights of a run on `ran` moved into the frame of `unit`, whose surface the analysis
/// measures depth from: a `packing_ignored` control runs another variant's bed, whose
/// surface lies elsewhere, and its depth must be the depth below the bed it ran on.
/// The identity whenever the two surfaces agree (every other run).
fn in_unit_frame(
    mut samples: Vec<IntruderSample>,
    ran: &Scene,
    unit: &Scene,
) -> Vec<IntruderSample> {
    let shift = unit.surface - ran.surface;
    if shift != 0.0 {
        for p in &mut samples {
            p.x[1] += shift;
            if let Some(y) = &mut p.interface_y {
                *y += shift;
            }
        }
    }
    samples
}

/// The beds a case needs, one per distinct bed (packing, count, length, seed), in
/// first-use order.
pub struct Beds {
    pub beds: Vec<(BedKey, Bed)>,
    /// The keys of the beds read from a reference record rather than prepared.
    pub recorded: Vec<BedKey>,
    /// Beds read from another case's sealed record (the same specification), with
    /// that record's name; prepared, as far as this case's record goes.
    pub(crate) from_other: Vec<(BedKey, String)>,
}

impl Beds {
    pub fn from_record(&self, k: &BedKey) -> bool {
        self.recorded.contains(k)
    }

    /// Where the bed came from when it was not settled here, for its note.
    fn origin_note(&self, k: &BedKey) -> String {
        if self.from_record(k) {
            return super::bed_cache::FROM_RECORD_NOTE.to_string();
        }
        match self.from_other.iter().find(|(key, _)| key == k) {
            Some((_, from)) => format!(
                "; taken from the sealed reference record of {from}, made from this very bed specification (not settled again here)"
            ),
            None => String::new(),
        }
    }

    pub fn get(&self, k: &BedKey) -> &Bed {
        &self
            .beds
            .iter()
            .find(|b| b.0 == *k)
            .expect("bed prepared for every variant's bed key")
            .1
    }
}

pub fn bed_note(case: &Impact2dCase, k: &BedKey, b: &Bed) -> String {
    let s = &case.scales;
    let size = if case.sweep_parameter.as_deref() == Some("bed") || case.is_ensemble() {
        format!(
            ", {} disks poured on L = {} d, seed {}",
            k.count,
            k.length / s.d,
            k.seed
        )
    } else {
        String::new()
    };
    let size = match &k.settled_with {
        Some(m) => format!(
            "{size}, settled with the variant's materials ({:?} friction, grains mu {} e_n {}, walls mu {} e_n {})",
            m.grains.friction, m.grains.mu, m.grains.e_n, m.walls.mu, m.walls.e_n
        ),
        None => size,
    };
    format!(
        "{} bed ({:?}{size}): {} grains ({} removed by smoothing), settled in {:.0} tau_c to total KE {:.2e} m g d, packing fraction {:.3}, surface at {:.2} d above the floor",
        case.name,
        k.packing,
        b.grains.len(),
        b.removed,
        b.settle_time / s.tau_c,
        b.final_ke / (s.m * s.g0 * s.d),
        b.packing_fraction,
        (b.surface_at(0.5 * k.length, k.length) - b.floor) / s.d
    )
}

/// Beds already prepared in this process, by sha256 of their specification:
/// preparation is deterministic, so cases sharing a bed (a test binary running the
/// CI cases) settle it once.
type BedSlot = std::sync::Arc<std::sync::Mutex<Option<Bed>>>;
static BED_MEMO: std::sync::Mutex<std::collections::BTreeMap<String, BedSlot>> =
    std::sync::Mutex::new(std::collections::BTreeMap::new());

/// The name under which a bed is stored (in the bed cache and in a reference record).
fn bed_file_name(case: &Impact2dCase, key: &BedKey) -> Option<String> {
    super::bed_cache::name("impact2d", &scene_mod::bed_spec(case, key))
}

/// A bed stored in a reference record (`recorded`: the record's root) with the first
/// unit that uses it (in its directory or, by its sealed hash, in the bed store). Reading it before the seal is verified is safe: the comparison
/// goes on only if every unit's scene, built from it, has the fingerprint the seal
/// holds, i.e. is bit for bit the input the reference engine ran from.
fn recorded_bed(case: &Impact2dCase, key: &BedKey, recorded: &Path) -> Option<Bed> {
    let first = case.variants.iter().find(|v| case.bed_of(v) == *key)?;
    let file = super::reference::store::recorded_bed_file(
        recorded,
        &label_dir(first),
        &bed_file_name(case, key)?,
    )?;
    super::bed_cache::load::<Bed>(Some(&file))
}

/// The beds of a case: from the sealed record when the comparison will read one
/// (`recorded`) and it holds them; else from this process's memo, the opt-in cache
/// (`GRANVAL_BED_CACHE=DIR`, one JSON file per bed specification: sha256 of the spec
/// and the crate version; tests never set it), another case's sealed record under
/// `reference_root` that holds a bed of the very same specification, or prepared
/// (settling a 6000-disk bed to 1e-10 m g d takes minutes). Preparation is
/// deterministic, so a hit is the bed that would be prepared.
pub fn prepare_beds(
    case: &Impact2dCase,
    progress: bool,
    recorded: Option<&Path>,
    reference_root: Option<&Path>,
) -> Result<Beds> {
    let mut beds: Vec<(BedKey, Bed)> = Vec::new();
    let mut from_record = Vec::new();
    let mut from_other = Vec::new();
    for v in &case.variants {
        let key = case.bed_of(v);
        if beds.iter().any(|b| b.0 == key) {
            continue;
        }
        if let Some(b) = recorded.and_then(|r| recorded_bed(case, &key, r)) {
            from_record.push(key);
            beds.push((key, b));
            continue;
        }
        let spec = scene_mod::bed_spec(case, &key);
        let memo_key =
            Sha256::of(serde_json::to_string(&spec).unwrap_or_default().as_bytes()).to_string();
        let slot = {
            let mut memo = BED_MEMO.lock().unwrap_or_else(|p| p.into_inner());
            memo.entry(memo_key).or_default().clone()
        };
        // Held while preparing, so a second case needing this bed waits for it.
        let mut slot = slot.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(b) = slot.as_ref() {
            beds.push((key, b.clone()));
            continue;
        }
        let cache = super::bed_cache::file("impact2d", &spec);
        // The seal names the whole bed specification (count, seed, packing): a 2D bed
        // loses grains to smoothing, so its size alone says nothing more.
        let cached = super::bed_cache::load_cached::<Bed>(cache.as_deref(), &spec, |_| Ok(()))?;
        let other = match (&cached, reference_root) {
            (None, Some(root)) => other_record_bed(case, &key, root),
            _ => None,
        };
        let b = match (cached, other) {
            (Some(b), _) => b,
            (None, Some((b, from))) => {
                super::bed_cache::store(cache.as_deref(), &spec, &b);
                from_other.push((key, from));
                b
            }
            (None, None) => {
                let bar = crate::report::progress::status(progress, "settle");
                let scale = case.scales.m * case.scales.g0 * case.scales.d;
                let tau = case.scales.tau_c;
                // A long settling keeps checkpoints beside the cache and continues from
                // them (`settle_checkpoint`); without a cache it starts from the pour.
                let mut file = super::settle_checkpoint::CheckpointFile::for_spec(&spec, progress);
                let mut none = bed::NoCheckpoints;
                let ckpt: &mut dyn bed::Checkpoints = match file.as_mut() {
                    Some(f) => f,
                    None => &mut none,
                };
                let b = bed::prepare_resumable(&spec, ckpt, |t, ke| {
                    bar.set_message(format!(
                        "t = {:.0} tau_c, KE = {:.1e} m g d",
                        t / tau,
                        ke / scale
                    ))
                })
                .with_context(|| {
                    format!(
                        "{}: preparing the {:?} bed of {} disks on L = {} d, seed {}",
                        case.source.display(),
                        key.packing,
                        key.count,
                        key.length / case.scales.d,
                        key.seed
                    )
                })?;
                bar.finish_and_clear();
                super::bed_cache::store(cache.as_deref(), &spec, &b);
                if let (Some(f), Some(c)) = (file, cache.as_deref())
                    && c.exists()
                {
                    f.finished();
                }
                b
            }
        };
        *slot = Some(b.clone());
        beds.push((key, b));
    }
    Ok(Beds {
        beds,
        recorded: from_record,
        from_other,
    })
}

/// The bed of `key` from another case's sealed record under `reference_root` that
/// holds it under the same file name, i.e. the same specification
/// ([`super::reference::store::bed_in_other_records`]), with that record's name.
fn other_record_bed(
    case: &Impact2dCase,
    key: &BedKey,
    reference_root: &Path,
) -> Option<(Bed, String)> {
    let name = bed_file_name(case, key)?;
    let (file, from) = super::reference::store::bed_in_other_records(
        reference_root,
        "impact2d",
        &case.name,
        &name,
    )?;
    Some((super::bed_cache::load::<Bed>(Some(&file))?, from))
}

/// Energies: walls frozen; wall-wall and (cluster) intruder-intruder pairs excluded.
pub(crate) fn energy_model(scene: &Scene) -> EnergyModel {
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
/// position and velocity, full precision; comments left out) and coefficients.
pub(crate) fn scene_hash(scene: &Scene) -> Sha256 {
    let mut text = crate::engines::deck_text::canonical(&lammps::deck::write_data(&scene.sys));
    for c in &scene.sys.coeffs {
        text += &c.fingerprint_line();
    }
    text += &format!("g {:e} dt {:e}\n", scene.sys.gravity, scene.sys.dt);
    Sha256::of(text.as_bytes())
}

/// A time in tau_c as the case file wrote it (a whole number of steps times dt, whose
/// product carries round-off): to 1e-6.
fn round6(t: f64) -> f64 {
    (t * 1e6).round() / 1e6
}

/// The bed snapshots a case asks for (none without `[fields]`).
pub(crate) fn snapshot_steps(case: &Impact2dCase) -> SnapshotSteps {
    case.fields
        .as_ref()
        .map(|f| SnapshotSteps {
            position_steps: f.position_steps(),
            contact_steps: f.network_steps.clone(),
        })
        .unwrap_or_default()
}

/// The fields of one run reduced (K Sec. IV): B0 curves at each network step, the
/// affine field at the affine step; lengths in d.
pub(crate) fn observe_fields(
    case: &Impact2dCase,
    v: &Variant,
    run: &ImpactRun,
) -> Result<Option<FieldObs>> {
    use crate::analysis::{affine, force_network};
    let Some(f) = &case.fields else {
        return Ok(None);
    };
    let (d, tau) = (case.scales.d, case.scales.tau_c);
    let at = |step: u64| {
        run.fields
            .iter()
            .find(|s| s.step == step)
            .with_context(|| format!("no bed snapshot at step {step}"))
    };
    let mut networks = Vec::new();
    for &k in &f.network_steps {
        let s = at(k)?;
        let contacts = s
            .contacts
            .as_ref()
            .with_context(|| format!("the snapshot at step {k} has no contacts"))?;
        let ids: Vec<u64> = s.grains.iter().map(|g| g.id).collect();
        let net = force_network::Network::new(&ids, contacts);
        networks.push((
            round6(k as f64 * case.dt / tau),
            force_network::curves(&net, f.threshold_max, f.threshold_step)
                .with_context(|| format!("B0 at step {k}"))?,
        ));
    }
    let (mut summary, mut map, mut affine_t) = (None, Vec::new(), f64::NAN);
    if let Some((a, b, radius)) = f.affine {
        let field = affine::field(
            &at(a)?.grains,
            &at(b)?.grains,
            radius,
            Some(case.bed_of(v).length),
        )
        .with_context(|| format!("affine field between steps {a} and {b}"))?;
        summary = Some(affine::summary(&field, d));
        map = field
            .grains
            .iter()
            .map(|g| affine::AffineGrain {
                id: g.id,
                x: [g.x[0] / d, g.x[1] / d],
                af: [g.af[0] / d, g.af[1] / d],
                d2min: g.d2min / (d * d),
            })
            .collect();
        affine_t = round6(b as f64 * case.dt / tau);
    }
    Ok(Some(FieldObs {
        networks,
        affine: summary,
        affine_t,
        affine_map: map,
    }))
}

/// Final and maximum depth (in d) of one run.
pub fn observe(
    case: &Impact2dCase,
    v: &Variant,
    scene: &Scene,
    run: &ImpactRun,
) -> Result<(VariantObs, Vec<(f64, f64)>)> {
    let d = case.scales.d;
    let series = obs::depth(&run.samples, scene.surface, scene.bottom_offset);
    let fin = obs::final_depth(&series, case.final_window)?;
    // The first sample at the maximum depth (time since release).
    let (t_max, max) = series
        .iter()
        .fold((0.0, f64::NEG_INFINITY), |(tm, m), &(t, z)| {
            if z > m { (t, z) } else { (tm, m) }
        });
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
            t_max_depth: t_max / case.scales.tau_c,
            energy: {
                let e_unit = case.scales.m * case.scales.g0 * d;
                let rel = obs::relative_potential(&run.energy);
                run.energy
                    .iter()
                    .zip(rel)
                    .map(|(s, p)| {
                        (
                            s.t / case.scales.tau_c,
                            (s.kinetic + p + s.elastic) / e_unit,
                        )
                    })
                    .collect()
            },
            impact_energy: 0.5 * case.intruder_mass * v.speed.powi(2)
                / (case.scales.m * case.scales.g0 * d),
            final_speed,
            final_samples: obs::final_window_samples(&series, case.final_window),
            trajectory: {
                let (tau, vel) = (case.scales.tau_c, case.scales.velocity());
                series
                    .iter()
                    .zip(&run.samples)
                    .map(|(&(t, z), s)| (t / tau, z / d, -s.v[1] / vel))
                    .collect()
            },
            force: {
                let (tau, weight) = (case.scales.tau_c, case.scales.m * case.scales.g0);
                run.samples
                    .iter()
                    .map(|s| (s.t / tau, s.f[1] / weight))
                    .collect()
            },
            fields: observe_fields(case, v, run)?,
            interface: if case.track_interface {
                Some(observe_interface(case, scene, run, &series)?)
            } else {
                None
            },
        },
        series,
    ))
}

/// The depth below the moving interface of one run (K Fig 12; docs/impact2d.md rules
/// 2 and 4): s(t), D_rel(t) and the oscillations of D and D_rel over the final window,
/// lengths in d, times in tau_c. `depth` is D(t) in m.
pub(crate) fn observe_interface(
    case: &Impact2dCase,
    scene: &Scene,
    run: &ImpactRun,
    depth: &[(f64, f64)],
) -> Result<crate::compare::interface::InterfaceObs> {
    use crate::analysis::interface::{oscillation, relative_depth, shift};
    let (d, tau) = (case.scales.d, case.scales.tau_c);
    let scaled = |s: &[(f64, f64)]| s.iter().map(|p| (p.0 / tau, p.1 / d)).collect::<Vec<_>>();
    // In SI over the final window, so that its samples are exactly the final depth's.
    let osc = |x: &[(f64, f64)]| -> Result<crate::analysis::interface::Oscillation> {
        let o = oscillation(x, case.final_window)?;
        Ok(crate::analysis::interface::Oscillation {
            amplitude: o.amplitude / d,
            period: o.period.map(|p| p / tau),
            ..o
        })
    };
    let s = shift(&run.samples)?;
    let rel = relative_depth(depth, &s)?;
    Ok(crate::compare::interface::InterfaceObs {
        tracers: scene.tracers.len(),
        depth: osc(depth)?,
        relative: osc(&rel)?,
        shift: scaled(&s),
        relative_series: scaled(&rel),
    })
}

/// Directory name of a variant: its label with `=` kept, other odd characters `_`.
pub fn label_dir(v: &Variant) -> String {
    label_dir_str(&v.label)
}

fn label_dir_str(label: &str) -> String {
    label
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "=.-".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The chaos replicas of a Kondic (2D) case (docs/statistics.md, "The chaos baseline"):
/// every variant run natively into `out/prepared/LABEL` and again, with `replica` as its
/// perturbation (`granval chaos`: [`chaos::one_ulp`], every bed disk moved by one ulp in
/// x), into `out/nudged/LABEL`, reduced to the final depths and their differences.
/// With no perturbation the replica is the original run again and every c_k must be
/// exactly 0 (the engine is deterministic, so any chaos the one-ulp replica shows is the
/// nudge's).
pub fn chaos_replicas(
    exp: &Impact2d,
    family: &str,
    replica: &Perturbation,
    opts: &Options,
    out: &Path,
) -> Result<chaos::ChaosRecord> {
    let case = &exp.case;
    let units = chaos::units_from_record(exp, opts)?;
    anyhow::ensure!(
        units.len() >= 2,
        "{}: a chaos spread needs at least two variants (a sweep or seed ensemble); the case has {}",
        case.source.display(),
        units.len()
    );
    let same = Perturbation::default();
    let (mut depth, mut depth_nudged) = (Vec::new(), Vec::new());
    for u in &units {
        let t = std::time::Instant::now();
        let name = label_dir(&u.variant);
        let final_depth = |role: Role, dir: &str| -> Result<f64> {
            let run = exp.run_native(u, role, &out.join(dir).join(&name), opts)?;
            let (o, _) = observe(case, &u.variant, &u.scene, &run)
                .with_context(|| format!("{}: variant {}", case.name, u.variant.label))?;
            Ok(o.final_depth)
        };
        let a = final_depth(Role::Control(&same), "prepared")?;
        let b = final_depth(Role::Control(replica), "nudged")?;
        eprintln!(
            "   {}: both replicas in {:.0} s",
            u.variant.label,
            t.elapsed().as_secs_f64()
        );
        depth.push(a);
        depth_nudged.push(b);
    }
    let depth_difference = depth
        .iter()
        .zip(&depth_nudged)
        .map(|(a, b)| a - b)
        .collect();
    Ok(chaos::ChaosRecord {
        case: case.name.clone(),
        canonical_hash: case.canonical_hash().to_string(),
        family: family.to_string(),
        kind: chaos::IMPACT2D.to_string(),
        bed_hashes: units
            .iter()
            .map(|u| scene_hash(&u.scene).to_string())
            .collect(),
        variants: units.iter().map(|u| u.variant.label.clone()).collect(),
        fit_h: None,
        k_phi: Vec::new(),
        k_phi_nudged: Vec::new(),
        log_ratio: Vec::new(),
        final_depth: depth,
        final_depth_nudged: depth_nudged,
        depth_difference,
        granval: env!("CARGO_PKG_VERSION").to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The engine pairs of a final-depth file: by label whatever the order, only from the
    /// case version named; another version's file and one that names none are refused.
    #[test]
    fn final_depths_pair_by_variant_and_name_their_case_version() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join(FINAL_DEPTHS_FILE);
        let obs = |l: &str, d: f64| serde_json::json!({"label": l, "final_depth": d});
        let write = |hash: Option<&str>| {
            let mut v = serde_json::json!({
                "native": [obs("a", 13.0), obs("b", 12.5)],
                "lammps": [obs("b", 12.25), obs("a", 13.5)],
            });
            if let Some(h) = hash {
                v["canonical_hash"] = h.into();
            }
            std::fs::write(&f, v.to_string()).unwrap();
        };
        write(Some("abc"));
        assert_eq!(
            read_final_depths(&f, "abc").unwrap(),
            vec![
                ("a".to_string(), 13.0, 13.5),
                ("b".to_string(), 12.5, 12.25)
            ]
        );
        let e = format!("{:#}", read_final_depths(&f, "def").unwrap_err());
        assert!(e.contains("another version") && e.contains("abc"), "{e}");
        write(None);
        let e = format!("{:#}", read_final_depths(&f, "abc").unwrap_err());
        assert!(e.contains("not recorded"), "{e}");
    }

    /// The ensemble figure and table: per engine mean +- SE and the seeds, a text sweep's
    /// axis saying which position is which value.
    #[test]
    fn ensemble_section_draws_and_tabulates_means_with_errors() {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/cases/impact2d/ci.toml"
        ))
        .unwrap()
        .replace("seed = 7", "seeds = [1, 2]")
            + "\n[sweep]\nparameter = \"friction\"\nvalues = [\"static\", \"kinetic\"]\n";
        let case = Impact2dCase::from_toml_str(&text, Path::new("t.toml")).unwrap();
        let stats = |shift: f64| {
            vec![
                ValueStats::new("friction=static", 0.0, vec![(1, 3.0 + shift), (2, 3.4)]),
                ValueStats::new("friction=kinetic", 1.0, vec![(1, 5.0), (2, 5.6 + shift)]),
            ]
        };
        let dir = tempfile::tempdir().unwrap();
        let s = ensemble_section(&case, &stats(0.0), &stats(0.1), dir.path(), None).unwrap();
        assert_eq!(s.figures, [ENSEMBLE_FIGURE]);
        let svg = std::fs::read_to_string(dir.path().join(ENSEMBLE_FIGURE)).unwrap();
        assert!(
            svg.contains("<svg")
                && svg.contains("final depth / d")
                && svg.contains("0 = friction=static, 1 = friction=kinetic")
                && svg.contains("LAMMPS"),
            "{svg}"
        );
        assert!(
            s.body
                .contains("| friction=static | 3.200 +- 0.200 | 3.250 +- 0.150 | 1: 3.000, 2: 3.400 | 1: 3.100, 2: 3.400 |"),
            "{}",
            s.body
        );
    }

    /// Beds another case's sealed record holds under the same specification are taken
    /// from there: the five-seed Fig 9 case (gravity) settles its beds as the five-seed
    /// Fig 6 record's (which Fig 11's share in part), so none is settled again. A
    /// record whose bytes for the bed do not hash to its seal is passed over.
    #[test]
    fn beds_of_the_same_specification_come_from_another_record() {
        let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
        let case = Impact2dCase::load(&root.join("cases/release/kondic-fig9-gravity-5seeds.toml"))
            .unwrap();
        let reference = root.join("reference/release");
        let keys: Vec<BedKey> = {
            let mut k: Vec<BedKey> = case.variants.iter().map(|v| case.bed_of(v)).collect();
            k.dedup();
            k
        };
        for key in &keys {
            let (b, from) = other_record_bed(&case, key, &reference).expect("in a record");
            // The first record by name that seals it (Fig 11's W = 60 runs hold some).
            let sealed =
                std::fs::read_to_string(reference.join("impact2d").join(&from).join("seal.json"))
                    .unwrap();
            assert!(
                sealed.contains(&bed_file_name(&case, key).unwrap()),
                "{from}"
            );
            assert_ne!(from, case.name);
            assert!(b.grains.len() > 5000);
        }
        // Tampered: a copy of the Fig 6 record whose first bed is one byte off.
        let tmp = tempfile::tempdir().unwrap();
        let fig6 = reference.join("impact2d/kondic-fig6-friction-5beds");
        let copy = tmp.path().join("impact2d/kondic-fig6-friction-5beds");
        let name = bed_file_name(&case, &keys[0]).unwrap();
        let seal: crate::experiments::reference::Seal =
            serde_json::from_str(&std::fs::read_to_string(fig6.join("seal.json")).unwrap())
                .unwrap();
        let unit = seal
            .units
            .iter()
            .find(|(_, u)| u.files.contains_key(&name))
            .map(|(n, _)| n.clone())
            .unwrap();
        std::fs::create_dir_all(copy.join(&unit)).unwrap();
        std::fs::copy(fig6.join("seal.json"), copy.join("seal.json")).unwrap();
        let good =
            crate::experiments::reference::store::recorded_bed_file(&fig6, &unit, &name).unwrap();
        let mut bytes = std::fs::read(&good).unwrap();
        let at = bytes.len() / 2;
        bytes[at] = if bytes[at] == b'1' { b'2' } else { b'1' };
        std::fs::write(copy.join(&unit).join(&name), bytes).unwrap();
        assert!(other_record_bed(&case, &keys[0], tmp.path()).is_none());
        // The genuine bytes there: found again.
        std::fs::copy(&good, copy.join(&unit).join(&name)).unwrap();
        let (_, from) = other_record_bed(&case, &keys[0], tmp.path()).unwrap();
        assert_eq!(from, "kondic-fig6-friction-5beds");
        // The case's own record is never searched as "another".
        let own = Impact2dCase {
            name: "kondic-fig6-friction-5beds".into(),
            ..case.clone()
        };
        assert!(other_record_bed(&own, &keys[0], tmp.path()).is_none());
    }
}
