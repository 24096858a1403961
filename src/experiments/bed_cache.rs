//! An opt-in on-disk cache of prepared beds (`GRANVAL_BED_CACHE=DIR`): preparing a bed
//! (pour and settle) often costs more than the runs that use it, and the release suite
//! prepares the same beds again for the recording and for the comparison. A bed is keyed
//! by the granval version and everything it was prepared from, so a changed case or a
//! new build never reads a stale bed; the beds are still fingerprinted into every run's
//! provenance and seal as before, so a cached bed that differed would fail the seal.

use crate::rundata::provenance::Sha256;
use anyhow::{Context, Result, bail};
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
pub(crate) fn in_cache(name: &str) -> Option<PathBuf> {
    Some(PathBuf::from(std::env::var_os("GRANVAL_BED_CACHE")?).join(name))
}

/// Appended to the note of a bed read from a reference record.
pub(crate) const FROM_RECORD_NOTE: &str = "; taken from the sealed reference record, where it was stored when the reference run was recorded (not settled again here)";

/// The bed stored as `file` in a sealed reference record, if there is a readable one
/// (the record's seal, checked before the comparison goes on, covers it).
pub fn load<T: DeserializeOwned>(file: Option<&Path>) -> Option<T> {
    let bytes = crate::rundata::fsio::read(
        file?,
        crate::rundata::fsio::MAX_RECORD_JSON,
        "a prepared bed (JSON)",
    );
    serde_json::from_slice(&bytes.ok()?).ok()
}

/// The seal beside a cached bed (`<bed file>.seal.json`): what it was prepared from
/// and its sha256.
#[derive(Serialize, serde::Deserialize, PartialEq, Debug)]
#[serde(deny_unknown_fields)]
struct CacheSeal {
    granval: String,
    /// The bed's specification as prepared (JSON; it holds the seed).
    spec: String,
    /// sha256 of the bed file's bytes.
    sha256: Sha256,
}

fn seal_path(file: &Path) -> PathBuf {
    let mut name = file.file_name().unwrap_or_default().to_os_string();
    name.push(".seal.json");
    file.with_file_name(name)
}

/// The cached bed of `spec` in `file` (None: no cache, or no bed cached yet). A cache
/// file is used only when its seal (written by [`store`]) names this specification and
/// the file's sha256, and `check` (the case's own count of grains) accepts the bed;
/// anything else is an error naming the file, never a bed prepared elsewhere reported
/// as prepared here. The seal is written by granval and can be rewritten by a person
/// too: it stops a stale, truncated or hand-made file, not a forger.
pub(crate) fn load_cached<T: DeserializeOwned>(
    file: Option<&Path>,
    spec: &impl Serialize,
    check: impl Fn(&T) -> Result<()>,
) -> Result<Option<T>> {
    let Some(file) = file else { return Ok(None) };
    if !file.exists() {
        return Ok(None);
    }
    let remedy = "move it out of GRANVAL_BED_CACHE: granval then prepares the bed again and stores it sealed";
    let sp = seal_path(file);
    let seal: CacheSeal = std::fs::read_to_string(&sp)
        .map_err(anyhow::Error::from)
        .and_then(|t| Ok(serde_json::from_str(&t)?))
        .with_context(|| {
            format!(
                "{}: a cached bed without a readable seal ({}); {remedy}",
                file.display(),
                sp.display()
            )
        })?;
    let want = serde_json::to_string(spec)?;
    if seal.spec != want {
        bail!(
            "{}: cached for another specification ({} names {}, this bed is {want}); {remedy}",
            file.display(),
            sp.display(),
            seal.spec
        );
    }
    let got = crate::rundata::file_seal::digest(
        file.parent().unwrap_or(Path::new(".")),
        &file.file_name().unwrap_or_default().to_string_lossy(),
    )?;
    if got != seal.sha256 {
        bail!(
            "{}: content differs from its seal (sha256 {got}, sealed {}); {remedy}",
            file.display(),
            seal.sha256
        );
    }
    let bed: T = serde_json::from_slice(&std::fs::read(file)?)
        .with_context(|| format!("{}: not a bed; {remedy}", file.display()))?;
    check(&bed).with_context(|| format!("{}: {remedy}", file.display()))?;
    Ok(Some(bed))
}

/// Stores a bed of `spec` with its seal; a failure only costs the next run a preparation.
pub fn store<T: Serialize>(file: Option<&Path>, spec: &impl Serialize, bed: &T) {
    if let Some(path) = file {
        let _ = std::fs::create_dir_all(path.parent().unwrap_or(Path::new(".")));
        let bytes = serde_json::to_vec(bed).unwrap_or_default();
        if std::fs::write(path, &bytes).is_err() {
            return;
        }
        let seal = CacheSeal {
            granval: env!("CARGO_PKG_VERSION").into(),
            spec: serde_json::to_string(spec).unwrap_or_default(),
            sha256: Sha256::of(&bytes),
        };
        let _ = std::fs::write(
            seal_path(path),
            serde_json::to_string_pretty(&seal).unwrap_or_default() + "\n",
        );
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
        store(Some(&f), &"spec", &bed);
        let back: Bed = load_cached(Some(&f), &"spec", |_: &Bed| Ok(()))
            .unwrap()
            .expect("cached bed");
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
        let none = |p: Option<&Path>| load_cached::<Bed>(p, &"spec", |_| Ok(())).unwrap();
        assert!(none(Some(&d.path().join("missing.json"))).is_none());
        assert!(none(None).is_none());
    }

    /// A cached bed is used only through its seal: of another specification, edited,
    /// without a seal, or refused by the case's check, it is an error naming the file;
    /// the sealed one (the negative control) is used.
    #[test]
    fn a_cached_bed_is_checked_before_use() {
        let d = tempfile::tempdir().unwrap();
        let f = d.path().join("b.json");
        let bed = vec![1.0f64, 2.0, 3.0];
        store(Some(&f), &("spec", 7u64), &bed);
        let ok = |_: &Vec<f64>| Ok(());
        assert_eq!(
            load_cached(Some(&f), &("spec", 7u64), ok).unwrap(),
            Some(bed.clone())
        );
        let err = |spec: (&str, u64), check: &dyn Fn(&Vec<f64>) -> Result<()>| {
            format!("{:#}", load_cached(Some(&f), &spec, check).unwrap_err())
        };
        // Another seed.
        let e = err(("spec", 8), &ok);
        assert!(
            e.contains("b.json") && e.contains("another specification"),
            "{e}"
        );
        // The case's own check (e.g. 5 grains where the case pours 2000).
        let e = err(("spec", 7), &|b| {
            anyhow::ensure!(b.len() == 2000, "{} grains, the case pours 2000", b.len());
            Ok(())
        });
        assert!(e.contains("3 grains, the case pours 2000"), "{e}");
        // Edited after it was stored.
        std::fs::write(&f, "[1.0,2.0]").unwrap();
        let e = err(("spec", 7), &ok);
        assert!(e.contains("content differs from its seal"), "{e}");
        // No seal at all (written by hand, or before beds were sealed).
        std::fs::remove_file(seal_path(&f)).unwrap();
        let e = err(("spec", 7), &ok);
        assert!(e.contains("without a readable seal"), "{e}");
    }
}
