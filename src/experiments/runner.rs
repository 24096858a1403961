//! The one runner: for any [`Experiment`], resolve the reference source (live, sealed
//! record, or error), run both engines unit by unit into the output directory, compute
//! the checks, run the case's negative controls against the same reference runs, and
//! turn every failure into an error check — never a pass.

use super::reference::store as record_store;
use super::reference::{self, RefMode, Source};
use super::{Experiment, Options, Role, Run};
use crate::case::NegativeControl;
use crate::compare::{Check, Gate, Status};
use crate::engines::children::OwnedDir;
use crate::report::CaseRun;
use crate::rundata::provenance::Sha256;
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};

/// What one case contributed to a report.
#[derive(Debug, Default)]
pub struct CaseOutcome {
    pub checks: Vec<Check>,
    pub run: Option<CaseRun>,
    pub notes: Vec<String>,
    /// Report sections of the case, figures relative to the case's output directory.
    pub sections: Vec<crate::report::Section>,
}

impl CaseOutcome {
    /// Names `case` as the case of every check that has none (JUnit's classname); the
    /// claims across cases added by a suite stay unnamed.
    pub fn for_case(mut self, case: &str) -> CaseOutcome {
        for c in &mut self.checks {
            if c.case.is_empty() {
                c.case = case.to_string();
            }
        }
        self
    }

    fn error(name: &str, what: &str, e: anyhow::Error, notes: Vec<String>) -> CaseOutcome {
        CaseOutcome {
            checks: vec![Check::error(format!("{name}: {what}"), format!("{e:#}"))],
            run: None,
            notes,
            sections: Vec::new(),
        }
        .for_case(name)
    }
}

/// Output directory of a unit (`""`: the directory itself).
pub fn unit_out(out: &Path, unit: &str) -> PathBuf {
    reference::unit_dir(out, unit)
}

/// The reference engine's run directory inside a unit's output directory.
pub fn reference_out(
    out: &Path,
    unit: &str,
    exp_engine: crate::rundata::provenance::EngineKind,
) -> PathBuf {
    unit_out(out, unit).join(exp_engine.label().to_lowercase())
}

/// Decides where the reference comes from before anything runs.
pub fn resolve<E: Experiment>(exp: &E, opts: &Options) -> Result<Option<String>> {
    let engine = exp.reference_engine();
    match opts.ref_mode {
        RefMode::Recorded => Ok(None),
        RefMode::Live => match exp.probe_reference()? {
            Some(v) => Ok(Some(v)),
            None => bail!(
                "{engine} is not installed but live engines are required (GRANVAL_REQUIRE_LIVE / --reference-mode live / --require-live)"
            ),
        },
        RefMode::Auto => exp.probe_reference(),
    }
}

fn check_limits<E: Experiment>(exp: &E, opts: &Options) -> Result<()> {
    if opts.allow_large {
        return Ok(());
    }
    if let Some(why) = super::limits::refuse(&exp.estimate(), &exp.source().display().to_string()) {
        bail!("{}: refused before running: {why}", exp.source().display());
    }
    Ok(())
}

/// `granval compare` / `check` for one case.
pub fn compare<E: Experiment>(exp: &E, opts: &Options, out: &Path) -> CaseOutcome {
    let name = exp.name().to_string();
    if let Err(e) = check_limits(exp, opts) {
        return CaseOutcome::error(&name, "resource limits", e, vec![]);
    }
    if let Err(e) = exp.preflight() {
        return CaseOutcome::error(&name, "case", e, vec![]);
    }
    let live = match resolve(exp, opts) {
        Ok(l) => l,
        Err(e) => return CaseOutcome::error(&name, "reference engine", e, vec![]),
    };
    if let Err(e) = std::fs::create_dir_all(out) {
        return CaseOutcome::error(&name, "output directory", e.into(), vec![]);
    }
    // The case file next to its outputs: `granval analyze` re-reads a compare directory.
    if let Err(e) = std::fs::copy(exp.source(), out.join("case.toml")) {
        return CaseOutcome::error(&name, "output directory", e.into(), vec![]);
    }
    let root = reference::record_root(&opts.reference_root, exp.kind(), &name);
    // Without a live engine the reference is the record: inputs it holds (prepared at
    // recording) need not be prepared again; verify() below checks them.
    let unit_opts = Options {
        recorded_inputs: live.is_none().then(|| root.clone()),
        ..opts.clone()
    };
    let units = match exp.units(&unit_opts) {
        Ok(u) => u,
        Err(e) => return CaseOutcome::error(&name, "preparation", e, vec![]),
    };
    let names: Vec<String> = units.iter().map(|u| exp.unit_name(u)).collect();
    let engine = exp.reference_engine();
    let mut notes = Vec::new();
    let source = match live {
        Some(_) => Source::Live,
        None => {
            let fingerprints = match reference::unit_keys(exp, &units) {
                Ok(f) => f,
                Err(e) => return CaseOutcome::error(&name, "reference input", e, vec![]),
            };
            match reference::verify(
                &root,
                exp.source(),
                &exp.canonical_hash(),
                engine,
                &fingerprints,
                &regenerator(exp, &units, &names),
            ) {
                Ok(v) => {
                    notes.push(format!(
                        "{engine} is not used live here: {name} was compared against the RECORDED {engine} run in {} ({}, sealed {}; seal verified: case, engine input and every file)",
                        root.display(),
                        v.seal.engine_version,
                        v.seal.sealed
                    ));
                    Source::Recorded { seal: Box::new(v) }
                }
                Err(e) => {
                    return CaseOutcome::error(
                        &name,
                        "recorded reference",
                        e,
                        vec![format!(
                            "the recorded {engine} reference of {name} cannot be used: this is an error, not a pass"
                        )],
                    );
                }
            }
        }
    };

    run_units(exp, opts, out, &units, &names, source, notes)
}

