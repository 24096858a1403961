//! Careless input caught early: a collision case whose spheres miss is NOT COMPARED
//! (not a pass of free flight), values in the wrong unit warn with the likely unit
//! named, TOML type errors are said in words, and a bed read back from files reports
//! no NaN settle time. Every test here is fast: micro runs of a few thousand steps.

mod common;

use common::{expect, text};
use granval::case::{AnyCase, Case, Observation};
use granval::compare::{Gate, Status};
use granval::experiments::micro::{Micro, PARTICLES_FILE, compare_streams};
use granval::experiments::runner;
use granval::rundata::frames::CsvFrames;
use std::path::{Path, PathBuf};

/// Every case file shipped under `cases/` (the suite manifests under `cases/suites/`
/// are not cases).
fn shipped_case_files() -> Vec<PathBuf> {
    fn walk(d: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                if p.file_name().is_some_and(|n| n != "suites") {
                    walk(&p, out);
                }
            } else if p.extension().is_some_and(|x| x == "toml") {
                out.push(p);
            }
        }
    }
    let mut v = Vec::new();
    walk(&common::root().join("cases"), &mut v);
    v.sort();
    v
}

#[test]
fn no_shipped_case_warns() {
    let files = shipped_case_files();
    assert!(files.len() >= 60, "found only {} case files", files.len());
    let mut warned = Vec::new();
    for f in &files {
        let c = AnyCase::load(f).unwrap_or_else(|e| panic!("{e}"));
        for w in c.warnings() {
            warned.push(format!("{}: {w}", f.display()));
        }
    }
    assert!(
        warned.is_empty(),
        "shipped cases warn:\n{}",
        warned.join("\n")
    );
}

/// `cases/micro/<name>.toml` with `edit` applied, written into `dir`.
fn edited(name: &str, dir: &Path, edit: impl Fn(String) -> String) -> PathBuf {
    let src = common::root()
        .join("cases/micro")
        .join(format!("{name}.toml"));
    let text = std::fs::read_to_string(&src).unwrap();
    let out = dir.join(format!("{name}.toml"));
    let new = edit(text.clone());
    assert_ne!(new, text, "the edit changed nothing");
    std::fs::write(&out, new).unwrap();
    out
}

/// head-on-e05 with the second sphere moved 3 mm sideways: the spheres still approach
/// along their line of centres at t = 0, but pass each other 3 mm apart (radii 1 mm).
fn near_miss(dir: &Path, tail: &str) -> PathBuf {
    edited("head-on-e05", dir, |t| {
        t.replace("x = [1.2e-3, 0.0, 0.0]", "x = [1.2e-3, 3.0e-3, 0.0]") + tail
    })
}

/// The coverage rule applied to one native run fed as both sides: the rule is a
/// function of the frames, and the frames here are free flight or a collision by
/// construction. (Only the rule is tested; no reference data is made.)
fn coverage_of_native_run(case: &Case) -> granval::compare::Check {
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join(PARTICLES_FILE);
    granval::engines::native::micro(case, &Default::default(), &csv, |_| {}).unwrap();
    let checks = compare_streams(
        case,
        CsvFrames::open(&csv, case.dt).unwrap(),
        CsvFrames::open(&csv, case.dt).unwrap(),
    );
    checks
        .into_iter()
        .find(|c| c.gate == Gate::Coverage)
        .expect("a coverage check")
}

#[test]
fn a_collision_whose_spheres_miss_is_not_compared() {
    let d = tempfile::tempdir().unwrap();
    let case = Case::load(&near_miss(d.path(), "")).unwrap();
    assert_eq!(case.expect, vec![Observation::Contact], "the default");
    let c = coverage_of_native_run(&case);
    assert_eq!(c.status, Status::NotCompared, "{c:?}");
    assert!(
        c.detail
            .contains("the spheres never touch: the case expects a contact"),
        "{}",
        c.detail
    );
}

#[test]
fn the_same_miss_with_expect_empty_keeps_the_motion_rule() {
    let d = tempfile::tempdir().unwrap();
    let case = Case::load(&near_miss(d.path(), "\n[compare]\nexpect = []\n")).unwrap();
    assert!(case.expect.is_empty());
    // Free flight moves the grains by more than 1 % of r_min: covered, as before.
    let c = coverage_of_native_run(&case);
    assert_eq!(c.status, Status::Pass, "{c:?}");
}

