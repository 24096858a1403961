//! LIGGGHTS penetration deck: unit conversion, unit choice against LIGGGHTS' measured
//! limits, deck content, the force-file parser, and (when `liggghts` is installed) live
//! runs in cgs and SI, plus runs that must fail.

mod common;

use granval::case::{Material, PairTable, Particle, RollingModel};
use granval::engines::liggghts::penetration::{
    self, DATA_FILE, DECK_FILE, FORCE_FILE, ForceSample, PenetrationDeck, STL_FILE, Units,
    choose_units, parse_force_file, write_deck_dir,
};
use std::time::{Duration, Instant};

fn material(e: f64, nu: f64) -> Material {
    Material {
        youngs_modulus: e,
        shear_modulus: e / (2.0 * (1.0 + nu)),
        poisson_ratio: nu,
    }
}

const D: f64 = 0.004;
const RHO: f64 = 2500.0;
const RC: f64 = 0.020;
/// In-plane lattice spacing (0.2 mm gaps) and layer pitch: alternate layers are shifted
/// by half a spacing and sit 2.75 mm higher, just above the nested (BCC-like) height
/// sqrt(d^2 - s^2/2) = 2.68 mm, so the loose lattice settles little.
const SPACING: f64 = 0.0042;
const PITCH: f64 = 0.00275;
const LAYERS: usize = 6;

/// ~300 spheres (d = 4 mm) on a loose lattice inside R = 20 mm, above the floor z = 0;
/// returns them and the top z.
fn lattice_bed() -> (Vec<Particle>, f64) {
    let r = D / 2.0;
    let mut ps = Vec::new();
    let mut top: f64 = 0.0;
    for layer in 0..LAYERS {
        let shift = if layer % 2 == 0 { 0.0 } else { SPACING / 2.0 };
        let z = r + 0.0002 + layer as f64 * PITCH;
        for i in -5i32..=5 {
            for j in -5i32..=5 {
                let (x, y) = (i as f64 * SPACING + shift, j as f64 * SPACING + shift);
                if (x * x + y * y).sqrt() + r > RC - 0.0002 {
                    continue;
                }
                ps.push(Particle {
                    id: ps.len() as u64 + 1,
                    type_: 0,
                    radius: r,
                    density: RHO,
                    x: [x, y, z],
                    v: [0.0; 3],
                    omega: [0.0; 3],
                });
                top = top.max(z + r);
            }
        }
    }
    (ps, top)
}

fn deck(units: Units, e: f64) -> PenetrationDeck {
    let (particles, top) = lattice_bed();
    let n = 2;
    PenetrationDeck {
        units,
        clump: None,
        bodies: Vec::new(),
        materials: vec![material(e, 0.3); n],
        pairs: PairTable {
            n_types: n,
            restitution: vec![0.5; n * n],
            friction: vec![0.5; n * n],
            rolling_friction: vec![0.01; n * n],
        },
        rolling: RollingModel::Cdt,
        tangential_damping: None,
        dt: 2e-5,
        gravity: 9.81,
        container_radius: RC,
        floor_z: 0.0,
        domain_lo: [-0.022, -0.022, -0.002],
        domain_hi: [0.022, 0.022, 0.07],
        particles,
        intruder_radius: 0.006,
        intruder_length: 0.02,
        intruder_type: 1,
        intruder_bottom_z0: top + 0.002,
        speed: 0.1,
        n_steps: 6_000,
        force_every: 100,
        neighbor_skin: 0.001,
        rim_error_frac: 0.01,
        wall_type: 0,
        soft_particles: e < 5e6,
        hard_particles: false,
        settle: None,
        header: Default::default(),
        viz_every: None,
    }
}

#[test]
fn bed_has_about_300_spheres() {
    let (ps, top) = lattice_bed();
    assert!((250..=350).contains(&ps.len()), "{}", ps.len());
    assert!(top < 0.02, "{top}");
}

