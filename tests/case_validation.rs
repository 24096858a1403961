//! Bad input must produce an error naming file, field, value and reason — never a
//! panic and never a silent default.

mod common;

use granval::case::Case;
use std::path::Path;

fn base() -> String {
    std::fs::read_to_string(common::root().join("cases/micro/head-on-e09.toml")).unwrap()
}

fn err(text: &str) -> String {
    match Case::from_toml_str(text, Path::new("cases/bad.toml")) {
        Ok(_) => panic!("bad input was accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

fn assert_mentions(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(
            msg.contains(p),
            "error message {msg:?} does not mention {p:?}"
        );
    }
}

#[test]
fn all_shipped_cases_load() {
    assert!(common::micro_cases().len() >= 11);
    // Every case file of every kind, in or out of a suite.
    let mut n = 0;
    for kind in ["micro", "penetration", "impact2d"] {
        for e in std::fs::read_dir(common::root().join("cases").join(kind)).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "toml") {
                granval::case::AnyCase::load(&p).unwrap_or_else(|e| panic!("{e}"));
                n += 1;
            }
        }
    }
    assert!(n >= 11 + 5 + 9, "{n} case files");
}

/// A negative control must name gates its case kind has and must perturb something.
#[test]
fn bad_negative_control_is_an_error() {
    let control = |must_fail: &str, perturbation: &str| {
        format!(
            "{}\n[[negative_control]]\nname = \"wrong\"\nmust_fail = {must_fail}\nperturbation = {perturbation}\n",
            base()
        )
    };
    let m = err(&control("[\"k_phi\"]", "{ friction_factor = 1.1 }"));
    assert_mentions(
        &m,
        &["cases/bad.toml", "negative_control[0].must_fail", "k_phi"],
    );
    let m = err(&control("[]", "{ friction_factor = 1.1 }"));
    assert_mentions(&m, &["negative_control[0].must_fail"]);
    let m = err(&control("[\"velocity\"]", "{}"));
    assert_mentions(&m, &["negative_control[0].perturbation", "changes nothing"]);
    let m = err(&control("[\"velocity\"]", "{ friction_factor = -1.0 }"));
    assert_mentions(
        &m,
        &["negative_control[0].perturbation.friction_factor", ">= 0"],
    );
    // The same control with a micro gate and a real perturbation is accepted.
    let ok = control("[\"velocity\"]", "{ friction_factor = 1.1 }");
    let c = Case::from_toml_str(&ok, Path::new("cases/ok.toml")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(c.negative_controls.len(), 1);
}

#[test]
fn non_positive_radius() {
    let m = err(&base().replacen("radius = 1.0e-3", "radius = -1.0e-3", 1));
    assert_mentions(
        &m,
        &["cases/bad.toml", "particles[0].radius", "-0.001", "> 0"],
    );
}

/// Isotropic elasticity needs -1 < nu <= 0.5 (positive bulk and shear moduli; 0.5 is
/// the incompressible limit, which LIGGGHTS takes too): outside, refused.
#[test]
fn poisson_out_of_range() {
    for bad in ["0.51", "-1.0"] {
        let m = err(&base().replacen("poisson_ratio = 0.3", &format!("poisson_ratio = {bad}"), 1));
        assert_mentions(
            &m,
            &[
                "cases/bad.toml",
                "materials[0].poisson_ratio",
                bad.trim_end_matches(".0"),
                "(-1, 0.5]",
            ],
        );
    }
    for good in ["0.5", "-0.2", "0.0"] {
        Case::from_toml_str(
            &base().replacen("poisson_ratio = 0.3", &format!("poisson_ratio = {good}"), 1),
            Path::new("cases/ok.toml"),
        )
        .unwrap_or_else(|e| panic!("nu = {good}: {e}"));
    }
}

#[test]
fn restitution_out_of_range() {
    for bad in ["0.0", "1.2"] {
        let m = err(&base().replacen("restitution = 0.9", &format!("restitution = {bad}"), 1));
        assert_mentions(&m, &["interactions[0].restitution", "(0, 1]"]);
    }
}

#[test]
fn negative_friction() {
    let m = err(&base().replacen("friction = 0.5", "friction = -0.1", 1));
    assert_mentions(&m, &["interactions[0].friction", "-0.1", ">= 0"]);
}

#[test]
fn time_step_above_rayleigh_time() {
    let m = err(&base().replacen("dt = 1e-6", "dt = 1e-4", 1).replacen(
        "duration = 1e-3",
        "duration = 1e-2",
        1,
    ));
    assert_mentions(&m, &["simulation.dt", "0.0001", "Rayleigh"]);
}

#[test]
fn unknown_field_is_an_error() {
    let m = err(&base().replacen("restitution = 0.9", "restitutoin = 0.9", 1));
    assert_mentions(&m, &["cases/bad.toml", "restitutoin"]);
}

#[test]
fn missing_pair_is_an_error() {
    let text = base();
    let cut = text
        .find("[[interactions]]\ntypes = [2, 2]")
        .expect("fixture has a 2-2 pair");
    let end = text[cut..].find("\n\n").unwrap() + cut;
    let m = err(&format!("{}{}", &text[..cut], &text[end..]));
    assert_mentions(&m, &["interactions", "types [2, 2]", "missing"]);
}

#[test]
fn missing_modulus_is_an_error() {
    let m = err(&base().replacen("youngs_modulus = 1.0e8\n", "", 1));
    assert_mentions(&m, &["materials[0].youngs_modulus", "missing"]);
}

#[test]
fn particle_outside_domain() {
    let m = err(&base().replacen("x = [-1.2e-3, 0.0, 0.0]", "x = [-0.5, 0.0, 0.0]", 1));
    assert_mentions(&m, &["particles[0].x", "domain"]);
}

/// The impact2d-only switches of a control (a sweep, a packing sweep, an interface to
/// freeze) are refused on a penetration case, which has none of those gates, with the
/// field and the reason, instead of being accepted and perturbing nothing.
#[test]
fn impact2d_switches_are_refused_on_a_penetration_case() {
    let ci = std::fs::read_to_string(common::root().join("cases/penetration/ci.toml")).unwrap();
    for (switch, reason) in [
        ("sweep_ignored", "cases have a sweep to ignore"),
        ("packing_ignored", "packing sweep to ignore"),
        ("interface_frozen_floor", "only impact2d"),
    ] {
        let text = format!(
            "{ci}\n[[negative_control]]\nname = \"x\"\nmust_fail = [\"k_phi\"]\nperturbation = {{ {switch} = true }}\n"
        );
        let e = match granval::case::AnyCase::from_toml_str(&text, Path::new("p.toml")) {
            Ok(_) => panic!("{switch} accepted on a penetration case"),
            Err(e) => e.to_string(),
        };
        assert_mentions(
            &e,
            &[
                "p.toml",
                &format!("negative_control[1].perturbation.{switch}"),
                reason,
            ],
        );
    }
}
