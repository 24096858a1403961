//! Where the reference side of a comparison comes from, and the seal that makes a
//! recorded reference trustworthy.
//!
//! A recorded reference lives in `reference/<kind>/<case name>/` with one directory per
//! unit (a bed, a sweep variant; single-unit cases use the case directory itself) and a
//! `seal.json` written by `granval reference refresh` only. The seal names the sha256
//! of the case's canonical content (its physics, not its formatting), of every unit's
//! reference-engine input (its fingerprint) and of every file recorded. Before a record
//! is used, all three are checked; any mismatch is an error (exit 2) that names the file
//! and says how to re-record. A record is never produced by the native engine: the seal
//! names the engine, and only LIGGGHTS or LAMMPS are accepted. A file's bytes may live
//! outside its unit directory (a bed in the bed store) or be written again by granval
//! (a data file); [`store`] says where, the seal stays as recorded.

pub mod store;

use crate::rundata::provenance::{EngineKind, Sha256, now_utc};
use anyhow::{Context, Result, bail, ensure};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub const SEAL_FILE: &str = "seal.json";

/// How the reference engine is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum RefMode {
    /// Live when the reference engine is installed, else the sealed record.
    #[default]
    Auto,
    /// Live only: a missing engine is an error (CI: `GRANVAL_REQUIRE_LIVE=1`).
    Live,
    /// The sealed record even when the engine is installed (re-checks the native side
    /// against what was recorded).
    Recorded,
}

/// The reference source a comparison ends up with.
#[derive(Debug, Clone)]
pub(crate) enum Source {
    /// The engine runs now (its banner line was read).
    Live,
    /// A sealed record, verified.
    Recorded { seal: Box<Verified> },
    /// A run directory a user brought back (`granval analyze`): not sealed, said so.
    RunDir { dir: PathBuf },
}

impl Source {
    pub(crate) fn describe(&self) -> String {
        match self {
            Source::Live => "live".into(),
            Source::Recorded { seal } => format!("recorded {}", seal.root.display()),
            Source::RunDir { dir } => format!("run directory {}", dir.display()),
        }
    }
}

/// The banner of the installed reference engine when it works, `None` otherwise (a
/// missing one, or one that fails its probe: [`probe`] tells them apart).
pub fn installed(engine: EngineKind) -> Option<String> {
    probe(engine).ok().flatten()
}

/// Whether the reference engine runs here: its banner, `None` when no executable of
/// that name exists (the recorded reference may stand in), an error when one exists
/// but hangs, fails, prints no banner or is the wrong version. That is never a reason
/// to fall back to the record: the user has an engine and it does not work, so a
/// RECORDED pass would hide it.
pub fn probe(engine: EngineKind) -> Result<Option<String>> {
    use crate::engines::process::Probe;
    let (found, binary) = match engine {
        EngineKind::Liggghts => {
            let b = crate::engines::liggghts::binary();
            (crate::engines::liggghts::probe(&b), b)
        }
        EngineKind::Lammps => {
            let b = crate::engines::lammps::binary();
            (crate::engines::lammps::probe(&b), b)
        }
        EngineKind::Native => return Ok(None),
    };
    match found {
        Probe::Absent => Ok(None),
        Probe::Found(banner) => Ok(Some(banner)),
        Probe::Broken(why) => bail!(
            "{why}. granval does not fall back to the recorded {engine} reference while an executable named `{binary}` is there and does not work: fix it, take it off PATH, or pass --reference-mode recorded"
        ),
    }
}

/// Where a case's record lives.
pub fn record_root(reference_root: &Path, kind: &str, case_name: &str) -> PathBuf {
    reference_root.join(kind).join(case_name)
}

/// A unit's record directory (`""` = the case directory itself).
pub fn unit_dir(root: &Path, unit: &str) -> PathBuf {
    if unit.is_empty() {
        root.to_path_buf()
    } else {
        root.join(unit)
    }
}

/// What a comparison needs of one unit's record: its name, the fingerprint the seal
/// must hold, and the reference engine's input the record must store (file names in
/// fingerprint order, and the fingerprint of those files).
#[derive(Debug, Clone, PartialEq)]
pub struct UnitKey {
    pub name: String,
    pub fingerprint: Sha256,
    pub input: Vec<&'static str>,
    pub input_hash: Sha256,
}

