//! The native engine with LAMMPS' laws in penetration: the deck
//! [`crate::engines::lammps3d_penetration`] writes for LAMMPS 22 Jul 2025, stepped
//! natively with LAMMPS' semantics, so that "native (LAMMPS laws) vs LAMMPS" compares
//! one implementation of the same physics with another.
//!
//! Input is the [`PenetrationDeck`] itself (the bed granval prepared natively, the
//! container, the intruder, the laws [`lp::law_values`] prints), so both sides start
//! from the same doubles. What is ported, from which LAMMPS sources:
//! - contact law: [`crate::physics::dem::lammps_granular`] (`GranularModel::calculate_forces`), with
//!   the region-wall variant of `GranularModel::check_contact` (contact type
//!   WALLREGION: the region's surface distance `r` is used as given, Reff from the
//!   region contact's curvature radius);
//! - `pair_style granular` pairs, history per pair, cleared whenever the pair does not
//!   touch (`PairGranular::compute`);
//! - `fix gravity` (`FixGravity::post_force`), `fix wall/gran granular ... zplane`
//!   (`FixWallGran::post_force`, flat wall, history per grain);
//! - the two `fix wall/gran/region` walls (`FixWallGranRegion::post_force` and
//!   `update_contacts`, fix_wall_gran_region.cpp): per grain, `Region::match`, then
//!   `Region::surface` (region.cpp) with cutoff = the grain's radius (the pull-off
//!   distance of `hertz/material` is 0), history per grain and region wall index
//!   (`iwall`), zeroed for a new contact or one that does not touch;
//! - the cylinder geometry of region_cylinder.cpp for axis z through the origin:
//!   `RegCylinder::inside`, `surface_interior` (container: `side in open 1 open 2`, so
//!   only its mantle, contact radius -2 R, iwall 2) and `surface_exterior` (intruder:
//!   `side out`, closed: the nearest point of the solid cylinder, its bottom face flat
//!   with contact radius 0, its mantle AND its rim edge with contact radius 2 R, one
//!   contact and one history slot, iwall 0, for all three);
//! - the moving intruder (`region ... move NULL NULL v_dz`): `Region::prematch` /
//!   `pretransform` evaluate dz = -v step dt as the deck's equal-style variable does
//!   ((-v) step) dt, `inverse_transform` subtracts it from the grain's z before the
//!   geometry, and `Region::set_velocity` gives the wall velocity by finite difference,
//!   (dz_n - dz_(n-1)) / dt, zero at step 0 (setup);
//! - `fix nve/sphere` (I = 0.4 m r^2) and `Verlet`'s order: setup forces without
//!   history update, then per step initial_integrate, neighbour check, forces (pair,
//!   gravity, floor, side, intruder), final_integrate, output;
//! - the force on the intruder: the deck's `compute reduce sum` of the intruder fix's
//!   per-grain force (`contacts`, the last contact's force per grain), negated, sampled
//!   every `force_every` steps and at step 0 as LAMMPS' `fix print` does.
//!
//! What differs: neighbour lists are this module's own bins (a pair enters at distance
//! below r_i + r_j + skin and the list is rebuilt when a grain moved more than half the
//! skin, as `neigh_modify delay 0 every 1 check yes`), and LAMMPS sorts its atoms
//! spatially, so per-grain force sums (and the intruder force sum) are added in another
//! order: equal up to round-off, which the bed's chaos then amplifies
//! (docs/lammps-laws.md, "The native engine with LAMMPS' laws in penetration").

use crate::case::Perturbation;
use crate::engines::lammps3d_penetration as lp;
use crate::engines::liggghts::penetration::PenetrationDeck;
use crate::physics::dem::lammps_granular::{
    Coeffs, Contact, History, calculate_forces, calculate_region_forces, check_contact,
    check_region_contact,
};
use crate::physics::dem::lammps_micro::gravity_acceleration;
use crate::rundata::force::ForceSample;
use anyhow::{Result, bail};
use std::collections::HashMap;

type V3 = [f64; 3];

/// `INERTIA` of fix_nve_sphere.cpp (solid sphere).
const INERTIA: f64 = 0.4;
/// `BIG` of region_cylinder.cpp.
const BIG: f64 = 1.0e20;

/// One entry of `Region::contact[]` (region.h): distance `r` from the surface, `del`
/// the vector from the nearest surface point to the grain centre, `radius` the
/// curvature radius handed to the contact model (0 flat), `iwall` which face.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct RegionContact {
    pub r: f64,
    pub del: V3,
    pub radius: f64,
    pub iwall: u8,
}

/// What `Region::surface` returns: `n` contacts in `c[..n]` (`RegCylinder::cmax` = 3).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Contacts {
    pub n: usize,
    pub c: [RegionContact; 3],
}

impl Contacts {
    pub fn as_slice(&self) -> &[RegionContact] {
        &self.c[..self.n]
    }
}

/// `region ID cylinder z 0 0 radius lo hi side in|out [open 1] [open 2] [open 3] units
/// box` (RegCylinder, axis z, c1 = c2 = 0), in the region's own (unmoved) frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ZCylinder {
    pub radius: f64,
    pub lo: f64,
    pub hi: f64,
    /// `side in` (`Region::interior`).
    pub interior: bool,
    /// `open_faces[0..3]`: the lo cap, the hi cap, the mantle (`open 1`, `open 2`,
    /// `open 3`).
    pub open: [bool; 3],
}