/// `granval analyze DIR` for a case kind whose deck directories hold one unit each
/// (`DIR/<unit>/`, written by [`deck`]): the reference runs are read from the units'
/// directories, where a person ran the engine by hand (here or on a cluster); the
/// native runs, checks and negative controls are those of [`compare`], so the report
/// is the same. `DIR` may also be a `compare` output directory (the engine's run in
/// `DIR/<unit>/<engine>/`).
pub fn analyze<E: Experiment>(exp: &E, opts: &Options, dir: &Path, out: &Path) -> CaseOutcome {
    let name = exp.name().to_string();
    if let Err(e) = check_limits(exp, opts) {
        return CaseOutcome::error(&name, "resource limits", e, vec![]);
    }
    if let Err(e) = exp.preflight() {
        return CaseOutcome::error(&name, "case", e, vec![]);
    }
    if let Err(e) = std::fs::create_dir_all(out) {
        return CaseOutcome::error(&name, "output directory", e.into(), vec![]);
    }
    let units = match exp.units(opts) {
        Ok(u) => u,
        Err(e) => return CaseOutcome::error(&name, "preparation", e, vec![]),
    };
    let names: Vec<String> = units.iter().map(|u| exp.unit_name(u)).collect();
    let notes = vec![format!(
        "the {} runs were made outside granval in {} (deck directories, checked against the inputs granval writes for this case); not sealed",
        exp.reference_engine(),
        dir.display()
    )];
    run_units(
        exp,
        opts,
        out,
        &units,
        &names,
        Source::RunDir {
            dir: dir.to_path_buf(),
        },
        notes,
    )
}

/// Reference and native runs of every unit, the checks and the negative controls.
fn run_units<E: Experiment>(
    exp: &E,
    opts: &Options,
    out: &Path,
    units: &[E::Unit],
    names: &[String],
    source: Source,
    mut notes: Vec<String>,
) -> CaseOutcome {
    let name = exp.name().to_string();
    let engine = exp.reference_engine();
    let mut refs = Vec::with_capacity(units.len());
    for (u, n) in units.iter().zip(names) {
        let r = match &source {
            Source::Live => exp.run_reference(u, &reference_out(out, n, engine), opts),
            Source::Recorded { seal } => exp.read_record(u, n, seal),
            Source::RunDir { dir } => {
                let compared = reference_out(dir, n, engine);
                let d = if compared.join(exp.deck_files().deck).exists() {
                    compared
                } else {
                    unit_out(dir, n)
                };
                exp.read_run_dir(u, &d)
                    .with_context(|| format!("run directory {}", d.display()))
            }
        };
        match r {
            Ok(r) => refs.push(r),
            Err(e) => {
                notes.push(format!(
                    "the {engine} reference failed for {name}: this is an error, not a pass"
                ));
                return CaseOutcome::error(&name, &unit_label(n, "reference run"), e, notes);
            }
        }
    }
    judge(
        exp,
        opts,
        out,
        Inputs {
            units,
            names,
            refs: &refs,
        },
        &source,
        notes,
    )
}

/// The native runs of every unit against reference runs already read, the checks and
/// the negative controls: the part of a comparison after the reference side, shared by
/// [`run_units`] and by readers of run directories that build their units from what
/// the directory holds (a penetration deck directory holds its beds).
pub(crate) fn judge<E: Experiment>(
    exp: &E,
    opts: &Options,
    out: &Path,
    inputs: Inputs<E>,
    source: &Source,
    mut notes: Vec<String>,
) -> CaseOutcome {
    let Inputs { units, names, refs } = inputs;
    let name = exp.name().to_string();
    let engine = exp.reference_engine();
    let mut natives = Vec::with_capacity(units.len());
    for (u, n) in units.iter().zip(names) {
        match exp.run_native(u, Role::Main, &unit_out(out, n).join("native"), opts) {
            Ok(r) => natives.push(r),
            Err(e) => return CaseOutcome::error(&name, &unit_label(n, "native run"), e, notes),
        }
    }

    let started = std::time::Instant::now();
    let verdict = exp.checks(units, &natives, refs, out, opts);
    let mut checks = verdict.checks;
    // One evaluation produced all these verdicts: each gets an equal share of its time.
    let share = started.elapsed().as_secs_f64() / checks.len().max(1) as f64;
    for c in &mut checks {
        c.time_s = Some(share);
    }
    notes.extend(verdict.notes);
    let sections = verdict.sections;
    let failed_here: Vec<String> = checks
        .iter()
        .filter(|k| k.status == Status::Fail)
        .map(|k| k.name.clone())
        .collect();
    for (k, c) in exp.negative_controls().iter().enumerate() {
        let dir = out.join(format!("control-{k}"));
        let started = std::time::Instant::now();
        let mut check = negative_control(
            exp,
            c,
            Inputs { units, names, refs },
            &failed_here,
            &dir,
            opts,
        );
        check.time_s = Some(started.elapsed().as_secs_f64());
        checks.push(check);
    }
    let wall = |rs: &mut dyn Iterator<Item = f64>| rs.sum::<f64>();
    let run = CaseRun {
        case: name.clone(),
        case_file: exp.source().display().to_string(),
        test_engine: "native".into(),
        reference_engine: engine.to_string(),
        reference_version: refs
            .first()
            .map(|r| r.provenance().version.clone())
            .unwrap_or_default(),
        reference_source: source.describe(),
        wall_time_test_s: wall(&mut natives.iter().map(|r| r.provenance().wall_time_s)),
        wall_time_reference_s: wall(&mut refs.iter().map(|r| r.provenance().wall_time_s)),
    };
    CaseOutcome {
        checks,
        run: Some(run),
        notes,
        sections,
    }
    .for_case(&name)
}

