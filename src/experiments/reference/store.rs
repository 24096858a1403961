//! The lean record store: where the bytes of a sealed record's files come from when the
//! record does not hold them itself. A seal names every file of a unit with its sha256
//! (`reference::Seal`); this module changes where those bytes live, never the seal:
//!
//! - **Beds, stored once by content.** The bed a unit's reference run started from
//!   (`<kind>-bed-<key>.json`, sealed with the unit) lives in
//!   `<reference root>/beds/<sha256>.json`, the sha256 being the one the seal names for
//!   it. Every record that used the bed finds it through its own seal, so beds shared by
//!   several cases or variants are stored once.
//! - **Regenerable files.** The reference engine's data file of a unit (LIGGGHTS'
//!   `data.bed`) is text granval wrote from the unit's bed with its own writer; a record
//!   need not hold it. When the record is used, the experiment writes it again from the
//!   unit ([`crate::experiments::Experiment::regenerate`]) and its sha256 must equal the sealed one:
//!   anything else is an error naming the file, never a pass.
//!
//! A file still present in its unit directory is read there first, so records made
//! before the store (and the directory of a recording before [`make_lean`]) work as
//! they always did. `reference refresh` records with every file present, seals, then
//! calls [`make_lean`].

use super::{SEAL_FILE, Seal, unit_dir};
use crate::rundata::provenance::Sha256;
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};

/// The store of beds, under the reference root (beside the kind directories).
pub const BEDS_DIR: &str = "beds";

/// Gives the bytes of a sealed file of a unit that the record may leave out because
/// granval writes it itself (unit name, file name); `None`: not regenerable.
pub type Regenerate<'a> = &'a dyn Fn(&str, &str) -> Option<Result<Vec<u8>>>;

/// Nothing is regenerable (a record that must hold every file).
pub fn nothing_regenerable(_unit: &str, _file: &str) -> Option<Result<Vec<u8>>> {
    None
}

/// The bed store of a record rooted at `<reference root>/<kind>/<case>` (a recording's
/// `<case>.recording` beside it shares the store).
pub fn store_dir(record_root: &Path) -> Option<PathBuf> {
    Some(record_root.parent()?.parent()?.join(BEDS_DIR))
}

/// Whether a sealed file is a bed (`<kind>-bed-<key>.json`, see
/// [`crate::experiments::bed_cache::name`]), which lives in the store.
pub fn is_bed_file(name: &str) -> bool {
    name.strip_suffix(".json")
        .and_then(|s| s.split_once("-bed-"))
        .is_some_and(|(kind, key)| {
            !kind.is_empty() && key.len() == 64 && key.bytes().all(|b| b.is_ascii_hexdigit())
        })
}

/// Where the store keeps a bed whose sealed sha256 is `sha`.
pub fn stored_bed(record_root: &Path, sha: &Sha256) -> Option<PathBuf> {
    Some(store_dir(record_root)?.join(format!("{}.json", sha.hex())))
}

/// Where the bytes of sealed file `name` of `unit` (sealed as `sha`) are on disk: the
/// unit directory, or for a bed the store; `None` when neither holds it.
pub fn locate(record_root: &Path, unit: &str, name: &str, sha: &Sha256) -> Option<PathBuf> {
    let here = unit_dir(record_root, unit).join(name);
    if here.is_file() {
        return Some(here);
    }
    if is_bed_file(name) {
        return stored_bed(record_root, sha).filter(|p| p.is_file());
    }
    None
}

/// The bed file `name` of `unit`, read before the seal is verified (the seal is only
/// read to find the bed's hash). Safe: a comparison goes on only if the unit built from
/// this bed has the fingerprint the seal holds, and the seal check hashes the file.
pub fn recorded_bed_file(record_root: &Path, unit: &str, name: &str) -> Option<PathBuf> {
    let here = unit_dir(record_root, unit).join(name);
    if here.is_file() {
        return Some(here);
    }
    locate(
        record_root,
        unit,
        name,
        &sealed_sha(record_root, unit, name)?,
    )
}