/// The [`UnitKey`]s of an experiment's units.
pub fn unit_keys<E: super::Experiment>(exp: &E, units: &[E::Unit]) -> Result<Vec<UnitKey>> {
    units
        .iter()
        .map(|u| {
            let input = exp.engine_input(u)?;
            Ok(UnitKey {
                name: exp.unit_name(u),
                fingerprint: exp.fingerprint(u)?,
                input_hash: crate::engines::deck_text::fingerprint(
                    &input.iter().map(|(_, t)| t.as_str()).collect::<Vec<_>>(),
                ),
                input: input.into_iter().map(|(n, _)| n).collect(),
            })
        })
        .collect()
}

/// One unit as sealed: the fingerprint of its reference-engine input and its files.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct SealedUnit {
    pub fingerprint: Sha256,
    /// File name (relative to the unit directory) -> sha256.
    pub files: BTreeMap<String, Sha256>,
}

/// `seal.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Seal {
    pub granval: String,
    pub case_name: String,
    pub case_kind: String,
    pub case_sha256: Sha256,
    pub engine: EngineKind,
    pub engine_version: String,
    pub sealed: String,
    /// The case file the record was made from, as `reference refresh` was given it
    /// (absent in records sealed before it was kept): a refresh of another case file
    /// with the same name is refused instead of replacing this record.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub case_file: Option<String>,
    /// Unit name -> contents, in unit order.
    pub units: BTreeMap<String, SealedUnit>,
    /// Files added to the seal after it was sealed, each with why it could be
    /// ([`SealAmendment`]); empty (and absent from the file) for a seal as made.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub amendments: Vec<SealAmendment>,
}

/// Inputs added to a committed seal: `granval reference lean --add-beds` stores the bed
/// each unit's reference run started from in a record that was sealed without it. Only
/// an input granval prepares deterministically may be added, and only once it is proven
/// to be the one used: the units prepared from it have the sealed fingerprints and every
/// file granval writes from it (the engine's data file) hashes to its sealed sha256. The
/// engine's outputs, the sealed time and every file sealed before are never changed.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SealAmendment {
    /// When it was added (RFC 3339, UTC).
    pub utc: String,
    /// The granval commit that added it, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub granval_commit: Option<String>,
    /// `unit/file` of every file added (the file's sha256 is in its unit).
    pub added: Vec<String>,
    /// How each added file was proven to be the one the run used.
    pub proof: String,
}

/// A seal whose case and files have been checked.
#[derive(Debug, Clone)]
pub struct Verified {
    pub root: PathBuf,
    pub seal: Seal,
}

impl Verified {
    /// A recorded file of a unit; refuses a file the seal does not cover, so no loader
    /// can read unsealed data by accident.
    pub fn file(&self, unit: &str, name: &str) -> Result<PathBuf> {
        let u =
            self.seal.units.get(unit).with_context(|| {
                format!("{}: no unit {unit:?} in the seal", self.root.display())
            })?;
        let Some(sha) = u.files.get(name) else {
            bail!(
                "{}: {name} of unit {unit:?} is not covered by the seal",
                self.root.join(SEAL_FILE).display()
            );
        };
        // A bed may live in the record store (`store`), found by its sealed hash; a
        // large file may be kept compressed (read from the cache, hashed at verify).
        Ok(store::locate(&self.root, unit, name, sha)?
            .unwrap_or_else(|| unit_dir(&self.root, unit).join(name)))
    }