fn unit_label(unit: &str, what: &str) -> String {
    if unit.is_empty() {
        what.into()
    } else {
        format!("{unit} {what}")
    }
}

/// The units of a case, their names and the reference runs a control reuses.
pub(crate) struct Inputs<'a, E: Experiment> {
    pub units: &'a [E::Unit],
    pub names: &'a [String],
    pub refs: &'a [E::RefRun],
}

/// One negative control: the native engine with wrong physics against the same
/// reference runs. It passes only when every gate it names has at least one check with
/// status `fail` that did not fail with the right physics (`failed_here`: the names of
/// the case's own failed checks). A check that fails either way (a claim the reference
/// engine alone fails, a finding) shows nothing about the wrong physics; an error or a
/// not-compared check is not the control biting either.
fn negative_control<E: Experiment>(
    exp: &E,
    c: &NegativeControl,
    inputs: Inputs<E>,
    failed_here: &[String],
    dir: &Path,
    opts: &Options,
) -> Check {
    let Inputs { units, names, refs } = inputs;
    let label = format!("{}: negative control \"{}\"", exp.name(), c.name);
    let mut natives = Vec::with_capacity(units.len());
    for (u, n) in units.iter().zip(names) {
        match exp.run_native(
            u,
            Role::Control(&c.perturbation),
            &unit_out(dir, n).join("native"),
            opts,
        ) {
            Ok(r) => natives.push(r),
            Err(e) => return Check::error_in(label, Gate::NegativeControl, format!("{e:#}")),
        }
    }
    let opts = Options {
        control: Some(c.perturbation.to_string()),
        ..opts.clone()
    };
    let verdict = exp.checks(units, &natives, refs, dir, &opts);
    control_check(label, c, &verdict, failed_here)
}

/// The control's check from the verdict of its wrong-physics runs. The gates the
/// verdict could not evaluate in this mode are left out, named in the detail; a control
/// none of whose gates was evaluated is NOT COMPARED, never a pass.
fn control_check(
    label: String,
    c: &NegativeControl,
    verdict: &super::Verdict,
    failed_here: &[String],
) -> Check {
    let (asked, skipped): (Vec<Gate>, Vec<Gate>) = c
        .must_fail
        .iter()
        .partition(|g| !verdict.unevaluated.iter().any(|(u, _)| u == *g));
    let (missing, mut summary) = unbitten(&asked, &verdict.checks, failed_here);
    for g in &skipped {
        let why = verdict
            .unevaluated
            .iter()
            .find(|(u, _)| u == g)
            .map_or("", |(_, w)| w.as_str());
        summary.push(format!("{}: not evaluated here ({why})", g.key()));
    }
    let detail = format!("perturbation: {}; {}", c.perturbation, summary.join(" | "));
    if asked.is_empty() {
        return Check::not_compared(
            label,
            Gate::NegativeControl,
            format!("none of its gates is evaluated here: {detail}"),
        );
    }
    // A gate the wrong physics left INCONCLUSIVE (none of its checks failed, at least
    // one is undecided) has not shown the control biting nor failing to: the data cannot
    // tell (docs/statistics.md, "Negative controls"). A gate passes only when every check
    // of it passes: a claim gate also holds claims stated of each run (the energy never
    // rises), which pass whatever the sweep, beside the between-conditions claim a sweep
    // control is aimed at.
    let undecided = |g: &String| {
        verdict
            .checks
            .iter()
            .any(|k| k.gate.key() == *g && k.status == Status::Inconclusive)
    };
    if !missing.is_empty() && missing.iter().all(undecided) {
        return Check::control_unresolved(label, &missing, detail);
    }
    Check::control(label, &missing, detail)
}

/// The gates of `must_fail` that the control's `checks` do not bite, and a summary per
/// gate. A gate is bitten by a check of it that fails here and did not fail with the right
/// physics (`failed_here`).
fn unbitten(
    must_fail: &[Gate],
    checks: &[Check],
    failed_here: &[String],
) -> (Vec<String>, Vec<String>) {
    let mut missing = Vec::new();
    let mut summary = Vec::new();
    for g in must_fail {
        let of_gate: Vec<&Check> = checks.iter().filter(|k| k.gate == *g).collect();
        let anyway = |k: &Check| failed_here.contains(&k.name);
        let failed = of_gate
            .iter()
            .filter(|k| k.status == Status::Fail && !anyway(k))
            .count();
        let failed_anyway = of_gate
            .iter()
            .filter(|k| k.status == Status::Fail && anyway(k))
            .count();
        summary.push(format!(
            "{}: {failed} of {} check(s) failed where the right physics did not ({failed_anyway} failed with both: not counted) ({})",
            g.key(),
            of_gate.len(),
            of_gate
                .iter()
                .map(|k| match k.status {
                    Status::NotCompared | Status::Inconclusive | Status::Error => format!(
                        "{}: {}",
                        k.status.label(),
                        k.detail.chars().take(400).collect::<String>()
                    ),
                    _ => format!(
                        "{} = {} vs {}",
                        k.metric,
                        crate::numerics::fmt::number(k.value),
                        crate::numerics::fmt::number(k.tolerance)
                    ),
                })
                .collect::<Vec<_>>()
                .join("; ")
        ));
        if failed == 0 {
            missing.push(g.key());
        }
    }
    (missing, summary)
}