impl ZCylinder {
    fn openflag(&self) -> bool {
        self.open.iter().any(|&o| o)
    }

    /// `RegCylinder::inside` (axis z): on the surface counts as inside.
    pub fn inside(&self, x: V3) -> bool {
        let del1 = x[0] - 0.0;
        let del2 = x[1] - 0.0;
        let dist = (del1 * del1 + del2 * del2).sqrt();
        dist <= self.radius && x[2] >= self.lo && x[2] <= self.hi
    }

    /// `Region::match` once the point is in the region's frame: any point of an open
    /// region, else inside XOR exterior.
    pub fn matches(&self, x: V3) -> bool {
        if self.openflag() {
            return true;
        }
        self.inside(x) == self.interior
    }

    /// `RegCylinder::surface_interior` (axis z), writing from `c[0]`.
    fn surface_interior(&self, x: V3, cutoff: f64, c: &mut [RegionContact; 3]) -> usize {
        let (radius, lo, hi) = (self.radius, self.lo, self.hi);
        let del1 = x[0] - 0.0;
        let del2 = x[1] - 0.0;
        let r = (del1 * del1 + del2 * del2).sqrt();
        // x is exterior to cylinder
        if r > radius || x[2] < lo || x[2] > hi {
            return 0;
        }
        let mut n = 0;
        let delta = radius - r;
        if delta < cutoff && r > 0.0 && !self.open[2] {
            c[n] = RegionContact {
                r: delta,
                del: [del1 * (1.0 - radius / r), del2 * (1.0 - radius / r), 0.0],
                radius: -2.0 * radius,
                iwall: 2,
            };
            n += 1;
        }
        let delta = x[2] - lo;
        if delta < cutoff && !self.open[0] {
            c[n] = RegionContact {
                r: delta,
                del: [0.0, 0.0, delta],
                radius: 0.0,
                iwall: 0,
            };
            n += 1;
        }
        let delta = hi - x[2];
        if delta < cutoff && !self.open[1] {
            c[n] = RegionContact {
                r: delta,
                del: [0.0, 0.0, -delta],
                radius: 0.0,
                iwall: 1,
            };
            n += 1;
        }
        n
    }

    /// `RegCylinder::surface_exterior` (axis z), writing `c[0]`: one contact with the
    /// nearest point of the solid cylinder, which may lie on a cap, on the mantle or on
    /// a rim edge. Closed cylinder: curvature radius 2 R whenever the grain centre is
    /// outside the mantle's radius (mantle and rim), 0 over a cap; with open faces
    /// (`openflag`) LAMMPS leaves it 0 everywhere.
    fn surface_exterior(&self, x: V3, cutoff: f64, c: &mut [RegionContact; 3]) -> usize {
        let (radius, lo, hi) = (self.radius, self.lo, self.hi);
        let (c1, c2) = (0.0, 0.0);
        let del1 = x[0] - c1;
        let del2 = x[1] - c2;
        let r = (del1 * del1 + del2 * del2).sqrt();
        // far enough from the cylinder that there is no contact
        if r >= radius + cutoff || x[2] <= lo - cutoff || x[2] >= hi + cutoff {
            return 0;
        }
        // interior to the cylinder
        if r < radius && x[2] > lo && x[2] < hi {
            return 0;
        }
        let mut crad = 0.0;
        let (mut xp, mut yp, mut zp) = (0.0, 0.0, 0.0);
        let mut d2prev = BIG;
        if !self.openflag() {
            if r > radius {
                xp = c1 + del1 * radius / r;
                yp = c2 + del2 * radius / r;
                crad = 2.0 * radius;
            } else {
                xp = x[0];
                yp = x[1];
            }
            zp = if x[2] < lo {
                lo
            } else if x[2] > hi {
                hi
            } else {
                x[2]
            };
        } else {
            // closest point on curved surface
            let dr = r - radius;
            let dr2 = dr * dr;
            if !self.open[2] {
                xp = c1 + del1 * radius / r;
                yp = c2 + del2 * radius / r;
                let dx;
                if x[2] < lo {
                    dx = lo - x[2];
                    zp = lo;
                } else if x[2] > hi {
                    dx = x[2] - hi;
                    zp = hi;
                } else {
                    dx = 0.0;
                    zp = x[2];
                }
                d2prev = dr2 + dx * dx;
            }
            // closest point on bottom cap
            if !self.open[0] {
                let dx = lo - x[2];
                let d2 = if r < radius { dx * dx } else { dr2 + dx * dx };
                if d2 < d2prev {
                    zp = lo;
                    if r < radius {
                        xp = x[0];
                        yp = x[1];
                    } else {
                        xp = c1 + del1 * radius / r;
                        yp = c2 + del2 * radius / r;
                    }
                    d2prev = d2;
                }
            }
            // closest point on top cap
            if !self.open[1] {
                let dx = hi - x[2];
                let d2 = if r < radius { dx * dx } else { dr2 + dx * dx };
                if d2 < d2prev {
                    zp = hi;
                    if r < radius {
                        xp = x[0];
                        yp = x[1];
                    } else {
                        xp = c1 + del1 * radius / r;
                        yp = c2 + del2 * radius / r;
                    }
                }
            }
        }
        // Region::add_contact
        let del = [x[0] - xp, x[1] - yp, x[2] - zp];
        c[0] = RegionContact {
            r: (del[0] * del[0] + del[1] * del[1] + del[2] * del[2]).sqrt(),
            del,
            radius: crad,
            iwall: 0,
        };
        usize::from(c[0].r < cutoff)
    }