/// The sha256 the seal of the record at `record_root` names for file `name` of `unit`,
/// read without verifying the record (the caller checks what it reads against it).
pub fn sealed_sha(record_root: &Path, unit: &str, name: &str) -> Option<Sha256> {
    let text = std::fs::read_to_string(record_root.join(SEAL_FILE)).ok()?;
    let seal: Seal = serde_json::from_str(&text).ok()?;
    seal.units.get(unit)?.files.get(name).cloned()
}

/// Checks one sealed file of a unit against the seal, wherever its bytes are: in the
/// unit directory, in the bed store, or regenerated. `hint` says how to re-record.
pub fn check_sealed_file(
    record_root: &Path,
    unit: &str,
    name: &str,
    want: &Sha256,
    regenerate: Regenerate,
    hint: &str,
) -> Result<()> {
    let in_unit = unit_dir(record_root, unit).join(name);
    if std::fs::symlink_metadata(&in_unit).is_ok_and(|m| !m.file_type().is_file()) {
        // Named by its kind (a FIFO, a device, a directory), refused before it is opened.
        if let Err(e) = crate::rundata::fsio::check_regular(&in_unit, u64::MAX, "a sealed file") {
            bail!("{e} (a sealed file must be the regular file recorded; {hint})");
        }
        bail!(
            "{}: a symbolic link (a sealed file must be the regular file recorded; {hint})",
            in_unit.display()
        );
    }
    if let Some(p) = locate(record_root, unit, name, want) {
        let (parent, file) = (
            p.parent().unwrap_or(Path::new(".")),
            p.file_name().unwrap_or_default(),
        );
        let got =
            crate::rundata::file_seal::digest(parent, &file.to_string_lossy()).map_err(|e| {
                anyhow::anyhow!("{e:#}: a sealed file must be the regular file recorded ({hint})")
            })?;
        if &got != want {
            bail!(
                "{}: content differs from the seal (sha256 {got}, sealed {want}): the recorded reference was modified; {hint}",
                p.display()
            );
        }
        return Ok(());
    }
    let Some(bytes) = regenerate(unit, name) else {
        let also = if is_bed_file(name) {
            stored_bed(record_root, want)
                .map(|p| format!(" nor at {}", p.display()))
                .unwrap_or_default()
        } else {
            String::new()
        };
        bail!("{}{also}: sealed file missing ({hint})", in_unit.display());
    };
    let bytes = bytes.with_context(|| {
        format!(
            "{}: not in the record, and writing it again from the unit failed ({hint})",
            in_unit.display()
        )
    })?;
    let got = Sha256::of(&bytes);
    if &got != want {
        bail!(
            "{}: not in the record; written again from the unit's bed it has sha256 {got}, but the seal holds {want}: granval's writer of this file or the bed changed since recording, so the record cannot be checked; {hint}",
            in_unit.display()
        );
    }
    Ok(())
}

/// Makes a freshly sealed record lean: each bed moves to the store (or is dropped when
/// the store already holds its bytes), each regenerable file is dropped once writing
/// it again gives its sealed sha256 exactly (else it is kept, and said so). Returns one
/// line per thing done. The seal is not touched.
pub fn make_lean(record_root: &Path, seal: &Seal, regenerate: Regenerate) -> Result<Vec<String>> {
    let mut lines = Vec::new();
    for (unit, sealed) in &seal.units {
        let dir = unit_dir(record_root, unit);
        for (name, sha) in &sealed.files {
            let path = dir.join(name);
            if !path.is_file() {
                continue;
            }
            if is_bed_file(name) {
                let Some(to) = stored_bed(record_root, sha) else {
                    continue;
                };
                if to.is_file() && &Sha256::of_file(&to)? == sha {
                    std::fs::remove_file(&path)
                        .with_context(|| format!("cannot remove {}", path.display()))?;
                    lines.push(format!(
                        "{}: already in the bed store as {}",
                        path.display(),
                        to.display()
                    ));
                } else {
                    let store = to.parent().unwrap_or(Path::new("."));
                    std::fs::create_dir_all(store)
                        .with_context(|| format!("cannot create {}", store.display()))?;
                    move_file(&path, &to)?;
                    lines.push(format!("{}: moved to {}", path.display(), to.display()));
                }
            } else if let Some(bytes) = regenerate(unit, name) {
                match bytes {
                    Ok(b) if &Sha256::of(&b) == sha => {
                        std::fs::remove_file(&path)
                            .with_context(|| format!("cannot remove {}", path.display()))?;
                        lines.push(format!(
                            "{}: left out of the record (written again from the bed on use, sha256 {sha} checked)",
                            path.display()
                        ));
                    }
                    Ok(b) => lines.push(format!(
                        "{}: KEPT in the record: written again it has sha256 {}, not the sealed {sha}",
                        path.display(),
                        Sha256::of(&b)
                    )),
                    Err(e) => lines.push(format!(
                        "{}: KEPT in the record: it cannot be written again ({e:#})",
                        path.display()
                    )),
                }
            }
        }
    }
    Ok(lines)
}

