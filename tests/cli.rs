//! The stable interface: `granval check/compare` write report.json shaped
//! {"passed", "checks": [{name, gate, metric, value, tolerance, status, passed}]} and
//! exit 0/1/2; outputs go into a fresh directory.

mod common;

use common::granval;

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
    // The three trajectory gates and the coverage check (enough dynamics compared).
    let mut gates: Vec<&str> = checks.iter().map(|c| c["gate"].as_str().unwrap()).collect();
    gates.sort();
    assert_eq!(
        gates,
        ["angular_velocity", "coverage", "position", "velocity"],
        "{checks:?}"
    );
    for c in checks {
        for k in [
            "name",
            "gate",
            "metric",
            "value",
            "tolerance",
            "status",
            "passed",
        ] {
            assert!(c.get(k).is_some(), "check lacks {k}: {c}");
        }
        assert_eq!((&c["status"], &c["passed"]), (&"pass".into(), &true.into()));
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

/// Outputs go into a fresh directory: a non-empty one is refused (exit 2, nothing
/// written); `--force` clears it only when granval created it (its marker), and a
/// directory granval did not create is refused even with `--force`, its files kept.
#[test]
fn non_empty_output_directory_is_refused_unless_forced() {
    let foreign = tempfile::tempdir().unwrap();
    let mine = foreign.path().join("notes.txt");
    std::fs::write(&mine, "not granval's").unwrap();
    for force in [false, true] {
        let mut c = granval();
        c.args(["compare", "cases/micro/spin.toml", "--report"])
            .arg(foreign.path());
        if force {
            c.arg("--force");
        }
        let st = c.output().unwrap();
        let err = String::from_utf8_lossy(&st.stderr);
        assert_eq!(st.status.code(), Some(2), "{err}");
        assert!(err.contains("not created by granval"), "{err}");
        assert!(mine.exists() && !foreign.path().join("report.json").exists());
    }

    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("report");
    let compare = |force: bool| {
        let mut c = granval();
        c.args(["compare", "cases/micro/spin.toml", "--report"])
            .arg(&out);
        if force {
            c.arg("--force");
        }
        c.output().unwrap()
    };
    assert_eq!(compare(false).status.code(), Some(0));
    let stale = out.join("stale.txt");
    std::fs::write(&stale, "from an earlier run").unwrap();
    let st = compare(false);
    let err = String::from_utf8_lossy(&st.stderr);
    assert_eq!(st.status.code(), Some(2), "{err}");
    assert!(
        err.contains("not empty") && err.contains("--force"),
        "{err}"
    );
    assert!(stale.exists());
    let st = compare(true);
    assert_eq!(
        st.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    assert!(!stale.exists() && out.join("report.json").exists());
}

/// `--reference-mode recorded` uses the sealed record even with LIGGGHTS installed, and
/// the report says so.
#[test]
fn reference_mode_recorded_uses_the_seal() {
    let out = tempfile::tempdir().unwrap();
    let st = granval()
        .args([
            "compare",
            "cases/micro/head-on-e05.toml",
            "--reference-mode",
            "recorded",
            "--report",
        ])
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
        md.contains("RECORDED") && md.contains("seal verified"),
        "{md}"
    );
}

/// `check --suite NAME --only CASE` runs that one case of the suite into the report
/// directory; a case outside the suite is an error.
#[test]
fn check_suite_only_one_case() {
    let out = tempfile::tempdir().unwrap();
    let st = granval()
        .args([
            "check",
            "--suite",
            "micro",
            "--only",
            "cases/micro/spin.toml",
            "--report",
        ])
        .arg(out.path())
        .output()
        .unwrap();
    assert_eq!(
        st.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.path().join("report.json")).unwrap())
            .unwrap();
    assert_eq!(report["passed"], true);
    let names: Vec<&str> = report["checks"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert!(
        !names.is_empty() && names.iter().all(|n| n.starts_with("spin")),
        "{names:?}"
    );
    assert!(out.path().join("spin/native/particles.csv").exists());
    let other = tempfile::tempdir().unwrap();
    let st = granval()
        .args([
            "check",
            "--suite",
            "micro",
            "--only",
            "cases/impact2d/ci.toml",
            "--report",
        ])
        .arg(other.path())
        .output()
        .unwrap();
    assert_eq!(st.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&st.stderr).contains("not a case of suite micro"));
}
