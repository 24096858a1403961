//! Bed preparation of K Sec. II, in the native engine only (the LAMMPS run reads the
//! finished bed through `read_data`, so both engines start from the very same grains).
//!
//! - random: polydisperse disks, diameters uniform in `d (1 +- r)`, on a square lattice
//!   of pitch `d (1 + r)` with uniformly random velocity components in `+- v0`
//!   (seeded), settled under gravity until the total kinetic energy
//!   (translation + rotation) is below `settle_ke` (K: 1e-10 m g d). The rough top is
//!   then smoothed: the bed is cut into columns 2 d wide, the lowest of the columns'
//!   highest grain tops is the cut height, and every grain whose centre lies above it
//!   is removed; the rest settles again to the same criterion.
//! - hexagonal: monodisperse disks of diameter d touching in a hexagonal lattice on a
//!   wall row of the same pitch, equilibrated under gravity to the same criterion.
//!
//! The bottom wall is one row of frozen disks (K: "rigid horizontal walls made up from
//! monodisperse particles"), pitch `L / n` with n = floor(L / wall_d).

use super::contact::Coeffs;
use super::neighbor::Box2;
use super::{Disk, Role, System, lammps_mass};
use anyhow::{Result, bail};
use rand::{Rng, SeedableRng};

pub use crate::case::impact2d::Packing;

/// Everything bed preparation needs, SI.
#[derive(Debug, Clone, serde::Serialize)]
pub struct BedSpec {
    pub packing: Packing,
    pub count: usize,
    /// Periodic length L (m).
    pub length: f64,
    /// Mean grain diameter d (m).
    pub d: f64,
    /// Polydispersity r: diameters uniform in d (1 +- r). Ignored (0) for hexagonal.
    pub polydispersity: f64,
    /// Mass per area (kg/m^2) so that a disk of diameter d has the mass scale m.
    pub areal_density: f64,
    pub wall_d: f64,
    pub seed: u64,
    /// Initial velocity components uniform in +- this (m/s).
    pub initial_speed: f64,
    /// Total kinetic energy threshold (J).
    pub settle_ke: f64,
    /// How long (s) the total kinetic energy must stay below `settle_ke`, tested at
    /// every check, before the bed counts as settled; 0 tests one check (K Sec. II's
    /// criterion as written). A bed settled with a tangential spring rings in a
    /// collective mode whose kinetic energy passes near zero twice a period, so one
    /// check can land on a node while the mode still carries thousands of times the
    /// threshold (docs/impact2d.md, "Protocol and observables"). Left out of the
    /// serialized specification when 0, so the names and seals of beds made before it
    /// stay as they were.
    #[serde(skip_serializing_if = "is_zero")]
    pub settle_hold: f64,
    /// Give up (error) after this much simulated settling time (s).
    pub max_settle_time: f64,
    pub dt: f64,
    pub skin: f64,
    pub gravity: f64,
    /// Coefficients for types 0 (grain) and 1 (wall), 2x2 symmetric.
    pub coeffs: [Coeffs; 4],
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// A settled bed: grains (type 0, free) and the bottom wall (type 1, frozen).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Bed {
    pub grains: Vec<Disk>,
    pub wall: Vec<Disk>,
    /// Top of the bottom wall (y of the wall disks' tops).
    pub floor: f64,
    pub settle_time: f64,
    pub final_ke: f64,
    /// Grains removed by smoothing.
    pub removed: usize,
    /// Packing fraction (disk area / area) between 2 d above the floor and 2 d
    /// below the surface.
    pub packing_fraction: f64,
}