/// `granval run --engine native|<reference>`: one engine, every unit, into `out`.
pub fn run_one<E: Experiment>(
    exp: &E,
    native: bool,
    opts: &Options,
    out: &Path,
) -> Result<Vec<String>> {
    check_limits(exp, opts)?;
    let units = exp.units(opts)?;
    let mut lines = Vec::new();
    for u in &units {
        let n = exp.unit_name(u);
        let dir = unit_out(out, &n);
        let p = if native {
            exp.run_native(u, Role::Main, &dir, opts)?
                .provenance()
                .clone()
        } else {
            if resolve(
                exp,
                &Options {
                    ref_mode: RefMode::Live,
                    ..opts.clone()
                },
            )?
            .is_none()
            {
                bail!("{} is not installed", exp.reference_engine());
            }
            exp.preflight()?;
            exp.run_reference(u, &dir, opts)?.provenance().clone()
        };
        lines.push(format!(
            "{:<24} {} ({}, {:.1} s) -> {}",
            if n.is_empty() { exp.name() } else { &n },
            p.engine,
            p.version,
            p.wall_time_s,
            dir.display()
        ));
    }
    Ok(lines)
}

/// `granval reference refresh`: every unit in the live reference engine, recorded under
/// `reference/<kind>/<case>/` and sealed; the drift against the previous record is
/// returned line by line. The new record replaces the old one only when complete.
pub fn refresh<E: Experiment>(exp: &E, opts: &Options) -> Result<Vec<String>> {
    let engine = exp.reference_engine();
    let name = exp.name();
    exp.preflight()?;
    reference::refuse_other_case_file(
        &reference::record_root(&opts.reference_root, exp.kind(), name),
        exp.source(),
        name,
    )?;
    let version = exp.probe_reference()?.with_context(|| {
        format!("reference refresh needs a live {engine}: it records what the real engine computes")
    })?;
    let units = exp.units(opts)?;
    let names: Vec<String> = units.iter().map(|u| exp.unit_name(u)).collect();
    let fingerprints = reference::unit_keys(exp, &units)?;
    let root = reference::record_root(&opts.reference_root, exp.kind(), name);
    let regenerate = regenerator(exp, &units, &names);
    let previous = reference::verify(
        &root,
        exp.source(),
        &exp.canonical_hash(),
        engine,
        &fingerprints,
        &regenerate,
    );
    let fresh = recording_dir(&root);
    if fresh.exists() {
        std::fs::remove_dir_all(&fresh)
            .with_context(|| format!("cannot clear {}", fresh.display()))?;
    }
    // Both are granval's own: removed on an error or a signal, so an interrupted
    // refresh leaves neither a half record nor its engine runs behind.
    let _recording = OwnedDir::adopt(&fresh);
    let scratch = OwnedDir::temp()?;
    let mut lines = vec![format!("using {version}")];
    for (u, n) in units.iter().zip(&names) {
        let run_dir = unit_out(scratch.path(), n).join("run");
        let run = exp.run_reference(u, &run_dir, opts)?;
        let rec = reference::unit_dir(&fresh, n);
        exp.record(u, &run, &run_dir, &rec)?;
        let drift = match &previous {
            Ok(seal) => match exp.read_record(u, n, seal) {
                Ok(prev) => exp.drift(&prev, &run),
                Err(e) => format!("previous record unreadable: {e:#}"),
            },
            Err(_) if !root.exists() => "new record".into(),
            Err(e) => format!(
                "previous record not usable ({})",
                first_line(&format!("{e:#}"))
            ),
        };
        lines.push(format!(
            "{name} {}: recorded in {:.1} s; drift vs previous record: {drift}",
            if n.is_empty() { "" } else { n },
            run.provenance().wall_time_s
        ));
    }
    std::fs::copy(exp.source(), fresh.join("case.toml"))
        .with_context(|| format!("copying {} into the record", exp.source().display()))?;
    let seal = reference::write(
        &fresh,
        name,
        exp.kind(),
        exp.source(),
        &exp.canonical_hash(),
        engine,
        &version,
        &fingerprints,
    )?;
    // Sealed with every file present; then the beds go to the store and the files
    // granval writes itself are left out (each only if it is written again exactly).
    lines.extend(record_store::make_lean(
        &fresh,
        &seal,
        &regenerate,
        record_store::BedPlacement::Store,
    )?);
    if root.exists() {
        std::fs::remove_dir_all(&root)
            .with_context(|| format!("cannot replace {}", root.display()))?;
    }
    std::fs::rename(&fresh, &root)
        .with_context(|| format!("cannot move {} to {}", fresh.display(), root.display()))?;
    lines.push(format!(
        "sealed {}",
        root.join(reference::SEAL_FILE).display()
    ));
    Ok(lines)
}

/// The units of a case's record as a recorded comparison prepares them (beds from the
/// record, or settled natively for records that hold none), with their names and seal
/// keys; `None` when the case has no record.
struct RecordedUnits<U> {
    root: PathBuf,
    units: Vec<U>,
    names: Vec<String>,
    fingerprints: Vec<reference::UnitKey>,
}

