//! `granval` command line: argument parsing, one dispatch on the case kind, the report.
//! Exit codes: 0 every gated check passed, 1 a check failed, 2 an error (bad input, a
//! crashed or silent engine, a corrupt reference, a gate that could not be evaluated).

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand, ValueEnum};
use granval::case::AnyCase;
use granval::experiments::output_dir::{self, OutputDir, Protected};
use granval::experiments::runner::{self, CaseOutcome};
use granval::experiments::{Experiment, Options, RefMode, suite};
use granval::report::Report;
use granval::rundata::provenance::EngineKind;
use granval::{out, outln, with_experiment};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "granval",
    version,
    about = "Validation harness for granular DEM: native Rust DEM vs LIGGGHTS/LAMMPS"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
    /// Print nothing on stdout (errors and warnings still go to stderr) and show no
    /// progress: the exit code and the report files say it all. `malt`, `bench` and
    /// `cg-bench`, whose printed lines are their result, still print them.
    #[arg(long, short, global = true)]
    quiet: bool,
    /// Print the whole report on stdout, not only the verdict and what did not pass.
    #[arg(long, short, global = true, conflicts_with = "quiet")]
    verbose: bool,
    /// `json`: one line of JSON on stdout after a comparison (verdict, counts, the
    /// checks that did not pass, where the report is), for scripts; nothing else.
    #[arg(long, global = true, value_enum, default_value = "text")]
    format: Format,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum Format {
    Text,
    Json,
}

/// What goes to the terminal: set once from the global flags.
#[derive(Clone, Copy)]
struct Output {
    quiet: bool,
    verbose: bool,
    format: Format,
}

impl Output {
    /// Human text on stdout (not with --quiet or --format json).
    fn text(self) -> bool {
        !self.quiet && self.format == Format::Text
    }

    /// Progress bars: only on a terminal (a CI log or a pipe gets none) and not with
    /// --quiet or --format json.
    fn progress(self) -> bool {
        use std::io::IsTerminal;
        self.text() && std::io::stderr().is_terminal()
    }
}

static OUTPUT: std::sync::OnceLock<Output> = std::sync::OnceLock::new();

fn output() -> Output {
    *OUTPUT.get().unwrap_or(&Output {
        quiet: false,
        verbose: false,
        format: Format::Text,
    })
}

/// A line of a command's own output on stdout, unless --quiet or --format json.
macro_rules! show {
    ($($t:tt)*) => {
        if output().text() {
            outln!($($t)*);
        }
    };
}

