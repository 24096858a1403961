//! Nothing corrupt, vacuous or hostile can pass. Each probe is what a careless or
//! hostile user could do; each must end with exit 2 and a message that names the file,
//! the field or the quantity and says why — never a pass, a panic or a silent default.

mod common;

use common::{expect, text};

use std::path::{Path, PathBuf};
use std::process::Output;

fn run(args: &[&str]) -> Output {
    common::granval().args(args).output().unwrap()
}

/// A copy of the micro references in a temporary directory, for tampering.
fn reference_copy() -> tempfile::TempDir {
    let d = tempfile::tempdir().unwrap();
    let src = common::root().join("reference/micro");
    for e in std::fs::read_dir(&src).unwrap() {
        let e = e.unwrap();
        let to = d.path().join("micro").join(e.file_name());
        std::fs::create_dir_all(&to).unwrap();
        for f in std::fs::read_dir(e.path()).unwrap() {
            let f = f.unwrap();
            std::fs::copy(f.path(), to.join(f.file_name())).unwrap();
        }
    }
    d
}

fn compare_recorded(case: &str, reference: &Path, out: &Path) -> Output {
    common::granval()
        .env_remove("GRANVAL_REQUIRE_LIVE")
        .args([
            "compare",
            case,
            "--reference-mode",
            "recorded",
            "--reference",
        ])
        .arg(reference)
        .arg("--report")
        .arg(out)
        .output()
        .unwrap()
}

#[test]
fn untouched_records_pass_through_their_seal() {
    let out = tempfile::tempdir().unwrap();
    let o = compare_recorded(
        "cases/micro/head-on-e05.toml",
        &common::root().join("reference"),
        out.path(),
    );
    expect(&o, 0, &["RECORDED", "seal verified"]);
}

#[test]
fn a_record_changed_by_1e_12_is_refused() {
    let refs = reference_copy();
    let dump = refs.path().join("micro/head-on-e05/dump.granval");
    let lines: Vec<String> = std::fs::read_to_string(&dump)
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect();
    // The first atom line of the second frame: change x by a relative 1e-12.
    let k = lines
        .iter()
        .enumerate()
        .filter(|(_, l)| l.starts_with("ITEM: ATOMS"))
        .nth(1)
        .unwrap()
        .0
        + 1;
    let mut f: Vec<String> = lines[k].split_whitespace().map(str::to_string).collect();
    let x: f64 = f[1].parse().unwrap();
    f[1] = format!("{:.17e}", x * (1.0 + 1e-12));
    assert_ne!(f[1], lines[k].split_whitespace().nth(1).unwrap());
    let mut edited = lines.clone();
    edited[k] = f.join(" ");
    std::fs::write(&dump, edited.join("\n") + "\n").unwrap();
    let out = tempfile::tempdir().unwrap();
    let o = compare_recorded("cases/micro/head-on-e05.toml", refs.path(), out.path());
    expect(
        &o,
        2,
        &[
            "dump.granval",
            "modified",
            "granval reference refresh --only",
        ],
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.path().join("report.json")).unwrap())
            .unwrap();
    assert_eq!(report["passed"], false);
}

#[test]
fn another_cases_record_is_refused() {
    let refs = reference_copy();
    let (a, b) = (
        refs.path().join("micro/head-on-e05"),
        refs.path().join("micro/head-on-e09"),
    );
    let tmp = refs.path().join("swap");
    std::fs::rename(&a, &tmp).unwrap();
    std::fs::rename(&b, &a).unwrap();
    std::fs::rename(&tmp, &b).unwrap();
    for case in [
        "cases/micro/head-on-e05.toml",
        "cases/micro/head-on-e09.toml",
    ] {
        let out = tempfile::tempdir().unwrap();
        let o = compare_recorded(case, refs.path(), out.path());
        expect(&o, 2, &["recorded for a different case"]);
    }
}