#[test]
fn unit_factors_round_trip() {
    for u in [Units::Si, Units::Cgs] {
        for x in [0.004, 2500.0, 2.6e6, 9.81, 0.1, 1.234567890123e-3] {
            for k in [u.length(), u.density(), u.pressure(), u.force(), u.mass()] {
                let back = (x * k) / k;
                assert!(
                    ((back - x) / x).abs() <= 2.0 * f64::EPSILON,
                    "{u:?} {x} {k}"
                );
            }
        }
    }
    let c = Units::Cgs;
    assert_eq!(
        (
            c.length(),
            c.density(),
            c.pressure(),
            c.velocity(),
            c.force()
        ),
        (100.0, 1e-3, 10.0, 100.0, 1e5)
    );
    // Force = mass * acceleration: N = kg m/s^2 -> g cm/s^2 = dyn.
    assert_eq!(c.mass() * c.length(), c.force());
    // Pressure = force / area.
    assert_eq!(c.force() / (c.length() * c.length()), c.pressure());
    // Density = mass / volume.
    approx::assert_relative_eq!(c.mass() / c.length().powi(3), c.density());
}

#[test]
fn force_file_round_trip_to_si() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(FORCE_FILE);
    // What LIGGGHTS writes in cgs (cm, dyn), %.20g.
    std::fs::write(
        &p,
        "# step t z_bottom fx fy fz (cgs)\n100 0.0020000000000000000416 4.2000000000000001776 0 -1.5e-3 123.45600000000000307\n\n200 0.004 4.18 1 2 3\n",
    )
    .unwrap();
    let s = parse_force_file(&p, Units::Cgs).unwrap();
    assert_eq!(s.len(), 2);
    assert_eq!(s[0].step, 100);
    assert_eq!(s[0].t, 0.002);
    approx::assert_relative_eq!(s[0].z_bottom, 0.042, max_relative = 1e-15);
    approx::assert_relative_eq!(s[0].f[2], 123.456e-5, max_relative = 1e-15);
    approx::assert_relative_eq!(s[0].f[1], -1.5e-8, max_relative = 1e-15);
    let si = parse_force_file(&p, Units::Si).unwrap();
    assert_eq!(si[1].f, [1.0, 2.0, 3.0]);
    assert_eq!(si[1].z_bottom, 4.18);

    // Errors name the file and the line.
    std::fs::write(&p, "# title\n100 0.002 4.2 0 0 1\n200 0.004 4.1 0 zero 1\n").unwrap();
    let e = format!("{:#}", parse_force_file(&p, Units::Si).unwrap_err());
    assert!(e.contains(&format!("{}:3", p.display())), "{e}");
    assert!(e.contains("fy"), "{e}");
    std::fs::write(&p, "100 0.002 4.2 0 0\n").unwrap();
    let e = format!("{:#}", parse_force_file(&p, Units::Si).unwrap_err());
    assert!(e.contains(":1") && e.contains("fz"), "{e}");
    assert!(parse_force_file(&dir.path().join("nope.txt"), Units::Si).is_err());
}

#[test]
fn choose_units_follows_liggghts_limits() {
    // E = 5.2e6 Pa: SI accepts it.
    assert_eq!(choose_units(&[material(5.2e6, 0.3)]).unwrap(), Units::Si);
    assert_eq!(
        choose_units(&[material(5.2e6, 0.3), material(1e8, 0.3)]).unwrap(),
        Units::Si
    );
    // Table 2, G = 1 MPa -> E = 2.6 MPa. LIGGGHTS 3.8.0 refuses it in SI (< 5e6 Pa) AND in
    // cgs (< 5e7 barye, the same 5e6 Pa; measured), so no unit choice represents it: the
    // answer is an error naming the value, never a silently changed material.
    let e = format!("{:#}", choose_units(&[material(2.6e6, 0.3)]).unwrap_err());
    assert!(e.contains("2.6e6"), "{e}");
    assert!(e.contains("soft_particles"), "{e}");
    let e = format!("{:#}", choose_units(&[material(2.6e9, 0.3)]).unwrap_err());
    assert!(e.contains("2.6e9") && e.contains("hard_particles"), "{e}");
}

#[test]
fn soft_material_is_refused_without_override() {
    let mut d = deck(Units::Cgs, 2.6e6);
    d.soft_particles = false;
    let dir = tempfile::tempdir().unwrap();
    let e = format!("{:#}", write_deck_dir(&d, dir.path()).unwrap_err());
    assert!(e.contains("2.6e6") && e.contains("soft_particles"), "{e}");
    assert!(!dir.path().join(DECK_FILE).exists());
}

