//! A whole suite as deck directories for a cluster (`granval deck --suite S --scheduler
//! slurm`), what came back of it (`granval status`), and its analysis (`granval analyze`
//! on the directory): the release suite is hundreds of reference-engine runs, work for a
//! job array rather than a loop on two cores.
//!
//! Layout (docs/cluster.md):
//! ```text
//! DIR/suite.json          what was asked, each case's canonical hash, granval's version and commit
//! DIR/units.tsv           one line per unit: index, id, case, engine, directory, command, estimate
//! DIR/submit.sh           one `sbatch --array` per engine and the dependent analysis job
//! DIR/run-unit.sh         one array task: the engine in its unit directory (a no-op when done)
//! DIR/cases/<case>/       the case's `granval deck` directory (case.toml, README, units)
//! DIR/state/<index>.*     per unit: Slurm's output (.out), running / done markers
//! ```
//! The unit directories hold exactly what `granval deck` writes and what the engine adds
//! (a penetration bed directory refuses foreign files); granval's own bookkeeping lives in
//! `state/`.

use super::{Experiment, Options};
use crate::case::AnyCase;
use crate::engines::process::Limits;
use crate::rundata::fsio;
use anyhow::{Context, Result, bail, ensure};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub const SUITE_FILE: &str = "suite.json";
pub(crate) const UNITS_FILE: &str = "units.tsv";
pub const SUBMIT_FILE: &str = "submit.sh";
pub(crate) const RUN_UNIT_FILE: &str = "run-unit.sh";
pub(crate) const CASES_DIR: &str = "cases";
pub(crate) const STATE_DIR: &str = "state";
/// The array job ids `submit.sh` submitted, one line per engine (`engine<TAB>job id`).
pub(crate) const JOBS_FILE: &str = "jobs.tsv";
/// The start of the line LIGGGHTS and LAMMPS write to their log when a `run` ends (the
/// closing "Total wall time" goes to stdout only in LIGGGHTS 3.8): a log without it is of
/// a run that never finished a `run` command.
pub(crate) const LOG_COMPLETE: &str = "Loop time of";

/// The columns of `units.tsv`, in order (its header line).
pub(crate) const UNIT_COLUMNS: [&str; 9] = [
    "index", "unit", "case", "engine", "dir", "command", "time_s", "log", "output",
];

/// One engine run of the suite: a line of `units.tsv`.
#[derive(Debug, Clone, PartialEq)]
pub struct UnitRow {
    /// 1-based; the Slurm array task id of the unit.
    pub index: usize,
    /// `<case>` or `<case>/<unit>` (a bed, a variant).
    pub id: String,
    pub case: String,
    /// `liggghts` or `lammps`.
    pub engine: String,
    /// The unit's run directory, relative to the suite directory.
    pub dir: String,
    /// The command run in `dir` (the one the case's deck README gives).
    pub command: String,
    /// Estimated run time of the unit, seconds: the case's native estimate
    /// (`granval validate`) shared equally by its units.
    pub time_s: u64,
    /// The engine's log, in `dir`.
    pub log: String,
    /// The engine's main output, in `dir` (non-empty when the run is complete).
    pub output: String,
}

impl UnitRow {
    fn line(&self) -> String {
        [
            self.index.to_string(),
            self.id.clone(),
            self.case.clone(),
            self.engine.clone(),
            self.dir.clone(),
            self.command.clone(),
            self.time_s.to_string(),
            self.log.clone(),
            self.output.clone(),
        ]
        .join("\t")
    }
}

/// One case as `suite.json` records it.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct CaseRecord {
    pub name: String,
    /// The case file as the suite names it, where `granval deck` read it.
    pub source: String,
    /// Its deck directory, relative to the suite directory (holds the copy, case.toml).
    pub dir: String,
    pub kind: String,
    /// `Case::canonical_hash` of the case when the decks were written: `analyze` refuses
    /// a case.toml edited since.
    pub canonical_hash: String,
    pub theory: bool,
    pub units: usize,
    /// The reference engine's whole-comparison estimate, particle-steps.
    pub particle_steps: f64,
}

