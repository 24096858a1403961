//! What a penetration run directory was written with (`inputs.json`), so that `granval
//! analyze` can refuse a directory whose inputs are not the ones granval wrote.
//!
//! micro and impact2d deck directories are checked by writing their inputs again from
//! the case and comparing (`read_run_dir`). A penetration deck cannot be rewritten that
//! way: it starts from a bed that took the native engine minutes to hours to settle, and
//! whatever `data.bed` a directory holds gives a deck consistent with itself. So when
//! granval writes a run directory (`granval deck`, `compare`'s LIGGGHTS run) it also
//! writes this manifest: the case's canonical hash, the bed (number, seed, sha256) and the
//! fingerprint of every input file. `analyze` checks the whole directory against it (an
//! edited, missing or foreign input is refused, naming the file), and then still writes
//! the deck again from the case and the bed it read and compares, as for the other
//! kinds. A person who edits an input and rewrites the manifest to match can pass the
//! first check; the second then still refuses anything but the deck of this case on the
//! bed in `data.bed`. What it cannot tell is whether that bed is the one the native
//! engine settled for this case (which would take the settling again to prove).

use crate::engines::deck_text;
use crate::engines::lammps3d_penetration as lmp;
use crate::engines::liggghts::clump_bed;
use crate::engines::liggghts::penetration as lp;
use crate::rundata::provenance::Sha256;
use anyhow::{Context, Result, bail, ensure};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

pub(crate) const MANIFEST_FILE: &str = "inputs.json";

/// Every file name an input of a penetration run directory can have: one present that
/// the manifest does not list is foreign (it would change what `analyze` reads, e.g. a
/// `data.lattice` makes the directory a LIGGGHTS-settled one).
const INPUT_NAMES: [&str; 7] = [
    lp::DECK_FILE,
    lp::DATA_FILE,
    lp::LATTICE_FILE,
    clump_bed::BODIES_FILE,
    lp::STL_FILE,
    lmp::DECK_FILE,
    lmp::DATA_FILE,
];

/// `inputs.json` of a run directory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct InputManifest {
    pub granval: String,
    pub case: String,
    /// Canonical hash of the whole case (`case.toml` of the deck directory).
    pub case_sha256: Sha256,
    /// Bed number K (directory `bed-K`) and its seed.
    pub bed: usize,
    pub seed: u64,
    /// sha256 of the bed the deck starts from ([`super::bed::bed_hash`]); none when
    /// LIGGGHTS settles the bed itself.
    #[serde(default)]
    pub bed_sha256: Option<Sha256>,
    /// Fingerprint ([`deck_text::fingerprint`]: comments and layout aside) of each input
    /// file as written.
    pub inputs: BTreeMap<String, Sha256>,
    /// The visualisation dump interval the deck was written with (`granval deck --viz
    /// N`); none for a deck without one. `analyze` writes the deck again with it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub viz_every: Option<u64>,
}

impl InputManifest {
    /// The manifest of the inputs just written into `dir`.
    pub(crate) fn of_dir(
        dir: &Path,
        case: &crate::case::penetration::PenetrationCase,
        bed: usize,
        seed: u64,
        bed_sha256: Option<Sha256>,
    ) -> Result<InputManifest> {
        let mut inputs = BTreeMap::new();
        for name in INPUT_NAMES {
            let p = dir.join(name);
            if p.exists() {
                inputs.insert(name.to_string(), fingerprint_of(&p)?);
            }
        }
        ensure!(
            inputs.contains_key(lp::DECK_FILE) != inputs.contains_key(lmp::DECK_FILE),
            "{}: neither {} (LIGGGHTS) nor {} (LAMMPS) alone to record",
            dir.display(),
            lp::DECK_FILE,
            lmp::DECK_FILE
        );
        Ok(InputManifest {
            granval: env!("CARGO_PKG_VERSION").into(),
            case: case.name.clone(),
            case_sha256: crate::case::ValidatedCase::canonical_hash(case),
            bed,
            seed,
            bed_sha256,
            inputs,
            viz_every: None,
        })
    }