impl Bed {
    /// Height of the bed's surface at horizontal position `x`: the highest point of
    /// any grain above `x` (K Sec. III: "the initial upper boundary of the granular bed
    /// at the point of impact").
    pub fn surface_at(&self, x: f64, length: f64) -> f64 {
        self.grains
            .iter()
            .filter_map(|g| {
                let mut dx = (g.x[0] - x).abs();
                dx = dx.min(length - dx);
                (dx < g.radius).then(|| g.x[1] + (g.radius * g.radius - dx * dx).sqrt())
            })
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// Highest grain top anywhere.
    pub fn top(&self) -> f64 {
        self.grains
            .iter()
            .map(|g| g.x[1] + g.radius)
            .fold(f64::NEG_INFINITY, f64::max)
    }
}

pub(crate) fn wall_row(length: f64, wall_d: f64, y: f64, first_id: u64) -> Vec<Disk> {
    let n = ((length / wall_d).floor() as usize).max(1);
    let pitch = length / n as f64;
    (0..n)
        .map(|k| Disk {
            id: first_id + k as u64,
            type_: 1,
            radius: 0.5 * wall_d,
            // Walls are frozen: their mass never enters m_eff (LAMMPS uses the mobile
            // partner's mass), any positive value will do.
            mass: 1.0,
            x: [(k as f64 + 0.5) * pitch, y],
            v: [0.0; 2],
            omega: 0.0,
            role: Role::Frozen,
        })
        .collect()
}

fn disk_mass(spec: &BedSpec, r: f64) -> f64 {
    lammps_mass(spec.areal_density * std::f64::consts::PI * r * r, r)
}

fn initial_grains(spec: &BedSpec, floor: f64) -> Result<Vec<Disk>> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(spec.seed);
    let mut out = Vec::with_capacity(spec.count);
    match spec.packing {
        Packing::Random => {
            let pitch = spec.d * (1.0 + spec.polydispersity) * 1.02;
            let ncols = (spec.length / pitch).floor() as usize;
            if ncols == 0 {
                bail!(
                    "bed length {} m is shorter than one lattice pitch {pitch} m",
                    spec.length
                );
            }
            let px = spec.length / ncols as f64;
            for k in 0..spec.count {
                let (c, row) = (k % ncols, k / ncols);
                let dia = spec.d * (1.0 + spec.polydispersity * (2.0 * rng.random::<f64>() - 1.0));
                let r = 0.5 * dia;
                let v = [
                    spec.initial_speed * (2.0 * rng.random::<f64>() - 1.0),
                    spec.initial_speed * (2.0 * rng.random::<f64>() - 1.0),
                ];
                out.push(Disk {
                    id: k as u64 + 1,
                    type_: 0,
                    radius: r,
                    mass: disk_mass(spec, r),
                    x: [(c as f64 + 0.5) * px, floor + (row as f64 + 0.5) * pitch],
                    v,
                    omega: 0.0,
                    role: Role::Free,
                });
            }
        }
        Packing::Hexagonal => {
            let ncols = (spec.length / spec.d).round() as usize;
            let pitch = spec.length / ncols as f64;
            if pitch < spec.d * (1.0 - 1e-12) {
                bail!("hexagonal bed: L / round(L/d) = {pitch} m < d; choose L a multiple of d");
            }
            let dy = pitch * 3f64.sqrt() / 2.0;
            let r = 0.5 * spec.d;
            for k in 0..spec.count {
                let (c, row) = (k % ncols, k / ncols);
                // Row 0 sits in the pockets of the wall row (wall disks at (k + 1/2) pitch).
                let shift = if row % 2 == 0 { 0.0 } else { 0.5 };
                let x = ((c as f64 + shift) * pitch).rem_euclid(spec.length);
                out.push(Disk {
                    id: k as u64 + 1,
                    type_: 0,
                    radius: r,
                    mass: disk_mass(spec, r),
                    x: [x, floor - 0.5 * spec.wall_d + (row as f64 + 1.0) * dy],
                    v: [0.0; 2],
                    omega: 0.0,
                    role: Role::Free,
                });
            }
        }
    }
    Ok(out)
}

fn system(spec: &BedSpec, grains: Vec<Disk>, wall: &[Disk], top: f64) -> System {
    let mut disks = grains;
    disks.extend_from_slice(wall);
    let bx = Box2 {
        lo: [0.0, 0.0],
        hi: [spec.length, top],
        periodic_x: true,
    };
    System::new(
        disks,
        None,
        spec.coeffs.to_vec(),
        2,
        bx,
        spec.gravity,
        spec.dt,
        spec.skin,
        vec![],
    )
}

