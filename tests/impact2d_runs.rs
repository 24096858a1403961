//! The impact experiment at CI size (cases/impact2d/ci*.toml), both engines from the
//! same bed: native vs LAMMPS final depth and D(t), K's claims in each engine, and the
//! negative control (friction models swapped in the native engine) that must make the
//! cross-check fail. LAMMPS runs live when `lmp` is installed; otherwise the sealed
//! recorded runs under reference/impact2d/ are used and the log says so; with
//! GRANVAL_REQUIRE_LIVE=1 a missing `lmp` is a failure. All cases share one prepared
//! bed per packing (prepared once per process).

mod common;

use granval::case::Perturbation;
use granval::case::impact2d::Impact2dCase;
use granval::compare::{Check, Gate, Status};
use granval::experiments::impact2d::{Impact2d, label_dir};
use granval::experiments::{Experiment, Role, reference, runner};
use granval::rundata::provenance::EngineKind;

fn case(name: &str) -> Impact2dCase {
    Impact2dCase::load(&common::root().join("cases/impact2d").join(name))
        .unwrap_or_else(|e| panic!("{e}"))
}

fn exp(name: &str) -> Impact2d {
    Impact2d { case: case(name) }
}

/// The native engine with K's friction models swapped (static k_t = 0.8 k_n <->
/// kinetic k_t = 0) in every contact.
fn swapped() -> Perturbation {
    Perturbation {
        swap_friction_model: true,
        ..Perturbation::default()
    }
}

fn run(name: &str) -> Vec<Check> {
    run_in(name, tempfile::tempdir().unwrap().path())
}

/// `granval compare` of the case (with the negative controls its file declares).
fn run_in(name: &str, out: &std::path::Path) -> Vec<Check> {
    common::live(EngineKind::Lammps, name);
    let r = runner::compare(&exp(name), &common::options(), out);
    for n in &r.notes {
        eprintln!("[{name}] note: {n}");
    }
    if let Some(run) = &r.run {
        eprintln!(
            "[{name}] reference: {} {} ({})",
            run.reference_engine, run.reference_version, run.reference_source
        );
    }
    common::show(name, &r.checks);
    assert!(r.run.is_some(), "{name}: {:?}", r.checks);
    assert!(
        r.checks.iter().all(|c| !c.is_error()),
        "{name}: errored: {:?}",
        r.checks.iter().filter(|c| c.is_error()).collect::<Vec<_>>()
    );
    r.checks
}

/// The case's checks with the friction models swapped in the native engine, against the
/// same reference runs.
fn run_swapped(name: &str) -> Vec<Check> {
    common::live(EngineKind::Lammps, name);
    let out = tempfile::tempdir().unwrap();
    let checks = common::checks_with(
        &exp(name),
        Role::Control(&swapped()),
        &common::options(),
        out.path(),
    );
    common::show(&format!("{name}, friction swapped"), &checks);
    assert!(
        checks.iter().all(|c| !c.is_error()),
        "{name}: errored: {checks:?}"
    );
    checks
}

fn named<'a>(checks: &'a [Check], part: &str) -> Vec<&'a Check> {
    let v: Vec<&Check> = checks.iter().filter(|c| c.name.contains(part)).collect();
    assert!(!v.is_empty(), "no check named like {part:?}");
    v
}

