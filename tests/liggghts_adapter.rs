//! LIGGGHTS adapter: deck/data text, refusal of values LIGGGHTS would refuse, the dump
//! parser, and (when `liggghts` is installed) live runs, including runs that must fail.

mod common;

use granval::case::Case;
use granval::engines::deck_text::{canonical, same_input};
use granval::engines::liggghts::{self, Liggghts};
use granval::rundata::frames::Frame;
use granval::rundata::provenance::{EngineKind, Provenance};
use std::path::Path;
use std::time::{Duration, Instant};

/// A micro run in LIGGGHTS (`engines::liggghts::micro`) and every frame of its dump.
#[derive(Debug)]
struct RunOutput {
    frames: Vec<Frame>,
    provenance: Provenance,
}

fn run(lig: &Liggghts, c: &Case, dir: &Path) -> anyhow::Result<RunOutput> {
    let provenance = liggghts::micro(lig, c, dir)?;
    let frames = liggghts::micro_frames(c, dir)?.collect::<anyhow::Result<Vec<_>>>()?;
    Ok(RunOutput { frames, provenance })
}

/// Two equal spheres on the x axis, one of them spinning, above a z = 0 plane wall that
/// they never reach (no gravity), so total momentum must be conserved exactly.
fn two_spheres(youngs: f64, rolling: &str, extra: &str) -> String {
    format!(
        r#"
[case]
name = "two-sphere-head-on"
kind = "micro"

[simulation]
dt = 1e-6
duration = 5e-4
output_every = 50
gravity = [0.0, 0.0, 0.0]
neighbor_skin = 5e-4

[models]
normal = "hertz"
tangential = "history"
rolling = "{rolling}"

[domain]
lo = [-5e-3, -5e-3, -1e-3]
hi = [5e-3, 5e-3, 5e-3]

[[materials]]
type = 1
youngs_modulus = {youngs:e}
poisson_ratio = 0.3

[[interactions]]
types = [1, 1]
restitution = 0.8
friction = 0.5
rolling_friction = 0.01

[[particles]]
id = 1
type = 1
radius = 1e-3
density = 2500.0
x = [-1.05e-3, 0.0, 2e-3]
v = [0.7, 0.0, 0.0]
omega = [0.0, 0.0, 300.0]

[[particles]]
id = 2
type = 1
radius = 1e-3
density = 2500.0
x = [1.05e-3, 0.0, 2e-3]
v = [-0.3, 0.0, 0.0]

[[walls]]
kind = "plane"
axis = "z"
position = 0.0
type = 1
{extra}
"#
    )
}

fn case(toml: &str) -> Case {
    Case::from_toml_str(toml, Path::new("test.toml")).expect("test case must validate")
}

fn live() -> Option<String> {
    common::live_or_skip(
        granval::rundata::provenance::EngineKind::Liggghts,
        "liggghts_adapter",
        "live LIGGGHTS test not run",
    )
    .then(|| liggghts::installed_version("liggghts"))
    .flatten()
}

