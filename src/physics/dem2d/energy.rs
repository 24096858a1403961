//! Energies of a 2D system from one snapshot (K Sec. III): kinetic (translation +
//! rotation, I = m r^2/2, mobile disks incl. the intruder), potential `sum m g y`,
//! elastic `sum k_n x^2 / 2` over touching pairs (normal springs only: the tangential
//! spring length is history LAMMPS does not dump; wall-wall and intra-cluster pairs
//! excluded). Physics, so the native run and the LAMMPS adapter use the same formula.

use super::neighbor::{Box2, Excluded, PairList};
use crate::rundata::impact::EnergySample;

/// One disk of a snapshot, as far as energies need it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SnapDisk {
    pub type_: usize,
    pub radius: f64,
    pub mass: f64,
    pub x: [f64; 2],
    pub v: [f64; 2],
    pub omega: f64,
}

/// Which disks take part, and the normal stiffness of each type pair.
pub struct EnergyModel {
    pub n_types: usize,
    /// `kn[a * n_types + b]`; `None` for pairs that do not interact.
    pub kn: Vec<Option<f64>>,
    /// Types whose disks never move (walls): no kinetic or potential energy.
    pub frozen_type: Vec<bool>,
    pub gravity: f64,
    pub bx: Box2,
}

struct TypeExcl<'a> {
    model: &'a EnergyModel,
    types: &'a [usize],
}

impl Excluded for TypeExcl<'_> {
    fn excluded(&self, i: usize, j: usize) -> bool {
        let n = self.model.n_types;
        self.model.kn[self.types[i] * n + self.types[j]].is_none()
    }
}

pub(crate) fn energies(step: u64, t: f64, disks: &[SnapDisk], model: &EnergyModel) -> EnergySample {
    let mut kinetic = 0.0;
    let mut potential = 0.0;
    for d in disks {
        if model.frozen_type[d.type_] {
            continue;
        }
        kinetic += 0.5 * d.mass * (d.v[0] * d.v[0] + d.v[1] * d.v[1])
            + 0.25 * d.mass * d.radius * d.radius * d.omega * d.omega;
        potential += d.mass * model.gravity * d.x[1];
    }
    let x: Vec<[f64; 2]> = disks.iter().map(|d| d.x).collect();
    let r: Vec<f64> = disks.iter().map(|d| d.radius).collect();
    let types: Vec<usize> = disks.iter().map(|d| d.type_).collect();
    let mut list = PairList::default();
    list.build(
        &model.bx,
        &x,
        &r,
        0.0,
        &TypeExcl {
            model,
            types: &types,
        },
    );
    let mut elastic = 0.0;
    for &(i, j) in &list.pairs {
        let (i, j) = (i as usize, j as usize);
        let d = model.bx.delta(x[i], x[j]);
        let overlap = r[i] + r[j] - (d[0] * d[0] + d[1] * d[1]).sqrt();
        if overlap > 0.0 {
            let k = model.kn[types[i] * model.n_types + types[j]].unwrap_or(0.0);
            elastic += 0.5 * k * overlap * overlap;
        }
    }
    EnergySample {
        step,
        t,
        kinetic,
        potential,
        elastic,
    }
}
