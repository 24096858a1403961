//! An opt-in on-disk cache of prepared beds (`GRANVAL_BED_CACHE=DIR`): preparing a bed
//! (pour and settle) often costs more than the runs that use it, and the release suite
//! prepares the same beds again for the recording and for the comparison. A bed is keyed
//! by the granval version and everything it was prepared from, so a changed case or a
//! new build never reads a stale bed; the beds are still fingerprinted into every run's
//! provenance and seal as before, so a cached bed that differed would fail the seal.

use crate::rundata::provenance::Sha256;
use serde::{Serialize, de::DeserializeOwned};
use std::path::{Path, PathBuf};

/// The cache file of a bed of `kind` prepared from `spec` (None: no cache configured).
pub fn file(kind: &str, spec: &impl Serialize) -> Option<PathBuf> {
    let dir = std::env::var_os("GRANVAL_BED_CACHE")?;
    let key = Sha256::of(
        format!(
            "{} {}",
            env!("CARGO_PKG_VERSION"),
            serde_json::to_string(spec).ok()?
        )
        .as_bytes(),
    );
    Some(PathBuf::from(dir).join(format!("{kind}-bed-{key}.json")))
}

/// The cached bed, if there is a readable one.
pub fn load<T: DeserializeOwned>(file: Option<&Path>) -> Option<T> {
    serde_json::from_slice(&std::fs::read(file?).ok()?).ok()
}

/// Stores a bed; a failure only costs the next run a preparation.
pub fn store<T: Serialize>(file: Option<&Path>, bed: &T) {
    if let Some(path) = file {
        let _ = std::fs::create_dir_all(path.parent().unwrap_or(Path::new(".")));
        let _ = std::fs::write(path, serde_json::to_vec(bed).unwrap_or_default());
    }
}
