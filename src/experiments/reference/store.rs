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
//! - **Large files, compressed.** A sealed file of at least [`COMPRESS_AT_LEAST`] bytes
//!   that must stay in the record (a force curve, a log, a bed) is kept as `NAME.zst`
//!   (zstd). The seal still names the sha256 of the file as the engine wrote it: the
//!   bytes are decompressed once into a cache outside the repository
//!   ([`cache_dir`]), keyed by that sha256, and hashed against the seal before anything
//!   reads them. Text of numbers compresses 3-5x; nothing is lost and nothing about the
//!   seal changes.
//!
//! A file still present in its unit directory is read there first, so records made
//! before the store (and the directory of a recording before [`make_lean`]) work as
//! they always did. `reference refresh` records with every file present, seals, then
//! calls [`make_lean`]; `reference lean` does the same to a committed record that
//! verifies (see [`BedPlacement`] for why its beds stay where they are).

use super::{SEAL_FILE, Seal, unit_dir};
use crate::rundata::provenance::Sha256;
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};

/// The store of beds, under the reference root (beside the kind directories).
pub(crate) const BEDS_DIR: &str = "beds";

/// The suffix of a sealed file kept compressed (zstd frame of the sealed bytes).
pub(crate) const COMPRESSED_SUFFIX: &str = ".zst";

/// Sealed files at least this large are kept compressed by [`make_lean`]: below it the
/// saving is a few kilobytes, and small files (provenance, seals of decks) stay
/// readable with any tool.
pub(crate) const COMPRESS_AT_LEAST: u64 = 64 * 1024;

/// zstd level of the store: the highest of zstd's normal levels. Compression runs once
/// per record; decompression speed does not depend on the level.
const ZSTD_LEVEL: i32 = 19;

/// Where a bed goes when a record is made lean.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum BedPlacement {
    /// Into the bed store, once by content (a new record: the bed is new to the
    /// repository either way).
    Store,
    /// Left in its unit directory (compressed): a record already committed, whose bed
    /// moving would be a rename in the repository's history and gain nothing unless
    /// another record holds the same bed.
    InPlace,
}

/// The cache of decompressed record files, outside the repository:
/// `$GRANVAL_RECORD_CACHE`, else `<temp dir>/granval-records-<uid>`. Files in it are
/// named by their sealed sha256 and hashed against the seal whenever they are used, so
/// the cache is never trusted, only reused; removing it costs one decompression.
pub fn cache_dir() -> PathBuf {
    match std::env::var_os("GRANVAL_RECORD_CACHE") {
        Some(d) if !d.is_empty() => PathBuf::from(d),
        // SAFETY: getuid(2) cannot fail and touches no memory.
        _ => std::env::temp_dir().join(format!("granval-records-{}", unsafe { libc::getuid() })),
    }
}

/// `name` as the store keeps it compressed.
fn packed_name(name: &str) -> String {
    format!("{name}{COMPRESSED_SUFFIX}")
}

/// The decompressed bytes of `packed` (the compressed form of sealed file `name`,
/// sealed as `sha`), as a file in the cache: reused when one there already hashes to
/// `sha`, else written anew (atomically, so concurrent readers never see half a file).
/// The caller hashes what it reads against the seal as for any other sealed file.
fn unpacked(packed: &Path, name: &str, sha: &Sha256) -> Result<PathBuf> {
    let dir = cache_dir().join(sha.hex());
    let out = dir.join(name);
    if out.is_file() && Sha256::of_file(&out).is_ok_and(|s| &s == sha) {
        return Ok(out);
    }
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let bytes = decode(packed)?;
    let tmp = tempfile::NamedTempFile::new_in(&dir)
        .with_context(|| format!("cannot write in {}", dir.display()))?;
    std::fs::write(tmp.path(), &bytes)
        .with_context(|| format!("cannot write {}", tmp.path().display()))?;
    tmp.persist(&out)
        .with_context(|| format!("cannot write {}", out.display()))?;
    Ok(out)
}

/// The bytes a compressed sealed file stands for (a regular file, one or more whole
/// zstd frames).
fn decode(packed: &Path) -> Result<Vec<u8>> {
    crate::rundata::fsio::check_regular(packed, u64::MAX, "a sealed file (compressed)")?;
    let input =
        std::fs::File::open(packed).with_context(|| format!("cannot open {}", packed.display()))?;
    zstd::stream::decode_all(input)
        .with_context(|| format!("{}: not a whole zstd stream", packed.display()))
}

