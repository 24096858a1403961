//! The commands' shared flow: run a case in the native engine and in the reference
//! engine (live LIGGGHTS when installed, else the recorded run under `reference/`),
//! compare, and collect everything a report needs.

use crate::case::Case;
use crate::compare::{Check, trajectory};
use crate::engines::liggghts::{self, Liggghts};
use crate::engines::native::Native;
use crate::engines::recorded::Recorded;
use crate::engines::{Engine, RunOutput};
use crate::report::CaseRun;
use crate::rundata::frames::write_particles_csv;
use crate::rundata::provenance::write_provenance;
use std::path::{Path, PathBuf};

#[derive(Debug, Clone)]
pub struct Options {
    pub reference_root: PathBuf,
    /// Refuse the recorded fallback (CI sets this: live engines are required there).
    pub require_live: bool,
    pub mpi_procs: usize,
    pub progress: bool,
    pub native: Native,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            reference_root: PathBuf::from("reference"),
            require_live: std::env::var("GRANVAL_REQUIRE_LIVE").is_ok_and(|v| v == "1"),
            mpi_procs: 1,
            progress: false,
            native: Native::default(),
        }
    }
}

pub struct CaseResult {
    pub checks: Vec<Check>,
    pub run: Option<CaseRun>,
    pub notes: Vec<String>,
    pub errored: bool,
}

/// Writes a run as `particles.csv` + `provenance.json` into `dir`.
pub fn save_run(dir: &Path, out: &RunOutput) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)?;
    write_particles_csv(&dir.join("particles.csv"), &out.frames)?;
    write_provenance(&dir.join("provenance.json"), &out.provenance)
}

/// The reference run of a case: live LIGGGHTS if installed, else the recorded one.
pub fn reference_run(
    case: &Case,
    opts: &Options,
    run_dir: &Path,
) -> anyhow::Result<(RunOutput, String, Vec<String>)> {
    let mut notes = Vec::new();
    if liggghts::installed_version("liggghts").is_some() {
        let eng = Liggghts {
            mpi_procs: opts.mpi_procs,
            ..Liggghts::default()
        };
        std::fs::create_dir_all(run_dir)?;
        let out = eng.run(case, run_dir)?;
        return Ok((out, "live".into(), notes));
    }
    if opts.require_live {
        anyhow::bail!(
            "LIGGGHTS is not installed but live engines are required (GRANVAL_REQUIRE_LIVE=1 / --require-live)"
        );
    }
    let rec = Recorded::for_case(&opts.reference_root, case);
    let out = rec.run(case, run_dir)?;
    notes.push(format!(
        "LIGGGHTS is not installed here: {} was compared against the RECORDED LIGGGHTS run in {} ({}, recorded {}).",
        case.name,
        rec.dir.display(),
        out.provenance.version,
        out.provenance.date
    ));
    Ok((out, format!("recorded {}", rec.dir.display()), notes))
}

/// Native vs reference for one micro case; outputs of both runs go under `out_dir`.
pub fn compare_case(case: &Case, opts: &Options, out_dir: &Path) -> CaseResult {
    let native_dir = out_dir.join("native");
    let ref_dir = out_dir.join("liggghts");
    let native = match opts.native.run(case, &native_dir) {
        Ok(o) => o,
        Err(e) => {
            return CaseResult {
                checks: vec![Check::error(
                    format!("{}: native run", case.name),
                    format!("{e:#}"),
                )],
                run: None,
                notes: vec![],
                errored: true,
            };
        }
    };
    let (reference, source, notes) = match reference_run(case, opts, &ref_dir) {
        Ok(r) => r,
        Err(e) => {
            return CaseResult {
                checks: vec![Check::error(
                    format!("{}: reference run", case.name),
                    format!("{e:#}"),
                )],
                run: None,
                notes: vec![format!(
                    "the reference engine failed for {}: this is an error, not a pass",
                    case.name
                )],
                errored: true,
            };
        }
    };
    let mut errored = false;
    let mut checks = Vec::new();
    for (dir, run) in [(&native_dir, &native), (&ref_dir, &reference)] {
        if let Err(e) = save_run(dir, run) {
            checks.push(Check::error(
                format!("{}: writing outputs", case.name),
                format!("{e:#}"),
            ));
            errored = true;
        }
    }
    checks.extend(trajectory::compare(case, &native.frames, &reference.frames));
    errored |= checks.iter().any(|c| c.metric == "error");
    CaseResult {
        checks,
        run: Some(CaseRun {
            case: case.name.clone(),
            case_file: case.source.display().to_string(),
            test_engine: "native".into(),
            reference_engine: reference.provenance.engine.clone(),
            reference_version: reference.provenance.version.clone(),
            reference_source: source,
            wall_time_test_s: native.provenance.wall_time_s,
            wall_time_reference_s: reference.provenance.wall_time_s,
        }),
        notes,
        errored,
    }
}

/// Case files of a suite: `cases/<suite>/*.toml`, sorted.
pub fn suite_cases(cases_root: &Path, suite: &str) -> anyhow::Result<Vec<PathBuf>> {
    let dir = cases_root.join(suite);
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map_err(|e| anyhow::anyhow!("cannot list suite {suite:?} in {}: {e}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    v.sort();
    if v.is_empty() {
        anyhow::bail!("suite {suite:?}: no case files in {}", dir.display());
    }
    Ok(v)
}
