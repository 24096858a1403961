//! Experiments: every case kind says what its units of work are and how to run, record
//! and compare them; [`runner`] does the rest once for all kinds (reference source,
//! seals, outputs, negative controls, errors as checks, the report).
//!
//! A *unit* is what one engine run covers: the whole case (micro), one bed of an
//! ensemble (penetration), one variant of a sweep (impact2d). Units are prepared
//! natively (a bed is poured by the native engine) so both engines start from the same
//! state; each unit has a *fingerprint*, the sha256 of the reference engine's input,
//! which a recorded reference must match.

pub mod bed_cache;
pub mod chaos;
pub mod env_flags;
pub mod impact2d;
pub mod micro;
pub mod output_dir;
pub mod penetration;
pub mod reference;
pub mod registration;
pub mod release_status;
pub mod runner;
pub(crate) mod settle_checkpoint;
pub mod suite;
pub mod suite_deck;
pub mod triaxial;

use crate::case::{NegativeControl, Perturbation, ValidatedCase};
use crate::compare::Check;
use crate::engines::process::Limits;
use crate::rundata::provenance::{EngineKind, Provenance, Sha256};
use anyhow::Result;
use std::path::{Path, PathBuf};

pub use reference::RefMode;

/// Runs `$body` with `$exp` bound to the experiment of an [`crate::case::AnyCase`]
/// (`$stress`: the penetration stress option; `$reference`, when given: the reference
/// engine, one of [`crate::case::AnyCase::references`], else the case's own): the one
/// place a case kind chooses its experiment, so the commands hold no per-kind match.
/// A new kind is one arm here and one in `AnyCase` (docs/architecture.md, "Adding a
/// kind").
#[macro_export]
macro_rules! with_experiment {
    ($case:expr, $stress:expr, |$exp:ident| $body:expr) => {{
        let case = $case;
        let reference = case.reference_engine();
        $crate::with_experiment!(case, $stress, reference, |$exp| $body)
    }};
    ($case:expr, $stress:expr, $reference:expr, |$exp:ident| $body:expr) => {
        match $case {
            $crate::case::AnyCase::Micro(case) => {
                let $exp = $crate::experiments::micro::Micro { case };
                $body
            }
            $crate::case::AnyCase::Penetration(case) => {
                let $exp = $crate::experiments::penetration::Penetration {
                    case,
                    stress: $stress,
                    reference: $reference,
                };
                $body
            }
            $crate::case::AnyCase::Impact2d(case) => {
                let $exp = $crate::experiments::impact2d::Impact2d { case };
                $body
            }
            $crate::case::AnyCase::Triaxial(case) => {
                let $exp = $crate::experiments::triaxial::Triaxial { case };
                $body
            }
        }
    };
}

/// Who prepares the beds of a deck directory (`granval deck --bed`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BedBy {
    /// granval's native pour; the deck's data file holds the exact settled bed, so the
    /// native engine can run the very same grains (the engine comparison).
    Native,
    /// The reference engine pours and settles the same loose lattice with the same
    /// criterion (a penetration case in LIGGGHTS: `data.lattice` in, `bed.dump` out):
    /// for full-size beds a native pour would take hours for.
    Liggghts,
}

