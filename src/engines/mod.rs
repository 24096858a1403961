//! Engine adapters: each turns a validated [`Case`] into the same [`RunOutput`]
//! (DESIGN.md "Data flow"). Engine-specific code stops at these adapters.

pub mod lammps;
pub mod liggghts;
pub mod native;
pub mod process;
pub mod recorded;

pub use crate::rundata::frames::{Frame, ParticleState};
pub use crate::rundata::provenance::Provenance;

use crate::case::Case;
use std::path::Path;

pub trait Engine {
    fn name(&self) -> &'static str;
    /// Runs the case; `dir` is a scratch/run directory the engine may write into.
    fn run(&self, case: &Case, dir: &Path) -> anyhow::Result<RunOutput>;
}

/// A micro run: every output frame and where it came from.
#[derive(Debug, Clone)]
pub struct RunOutput {
    pub frames: Vec<Frame>,
    pub provenance: Provenance,
}
