//! A LIGGGHTS (or LAMMPS) run recorded earlier under `reference/`, used where the
//! engine is not installed. It is never produced by the native engine: `provenance.json`
//! must name a real reference engine and its version line.

use super::Engine;
use super::RunOutput;
use crate::case::Case;
use crate::rundata::frames::read_particles_csv;
use crate::rundata::provenance::read_provenance;
use std::path::{Path, PathBuf};

#[derive(Debug, Clone)]
pub struct Recorded {
    /// Directory holding `particles.csv` and `provenance.json`.
    pub dir: PathBuf,
}

impl Recorded {
    /// Where the reference run of a case lives: `reference/<suite>/<case name>/`.
    pub fn for_case(reference_root: &Path, case: &Case) -> Recorded {
        Recorded {
            dir: reference_root.join(&case.kind).join(&case.name),
        }
    }
}

impl Engine for Recorded {
    fn name(&self) -> &'static str {
        "recorded"
    }

    fn run(&self, case: &Case, _dir: &Path) -> anyhow::Result<RunOutput> {
        let prov_path = self.dir.join("provenance.json");
        let provenance = read_provenance(&prov_path)?;
        if provenance.engine != "liggghts" && provenance.engine != "lammps" {
            anyhow::bail!(
                "{}: engine {:?} is not a reference engine; reference data must come from LIGGGHTS or LAMMPS",
                prov_path.display(),
                provenance.engine
            );
        }
        let frames = read_particles_csv(&self.dir.join("particles.csv"), case.dt)?;
        let expected = case.n_steps / case.output_every + 1;
        if frames.len() as u64 != expected {
            anyhow::bail!(
                "{}: {} frames recorded, the case implies {}",
                self.dir.display(),
                frames.len(),
                expected
            );
        }
        Ok(RunOutput { frames, provenance })
    }
}
