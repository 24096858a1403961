//! `granval` command line. Exit codes: 0 every gated check passed, 1 a check failed,
//! 2 an error (bad input, crashed or silent engine).

use anyhow::{Context, Result};
use clap::{Parser, Subcommand, ValueEnum};
use granval::case::Case;
use granval::engines::Engine;
use granval::engines::liggghts::{self, Liggghts};
use granval::engines::native::Native;
use granval::pipeline::{self, Options};
use granval::report::Report;
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
}

#[derive(Clone, Copy, ValueEnum)]
enum EngineName {
    Native,
    Liggghts,
    /// LAMMPS (2D impact2d cases).
    Lammps,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run one case in one engine; writes OUT/particles.csv and OUT/provenance.json.
    Run {
        case: PathBuf,
        #[arg(long, value_enum, default_value = "native")]
        engine: EngineName,
        #[arg(long)]
        out: PathBuf,
        /// MPI processes for LIGGGHTS (`mpirun -np N`).
        #[arg(long, default_value_t = 1)]
        np: usize,
    },
    /// Run a case in the native engine and the reference engine and compare them.
    Compare {
        case: PathBuf,
        #[arg(long)]
        report: PathBuf,
        #[command(flatten)]
        common: Common,
    },
    /// Run every case of a suite and write one combined report (the main job).
    Check {
        #[arg(long, default_value = "micro")]
        suite: String,
        #[arg(long)]
        report: PathBuf,
        #[arg(long, default_value = "cases")]
        cases: PathBuf,
        #[command(flatten)]
        common: Common,
    },
    /// Write a self-contained LIGGGHTS deck directory for a penetration case (one
    /// sub-directory per bed; README with the one-core and mpirun commands).
    Deck {
        case: PathBuf,
        #[arg(short = 'o', long = "out")]
        out: PathBuf,
        /// Who prepares the beds: `native` (exact `data.bed`, needed to compare engines)
        /// or `liggghts` (the deck pours and settles them; for full-size beds).
        #[arg(long, value_enum, default_value = "native")]
        bed: granval::penetration::deck_dir::BedBy,
    },
    /// Analyse a deck directory after LIGGGHTS ran in it (here or on a cluster): the
    /// same observables, checks and report as `granval compare`.
    Analyze {
        dir: PathBuf,
        #[arg(long)]
        report: PathBuf,
        /// Do not re-run the native engine from the same beds (LIGGGHTS observables and
        /// published-value checks only).
        #[arg(long)]
        no_native: bool,
        #[command(flatten)]
        common: Common,
    },
    /// Reference data management.
    Reference {
        #[command(subcommand)]
        cmd: RefCmd,
    },
    /// Throughput of the native engine vs LIGGGHTS on the same dense settled packing.
    Bench {
        /// Number of spheres in the packing.
        #[arg(long, default_value_t = 10_000)]
        n: usize,
        /// Timed steps per engine.
        #[arg(long, default_value_t = 2000)]
        steps: u64,
    },
    /// Stress and velocity fields of a penetration case from both engines (issue 4),
    /// every bed of its ensemble (OUT/bed-K/): phi per engine, (phi, K_phi) against
    /// MALT, CSV/VTK/SVG under OUT.
    Stress {
        case: PathBuf,
        #[arg(long)]
        out: PathBuf,
        /// MPI processes for LIGGGHTS (at least 2 are used).
        #[arg(long, default_value_t = 2)]
        np: usize,
        /// Re-analyse the snapshots of an earlier run in OUT instead of running again.
        #[arg(long)]
        reuse: bool,
        /// Gaussian range w of eq 6 in grain diameters (sensitivity studies only).
        #[arg(long, default_value_t = granval::stress_fields::DEFAULT_WIDTH_OVER_D)]
        kernel_width: f64,
        /// A `granval compare` output directory of the same case (OUT/bed-K/ with the
        /// LIGGGHTS outputs, OUT/bed-K/native/): K_phi and the unified fit on its
        /// ensemble-mean FDR instead of the mean FDR of the stress run's own beds.
        #[arg(long)]
        fdr_from: Option<PathBuf>,
    },
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

#[derive(clap::Args)]
struct Common {
    /// Recorded reference runs (used only when LIGGGHTS is not installed).
    #[arg(long, default_value = "reference")]
    reference: PathBuf,
    /// Fail instead of falling back to recorded references (also: GRANVAL_REQUIRE_LIVE=1).
    #[arg(long)]
    require_live: bool,
    #[arg(long, default_value_t = 1)]
    np: usize,
}

#[derive(Subcommand)]
enum RefCmd {
    /// Re-run every case of a suite in live LIGGGHTS, store it under reference/, report drift.
    Refresh {
        #[arg(long, default_value = "micro")]
        suite: String,
        #[arg(long, default_value = "cases")]
        cases: PathBuf,
        #[arg(long, default_value = "reference")]
        reference: PathBuf,
        /// Only this case file of the suite (e.g. cases/penetration/ci.toml: the
        /// full-size penetration cases would take hours here).
        #[arg(long)]
        only: Option<PathBuf>,
    },
}

fn options(c: &Common) -> Options {
    let mut o = Options {
        reference_root: c.reference.clone(),
        mpi_procs: c.np,
        progress: true,
        ..Options::default()
    };
    o.require_live |= c.require_live;
    o
}

fn finish(report: &Report, dir: &Path, title: &str) -> Result<ExitCode> {
    report.write(dir, title)?;
    print!("{}", report.markdown(title));
    println!("\nreport written to {}", dir.display());
    Ok(ExitCode::from(report.exit_code() as u8))
}

fn run_suite(
    paths: &[PathBuf],
    opts: &Options,
    report_dir: &Path,
    title: &str,
) -> Result<ExitCode> {
    let (mut checks, mut runs, mut notes, mut errored) = (vec![], vec![], vec![], false);
    for path in paths {
        if matches!(
            granval::case::impact2d::kind_of(path).as_deref(),
            Ok("impact2d")
        ) {
            let r = impact2d_compare(path, opts, report_dir);
            checks.extend(r.checks);
            runs.extend(r.run);
            notes.extend(r.notes);
            errored |= r.errored;
            continue;
        }
        if matches!(
            granval::case::penetration::kind_of(path).as_deref(),
            Ok("penetration")
        ) {
            match granval::case::penetration::PenetrationCase::load(path) {
                Err(e) => {
                    checks.push(granval::compare::Check::error(
                        path.display().to_string(),
                        e.to_string(),
                    ));
                    errored = true;
                }
                Ok(case) => {
                    eprintln!("== {} ({})", case.name, path.display());
                    let r = granval::penetration::ensemble::compare_case(
                        &case,
                        opts,
                        &report_dir.join(&case.name),
                    );
                    checks.extend(r.checks);
                    runs.extend(r.run);
                    notes.extend(r.notes);
                    errored |= r.errored;
                }
            }
            continue;
        }
        match Case::load(path) {
            Err(e) => {
                checks.push(granval::compare::Check::error(
                    path.display().to_string(),
                    e.to_string(),
                ));
                errored = true;
            }
            Ok(case) => {
                eprintln!("== {} ({})", case.name, path.display());
                let r = pipeline::compare_case(&case, opts, &report_dir.join(&case.name));
                checks.extend(r.checks);
                runs.extend(r.run);
                notes.extend(r.notes);
                errored |= r.errored;
            }
        }
    }
    finish(
        &Report::new(checks, runs, notes, errored),
        report_dir,
        title,
    )
}

/// `granval run` for a penetration case: prepare the bed natively, then penetrate.
fn run_penetration(case: &Path, native: bool, out: &Path) -> Result<ExitCode> {
    let case = granval::case::penetration::PenetrationCase::load(case)?;
    if !native {
        anyhow::bail!(
            "penetration runs in LIGGGHTS go through `granval compare` (both engines start from the natively prepared bed)"
        );
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let t0 = std::time::Instant::now();
    let bed = granval::penetration::prepare_bed(&case, true)?;
    println!(
        "{} (prepared in {:.1} s)",
        granval::physics::dem::packing::bed_note(&case, &bed),
        t0.elapsed().as_secs_f64()
    );
    let run = granval::penetration::run_native(
        &case,
        &bed,
        granval::case::Perturbation::default(),
        true,
    )?;
    if case.ensemble_beds > 1 {
        println!(
            "note: `granval run` penetrates bed 0 only; `granval compare` runs all {} beds",
            case.ensemble_beds
        );
    }
    granval::rundata::force::write_force_csv(&out.join("force.csv"), &run.samples)?;
    granval::rundata::provenance::write_provenance(&out.join("provenance.json"), &run.provenance)?;
    println!(
        "{} force samples written to {} ({:.1} s)",
        run.samples.len(),
        out.join("force.csv").display(),
        run.provenance.wall_time_s
    );
    Ok(ExitCode::SUCCESS)
}

/// `granval reference refresh` for a penetration case: every bed of its ensemble in live
/// LIGGGHTS (np 2), stored as a deck directory with the run's outputs and provenance.
fn refresh_penetration(path: &Path, reference: &Path) -> Result<()> {
    use granval::penetration::{self as pen, deck_dir};
    let case = granval::case::penetration::PenetrationCase::load(path)?;
    let root = reference.join("penetration").join(&case.name);
    if root.exists() {
        std::fs::remove_dir_all(&root)
            .with_context(|| format!("cannot clear {}", root.display()))?;
    }
    std::fs::create_dir_all(&root)?;
    std::fs::copy(path, root.join(deck_dir::CASE_FILE))?;
    for k in 0..case.ensemble_beds {
        let ck = case.realisation(k);
        let dir = root.join(deck_dir::bed_dir_name(k));
        let bed = pen::prepare_bed(&ck, true)?;
        let run = pen::run_liggghts(&ck, &bed, &dir, 2, true)?;
        granval::rundata::provenance::write_provenance(
            &dir.join("provenance.json"),
            &run.provenance,
        )?;
        println!(
            "{:<32} bed {k}: {} force samples recorded in {} ({:.0} s)",
            case.name,
            run.samples,
            dir.display(),
            run.provenance.wall_time_s
        );
    }
    Ok(())
}

/// `granval deck`: the case's deck directory, ready for LIGGGHTS here or on a cluster.
fn write_deck(
    case: &Path,
    out: &Path,
    bed: granval::penetration::deck_dir::BedBy,
) -> Result<ExitCode> {
    let kind = granval::case::penetration::kind_of(case)?;
    if kind != "penetration" {
        anyhow::bail!(
            "{}: `granval deck` writes penetration decks; this case has kind = {kind:?}",
            case.display()
        );
    }
    let case = granval::case::penetration::PenetrationCase::load(case)?;
    let dirs = granval::penetration::deck_dir::write(&case, out, bed, true)?;
    for d in &dirs {
        println!("{}", d.display());
    }
    println!(
        "{} deck director{} written; see {}",
        dirs.len(),
        if dirs.len() == 1 { "y" } else { "ies" },
        out.join("README.md").display()
    );
    Ok(ExitCode::SUCCESS)
}

/// `granval analyze`: a deck directory after LIGGGHTS ran in it.
fn analyze(dir: &Path, native: bool, opts: &Options, report: &Path) -> Result<ExitCode> {
    let r = granval::penetration::deck_dir::analyze(dir, native, opts, report)?;
    let report_ = Report::new(r.checks, r.run.into_iter().collect(), r.notes, r.errored);
    let code = finish(
        &report_,
        report,
        &format!("granval analyze {}", dir.display()),
    )?;
    if !native && !report_.errored && report_.checks.is_empty() {
        // Nothing was compared on purpose: the LIGGGHTS observables are the product.
        println!("--no-native: LIGGGHTS observables only, nothing gated");
        return Ok(ExitCode::SUCCESS);
    }
    Ok(code)
}

/// `granval compare/check` entry for one impact2d case file.
fn impact2d_compare(path: &Path, opts: &Options, report_dir: &Path) -> pipeline::CaseResult {
    match granval::case::impact2d::Impact2dCase::load(path) {
        Err(e) => pipeline::CaseResult {
            checks: vec![granval::compare::Check::error(
                path.display().to_string(),
                e.to_string(),
            )],
            run: None,
            notes: vec![],
            errored: true,
        },
        Ok(case) => {
            eprintln!("== {} ({})", case.name, path.display());
            granval::impact2d::compare_case(&case, opts, &report_dir.join(&case.name))
        }
    }
}

/// `granval run` for an impact2d case: every variant in one engine, from the
/// natively prepared bed; OUT/<variant>/{intruder,energy}.csv + provenance.json.
fn run_impact2d(path: &Path, engine: EngineName, out: &Path, np: usize) -> Result<ExitCode> {
    use granval::impact2d as i2;
    if matches!(engine, EngineName::Liggghts) {
        anyhow::bail!("impact2d cases are 2D: use --engine native or --engine lammps");
    }
    let case = granval::case::impact2d::Impact2dCase::load(path)?;
    let beds = i2::prepare_beds(&case, true)?;
    for (p, b) in &beds.beds {
        println!("{}", i2::bed_note(&case, *p, b));
    }
    for v in &case.variants {
        let scene = i2::scene(&case, v, &beds)?;
        let dir = out.join(&v.label);
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        let run = match engine {
            EngineName::Native => i2::run_native(&case, &scene, true)?,
            EngineName::Lammps => i2::run_lammps(&case, &scene, &dir.join("lammps-run"), np)?,
            EngineName::Liggghts => {
                anyhow::bail!("impact2d cases are 2D: use --engine native or --engine lammps")
            }
        };
        let (o, _) = i2::observe(&case, v, &scene, &run)?;
        granval::analysis::impact::write_intruder_csv(
            &dir.join("intruder.csv"),
            &run.samples,
            scene.surface,
            scene.bottom_offset,
        )?;
        granval::analysis::impact::write_energy_csv(&dir.join("energy.csv"), &run.energy)?;
        granval::rundata::provenance::write_provenance(
            &dir.join("provenance.json"),
            &run.provenance,
        )?;
        println!(
            "{:<24} final depth {:.3} d, max depth {:.3} d ({} engine, {:.1} s) -> {}",
            v.label,
            o.final_depth,
            o.max_depth,
            run.provenance.engine,
            run.provenance.wall_time_s,
            dir.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// `granval reference refresh --suite impact2d`: record every variant in live LAMMPS
/// and report the final-depth drift against the previous record.
fn refresh_impact2d(
    cases: &Path,
    suite: &str,
    reference: &Path,
    only: Option<&Path>,
) -> Result<ExitCode> {
    use granval::impact2d as i2;
    let version = granval::engines::lammps::installed_version(&granval::engines::lammps::binary())
        .context("reference refresh for impact2d needs a live LAMMPS (`apt-get install lammps`)")?;
    println!("using {version}");
    let mut paths = pipeline::suite_cases(cases, suite)?;
    if let Some(o) = only {
        paths.retain(|p| p == o);
        anyhow::ensure!(
            !paths.is_empty(),
            "{} is not a case of suite {suite} in {}",
            o.display(),
            cases.display()
        );
    }
    for path in paths {
        let case = granval::case::impact2d::Impact2dCase::load(&path)?;
        let beds = i2::prepare_beds(&case, true)?;
        for v in &case.variants {
            let scene = i2::scene(&case, v, &beds)?;
            let rec = i2::record_dir(reference, &case, v);
            let previous = i2::recorded(&rec, &scene)
                .ok()
                .and_then(|r| i2::observe(&case, v, &scene, &r).ok());
            let tmp = tempfile::tempdir()?;
            let run = i2::run_lammps(&case, &scene, tmp.path(), 1)?;
            i2::store_reference(&run, tmp.path(), &rec, &scene)?;
            let (now, _) = i2::observe(&case, v, &scene, &run)?;
            let drift = match previous {
                Some((p, _)) => format!("{:+.2e} d", now.final_depth - p.final_depth),
                None => "new".into(),
            };
            println!(
                "{:<14} {:<20} final depth {:.3} d, drift vs previous record {drift}, {:.1} s -> {}",
                case.name,
                v.label,
                now.final_depth,
                run.provenance.wall_time_s,
                rec.display()
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn real_main() -> Result<ExitCode> {
    let cli = Cli::parse();
    match cli.cmd {
        Cmd::Run {
            case,
            engine,
            out,
            np,
        } => {
            if granval::case::impact2d::kind_of(&case)? == "impact2d" {
                return run_impact2d(&case, engine, &out, np);
            }
            if granval::case::penetration::kind_of(&case)? == "penetration" {
                return run_penetration(&case, matches!(engine, EngineName::Native), &out);
            }
            let case = Case::load(&case)?;
            std::fs::create_dir_all(&out)
                .with_context(|| format!("cannot create {}", out.display()))?;
            let result = match engine {
                EngineName::Native => Native {
                    progress: true,
                    ..Native::default()
                }
                .run(&case, &out)?,
                EngineName::Liggghts => Liggghts {
                    mpi_procs: np,
                    ..Liggghts::default()
                }
                .run(&case, &out)?,
                EngineName::Lammps => {
                    anyhow::bail!("--engine lammps runs 2D impact2d cases only")
                }
            };
            pipeline::save_run(&out, &result)?;
            println!(
                "{} frames written to {}",
                result.frames.len(),
                out.join("particles.csv").display()
            );
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Compare {
            case,
            report,
            common,
        } => {
            let name = case.display().to_string();
            run_suite(
                &[case],
                &options(&common),
                &report,
                &format!("granval compare {name}"),
            )
        }
        Cmd::Check {
            suite,
            report,
            cases,
            common,
        } => {
            let paths = pipeline::suite_cases(&cases, &suite)?;
            run_suite(
                &paths,
                &options(&common),
                &report,
                &format!("granval check --suite {suite}"),
            )
        }
        Cmd::Reference {
            cmd:
                RefCmd::Refresh {
                    suite,
                    cases,
                    reference,
                    only,
                },
        } => {
            if suite == "impact2d" {
                return refresh_impact2d(&cases, &suite, &reference, only.as_deref());
            }
            let version = liggghts::installed_version("liggghts")
                .context("reference refresh needs a live LIGGGHTS (`apt-get install liggghts`)")?;
            println!("using {version}");
            let mut paths = pipeline::suite_cases(&cases, &suite)?;
            if let Some(o) = &only {
                paths.retain(|p| p == o);
                anyhow::ensure!(
                    !paths.is_empty(),
                    "--only {}: not a case of suite {suite} in {}",
                    o.display(),
                    cases.display()
                );
            }
            for path in paths {
                if granval::case::penetration::kind_of(&path)? == "penetration" {
                    refresh_penetration(&path, &reference)?;
                    continue;
                }
                let case = Case::load(&path)?;
                let dir = reference.join(&case.kind).join(&case.name);
                let previous = granval::engines::recorded::Recorded { dir: dir.clone() }
                    .run(&case, &dir)
                    .ok();
                std::fs::create_dir_all(&dir)?;
                let out = Liggghts::default().run(&case, &dir)?;
                pipeline::save_run(&dir, &out)?;
                let drift = match previous {
                    Some(prev) => {
                        granval::compare::trajectory::compare(&case, &out.frames, &prev.frames)
                            .iter()
                            .map(|c| format!("{} {:.2e}", c.metric, c.value))
                            .collect::<Vec<_>>()
                            .join(", ")
                    }
                    None => "new".into(),
                };
                println!(
                    "{:<32} {} frames  drift vs previous record: {drift}",
                    case.name,
                    out.frames.len()
                );
            }
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Deck { case, out, bed } => write_deck(&case, &out, bed),
        Cmd::Analyze {
            dir,
            report,
            no_native,
            common,
        } => analyze(&dir, !no_native, &options(&common), &report),
        Cmd::Bench { n, steps } => {
            granval::bench::run(n, steps)?;
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Stress {
            case,
            out,
            np,
            reuse,
            kernel_width,
            fdr_from,
        } => {
            let case = granval::case::penetration::PenetrationCase::load(&case)?;
            let opts = Options {
                mpi_procs: np,
                progress: true,
                ..Options::default()
            };
            std::fs::create_dir_all(&out)?;
            let so = granval::stress_fields::StressOptions {
                reuse,
                width_over_d: kernel_width,
                fdr_from,
            };
            let rep = granval::stress_fields::run_case(&case, &opts, &out, &so)?;
            let n = &rep.negative_control_check;
            let mut notes = vec![
                format!(
                    "negative control (must FAIL): {} = {:.3} deg (tolerance {}) -> {}; {}",
                    n.name,
                    n.value,
                    n.tolerance,
                    if n.passed {
                        "PASSED: the control did not bite"
                    } else {
                        "FAILED as it must"
                    },
                    n.detail
                ),
                format!(
                    "kernel method (not gated), phi over depths: {}",
                    rep.beds
                        .iter()
                        .map(|b| format!(
                            "bed {} native {:.2} +- {:.2} deg, LIGGGHTS {:.2} +- {:.2} deg",
                            b.bed,
                            b.native.phi_kernel_deg,
                            b.native.phi_kernel_std_deg,
                            b.liggghts.phi_kernel_deg,
                            b.liggghts.phi_kernel_std_deg
                        ))
                        .collect::<Vec<_>>()
                        .join("; ")
                ),
            ];
            notes.extend(rep.notes.iter().cloned());
            notes.push(format!(
                "wall time: field analysis {:.1} s",
                rep.analysis_wall_s
            ));
            let errored = rep.checks.iter().any(|c| c.metric == "error");
            let report = Report::new(rep.checks.clone(), vec![], notes.clone(), errored);
            report.write(&out, &format!("{}: stress fields and MALT", case.name))?;
            for c in &rep.checks {
                let verdict = if c.passed { "PASS" } else { "FAIL" };
                println!(
                    "{verdict} {}: {} = {:.4} (tolerance {}) {}",
                    c.name, c.metric, c.value, c.tolerance, c.detail
                );
            }
            for note in &notes {
                println!("{note}");
            }
            for p in granval::stress_fields::output_files(&out, rep.beds.len()) {
                println!("wrote {}", p.display());
            }
            Ok(ExitCode::from(report.exit_code() as u8))
        }
        Cmd::CgBench { contacts, grid } => {
            let t = granval::analysis::cg_bench::time_cg(contacts, grid)?;
            println!(
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
                let q = malt::k_phi(phi.to_radians())?;
                println!(
                    "K_phi({phi} deg) = {:.9} (quadrature error estimate {:.1e})",
                    q.value, q.abs_err
                );
            }
            if let Some(k) = k {
                println!("phi(K = {k}) = {:.6} deg", malt::phi_of_k(k)?.to_degrees());
            }
            if table {
                println!("phi_deg,K");
                for (p, kv) in malt::table(45.0, 0.5)? {
                    println!("{p},{kv:.9}");
                }
            }
            if phi.is_none() && k.is_none() && !table {
                anyhow::bail!("give --phi DEG, --k VALUE or --table");
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}

fn main() -> ExitCode {
    match real_main() {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
