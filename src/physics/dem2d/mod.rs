//! Native 2D disk DEM for the impact experiment of Kondic et al. (K Sec. II):
//! linear spring-dashpot disks with Cundall-Strack friction ([`contact`]), periodic in
//! x, walls of frozen disks, gravity along -y, a rigid intruder (one disk or a
//! translating cluster of disks), integrated in the order of LAMMPS `fix nve/sphere
//! disc` + `fix rigid` so that the LAMMPS adapter is a like-for-like reference.
//!
//! One step (LAMMPS `run_style verlet`): half kick + drift (initial_integrate),
//! re-neighbour if needed, pair forces, gravity, half kick (final_integrate).

pub mod bed;
pub mod contact;
pub(crate) mod energy;
pub mod impact;
pub mod neighbor;

use contact::{Coeffs, PairIn, PairOut};
use neighbor::{Box2, Excluded, PairList};
use rayon::prelude::*;

/// How a disk moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Role {
    /// Integrated by velocity Verlet (`fix nve/sphere disc`).
    Free,
    /// Never moves (`fix freeze`, not integrated): wall disks.
    Frozen,
    /// Member of the rigid intruder cluster (`fix rigid`, rotation off).
    Cluster,
}

#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Disk {
    pub id: u64,
    /// 0-based type (coefficient table row).
    pub type_: usize,
    pub radius: f64,
    pub mass: f64,
    pub x: [f64; 2],
    pub v: [f64; 2],
    pub omega: f64,
    pub role: Role,
}

/// `4 pi/3 r^3`, in the operation order of LAMMPS' `read_data` for `atom_style
/// sphere` (`rmass *= 4.0*MY_PI/3.0 * r*r*r`), which turns the data file's density back
/// into a mass. LAMMPS 7Jan2022 does this in 2D too, so the data file carries
/// `mass / sphere_volume(r)` and both engines use the mass [`lammps_mass`] returns.
pub(crate) fn sphere_volume(r: f64) -> f64 {
    4.0 * std::f64::consts::PI / 3.0 * r * r * r
}

/// The mass LAMMPS will hold after reading `density = mass / sphere_volume(r)`.
pub fn lammps_mass(mass: f64, r: f64) -> f64 {
    let density = mass / sphere_volume(r);
    density * sphere_volume(r)
}

/// The rigid intruder cluster: translation only (K Sec. III A switches its rotation
/// off; LAMMPS `fix rigid ... torque 1 off off off`).
#[derive(Debug, Clone)]
pub struct Cluster {
    pub members: Vec<usize>,
    pub mass: f64,
    pub xcm: [f64; 2],
    pub vcm: [f64; 2],
    /// Member offsets from the centre of mass (fixed: no rotation).
    pub displace: Vec<[f64; 2]>,
    pub fcm: [f64; 2],
}

impl Cluster {
    /// A rigid cluster of `members` (indices into `disks`, whose role must be
    /// `Cluster`), centre of mass computed as LAMMPS' `fix rigid` does (mass-weighted).
    pub fn new(disks: &mut [Disk], members: Vec<usize>, vcm: [f64; 2]) -> Cluster {
        let mass: f64 = members.iter().map(|&k| disks[k].mass).sum();
        let mut xcm = [0.0; 2];
        for &k in &members {
            xcm[0] += disks[k].mass * disks[k].x[0];
            xcm[1] += disks[k].mass * disks[k].x[1];
        }
        xcm = [xcm[0] / mass, xcm[1] / mass];
        let displace = members
            .iter()
            .map(|&k| [disks[k].x[0] - xcm[0], disks[k].x[1] - xcm[1]])
            .collect();
        for &k in &members {
            disks[k].v = vcm;
            disks[k].role = Role::Cluster;
        }
        Cluster {
            members,
            mass,
            xcm,
            vcm,
            displace,
            fcm: [0.0; 2],
        }
    }
}

struct Exclusions<'a> {
    role: &'a [Role],
}

