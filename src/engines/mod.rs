//! Engine adapters: the native solvers run in-process, LIGGGHTS and LAMMPS as
//! subprocesses on decks written here; each leaves run data and a provenance record.
//! Engine-specific code (deck syntax, dump formats, units) stops at these adapters; no
//! adapter analyses or compares anything.

pub mod children;
pub mod deck_text;
pub mod lammps;
pub mod lammps3d;
pub mod lammps3d_penetration;
pub mod liggghts;
pub mod native;
pub mod process;
pub(crate) mod viz_dump;
