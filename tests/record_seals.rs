//! Every sealed record under `reference/` verifies with the seal's full check (plain file
//! names, every digest, and the stored engine input and provenance agreeing with the
//! fingerprint), and a record whose provenance or stored deck contradicts its seal is
//! refused even though every digest in the seal matches its file.

mod common;

use granval::case::AnyCase;
use granval::experiments::penetration::{deck_dir, reduce_liggghts_dir};
use granval::experiments::{Experiment, Options, reference, suite};
use granval::with_experiment;
use std::path::{Path, PathBuf};

/// The keys a comparison would pass, taken from the seal itself: each unit's
/// fingerprint, and its engine input as the kind stores it. For micro, penetration and
/// triaxial records the fingerprint is that of the engine input; an impact2d seal holds
/// the scene's hash, and its input's fingerprint is the one its provenance names.
fn keys_from_seal(dir: &Path, kind: &str) -> Vec<reference::UnitKey> {
    use granval::engines::{lammps, lammps3d, liggghts};
    let seal: reference::Seal =
        serde_json::from_str(&std::fs::read_to_string(dir.join(reference::SEAL_FILE)).unwrap())
            .unwrap();
    seal.units
        .iter()
        .map(|(name, u)| {
            let has = |f: &str| u.files.contains_key(f);
            let input: Vec<&'static str> = match kind {
                // LIGGGHTS' deck and data file, or LAMMPS 2025's (LAMMPS-family cases)
                "micro" => [
                    liggghts::DECK_FILE,
                    "data.granval",
                    lammps3d::DECK_FILE,
                    lammps3d::DATA_FILE,
                ]
                .into_iter()
                .filter(|f| has(f))
                .collect(),
                "penetration" => {
                    use liggghts::penetration as lp;
                    let grains = if has(lp::DATA_FILE) {
                        lp::DATA_FILE
                    } else {
                        liggghts::clump_bed::BODIES_FILE
                    };
                    vec![lp::DECK_FILE, grains, lp::STL_FILE]
                }
                "triaxial" => {
                    use liggghts::triaxial as lt;
                    [lt::DECK_FILE, lt::DATA_FILE]
                        .into_iter()
                        .chain(lt::STL_FILES)
                        .collect()
                }
                "impact2d" => vec![lammps::DECK_FILE, lammps::DATA_FILE],
                k => panic!("kind {k}"),
            };
            let input_hash = if kind == "impact2d" {
                let p = granval::rundata::provenance::read_provenance(
                    &reference::unit_dir(dir, name).join(reference::PROVENANCE_FILE),
                )
                .unwrap();
                assert!(
                    p.notes
                        .iter()
                        .any(|n| n == &format!("scene sha256 {}", u.fingerprint)),
                    "{}: the provenance names another scene",
                    dir.display()
                );
                p.input_hash
            } else {
                u.fingerprint.clone()
            };
            reference::UnitKey {
                name: name.clone(),
                fingerprint: u.fingerprint.clone(),
                input,
                input_hash,
            }
        })
        .collect()
}

/// Every sealed record under `reference/` (each case of each suite, under the suite's
/// reference root) passes the full seal check against its case, with the keys its seal
/// implies (`keys_from_seal`; building the units themselves would settle beds the older
/// records do not store). The comparisons' own keys are exercised by the tests that
/// compare against records.
#[test]
fn every_record_verifies_with_its_engine_input_and_provenance() {
    let cases = common::root().join("cases");
    let mut checked = 0;
    for name in suite::names(&cases) {
        let s = suite::load(&cases, &name).unwrap_or_else(|e| panic!("{name}: {e:#}"));
        let reference_root = s.reference_root(&common::root().join("reference"));
        for e in &s.cases {
            let c = AnyCase::load(&e.path).unwrap_or_else(|e| panic!("{e}"));
            with_experiment!(c, false, |exp| {
                let root = reference::record_root(&reference_root, exp.kind(), exp.name());
                if root.join(reference::SEAL_FILE).exists() {
                    if holds_its_beds(&root) {
                        // A lean record: its units are built from the beds it holds
                        // (cheap), and the data files it leaves out are written again
                        // from them and checked.
                        verify_lean(&exp, &root)
                            .unwrap_or_else(|err| panic!("{}: {err:#}", root.display()));
                    } else {
                        reference::verify(
                            &root,
                            exp.source(),
                            &exp.canonical_hash(),
                            exp.reference_engine(),
                            &keys_from_seal(&root, exp.kind()),
                            // Records without their beds hold every file.
                            &granval::experiments::reference::store::nothing_regenerable,
                        )
                        .unwrap_or_else(|err| panic!("{}: {err:#}", root.display()));
                    }
                    checked += 1;
                }
            });
        }
    }
    assert!(checked >= 50, "only {checked} records verified");
}

