//! LIGGGHTS 3.8 deck for the shear of a triaxial sample (docs/stress.md rule 5): the
//! compacted sample granval's native engine prepared (`read_data`: positions, velocities,
//! spins), six plane walls as STL triangles whose edges lie far outside the box, x_hi and y_hi as
//! `mesh/surface/stress/servo` walls holding sigma_c (target: an equal-style variable
//! sigma_c x the current face area), z_hi moved down at constant speed by `move/mesh
//! linear`, and every `output_every` steps the walls' positions and forces (`walls.txt`).
//!
//! Facts of LIGGGHTS 3.8 this relies on (mesh_module_stress*.cpp, fix_mesh_surface.cpp,
//! mesh_mover_linear.cpp):
//! - `fix mesh/surface/stress[/servo]` has a global vector: the stress module's 9
//!   components first (force of the grains on the mesh 1-3, torque 4-6, the moved
//!   reference point 7-9), then the servo's 3 (its centre xcm). The servo sets the
//!   reference point to xcm, so `f_xhi[7]` is the x_hi wall's position; a stress mesh's
//!   reference point moves with `move/mesh`, so `f_zhi[9]` is z_hi's.
//! - The servo (PID, `ctrlPV force`): `initial_integrate` moves the mesh by dt vcm;
//!   `final_integrate`, after the force pass, evaluates the target variable (with this
//!   step's wall positions) and sets vcm; a negative target drives the wall towards
//!   -axis, so with `axis 1 0 0` and target -sigma_c A the x_hi wall closes until the
//!   grains push it with sigma_c A. `vel_max < skin / (2 dt)` is required.
//! - `move/mesh linear` adds vel dt to the nodes every step; the mesh velocity is 0 in
//!   setup (step 0) and vel from step 1.
//! - `$(...)` prints %.20g (exact doubles).

pub use super::LOG_FILE;
use super::deck::{f, model_keywords, write_contact_model};
pub(crate) use super::{STDERR_FILE, STDOUT_FILE};
use super::{TRANSCRIPT, VERSION_PREFIX};
use crate::case::triaxial::ServoGains;
use crate::case::{Material, PairTable, Particle, RollingModel};
use crate::engines::deck_text;
use crate::engines::process::{self, Transcript};
use crate::rundata::provenance::{EngineKind, Provenance, Sha256, now_utc};
use crate::rundata::triaxial::WallRecord;
use anyhow::{Context, Result, bail};
use std::fmt::Write as _;
use std::path::Path;

pub const DECK_FILE: &str = "in.triaxial";
pub const DATA_FILE: &str = "data.sample";
pub(crate) const WALLS_FILE: &str = "walls.txt";
/// The six wall meshes, in the native engine's wall order.
pub const STL_FILES: [&str; 6] = [
    "x_lo.stl", "y_lo.stl", "z_lo.stl", "x_hi.stl", "y_hi.stl", "z_hi.stl",
];
const FIX_IDS: [&str; 6] = ["xlo", "ylo", "zlo", "xhi", "yhi", "zhi"];

/// One shear run, SI.
#[derive(Debug, Clone)]
pub struct TriaxialDeck {
    pub materials: Vec<Material>,
    pub pairs: PairTable,
    pub rolling: RollingModel,
    pub dt: f64,
    pub neighbor_skin: f64,
    pub domain_lo: [f64; 3],
    pub domain_hi: [f64; 3],
    /// The compacted sample.
    pub particles: Vec<Particle>,
    /// Positions of x_hi, y_hi, z_hi at step 0 (the lo walls are at 0).
    pub hi: [f64; 3],
    /// Every wall mesh is one triangle centred at this in-plane coordinate (both) with
    /// this circumradius, its edges far outside the box.
    pub mesh_centre: f64,
    pub mesh_circumradius: f64,
    /// 0-based material type of the walls.
    pub wall_type: usize,
    pub sigma_c: f64,
    pub servo: ServoGains,
    /// Speed of z_hi, downward (m/s).
    pub z_speed: f64,
    pub n_steps: u64,
    pub output_every: u64,
    pub soft_particles: bool,
    pub hard_particles: bool,
    pub header: deck_text::Header,
}