impl Excluded for Exclusions<'_> {
    fn excluded(&self, i: usize, j: usize) -> bool {
        matches!(
            (self.role[i], self.role[j]),
            (Role::Frozen, Role::Frozen) | (Role::Cluster, Role::Cluster)
        )
    }
}

/// What the contact law of one pair reads of the system (shared by the force pass and
/// [`System::contact_forces`], so both evaluate the same expression).
struct PairView<'a> {
    disks: &'a [Disk],
    /// The whole cluster's mass, which a cluster member brings into m_eff.
    cluster_mass: Option<f64>,
    coeffs: &'a [Coeffs],
    n_types: usize,
    bx: &'a Box2,
}

impl PairView<'_> {
    #[inline]
    fn meff_mass(&self, d: &Disk) -> f64 {
        match (d.role, self.cluster_mass) {
            (Role::Cluster, Some(m)) => m,
            _ => d.mass,
        }
    }

    /// The contact law's input for pair (i, j), or `None` when the two do not touch.
    /// Most listed pairs are within the skin but not touching: that is decided from the
    /// positions and radii alone, with the very test `hooke` makes, before loading
    /// velocities, spins and masses.
    #[inline]
    fn pair_in(&self, i: usize, j: usize) -> Option<(PairIn, &Coeffs)> {
        let (a, b) = (&self.disks[i], &self.disks[j]);
        let del = self.bx.delta(a.x, b.x);
        let rsq = del[0] * del[0] + del[1] * del[1];
        let radsum = a.radius + b.radius;
        if rsq >= radsum * radsum {
            return None;
        }
        let p = PairIn {
            del,
            ri: a.radius,
            rj: b.radius,
            vi: a.v,
            vj: b.v,
            wi: a.omega,
            wj: b.omega,
            mi: self.meff_mass(a),
            mj: self.meff_mass(b),
            frozen_i: a.role == Role::Frozen,
            frozen_j: b.role == Role::Frozen,
        };
        Some((p, &self.coeffs[a.type_ * self.n_types + b.type_]))
    }

    /// The contact law on pair (i, j) with its stored shear `sh` (zeroed when the pair
    /// does not touch).
    #[inline]
    fn pair(
        &self,
        i: usize,
        j: usize,
        sh: &mut [f64; 2],
        shear_update: bool,
        dt: f64,
    ) -> Option<PairOut> {
        match self.pair_in(i, j) {
            Some((p, c)) => contact::hooke(c, &p, sh, shear_update, dt),
            None => {
                *sh = [0.0, 0.0];
                None
            }
        }
    }
}

/// The state a step reads beyond the fixed inputs (contact table, box, gravity, dt,
/// skin): the disks, the forces and torques of the last step (the next half kick uses
/// them), the neighbour list with its shear history and its build positions, and the
/// step count. A system restored from it continues exactly as the one it was taken
/// from (every float round-trips through JSON), so a settling run stopped at a
/// checkpoint and continued later prepares the very bed an uninterrupted run does.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct Resume {
    disks: Vec<Disk>,
    f: Vec<[f64; 2]>,
    torque: Vec<f64>,
    list: PairList,
    step: u64,
}

impl Resume {
    pub(crate) fn disks(&self) -> &[Disk] {
        &self.disks
    }
}

#[derive(Debug, Clone)]
pub struct System {
    pub disks: Vec<Disk>,
    pub cluster: Option<Cluster>,
    /// `coeffs[a * n_types + b]`, symmetric.
    pub coeffs: Vec<Coeffs>,
    pub n_types: usize,
    pub bx: Box2,
    /// |g| (m/s^2), acting along -y.
    pub gravity: f64,
    pub dt: f64,
    pub skin: f64,
    pub step: u64,
    pub f: Vec<[f64; 2]>,
    pub torque: Vec<f64>,
    pub list: PairList,
    /// Per-pair result of the last force pass, in `list.pairs` order.
    pub last: Vec<Option<PairOut>>,
    /// Disks whose contact force is the intruder's observable.
    pub intruder: Vec<usize>,
    xs: Vec<[f64; 2]>,
    radii: Vec<f64>,
    roles: Vec<Role>,
    setup_done: bool,
}

