//! The release suite's registration (docs/statistics.md, "Registration"), computed from
//! its case files, its suite file, its records' seals and git only: no engine, no
//! simulation. `cargo test --test registration -- --nocapture` prints, per case and per
//! claim, registered (and by which commit) or EXPLORATORY and why.

mod common;

use granval::experiments::registration::{self, Registration, case_rules};
use granval::experiments::suite;
use std::process::Command;

fn release() -> (suite::Suite, Registration) {
    let root = common::root();
    let s = suite::load(&root.join("cases"), "release").expect("the release suite loads");
    let reg = registration::of_suite(&s, &s.reference_root(&root.join("reference")))
        .expect("registration is read")
        .expect("the release suite declares registration = \"git\"");
    (s, reg)
}

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git")
        .arg("-C")
        .arg(common::root())
        .args(args)
        .output()
        .ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

/// Prints the registration of every case and claim of the release suite, and checks it
/// against git read independently: a registered case with a record has, at the last
/// commit of its case file strictly before the seal (`git log -1 --before`), the rules it
/// has today; an EXPLORATORY one has not, or had no such commit.
#[test]
fn the_release_suite_registration_follows_from_git_and_the_seals() {
    let (s, reg) = release();
    for l in reg.lines() {
        println!("{l}");
    }
    for n in reg.notes() {
        println!("\n{n}");
    }
    assert_eq!(reg.cases.len(), s.cases.len());
    assert_eq!(reg.claims.len(), s.claims.len());
    for st in reg.cases.iter().chain(&reg.claims) {
        assert_eq!(st.rules_sha256.len(), 64, "{st:?}");
    }
    if let Some(why) = &reg.unavailable {
        // A shallow clone or no git: nothing may be marked, and the note says why.
        println!("registration not checkable here: {why}");
        assert!(
            reg.cases
                .iter()
                .chain(&reg.claims)
                .all(|s| s.exploratory.is_none())
        );
        return;
    }
    let root = common::root();
    let reference = s.reference_root(&root.join("reference"));
    let mut with_record = 0;
    for (e, st) in s.cases.iter().zip(&reg.cases) {
        let text = std::fs::read_to_string(&e.path).unwrap();
        let t: toml::Table = text.parse().unwrap();
        let kind = t["case"]["kind"].as_str().unwrap();
        let seal = reference.join(kind).join(&st.name).join("seal.json");
        let rel = e.path.strip_prefix(&root).unwrap().to_str().unwrap();
        let Ok(seal) = std::fs::read_to_string(&seal) else {
            assert!(
                st.basis.contains("no record yet")
                    || st
                        .exploratory
                        .as_deref()
                        .is_some_and(|w| w.contains("no record yet")),
                "{st:?}"
            );
            continue;
        };
        with_record += 1;
        let sealed: serde_json::Value = serde_json::from_str(&seal).unwrap();
        let sealed = chrono::DateTime::parse_from_rfc3339(sealed["sealed"].as_str().unwrap())
            .unwrap()
            .timestamp();
        let before = format!("--before=@{}", sealed - 1);
        let at = git(&["log", "-1", "--format=%H", &before, "--", rel]).unwrap();
        let same = (!at.is_empty())
            .then(|| git(&["show", &format!("{at}:{rel}")]))
            .flatten()
            .is_some_and(|old| case_rules(&old) == case_rules(&text));
        match &st.exploratory {
            None => {
                assert!(same, "registered, but git disagrees: {st:?}");
                assert!(st.basis.contains(&at[..10]), "{st:?} names {at}");
            }
            // Registered by its text at the seal, but made with the rules in the same
            // commit as its record: the one reason the text comparison cannot see.
            Some(w) if w.contains("first committed together") => {}
            Some(w) => assert!(!same, "EXPLORATORY ({w}) but git shows the same rules"),
        }
    }
    assert!(with_record > 0, "the release suite has records");
    // A claim reading an EXPLORATORY case is EXPLORATORY.
    for (c, st) in s.claims.iter().zip(&reg.claims) {
        let reads_exploratory = c.cases.iter().any(|p| {
            let k = s.cases.iter().position(|e| e.path == *p).unwrap();
            reg.cases[k].exploratory.is_some()
        });
        if reads_exploratory {
            assert!(st.exploratory.is_some(), "{st:?}");
        }
    }
    let count = |v: &[registration::Standing]| v.iter().filter(|s| s.exploratory.is_some()).count();
    println!(
        "\n{} of {} cases EXPLORATORY, {} of {} claims EXPLORATORY",
        count(&reg.cases),
        reg.cases.len(),
        count(&reg.claims),
        reg.claims.len()
    );
}