#[test]
fn a_missing_seal_is_refused() {
    let refs = reference_copy();
    std::fs::remove_file(refs.path().join("micro/spin/seal.json")).unwrap();
    let out = tempfile::tempdir().unwrap();
    let o = compare_recorded("cases/micro/spin.toml", refs.path(), out.path());
    expect(&o, 2, &["seal.json", "no sealed reference record"]);
}

/// A case file next to the shipped ones, edited.
fn edited(rel: &str, dir: &Path, edit: impl Fn(String) -> String) -> PathBuf {
    let t = std::fs::read_to_string(common::root().join(rel)).unwrap();
    let e = edit(t.clone());
    assert_ne!(t, e, "the edit of {rel} changed nothing");
    let p = dir.join(Path::new(rel).file_name().unwrap());
    std::fs::write(&p, e).unwrap();
    p
}

#[test]
fn a_comparison_of_step_zero_only_is_not_a_pass() {
    // output_every beyond the run: only step 0 would be compared.
    let d = tempfile::tempdir().unwrap();
    let case = edited("cases/micro/spin.toml", d.path(), |t| {
        t.replace("output_every = 5", "output_every = 100000")
    });
    let out = d.path().join("out");
    let o = common::granval()
        .args(["compare"])
        .arg(&case)
        .arg("--report")
        .arg(&out)
        .output()
        .unwrap();
    if common::live(
        granval::rundata::provenance::EngineKind::Liggghts,
        "a_comparison_of_step_zero_only_is_not_a_pass",
    ) {
        expect(&o, 2, &["NOT COMPARED", "0 frames after step 0"]);
    } else {
        // Without LIGGGHTS the edited case has no record of its own (output_every is
        // part of what the seal binds): refused before anything is compared, never a
        // pass. The coverage rule itself is then checked only where LIGGGHTS runs.
        expect(
            &o,
            2,
            &["recorded for a different case", "reference refresh"],
        );
    }
}

#[test]
fn a_case_where_nothing_happens_is_not_a_pass() {
    // No gravity, no velocity, no contact: the engines "agree" on nothing at all.
    let d = tempfile::tempdir().unwrap();
    let case = edited("cases/micro/plane-normal.toml", d.path(), |t| {
        t.replace("gravity = [0.0, 0.0, -9.81]", "gravity = [0.0, 0.0, 0.0]")
            .replace("v = [0.0, 0.0, -0.6]", "v = [0.0, 0.0, 0.0]")
    });
    let o = common::granval()
        .args(["compare"])
        .arg(&case)
        .arg("--report")
        .arg(d.path().join("out"))
        .output()
        .unwrap();
    // Either the trajectory gates are not compared (coverage) or the reference "never
    // moves" error: both exit 2.
    expect(&o, 2, &[]);
    assert!(!text(&o).contains("| pass |") || text(&o).contains("NOT COMPARED"));
}

#[test]
fn a_case_name_that_is_a_path_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let case = edited("cases/micro/spin.toml", d.path(), |t| {
        t.replace("name = \"spin\"", "name = \"../../x\"")
    });
    let out = d.path().join("report");
    let o = common::granval()
        .args(["compare"])
        .arg(&case)
        .arg("--report")
        .arg(&out)
        .output()
        .unwrap();
    expect(&o, 2, &["case.name", "../../x", "[A-Za-z0-9._-]"]);
    assert!(!d.path().join("x").exists() && !d.path().parent().unwrap().join("x").exists());
}

