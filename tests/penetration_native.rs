//! Fast checks of the native penetration pieces on a tiny bed: preparation protocol,
//! packing fraction, intruder kinematics and the sign of the resistance.

mod common;

use granval::case::penetration::PenetrationCase;
use granval::experiments::penetration::bed::{liggghts_deck, prepare_bed};
use std::path::Path;

fn tiny(extra: &str) -> String {
    common::tiny_penetration_toml(0.010, extra, "")
}

#[test]
fn bed_settles_and_intruder_meets_resistance() {
    let case = PenetrationCase::from_toml_str(&tiny(""), Path::new("tiny.toml")).unwrap();
    let bed = prepare_bed(&case, false).unwrap();
    eprintln!("{}", granval::physics::dem::packing::bed_note(&case, &bed));
    assert!(bed.ke_ratio < 1e-6);
    assert!(
        bed.psi > 0.45 && bed.psi < 0.70,
        "implausible packing fraction {}",
        bed.psi
    );
    let top = bed
        .particles
        .iter()
        .map(|p| p.x[2] + p.radius)
        .fold(0.0, f64::max);
    assert!(bed.surface_z > 0.0 && bed.surface_z <= top);
    let (samples, provenance) = granval::engines::native::penetration(
        &case,
        &bed,
        &Default::default(),
        &[],
        |_| Ok(()),
        |_, _| {},
    )
    .unwrap();
    assert_eq!(
        provenance.engine,
        granval::rundata::provenance::EngineKind::Native
    );
    let s = &samples;
    // Constant-speed drive: z_bottom falls by v dt per step exactly (to round-off).
    let dz = (s[0].z_bottom - s.last().unwrap().z_bottom) / (s.last().unwrap().t - s[0].t);
    assert!(
        (dz / case.speed - 1.0).abs() < 1e-9,
        "intruder speed {dz} vs {}",
        case.speed
    );
    // Above the bed no force; deep in it the grains push back up (+z).
    assert_eq!(s[0].f, [0.0; 3]);
    let deep: Vec<f64> = s
        .iter()
        .filter(|x| x.z_bottom < bed.surface_z - 0.004)
        .map(|x| x.f[2])
        .collect();
    assert!(!deep.is_empty() && deep.iter().sum::<f64>() / deep.len() as f64 > 0.0);
}

