//! `granval deck` / `granval analyze` and the streaming FDR reduction: deck directories
//! hold the exact bed, analysis of a LIGGGHTS run of a deck reproduces `compare`, and the
//! full-size Feng deck starts under mpirun.

mod common;

use granval::analysis::fdr::{self, FdrBinner, Scales};
use granval::case::penetration::PenetrationCase;
use granval::experiments::penetration::{Penetration, bed as pen, deck_dir};
use granval::experiments::{BedBy, Options, RefMode, runner};
use granval::rundata::provenance::EngineKind;
use std::path::Path;
use std::process::Command;

use common::root;

/// Live LIGGGHTS, or a loud skip — never a silent one, and never in CI (where
/// GRANVAL_REQUIRE_LIVE=1 turns a missing LIGGGHTS into a failure).
fn liggghts_or_skip(test: &str) -> bool {
    let live = common::live(EngineKind::Liggghts, test);
    if !live {
        common::engineless(test, "SKIPPED: `liggghts` is not installed");
    }
    live
}

/// A 300-grain bed (E above LIGGGHTS' 5e6 Pa floor), two beds, written to `dir`.
fn tiny_case(dir: &Path) -> PenetrationCase {
    let text = std::fs::read_to_string(root().join("tests/data/penetration-tiny.toml")).unwrap();
    let path = dir.join("tiny.toml");
    std::fs::write(&path, text + "\n[ensemble]\nbeds = 2\n").unwrap();
    PenetrationCase::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn binner_applies_eq5_and_memory_does_not_grow_with_samples() {
    let scales = Scales {
        rho_g: 2500.0,
        psi: 0.6,
        g: 9.81,
        radius: 0.01,
    };
    let f_scale = 2500.0 * 0.6 * 9.81 * std::f64::consts::PI * 1e-6;
    let surface = 0.05;
    let mut b = FdrBinner::new(&scales, surface, 0.01).unwrap();
    // p = 20 h + 3 sampled 1e6 times over h in [-0.2, 2): the bins, not the samples,
    // set the size of what is kept.
    let n = 1_000_000;
    for k in 0..n {
        let h = -0.2 + 2.2 * k as f64 / n as f64;
        b.push(surface - h * 0.01, (20.0 * h + 3.0) * f_scale)
            .unwrap();
    }
    let f = b.fdr();
    assert_eq!(b.samples(), n as u64);
    assert_eq!(f.h.len(), 200, "one point per bin of h in [0, 2)");
    let fit = fdr::steady_state_fit(&f, 0.5, f64::INFINITY).unwrap();
    assert!((fit.k_phi - 20.0).abs() < 1e-9, "K = {}", fit.k_phi);
    assert!((fit.p0 - 3.0).abs() < 1e-9, "p0 = {}", fit.p0);
    assert!(b.push(f64::NAN, 1.0).is_err());
    assert!(FdrBinner::new(&scales, surface, 0.0).is_err());
}

/// Sec. 3's quasi-static check compares the native K_phi at two speeds bed by bed
/// (docs/statistics.md: an equivalence test on the per-bed ln K(v2)/K(v1)): it passes
/// for the same force-depth relation, fails for one whose K_phi really differs (the
/// check's own negative control; `granval check --suite ci` runs the check itself on
/// the CI case, where a control run has no second speed to fail it with) and is
/// INCONCLUSIVE on one bed, which has no bed-to-bed variance.
#[test]
fn quasi_static_check_catches_a_different_k_phi() {
    use granval::compare::Status;
    let tmp = tempfile::tempdir().unwrap();
    let case = tiny_case(tmp.path());
    let fdr_of = |k: f64| {
        let h: Vec<f64> = (0..120).map(|i| 0.005 + 0.01 * i as f64).collect();
        let p = h.iter().map(|h| k * h + 3.0).collect();
        fdr::Fdr::new(h, p).unwrap()
    };
    // Four beds whose K_phi scatter by about 1 %, as the CI beds do.
    let beds = [20.0, 20.2, 19.8, 20.1];
    let obs = |ratios: &[f64]| {
        let fdrs: Vec<fdr::Fdr> = beds
            .iter()
            .zip(ratios)
            .map(|(k, r)| fdr_of(k * r))
            .collect();
        let refs: Vec<&fdr::Fdr> = fdrs.iter().collect();
        granval::compare::penetration::ensemble(&case, &refs).unwrap_or_else(|e| panic!("{e:#}"))
    };
    let fast = obs(&[1.0; 4]);
    let same = obs(&[1.02, 1.025, 1.015, 1.02]);
    let wrong = obs(&[0.79, 0.80, 0.78, 0.79]);
    let ok = granval::compare::penetration::quasi_static(&case, &fast, &same, case.speed / 2.0);
    assert_eq!(ok.status, Status::Pass, "{ok:?}");
    let bad = granval::compare::penetration::quasi_static(&case, &fast, &wrong, case.speed);
    assert!(
        bad.status == Status::Fail && bad.gate == granval::compare::Gate::QuasiStatic,
        "{bad:?}"
    );
    let expected = [0.79f64, 0.80, 0.78, 0.79]
        .iter()
        .map(|r| r.ln())
        .sum::<f64>()
        / 4.0;
    assert!((bad.value - expected).abs() < 1e-6, "{bad:?}");
    // One bed: no bed-to-bed variance, so no verdict either way.
    let one = |r: f64| {
        granval::compare::penetration::ensemble(&case, &[&fdr_of(20.0 * r)])
            .unwrap_or_else(|e| panic!("{e:#}"))
    };
    let single =
        granval::compare::penetration::quasi_static(&case, &one(1.0), &one(0.79), case.speed);
    assert_eq!(single.status, Status::Inconclusive, "{single:?}");
}

#[test]
fn ensemble_mean_averages_members_pointwise() {
    let a = fdr::Fdr::new(vec![0.0, 1.0, 2.0], vec![0.0, 10.0, 20.0]).unwrap();
    let b = fdr::Fdr::new(vec![0.0, 1.0, 2.0], vec![2.0, 12.0, 22.0]).unwrap();
    let m = fdr::ensemble_mean(&[&a, &b], 0.1).unwrap();
    assert_eq!(m.h.len(), 20, "bin centres 0.05 .. 1.95");
    for (h, p) in m.h.iter().zip(&m.p) {
        assert!((p - (10.0 * h + 1.0)).abs() < 1e-12, "p({h}) = {p}");
    }
    let far = fdr::Fdr::new(vec![5.0, 6.0], vec![1.0, 2.0]).unwrap();
    assert!(fdr::ensemble_mean(&[&a, &far], 0.1).is_err());
}

#[test]
fn deck_directory_holds_the_exact_bed_and_a_readme() {
    let tmp = tempfile::tempdir().unwrap();
    let case = tiny_case(tmp.path());
    let out = tmp.path().join("deck");
    let dirs = deck_dir::write(&case, &out, BedBy::Native, false, None).unwrap();
    assert_eq!(dirs.len(), 2);
    for (k, d) in dirs.iter().enumerate() {
        let ck = case.realisation(k);
        let bed = pen::prepare_bed(&ck, false).unwrap();
        let back = deck_dir::read_bed(&ck, d).unwrap();
        assert_eq!(
            pen::bed_hash(&bed),
            pen::bed_hash(&back),
            "bed {k} round trip"
        );
        assert_eq!(bed.psi, back.psi);
        assert_eq!(bed.surface_z, back.surface_z);
        for f in ["in.penetration", "data.bed", "intruder.stl", "README.md"] {
            assert!(d.join(f).exists(), "{f} missing in {}", d.display());
        }
    }
    let readme = std::fs::read_to_string(out.join("README.md")).unwrap();
    assert!(readme.contains("mpirun -np N liggghts -in in.penetration"));
    assert!(readme.contains("granval analyze DIR"));
    assert!(out.join("case.toml").exists());
    // A deck directory without LIGGGHTS outputs is an error naming what is missing.
    let e = match deck_dir::analyze(&out, false, &Default::default(), &tmp.path().join("r")) {
        Ok(_) => panic!("analyze of a deck LIGGGHTS never ran must fail"),
        Err(e) => format!("{e:#}"),
    };
    assert!(e.contains("did not run here"), "{e}");
}

#[test]
fn settle_deck_pours_settles_and_places_the_intruder_in_liggghts() {
    let tmp = tempfile::tempdir().unwrap();
    let case = tiny_case(tmp.path());
    let d = pen::liggghts_settle_deck(&case).unwrap();
    let text = granval::engines::liggghts::penetration::deck_text(&d).unwrap();
    for needle in [
        "read_data data.lattice",
        "variable settle_checks index",
        "variable smoke index 0",
        // Plain notation, as every number of a deck.
        "< 0.000001\" then \"jump SELF settled\"",
        "write_dump all custom bed.dump",
        "compute ztop all reduce/region foot max v_top",
        "move 0 0 ${z0}",
        "reset_timestep 0",
        "run ${pen_steps}",
    ] {
        assert!(text.contains(needle), "deck lacks {needle:?}:\n{text}");
    }
    assert!(!text.contains("read_data data.bed"));
}

/// Runs `liggghts` in `dir` as the deck README says, with `np` ranks.
fn run_liggghts(dir: &Path, np: usize, extra: &[&str]) -> std::process::Output {
    let mut c = Command::new("mpirun");
    c.args(["--allow-run-as-root", "-np", &np.to_string()])
        .args(["liggghts", "-in", "in.penetration", "-log", "log.liggghts"])
        .args(extra)
        .current_dir(dir);
    c.output().expect("mpirun starts")
}

#[test]
fn analyze_of_a_deck_run_reproduces_compare() {
    if !liggghts_or_skip("analyze_of_a_deck_run_reproduces_compare") {
        return;
    }
    let _mpi = common::mpi_lock();
    let tmp = tempfile::tempdir().unwrap();
    // With a negative control, so that analyze is seen to run it as compare does.
    let case = {
        let c = tiny_case(tmp.path());
        let text = std::fs::read_to_string(&c.source).unwrap()
            + "\n[[negative_control]]\nname = \"mu_gg = 0.1\"\nmust_fail = [\"k_phi\"]\nperturbation = { pair_friction = { types = [1, 1], value = 0.1 } }\n";
        std::fs::write(&c.source, text).unwrap();
        PenetrationCase::load(&c.source).unwrap_or_else(|e| panic!("{e}"))
    };
    assert_eq!(case.negative_controls.len(), 1);
    let opts = Options {
        reference_root: tmp.path().join("no-reference"),
        ref_mode: RefMode::Live,
        mpi_procs: 2,
        ..Default::default()
    };
    let cmp_dir = tmp.path().join("compare");
    let exp = Penetration::against_liggghts(case.clone(), false);
    let compared = runner::compare(&exp, &opts, &cmp_dir);
    assert!(compared.run.is_some(), "{:?}", compared.checks);
    assert!(!compared.checks.is_empty());
    assert!(
        compared.checks.iter().all(|c| !c.is_error()),
        "{:?}",
        compared.checks
    );

    let deck = tmp.path().join("deck");
    let dirs = deck_dir::write(&case, &deck, BedBy::Native, false, None).unwrap();
    for (k, d) in dirs.iter().enumerate() {
        // `granval deck` writes exactly the inputs `compare` ran (in OUT/bed-K/liggghts/);
        // the deck's header carries the date it was written, so the deck is compared as
        // LIGGGHTS reads it (comments out).
        for f in ["in.penetration", "data.bed", "intruder.stl"] {
            let a = std::fs::read_to_string(d.join(f)).unwrap();
            let b =
                std::fs::read_to_string(cmp_dir.join(format!("bed-{k}/liggghts")).join(f)).unwrap();
            let same = if f == "in.penetration" {
                granval::engines::deck_text::canonical(&a)
                    == granval::engines::deck_text::canonical(&b)
            } else {
                a == b
            };
            assert!(same, "bed-{k}/{f} differs between deck and compare");
        }
        let o = run_liggghts(d, 2, &[]);
        assert!(o.status.success(), "LIGGGHTS failed in {}", d.display());
    }
    let analyzed = deck_dir::analyze(&deck, true, &opts, &tmp.path().join("analyze")).unwrap();
    same_checks(&analyzed.checks, &compared.checks);
    assert!(
        analyzed
            .checks
            .iter()
            .any(|c| c.name.contains("negative control \"mu_gg = 0.1\"")),
        "the negative control is not in analyze's report: {:?}",
        analyzed.checks
    );
    // `granval analyze` of the `compare` output itself (LIGGGHTS outputs in
    // OUT/bed-K/liggghts/) gives the same report too.
    let again =
        deck_dir::analyze(&cmp_dir, true, &opts, &tmp.path().join("analyze-compare")).unwrap();
    same_checks(&again.checks, &compared.checks);
}

fn same_checks(analyzed: &[granval::compare::Check], compared: &[granval::compare::Check]) {
    assert_eq!(analyzed.len(), compared.len());
    for (a, c) in analyzed.iter().zip(compared) {
        assert_eq!(a.name, c.name);
        assert_eq!(a.passed, c.passed, "{}", a.name);
        let same = (a.value.is_nan() && c.value.is_nan())
            || (a.value - c.value).abs() <= 1e-12 * c.value.abs().max(1e-300);
        assert!(
            same,
            "{}: analyze {} vs compare {}",
            a.name, a.value, c.value
        );
        eprintln!("{}: {} = {:.6} (both)", a.name, a.metric, a.value);
    }
}

#[test]
fn full_size_d2mm_deck_starts_under_mpirun() {
    if !liggghts_or_skip("full_size_d2mm_deck_starts_under_mpirun") {
        return;
    }
    let _mpi = common::mpi_lock();
    let case = PenetrationCase::load(&root().join("cases/penetration/feng-table2-d2mm.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    let tmp = tempfile::tempdir().unwrap();
    let dirs = deck_dir::write(&case, tmp.path(), BedBy::Liggghts, false, None).unwrap();
    let d = &dirs[0];
    // 100 settling steps, then every later command (bed dump, intruder placement, mesh,
    // move, force output) with 100 penetration steps.
    let o = run_liggghts(
        d,
        2,
        &[
            "-var",
            "smoke",
            "1",
            "-var",
            "settle_checks",
            "2",
            "-var",
            "pen_steps",
            "100",
        ],
    );
    let log = std::fs::read_to_string(d.join("log.liggghts")).unwrap_or_default();
    assert!(
        o.status.success() && !log.contains("ERROR"),
        "full-size deck failed:\n{}",
        &log[log.len().saturating_sub(3000)..]
    );
    assert!(log.contains("460000 atoms"), "bed size not in log");
    let bed = granval::engines::liggghts::penetration::parse_bed_dump(
        &d.join("bed.dump"),
        granval::engines::liggghts::penetration::Units::Si,
        case.density,
    )
    .unwrap();
    assert_eq!(bed.len(), 460_000);
    let forces = granval::engines::liggghts::penetration::parse_force_file(
        &d.join("force.txt"),
        granval::engines::liggghts::penetration::Units::Si,
    )
    .unwrap();
    assert_eq!(forces.len(), 2, "force every 50 steps over 100 steps");
    assert!((forces[1].z_bottom - forces[0].z_bottom + 50.0 * case.dt * case.speed).abs() < 1e-9);
}

/// A penetration record carries each bed its LIGGGHTS run started from, so a recorded
/// comparison takes the beds from there instead of settling them again (at G = 100 MPa
/// settling costs as much as the run); a bed is used only if the deck built from it
/// has the fingerprint the seal holds, which one ulp in one grain changes. The record
/// is lean: each bed is in the bed store under its sealed sha256, and `data.bed` is
/// left out and written again from the bed when the record is verified.
#[test]
fn records_carry_their_beds_and_a_moved_bed_changes_the_fingerprint() {
    use granval::experiments::Experiment;
    use granval::experiments::reference::{self, store as record_store};
    use granval::physics::dem::packing::Bed;
    let tmp = tempfile::tempdir().unwrap();
    let case = tiny_case(tmp.path());
    let exp = Penetration::against_liggghts(case.clone(), false);
    let reference_root = tmp.path().join("reference");
    let record = reference::record_root(&reference_root, exp.kind(), exp.name());
    let plain = exp.units(&Options::default()).unwrap();
    let fingerprints: Vec<_> = plain.iter().map(|u| exp.fingerprint(u).unwrap()).collect();
    let file_of = |k: usize| {
        reference::unit_dir(&record, &exp.unit_name(&plain[k]))
            .join(pen::bed_file_name(&plain[k].case).unwrap())
    };
    let recorded_units = || {
        exp.units(&Options {
            recorded_inputs: Some(record.clone()),
            ..Options::default()
        })
        .unwrap()
    };
    let live = liggghts_or_skip("records_carry_their_beds_and_a_moved_bed_changes_the_fingerprint");
    if live {
        let _mpi = common::mpi_lock();
        runner::refresh(
            &exp,
            &Options {
                reference_root: reference_root.clone(),
                mpi_procs: 2,
                ..Options::default()
            },
        )
        .unwrap();
        let seal: reference::Seal = serde_json::from_str(
            &std::fs::read_to_string(record.join(reference::SEAL_FILE)).unwrap(),
        )
        .unwrap();
        for (k, u) in plain.iter().enumerate() {
            let name = file_of(k)
                .file_name()
                .unwrap()
                .to_string_lossy()
                .into_owned();
            let unit = exp.unit_name(u);
            let files = &seal.units[&unit].files;
            assert!(files.contains_key(&name) && files.contains_key("data.bed"));
            let dir = reference::unit_dir(&record, &unit);
            assert!(
                !dir.join("data.bed").exists() && !dir.join(&name).exists(),
                "{}: the record is lean",
                dir.display()
            );
            // In the store by its sealed hash (compressed when large), read back as
            // the bed that was sealed.
            let in_store = record_store::stored_bed_file(&record, &files[&name]).unwrap();
            assert!(
                in_store.starts_with(reference_root.join("beds")),
                "{}",
                in_store.display()
            );
            let read = record_store::recorded_bed_file(&record, &unit, &name).unwrap();
            assert_eq!(
                granval::rundata::provenance::Sha256::of_file(&read).unwrap(),
                files[&name]
            );
        }
        let verified = runner::verify_record(
            &exp,
            &Options {
                reference_root: reference_root.clone(),
                ..Options::default()
            },
        )
        .unwrap()
        .unwrap();
        assert!(
            verified.contains("2 bed(s) from the bed store, 2 written again"),
            "{verified}"
        );
    } else {
        // The loader alone, on bed files written by hand where the record keeps them.
        for (k, u) in plain.iter().enumerate() {
            std::fs::create_dir_all(file_of(k).parent().unwrap()).unwrap();
            std::fs::write(file_of(k), serde_json::to_vec(&u.bed).unwrap()).unwrap();
        }
    }
    for (k, u) in recorded_units().iter().enumerate() {
        assert!(u.bed_from_record, "bed {k} not read from the record");
        assert_eq!(exp.fingerprint(u).unwrap(), fingerprints[k], "bed {k}");
    }
    // Where the record keeps bed 1 (the store after `refresh`); a bed in the unit's
    // directory is read first.
    let kept = record_store::recorded_bed_file(
        &record,
        &exp.unit_name(&plain[1]),
        &pen::bed_file_name(&plain[1].case).unwrap(),
    )
    .unwrap();
    let mut b: Bed = serde_json::from_slice(&std::fs::read(kept).unwrap()).unwrap();
    let x = &mut b.particles[5].x[2];
    *x = f64::from_bits(x.to_bits() + 1);
    std::fs::write(file_of(1), serde_json::to_vec(&b).unwrap()).unwrap();
    let moved = recorded_units();
    assert!(moved[1].bed_from_record);
    assert_eq!(exp.fingerprint(&moved[0]).unwrap(), fingerprints[0]);
    assert_ne!(exp.fingerprint(&moved[1]).unwrap(), fingerprints[1]);
}

/// `granval deck --viz N`: every deck dumps the grains and the intruder mesh as VTK every
/// N steps, and `inputs.json` records N, so `analyze` writes the same deck again and
/// accepts it. Negative controls: the same deck with `viz_every` taken out of its
/// `inputs.json` is refused by the rewrite check, naming `in.penetration`, and an interval
/// beyond the run is refused when the deck is written. Live LIGGGHTS: the run writes one
/// grains file per interval with every grain, and `analyze` reads the run.
#[test]
fn viz_deck_dumps_vtk_and_analyze_accepts_it_as_written() {
    let tmp = tempfile::tempdir().unwrap();
    let case = tiny_case(tmp.path());
    let n_steps = pen::liggghts_deck(
        &case.realisation(0),
        &pen::prepare_bed(&case.realisation(0), false).unwrap(),
    )
    .unwrap()
    .n_steps;
    let every = (n_steps / 4).max(1);
    let too_long = deck_dir::write(
        &case,
        &tmp.path().join("bad"),
        BedBy::Native,
        false,
        Some(n_steps + 1),
    )
    .unwrap_err();
    assert!(format!("{too_long:#}").contains("--viz"), "{too_long:#}");
    let deck = tmp.path().join("deck");
    let dirs = deck_dir::write(&case, &deck, BedBy::Native, false, Some(every)).unwrap();
    let text = std::fs::read_to_string(dirs[0].join("in.penetration")).unwrap();
    assert!(
        text.contains(&format!(
            "dump viz all custom/vtk {every} viz-grains-*.vtk id type radius x y z"
        )) && text.contains(&format!(
            "dump vizmesh all mesh/vtk {every} viz-intruder-*.vtk stress cad"
        )),
        "{text}"
    );
    let manifest = std::fs::read_to_string(dirs[0].join("inputs.json")).unwrap();
    assert!(
        manifest.contains(&format!("\"viz_every\": {every}")),
        "{manifest}"
    );
    assert!(
        std::fs::read_to_string(deck.join("README.md"))
            .unwrap()
            .contains("## Look at it")
    );
    // A deck written without --viz has no dump and no viz_every.
    let plain =
        deck_dir::write(&case, &tmp.path().join("plain"), BedBy::Native, false, None).unwrap();
    assert!(
        !std::fs::read_to_string(plain[0].join("in.penetration"))
            .unwrap()
            .contains("viz")
    );
    assert!(
        !std::fs::read_to_string(plain[0].join("inputs.json"))
            .unwrap()
            .contains("viz_every")
    );

    let opts = Options {
        reference_root: tmp.path().join("no-reference"),
        ref_mode: RefMode::Live,
        mpi_procs: 1,
        ..Default::default()
    };
    // The control: the same directory with viz_every taken out of inputs.json (every
    // fingerprint still matches) is refused by the rewrite check.
    let control = tmp.path().join("control");
    std::fs::create_dir_all(&control).unwrap();
    for e in walk(&deck) {
        let to = control.join(e.strip_prefix(&deck).unwrap());
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(&e, &to).unwrap();
    }
    for k in 0..dirs.len() {
        let m = control.join(format!("bed-{k}/inputs.json"));
        let text = std::fs::read_to_string(&m).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        let mut v = v.as_object().unwrap().clone();
        assert!(v.remove("viz_every").is_some());
        std::fs::write(&m, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    }
    let err = deck_dir::analyze(&control, false, &opts, &tmp.path().join("a-control"))
        .map(|_| ())
        .expect_err("a deck whose dump inputs.json does not declare is refused");
    assert!(format!("{err:#}").contains("in.penetration"), "{err:#}");

    if !liggghts_or_skip("viz_deck_dumps_vtk_and_analyze_accepts_it_as_written") {
        return;
    }
    let _mpi = common::mpi_lock();
    for d in &dirs {
        let o = run_liggghts(d, 1, &[]);
        assert!(
            o.status.success(),
            "LIGGGHTS failed in {}: {}",
            d.display(),
            String::from_utf8_lossy(&o.stdout)
        );
        let mut grains: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
            .filter(|n| {
                n.starts_with("viz-grains-") && n.ends_with(".vtk") && !n.contains("boundingBox")
            })
            .collect();
        grains.sort();
        assert_eq!(grains.len() as u64, n_steps / every + 1, "{grains:?}");
        let first = std::fs::read_to_string(d.join("viz-grains-0.vtk")).unwrap();
        let points = first
            .lines()
            .find(|l| l.starts_with("POINTS"))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|n| n.parse::<usize>().ok());
        assert_eq!(points, Some(300), "{}", &first[..first.len().min(400)]);
        assert!(d.join("viz-intruder-0.vtk").is_file());
        vtk_reads(d);
    }
    let analyzed = deck_dir::analyze(&deck, false, &opts, &tmp.path().join("analyze")).unwrap();
    assert!(!analyzed.checks.is_empty());
    assert!(
        analyzed.checks.iter().all(|c| !c.is_error()),
        "{:?}",
        analyzed.checks
    );
}

/// Every file under `dir`.
fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}

/// The viz files of `d` read through VTK itself (ParaView's reader) when a Python with
/// `vtkmodules` is here (Debian `python3-vtk9`): every grain with its arrays, every facet
/// of the intruder with its stress. Without one it says so and checks nothing more.
fn vtk_reads(d: &Path) {
    let Some(py) = common::vtk_python() else {
        eprintln!("viz files not read through VTK: no Python with vtkmodules");
        return;
    };
    let g = common::vtk_legacy_summary(&py, &d.join("viz-grains-0.vtk"));
    let m = common::vtk_legacy_summary(&py, &d.join("viz-intruder-0.vtk"));
    assert_eq!(g["points"], 300, "{g}");
    for a in ["f", "id", "omega", "radius", "type", "v"] {
        assert!(
            g["point_arrays"].as_array().unwrap().iter().any(|x| x == a),
            "{a}: {g}"
        );
    }
    assert!(m["cells"].as_u64().unwrap() > 0, "{m}");
    assert!(
        m["cell_arrays"]
            .as_array()
            .unwrap()
            .iter()
            .any(|x| x == "normal_stress_average"),
        "{m}"
    );
}
