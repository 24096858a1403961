//! The native solvers: `dem` (3D Hertz-Mindlin spheres, as LIGGGHTS 3.8) and `dem2d`
//! (linear spring-dashpot disks, as LAMMPS `gran/hooke(/history)`). They read validated
//! cases and emit run data; they know nothing of engines, analysis or reports.

pub mod dem;
pub mod dem2d;
pub(crate) mod settle_trace;