/// `suite.json`: what was asked and with which granval.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct SuiteRecord {
    pub suite: String,
    pub description: String,
    /// The cases directory the suite was read from (absolute): `analyze` reads the
    /// suite's claims from there.
    pub cases_root: String,
    /// The suite file's sha256: `analyze` evaluates the claims of this suite file only.
    pub suite_file_sha256: String,
    /// `--only` as given (empty: the whole suite).
    pub only: Vec<String>,
    pub scheduler: String,
    pub np: usize,
    pub partition: Option<String>,
    /// `--time` as given (`auto` or HH:MM:SS).
    pub time: String,
    pub granval_version: String,
    pub git_commit: String,
    pub written: String,
    pub cases: Vec<CaseRecord>,
}

/// How the array jobs ask for resources.
#[derive(Debug, Clone)]
pub struct Scheduler {
    pub np: usize,
    pub partition: Option<String>,
    /// `None`: auto (from the estimate, [`auto_time`]).
    pub time: Option<String>,
    /// The granval binary the analysis job runs.
    pub granval: PathBuf,
}

/// `--time` checked: `auto` or `[D-]HH:MM:SS` as Slurm reads it.
pub fn parse_time(s: &str) -> Result<Option<String>> {
    if s == "auto" {
        return Ok(None);
    }
    let (days, hms) = match s.split_once('-') {
        Some((d, rest)) => (Some(d), rest),
        None => (None, s),
    };
    let parts: Vec<&str> = hms.split(':').collect();
    let num = |p: &str| !p.is_empty() && p.len() <= 2 && p.chars().all(|c| c.is_ascii_digit());
    let ok = days.is_none_or(|d| !d.is_empty() && d.chars().all(|c| c.is_ascii_digit()))
        && parts.len() == 3
        && num(parts[0])
        && num(parts[1])
        && num(parts[2])
        && parts[1].parse::<u32>().is_ok_and(|m| m < 60)
        && parts[2].parse::<u32>().is_ok_and(|m| m < 60);
    ensure!(
        ok,
        "--time {s:?}: give `auto` or a Slurm time limit HH:MM:SS (or D-HH:MM:SS)"
    );
    Ok(Some(s.to_string()))
}

/// The time limit of a job that runs `particle_steps`: the engine timeout granval itself
/// would give the run (`engines::process::Limits::derived`: particle-steps at 5e5 per
/// second, six times the 3e6 per second `granval validate` estimates with, at least
/// 10 min), as Slurm's HH:MM:SS rounded up to the minute.
pub(crate) fn auto_time(particle_steps: f64) -> String {
    let t = Limits::derived(particle_steps, None, None)
        .timeout
        .as_secs();
    let m = t.div_ceil(60);
    format!("{:02}:{:02}:00", m / 60, m % 60)
}

/// The command a unit runs in its directory, as the case's deck README gives it.
pub(crate) fn unit_command(binary: &str, deck: &str, log: &str, np: usize) -> String {
    if np <= 1 {
        format!("{binary} -in {deck} -log {log}")
    } else {
        format!("mpirun -np {np} {binary} -in {deck} -log {log}")
    }
}