#[test]
fn native_matches_lammps_on_the_ci_bed() {
    let out = tempfile::tempdir().unwrap();
    let checks = run_in("ci.toml", out.path());
    // The two cross-checks of the one variant (final depth, D(t)); every check passes,
    // the negative controls declared in ci.toml included.
    let cross: Vec<_> = checks
        .iter()
        .filter(|c| c.gate == Gate::FinalDepth || c.gate == Gate::DepthSeries)
        .collect();
    assert_eq!(cross.len(), 2, "{checks:?}");
    for c in &checks {
        assert!(c.passed && c.status == Status::Pass, "{c:?}");
    }
    // Energies (kinetic model: no tangential spring energy) can only be dissipated:
    // KE + PE + normal elastic energy never exceeds its initial value by more than
    // the integrator's error; and both engines agree while their trajectories do.
    let c = case("ci.toml");
    let unit = label_dir(&c.variants[0]);
    let read = |p: &std::path::Path| {
        granval::rundata::impact::read_energy_csv(p).unwrap_or_else(|e| panic!("{e:#}"))
    };
    let a = read(&runner::unit_out(out.path(), &unit).join("native/energy.csv"));
    // LAMMPS' series: from this run when it ran live, else from the sealed record.
    let live = runner::resolve(&exp("ci.toml"), &common::options())
        .unwrap()
        .is_some();
    let b = if live {
        read(&runner::reference_out(out.path(), &unit, EngineKind::Lammps).join("energy.csv"))
    } else {
        let root = reference::record_root(&common::options().reference_root, "impact2d", "ci");
        read(&reference::unit_dir(&root, &unit).join("energy.csv"))
    };
    assert_eq!(a.len(), b.len());
    let total = |e: &granval::rundata::impact::EnergySample, p0: f64| {
        e.kinetic + (e.potential - p0) + e.elastic
    };
    let e0 = total(&a[0], a[0].potential);
    for e in &a {
        assert!(
            total(e, a[0].potential) <= e0 * (1.0 + 1e-3),
            "energy grew: {e:?} vs {e0}"
        );
    }
    assert!(
        total(a.last().unwrap(), a[0].potential) < 0.5 * e0,
        "impact energy was not dissipated"
    );
    for (x, y) in a.iter().zip(&b).take(3) {
        assert!(
            (x.kinetic - y.kinetic).abs() <= 1e-9 * x.kinetic.abs().max(1e-30),
            "{x:?} vs {y:?}"
        );
    }
}

/// The recorded LAMMPS run of the CI case (what a machine without `lmp` compares
/// against) is sealed to today's case and scene, and matches today's native run of the
/// same scene.
#[test]
fn recorded_lammps_reference_matches_native() {
    let exp = exp("ci.toml");
    let opts = common::recorded();
    let units = exp.units(&opts).unwrap();
    assert_eq!(units.len(), 1);
    let dir = tempfile::tempdir().unwrap();
    let reference = common::reference_runs(&exp, &units, &opts, dir.path());
    let (u, reference) = (&units[0], &reference[0]);
    eprintln!(
        "[ci] recorded reference: {} ({})",
        reference.provenance.version, reference.provenance.date
    );
    assert_eq!(reference.provenance.engine, EngineKind::Lammps);
    assert!(reference.provenance.version.starts_with("LAMMPS ("));
    let native = exp
        .run_native(u, Role::Main, &dir.path().join("native"), &opts)
        .unwrap();
    let c = &exp.case;
    let v = &u.variant;
    let (a, sa) = granval::experiments::impact2d::observe(c, v, &u.scene, &native).unwrap();
    let (b, sb) = granval::experiments::impact2d::observe(c, v, &u.scene, reference).unwrap();
    let rms = granval::analysis::impact::rms_distance(&sa, &sb)
        .map(|r| r / c.scales.d)
        .map_err(|e| e.to_string());
    let checks = granval::compare::impact2d::cross_check(c, &a, &b, rms, "lammps");
    assert!(
        checks.iter().any(|k| k.gate == Gate::FinalDepth),
        "{checks:?}"
    );
    for k in checks {
        assert!(k.passed, "{k:?}");
    }
}

#[test]
fn swapped_friction_in_the_native_engine_fails_the_cross_check() {
    let checks = run_swapped("ci.toml");
    for part in ["final depth", "D(t) distance"] {
        for c in named(&checks, part) {
            assert!(
                !c.passed && c.status == Status::Fail,
                "negative control passed: {c:?}"
            );
        }
    }
}

