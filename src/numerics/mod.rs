//! General numerics with no physics in them: 3-vectors, quadrature, root finding,
//! minimisation, the first overlapping pair of a set of spheres (a hash-grid search), quaternions, the decision statistics of docs/statistics.md. The bottom layer: it
//! imports nothing from the crate.

pub mod fmt;
pub(crate) mod minimize;
pub mod overlap;
pub(crate) mod quadrature;
pub(crate) mod quat;
pub(crate) mod roots;
pub(crate) mod stats;
pub mod vec3;
