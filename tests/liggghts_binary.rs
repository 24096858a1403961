//! `GRANVAL_LIGGGHTS` names the LIGGGHTS executable granval probes and runs (as
//! `GRANVAL_LMP` does for LAMMPS).

mod common;

use common::granval;

/// `GRANVAL_LIGGGHTS` names the executable granval probes and runs: one that exists but
/// does not work is an error naming it (exit 2), never a silent recorded pass. Before,
/// `liggghts` was hard-coded and the variable ignored (the live engine, or the record
/// on a machine without it, passed).
#[test]
fn granval_liggghts_names_the_executable() {
    use std::os::unix::fs::PermissionsExt;
    let bin = tempfile::tempdir().unwrap();
    let broken = bin.path().join("liggghts-broken");
    std::fs::write(&broken, "#!/bin/sh\necho 'segfault' >&2\nexit 139\n").unwrap();
    std::fs::set_permissions(&broken, std::fs::Permissions::from_mode(0o755)).unwrap();
    let out = tempfile::tempdir().unwrap();
    let st = granval()
        .env("GRANVAL_LIGGGHTS", &broken)
        .env_remove("GRANVAL_REQUIRE_LIVE")
        .args([
            "compare",
            "cases/micro/head-on-e05.toml",
            "--verbose",
            "--report",
        ])
        .arg(out.path())
        .output()
        .unwrap();
    let all = format!(
        "{}{}",
        String::from_utf8_lossy(&st.stdout),
        String::from_utf8_lossy(&st.stderr)
    );
    assert_eq!(st.status.code(), Some(2), "{all}");
    assert!(all.contains("liggghts-broken"), "{all}");
}