#[test]
fn the_head_on_collision_itself_is_covered() {
    // Negative control of the two tests above: the unedited case collides.
    let case = common::load("cases/micro/head-on-e05.toml");
    assert_eq!(case.expect, vec![Observation::Contact]);
    let c = coverage_of_native_run(&case);
    assert_eq!(c.status, Status::Pass, "{c:?}");
}

#[test]
fn receding_or_single_grains_expect_nothing_by_default() {
    let d = tempfile::tempdir().unwrap();
    // The positions swapped: the spheres fly apart.
    let apart = edited("head-on-e05", d.path(), |t| {
        t.replace("x = [-1.2e-3, 0.0, 0.0]", "x = [@, 0.0, 0.0]")
            .replace("x = [1.2e-3, 0.0, 0.0]", "x = [-1.2e-3, 0.0, 0.0]")
            .replace('@', "1.2e-3")
    });
    let c = Case::load(&apart).unwrap();
    assert!(c.expect.is_empty(), "{:?}", c.expect);
    // One sphere on a wall, a cluster: no pair to approach.
    assert!(
        common::load("cases/micro/steel-on-alumina.toml")
            .expect
            .is_empty()
    );
    assert!(
        common::load("cases/micro/cluster-settle.toml")
            .expect
            .is_empty()
    );
}

#[test]
fn an_unknown_expectation_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let f = near_miss(d.path(), "\n[compare]\nexpect = [\"collision\"]\n");
    let e = Case::load(&f).unwrap_err().to_string();
    assert!(
        e.contains("compare.expect[0]") && e.contains("\"contact\""),
        "{e}"
    );
}

/// Every shipped micro case that expects a contact shows one in the native run and in
/// its sealed LIGGGHTS record, and passes its coverage check.
#[test]
fn every_shipped_collision_case_collides_in_both_runs() {
    let mut expecting = Vec::new();
    for case in common::micro_cases() {
        if !case.expect.contains(&Observation::Contact) {
            continue;
        }
        let name = case.name.clone();
        let out = tempfile::tempdir().unwrap();
        let o = runner::compare(&Micro { case }, &common::recorded(), out.path());
        let cov = o
            .checks
            .iter()
            .find(|c| c.gate == Gate::Coverage)
            .unwrap_or_else(|| panic!("{name}: no coverage check: {:?}", o.checks));
        assert_eq!(cov.status, Status::Pass, "{name}: {}", cov.detail);
        expecting.push(name);
    }
    eprintln!("cases expecting a contact: {expecting:?}");
    for n in ["head-on-e05", "head-on-e09", "oblique-slide", "unequal"] {
        assert!(
            expecting.iter().any(|e| e == n),
            "{n} should expect a contact (two spheres approaching); got {expecting:?}"
        );
    }
}