    /// `Region::surface` for a point already in the region's frame: the interior or
    /// exterior contacts, or with open faces both, written from the same index 0 as
    /// LAMMPS writes them (one of the two finds none).
    pub fn surface(&self, x: V3, cutoff: f64) -> Contacts {
        let mut out = Contacts::default();
        out.n = if !self.openflag() {
            if self.interior {
                self.surface_interior(x, cutoff, &mut out.c)
            } else {
                self.surface_exterior(x, cutoff, &mut out.c)
            }
        } else {
            let ne = self.surface_exterior(x, cutoff, &mut out.c);
            ne + self.surface_interior(x, cutoff, &mut out.c)
        };
        out
    }

    /// `RegCylinder::tmax`: history slots per grain.
    fn tmax(&self) -> usize {
        if self.interior { 2 } else { 1 }
    }
}

/// One grain's history with one `fix wall/gran/region` (`ncontact`, `walls`,
/// `history_many` of fix_wall_gran_region.cpp).
#[derive(Debug, Clone, Copy, Default)]
struct RegionSlots {
    n: usize,
    walls: [u8; 3],
    hist: [History; 3],
}

impl RegionSlots {
    /// The history maintenance of `FixWallGranRegion::post_force` for `nc` >= 1
    /// contacts; returns `c2r`.
    fn maintain(&mut self, cs: &[RegionContact]) -> [usize; 3] {
        let mut c2r = [0usize; 3];
        if cs.len() == 1 {
            c2r[0] = 0;
            let iwall = cs[0].iwall;
            if self.n == 0 {
                self.n = 1;
                self.walls[0] = iwall;
                self.hist[0] = [0.0; 6];
            } else if self.n > 1 || iwall != self.walls[0] {
                self.update_contacts(cs, &mut c2r);
            }
        } else {
            self.update_contacts(cs, &mut c2r);
        }
        c2r
    }

    /// `FixWallGranRegion::update_contacts`, as written (including its `c2r[m] = inew`,
    /// which indexes by slot; with the one contact per grain of this geometry slot and
    /// contact index are both 0).
    fn update_contacts(&mut self, cs: &[RegionContact], c2r: &mut [usize; 3]) {
        let mut iold = 0;
        while iold < self.n {
            if !cs.iter().any(|c| c.iwall == self.walls[iold]) {
                let ilast = self.n - 1;
                self.hist[iold] = self.hist[ilast];
                self.walls[iold] = self.walls[ilast];
                self.n -= 1;
            } else {
                iold += 1;
            }
        }
        let nold = self.n;
        for (inew, c) in cs.iter().enumerate() {
            match (0..nold).find(|&m| self.walls[m] == c.iwall) {
                Some(m) => c2r[m] = inew,
                None => {
                    let iadd = self.n;
                    c2r[iadd] = inew;
                    self.hist[iadd] = [0.0; 6];
                    self.walls[iadd] = c.iwall;
                    self.n += 1;
                }
            }
        }
    }
}

/// The set-up coefficients of the deck's laws (`coeffs_to_local`, `init`): one per grain
/// type pair, and the floor's, side wall's and intruder's for the grains' type.
pub(crate) struct Laws {
    n_types: usize,
    pair: Vec<Coeffs>,
    floor: Coeffs,
    side: Coeffs,
    intruder: Coeffs,
}

fn coeffs(l: lp::DeckLaw, wall: bool) -> Coeffs {
    Coeffs::new(l.e_mod, l.restitution, l.nu, l.xt, l.mu, None, wall)
}

impl Laws {
    pub fn new(d: &PenetrationDeck) -> Laws {
        let n = d.materials.len();
        let mut pair = Vec::with_capacity(n * n);
        for a in 0..n {
            for b in 0..n {
                pair.push(coeffs(lp::law_values(d, a.min(b), a.max(b), false), false));
            }
        }
        let gt = d.particles.first().map(|p| p.type_).unwrap_or(0);
        Laws {
            n_types: n,
            pair,
            floor: coeffs(lp::law_values(d, gt, d.wall_type, true), true),
            side: coeffs(lp::law_values(d, gt, d.wall_type, true), true),
            intruder: coeffs(lp::law_values(d, gt, d.intruder_type, true), true),
        }
    }
}

