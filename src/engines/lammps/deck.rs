//! The LAMMPS deck and `read_data` file of a 2D disk system, written from the very
//! [`System`] the native engine integrates (same disks, masses, coefficients, box,
//! intruder), so both engines start from identical state.
//!
//! Model mapping (docs/impact2d.md): every interacting type pair gets its own
//! `gran/hooke/history` (k_t > 0) or `gran/hooke` (k_t = 0) instance under
//! `pair_style hybrid` — one `pair_style gran/*` has a single global coefficient set,
//! while K's wall disks (mu 0.9, e_n 0.1) differ from the grains. Wall disks are
//! `fix freeze` (LAMMPS then uses the mobile mass as m_eff, like the native engine) and
//! not integrated; grains and a disk intruder are `fix nve/sphere disc` (I = m r^2/2);
//! a cluster intruder is `fix rigid single` with all torque components off.

use crate::physics::dem2d::{Role, System, sphere_volume};
use anyhow::{Result, bail};
use std::fmt::Write as _;

pub const DATA_FILE: &str = "data.impact2d";
pub const DECK_FILE: &str = "in.impact2d";
pub const SNAP_FILE: &str = "snap.dump";
pub const INTRUDER_FILE: &str = "intruder.txt";

/// What to run and what to write.
#[derive(Debug, Clone)]
pub struct Outputs {
    pub n_steps: u64,
    /// Intruder centre of mass, velocity and total force every this many steps
    /// (0: no intruder output).
    pub intruder_every: u64,
    /// Full per-disk snapshot every this many steps (0: none).
    pub snapshot_every: u64,
}

/// Number of a LAMMPS atom type (1-based) for a 0-based native type.
fn ty(t: usize) -> usize {
    t + 1
}

/// Compact `group NAME id a:b c ...` arguments from sorted ids.
fn id_ranges(mut ids: Vec<u64>) -> String {
    ids.sort_unstable();
    let mut out = Vec::new();
    let mut k = 0;
    while k < ids.len() {
        let start = ids[k];
        let mut end = start;
        while k + 1 < ids.len() && ids[k + 1] == end + 1 {
            k += 1;
            end = ids[k];
        }
        out.push(if start == end {
            format!("{start}")
        } else {
            format!("{start}:{end}")
        });
        k += 1;
    }
    out.join(" ")
}

/// `read_data` file: `atom_style sphere` lines `id type diameter density x y z`, with
/// density = mass / (4/3 pi r^3) because LAMMPS converts it back with the sphere
/// volume (also in 2D); velocities in a `Velocities` section (`id vx vy vz wx wy wz`).
pub fn write_data(sys: &System) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "granval impact2d bed (SI units)\n");
    let _ = writeln!(s, "{} atoms", sys.disks.len());
    let _ = writeln!(s, "{} atom types\n", sys.n_types);
    let (lo, hi) = (sys.bx.lo, sys.bx.hi);
    let _ = writeln!(s, "{:e} {:e} xlo xhi", lo[0], hi[0]);
    let _ = writeln!(s, "{:e} {:e} ylo yhi", lo[1], hi[1]);
    // z is inert in 2D, but LAMMPS' binning refuses a z extent far below the cutoff.
    let zh = sys.disks.iter().map(|d| d.radius).fold(0.0, f64::max) * 2.0 + sys.skin;
    let _ = writeln!(s, "{:e} {:e} zlo zhi\n", -zh, zh);
    let _ = writeln!(s, "Atoms # sphere\n");
    for d in &sys.disks {
        let density = d.mass / sphere_volume(d.radius);
        let _ = writeln!(
            s,
            "{} {} {:e} {:e} {:e} {:e} 0",
            d.id,
            ty(d.type_),
            2.0 * d.radius,
            density,
            d.x[0],
            d.x[1]
        );
    }
    let _ = writeln!(s, "\nVelocities\n");
    for d in &sys.disks {
        let _ = writeln!(s, "{} {:e} {:e} 0 0 0 {:e}", d.id, d.v[0], d.v[1], d.omega);
    }
    s
}