fn validate(d: &TriaxialDeck) -> Result<()> {
    for (name, x) in [
        ("dt", d.dt),
        ("neighbor_skin", d.neighbor_skin),
        ("sigma_c", d.sigma_c),
        ("z_speed", d.z_speed),
        ("vel_max", d.servo.vel_max),
    ] {
        if !(x.is_finite() && x > 0.0) {
            bail!("triaxial deck: {name} = {x} must be > 0");
        }
    }
    if d.servo.vel_max >= d.neighbor_skin / (2.0 * d.dt) {
        bail!(
            "triaxial deck: vel_max {} >= skin / (2 dt) = {}: LIGGGHTS refuses it",
            d.servo.vel_max,
            d.neighbor_skin / (2.0 * d.dt)
        );
    }
    if d.output_every == 0 || d.n_steps == 0 {
        bail!("triaxial deck: n_steps and output_every must be >= 1");
    }
    for p in &d.particles {
        if (0..3).any(|k| !(p.x[k] > 0.0 && p.x[k] < d.hi[k])) {
            bail!(
                "triaxial deck: grain {} at {:?} m is outside the box (0, {:?})",
                p.id,
                p.x,
                d.hi
            );
        }
    }
    Ok(())
}

/// The `read_data` file of the sample.
pub(crate) fn data_text(d: &TriaxialDeck) -> Result<String> {
    validate(d)?;
    Ok(super::deck::data_text(
        "compacted triaxial sample (si units)",
        &d.particles,
        d.materials.len(),
        d.domain_lo,
        d.domain_hi,
        1.0,
        1.0,
        1.0,
    ))
}

/// The six STL triangles: the lo walls at 0, the hi walls at `hi`.
pub(crate) fn stl_texts(d: &TriaxialDeck) -> [String; 6] {
    [0, 1, 2, 3, 4, 5].map(|k| {
        let axis = k % 3;
        let pos = if k < 3 { 0.0 } else { d.hi[axis] };
        super::stl::triangle_stl(
            FIX_IDS[k],
            axis,
            pos,
            [d.mesh_centre; 2],
            d.mesh_circumradius,
        )
    })
}

/// Lines `walls.txt` holds after a complete run (fix print skips step 0).
pub(crate) fn expected_records(d: &TriaxialDeck) -> usize {
    (d.n_steps / d.output_every) as usize
}

/// The deck text.
pub fn deck_text(d: &TriaxialDeck) -> Result<String> {
    validate(d)?;
    let mut s = String::new();
    write_triaxial_header(&mut s, d);
    write_box_and_sample(&mut s, d)?;
    write_contact_model(&mut s, &d.materials, &d.pairs, d.rolling, 1.0, "Pa")?;
    deck_text::block(
        &mut s,
        &format!(
            "---- Time step ----\n{} s (the case's dt), no gravity.",
            f(d.dt)
        ),
    );
    writeln!(s, "timestep {}", f(d.dt))?;
    write_wall_meshes(&mut s, d)?;
    write_wall_contacts_and_drive(&mut s, d)?;
    write_output_and_run(&mut s, d)?;
    Ok(s)
}