impl System {
    /// Every argument is an independent physical input of the same rank (the state,
    /// the contact table, the box, gravity, step and skin); a builder would only hide
    /// which of them a caller forgot.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        disks: Vec<Disk>,
        cluster: Option<Cluster>,
        coeffs: Vec<Coeffs>,
        n_types: usize,
        bx: Box2,
        gravity: f64,
        dt: f64,
        skin: f64,
        intruder: Vec<usize>,
    ) -> System {
        let n = disks.len();
        let radii = disks.iter().map(|d| d.radius).collect();
        let roles = disks.iter().map(|d| d.role).collect();
        System {
            disks,
            cluster,
            coeffs,
            n_types,
            bx,
            gravity,
            dt,
            skin,
            step: 0,
            f: vec![[0.0; 2]; n],
            torque: vec![0.0; n],
            list: PairList::default(),
            last: Vec::new(),
            intruder,
            xs: Vec::new(),
            radii,
            roles,
            setup_done: false,
        }
    }

    pub fn time(&self) -> f64 {
        self.step as f64 * self.dt
    }

    /// The state to continue from later ([`Resume`]); the system must have been set up
    /// (a step or [`System::setup`]) and hold no rigid cluster (a settling bed has none).
    pub(crate) fn resume_state(&self) -> Resume {
        debug_assert!(self.setup_done && self.cluster.is_none());
        Resume {
            disks: self.disks.clone(),
            f: self.f.clone(),
            torque: self.torque.clone(),
            list: self.list.clone(),
            step: self.step,
        }
    }

    /// Continues from `r`, taken from a system built from the same inputs: the disks'
    /// count, radii and roles must be this system's, the force arrays and the shear
    /// history must match them, or the state belongs to another system.
    pub(crate) fn restore(&mut self, r: Resume) -> anyhow::Result<()> {
        let n = self.disks.len();
        let same_disks = r.disks.len() == n
            && r.disks
                .iter()
                .zip(&self.disks)
                .all(|(a, b)| a.id == b.id && a.radius == b.radius && a.role == b.role);
        if !same_disks {
            anyhow::bail!(
                "the saved state holds {} disks that are not this system's {n} (ids, radii or roles differ)",
                r.disks.len()
            );
        }
        if self.cluster.is_some() {
            anyhow::bail!("a system with a rigid cluster cannot be continued from a saved state");
        }
        let list_ok = r.list.shear.len() == r.list.pairs.len()
            && r.list.pairs.iter().all(|&(i, j)| i < j && (j as usize) < n);
        if r.f.len() != n || r.torque.len() != n || !list_ok {
            anyhow::bail!(
                "the saved state is inconsistent: {} forces, {} torques, {} pairs with {} shears for {n} disks",
                r.f.len(),
                r.torque.len(),
                r.list.pairs.len(),
                r.list.shear.len()
            );
        }
        self.disks = r.disks;
        self.f = r.f;
        self.torque = r.torque;
        self.list = r.list;
        self.step = r.step;
        self.last.clear();
        self.setup_done = true;
        Ok(())
    }

    fn neighbours(&mut self, force: bool) {
        // The displacement check reads the disks in place: no copy of the positions
        // unless the list is rebuilt.
        if force
            || self
                .list
                .needs_rebuild(&self.bx, self.disks.iter().map(|d| d.x), self.skin)
        {
            for d in &mut self.disks {
                d.x = self.bx.wrap(d.x);
            }
            self.xs.clear();
            self.xs.extend(self.disks.iter().map(|d| d.x));
            let ex = Exclusions { role: &self.roles };
            self.list
                .build(&self.bx, &self.xs, &self.radii, self.skin, &ex);
        }
    }

    /// Pair forces + gravity. Pairs are evaluated in parallel, each writing its result
    /// and its shear in place (no allocation per step), and summed serially in list
    /// order, so the result is independent of the thread count.
    fn forces(&mut self, shear_update: bool) {
        let dt = self.dt;
        let n_pairs = self.list.pairs.len();
        // `last` is fully overwritten below; resizing only allocates after a rebuild
        // that grew the list.
        self.last.resize(n_pairs, None);
        let this = PairView {
            disks: &self.disks,
            cluster_mass: self.cluster.as_ref().map(|c| c.mass),
            coeffs: &self.coeffs,
            n_types: self.n_types,
            bx: &self.bx,
        };
        self.last
            .par_iter_mut()
            .zip(self.list.shear.par_iter_mut())
            .zip(self.list.pairs.par_iter())
            // Chunks large enough that small systems do not drown in scheduling.
            .with_min_len(2048)
            .for_each(|((r, sh), &(i, j))| {
                *r = this.pair(i as usize, j as usize, sh, shear_update, dt);
            });
        for f in &mut self.f {
            *f = [0.0; 2];
        }
        for t in &mut self.torque {
            *t = 0.0;
        }
        for (r, &(i, j)) in self.last.iter().zip(&self.list.pairs) {
            if let Some(o) = r {
                let (i, j) = (i as usize, j as usize);
                self.f[i][0] += o.f[0];
                self.f[i][1] += o.f[1];
                self.f[j][0] -= o.f[0];
                self.f[j][1] -= o.f[1];
                self.torque[i] += o.torque_i;
                self.torque[j] += o.torque_j;
            }
        }
        // fix gravity: f += m g after the pair forces (fix freeze then zeroes walls).
        for (d, f) in self.disks.iter().zip(&mut self.f) {
            if d.role == Role::Frozen {
                *f = [0.0; 2];
            } else {
                f[1] += d.mass * -self.gravity;
            }
        }
        for (d, t) in self.disks.iter().zip(&mut self.torque) {
            if d.role == Role::Frozen {
                *t = 0.0;
            }
        }
        if let Some(c) = &mut self.cluster {
            let mut s = [0.0; 2];
            for &m in &c.members {
                s[0] += self.f[m][0];
                s[1] += self.f[m][1];
            }
            c.fcm = s;
        }
    }

    /// LAMMPS `setup`: neighbour list and forces without advancing the shear history.
    pub fn setup(&mut self) {
        if let Some(c) = &self.cluster {
            for (&m, d) in c.members.iter().zip(&c.displace) {
                let x = [c.xcm[0] + d[0], c.xcm[1] + d[1]];
                self.disks[m].x = self.bx.wrap(x);
                self.disks[m].v = c.vcm;
                self.disks[m].omega = 0.0;
            }
        }
        self.neighbours(true);
        self.forces(false);
        self.setup_done = true;
    }

    /// One velocity-Verlet step in the order of `fix nve/sphere disc` / `fix rigid`.
    pub fn step(&mut self) {
        if !self.setup_done {
            self.setup();
        }
        let dtf = 0.5 * self.dt;
        let dtv = self.dt;
        // fix nve/sphere disc: moment of inertia 0.5 m r^2.
        let dtfrotate = dtf / 0.5;
        for (k, d) in self.disks.iter_mut().enumerate() {
            if d.role != Role::Free {
                continue;
            }
            let dtfm = dtf / d.mass;
            d.v[0] += dtfm * self.f[k][0];
            d.v[1] += dtfm * self.f[k][1];
            d.x[0] += dtv * d.v[0];
            d.x[1] += dtv * d.v[1];
            let dtirotate = dtfrotate / (d.radius * d.radius * d.mass);
            d.omega += dtirotate * self.torque[k];
        }
        if let Some(c) = &mut self.cluster {
            let dtfm = dtf / c.mass;
            c.vcm[0] += dtfm * c.fcm[0];
            c.vcm[1] += dtfm * c.fcm[1];
            c.xcm[0] += dtv * c.vcm[0];
            c.xcm[1] += dtv * c.vcm[1];
            for (&m, o) in c.members.iter().zip(&c.displace) {
                self.disks[m].x = [c.xcm[0] + o[0], c.xcm[1] + o[1]];
                self.disks[m].v = c.vcm;
            }
        }
        self.neighbours(false);
        self.forces(true);
        for (k, d) in self.disks.iter_mut().enumerate() {
            if d.role != Role::Free {
                continue;
            }
            let dtfm = dtf / d.mass;
            d.v[0] += dtfm * self.f[k][0];
            d.v[1] += dtfm * self.f[k][1];
            let dtirotate = dtfrotate / (d.radius * d.radius * d.mass);
            d.omega += dtirotate * self.torque[k];
        }
        if let Some(c) = &mut self.cluster {
            let dtfm = dtf / c.mass;
            c.vcm[0] += dtfm * c.fcm[0];
            c.vcm[1] += dtfm * c.fcm[1];
            for &m in &c.members {
                self.disks[m].v = c.vcm;
            }
        }
        self.step += 1;
    }

    /// Every touching pair's (i, j, |F_n|, |F_t|) (indices into `disks`), the contact law
    /// re-evaluated on the current state with the stored shear left as it is: what LAMMPS'
    /// `compute pair/local` reports at the end of a step (its `single()` reads positions,
    /// full-step velocities and the stored shear the same way). F_n is the component
    /// along the centre line; the tangential force is perpendicular to it.
    pub(crate) fn contact_forces(&self) -> Vec<(usize, usize, f64, f64)> {
        let view = PairView {
            disks: &self.disks,
            cluster_mass: self.cluster.as_ref().map(|c| c.mass),
            coeffs: &self.coeffs,
            n_types: self.n_types,
            bx: &self.bx,
        };
        let mut out = Vec::new();
        for (&(i, j), &sh) in self.list.pairs.iter().zip(&self.list.shear) {
            let (i, j) = (i as usize, j as usize);
            let Some((p, c)) = view.pair_in(i, j) else {
                continue;
            };
            let mut sh = sh;
            if let Some(o) = contact::hooke(c, &p, &mut sh, false, self.dt) {
                let r = p.del[0].hypot(p.del[1]);
                let n = [p.del[0] / r, p.del[1] / r];
                let f_n = o.f[0] * n[0] + o.f[1] * n[1];
                let ft = [o.f[0] - f_n * n[0], o.f[1] - f_n * n[1]];
                out.push((i, j, f_n.abs(), ft[0].hypot(ft[1])));
            }
        }
        out
    }

    /// Contact force on the intruder from everything else (gravity excluded).
    pub(crate) fn intruder_contact_force(&self) -> [f64; 2] {
        let mut s = [0.0; 2];
        let mut is_intr = vec![false; self.disks.len()];
        for &k in &self.intruder {
            is_intr[k] = true;
        }
        for (r, &(i, j)) in self.last.iter().zip(&self.list.pairs) {
            if let Some(o) = r {
                let (i, j) = (i as usize, j as usize);
                if is_intr[i] && !is_intr[j] {
                    s[0] += o.f[0];
                    s[1] += o.f[1];
                } else if is_intr[j] && !is_intr[i] {
                    s[0] -= o.f[0];
                    s[1] -= o.f[1];
                }
            }
        }
        s
    }

    /// Kinetic energy (translation + rotation, I = m r^2/2) of the mobile disks.
    pub(crate) fn kinetic_energy(&self) -> f64 {
        self.disks
            .iter()
            .filter(|d| d.role != Role::Frozen)
            .map(|d| {
                0.5 * d.mass * (d.v[0] * d.v[0] + d.v[1] * d.v[1])
                    + 0.25 * d.mass * d.radius * d.radius * d.omega * d.omega
            })
            .sum()
    }
}