/// How a comparison runs; built once from the command line.
#[derive(Debug, Clone)]
pub struct Options {
    pub reference_root: PathBuf,
    pub ref_mode: RefMode,
    /// MPI processes for the reference engine.
    pub mpi_procs: usize,
    pub progress: bool,
    /// Accept runs larger than the resource limits ([`limits`]).
    pub allow_large: bool,
    /// Penetration: also take contact snapshots and compute the stress fields, phi and
    /// the MALT checks (`granval stress`; a case's `[stress]` table turns it on too).
    pub stress: bool,
    /// Stress analysis: Gaussian range w of eq 6 in grain diameters.
    pub kernel_width: Option<f64>,
    /// Stress analysis: re-analyse the snapshots of an earlier run in the output
    /// directory instead of running the engines again.
    pub reuse: bool,
    /// Gate the comparisons with theory (the MALT curve); when false they are reported
    /// with their would-be verdict but not gated (the CI suite gates engine agreement,
    /// the release suite gates theory).
    pub gate_theory: bool,
    /// Stress analysis: also the estimator study of docs/stress.md (null window,
    /// Janssen, convergence): one extra run per bed in each engine.
    pub study: bool,
    /// Set by the runner, not the command line: the sealed record the comparison will
    /// read its reference from. An experiment may take inputs it prepared at
    /// recording (the 2D beds) from there instead of preparing them again; the seal's
    /// fingerprints then prove they are the inputs the reference engine ran from.
    pub recorded_inputs: Option<PathBuf>,
    /// `--engine-timeout`: how long one reference-engine run may take; `None`: derived
    /// from the estimate ([`engine_limits`]).
    pub engine_timeout: Option<std::time::Duration>,
    /// `--engine-stall`: how long a reference engine may write nothing; `None`: derived.
    pub engine_stall: Option<std::time::Duration>,
    /// Set by the runner, not the command line: the perturbation in words while a
    /// negative control's runs are judged, so its figures are titled and drawn as a
    /// control (`report::plot::Caption::control`), never as an engine comparison.
    pub control: Option<String>,
    /// `granval deck --viz N`: the deck also writes a visualisation dump every N steps
    /// (micro, impact2d: `engines::viz_dump`; penetration decks take it directly).
    pub viz_every: Option<u64>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            reference_root: PathBuf::from("reference"),
            // A value that is not a switch counts as on here, the strict reading (the
            // binary refuses it with exit 2 before any run).
            ref_mode: if env_flags::require_live().unwrap_or(true) {
                RefMode::Live
            } else {
                RefMode::Auto
            },
            mpi_procs: 1,
            progress: false,
            allow_large: false,
            stress: false,
            kernel_width: None,
            reuse: false,
            gate_theory: true,
            study: false,
            recorded_inputs: None,
            engine_timeout: None,
            engine_stall: None,
            viz_every: None,
            control: None,
        }
    }
}

/// Why the native engine runs: the comparison itself, or a negative control (which
/// skips extra runs, such as a second speed, that its gates do not need).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Role<'a> {
    Main,
    Control(&'a Perturbation),
}

impl Role<'_> {
    pub fn perturbation(&self) -> Perturbation {
        match self {
            Role::Main => Perturbation::default(),
            Role::Control(p) => **p,
        }
    }
}

/// Anything that came out of one engine run.
pub trait Run {
    fn provenance(&self) -> &Provenance;
}

/// What the checks of an experiment produced besides the checks.
#[derive(Debug, Default)]
pub struct Verdict {
    pub checks: Vec<Check>,
    pub notes: Vec<String>,
    /// Report sections of the case (e.g. a seed ensemble's error-bar figure), figures
    /// relative to the output directory `checks` was given.
    pub sections: Vec<crate::report::Section>,
    /// Gates this verdict cannot evaluate at all in this mode, with the reason (the
    /// stress gate native vs reference against a record, which holds no snapshots). A
    /// negative control is not asked to make them fail: it could not, and a control that
    /// fails for that would make every such run fail.
    pub unevaluated: Vec<(crate::compare::Gate, String)>,
}

/// Resource estimate of a comparison, made before anything runs.
#[derive(Debug, Clone, Copy, Default)]
pub struct Estimate {
    /// Particle-steps of all native runs.
    pub particle_steps: f64,
    /// Largest number of particles in one run.
    pub particles: f64,
    /// Bytes of output files written.
    pub output_bytes: f64,
    /// Peak memory of one native run, bytes.
    pub memory_bytes: f64,
}

/// What a deck directory holds and what the engine leaves in it: the README of
/// `granval deck` is written from this.
#[derive(Debug, Clone, Copy)]
pub struct DeckFiles {
    /// `liggghts` or `lmp`.
    pub binary: &'static str,
    pub deck: &'static str,
    pub log: &'static str,
    /// Other inputs (data files, meshes), each with what it holds.
    pub inputs: &'static [(&'static str, &'static str)],
    /// What a complete run writes, each with what it holds.
    pub outputs: &'static [(&'static str, &'static str)],
}

/// One line of `granval validate`.
#[derive(Debug, Clone)]
pub struct Derived {
    pub label: &'static str,
    pub value: String,
    pub comment: String,
}

impl Derived {
    pub fn new(label: &'static str, value: impl Into<String>, comment: impl Into<String>) -> Self {
        Derived {
            label,
            value: value.into(),
            comment: comment.into(),
        }
    }
}

