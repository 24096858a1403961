//! Claims across cases read only sealed run directories: hand-written `summary.json`
//! files (the forgery that turned every Feng claim into PASS) make every claim an ERROR
//! naming the file, exit 2, never a pass. The verification itself (a run's own sealed
//! summary verifies; an edited summary, changed outputs or another case's run do not)
//! is tested next to it, in `experiments::penetration::run_seal`.

mod common;

use granval::case::AnyCase;
use granval::compare::sweep::{CaseSummary, EngineSummary};
use granval::experiments::suite;

/// A summary as a forger would write it for every case of every claim of the release
/// suite: the case's name and canonical hash (public, in every seal), both engines
/// with a K_phi and an FDR that rise along each sweep.
fn forge(dir: &std::path::Path) -> usize {
    let cases = common::root().join("cases");
    let s = suite::load(&cases, "release").unwrap();
    let mut n = 0;
    let mut done = std::collections::BTreeSet::new();
    for c in &s.claims {
        for (i, p) in c.cases.iter().enumerate() {
            let AnyCase::Penetration(pc) = AnyCase::load(p).unwrap() else {
                panic!("{}", p.display())
            };
            if !done.insert(pc.name.clone()) {
                continue;
            }
            let k = 10.0 + 15.0 * i as f64;
            let h: Vec<f64> = (1..300).map(|j| j as f64 * 0.01).collect();
            let p: Vec<f64> = h.iter().map(|x| k * x + 1.0).collect();
            let e = EngineSummary {
                k_phi: k,
                k_phi_se_regression: 0.01,
                k_phi_beds: vec![k; pc.ensemble_beds],
                bed_fdrs: vec![(h.clone(), p.clone()); pc.ensemble_beds],
                p,
                h,
                psi: 0.6,
            };
            let d = dir.join(&pc.name);
            std::fs::create_dir_all(&d).unwrap();
            CaseSummary {
                case: pc.name.clone(),
                canonical_hash: granval::case::ValidatedCase::canonical_hash(&pc).to_string(),
                bed_hashes: Vec::new(),
                engines: [("native".to_string(), e.clone()), ("liggghts".into(), e)].into(),
            }
            .write(&d)
            .unwrap();
            n += 1;
        }
    }
    n
}

#[test]
fn hand_written_summaries_make_every_claim_an_error() {
    let runs = tempfile::tempdir().unwrap();
    let forged = forge(runs.path());
    assert!(forged >= 8, "{forged} summaries");
    let report = tempfile::tempdir().unwrap();
    let o = common::granval()
        .args(["check", "--suite", "release", "--claims-only", "--runs"])
        .arg(runs.path())
        .arg("--report")
        .arg(report.path().join("r"))
        .output()
        .unwrap();
    let t = format!(
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(o.status.code(), Some(2), "{t}");
    let r: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(report.path().join("r/report.json")).unwrap(),
    )
    .unwrap();
    let checks = r["checks"].as_array().unwrap();
    let claims: Vec<&serde_json::Value> = checks
        .iter()
        .filter(|c| c["gate"] == "claim" || c["gate"] == "negative_control")
        .collect();
    assert!(claims.len() >= 6, "{t}");
    for c in &claims {
        assert_eq!(c["status"], "error", "{c}");
        assert!(
            c["detail"].as_str().unwrap().contains("run-seal.json")
                && c["detail"].as_str().unwrap().contains("no run seal"),
            "{c}"
        );
    }
    assert!(!checks.iter().any(|c| c["status"] == "pass"), "{t}");
}

/// `granval agreement` reads only sealed runs too: a hand-written summary of the
/// three-code case with three engines is refused (exit 2, naming the missing run seal),
/// as are a case of another kind and a chaos record that is not one.
#[test]
fn agreement_refuses_hand_written_summaries() {
    let case_file = common::root().join("cases/penetration/three-code-ci.toml");
    let AnyCase::Penetration(pc) = AnyCase::load(&case_file).unwrap() else {
        panic!("{}", case_file.display())
    };
    let runs = tempfile::tempdir().unwrap();
    let e = |k: f64| EngineSummary {
        k_phi: k,
        k_phi_se_regression: 0.01,
        k_phi_beds: vec![k; pc.ensemble_beds],
        bed_fdrs: Vec::new(),
        p: Vec::new(),
        h: Vec::new(),
        psi: 0.6,
    };
    let d = runs.path().join(&pc.name);
    std::fs::create_dir_all(&d).unwrap();
    CaseSummary {
        case: pc.name.clone(),
        canonical_hash: granval::case::ValidatedCase::canonical_hash(&pc).to_string(),
        bed_hashes: (0..pc.ensemble_beds).map(|k| format!("{k:064}")).collect(),
        engines: [
            ("native".to_string(), e(26.0)),
            ("liggghts".into(), e(26.0)),
            ("lammps".into(), e(26.0)),
        ]
        .into(),
    }
    .write(&d)
    .unwrap();
    let chaos = common::root().join("docs/data/chaos/ci-seeds-20261200.json");
    let out = tempfile::tempdir().unwrap();
    let run = |case: &std::path::Path, chaos: &std::path::Path, name: &str| {
        common::granval()
            .arg("agreement")
            .arg(case)
            .arg("--runs")
            .arg(runs.path())
            .arg("--chaos")
            .arg(chaos)
            .arg("--report")
            .arg(out.path().join(name))
            .output()
            .unwrap()
    };
    common::expect(&run(&case_file, &chaos, "a"), 2, &["no run seal"]);
    let micro = common::root().join("cases/micro/head-on-e09.toml");
    common::expect(&run(&micro, &chaos, "b"), 2, &["penetration case"]);
    common::expect(
        &run(&case_file, &case_file, "c"),
        2,
        &["not a chaos record"],
    );
}