/// The bytes of `path`, compressed as the store keeps them.
fn compress(path: &Path) -> Result<Vec<u8>> {
    let input =
        std::fs::File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    zstd::stream::encode_all(input, ZSTD_LEVEL)
        .with_context(|| format!("cannot compress {}", path.display()))
}

/// Gives the bytes of a sealed file of a unit that the record may leave out because
/// granval writes it itself (unit name, file name); `None`: not regenerable.
pub(crate) type Regenerate<'a> = &'a dyn Fn(&str, &str) -> Option<Result<Vec<u8>>>;

/// Nothing is regenerable (a record that must hold every file).
pub fn nothing_regenerable(_unit: &str, _file: &str) -> Option<Result<Vec<u8>>> {
    None
}

/// The bed store of a record rooted at `<reference root>/<kind>/<case>` (a recording's
/// `<case>.recording` beside it shares the store).
pub(crate) fn store_dir(record_root: &Path) -> Option<PathBuf> {
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
pub(crate) fn stored_bed(record_root: &Path, sha: &Sha256) -> Option<PathBuf> {
    Some(store_dir(record_root)?.join(format!("{}.json", sha.hex())))
}

/// Where the bytes of sealed file `name` of `unit` (sealed as `sha`) are on disk: the
/// unit directory, its compressed form there (decompressed into the cache), or for a
/// bed the store; `None` when none holds it. Errors only when a compressed form exists
/// but cannot be read.
pub(crate) fn locate(
    record_root: &Path,
    unit: &str,
    name: &str,
    sha: &Sha256,
) -> Result<Option<PathBuf>> {
    let dir = unit_dir(record_root, unit);
    let here = dir.join(name);
    if here.is_file() {
        return Ok(Some(here));
    }
    let packed = dir.join(packed_name(name));
    if packed.exists() {
        return unpacked(&packed, name, sha).map(Some);
    }
    if is_bed_file(name) {
        return in_store(record_root, sha);
    }
    Ok(None)
}

/// The bed sealed as `sha` in the store of `record_root`, plain or compressed.
fn in_store(record_root: &Path, sha: &Sha256) -> Result<Option<PathBuf>> {
    let Some(stored) = stored_bed(record_root, sha) else {
        return Ok(None);
    };
    if stored.is_file() {
        return Ok(Some(stored));
    }
    let name = format!("{}.json", sha.hex());
    let packed = stored.with_file_name(packed_name(&name));
    if packed.exists() {
        return unpacked(&packed, &name, sha).map(Some);
    }
    Ok(None)
}

/// The store's own file of the bed sealed as `sha` (plain `<sha>.json` or compressed
/// `<sha>.json.zst`), as it lies on disk; `None` when the store does not hold it.
pub fn stored_bed_file(record_root: &Path, sha: &Sha256) -> Option<PathBuf> {
    let plain = stored_bed(record_root, sha)?;
    let packed = plain.with_file_name(packed_name(&format!("{}.json", sha.hex())));
    [plain, packed].into_iter().find(|p| p.is_file())
}

/// Whether sealed file `name` of `unit` is kept compressed in its unit directory.
pub(crate) fn is_packed(record_root: &Path, unit: &str, name: &str) -> bool {
    unit_dir(record_root, unit).join(packed_name(name)).exists()
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
    .ok()
    .flatten()
}

/// A bed another record of `kind` under `reference_root` sealed under this very file
/// name (`<kind>-bed-<sha256 of its specification>.json`: the same specification, so
/// the bed its preparation gives), as a file whose bytes hash to the sha256 that
/// record's seal names, with the record it came from. Records are searched in name
/// order, the case's own (`own`) left out; a record whose seal cannot be read, or
/// whose bytes for the bed do not match its seal, is passed over (never trusted), so
/// the worst case is a bed prepared again. Used for beds shared by cases (the Fig 2 beds
/// of seeds 1-5: settling each takes 10-25 minutes of CPU).
pub(crate) fn bed_in_other_records(
    reference_root: &Path,
    kind: &str,
    own: &str,
    name: &str,
) -> Option<(PathBuf, String)> {
    let dir = reference_root.join(kind);
    let mut records: Vec<PathBuf> = std::fs::read_dir(&dir)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.file_name().is_some_and(|n| n != own) && p.join(SEAL_FILE).is_file())
        .collect();
    records.sort();
    for rec in records {
        let Ok(text) = std::fs::read_to_string(rec.join(SEAL_FILE)) else {
            continue;
        };
        let Ok(seal) = serde_json::from_str::<Seal>(&text) else {
            continue;
        };
        for (unit, sealed) in &seal.units {
            let Some(sha) = sealed.files.get(name) else {
                continue;
            };
            let Ok(Some(file)) = locate(&rec, unit, name, sha) else {
                continue;
            };
            if Sha256::of_file(&file).is_ok_and(|s| &s == sha) {
                let from = rec
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                return Some((file, from));
            }
        }
    }
    None
}