/// The decks of one case into `dir` (as `granval deck` writes them) and its units.
fn write_case(
    case: AnyCase,
    source: &Path,
    dir: &Path,
    rel: &str,
    np: usize,
    opts: &Options,
) -> Result<(CaseRecord, Vec<UnitRow>)> {
    let kind = case.kind();
    let name = case.name().to_string();
    let (dirs, files, engine, estimate, hash) = crate::with_experiment!(case, false, |exp| {
        let dirs = exp.write_decks(super::BedBy::Native, opts, dir)?;
        (
            dirs,
            exp.deck_files(),
            exp.reference_engine(),
            exp.estimate(),
            exp.canonical_hash(),
        )
    });
    // LIGGGHTS penetration runs use at least two processes in `compare` (and so in
    // `check`); the same count here reproduces them.
    let np = if kind == "penetration" { np.max(2) } else { np };
    let n = dirs.len().max(1);
    let per_unit = estimate.particle_steps / n as f64;
    let mut rows = Vec::new();
    for d in &dirs {
        let sub = d
            .strip_prefix(dir)
            .with_context(|| format!("{} is not under {}", d.display(), dir.display()))?
            .to_string_lossy()
            .into_owned();
        let (id, udir) = if sub.is_empty() {
            (name.clone(), rel.to_string())
        } else {
            (format!("{name}/{sub}"), format!("{rel}/{sub}"))
        };
        rows.push(UnitRow {
            index: 0,
            id,
            case: name.clone(),
            engine: engine.label().to_lowercase(),
            dir: udir,
            command: unit_command(files.binary, files.deck, files.log, np),
            time_s: (per_unit / super::NATIVE_PARTICLE_STEPS_PER_S).ceil() as u64,
            log: files.log.to_string(),
            output: files.outputs.first().map_or(files.log, |o| o.0).to_string(),
        });
    }
    Ok((
        CaseRecord {
            name,
            source: source.display().to_string(),
            dir: rel.to_string(),
            kind: kind.into(),
            canonical_hash: hash.to_string(),
            theory: true,
            units: rows.len(),
            particle_steps: estimate.particle_steps,
        },
        rows,
    ))
}

/// `granval deck --suite`: every entry's decks under `out/cases/<case>/`, then
/// `units.tsv`, `suite.json`, `run-unit.sh` and `submit.sh`. Returns the units.
pub fn write(
    suite: &super::suite::Suite,
    suite_file: &Path,
    entries: &[super::suite::SuiteCase],
    only: &[PathBuf],
    out: &Path,
    sched: &Scheduler,
    opts: &Options,
) -> Result<Vec<UnitRow>> {
    ensure!(
        !entries.is_empty(),
        "suite {}: no case to write",
        suite.name
    );
    for e in entries {
        if e.stress {
            bail!(
                "suite {}: {} runs with stress = true (contact snapshots and the stress fields), which `granval deck` does not write: leave it out with --only, or run it with `granval stress`",
                suite.name,
                e.path.display()
            );
        }
    }
    std::fs::create_dir_all(out.join(STATE_DIR))
        .with_context(|| format!("cannot create {}", out.join(STATE_DIR).display()))?;
    let mut rows = Vec::new();
    let mut cases = Vec::new();
    for e in entries {
        let case = AnyCase::load(&e.path)?;
        let rel = format!("{CASES_DIR}/{}", case.name());
        ensure!(
            !cases.iter().any(|c: &CaseRecord| c.dir == rel),
            "suite {}: two cases are named {:?} ({}): their decks would share {rel}",
            suite.name,
            case.name(),
            e.path.display()
        );
        let (mut rec, r) = write_case(case, &e.path, &out.join(&rel), &rel, sched.np, opts)
            .with_context(|| format!("writing the decks of {}", e.path.display()))?;
        rec.theory = e.theory;
        cases.push(rec);
        rows.extend(r);
    }
    for (i, r) in rows.iter_mut().enumerate() {
        r.index = i + 1;
    }
    let suite_text = std::fs::read(suite_file)
        .with_context(|| format!("cannot read {}", suite_file.display()))?;
    let cases_root = suite_file
        .parent()
        .and_then(Path::parent)
        .map(|p| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf()))
        .unwrap_or_default();
    let record = SuiteRecord {
        suite: suite.name.clone(),
        cases_root: cases_root.display().to_string(),
        description: suite.description.clone(),
        suite_file_sha256: crate::rundata::provenance::Sha256::of(&suite_text).to_string(),
        only: only.iter().map(|p| p.display().to_string()).collect(),
        scheduler: "slurm".into(),
        np: sched.np,
        partition: sched.partition.clone(),
        time: sched.time.clone().unwrap_or_else(|| "auto".into()),
        granval_version: env!("CARGO_PKG_VERSION").into(),
        git_commit: option_env!("GRANVAL_GIT_COMMIT").unwrap_or("").into(),
        written: chrono::Utc::now().to_rfc3339(),
        cases,
    };
    let write = |name: &str, text: &str, exec: bool| -> Result<()> {
        let p = out.join(name);
        fsio::write_atomic(&p, text.as_bytes())?;
        if exec {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755))
                .with_context(|| format!("cannot make {} executable", p.display()))?;
        }
        Ok(())
    };
    write(UNITS_FILE, &units_tsv(&rows), false)?;
    write(
        SUITE_FILE,
        &(serde_json::to_string_pretty(&record)? + "\n"),
        false,
    )?;
    write(RUN_UNIT_FILE, &run_unit_script(), true)?;
    write(SUBMIT_FILE, &submit_script(&record, &rows, sched), true)?;
    Ok(rows)
}

