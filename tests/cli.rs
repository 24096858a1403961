//! The stable interface: `granval check/compare` write report.json shaped
//! {"passed", "checks": [{name, metric, value, tolerance, passed}]} and exit 0/1/2.

mod common;

use std::process::Command;

fn granval() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_granval"));
    c.current_dir(common::root());
    c
}

#[test]
fn compare_writes_report_and_exits_zero() {
    let out = tempfile::tempdir().unwrap();
    let st = granval()
        .args(["compare", "cases/micro/spin.toml", "--report"])
        .arg(out.path())
        .output()
        .unwrap();
    assert_eq!(
        st.status.code(),
        Some(0),
        "stdout: {}\nstderr: {}",
        String::from_utf8_lossy(&st.stdout),
        String::from_utf8_lossy(&st.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.path().join("report.json")).unwrap())
            .unwrap();
    assert_eq!(report["passed"], true);
    let checks = report["checks"].as_array().unwrap();
    assert_eq!(checks.len(), 3);
    for c in checks {
        for k in ["name", "metric", "value", "tolerance", "passed"] {
            assert!(c.get(k).is_some(), "check lacks {k}: {c}");
        }
    }
    assert!(out.path().join("report.md").exists() && out.path().join("report.junit.xml").exists());
    assert!(
        out.path().join("spin/native/particles.csv").exists()
            && out.path().join("spin/native/provenance.json").exists()
    );
}

#[test]
fn bad_case_exits_two_with_located_message() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    let text = std::fs::read_to_string(common::root().join("cases/micro/spin.toml"))
        .unwrap()
        .replacen("friction = 0.5", "friction = -1.0", 1);
    std::fs::write(&bad, text).unwrap();
    let st = granval()
        .args(["run"])
        .arg(&bad)
        .args(["--out"])
        .arg(dir.path().join("o"))
        .output()
        .unwrap();
    assert_eq!(st.status.code(), Some(2));
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(
        err.contains("bad.toml")
            && err.contains("interactions[0].friction")
            && err.contains("-1.0"),
        "{err}"
    );
}

#[test]
fn missing_reference_is_an_error_not_a_pass() {
    // With no LIGGGHTS on PATH and an empty reference root, compare must exit 2.
    let out = tempfile::tempdir().unwrap();
    let empty = tempfile::tempdir().unwrap();
    let st = granval()
        .env("PATH", "/nonexistent")
        .env_remove("GRANVAL_REQUIRE_LIVE")
        .args(["compare", "cases/micro/spin.toml", "--reference"])
        .arg(empty.path())
        .args(["--report"])
        .arg(out.path())
        .output()
        .unwrap();
    assert_eq!(
        st.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&st.stdout)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.path().join("report.json")).unwrap())
            .unwrap();
    assert_eq!(report["passed"], false);
}

#[test]
fn recorded_fallback_says_so() {
    // Hide LIGGGHTS: the run must use reference/ and the report must say it did.
    let out = tempfile::tempdir().unwrap();
    let st = granval()
        .env("PATH", "/nonexistent")
        .env_remove("GRANVAL_REQUIRE_LIVE")
        .args(["compare", "cases/micro/head-on-e05.toml", "--report"])
        .arg(out.path())
        .output()
        .unwrap();
    assert_eq!(
        st.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&st.stdout)
    );
    let md = std::fs::read_to_string(out.path().join("report.md")).unwrap();
    assert!(
        md.contains("RECORDED") && md.contains("reference/micro/head-on-e05"),
        "{md}"
    );
}

#[test]
fn require_live_refuses_fallback() {
    let out = tempfile::tempdir().unwrap();
    let st = granval()
        .env("PATH", "/nonexistent")
        .args([
            "compare",
            "cases/micro/head-on-e05.toml",
            "--require-live",
            "--report",
        ])
        .arg(out.path())
        .output()
        .unwrap();
    assert_eq!(st.status.code(), Some(2));
}