/// The header: what the run measures (docs/stress.md, rule 5) and the geometry the
/// native compaction left, with why each wall is one large triangle.
fn write_triaxial_header(s: &mut String, d: &TriaxialDeck) {
    let mut paragraphs = d.header.paragraphs.clone();
    paragraphs.push(format!(
        "What the run measures: axisymmetric-stress compression of a compacted sample of {} \
         grains between six frictionless plane walls (docs/stress.md, rule 5). The z_hi wall \
         moves down at {} m/s for {} steps of {} s (axial strain {}); x_hi and y_hi are stress \
         servos holding sigma_c = {} Pa on their current face areas. Every {} steps \
         {WALLS_FILE} gets the wall positions and the normal forces of the grains on all six \
         walls; granval turns them into the wall stresses, phi_mob = asin((s1 - s3) / (s1 + \
         s3)), phi_peak and phi_cs.",
        d.particles.len(),
        f(d.z_speed),
        d.n_steps,
        f(d.dt),
        deck_text::approx(d.z_speed * d.dt * d.n_steps as f64 / d.hi[2]),
        f(d.sigma_c),
        d.output_every,
    ));
    paragraphs.push(format!(
        "Geometry (SI): the box [0, x_hi] x [0, y_hi] x [0, z_hi] with x_hi, y_hi, z_hi = {}, \
         {}, {} m at step 0, where granval's native compaction left them. Each wall is one \
         equilateral triangle centred at {} m in its plane coordinates with circumradius {} m: \
         its edges stay far outside the box, so it acts as a plane (a rectangle of two \
         triangles has a diagonal across the face, where LIGGGHTS 3.8 was measured to count \
         one grain's contact twice for a step). The simulation box is large enough to hold \
         the triangles.",
        f(d.hi[0]),
        f(d.hi[1]),
        f(d.hi[2]),
        f(d.mesh_centre),
        f(d.mesh_circumradius)
    ));
    paragraphs.push(format!(
        "Run it in this directory: `liggghts -in {DECK_FILE} -log {LOG_FILE}`, or with N MPI \
         processes `mpirun -np N liggghts -in {DECK_FILE} -log {LOG_FILE}`; then `granval \
         analyze DIR --report OUT`."
    ));
    deck_text::write_header(
        s,
        &deck_text::Header {
            title: d.header.title.clone(),
            paragraphs,
        },
    );
}

/// Units, atom style, the closed box and what LIGGGHTS' granular pair style needs, the
/// Young's modulus switches, the compacted sample exactly as the native engine left it,
/// and the neighbour lists.
fn write_box_and_sample(s: &mut String, d: &TriaxialDeck) -> Result<()> {
    deck_text::block(
        s,
        "---- Box, atoms ----\n\
         Units `si`. `atom_style granular`: spheres with diameter, density and angular \
         velocity. `boundary f f f`: a closed box; a grain that leaves it stops the run \
         (thermo_modify below). `newton off` and `communicate single vel yes`: LIGGGHTS' \
         granular pair style with shear history needs both (ghost atoms carry velocities).",
    );
    writeln!(s, "units si")?;
    writeln!(s, "atom_style granular")?;
    writeln!(s, "atom_modify map array")?;
    writeln!(s, "boundary f f f")?;
    writeln!(s, "newton off")?;
    writeln!(s, "communicate single vel yes")?;
    super::deck::write_hardness(s, &d.materials, d.soft_particles, d.hard_particles)?;
    deck_text::block(
        s,
        &format!(
            "The sample: {DATA_FILE} holds the box (m) and per grain its ID, type, diameter (m), \
             density (kg/m^3), position (m), velocity (m/s) and angular velocity (rad/s), \
             exactly as granval's native compaction ended; both engines shear the very same \
             grains. Contact history starts empty, as in the native run."
        ),
    );
    writeln!(s, "read_data {DATA_FILE}")?;
    deck_text::block(
        s,
        &format!(
            "Neighbour lists: skin {} m, rebuilt whenever a grain (or a mesh) has moved more \
             than half the skin since the last build. It changes the cost, not the physics.",
            f(d.neighbor_skin)
        ),
    );
    writeln!(s, "neighbor {} bin", f(d.neighbor_skin))?;
    writeln!(s, "neigh_modify delay 0")?;
    Ok(())
}