/// The text of `units.tsv`: a header line, then one line per unit.
pub(crate) fn units_tsv(rows: &[UnitRow]) -> String {
    let mut s = UNIT_COLUMNS.join("\t") + "\n";
    for r in rows {
        s += &r.line();
        s.push('\n');
    }
    s
}

/// Reads `units.tsv` of a suite directory, every field checked.
pub fn read_units(dir: &Path) -> Result<Vec<UnitRow>> {
    let path = dir.join(UNITS_FILE);
    let text = fsio::read_to_string(&path, 64 << 20, "units.tsv of a suite directory")?;
    let mut lines = text.lines();
    let header = lines.next().unwrap_or("");
    ensure!(
        header == UNIT_COLUMNS.join("\t"),
        "{}: header {header:?}: expected the columns {}",
        path.display(),
        UNIT_COLUMNS.join(", ")
    );
    let mut rows = Vec::new();
    for (k, l) in lines.enumerate() {
        let f: Vec<&str> = l.split('\t').collect();
        ensure!(
            f.len() == UNIT_COLUMNS.len(),
            "{} line {}: {} fields, expected {}",
            path.display(),
            k + 2,
            f.len(),
            UNIT_COLUMNS.len()
        );
        let num = |i: usize| -> Result<u64> {
            f[i].parse().with_context(|| {
                format!(
                    "{} line {}: {} = {:?}: not a whole number",
                    path.display(),
                    k + 2,
                    UNIT_COLUMNS[i],
                    f[i]
                )
            })
        };
        let index = num(0)? as usize;
        ensure!(
            index == k + 1,
            "{} line {}: index {index}, expected {} (units are numbered from 1 in order)",
            path.display(),
            k + 2,
            k + 1
        );
        let rel = Path::new(f[4]);
        ensure!(
            rel.components()
                .all(|c| matches!(c, std::path::Component::Normal(_))),
            "{} line {}: dir = {:?}: must be a plain relative directory",
            path.display(),
            k + 2,
            f[4]
        );
        rows.push(UnitRow {
            index,
            id: f[1].into(),
            case: f[2].into(),
            engine: f[3].into(),
            dir: f[4].into(),
            command: f[5].into(),
            time_s: num(6)?,
            log: f[7].into(),
            output: f[8].into(),
        });
    }
    ensure!(!rows.is_empty(), "{}: no unit", path.display());
    Ok(rows)
}