#[test]
fn deck_contains_expected_commands() {
    let d = deck(Units::Cgs, 2.6e6);
    let dir = tempfile::tempdir().unwrap();
    let files = write_deck_dir(&d, dir.path()).unwrap();
    let text = std::fs::read_to_string(&files.deck).unwrap();
    let z0 = d.intruder_bottom_z0 * 100.0;
    for line in [
        "units cgs".to_string(),
        "atom_style granular".to_string(),
        "atom_modify map array".to_string(),
        "boundary f f f".to_string(),
        "newton off".to_string(),
        "communicate single vel yes".to_string(),
        "soft_particles yes".to_string(),
        "read_data data.bed".to_string(),
        "neighbor 1e-1 bin".to_string(),
        "neigh_modify delay 0".to_string(),
        "fix m1 all property/global youngsModulus peratomtype 2.6e7 2.6e7".to_string(),
        "fix m2 all property/global poissonsRatio peratomtype 3e-1 3e-1".to_string(),
        "fix m3 all property/global coefficientRestitution peratomtypepair 2 5e-1 5e-1 5e-1 5e-1"
            .to_string(),
        "fix m4 all property/global coefficientFriction peratomtypepair 2 5e-1 5e-1 5e-1 5e-1"
            .to_string(),
        "fix m5 all property/global coefficientRollingFriction peratomtypepair 2 1e-2 1e-2 1e-2 1e-2"
            .to_string(),
        "pair_style gran model hertz tangential history rolling_friction cdt".to_string(),
        "pair_coeff * *".to_string(),
        "timestep 2e-5".to_string(),
        "fix gravi all gravity 9.81e2 vector 0 0 -1".to_string(),
        "fix floor all wall/gran model hertz tangential history rolling_friction cdt primitive type 1 zplane 0e0"
            .to_string(),
        "fix container all wall/gran model hertz tangential history rolling_friction cdt primitive type 1 zcylinder 2e0 0 0"
            .to_string(),
        "fix integr all nve/sphere".to_string(),
        format!(
            "fix cad all mesh/surface/stress file intruder.stl type 2 stress on reference_point 0 0 {z0:e}"
        ),
        "fix wallint all wall/gran model hertz tangential history rolling_friction cdt mesh n_meshes 1 meshes cad"
            .to_string(),
        "fix mv all move/mesh mesh cad linear 0 0 -1e1".to_string(),
        "thermo 60".to_string(),
        "thermo_modify lost error".to_string(),
        "run 6000".to_string(),
    ] {
        // As LIGGGHTS reads it: numbers compared as f64 (`1e-1` is the deck's `0.1`).
        assert!(
            text.lines()
                .any(|l| granval::engines::deck_text::same_input(l, &line)),
            "missing line {line:?} in\n{text}"
        );
    }
    // Numbers are written in plain notation, comments explain the switches.
    assert!(text.lines().any(|l| l == "neighbor 0.1 bin"), "{text}");
    assert!(
        text.contains("# soft_particles yes: type 1 has E = 2600000 Pa"),
        "{text}"
    );
    assert!(text.contains(
        "fix fout all print 100 \"$(step) $(step*dt) $(f_cad[9]) $(f_cad[1]) $(f_cad[2]) $(f_cad[3])\" file force.txt"
    ));
    // Mesh fixes come after the integrator and the walls, before run.
    let pos = |k: &str| text.find(k).unwrap();
    assert!(pos("read_data") < pos("fix m1") && pos("fix m1") < pos("pair_style"));
    assert!(pos("fix integr") < pos("fix cad") && pos("fix cad") < pos("fix wallint"));
    assert!(pos("fix wallint") < pos("fix mv") && pos("fix fout") < pos("run 6000"));

    // The data file and STL are in cm / g/cm^3.
    let data = std::fs::read_to_string(&files.data).unwrap();
    // Converted values are written in full (shortest round trip of x * 100, e.g.
    // -2.1999999999999997).
    assert!(
        data.contains(&format!(
            "{} {} xlo xhi",
            granval::engines::deck_text::num(-0.022 * 100.0),
            granval::engines::deck_text::num(0.022 * 100.0)
        )),
        "{data}"
    );
    assert!(data.contains(&format!("{} atoms", d.particles.len())));
    let first = data
        .lines()
        .skip_while(|l| *l != "Atoms")
        .nth(2)
        .unwrap()
        .to_string();
    let cols: Vec<&str> = first.split_whitespace().collect();
    assert_eq!(cols[0], "1");
    assert_eq!(cols[1], "1");
    assert_eq!(cols[2].parse::<f64>().unwrap(), 0.4);
    assert_eq!(cols[3].parse::<f64>().unwrap(), 2.5);
    let stl = std::fs::read_to_string(&files.stl).unwrap();
    assert!(stl.starts_with("solid "));
    let zs: Vec<f64> = stl
        .lines()
        .filter_map(|l| l.trim().strip_prefix("vertex "))
        .map(|v| v.split_whitespace().nth(2).unwrap().parse().unwrap())
        .collect();
    let zmin = zs.iter().copied().fold(f64::INFINITY, f64::min);
    let zmax = zs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    assert_eq!(zmin, z0);
    approx::assert_relative_eq!(zmax, z0 + 2.0, max_relative = 1e-12);
    assert_eq!(stl.matches("facet normal").count(), 4 * files.stl_segments);
    let readme = std::fs::read_to_string(&files.readme).unwrap();
    for k in [
        "liggghts -in in.penetration",
        "mpirun -np N liggghts -in in.penetration",
        "granval analyze DIR",
        "force.txt",
        "dyn",
    ] {
        assert!(readme.contains(k), "README lacks {k:?}");
    }

    // SI: nothing converted, no override.
    let si = deck(Units::Si, 5.2e6);
    let t = penetration::deck_text(&si).unwrap();
    for l in [
        "units si",
        "fix m1 all property/global youngsModulus peratomtype 5.2e6 5.2e6",
        "fix gravi all gravity 9.81e0 vector 0 0 -1",
        "fix mv all move/mesh mesh cad linear 0 0 -1e-1",
        "neighbor 1e-3 bin",
    ] {
        assert!(
            t.lines()
                .any(|x| granval::engines::deck_text::same_input(x, l)),
            "missing {l:?}"
        );
    }
    assert!(!t.contains("soft_particles"));
}