/// Native throughput `granval validate` estimates run times with: particle-steps per
/// second of one core, as measured by `granval bench` on this project's machines
/// (order of magnitude; contacts per grain change it).
pub(crate) const NATIVE_PARTICLE_STEPS_PER_S: f64 = 3e6;

/// The limits of one reference-engine run of `exp`: `--engine-timeout` and
/// `--engine-stall` when given, else derived from the estimated particle-steps of the
/// whole comparison ([`crate::engines::process::Limits::derived`]).
pub(crate) fn engine_limits<E: Experiment + ?Sized>(exp: &E, opts: &Options) -> Limits {
    Limits::derived(
        exp.estimate().particle_steps,
        opts.engine_timeout,
        opts.engine_stall,
    )
}

/// The lines `granval validate` prints for any case: its own [`Experiment::derived`],
/// then the resource estimate, the estimated native run time and whether the limits
/// refuse it.
pub fn validation_summary<E: Experiment>(exp: &E) -> Vec<Derived> {
    let mut v = exp.derived();
    let e = exp.estimate();
    v.push(Derived::new(
        "particle-steps",
        format!("{:.3e}", e.particle_steps),
        "all native runs of a comparison, negative controls included",
    ));
    let t = e.particle_steps / NATIVE_PARTICLE_STEPS_PER_S;
    v.push(Derived::new(
        "estimated native time",
        human_time(t),
        format!(
            "at about {NATIVE_PARTICLE_STEPS_PER_S:.0e} particle-steps/s on one core; the reference engine takes the same order"
        ),
    ));
    let limits = engine_limits(exp, &Options::default());
    v.push(Derived::new(
        "engine timeout",
        crate::engines::process::fmt_duration(limits.timeout),
        format!(
            "{}; the run is also ended when no output grows for {}",
            limits.timeout_origin,
            crate::engines::process::fmt_duration(limits.stall)
        ),
    ));
    v.push(Derived::new(
        "estimated output",
        format!("{:.3e} bytes", e.output_bytes),
        "",
    ));
    v.push(Derived::new(
        "resource limits",
        match limits::refuse(&e, &exp.source().display().to_string()) {
            None => "within".to_string(),
            Some(why) => format!("EXCEEDED: {why}"),
        },
        "",
    ));
    v
}

/// `t` seconds as s, min, h or days.
pub(crate) fn human_time(t: f64) -> String {
    if !t.is_finite() {
        format!("{t} s")
    } else if t < 120.0 {
        format!("{t:.1} s")
    } else if t < 7200.0 {
        format!("{:.1} min", t / 60.0)
    } else if t < 2.0 * 86400.0 {
        format!("{:.1} h", t / 3600.0)
    } else {
        format!("{:.1} days", t / 86400.0)
    }
}

/// One case kind, as the runner sees it.
pub trait Experiment {
    type Unit;
    type NativeRun: Run;
    type RefRun: Run;
    type Case: ValidatedCase;

    /// The validated case the experiment runs.
    fn case(&self) -> &Self::Case;
    fn name(&self) -> &str {
        self.case().name()
    }
    /// `micro`, `penetration`, `impact2d`: the directory under `reference/`.
    fn kind(&self) -> &'static str;
    fn source(&self) -> &Path {
        self.case().source()
    }
    fn reference_engine(&self) -> EngineKind;
    /// Whether this experiment's reference engine runs here ([`reference::probe`]):
    /// its banner, `None` when absent, an error when present but broken. LAMMPS-family
    /// micro cases probe LAMMPS 2025, not the 2D cases' `lmp`.
    fn probe_reference(&self) -> Result<Option<String>> {
        reference::probe(self.reference_engine())
    }
    /// sha256 of the case's run-relevant content; a record is sealed to it.
    fn canonical_hash(&self) -> Sha256 {
        self.case().canonical_hash()
    }
    fn negative_controls(&self) -> &[NegativeControl] {
        self.case().negative_controls()
    }
    fn estimate(&self) -> Estimate;

    /// What a comparison of this case refuses before anything is prepared or run, checked
    /// by every command that compares, writes a deck or validates (so a case that
    /// validates is a case that runs): what the reference engine refuses of its input
    /// (LIGGGHTS: 0 <= nu <= 0.5, 0.05 < e <= 1, atom IDs below 2^31) and the native
    /// engine's start checks (overlaps). `granval run --engine native` makes only the
    /// native checks, so a case only the native engine takes still runs there.
    fn preflight(&self) -> Result<()> {
        Ok(())
    }

