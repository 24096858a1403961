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

// The interface a program built on granval needs, in one place: load a case, run the
// experiment of its kind in both engines, read the verdict. The modules above stay
// public for the integration tests and the bench, which reach into each layer.
pub use case::impact2d::Impact2dCase;
pub use case::penetration::PenetrationCase;
pub use case::{AnyCase, Case, CaseError};
pub use compare::{Check, Gate, Status};
pub use experiments::runner::{CaseOutcome, analyze, compare};
pub use experiments::{Experiment, Options, RefMode};
pub use report::Report;
