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

use crate::engines::deck_text::{Header, approx, block, comment, num, write_header};
use crate::physics::dem2d::{Role, System, sphere_volume};
use anyhow::{Result, bail};
use std::fmt::Write as _;

pub const DATA_FILE: &str = "data.impact2d";
pub const DECK_FILE: &str = "in.impact2d";
pub const SNAP_FILE: &str = "snap.dump";
pub(crate) const INTRUDER_FILE: &str = "intruder.txt";
pub(crate) const GRAINS_FILE: &str = "grains.dump";
pub(crate) const CONTACTS_FILE: &str = "contacts.dump";

/// What to run and what to write.
#[derive(Debug, Clone)]
pub struct Outputs {
    pub n_steps: u64,
    /// Intruder centre of mass, velocity and total force every this many steps
    /// (0: no intruder output).
    pub intruder_every: u64,
    /// Full per-disk snapshot every this many steps (0: none).
    pub snapshot_every: u64,
    /// Title and leading paragraphs of the deck's header (the case, its units); the deck
    /// adds what it runs and writes.
    pub header: Header,
    /// Bed snapshots (K Sec. IV): grain positions and contact forces at chosen steps.
    pub fields: crate::physics::dem2d::impact::SnapshotSteps,
    /// Atom ids of the interface tracers (K Fig 12): their centre of mass in y is an
    /// eighth column of the intruder file. Empty: not tracked, and the deck does not
    /// mention it.
    pub tracers: Vec<u64>,
}

/// An equal-style LAMMPS formula whose value is the first of `steps` (sorted, > 0)
/// after the current step, and `beyond` after the last: `dump_modify every v_NAME`
/// writes exactly at those steps (LAMMPS 29Sep2021 has no ternary(), so the cases are
/// products of logical terms).
fn next_step_formula(steps: &[u64], beyond: u64) -> String {
    let mut terms = Vec::new();
    let mut prev: Option<u64> = None;
    for &k in steps {
        terms.push(match prev {
            None => format!("{k}*(step<{k})"),
            Some(p) => format!("{k}*(step>={p})*(step<{k})"),
        });
        prev = Some(k);
    }
    if let Some(p) = prev {
        terms.push(format!("{beyond}*(step>={p})"));
    }
    terms.join("+")
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
/// Every number in [`num`] (shortest round-trip).
pub fn write_data(sys: &System) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "granval impact2d bed (SI units); Atoms: id type diameter density(= mass / (4/3 pi r^3)) x y z, Velocities: id vx vy vz wx wy wz\n"
    );
    let _ = writeln!(s, "{} atoms", sys.disks.len());
    let _ = writeln!(s, "{} atom types\n", sys.n_types);
    let (lo, hi) = (sys.bx.lo, sys.bx.hi);
    let _ = writeln!(s, "{} {} xlo xhi", num(lo[0]), num(hi[0]));
    let _ = writeln!(s, "{} {} ylo yhi", num(lo[1]), num(hi[1]));
    // z is inert in 2D, but LAMMPS' binning refuses a z extent far below the cutoff.
    let zh = sys.disks.iter().map(|d| d.radius).fold(0.0, f64::max) * 2.0 + sys.skin;
    let _ = writeln!(s, "{} {} zlo zhi\n", num(-zh), num(zh));
    let _ = writeln!(s, "Atoms # sphere\n");
    for d in &sys.disks {
        let density = d.mass / sphere_volume(d.radius);
        let _ = writeln!(
            s,
            "{} {} {} {} {} {} 0",
            d.id,
            ty(d.type_),
            num(2.0 * d.radius),
            num(density),
            num(d.x[0]),
            num(d.x[1])
        );
    }
    let _ = writeln!(s, "\nVelocities\n");
    for d in &sys.disks {
        let _ = writeln!(
            s,
            "{} {} {} 0 0 0 {}",
            d.id,
            num(d.v[0]),
            num(d.v[1]),
            num(d.omega)
        );
    }
    s
}

