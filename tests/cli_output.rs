//! What granval prints for people and scripts after a comparison: by default the
//! verdict and what did not pass (the whole report is in report.md), `--verbose` the
//! whole report, `--format json` one line of JSON, `--quiet` nothing.

mod common;

use common::granval;

/// `granval compare` on a recorded micro case (no engine needed), with extra flags:
/// exit code, stdout, and the report directory.
fn compare(flags: &[&str]) -> (Option<i32>, String, tempfile::TempDir) {
    let out = tempfile::tempdir().unwrap();
    let st = granval()
        .args([
            "compare",
            "cases/micro/head-on-e05.toml",
            "--reference-mode",
            "recorded",
        ])
        .args(flags)
        .arg("--report")
        .arg(out.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8(st.stdout).unwrap();
    assert!(
        st.status.code() == Some(0),
        "stdout: {stdout}\nstderr: {}",
        String::from_utf8_lossy(&st.stderr)
    );
    (st.status.code(), stdout, out)
}

/// Default stdout is the verdict and where the report is, not the report's tables;
/// `--verbose` prints the tables; `--quiet` prints nothing; `--format json` prints one
/// line a script parses, agreeing with report.json. Before, the whole report.md went
/// to stdout whatever the flags (and the flags did not exist).
#[test]
fn stdout_is_a_summary_the_whole_report_json_or_nothing() {
    let (_, text, dir) = compare(&[]);
    assert!(
        text.starts_with("granval compare") && text.contains(": PASS\n"),
        "{text}"
    );
    assert!(
        text.contains("report: ") && !text.contains("| check |"),
        "{text}"
    );
    assert!(dir.path().join("report.md").exists());

    let (_, verbose, _) = compare(&["--verbose"]);
    assert!(verbose.contains("| check | metric | value |"), "{verbose}");

    let (_, quiet, dir) = compare(&["--quiet"]);
    assert_eq!(quiet, "");
    assert!(dir.path().join("report.json").exists());
    let v = granval()
        .args(["validate", "cases/micro/head-on-e05.toml", "--quiet"])
        .output()
        .unwrap();
    assert_eq!((v.status.code(), v.stdout.len()), (Some(0), 0));

    let (_, json, dir) = compare(&["--format", "json"]);
    assert_eq!(json.lines().count(), 1, "{json}");
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
            .unwrap();
    assert_eq!(v["verdict"], "PASS");
    assert_eq!(v["exit_code"], 0);
    assert_eq!(v["checks"], report["checks"].as_array().unwrap().len());
    assert_eq!(v["pass"], v["checks"]);
    assert_eq!(v["not_passed"].as_array().unwrap().len(), 0);
    assert_eq!(v["report"], dir.path().display().to_string());
}