/// Whether the record at `root` holds the beds its reference runs started from (only
/// such records leave data files out: `granval reference lean`).
fn holds_its_beds(root: &Path) -> bool {
    let seal: reference::Seal =
        serde_json::from_str(&std::fs::read_to_string(root.join(reference::SEAL_FILE)).unwrap())
            .unwrap();
    // A bed shared by several units (a seed ensemble) is sealed once, with the first
    // unit that uses it, so one unit holding a bed makes the record lean.
    seal.units
        .values()
        .any(|u| u.files.keys().any(|f| reference::store::is_bed_file(f)))
}

/// Verifies a record that holds its beds as a recorded comparison does: units from
/// those beds, left-out data files written again and checked.
fn verify_lean<E: Experiment>(exp: &E, root: &Path) -> anyhow::Result<reference::Verified> {
    let units = exp.units(&Options {
        recorded_inputs: Some(root.to_path_buf()),
        ..Options::default()
    })?;
    let keys = reference::unit_keys(exp, &units)?;
    let names: Vec<String> = units.iter().map(|u| exp.unit_name(u)).collect();
    reference::verify(
        root,
        exp.source(),
        &exp.canonical_hash(),
        exp.reference_engine(),
        &keys,
        &granval::experiments::runner::regenerator(exp, &units, &names),
    )
}

/// Verifies the record of `case` under `reference_root` as `compare` does.
fn verify_record(case: &Path, reference_root: &Path) -> anyhow::Result<()> {
    let c = AnyCase::load(case).unwrap_or_else(|e| panic!("{e}"));
    with_experiment!(c, false, |exp| {
        let root = reference::record_root(reference_root, exp.kind(), exp.name());
        let units = exp.units(&Options::default())?;
        let keys = reference::unit_keys(&exp, &units)?;
        let names: Vec<String> = units.iter().map(|u| exp.unit_name(u)).collect();
        reference::verify(
            &root,
            exp.source(),
            &exp.canonical_hash(),
            exp.reference_engine(),
            &keys,
            &granval::experiments::runner::regenerator(&exp, &units, &names),
        )
        .map(|_| ())
    })
}

/// A copy of one micro record, re-sealed after an edit, so that every digest matches:
/// what only the engine-input check can catch.
fn resealed_copy(edit: impl Fn(&Path)) -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let src = common::root().join("reference/micro/head-on-e05");
    let dst = tmp.path().join("micro/head-on-e05");
    std::fs::create_dir_all(&dst).unwrap();
    for e in std::fs::read_dir(&src).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), dst.join(e.file_name())).unwrap();
    }
    edit(&dst);
    let mut seal: reference::Seal =
        serde_json::from_str(&std::fs::read_to_string(dst.join(reference::SEAL_FILE)).unwrap())
            .unwrap();
    for u in seal.units.values_mut() {
        for (f, h) in u.files.iter_mut() {
            *h = granval::rundata::provenance::Sha256::of_file(&dst.join(f)).unwrap();
        }
    }
    std::fs::write(
        dst.join(reference::SEAL_FILE),
        serde_json::to_string_pretty(&seal).unwrap(),
    )
    .unwrap();
    let case = common::root().join("cases/micro/head-on-e05.toml");
    (tmp, case)
}