/// Reads `suite.json` of a suite directory; `None` when `dir` is not one.
pub fn read_record(dir: &Path) -> Result<Option<SuiteRecord>> {
    let path = dir.join(SUITE_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let text = fsio::read_to_string(&path, 16 << 20, "suite.json of a suite directory")?;
    let r: SuiteRecord = serde_json::from_str(&text).with_context(|| {
        format!(
            "{}: not the suite.json `granval deck --suite` writes",
            path.display()
        )
    })?;
    Ok(Some(r))
}

/// The engines of `rows` in order of first appearance, each with its units' indices.
pub fn by_engine(rows: &[UnitRow]) -> Vec<(String, Vec<usize>)> {
    let mut v: Vec<(String, Vec<usize>)> = Vec::new();
    for r in rows {
        match v.iter_mut().find(|(e, _)| *e == r.engine) {
            Some((_, ix)) => ix.push(r.index),
            None => v.push((r.engine.clone(), vec![r.index])),
        }
    }
    v
}

/// Shell-quotes `s` (single quotes).
fn sh(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// `run-unit.sh INDEX` (or the array task id): runs unit INDEX of `units.tsv` in its
/// directory unless it is done; marks it running while it runs and done when the engine
/// exited 0 and its log and main output are complete ([`LOG_COMPLETE`]).
pub(crate) fn run_unit_script() -> String {
    format!(
        r#"#!/bin/bash
# One unit of a granval suite directory (written by `granval deck --suite`): the
# reference engine in the unit's directory, as units.tsv gives it. A unit that is done
# already (state/INDEX.done, its log complete and its main output non-empty) is not run
# again. Usage: run-unit.sh INDEX (a Slurm array task takes its SLURM_ARRAY_TASK_ID).
set -u
here=$(cd "$(dirname "${{BASH_SOURCE[0]}}")" && pwd)
# Slurm runs a copy of this script from its spool directory, in --chdir (the suite
# directory): units.tsv is found beside the script, else in the working directory.
if [ -f "$here/{UNITS_FILE}" ]; then DIR=$here; else DIR=$(pwd); fi
i=${{1:-${{SLURM_ARRAY_TASK_ID:-}}}}
if [ -z "$i" ]; then echo "run-unit.sh: give a unit index (a line of units.tsv)" >&2; exit 2; fi
row=$(awk -F'\t' -v i="$i" 'NR > 1 && $1 == i' "$DIR/{UNITS_FILE}")
if [ -z "$row" ]; then echo "run-unit.sh: no unit $i in $DIR/{UNITS_FILE}" >&2; exit 2; fi
IFS=$'\t' read -r _ unit _ engine dir command _ log output <<<"$row"
state="$DIR/{STATE_DIR}"
mkdir -p "$state"
complete() {{
  [ -s "$DIR/$dir/$output" ] && grep -q '^{LOG_COMPLETE}' "$DIR/$dir/$log" 2>/dev/null
}}
if [ -f "$state/$i.done" ] && complete; then
  echo "unit $i ($unit) is done: nothing to run"
  exit 0
fi
rm -f "$state/$i.done"
echo "${{SLURM_JOB_ID:-}} $(hostname) $(date -u +%Y-%m-%dT%H:%M:%SZ)" >"$state/$i.running"
trap 'rm -f "$state/$i.running"' EXIT
# Open MPI refuses root unless told; a cluster job is not root, a test node may be.
if [ "$(id -u)" = 0 ]; then export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1; fi
cd "$DIR/$dir" || exit 2
echo "unit $i ($unit, $engine) in $DIR/$dir: $command"
started=$(date +%s)
bash -c "$command" </dev/null
rc=$?
if [ "$rc" = 0 ] && complete; then
  echo "$(date -u +%Y-%m-%dT%H:%M:%SZ) $(hostname) $(( $(date +%s) - started )) s" >"$state/$i.done"
  echo "unit $i ($unit): done"
  exit 0
fi
echo "unit $i ($unit): FAILED (exit $rc; complete log and $output: $(complete && echo yes || echo no))" >&2
tail -n 20 "$log" >&2 2>/dev/null
[ "$rc" = 0 ] && exit 1
exit "$rc"
"#
    )
}

/// `submit.sh [--missing]`: one `sbatch --array` per engine (one task per unit; with
/// `--missing` only the units `granval status` does not find done), then the analysis
/// job after all of them (`--dependency=afterany`), which runs `granval analyze`.
pub(crate) fn submit_script(rec: &SuiteRecord, rows: &[UnitRow], sched: &Scheduler) -> String {
    let mut s = format!(
        r#"#!/bin/bash
# Submits the suite `{suite}` to Slurm (written by granval {version} `granval deck --suite`).
#   ./submit.sh            every unit: one array job per engine, then the analysis job
#   ./submit.sh --missing  only the units not done (`granval status`), then the analysis
# Re-running a unit that is done is a no-op (run-unit.sh). The analysis job runs
# `granval analyze` on this directory into report/ after every array task ended.
set -euo pipefail
DIR=$(cd "$(dirname "${{BASH_SOURCE[0]}}")" && pwd)
GRANVAL=${{GRANVAL:-{granval}}}
missing=0
case "${{1:-}}" in
  --missing) missing=1 ;;
  "") ;;
  *) echo "usage: $0 [--missing]" >&2; exit 2 ;;
esac
mkdir -p "$DIR/{STATE_DIR}"
deps=""
: >"$DIR/{STATE_DIR}/{JOBS_FILE}.new"
"#,
        suite = rec.suite,
        version = rec.granval_version,
        granval = sh(&sched.granval.display().to_string()),
    );
    let partition = sched
        .partition
        .as_ref()
        .map(|p| format!(" --partition={}", sh(p)))
        .unwrap_or_default();
    for (engine, ix) in by_engine(rows) {
        let steps: f64 = rows
            .iter()
            .filter(|r| r.engine == engine)
            .map(|r| r.time_s as f64 * super::NATIVE_PARTICLE_STEPS_PER_S)
            .fold(0.0, f64::max);
        let time = sched.time.clone().unwrap_or_else(|| auto_time(steps));
        let all = ix
            .iter()
            .map(|i| i.to_string())
            .collect::<Vec<_>>()
            .join(",");
        let np = rows
            .iter()
            .filter(|r| r.engine == engine)
            .map(|r| command_np(&r.command))
            .max()
            .unwrap_or(1);
        s += &format!(
            r#"
# {engine}: units {all} of {UNITS_FILE}, {np} task(s) each, at most {time} each
ids={all}
if [ "$missing" = 1 ]; then ids=$("$GRANVAL" status "$DIR" --not-done {engine}); fi
if [ -n "$ids" ]; then
  id=$(sbatch --parsable --job-name={job} --array="$ids" --ntasks={np} --time={time}{partition} \
    --chdir="$DIR" --output="$DIR/{STATE_DIR}/%a.out" "$DIR/{RUN_UNIT_FILE}")
  id=${{id%%;*}}
  echo "{engine}: array job $id, units $ids"
  printf '%s\t%s\n' {engine} "$id" >>"$DIR/{STATE_DIR}/{JOBS_FILE}.new"
  deps="$deps:$id"
else
  echo "{engine}: every unit is done"
fi
"#,
            job = sh(&format!("granval-{}-{engine}", rec.suite)),
        );
    }
    let analysis_steps: f64 = rec.cases.iter().map(|c| c.particle_steps).sum();
    s += &format!(
        r#"
mv "$DIR/{STATE_DIR}/{JOBS_FILE}.new" "$DIR/{STATE_DIR}/{JOBS_FILE}"
# The analysis: the native runs and every check, after every array task ended (done or
# not: `granval analyze` refuses what is missing or incomplete, naming it).
dep=""
if [ -n "$deps" ]; then dep="--dependency=afterany$deps"; fi
id=$(sbatch --parsable --job-name={job} $dep --ntasks=1 --time={time}{partition} \
  --chdir="$DIR" --output="$DIR/{STATE_DIR}/analyze.out" \
  --wrap="$(printf '%q ' "$GRANVAL" analyze "$DIR" --report "$DIR/report" --force)")
id=${{id%%;*}}
printf '%s\t%s\n' analyze "$id" >>"$DIR/{STATE_DIR}/{JOBS_FILE}"
echo "analysis: job $id -> $DIR/report (granval status $DIR shows progress)"
"#,
        job = sh(&format!("granval-{}-analyze", rec.suite)),
        time = sched
            .time
            .clone()
            .unwrap_or_else(|| auto_time(analysis_steps)),
    );
    s
}

