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
}

#[test]
fn non_positive_radius() {
    let m = err(&base().replacen("radius = 1.0e-3", "radius = -1.0e-3", 1));
    assert_mentions(
        &m,
        &["cases/bad.toml", "particles[0].radius", "-0.001", "> 0"],
    );
}

#[test]
fn poisson_out_of_range() {
    let m = err(&base().replacen("poisson_ratio = 0.3", "poisson_ratio = 0.5", 1));
    assert_mentions(
        &m,
        &[
            "cases/bad.toml",
            "materials[0].poisson_ratio",
            "0.5",
            "(-1, 0.5)",
        ],
    );
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