#[test]
fn a_provenance_or_stored_deck_contradicting_the_seal_is_refused() {
    // Negative control: the re-sealed copy without an edit verifies.
    let (tmp, case) = resealed_copy(|_| {});
    verify_record(&case, tmp.path()).unwrap();

    let (tmp, case) = resealed_copy(|d| {
        let p = d.join("provenance.json");
        let text = std::fs::read_to_string(&p).unwrap();
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        v["input_hash"] = serde_json::Value::String("ab".repeat(32));
        std::fs::write(&p, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    });
    let e = format!("{:#}", verify_record(&case, tmp.path()).unwrap_err());
    assert!(
        e.contains("provenance.json") && e.contains("contradicts the seal"),
        "{e}"
    );

    // The deck edited (restitution of the only pair): the digests match after resealing,
    // the stored input does not.
    let (tmp, case) = resealed_copy(|d| {
        let p = d.join("in.granval");
        let text = std::fs::read_to_string(&p).unwrap();
        let edited = text.replacen(
            "coefficientRestitution peratomtypepair 2 0.5 0.5 0.5 0.5",
            "coefficientRestitution peratomtypepair 2 0.6 0.6 0.6 0.6",
            1,
        );
        assert_ne!(edited, text, "the deck names the restitution");
        std::fs::write(&p, edited).unwrap();
    });
    let e = format!("{:#}", verify_record(&case, tmp.path()).unwrap_err());
    assert!(
        e.contains("stored in the record") && e.contains("contradicts the seal"),
        "{e}"
    );
}

#[test]
fn a_seal_entry_outside_the_record_is_refused_before_it_is_opened() {
    let (tmp, case) = resealed_copy(|_| {});
    let dst = tmp.path().join("micro/head-on-e05");
    let text = std::fs::read_to_string(dst.join(reference::SEAL_FILE)).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    // The digest of the file it names, so only the name is wrong.
    let passwd = granval::rundata::provenance::Sha256::of_file(Path::new("/etc/passwd"))
        .map(|h| h.to_string())
        .unwrap_or_else(|_| "00".repeat(32));
    v["units"][""]["files"]["../../../../etc/passwd"] = serde_json::Value::String(passwd);
    std::fs::write(
        dst.join(reference::SEAL_FILE),
        serde_json::to_string_pretty(&v).unwrap(),
    )
    .unwrap();
    let e = format!("{:#}", verify_record(&case, tmp.path()).unwrap_err());
    assert!(
        e.contains("\"../../../../etc/passwd\" is not a plain file name"),
        "{e}"
    );
}

/// Every penetration record's outputs are of its own deck, as `analyze` now demands of
/// a run directory: its log echoes the deck (title, then every command in order), its
/// force file carries the deck's title and its intruder follows the deck's start and
/// speed (within 1e-7 of z0; the records stay below 2e-11).
#[test]
fn every_penetration_record_holds_the_outputs_of_its_own_deck() {
    let cases = common::root().join("cases");
    let mut n = 0;
    for name in suite::names(&cases) {
        let s = suite::load(&cases, &name).unwrap();
        let rr = s.reference_root(&common::root().join("reference"));
        for e in &s.cases {
            let Ok(AnyCase::Penetration(c)) = AnyCase::load(&e.path) else {
                continue;
            };
            let root = reference::record_root(&rr, "penetration", &c.name);
            if !root.join(reference::SEAL_FILE).exists() {
                continue;
            }
            // A lean record leaves its data files out and keeps large files
            // compressed: its beds come from the bed files it holds, its outputs from
            // the unit directories the seal gives back. A record without beds may be
            // compressed too: its files (data file included) come back the same way.
            let compressed = (!holds_its_beds(&root)).then(|| {
                let exp = granval::experiments::penetration::Penetration::against_liggghts(
                    c.clone(),
                    false,
                );
                reference::verify(
                    &root,
                    exp.source(),
                    &exp.canonical_hash(),
                    exp.reference_engine(),
                    &keys_from_seal(&root, "penetration"),
                    &granval::experiments::reference::store::nothing_regenerable,
                )
                .unwrap_or_else(|err| panic!("{}: {err:#}", root.display()))
            });
            let lean = (!root.join("bed-0").join("data.bed").exists() && holds_its_beds(&root))
                .then(|| {
                    let exp = granval::experiments::penetration::Penetration::against_liggghts(
                        c.clone(),
                        false,
                    );
                    let v = verify_lean(&exp, &root).unwrap();
                    let units = exp
                        .units(&Options {
                            recorded_inputs: Some(root.clone()),
                            ..Options::default()
                        })
                        .unwrap();
                    (v, units)
                });
            for k in 0..c.ensemble_beds {
                let ck = c.realisation(k);
                let (d, bed) = match &lean {
                    Some((v, units)) => (
                        v.unit_files(&format!("bed-{k}")).unwrap(),
                        units[k].bed.clone(),
                    ),
                    None => {
                        let d = match &compressed {
                            Some(v) => v.unit_files(&format!("bed-{k}")).unwrap(),
                            None => root.join(format!("bed-{k}")),
                        };
                        let bed = deck_dir::read_bed(&ck, &d).unwrap();
                        (d, bed)
                    }
                };
                reduce_liggghts_dir(&ck, &bed, &d)
                    .unwrap_or_else(|e| panic!("{}: {e:#}", d.display()));
                n += 1;
            }
        }
    }
    assert!(n >= 60, "{n} beds");
}

/// Real LIGGGHTS outputs of the CI record, swapped between beds: bed 1's force file or
/// log in bed 0's directory is refused (another bed's intruder start; another seed's
/// title), and so is a force file written with another title; bed 0's own outputs (the
/// negative control) reduce.
#[test]
fn outputs_of_another_bed_are_refused_not_reduced() {
    use granval::engines::liggghts::penetration as lp;
    let c = match AnyCase::load(&common::root().join("cases/penetration/ci.toml")).unwrap() {
        AnyCase::Penetration(c) => c,
        _ => panic!(),
    };
    let rec = common::root().join("reference/penetration/penetration-ci");
    let ck = c.realisation(0);
    let copy = |swap: &str| {
        let tmp = tempfile::tempdir().unwrap();
        for e in std::fs::read_dir(rec.join("bed-0")).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), tmp.path().join(e.file_name())).unwrap();
        }
        if !swap.is_empty() {
            std::fs::copy(rec.join("bed-1").join(swap), tmp.path().join(swap)).unwrap();
        }
        tmp
    };
    let reduce = |d: &Path| {
        let bed = deck_dir::read_bed(&ck, d).unwrap();
        reduce_liggghts_dir(&ck, &bed, d).map(|_| ())
    };
    reduce(copy("").path()).unwrap();
    let e = format!("{:#}", reduce(copy(lp::FORCE_FILE).path()).unwrap_err());
    assert!(
        e.contains("force.txt") && e.contains("the force file is of another bed"),
        "{e}"
    );
    let e = format!("{:#}", reduce(copy(lp::LOG_FILE).path()).unwrap_err());
    assert!(
        e.contains("log.liggghts") && e.contains("does not echo the title"),
        "{e}"
    );
    let d = copy("");
    let f = d.path().join(lp::FORCE_FILE);
    let text = std::fs::read_to_string(&f).unwrap();
    std::fs::write(
        &f,
        text.replacen("units SI: s, m, N", "units cgs: s, cm, dyn", 1),
    )
    .unwrap();
    let e = format!("{:#}", reduce(d.path()).unwrap_err());
    assert!(e.contains("not this run's force file"), "{e}");
}