/// The rank count of a unit command ([`unit_command`]).
fn command_np(command: &str) -> usize {
    command
        .strip_prefix("mpirun -np ")
        .and_then(|r| r.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(1)
}

/// Where a unit stands.
#[derive(Debug, Clone, PartialEq)]
pub enum UnitState {
    /// The engine exited 0 and its log and main output are complete.
    Done,
    /// Slurm lists the unit's task (pending or running), or without Slurm its running
    /// marker is there.
    Running(String),
    /// It ran and did not finish: the last lines of its log or Slurm output.
    Failed(String),
    /// Nothing ran.
    Missing,
}

impl UnitState {
    pub fn label(&self) -> &'static str {
        match self {
            UnitState::Done => "done",
            UnitState::Running(_) => "running",
            UnitState::Failed(_) => "failed",
            UnitState::Missing => "missing",
        }
    }
}

/// The array tasks Slurm still lists for this directory's jobs, by unit index (pending,
/// running, ...); `None` when there is no `squeue` or no job was submitted.
pub fn slurm_tasks(dir: &Path) -> Option<Vec<(usize, String)>> {
    let jobs = std::fs::read_to_string(dir.join(STATE_DIR).join(JOBS_FILE)).ok()?;
    let ids: Vec<&str> = jobs
        .lines()
        .filter_map(|l| l.split_once('\t'))
        .filter(|(e, _)| *e != "analyze")
        .map(|(_, id)| id.trim())
        .filter(|id| !id.is_empty() && id.chars().all(|c| c.is_ascii_digit()))
        .collect();
    if ids.is_empty() {
        return None;
    }
    // Every job squeue lists (one line per array task): asking for the ids alone errors
    // once Slurm has forgotten one of them.
    let out = std::process::Command::new("squeue")
        .args(["-h", "-r", "-o", "%F %K %T"])
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    let text = String::from_utf8_lossy(&out.stdout);
    Some(parse_squeue(&text, &ids))
}