#[test]
fn deck_has_the_commands_of_the_case() {
    let c = case(&two_spheres(5e7, "cdt", ""));
    let deck = liggghts::write_deck(&c, "dump.granval", "data.granval").unwrap();
    println!("{deck}");
    let lines: Vec<&str> = deck.lines().collect();
    for want in [
        "units si",
        "atom_style granular",
        "atom_modify map array",
        "boundary f f f",
        "newton off",
        "communicate single vel yes",
        "read_data data.granval",
        "neighbor 5e-4 bin",
        "neigh_modify delay 0",
        "fix m1 all property/global youngsModulus peratomtype 5e7",
        "fix m2 all property/global poissonsRatio peratomtype 3e-1",
        "fix m3 all property/global coefficientRestitution peratomtypepair 1 8e-1",
        "fix m4 all property/global coefficientFriction peratomtypepair 1 5e-1",
        "fix m5 all property/global coefficientRollingFriction peratomtypepair 1 1e-2",
        "pair_style gran model hertz tangential history rolling_friction cdt",
        "pair_coeff * *",
        "timestep 1e-6",
        "fix w1 all wall/gran model hertz tangential history rolling_friction cdt primitive type 1 zplane 0e0",
        "fix integr all nve/sphere",
        "thermo_modify lost error",
        "thermo 25",
        "dump d all custom 50 dump.granval id x y z vx vy vz omegax omegay omegaz fx fy fz",
        "dump_modify d sort id format \"%d %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\"",
        "run 500",
    ] {
        // As LIGGGHTS reads it: numbers compared as f64 (`5e-4` is the deck's `0.0005`).
        assert!(
            lines.iter().any(|l| same_input(l, want)),
            "deck lacks `{want}`:\n{deck}"
        );
    }
    assert!(
        !deck.contains("gravity"),
        "no gravity fix for zero gravity:\n{deck}"
    );
    // Ordering constraints LIGGGHTS enforces.
    let pos = |s: &str| lines.iter().position(|l| l.starts_with(s)).unwrap();
    assert!(pos("atom_modify") < pos("read_data") && pos("boundary") < pos("read_data"));
    assert!(pos("fix m5") < pos("pair_style") && pos("pair_style") < pos("fix w1"));
    assert!(pos("dump_modify") < pos("run"));

    let data = liggghts::write_data_file(&c).unwrap();
    println!("{data}");
    let dl: Vec<&str> = data.lines().collect();
    for want in [
        "2 atoms",
        "1 atom types",
        "-5e-3 5e-3 xlo xhi",
        "-5e-3 5e-3 ylo yhi",
        "-1e-3 5e-3 zlo zhi",
        "Atoms",
        "1 1 2e-3 2.5e3 -1.05e-3 0e0 2e-3",
        "2 1 2e-3 2.5e3 1.05e-3 0e0 2e-3",
        "Velocities",
        "1 7e-1 0e0 0e0 0e0 0e0 3e2",
        "2 -3e-1 0e0 0e0 0e0 0e0 0e0",
    ] {
        assert!(
            dl.iter().any(|l| same_input(l, want)),
            "data file lacks `{want}`:\n{data}"
        );
    }
}

#[test]
fn deck_gravity_cylinder_two_types_no_rolling() {
    let toml = two_spheres(5e7, "none", "")
        .replace("gravity = [0.0, 0.0, 0.0]", "gravity = [0.0, 0.0, -9.81]")
        .replace(
            "[[interactions]]",
            "[[materials]]\ntype = 2\nyoungs_modulus = 7e7\npoisson_ratio = 0.25\n\n\
             [[interactions]]\ntypes = [1, 2]\nrestitution = 0.5\nfriction = 0.3\nrolling_friction = 0.0\n\n\
             [[interactions]]\ntypes = [2, 2]\nrestitution = 0.9\nfriction = 0.1\nrolling_friction = 0.0\n\n[[interactions]]",
        )
        .replace("[[walls]]\nkind = \"plane\"\naxis = \"z\"\nposition = 0.0\ntype = 1", "[[walls]]\nkind = \"cylinder\"\naxis = \"z\"\nradius = 4.5e-3\ncenter = [0.0, 1e-4]\ntype = 2");
    let c = case(&toml);
    let deck = liggghts::write_deck(&c, "d", "x").unwrap();
    let lines: Vec<&str> = deck.lines().collect();
    for want in [
        "fix m1 all property/global youngsModulus peratomtype 5e7 7e7",
        "fix m2 all property/global poissonsRatio peratomtype 3e-1 2.5e-1",
        "fix m3 all property/global coefficientRestitution peratomtypepair 2 8e-1 5e-1 5e-1 9e-1",
        "fix m4 all property/global coefficientFriction peratomtypepair 2 5e-1 3e-1 3e-1 1e-1",
        "pair_style gran model hertz tangential history",
        "fix gravi all gravity 9.81e0 vector 0e0 0e0 -9.81e0",
        "fix w1 all wall/gran model hertz tangential history primitive type 2 zcylinder 4.5e-3 0e0 1e-4",
    ] {
        // As LIGGGHTS reads it: numbers compared as f64 (`5e-4` is the deck's `0.0005`).
        assert!(
            lines.iter().any(|l| same_input(l, want)),
            "deck lacks `{want}`:\n{deck}"
        );
    }
    assert!(
        !deck.contains("coefficientRollingFriction") && !deck.contains("rolling_friction"),
        "{deck}"
    );
}