impl<U> RecordedUnits<U> {
    /// The record checked against these units: case, fingerprints and every sealed file,
    /// data files written again from the units' beds ([`reference::verify`]).
    fn verify<E: Experiment<Unit = U>>(&self, exp: &E) -> Result<reference::Verified> {
        let regenerate = regenerator(exp, &self.units, &self.names);
        reference::verify(
            &self.root,
            exp.source(),
            &exp.canonical_hash(),
            exp.reference_engine(),
            &self.fingerprints,
            &regenerate,
        )
    }
}

fn recorded_units<E: Experiment>(
    exp: &E,
    opts: &Options,
) -> Result<Option<RecordedUnits<E::Unit>>> {
    let root = reference::record_root(&opts.reference_root, exp.kind(), exp.name());
    if !root.join(reference::SEAL_FILE).exists() {
        return Ok(None);
    }
    let units = exp.units(&Options {
        recorded_inputs: Some(root.clone()),
        ..opts.clone()
    })?;
    let names: Vec<String> = units.iter().map(|u| exp.unit_name(u)).collect();
    let fingerprints = reference::unit_keys(exp, &units)?;
    Ok(Some(RecordedUnits {
        root,
        units,
        names,
        fingerprints,
    }))
}

/// `granval reference lean`: a committed record made lean in place, as `refresh` makes
/// a new one ([`record_store::make_lean`]). The record must verify first (nothing of a
/// record that does not is touched) and verifies again after. Data files are left out
/// only in units whose bed the record holds: a unit whose bed is settled anew on every
/// use would turn each later read of the record into a settling. Beds stay in their
/// unit directories ([`record_store::BedPlacement::InPlace`]); a record that holds no
/// bed is only compressed ([`compress_record`]). Returns what was done, or `None` when
/// the case has no record.
///
/// With `add_beds`, a record that holds no bed gets its beds first ([`add_beds`]) and
/// is then made lean as a new record is (beds in the store, data files left out).
pub fn lean_record<E: Experiment>(
    exp: &E,
    opts: &Options,
    add_beds: bool,
) -> Result<Option<Vec<String>>> {
    let name = exp.name();
    let root = reference::record_root(&opts.reference_root, exp.kind(), exp.name());
    if root.join(reference::SEAL_FILE).exists() {
        let seal = reference::read_seal(
            &root,
            exp.source(),
            &exp.canonical_hash(),
            exp.reference_engine(),
        )?;
        let holds_a_bed = seal
            .units
            .values()
            .any(|u| u.files.keys().any(|f| record_store::is_bed_file(f)));
        if !holds_a_bed {
            return if add_beds {
                add_beds_and_lean(exp, opts)
            } else {
                compress_record(exp, &root).map(Some)
            };
        }
    }
    let Some(RecordedUnits {
        root,
        units,
        names,
        fingerprints,
    }) = recorded_units(exp, opts)?
    else {
        return Ok(None);
    };
    let regenerate = regenerator(exp, &units, &names);
    let check = |regenerate: record_store::Regenerate| {
        reference::verify(
            &root,
            exp.source(),
            &exp.canonical_hash(),
            exp.reference_engine(),
            &fingerprints,
            regenerate,
        )
    };
    let v = check(&regenerate).with_context(|| {
        format!("{name}: the record does not verify, so nothing of it is made lean")
    })?;
    let bedded: Vec<&str> = v
        .seal
        .units
        .iter()
        .filter(|(_, u)| u.files.keys().any(|f| record_store::is_bed_file(f)))
        .map(|(n, _)| n.as_str())
        .collect();
    let only_bedded = |unit: &str, file: &str| {
        if bedded.contains(&unit) {
            regenerate(unit, file)
        } else {
            None
        }
    };
    let mut lines = record_store::make_lean(
        &root,
        &v.seal,
        &only_bedded,
        record_store::BedPlacement::InPlace,
    )?;
    check(&regenerate).with_context(|| {
        format!(
            "{name}: after making it lean the record no longer verifies (restore it from git: `git checkout -- {}`)",
            root.display()
        )
    })?;
    lines.push(format!(
        "{name}: verified again after ({} of {} unit(s) hold their bed)",
        bedded.len(),
        names.len()
    ));
    Ok(Some(lines))
}