/// The unit indices and states of the lines `squeue -h -r -o "%F %K %T"` prints (array
/// job id, task id, state) that belong to the array jobs `ids`.
pub(crate) fn parse_squeue(text: &str, ids: &[&str]) -> Vec<(usize, String)> {
    text.lines()
        .filter_map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            let [job, task, state] = f[..] else {
                return None;
            };
            ids.contains(&job)
                .then(|| Some((task.parse().ok()?, state.to_string())))
                .flatten()
        })
        .collect()
}

/// The last `n` lines of a file (lossy), or `None` when it is absent or empty.
fn tail(p: &Path, n: usize) -> Option<String> {
    let bytes = std::fs::read(p).ok()?;
    let text = String::from_utf8_lossy(&bytes);
    let lines: Vec<&str> = text.lines().collect();
    if lines.is_empty() {
        return None;
    }
    Some(lines[lines.len().saturating_sub(n)..].join("\n"))
}

/// Whether a unit's engine outputs are complete as far as files tell: its log holds the
/// end of a run ([`LOG_COMPLETE`]) and its main output is non-empty (with the exit code
/// `run-unit.sh` saw, recorded in its done marker; `analyze` checks the rest: every
/// input as written, every output of this deck and complete).
pub(crate) fn complete(dir: &Path, row: &UnitRow) -> bool {
    let d = dir.join(&row.dir);
    let log_done = std::fs::read(d.join(&row.log)).is_ok_and(|b| {
        String::from_utf8_lossy(&b)
            .lines()
            .any(|l| l.starts_with(LOG_COMPLETE))
    });
    log_done && std::fs::metadata(d.join(&row.output)).is_ok_and(|m| m.is_file() && m.len() > 0)
}

/// Where each unit stands, from Slurm (`queued`: the tasks [`slurm_tasks`] lists) and
/// the files: done = marked done by `run-unit.sh` and complete; running = listed by
/// Slurm, or (without Slurm) marked running; failed = ran and not done (the last lines
/// of its log, else of its Slurm output); missing = nothing ran.
pub fn status(dir: &Path, rows: &[UnitRow], queued: Option<&[(usize, String)]>) -> Vec<UnitState> {
    let state = dir.join(STATE_DIR);
    rows.iter()
        .map(|r| {
            let mark = |ext: &str| state.join(format!("{}.{ext}", r.index));
            if mark("done").exists() && complete(dir, r) {
                return UnitState::Done;
            }
            if let Some(q) = queued
                && let Some((_, st)) = q.iter().find(|(k, _)| *k == r.index)
            {
                return UnitState::Running(st.to_lowercase());
            }
            if queued.is_none() && mark("running").exists() {
                return UnitState::Running("running (by its marker; no squeue here)".into());
            }
            let log = dir.join(&r.dir).join(&r.log);
            let ran = log.exists() || mark("out").exists() || mark("running").exists();
            if !ran {
                return UnitState::Missing;
            }
            let why = tail(&log, 5)
                .map(|t| format!("{}:\n{t}", log.display()))
                .or_else(|| {
                    tail(&mark("out"), 5).map(|t| format!("{}:\n{t}", mark("out").display()))
                })
                .unwrap_or_else(|| {
                    if mark("running").exists() {
                        "its job ended without finishing (time limit, node failure?); no log".into()
                    } else {
                        "empty log".into()
                    }
                });
            UnitState::Failed(why)
        })
        .collect()
}