/// Which settling a checkpoint was taken in: the pour's, or the one after the rough
/// top was cut away (which needs the first's duration and how many grains went).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) enum Phase {
    First,
    Second { first_time: f64, removed: usize },
}

/// A settling stopped part way, to be continued later: a bed of 20 000 disks takes
/// hours to settle to K's criterion, longer than a cluster job's wall time or a
/// working session may allow. Continuing from it gives the bed an uninterrupted run
/// gives, bit for bit ([`super::Resume`]).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct SettleCheckpoint {
    /// [`identity`] of the specification it was taken under.
    pub(crate) identity: String,
    pub(crate) phase: Phase,
    /// Mobile grains in the system (the wall disks follow them).
    pub(crate) grains: usize,
    /// Top of the settling box (from the grains the phase started with).
    pub(crate) top: f64,
    pub(crate) state: super::Resume,
    pub(crate) trace: crate::physics::settle_trace::SettleTrace,
    /// Consecutive checks, up to the checkpoint, at which the kinetic energy was below
    /// the threshold (`BedSpec::settle_hold`); absent in checkpoints taken before the
    /// hold existed, whose settlings test one check (0 is then exact).
    #[serde(default)]
    pub(crate) below: u64,
}

impl SettleCheckpoint {
    /// The settling it was taken in.
    pub(crate) fn phase(&self) -> Phase {
        self.phase
    }
}

/// The specification a checkpoint belongs to, as JSON with the time cap left out: a
/// bed stopped by `max_settle_time` continues when the cap is raised, and the cap
/// changes nothing else of the settling.
pub(crate) fn identity(spec: &BedSpec) -> String {
    let mut s = spec.clone();
    s.max_settle_time = 0.0;
    serde_json::to_string(&s).unwrap_or_default()
}

/// Where a settling keeps its checkpoints. The default keeps none.
pub(crate) trait Checkpoints {
    /// A checkpoint to continue from, if one was kept.
    fn resume(&mut self) -> Result<Option<SettleCheckpoint>> {
        Ok(None)
    }
    /// Asked at every energy check: whether to save now.
    fn due(&mut self) -> bool {
        false
    }
    fn save(&mut self, _checkpoint: &SettleCheckpoint) -> Result<()> {
        Ok(())
    }
    /// Where the state is kept, for the message of a bed that did not settle.
    fn kept_at(&self) -> Option<String> {
        None
    }
}

/// No checkpoints: a settling that stops starts again from the pour.
pub(crate) struct NoCheckpoints;
impl Checkpoints for NoCheckpoints {}

/// How one settling phase starts.
enum Start {
    Pour(Vec<Disk>),
    Resume(Box<SettleCheckpoint>),
}