#[test]
fn refuses_values_liggghts_would_refuse() {
    let c = case(&two_spheres(5e6, "cdt", "").replace("restitution = 0.8", "restitution = 0.05"));
    let msg = format!("{:#}", liggghts::write_deck(&c, "d", "x").unwrap_err());
    println!("{msg}");
    assert!(
        msg.contains("test.toml") && msg.contains("restitution") && msg.contains("5e-2"),
        "{msg}"
    );
    assert!(liggghts::write_data_file(&c).is_err());
    // The engine refuses before running anything.
    let dir = tempfile::tempdir().unwrap();
    let err = run(&Liggghts::default(), &c, dir.path()).unwrap_err();
    assert!(format!("{err:#}").contains("restitution"));
    assert!(!dir.path().join("dump.granval").exists() && !dir.path().join("in.granval").exists());

    let c =
        case(&two_spheres(5e6, "cdt", "").replace("poisson_ratio = 0.3", "poisson_ratio = -0.2"));
    let msg = format!("{:#}", liggghts::write_deck(&c, "d", "x").unwrap_err());
    assert!(
        msg.contains("test.toml") && msg.contains("poisson_ratio") && msg.contains("-2e-1"),
        "{msg}"
    );
    assert!(liggghts::write_data_file(&c).is_err());
    let dir = tempfile::tempdir().unwrap();
    let err = run(&Liggghts::default(), &c, dir.path()).unwrap_err();
    assert!(format!("{err:#}").contains("poisson_ratio"));
    assert!(!dir.path().join("dump.granval").exists() && !dir.path().join("in.granval").exists());
}

/// Young's moduli outside LIGGGHTS' 5e6-1e9 Pa range check (glass, steel, soft
/// grains) are written unchanged, with `soft_particles yes` / `hard_particles yes`
/// lifting only that check; LIGGGHTS accepts the deck and the provenance says so.
#[test]
fn soft_and_hard_materials_lift_the_range_check_unchanged() {
    for (e, on, off) in [
        (4.9e6, "soft_particles yes", "hard_particles"),
        (2e9, "hard_particles yes", "soft_particles"),
    ] {
        let c = case(&two_spheres(e, "cdt", ""));
        let deck = liggghts::write_deck(&c, "d", "x").unwrap();
        let lines: Vec<&str> = deck.lines().collect();
        let modulus = format!("fix m1 all property/global youngsModulus peratomtype {e:e}");
        assert!(
            lines.contains(&on) && lines.iter().any(|l| same_input(l, &modulus)),
            "{deck}"
        );
        assert!(!canonical(&deck).contains(off), "{deck}");
        let pos = |s: &str| lines.iter().position(|l| l.starts_with(s)).unwrap();
        assert!(pos(on) < pos("read_data"), "{deck}");
        assert!(liggghts::write_data_file(&c).is_ok());
        assert_eq!(
            liggghts::hardness_note(&c.materials).len(),
            1,
            "{e:e}: one switch"
        );
    }
    let deck = liggghts::write_deck(&case(&two_spheres(5e7, "cdt", "")), "d", "x").unwrap();
    assert!(
        !deck.contains("soft_particles") && !deck.contains("hard_particles"),
        "{deck}"
    );
    if live().is_none() {
        return;
    }
    for (e, on) in [(4.9e6, "soft_particles yes"), (2e9, "hard_particles yes")] {
        let c = case(&two_spheres(e, "cdt", ""));
        let dir = tempfile::tempdir().unwrap();
        let out = run(&Liggghts::default(), &c, dir.path())
            .unwrap_or_else(|err| panic!("E = {e:e}: {err:#}"));
        assert_eq!(out.frames.len(), liggghts::expected_frames(&c));
        assert!(
            out.provenance.notes.iter().any(|n| n.starts_with(on)),
            "{:?}",
            out.provenance.notes
        );
        // The collision happened with the material as written.
        assert!(out.frames.last().unwrap().particles[1].v[0] > 0.2);
    }
}