/// The deck with a negative control's changes applied the way the LAMMPS deck would
/// carry them: friction scaled (or one pair's replaced), restitution and Poisson's
/// ratio shifted. Any other control is refused: these laws have no rolling resistance,
/// no clumps and no 2D model for it to act on, so it could not bite.
pub(crate) fn perturbed(d: &PenetrationDeck, pert: &Perturbation) -> Result<PenetrationDeck> {
    let handled = Perturbation {
        friction_factor: pert.friction_factor,
        restitution_shift: pert.restitution_shift,
        poisson_shift: pert.poisson_shift,
        pair_friction: pert.pair_friction,
        nudge_one_ulp: pert.nudge_one_ulp,
        ..Perturbation::default()
    };
    if handled != *pert {
        bail!(
            "control {pert:?}: the native engine with LAMMPS' laws applies friction, restitution and Poisson-ratio controls only (no rolling resistance, clumps or 2D models to perturb)"
        );
    }
    let mut d = d.clone();
    if *pert == Perturbation::default() {
        return Ok(d);
    }
    for m in &mut d.materials {
        m.poisson_ratio += pert.poisson_shift;
    }
    let n = d.pairs.n_types;
    for a in 0..n {
        for b in 0..n {
            let k = d.pairs.idx(a, b);
            d.pairs.restitution[k] = (d.pairs.restitution[k] + pert.restitution_shift).min(1.0);
            d.pairs.friction[k] = match pert.pair_friction {
                Some((i, j, mu)) if (i, j) == (a, b) || (j, i) == (a, b) => mu,
                _ => d.pairs.friction[k] * pert.friction_factor,
            };
        }
    }
    Ok(d)
}

/// Pair list rebuilt by binning (cells of the largest diameter plus the skin) when a
/// grain moved more than half the skin since the last build; the history of each
/// listed pair (i < j) rides with it.
struct Neighbors {
    skin: f64,
    pairs: Vec<(u32, u32)>,
    hist: Vec<History>,
    x_built: Vec<V3>,
}

impl Neighbors {
    fn needs_rebuild(&self, x: &[V3]) -> bool {
        let trigger = 0.5 * self.skin;
        let triggersq = trigger * trigger;
        x.iter().zip(&self.x_built).any(|(a, b)| {
            let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
            d[0] * d[0] + d[1] * d[1] + d[2] * d[2] > triggersq
        })
    }

    fn build(&mut self, x: &[V3], radius: &[f64], lo: V3, hi: V3) {
        let rmax = radius.iter().cloned().fold(0.0, f64::max);
        let cell = 2.0 * rmax + self.skin;
        let dims: [usize; 3] =
            std::array::from_fn(|k| (((hi[k] - lo[k]) / cell).floor() as usize).max(1));
        let cell_of = |p: &V3| -> [usize; 3] {
            std::array::from_fn(|k| {
                let c = ((p[k] - lo[k]) / cell).floor();
                (c.max(0.0) as usize).min(dims[k] - 1)
            })
        };
        let flat = |c: [usize; 3]| (c[2] * dims[1] + c[1]) * dims[0] + c[0];
        let ncell = dims[0] * dims[1] * dims[2];
        let mut start = vec![0usize; ncell + 1];
        let cells: Vec<usize> = x.iter().map(|p| flat(cell_of(p))).collect();
        for &c in &cells {
            start[c + 1] += 1;
        }
        for c in 0..ncell {
            start[c + 1] += start[c];
        }
        let mut fill = start.clone();
        let mut members = vec![0u32; x.len()];
        for (i, &c) in cells.iter().enumerate() {
            members[fill[c]] = i as u32;
            fill[c] += 1;
        }
        let old: HashMap<(u32, u32), History> = self
            .pairs
            .iter()
            .zip(&self.hist)
            .filter(|(_, h)| h.iter().any(|&v| v != 0.0))
            .map(|(&p, &h)| (p, h))
            .collect();
        self.pairs.clear();
        self.hist.clear();
        for (i, p) in x.iter().enumerate() {
            let c = cell_of(p);
            let mut js: Vec<u32> = Vec::new();
            for dz in -1i64..=1 {
                for dy in -1i64..=1 {
                    for dx in -1i64..=1 {
                        let n = [c[0] as i64 + dx, c[1] as i64 + dy, c[2] as i64 + dz];
                        if (0..3).any(|k| n[k] < 0 || n[k] >= dims[k] as i64) {
                            continue;
                        }
                        let f = flat([n[0] as usize, n[1] as usize, n[2] as usize]);
                        for &j in &members[start[f]..start[f + 1]] {
                            if (j as usize) <= i {
                                continue;
                            }
                            let q = &x[j as usize];
                            let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
                            let cut = radius[i] + radius[j as usize] + self.skin;
                            if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= cut * cut {
                                js.push(j);
                            }
                        }
                    }
                }
            }
            js.sort_unstable();
            for j in js {
                let key = (i as u32, j);
                self.pairs.push(key);
                self.hist.push(old.get(&key).copied().unwrap_or([0.0; 6]));
            }
        }
        self.x_built = x.to_vec();
    }
}