    /// Quantities derived from the case, for `granval validate` (what a person
    /// writing a case checks before running it): label, value with unit, comment.
    fn derived(&self) -> Vec<Derived>;

    /// The units, prepared (beds poured, scenes built).
    fn units(&self, opts: &Options) -> Result<Vec<Self::Unit>>;
    /// Directory name of a unit (`""`: the case directory itself).
    fn unit_name(&self, unit: &Self::Unit) -> String;
    /// sha256 of the reference engine's input for this unit.
    fn fingerprint(&self, unit: &Self::Unit) -> Result<Sha256>;
    /// The reference engine's input files of a unit (name, text) as
    /// [`Experiment::write_deck`] writes them, in the order their fingerprint
    /// ([`crate::engines::deck_text::fingerprint`]) is taken: a record must store exactly
    /// this input (comments aside), and its provenance must name that fingerprint.
    fn engine_input(&self, unit: &Self::Unit) -> Result<Vec<(&'static str, String)>>;

    fn run_native(
        &self,
        unit: &Self::Unit,
        role: Role,
        dir: &Path,
        opts: &Options,
    ) -> Result<Self::NativeRun>;
    /// Writes the reference engine's deck (and data, meshes) for the unit into `dir`.
    fn write_deck(&self, unit: &Self::Unit, dir: &Path, opts: &Options) -> Result<()>;
    /// Runs the reference engine live in `dir` and reads what it produced.
    fn run_reference(&self, unit: &Self::Unit, dir: &Path, opts: &Options) -> Result<Self::RefRun>;
    /// Stores a live reference run as a record in `rec` (then sealed by the runner).
    fn record(
        &self,
        unit: &Self::Unit,
        run: &Self::RefRun,
        run_dir: &Path,
        rec: &Path,
    ) -> Result<()>;
    /// The bytes of a record file of `unit` that granval itself wrote from the unit
    /// (the reference engine's data file of a bed), so a record may leave it out
    /// ([`reference::store`]): written again on use and checked against the sealed sha256.
    /// `None`: `file` is not regenerable (the engine's outputs never are).
    fn regenerate(&self, _unit: &Self::Unit, _file: &str) -> Option<Result<Vec<u8>>> {
        None
    }
    /// The bed the unit's reference run starts from, as a record holds it (file name
    /// `<kind>-bed-<key>.json`, bytes): what [`Experiment::record`] stores with a new
    /// record and `reference lean --add-beds` adds to an older one. `None`: the unit
    /// keeps no bed in a record (its bed is in another unit of the record, or the kind
    /// has none).
    fn bed_file(&self, _unit: &Self::Unit) -> Option<Result<(String, Vec<u8>)>> {
        None
    }
    /// Reads the record of a unit from a verified seal.
    fn read_record(
        &self,
        unit: &Self::Unit,
        name: &str,
        seal: &reference::Verified,
    ) -> Result<Self::RefRun>;
    /// Reads a reference run made by hand in a unit's deck directory `dir` (`granval
    /// deck`, then the engine run there or on a cluster, `granval analyze`): checks that
    /// it completed and that its inputs are the ones [`Experiment::write_deck`] writes.
    fn read_run_dir(&self, unit: &Self::Unit, dir: &Path) -> Result<Self::RefRun>;
    /// The files of a unit's deck directory, for its README.
    fn deck_files(&self) -> DeckFiles;
    /// How a fresh reference run differs from the previous record (`reference refresh`).
    fn drift(&self, previous: &Self::RefRun, now: &Self::RefRun) -> String;

    /// Every check of the case from the runs of both engines, unit by unit; outputs
    /// (CSV, SVG) go to `out`.
    fn checks(
        &self,
        units: &[Self::Unit],
        native: &[Self::NativeRun],
        reference: &[Self::RefRun],
        out: &Path,
        opts: &Options,
    ) -> Verdict;

    /// `granval deck`: the reference engine's input of every unit under `out`, one
    /// directory each, with the case file and a README. Only a kind whose reference
    /// engine can pour its beds (penetration in LIGGGHTS) takes [`BedBy::Liggghts`].
    fn write_decks(&self, bed_by: BedBy, opts: &Options, out: &Path) -> Result<Vec<PathBuf>>
    where
        Self: Sized,
    {
        if bed_by != BedBy::Native {
            anyhow::bail!(
                "{}: --bed liggghts: a {} case's units are prepared natively (only a penetration case's beds can be poured by LIGGGHTS)",
                self.source().display(),
                self.kind()
            );
        }
        runner::deck(self, opts, out)
    }

    /// `granval analyze` of a deck directory `dir` its reference engine ran in: checked
    /// against the inputs granval writes, reduced as `compare` reduces a live run.
    /// `native = false` (`--no-native`: the reference engine's observables alone) only
    /// where the kind supports it (penetration).
    fn analyze_decks(
        &self,
        dir: &Path,
        native: bool,
        opts: &Options,
        out: &Path,
    ) -> Result<runner::CaseOutcome>
    where
        Self: Sized,
    {
        if !native {
            anyhow::bail!(
                "--no-native: only for penetration deck directories; {} is a {} case",
                dir.join("case.toml").display(),
                self.kind()
            );
        }
        Ok(runner::analyze(self, opts, dir, out))
    }

    /// Whether `granval stress` applies: the kind takes contact snapshots and reduces
    /// them to coarse-grained stress fields and phi (penetration, docs/stress.md).
    fn has_stress_fields(&self) -> bool {
        false
    }

    /// Whether `granval chaos` applies: the kind's units are granular flows on beds
    /// (penetration, impact2d), whose spread over replicas moved by one ulp is the chaos
    /// baseline of docs/statistics.md.
    fn has_chaos_baseline(&self) -> bool {
        false
    }

    /// `granval chaos`: the chaos baseline (every unit twice, the second moved by one
    /// ulp; docs/statistics.md), where [`Experiment::has_chaos_baseline`].
    fn chaos(&self, family: &str, opts: &Options, out: &Path) -> Result<chaos::ChaosRecord>
    where
        Self: Sized,
    {
        let _ = (family, opts, out);
        anyhow::bail!(
            "{}: `granval chaos` takes a penetration or impact2d case, not a {} case: the chaos baseline (docs/statistics.md) is a spread over the beds of a granular flow, which such a case has not",
            self.source().display(),
            self.kind()
        )
    }
}

/// Resource limits checked before a run ([`Options::allow_large`] lifts them).
pub mod limits {
    use super::Estimate;