/// One seed: the claims are comparisons between conditions on one bed, INCONCLUSIVE
/// under docs/statistics.md in both engines, with the single-bed rule's verdict printed;
/// that rule gives pass in both engines, the depths agree between engines, and each of
/// the `controls` negative controls the case file declares flips the single-bed rule to
/// fail, while the control itself stays INCONCLUSIVE (it cannot bite an unresolved gate).
fn claims_hold_on_one_bed(name: &str, controls: usize) {
    let checks = run(name);
    for engine in ["claim (native)", "claim (lammps)"] {
        let claims = named(&checks, engine);
        assert!(!claims.is_empty(), "{name}: no {engine}");
        for c in claims {
            assert_eq!(c.status, Status::Inconclusive, "{c:?}");
            assert!(c.detail.contains("the single-bed rule gives pass"), "{c:?}");
        }
    }
    for c in named(&checks, "final depth native vs") {
        assert!(c.passed, "{c:?}");
    }
    let declared: Vec<_> = checks
        .iter()
        .filter(|c| c.gate == Gate::NegativeControl)
        .collect();
    assert_eq!(declared.len(), controls, "{declared:?}");
    for c in declared {
        assert_eq!(c.status, Status::Inconclusive, "{c:?}");
        assert!(
            c.detail.contains("the single-bed rule gives FAIL"),
            "the wrong physics did not flip the single-bed rule: {c:?}"
        );
    }
}

#[test]
fn static_friction_penetrates_less_than_kinetic() {
    claims_hold_on_one_bed("ci-friction.toml", 1);
}

#[test]
fn swapped_friction_breaks_the_friction_claim_in_the_native_engine() {
    let checks = run_swapped("ci-friction.toml");
    let claims = named(&checks, "claim (native)");
    assert!(!claims.is_empty());
    for c in claims {
        assert!(
            c.status == Status::Inconclusive && c.detail.contains("the single-bed rule gives FAIL"),
            "negative control passed: {c:?}"
        );
    }
}

#[test]
fn hexagonal_bed_penetrates_less_than_random() {
    claims_hold_on_one_bed("ci-packing.toml", 1);
}

#[test]
fn final_depth_grows_with_restitution() {
    claims_hold_on_one_bed("ci-en.toml", 1);
}

#[test]
fn final_depth_grows_as_gravity_drops() {
    claims_hold_on_one_bed("ci-gravity.toml", 1);
}

/// Every speed of the CI-size sweep agrees between the engines. K Fig 8b's linearity
/// claim is gated on the Fig 2 bed (`granval check --suite ci`): on this 450-disk bed
/// one realisation gives R^2 0.84 in both engines (docs/impact2d.md).
#[test]
fn speed_sweep_agrees_between_engines() {
    let checks = run("ci-speed.toml");
    assert!(
        checks.iter().all(|c| !c.name.contains("claim")),
        "ci-speed.toml carries no claim"
    );
    let depth = named(&checks, "final depth native vs");
    assert_eq!(depth.len(), 6, "one cross-check per speed");
    for c in depth {
        assert!(c.passed, "{c:?}");
    }
}

#[test]
fn elliptical_cluster_intruder_matches_lammps() {
    for c in run("ci-ellipse.toml") {
        assert!(c.passed, "{c:?}");
    }
}

