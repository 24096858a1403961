//! `granval validate` and `granval deck` make the checks `compare` makes before it runs
//! (what the reference engine refuses, the start state, the resource limits): a case
//! that validates is a case that runs, and one `compare` refuses does not validate.
//! Each refusal has its negative control, a case just inside the limit that validates.

mod common;

use common::{expect, text};

use std::path::{Path, PathBuf};
use std::process::Output;

fn granval(args: &[&str], case: &Path) -> Output {
    common::granval().args(args).arg(case).output().unwrap()
}

/// Two spheres of radius 1 mm on the x axis, `gap` apart (negative: overlapping), with
/// ids `ids` and `edit` applied to the text.
fn two_spheres(
    dir: &Path,
    name: &str,
    gap: f64,
    ids: [u64; 2],
    edit: &dyn Fn(String) -> String,
) -> PathBuf {
    let r = 1e-3;
    let t = format!(
        "[case]\nname = \"{name}\"\nkind = \"micro\"\n[simulation]\ndt = 1e-7\nduration = 1e-5\noutput_every = 10\ngravity = [0.0, 0.0, 0.0]\n[models]\nnormal = \"hertz\"\ntangential = \"history\"\nrolling = \"none\"\n[domain]\nlo = [-0.01, -0.01, -0.01]\nhi = [0.01, 0.01, 0.01]\n[[materials]]\ntype = 1\nyoungs_modulus = 1e8\npoisson_ratio = 0.3\n[[interactions]]\ntypes = [1, 1]\nrestitution = 0.5\nfriction = 0.5\nrolling_friction = 0.0\n[[particles]]\nid = {}\ntype = 1\nradius = {r:e}\ndensity = 2500.0\nx = [0.0, 0.0, 0.0]\n[[particles]]\nid = {}\ntype = 1\nradius = {r:e}\ndensity = 2500.0\nx = [{:e}, 0.0, 0.0]\n",
        ids[0],
        ids[1],
        2.0 * r + gap
    );
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, edit(t)).unwrap();
    p
}

fn same(t: String) -> String {
    t
}

#[test]
fn a_30_percent_start_overlap_does_not_validate_or_write_a_deck() {
    let d = tempfile::tempdir().unwrap();
    let bad = two_spheres(d.path(), "overlap30", -0.3e-3, [1, 2], &same);
    expect(
        &granval(&["validate"], &bad),
        2,
        &["overlap by", "30.0 %", "at the start"],
    );
    let deck = d.path().join("deck");
    let o = common::granval()
        .args(["deck"])
        .arg(&bad)
        .arg("-o")
        .arg(&deck)
        .output()
        .unwrap();
    expect(&o, 2, &["overlap by"]);
    assert!(!deck.join("in.granval").exists(), "a deck was written");
    // compare refuses it the same way (the native start check).
    let o = common::granval()
        .args(["compare"])
        .arg(&bad)
        .args(["--reference-mode", "recorded", "--report"])
        .arg(d.path().join("r"))
        .output()
        .unwrap();
    expect(&o, 2, &["overlap by"]);
    // Negative control: a 4 % overlap (under the 5 % limit) validates.
    let ok = two_spheres(d.path(), "overlap4", -0.04e-3, [1, 2], &same);
    expect(&granval(&["validate"], &ok), 0, &["valid micro case"]);
}

#[test]
fn atom_ids_liggghts_cannot_hold_do_not_validate() {
    let d = tempfile::tempdir().unwrap();
    for id in [2_147_483_648u64, 3_000_000_000] {
        let bad = two_spheres(d.path(), "bigid", 1e-4, [1, id], &same);
        expect(
            &granval(&["validate"], &bad),
            2,
            &["particles[1].id", &id.to_string(), "signed 32-bit"],
        );
    }
    // 2^64 - 1 does not even fit the case file's integers.
    let bad = two_spheres(d.path(), "hugeid", 1e-4, [1, 2], &|t| {
        t.replacen("id = 2\n", "id = 18446744073709551615\n", 1)
    });
    expect(&granval(&["validate"], &bad), 2, &["hugeid.toml"]);
    let ok = two_spheres(d.path(), "maxid", 1e-4, [1, 2_147_483_647], &same);
    expect(&granval(&["validate"], &ok), 0, &["valid micro case"]);
}

