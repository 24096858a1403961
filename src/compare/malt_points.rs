//! The cross-scale MALT verdict of docs/stress.md rule 6: every stress run of a suite
//! leaves its (phi, K_phi) points in `malt_points.json`, and the suite gathers them, with
//! any independent angle (the triaxial test of rule 5), into one table and one figure.
//! Nothing here is a new gate: each case keeps its own MALT and engine gates ("the gates
//! stay as they are"); this is the view across scales that no single case has.

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// File name of a stress run's points inside its output directory.
pub(crate) const MALT_POINTS_FILE: &str = "malt_points.json";

/// One engine's point of one stress run. A value that could not be computed is NaN,
/// written as `null`, and read back as NaN (else the suite would drop the whole point).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct MaltPoint {
    /// Estimator v1 (window phi pooled over beds and depths) and its sd over windows.
    #[serde(deserialize_with = "super::nan_from_null")]
    pub phi_v1_deg: f64,
    #[serde(deserialize_with = "super::nan_from_null")]
    pub phi_v1_sd_deg: f64,
    /// Estimator v2 (pooled regime-C field, docs/stress.md rule 2) and its bootstrap sd;
    /// NaN when it could not be computed.
    #[serde(deserialize_with = "super::nan_from_null")]
    pub phi_v2_deg: f64,
    #[serde(deserialize_with = "super::nan_from_null")]
    pub phi_v2_sd_deg: f64,
    /// K_phi of the ensemble-mean FDR on the case's fit range and its regression SE.
    #[serde(deserialize_with = "super::nan_from_null")]
    pub k_phi: f64,
    #[serde(deserialize_with = "super::nan_from_null")]
    pub k_phi_se: f64,
    /// Mean packing fraction of the beds.
    #[serde(deserialize_with = "super::nan_from_null")]
    pub psi: f64,
}

/// The scale a stress run was made at: what distinguishes its points in the verdict.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Scale {
    /// Intruder radius over mean grain diameter (Feng et al.: 7.5 for Table 2).
    pub r_over_d: f64,
    /// Container radius over intruder radius.
    pub container_over_r: f64,
    pub grains_per_bed: usize,
    pub beds: usize,
    /// All sliding friction coefficients zero (the paper's 9 deg point).
    pub frictionless: bool,
}

/// `malt_points.json`: one stress run's points per engine.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct MaltPoints {
    pub case: String,
    pub canonical_hash: String,
    /// The estimator the case gates (`v1` or `v2`).
    pub gated_estimator: String,
    pub scale: Scale,
    pub engines: BTreeMap<String, MaltPoint>,
}

impl MaltPoints {
    pub fn write(&self, dir: &Path) -> Result<()> {
        let p = dir.join(MALT_POINTS_FILE);
        std::fs::write(&p, serde_json::to_string_pretty(self)?)
            .with_context(|| format!("writing {}", p.display()))
    }

    pub fn read(dir: &Path) -> Result<MaltPoints> {
        let p = dir.join(MALT_POINTS_FILE);
        let text = crate::rundata::fsio::read_to_string(
            &p,
            crate::rundata::fsio::MAX_RECORD_JSON,
            "a stress run's MALT points (JSON)",
        )?;
        serde_json::from_str(&text)
            .with_context(|| format!("{}: not a stress run's MALT points", p.display()))
    }
}

/// An angle measured without the stress-field estimators (rule 5: the triaxial test's
/// critical-state angle), drawn as a band on the phi axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IndependentAngle {
    pub label: String,
    /// The engine that measured the angle: its band's colour in the MALT verdict. A
    /// file written before the engine was recorded has none, and its band is drawn in
    /// the colour of no engine rather than guessed from the label.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub engine: Option<crate::rundata::provenance::EngineKind>,
    pub phi_deg: f64,
    pub se_deg: f64,
}

/// File name of a run's independent angles inside its output directory.
pub(crate) const ANGLES_FILE: &str = "independent_angles.json";

/// `independent_angles.json`: the angles one case measured, per engine.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub(crate) struct IndependentAngles {
    pub case: String,
    pub canonical_hash: String,
    pub angles: Vec<IndependentAngle>,
}

impl IndependentAngles {
    pub fn write(&self, dir: &Path) -> Result<()> {
        let p = dir.join(ANGLES_FILE);
        std::fs::write(&p, serde_json::to_string_pretty(self)?)
            .with_context(|| format!("writing {}", p.display()))
    }

    pub fn read(dir: &Path) -> Result<IndependentAngles> {
        let p = dir.join(ANGLES_FILE);
        let text = crate::rundata::fsio::read_to_string(
            &p,
            crate::rundata::fsio::MAX_RECORD_JSON,
            "a run's independent angles (JSON)",
        )?;
        serde_json::from_str(&text)
            .with_context(|| format!("{}: not a run's independent angles", p.display()))
    }
}

