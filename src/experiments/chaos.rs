//! The chaos baseline of docs/statistics.md: how far one engine drifts from itself. Every
//! bed of a penetration case runs natively twice, as prepared and with every grain moved
//! by one unit in the last place of x, and the two runs are reduced exactly as the
//! engine gate reduces a native and a reference run (rule 3's common fit range, each bed
//! fitted alone on it). The per-bed log ratios c_k = ln(K_k / K'_k) are what two runs of
//! the same physics do to each other; an engine difference is evidence of different
//! physics only beyond them. A Kondic (2D) case does the same per variant: its scene as
//! built and with every bed disk moved by one ulp in x, reduced to the gated final depth,
//! c_k = (D_k - D'_k) / d (a difference, not a log ratio; docs/statistics.md says why).
//!
//! `granval chaos CASE --out DIR` writes `DIR/chaos.json` ([`ChaosRecord`]); the release
//! report's "Engine agreement against chaos" section reads such records.

use super::{Experiment, Options};
use crate::case::Perturbation;
use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// File name of a chaos record inside its output directory.
pub const CHAOS_FILE: &str = "chaos.json";

/// Kind of a chaos record of a penetration case (and of every record written before
/// 2D records existed).
pub(crate) const PENETRATION: &str = "penetration";
/// Kind of a chaos record of a Kondic (2D) case.
pub const IMPACT2D: &str = "impact2d";

fn penetration_kind() -> String {
    PENETRATION.to_string()
}

/// One case's chaos replicas.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ChaosRecord {
    pub case: String,
    pub canonical_hash: String,
    /// The family the case belongs to (spheres at CI scale, dense, clumps, soft, stiff,
    /// ...), as `granval chaos --family` named it.
    pub family: String,
    /// [`PENETRATION`] (c_k = ln(K_k / K'_k)) or [`IMPACT2D`] (c_k = (D_k - D'_k) / d):
    /// a family pools records of one kind only, since the two c_k are not the same
    /// quantity.
    #[serde(default = "penetration_kind")]
    pub kind: String,
    /// Penetration: sha256 of each bed, in bed order. 2D: each variant's scene
    /// fingerprint (its bed, walls and intruder, the input the seal records), in variant
    /// order.
    pub bed_hashes: Vec<String>,
    /// 2D: the variant of each entry.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub variants: Vec<String>,
    /// Penetration: rule 3's common fit range of the two sets of runs (h_C,start,
    /// h_C,end).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit_h: Option<(f64, f64)>,
    /// Penetration: K_phi of each bed as prepared and as nudged.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub k_phi: Vec<f64>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub k_phi_nudged: Vec<f64>,
    /// Penetration: ln(K_k / K'_k).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub log_ratio: Vec<f64>,
    /// 2D: the final depth (in d) of each variant as built and as nudged.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub final_depth: Vec<f64>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub final_depth_nudged: Vec<f64>,
    /// 2D: (D_k - D'_k) / d.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub depth_difference: Vec<f64>,
    /// The granval version that ran them.
    pub granval: String,
}

impl ChaosRecord {
    /// The per-bed chaos values c_k of the record's kind.
    pub fn values(&self) -> &[f64] {
        if self.kind == IMPACT2D {
            &self.depth_difference
        } else {
            &self.log_ratio
        }
    }

    /// s_c = sqrt(mean c_k^2): the chaos spread of a per-bed value between two runs of
    /// one engine, with as many degrees of freedom as beds (the expected mean is zero).
    pub fn spread(&self) -> (f64, usize) {
        crate::numerics::stats::root_mean_square(self.values())
    }

    /// What c_k is, for messages and tables.
    pub fn quantity(&self) -> &'static str {
        if self.kind == IMPACT2D {
            "(D - D') / d"
        } else {
            "ln(K_phi / K_phi')"
        }
    }

    pub fn write(&self, dir: &Path) -> Result<()> {
        let p = dir.join(CHAOS_FILE);
        std::fs::write(&p, serde_json::to_string_pretty(self)? + "\n")
            .with_context(|| format!("writing {}", p.display()))
    }

    pub fn read(path: &Path) -> Result<ChaosRecord> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        serde_json::from_str(&text)
            .with_context(|| format!("{}: not a chaos record", path.display()))
    }
}

/// The units of `exp`'s case, their beds read from the case's record where it holds
/// them (the ones its reference runs started from), not settled again; their hashes go
/// into the chaos record either way.
pub(crate) fn units_from_record<E: Experiment>(exp: &E, opts: &Options) -> Result<Vec<E::Unit>> {
    let root = super::reference::record_root(&opts.reference_root, exp.kind(), exp.name());
    exp.units(&Options {
        recorded_inputs: root.is_dir().then_some(root),
        ..opts.clone()
    })
}

/// The one-ulp replica of docs/statistics.md: every grain (every bed disk in 2D) moved
/// by one ulp in x.
pub(crate) fn one_ulp() -> Perturbation {
    Perturbation {
        nudge_one_ulp: true,
        ..Perturbation::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first record, written before records had a kind, still reads as a penetration
    /// record with its fit range and its spread (docs/statistics.md: s_c = 0.0585 over 3
    /// beds), and writes back without any 2D field.
    #[test]
    fn a_record_without_a_kind_is_a_penetration_record() {
        let p = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("docs/data/chaos")
            .join("ci-seeds-20261200.json");
        let r = ChaosRecord::read(&p).unwrap();
        assert_eq!(r.kind, PENETRATION);
        assert_eq!(r.fit_h, Some((1.0, 2.5)));
        assert_eq!(r.values(), r.log_ratio.as_slice());
        assert!(r.depth_difference.is_empty() && r.variants.is_empty());
        let (s, n) = r.spread();
        assert_eq!((format!("{s:.4}"), n), ("0.0585".to_string(), 3));
        let back = serde_json::to_value(&r).unwrap();
        for f in ["final_depth", "depth_difference", "variants"] {
            assert!(back.get(f).is_none(), "{f} in {back}");
        }
        assert_eq!(back["fit_h"], serde_json::json!([1.0, 2.5]));
    }
}