/// nu < 0 and e <= 0.05 are physical and run natively, but LIGGGHTS 3.8 refuses them
/// (global_properties.cpp): a comparison cannot run, so they do not validate.
#[test]
fn values_liggghts_refuses_do_not_validate() {
    let d = tempfile::tempdir().unwrap();
    let nu = two_spheres(d.path(), "nu", 1e-4, [1, 2], &|t| {
        t.replacen("poisson_ratio = 0.3", "poisson_ratio = -0.2", 1)
    });
    expect(
        &granval(&["validate"], &nu),
        2,
        &["poisson_ratio", "-2e-1", "0 <= poissonsRatio <= 0.5"],
    );
    let e = two_spheres(d.path(), "e", 1e-4, [1, 2], &|t| {
        t.replacen("restitution = 0.5", "restitution = 0.05", 1)
    });
    expect(
        &granval(&["validate"], &e),
        2,
        &["restitution", "5e-2", "0.05 < coefficientRestitution <= 1"],
    );
    // The native engine alone takes them.
    let o = common::granval()
        .args(["run"])
        .arg(&nu)
        .arg("--out")
        .arg(d.path().join("native"))
        .output()
        .unwrap();
    expect(&o, 0, &[]);
    // Negative control: the edges LIGGGHTS takes.
    let edge = two_spheres(d.path(), "edge", 1e-4, [1, 2], &|t| {
        t.replacen("poisson_ratio = 0.3", "poisson_ratio = 0.0", 1)
            .replacen("restitution = 0.5", "restitution = 0.050001", 1)
    });
    expect(&granval(&["validate"], &edge), 0, &["valid micro case"]);
}

/// 50 000 rigid dimers for 1e8 steps: 1e5 spheres, 1e13 particle-steps. The estimate
/// counts the member spheres, so the case is over the limits (it was "particles 0,
/// particle-steps 0: within"); the same case for 1e5 steps is within.
#[test]
fn clump_cases_count_their_spheres_against_the_limits() {
    let d = tempfile::tempdir().unwrap();
    let write = |name: &str, steps: f64| {
        let dt = 1e-7;
        let mut t = format!(
            "[case]\nname = \"{name}\"\nkind = \"micro\"\n[simulation]\ndt = {dt:e}\nduration = {:e}\noutput_every = 1000000\ngravity = [0.0, 0.0, 0.0]\n[models]\nnormal = \"hertz\"\ntangential = \"history\"\nrolling = \"none\"\n[domain]\nlo = [0.0, 0.0, 0.0]\nhi = [0.41, 0.41, 0.41]\n[[materials]]\ntype = 1\nyoungs_modulus = 1e8\npoisson_ratio = 0.3\n[[interactions]]\ntypes = [1, 1]\nrestitution = 0.5\nfriction = 0.5\nrolling_friction = 0.0\n[[clump_templates]]\nname = \"dimer\"\ntype = 1\ndensity = 2500.0\nspheres = [\n  {{ offset = [-0.0005, 0.0, 0.0], radius = 1.0e-3 }},\n  {{ offset = [0.0005, 0.0, 0.0], radius = 1.0e-3 }},\n]\n",
            steps * dt
        );
        // 50 000 bodies on a 5 mm lattice (37 x 37 x 37 sites), none touching.
        let mut id = 0;
        'fill: for i in 0..37 {
            for j in 0..37 {
                for k in 0..37 {
                    if id == 50_000 {
                        break 'fill;
                    }
                    id += 1;
                    t += &format!(
                        "[[clumps]]\nid = {id}\ntemplate = \"dimer\"\nx = [{:e}, {:e}, {:e}]\n",
                        0.01 + 0.005 * i as f64,
                        0.01 + 0.005 * j as f64,
                        0.01 + 0.005 * k as f64
                    );
                }
            }
        }
        let p = d.path().join(format!("{name}.toml"));
        std::fs::write(&p, t).unwrap();
        p
    };
    let big = write("dimers-1e8", 1e8);
    let o = granval(&["validate"], &big);
    expect(
        &o,
        2,
        &[
            "clumps",
            "50000",
            "1.000e13",
            "particle-steps",
            "--allow-large",
        ],
    );
    assert!(text(&o).contains("too large to run here"), "{}", text(&o));
    let small = write("dimers-1e5", 1e5);
    expect(
        &granval(&["validate"], &small),
        0,
        &["valid micro case", "within"],
    );
}
