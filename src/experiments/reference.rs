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
//! (a data file); [`super::record_store`] says where, the seal stays as recorded.

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
pub enum Source {
    /// The engine runs now; the banner line of the installed binary.
    Live { version: String },
    /// A sealed record, verified.
    Recorded { seal: Box<Verified> },
    /// A run directory a user brought back (`granval analyze`): not sealed, said so.
    RunDir { dir: PathBuf },
}

impl Source {
    pub fn describe(&self) -> String {
        match self {
            Source::Live { .. } => "live".into(),
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
    /// Unit name -> contents, in unit order.
    pub units: BTreeMap<String, SealedUnit>,
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
        // A bed may live in the record store (`record_store`), found by its sealed hash.
        Ok(super::record_store::locate(&self.root, unit, name, sha)
            .unwrap_or_else(|| unit_dir(&self.root, unit).join(name)))
    }
}

fn rerecord_hint(case_file: &Path) -> String {
    format!(
        "re-record it where the reference engine is installed: `granval reference refresh --only {}`",
        case_file.display()
    )
}

/// Checks a record against the case it is about to stand in for: the case's canonical
/// hash, each unit's fingerprint, and every file's hash. `units` are (name, fingerprint)
/// of the units the comparison needs, in order; `regenerate` writes again the files a
/// lean record leaves out (`record_store`).
pub fn verify(
    root: &Path,
    case_file: &Path,
    case_hash: &Sha256,
    engine: EngineKind,
    units: &[(String, Sha256)],
    regenerate: super::record_store::Regenerate,
) -> Result<Verified> {
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
    for (name, fingerprint) in units {
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
            super::record_store::check_sealed_file(root, name, file, want, regenerate, &hint)?;
        }
    }
    Ok(Verified {
        root: root.to_path_buf(),
        seal,
    })
}

/// Writes the seal of a freshly recorded case: every file now present in each unit's
/// directory (sub-directories excepted) is covered.
pub fn write(
    root: &Path,
    case_name: &str,
    case_kind: &str,
    case_hash: &Sha256,
    engine: EngineKind,
    engine_version: &str,
    units: &[(String, Sha256)],
) -> Result<Seal> {
    let mut sealed = BTreeMap::new();
    for (name, fingerprint) in units {
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
        units: sealed,
    };
    let path = root.join(SEAL_FILE);
    std::fs::write(&path, serde_json::to_string_pretty(&seal)? + "\n")
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(seal)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiments::record_store::nothing_regenerable;

    fn setup() -> (tempfile::TempDir, Sha256, Vec<(String, Sha256)>) {
        let d = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(d.path().join("bed-0")).unwrap();
        std::fs::write(d.path().join("bed-0/force.txt"), "1 2 3\n").unwrap();
        let case = Sha256::of(b"case");
        let units = vec![("bed-0".to_string(), Sha256::of(b"deck"))];
        write(
            d.path(),
            "c",
            "penetration",
            &case,
            EngineKind::Liggghts,
            "LIGGGHTS (Version x)",
            &units,
        )
        .unwrap();
        (d, case, units)
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
        let moved = vec![("bed-0".to_string(), Sha256::of(b"another deck"))];
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