/// `reference lean --add-beds` on a record sealed without its beds: the units are
/// prepared as a recorded comparison prepares them (beds settled again, deterministic,
/// or taken from `GRANVAL_BED_CACHE`), and the whole record must verify with them
/// (each unit's fingerprint, every sealed file). A unit's bed ([`Experiment::bed_file`])
/// is then added to the seal only when every file granval writes from it that the
/// record holds (the engine's data file) is written again byte for byte: the bed is
/// proven to be the one the reference run started from. The seal keeps its time and
/// every file it sealed, and names what was added and why ([`reference::SealAmendment`]).
/// The record is then made lean as `refresh` makes a new one (beds to the store, once
/// by content; data files left out) and verified again, its beds now read from itself.
/// A record none of whose units can be proven this way is only compressed.
fn add_beds_and_lean<E: Experiment>(exp: &E, opts: &Options) -> Result<Option<Vec<String>>> {
    let name = exp.name();
    let Some(recorded) = recorded_units(exp, opts)? else {
        return Ok(None);
    };
    let verified = recorded
        .verify(exp)
        .with_context(|| format!("{name}: the record does not verify, so no bed is added to it"))?;
    let RecordedUnits {
        root, units, names, ..
    } = recorded;
    let regenerate = regenerator(exp, &units, &names);
    let mut seal = verified.seal;
    let mut lines = Vec::new();
    let mut added = Vec::new();
    for (u, unit) in units.iter().zip(&names) {
        let Some(bed) = exp.bed_file(u) else {
            continue;
        };
        let (bed_name, bytes) = bed.with_context(|| format!("{name} {unit}: the bed"))?;
        let sealed = seal
            .units
            .get(unit)
            .with_context(|| format!("{name}: no unit {unit:?} in the seal"))?;
        // The proof: every sealed file the bed writes is written again exactly.
        let mut proven = Vec::new();
        for (file, sha) in &sealed.files {
            match regenerate(unit, file) {
                None => {}
                Some(Ok(b)) if &Sha256::of(&b) == sha => proven.push(file.clone()),
                Some(Ok(b)) => bail!(
                    "{name} {unit}: {file} written again from the prepared bed has sha256 {}, not the sealed {sha}, although the record verified",
                    Sha256::of(&b)
                ),
                Some(Err(e)) => {
                    return Err(e.context(format!("{name} {unit}: writing {file} again")));
                }
            }
        }
        if proven.is_empty() {
            lines.push(format!(
                "{name} {unit}: no bed added (no file of the record is written from it, so nothing proves it)"
            ));
            continue;
        }
        let dir = reference::unit_dir(&root, unit);
        let path = dir.join(&bed_name);
        std::fs::write(&path, &bytes)
            .with_context(|| format!("cannot write {}", path.display()))?;
        let sha = Sha256::of(&bytes);
        lines.push(format!(
            "{name} {unit}: bed {bed_name} added (sha256 {sha}; proven by the unit's sealed fingerprint and {})",
            proven.join(", ")
        ));
        if let Some(u) = seal.units.get_mut(unit) {
            u.files.insert(bed_name.clone(), sha);
        }
        added.push(format!("{unit}/{bed_name}"));
    }
    if added.is_empty() {
        lines.extend(compress_record(exp, &root)?);
        return Ok(Some(lines));
    }
    seal.amendments.push(reference::SealAmendment {
        utc: crate::rundata::provenance::now_utc(),
        granval_commit: crate::rundata::provenance::git_commit(),
        added: added.clone(),
        proof: "each bed prepared again by granval from the case (deterministic; the same preparation the recording used), the units built from it have the sealed fingerprints, and every file of the record granval writes from the bed (the reference engine's data file) is written again with its sealed sha256; the reference engine's outputs and every file sealed before are unchanged".into(),
    });
    reference::write_seal(&root, &seal)?;
    lines.extend(record_store::make_lean(
        &root,
        &seal,
        &regenerate,
        record_store::BedPlacement::Store,
    )?);
    // Verified again as a comparison will read it: beds from the record itself.
    let Some(again) = recorded_units(exp, opts)? else {
        bail!("{name}: the record vanished while it was made lean");
    };
    again.verify(exp).with_context(|| {
        format!(
            "{name}: after adding its beds and making it lean the record no longer verifies (restore it from git: `git checkout -- {}`)",
            root.display()
        )
    })?;
    lines.push(format!(
        "{name}: {} bed(s) added to the seal; verified again after, beds read from the record",
        added.len()
    ));
    Ok(Some(lines))
}

/// A record that holds no bed made lean: nothing can be left out of it (each later use
/// would settle its beds again to write a data file back), so its large files are only
/// kept compressed. What is checked before and after is what compression could break,
/// every sealed file's bytes against the seal ([`reference::verify_files`]); the units'
/// fingerprints are not recomputed, which for a record without beds would mean settling
/// every bed, and compression changes neither the seal nor any input it covers.
fn compress_record<E: Experiment>(exp: &E, root: &Path) -> Result<Vec<String>> {
    let name = exp.name();
    let files = || {
        reference::verify_files(
            root,
            exp.source(),
            &exp.canonical_hash(),
            exp.reference_engine(),
        )
    };
    let seal = files().with_context(|| {
        format!("{name}: the record does not verify, so nothing of it is made lean")
    })?;
    let mut lines = record_store::make_lean(
        root,
        &seal,
        &record_store::nothing_regenerable,
        record_store::BedPlacement::InPlace,
    )?;
    files().with_context(|| {
        format!(
            "{name}: after making it lean the record no longer verifies (restore it from git: `git checkout -- {}`)",
            root.display()
        )
    })?;
    lines.push(format!(
        "{name}: holds no bed, so its files were only compressed; every sealed file verified before and after ({} unit(s))",
        seal.units.len()
    ));
    Ok(lines)
}

