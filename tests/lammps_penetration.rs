//! Penetration in LAMMPS 2025, first stage: `granval deck --engine lammps` writes the
//! deck, and a live smoke run on the 300-grain tiny bed. The smoke run is NOT the
//! validation: it checks that LAMMPS runs the deck to the end, that the force file is
//! complete and parses, that the bed resists (fz > 0, growing with depth) and that the
//! force is of the native engine's magnitude on the same bed within a factor 3 (the
//! LAMMPS deck has no rolling resistance and a Mindlin tangential law; docs/lammps-laws.md).

mod common;

use granval::case::penetration::PenetrationCase;
use granval::engines::lammps3d_penetration as lp;
use granval::experiments::penetration::bed::prepare_bed;
use granval::experiments::penetration::deck_dir::lammps_deck;
use std::path::Path;

/// The force file the LAMMPS deck writes (the deck's `fix print` names it).
const FORCE_FILE: &str = "force.lammps.txt";

fn tiny_case(dir: &Path) -> PenetrationCase {
    let path = dir.join("tiny.toml");
    std::fs::write(&path, common::tiny_penetration_toml(0.010, "", "")).unwrap();
    PenetrationCase::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn deck_engine_lammps_writes_a_lammps_deck_and_refuses_liggghts_beds() {
    let tmp = tempfile::tempdir().unwrap();
    let case = tiny_case(tmp.path());
    let out = tmp.path().join("deck");
    let o = common::granval()
        .args(["deck", "--engine", "lammps"])
        .arg(&case.source)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let deck = std::fs::read_to_string(out.join("bed-0").join(lp::DECK_FILE)).unwrap();
    for needle in [
        "atom_style sphere",
        &format!("read_data {}", lp::DATA_FILE),
        "pair_style granular",
        "pair_coeff 1 1 hertz/material 5.2e6 5e-1 3e-1 damping coeff_restitution tangential mindlin NULL 9.074852129730301e-1 5e-1",
        "pair_coeff 1 2 ",
        "fix floor all wall/gran granular hertz/material 5.2e6",
        "region container cylinder z 0 0 1.6e-2",
        "side in open 1 open 2",
        "region intruder cylinder z 0 0 5e-3",
        "side out units box move NULL NULL v_dz",
        "fix wint all wall/gran/region granular hertz/material 5.2e6 5e-1 3e-1 damping coeff_restitution tangential mindlin NULL 9.074852129730301e-1 3e-1 twisting none region intruder contacts",
        "compute fint all reduce sum f_wint[2] f_wint[3] f_wint[4]",
        "NO rolling resistance",
        "timestep 4e-5",
        "fix gravi all gravity 9.81e0 vector 0 0 -1",
    ] {
        assert!(deck.contains(needle), "deck lacks {needle:?}:\n{deck}");
    }
    // Mindlin's damping ratio is LIGGGHTS' sqrt(S_t / S_n) = sqrt(2 (1 - nu) / (2 - nu)).
    assert!(((2.0 * 0.7 / 1.7_f64).sqrt() - 9.074852129730301e-1).abs() < 1e-15);
    let data = std::fs::read_to_string(out.join("bed-0").join(lp::DATA_FILE)).unwrap();
    assert!(
        data.contains("300 atoms")
            && data.contains("Atoms # sphere")
            && data.contains("Velocities")
    );
    // A LIGGGHTS-settled bed has no exact grains to hand LAMMPS: refused, naming the option.
    let o = common::granval()
        .args(["deck", "--engine", "lammps", "--bed", "liggghts"])
        .arg(&case.source)
        .arg("-o")
        .arg(tmp.path().join("deck2"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("--bed liggghts"),
        "{err}"
    );
}

#[test]
fn force_file_parser_refuses_broken_lines() {
    let ok =
        lp::parse_force_text("# step t z_bottom fx fy fz\n10 4e-4 0.03 0 0 1.5\n", "f").unwrap();
    assert_eq!(ok.len(), 1);
    assert_eq!(ok[0].f[2], 1.5);
    assert!(lp::parse_force_text("10 4e-4 0.03 0 0\n", "f").is_err());
    assert!(lp::parse_force_text("10 4e-4 0.03 0 0 nan\n", "f").is_err());
    assert!(lp::parse_force_text("10 4e-4 0.03 0 0 x\n", "f").is_err());
}

#[test]
fn lammps_smoke_run_resists_like_the_native_engine() {
    let test = "lammps penetration smoke";
    if !common::lammps3d_live(test) {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let case = tiny_case(tmp.path());
    let bed = prepare_bed(&case, false).unwrap();
    let deck = lammps_deck(&case, &bed).unwrap();
    let dir = tmp.path().join("run");
    lp::write_inputs(&deck, &dir).unwrap();
    let lmp = granval::engines::lammps3d::Lammps3d {
        binary: granval::engines::lammps3d::binary().unwrap(),
        limits: granval::engines::process::Limits::fixed(
            std::time::Duration::from_secs(600),
            "smoke test",
        ),
    };
    let (lines, wall) =
        lp::run_dir(&lmp, &dir, lp::expected_samples(&deck)).unwrap_or_else(|e| panic!("{e:#}"));
    let (native, _) = granval::engines::native::penetration(
        &case,
        &bed,
        &Default::default(),
        &[],
        |_| Ok(()),
        |_, _| {},
    )
    .unwrap();
    // Mean fz over the deepest third of the travel below the bed surface, both engines.
    let surface = bed.surface_z;
    let deep_mean = |zs: &[(f64, f64)], lo: f64, hi: f64| {
        let v: Vec<f64> = zs
            .iter()
            .filter(|(z, _)| surface - z >= lo && surface - z < hi)
            .map(|(_, f)| *f)
            .collect();
        assert!(!v.is_empty(), "no samples at depth [{lo}, {hi})");
        v.iter().sum::<f64>() / v.len() as f64
    };
    let lz: Vec<(f64, f64)> = lines.iter().map(|l| (l.z_bottom, l.f[2])).collect();
    let nz: Vec<(f64, f64)> = native.iter().map(|s| (s.z_bottom, s.f[2])).collect();
    let depth = surface - lz.last().unwrap().0;
    let (a, b) = (depth / 3.0, 2.0 * depth / 3.0);
    let l_mid = deep_mean(&lz, a, b);
    let l_deep = deep_mean(&lz, b, depth + 1e-12);
    let n_deep = deep_mean(&nz, b, depth + 1e-12);
    eprintln!(
        "[{test}] {} grains, depth {depth:.4} m, LAMMPS wall {wall:.1} s; mean fz middle third {l_mid:.4e} N, deepest third {l_deep:.4e} N (native {n_deep:.4e} N, ratio {:.3})",
        bed.particles.len(),
        l_deep / n_deep
    );
    assert!(l_deep > 0.0, "the bed does not resist in LAMMPS: {l_deep}");
    assert!(
        l_deep > l_mid,
        "force does not grow with depth: {l_mid} -> {l_deep}"
    );
    let ratio = l_deep / n_deep;
    assert!(
        (1.0 / 3.0..=3.0).contains(&ratio),
        "LAMMPS force {l_deep} N vs native {n_deep} N: ratio {ratio} outside [1/3, 3]"
    );
}

/// `granval compare --engine lammps` refuses, before anything runs (exit 2, naming the
/// option): a recorded LAMMPS reference (there is none), a case whose reference cannot
/// be LAMMPS 2025 (micro), and `native` named as the reference.
#[test]
fn compare_engine_lammps_refuses_what_it_cannot_do() {
    let tmp = tempfile::tempdir().unwrap();
    let case = tiny_case(tmp.path());
    let micro = common::root().join("cases/micro/glass-head-on.toml");
    for (case, args, needle) in [
        (
            case.source.clone(),
            vec!["--engine", "lammps", "--reference-mode", "recorded"],
            "--reference-mode recorded",
        ),
        (
            micro,
            vec!["--engine", "lammps"],
            "compared against LIGGGHTS 3.8",
        ),
        (
            case.source.clone(),
            vec!["--engine", "native"],
            "--engine names the reference",
        ),
    ] {
        let o = common::granval()
            .arg("compare")
            .arg(&case)
            .args(&args)
            .arg("--report")
            .arg(tmp.path().join("report"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!tmp.path().join("report").join("tiny").exists());
    }
}

/// `granval compare --engine lammps` on the tiny case (two beds of 300 grains): LAMMPS
/// 2025 runs each bed from the natively prepared grains, its force file goes through the
/// LIGGGHTS binner into the same FDR, K_phi and distance checks, with its provenance
/// and a run seal that names LAMMPS. The verdict itself is not asserted (two tiny beds,
/// and the tiny case has rolling resistance that the LAMMPS deck lacks): what is
/// asserted is that the comparison is made against LAMMPS and says so.
#[test]
fn compare_engine_lammps_judges_the_native_engine_against_lammps() {
    let test = "compare --engine lammps";
    if !common::lammps3d_live(test) {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("tiny.toml");
    std::fs::write(
        &path,
        common::tiny_penetration_toml(0.010, "", "\n[ensemble]\nbeds = 2\n"),
    )
    .unwrap();
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
    let runs = json["runs"].as_array().unwrap();
    assert_eq!(runs[0]["reference_engine"], "LAMMPS", "{text}");
    assert!(
        runs[0]["reference_version"]
            .as_str()
            .unwrap()
            .contains("22 Jul 2025"),
        "{text}"
    );
    let checks = json["checks"].as_array().unwrap();
    let k_phi = checks
        .iter()
        .find(|c| c["gate"] == "k_phi")
        .unwrap_or_else(|| panic!("no K_phi check: {text}"));
    eprintln!("[{test}] {k_phi}");
    assert!(
        checks
            .iter()
            .any(|c| c["name"].as_str().unwrap().contains("FDR distance")),
        "{text}"
    );
    let case_dir = report.join("tiny");
    for k in 0..2 {
        let dir = case_dir.join(format!("bed-{k}")).join("lammps");
        assert!(dir.join(FORCE_FILE).exists(), "{}", dir.display());
        let prov = std::fs::read_to_string(dir.join("provenance.json")).unwrap();
        assert!(
            prov.contains("\"engine\": \"lammps\"") && prov.contains("22 Jul 2025"),
            "{prov}"
        );
    }
    let seal = std::fs::read_to_string(case_dir.join("run-seal.json")).unwrap();
    assert!(seal.contains("\"reference_engine\": \"lammps\""), "{seal}");
    let summary = std::fs::read_to_string(case_dir.join("summary.json")).unwrap();
    assert!(
        summary.contains("\"lammps\"") && !summary.contains("\"liggghts\""),
        "{summary}"
    );
    assert!(case_dir.join("fdr_lammps.csv").exists());

    // `granval agreement` on this run alone: its pair native / LAMMPS is the run's own
    // K_phi gate, value and verdict, and the exit code says the verdict. The same run
    // with one per-bed K_phi edited in its summary is refused (exit 2: the summary differs from its seal).
    let chaos = common::root().join("docs/data/chaos/ci-seeds-20261200.json");
    let agree = |runs: &Path, out: &str| {
        common::granval()
            .arg("agreement")
            .arg(&path)
            .arg("--runs")
            .arg(runs)
            .arg("--chaos")
            .arg(&chaos)
            .arg("--report")
            .arg(tmp.path().join(out))
            .output()
            .unwrap()
    };
    let o = agree(&report, "agreement");
    let aj: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(tmp.path().join("agreement/report.json")).unwrap(),
    )
    .unwrap_or_else(|e| panic!("[{test}] agreement: {e}\n{}", common::text(&o)));
    let pairs = aj["checks"].as_array().unwrap();
    assert_eq!(pairs.len(), 1, "{aj}");
    assert!(
        pairs[0]["name"]
            .as_str()
            .unwrap()
            .ends_with("K_phi native / lammps"),
        "{aj}"
    );
    assert_eq!(pairs[0]["value"], k_phi["value"], "{aj}\n{k_phi}");
    assert_eq!(pairs[0]["status"], k_phi["status"], "{aj}\n{k_phi}");
    let code = match k_phi["status"].as_str().unwrap() {
        "pass" => 0,
        "fail" => 1,
        _ => 2,
    };
    assert_eq!(o.status.code(), Some(code), "{}", common::text(&o));
    let md = std::fs::read_to_string(tmp.path().join("agreement/report.md")).unwrap();
    assert!(
        md.contains("Codes against chaos") && md.contains("| native / lammps | 2 |"),
        "{md}"
    );
    let edited = summary.replacen(
        "\"k_phi_beds\": [\n",
        "\"k_phi_beds\": [\n      1.5e1,\n",
        1,
    );
    assert_ne!(edited, summary);
    std::fs::write(case_dir.join("summary.json"), edited).unwrap();
    common::expect(
        &agree(&report, "agreement2"),
        2,
        &["summary.json: content differs from its seal"],
    );
}

/// `granval deck --engine lammps`, LAMMPS run by hand in each bed directory as its README
/// says, then `granval analyze`: the report is `compare --engine lammps`'s, check for
/// check (same beds, same LAMMPS, one core: the same numbers). A bed directory brought
/// back with an edited data file, or with its force file cut short, is refused (exit 2),
/// naming the file.
#[test]
fn analyze_reads_a_lammps_deck_directory_run_by_hand() {
    let test = "analyze LAMMPS deck";
    if !common::lammps3d_live(test) {
        return;
    }
    let lmp = granval::engines::lammps3d::binary().unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("tiny.toml");
    std::fs::write(
        &path,
        common::tiny_penetration_toml(0.010, "", "\n[ensemble]\nbeds = 2\n"),
    )
    .unwrap();
    let deck = tmp.path().join("deck");
    // Written with a visualisation dump, which the decks declare: analyze still takes
    // them as granval's own (the dump changes what is written, not what is computed).
    let o = common::granval()
        .args(["deck", "--engine", "lammps", "--viz", "100"])
        .arg(&path)
        .arg("-o")
        .arg(&deck)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let readme = std::fs::read_to_string(deck.join("README.md")).unwrap();
    assert!(
        readme.contains("granval analyze DIR")
            && readme.contains(FORCE_FILE)
            && readme.contains("## Visualisation"),
        "{readme}"
    );
    for k in 0..2 {
        let dir = deck.join(format!("bed-{k}"));
        assert!(dir.join("inputs.json").exists());
        let st = std::process::Command::new(&lmp)
            .args([
                "-in",
                lp::DECK_FILE,
                "-log",
                "log.lammps",
                "-screen",
                "none",
            ])
            .current_dir(&dir)
            .status()
            .unwrap();
        assert!(st.success(), "[{test}] LAMMPS in {}", dir.display());
        let head = std::fs::read_to_string(dir.join("viz-0.lammpstrj")).unwrap();
        assert!(head.contains("ITEM: ATOMS id type radius x y z"), "{head}");
    }
    let analyzed = tmp.path().join("analyzed");
    let o = common::granval()
        .arg("analyze")
        .arg(&deck)
        .arg("--report")
        .arg(&analyzed)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    let read = |dir: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap())
            .unwrap_or_else(|e| panic!("[{test}] {}: {e}\n{err}", dir.display()))
    };
    let a = read(&analyzed);
    assert_eq!(a["runs"][0]["reference_engine"], "LAMMPS", "{a}");
    let compared = tmp.path().join("compared");
    let o = common::granval()
        .arg("compare")
        .arg(&path)
        .args(["--engine", "lammps", "--report"])
        .arg(&compared)
        .output()
        .unwrap();
    assert!(o.status.code().is_some());
    let c = read(&compared);
    let values = |r: &serde_json::Value| -> Vec<(String, String)> {
        r["checks"]
            .as_array()
            .unwrap()
            .iter()
            .map(|k| (k["name"].to_string(), k["value"].to_string()))
            .collect()
    };
    assert!(!values(&a).is_empty());
    assert_eq!(values(&a), values(&c), "[{test}] analyze vs compare");
    eprintln!("[{test}] analyze = compare: {:?}", values(&a));
    // Negative controls: an edited data file, a force file cut short.
    let bed0 = deck.join("bed-0");
    let data = std::fs::read_to_string(bed0.join(lp::DATA_FILE)).unwrap();
    let edited = data.replacen(" 2.5e3 ", " 2.6e3 ", 1);
    assert_ne!(edited, data);
    std::fs::write(bed0.join(lp::DATA_FILE), &edited).unwrap();
    let o = common::granval()
        .arg("analyze")
        .arg(&deck)
        .arg("--report")
        .arg(tmp.path().join("edited"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains(lp::DATA_FILE), "{err}");
    std::fs::write(bed0.join(lp::DATA_FILE), &data).unwrap();
    let force = std::fs::read_to_string(bed0.join(FORCE_FILE)).unwrap();
    let cut: Vec<&str> = force.lines().collect();
    std::fs::write(
        bed0.join(FORCE_FILE),
        cut[..cut.len() - 3].join("\n") + "\n",
    )
    .unwrap();
    let o = common::granval()
        .arg("analyze")
        .arg(&deck)
        .arg("--report")
        .arg(tmp.path().join("cut"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains(FORCE_FILE) && err.contains("lines"), "{err}");
}
