//! The release suite's status table (docs/release.md, "Status of every claim") is
//! generated from the digests of the reports that judged its cases: the committed table
//! must be what its files make, a changed digest or changed rules must change it, and
//! every release case and claim must have a row.

use granval::experiments::release_status::{
    self as rs, CurrentRules, DIGEST_DIR, DOC_FILE, ROWS_FILE,
};
use std::path::{Path, PathBuf};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The files the table is made from, copied into a scratch repository.
fn scratch() -> tempfile::TempDir {
    let t = tempfile::tempdir().unwrap();
    copy_dir(&repo().join("cases"), &t.path().join("cases"));
    copy_dir(&repo().join(DIGEST_DIR), &t.path().join(DIGEST_DIR));
    for f in [ROWS_FILE, DOC_FILE] {
        let to = t.path().join(f);
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(repo().join(f), to).unwrap();
    }
    t
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let p = e.path();
        if p.is_dir() {
            copy_dir(&p, &to.join(e.file_name()));
        } else {
            std::fs::copy(&p, to.join(e.file_name())).unwrap();
        }
    }
}

fn spliced(root: &Path) -> (String, String) {
    let doc = std::fs::read_to_string(root.join(DOC_FILE)).unwrap();
    let section = rs::generate(root).unwrap();
    let new = rs::splice(&doc, &section).unwrap();
    (doc, new)
}

/// The committed table is what `granval release table` makes of the committed rows and
/// digests (the fix when this fails: run `granval release table` and commit).
#[test]
fn the_committed_status_table_is_up_to_date() {
    let (doc, new) = spliced(&repo());
    assert!(
        doc == new,
        "docs/release.md's status table is stale: run `granval release table` and commit it"
    );
}