/// `granval reference verify`: a case's record checked against its seal without
/// running anything. The units are prepared as a recorded comparison prepares them
/// (beds from the record, or settled natively for records that hold none); their
/// fingerprints and every sealed file are checked, wherever the file's bytes are
/// ([`reference::store`]). Returns what was checked and where the files came from, or
/// `None` when the case has no record at all (nothing to verify).
pub fn verify_record<E: Experiment>(exp: &E, opts: &Options) -> Result<Option<String>> {
    let name = exp.name();
    let Some(RecordedUnits {
        root,
        units,
        names,
        fingerprints,
    }) = recorded_units(exp, opts)?
    else {
        return Ok(None);
    };
    let v = reference::verify(
        &root,
        exp.source(),
        &exp.canonical_hash(),
        exp.reference_engine(),
        &fingerprints,
        &regenerator(exp, &units, &names),
    )?;
    let (mut here, mut packed, mut stored, mut written) = (0, 0, 0, 0);
    for n in &names {
        for (file, sha) in &v.seal.units[n].files {
            match record_store::locate(&root, n, file, sha)? {
                _ if record_store::is_packed(&root, n, file) => packed += 1,
                Some(p) if p.starts_with(&root) => here += 1,
                Some(_) => stored += 1,
                None => written += 1,
            }
        }
    }
    Ok(Some(format!(
        "{name}: verified {} ({} unit(s)): case, engine input, and {} sealed files: {here} in the record, {packed} compressed in the record, {stored} bed(s) from the bed store, {written} written again from the beds",
        root.display(),
        names.len(),
        here + packed + stored + written
    )))
}

/// The record files of `units` (named `names`) that the experiment writes again from
/// the unit itself ([`Experiment::regenerate`]), for a lean record ([`reference::store`]).
pub fn regenerator<'a, E: Experiment>(
    exp: &'a E,
    units: &'a [E::Unit],
    names: &'a [String],
) -> impl Fn(&str, &str) -> Option<Result<Vec<u8>>> + 'a {
    move |unit, file| {
        let i = names.iter().position(|n| n == unit)?;
        exp.regenerate(&units[i], file)
    }
}

/// Where a record is written before it replaces `root`: beside it, the whole name kept
/// (`Path::with_extension` would cut "feng-fig3b-mugg-1.1" and "-1.5" to the same
/// "feng-fig3b-mugg-1.recording").
fn recording_dir(root: &Path) -> PathBuf {
    let mut name = root.file_name().unwrap_or_default().to_os_string();
    name.push(".recording");
    root.with_file_name(name)
}

fn first_line(s: &str) -> &str {
    s.lines().next().unwrap_or(s)
}

/// `granval deck`: the reference engine's input for every unit, without running it.
pub(crate) fn deck<E: Experiment>(exp: &E, opts: &Options, out: &Path) -> Result<Vec<PathBuf>> {
    exp.preflight()?;
    let units = exp.units(opts)?;
    let mut dirs = Vec::new();
    for u in &units {
        let dir = unit_out(out, &exp.unit_name(u));
        exp.write_deck(u, &dir, opts)?;
        dirs.push(dir);
    }
    std::fs::copy(exp.source(), out.join("case.toml"))
        .with_context(|| format!("copying {} into {}", exp.source().display(), out.display()))?;
    let names: Vec<String> = units.iter().map(|u| exp.unit_name(u)).collect();
    let readme = out.join(README_FILE);
    std::fs::write(
        &readme,
        deck_readme(exp, &names, opts.mpi_procs.max(2), opts.viz_every),
    )
    .with_context(|| format!("cannot write {}", readme.display()))?;
    Ok(dirs)
}

/// The README of a deck directory ([`deck`]).
pub(crate) const README_FILE: &str = "README.txt";

