//! Settling checkpoints of 2D beds, kept in the bed cache (`GRANVAL_BED_CACHE=DIR`).
//!
//! Settling a bed to K's 1e-10 m g d takes minutes at 6000 disks and hours at the 20 000
//! of K Fig 12 (the column rings down with an e-folding time of thousands of tau_c,
//! docs/release.md), longer than a cluster job's wall time or a working session may
//! run. While a bed settles, its state is saved here every ten minutes of wall time and
//! when its time cap runs out; the next command that needs the same bed continues from
//! the last save and prepares, bit for bit, the bed an uninterrupted settling prepares
//! (`physics::dem2d::bed::prepare_resumable`). Once the finished bed is stored in the
//! cache with its seal, its checkpoint is removed: it is granval's own intermediate
//! file, and the sealed bed holds everything it did.
//!
//! The file is named by the sha256 of the bed specification without its time cap, so
//! raising `bed.max_settle_time` continues the same settling, and any other change
//! (seed, count, a coefficient) starts a new one. It is zstd-compressed JSON with the
//! frame checksum on and written atomically, so a killed job leaves the previous save.

use crate::physics::dem2d::bed::{self, BedSpec, Checkpoints, SettleCheckpoint};
use crate::rundata::provenance::Sha256;
use anyhow::{Context, Result};
use std::io::{Read, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Wall time between saves: a killed job loses at most this much settling.
const EVERY: Duration = Duration::from_secs(600);

/// zstd level: a save of 20 000 disks is a few MB of JSON and must not stall the run.
const LEVEL: i32 = 3;

/// The checkpoint file of one bed specification in the bed cache.
pub(crate) struct CheckpointFile {
    path: PathBuf,
    every: Duration,
    last: Instant,
    /// Say where a settling continues from (off for quiet runs).
    tell: bool,
}

impl CheckpointFile {
    /// The checkpoint file of `spec` (None when no bed cache is configured).
    pub(crate) fn for_spec(spec: &BedSpec, tell: bool) -> Option<CheckpointFile> {
        let dir = std::env::var_os("GRANVAL_BED_CACHE")?;
        let key =
            Sha256::of(format!("{} {}", env!("CARGO_PKG_VERSION"), bed::identity(spec)).as_bytes());
        Some(CheckpointFile {
            path: PathBuf::from(dir).join(format!("impact2d-settle-{key}.json.zst")),
            every: EVERY,
            last: Instant::now(),
            tell,
        })
    }

    /// The bed is stored in the cache: its checkpoint has nothing more to give.
    pub(crate) fn finished(self) {
        let _ = std::fs::remove_file(&self.path);
    }

    fn remedy(&self) -> String {
        format!(
            "move {} out of GRANVAL_BED_CACHE to settle the bed from the pour",
            self.path.display()
        )
    }
}

impl Checkpoints for CheckpointFile {
    fn resume(&mut self) -> Result<Option<SettleCheckpoint>> {
        if !self.path.exists() {
            return Ok(None);
        }
        let read = || -> Result<SettleCheckpoint> {
            let mut json = Vec::new();
            zstd::stream::Decoder::new(std::fs::File::open(&self.path)?)?.read_to_end(&mut json)?;
            Ok(serde_json::from_slice(&json)?)
        };
        let c = read().with_context(|| {
            format!(
                "{}: not a readable settling checkpoint; {}",
                self.path.display(),
                self.remedy()
            )
        })?;
        if self.tell {
            eprintln!(
                "continuing the bed's {} settling from {}",
                match c.phase() {
                    bed::Phase::First => "first",
                    bed::Phase::Second { .. } => "second (after smoothing)",
                },
                self.path.display()
            );
        }
        Ok(Some(c))
    }

    fn due(&mut self) -> bool {
        self.last.elapsed() >= self.every
    }

    fn save(&mut self, c: &SettleCheckpoint) -> Result<()> {
        let json = serde_json::to_vec(c)?;
        let mut enc = zstd::stream::Encoder::new(Vec::new(), LEVEL)?;
        enc.include_checksum(true)?;
        enc.write_all(&json)?;
        let bytes = enc.finish()?;
        if let Some(dir) = self.path.parent() {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create {}", dir.display()))?;
        }
        crate::rundata::fsio::write_atomic(&self.path, &bytes)?;
        self.last = Instant::now();
        Ok(())
    }

    fn kept_at(&self) -> Option<String> {
        Some(self.path.display().to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bed stopped by its cap continues from its checkpoint file to the bed an
    /// uninterrupted settling prepares; a damaged file is an error naming it and the
    /// way out, never a settling from the pour reported as continued.
    #[test]
    fn a_bed_continues_from_its_file_and_a_damaged_file_is_refused() {
        use crate::physics::dem2d::bed::{prepare, prepare_resumable};
        // The unit tests' small bed, with static friction (k_t > 0: the shear history
        // is part of what the file must keep).
        let mut spec = crate::physics::dem2d::bed::tests::spec();
        for c in &mut spec.coeffs {
            c.kt = 0.5 * c.kn;
        }
        let whole = prepare(&spec, |_, _| {}).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let file = |every| CheckpointFile {
            path: dir.path().join("sub/c.json.zst"),
            every,
            last: Instant::now(),
            tell: false,
        };
        let capped = BedSpec {
            max_settle_time: 0.3 * whole.settle_time,
            ..spec.clone()
        };
        let e = format!(
            "{:#}",
            prepare_resumable(&capped, &mut file(Duration::from_secs(3600)), |_, _| {})
                .unwrap_err()
        );
        assert!(e.contains("its state is kept in"), "{e}");
        let go_on = prepare_resumable(&spec, &mut file(Duration::ZERO), |_, _| {}).unwrap();
        assert_eq!(
            serde_json::to_string(&go_on).unwrap(),
            serde_json::to_string(&whole).unwrap()
        );
        let f = file(Duration::ZERO);
        let mut bytes = std::fs::read(&f.path).unwrap();
        let mid = bytes.len() / 2;
        bytes[mid] ^= 0xff;
        std::fs::write(&f.path, &bytes).unwrap();
        let e = format!(
            "{:#}",
            prepare_resumable(&spec, &mut file(Duration::ZERO), |_, _| {}).unwrap_err()
        );
        assert!(
            e.contains("not a readable settling checkpoint")
                && e.contains("out of GRANVAL_BED_CACHE"),
            "{e}"
        );
        f.finished();
        assert!(!dir.path().join("sub/c.json.zst").exists());
    }
}
