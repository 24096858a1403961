//! granval: runs one granular experiment in the native Rust DEM and in LIGGGHTS/LAMMPS,
//! reduces both to the observables of the source papers and gates on their agreement.
//!
//! Data flow (DESIGN.md): `case` → `engines` (native | liggghts | recorded) → `compare`
//! → `report`; `dem` is the native engine, `analysis` the theory side (MALT).

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