    /// A directory holding the sealed files of `unit` as the engine wrote them, for
    /// readers of a whole run directory: the unit's own directory when it keeps every
    /// file plain, else a directory in the record cache ([`store::cache_dir`]) named
    /// by the sha256 of the unit's seal, each file copied from where the store keeps
    /// it and hashed against the seal. Files a lean record leaves out to be written
    /// again (engine data files) are not in it.
    pub fn unit_files(&self, unit: &str) -> Result<PathBuf> {
        let u =
            self.seal.units.get(unit).with_context(|| {
                format!("{}: no unit {unit:?} in the seal", self.root.display())
            })?;
        let own = unit_dir(&self.root, unit);
        if !u
            .files
            .keys()
            .any(|f| store::is_packed(&self.root, unit, f))
        {
            return Ok(own);
        }
        let key = Sha256::of(serde_json::to_string(&u.files)?.as_bytes());
        let dir = store::cache_dir().join("units").join(key.hex());
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        for (name, sha) in &u.files {
            let Some(from) = store::locate(&self.root, unit, name, sha)? else {
                continue;
            };
            let to = dir.join(name);
            if !(to.is_file() && Sha256::of_file(&to).is_ok_and(|s| &s == sha)) {
                let tmp = tempfile::NamedTempFile::new_in(&dir)
                    .with_context(|| format!("cannot write in {}", dir.display()))?;
                std::fs::copy(&from, tmp.path())
                    .with_context(|| format!("cannot copy {}", from.display()))?;
                tmp.persist(&to)
                    .with_context(|| format!("cannot write {}", to.display()))?;
            }
            let got = Sha256::of_file(&to)?;
            ensure!(
                &got == sha,
                "{}: content differs from the seal (sha256 {got}, sealed {sha})",
                to.display()
            );
        }
        Ok(dir)
    }
}

fn rerecord_hint(case_file: &Path) -> String {
    format!(
        "re-record it where the reference engine is installed: `granval reference refresh --only {}`",
        case_file.display()
    )
}

/// The seal of the record at `root`, checked for what does not need the units: that it
/// parses, was made by `engine` for the case whose canonical hash is `case_hash`, and
/// names only plain files inside the record.
pub(crate) fn read_seal(
    root: &Path,
    case_file: &Path,
    case_hash: &Sha256,
    engine: EngineKind,
) -> Result<Seal> {
    let hint = rerecord_hint(case_file);
    let path = root.join(SEAL_FILE);
    let text = crate::rundata::fsio::read_to_string(
        &path,
        crate::rundata::fsio::MAX_RECORD_JSON,
        "a seal (JSON)",
    )
    .map_err(|e| {
        if e.is_not_found() {
            anyhow::anyhow!(
                "{}: no sealed reference record for this case ({hint})",
                path.display()
            )
        } else {
            anyhow::anyhow!("{e} ({hint})")
        }
    })?;
    let seal: Seal = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a seal ({hint})", path.display()))?;
    ensure!(
        seal.engine.is_reference() && seal.engine == engine,
        "{}: recorded with {}, but this case's reference engine is {engine}; reference data must come from LIGGGHTS or LAMMPS ({hint})",
        path.display(),
        seal.engine
    );
    if &seal.case_sha256 != case_hash {
        bail!(
            "{}: recorded for a different case (case sha256 {} in the seal, {} now: the physics of {} changed, or this is another case's record); {hint}",
            path.display(),
            seal.case_sha256,
            case_hash,
            case_file.display()
        );
    }
    for (name, u) in &seal.units {
        if !name.is_empty() {
            crate::rundata::file_seal::plain_name(name)
                .with_context(|| format!("{}: unit {name:?}", path.display()))?;
        }
        for file in u.files.keys() {
            crate::rundata::file_seal::plain_name(file)
                .with_context(|| format!("{}: unit {name:?}: sealed file", path.display()))?;
        }
    }
    Ok(seal)
}

/// Every file of every unit of the record at `root` checked against its seal, without
/// the units' fingerprints: what a change of how files are kept (not of what they hold)
/// must leave intact. No file is written again from a bed here, so every sealed file
/// must be in the record (plain or compressed). Returns the seal.
pub(crate) fn verify_files(
    root: &Path,
    case_file: &Path,
    case_hash: &Sha256,
    engine: EngineKind,
) -> Result<Seal> {
    let hint = rerecord_hint(case_file);
    let seal = read_seal(root, case_file, case_hash, engine)?;
    for (name, u) in &seal.units {
        for (file, want) in &u.files {
            store::check_sealed_file(root, name, file, want, &store::nothing_regenerable, &hint)?;
        }
    }
    Ok(seal)
}