#[test]
fn a_used_output_directory_is_refused_unless_forced() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("out");
    // An earlier run's directory (granval's marker in it), with stale outputs.
    let o = run(&[
        "run",
        "cases/micro/spin.toml",
        "--out",
        out.to_str().unwrap(),
    ]);
    expect(&o, 0, &[]);
    std::fs::write(out.join("particles.csv"), "stale").unwrap();
    std::fs::write(out.join("force.csv"), "stale from another run").unwrap();
    let o = run(&[
        "run",
        "cases/micro/spin.toml",
        "--out",
        out.to_str().unwrap(),
    ]);
    expect(&o, 2, &["is not empty", "--force"]);
    let o = run(&[
        "run",
        "cases/micro/spin.toml",
        "--out",
        out.to_str().unwrap(),
        "--force",
    ]);
    expect(&o, 0, &[]);
    let fresh = std::fs::read_to_string(out.join("particles.csv")).unwrap();
    assert!(fresh.starts_with("t,id,x") && !fresh.contains("stale"));
    assert!(
        !out.join("force.csv").exists(),
        "a stale file survived --force"
    );
}

#[test]
fn coincident_spheres_are_named() {
    let d = tempfile::tempdir().unwrap();
    let case = edited("cases/micro/head-on-e05.toml", d.path(), |t| {
        t.replace("x = [1.2e-3, 0.0, 0.0]", "x = [-1.2e-3, 0.0, 0.0]")
    });
    let o = common::granval()
        .args(["run"])
        .arg(&case)
        .arg("--out")
        .arg(d.path().join("out"))
        .output()
        .unwrap();
    expect(&o, 2, &["particles id 1 and id 2 overlap", "at the start"]);
}

#[test]
fn a_million_grains_in_a_box_fail_fast_and_small() {
    // 1e5 spheres in a 2 mm box: the overlap check refuses it before any neighbour
    // list is built (the old behaviour was a 3.4 GB allocation failure).
    let d = tempfile::tempdir().unwrap();
    let mut t = String::from(
        "[case]\nname = \"crowd\"\nkind = \"micro\"\n[simulation]\ndt = 1e-7\nduration = 1e-5\noutput_every = 10\ngravity = [0.0, 0.0, 0.0]\n[models]\nnormal = \"hertz\"\ntangential = \"history\"\nrolling = \"none\"\n[domain]\nlo = [0.0, 0.0, 0.0]\nhi = [0.002, 0.002, 0.002]\n[[materials]]\ntype = 1\nyoungs_modulus = 1e8\npoisson_ratio = 0.3\n[[interactions]]\ntypes = [1, 1]\nrestitution = 0.5\nfriction = 0.5\nrolling_friction = 0.0\n",
    );
    let n = 100_000;
    for k in 0..n {
        let (i, j, l) = (k % 47, (k / 47) % 47, k / (47 * 47));
        t += &format!(
            "[[particles]]\nid = {}\ntype = 1\nradius = 5e-5\ndensity = 2500.0\nx = [{:e}, {:e}, {:e}]\n",
            k + 1,
            1e-4 + 3.8e-5 * i as f64,
            1e-4 + 3.8e-5 * j as f64,
            1e-4 + 3.8e-5 * l as f64
        );
    }
    let case = d.path().join("crowd.toml");
    std::fs::write(&case, t).unwrap();
    let start = std::time::Instant::now();
    let o = common::granval()
        .args(["run"])
        .arg(&case)
        .arg("--out")
        .arg(d.path().join("out"))
        .output()
        .unwrap();
    expect(&o, 2, &["overlap by", "at the start"]);
    assert!(start.elapsed().as_secs() < 60);
}

#[test]
fn a_run_that_cannot_finish_or_fit_is_refused_before_it_starts() {
    let d = tempfile::tempdir().unwrap();
    let endless = edited("cases/micro/spin.toml", d.path(), |t| {
        t.replace("duration = 1e-3", "duration = 1e300")
    });
    let o = common::granval()
        .args(["run"])
        .arg(&endless)
        .arg("--out")
        .arg(d.path().join("a"))
        .output()
        .unwrap();
    expect(&o, 2, &["simulation.duration", "cannot finish"]);
    // 1e9 steps written every step: terabytes of output, refused by the estimate.
    let big = edited("cases/micro/spin.toml", d.path(), |t| {
        t.replace("duration = 1e-3", "duration = 1e3")
            .replace("output_every = 5", "output_every = 1")
    });
    let o = common::granval()
        .args(["run"])
        .arg(&big)
        .arg("--out")
        .arg(d.path().join("b"))
        .output()
        .unwrap();
    expect(
        &o,
        2,
        &["refused before running", "bytes of output", "--allow-large"],
    );
}

