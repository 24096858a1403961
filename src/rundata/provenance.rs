//! Where a run came from: engine, version line, command, input hash, date, wall time.
//! A reference record is trusted only through this record and its seal.

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Which program produced a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EngineKind {
    Native,
    Liggghts,
    Lammps,
}

impl EngineKind {
    /// Only these may produce data under `reference/`.
    pub(crate) fn is_reference(self) -> bool {
        matches!(self, EngineKind::Liggghts | EngineKind::Lammps)
    }

    /// The lower-case key an engine is stored under (its serde form, and the key of
    /// per-engine maps in run summaries).
    pub(crate) fn key(self) -> &'static str {
        match self {
            EngineKind::Native => "native",
            EngineKind::Liggghts => "liggghts",
            EngineKind::Lammps => "lammps",
        }
    }

    /// The engine whose [`EngineKind::key`] is exactly `key`; `None` otherwise.
    pub(crate) fn from_key(key: &str) -> Option<EngineKind> {
        [EngineKind::Native, EngineKind::Liggghts, EngineKind::Lammps]
            .into_iter()
            .find(|e| e.key() == key)
    }

    pub fn label(self) -> &'static str {
        match self {
            EngineKind::Native => "native",
            EngineKind::Liggghts => "LIGGGHTS",
            EngineKind::Lammps => "LAMMPS",
        }
    }
}

impl std::fmt::Display for EngineKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.label())
    }
}

/// A SHA-256 digest, written as 64 lowercase hex digits.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct Sha256(String);

impl Sha256 {
    pub fn of(bytes: &[u8]) -> Sha256 {
        Sha256(sha256_hex(bytes))
    }

    /// Digest of a file, streamed in chunks. The file must be a regular file (checked
    /// before it is opened: a FIFO in a record would block, `/dev/zero` never end) and
    /// is read up to the size its metadata gave: a file that grows while it is hashed is
    /// an error, not an endless read.
    pub fn of_file(path: &Path) -> Result<Sha256> {
        use sha2::Digest;
        use std::io::Read;
        let what = "a file granval hashes";
        let size = super::fsio::check_regular(path, u64::MAX, what)?;
        let mut f = super::fsio::open_unlined(path, size, what)?;
        let mut h = sha2::Sha256::new();
        let mut buf = vec![0u8; 1 << 16];
        loop {
            let n = f
                .read(&mut buf)
                .with_context(|| format!("cannot read {}", path.display()))?;
            if n == 0 {
                break;
            }
            h.update(&buf[..n]);
        }
        Ok(Sha256(hex::encode(h.finalize())))
    }

    pub fn hex(&self) -> &str {
        &self.0
    }
}

impl TryFrom<String> for Sha256 {
    type Error = String;
    fn try_from(s: String) -> std::result::Result<Sha256, String> {
        if s.len() == 64
            && s.bytes()
                .all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
        {
            Ok(Sha256(s))
        } else {
            Err(format!(
                "{s:?} is not a SHA-256 digest (64 lowercase hex digits)"
            ))
        }
    }
}

impl From<Sha256> for String {
    fn from(h: Sha256) -> String {
        h.0
    }
}

impl std::fmt::Display for Sha256 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// Where a run came from: enough to reproduce it and to refuse to trust it blindly.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Provenance {
    pub engine: EngineKind,
    /// Version line (LIGGGHTS: the first line of its log; native: crate version).
    pub version: String,
    pub command: String,
    /// SHA-256 of what the engine was given: deck and data files (reference engines),
    /// the case's canonical content or scene (native).
    pub input_hash: Sha256,
    pub date: String,
    pub wall_time_s: f64,
    pub threads: usize,
    pub case_file: String,
    #[serde(default)]
    pub notes: Vec<String>,
}

pub fn write_provenance(path: &Path, p: &Provenance) -> Result<()> {
    std::fs::write(path, serde_json::to_string_pretty(p)? + "\n")
        .with_context(|| format!("cannot write {}", path.display()))
}

pub fn read_provenance(path: &Path) -> Result<Provenance> {
    let text = super::fsio::read_to_string(
        path,
        super::fsio::MAX_RECORD_JSON,
        "a provenance record (JSON)",
    )?;
    serde_json::from_str(&text)
        .with_context(|| format!("{}: not a provenance record", path.display()))
}

/// The git commit this granval was built from, when the build knew it (build.rs): what
/// computed a run seal or judged a report.
pub(crate) fn git_commit() -> Option<String> {
    option_env!("GRANVAL_GIT_COMMIT")
        .filter(|c| !c.is_empty())
        .map(str::to_string)
}

pub(crate) fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    hex::encode(sha2::Sha256::digest(bytes))
}

pub fn now_utc() -> String {
    chrono::Utc::now().to_rfc3339_opts(chrono::SecondsFormat::Secs, true)
}