/// The six wall meshes ([`stl_texts`]): the fixed lo walls, the x_hi and y_hi stress
/// servos and the driven z_hi wall, each a `mesh/surface/stress` whose force and
/// reference point the output line reads.
fn write_wall_meshes(s: &mut String, d: &TriaxialDeck) -> Result<()> {
    let wt = d.wall_type + 1;
    let c = d.mesh_centre;
    deck_text::block(
        s,
        &format!(
            "---- The walls ----\n\
             Six STL triangles of material type {wt} (frictionless against the grains: mu = \
             0, mu_r = 0, e = 0.8, the grains' G and nu; their forces are normal, so the wall \
             stresses are principal). `mesh/surface/stress` sums the force of the grains on \
             each (f_ID[1..3]) and moves its reference point with the mesh (f_ID[7..9]). The lo \
             walls at x, y, z = 0 stay where they are."
        ),
    );
    for k in 0..3 {
        let mut p = [c; 3];
        p[k] = 0.0;
        writeln!(
            s,
            "fix {} all mesh/surface/stress file {} type {wt} stress on reference_point {}",
            FIX_IDS[k],
            STL_FILES[k],
            deck_text::nums(p)
        )?;
    }
    let g = d.servo;
    deck_text::comment(
        s,
        &format!(
            "x_hi and y_hi: LIGGGHTS' stress servo (mesh module servo, PID on the force along \
             the axis, `ctrlPV force`): kp {}, ki {}, kd {}, at most {} m/s. Its centre `com` is \
             on the wall, so f_xhi[7] / f_yhi[8] are the walls' positions. The target is -sigma_c \
             times the current face area (v_tx, v_ty below): negative, so the wall closes \
             along -axis until the grains push it outward with sigma_c A.",
            f(g.kp),
            f(g.ki),
            f(g.kd),
            f(g.vel_max)
        ),
    );
    for (k, axis, var) in [(3usize, "1 0 0", "tx"), (4, "0 1 0", "ty")] {
        let mut p = [c; 3];
        p[k - 3] = d.hi[k - 3];
        writeln!(
            s,
            "fix {} all mesh/surface/stress/servo file {} type {wt} stress on com {} ctrlPV force axis {axis} target_val v_{var} vel_max {} kp {} ki {} kd {}",
            FIX_IDS[k],
            STL_FILES[k],
            deck_text::nums(p),
            f(g.vel_max),
            f(g.kp),
            f(g.ki),
            f(g.kd)
        )?;
    }
    deck_text::comment(
        s,
        "z_hi: a stress mesh moved down at constant speed (below); its reference point follows \
         it, so f_zhi[9] is its position.",
    );
    let mut p = [c; 3];
    p[2] = d.hi[2];
    writeln!(
        s,
        "fix zhi all mesh/surface/stress file {} type {wt} stress on reference_point {}",
        STL_FILES[5],
        deck_text::nums(p)
    )?;
    Ok(())
}

/// The servo targets (sigma_c on the current face areas), the grain-wall contacts on
/// all six meshes, the axial drive of z_hi and the integration of the grains.
fn write_wall_contacts_and_drive(s: &mut String, d: &TriaxialDeck) -> Result<()> {
    let models = model_keywords(d.rolling);
    deck_text::comment(
        s,
        &format!(
            "The servo targets (N): -sigma_c x the face area from the other walls' current \
             positions (the lo walls are at 0), evaluated by the servo in final_integrate, \
             after this step's wall moves; sigma_c = {} Pa.",
            f(d.sigma_c)
        ),
    );
    writeln!(s, "variable tx equal -{}*f_yhi[8]*f_zhi[9]", f(d.sigma_c))?;
    writeln!(s, "variable ty equal -{}*f_xhi[7]*f_zhi[9]", f(d.sigma_c))?;
    deck_text::comment(
        s,
        "Grain-wall contacts: the grains' contact law on all six meshes.",
    );
    writeln!(
        s,
        "fix walls all wall/gran {models} mesh n_meshes 6 meshes {}",
        FIX_IDS.join(" ")
    )?;
    deck_text::comment(
        s,
        &format!(
            "The axial drive: z_hi down at eps_dot H0 = {} m/s from step 1.",
            f(d.z_speed)
        ),
    );
    writeln!(
        s,
        "fix mvz all move/mesh mesh zhi linear 0 0 {}",
        f(-d.z_speed)
    )?;
    deck_text::comment(
        s,
        "Velocity Verlet for spheres (`nve/sphere`: half kick, drift, forces, half kick).",
    );
    writeln!(s, "fix integr all nve/sphere")?;
    Ok(())
}

