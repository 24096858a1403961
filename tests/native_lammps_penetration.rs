//! The native engine with LAMMPS' laws against LAMMPS 2025 in penetration: the same
//! deck (the 300-grain tiny bed, prepared natively), stepped by LAMMPS and by
//! `granval::engines::native::penetration_lammps_laws`, force of the grains on the
//! intruder compared step by step (docs/lammps-laws.md, "The native engine with LAMMPS'
//! laws in penetration").

mod common;

use granval::case::Perturbation;
use granval::case::penetration::PenetrationCase;
use granval::engines::lammps3d_penetration as lp;
use granval::engines::liggghts::penetration::PenetrationDeck;
use granval::experiments::penetration::bed::prepare_bed;
use granval::experiments::penetration::deck_dir::lammps_deck;
use granval::rundata::force::ForceSample;
use std::path::Path;

/// Windows of steps the agreement is reported over.
const WINDOWS: [(usize, usize); 5] = [(1, 50), (1, 100), (100, 200), (200, 300), (300, 401)];

/// Steps compared. The intruder starts flush with the highest grain top under it, so
/// it pushes on grains from step 1.
const STEPS: u64 = 400;

fn tiny_deck(dir: &Path) -> (PenetrationCase, PenetrationDeck) {
    let path = dir.join("tiny.toml");
    std::fs::write(&path, common::tiny_penetration_toml(0.010, "", "")).unwrap();
    let case = PenetrationCase::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let bed = prepare_bed(&case, false).unwrap();
    let mut deck = lammps_deck(&case, &bed).unwrap();
    deck.intruder_bottom_z0 -= case.start_gap;
    deck.n_steps = STEPS;
    deck.force_every = 1;
    (case, deck)
}

fn native(case: &PenetrationCase, deck: &PenetrationDeck, pert: &Perturbation) -> Vec<ForceSample> {
    granval::engines::native::penetration_lammps_laws(case, deck, pert, |_, _| {})
        .unwrap_or_else(|e| panic!("{e:#}"))
        .0
}

