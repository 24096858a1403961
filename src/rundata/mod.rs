//! What a run produces, independent of the engine that produced it: particle frames,
//! intruder force samples, 2D impact series, contact snapshots, and provenance. Plain
//! data and its file formats; no physics, no analysis.

pub(crate) mod file_seal;
pub mod force;
pub mod frames;
pub mod fsio;
pub mod impact;
pub(crate) mod paired_frames;
pub mod provenance;
pub mod snapshot;
pub mod triaxial;