/// A rename, or a copy and remove across file systems.
fn move_file(from: &Path, to: &Path) -> Result<()> {
    if std::fs::rename(from, to).is_ok() {
        return Ok(());
    }
    std::fs::copy(from, to)
        .with_context(|| format!("cannot copy {} to {}", from.display(), to.display()))?;
    std::fs::remove_file(from).with_context(|| format!("cannot remove {}", from.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiments::reference::{self, UnitKey, verify};
    use crate::rundata::provenance::EngineKind;

    const BED: &str =
        "penetration-bed-8d065699e27d89cac08de45e2fa7c668c312407feef2e0e348eb922261192849.json";

    /// A sealed two-unit record under `<tmp>/reference/penetration/c`, each unit with a
    /// data file written "by granval" (`data.bed`, regenerable), a bed (the same bed in
    /// both units) and a force file.
    fn sealed() -> (tempfile::TempDir, PathBuf, Seal, Vec<UnitKey>) {
        let d = tempfile::tempdir().unwrap();
        let root = reference::record_root(&d.path().join("reference"), "penetration", "c");
        // The engine input of a unit is its data file, so the seal check also reads the
        // data file written again for a lean record.
        let units: Vec<UnitKey> = ["bed-0", "bed-1"]
            .iter()
            .map(|u| UnitKey {
                name: u.to_string(),
                fingerprint: Sha256::of(u.as_bytes()),
                input: vec!["data.bed"],
                input_hash: crate::engines::deck_text::fingerprint(&[&data_of(u)]),
            })
            .collect();
        for UnitKey { name: u, .. } in &units {
            let dir = unit_dir(&root, u);
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(dir.join("data.bed"), data_of(u)).unwrap();
            std::fs::write(dir.join(BED), "{\"bed\":1}").unwrap();
            std::fs::write(dir.join("force.txt"), format!("{u} 1 2\n")).unwrap();
        }
        let seal = reference::write(
            &root,
            "c",
            "penetration",
            Path::new("c.toml"),
            &Sha256::of(b"case"),
            EngineKind::Liggghts,
            "LIGGGHTS (Version x)",
            &units,
        )
        .unwrap();
        (d, root, seal, units)
    }

    fn data_of(unit: &str) -> String {
        format!("LIGGGHTS data file of {unit}\n1 1 0.002 2500 0 0 0\n")
    }

    fn writer(unit: &str, file: &str) -> Option<Result<Vec<u8>>> {
        (file == "data.bed").then(|| Ok(data_of(unit).into_bytes()))
    }

    fn check(root: &Path, units: &[UnitKey], regen: Regenerate) -> Result<()> {
        verify(
            root,
            Path::new("c.toml"),
            &Sha256::of(b"case"),
            EngineKind::Liggghts,
            units,
            regen,
        )
        .map(|_| ())
    }

    #[test]
    fn bed_files_are_recognised_by_their_name() {
        assert!(is_bed_file(BED));
        assert!(is_bed_file(
            "impact2d-bed-68096ce7659100127f541f4d98315e8f112ab3c0fc32910f2732f85d185023ec.json"
        ));
        for not in [
            "data.bed",
            "provenance.json",
            "penetration-bed-1234.json",
            "-bed-8d065699e27d89cac08de45e2fa7c668c312407feef2e0e348eb922261192849.json",
            "penetration-bed-8d065699e27d89cac08de45e2fa7c668c312407feef2e0e348eb92226119284/.json",
        ] {
            assert!(!is_bed_file(not), "{not}");
        }
    }

    /// A lean record verifies with the same seal: its bed is stored once and found by
    /// the sealed hash from both units, its data files are written again and checked.
    #[test]
    fn a_lean_record_verifies_with_its_unchanged_seal() {
        let (_d, root, seal, units) = sealed();
        let seal_text = std::fs::read(root.join(SEAL_FILE)).unwrap();
        let lines = make_lean(&root, &seal, &writer).unwrap();
        assert_eq!(lines.len(), 4, "{lines:?}");
        assert_eq!(std::fs::read(root.join(SEAL_FILE)).unwrap(), seal_text);
        for UnitKey { name: u, .. } in &units {
            let dir = unit_dir(&root, u);
            assert!(!dir.join("data.bed").exists() && !dir.join(BED).exists());
            assert!(dir.join("force.txt").exists());
        }
        let beds: Vec<_> = std::fs::read_dir(store_dir(&root).unwrap())
            .unwrap()
            .collect();
        assert_eq!(beds.len(), 1, "one bed, stored once");
        let bed_sha = &seal.units["bed-1"].files[BED];
        assert_eq!(
            recorded_bed_file(&root, "bed-1", BED),
            stored_bed(&root, bed_sha)
        );
        check(&root, &units, &writer).unwrap();
        let v = verify(
            &root,
            Path::new("c.toml"),
            &Sha256::of(b"case"),
            EngineKind::Liggghts,
            &units,
            &writer,
        )
        .unwrap();
        assert_eq!(
            v.file("bed-0", BED).unwrap(),
            stored_bed(&root, bed_sha).unwrap()
        );
    }

    /// Negative controls: a writer that changed by one character, a unit that cannot
    /// write its data file, a tampered stored bed, a lost bed: each is an error naming
    /// the file.
    #[test]
    fn a_lean_record_refuses_what_does_not_hash_to_the_seal() {
        let (_d, root, seal, units) = sealed();
        make_lean(&root, &seal, &writer).unwrap();
        let changed = |u: &str, f: &str| {
            (f == "data.bed").then(|| Ok(data_of(u).replace("2500", "2500.0").into_bytes()))
        };
        let e = format!("{:#}", check(&root, &units, &changed).unwrap_err());
        assert!(
            e.contains("bed-0/data.bed") && e.contains("written again") && e.contains("re-record"),
            "{e}"
        );
        let e = format!(
            "{:#}",
            check(&root, &units, &nothing_regenerable).unwrap_err()
        );
        assert!(e.contains("bed-0/data.bed: sealed file missing"), "{e}");
        let failing = |_: &str, f: &str| (f == "data.bed").then(|| Err(anyhow::anyhow!("no bed")));
        let e = format!("{:#}", check(&root, &units, &failing).unwrap_err());
        assert!(
            e.contains("data.bed: not in the record") && e.contains("no bed"),
            "{e}"
        );
        let stored = stored_bed(&root, &seal.units["bed-0"].files[BED]).unwrap();
        std::fs::write(&stored, "{\"bed\":2}").unwrap();
        let e = format!("{:#}", check(&root, &units, &writer).unwrap_err());
        assert!(
            e.contains(&stored.display().to_string()) && e.contains("modified"),
            "{e}"
        );
        std::fs::remove_file(&stored).unwrap();
        let e = format!("{:#}", check(&root, &units, &writer).unwrap_err());
        assert!(e.contains(BED) && e.contains("sealed file missing"), "{e}");
        assert!(recorded_bed_file(&root, "bed-0", BED).is_none());
    }

    /// A writer that does not reproduce the sealed bytes leaves the file in the record:
    /// nothing is dropped that could not be checked later.
    #[test]
    fn a_file_that_does_not_regenerate_exactly_is_kept() {
        let (_d, root, seal, units) = sealed();
        let other = |u: &str, f: &str| (f == "data.bed").then(|| Ok(format!("{u}\n").into_bytes()));
        let lines = make_lean(&root, &seal, &other).unwrap();
        assert!(lines.iter().any(|l| l.contains("KEPT")), "{lines:?}");
        for UnitKey { name: u, .. } in &units {
            assert!(unit_dir(&root, u).join("data.bed").is_file());
        }
        check(&root, &units, &nothing_regenerable).unwrap();
    }
}