/// What the disks of each type are, from their roles: walls (frozen), intruder, grains.
fn type_names(sys: &System) -> Vec<String> {
    (0..sys.n_types)
        .map(|t| {
            let of: Vec<usize> = (0..sys.disks.len())
                .filter(|&k| sys.disks[k].type_ == t)
                .collect();
            let frozen = of
                .iter()
                .filter(|&&k| sys.disks[k].role == Role::Frozen)
                .count();
            let intr = of.iter().filter(|k| sys.intruder.contains(k)).count();
            if of.is_empty() {
                "unused".to_string()
            } else if frozen == of.len() {
                format!("wall disks ({frozen}, frozen)")
            } else if intr == of.len() {
                format!("intruder ({intr} disk(s))")
            } else {
                format!("grains ({})", of.len())
            }
        })
        .collect()
}

/// The disks of each role, by atom id: what the deck's groups, exclusions and fixes are
/// made of.
struct Groups {
    /// Wall disks: `fix freeze`, never integrated.
    frozen: Vec<u64>,
    /// Members of a rigid intruder cluster (`fix rigid single`).
    cluster: Vec<u64>,
    /// The intruder (a single disk or the cluster).
    intr: Vec<u64>,
    /// Disks integrated by `nve/sphere disc`.
    free: Vec<u64>,
}

impl Groups {
    fn of(sys: &System) -> Groups {
        let with_role = |role: Role| -> Vec<u64> {
            sys.disks
                .iter()
                .filter(|d| d.role == role)
                .map(|d| d.id)
                .collect()
        };
        Groups {
            frozen: with_role(Role::Frozen),
            cluster: with_role(Role::Cluster),
            intr: sys.intruder.iter().map(|&k| sys.disks[k].id).collect(),
            free: with_role(Role::Free),
        }
    }
}

/// The input deck, commented block by block. `System::dt`, gravity and skin are used
/// as they are; the header carries the date (fingerprints ignore comments).
pub fn write_deck(sys: &System, out: &Outputs) -> Result<String> {
    let groups = Groups::of(sys);
    if groups.free.is_empty() && groups.cluster.is_empty() {
        bail!("nothing moves in this system");
    }
    let names = type_names(sys);
    let mut s = String::new();
    write_deck_header(&mut s, sys, out, &groups);
    write_box_and_atoms(&mut s, sys, &groups, &names);
    write_neighbour_lists(&mut s, sys, &groups);
    write_contact_law(&mut s, sys, out, &names)?;
    write_integration(&mut s, sys, &groups);
    block(&mut s, "---- Output ----");
    if out.intruder_every > 0 && !groups.intr.is_empty() {
        write_intruder_output(&mut s, out);
    }
    if out.snapshot_every > 0 {
        write_energy_snapshots(&mut s, out);
    }
    if !out.fields.position_steps.is_empty() {
        write_field_dumps(&mut s, out);
    }
    write_run(&mut s, sys, out);
    Ok(s)
}

/// The header: the caller's title and paragraphs, then what the run writes, its units
/// and how to run it; the counts must be those of the groups below.
fn write_deck_header(s: &mut String, sys: &System, out: &Outputs, g: &Groups) {
    let mut paragraphs = out.header.paragraphs.clone();
    paragraphs.push(format!(
        "What the run writes: {}{}. {} disks ({} free, {} frozen wall disks{}); {} steps of {} s.",
        if out.intruder_every > 0 && !g.intr.is_empty() {
            format!(
                "the intruder's centre of mass, velocity and total force every {} steps \
                 ({INTRUDER_FILE}), ",
                out.intruder_every
            )
        } else {
            String::new()
        },
        if out.snapshot_every > 0 {
            format!(
                "every disk every {} steps ({SNAP_FILE}, for the energies)",
                out.snapshot_every
            )
        } else {
            "no snapshots".to_string()
        },
        sys.disks.len(),
        g.free.len(),
        g.frozen.len(),
        if g.cluster.is_empty() {
            String::new()
        } else {
            format!(", {} in the rigid intruder cluster", g.cluster.len())
        },
        out.n_steps,
        num(sys.dt),
    ));
    paragraphs.push(
        "Units: SI (m, kg, s, N; N/m for spring constants, 1/s for damping rates). 2D disks in \
         the x-y plane, gravity along -y."
            .to_string(),
    );
    paragraphs.push(format!(
        "Run it in this directory: `lmp -in {DECK_FILE} -log log.lammps`, or with N MPI \
         processes `mpirun -np N lmp -in {DECK_FILE} -log log.lammps`; then `granval analyze \
         DIR --report OUT` (README.txt)."
    ));
    write_header(
        s,
        &Header {
            title: if out.header.title.is_empty() {
                format!("granval 2D disk deck: LAMMPS input ({DECK_FILE})")
            } else {
                out.header.title.clone()
            },
            paragraphs,
        },
    );
}