#[test]
fn invalid_geometry_is_refused() {
    let mut d = deck(Units::Si, 5.2e6);
    d.n_steps = 1_000_000; // the intruder would go through the floor
    assert!(penetration::deck_text(&d).is_err());
    let mut d = deck(Units::Si, 5.2e6);
    d.intruder_bottom_z0 = 0.055; // top above the domain
    let e = format!("{:#}", penetration::deck_text(&d).unwrap_err());
    assert!(e.contains("domain_hi"), "{e}");
    let mut d = deck(Units::Si, 5.2e6);
    d.intruder_type = 2;
    assert!(penetration::deck_text(&d).is_err());
}

/// Live LIGGGHTS, or a loud skip (a failure with GRANVAL_REQUIRE_LIVE=1).
fn liggghts_or_skip(test: &str) -> bool {
    let live = common::live(granval::rundata::provenance::EngineKind::Liggghts, test);
    if !live {
        common::engineless(test, "SKIPPED: `liggghts` is not installed or does not run");
    }
    live
}

/// Mean fz (N) over the second half of the run, and the checks every live run must pass.
fn check_live(d: &PenetrationDeck, s: &[ForceSample], label: &str) -> f64 {
    assert_eq!(s.len(), (d.n_steps / d.force_every) as usize, "{label}");
    for (k, x) in s.iter().enumerate() {
        let step = (k as u64 + 1) * d.force_every;
        assert_eq!(x.step, step, "{label}");
        let t = step as f64 * d.dt;
        approx::assert_relative_eq!(x.t, t, max_relative = 1e-12);
        // Measured position of the bottom face, in SI: linear at the set speed.
        let z = d.intruder_bottom_z0 - d.speed * t;
        assert!(
            ((x.z_bottom - z) / z).abs() < 1e-9,
            "{label}: step {step}: z_bottom {} vs {z} (rel {:e})",
            x.z_bottom,
            (x.z_bottom - z) / z
        );
        assert!(x.f.iter().all(|v| v.is_finite()), "{label}");
    }
    // Starts above the bed: no force in the first sample (2 mm gap, 0.2 mm travelled).
    assert_eq!(s[0].f, [0.0; 3], "{label}: force before contact");
    let first = s
        .iter()
        .position(|x| x.f[2] != 0.0)
        .unwrap_or_else(|| panic!("{label}: the intruder never touched the grains"));
    let half = &s[s.len() / 2..];
    let mean = half.iter().map(|x| x.f[2]).sum::<f64>() / half.len() as f64;
    let max = s.iter().map(|x| x.f[2]).fold(f64::NEG_INFINITY, f64::max);
    let min = s.iter().map(|x| x.f[2]).fold(f64::INFINITY, f64::min);
    eprintln!(
        "{label}: first contact at sample {first} (z_bottom {:.6e} m); fz second-half mean {mean:.4e} N, max {max:.4e} N, min {min:.4e} N",
        s[first].z_bottom
    );
    // The bed resists: the force of the grains on the intruder points up.
    assert!(mean > 0.0, "{label}: mean fz {mean:e} N is not upward");
    assert!(max > 0.0);
    // Grain weight scale: one grain weighs ~8.2e-4 N; the force is a few grain weights
    // up to the whole bed's weight (~0.25 N) — not numerically absurd.
    assert!(max < 5.0, "{label}: max fz {max:e} N");
    mean
}