/// Negative controls of the staleness test: a digest whose value moved changes the
/// table, and so does a case whose rules changed after its digest (it is then shown
/// as stale, not with the old verdict).
#[test]
fn a_moved_value_or_changed_rules_make_the_table_stale() {
    let t = scratch();
    let (doc, new) = spliced(t.path());
    assert_eq!(doc, new, "the scratch copy starts up to date");

    // One value of one digest moved.
    let dir = t.path().join(DIGEST_DIR);
    let first = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .min()
        .expect("at least one digest is committed");
    let mut d: rs::Digest =
        serde_json::from_str(&std::fs::read_to_string(&first).unwrap()).unwrap();
    let c = d
        .checks
        .iter_mut()
        .find(|c| c.value.is_finite())
        .expect("a digest with a finite value");
    c.value += 1.0;
    let name = d.name.clone();
    std::fs::write(&first, serde_json::to_string_pretty(&d).unwrap()).unwrap();
    let (_, moved) = spliced(t.path());
    assert_ne!(moved, doc, "a moved value must change the table");

    // The same case's rules changed (a value of its case file): shown as stale.
    let case_file = std::fs::read_dir(t.path().join("cases/release"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| {
            std::fs::read_to_string(p)
                .unwrap()
                .contains(&format!("name = \"{name}\""))
        })
        .expect("the digest's case file");
    let text = std::fs::read_to_string(&case_file).unwrap();
    std::fs::write(
        &case_file,
        format!("{text}\n[changed_after_the_run]\nx = 1\n"),
    )
    .unwrap();
    let (_, stale) = spliced(t.path());
    assert!(
        stale.contains(&format!("{name}: stale (its rules changed")),
        "a case whose rules changed after its digest must be shown as stale"
    );
}

/// A release case in no row is refused by name, as is a row naming no such case.
#[test]
fn every_release_case_and_claim_has_a_row() {
    let t = scratch();
    let rows_path = t.path().join(ROWS_FILE);
    let text = std::fs::read_to_string(&rows_path).unwrap();
    let rules = CurrentRules::read(t.path(), "release").unwrap();
    rs::read_rows(&rows_path, &rules).expect("the committed rows cover the suite");

    let without = text.replace(
        "cases = [\"triaxial-table2\"]",
        "cases = [\"triaxial-table2-typo\"]",
    );
    assert_ne!(without, text, "the rows name triaxial-table2");
    std::fs::write(&rows_path, &without).unwrap();
    let e = format!("{:#}", rs::read_rows(&rows_path, &rules).unwrap_err());
    assert!(
        e.contains("triaxial-table2-typo") && e.contains("not a case"),
        "{e}"
    );

    let dropped = text.replace("cases = [\"triaxial-table2\"]\n", "");
    std::fs::write(&rows_path, &dropped).unwrap();
    let e = format!("{:#}", rs::read_rows(&rows_path, &rules).unwrap_err());
    assert!(
        e.contains("case \"triaxial-table2\"") && e.contains("no row holds"),
        "{e}"
    );
}

/// Every committed digest is of a case or claim of today's suite and is in its own file.
#[test]
fn committed_digests_read_back() {
    let digests = rs::read_digests(&repo().join(DIGEST_DIR)).unwrap();
    let rules = CurrentRules::read(&repo(), "release").unwrap();
    for ((holder, name), d) in &digests {
        let known = match holder.as_str() {
            "case" => rules.cases.contains_key(name),
            "claim" => rules.claims.contains_key(name),
            _ => false,
        };
        assert!(
            known,
            "digest of {holder} {name:?}: not in the release suite"
        );
        assert!(!d.checks.is_empty(), "digest of {name:?} holds no check");
    }
}

/// The release gate over the digests (`granval release gate`): a judged case whose
/// every finding is registered holds; moving one pinned interval, or dropping one
/// expectation, is a change (exit 1); an unknown name is refused.
#[test]
fn the_gate_over_the_digests_holds_as_registered_and_fails_on_a_moved_pin() {
    let case = "kondic-fig29-per-depth-4beds".to_string();
    let (text, code) = rs::gate_of_digests(&repo(), std::slice::from_ref(&case)).unwrap();
    assert_eq!(code, 0, "{text}");
    assert!(text.contains(": PASS"), "{text}");
    assert!(
        text.contains("6 registered finding(s) as expected, 0 change(s)"),
        "{text}"
    );

    let suite = Path::new("cases/suites/release.toml");
    let original = std::fs::read_to_string(repo().join(suite)).unwrap();
    let pin = "interval = [0.354, 0.8656]";
    assert_eq!(
        original.matches(pin).count(),
        2,
        "the two engines' depth-1 pins"
    );

    let moved = scratch();
    // The native depth-1 finding pinned where it was not found: value and interval.
    let native = "value = 0.6097852796187895\ninterval = [0.354, 0.8656]";
    assert!(original.contains(native));
    let text_moved = original.replacen(native, "value = 0.95\ninterval = [0.9, 1.0]", 1);
    std::fs::write(moved.path().join(suite), text_moved).unwrap();
    let (text, code) = rs::gate_of_digests(moved.path(), std::slice::from_ref(&case)).unwrap();
    assert_eq!(code, 1, "{text}");
    assert!(text.contains("outside the pinned interval"), "{text}");
    assert!(text.contains(": FAIL"), "{text}");

    let dropped = scratch();
    let start = original
        .find("check = \"kondic-fig29-per-depth-4beds: claim (lammps)")
        .unwrap();
    let block = original[..start].rfind("[[expect]]").unwrap();
    let end = block + original[block..].find("found = ").unwrap();
    let end = end + original[end..].find('\n').unwrap() + 1;
    let text_dropped = format!("{}{}", &original[..block], &original[end..]);
    std::fs::write(dropped.path().join(suite), text_dropped).unwrap();
    let (text, code) = rs::gate_of_digests(dropped.path(), std::slice::from_ref(&case)).unwrap();
    assert_ne!(code, 0, "{text}");
    assert!(
        text.contains("CHANGED kondic-fig29-per-depth-4beds: claim (lammps)"),
        "{text}"
    );

    let err = rs::gate_of_digests(&repo(), &["no-such-case".to_string()]).unwrap_err();
    assert!(err.to_string().contains("no-such-case"), "{err}");
}