const DUMP: &str = "ITEM: TIMESTEP
0
ITEM: NUMBER OF ATOMS
2
ITEM: BOX BOUNDS ff ff ff
-0.01 0.01
-0.01 0.01
-0.01 0.01
ITEM: ATOMS x y z id vx vy vz fx fy fz omegax omegay omegaz 
0.0011000000000000001 0 0.002 2 -0.10000000000000001 0 0 0 0 -0.00010273007977238625 0 0 7
-0.0011000000000000001 0 0.002 1 0.10000000000000001 0 0 0 0 -0.00010273007977238625 0 0 0
ITEM: TIMESTEP
100
ITEM: NUMBER OF ATOMS
2
ITEM: BOX BOUNDS ff ff ff
-0.01 0.01
-0.01 0.01
-0.01 0.01
ITEM: ATOMS x y z id vx vy vz fx fy fz omegax omegay omegaz
-0.0010899999999999944 0 0.00199995095 1 0.10000000000000001 0 -0.0009810000000000027 0 0 -1e-4 1 2 3
0.0010899999999999944 0 0.00199995095 2 -0.10000000000000001 0 -0.0009810000000000027 0 0 -1e-4 4 5 6
";

#[test]
fn parses_a_hand_written_dump() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("dump.test");
    std::fs::write(&p, DUMP).unwrap();
    let frames = liggghts::parse_dump(&p, 1e-6).unwrap();
    assert_eq!(frames.len(), 2);
    assert_eq!((frames[0].step, frames[1].step), (0, 100));
    assert_eq!(frames[1].t, 100.0 * 1e-6);
    let ids: Vec<u64> = frames[0].particles.iter().map(|p| p.id).collect();
    assert_eq!(ids, [1, 2], "sorted by id");
    let a = &frames[0].particles[1];
    // %.17g text of 1.1e-3 and -0.1 parses back to exactly those doubles.
    assert_eq!(a.x, [1.1e-3, 0.0, 0.002]);
    assert_eq!(a.v, [-0.1, 0.0, 0.0]);
    assert_eq!(a.f, [0.0, 0.0, -0.00010273007977238625]);
    assert_eq!(a.omega, [0.0, 0.0, 7.0]);
    assert_eq!(frames[1].particles[0].omega, [1.0, 2.0, 3.0]);
    assert_eq!(frames[1].particles[1].v[2], -0.0009810000000000027);

    // Malformed number: file and line number in the error.
    std::fs::write(&p, DUMP.replace("0.00199995095 2", "0.0019999x 2")).unwrap();
    let msg = format!("{:#}", liggghts::parse_dump(&p, 1e-6).unwrap_err());
    assert!(
        msg.contains("dump.test") && msg.contains("line 22") && msg.contains("0.0019999x"),
        "{msg}"
    );
    // Wrong column count.
    std::fs::write(&p, DUMP.replace(" 4 5 6\n", " 4 5\n")).unwrap();
    let msg = format!("{:#}", liggghts::parse_dump(&p, 1e-6).unwrap_err());
    assert!(
        msg.contains("line 22") && msg.contains("12 values"),
        "{msg}"
    );
    // Truncated in the middle of a frame.
    let cut: String = DUMP.lines().take(20).map(|l| format!("{l}\n")).collect();
    std::fs::write(&p, cut).unwrap();
    let msg = format!("{:#}", liggghts::parse_dump(&p, 1e-6).unwrap_err());
    assert!(msg.contains("truncated"), "{msg}");
    // Missing column.
    std::fs::write(
        &p,
        DUMP.replace("omegaz \n", "\n")
            .replace(" 0 0 7\n", " 0 7\n"),
    )
    .unwrap();
    let msg = format!("{:#}", liggghts::parse_dump(&p, 1e-6).unwrap_err());
    assert!(msg.contains("omegaz") && msg.contains("line 9"), "{msg}");
    // Missing file.
    assert!(liggghts::parse_dump(&dir.path().join("nope"), 1e-6).is_err());
}

