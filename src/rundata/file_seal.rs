//! Files of a directory named with their sha256: what every seal granval writes is made
//! of (a reference record's `seal.json`, a run's `run-seal.json`, a snapshot directory's
//! seal, a deck directory's manifest). The names come from a file a person can edit, so
//! they are checked before anything is opened: a relative path of plain components that
//! stays inside the directory (no `..`, no root, no `.`), naming a regular file (a
//! symlink could point anywhere). A digest that differs names the file.

use super::provenance::Sha256;
use anyhow::{Result, bail};
use std::collections::BTreeMap;
use std::path::{Component, Path};

/// Errors unless `name` is one plain file name (no `/`, not `..` or `.`, not empty).
pub(crate) fn plain_name(name: &str) -> Result<()> {
    let p = Path::new(name);
    let mut c = p.components();
    match (c.next(), c.next()) {
        (Some(Component::Normal(n)), None) if n == p.as_os_str() && !name.contains('\\') => Ok(()),
        _ => bail!(
            "{name:?} is not a plain file name (a seal names files inside its own directory: no `/`, no `..`, not absolute)"
        ),
    }
}

/// Errors unless `rel` is a relative path of plain names (`bed-0/native/force.csv`),
/// which cannot leave the directory it is relative to.
pub(crate) fn inside(rel: &str) -> Result<()> {
    let p = Path::new(rel);
    let ok = !rel.is_empty()
        && !rel.contains('\\')
        && p.components().all(|c| matches!(c, Component::Normal(_)));
    if !ok {
        bail!(
            "{rel:?} is not a path inside the sealed directory (plain names separated by `/`: no `..`, no `.`, not absolute)"
        );
    }
    Ok(())
}

/// sha256 of the regular file `dir/rel` (`rel` checked with [`inside`]); a symlink, a
/// directory, a FIFO or a device is refused before it is read.
pub(crate) fn digest(dir: &Path, rel: &str) -> Result<Sha256> {
    inside(rel)?;
    let p = dir.join(rel);
    let meta = std::fs::symlink_metadata(&p)
        .map_err(|e| anyhow::anyhow!("{}: sealed file missing ({e})", p.display()))?;
    if !meta.file_type().is_file() {
        bail!(
            "{}: not a regular file (a sealed file is never a link, directory or device)",
            p.display()
        );
    }
    Sha256::of_file(&p)
}

/// The digests of `names` in `dir`.
pub fn seal<'a>(
    dir: &Path,
    names: impl IntoIterator<Item = &'a str>,
) -> Result<BTreeMap<String, Sha256>> {
    names
        .into_iter()
        .map(|n| Ok((n.to_string(), digest(dir, n)?)))
        .collect()
}

/// Checks every file of `files` in `dir` against its digest; the first that differs (or
/// is missing, or is not a plain path inside `dir`) is an error naming it, with
/// `remedy` appended.
pub fn verify(dir: &Path, files: &BTreeMap<String, Sha256>, remedy: &str) -> Result<()> {
    for (name, want) in files {
        let got = digest(dir, name).map_err(|e| anyhow::anyhow!("{e:#}; {remedy}"))?;
        if &got != want {
            bail!(
                "{}: content differs from its seal (sha256 {got}, sealed {want}); {remedy}",
                dir.join(name).display()
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_that_leave_the_directory_are_refused_before_opening() {
        for ok in ["force.txt", "seal.json", "a.b-c_d"] {
            assert!(plain_name(ok).is_ok(), "{ok}");
            assert!(inside(ok).is_ok(), "{ok}");
        }
        assert!(inside("bed-0/native/force.csv").is_ok());
        for bad in [
            "",
            ".",
            "..",
            "../../../../etc/passwd",
            "/etc/passwd",
            "a/b",
            "a\\b",
        ] {
            assert!(plain_name(bad).is_err(), "{bad:?}");
        }
        for bad in ["", ".", "..", "a/../b", "/etc/passwd", "./a", "a\\..\\b"] {
            assert!(inside(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn digests_name_the_file_and_refuse_links() {
        let d = tempfile::tempdir().unwrap();
        std::fs::write(d.path().join("a"), "x").unwrap();
        let sealed = seal(d.path(), ["a"]).unwrap();
        verify(d.path(), &sealed, "redo").unwrap();
        std::fs::write(d.path().join("a"), "y").unwrap();
        let e = format!("{:#}", verify(d.path(), &sealed, "redo").unwrap_err());
        assert!(
            e.contains("/a: content differs") && e.ends_with("redo"),
            "{e}"
        );
        std::fs::remove_file(d.path().join("a")).unwrap();
        std::os::unix::fs::symlink("/etc/hostname", d.path().join("a")).unwrap();
        let e = format!("{:#}", verify(d.path(), &sealed, "redo").unwrap_err());
        assert!(e.contains("not a regular file"), "{e}");
        let mut up = BTreeMap::new();
        up.insert("../a".to_string(), Sha256::of(b"x"));
        let e = format!("{:#}", verify(d.path(), &up, "redo").unwrap_err());
        assert!(e.contains("not a path inside"), "{e}");
    }
}