/// phi(K) through eq 10, NaN where K has no angle (below 1 or beyond the table).
fn phi_of_k_deg(k: f64) -> f64 {
    crate::analysis::malt::phi_of_k(k).map_or(f64::NAN, f64::to_degrees)
}

/// The verdict table (Markdown) of the gathered points: per case and engine, K_phi,
/// phi(K) through MALT, both estimators and their distance to phi(K), then the
/// independent angles against each case's phi(K).
pub fn table(points: &[MaltPoints], angles: &[IndependentAngle]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| case | R/d | R_c/R | beds | engine | psi | K_phi | phi(K_phi) | phi v2 | v2 - phi(K) | phi v1 | v1 - phi(K) |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|---|");
    for p in points {
        for (engine, e) in &p.engines {
            let pk = phi_of_k_deg(e.k_phi);
            let _ = writeln!(
                s,
                "| {}{} | {:.1} | {:.1} | {} | {engine} | {:.3} | {:.2} +- {:.2} | {:.2} | {:.2} +- {:.2} | {:+.2} | {:.2} +- {:.2} | {:+.2} |",
                p.case,
                if p.scale.frictionless {
                    " (frictionless)"
                } else {
                    ""
                },
                p.scale.r_over_d,
                p.scale.container_over_r,
                p.scale.beds,
                e.psi,
                e.k_phi,
                e.k_phi_se,
                pk,
                e.phi_v2_deg,
                e.phi_v2_sd_deg,
                e.phi_v2_deg - pk,
                e.phi_v1_deg,
                e.phi_v1_sd_deg,
                e.phi_v1_deg - pk,
            );
        }
    }
    for a in angles {
        let _ = writeln!(
            s,
            "\nindependent angle: {} = {:.2} +- {:.2} deg (K(phi) = {:.2} on the MALT curve)",
            a.label,
            a.phi_deg,
            a.se_deg,
            crate::analysis::malt::k_phi_deg(a.phi_deg).map_or(f64::NAN, |q| q.value)
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points() -> MaltPoints {
        let e = MaltPoint {
            phi_v1_deg: 35.0,
            phi_v1_sd_deg: 3.0,
            phi_v2_deg: 29.0,
            phi_v2_sd_deg: 0.6,
            k_phi: 31.0,
            k_phi_se: 0.4,
            psi: 0.594,
        };
        MaltPoints {
            case: "c".into(),
            canonical_hash: "h".into(),
            gated_estimator: "v2".into(),
            scale: Scale {
                r_over_d: 4.0,
                container_over_r: 3.1,
                grains_per_bed: 11250,
                beds: 3,
                frictionless: false,
            },
            engines: [("native".to_string(), e)].into_iter().collect(),
        }
    }

    #[test]
    fn points_round_trip_and_tabulate_against_eq_10() {
        let dir = tempfile::tempdir().unwrap();
        let p = points();
        p.write(dir.path()).unwrap();
        assert_eq!(MaltPoints::read(dir.path()).unwrap(), p);
        let t = table(
            &[p],
            &[IndependentAngle {
                label: "triaxial".into(),
                engine: None,
                phi_deg: 28.0,
                se_deg: 0.5,
            }],
        );
        // K = 31 is phi = 28.0-28.5 deg on the MALT curve (docs/stress.md), so v1 sits
        // about 7 deg above it and v2 about 1 deg.
        let pk = phi_of_k_deg(31.0);
        assert!((27.5..29.0).contains(&pk), "phi(31) = {pk}");
        assert!(t.contains(&format!("{:+.2}", 35.0 - pk)), "{t}");
        assert!(t.contains(&format!("{:+.2}", 29.0 - pk)), "{t}");
        assert!(t.contains("triaxial = 28.00 +- 0.50"), "{t}");
        assert!(MaltPoints::read(&dir.path().join("none")).is_err());
        // v2 not computed: NaN is written as null and read back as NaN, the point kept.
        let mut q = points();
        q.engines.get_mut("native").unwrap().phi_v2_deg = f64::NAN;
        q.write(dir.path()).unwrap();
        let back = MaltPoints::read(dir.path()).unwrap();
        assert!(back.engines["native"].phi_v2_deg.is_nan());
        assert_eq!(back.engines["native"].k_phi, 31.0);
        let a = IndependentAngles {
            case: "t".into(),
            canonical_hash: "h".into(),
            angles: vec![IndependentAngle {
                label: "triaxial phi_cs, native".into(),
                engine: Some(crate::rundata::provenance::EngineKind::Native),
                phi_deg: 20.8,
                se_deg: 0.1,
            }],
        };
        a.write(dir.path()).unwrap();
        assert_eq!(IndependentAngles::read(dir.path()).unwrap(), a);
    }
}