/// Runs until the total kinetic energy is below the threshold; returns the settled
/// grains and the time it took. Saves a checkpoint when `ckpt` says it is due and
/// when the time allowed runs out (so a raised cap continues from there).
fn settle(
    spec: &BedSpec,
    start: Start,
    wall: &[Disk],
    phase: Phase,
    ckpt: &mut dyn Checkpoints,
    mut progress: impl FnMut(f64, f64),
) -> Result<(Vec<Disk>, f64, f64)> {
    let (mut sys, n, top, mut trace, mut below) = match start {
        Start::Pour(grains) => {
            let n = grains.len();
            let top = grains.iter().map(|g| g.x[1] + g.radius).fold(0.0, f64::max) + spec.d;
            let mut sys = system(spec, grains, wall, top);
            sys.setup();
            (
                sys,
                n,
                top,
                crate::physics::settle_trace::SettleTrace::default(),
                0,
            )
        }
        Start::Resume(c) => {
            let c = *c;
            let saved = c.state.disks();
            if c.grains > saved.len() || saved[c.grains..].len() != wall.len() {
                bail!(
                    "the checkpoint holds {} disks for {} grains, not the {} wall disks of this bed",
                    saved.len(),
                    c.grains,
                    wall.len()
                );
            }
            let grains = saved[..c.grains].to_vec();
            let mut sys = system(spec, grains, wall, c.top);
            sys.restore(c.state)?;
            (sys, c.grains, c.top, c.trace, c.below)
        }
    };
    let check_every = 50u64;
    let needed = checks_below_needed(spec, check_every);
    let max_steps = (spec.max_settle_time / spec.dt).ceil() as u64;
    let mut ke = sys.kinetic_energy();
    let checkpoint = |sys: &System,
                      trace: &crate::physics::settle_trace::SettleTrace,
                      below: u64| SettleCheckpoint {
        identity: identity(spec),
        phase,
        grains: n,
        top,
        state: sys.resume_state(),
        trace: trace.clone(),
        below,
    };
    while sys.step < max_steps {
        for _ in 0..check_every {
            sys.step();
        }
        ke = sys.kinetic_energy();
        if !ke.is_finite() {
            bail!(
                "bed settling diverged at t = {:.4e} s (kinetic energy {ke})",
                sys.time()
            );
        }
        progress(sys.time(), ke);
        trace.push(sys.time(), ke);
        below = if ke < spec.settle_ke { below + 1 } else { 0 };
        if below >= needed && sys.step >= 2 * check_every {
            let t = sys.time();
            let grains = sys.disks.into_iter().take(n).collect();
            return Ok((grains, t, ke));
        }
        if ckpt.due() {
            ckpt.save(&checkpoint(&sys, &trace, below))?;
        }
    }
    let kept = match ckpt.save(&checkpoint(&sys, &trace, below)) {
        Ok(()) => ckpt.kept_at().map_or(String::new(), |at| {
            format!("; its state is kept in {at}: raise bed.max_settle_time and run again to continue from there")
        }),
        Err(e) => format!("; its state could not be kept: {e:#}"),
    };
    // K's criterion is in m g d: the weight of a grain of diameter d lifted by d.
    let mgd = spec.areal_density * std::f64::consts::FRAC_PI_4 * spec.d.powi(3) * spec.gravity;
    // Below the threshold at the cap, but not yet for the whole hold.
    let state = if below > 0 {
        format!(
            "below {:.3e} J at the last {below} checks only, not the {needed} that span bed.settle_hold",
            spec.settle_ke
        )
    } else {
        format!("still above {:.3e} J", spec.settle_ke)
    };
    bail!(
        "bed did not settle: total kinetic energy {ke:.3e} J {state} after {:.4e} s (bed.max_settle_time); m g d = {mgd:.3e} J, {}{kept}",
        spec.max_settle_time,
        trace.describe("total KE", mgd, " m g d")
    )
}

/// How many consecutive checks, `check_every` steps apart, must find the kinetic
/// energy below the threshold: one without a hold (K's test), else enough to span
/// `settle_hold` from the first to the last.
fn checks_below_needed(spec: &BedSpec, check_every: u64) -> u64 {
    let interval = check_every as f64 * spec.dt;
    1 + (spec.settle_hold / interval).ceil() as u64
}

/// Prepares the bed; `progress(t, ke)` is called during settling.
pub fn prepare(spec: &BedSpec, progress: impl FnMut(f64, f64)) -> Result<Bed> {
    prepare_resumable(spec, &mut NoCheckpoints, progress)
}