/// The state of one run.
struct Engine {
    id: Vec<u64>,
    type_: Vec<usize>,
    radius: Vec<f64>,
    rmass: Vec<f64>,
    x: Vec<V3>,
    v: Vec<V3>,
    omega: Vec<V3>,
    f: Vec<V3>,
    torque: Vec<V3>,
    neigh: Neighbors,
    floor_hist: Vec<History>,
    side_slots: Vec<RegionSlots>,
    intruder_slots: Vec<RegionSlots>,
    /// The intruder fix's per-grain force (`contacts`, columns 2-4), cleared each step.
    intruder_f: Vec<V3>,
    laws: Laws,
    gacc: V3,
    dt: f64,
    floor_z: f64,
    side: ZCylinder,
    intruder: ZCylinder,
    speed: f64,
    /// `Region::prev[2]` and `Region::v[2]` of the intruder.
    dz_prev: f64,
    vz: f64,
    lo: V3,
    hi: V3,
}

impl Engine {
    fn new(d: &PenetrationDeck) -> Engine {
        let n = d.particles.len();
        let side = ZCylinder {
            radius: d.container_radius,
            lo: d.domain_lo[2],
            hi: d.domain_hi[2],
            interior: true,
            open: [true, true, false],
        };
        let intruder = ZCylinder {
            radius: d.intruder_radius,
            lo: d.intruder_bottom_z0,
            hi: d.intruder_bottom_z0 + d.intruder_length,
            interior: false,
            open: [false; 3],
        };
        debug_assert_eq!(side.tmax(), 2);
        debug_assert_eq!(intruder.tmax(), 1);
        let x: Vec<V3> = d.particles.iter().map(|p| p.x).collect();
        Engine {
            id: d.particles.iter().map(|p| p.id).collect(),
            type_: d.particles.iter().map(|p| p.type_).collect(),
            radius: d.particles.iter().map(|p| p.radius).collect(),
            // AtomVecSphere::data_atom_post: rmass = density 4 pi / 3 r^3
            rmass: d.particles.iter().map(|p| p.mass()).collect(),
            v: d.particles.iter().map(|p| p.v).collect(),
            omega: d.particles.iter().map(|p| p.omega).collect(),
            f: vec![[0.0; 3]; n],
            torque: vec![[0.0; 3]; n],
            neigh: Neighbors {
                skin: d.neighbor_skin,
                pairs: Vec::new(),
                hist: Vec::new(),
                x_built: x.clone(),
            },
            x,
            floor_hist: vec![[0.0; 6]; n],
            side_slots: vec![RegionSlots::default(); n],
            intruder_slots: vec![RegionSlots::default(); n],
            intruder_f: vec![[0.0; 3]; n],
            laws: Laws::new(d),
            gacc: if d.gravity > 0.0 {
                gravity_acceleration([0.0, 0.0, -d.gravity])
            } else {
                [0.0; 3]
            },
            dt: d.dt,
            floor_z: d.floor_z,
            side,
            intruder,
            speed: d.speed,
            dz_prev: 0.0,
            vz: 0.0,
            lo: d.domain_lo,
            hi: d.domain_hi,
        }
    }

    /// The deck's `variable dz equal -v*step*dt`: ((-v) step) dt.
    fn dz(&self, step: u64) -> f64 {
        -self.speed * step as f64 * self.dt
    }

    /// A grain that left the closed box or became non-finite ends the run, as
    /// `thermo_modify lost error` ends LAMMPS'.
    fn check(&self, step: u64) -> Result<()> {
        crate::physics::dem::lammps_micro::check_lost(
            &self.id,
            [&self.x, &self.v, &self.omega],
            (self.lo, self.hi),
            ("grain", "box"),
            step,
        )
    }

