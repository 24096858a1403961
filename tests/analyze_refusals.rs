//! `granval analyze` of a penetration deck directory decides a verdict only from the
//! inputs `granval deck` wrote and from outputs of those inputs: an edited, missing or
//! foreign input, or an output of another bed, is refused with exit 2 naming the file,
//! with `--no-native` too; the unedited directory (the negative control) is analysed.
//!
//! No engine is needed: "LIGGGHTS ran" is written by the test the way LIGGGHTS writes it
//! (its log echoes the deck; its force file has the deck's title and an intruder that
//! moves as the deck moves it, with a force linear in depth).

mod common;

use common::text;

use granval::case::penetration::PenetrationCase;
use granval::engines::liggghts::penetration as lp;
use granval::experiments::penetration::{bed, deck_dir};
use std::path::{Path, PathBuf};
use std::process::Output;

/// A deck directory of the tiny case with two beds, written by `granval deck`, with
/// both beds "run" (outputs as LIGGGHTS writes them).
fn ran_deck() -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let case = tmp.path().join("tiny.toml");
    std::fs::write(
        &case,
        std::fs::read_to_string(common::root().join("tests/data/penetration-tiny.toml")).unwrap()
            + "\n[ensemble]\nbeds = 2\n",
    )
    .unwrap();
    let deck = tmp.path().join("deck");
    let o = common::granval()
        .args(["deck"])
        .arg(&case)
        .arg("-o")
        .arg(&deck)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    for k in 0..2 {
        fake_liggghts_run(&deck, k);
    }
    (tmp, deck)
}

/// What a complete LIGGGHTS run of bed `k` leaves in its directory.
fn fake_liggghts_run(deck: &Path, k: usize) {
    let case = PenetrationCase::load(&deck.join("case.toml")).unwrap();
    let ck = case.realisation(k);
    let dir = deck.join(format!("bed-{k}"));
    let b = deck_dir::read_bed(&ck, &dir).unwrap();
    let d = bed::liggghts_deck(&ck, &b).unwrap();
    let deck_text = std::fs::read_to_string(dir.join(lp::DECK_FILE)).unwrap();
    let n = lp::expected_samples(&d);
    std::fs::write(
        dir.join(lp::LOG_FILE),
        format!(
            "LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, compiled by the test)\n{deck_text}\nLoop time of 1.5 on 1 procs for {} steps with {} atoms\n",
            d.n_steps,
            b.particles.len()
        ),
    )
    .unwrap();
    // F = rho_g psi g S R (20 h + 3) below the surface: a sane force-depth relation.
    let scale = ck.density * b.psi * ck.gravity * std::f64::consts::PI * ck.intruder_radius.powi(3);
    let mut force = String::from(
        "# step t z_bottom fx fy fz (units SI: s, m, N; f = force of the grains on the intruder)\n",
    );
    for i in 1..=n as u64 {
        let step = i * d.force_every;
        let z = d.intruder_bottom_z0 - d.speed * d.dt * step as f64;
        let h = (b.surface_z - z) / ck.intruder_radius;
        let fz = if h > 0.0 {
            scale * (20.0 * h + 3.0)
        } else {
            0.0
        };
        force += &format!("{step} {} {z} 0 0 {fz}\n", step as f64 * d.dt);
    }
    std::fs::write(dir.join(lp::FORCE_FILE), force).unwrap();
}

fn analyze(deck: &Path, native: bool) -> Output {
    // The report goes to a directory of its own (never next to the deck: a record
    // under reference/ is analysed too).
    let report = tempfile::tempdir().unwrap();
    let mut c = common::granval();
    c.arg("analyze")
        .arg(deck)
        .arg("--report")
        .arg(report.path().join("r"))
        .arg("--verbose");
    if !native {
        c.arg("--no-native");
    }
    c.output().unwrap()
}

fn refused(o: &Output, needles: &[&str]) {
    let t = text(o);
    assert_eq!(o.status.code(), Some(2), "{t}");
    for n in needles {
        assert!(t.contains(n), "missing {n:?} in:\n{t}");
    }
}

/// Edits `file` of bed 0 by `edit`, then analyses with and without `--no-native`:
/// exit 2 both times, naming the file and `why`.
fn edited_is_refused(file: &str, edit: impl Fn(&str) -> String, why: &str) {
    let (_tmp, deck) = ran_deck();
    let p = deck.join("bed-0").join(file);
    let before = std::fs::read_to_string(&p).unwrap();
    let after = edit(&before);
    assert_ne!(before, after, "the edit changed nothing in {file}");
    std::fs::write(&p, after).unwrap();
    for native in [false, true] {
        let o = analyze(&deck, native);
        refused(&o, &[&format!("bed-0/{file}"), why]);
    }
}

/// The negative control: the unedited directory with its outputs is analysed (a
/// verdict, not a refusal), with and without `--no-native`.
#[test]
fn the_unedited_deck_directory_is_analysed() {
    let (_tmp, deck) = ran_deck();
    for native in [false, true] {
        let o = analyze(&deck, native);
        let t = text(&o);
        assert!(
            matches!(o.status.code(), Some(0 | 1)),
            "native {native}: {t}"
        );
        assert!(t.contains("K_phi"), "{t}");
    }
}