/// [`prepare`], continuing from the checkpoint `ckpt` holds (if any) and saving new
/// ones as it asks. A checkpoint of another specification is an error, never a bed
/// of this one.
pub(crate) fn prepare_resumable(
    spec: &BedSpec,
    ckpt: &mut dyn Checkpoints,
    mut progress: impl FnMut(f64, f64),
) -> Result<Bed> {
    let wall_y = 0.5 * spec.wall_d;
    let wall = wall_row(spec.length, spec.wall_d, wall_y, spec.count as u64 + 1);
    let floor = spec.wall_d;
    let resume = ckpt.resume()?;
    if let Some(c) = &resume
        && c.identity != identity(spec)
    {
        bail!(
            "the settling checkpoint{} was taken for another bed specification ({}), not this one ({})",
            ckpt.kept_at().map_or(String::new(), |at| format!(" {at}")),
            c.identity,
            identity(spec)
        );
    }

    let (first, second) = match resume {
        None => (Some(Start::Pour(initial_grains(spec, floor)?)), None),
        Some(c) if c.phase == Phase::First => (Some(Start::Resume(Box::new(c))), None),
        Some(c) => (None, Some(c)),
    };
    let (grains, removed, t1, t2, ke) = match (first, second) {
        (Some(start), _) => {
            let (grains, t1, ke1) = settle(spec, start, &wall, Phase::First, ckpt, &mut progress)?;
            match spec.packing {
                Packing::Hexagonal => (grains, 0, t1, 0.0, ke1),
                Packing::Random => {
                    let (kept, removed) = smooth(spec, grains);
                    let phase = Phase::Second {
                        first_time: t1,
                        removed,
                    };
                    let (kept, t2, ke2) =
                        settle(spec, Start::Pour(kept), &wall, phase, ckpt, &mut progress)?;
                    (kept, removed, t1, t2, ke2)
                }
            }
        }
        (None, Some(c)) => {
            let Phase::Second {
                first_time,
                removed,
            } = c.phase
            else {
                unreachable!("only a second-phase checkpoint reaches here")
            };
            let phase = c.phase;
            let (kept, t2, ke2) = settle(
                spec,
                Start::Resume(Box::new(c)),
                &wall,
                phase,
                ckpt,
                &mut progress,
            )?;
            (kept, removed, first_time, t2, ke2)
        }
        (None, None) => unreachable!("a settling starts from the pour or a checkpoint"),
    };
    let mut bed = Bed {
        grains,
        wall,
        floor,
        settle_time: t1 + t2,
        final_ke: ke,
        removed,
        packing_fraction: 0.0,
    };
    bed.packing_fraction = packing_fraction(&bed, spec);
    Ok(bed)
}

/// K's smoothing of the rough top: columns 2 d wide, the lowest of their highest grain
/// tops is the cut, every grain whose centre is above it goes. Returns the kept grains
/// and how many went.
fn smooth(spec: &BedSpec, grains: Vec<Disk>) -> (Vec<Disk>, usize) {
    let width = 2.0 * spec.d;
    let ncol = ((spec.length / width).floor() as usize).max(1);
    let mut col_top = vec![f64::NEG_INFINITY; ncol];
    for g in &grains {
        let c = ((g.x[0] / spec.length * ncol as f64) as usize).min(ncol - 1);
        col_top[c] = col_top[c].max(g.x[1] + g.radius);
    }
    let cut = col_top.iter().copied().fold(f64::INFINITY, f64::min);
    let before = grains.len();
    let kept: Vec<Disk> = grains.into_iter().filter(|g| g.x[1] <= cut).collect();
    let removed = before - kept.len();
    (kept, removed)
}