/// Checks a record against the case it is about to stand in for: the case's canonical
/// hash, each unit's fingerprint, every file's hash (file names checked to be plain
/// names inside the record before any is opened), and that the record's engine input
/// and its provenance agree with the fingerprint (a provenance or a stored deck that
/// contradicts the seal is refused). `units`: the units the comparison needs, in order;
/// `regenerate` writes again the files a lean record leaves out ([`store`]).
pub fn verify(
    root: &Path,
    case_file: &Path,
    case_hash: &Sha256,
    engine: EngineKind,
    units: &[UnitKey],
    regenerate: store::Regenerate,
) -> Result<Verified> {
    let hint = rerecord_hint(case_file);
    let seal = read_seal(root, case_file, case_hash, engine)?;
    let path = root.join(SEAL_FILE);
    for key in units {
        let (name, fingerprint) = (&key.name, &key.fingerprint);
        let Some(u) = seal.units.get(name) else {
            bail!(
                "{}: no recorded unit {name:?} (the record has {:?}); {hint}",
                path.display(),
                seal.units.keys().collect::<Vec<_>>()
            );
        };
        if &u.fingerprint != fingerprint {
            bail!(
                "{}: unit {name:?} was recorded from different engine input (sha256 {} in the seal, {} now); {hint}",
                path.display(),
                u.fingerprint,
                fingerprint
            );
        }
        for (file, want) in &u.files {
            store::check_sealed_file(root, name, file, want, regenerate, &hint)?;
        }
        check_engine_input(root, key, u, regenerate, &hint)?;
    }
    Ok(Verified {
        root: root.to_path_buf(),
        seal,
    })
}

/// The engine input a unit's record stores and the provenance it carries must be the
/// input the seal's fingerprint stands for: every input file sealed, their fingerprint
/// the one the case gives today, and `provenance.json`'s `input_hash` that same value.
/// The files' hashes alone prove only that nothing changed since sealing, not that what
/// was sealed is consistent.
fn check_engine_input(
    root: &Path,
    key: &UnitKey,
    u: &SealedUnit,
    regenerate: store::Regenerate,
    hint: &str,
) -> Result<()> {
    let dir = unit_dir(root, &key.name);
    let mut texts = Vec::with_capacity(key.input.len());
    for f in &key.input {
        ensure!(
            u.files.contains_key(*f),
            "{}: the record of unit {:?} does not hold its engine input {f} ({hint})",
            dir.display(),
            key.name
        );
        // Where the store keeps it (plain, compressed, a stored bed); a file a lean
        // record left out is the one written again from the unit. check_sealed_file
        // has just hashed either against the seal.
        let p = match store::locate(root, &key.name, f, &u.files[*f])? {
            Some(p) => p,
            None => dir.join(f),
        };
        let again = if p.exists() {
            None
        } else {
            regenerate(&key.name, f)
        };
        let text = match again {
            Some(bytes) => String::from_utf8(bytes?)
                .with_context(|| format!("{}: written again, not UTF-8", p.display()))?,
            None => std::fs::read_to_string(&p)
                .with_context(|| format!("cannot read {}", p.display()))?,
        };
        texts.push(text);
    }
    let stored = crate::engines::deck_text::fingerprint(
        &texts.iter().map(String::as_str).collect::<Vec<_>>(),
    );
    if stored != key.input_hash {
        bail!(
            "{}: the engine input stored in the record ({}) has fingerprint {stored}, but the input this case gives the engine has {}: the stored input contradicts the seal; {hint}",
            dir.display(),
            key.input.join(", "),
            key.input_hash
        );
    }
    if u.files.contains_key(PROVENANCE_FILE) {
        let p = dir.join(PROVENANCE_FILE);
        let prov = crate::rundata::provenance::read_provenance(&p)?;
        if prov.input_hash != key.input_hash {
            bail!(
                "{}: input_hash {} contradicts the seal's engine input (fingerprint {}); {hint}",
                p.display(),
                prov.input_hash,
                key.input_hash
            );
        }
    }
    Ok(())
}

/// The case file a record was made from: the seal's `case_file`, or for records sealed
/// before it was kept, the `case_file` a unit's provenance names when that is a case
/// file (`.toml`).
pub(crate) fn recorded_case_file(root: &Path) -> Option<PathBuf> {
    let seal: Seal =
        serde_json::from_str(&std::fs::read_to_string(root.join(SEAL_FILE)).ok()?).ok()?;
    if let Some(f) = seal.case_file {
        return Some(PathBuf::from(f));
    }
    seal.units.keys().find_map(|u| {
        let p =
            crate::rundata::provenance::read_provenance(&unit_dir(root, u).join(PROVENANCE_FILE))
                .ok()?;
        p.case_file
            .ends_with(".toml")
            .then(|| PathBuf::from(p.case_file))
    })
}