/// A seed ensemble end to end on a tiny bed (120 disks, L = 12 d, two seeds, two speeds):
/// one bed per seed shared by both speeds, one run per (speed, seed), the claim judged on
/// the per-speed means, and the sweep-ignored control (every run at the base speed: equal
/// means) biting on it. With `lmp` installed the whole comparison runs live (cross-checks
/// per run, the ensemble figure and report section); without it there is no record of
/// this test-only case, so only the native side runs, and the log says so.
#[test]
fn seed_ensemble_runs_each_value_on_each_seed_and_its_control_bites() {
    use granval::compare::impact2d::claim_checks;
    use granval::experiments::impact2d::{ENSEMBLE_FIGURE, observe};
    let text = std::fs::read_to_string(common::root().join("cases/impact2d/ci.toml"))
        .unwrap()
        .replace("name = \"ci\"", "name = \"tiny-ensemble\"")
        .replace("count = 450", "count = 200")
        .replace("length = 30.0", "length = 16.0")
        .replace("seed = 7", "seeds = [3, 4]")
        .replace("settle_ke = 1e-10", "settle_ke = 1e-6")
        .replace("diameter = 6.0", "diameter = 4.0")
        .replace("duration = 1000.0", "duration = 300.0")
        .replace("final_window = 200.0", "final_window = 100.0")
        + "\n[sweep]\nparameter = \"speed\"\nvalues = [0.1, 0.7]\n\n[claim]\nkind = \"increasing\"\nmin_step = 0.1\n\n[[negative_control]]\nname = \"speed ignored\"\nmust_fail = [\"claim\"]\nperturbation = { sweep_ignored = true }\n";
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("tiny-ensemble.toml");
    std::fs::write(&file, &text).unwrap();
    let exp = Impact2d {
        case: Impact2dCase::load(&file).unwrap_or_else(|e| panic!("{e}")),
    };
    let c = &exp.case;
    assert_eq!(c.variants.len(), 4);
    let start = std::time::Instant::now();
    let live = reference::installed(EngineKind::Lammps).is_some();
    if live {
        eprintln!("[tiny-ensemble] reference: LIVE LAMMPS");
        let out = dir.path().join("out");
        let r = runner::compare(&exp, &common::options(), &out);
        common::show("tiny-ensemble", &r.checks);
        assert!(r.checks.iter().all(|k| !k.is_error()), "{:?}", r.checks);
        // Native vs LAMMPS per run: final depth and D(t) for each (speed, seed).
        for v in &c.variants {
            let per: Vec<_> = r
                .checks
                .iter()
                .filter(|k| k.name.contains(&format!("[{}]", v.label)))
                .collect();
            assert_eq!(per.len(), 2, "{}: {per:?}", v.label);
        }
        let claims: Vec<_> = r.checks.iter().filter(|k| k.gate == Gate::Claim).collect();
        assert_eq!(claims.len(), 2, "one per engine: {claims:?}");
        for k in &claims {
            assert!(k.name.contains("mean of 2 seeds"), "{}", k.name);
            assert!(k.detail.contains("speed=0.1: ") && k.detail.contains("seed 4: "));
            assert!(k.passed, "the speed raises the mean depth: {k:?}");
        }
        let control = r
            .checks
            .iter()
            .find(|k| k.gate == Gate::NegativeControl)
            .unwrap();
        assert!(control.passed, "{control:?}");
        assert_eq!(r.sections.len(), 1, "{:?}", r.sections);
        assert_eq!(r.sections[0].figures, [ENSEMBLE_FIGURE]);
        let svg = std::fs::read_to_string(out.join(ENSEMBLE_FIGURE)).unwrap();
        assert!(svg.contains("final depth / d") && svg.contains("LAMMPS"));
    } else {
        assert!(
            !common::require_live(),
            "GRANVAL_REQUIRE_LIVE=1 but LAMMPS is not installed"
        );
        common::engineless(
            "tiny-ensemble",
            "LAMMPS is not installed and this test-only case has no record: NATIVE SIDE ONLY (claim and control on the native runs)",
        );
        let units = exp.units(&common::options()).unwrap();
        let ignored = Perturbation {
            sweep_ignored: true,
            ..Perturbation::default()
        };
        let judge = |role: Role| {
            let obs: Vec<_> = units
                .iter()
                .map(|u| {
                    let d = dir.path().join("native").join(label_dir(&u.variant));
                    let run = exp.run_native(u, role, &d, &common::options()).unwrap();
                    observe(c, &u.variant, &u.scene, &run).unwrap().0
                })
                .collect();
            claim_checks(c, "native", &obs).remove(0)
        };
        let k = judge(Role::Main);
        common::show("tiny-ensemble", std::slice::from_ref(&k));
        assert!(k.passed, "the speed raises the mean depth: {k:?}");
        let k = judge(Role::Control(&ignored));
        assert!(
            k.status == Status::Fail && k.value.abs() < 1e-12,
            "equal means: a per-seed rise of 0, below min_step, fails: {k:?}"
        );
    }
    eprintln!("[tiny-ensemble] {:.1} s", start.elapsed().as_secs_f64());
}