fn momentum(fr: &Frame, c: &Case) -> [f64; 3] {
    let mut p = [0.0; 3];
    for s in &fr.particles {
        let m = c.particles.iter().find(|q| q.id == s.id).unwrap().mass();
        for (pk, vk) in p.iter_mut().zip(s.v) {
            *pk += m * vk;
        }
    }
    p
}

#[test]
fn live_two_sphere_collision() {
    let Some(version) = live() else { return };
    println!("{version}");
    let c = case(&two_spheres(5e7, "cdt", ""));
    let dir = tempfile::tempdir().unwrap();
    let t0 = Instant::now();
    let out = run(&Liggghts::default(), &c, dir.path()).unwrap();
    println!(
        "live run: {:.3} s total, provenance wall_time_s = {:.3}",
        t0.elapsed().as_secs_f64(),
        out.provenance.wall_time_s
    );
    println!("{}", serde_json::to_string_pretty(&out.provenance).unwrap());
    assert_eq!(out.frames.len(), 11);
    assert_eq!(out.frames.len(), liggghts::expected_frames(&c));
    for name in [
        "in.granval",
        "data.granval",
        "dump.granval",
        "log.liggghts",
        "liggghts.stdout",
        "liggghts.stderr",
    ] {
        assert!(dir.path().join(name).exists(), "{name} missing");
    }
    // The deck LIGGGHTS ran is the case's (its header's date aside).
    assert_eq!(
        canonical(&std::fs::read_to_string(dir.path().join("in.granval")).unwrap()),
        canonical(&liggghts::write_deck(&c, "dump.granval", "data.granval").unwrap())
    );
    let p = &out.provenance;
    assert_eq!(p.engine, EngineKind::Liggghts);
    assert!(p.version.starts_with("LIGGGHTS (Version"), "{}", p.version);
    assert_eq!(p.command, "liggghts -in in.granval -log log.liggghts");
    assert_eq!(p.threads, 1);
    assert_eq!(p.case_file, "test.toml");
    assert_eq!(p.input_hash.hex().len(), 64);
    // The fingerprint a recorded reference must match: the deck and data file given.
    assert_eq!(p.input_hash, liggghts::micro_input_hash(&c).unwrap());

    // Full precision in the dump: initial state must round-trip exactly.
    let f0 = &out.frames[0];
    assert_eq!((f0.step, f0.t), (0, 0.0));
    for (s, q) in f0.particles.iter().zip(&c.particles) {
        assert_eq!(s.id, q.id);
        assert_eq!(s.x, q.x);
        assert_eq!(s.v, q.v);
        assert_eq!(s.omega, q.omega);
    }
    let dump = std::fs::read_to_string(dir.path().join("dump.granval")).unwrap();
    // %.17g of -1.05e-3 and 0.7 (printf gives 17 significant digits, not the shortest form).
    assert!(
        dump.contains(" -0.0010499999999999999 ") && dump.contains(" 0.69999999999999996 "),
        "17 significant digits expected in the dump:\n{dump}"
    );

    // The collision happened and conserved momentum.
    let last = out.frames.last().unwrap();
    assert_eq!(last.step, 500);
    assert!((last.t - 5e-4).abs() < 1e-15);
    assert!(
        last.particles[1].v[0] > 0.2,
        "particle 2 must bounce back: {:?}",
        last.particles[1]
    );
    assert!(
        last.particles[0].v[1].abs() > 1e-6,
        "friction with the spinning sphere must give a sideways kick"
    );
    let scale: f64 = c
        .particles
        .iter()
        .map(|q| q.mass() * q.v.iter().map(|v| v * v).sum::<f64>().sqrt())
        .sum();
    let p0 = momentum(f0, &c);
    for fr in &out.frames {
        let p = momentum(fr, &c);
        for k in 0..3 {
            let rel = (p[k] - p0[k]).abs() / scale;
            assert!(
                rel < 1e-12,
                "momentum[{k}] drift {rel:e} at step {}",
                fr.step
            );
        }
    }

    // The same case on two MPI ranks gives the same trajectory (to round-off).
    let dir2 = tempfile::tempdir().unwrap();
    let out2 = run(
        &Liggghts {
            mpi_procs: 2,
            ..Liggghts::default()
        },
        &c,
        dir2.path(),
    )
    .unwrap();
    println!(
        "mpirun -np 2: wall_time_s = {:.3}",
        out2.provenance.wall_time_s
    );
    assert_eq!(
        out2.provenance.command,
        "mpirun --allow-run-as-root -np 2 liggghts -in in.granval -log log.liggghts"
    );
    assert_eq!(out2.provenance.threads, 2);
    assert_eq!(out2.frames.len(), out.frames.len());
    for (a, b) in out.frames.iter().zip(&out2.frames) {
        for (pa, pb) in a.particles.iter().zip(&b.particles) {
            for k in 0..3 {
                assert!(
                    (pa.v[k] - pb.v[k]).abs() <= 1e-12 * (1.0 + pa.v[k].abs()),
                    "step {} id {}",
                    a.step,
                    pa.id
                );
            }
        }
    }
}