/// The wall record ([`WALLS_FILE`], at full precision, the columns granval reads back
/// into [`WallRecord`]s), thermo, and the shear run.
fn write_output_and_run(s: &mut String, d: &TriaxialDeck) -> Result<()> {
    deck_text::block(
        s,
        &format!(
            "---- Output ----\n\
             Every {} steps one line of {WALLS_FILE}: step, positions of x_hi, y_hi, z_hi (m), \
             the force of the grains on x_lo, y_lo, z_lo along x, y, z and on x_hi, y_hi, z_hi \
             along x, y, z (N). `$(...)` prints %.20g, so every double reads back exactly.",
            d.output_every
        ),
    );
    writeln!(
        s,
        "fix out all print {} \"$(step) $(f_xhi[7]) $(f_yhi[8]) $(f_zhi[9]) $(f_xlo[1]) $(f_ylo[2]) $(f_zlo[3]) $(f_xhi[1]) $(f_yhi[2]) $(f_zhi[3])\" file {WALLS_FILE} screen no title \"# step x_hi y_hi z_hi f_xlo f_ylo f_zlo f_xhi f_yhi f_zhi (SI)\"",
        d.output_every
    )?;
    deck_text::comment(
        s,
        "Thermo line about every 1 % of the run. `thermo_modify lost error`: a grain leaving \
         the box is an error, not a silent loss (it must follow thermo_style).",
    );
    writeln!(s, "thermo_style custom step atoms ke cpu")?;
    writeln!(s, "thermo_modify lost error")?;
    writeln!(s, "thermo {}", (d.n_steps / 100).max(1))?;
    deck_text::block(
        s,
        &format!(
            "{} steps of shear ({} s).",
            d.n_steps,
            deck_text::approx(d.dt * d.n_steps as f64)
        ),
    );
    writeln!(s, "run {}", d.n_steps)?;
    Ok(())
}

/// Every input file of the deck: name and text.
pub(crate) fn inputs(d: &TriaxialDeck) -> Result<Vec<(&'static str, String)>> {
    let mut v = vec![(DECK_FILE, deck_text(d)?), (DATA_FILE, data_text(d)?)];
    for (name, text) in STL_FILES.iter().zip(stl_texts(d)) {
        v.push((name, text));
    }
    Ok(v)
}

/// sha256 of what LIGGGHTS is given (deck, data file, meshes), canonical.
pub(crate) fn input_hash_of(d: &TriaxialDeck) -> Result<Sha256> {
    let files = inputs(d)?;
    Ok(deck_text::fingerprint(
        &files.iter().map(|(_, t)| t.as_str()).collect::<Vec<_>>(),
    ))
}

/// Writes the deck directory.
pub fn write_deck_dir(d: &TriaxialDeck, dir: &Path) -> Result<()> {
    let files = inputs(d)?;
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create run directory {}", dir.display()))?;
    for (name, text) in files {
        std::fs::write(dir.join(name), text)
            .with_context(|| format!("cannot write {}", dir.join(name).display()))?;
    }
    Ok(())
}

/// Parses `walls.txt` (SI); errors name the file and line.
pub(crate) fn parse_walls(path: &Path) -> Result<Vec<WallRecord>> {
    let text = crate::rundata::fsio::read_to_string(
        path,
        crate::rundata::fsio::max_engine_output(),
        "the walls of a triaxial run",
    )?;
    let mut out = Vec::new();
    for (k, line) in text.lines().enumerate() {
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let bad = |what: &str| anyhow::anyhow!("{}:{}: {what}: {t:?}", path.display(), k + 1);
        let v: Vec<f64> = t
            .split_whitespace()
            .map(|x| x.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| bad("unparsable number"))?;
        if v.len() != 10 {
            return Err(bad("expected 10 columns (step, 3 positions, 6 forces)"));
        }
        if v.iter().any(|x| !x.is_finite()) || v[0] < 0.0 || v[0].fract() != 0.0 {
            return Err(bad("non-finite value or non-integer step"));
        }
        out.push(WallRecord {
            step: v[0] as u64,
            hi: [v[1], v[2], v[3]],
            f_lo: [v[4], v[5], v[6]],
            f_hi: [v[7], v[8], v[9]],
        });
    }
    Ok(out)
}