/// Canonical hash of a case file, for `analyze`'s refusal of an edited case.toml.
pub(crate) fn case_hash(path: &Path) -> Result<String> {
    let c = AnyCase::load(path)?;
    Ok(crate::with_experiment!(c, false, |exp| exp
        .canonical_hash()
        .to_string()))
}

/// Checks that every case of `rec` is in `dir` as written: its case.toml has the
/// canonical hash recorded, and the units of `units.tsv` are those of `suite.json`.
pub fn check_cases(dir: &Path, rec: &SuiteRecord, rows: &[UnitRow]) -> Result<()> {
    for c in &rec.cases {
        let file = dir.join(&c.dir).join("case.toml");
        let h = case_hash(&file)
            .with_context(|| format!("case {} of {}", c.name, dir.join(SUITE_FILE).display()))?;
        ensure!(
            h == c.canonical_hash,
            "{}: its canonical hash is {h}, {} recorded {} when the decks were written: the case was edited; write the decks again (`granval deck --suite`)",
            file.display(),
            dir.join(SUITE_FILE).display(),
            c.canonical_hash
        );
        let n = rows.iter().filter(|r| r.case == c.name).count();
        ensure!(
            n == c.units,
            "{}: {n} unit(s) of case {} but {} records {}",
            dir.join(UNITS_FILE).display(),
            c.name,
            dir.join(SUITE_FILE).display(),
            c.units
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_are_slurm_limits() {
        assert_eq!(parse_time("auto").unwrap(), None);
        assert_eq!(parse_time("01:30:00").unwrap().as_deref(), Some("01:30:00"));
        assert_eq!(
            parse_time("2-00:00:00").unwrap().as_deref(),
            Some("2-00:00:00")
        );
        for bad in ["1h", "01:60:00", "1:2", "", "x-01:00:00", "01:00:0a"] {
            assert!(parse_time(bad).is_err(), "{bad:?} accepted");
        }
        // At least the 10 min the engine timeout never goes below; then 5e5 per second.
        assert_eq!(auto_time(0.0), "00:10:00");
        assert_eq!(auto_time(5e5 * 3600.0), "01:00:00");
        assert_eq!(auto_time(5e5 * 3601.0), "01:01:00");
    }

    #[test]
    fn squeue_lines_of_other_jobs_are_not_ours() {
        let text = "17 1 RUNNING\n17 2 PENDING\n18 3 RUNNING\n99 1 RUNNING\n20 N/A RUNNING\n";
        assert_eq!(
            parse_squeue(text, &["17", "18"]),
            vec![
                (1, "RUNNING".to_string()),
                (2, "PENDING".to_string()),
                (3, "RUNNING".to_string())
            ]
        );
        assert!(parse_squeue(text, &["5"]).is_empty());
    }

    #[test]
    fn commands_and_their_rank_counts() {
        let one = unit_command("liggghts", "in.x", "log.x", 1);
        assert_eq!(one, "liggghts -in in.x -log log.x");
        assert_eq!(command_np(&one), 1);
        let four = unit_command("lmp", "in.x", "log.x", 4);
        assert_eq!(four, "mpirun -np 4 lmp -in in.x -log log.x");
        assert_eq!(command_np(&four), 4);
    }
}