#[test]
fn a_deck_with_changed_friction_is_refused() {
    edited_is_refused(
        lp::DECK_FILE,
        |t| {
            // The grain-grain friction of the pair table (the first pair, 0.5).
            let line = t
                .lines()
                .find(|l| l.contains("coefficientFriction peratomtypepair"))
                .expect("the friction line");
            t.replacen(line, &line.replacen(" 0.5", " 0.4", 1), 1)
        },
        "not the input granval wrote",
    );
}

#[test]
fn a_bed_edited_by_1e_12_is_refused() {
    edited_is_refused(
        lp::DATA_FILE,
        |t| {
            // The x of the first atom, relatively 1e-12 further.
            let (head, rest) = t.split_once("\nAtoms").unwrap();
            let mut lines: Vec<String> = rest.lines().map(str::to_string).collect();
            let k = lines
                .iter()
                .position(|l| l.split_whitespace().count() >= 7)
                .unwrap();
            let mut w: Vec<String> = lines[k].split_whitespace().map(str::to_string).collect();
            let x: f64 = w[4].parse().unwrap();
            w[4] = format!("{}", x * (1.0 + 1e-12));
            assert_ne!(w[4], lines[k].split_whitespace().nth(4).unwrap());
            lines[k] = w.join(" ");
            format!("{head}\nAtoms{}\n", lines.join("\n"))
        },
        "not the input granval wrote",
    );
}

#[test]
fn a_moved_intruder_mesh_is_refused() {
    edited_is_refused(
        lp::STL_FILE,
        |t| {
            // Every vertex 0.1 mm higher.
            t.lines()
                .map(|l| match l.trim().strip_prefix("vertex ") {
                    Some(v) => {
                        let c: Vec<f64> =
                            v.split_whitespace().map(|x| x.parse().unwrap()).collect();
                        format!("vertex {} {} {}", c[0], c[1], c[2] + 1e-4)
                    }
                    None => l.to_string(),
                })
                .collect::<Vec<_>>()
                .join("\n")
                + "\n"
        },
        "not the input granval wrote",
    );
}

#[test]
fn a_deleted_deck_is_refused() {
    let (_tmp, deck) = ran_deck();
    std::fs::remove_file(deck.join("bed-0").join(lp::DECK_FILE)).unwrap();
    for native in [false, true] {
        refused(
            &analyze(&deck, native),
            &["bed-0/in.penetration", "missing"],
        );
    }
}

#[test]
fn an_edited_case_file_is_refused() {
    let (_tmp, deck) = ran_deck();
    let p = deck.join("case.toml");
    let t = std::fs::read_to_string(&p).unwrap();
    std::fs::write(&p, t.replacen("friction = 0.5", "friction = 0.4", 1)).unwrap();
    for native in [false, true] {
        refused(
            &analyze(&deck, native),
            &["case.toml", "not the one this deck was written for"],
        );
    }
}

#[test]
fn a_foreign_input_is_refused() {
    let (_tmp, deck) = ran_deck();
    // A lattice next to the bed would make analyze read the bed from bed.dump.
    std::fs::write(deck.join("bed-0").join(lp::LATTICE_FILE), "lattice\n").unwrap();
    refused(
        &analyze(&deck, false),
        &["bed-0/data.lattice", "a foreign input"],
    );
}

/// Outputs that do not belong to the deck are a refusal (exit 2), not a physics FAIL:
/// bed 1's force file or log in bed 0's directory, or bed 1's whole inputs and outputs
/// under bed 0.
#[test]
fn outputs_of_another_bed_are_refused() {
    for file in [lp::FORCE_FILE, lp::LOG_FILE] {
        let (_tmp, deck) = ran_deck();
        std::fs::copy(deck.join("bed-1").join(file), deck.join("bed-0").join(file)).unwrap();
        let o = analyze(&deck, false);
        refused(&o, &[&format!("bed-0/{file}")]);
        assert!(
            text(&o).contains("another bed") || text(&o).contains("does not echo the title"),
            "{}",
            text(&o)
        );
    }
    let (_tmp, deck) = ran_deck();
    let (a, b) = (deck.join("bed-0"), deck.join("bed-1"));
    std::fs::rename(&a, deck.join("tmp")).unwrap();
    std::fs::rename(&b, &a).unwrap();
    std::fs::rename(deck.join("tmp"), &b).unwrap();
    refused(
        &analyze(&deck, false),
        &["written for bed 1", "another bed"],
    );
}

/// A sealed reference record is not a deck directory (it has no `inputs.json`): analyze
/// refuses it and says how a record is read.
#[test]
fn a_record_is_refused_with_the_command_that_reads_it() {
    let rec = common::root().join("reference/penetration/penetration-ci");
    refused(
        &analyze(&rec, false),
        &[
            "bed-0/inputs.json",
            "sealed reference record",
            "--reference-mode recorded",
        ],
    );
}