/// A copy of the CI penetration record (three beds, no bed stored) under a temporary
/// reference root.
fn ci_record_copy() -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let src = common::root().join("reference/penetration/penetration-ci");
    let dst = tmp.path().join("penetration/penetration-ci");
    copy_tree(&src, &dst);
    (tmp, dst)
}

fn copy_tree(src: &Path, dst: &Path) {
    std::fs::create_dir_all(dst).unwrap();
    for e in std::fs::read_dir(src).unwrap() {
        let e = e.unwrap();
        let to = dst.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_tree(&e.path(), &to);
        } else {
            std::fs::copy(e.path(), to).unwrap();
        }
    }
}

/// `reference lean` (with `--add-beds` when `add_beds`) of the record of `case` under
/// `reference_root`.
fn lean_case(
    case: &Path,
    reference_root: &Path,
    add_beds: bool,
) -> anyhow::Result<Option<Vec<String>>> {
    let c = AnyCase::load(case).unwrap_or_else(|e| panic!("{e}"));
    with_experiment!(c, false, |exp| {
        granval::experiments::runner::lean_record(
            &exp,
            &Options {
                reference_root: reference_root.to_path_buf(),
                ..Options::default()
            },
            add_beds,
        )
    })
}

/// `reference lean` of a record that holds no bed only compresses: its large files
/// (force curves, engine data files) become `.zst`, nothing is left out, and the record
/// still passes the full seal check. Negative control: a copy with one byte of a force
/// curve changed is refused before anything is touched, and that file stays plain.
#[test]
fn a_record_without_beds_is_only_compressed_and_still_verifies() {
    let case = common::root().join("cases/penetration/ci.toml");
    let lean = |reference_root: &Path| lean_case(&case, reference_root, false);

    let (tmp, root) = ci_record_copy();
    let lines = lean(tmp.path()).unwrap().expect("the record exists");
    let packed: Vec<&String> = lines
        .iter()
        .filter(|l| l.contains("kept compressed"))
        .collect();
    assert!(
        packed.len() >= 6,
        "force.txt and data.bed of three beds should be compressed: {lines:#?}"
    );
    assert!(
        !lines.iter().any(|l| l.contains("left out")),
        "nothing may be left out of a record without beds: {lines:#?}"
    );
    for bed in ["bed-0", "bed-1", "bed-2"] {
        for f in ["force.txt", "data.bed"] {
            assert!(!root.join(bed).join(f).exists(), "{bed}/{f} still plain");
            assert!(root.join(bed).join(format!("{f}.zst")).is_file());
        }
    }
    let c = AnyCase::load(&case).unwrap_or_else(|e| panic!("{e}"));
    with_experiment!(c, false, |exp| {
        reference::verify(
            &root,
            exp.source(),
            &exp.canonical_hash(),
            exp.reference_engine(),
            &keys_from_seal(&root, exp.kind()),
            &granval::experiments::reference::store::nothing_regenerable,
        )
        .unwrap_or_else(|err| panic!("{}: {err:#}", root.display()));
    });

    let (bad, bad_root) = ci_record_copy();
    let force = bad_root.join("bed-1/force.txt");
    let mut bytes = std::fs::read(&force).unwrap();
    let last = bytes.len() - 2;
    bytes[last] = if bytes[last] == b'1' { b'2' } else { b'1' };
    std::fs::write(&force, &bytes).unwrap();
    let err = format!("{:#}", lean(bad.path()).unwrap_err());
    assert!(
        err.contains("force.txt") && err.contains("differs from the seal"),
        "{err}"
    );
    assert!(force.is_file() && !bad_root.join("bed-1/force.txt.zst").exists());
    assert!(!bad_root.join("bed-0/force.txt.zst").exists());
}