fn packing_fraction(bed: &Bed, spec: &BedSpec) -> f64 {
    let lo = bed.floor + 2.0 * spec.d;
    let hi = bed.top() - 2.0 * spec.d;
    if hi <= lo {
        return f64::NAN;
    }
    let area: f64 = bed
        .grains
        .iter()
        .filter(|g| g.x[1] > lo && g.x[1] < hi)
        .map(|g| std::f64::consts::PI * g.radius * g.radius)
        .sum();
    area / (spec.length * (hi - lo))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The random bed of `tests/impact2d_bed.rs`: 160 disks on 16 d, soft springs.
    pub(crate) fn spec() -> BedSpec {
        let d = 0.004;
        let c = Coeffs {
            kn: 400.0,
            kt: 0.0,
            gamma_n: 1500.0,
            gamma_t: 750.0,
            mu: 0.5,
        };
        let w = Coeffs {
            kn: 400.0,
            kt: 0.0,
            gamma_n: 4000.0,
            gamma_t: 2000.0,
            mu: 0.9,
        };
        BedSpec {
            packing: Packing::Random,
            count: 160,
            length: 16.0 * d,
            d,
            polydispersity: 0.2,
            areal_density: 1e-4 / (std::f64::consts::PI * 0.25 * d * d),
            wall_d: d,
            seed: 11,
            initial_speed: 0.05,
            settle_ke: 1e-8 * 1e-4 * 9.81 * d,
            settle_hold: 0.0,
            max_settle_time: 30.0,
            dt: 2e-5,
            skin: 0.3 * d,
            gravity: 9.81,
            coeffs: [c, w, w, w],
        }
    }

    /// Keeps every checkpoint a settling saves (as the JSON a checkpoint file holds) and
    /// hands one back to continue from.
    #[derive(Default)]
    struct Kept {
        every: usize,
        checks: usize,
        saved: Vec<String>,
        resume_from: Option<String>,
    }

    impl Checkpoints for Kept {
        fn resume(&mut self) -> anyhow::Result<Option<SettleCheckpoint>> {
            Ok(match &self.resume_from {
                Some(j) => Some(serde_json::from_str(j)?),
                None => None,
            })
        }
        fn due(&mut self) -> bool {
            self.checks += 1;
            self.every > 0 && self.checks.is_multiple_of(self.every)
        }
        fn save(&mut self, c: &SettleCheckpoint) -> anyhow::Result<()> {
            self.saved.push(serde_json::to_string(c)?);
            Ok(())
        }
        fn kept_at(&self) -> Option<String> {
            Some("memory".into())
        }
    }

    fn phase_of(json: &str) -> Phase {
        serde_json::from_str::<SettleCheckpoint>(json)
            .unwrap()
            .phase()
    }

    /// A settling continued from a checkpoint, in the pour's settling or in the one after
    /// smoothing, prepares the very bed an uninterrupted settling prepares (every float,
    /// through JSON as a checkpoint file keeps it); and a bed stopped by its time cap keeps
    /// its state, and continues to that same bed when the cap is raised. A bed of 20 000
    /// disks needs hours to settle (K Fig 12), more than one job may run.
    #[test]
    fn a_settling_continued_from_a_checkpoint_is_the_uninterrupted_one() {
        // Static friction (k_t > 0), so the shear history is part of the state.
        let mut s = spec();
        for c in &mut s.coeffs {
            c.kt = 0.5 * c.kn;
        }
        let whole = prepare(&s, |_, _| {}).unwrap();
        let whole_json = serde_json::to_string(&whole).unwrap();
        let mut rec = Kept {
            every: 40,
            ..Kept::default()
        };
        let recorded = prepare_resumable(&s, &mut rec, |_, _| {}).unwrap();
        assert_eq!(
            serde_json::to_string(&recorded).unwrap(),
            whole_json,
            "saving checkpoints changed the bed"
        );
        let first: Vec<&String> = rec
            .saved
            .iter()
            .filter(|j| phase_of(j) == Phase::First)
            .collect();
        let second: Vec<&String> = rec
            .saved
            .iter()
            .filter(|j| phase_of(j) != Phase::First)
            .collect();
        assert!(
            first.len() >= 2 && second.len() >= 2,
            "{} + {} checkpoints: the test needs some in each phase",
            first.len(),
            second.len()
        );
        for from in [first[first.len() / 2], second[second.len() / 2]] {
            let mut again = Kept {
                resume_from: Some(from.clone()),
                ..Kept::default()
            };
            let b = prepare_resumable(&s, &mut again, |_, _| {}).unwrap();
            assert_eq!(
                serde_json::to_string(&b).unwrap(),
                whole_json,
                "continued from a {:?} checkpoint",
                phase_of(from)
            );
        }
        // Stopped by the cap in the pour's settling, then continued with the cap raised.
        let capped = BedSpec {
            max_settle_time: 0.25 * whole.settle_time,
            ..s.clone()
        };
        let mut stop = Kept::default();
        let e = format!(
            "{:#}",
            prepare_resumable(&capped, &mut stop, |_, _| {}).unwrap_err()
        );
        assert!(
            e.contains("its state is kept in memory: raise bed.max_settle_time"),
            "{e}"
        );
        let mut go_on = Kept {
            resume_from: stop.saved.last().cloned(),
            ..Kept::default()
        };
        let b = prepare_resumable(&s, &mut go_on, |_, _| {}).unwrap();
        assert_eq!(serde_json::to_string(&b).unwrap(), whole_json);
        // A checkpoint of another bed is refused, not continued.
        let other = BedSpec {
            seed: 12,
            ..s.clone()
        };
        let mut wrong = Kept {
            resume_from: stop.saved.last().cloned(),
            ..Kept::default()
        };
        let e = format!(
            "{:#}",
            prepare_resumable(&other, &mut wrong, |_, _| {}).unwrap_err()
        );
        assert!(e.contains("taken for another bed specification"), "{e}");
    }

    /// `settle_hold`: the bed counts as settled only after the kinetic energy has been
    /// below the threshold at every check spanning the hold, in each settling (the
    /// pour's and the one after smoothing), never at the first check below it; and a
    /// settling continued from a checkpoint taken inside a hold prepares the same bed.
    #[test]
    fn a_held_criterion_needs_every_check_of_the_hold_below_the_threshold() {
        let mut s = spec();
        for c in &mut s.coeffs {
            c.kt = 0.5 * c.kn;
        }
        let check = 50.0 * s.dt;
        s.settle_hold = 20.0 * check;
        let needed = checks_below_needed(&s, 50);
        assert_eq!(needed, 21);
        let mut samples: Vec<(f64, f64)> = Vec::new();
        let held = prepare(&s, |t, ke| samples.push((t, ke))).unwrap();
        // The two settlings, split where the clock starts again.
        let cut = samples
            .windows(2)
            .position(|w| w[1].0 < w[0].0)
            .expect("a random bed settles twice")
            + 1;
        for phase in [&samples[..cut], &samples[cut..]] {
            let below: Vec<bool> = phase.iter().map(|x| x.1 < s.settle_ke).collect();
            let n = below.len();
            assert!(below[n - needed as usize..].iter().all(|b| *b));
            // No earlier run of `needed` checks below: the first such run ends it.
            let mut run = 0;
            for b in &below[..n - 1] {
                run = if *b { run + 1 } else { 0 };
                assert!(run < needed, "settled later than the first full hold");
            }
        }
        // K's one-check criterion ends the pour's settling at the first check below,
        // `needed - 1` checks or more before the hold does.
        let mut one: Vec<f64> = Vec::new();
        let one_check = BedSpec {
            settle_hold: 0.0,
            ..s.clone()
        };
        prepare(&one_check, |t, _| one.push(t)).unwrap();
        let one_cut = one.windows(2).position(|w| w[1] < w[0]).unwrap() + 1;
        let gap = samples[cut - 1].0 - one[one_cut - 1];
        assert!(gap > (needed - 1) as f64 * check * (1.0 - 1e-9), "{gap}");
        // Continued from a checkpoint taken inside a hold: the same bed, every float.
        let held_json = serde_json::to_string(&held).unwrap();
        let mut rec = Kept {
            every: 1,
            ..Kept::default()
        };
        prepare_resumable(&s, &mut rec, |_, _| {}).unwrap();
        let inside = rec
            .saved
            .iter()
            .filter(|j| {
                let b = serde_json::from_str::<SettleCheckpoint>(j).unwrap().below;
                b > 0 && b < needed
            })
            .nth(3)
            .expect("checkpoints inside a hold")
            .clone();
        let mut again = Kept {
            resume_from: Some(inside),
            ..Kept::default()
        };
        let b = prepare_resumable(&s, &mut again, |_, _| {}).unwrap();
        assert_eq!(serde_json::to_string(&b).unwrap(), held_json);
    }
}
