//! Every gated micro comparison must be able to fail: the native engine run with
//! deliberately wrong physics (mu x 1.1, e +- 0.05, nu +- 0.1) must be caught.

mod common;

use granval::case::Perturbation;
use granval::compare::trajectory;
use granval::physics::dem;

/// Runs the whole micro suite with a perturbed native engine; returns the cases caught.
fn caught(pert: Perturbation) -> Vec<String> {
    let mut names = Vec::new();
    for case in common::micro_cases() {
        let dir = tempfile::tempdir().unwrap();
        let reference = common::reference_frames(&case, dir.path());
        let native = {
            let mut v = Vec::new();
            dem::run(
                &case,
                pert,
                |_| {},
                |f| {
                    v.push(f);
                    Ok(())
                },
            )
            .unwrap();
            v
        };
        if trajectory::compare(&case, &native, &reference)
            .iter()
            .any(|c| !c.passed)
        {
            names.push(case.name.clone());
        }
    }
    names
}

fn assert_caught(pert: Perturbation, must_include: &[&str]) {
    let names = caught(pert);
    eprintln!("{pert:?} caught by: {names:?}");
    for m in must_include {
        assert!(
            names.iter().any(|n| n == m),
            "{pert:?} not caught by {m} (caught by {names:?})"
        );
    }
}

#[test]
fn friction_times_1_1_fails() {
    assert_caught(
        Perturbation {
            friction_factor: 1.1,
            ..Default::default()
        },
        &["oblique-stick", "oblique-slide", "spin", "plane-oblique"],
    );
}

#[test]
fn restitution_plus_0_05_fails() {
    assert_caught(
        Perturbation {
            restitution_shift: 0.05,
            ..Default::default()
        },
        &["head-on-e05", "head-on-e09", "unequal", "plane-normal"],
    );
}

#[test]
fn restitution_minus_0_05_fails() {
    assert_caught(
        Perturbation {
            restitution_shift: -0.05,
            ..Default::default()
        },
        &["head-on-e05", "head-on-e09", "unequal", "plane-normal"],
    );
}

#[test]
fn poisson_plus_0_1_fails() {
    assert_caught(
        Perturbation {
            poisson_shift: 0.1,
            ..Default::default()
        },
        &[
            "head-on-e05",
            "head-on-e09",
            "unequal",
            "plane-normal",
            "oblique-stick",
        ],
    );
}

#[test]
fn poisson_minus_0_1_fails() {
    assert_caught(
        Perturbation {
            poisson_shift: -0.1,
            ..Default::default()
        },
        &[
            "head-on-e05",
            "head-on-e09",
            "unequal",
            "plane-normal",
            "oblique-stick",
        ],
    );
}