/// A valid case whose particle leaves the box: LIGGGHTS stops with "ERROR: Lost atoms".
#[test]
fn live_lost_atom_is_an_error() {
    if live().is_none() {
        return;
    }
    let toml = two_spheres(5e7, "cdt", "").replace("v = [0.7, 0.0, 0.0]", "v = [0.7, 0.0, 30.0]");
    let c = case(&toml);
    let dir = tempfile::tempdir().unwrap();
    let err = run(&Liggghts::default(), &c, dir.path())
        .expect_err("a particle leaving a fixed box must fail the run");
    let msg = format!("{err:#}");
    println!("{msg}");
    assert!(msg.contains("ERROR: Lost atoms"), "{msg}");
    assert!(msg.contains("test.toml"), "{msg}");
}

/// Wraps `liggghts` in a script that sabotages the deck or data file before running it.
fn saboteur(dir: &Path, script: &str) -> String {
    let path = dir.join("liggghts-saboteur.sh");
    std::fs::write(
        &path,
        format!("#!/bin/sh\n{script}\nexec liggghts \"$@\"\n"),
    )
    .unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    path.display().to_string()
}

#[test]
fn live_broken_inputs_are_errors() {
    if live().is_none() {
        return;
    }
    let c = case(&two_spheres(5e7, "cdt", ""));
    let bin_dir = tempfile::tempdir().unwrap();

    // Particle 2 moved outside the box in the data file.
    let bin = saboteur(
        bin_dir.path(),
        "sed -i 's/^2 1 \\([^ ]*\\) \\([^ ]*\\) [^ ]*/2 1 \\1 \\2 1e0/' data.granval",
    );
    for np in [1, 2] {
        let dir = tempfile::tempdir().unwrap();
        let err = run(
            &Liggghts {
                binary: bin.clone(),
                mpi_procs: np,
                ..Liggghts::default()
            },
            &c,
            dir.path(),
        )
        .expect_err("particle outside the box");
        let msg = format!("{err:#}");
        println!("np={np}: {msg}");
        assert!(
            msg.contains("ERROR: Did not assign all atoms correctly"),
            "{msg}"
        );
    }

    // Unknown command after the run: the dump is complete, but the run must still fail.
    let bin = saboteur(bin_dir.path(), "echo 'bogus_command 1' >> in.granval");
    let dir = tempfile::tempdir().unwrap();
    let err = run(
        &Liggghts {
            binary: bin,
            ..Liggghts::default()
        },
        &c,
        dir.path(),
    )
    .expect_err("unknown command");
    let msg = format!("{err:#}");
    println!("{msg}");
    assert!(
        msg.contains("ERROR: Unknown command: bogus_command 1"),
        "{msg}"
    );

    // A binary that does not exist.
    let dir = tempfile::tempdir().unwrap();
    let err = run(
        &Liggghts {
            binary: "/nonexistent/liggghts".into(),
            ..Liggghts::default()
        },
        &c,
        dir.path(),
    )
    .unwrap_err();
    assert!(format!("{err:#}").contains("cannot start"), "{err:#}");
    assert!(liggghts::installed_version("/nonexistent/liggghts").is_none());
}