/// Checks the outputs of a finished run of `d` in `dir` and reads its wall records: no
/// `ERROR`, every record present at its step.
pub(crate) fn read_outputs(d: &TriaxialDeck, dir: &Path) -> Result<(Vec<WallRecord>, Provenance)> {
    let tr = Transcript::read(TRANSCRIPT, dir);
    if tr.log.is_empty() && tr.stdout.is_empty() {
        bail!(
            "{}: neither {LOG_FILE} nor {STDOUT_FILE} has content: LIGGGHTS did not run here",
            dir.display()
        );
    }
    if !tr.errors.is_empty() {
        bail!("ERROR in the LIGGGHTS output: {}", tr.errors.join(" | "));
    }
    let path = dir.join(WALLS_FILE);
    if !path.exists() {
        bail!("no {} was written", path.display());
    }
    let records = parse_walls(&path)?;
    for (n, r) in records.iter().enumerate() {
        let step = (n as u64 + 1) * d.output_every;
        if r.step != step {
            bail!(
                "record {n} of {} is step {}, expected {step}",
                path.display(),
                r.step
            );
        }
    }
    if records.len() != expected_records(d) {
        bail!(
            "{} has {} records, expected {} (n_steps {} / output_every {}): the run is incomplete",
            path.display(),
            records.len(),
            expected_records(d),
            d.n_steps,
            d.output_every
        );
    }
    let mut notes = vec![format!("run directory: {}", dir.display())];
    if d.soft_particles {
        notes.push(
            "soft_particles yes (LIGGGHTS' E >= 5e6 Pa check disabled; materials unchanged)"
                .to_string(),
        );
    }
    notes.extend(tr.warnings());
    let texts: Vec<String> = std::iter::once(DECK_FILE)
        .chain(std::iter::once(DATA_FILE))
        .chain(STL_FILES)
        .filter_map(|n| {
            let p = dir.join(n);
            crate::rundata::fsio::read_to_string(
                &p,
                crate::rundata::fsio::max_engine_output(),
                "a LIGGGHTS input",
            )
            .ok()
        })
        .collect();
    Ok((
        records,
        Provenance {
            engine: EngineKind::Liggghts,
            version: tr.version(VERSION_PREFIX),
            command: "run outside granval".into(),
            input_hash: deck_text::fingerprint(
                &texts.iter().map(String::as_str).collect::<Vec<_>>(),
            ),
            date: now_utc(),
            wall_time_s: super::penetration::log_wall_time(
                if tr.stdout.contains("Total wall time:") {
                    &tr.stdout
                } else {
                    &tr.log
                },
            )
            .unwrap_or(f64::NAN),
            threads: 1,
            case_file: dir.join(DECK_FILE).display().to_string(),
            notes,
        },
    ))
}

/// Writes the deck directory and runs LIGGGHTS in it (`mpirun -np N` when N > 1), killed
/// at its `limits`; a crash, an `ERROR` line or a short output is an error.
pub fn run(
    d: &TriaxialDeck,
    dir: &Path,
    mpi_procs: usize,
    limits: &process::Limits,
) -> Result<(Vec<WallRecord>, Provenance)> {
    write_deck_dir(d, dir)?;
    process::remove_stale(dir, &[WALLS_FILE, LOG_FILE, STDOUT_FILE, STDERR_FILE])?;
    let mut argv = process::mpi_prefix(mpi_procs);
    argv.push(super::binary());
    argv.extend(["-in", DECK_FILE, "-log", LOG_FILE].map(String::from));
    let command = process::command_line(&argv);
    let fin = process::run(
        &argv,
        dir,
        &dir.join(STDOUT_FILE),
        &dir.join(STDERR_FILE),
        limits,
    )
    .context("LIGGGHTS triaxial run failed to start")?;
    let what = "LIGGGHTS triaxial run";
    let tr = Transcript::read(TRANSCRIPT, dir);
    tr.check_exit(&fin, limits, what, &command, dir)?;
    let (records, mut prov) =
        read_outputs(d, dir).map_err(|e| tr.failure(what, &command, dir, &format!("{e:#}")))?;
    prov.command = command;
    prov.wall_time_s = fin.wall_time_s;
    prov.threads = mpi_procs.max(1);
    Ok((records, prov))
}