/// The input deck. `System::dt`, gravity and skin are used as they are.
pub fn write_deck(sys: &System, out: &Outputs) -> Result<String> {
    let n_types = sys.n_types;
    let mut used = vec![false; n_types];
    for d in &sys.disks {
        used[d.type_] = true;
    }
    let frozen: Vec<u64> = sys
        .disks
        .iter()
        .filter(|d| d.role == Role::Frozen)
        .map(|d| d.id)
        .collect();
    let cluster: Vec<u64> = sys
        .disks
        .iter()
        .filter(|d| d.role == Role::Cluster)
        .map(|d| d.id)
        .collect();
    let intr: Vec<u64> = sys.intruder.iter().map(|&k| sys.disks[k].id).collect();
    let free: Vec<u64> = sys
        .disks
        .iter()
        .filter(|d| d.role == Role::Free)
        .map(|d| d.id)
        .collect();
    if free.is_empty() && cluster.is_empty() {
        bail!("nothing moves in this system");
    }
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# granval impact2d: generated deck, edits are overwritten"
    );
    let _ = writeln!(
        s,
        "units si\ndimension 2\natom_style sphere\natom_modify map array"
    );
    let _ = writeln!(
        s,
        "boundary {} f p",
        if sys.bx.periodic_x { "p" } else { "f" }
    );
    let _ = writeln!(s, "comm_modify vel yes");
    let _ = writeln!(s, "read_data {DATA_FILE}");
    let _ = writeln!(s, "group free id {}", id_ranges(free.clone()));
    if !frozen.is_empty() {
        let _ = writeln!(s, "group walls id {}", id_ranges(frozen.clone()));
    }
    if !intr.is_empty() {
        let _ = writeln!(s, "group intr id {}", id_ranges(intr.clone()));
    }
    let _ = writeln!(s, "neighbor {:e} bin", sys.skin);
    let mut nm = "neigh_modify delay 0 every 1 check yes".to_string();
    if !frozen.is_empty() {
        nm += " exclude group walls walls";
    }
    if !cluster.is_empty() {
        nm += " exclude group intr intr";
    }
    let _ = writeln!(s, "{nm}");
    // One sub-style instance per interacting type pair (see module doc).
    let mut pairs = Vec::new();
    for a in 0..n_types {
        for b in a..n_types {
            if used[a] && used[b] {
                pairs.push((a, b));
            }
        }
    }
    let style = |a: usize, b: usize| {
        let c = &sys.coeffs[a * n_types + b];
        if c.history() {
            "gran/hooke/history"
        } else {
            "gran/hooke"
        }
    };
    let count = |name: &str| pairs.iter().filter(|&&(a, b)| style(a, b) == name).count();
    let mut args = String::from("pair_style hybrid");
    for &(a, b) in &pairs {
        let c = &sys.coeffs[a * n_types + b];
        // dampflag 1: tangential damping on (gamma_t given explicitly).
        let _ = write!(
            args,
            " {} {:e} {:e} {:e} {:e} {:e} 1",
            style(a, b),
            c.kn,
            c.kt,
            c.gamma_n,
            c.gamma_t,
            c.mu
        );
    }
    let _ = writeln!(s, "{args}");
    let mut seen = std::collections::HashMap::<&str, usize>::new();
    for a in 0..n_types {
        for b in a..n_types {
            if pairs.contains(&(a, b)) {
                let st = style(a, b);
                let k = seen.entry(st).or_insert(0);
                *k += 1;
                let inst = if count(st) > 1 {
                    format!(" {k}")
                } else {
                    String::new()
                };
                let _ = writeln!(s, "pair_coeff {} {} {st}{inst}", ty(a), ty(b));
            } else {
                let _ = writeln!(s, "pair_coeff {} {} none", ty(a), ty(b));
            }
        }
    }
    let _ = writeln!(s, "timestep {:e}", sys.dt);
    let _ = writeln!(s, "fix grav all gravity {:e} vector 0 -1 0", sys.gravity);
    let _ = writeln!(s, "fix integ free nve/sphere disc");
    if !cluster.is_empty() {
        let _ = writeln!(s, "fix rig intr rigid single torque 1 off off off");
    }
    if !frozen.is_empty() {
        let _ = writeln!(s, "fix frz walls freeze");
    }
    let _ = writeln!(s, "fix e2d all enforce2d");
    if out.intruder_every > 0 && !intr.is_empty() {
        for (v, f) in [
            ("ix", "xcm(intr,x)"),
            ("iy", "xcm(intr,y)"),
            ("ivx", "vcm(intr,x)"),
            ("ivy", "vcm(intr,y)"),
            ("ifx", "fcm(intr,x)"),
            ("ify", "fcm(intr,y)"),
        ] {
            let _ = writeln!(s, "variable {v} equal {f}");
        }
        let n = out.intruder_every;
        let _ = writeln!(
            s,
            "fix iout all ave/time {n} 1 {n} v_ix v_iy v_ivx v_ivy v_ifx v_ify file {INTRUDER_FILE} format \" %.17g\""
        );
    }
    if out.snapshot_every > 0 {
        let _ = writeln!(
            s,
            "dump snap all custom {} {SNAP_FILE} id type radius mass x y vx vy omegaz fx fy",
            out.snapshot_every
        );
        let _ = writeln!(s, "dump_modify snap sort id format float %.17g");
    }
    let _ = writeln!(
        s,
        "thermo_style custom step atoms\nthermo {}",
        out.n_steps.clamp(1, 10_000)
    );
    let _ = writeln!(s, "run {}", out.n_steps);
    Ok(s)
}