#[test]
fn penetration_case_errors_name_field() {
    let bad = tiny("").replace("final_depth = 0.006", "final_depth = 0.05");
    let e = PenetrationCase::from_toml_str(&bad, Path::new("tiny.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("tiny.toml") && e.contains("intruder.final_depth") && e.contains("0.05"),
        "{e}"
    );
    let bad = tiny("").replace("friction = 0.5", "friction = -0.5");
    let e = PenetrationCase::from_toml_str(&bad, Path::new("tiny.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("interactions[0].friction"), "{e}");
    for (value, why) in [("0.0", "must be > 0"), ("0.2", "must be below 0.1")] {
        let bad = tiny("").replace(
            "force_every = 10",
            &format!("force_every = 10\nstl_rim_error = {value}"),
        );
        let e = PenetrationCase::from_toml_str(&bad, Path::new("tiny.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("intruder.stl_rim_error") && e.contains(why),
            "{e}"
        );
    }
}

/// The STL's rim error reaches the LIGGGHTS deck: 24 segments by default, 72 at 0.001.
#[test]
fn stl_rim_error_sets_the_segment_count() {
    use granval::engines::liggghts::stl::segments_for_rim_error;
    let case = PenetrationCase::from_toml_str(&tiny(""), Path::new("tiny.toml")).unwrap();
    assert_eq!(case.stl_rim_error, 0.01);
    let text = tiny("").replace("force_every = 10", "force_every = 10\nstl_rim_error = 1e-3");
    let fine = PenetrationCase::from_toml_str(&text, Path::new("tiny.toml")).unwrap();
    let bed = granval::physics::dem::packing::Bed {
        particles: vec![],
        bodies: vec![],
        surface_z: 0.01,
        psi: 0.0,
        ke_ratio: 0.0,
        settle_time: 0.0,
        ke_at_end_of_pour: 0.0,
    };
    let segments = |c: &PenetrationCase| {
        let d = liggghts_deck(c, &bed).unwrap();
        segments_for_rim_error(d.rim_error_frac)
    };
    assert_eq!((segments(&case), segments(&fine)), (24, 72));
}

#[test]
fn shipped_penetration_cases_load() {
    let cases = common::root().join("cases");
    let suite = granval::experiments::suite::load(&cases, "penetration").unwrap();
    assert!(!suite.cases.is_empty());
    for e in &suite.cases {
        PenetrationCase::load(&e.path).unwrap_or_else(|e| panic!("{e}"));
    }
    // Every penetration case file, in a suite or not.
    let mut n = 0;
    for e in std::fs::read_dir(cases.join("penetration")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "toml") {
            PenetrationCase::load(&p).unwrap_or_else(|e| panic!("{e}"));
            n += 1;
        }
    }
    assert!(n >= suite.cases.len());
}

/// What `granval check --suite ci` gates on the CI penetration case (the checks of the
/// former tests/penetration_ci.rs): Sec. 3's quasi-static test needs a second speed,
/// and the mu_gg = 0.3 negative control must fail K_phi against the same LIGGGHTS runs.
#[test]
fn ci_case_carries_the_quasi_static_speed_and_the_mu_gg_control() {
    let path = common::root().join("cases/penetration/ci.toml");
    let case = PenetrationCase::load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        case.quasi_static_speed.is_some_and(|v| v != case.speed),
        "ci.toml must carry [quasi_static] speed for Sec. 3's test"
    );
    let g = case.grain_type;
    assert!(
        case.negative_controls.iter().any(|c| {
            c.perturbation.pair_friction == Some((g, g, 0.3))
                && c.must_fail.contains(&granval::compare::Gate::KPhi)
        }),
        "{:?}",
        case.negative_controls
    );
    let suite = granval::experiments::suite::load(&common::root().join("cases"), "ci").unwrap();
    assert!(
        suite
            .cases
            .iter()
            .any(|e| e.path.ends_with("penetration/ci.toml") && e.stress),
        "{:?}",
        suite.cases
    );
}

/// `--reuse` (`check --reuse`, `stress --reuse`) takes an earlier native run of a bed as
/// this one only when it is the same case, bed, physics and build: the run is read back
/// (same force samples, a "reused from" note), while a run under a negative control's
/// perturbation, or one computed by another granval build, is refused by name.
#[test]
fn reuse_takes_only_a_run_of_the_same_physics_and_build() {
    use granval::experiments::penetration::Penetration;
    use granval::experiments::{Experiment, Options, Role};
    let case = PenetrationCase::from_toml_str(&tiny(""), Path::new("tiny.toml")).unwrap();
    let exp = Penetration::against_liggghts(case, false);
    let opts = Options::default();
    let units = exp.units(&opts).unwrap();
    let u = &units[0];
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("bed-0");
    let first = exp.run_native(u, Role::Main, &dir, &opts).unwrap();
    let reuse = Options {
        reuse: true,
        ..opts.clone()
    };
    let again = exp.run_native(u, Role::Main, &dir, &reuse).unwrap();
    assert_eq!(again.run.samples, first.run.samples);
    assert_eq!(
        format!("{:?}", again.run.fdr),
        format!("{:?}", first.run.fdr)
    );
    assert!(
        again
            .run
            .provenance
            .notes
            .iter()
            .any(|n| n.starts_with("reused from")),
        "{:?}",
        again.run.provenance.notes
    );
    // A control's perturbation is other physics: the main run is not its run.
    let pert = granval::case::Perturbation {
        friction_factor: 0.8,
        ..Default::default()
    };
    let e = format!(
        "{:#}",
        exp.run_native(u, Role::Control(&pert), &dir, &reuse)
            .err()
            .expect("a main run reused as a control's")
    );
    assert!(
        e.contains("other physics") && e.contains("without --reuse"),
        "{e}"
    );
    // A run another build computed (its commit note edited) is refused.
    let prov = dir.join("provenance.json");
    let text = std::fs::read_to_string(&prov).unwrap();
    assert!(text.contains("computed by granval at commit "), "{text}");
    std::fs::write(
        &prov,
        text.replace(
            "computed by granval at commit ",
            "computed by granval at commit 0",
        ),
    )
    .unwrap();
    let e = format!(
        "{:#}",
        exp.run_native(u, Role::Main, &dir, &reuse)
            .err()
            .expect("another build's run reused")
    );
    assert!(
        e.contains("another granval build") && e.contains("without --reuse"),
        "{e}"
    );
}