fn live(units: Units, e: f64, label: &str) -> Option<(PenetrationDeck, Vec<ForceSample>, f64)> {
    if !liggghts_or_skip(label) {
        return None;
    }
    let d = deck(units, e);
    let tmp = tempfile::tempdir().unwrap();
    // GRANVAL_KEEP_RUNS=1 keeps the run directories for inspection.
    let (_guard, dir) = if granval::experiments::env_flags::flag("GRANVAL_KEEP_RUNS")
        .unwrap_or_else(|e| panic!("{e:#}"))
    {
        let p = tmp.keep();
        eprintln!("{label}: run directory kept at {}", p.display());
        (None, p)
    } else {
        let p = tmp.path().to_path_buf();
        (Some(tmp), p)
    };
    let t0 = Instant::now();
    let (s, prov) = penetration::run(
        &d,
        &dir,
        1,
        &granval::engines::process::Limits::fixed(Duration::from_secs(300), "the test's limit"),
    )
    .unwrap_or_else(|err| panic!("{label}: {err:#}"));
    let wall = t0.elapsed().as_secs_f64();
    eprintln!(
        "{label}: {} grains, {} steps: LIGGGHTS wall {:.2} s (total {wall:.2} s); {}; notes {:?}",
        d.particles.len(),
        d.n_steps,
        prov.wall_time_s,
        prov.version,
        prov.notes
    );
    assert!(prov.version.starts_with("LIGGGHTS (Version"));
    assert!(
        prov.command
            .ends_with("liggghts -in in.penetration -log log.liggghts"),
        "{}",
        prov.command
    );
    // The force file carries 17+ significant digits (%.20g), not %g's 6.
    let raw = std::fs::read_to_string(dir.join(FORCE_FILE)).unwrap();
    let zcol = raw
        .lines()
        .find(|l| !l.starts_with('#'))
        .unwrap()
        .split_whitespace()
        .nth(2)
        .unwrap()
        .to_string();
    let digits = zcol.chars().filter(|c| c.is_ascii_digit()).count();
    assert!(digits >= 15, "{label}: z column {zcol:?}");
    let mean = check_live(&d, &s, label);
    Some((d, s, mean))
}

