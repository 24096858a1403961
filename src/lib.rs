//! granval: runs one granular experiment in the native Rust DEM and in LIGGGHTS/LAMMPS,
//! reduces both to the observables of the source papers and gates on their agreement.
//!
//! Layers, bottom to top (docs/architecture.md; `tests/architecture.rs` enforces that
//! imports only point down): `numerics` → `rundata` → `case` → `physics` → `engines` →
//! `analysis` → `compare` → `report` → `experiments`; the binary parses arguments and
//! dispatches one case kind to the experiment runner.

pub mod analysis;
pub mod bench;
pub mod case;
pub mod compare;
pub mod engines;
pub mod experiments;
pub mod numerics;
pub mod physics;
pub mod report;
pub mod rundata;