/// The sha256 the seal of the record at `record_root` names for file `name` of `unit`,
/// read without verifying the record (the caller checks what it reads against it).
pub(crate) fn sealed_sha(record_root: &Path, unit: &str, name: &str) -> Option<Sha256> {
    let text = std::fs::read_to_string(record_root.join(SEAL_FILE)).ok()?;
    let seal: Seal = serde_json::from_str(&text).ok()?;
    seal.units.get(unit)?.files.get(name).cloned()
}

/// Checks one sealed file of a unit against the seal, wherever its bytes are: in the
/// unit directory, in the bed store, or regenerated. `hint` says how to re-record.
pub(crate) fn check_sealed_file(
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
    // A compressed file is decompressed and hashed here every time, not taken from the
    // cache: verifying a record checks the record's own bytes.
    let packed = unit_dir(record_root, unit).join(packed_name(name));
    if !in_unit.exists() && packed.exists() {
        let bytes = decode(&packed).map_err(|e| anyhow::anyhow!("{e:#} ({hint})"))?;
        let got = Sha256::of(&bytes);
        if &got != want {
            bail!(
                "{}: decompressed, its content differs from the seal (sha256 {got}, sealed {want}): the recorded reference was modified; {hint}",
                packed.display()
            );
        }
        return Ok(());
    }
    let found = locate(record_root, unit, name, want)
        .map_err(|e| anyhow::anyhow!("{e:#}: a sealed file must be the file recorded ({hint})"))?;
    if let Some(p) = found {
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

/// Makes a sealed record lean: each bed moves to the store (or is dropped when the
/// store already holds its bytes) or stays where it is ([`BedPlacement`]), each
/// regenerable file is dropped once writing it again gives its sealed sha256 exactly
/// (else it is kept, and said so), and each file left of at least
/// [`COMPRESS_AT_LEAST`] bytes is kept compressed once its compressed form
/// decompresses to the sealed sha256. Returns one line per thing done. The seal is not
/// touched.
pub(crate) fn make_lean(
    record_root: &Path,
    seal: &Seal,
    regenerate: Regenerate,
    beds: BedPlacement,
) -> Result<Vec<String>> {
    let mut lines = Vec::new();
    for (unit, sealed) in &seal.units {
        let dir = unit_dir(record_root, unit);
        for (name, sha) in &sealed.files {
            let path = dir.join(name);
            if !path.is_file() {
                continue;
            }
            if is_bed_file(name) && beds == BedPlacement::Store {
                let Some(to) = stored_bed(record_root, sha) else {
                    continue;
                };
                let have = in_store(record_root, sha)?;
                if let Some(have) = have.filter(|p| Sha256::of_file(p).is_ok_and(|s| &s == sha)) {
                    std::fs::remove_file(&path)
                        .with_context(|| format!("cannot remove {}", path.display()))?;
                    lines.push(format!(
                        "{}: already in the bed store as {}",
                        path.display(),
                        have.display()
                    ));
                } else {
                    let store = to.parent().unwrap_or(Path::new("."));
                    std::fs::create_dir_all(store)
                        .with_context(|| format!("cannot create {}", store.display()))?;
                    move_file(&path, &to)?;
                    lines.push(format!("{}: moved to {}", path.display(), to.display()));
                    lines.extend(pack(&to, sha)?);
                }
                continue;
            }
            if let Some(bytes) = regenerate(unit, name) {
                match bytes {
                    Ok(b) if &Sha256::of(&b) == sha => {
                        std::fs::remove_file(&path)
                            .with_context(|| format!("cannot remove {}", path.display()))?;
                        lines.push(format!(
                            "{}: left out of the record (written again from the bed on use, sha256 {sha} checked)",
                            path.display()
                        ));
                        continue;
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
            lines.extend(pack(&path, sha)?);
        }
    }
    Ok(lines)
}

/// Keeps `path` (sealed as `sha`) compressed when it is large enough: the compressed
/// form is written beside it, decompressed again and hashed, and only then is the
/// original removed. Returns what was done.
fn pack(path: &Path, sha: &Sha256) -> Result<Option<String>> {
    let size = std::fs::metadata(path)
        .with_context(|| format!("cannot read {}", path.display()))?
        .len();
    if size < COMPRESS_AT_LEAST {
        return Ok(None);
    }
    let name = path
        .file_name()
        .unwrap_or_default()
        .to_string_lossy()
        .into_owned();
    let packed = path.with_file_name(packed_name(&name));
    let bytes = compress(path)?;
    std::fs::write(&packed, &bytes)
        .with_context(|| format!("cannot write {}", packed.display()))?;
    let back = zstd::stream::decode_all(bytes.as_slice())
        .with_context(|| format!("{}: cannot decompress what was written", packed.display()))?;
    if &Sha256::of(&back) != sha {
        std::fs::remove_file(&packed).ok();
        bail!(
            "{}: decompressed it does not hash to the sealed {sha}; the original is kept",
            packed.display()
        );
    }
    std::fs::remove_file(path).with_context(|| format!("cannot remove {}", path.display()))?;
    Ok(Some(format!(
        "{}: kept compressed as {} ({size} -> {} bytes)",
        path.display(),
        packed.file_name().unwrap_or_default().to_string_lossy(),
        bytes.len()
    )))
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
        let lines = make_lean(&root, &seal, &writer, BedPlacement::Store).unwrap();
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
        make_lean(&root, &seal, &writer, BedPlacement::Store).unwrap();
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
        let lines = make_lean(&root, &seal, &other, BedPlacement::Store).unwrap();
        assert!(lines.iter().any(|l| l.contains("KEPT")), "{lines:?}");
        for UnitKey { name: u, .. } in &units {
            assert!(unit_dir(&root, u).join("data.bed").is_file());
        }
        check(&root, &units, &nothing_regenerable).unwrap();
    }

    /// A large sealed file is kept compressed: the record verifies with its unchanged
    /// seal, readers get the engine's bytes (through the cache, and as a whole unit
    /// directory), and a compressed file that was altered, truncated or is not zstd at
    /// all is refused naming it.
    #[test]
    fn a_large_file_is_kept_compressed_and_read_back_exactly() {
        let (_d, root, _, units) = sealed();
        let big: String = (0..20_000)
            .map(|i| format!("{i} {:.6e}\n", i as f64 * 0.37))
            .collect();
        for UnitKey { name: u, .. } in &units {
            std::fs::write(unit_dir(&root, u).join("force.txt"), &big).unwrap();
        }
        // Sealed again with the large force file, as a recording would be.
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
        let lines = make_lean(&root, &seal, &writer, BedPlacement::InPlace).unwrap();
        assert!(
            lines
                .iter()
                .filter(|l| l.contains("kept compressed as force.txt.zst"))
                .count()
                == 2,
            "{lines:?}"
        );
        let dir0 = unit_dir(&root, "bed-0");
        assert!(!dir0.join("force.txt").exists() && dir0.join("force.txt.zst").is_file());
        assert!(
            dir0.join(BED).is_file(),
            "InPlace leaves the bed in its unit"
        );
        assert!(
            std::fs::metadata(dir0.join("force.txt.zst")).unwrap().len() < big.len() as u64 / 2
        );
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
            std::fs::read_to_string(v.file("bed-0", "force.txt").unwrap()).unwrap(),
            big
        );
        let whole = v.unit_files("bed-0").unwrap();
        assert_ne!(whole, dir0);
        assert_eq!(
            std::fs::read_to_string(whole.join("force.txt")).unwrap(),
            big
        );
        assert!(whole.join(BED).is_file());

        // Negative controls: verifying decompresses the record's own bytes, so a copy
        // already in the cache does not hide a damaged compressed file.
        let packed = dir0.join("force.txt.zst");
        let good = std::fs::read(&packed).unwrap();
        let other: String = big.replacen("1 3.7", "1 3.8", 1);
        let cases: [(&str, Vec<u8>); 3] = [
            (
                "another force curve",
                zstd::stream::encode_all(other.as_bytes(), 3).unwrap(),
            ),
            ("truncated", good[..good.len() / 2].to_vec()),
            ("not zstd", b"force.txt".to_vec()),
        ];
        for (what, bytes) in cases {
            std::fs::write(&packed, bytes).unwrap();
            let e = format!("{:#}", check(&root, &units, &writer).unwrap_err());
            assert!(e.contains("force.txt"), "{what}: {e}");
        }
        std::fs::write(&packed, good).unwrap();
        check(&root, &units, &writer).unwrap();
    }
}
