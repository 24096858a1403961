//! Where a run came from: engine, version line, command, input hash, date, wall time.
//! A reference record is trusted only through this record and its seal.

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Where a run came from: enough to reproduce it and to refuse to trust it blindly.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Provenance {
    pub engine: String,
    /// Version line (LIGGGHTS: the first line of its log; native: crate version).
    pub version: String,
    pub command: String,
    /// SHA-256 of the input deck (LIGGGHTS) or of the case file (native).
    pub input_hash: String,
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
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_str(&text)
        .with_context(|| format!("{}: not a provenance record", path.display()))
}

pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    hex::encode(sha2::Sha256::digest(bytes))
}

pub fn now_utc() -> String {
    chrono::Utc::now().to_rfc3339_opts(chrono::SecondsFormat::Secs, true)
}