#[test]
fn live_timeout_kills_the_run() {
    if live().is_none() {
        return;
    }
    // Spheres at rest, never touching: 2e7 cheap steps still take ~15 s, far beyond 1 s.
    let toml = two_spheres(5e7, "cdt", "")
        .replace("duration = 5e-4", "duration = 20.0")
        .replace("output_every = 50", "output_every = 1000000")
        .replace("v = [0.7, 0.0, 0.0]", "")
        .replace("v = [-0.3, 0.0, 0.0]", "");
    let c = case(&toml);
    for np in [1, 2] {
        let dir = tempfile::tempdir().unwrap();
        let t0 = Instant::now();
        let err = run(
            &Liggghts {
                mpi_procs: np,
                limits: granval::engines::process::Limits::fixed(
                    Duration::from_secs(1),
                    "--engine-timeout 1.0 s",
                ),
                ..Liggghts::default()
            },
            &c,
            dir.path(),
        )
        .expect_err("must time out");
        let msg = format!("{err:#}");
        println!("np={np}: {msg}");
        // The watchdog ends the run at the limit; how long after it noticed depends on
        // the machine's load (1.1 s seen beside a CI run), so the elapsed time printed is
        // read, not matched.
        let ran: f64 = msg
            .split_once("LIGGGHTS ran for ")
            .and_then(|(_, r)| {
                r.split_once(" s, the limit (--engine-timeout 1.0 s); its processes were ended")
            })
            .and_then(|(t, _)| t.parse().ok())
            .unwrap_or_else(|| panic!("{msg}"));
        assert!((1.0..10.0).contains(&ran), "{msg}");
        assert!(t0.elapsed() < Duration::from_secs(10), "killed promptly");
    }
}

/// The other deck branches (two types, gravity, cylinder wall, epsd2) are accepted by
/// LIGGGHTS too, and its warnings land in the provenance notes.
#[test]
fn live_cylinder_gravity_epsd2_runs() {
    if live().is_none() {
        return;
    }
    let toml = two_spheres(5e7, "epsd2", "")
        .replace("gravity = [0.0, 0.0, 0.0]", "gravity = [0.5, 0.0, -9.81]")
        .replace(
            "[[interactions]]",
            "[[materials]]\ntype = 2\nyoungs_modulus = 7e7\npoisson_ratio = 0.25\n\n\
             [[interactions]]\ntypes = [1, 2]\nrestitution = 0.5\nfriction = 0.3\nrolling_friction = 0.02\n\n\
             [[interactions]]\ntypes = [2, 2]\nrestitution = 0.9\nfriction = 0.1\nrolling_friction = 0.0\n\n[[interactions]]",
        )
        .replace("[[walls]]\nkind = \"plane\"\naxis = \"z\"\nposition = 0.0\ntype = 1", "[[walls]]\nkind = \"cylinder\"\naxis = \"z\"\nradius = 3.5e-3\ncenter = [0.0, 0.0]\ntype = 2")
        .replace("id = 2\ntype = 1", "id = 7\ntype = 2");
    let c = case(&toml);
    let dir = tempfile::tempdir().unwrap();
    let out = run(&Liggghts::default(), &c, dir.path()).unwrap();
    println!("{:#?}", out.provenance.notes);
    assert_eq!(out.frames.len(), 11);
    assert_eq!(
        out.frames[0]
            .particles
            .iter()
            .map(|p| p.id)
            .collect::<Vec<_>>(),
        [1, 7]
    );
    // Gravity shows in the step-0 force of a free sphere: f = m g.
    let m = c.particles[0].mass();
    let f = out.frames[0].particles[0].f;
    assert!(
        (f[2] - m * -9.81).abs() <= 1e-12 * m * 9.81 && (f[0] - m * 0.5).abs() <= 1e-12 * m * 9.81,
        "{f:?}"
    );
    // Particle 1 (x = -1.05 mm, r = 1 mm, v = 0.7) hits particle 7 and the cylinder wall (R = 3.5 mm).
    assert!(out.frames.last().unwrap().particles[1].v[0] > 0.0);
}
