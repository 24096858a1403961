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
    /// Stress and velocity fields of a penetration case from both engines (issue 4):
    /// phi per engine, (phi, K_phi) against MALT, CSV/VTK/SVG under OUT.
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
                    let r = granval::penetration::compare_case(
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
        granval::dem::packing::bed_note(&case, &bed),
        t0.elapsed().as_secs_f64()
    );
    let run =
        granval::penetration::run_native(&case, &bed, granval::dem::Perturbation::default(), true)?;
    granval::penetration::write_force_csv(&out.join("force.csv"), &run.samples)?;
    granval::engines::output::write_provenance(&out.join("provenance.json"), &run.provenance)?;
    println!(
        "{} force samples written to {} ({:.1} s)",
        run.samples.len(),
        out.join("force.csv").display(),
        run.provenance.wall_time_s
    );
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
                },
        } => {
            let version = liggghts::installed_version("liggghts")
                .context("reference refresh needs a live LIGGGHTS (`apt-get install liggghts`)")?;
            println!("using {version}");
            for path in pipeline::suite_cases(&cases, &suite)? {
                if granval::case::penetration::kind_of(&path)? == "penetration" {
                    let case = granval::case::penetration::PenetrationCase::load(&path)?;
                    let dir = reference.join("penetration").join(&case.name);
                    let bed = granval::penetration::prepare_bed(&case, true)?;
                    let mut run = granval::penetration::run_liggghts(&case, &bed, &dir, 2)?;
                    run.provenance.notes.push(format!(
                        "bed sha256 {}",
                        granval::penetration::bed_hash(&bed)
                    ));
                    granval::penetration::write_force_csv(&dir.join("force.csv"), &run.samples)?;
                    granval::engines::output::write_provenance(
                        &dir.join("provenance.json"),
                        &run.provenance,
                    )?;
                    println!(
                        "{:<32} {} force samples recorded in {}",
                        case.name,
                        run.samples.len(),
                        dir.display()
                    );
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
        } => {
            let case = granval::case::penetration::PenetrationCase::load(&case)?;
            let opts = Options {
                mpi_procs: np,
                progress: true,
                ..Options::default()
            };
            std::fs::create_dir_all(&out)?;
            let rep = granval::stress_fields::run_case(&case, &opts, &out, reuse, kernel_width)?;
            let n = &rep.negative_control_check;
            let notes = vec![
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
                    "kernel method (not gated): phi native {:.2} +- {:.2} deg, LIGGGHTS {:.2} +- {:.2} deg",
                    rep.native.phi_kernel_deg,
                    rep.native.phi_kernel_std_deg,
                    rep.liggghts.phi_kernel_deg,
                    rep.liggghts.phi_kernel_std_deg
                ),
            ];
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
            for p in granval::stress_fields::output_files(&out) {
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