#[test]
fn a_huge_radius_is_blamed_on_the_radius() {
    let d = tempfile::tempdir().unwrap();
    let case = edited("cases/micro/spin.toml", d.path(), |t| {
        t.replacen("radius = 1.0e-3", "radius = 1e308", 1)
    });
    let o = common::granval()
        .args(["run"])
        .arg(&case)
        .arg("--out")
        .arg(d.path().join("o"))
        .output()
        .unwrap();
    expect(
        &o,
        2,
        &["particles[0].radius", "1e308", "wider than the domain"],
    );
}

#[test]
fn zero_mpi_processes_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let o = common::granval()
        .args(["compare", "cases/micro/spin.toml", "--np", "0", "--report"])
        .arg(d.path().join("o"))
        .output()
        .unwrap();
    expect(&o, 2, &["--np", "0"]);
}

#[test]
fn malt_outside_its_domain_is_refused_in_degrees() {
    for phi in ["90", "89", "-1", "NaN"] {
        let o = run(&["malt", &format!("--phi={phi}")]);
        expect(&o, 2, &["deg", "0 <= phi <= 60"]);
    }
    let o = run(&["malt", "--phi", "25.94"]);
    expect(&o, 0, &["K_phi(25.94 deg) = 22.99"]);
}

#[test]
fn a_bed_taller_than_its_container_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let case = edited("cases/penetration/ci.toml", d.path(), |t| {
        let h = t
            .lines()
            .find(|l| l.starts_with("height"))
            .unwrap()
            .to_string();
        t.replace(&h, "height = 0.02")
    });
    let o = common::granval()
        .args(["run"])
        .arg(&case)
        .arg("--out")
        .arg(d.path().join("o"))
        .output()
        .unwrap();
    expect(&o, 2, &["bed.fill_height", "overflow the container"]);
}

#[test]
fn an_intruder_as_wide_as_its_container_is_named() {
    let d = tempfile::tempdir().unwrap();
    let case = edited("cases/penetration/ci.toml", d.path(), |t| {
        let dia = t
            .lines()
            .skip_while(|l| !l.starts_with("[intruder]"))
            .find(|l| l.starts_with("diameter"))
            .unwrap()
            .to_string();
        t.replacen(&dia, "diameter = 0.049", 1)
    });
    let o = common::granval()
        .args(["run"])
        .arg(&case)
        .arg("--out")
        .arg(d.path().join("o"))
        .output()
        .unwrap();
    expect(&o, 2, &["intruder.diameter", "two grain diameters"]);
}

#[test]
fn hard_materials_get_hard_particles_in_the_deck() {
    let d = tempfile::tempdir().unwrap();
    let o = run(&[
        "deck",
        "cases/micro/glass-head-on.toml",
        "-o",
        d.path().join("deck").to_str().unwrap(),
    ]);
    expect(&o, 0, &[]);
    let deck = std::fs::read_to_string(d.path().join("deck/in.granval")).unwrap();
    assert!(
        deck.contains("hard_particles yes") && !deck.contains("soft_particles"),
        "{deck}"
    );
    let soft = tempfile::tempdir().unwrap();
    let case = edited("cases/micro/spin.toml", soft.path(), |t| {
        t.replace("youngs_modulus = 1.0e8", "youngs_modulus = 1.0e6")
    });
    let o = common::granval()
        .args(["deck"])
        .arg(&case)
        .arg("-o")
        .arg(soft.path().join("deck"))
        .output()
        .unwrap();
    expect(&o, 0, &[]);
    let deck = std::fs::read_to_string(soft.path().join("deck/in.granval")).unwrap();
    assert!(deck.contains("soft_particles yes"), "{deck}");
}