/// A progress line on stderr (per case of a suite), unless --quiet or --format json.
macro_rules! say {
    ($($t:tt)*) => {
        if output().text() {
            eprintln!($($t)*);
        }
    };
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum EngineName {
    Native,
    /// LIGGGHTS 3.8 (3D cases).
    Liggghts,
    /// LAMMPS (2D impact2d cases).
    Lammps,
}

impl EngineName {
    /// The engine as the command line names it.
    fn of(kind: EngineKind) -> EngineName {
        match kind {
            EngineKind::Lammps => EngineName::Lammps,
            EngineKind::Liggghts => EngineName::Liggghts,
            EngineKind::Native => EngineName::Native,
        }
    }

    fn kind(self) -> EngineKind {
        match self {
            EngineName::Native => EngineKind::Native,
            EngineName::Liggghts => EngineKind::Liggghts,
            EngineName::Lammps => EngineKind::Lammps,
        }
    }

    fn name(self) -> &'static str {
        match self {
            EngineName::Native => "native",
            EngineName::Liggghts => "liggghts",
            EngineName::Lammps => "lammps",
        }
    }
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum SchedulerName {
    Slurm,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run one case in one engine; outputs (per unit: the case, a bed, a variant) under OUT.
    Run(RunArgs),
    /// Run a case in the native engine and the reference engine and compare them.
    Compare(CompareArgs),
    /// Run every case of a suite (cases/suites/NAME.toml) and write one combined report.
    Check(CheckArgs),
    /// Write the reference engine's input for a case (one directory per unit), ready to
    /// run here or on a cluster; README with the one-core and mpirun commands (`--np N`
    /// sets N in it), the expected outputs and the `granval analyze` command.
    ///
    /// With `--suite NAME --scheduler slurm` instead of a case: every case of the suite
    /// (or `--only` these) under OUT/cases/, with OUT/units.tsv (one line per engine run),
    /// OUT/suite.json and OUT/submit.sh (one Slurm job array per engine, then the
    /// analysis job); docs/cluster.md.
    Deck(DeckArgs),
    /// Analyse a deck directory (`granval deck`) after the engine ran in it, here or on
    /// a cluster: checks every run completed from the case's unedited inputs, then the
    /// same observables, checks and report as `granval compare`.
    Analyze(AnalyzeArgs),
    /// Where the units of a suite directory (`granval deck --suite`) stand: done, running
    /// (Slurm's word when `squeue` is here), failed (with the last lines of its log) or
    /// missing. Exit 0 when every unit is done, 1 otherwise.
    Status {
        dir: PathBuf,
        /// Print only the indices of ENGINE's units that are neither done nor queued,
        /// comma-separated (what `submit.sh --missing` submits).
        #[arg(long, value_name = "ENGINE")]
        not_done: Option<String>,
    },
    /// Validate a case file without running anything and print what follows from it:
    /// grain count, Rayleigh (or collision) time and the time step's fraction of it,
    /// steps, estimated run time and output, the resource limits. Exit 0 if valid.
    Validate(ValidateArgs),
    /// Reference data management.
    Reference {
        #[command(subcommand)]
        cmd: RefCmd,
    },
    /// The release suite's status table (docs/release.md, "Status of every claim"),
    /// generated from the reports that judged its cases.
    Release {
        #[command(subcommand)]
        cmd: ReleaseCmd,
    },
    /// Throughput of the native engine vs LIGGGHTS on the same dense settled packing
    /// (native 1 thread vs LIGGGHTS 1 process, native 2 threads vs 1 thread), or with
    /// `--penetration` on bed 0 of a penetration case (native 2 threads vs LIGGGHTS np 2),
    /// `--clumps` on bed 0 of the CI bed of rigid dimers.
    /// Best of `--reps`, every repetition printed, memory per particle.
    Bench(BenchArgs),
    /// Stress and velocity fields of a penetration case from both engines, every bed of
    /// its ensemble: phi per engine, (phi, K_phi) against MALT, CSV/VTK/SVG under OUT
    /// (`compare` with the stress option; needs a live LIGGGHTS).
    Stress(StressArgs),
    /// The chaos baseline (docs/statistics.md): every bed of a penetration case (every
    /// variant of an impact2d case) runs natively twice, as prepared and with every grain
    /// moved by one ulp; writes OUT/chaos.json with each bed's K_phi pair and the chaos
    /// spread of ln K_phi (each variant's final depth pair and the spread of their
    /// difference in d).
    Chaos(ChaosArgs),
    /// The agreement of several codes on the same beds of a penetration case, from the
    /// sealed summaries of runs made separately (`compare`, `compare --engine lammps`,
    /// `analyze` of a deck directory): for each pair of codes the per-bed ln(K_a / K_b)
    /// judged as the case's K_phi gate (equivalence within ln(1 + compare.k_phi_rel))
    /// and against a chaos record (docs/lammps-laws.md, "The three-code table").
    Agreement(AgreementArgs),
    /// Coarse-graining throughput: N contacts onto a G^3 grid (all fields).
    CgBench {
        #[arg(long, default_value_t = 1_000_000)]
        contacts: usize,
        #[arg(long, default_value_t = 50)]
        grid: usize,
    },
    /// MALT curve K_phi(phi) of Feng et al. eq 10.
    Malt {
        /// Internal friction angle in degrees: print K_phi(phi).
        #[arg(long)]
        phi: Option<f64>,
        /// Steady-state slope: print phi(K).
        #[arg(long)]
        k: Option<f64>,
        /// Print the curve as CSV (phi_deg,K).
        #[arg(long)]
        table: bool,
    },
}

/// Arguments of `granval run`.
#[derive(clap::Args)]
struct RunArgs {
    case: PathBuf,
    #[arg(long, value_enum, default_value = "native")]
    engine: EngineName,
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    common: Common,
}

/// Arguments of `granval compare`.
#[derive(clap::Args)]
struct CompareArgs {
    case: PathBuf,
    #[arg(long)]
    report: PathBuf,
    /// The reference engine; it must be the case kind's (micro and penetration:
    /// liggghts; impact2d: lammps). Penetration also takes `lammps`: LAMMPS 2025,
    /// live, on the same natively prepared beds (docs/lammps-laws.md, "Penetration
    /// in LAMMPS 2025"). Default: the case kind's.
    #[arg(long)]
    engine: Option<EngineName>,
    #[command(flatten)]
    common: Common,
}

/// Arguments of `granval check`.
#[derive(clap::Args)]
struct CheckArgs {
    #[arg(long, default_value = "micro")]
    suite: String,
    #[arg(long)]
    report: PathBuf,
    #[arg(long, default_value = "cases")]
    cases: PathBuf,
    /// Only these case files of the suite (repeatable).
    #[arg(long)]
    only: Vec<PathBuf>,
    /// Earlier output directories (`check --report`, `compare --report`, `stress
    /// --out`) whose case summaries the suite's claims across cases may use
    /// (repeatable); this run's own outputs come first.
    #[arg(long)]
    runs: Vec<PathBuf>,
    /// Run no case: evaluate the suite's claims across cases from the summaries in
    /// `--runs` (cases run separately, or on a cluster and brought back with
    /// `analyze`). A claim none of whose cases is there is left out with a note.
    #[arg(long, requires = "runs", conflicts_with = "only")]
    claims_only: bool,
    /// Continue an interrupted check in its own `--report` directory: native
    /// penetration runs that finished there (same case, bed, negative control and
    /// granval commit) and LIGGGHTS stress runs whose deck and snapshots are complete
    /// are read back instead of run again; everything else runs again.
    #[arg(long, conflicts_with_all = ["claims_only", "force"])]
    reuse: bool,
    #[command(flatten)]
    common: Common,
}

/// Arguments of `granval deck`.
#[derive(clap::Args)]
struct DeckArgs {
    #[arg(required_unless_present = "suite", conflicts_with = "suite")]
    case: Option<PathBuf>,
    #[arg(short = 'o', long = "out")]
    out: PathBuf,
    /// Every case of this suite (cases/suites/NAME.toml), for a cluster (needs
    /// `--scheduler`).
    #[arg(long, requires = "scheduler")]
    suite: Option<String>,
    /// With `--suite`: only these case files of the suite (repeatable).
    #[arg(long, requires = "suite")]
    only: Vec<PathBuf>,
    /// With `--suite`: where the suites and cases are.
    #[arg(long, default_value = "cases", requires = "suite")]
    cases: PathBuf,
    /// With `--suite`: write job scripts for this scheduler (`slurm`).
    #[arg(long, value_enum, requires = "suite")]
    scheduler: Option<SchedulerName>,
    /// With `--scheduler`: the partition the jobs ask for (default: the cluster's).
    #[arg(long, requires = "scheduler")]
    partition: Option<String>,
    /// With `--scheduler`: each job's time limit, `auto` (from the case's estimate,
    /// as granval's own engine timeout: docs/cluster.md) or HH:MM:SS.
    #[arg(long, default_value = "auto", requires = "scheduler")]
    time: String,
    /// The engine the deck is for; it must be the case kind's reference engine
    /// (micro and penetration: liggghts; impact2d: lammps). Default: that engine.
    /// Penetration also takes `lammps`: a LAMMPS 2025 deck of the same natively
    /// prepared bed (docs/lammps-laws.md, "Penetration in LAMMPS 2025").
    #[arg(long, value_enum)]
    engine: Option<EngineName>,
    /// Penetration: who prepares the beds: `native` (exact `data.bed`, needed to
    /// compare engines) or `liggghts` (the deck pours and settles them; full size).
    #[arg(long, value_enum, default_value = "native")]
    bed: granval::experiments::BedBy,
    /// Penetration: add a visualisation dump every N steps (the grains and the
    /// intruder mesh as VTK that ParaView opens; `analyze` accepts the deck).
    #[arg(long, value_name = "N")]
    viz: Option<u64>,
    #[command(flatten)]
    common: Common,
}

/// Arguments of `granval analyze`.
#[derive(clap::Args)]
struct AnalyzeArgs {
    dir: PathBuf,
    #[arg(long)]
    report: PathBuf,
    /// Penetration only: do not re-run the native engine from the same beds
    /// (LIGGGHTS observables and published-value checks only).
    #[arg(long)]
    no_native: bool,
    #[command(flatten)]
    common: Common,
}

/// Arguments of `granval validate`.
#[derive(clap::Args)]
struct ValidateArgs {
    case: PathBuf,
    /// Accept a case whose estimated steps, output or memory exceed the limits (as
    /// `--allow-large` does for the commands that run it).
    #[arg(long)]
    allow_large: bool,
}

/// Arguments of `granval bench`.
#[derive(clap::Args)]
struct BenchArgs {
    /// Number of spheres in the packing.
    #[arg(long, default_value_t = 10_000)]
    n: usize,
    /// Timed steps per engine (packing; with `--penetration` the default is 10 000).
    #[arg(long)]
    steps: Option<u64>,
    /// Repetitions per engine, interleaved so load hits all alike; the best is reported.
    #[arg(long, default_value_t = 3)]
    reps: usize,
    /// Time the penetration of bed 0 of CASE instead of the packing: same bed, same
    /// intruder start and speed in both engines.
    #[arg(long, num_args = 0..=1, default_missing_value = "cases/penetration/ci.toml")]
    penetration: Option<PathBuf>,
    /// The penetration benchmark on a bed of rigid clumps: bed 0 of
    /// `cases/penetration/ci-dimers.toml` (`--penetration` with that case).
    #[arg(long, conflicts_with = "penetration")]
    clumps: bool,
    /// Throughput against bed size: settled packings of each N of `--ns` (cached
    /// under $GRANVAL_BED_CACHE, else the temp dir), native 1 and 2 threads,
    /// LIGGGHTS 1 process and `mpirun -np 2`, ratios and bytes per particle.
    #[arg(long, conflicts_with_all = ["penetration", "clumps"])]
    scaling: bool,
    /// Bed sizes of `--scaling`, comma separated.
    #[arg(long, value_delimiter = ',', default_values_t = granval::bench::scaling::DEFAULT_NS)]
    ns: Vec<usize>,
    /// With `--scaling`: also time the native engine without spatial sorting,
    /// interleaved (the engine before it).
    #[arg(long, requires = "scaling")]
    unsorted: bool,
    /// With `--scaling`: particle-steps per timed run (steps = this / N, 50..4000).
    #[arg(long, requires = "scaling", default_value_t = granval::bench::scaling::DEFAULT_BUDGET)]
    budget: f64,
}

/// Arguments of `granval stress`.
#[derive(clap::Args)]
struct StressArgs {
    case: PathBuf,
    #[arg(long)]
    out: PathBuf,
    /// Re-analyse the snapshots of an earlier run in OUT instead of running again.
    #[arg(long)]
    reuse: bool,
    /// Gaussian range w of eq 6 in grain diameters (sensitivity studies only).
    #[arg(long)]
    kernel_width: Option<f64>,
    /// Also the estimator study (docs/stress.md): null window, Janssen check and
    /// convergence with 1-40 snapshots and the grid spacing, from one extra run per
    /// bed in each engine (DIR/study.json, DIR/study_*.csv).
    #[arg(long)]
    study: bool,
    #[command(flatten)]
    common: Common,
}

/// Arguments of `granval chaos`.
#[derive(clap::Args)]
struct ChaosArgs {
    case: PathBuf,
    #[arg(long)]
    out: PathBuf,
    /// The family of cases this one stands for (e.g. "spheres, CI scale").
    #[arg(long)]
    family: String,
    #[command(flatten)]
    common: Common,
}

/// Arguments of `granval agreement`.
#[derive(clap::Args)]
struct AgreementArgs {
    case: PathBuf,
    /// A run's output directory (repeatable; two engines or more among them).
    #[arg(long, required = true)]
    runs: Vec<PathBuf>,
    /// The chaos record (`granval chaos`) the pairs are set against.
    #[arg(long)]
    chaos: PathBuf,
    #[arg(long)]
    report: PathBuf,
    /// Clear a non-empty report directory instead of refusing it.
    #[arg(long)]
    force: bool,
}

#[derive(clap::Args)]
struct Common {
    /// Recorded reference runs (used when the reference engine is not installed).
    #[arg(long, default_value = "reference")]
    reference: PathBuf,
    /// Where the reference comes from: `auto` (live if installed, else the sealed
    /// record), `live` (error without the engine; also GRANVAL_REQUIRE_LIVE=1) or
    /// `recorded` (the sealed record even if the engine is installed).
    #[arg(long, value_enum)]
    reference_mode: Option<RefMode>,
    /// Same as `--reference-mode live`.
    #[arg(long)]
    require_live: bool,
    /// MPI processes for the reference engine.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..=1024))]
    np: u16,
    /// Clear a non-empty output directory instead of refusing it.
    #[arg(long)]
    force: bool,
    /// Run even if the estimated steps, output or memory exceed the limits.
    #[arg(long)]
    allow_large: bool,
    #[command(flatten)]
    engine: EngineLimits,
}

/// How long a reference engine may run (flattened into every command that runs one).
#[derive(clap::Args)]
struct EngineLimits {
    /// End a reference-engine run (an error) after DURATION, e.g. 90m, 4h, 600s.
    /// Default: from the case's estimated particle-steps (`granval validate` prints it).
    #[arg(long, value_name = "DURATION", value_parser = granval::engines::process::parse_duration)]
    engine_timeout: Option<std::time::Duration>,
    /// End a reference-engine run as stalled when no file in its run directory grew for
    /// DURATION. Default: a tenth of the timeout, at least 10 min.
    #[arg(long, value_name = "DURATION", value_parser = granval::engines::process::parse_duration)]
    engine_stall: Option<std::time::Duration>,
}

#[derive(Subcommand)]
enum ReleaseCmd {
    /// Keep what the report in each REPORT_DIR (of `check --suite release`) said of
    /// each release case and claim across cases it judged: one digest per case and
    /// claim in docs/data/release/digests/, replacing the previous one.
    Digest {
        #[arg(required = true)]
        report_dirs: Vec<PathBuf>,
        /// The repository (its cases/, docs/).
        #[arg(long, default_value = ".")]
        repo: PathBuf,
    },
    /// Write the status table into docs/release.md from the digests and
    /// docs/data/release/status-rows.toml; with `--check`, write nothing and exit 1
    /// when the committed table differs from the generated one.
    Table {
        #[arg(long)]
        check: bool,
        #[arg(long, default_value = ".")]
        repo: PathBuf,
    },
    /// Print draft `[[expect]]` entries for every gated check of the digests that did
    /// not pass (verdict, value, interval, date), each with an empty `reason` to write
    /// before it goes into cases/suites/release.toml.
    Expect {
        #[arg(long, default_value = ".")]
        repo: PathBuf,
    },
    /// The release gate over the digests, without running anything: every case and
    /// claim judged under today's rules against the suite's `[[expect]]`, what changed,
    /// and what still waits for a judgement. Exit 0 only when every case and claim (or
    /// every one of `--only`) is judged and holds as registered.
    Gate {
        /// Only these cases or claims (their names; repeatable).
        #[arg(long)]
        only: Vec<String>,
        #[arg(long, default_value = ".")]
        repo: PathBuf,
    },
}

#[derive(Subcommand)]
enum RefCmd {
    /// Re-run cases in the live reference engine, record and seal them under
    /// reference/<kind>/<case>/ (reference/release/<kind>/<case>/ for the release
    /// suite), and print the drift against the previous record.
    Refresh {
        #[arg(long, default_value = "micro")]
        suite: String,
        #[arg(long, default_value = "cases")]
        cases: PathBuf,
        #[arg(long, default_value = "reference")]
        reference: PathBuf,
        /// Only this case file (any case file; it is recorded where `--suite` records).
        #[arg(long)]
        only: Option<PathBuf>,
        #[command(flatten)]
        engine: EngineLimits,
    },
    /// Check the records of a suite against their seals without running anything: the
    /// case, each unit's engine input and every sealed file (beds from the bed store,
    /// data files written again from the beds). Records that hold no beds settle them.
    Verify {
        #[command(flatten)]
        records: Records,
    },
    /// Make committed records lean in place (as `refresh` makes new ones): each record
    /// must verify first; engine data files are left out where the record holds the
    /// unit's bed (written again and checked on use), files of 64 KiB or more are kept
    /// zstd-compressed; seals unchanged; verified again after.
    Lean {
        #[command(flatten)]
        records: Records,
        /// A record sealed without its beds gets them: each bed is prepared again
        /// (settled, or from GRANVAL_BED_CACHE) and added to the seal only when the units
        /// have their sealed fingerprints and the engine's data file written from it is
        /// byte-identical to the sealed one (the seal names what was added and why); the
        /// beds go to the bed store once by content and the data files are left out.
        #[arg(long)]
        add_beds: bool,
    },
}

/// The records `reference verify` and `reference lean` work on: every case of a suite,
/// or only the named case files, under the suite's reference root.
#[derive(clap::Args)]
struct Records {
    #[arg(long, default_value = "micro")]
    suite: String,
    #[arg(long, default_value = "cases")]
    cases: PathBuf,
    #[arg(long, default_value = "reference")]
    reference: PathBuf,
    /// Only this case file (repeatable).
    #[arg(long)]
    only: Vec<PathBuf>,
}

impl Records {
    /// The suite's reference root and the case files to work on.
    fn resolve(self) -> Result<(PathBuf, Vec<PathBuf>)> {
        let s = suite::load(&self.cases, &self.suite)?;
        let root = s.reference_root(&self.reference);
        let paths = if self.only.is_empty() {
            s.cases.into_iter().map(|e| e.path).collect()
        } else {
            only_entries(&s, &self.only)?
                .into_iter()
                .map(|e| e.path)
                .collect()
        };
        Ok((root, paths))
    }
}

fn options(c: &Common) -> Options {
    let mut o = Options {
        reference_root: c.reference.clone(),
        mpi_procs: usize::from(c.np),
        progress: output().progress(),
        allow_large: c.allow_large,
        engine_timeout: c.engine.engine_timeout,
        engine_stall: c.engine.engine_stall,
        ..Options::default()
    };
    if let Some(m) = c.reference_mode {
        o.ref_mode = m;
    }
    if c.require_live {
        o.ref_mode = RefMode::Live;
    }
    o
}

/// Claims `dir` as this command's output directory (`flag` names the option in errors):
/// new, empty, or (with `force`) one granval created, never where `protected` says it
/// must not be (`experiments::output_dir`); locked until the returned guard is dropped.
fn claim(dir: &Path, flag: &str, force: bool, protected: &Protected) -> Result<OutputDir> {
    output_dir::claim(dir, flag, force, protected, &command_line())
}

/// This command as typed, for the output directory's marker and lock.
fn command_line() -> String {
    std::env::args_os()
        .map(|a| a.to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join(" ")
}

/// What every output directory keeps away from: the reference store.
fn protected(common: &Common) -> Protected {
    Protected::default().store(&common.reference, "the reference store")
}

fn finish(report: &Report, dir: &Path, title: &str) -> Result<ExitCode> {
    report.write(dir, title)?;
    let out = output();
    match out.format {
        Format::Json => outln!("{}", report.machine_summary(title, dir)),
        Format::Text if out.quiet => {}
        Format::Text if out.verbose => {
            out!("{}", report.markdown(title));
            outln!("\nreport written to {}", dir.display());
        }
        Format::Text => {
            out!("{}", report.summary(title, 300));
            outln!(
                "\nreport: {} (report.md: every check; report.json; report.junit.xml)",
                dir.display()
            );
        }
    }
    Ok(ExitCode::from(report.exit_code() as u8))
}

/// A case file, its plausibility warnings printed on stderr (they never change the
/// exit code; [`granval::case::plausible`]).
fn load(path: &Path) -> Result<AnyCase> {
    let c = AnyCase::load(path)?;
    for w in warnings(&c, path) {
        eprintln!("{w}");
    }
    Ok(c)
}

/// The case's plausibility warnings as printed and as kept in the report's notes.
fn warnings(c: &AnyCase, path: &Path) -> Vec<String> {
    c.warnings()
        .iter()
        .map(|w| format!("warning: {}: {w}", path.display()))
        .collect()
}

/// The reference engine `--engine` names for a case (`None`: the case's own), refused
/// (exit 2) before anything runs when it is not one of the case's
/// ([`AnyCase::references`]) or is the native engine, which is what is compared. A
/// reference other than the case's own has no sealed record, so it runs live:
/// `--reference-mode recorded` is refused and `auto` becomes `live`.
fn reference_for(
    case: &Path,
    engine: Option<EngineName>,
    opts: &mut Options,
) -> Result<Option<EngineKind>> {
    let c = load(case)?;
    let refs = c.references();
    let Some(engine) = engine else {
        return Ok(None);
    };
    if engine == EngineName::Native {
        bail!(
            "{}: --engine native: the native engine is what is compared; --engine names the reference ({})",
            case.display(),
            engine_list(refs.engines)
        );
    }
    if !refs.engines.contains(&engine.kind()) {
        bail!(
            "{}: --engine {}: {} (use --engine {})",
            case.display(),
            engine.name(),
            refs.why,
            engine_list(refs.engines)
        );
    }
    if engine.kind() == refs.engines[0] {
        return Ok(None);
    }
    match opts.ref_mode {
        RefMode::Recorded => bail!(
            "{}: --engine {} --reference-mode recorded: the records of a {} case are of {} only; {} runs live",
            case.display(),
            engine.name(),
            c.kind(),
            refs.label,
            engine.name()
        ),
        RefMode::Auto => opts.ref_mode = RefMode::Live,
        RefMode::Live => {}
    }
    Ok(Some(engine.kind()))
}

/// Engines as the command line names them: `liggghts or lammps`.
fn engine_list(engines: &[EngineKind]) -> String {
    engines
        .iter()
        .map(|e| EngineName::of(*e).name())
        .collect::<Vec<_>>()
        .join(" or ")
}

/// `compare` of one case file into `out/<case name>/`; `reference`: another of the
/// case's reference engines than its own ([`reference_for`] checked it may).
fn compare_one(
    path: &Path,
    stress: bool,
    quasi_static: bool,
    reference: Option<EngineKind>,
    opts: &Options,
    out: &Path,
) -> CaseOutcome {
    match AnyCase::load(path) {
        Err(e) => CaseOutcome {
            checks: vec![granval::compare::Check::error(
                path.display().to_string(),
                e.to_string(),
            )],
            ..CaseOutcome::default()
        }
        .for_case(&path.display().to_string()),
        Ok(case) => {
            say!("== {} ({})", case.name(), path.display());
            let mut warned = warnings(&case, path);
            for w in &warned {
                eprintln!("{w}");
            }
            let name = case.name().to_string();
            let dir = out.join(&name);
            let mut case = case;
            if !quasi_static && let Some(v2) = case.drop_quasi_static() {
                warned.push(format!(
                    "{}: the quasi-static test at {v2} m/s ([quasi_static]) is not run in this suite (its entry says quasi_static = false)",
                    path.display()
                ));
            }
            let reference = reference.unwrap_or(case.reference_engine());
            let mut o = with_experiment!(case, stress, reference, |exp| runner::compare(
                &exp, opts, &dir
            ));
            o.notes.splice(0..0, warned);
            // The case's figures are under its own directory of the report.
            for s in &mut o.sections {
                for f in &mut s.figures {
                    *f = format!("{name}/{f}");
                }
            }
            o
        }
    }
}

/// The suite's entries `--only` names, matched by the file they name (`./cases/x.toml`,
/// an absolute path and `cases/x.toml` are one case); a name given twice is an error.
fn only_entries(s: &suite::Suite, only: &[PathBuf]) -> Result<Vec<suite::SuiteCase>> {
    let real = |p: &Path| std::fs::canonicalize(p).ok();
    let mut picked: Vec<(usize, &Path)> = Vec::new();
    for o in only {
        let Some(r) = real(o) else {
            // A case name given where its file is meant: say which file it is.
            let named = s.cases.iter().find(|e| {
                e.path.file_stem().is_some_and(|f| Some(f) == o.file_name())
                    || e.path.file_name().is_some_and(|f| Some(f) == o.file_name())
            });
            match named {
                Some(e) => bail!(
                    "--only {}: no such case file; give the case file: --only {}",
                    o.display(),
                    e.path.display()
                ),
                None => bail!("--only {}: no such case file", o.display()),
            }
        };
        let Some(k) = s
            .cases
            .iter()
            .position(|e| real(&e.path) == Some(r.clone()))
        else {
            bail!(
                "--only {}: not a case of suite {} (its cases: {})",
                o.display(),
                s.name,
                s.cases
                    .iter()
                    .map(|e| e.path.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        };
        if let Some((_, first)) = picked.iter().find(|(j, _)| *j == k) {
            bail!(
                "--only {} and --only {} name the same case file {}: give each case once",
                first.display(),
                o.display(),
                s.cases[k].path.display()
            );
        }
        picked.push((k, o));
    }
    picked.sort_by_key(|(k, _)| *k);
    Ok(picked
        .into_iter()
        .map(|(k, _)| s.cases[k].clone())
        .collect())
}

fn report_of(outcomes: Vec<CaseOutcome>) -> Report {
    let (mut checks, mut runs, mut notes, mut sections) = (vec![], vec![], vec![], vec![]);
    for o in outcomes.into_iter().map(named) {
        checks.extend(o.checks);
        runs.extend(o.run);
        notes.extend(o.notes);
        sections.extend(o.sections);
    }
    let mut r = Report::new(checks, runs, notes);
    r.sections = sections;
    r
}

/// [`report_of`] for outcomes whose checks are named after their case (JUnit's
/// classname) from the case's run where the runner did not name it.
fn named(o: CaseOutcome) -> CaseOutcome {
    match o.run.as_ref().map(|r| r.case.clone()) {
        Some(case) => o.for_case(&case),
        None => o,
    }
}

/// The report of a suite from its cases' outcomes: the claims across cases, the MALT
/// verdict and the chaos section from the case summaries in `dirs` (this run's `report`
/// first), then the release gate of the suite's registered expectations (every verdict
/// as registered, docs/statistics.md) when the whole suite ran (`partial`: a subset).
/// `check --suite` and `analyze` of a suite directory both end here.
#[allow(clippy::too_many_arguments)]
fn suite_report(
    s: &suite::Suite,
    mut outcomes: Vec<CaseOutcome>,
    dirs: &[PathBuf],
    report: &Path,
    partial: bool,
    registration: Option<&granval::experiments::registration::Registration>,
    n_cases: usize,
    started: std::time::Instant,
) -> Report {
    let (claim_checks, claim_notes) = suite::evaluate_claims(s, dirs, partial);
    let (malt_notes, malt_section) = suite::malt_verdict(s, dirs, report);
    let (chaos_notes, chaos_section) = suite::chaos_section(s, dirs);
    outcomes.push(CaseOutcome {
        checks: claim_checks,
        run: None,
        notes: claim_notes
            .into_iter()
            .chain(malt_notes)
            .chain(chaos_notes)
            .collect(),
        ..CaseOutcome::default()
    });
    let (figure_notes, claim_sections) = suite::claim_sections(s, dirs, report);
    if let Some(reg) = registration {
        for o in &mut outcomes {
            reg.apply(&mut o.checks);
        }
    }
    let mut r = report_of(outcomes);
    if let Some(reg) = registration {
        r.notes.extend(reg.notes());
        r.sections.push(reg.section());
    }
    r.notes.extend(figure_notes);
    r.sections.extend(claim_sections);
    r.sections.extend(malt_section);
    r.sections.extend(chaos_section);
    if !s.expectations.is_empty() {
        r.apply_gate(&s.expectations, !partial);
    }
    r.notes.push(format!(
        "suite {}: {} ({n_cases} case(s), {:.0} s)",
        s.name,
        s.description,
        started.elapsed().as_secs_f64()
    ));
    r
}

/// `granval deck --suite NAME --scheduler slurm -o OUT` (docs/cluster.md).
#[allow(clippy::too_many_arguments)]
fn deck_suite(
    name: &str,
    cases: &Path,
    only: &[PathBuf],
    out: &Path,
    partition: Option<String>,
    time: &str,
    common: &Common,
    opts: &Options,
) -> Result<ExitCode> {
    use granval::experiments::suite_deck;
    let s = suite::load(cases, name)?;
    let entries = if only.is_empty() {
        s.cases.clone()
    } else {
        only_entries(&s, only)?
    };
    let time = suite_deck::parse_time(time)?;
    if let Some(p) = &partition
        && (p.is_empty()
            || !p
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "_-.,".contains(c)))
    {
        bail!("--partition {p:?}: a Slurm partition name (letters, digits, _ - . ,)");
    }
    let mut keep = protected(common)
        .input(suite::manifest(cases, name))
        .input(cases);
    for e in &s.cases {
        keep = keep.input(&e.path);
    }
    let _out = claim(out, "-o", common.force, &keep)?;
    let sched = suite_deck::Scheduler {
        np: opts.mpi_procs,
        partition,
        time,
        granval: std::env::current_exe().context("the path of this granval binary")?,
    };
    let rows = suite_deck::write(
        &s,
        &suite::manifest(cases, name),
        &entries,
        only,
        out,
        &sched,
        opts,
    )?;
    for (engine, ix) in suite_deck::by_engine(&rows) {
        show!("{engine}: {} unit(s)", ix.len());
    }
    show!(
        "{} unit(s) of {} case(s) in {}; submit with {}",
        rows.len(),
        entries.len(),
        out.display(),
        out.join(suite_deck::SUBMIT_FILE).display()
    );
    Ok(ExitCode::SUCCESS)
}

/// `granval status DIR` of a suite directory: one line per unit (and the last lines of a
/// failed unit's log); with `not_done`, only that engine's units to submit again.
fn status(dir: &Path, not_done: Option<&str>) -> Result<ExitCode> {
    use granval::experiments::suite_deck::{self, UnitState};
    if suite_deck::read_record(dir)?.is_none() {
        bail!(
            "{}: not a suite directory (no {}; `granval deck --suite S --scheduler slurm -o DIR` writes one)",
            dir.display(),
            suite_deck::SUITE_FILE
        );
    }
    let rows = suite_deck::read_units(dir)?;
    let queued = suite_deck::slurm_tasks(dir);
    let states = suite_deck::status(dir, &rows, queued.as_deref());
    if let Some(engine) = not_done {
        if !rows.iter().any(|r| r.engine == engine) {
            bail!(
                "--not-done {engine}: no unit of {} runs {engine} (engines: {})",
                dir.display(),
                suite_deck::by_engine(&rows)
                    .into_iter()
                    .map(|(e, _)| e)
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        let ids: Vec<String> = rows
            .iter()
            .zip(&states)
            .filter(|(r, st)| {
                r.engine == engine && matches!(st, UnitState::Failed(_) | UnitState::Missing)
            })
            .map(|(r, _)| r.index.to_string())
            .collect();
        outln!("{}", ids.join(","));
        return Ok(ExitCode::SUCCESS);
    }
    let w = rows.iter().map(|r| r.id.len()).max().unwrap_or(4).max(4);
    show!("{:>5}  {:<w$}  {:<8}  state", "index", "unit", "engine");
    let mut count = std::collections::BTreeMap::<&str, usize>::new();
    for (r, st) in rows.iter().zip(&states) {
        *count.entry(st.label()).or_default() += 1;
        let extra = match st {
            UnitState::Running(s) => format!(" ({s})"),
            _ => String::new(),
        };
        show!(
            "{:>5}  {:<w$}  {:<8}  {}{extra}",
            r.index,
            r.id,
            r.engine,
            st.label()
        );
        if let UnitState::Failed(why) = st {
            for l in why.lines() {
                show!("{:>5}  | {l}", "");
            }
        }
    }
    show!(
        "{} unit(s): {}{}",
        rows.len(),
        ["done", "running", "failed", "missing"]
            .iter()
            .map(|k| format!("{} {k}", count.get(k).copied().unwrap_or(0)))
            .collect::<Vec<_>>()
            .join(", "),
        if queued.is_some() {
            "; running as squeue lists it"
        } else {
            "; from the files (no squeue or no job submitted)"
        }
    );
    let all_done = states.iter().all(|s| *s == UnitState::Done);
    Ok(ExitCode::from(if all_done { 0 } else { 1 }))
}

/// One case directory of a suite directory analysed into `out` (`analyze` of a deck
/// directory), any error an error check of the case, as `check` makes it.
fn analyze_case(dir: &Path, out: &Path, no_native: bool, opts: &Options) -> CaseOutcome {
    let case_file = dir.join("case.toml");
    let run = || -> Result<CaseOutcome> {
        let c = load(&case_file)?;
        let name = c.name().to_string();
        let mut o = with_experiment!(c, false, |exp| exp
            .analyze_decks(dir, !no_native, opts, out))?;
        for s in &mut o.sections {
            for f in &mut s.figures {
                *f = format!("{name}/{f}");
            }
        }
        Ok(o)
    };
    match run() {
        Ok(o) => o,
        Err(e) => CaseOutcome {
            checks: vec![granval::compare::Check::error(
                case_file.display().to_string(),
                format!("{e:#}"),
            )],
            ..CaseOutcome::default()
        }
        .for_case(&dir.file_name().unwrap_or_default().to_string_lossy()),
    }
}

/// `granval analyze DIR` of a suite directory: every case from its units, then the
/// suite's claims and release gate: the report and exit code of `granval check --suite`
/// on the same cases (docs/cluster.md).
fn analyze_suite(
    dir: &Path,
    rec: granval::experiments::suite_deck::SuiteRecord,
    report: &Path,
    no_native: bool,
    common: &Common,
) -> Result<ExitCode> {
    use granval::experiments::suite_deck;
    let rows = suite_deck::read_units(dir)?;
    suite_deck::check_cases(dir, &rec, &rows)?;
    // The suite file the decks were written from, for its claims and expectations.
    let cases_root = Path::new(&rec.cases_root);
    let s = suite::load(cases_root, &rec.suite).with_context(|| {
        format!(
            "the suite {} that {} was written from",
            rec.suite,
            dir.join(suite_deck::SUITE_FILE).display()
        )
    })?;
    let manifest = suite::manifest(cases_root, &rec.suite);
    let sha = granval::rundata::provenance::Sha256::of_file(&manifest)?.to_string();
    if sha != rec.suite_file_sha256 {
        bail!(
            "{}: sha256 {sha}, but {} was written from the suite file of sha256 {}: the suite changed since; write the decks again",
            manifest.display(),
            dir.join(suite_deck::SUITE_FILE).display(),
            rec.suite_file_sha256
        );
    }
    let mut keep = protected(common);
    for c in &rec.cases {
        keep = keep.store(dir.join(&c.dir), "a case directory being analysed");
    }
    let _out = claim(report, "--report", common.force, &keep)?;
    let opts = options(common);
    let started = std::time::Instant::now();
    let mut outcomes = Vec::new();
    for c in &rec.cases {
        say!("== {} ({})", c.name, dir.join(&c.dir).display());
        let o = Options {
            gate_theory: c.theory,
            ..opts.clone()
        };
        outcomes.push(analyze_case(
            &dir.join(&c.dir),
            &report.join(&c.name),
            no_native,
            &o,
        ));
    }
    let partial = !rec.only.is_empty();
    // Registration as `check --suite` reads it (docs/statistics.md, "Registration").
    let registration =
        granval::experiments::registration::of_suite(&s, &s.reference_root(&opts.reference_root))?;
    let r = suite_report(
        &s,
        outcomes,
        &[report.to_path_buf()],
        report,
        partial,
        registration.as_ref(),
        rec.cases.len(),
        started,
    );
    finish(
        &r,
        report,
        &format!("granval analyze {} (suite {})", dir.display(), rec.suite),
    )
}

fn real_main() -> Result<ExitCode> {
    let cli = Cli::parse();
    // A switch that is not one (GRANVAL_REQUIRE_LIVE=ture) is refused before anything.
    granval::experiments::env_flags::require_live()?;
    let _ = OUTPUT.set(Output {
        quiet: cli.quiet,
        verbose: cli.verbose,
        format: cli.format,
    });
    match cli.cmd {
        Cmd::Run(a) => run(a),
        Cmd::Compare(a) => compare(a),
        Cmd::Check(a) => check(a),
        Cmd::Reference { cmd } => reference(cmd),
        Cmd::Status { dir, not_done } => status(&dir, not_done.as_deref()),
        Cmd::Release { cmd } => release(cmd),
        Cmd::Validate(a) => validate(a),
        Cmd::Deck(a) => deck(a),
        Cmd::Analyze(a) => analyze(a),
        Cmd::Bench(a) => bench(a),
        Cmd::Stress(a) => stress(a),
        Cmd::Agreement(a) => agreement(a),
        Cmd::Chaos(a) => chaos(a),
        Cmd::CgBench { contacts, grid } => {
            let t = granval::analysis::cg_bench::time_cg(contacts, grid)?;
            outln!(
                "coarse graining: {} contacts, {} grains onto {} points ({grid}^3), {} threads: setup {:.3} s, fields {:.3} s, total {:.3} s",
                t.n_contacts,
                t.n_grains,
                t.grid_points,
                rayon::current_num_threads(),
                t.setup_s,
                t.eval_s,
                t.setup_s + t.eval_s
            );
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Malt { phi, k, table } => {
            use granval::analysis::malt;
            if let Some(phi) = phi {
                let q = malt::k_phi_deg(phi)?;
                outln!(
                    "K_phi({phi} deg) = {:.9} (quadrature error estimate {:.1e})",
                    q.value,
                    q.abs_err
                );
            }
            if let Some(k) = k {
                outln!("phi(K = {k}) = {:.6} deg", malt::phi_of_k(k)?.to_degrees());
            }
            if table {
                outln!("phi_deg,K");
                for (p, kv) in malt::table(45.0, 0.5)? {
                    outln!("{p},{kv:.9}");
                }
            }
            if phi.is_none() && k.is_none() && !table {
                bail!("give --phi DEG, --k VALUE or --table");
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// `granval run`: one case in one engine, outputs per unit under `--out`.
fn run(a: RunArgs) -> Result<ExitCode> {
    let RunArgs {
        case,
        engine,
        out,
        common,
    } = a;
    let opts = options(&common);
    let c = load(&case)?;
    let refs = c.references();
    if engine != EngineName::Native && !refs.engines.contains(&engine.kind()) {
        bail!(
            "{}: --engine {}: a {} case runs in the native engine or a reference engine of its own: {} (use native or {})",
            case.display(),
            engine.name(),
            c.kind(),
            refs.why,
            engine_list(refs.engines)
        );
    }
    // The reference engine named (the native run takes the case's own).
    let reference = match engine {
        EngineName::Native => c.reference_engine(),
        e => e.kind(),
    };
    let _out = claim(
        &out,
        "--out",
        common.force,
        &protected(&common).input(&case),
    )?;
    let native = engine == EngineName::Native;
    let lines = with_experiment!(c, false, reference, |exp| runner::run_one(
        &exp, native, &opts, &out
    ))?;
    for l in lines {
        show!("{l}");
    }
    Ok(ExitCode::SUCCESS)
}

/// `granval compare`: a case in the native and the reference engine, one report.
fn compare(a: CompareArgs) -> Result<ExitCode> {
    let CompareArgs {
        case,
        report,
        engine,
        common,
    } = a;
    let mut opts = options(&common);
    let reference = reference_for(&case, engine, &mut opts)?;
    let _out = claim(
        &report,
        "--report",
        common.force,
        &protected(&common).input(&case),
    )?;
    let o = compare_one(&case, false, true, reference, &opts, &report);
    finish(
        &report_of(vec![o]),
        &report,
        &format!("granval compare {}", case.display()),
    )
}

/// `granval check`: every case of a suite (or `--only` some, or none with
/// `--claims-only`), then the suite's claims across cases and the release gate, one report.
fn check(a: CheckArgs) -> Result<ExitCode> {
    let CheckArgs {
        suite,
        report,
        cases,
        only,
        runs,
        claims_only,
        reuse,
        common,
    } = a;
    let s = suite::load(&cases, &suite)?;
    let mut entries = s.cases.clone();
    if claims_only {
        entries.clear();
    } else if !only.is_empty() {
        entries = only_entries(&s, &only)?;
    }
    for r in &runs {
        if !r.is_dir() {
            bail!(
                "--runs {}: no such directory (an earlier output directory of check, compare or stress)",
                r.display()
            );
        }
    }
    let mut keep = protected(&common)
        .input(suite::manifest(&cases, &suite))
        .input(&cases);
    for e in &s.cases {
        keep = keep.input(&e.path);
    }
    for r in &runs {
        keep = keep.store(r, "the --runs directory");
    }
    let _out = if reuse {
        output_dir::reuse(&report, "--report", &keep, &command_line())?
    } else {
        claim(&report, "--report", common.force, &keep)?
    };
    let mut opts = options(&common);
    opts.reuse = reuse;
    opts.reference_root = s.reference_root(&opts.reference_root);
    // Which rules came before their records, decided before anything runs
    // (docs/statistics.md, "Registration").
    let registration = granval::experiments::registration::of_suite(&s, &opts.reference_root)?;
    let started = std::time::Instant::now();
    let mut outcomes = Vec::new();
    for e in &entries {
        let t = std::time::Instant::now();
        let o = Options {
            gate_theory: e.theory,
            ..opts.clone()
        };
        outcomes.push(compare_one(
            &e.path,
            e.stress,
            e.quasi_static,
            None,
            &o,
            &report,
        ));
        say!(
            "   {} took {:.0} s",
            e.path.display(),
            t.elapsed().as_secs_f64()
        );
    }
    let mut dirs = vec![report.clone()];
    dirs.extend(runs);
    let r = suite_report(
        &s,
        outcomes,
        &dirs,
        &report,
        claims_only || !only.is_empty(),
        registration.as_ref(),
        entries.len(),
        started,
    );
    finish(&r, &report, &format!("granval check --suite {suite}"))
}

/// `granval deck`: the reference engine's input for a case, or for every case of a suite
/// with job scripts for a scheduler.
fn deck(a: DeckArgs) -> Result<ExitCode> {
    let DeckArgs {
        case,
        out,
        suite,
        only,
        cases,
        scheduler,
        partition,
        time,
        engine,
        bed,
        viz,
        common,
    } = a;
    let opts = options(&common);
    if let Some(suite) = suite {
        if viz.is_some() {
            bail!(
                "--viz: not with --suite (a cluster suite's decks stay lean); write one case's deck with --viz"
            );
        }
        if engine.is_some() || bed != granval::experiments::BedBy::Native {
            bail!(
                "--suite: each case's deck is for its reference engine with natively prepared beds; drop --engine and --bed"
            );
        }
        let Some(SchedulerName::Slurm) = scheduler else {
            bail!("--suite needs --scheduler slurm");
        };
        return deck_suite(
            &suite, &cases, &only, &out, partition, &time, &common, &opts,
        );
    }
    let case = case.context("give a case file or --suite NAME")?;
    let c = load(&case)?;
    let refs = c.references();
    let reference = match engine {
        None => c.reference_engine(),
        Some(e) if e != EngineName::Native && refs.engines.contains(&e.kind()) => e.kind(),
        Some(e) => bail!(
            "{}: --engine {}: {}; granval writes decks for {} only",
            case.display(),
            e.name(),
            refs.why,
            engine_list(refs.engines)
        ),
    };
    let _out = claim(&out, "-o", common.force, &protected(&common).input(&case))?;
    let opts = Options {
        viz_every: viz,
        ..opts
    };
    let dirs = with_experiment!(c, false, reference, |exp| exp.write_decks(bed, &opts, &out))?;
    for d in &dirs {
        show!("{}", d.display());
    }
    show!(
        "{} deck director{} written",
        dirs.len(),
        if dirs.len() == 1 { "y" } else { "ies" }
    );
    Ok(ExitCode::SUCCESS)
}

/// `granval analyze`: a deck directory (or suite directory) after its engine ran, checked
/// against its unedited inputs, reduced as `compare` reduces a live run.
fn analyze(a: AnalyzeArgs) -> Result<ExitCode> {
    let AnalyzeArgs {
        dir,
        report,
        no_native,
        common,
    } = a;
    if let Some(rec) = granval::experiments::suite_deck::read_record(&dir)? {
        return analyze_suite(&dir, rec, &report, no_native, &common);
    }
    let case_file = dir.join("case.toml");
    let _out = claim(
        &report,
        "--report",
        common.force,
        &protected(&common)
            .input(&case_file)
            .store(&dir, "the deck directory being analysed"),
    )?;
    let c = load(&case_file).with_context(|| {
        format!(
            "{}: not a `granval deck` directory (it holds case.toml)",
            dir.display()
        )
    })?;
    let warned = warnings(&c, &case_file);
    let opts = options(&common);
    let mut o = with_experiment!(c, false, |exp| exp
        .analyze_decks(&dir, !no_native, &opts, &report))?;
    o.notes.splice(0..0, warned);
    let r = report_of(vec![o]);
    let code = finish(&r, &report, &format!("granval analyze {}", dir.display()))?;
    if no_native
        && !r.errored
        && r.checks.iter().all(|c| {
            c.gate == granval::compare::Gate::Coverage
                || c.gate == granval::compare::Gate::Published
        })
    {
        let engines = granval::compare::sweep::CaseSummary::read(&report)
            .map(|s| s.engines.into_keys().collect::<Vec<_>>().join(", "))
            .unwrap_or_else(|_| "the reference engine".into());
        show!("--no-native: {engines} observables only, nothing compared between engines");
    }
    Ok(code)
}

/// `granval bench`: throughput of the native engine against LIGGGHTS in the same run.
fn bench(a: BenchArgs) -> Result<ExitCode> {
    let BenchArgs {
        n,
        steps,
        reps,
        penetration,
        clumps,
        scaling,
        ns,
        unsorted,
        budget,
    } = a;
    if scaling {
        if ns.is_empty() || ns.contains(&0) || budget.is_nan() || budget <= 0.0 || reps == 0 {
            eprintln!(
                "error: --ns needs bed sizes above 0, --budget a positive number and --reps at least 1 (got --ns {ns:?} --budget {budget} --reps {reps})"
            );
            return Ok(ExitCode::from(2));
        }
        granval::bench::scaling::run(&granval::bench::scaling::ScalingOptions {
            ns,
            budget,
            reps,
            seed: 1,
            unsorted,
            liggghts: true,
            cache: granval::bench::scaling::cache_dir(),
        })?;
        return Ok(ExitCode::SUCCESS);
    }
    let penetration =
        penetration.or(clumps.then(|| PathBuf::from(granval::bench::CLUMP_BENCH_CASE)));
    match penetration {
        Some(case) => {
            granval::bench::run_penetration(&case, steps.unwrap_or(10_000), reps)?;
        }
        None => granval::bench::run(n, steps.unwrap_or(2000), reps)?,
    }
    Ok(ExitCode::SUCCESS)
}

/// `granval stress`: stress and velocity fields of a penetration case in both engines.
fn stress(a: StressArgs) -> Result<ExitCode> {
    let StressArgs {
        case,
        out,
        reuse,
        kernel_width,
        study,
        common,
    } = a;
    let mut opts = options(&common);
    opts.reuse = reuse;
    opts.study = study;
    opts.stress = true;
    opts.mpi_procs = opts.mpi_procs.max(2);
    if let Some(w) = kernel_width
        && !(w.is_finite() && w > 0.0 && w <= 5.0)
    {
        bail!("--kernel-width {w}: must lie in (0, 5] grain diameters");
    }
    opts.kernel_width = kernel_width;
    let c = load(&case)?;
    with_experiment!(c, true, |exp| {
        if !exp.has_stress_fields() {
            bail!(
                "{}: `granval stress` takes a penetration case, not a {} case",
                case.display(),
                exp.kind()
            );
        }
        let keep = protected(&common).input(&case);
        let _out = if reuse {
            output_dir::reuse(&out, "--out", &keep, &command_line())?
        } else {
            claim(&out, "--out", common.force, &keep)?
        };
        let o = runner::compare(&exp, &opts, &out);
        finish(
            &report_of(vec![o]),
            &out,
            &format!("{}: stress fields and MALT", exp.name()),
        )
    })
}

/// `granval agreement`: the pairwise agreement of several codes on the same beds.
fn agreement(a: AgreementArgs) -> Result<ExitCode> {
    let AgreementArgs {
        case,
        runs,
        chaos,
        report,
        force,
    } = a;
    let mut keep = Protected::default()
        .input(&case)
        .input(&chaos)
        .store(Path::new("reference"), "the reference store");
    for r in &runs {
        keep = keep.store(r, "a run directory being read");
    }
    let _out = claim(&report, "--report", force, &keep)?;
    let o = granval::experiments::penetration::agreement::agreement(&case, &runs, &chaos)?;
    let r = report_of(vec![o]);
    finish(
        &r,
        &report,
        &format!("granval agreement {}", case.display()),
    )
}

/// `granval chaos`: the chaos baseline of a case (every bed twice, once moved by one ulp).
fn chaos(a: ChaosArgs) -> Result<ExitCode> {
    let ChaosArgs {
        case,
        out,
        family,
        common,
    } = a;
    use granval::experiments::chaos;
    let c = load(&case)?;
    // The claimed directory (its lock) is held until the record is written.
    let (r, _out) = with_experiment!(c, false, |exp| {
        // Refused before the output directory is claimed.
        if !exp.has_chaos_baseline() {
            bail!(
                "{}: `granval chaos` takes a penetration or impact2d case, not a {} case: the chaos baseline (docs/statistics.md) is a spread over the beds of a granular flow, which such a case has not",
                case.display(),
                exp.kind()
            );
        }
        let held = claim(
            &out,
            "--out",
            common.force,
            &protected(&common).input(&case),
        )?;
        anyhow::Ok((exp.chaos(&family, &options(&common), &out)?, held))
    })?;
    r.write(&out)?;
    let (s, n) = r.spread();
    show!(
        "{}: chaos spread of {} s_c = {s:.4} over {n} beds (per bed: {}); {}",
        r.case,
        r.quantity(),
        r.values()
            .iter()
            .map(|c| format!("{c:+.4}"))
            .collect::<Vec<_>>()
            .join(", "),
        out.join(chaos::CHAOS_FILE).display()
    );
    Ok(ExitCode::SUCCESS)
}

/// `granval validate`: what `compare` would refuse before running, and what follows
/// from the case (grains, time step, steps, estimated time and output), running nothing.
fn validate(a: ValidateArgs) -> Result<ExitCode> {
    let ValidateArgs { case, allow_large } = a;
    let c = load(&case)?;
    let kind = c.kind();
    let engine = c.references().label;
    // Exactly what `compare` refuses before it runs (the reference engine's
    // limits, the start state, the resource limits): a case that validates runs.
    let (name, lines, refused) = with_experiment!(c, false, |exp| {
        exp.preflight()?;
        anyhow::Ok((
            exp.name().to_string(),
            granval::experiments::validation_summary(&exp),
            granval::experiments::limits::refuse(&exp.estimate(), &case.display().to_string()),
        ))
    })?;
    let refused = refused.filter(|_| !allow_large);
    show!(
        "{}: {} {kind} case `{name}` (reference engine {engine})",
        case.display(),
        if refused.is_some() {
            "too large to run here:"
        } else {
            "valid"
        }
    );
    let w = lines.iter().map(|l| l.label.len()).max().unwrap_or(0);
    for l in &lines {
        if l.comment.is_empty() {
            show!("  {:<w$}  {}", l.label, l.value);
        } else {
            show!("  {:<w$}  {}  ({})", l.label, l.value, l.comment);
        }
    }
    if let Some(why) = refused {
        bail!("{}: refused before running: {why}", case.display());
    }
    show!(
        "next: granval deck {} -o DIR   (the {engine} input to read or run), granval compare {} --report OUT",
        case.display(),
        case.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// `granval reference ...`: records refreshed from the live engine, made lean, verified.
fn reference(cmd: RefCmd) -> Result<ExitCode> {
    match cmd {
        RefCmd::Refresh {
            suite,
            cases,
            reference,
            only,
            engine,
        } => {
            let s = suite::load(&cases, &suite)?;
            let reference = s.reference_root(&reference);
            let paths: Vec<PathBuf> = match only {
                Some(p) => vec![p],
                None => s.cases.into_iter().map(|e| e.path).collect(),
            };
            // One process, as `compare` runs the reference by default (penetration runs
            // use at least two either way).
            let opts = Options {
                reference_root: reference,
                mpi_procs: 1,
                progress: output().progress(),
                engine_timeout: engine.engine_timeout,
                engine_stall: engine.engine_stall,
                ..Options::default()
            };
            for p in paths {
                let c = load(&p)?;
                let lines = with_experiment!(c, false, |exp| runner::refresh(&exp, &opts))?;
                for l in lines {
                    show!("{l}");
                }
            }
            Ok(ExitCode::SUCCESS)
        }
        RefCmd::Lean { records, add_beds } => {
            let (reference_root, paths) = records.resolve()?;
            let opts = Options {
                reference_root,
                progress: output().progress(),
                ..Options::default()
            };
            for p in &paths {
                let c = load(p)?;
                match with_experiment!(c, false, |exp| runner::lean_record(&exp, &opts, add_beds))?
                {
                    Some(lines) => {
                        for l in lines {
                            show!("{l}");
                        }
                    }
                    None => show!(
                        "{}: no record under {}",
                        p.display(),
                        opts.reference_root.display()
                    ),
                }
            }
            Ok(ExitCode::SUCCESS)
        }
        RefCmd::Verify { records } => {
            let (reference_root, paths) = records.resolve()?;
            let opts = Options {
                reference_root,
                progress: true,
                ..Options::default()
            };
            let (mut verified, mut failed) = (0, 0);
            for p in &paths {
                let c = load(p)?;
                match with_experiment!(c, false, |exp| runner::verify_record(&exp, &opts)) {
                    Ok(Some(line)) => {
                        verified += 1;
                        show!("{line}");
                    }
                    Ok(None) => show!(
                        "{}: no record under {}",
                        p.display(),
                        opts.reference_root.display()
                    ),
                    Err(e) => {
                        failed += 1;
                        eprintln!("error: {}: {e:#}", p.display());
                    }
                }
            }
            if failed > 0 || verified == 0 {
                bail!(
                    "{failed} of {} record(s) did not verify, {verified} did",
                    paths.len()
                );
            }
            show!("{verified} record(s) verified");
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// `granval release digest|table` (docs/release.md, "Status of every claim").
fn release(cmd: ReleaseCmd) -> Result<ExitCode> {
    use granval::experiments::release_status as rs;
    match cmd {
        ReleaseCmd::Digest { report_dirs, repo } => {
            let rules = rs::CurrentRules::read(&repo, "release")?;
            let mut all = Vec::new();
            for dir in &report_dirs {
                all.extend(rs::digests_of_report(dir, &rules)?);
            }
            for p in rs::write_digests(&all, &repo.join(rs::DIGEST_DIR))? {
                outln!("wrote {}", p.display());
            }
            outln!("now run `granval release table` to bring docs/release.md up to date");
            Ok(ExitCode::SUCCESS)
        }
        ReleaseCmd::Gate { only, repo } => {
            let (text, code) = rs::gate_of_digests(&repo, &only)?;
            out!("{text}");
            Ok(ExitCode::from(code as u8))
        }
        ReleaseCmd::Expect { repo } => {
            let digests = rs::read_digests(&repo.join(rs::DIGEST_DIR))?;
            out!("{}", rs::expect_drafts(&digests));
            Ok(ExitCode::SUCCESS)
        }
        ReleaseCmd::Table { check, repo } => {
            let section = rs::generate(&repo)?;
            let doc_path = repo.join(rs::DOC_FILE);
            let doc = granval::rundata::fsio::read_to_string(
                &doc_path,
                granval::rundata::fsio::MAX_CASE_FILE,
                "docs/release.md",
            )?;
            let new = rs::splice(&doc, &section)?;
            if check {
                if new == doc {
                    outln!("{}: the status table is up to date", doc_path.display());
                    Ok(ExitCode::SUCCESS)
                } else {
                    outln!(
                        "{}: the status table is stale; run `granval release table`",
                        doc_path.display()
                    );
                    Ok(ExitCode::from(1))
                }
            } else {
                granval::rundata::fsio::write_atomic(&doc_path, new.as_bytes())?;
                outln!("wrote the status table into {}", doc_path.display());
                Ok(ExitCode::SUCCESS)
            }
        }
    }
}

fn main() -> ExitCode {
    use granval::engines::children;
    // SIGINT/SIGTERM/SIGHUP end the engines and remove granval's temporary directories.
    if let Err(e) = children::exit_on_signals() {
        eprintln!("error: {e:#}");
        return ExitCode::from(2);
    }
    let result = real_main();
    // A signal's cleanup owns the exit (its code and its one line).
    children::wait_if_interrupted();
    let code = match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    };
    // A closed pipe stops the printing quietly; any other failure to write stdout (a
    // full disk under a redirection) is an error.
    match granval::report::console::failure() {
        Some(e) => {
            eprintln!("error: cannot write to standard output: {e}");
            ExitCode::from(2)
        }
        None => code,
    }
}