/// `reference refresh` of `case_file` (case `name`) into `root`: refused when the
/// record there was made from another case file that still declares the same name,
/// which the new record would silently replace. The same file (by its canonical path)
/// may be re-recorded, and a record whose case file is gone or renamed its case may be
/// replaced.
pub(crate) fn refuse_other_case_file(root: &Path, case_file: &Path, name: &str) -> Result<()> {
    let Some(recorded) = recorded_case_file(root) else {
        return Ok(());
    };
    let same = match (recorded.canonicalize(), case_file.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    let still_named = std::fs::read_to_string(&recorded)
        .ok()
        .and_then(|t| t.parse::<toml::Table>().ok())
        .and_then(|t| t.get("case")?.get("name")?.as_str().map(|n| n == name))
        .unwrap_or(false);
    if !same && still_named {
        bail!(
            "{}: case {name:?} is recorded there from {}, and {} declares the same [case] name: recording it would replace the other case's record; rename one of the two cases",
            root.display(),
            recorded.display(),
            case_file.display()
        );
    }
    Ok(())
}

/// Every record's provenance file.
pub const PROVENANCE_FILE: &str = "provenance.json";

/// Writes the seal of a freshly recorded case: every file now present in each unit's
/// directory (sub-directories excepted) is covered.
#[allow(clippy::too_many_arguments)]
pub fn write(
    root: &Path,
    case_name: &str,
    case_kind: &str,
    case_file: &Path,
    case_hash: &Sha256,
    engine: EngineKind,
    engine_version: &str,
    units: &[UnitKey],
) -> Result<Seal> {
    let mut sealed = BTreeMap::new();
    for UnitKey {
        name, fingerprint, ..
    } in units
    {
        let dir = unit_dir(root, name);
        let mut files = BTreeMap::new();
        for e in
            std::fs::read_dir(&dir).with_context(|| format!("cannot list {}", dir.display()))?
        {
            let e = e?;
            let fname = e.file_name().to_string_lossy().into_owned();
            if e.path().is_file() && fname != SEAL_FILE {
                files.insert(fname, Sha256::of_file(&e.path())?);
            }
        }
        ensure!(!files.is_empty(), "{}: nothing recorded", dir.display());
        sealed.insert(
            name.clone(),
            SealedUnit {
                fingerprint: fingerprint.clone(),
                files,
            },
        );
    }
    let seal = Seal {
        granval: env!("CARGO_PKG_VERSION").into(),
        case_name: case_name.into(),
        case_kind: case_kind.into(),
        case_sha256: case_hash.clone(),
        engine,
        engine_version: engine_version.into(),
        sealed: now_utc(),
        case_file: Some(case_file.display().to_string()),
        units: sealed,
        amendments: Vec::new(),
    };
    write_seal(root, &seal)?;
    Ok(seal)
}

/// Writes `seal` as the record's `seal.json` (the format [`write`] makes).
pub(crate) fn write_seal(root: &Path, seal: &Seal) -> Result<()> {
    let path = root.join(SEAL_FILE);
    std::fs::write(&path, serde_json::to_string_pretty(seal)? + "\n")
        .with_context(|| format!("cannot write {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use store::nothing_regenerable;

    fn key(fingerprint: Sha256) -> UnitKey {
        UnitKey {
            name: "bed-0".into(),
            input_hash: fingerprint.clone(),
            fingerprint,
            input: vec!["in.deck"],
        }
    }

    const DECK: &str = "# a deck\nrun 10\n";

    fn setup() -> (tempfile::TempDir, Sha256, Vec<UnitKey>) {
        let d = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(d.path().join("bed-0")).unwrap();
        std::fs::write(d.path().join("bed-0/force.txt"), "1 2 3\n").unwrap();
        std::fs::write(d.path().join("bed-0/in.deck"), DECK).unwrap();
        let case = Sha256::of(b"case");
        let units = vec![key(crate::engines::deck_text::fingerprint(&[DECK]))];
        write(
            d.path(),
            "c",
            "penetration",
            Path::new("c.toml"),
            &case,
            EngineKind::Liggghts,
            "LIGGGHTS (Version x)",
            &units,
        )
        .unwrap();
        (d, case, units)
    }

    /// A record names the case file it was made from; a refresh of another file that
    /// declares the same name is refused naming both, the same file (reached by another
    /// path) and a record whose file now names another case are not.
    #[test]
    fn a_record_is_not_replaced_by_another_case_file_of_the_same_name() {
        let (d, _, _) = setup();
        let cases = tempfile::tempdir().unwrap();
        let a = cases.path().join("a.toml");
        let b = cases.path().join("b.toml");
        std::fs::write(&a, "[case]\nname = \"c\"\n").unwrap();
        std::fs::write(&b, "[case]\nname = \"c\"\n").unwrap();
        let seal_path = d.path().join(SEAL_FILE);
        let mut seal: Seal =
            serde_json::from_str(&std::fs::read_to_string(&seal_path).unwrap()).unwrap();
        seal.case_file = Some(a.display().to_string());
        std::fs::write(&seal_path, serde_json::to_string(&seal).unwrap()).unwrap();
        assert_eq!(recorded_case_file(d.path()), Some(a.clone()));
        let e = format!(
            "{:#}",
            refuse_other_case_file(d.path(), &b, "c").unwrap_err()
        );
        assert!(
            e.contains(&*a.display().to_string()) && e.contains(&*b.display().to_string()),
            "{e}"
        );
        refuse_other_case_file(d.path(), &a, "c").unwrap();
        refuse_other_case_file(d.path(), &cases.path().join(".").join("a.toml"), "c").unwrap();
        std::fs::write(&a, "[case]\nname = \"renamed\"\n").unwrap();
        refuse_other_case_file(d.path(), &b, "c").unwrap();
        // No record yet: nothing to replace.
        refuse_other_case_file(&cases.path().join("none"), &b, "c").unwrap();
    }

    #[test]
    fn a_sealed_record_verifies_and_covers_only_its_files() {
        let (d, case, units) = setup();
        let v = verify(
            d.path(),
            Path::new("c.toml"),
            &case,
            EngineKind::Liggghts,
            &units,
            &nothing_regenerable,
        )
        .unwrap();
        assert!(v.file("bed-0", "force.txt").is_ok());
        assert!(v.file("bed-0", "other.txt").is_err());
    }

    #[test]
    fn tampering_swapping_and_wrong_input_are_refused() {
        let (d, case, units) = setup();
        let f = d.path().join("bed-0/force.txt");
        std::fs::write(&f, "1 2 3.000000000001\n").unwrap();
        let e = verify(
            d.path(),
            Path::new("c.toml"),
            &case,
            EngineKind::Liggghts,
            &units,
            &nothing_regenerable,
        )
        .unwrap_err();
        assert!(format!("{e:#}").contains("modified"), "{e:#}");
        std::fs::write(&f, "1 2 3\n").unwrap();
        let other = Sha256::of(b"another case");
        let e = verify(
            d.path(),
            Path::new("c.toml"),
            &other,
            EngineKind::Liggghts,
            &units,
            &nothing_regenerable,
        )
        .unwrap_err();
        assert!(format!("{e:#}").contains("different case"), "{e:#}");
        let moved = vec![key(Sha256::of(b"another deck"))];
        let e = verify(
            d.path(),
            Path::new("c.toml"),
            &case,
            EngineKind::Liggghts,
            &moved,
            &nothing_regenerable,
        )
        .unwrap_err();
        assert!(format!("{e:#}").contains("different engine input"), "{e:#}");
        let e = verify(
            d.path(),
            Path::new("c.toml"),
            &case,
            EngineKind::Lammps,
            &units,
            &nothing_regenerable,
        )
        .unwrap_err();
        assert!(format!("{e:#}").contains("reference engine"), "{e:#}");
        std::fs::remove_file(&f).unwrap();
        assert!(
            verify(
                d.path(),
                Path::new("c.toml"),
                &case,
                EngineKind::Liggghts,
                &units,
                &nothing_regenerable,
            )
            .is_err()
        );
    }
}
