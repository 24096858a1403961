//! Engine adapters: each turns a validated [`Case`] into the same [`RunOutput`]
//! (DESIGN.md "Data flow"). Engine-specific code stops at these adapters.

pub mod lammps;
pub mod liggghts;
pub mod native;
pub mod output;
pub mod process;
pub mod recorded;
pub mod snapshot;

pub use output::{Frame, ParticleState, Provenance, RunOutput};

use crate::case::Case;
use std::path::Path;

pub trait Engine {
    fn name(&self) -> &'static str;
    /// Runs the case; `dir` is a scratch/run directory the engine may write into.
    fn run(&self, case: &Case, dir: &Path) -> anyhow::Result<RunOutput>;
}