/// Largest relative difference of the force vector over steps `from..to`, relative to
/// the largest |f| LAMMPS reports over those steps (the force starts at zero, so a
/// per-step relative error would divide by nothing).
fn max_rel(native: &[ForceSample], lammps: &[lp::ForceLine], from: usize, to: usize) -> f64 {
    let scale = lammps[from..to]
        .iter()
        .map(|l| l.f.iter().map(|c| c * c).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    assert!(
        scale > 0.0,
        "no force on the intruder in steps {from}..{to}"
    );
    (from..to)
        .map(|k| {
            let d: f64 = (0..3)
                .map(|a| (native[k].f[a] - lammps[k].f[a]).powi(2))
                .sum::<f64>()
                .sqrt();
            d / scale
        })
        .fold(0.0, f64::max)
}

/// The same deck stepped by LAMMPS 2025 and natively with LAMMPS' laws: t and z_bottom
/// must be the same doubles at every step (LAMMPS' `$(v_zb)` keeps 15 digits, which the
/// native sampler reproduces), and the force on the intruder must agree to
/// `TOLERANCE` (relative to the largest |f| of the window) over the first 100 steps and
/// to `TOLERANCE_400` over all 400.
///
/// Why these numbers (measured 2026-11-29, this machine, LAMMPS 22 Jul 2025 - Update 4,
/// 300 grains, intruder flush with the highest grain top, 0.42 N on it at step 400):
/// max |df| / max |f| was 1.3e-16 over steps 1-50, 4.1e-14 over 1-100, 4.2e-14 over
/// 100-200, 1.7e-13 over 200-300, 2.0e-12 over 300-400; then 1.8e-6 over 400-1000 and
/// 0.22 over 1000-2000 (the two codes add each grain's forces in a different order,
/// and the bed's chaos amplifies that last-bit difference about e-fold every 45 steps,
/// so beyond ~1000 steps only statistics can be compared). The tolerances sit 250 and
/// 500 times above what was measured and far below any physical change: the negative
/// control, friction times 0.8 in the native side only, differs by 3.7e-2 over steps
/// 1-50 and 7.2e-2 over 1-100, and must exceed `CONTROL_MIN` there.
#[test]
fn native_lammps_laws_match_lammps_in_penetration() {
    const TOLERANCE: f64 = 1e-11;
    const TOLERANCE_400: f64 = 1e-9;
    const CONTROL_MIN: f64 = 1e-3;
    let test = "native LAMMPS laws vs LAMMPS, penetration";
    if !common::lammps3d_live(test) {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (case, deck) = tiny_deck(tmp.path());
    let dir = tmp.path().join("lammps");
    lp::write_inputs(&deck, &dir).unwrap();
    let lmp = granval::engines::lammps3d::Lammps3d {
        binary: granval::engines::lammps3d::binary().unwrap(),
        limits: granval::engines::process::Limits::fixed(
            std::time::Duration::from_secs(600),
            "native vs LAMMPS penetration test",
        ),
    };
    let (lines, _) =
        lp::run_dir(&lmp, &dir, lp::expected_samples(&deck)).unwrap_or_else(|e| panic!("{e:#}"));
    let ours = native(&case, &deck, &Perturbation::default());
    assert_eq!(ours.len(), lines.len());
    for (k, (n, l)) in ours.iter().zip(&lines).enumerate() {
        assert_eq!(l.step, k as u64);
        assert_eq!(
            (n.t, n.z_bottom),
            (l.t, l.z_bottom),
            "step {k}: t, z_bottom"
        );
    }
    let report = |s: &[ForceSample]| -> Vec<String> {
        WINDOWS
            .iter()
            .map(|&(a, b)| format!("steps {a}..{b}: {:.3e}", max_rel(s, &lines, a, b)))
            .collect()
    };
    let fz = lines[STEPS as usize].f[2];
    eprintln!(
        "[{test}] {} grains; fz at step {STEPS}: LAMMPS {fz:.6e} N, native {:.6e} N; max |df|/max|f|: {}",
        deck.particles.len(),
        ours[STEPS as usize].f[2],
        report(&ours).join(", ")
    );
    // The bed resists: the comparison is of real contact forces, not of zeros.
    assert!(fz > 0.1, "fz at step {STEPS}: {fz} N");
    let first = max_rel(&ours, &lines, 1, 101);
    assert!(first <= TOLERANCE, "steps 1-100: {first:e} > {TOLERANCE:e}");
    let all = max_rel(&ours, &lines, 1, STEPS as usize + 1);
    assert!(
        all <= TOLERANCE_400,
        "steps 1-{STEPS}: {all:e} > {TOLERANCE_400:e}"
    );

    let friction = Perturbation {
        friction_factor: 0.8,
        ..Perturbation::default()
    };
    let control = native(&case, &deck, &friction);
    eprintln!(
        "[{test}] control mu x 0.8 (native only): {}",
        report(&control).join(", ")
    );
    let off = max_rel(&control, &lines, 1, 101);
    assert!(
        off > CONTROL_MIN,
        "friction x 0.8 changes the force by only {off:e} over steps 1-100: the comparison cannot see it"
    );
}

/// What the native engine with LAMMPS' laws cannot express is refused, naming what:
/// a control it has nothing to act on (rolling friction: these laws have none) and a
/// clump bed (the LAMMPS deck takes spheres only). Runs without LAMMPS.
#[test]
fn native_lammps_laws_refuse_what_they_cannot_express() {
    let tmp = tempfile::tempdir().unwrap();
    let (case, deck) = tiny_deck(tmp.path());
    let rolling = Perturbation {
        rolling_friction_factor: 2.0,
        ..Perturbation::default()
    };
    let err = granval::engines::native::penetration_lammps_laws(&case, &deck, &rolling, |_, _| {})
        .unwrap_err();
    assert!(format!("{err:#}").contains("rolling"), "{err:#}");
    let mut clumps = deck.clone();
    clumps.bodies = vec![granval::case::clumps::Clump {
        id: 1,
        template: 0,
        x: [0.0; 3],
        orientation: [1.0, 0.0, 0.0, 0.0],
        v: [0.0; 3],
        omega: [0.0; 3],
    }];
    let err = granval::engines::native::penetration_lammps_laws(
        &case,
        &clumps,
        &Perturbation::default(),
        |_, _| {},
    )
    .unwrap_err();
    assert!(format!("{err:#}").contains("clump"), "{err:#}");
}

/// The tiny case with LAMMPS' own laws: `[models] family = "lammps"`, `hertz/material`,
/// `mindlin` with the damping ratio `xt`, no rolling resistance (`tail`: appended).
fn lammps_family_toml(xt: &str, rolling: &str, tail: &str) -> String {
    let text = common::tiny_penetration_toml(0.010, "", tail);
    let models = "normal = \"hertz\"\ntangential = \"history\"\nrolling = \"cdt\"\n";
    assert!(
        text.contains(models),
        "tests/data/penetration-tiny.toml changed shape"
    );
    text.replacen(
        models,
        &format!(
            "family = \"lammps\"\nnormal = \"hertz/material\"\ntangential = \"mindlin\"\nrolling = \"{rolling}\"\ntangential_damping = {xt}\n"
        ),
        1,
    )
}

/// A penetration case may say `family = "lammps"`: it loads with its own xt (and a
/// canonical hash of its own), the LAMMPS deck prints that xt, the LIGGGHTS deck and
/// the native engine with LIGGGHTS' laws refuse it naming the field, and what the
/// LAMMPS deck cannot carry (rolling resistance) is refused at load.
#[test]
fn lammps_family_penetration_case_loads_and_is_routed() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("tiny-lammps.toml");
    std::fs::write(&path, lammps_family_toml("0.5", "none", "")).unwrap();
    let case = PenetrationCase::load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert!(matches!(
        case.family,
        granval::case::family::ContactFamily::Lammps(_)
    ));
    let lig_path = tmp.path().join("tiny.toml");
    std::fs::write(&lig_path, common::tiny_penetration_toml(0.010, "", "")).unwrap();
    let lig = PenetrationCase::load(&lig_path).unwrap();
    assert_ne!(case.canonical_hash(), lig.canonical_hash());

    let bed = prepare_bed(&case, false).unwrap();
    let deck = lammps_deck(&case, &bed).unwrap();
    let text = lp::write_inputs(&deck, &tmp.path().join("deck"))
        .and_then(|_| {
            Ok(std::fs::read_to_string(
                tmp.path().join("deck").join(lp::DECK_FILE),
            )?)
        })
        .unwrap();
    assert!(
        text.contains("tangential mindlin NULL 5e-1 5e-1"),
        "the case's xt is not in the deck:\n{text}"
    );
    let err = granval::experiments::penetration::bed::liggghts_deck(&case, &bed).unwrap_err();
    assert!(format!("{err:#}").contains("models.family"), "{err:#}");
    let err = granval::engines::native::penetration(
        &case,
        &bed,
        &Perturbation::default(),
        &[],
        |_| Ok(()),
        |_, _| {},
    )
    .unwrap_err();
    assert!(format!("{err:#}").contains("models.family"), "{err:#}");

    let sds = tmp.path().join("sds.toml");
    std::fs::write(&sds, lammps_family_toml("0.5", "sds", "")).unwrap();
    let err = PenetrationCase::load(&sds).unwrap_err().to_string();
    assert!(
        err.contains("models.rolling") && err.contains("sds"),
        "{err}"
    );
}

/// `granval compare --engine lammps` on a LAMMPS-family case: the native side runs
/// LAMMPS' laws (its provenance says so) and LAMMPS 2025 is the reference, both from
/// the same natively prepared bed; the comparison has no error check.
#[test]
fn compare_engine_lammps_runs_the_native_engine_with_lammps_laws() {
    let test = "compare --engine lammps, LAMMPS-family case";
    if !common::lammps3d_live(test) {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("tiny.toml");
    std::fs::write(&path, lammps_family_toml("0.907", "none", "")).unwrap();
    let report = tmp.path().join("report");
    let o = common::granval()
        .arg("compare")
        .arg(&path)
        .args(["--engine", "lammps", "--report"])
        .arg(&report)
        .output()
        .unwrap();
    let (out, err) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    eprintln!("[{test}] exit {:?}\n{out}", o.status.code());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report.join("report.json")).unwrap())
            .unwrap_or_else(|e| panic!("[{test}] report.json: {e}\n{err}"));
    let text = json.to_string();
    assert!(
        !text.contains("\"error\""),
        "[{test}] an error check: {text}"
    );
    assert_eq!(json["runs"][0]["reference_engine"], "LAMMPS", "{text}");
    // The native side's provenance names LAMMPS' laws.
    let native = report.join("tiny").join("bed-0").join("native");
    let prov = std::fs::read_to_string(native.join("provenance.json"))
        .unwrap_or_else(|e| panic!("[{test}] {}: {e}", native.display()));
    assert!(
        prov.contains("LAMMPS granular laws")
            && prov.contains("stepped natively with LAMMPS' laws"),
        "[{test}] {prov}"
    );
    // Same laws, same bed: the two K_phi agree far inside the gate's margin (measured
    // 2026-11-29: 397.96 native, 397.26 LAMMPS, +0.18 %; FDR distance 0.0028).
    let fdr = json["checks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["gate"] == "fdr_distance")
        .unwrap_or_else(|| panic!("no FDR distance check: {text}"));
    let d = fdr["value"].as_f64().unwrap();
    assert!(d < 0.02, "[{test}] FDR distance {d}");
}

/// A LAMMPS-family case compared against LIGGGHTS (`--engine liggghts`) is refused
/// before anything runs: exit 2, the file and the field named, no report directory made.
/// Its own reference engine is LAMMPS 2025, which `validate` names (and `compare`
/// without `--engine` takes). No engine is needed for either.
#[test]
fn compare_refuses_a_lammps_family_case_against_liggghts() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("tiny.toml");
    std::fs::write(&path, lammps_family_toml("0.907", "none", "")).unwrap();
    for command in ["compare", "deck", "run"] {
        let report = tmp.path().join("report");
        let o = common::granval()
            .arg(command)
            .arg(&path)
            .args(["--engine", "liggghts"])
            .arg(if command == "compare" {
                "--report"
            } else if command == "deck" {
                "-o"
            } else {
                "--out"
            })
            .arg(&report)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{command}: {err}");
        assert!(
            err.contains("tiny.toml") && err.contains("models.family") && err.contains("lammps"),
            "{command}: {err}"
        );
        assert!(!report.exists(), "{command}: an output directory was made");
    }
    let o = common::granval()
        .arg("validate")
        .arg(&path)
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("reference engine LAMMPS 22 Jul 2025"),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
}
