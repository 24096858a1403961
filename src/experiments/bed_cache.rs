//! An opt-in on-disk cache of prepared beds (`GRANVAL_BED_CACHE=DIR`): preparing a bed
//! (pour and settle) often costs more than the runs that use it, and the release suite
//! prepares the same beds again for the recording and for the comparison. A bed is keyed
//! by the granval version and everything it was prepared from, so a changed case or a
//! new build never reads a stale bed; the beds are still fingerprinted into every run's
//! provenance and seal as before, so a cached bed that differed would fail the seal.

use crate::rundata::provenance::Sha256;
use serde::{Serialize, de::DeserializeOwned};
use std::path::{Path, PathBuf};

/// The file name of a bed of `kind` prepared from `spec`, in the cache and in a
/// reference record alike: the key changes with the spec and the granval version.
pub fn name(kind: &str, spec: &impl Serialize) -> Option<String> {
    let key = Sha256::of(
        format!(
            "{} {}",
            env!("CARGO_PKG_VERSION"),
            serde_json::to_string(spec).ok()?
        )
        .as_bytes(),
    );
    Some(format!("{kind}-bed-{key}.json"))
}

/// The cache file of a bed of `kind` prepared from `spec` (None: no cache configured).
pub fn file(kind: &str, spec: &impl Serialize) -> Option<PathBuf> {
    in_cache(&name(kind, spec)?)
}

/// Where the bed stored as `name` lives in the cache (None: no cache configured).
pub fn in_cache(name: &str) -> Option<PathBuf> {
    Some(PathBuf::from(std::env::var_os("GRANVAL_BED_CACHE")?).join(name))
}

/// Appended to the note of a bed read from a reference record.
pub const FROM_RECORD_NOTE: &str = "; taken from the sealed reference record, where it was stored when the reference run was recorded (not settled again here)";

/// The cached bed, if there is a readable one.
pub fn load<T: DeserializeOwned>(file: Option<&Path>) -> Option<T> {
    let bytes = crate::rundata::fsio::read(
        file?,
        crate::rundata::fsio::MAX_RECORD_JSON,
        "a prepared bed (JSON)",
    );
    serde_json::from_slice(&bytes.ok()?).ok()
}

/// Stores a bed; a failure only costs the next run a preparation.
pub fn store<T: Serialize>(file: Option<&Path>, bed: &T) {
    if let Some(path) = file {
        let _ = std::fs::create_dir_all(path.parent().unwrap_or(Path::new(".")));
        let _ = std::fs::write(path, serde_json::to_vec(bed).unwrap_or_default());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::Particle;
    use crate::physics::dem::packing::Bed;

    /// A cached bed must be the bed, bit for bit: its fingerprint goes into every seal.
    #[test]
    fn a_stored_bed_reads_back_bit_identical() {
        let d = tempfile::tempdir().unwrap();
        let f = d.path().join("x/b.json");
        let awkward: [f64; 5] = [
            0.1 + 0.2,
            1.0 / 3.0,
            -2.2250738585072014e-308,
            1e-300,
            5e-324,
        ];
        let bed = Bed {
            particles: (0..5)
                .map(|i| Particle {
                    id: i as u64 + 1,
                    type_: 0,
                    radius: awkward[i].abs() + 1e-3,
                    density: 2500.0,
                    x: [awkward[i], awkward[(i + 1) % 5], awkward[(i + 2) % 5]],
                    v: [awkward[(i + 3) % 5], 0.0, -0.0],
                    omega: [1.0 / 7.0, 0.0, awkward[(i + 4) % 5]],
                })
                .collect(),
            bodies: vec![crate::case::clumps::Clump {
                id: 6,
                template: 0,
                x: [awkward[1], awkward[3], -awkward[0]],
                orientation: [awkward[0], -1.0 / 3.0, 0.5, awkward[4]],
                v: [awkward[2], 1e-300, 0.0],
                omega: [-0.0, awkward[1], 7.0],
            }],
            surface_z: (0.1f64 + 0.2) / 7.0,
            psi: 0.5941,
            ke_ratio: 8.01e-8,
            settle_time: 0.342,
            ke_at_end_of_pour: 1.0 / 3.0,
        };
        store(Some(&f), &bed);
        let back: Bed = load(Some(&f)).expect("cached bed");
        let bits = |b: &Bed| {
            let mut v: Vec<u64> =
                vec![b.surface_z.to_bits(), b.psi.to_bits(), b.ke_ratio.to_bits()];
            for p in &b.particles {
                v.extend(p.x.iter().chain(&p.v).chain(&p.omega).map(|x| x.to_bits()));
                v.push(p.radius.to_bits());
            }
            for c in &b.bodies {
                v.extend(
                    c.x.iter()
                        .chain(&c.orientation)
                        .chain(&c.v)
                        .chain(&c.omega)
                        .map(|x| x.to_bits()),
                );
            }
            v
        };
        assert_eq!(bits(&bed), bits(&back));
        assert!(load::<Bed>(Some(&d.path().join("missing.json"))).is_none());
        assert!(load::<Bed>(None).is_none());
    }
}