/// `reference lean --add-beds` on the 2D CI record (sealed without its bed): the bed is
/// prepared again, added to the seal only because the data file written from it is the
/// sealed one byte for byte, moved to the bed store, and the data file is left out; the
/// seal keeps its time and every file it held, names the bed in an amendment, and the
/// record verifies with its bed read from the store. Negative control: a copy whose data
/// file differs by one byte from the seal is refused before anything is touched (no bed
/// added, seal unchanged, data file still there).
#[test]
fn add_beds_proves_each_bed_by_the_data_file_it_writes() {
    use granval::experiments::reference::store;
    let case = common::root().join("cases/impact2d/ci.toml");
    let copy = || {
        let tmp = tempfile::tempdir().unwrap();
        let dst = tmp.path().join("impact2d/ci");
        copy_tree(&common::root().join("reference/impact2d/ci"), &dst);
        (tmp, dst)
    };
    let lean = |reference_root: &Path| lean_case(&case, reference_root, true);
    let seal_of = |root: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(root.join("seal.json")).unwrap()).unwrap()
    };

    let (tmp, root) = copy();
    let before = seal_of(&root);
    assert!(before.get("amendments").is_none());
    let lines = lean(tmp.path()).unwrap().expect("the record exists");
    let after = seal_of(&root);
    assert_eq!(after["sealed"], before["sealed"], "the sealed time is kept");
    let (old, new) = (
        &before["units"]["base"]["files"],
        &after["units"]["base"]["files"],
    );
    for (file, sha) in old.as_object().unwrap() {
        assert_eq!(&new[file], sha, "{file}: a sealed file changed");
    }
    let beds: Vec<&String> = new
        .as_object()
        .unwrap()
        .keys()
        .filter(|f| store::is_bed_file(f))
        .collect();
    assert_eq!(beds.len(), 1, "{lines:#?}");
    let added = after["amendments"][0]["added"][0].as_str().unwrap();
    assert_eq!(added, format!("base/{}", beds[0]));
    assert!(!root.join("base/data.impact2d").exists(), "{lines:#?}");
    let sha = new[beds[0]].as_str().unwrap();
    assert!(
        tmp.path().join(format!("beds/{sha}.json.zst")).is_file(),
        "the bed is in the store: {lines:#?}"
    );
    let c = AnyCase::load(&case).unwrap_or_else(|e| panic!("{e}"));
    let report = with_experiment!(c, false, |exp| {
        granval::experiments::runner::verify_record(
            &exp,
            &Options {
                reference_root: tmp.path().to_path_buf(),
                ..Options::default()
            },
        )
    })
    .unwrap_or_else(|e| panic!("{e:#}"))
    .expect("the record exists");
    assert!(
        report.contains("1 bed(s) from the bed store") && report.contains("1 written again"),
        "{report}"
    );

    let (bad, bad_root) = copy();
    let data = bad_root.join("base/data.impact2d");
    let mut bytes = std::fs::read(&data).unwrap();
    let last = bytes.len() - 2;
    bytes[last] = if bytes[last] == b'1' { b'2' } else { b'1' };
    std::fs::write(&data, &bytes).unwrap();
    let seal_before = std::fs::read(bad_root.join("seal.json")).unwrap();
    let err = format!("{:#}", lean(bad.path()).unwrap_err());
    assert!(
        err.contains("data.impact2d") && err.contains("no bed is added"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(bad_root.join("seal.json")).unwrap(),
        seal_before
    );
    assert!(data.is_file() && !bad.path().join("beds").exists());
}