    /// Forces of step `step` (0: `Verlet::setup`, history not advanced); returns the
    /// force of the grains on the intruder (minus the sum of its forces on them).
    fn forces(&mut self, step: u64) -> V3 {
        let history_update = step > 0;
        let n = self.x.len();
        self.f.iter_mut().for_each(|f| *f = [0.0; 3]);
        self.torque.iter_mut().for_each(|t| *t = [0.0; 3]);
        let dt = self.dt;
        // PairGranular::compute
        for (p, h) in self.neigh.pairs.iter().zip(self.neigh.hist.iter_mut()) {
            let (i, j) = (p.0 as usize, p.1 as usize);
            let (mi, mj) = (self.rmass[i], self.rmass[j]);
            let c = Contact {
                dx: [
                    self.x[i][0] - self.x[j][0],
                    self.x[i][1] - self.x[j][1],
                    self.x[i][2] - self.x[j][2],
                ],
                radi: self.radius[i],
                radj: self.radius[j],
                wall: false,
                meff: mi * mj / (mi + mj),
                vi: self.v[i],
                vj: self.v[j],
                omegai: self.omega[i],
                omegaj: self.omega[j],
            };
            if !check_contact(&c).0 {
                *h = [0.0; 6];
                continue;
            }
            let k = &self.laws.pair[self.type_[i] * self.laws.n_types + self.type_[j]];
            let o = calculate_forces(&c, k, dt, h, history_update);
            for a in 0..3 {
                self.f[i][a] += o.forces[a];
                self.torque[i][a] += o.torquesi[a];
                self.f[j][a] -= o.forces[a];
                self.torque[j][a] += o.torquesj[a];
            }
        }
        // FixGravity::post_force
        if self.gacc != [0.0; 3] {
            for i in 0..n {
                let massone = self.rmass[i];
                for (f, acc) in self.f[i].iter_mut().zip(self.gacc) {
                    *f += massone * acc;
                }
            }
        }
        // FixWallGran::post_force, `zplane floor_z NULL`
        for i in 0..n {
            let c = Contact {
                dx: [0.0, 0.0, self.x[i][2] - self.floor_z],
                radi: self.radius[i],
                radj: 0.0,
                wall: true,
                meff: self.rmass[i],
                vi: self.v[i],
                vj: [0.0; 3],
                omegai: self.omega[i],
                omegaj: [0.0; 3],
            };
            let h = &mut self.floor_hist[i];
            if !check_contact(&c).0 {
                *h = [0.0; 6];
                continue;
            }
            let o = calculate_forces(&c, &self.laws.floor, dt, h, history_update);
            for a in 0..3 {
                self.f[i][a] += o.forces[a];
                self.torque[i][a] += o.torquesi[a];
            }
        }
        // FixWallGranRegion::post_force, the container (static)
        for i in 0..n {
            let side = self.side;
            let k = self.laws.side;
            self.region_wall(i, &side, 0.0, [0.0; 3], &k, history_update, false);
        }
        // The intruder: Region::prematch (dz at this step), Region::set_velocity
        let dz = self.dz(step);
        self.vz = if step > 0 {
            (dz - self.dz_prev) / dt
        } else {
            0.0
        };
        self.dz_prev = dz;
        self.intruder_f.iter_mut().for_each(|f| *f = [0.0; 3]);
        for i in 0..n {
            let intr = self.intruder;
            let k = self.laws.intruder;
            let vwall = [0.0, 0.0, self.vz];
            self.region_wall(i, &intr, dz, vwall, &k, history_update, true);
        }
        // compute reduce sum f_wint[2..4], then `$(-c_fint[k])`
        let mut sum = [0.0; 3];
        for f in &self.intruder_f {
            for a in 0..3 {
                sum[a] += f[a];
            }
        }
        [-sum[0], -sum[1], -sum[2]]
    }

    /// One grain against one `fix wall/gran/region` wall moved by `dz` along z.
    #[allow(clippy::too_many_arguments)]
    fn region_wall(
        &mut self,
        i: usize,
        region: &ZCylinder,
        dz: f64,
        vwall: V3,
        k: &Coeffs,
        history_update: bool,
        store: bool,
    ) {
        // Region::inverse_transform (move only): x - dx, y - dy (0), z - dz
        let xl = [self.x[i][0] - 0.0, self.x[i][1] - 0.0, self.x[i][2] - dz];
        if !region.matches(xl) {
            return;
        }
        let radi = self.radius[i];
        let contacts = region.surface(xl, radi + 0.0);
        let slots = if store {
            &mut self.intruder_slots[i]
        } else {
            &mut self.side_slots[i]
        };
        if contacts.n == 0 {
            slots.n = 0;
            return;
        }
        let c2r = slots.maintain(contacts.as_slice());
        for (ic, rc) in contacts.as_slice().iter().enumerate() {
            let h = &mut slots.hist[c2r[ic]];
            if !check_region_contact(radi, rc.radius, rc.r).0 {
                *h = [0.0; 6];
                continue;
            }
            let c = Contact {
                dx: rc.del,
                radi,
                radj: rc.radius,
                wall: true,
                meff: self.rmass[i],
                vi: self.v[i],
                vj: vwall,
                omegai: self.omega[i],
                omegaj: [0.0; 3],
            };
            let o = calculate_region_forces(&c, rc.r, k, self.dt, h, history_update);
            for a in 0..3 {
                self.f[i][a] += o.forces[a];
                self.torque[i][a] += o.torquesi[a];
            }
            if store {
                self.intruder_f[i] = o.forces;
            }
        }
    }

    /// `FixNVESphere::initial_integrate`.
    fn initial_integrate(&mut self) {
        let dtv = self.dt;
        let dtf = 0.5 * self.dt;
        let dtfrotate = dtf / INERTIA;
        for i in 0..self.x.len() {
            let dtfm = dtf / self.rmass[i];
            for c in 0..3 {
                self.v[i][c] += dtfm * self.f[i][c];
            }
            for c in 0..3 {
                self.x[i][c] += dtv * self.v[i][c];
            }
            let dtirotate = dtfrotate / (self.radius[i] * self.radius[i] * self.rmass[i]);
            for c in 0..3 {
                self.omega[i][c] += dtirotate * self.torque[i][c];
            }
        }
    }

    /// `FixNVESphere::final_integrate`.
    fn final_integrate(&mut self) {
        let dtf = 0.5 * self.dt;
        let dtfrotate = dtf / INERTIA;
        for i in 0..self.x.len() {
            let dtfm = dtf / self.rmass[i];
            for c in 0..3 {
                self.v[i][c] += dtfm * self.f[i][c];
            }
            let dtirotate = dtfrotate / (self.radius[i] * self.radius[i] * self.rmass[i]);
            for c in 0..3 {
                self.omega[i][c] += dtirotate * self.torque[i][c];
            }
        }
    }
}

