//! The triaxial test (docs/stress.md rule 5) on a tiny sample: the native engine compacts
//! and shears it with sensible stresses, and LIGGGHTS' deck of the same sample runs and
//! agrees with the native run over the first steps (same state, same walls, same servo).

mod common;

use granval::analysis::triaxial as at;
use granval::case::triaxial::TriaxialCase;
use granval::engines::liggghts::triaxial as lt;
use granval::experiments::triaxial::{Unit, liggghts_deck, sample_hash};
use granval::physics::dem::triaxial::{self as pt, Sample};
use granval::rundata::triaxial::WallRecord;
use std::sync::OnceLock;

/// The release case with 200 grains, one seed (1, not a registered one), 1 kPa, output
/// every 10 steps.
fn tiny_case() -> TriaxialCase {
    let mut c = TriaxialCase::load(&common::root().join("cases/release/triaxial-table2.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    c.grains = 200;
    c.seeds = vec![1];
    c.confining_pressures = vec![1000.0];
    c.output_every = 10;
    c
}

/// The unit of the tiny sample (seed 1, 1 kPa).
fn tiny_unit() -> Unit {
    let s = tiny_sample().clone();
    Unit {
        seed: 1,
        sigma_c: 1000.0,
        sample_hash: sample_hash(&s),
        sample: s,
    }
}

/// The tiny sample, compacted once for every test of this file.
fn tiny_sample() -> &'static Sample {
    static S: OnceLock<Sample> = OnceLock::new();
    S.get_or_init(|| pt::compact(&tiny_case(), 1, 1000.0, |_, _, _| {}).unwrap())
}

fn native(steps: u64) -> Vec<WallRecord> {
    let mut out = Vec::new();
    pt::shear(
        &tiny_case(),
        tiny_sample(),
        Default::default(),
        steps,
        |r| {
            out.push(*r);
            Ok(())
        },
    )
    .unwrap();
    out
}

/// Compaction reaches the registered criterion; the shear loads the sample axially
/// while the servos hold the lateral walls at sigma_c, with finite strains and a
/// mobilised angle of a frictional sample.
#[test]
fn a_tiny_sample_compacts_and_shears_with_sensible_stresses() {
    let c = tiny_case();
    let s = tiny_sample();
    assert!(
        s.stress_ratio.iter().all(|r| (r - 1.0).abs() <= 0.01),
        "{}",
        s.note()
    );
    assert!(s.ke_ratio < 1e-8, "{}", s.note());
    assert!(s.psi > 0.45 && s.psi < 0.65, "{}", s.note());
    // The lattice started at 0.30: the walls closed in.
    let (side, _) = c.lattice_box();
    assert!(s.hi.iter().all(|&h| h < 0.85 * side));
    let recs = native(3000);
    assert_eq!(recs.len(), 300);
    assert_eq!(recs.last().unwrap().step, 3000);
    let pts = at::points(&recs, s.hi);
    for p in &pts {
        assert!(
            p.s.iter()
                .chain([&p.eps_a, &p.eps_v])
                .all(|x| x.is_finite())
        );
    }
    let last = pts.last().unwrap();
    // 3000 steps at 0.158 /s: eps_a = 0.0142.
    assert!(
        (last.eps_a - 3000.0 * c.dt * c.strain_rate).abs() < 1e-9,
        "{}",
        last.eps_a
    );
    // Lateral walls at sigma_c (servo), within 5 % after the first 500 steps; axial
    // stress above them; a frictional angle.
    for p in &pts[50..] {
        for i in 0..2 {
            assert!((p.s_hi[i] / 1000.0 - 1.0).abs() < 0.05, "{:?}", p.s_hi);
        }
    }
    assert!(last.s[2] > 1.2 * last.s[0].max(last.s[1]), "{:?}", last.s);
    let phi = at::phi_deg(last.s);
    assert!(phi > 5.0 && phi < 60.0, "phi_mob {phi}");
}

/// LIGGGHTS' deck of the tiny sample, 1000 steps: it runs, its output parses, and every
/// wall force and position agrees with the native run's at the same step. Measured on
/// this machine (LIGGGHTS 3.8.0, 2026-11-24): the servo walls' positions agree to the
/// last bit, the six wall forces to 7e-13 of the axial force over 1000 steps
/// (3000 steps: 6e-12) — the engines start from the same state and only the
/// order of the force sums differs. Gated at 1e-9 of the axial force and 1e-12 m. (With
/// rectangles of two triangles, LIGGGHTS counted a grain's contact twice for one step
/// where it crossed the diagonal: a 5 % jump of one wall force at step 283.)
#[test]
fn the_liggghts_deck_runs_and_agrees_with_the_native_run_at_first() {
    if !common::live_or_skip(
        granval::rundata::provenance::EngineKind::Liggghts,
        "the_liggghts_deck_runs_and_agrees_with_the_native_run_at_first",
        "live triaxial deck skipped",
    ) {
        return;
    }
    let c = tiny_case();
    let u = tiny_unit();
    let steps = 1000;
    let mut d = liggghts_deck(&c, &u);
    d.n_steps = steps;
    let dir = tempfile::tempdir().unwrap();
    let (lig, prov) = lt::run(
        &d,
        dir.path(),
        1,
        &granval::engines::process::Limits::fixed(
            std::time::Duration::from_secs(600),
            "the test's limit",
        ),
    )
    .unwrap_or_else(|e| panic!("{e:#}"));
    assert!(prov.version.contains("LIGGGHTS"), "{}", prov.version);
    let nat = native(steps);
    assert_eq!(lig.len(), nat.len());
    let scale = nat.iter().map(|r| r.f_hi[2].abs()).fold(0.0, f64::max);
    assert!(scale > 0.0);
    let mut worst = (0.0f64, 0u64, "");
    for (a, b) in nat.iter().zip(&lig) {
        assert_eq!(a.step, b.step);
        for (k, (x, y)) in a
            .f_lo
            .iter()
            .chain(&a.f_hi)
            .zip(b.f_lo.iter().chain(&b.f_hi))
            .enumerate()
        {
            let e = (x - y).abs() / scale;
            if e > worst.0 {
                worst = (
                    e,
                    a.step,
                    ["x_lo", "y_lo", "z_lo", "x_hi", "y_hi", "z_hi"][k],
                );
            }
        }
        for i in 0..3 {
            assert!(
                (a.hi[i] - b.hi[i]).abs() < 1e-12,
                "step {}: wall positions {:?} vs {:?}",
                a.step,
                a.hi,
                b.hi
            );
        }
    }
    eprintln!(
        "largest wall-force difference native vs LIGGGHTS over {steps} steps: {:.3e} of the axial force (step {}, wall {})",
        worst.0, worst.1, worst.2
    );
    assert!(worst.0 < 1e-9, "{worst:?}");
}

/// `granval analyze` of a triaxial deck directory takes a run only from the inputs
/// granval writes: an edited deck, data file or wall mesh is refused naming the file,
/// before any output is read (it used to be taken with a note). The unedited directory
/// passes the input check and fails only on the missing LIGGGHTS outputs. No engine runs.
#[test]
fn a_triaxial_run_by_hand_from_edited_inputs_is_refused() {
    use granval::experiments::Experiment;
    let c = tiny_case();
    let u = tiny_unit();
    let exp = granval::experiments::triaxial::Triaxial { case: c.clone() };
    let tmp = tempfile::tempdir().unwrap();
    lt::write_deck_dir(&liggghts_deck(&c, &u), tmp.path()).unwrap();
    let err = |dir: &std::path::Path| match exp.read_run_dir(&u, dir) {
        Ok(_) => panic!("a deck directory without outputs was read"),
        Err(e) => format!("{e:#}"),
    };
    let unedited = err(tmp.path());
    assert!(
        !unedited.contains("not the input granval writes"),
        "{unedited}"
    );
    for (file, from, to) in [
        (lt::DECK_FILE, "\ntimestep ", "\ntimestep 1e-12 # was "),
        (lt::DATA_FILE, " atoms\n", " atoms\n\n"),
        (lt::STL_FILES[0], "vertex ", "vertex 1e-9 "),
    ] {
        let p = tmp.path().join(file);
        let text = std::fs::read_to_string(&p).unwrap();
        let edited = if file == lt::DATA_FILE {
            // One grain's diameter changed by a part in 1e12.
            let k = text.find("\nAtoms\n\n").unwrap() + 8;
            let line_end = k + text[k..].find('\n').unwrap();
            let mut w: Vec<String> = text[k..line_end]
                .split_whitespace()
                .map(String::from)
                .collect();
            let d: f64 = w[2].parse().unwrap();
            w[2] = format!("{:e}", d * (1.0 + 1e-12));
            format!("{}{}{}", &text[..k], w.join(" "), &text[line_end..])
        } else {
            assert!(text.contains(from), "{file}");
            text.replacen(from, to, 1)
        };
        assert_ne!(edited, text);
        std::fs::write(&p, &edited).unwrap();
        let e = err(tmp.path());
        assert!(
            e.contains(file) && e.contains("not the input granval writes"),
            "{file}: {e}"
        );
        std::fs::write(&p, &text).unwrap();
    }
}

/// `--viz N` on a triaxial deck: the deck declares its VTK dump before the shear's `run`,
/// and a run by hand from it passes the input check (it fails only on the missing
/// outputs); the dump edited (one more column) is another deck, refused. No engine runs.
#[test]
fn a_triaxial_deck_with_a_visualisation_dump_is_still_granvals() {
    use granval::experiments::Experiment;
    let c = tiny_case();
    let u = tiny_unit();
    let exp = granval::experiments::triaxial::Triaxial { case: c.clone() };
    let tmp = tempfile::tempdir().unwrap();
    let opts = granval::experiments::Options {
        viz_every: Some(50),
        ..common::options()
    };
    exp.write_deck(&u, tmp.path(), &opts).unwrap();
    let p = tmp.path().join(lt::DECK_FILE);
    let deck = std::fs::read_to_string(&p).unwrap();
    let line = "dump viz all custom/vtk 50 viz-*.vtk id type radius";
    assert!(
        deck.find(line).unwrap() < deck.rfind("\nrun ").unwrap(),
        "{deck}"
    );
    let err = || match exp.read_run_dir(&u, tmp.path()) {
        Ok(_) => panic!("a deck directory without outputs was read"),
        Err(e) => format!("{e:#}"),
    };
    let e = err();
    assert!(!e.contains("not the input granval writes"), "{e}");
    std::fs::write(&p, deck.replace("omegaz", "omegaz density")).unwrap();
    let e = err();
    assert!(e.contains("not the input granval writes"), "{e}");
}