/// Units, dimension, atom style and boundaries, the data file and the groups: the disks
/// exactly as the native engine holds them, so both engines start from the same state.
fn write_box_and_atoms(s: &mut String, sys: &System, g: &Groups, names: &[String]) {
    block(
        s,
        &format!(
            "---- Box and atoms ----\n\
             SI units, `dimension 2`. `atom_style sphere`: each disk has a diameter, a density \
             and an angular velocity; LAMMPS' density convention: read_data turns the density \
             into a mass with the sphere volume 4/3 pi r^3 even in 2D, so {DATA_FILE} holds \
             density = m / (4/3 pi r^3) and LAMMPS recovers each disk's mass m exactly. Atoms \
             are looked up by ID in an array (`map array`). Boundaries: {} in x, fixed in y \
             (the bed lies between two rows of frozen wall disks), periodic in the inert z. \
             `comm_modify vel yes`: ghost atoms carry velocities, which the damping needs.",
            if sys.bx.periodic_x {
                "periodic (Kondic et al. Sec. II)"
            } else {
                "fixed"
            }
        ),
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
    comment(
        s,
        &format!(
            "The disks, exactly as granval's native engine holds them (same bed, walls and \
             intruder, so both engines start from the same state): per disk its id, type, \
             diameter (m), density (kg/m^3, see above), position (m); velocities (m/s) and \
             angular velocity (rad/s). Types: {}.",
            names
                .iter()
                .enumerate()
                .map(|(t, n)| format!("{} = {n}", t + 1))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    );
    let _ = writeln!(s, "read_data {DATA_FILE}");
    comment(
        s,
        "Groups: the integrated disks (free), the frozen wall disks (walls), the intruder \
         (intr).",
    );
    let _ = writeln!(s, "group free id {}", id_ranges(g.free.clone()));
    if !g.frozen.is_empty() {
        let _ = writeln!(s, "group walls id {}", id_ranges(g.frozen.clone()));
    }
    if !g.intr.is_empty() {
        let _ = writeln!(s, "group intr id {}", id_ranges(g.intr.clone()));
    }
}

/// Neighbour lists, with the pairs that never interact (walls among themselves, the
/// rigid intruder's members) excluded, as the native engine leaves them out.
fn write_neighbour_lists(s: &mut String, sys: &System, g: &Groups) {
    let mut why = Vec::new();
    if !g.frozen.is_empty() {
        why.push("wall-wall pairs (they never move)");
    }
    if !g.cluster.is_empty() {
        why.push("pairs inside the rigid intruder");
    }
    block(
        s,
        &format!(
            "Neighbour lists: skin {} m, checked every step, rebuilt when a disk has moved \
             more than half the skin.{}",
            num(sys.skin),
            if why.is_empty() {
                String::new()
            } else {
                format!(" Excluded: {}.", why.join(", "))
            }
        ),
    );
    let _ = writeln!(s, "neighbor {} bin", num(sys.skin));
    let mut nm = "neigh_modify delay 0 every 1 check yes".to_string();
    if !g.frozen.is_empty() {
        nm += " exclude group walls walls";
    }
    if !g.cluster.is_empty() {
        nm += " exclude group intr intr";
    }
    let _ = writeln!(s, "{nm}");
}

/// The type pairs (0-based, a <= b) whose disks exist: one sub-style instance each
/// (see module doc).
fn interacting_pairs(sys: &System) -> Vec<(usize, usize)> {
    let n_types = sys.n_types;
    let mut used = vec![false; n_types];
    for d in &sys.disks {
        used[d.type_] = true;
    }
    let mut pairs = Vec::new();
    for a in 0..n_types {
        for b in a..n_types {
            if used[a] && used[b] {
                pairs.push((a, b));
            }
        }
    }
    pairs
}

/// The LAMMPS granular style of a type pair: K's model 1 (static friction, k_t > 0)
/// needs the shear history, model 2 (k_t = 0) the plain style.
fn pair_style_of(sys: &System, a: usize, b: usize) -> &'static str {
    let c = &sys.coeffs[a * sys.n_types + b];
    if c.history() {
        "gran/hooke/history"
    } else {
        "gran/hooke"
    }
}

/// `compute pair/local` calls the pair style's single(); under `pair_style hybrid` the
/// installed LAMMPS (29 Sep 2021) crashes in PairHybrid::copy_svector, so a deck that
/// dumps contact forces uses one style, which needs one coefficient set: refuses a
/// system whose interacting pairs differ.
fn check_single_style(sys: &System, pairs: &[(usize, usize)]) -> Result<()> {
    let n_types = sys.n_types;
    let first = &sys.coeffs[pairs[0].0 * n_types + pairs[0].1];
    if let Some(&(a, b)) = pairs
        .iter()
        .find(|&&(a, b)| sys.coeffs[a * n_types + b] != *first)
    {
        bail!(
            "contact forces are dumped with `compute pair/local`, which needs one pair style \
             (it crashes under `pair_style hybrid` in LAMMPS 29Sep2021), but types {} and {} \
             have other coefficients than types {} and {}: give the walls the grains' \
             coefficients during the impact (`[walls] impact_as_grains = true`)",
            ty(a),
            ty(b),
            ty(pairs[0].0),
            ty(pairs[0].1)
        );
    }
    Ok(())
}

/// The contact law (Kondic et al. Sec. II, eqs 1-2): its commented block, then one
/// style (contact-force dumps) or one `hybrid` instance per interacting type pair.
fn write_contact_law(s: &mut String, sys: &System, out: &Outputs, names: &[String]) -> Result<()> {
    let pairs = interacting_pairs(sys);
    let single_style = !out.fields.contact_steps.is_empty();
    if single_style {
        check_single_style(sys, &pairs)?;
    }
    block(s, &contact_law_text(sys, &pairs, names, single_style));
    if single_style {
        let (a, b) = pairs[0];
        let c = &sys.coeffs[a * sys.n_types + b];
        let _ = writeln!(
            s,
            "pair_style {} {} {} {} {} {} 1\npair_coeff * *",
            pair_style_of(sys, a, b),
            num(c.kn),
            num(c.kt),
            num(c.gamma_n),
            num(c.gamma_t),
            num(c.mu)
        );
    } else {
        write_hybrid_pairs(s, sys, &pairs);
    }
    Ok(())
}

/// The contact law's comment: the model with its paper equations, then the
/// coefficients of every interacting type pair in the order of the instances.
fn contact_law_text(
    sys: &System,
    pairs: &[(usize, usize)],
    names: &[String],
    single_style: bool,
) -> String {
    let mut text = String::from(
        "---- Contact law (Kondic et al. Sec. II, eqs 1-2) ----\n\
         Linear spring-dashpot normal force F_n = k_n x - gamma_n m_eff v_n, with gamma_n = -2 \
         ln(e_n) / tau_c; Cundall-Strack tangential spring k_t with Coulomb cap mu |F_n| and \
         damping gamma_t = gamma_n / 2 (`gran/hooke/history`, k_t = 0.8 k_n: K's model 1, \
         static friction), or damping only (`gran/hooke`, k_t = 0: K's model 2, kinetic \
         friction; `gran/hooke/history` would divide by k_t). One `gran/*` style has a single \
         coefficient set, so each interacting type pair gets its own instance under `pair_style \
         hybrid`, in this order (pair_coeff below numbers the instances of one style). \
         Arguments: k_n (N/m), k_t (N/m), gamma_n (1/s), gamma_t (1/s), mu, dampflag 1 \
         (tangential damping on).",
    );
    for (k, &(a, b)) in pairs.iter().enumerate() {
        let c = &sys.coeffs[a * sys.n_types + b];
        text += &format!(
            "\n{}. Types {}-{} ({} / {}): {}, k_n {} N/m, k_t {} N/m, gamma_n {} 1/s, gamma_t \
             {} 1/s, mu {}.",
            k + 1,
            ty(a),
            ty(b),
            names[a],
            names[b],
            pair_style_of(sys, a, b),
            approx(c.kn),
            approx(c.kt),
            approx(c.gamma_n),
            approx(c.gamma_t),
            approx(c.mu)
        );
    }
    if single_style {
        text += "\nEvery interacting pair has the same coefficients here, so one style without \
                 `hybrid` (the contact-force dump below needs it).";
    }
    text
}

/// `pair_style hybrid` with one instance per interacting type pair, then which instance
/// acts on which type pair (LAMMPS numbers the instances of one style from 1).
fn write_hybrid_pairs(s: &mut String, sys: &System, pairs: &[(usize, usize)]) {
    let n_types = sys.n_types;
    let mut args = String::from("pair_style hybrid");
    for &(a, b) in pairs {
        let c = &sys.coeffs[a * n_types + b];
        // dampflag 1: tangential damping on (gamma_t given explicitly).
        let _ = write!(
            args,
            " &\n  {} {} {} {} {} {} 1",
            pair_style_of(sys, a, b),
            num(c.kn),
            num(c.kt),
            num(c.gamma_n),
            num(c.gamma_t),
            num(c.mu)
        );
    }
    let _ = writeln!(s, "{args}");
    comment(
        s,
        "Which instance acts on which type pair (`none`: pairs that never meet).",
    );
    let count = |name: &str| {
        pairs
            .iter()
            .filter(|&&(a, b)| pair_style_of(sys, a, b) == name)
            .count()
    };
    let mut seen = std::collections::HashMap::<&str, usize>::new();
    for a in 0..n_types {
        for b in a..n_types {
            if pairs.contains(&(a, b)) {
                let st = pair_style_of(sys, a, b);
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
}

/// Time step, gravity and the fixes that move the disks: free disks and a single-disk
/// intruder as disks, a cluster intruder rigid without rotation, wall disks frozen (as
/// the native engine integrates them).
fn write_integration(s: &mut String, sys: &System, g: &Groups) {
    block(
        s,
        &format!(
            "---- Time integration ----\n\
             Time step {} s; gravity {} m/s^2 along -y. Free disks (and a single-disk \
             intruder): velocity Verlet for disks (`nve/sphere disc`: moment of inertia m r^2 \
             / 2).{}{} `enforce2d` zeroes the out-of-plane components.",
            num(sys.dt),
            num(sys.gravity),
            if g.cluster.is_empty() {
                ""
            } else {
                " The intruder cluster moves as one rigid body without rotation (`rigid single`, \
                 torque off: Kondic et al. Sec. III A)."
            },
            if g.frozen.is_empty() {
                ""
            } else {
                " Wall disks never move (`freeze`; LAMMPS then takes the mobile disk's mass as \
                 m_eff, as the native engine does)."
            }
        ),
    );
    let _ = writeln!(s, "timestep {}", num(sys.dt));
    let _ = writeln!(s, "fix grav all gravity {} vector 0 -1 0", num(sys.gravity));
    let _ = writeln!(s, "fix integ free nve/sphere disc");
    if !g.cluster.is_empty() {
        let _ = writeln!(s, "fix rig intr rigid single torque 1 off off off");
    }
    if !g.frozen.is_empty() {
        let _ = writeln!(s, "fix frz walls freeze");
    }
    let _ = writeln!(s, "fix e2d all enforce2d");
}

/// The measurement: the intruder's centre of mass, velocity and force (and, with
/// tracers, the interface height of Kondic et al. Fig 12) in the columns granval's
/// reader of the intruder file expects.
fn write_intruder_output(s: &mut String, out: &Outputs) {
    comment(
        s,
        &format!(
            "The measurement: every {} steps (from step 0) the intruder's centre of mass \
             (m), velocity (m/s) and total force (N, contacts and gravity) to \
             {INTRUDER_FILE}, %.17g (every double reads back exactly). granval turns it \
             into the penetration depth D(t) and the final depth (Kondic et al. Figs 2, 8).",
            out.intruder_every
        ),
    );
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
    let mut columns = "v_ix v_iy v_ivx v_ivy v_ifx v_ify".to_string();
    if !out.tracers.is_empty() {
        comment(
            s,
            &format!(
                "Kondic et al. Fig 12: the interface height, the centre of mass in y (m, \
                 mass-weighted) of the {} interface tracers (group iface: the grains whose \
                 centre lay within 2 d of the surface at release, at least L/4 from the \
                 impact point), as an eighth column at the same steps. granval turns it \
                 into the depth below the moving interface.",
                out.tracers.len()
            ),
        );
        let _ = writeln!(s, "group iface id {}", id_ranges(out.tracers.clone()));
        let _ = writeln!(s, "variable sy equal xcm(iface,y)");
        columns += " v_sy";
    }
    let n = out.intruder_every;
    let _ = writeln!(
        s,
        "fix iout all ave/time {n} 1 {n} {columns} file {INTRUDER_FILE} format \" %.17g\""
    );
}

/// Every disk at full precision, sorted by id: what granval's energies are computed
/// from.
fn write_energy_snapshots(s: &mut String, out: &Outputs) {
    comment(
        s,
        &format!(
            "Every {} steps every disk (id type radius mass x y vx vy omegaz fx fy, %.17g, \
             sorted by id) to {SNAP_FILE}: granval computes the energies from it.",
            out.snapshot_every
        ),
    );
    let _ = writeln!(
        s,
        "dump snap all custom {} {SNAP_FILE} id type radius mass x y vx vy omegaz fx fy",
        out.snapshot_every
    );
    let _ = writeln!(s, "dump_modify snap sort id format float %.17g");
}

/// Bed snapshots (Kondic et al. Sec. IV): grain positions and contact forces exactly at
/// the listed steps, through `dump_modify every v_NAME` ([`next_step_formula`]).
fn write_field_dumps(s: &mut String, out: &Outputs) {
    let f = &out.fields;
    comment(
        s,
        &format!(
            "Bed snapshots (Kondic et al. Sec. IV) at steps {:?}: the grains' positions \
             (id x y, %.17g, sorted by id) to {GRAINS_FILE}{}. `dump_modify every v_NAME` \
             writes when the step reaches the variable's value, the next listed step.",
            f.position_steps,
            if f.contact_steps.is_empty() {
                String::new()
            } else {
                format!(
                    "; at steps {:?} every touching pair (atom ids, centre distance, \
                     normal force |F_n| = `force`, tangential force |F_t| = `p4` of the \
                     pair style's single(), evaluated on the state at the end of the \
                     step) to {CONTACTS_FILE}",
                    f.contact_steps
                )
            }
        ),
    );
    let beyond = out.n_steps + 1;
    let _ = writeln!(
        s,
        "group grains type 1\nvariable gnext equal \"{}\"",
        next_step_formula(&f.position_steps, beyond)
    );
    let _ = writeln!(
        s,
        "dump grains grains custom 1 {GRAINS_FILE} id x y\ndump_modify grains every v_gnext sort id format float %.17g"
    );
    if !f.contact_steps.is_empty() {
        let _ = writeln!(
            s,
            "variable cnext equal \"{}\"",
            next_step_formula(&f.contact_steps, beyond)
        );
        let _ = writeln!(
            s,
            "compute cpl all pair/local dist force p4\ncompute cpp all property/local patom1 patom2\n\
             dump contacts all local 1 {CONTACTS_FILE} c_cpp[1] c_cpp[2] c_cpl[1] c_cpl[2] c_cpl[3]\n\
             dump_modify contacts every v_cnext format float %.17g"
        );
    }
}

/// Thermo output and the run of the case's step count.
fn write_run(s: &mut String, sys: &System, out: &Outputs) {
    comment(
        s,
        &format!(
            "Thermo line every {} steps; then {} steps ({} s).",
            out.n_steps.clamp(1, 10_000),
            out.n_steps,
            approx(sys.dt * out.n_steps as f64)
        ),
    );
    let _ = writeln!(
        s,
        "thermo_style custom step atoms\nthermo {}",
        out.n_steps.clamp(1, 10_000)
    );
    let _ = writeln!(s, "run {}", out.n_steps);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit disk at (x, 1) at rest: the hand-made systems of the deck tests.
    fn disk(
        id: u64,
        type_: usize,
        x: f64,
        role: crate::physics::dem2d::Role,
    ) -> crate::physics::dem2d::Disk {
        crate::physics::dem2d::Disk {
            id,
            type_,
            radius: 0.5,
            mass: 1.0,
            x: [x, 1.0],
            v: [0.0; 2],
            omega: 0.0,
            role,
        }
    }

    /// A deck that dumps contact forces uses one pair style (`compute pair/local` crashes
    /// under hybrid) and refuses a system whose pairs differ; it dumps at the listed steps.
    #[test]
    fn contact_dumps_need_one_pair_style() {
        use crate::case::impact2d::Coeffs;
        use crate::physics::dem2d::Role;
        use crate::physics::dem2d::neighbor::Box2;
        let g = Coeffs {
            kn: 1e3,
            kt: 800.0,
            gamma_n: 10.0,
            gamma_t: 5.0,
            mu: 0.5,
        };
        let w = Coeffs { mu: 0.9, ..g };
        let sys = |c: Vec<Coeffs>| {
            System::new(
                vec![
                    disk(1, 0, 1.0, Role::Free),
                    disk(2, 0, 2.0, Role::Free),
                    disk(3, 1, 3.0, Role::Frozen),
                ],
                None,
                c,
                2,
                Box2 {
                    lo: [0.0, 0.0],
                    hi: [10.0, 10.0],
                    periodic_x: true,
                },
                9.81,
                1e-4,
                0.1,
                vec![],
            )
        };
        let out = Outputs {
            n_steps: 100,
            intruder_every: 0,
            snapshot_every: 0,
            header: Header::default(),
            fields: crate::physics::dem2d::impact::SnapshotSteps {
                position_steps: vec![40, 50],
                contact_steps: vec![50],
            },
            tracers: Vec::new(),
        };
        let e = write_deck(&sys(vec![g, w, w, w]), &out)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("impact_as_grains") && e.contains("hybrid"),
            "{e}"
        );
        let deck = write_deck(&sys(vec![g; 4]), &out).unwrap();
        assert!(
            !deck.lines().any(|l| l.starts_with("pair_style hybrid")),
            "{deck}"
        );
        assert!(deck.contains("pair_style gran/hooke/history ") && deck.contains("pair_coeff * *"));
        assert!(deck.contains(
            "variable gnext equal \"40*(step<40)+50*(step>=40)*(step<50)+101*(step>=50)\""
        ));
        assert!(deck.contains("variable cnext equal \"50*(step<50)+101*(step>=50)\""));
        assert!(deck.contains("dump contacts all local 1 contacts.dump"));
        // Without contact dumps the same unequal system keeps its hybrid style.
        let plain = Outputs {
            fields: Default::default(),
            ..out
        };
        assert!(
            write_deck(&sys(vec![g, w, w, w]), &plain)
                .unwrap()
                .contains("pair_style hybrid")
        );
    }

    /// The interface tracers (K Fig 12) add a group, an `xcm` variable and an eighth
    /// column to the intruder output, and nothing else; without tracers the deck does
    /// not mention them (every case that does not track the interface keeps its deck).
    #[test]
    fn interface_tracers_add_one_column_to_the_intruder_output() {
        use crate::case::impact2d::Coeffs;
        use crate::physics::dem2d::neighbor::Box2;
        let c = Coeffs {
            kn: 1e3,
            kt: 0.0,
            gamma_n: 10.0,
            gamma_t: 5.0,
            mu: 0.5,
        };
        let sys = System::new(
            vec![
                disk(1, 0, 1.0, Role::Free),
                disk(2, 0, 2.0, Role::Free),
                disk(3, 0, 3.0, Role::Free),
                disk(5, 0, 5.0, Role::Free),
                disk(6, 1, 6.0, Role::Frozen),
                disk(7, 2, 8.0, Role::Free),
            ],
            None,
            vec![c; 9],
            3,
            Box2 {
                lo: [0.0, 0.0],
                hi: [10.0, 10.0],
                periodic_x: true,
            },
            9.81,
            1e-4,
            0.1,
            vec![5],
        );
        let plain = Outputs {
            n_steps: 100,
            intruder_every: 10,
            snapshot_every: 50,
            header: Header::default(),
            fields: Default::default(),
            tracers: Vec::new(),
        };
        let tracked = Outputs {
            tracers: vec![5, 1, 2, 3],
            ..plain.clone()
        };
        let (a, b) = (
            write_deck(&sys, &plain).unwrap(),
            write_deck(&sys, &tracked).unwrap(),
        );
        assert!(!a.contains("iface") && !a.contains("v_sy") && !a.contains("Fig 12"));
        assert_eq!(a.matches("xcm(").count(), 2, "only the intruder's: {a}");
        assert!(a.contains(
            "fix iout all ave/time 10 1 10 v_ix v_iy v_ivx v_ivy v_ifx v_ify file intruder.txt"
        ));
        assert!(b.contains("group iface id 1:3 5\nvariable sy equal xcm(iface,y)\n"));
        assert!(b.contains(
            "fix iout all ave/time 10 1 10 v_ix v_iy v_ivx v_ivy v_ifx v_ify v_sy file intruder.txt"
        ));
        // Commands: the tracked deck is the plain one plus exactly those lines.
        let commands = |d: &str| -> Vec<String> {
            crate::engines::deck_text::canonical(d)
                .lines()
                .map(str::to_string)
                .collect()
        };
        let (ca, cb) = (commands(&a), commands(&b));
        let extra: Vec<&String> = cb.iter().filter(|l| !ca.contains(l)).collect();
        assert_eq!(extra.len(), 3, "{extra:?}");
        assert_eq!(ca.len() + 2, cb.len());
    }

    /// LAMMPS evaluates the formula with `step` the current step: it must give the next
    /// listed step, and `beyond` after the last.
    #[test]
    fn next_step_formula_walks_the_list() {
        let f = next_step_formula(&[300, 575, 600], 1001);
        let eval = |step: u64| -> u64 {
            f.split('+')
                .map(|term| {
                    let mut parts = term.split('*');
                    let k: u64 = parts.next().unwrap().parse().unwrap();
                    let ok = parts.all(|c| {
                        let c = c.trim_matches(|c| c == '(' || c == ')');
                        if let Some(v) = c.strip_prefix("step>=") {
                            step >= v.parse::<u64>().unwrap()
                        } else {
                            step < c.strip_prefix("step<").unwrap().parse::<u64>().unwrap()
                        }
                    });
                    if ok { k } else { 0 }
                })
                .sum()
        };
        assert_eq!(eval(0), 300);
        assert_eq!(eval(300), 575);
        assert_eq!(eval(575), 600);
        assert_eq!(eval(600), 1001);
        assert_eq!(next_step_formula(&[], 5), "");
    }
}