/// What a deck directory holds, how to run it on one core and under mpirun, what a
/// complete run leaves behind and how to bring it back (`granval analyze`).
fn deck_readme<E: Experiment>(exp: &E, units: &[String], np: usize, viz: Option<u64>) -> String {
    let f = exp.deck_files();
    let engine = exp.reference_engine();
    let dirs: Vec<String> = units
        .iter()
        .map(|u| if u.is_empty() { ".".into() } else { u.clone() })
        .collect();
    let mut s = format!(
        "{engine} deck directory for the {} case `{}`, written by granval {}.\n\n",
        exp.kind(),
        exp.name(),
        env!("CARGO_PKG_VERSION")
    );
    s += &format!(
        "case.toml is the case file, copied: `granval analyze` reads it. {}\n\n",
        if units.iter().all(|u| u.is_empty()) {
            "The deck is in this directory.".to_string()
        } else {
            format!(
                "Run directories, one independent run (one variant of the case) each: {}.",
                dirs.join(", ")
            )
        }
    );
    s += "Inputs (in each run directory)\n";
    s += &format!(
        "  {:<16} the {engine} input deck: commented block by block, read it first\n",
        f.deck
    );
    for (name, what) in f.inputs {
        s += &format!("  {name:<16} {what}\n");
    }
    s += "\nRun (in each run directory; the inputs are found relative to it)\n";
    s += &format!(
        "  one core:     {} -in {} -log {}\n",
        f.binary, f.deck, f.log
    );
    s += &format!(
        "  {np} MPI ranks:  mpirun -np {np} {} -in {} -log {}\n",
        f.binary, f.deck, f.log
    );
    s += &format!(
        "  (add --allow-run-as-root to mpirun when running as root; the executable may be \
         called differently on your cluster, e.g. lmp_mpi. Another rank count changes the \
         round-off, which a granular flow amplifies: to reproduce `granval compare --np N` \
         bit for bit, run with the same N)\n  for every run directory: for d in {}; do (cd $d && {} -in {} -log {}); done\n",
        dirs.join(" "),
        f.binary,
        f.deck,
        f.log
    );
    s += "\nExpected outputs (in each run directory)\n";
    for (name, what) in f.outputs {
        s += &format!("  {name:<16} {what}\n");
    }
    if let Some(n) = viz {
        let e = match engine {
            crate::rundata::provenance::EngineKind::Liggghts => {
                crate::engines::viz_dump::VizEngine::Liggghts
            }
            _ => crate::engines::viz_dump::VizEngine::Lammps3d,
        };
        s += &format!(
            "\nVisualisation\n  {}\n",
            crate::engines::viz_dump::readme_line(e, n)
        );
    }
    s += "\nBring it back\n  Copy the whole directory back (inputs and outputs) and run\n\n    \
         granval analyze DIR --report OUT\n\n  It checks that every run completed and that \
         its inputs are the ones granval writes for case.toml (comments and number notation \
         aside: edit the case, not the deck), runs granval's native engine on the same \
         input and writes the same report as `granval compare case.toml --report OUT`.\n";
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A control bites only on a check that fails with the wrong physics and did not
    /// with the right physics: a claim the reference engine fails either way is no bite.
    #[test]
    fn a_control_bites_only_where_the_right_physics_did_not_fail() {
        let fail = |n: &str| Check::failed(n, Gate::Claim, "m", 1.0, "");
        let pass = |n: &str| Check::at_most(n, Gate::Claim, "m", 0.0, 1.0, "");
        let control = vec![fail("claim (lammps)"), pass("claim (native)")];
        let (missing, _) = unbitten(&[Gate::Claim], &control, &["claim (lammps)".into()]);
        assert_eq!(missing, vec!["claim".to_string()]);
        let control = vec![fail("claim (lammps)"), fail("claim (native)")];
        let (missing, _) = unbitten(&[Gate::Claim], &control, &["claim (lammps)".into()]);
        assert!(missing.is_empty());
    }

    /// A gate is passed with the wrong physics only when every check of it passes: a
    /// claim gate holding a per-run claim that passes and a between-conditions claim left
    /// INCONCLUSIVE (one bed) makes the control INCONCLUSIVE, not failed; with both
    /// claims passing the control fails, and with the between-conditions claim failing it
    /// bites.
    #[test]
    fn a_control_is_inconclusive_when_its_gate_is_only_partly_decided() {
        let control = NegativeControl {
            name: "sweep ignored".into(),
            perturbation: Default::default(),
            must_fail: vec![Gate::Claim],
        };
        let verdict_of = |between: Check| super::super::Verdict {
            checks: vec![
                Check::at_most("energy never rises", Gate::Claim, "m", 0.0, 1.0, ""),
                between,
            ],
            ..Default::default()
        };
        let judge = |between: Check| control_check("c".into(), &control, &verdict_of(between), &[]);
        let undecided = Check::with_status(
            "lost increases",
            Gate::Claim,
            "m",
            -1.0,
            0.0,
            Status::Inconclusive,
            "one bed",
        );
        assert_eq!(judge(undecided).status, Status::Inconclusive);
        let passes = Check::at_most("lost increases", Gate::Claim, "m", -1.0, 0.0, "");
        assert_eq!(judge(passes).status, Status::Fail);
        let fails = Check::failed("lost increases", Gate::Claim, "m", 1.0, "");
        assert_eq!(judge(fails).status, Status::Pass);
    }

    /// Against a record without snapshots the phi gate is not evaluated: the control is
    /// judged on its other gates (and still fails if they pass), and a control with no
    /// evaluated gate is NOT COMPARED, never a pass.
    #[test]
    fn a_control_skips_only_the_gates_its_verdict_could_not_evaluate() {
        let control = |must_fail: Vec<Gate>| NegativeControl {
            name: "mu_gg = 0.5".into(),
            perturbation: Default::default(),
            must_fail,
        };
        let verdict = |checks: Vec<Check>| super::super::Verdict {
            checks,
            unevaluated: vec![(Gate::Phi, "no snapshots".into())],
            ..Default::default()
        };
        let k_fails = verdict(vec![
            Check::failed("k", Gate::KPhi, "m", 1.0, ""),
            Check::not_compared("phi", Gate::Phi, "no snapshots"),
        ]);
        let c = control_check(
            "c".into(),
            &control(vec![Gate::KPhi, Gate::Phi]),
            &k_fails,
            &[],
        );
        assert_eq!(c.status, Status::Pass);
        assert!(c.detail.contains("phi: not evaluated here (no snapshots)"));
        let k_passes = verdict(vec![Check::at_most("k", Gate::KPhi, "m", 0.0, 1.0, "")]);
        let c = control_check(
            "c".into(),
            &control(vec![Gate::KPhi, Gate::Phi]),
            &k_passes,
            &[],
        );
        assert_eq!(c.status, Status::Fail);
        let c = control_check("c".into(), &control(vec![Gate::Phi]), &k_fails, &[]);
        assert_eq!(c.status, Status::NotCompared);
        // Evaluated gates are judged as before: a phi gate that ran and passed is unbitten.
        let ran = super::super::Verdict {
            checks: vec![Check::at_most("phi", Gate::Phi, "m", 0.0, 1.0, "")],
            ..Default::default()
        };
        let c = control_check("c".into(), &control(vec![Gate::Phi]), &ran, &[]);
        assert_eq!(c.status, Status::Fail);
    }

    /// Cases whose names differ after a dot record into different directories.
    #[test]
    fn recording_dirs_keep_the_whole_case_name() {
        let a = recording_dir(Path::new("r/penetration/feng-fig3b-mugg-1.1"));
        let b = recording_dir(Path::new("r/penetration/feng-fig3b-mugg-1.5"));
        assert_eq!(a, Path::new("r/penetration/feng-fig3b-mugg-1.1.recording"));
        assert_ne!(a, b);
    }
}