    /// Native particle-steps a comparison may take: about a week at the measured
    /// 3e6 particle-steps/s of one core.
    pub(crate) const MAX_PARTICLE_STEPS: f64 = 2e12;
    /// Output written by one comparison.
    pub(crate) const MAX_OUTPUT_BYTES: f64 = 50e9;

    /// Memory available now (`MemAvailable` of /proc/meminfo), if known.
    pub(crate) fn available_memory() -> Option<f64> {
        let text = std::fs::read_to_string("/proc/meminfo").ok()?;
        let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
        let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kb * 1024.0)
    }

    /// Why the estimate cannot run here, naming the quantity and the case field behind it.
    #[allow(clippy::neg_cmp_op_on_partial_ord)] // `!(x <= max)`: a NaN estimate is refused
    pub fn refuse(e: &Estimate, fields: &str) -> Option<String> {
        if !(e.particle_steps <= MAX_PARTICLE_STEPS) {
            return Some(format!(
                "{:.2e} particle-steps (from {fields}) exceed the limit of {MAX_PARTICLE_STEPS:.0e} (about a week of one core); shorten the run or pass --allow-large",
                e.particle_steps
            ));
        }
        if !(e.output_bytes <= MAX_OUTPUT_BYTES) {
            return Some(format!(
                "the run would write {:.2e} bytes of output (from {fields}); the limit is {MAX_OUTPUT_BYTES:.0e}: raise output_every or pass --allow-large",
                e.output_bytes
            ));
        }
        if let Some(avail) = available_memory()
            && !(e.memory_bytes <= 0.8 * avail)
        {
            return Some(format!(
                "the run needs about {:.2e} bytes of memory for {:.0} particles, more than 80 % of the {avail:.2e} available; pass --allow-large to try anyway",
                e.memory_bytes, e.particles
            ));
        }
        None
    }
}