    pub fn write(&self, dir: &Path) -> Result<()> {
        let p = dir.join(MANIFEST_FILE);
        std::fs::write(&p, serde_json::to_string_pretty(self)? + "\n")
            .with_context(|| format!("cannot write {}", p.display()))
    }

    pub fn read(dir: &Path) -> Result<InputManifest> {
        let p = dir.join(MANIFEST_FILE);
        let record = dir
            .parent()
            .is_some_and(|r| r.join(crate::experiments::reference::SEAL_FILE).is_file());
        let text = std::fs::read_to_string(&p).with_context(|| {
            if record {
                format!(
                    "{}: missing: this is a sealed reference record, not a deck directory; a record is read through its seal by `granval compare CASE --reference-mode recorded`",
                    p.display()
                )
            } else {
                format!(
                    "{}: missing: this run directory was not written by this granval's `deck` or `compare` (write the deck again with `granval deck`)",
                    p.display()
                )
            }
        })?;
        serde_json::from_str(&text)
            .with_context(|| format!("{}: not an inputs manifest", p.display()))
    }

    /// Refuses `dir` unless it holds exactly the inputs of this manifest, each with its
    /// fingerprint, for `case` (its canonical hash, `case_file` naming it), bed `bed` with
    /// `seed`. The error names the file and says what is wrong with it.
    pub fn check(
        &self,
        dir: &Path,
        case: &crate::case::penetration::PenetrationCase,
        case_file: &Path,
        bed: usize,
        seed: u64,
    ) -> Result<()> {
        let here = dir.join(MANIFEST_FILE);
        let hash = crate::case::ValidatedCase::canonical_hash(case);
        if self.case_sha256 != hash {
            bail!(
                "{}: the case is not the one this deck was written for ({} names case sha256 {}, {} has {hash}): edit the case, then write the deck again",
                case_file.display(),
                here.display(),
                self.case_sha256,
                case_file.display()
            );
        }
        if (self.bed, self.seed) != (bed, seed) {
            bail!(
                "{}: written for bed {} (seed {}), found as bed {bed} (seed {seed}): a directory of another bed",
                here.display(),
                self.bed,
                self.seed
            );
        }
        for (name, want) in &self.inputs {
            crate::rundata::file_seal::plain_name(name)
                .with_context(|| format!("{}: input", here.display()))?;
            let p = dir.join(name);
            if !p.exists() {
                bail!(
                    "{}: missing: an input of this deck (listed in {}); copy the whole deck directory back",
                    p.display(),
                    here.display()
                );
            }
            let got = fingerprint_of(&p)?;
            if &got != want {
                bail!(
                    "{}: not the input granval wrote (fingerprint {got}, written {want}; comments and layout aside): edited by hand or of another deck. Analyse only unedited `granval deck` directories; to run changed physics, change the case and write the deck again",
                    p.display()
                );
            }
        }
        for name in INPUT_NAMES {
            if !self.inputs.contains_key(name) && dir.join(name).exists() {
                bail!(
                    "{}: a foreign input: this deck was written without it (it lists {:?}); remove it or write the deck again",
                    dir.join(name).display(),
                    self.inputs.keys().collect::<Vec<_>>()
                );
            }
        }
        Ok(())
    }

    /// Whether this directory's deck is LAMMPS 2025's (`granval deck --engine lammps`).
    pub(crate) fn is_lammps(&self) -> bool {
        self.inputs.contains_key(lmp::DECK_FILE)
    }

    /// Whether this directory's deck settles its own bed in LIGGGHTS.
    pub(crate) fn settles_in_liggghts(&self) -> bool {
        self.inputs.contains_key(lp::LATTICE_FILE)
    }
}

/// Fingerprint of one input file: its canonical form ([`deck_text::fingerprint`]).
fn fingerprint_of(p: &Path) -> Result<Sha256> {
    let meta =
        std::fs::symlink_metadata(p).with_context(|| format!("cannot read {}", p.display()))?;
    ensure!(
        meta.file_type().is_file(),
        "{}: not a regular file",
        p.display()
    );
    let text =
        std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))?;
    Ok(deck_text::fingerprint(&[&text]))
}