#[test]
fn a_modulus_in_gpa_warns_and_still_validates() {
    let d = tempfile::tempdir().unwrap();
    let f = edited("head-on-e05", d.path(), |t| {
        t.replacen("youngs_modulus = 1.0e8", "youngs_modulus = 63", 1)
    });
    let c = Case::load(&f).unwrap();
    assert_eq!(c.warnings.len(), 1, "{:?}", c.warnings);
    assert!(
        c.warnings[0]
            .contains("materials[0].youngs_modulus: E = 63 Pa: did you mean 63 GPa = 6.3e10 Pa?"),
        "{:?}",
        c.warnings
    );
    // `granval validate`: exit code unchanged (0), the warning on stderr.
    let o = common::granval().arg("validate").arg(&f).output().unwrap();
    expect(&o, 0, &["did you mean 63 GPa"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("warning: ") && err.contains("63 GPa"), "{err}");
}

#[test]
fn a_density_in_g_per_cm3_is_named_beside_the_time_step_it_breaks() {
    let d = tempfile::tempdir().unwrap();
    let f = edited("head-on-e05", d.path(), |t| {
        t.replace("density = 2500.0", "density = 2.5")
    });
    let o = common::granval().arg("validate").arg(&f).output().unwrap();
    // The Rayleigh time shrinks with sqrt(density): dt is refused (exit 2), and the
    // message names the density as the likely cause.
    expect(
        &o,
        2,
        &[
            "simulation.dt",
            "likely cause",
            "particles[0].density = 2.5 kg/m^3: in g/cm^3? 2.5 g/cm^3 = 2500 kg/m^3",
        ],
    );
}

#[test]
fn a_radius_in_mm_and_an_initial_overlap_warn() {
    let d = tempfile::tempdir().unwrap();
    // Spheres 2.4 mm apart with radii 1.3 mm overlap by 0.2 mm = 15 % of a radius.
    let f = edited("head-on-e05", d.path(), |t| {
        t.replace("radius = 1.0e-3", "radius = 1.3e-3")
    });
    let c = Case::load(&f).unwrap();
    assert!(
        c.warnings
            .iter()
            .any(|w| w.contains("particles[0] and particles[1] overlap") && w.contains("15.4 %")),
        "{:?}",
        c.warnings
    );
    let w = granval::case::plausible::size("particles[0].radius", 2.0).unwrap();
    assert!(w.contains("in mm? 2 mm = 0.002 m"), "{w}");
}

#[test]
fn a_compare_report_keeps_the_warnings_in_its_notes() {
    // Whatever the comparison of the edited case comes to (without its own reference
    // record it is refused; LIGGGHTS refuses E below its floor), the warning is on stderr
    // and in report.json's notes.
    let d = tempfile::tempdir().unwrap();
    let f = edited("spin", d.path(), |t| {
        t.replacen("youngs_modulus = 1.0e8", "youngs_modulus = 63", 1)
    });
    let out = d.path().join("report");
    let o = common::granval()
        .arg("compare")
        .arg(&f)
        .arg("--report")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("warning: ") && err.contains("63 GPa"), "{err}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let notes = report["notes"].as_array().expect("notes");
    assert!(
        notes.iter().any(|n| n
            .as_str()
            .is_some_and(|n| n.contains("did you mean 63 GPa"))),
        "{notes:?}"
    );
}

#[test]
fn toml_type_errors_are_said_in_words() {
    let d = tempfile::tempdir().unwrap();
    for (from, to, needles) in [
        (
            "output_every = 5",
            "output_every = 1.5",
            &[
                "simulation.output_every: expected a whole number",
                "got 1.5",
            ][..],
        ),
        (
            "dt = 1e-6",
            "dt = \"1e-6\"",
            &["simulation.dt: expected a number, got \"1e-6\""][..],
        ),
        (
            "gravity = [0.0, 0.0, 0.0]",
            "gravity = [0.0, 0.0]",
            &["simulation.gravity: expected a list of 3 values"][..],
        ),
        (
            "name = \"head-on-e05\"",
            "name = 5",
            &["case.name: expected text in quotes, got 5"][..],
        ),
    ] {
        let f = edited("head-on-e05", d.path(), |t| t.replacen(from, to, 1));
        let o = common::granval().arg("validate").arg(&f).output().unwrap();
        let mut all = vec!["head-on-e05.toml"];
        all.extend(needles);
        expect(&o, 2, &all);
        let t = text(&o);
        assert!(
            !t.contains("expected u64") && !t.contains("expected f64"),
            "{t}"
        );
    }
}

#[test]
fn a_bed_read_from_files_has_no_nan_settle_time() {
    use granval::case::penetration::PenetrationCase;
    let text = common::tiny_penetration_toml(0.01, "", "");
    let case = PenetrationCase::from_toml_str(&text, Path::new("tiny.toml")).unwrap();
    let bed = granval::physics::dem::packing::Bed {
        particles: Vec::new(),
        bodies: Vec::new(),
        surface_z: 0.05,
        psi: f64::NAN,
        ke_ratio: f64::NAN,
        settle_time: f64::NAN,
        ke_at_end_of_pour: f64::NAN,
    };
    let note = granval::physics::dem::packing::bed_note(&case, &bed);
    assert!(!note.contains("NaN"), "{note}");
    assert!(note.contains("settled: n/a"), "{note}");
}