/// The value of an equal-style variable named inside another formula or printed as
/// `$(v_name)`: `Variable::evaluate` reads `v_name` through `Variable::retrieve`, which
/// formats it with "%.15g", and parses that string back (`atof`). The deck's printed
/// z_bottom, `$(v_zb)` with `zb = z0 + v_dz`, passes through this twice; the region's
/// own displacement (`Region::pretransform`, `compute_equal`) does not.
fn retrieve(x: f64) -> f64 {
    format!("{x:.14e}")
        .parse()
        .expect("a formatted finite double parses")
}

/// Runs the deck `d` natively with LAMMPS' laws (under the control `pert`, see
/// [`perturbed`]) for its `n_steps`: the force of the grains on the intruder and the
/// height of its bottom at step 0 and every `force_every` steps, as the deck's `fix
/// print` writes them (t = step dt, z_bottom = z0 + dz as LAMMPS prints it, see
/// [`retrieve`]). `progress(step, total)` is
/// called every 500 steps. Refuses what the LAMMPS deck refuses (clump beds,
/// LIGGGHTS-settled beds, other units than SI, no grains).
pub(crate) fn run(
    d: &PenetrationDeck,
    pert: &Perturbation,
    mut progress: impl FnMut(u64, u64),
) -> Result<Vec<ForceSample>> {
    lp::check(d)?;
    let d = perturbed(d, pert)?;
    if d.particles.iter().any(|p| p.type_ != d.particles[0].type_) {
        bail!(
            "bed: grains of more than one type: the LAMMPS deck's walls carry the first grain type's law only"
        );
    }
    let mut e = Engine::new(&d);
    e.check(0)?;
    e.neigh.build(&e.x, &e.radius, e.lo, e.hi);
    let z0 = d.intruder_bottom_z0;
    let sample = |e: &Engine, step: u64, f: V3| ForceSample {
        t: step as f64 * d.dt,
        z_bottom: retrieve(z0 + retrieve(e.dz(step))),
        f,
    };
    let f0 = e.forces(0);
    let mut out = vec![sample(&e, 0, f0)];
    for step in 1..=d.n_steps {
        e.initial_integrate();
        if e.neigh.needs_rebuild(&e.x) {
            e.check(step)?;
            e.neigh.build(&e.x, &e.radius, e.lo, e.hi);
        }
        let f = e.forces(step);
        e.final_integrate();
        if step.is_multiple_of(d.force_every) {
            out.push(sample(&e, step, f));
        }
        if step.is_multiple_of(500) {
            progress(step, d.n_steps);
        }
    }
    e.check(d.n_steps)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The intruder of the tiny case's shape: radius 5 mm, bottom at z = 10 mm, top 40 mm.
    fn intruder() -> ZCylinder {
        ZCylinder {
            radius: 5e-3,
            lo: 10e-3,
            hi: 40e-3,
            interior: false,
            open: [false; 3],
        }
    }

    /// The container: radius 16 mm, z in [0, 50 mm], both caps open.
    fn container() -> ZCylinder {
        ZCylinder {
            radius: 16e-3,
            lo: 0.0,
            hi: 50e-3,
            interior: true,
            open: [true, true, false],
        }
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-15 * (1.0 + a.abs().max(b.abs()))
    }

    fn close3(a: V3, b: V3) -> bool {
        (0..3).all(|k| close(a[k], b[k]))
    }

    /// Grain inside the container, 0.5 mm from its mantle: one contact, del pointing
    /// from the mantle to the centre (-x), curvature radius -2 R (concave), iwall 2;
    /// Reff = r (-2R) / (r - 2R) = 2 mm * 32 / 30 mm, above the grain's radius.
    #[test]
    fn inside_mantle_contact() {
        let c = container();
        let x = [15.5e-3, 0.0, 10e-3];
        assert!(c.matches(x));
        let s = c.surface(x, 2e-3);
        assert_eq!(s.n, 1);
        let k = s.c[0];
        assert!(close(k.r, 0.5e-3), "{k:?}");
        assert!(close3(k.del, [-0.5e-3, 0.0, 0.0]), "{k:?}");
        assert_eq!((k.radius, k.iwall), (-32e-3, 2));
        let (touch, radsum, reff) = check_region_contact(2e-3, k.radius, k.r);
        assert!(touch);
        assert_eq!(radsum, 2e-3);
        assert!(close(reff, 2e-3 * 32e-3 / 30e-3), "{reff}");
        // Near the floor the open lo cap gives no contact; off the mantle, nothing.
        let s = c.surface([0.0, 0.0, 0.5e-3], 2e-3);
        assert_eq!(s.n, 0);
        // Diagonal: del is along the radius, |del| = r.
        let x = [15e-3 / 2f64.sqrt(), 15e-3 / 2f64.sqrt(), 5e-3];
        let k = c.surface(x, 2e-3).c[0];
        assert!(close(k.r, 1e-3));
        assert!(close3(
            k.del,
            [-1e-3 / 2f64.sqrt(), -1e-3 / 2f64.sqrt(), 0.0]
        ));
    }

    /// Grain beside the intruder, 1.5 mm from its mantle: del along +x, curvature
    /// radius +2 R (convex), Reff = r 2R / (r + 2R).
    #[test]
    fn outside_mantle_contact() {
        let c = intruder();
        let x = [6.5e-3, 0.0, 20e-3];
        assert!(c.matches(x));
        let s = c.surface(x, 2e-3);
        assert_eq!(s.n, 1);
        let k = s.c[0];
        assert!(
            close(k.r, 1.5e-3) && close3(k.del, [1.5e-3, 0.0, 0.0]),
            "{k:?}"
        );
        assert_eq!((k.radius, k.iwall), (10e-3, 0));
        let (_, _, reff) = check_region_contact(2e-3, k.radius, k.r);
        assert!(close(reff, 2e-3 * 10e-3 / 12e-3));
        // 2.5 mm away: beyond the cutoff (the grain radius), no contact.
        assert_eq!(c.surface([7.5e-3, 0.0, 20e-3], 2e-3).n, 0);
    }

    /// Grain under the flat bottom: del straight down, flat (radius 0, Reff = r).
    #[test]
    fn flat_bottom_contact() {
        let c = intruder();
        let x = [1e-3, 2e-3, 8.5e-3];
        let s = c.surface(x, 2e-3);
        assert_eq!(s.n, 1);
        let k = s.c[0];
        assert!(
            close(k.r, 1.5e-3) && close3(k.del, [0.0, 0.0, -1.5e-3]),
            "{k:?}"
        );
        assert_eq!((k.radius, k.iwall), (0.0, 0));
        let (_, _, reff) = check_region_contact(2e-3, k.radius, k.r);
        assert_eq!(reff, 2e-3);
    }

    /// Grain off the rim edge, 1 mm out and 1 mm below: the nearest point is the edge
    /// (R, 0, lo), r = sqrt(2) mm, del at 45 degrees; LAMMPS gives the edge the mantle's
    /// curvature radius 2 R, and the same wall index (so the same history) as the
    /// bottom face and the mantle.
    #[test]
    fn rim_edge_contact() {
        let c = intruder();
        let x = [6e-3, 0.0, 9e-3];
        let s = c.surface(x, 2e-3);
        assert_eq!(s.n, 1);
        let k = s.c[0];
        assert!(close(k.r, 2f64.sqrt() * 1e-3), "{k:?}");
        assert!(close3(k.del, [1e-3, 0.0, -1e-3]), "{k:?}");
        assert_eq!((k.radius, k.iwall), (10e-3, 0));
        // 1.5 mm out and 1.5 mm below: sqrt(2) 1.5 mm > 2 mm cutoff, no contact, though
        // each coordinate alone is within it.
        assert_eq!(c.surface([6.5e-3, 0.0, 8.5e-3], 2e-3).n, 0);
    }

    /// A grain centre inside the solid intruder does not match the `side out` region
    /// (`Region::match`), so the wall ignores it; on its surface counts as inside.
    #[test]
    fn centre_inside_the_intruder_does_not_match() {
        let c = intruder();
        assert!(!c.matches([0.0, 0.0, 20e-3]));
        assert!(!c.matches([5e-3, 0.0, 20e-3]));
        assert!(!c.matches([0.0, 0.0, 10e-3]));
        assert!(c.matches([0.0, 0.0, 9.999e-3]));
    }

    /// A history slot is kept while the grain keeps its wall index, zeroed when a new
    /// contact starts or the index changes (`update_contacts`).
    #[test]
    fn region_history_follows_the_wall_index() {
        let mut s = RegionSlots::default();
        let a = RegionContact {
            iwall: 0,
            ..Default::default()
        };
        let b = RegionContact {
            iwall: 2,
            ..Default::default()
        };
        assert_eq!(s.maintain(&[a])[0], 0);
        s.hist[0][0] = 1.0;
        s.maintain(&[a]);
        assert_eq!(s.hist[0][0], 1.0, "same wall: history kept");
        s.maintain(&[b]);
        assert_eq!(
            (s.n, s.walls[0], s.hist[0][0]),
            (1, 2, 0.0),
            "other wall: new"
        );
    }

    /// "%.15g" then back: 15 significant digits, as LAMMPS 2025 printed 0.0258359861195345
    /// for the variable z0 + v_dz with z0 = 0.025835986119534516 at step 0 (measured).
    #[test]
    fn retrieve_keeps_fifteen_digits() {
        assert_eq!(retrieve(0.025835986119534516), 0.0258359861195345);
        assert_eq!(retrieve(0.1 + 0.2), 0.3);
        assert_eq!(retrieve(-0.0), 0.0);
    }

    /// The moving region's variable and velocity: dz = ((-v) n) dt, and the finite
    /// difference is -v up to round-off (not bit-exactly, which is why it is computed
    /// as LAMMPS computes it).
    #[test]
    fn intruder_velocity_is_the_finite_difference_of_dz() {
        let (v, dt) = (0.1, 4e-5);
        let dz = |n: u64| -v * n as f64 * dt;
        for n in [1u64, 7, 1000] {
            let vz = (dz(n) - dz(n - 1)) / dt;
            assert!((vz + v).abs() < 1e-9 * v, "{vz}");
        }
        assert_eq!(dz(0), 0.0);
    }
}