#[test]
fn live_soft_cgs_and_stiff_si() {
    let Some((_, _, soft)) = live(Units::Cgs, 2.6e6, "cgs E=2.6e6 (soft_particles)") else {
        return;
    };
    let Some((_, si, stiff)) = live(Units::Si, 5.2e6, "si E=5.2e6") else {
        return;
    };
    let Some((_, cgs, stiff_cgs)) = live(Units::Cgs, 5.2e6, "cgs E=5.2e6") else {
        return;
    };
    // Same material in two unit systems: identical up to round-off, which only grows
    // chaotically later, so the first contact and the first contact samples agree.
    let first = |s: &[ForceSample]| s.iter().position(|x| x.f[2] != 0.0).unwrap();
    assert_eq!(first(&si), first(&cgs), "first contact sample SI vs cgs");
    for k in first(&si)..first(&si) + 3 {
        let (a, b) = (si[k].f[2], cgs[k].f[2]);
        eprintln!("step {}: fz SI {a:e} N, cgs {b:e} N", si[k].step);
        assert!(
            ((a - b) / a).abs() < 0.1,
            "step {}: SI {a:e} vs cgs {b:e}",
            si[k].step
        );
        approx::assert_relative_eq!(si[k].z_bottom, cgs[k].z_bottom, max_relative = 1e-12);
    }
    let r = soft / stiff;
    eprintln!(
        "mean fz: soft cgs {soft:e} N, stiff SI {stiff:e} N (ratio {r:.3}), stiff cgs {stiff_cgs:e} N"
    );
    assert!((0.2..5.0).contains(&r), "soft/stiff force ratio {r}");
    // Same material, two unit systems: the same physics up to chaotic divergence.
    let r = stiff_cgs / stiff;
    assert!((0.5..2.0).contains(&r), "cgs/SI force ratio {r}");
}

#[test]
fn live_missing_stl_and_broken_deck_are_errors() {
    if !liggghts_or_skip("live_missing_stl_and_broken_deck_are_errors") {
        return;
    }
    let mut d = deck(Units::Si, 5.2e6);
    d.n_steps = 200;
    let dir = tempfile::tempdir().unwrap();
    write_deck_dir(&d, dir.path()).unwrap();
    std::fs::remove_file(dir.path().join(STL_FILE)).unwrap();
    let e = format!(
        "{:#}",
        penetration::run_existing(
            &d,
            dir.path(),
            1,
            &granval::engines::process::Limits::fixed(Duration::from_secs(120), "the test's limit")
        )
        .unwrap_err()
    );
    eprintln!("missing STL: {e}");
    assert!(e.contains("ERROR"), "{e}");

    // A deck pointing at a wrong STL path.
    write_deck_dir(&d, dir.path()).unwrap();
    let deck_path = dir.path().join(DECK_FILE);
    let text = std::fs::read_to_string(&deck_path).unwrap();
    std::fs::write(
        &deck_path,
        text.replace("file intruder.stl", "file no/such/intruder.stl"),
    )
    .unwrap();
    let e = format!(
        "{:#}",
        penetration::run_existing(
            &d,
            dir.path(),
            1,
            &granval::engines::process::Limits::fixed(Duration::from_secs(120), "the test's limit")
        )
        .unwrap_err()
    );
    assert!(e.contains("ERROR"), "{e}");

    // A broken command.
    write_deck_dir(&d, dir.path()).unwrap();
    let text = std::fs::read_to_string(&deck_path).unwrap();
    std::fs::write(
        &deck_path,
        text.replace("fix integr all nve/sphere", "fix integr all nve/spherez"),
    )
    .unwrap();
    let e = format!(
        "{:#}",
        penetration::run_existing(
            &d,
            dir.path(),
            1,
            &granval::engines::process::Limits::fixed(Duration::from_secs(120), "the test's limit")
        )
        .unwrap_err()
    );
    assert!(e.contains("ERROR"), "{e}");

    // A data file with a missing atom.
    write_deck_dir(&d, dir.path()).unwrap();
    let data_path = dir.path().join(DATA_FILE);
    let data = std::fs::read_to_string(&data_path).unwrap();
    std::fs::write(&data_path, data.replacen(" atoms", "0 atoms", 1)).unwrap();
    assert!(
        penetration::run_existing(
            &d,
            dir.path(),
            1,
            &granval::engines::process::Limits::fixed(Duration::from_secs(120), "the test's limit")
        )
        .is_err()
    );
}
