//! Two-disk micro cases, native 2D engine vs LAMMPS `gran/hooke(/history)` from the
//! same state: every output step must agree to ~1e-10 relative. Live `lmp` when
//! installed; otherwise the recorded LAMMPS dumps under reference/impact2d/micro/.

mod common;

use granval::engines::lammps::{self, Lammps, Outputs, parse};
use granval::physics::dem2d::contact::Coeffs;
use granval::physics::dem2d::neighbor::Box2;
use granval::physics::dem2d::{Disk, Role, System, lammps_mass};
use std::path::Path;

const DT: f64 = 1e-5;

fn coeffs(kt_ratio: f64, mu: f64, e_n: f64) -> Coeffs {
    let kn: f64 = 2.0e3;
    let m_eff: f64 = 0.5 * 1e-3;
    let tau = std::f64::consts::PI * (m_eff / kn).sqrt();
    let gamma_n = granval::physics::dem2d::contact::gamma_n_from_restitution(e_n, tau);
    Coeffs {
        kn,
        kt: kt_ratio * kn,
        gamma_n,
        gamma_t: 0.5 * gamma_n,
        mu,
    }
}

fn disk(id: u64, type_: usize, r: f64, x: [f64; 2], v: [f64; 2], omega: f64, role: Role) -> Disk {
    Disk {
        id,
        type_,
        radius: r,
        mass: lammps_mass(1e-3 * (r / 0.002).powi(2), r),
        x,
        v,
        omega,
        role,
    }
}

fn system(disks: Vec<Disk>, c_grain: Coeffs, c_wall: Coeffs, gravity: f64) -> System {
    let bx = Box2 {
        lo: [0.0, 0.0],
        hi: [0.05, 0.05],
        periodic_x: true,
    };
    System::new(
        disks,
        None,
        vec![c_grain, c_wall, c_wall, c_wall],
        2,
        bx,
        gravity,
        DT,
        0.001,
        vec![],
    )
}

/// (step, id, x, y, vx, vy, omega) rows of the native run every `every` steps.
fn native_rows(mut sys: System, n: u64, every: u64) -> Vec<(u64, u64, [f64; 5])> {
    let mut rows = Vec::new();
    sys.setup();
    loop {
        if sys.step.is_multiple_of(every) {
            for d in &sys.disks {
                rows.push((sys.step, d.id, [d.x[0], d.x[1], d.v[0], d.v[1], d.omega]));
            }
        }
        if sys.step == n {
            break;
        }
        sys.step();
    }
    rows
}

fn lammps_rows(sys: &System, n: u64, every: u64, name: &str) -> Vec<(u64, u64, [f64; 5])> {
    let rec = common::root().join("reference/impact2d/micro").join(name);
    let outputs = Outputs {
        n_steps: n,
        intruder_every: 0,
        snapshot_every: every,
        header: Default::default(),
        fields: Default::default(),
        tracers: Vec::new(),
    };
    // The record stands in for LAMMPS only if it was made from today's inputs (these
    // records are test fixtures, not sealed cases: the check is done here). Left out:
    // thermo lines (screen output only) and the z extent of the 2D box (no physics).
    let today = tempfile::tempdir().unwrap();
    lammps::write_inputs(sys, &outputs, today.path(), None).unwrap();
    for f in [lammps::DECK_FILE, lammps::DATA_FILE] {
        // Compared as the engine reads them (comments out, numbers as f64s): the
        // records predate the commented, plain-notation decks.
        // read_data skips a data file's first line (a title).
        let skip = usize::from(f == lammps::DATA_FILE);
        let physics = |p: &Path| {
            let text = std::fs::read_to_string(p).unwrap_or_default();
            granval::engines::deck_text::canonical(&text)
                .lines()
                .skip(skip)
                .filter(|l| !l.starts_with("thermo") && !l.ends_with("zlo zhi"))
                .map(|l| format!("{l}\n"))
                .collect::<String>()
        };
        let (was, now) = (physics(&rec.join(f)), physics(&today.path().join(f)));
        assert!(
            granval::engines::deck_text::same_input(&was, &now),
            "[{name}] {} differs from today's LAMMPS input: re-record with GRANVAL_RECORD=1 and a live lmp\n{was}\n---\n{now}",
            rec.join(f).display()
        );
    }
    // Reference data never comes from the native engine.
    let recorded = granval::rundata::provenance::read_provenance(&rec.join("provenance.json"))
        .unwrap_or_else(|e| panic!("[{name}] {e:#}"));
    assert_eq!(
        recorded.engine,
        granval::rundata::provenance::EngineKind::Lammps,
        "[{name}] {}",
        rec.display()
    );
    let live = lammps::installed_version(&lammps::binary()).is_some();
    let dump = if live {
        let dir = tempfile::tempdir().unwrap().keep();
        let fin = Lammps::default()
            .run(sys, &outputs, &dir)
            .unwrap_or_else(|e| panic!("{e:#}"));
        eprintln!("[{name}] reference: LIVE {}", fin.version);
        if granval::experiments::env_flags::flag("GRANVAL_RECORD")
            .unwrap_or_else(|e| panic!("{e:#}"))
        {
            record(&dir, &rec, &fin);
        }
        dir.join(lammps::SNAP_FILE)
    } else {
        assert!(
            !common::require_live(),
            "[{name}] LAMMPS is not installed but GRANVAL_REQUIRE_LIVE=1"
        );
        common::engineless(
            name,
            &format!(
                "reference: FALLBACK to recorded {} (lmp not installed)",
                rec.display()
            ),
        );
        rec.join(lammps::SNAP_FILE)
    };
    let mut rows = Vec::new();
    parse::for_each_snapshot(&dump, |step, atoms| {
        for a in atoms {
            rows.push((step, a.id, [a.x[0], a.x[1], a.v[0], a.v[1], a.omega]));
        }
        Ok(())
    })
    .unwrap();
    rows
}

fn record(dir: &Path, rec: &Path, fin: &lammps::Finished) {
    std::fs::create_dir_all(rec).unwrap();
    for f in [
        lammps::DECK_FILE,
        lammps::DATA_FILE,
        lammps::SNAP_FILE,
        lammps::LOG_FILE,
    ] {
        std::fs::copy(dir.join(f), rec.join(f)).unwrap();
    }
    let p = granval::rundata::provenance::Provenance {
        engine: granval::rundata::provenance::EngineKind::Lammps,
        version: fin.version.clone(),
        command: fin.command.clone(),
        input_hash: fin.input_hash.clone(),
        date: granval::rundata::provenance::now_utc(),
        wall_time_s: fin.wall_time_s,
        threads: 1,
        case_file: "tests/impact2d_micro.rs".into(),
        notes: vec![],
    };
    granval::rundata::provenance::write_provenance(&rec.join("provenance.json"), &p).unwrap();
}

/// Largest |native - lammps| / scale over all rows, per column scale = max |lammps|.
fn worst(a: &[(u64, u64, [f64; 5])], b: &[(u64, u64, [f64; 5])]) -> f64 {
    assert_eq!(a.len(), b.len(), "row counts differ");
    let mut scale = [0.0f64; 5];
    for r in b {
        for (s, v) in scale.iter_mut().zip(r.2) {
            *s = s.max(v.abs());
        }
    }
    let mut w = 0.0f64;
    for (x, y) in a.iter().zip(b) {
        assert_eq!((x.0, x.1), (y.0, y.1));
        for ((s, p), q) in scale.iter().zip(x.2).zip(y.2) {
            if *s > 0.0 {
                w = w.max((p - q).abs() / s);
            }
        }
    }
    w
}

fn check(name: &str, sys: System, n: u64, every: u64) -> f64 {
    let native = native_rows(sys.clone(), n, every);
    let reference = lammps_rows(&sys, n, every, name);
    let w = worst(&native, &reference);
    eprintln!("[{name}] worst relative deviation {w:.3e}");
    w
}

#[test]
fn head_on_static_friction() {
    let c = coeffs(0.8, 0.5, 0.5);
    let s = system(
        vec![
            disk(1, 0, 0.002, [0.02, 0.02], [0.3, 0.0], 0.0, Role::Free),
            disk(2, 0, 0.0022, [0.025, 0.02], [-0.2, 0.0], 0.0, Role::Free),
        ],
        c,
        c,
        0.0,
    );
    assert!(check("head-on", s, 400, 10) < 1e-10);
}

#[test]
fn oblique_sticking_and_sliding() {
    for (name, mu) in [("oblique-stick", 0.9), ("oblique-slide", 0.1)] {
        let c = coeffs(0.8, mu, 0.5);
        let s = system(
            vec![
                disk(1, 0, 0.002, [0.02, 0.02], [0.3, 0.1], 20.0, Role::Free),
                disk(
                    2,
                    0,
                    0.0018,
                    [0.0245, 0.0215],
                    [-0.2, -0.15],
                    -10.0,
                    Role::Free,
                ),
            ],
            c,
            c,
            0.0,
        );
        assert!(check(name, s, 600, 10) < 1e-10, "{name}");
    }
}

#[test]
fn oblique_kinetic_friction() {
    let c = coeffs(0.0, 0.3, 0.5);
    let s = system(
        vec![
            disk(1, 0, 0.002, [0.02, 0.02], [0.3, 0.1], 20.0, Role::Free),
            disk(
                2,
                0,
                0.0018,
                [0.0245, 0.0215],
                [-0.2, -0.15],
                -10.0,
                Role::Free,
            ),
        ],
        c,
        c,
        0.0,
    );
    assert!(check("oblique-kinetic", s, 600, 10) < 1e-10);
}

#[test]
fn disk_on_wall_particle_with_gravity() {
    let c = coeffs(0.8, 0.5, 0.5);
    let w = coeffs(0.8, 0.9, 0.1);
    let s = system(
        vec![
            disk(1, 0, 0.002, [0.0203, 0.0045], [0.05, -0.2], 5.0, Role::Free),
            disk(2, 1, 0.002, [0.02, 0.002], [0.0, 0.0], 0.0, Role::Frozen),
        ],
        c,
        w,
        9.81,
    );
    assert!(check("disk-on-wall", s, 3000, 50) < 1e-10);
}

/// A rigid ring of 12 disks (the ellipse intruder's `fix rigid`, rotation off) falling
/// onto a grain resting on two wall disks: cluster + grain trajectories must agree.
#[test]
fn rigid_cluster_on_a_grain_with_gravity() {
    let c = coeffs(0.8, 0.5, 0.5);
    let w = coeffs(0.8, 0.9, 0.1);
    let mut disks = vec![
        disk(1, 0, 0.002, [0.0201, 0.0059], [0.0, 0.0], 0.0, Role::Free),
        disk(2, 1, 0.002, [0.018, 0.002], [0.0, 0.0], 0.0, Role::Frozen),
        disk(3, 1, 0.002, [0.022, 0.002], [0.0, 0.0], 0.0, Role::Frozen),
    ];
    let mut members = Vec::new();
    for k in 0..12 {
        let a = 2.0 * std::f64::consts::PI * k as f64 / 12.0;
        members.push(disks.len());
        disks.push(disk(
            4 + k,
            2,
            0.0015,
            [0.02 + 0.005 * a.cos(), 0.0165 + 0.004 * a.sin()],
            [0.0, 0.0],
            0.0,
            Role::Cluster,
        ));
    }
    let cluster = granval::physics::dem2d::Cluster::new(&mut disks, members.clone(), [0.0, -0.3]);
    let bx = Box2 {
        lo: [0.0, 0.0],
        hi: [0.05, 0.05],
        periodic_x: true,
    };
    let coeffs = vec![c, w, c, w, w, w, c, w, c];
    let s = System::new(
        disks,
        Some(cluster),
        coeffs,
        3,
        bx,
        9.81,
        DT,
        0.001,
        members,
    );
    let w = check("rigid-cluster", s, 4000, 100);
    // fix rigid stores member offsets in its principal-axis frame: round-off, not bitwise.
    assert!(w < 1e-10, "{w}");
}

/// A LAMMPS that fails, or exits 0 having written nothing, is an error with a
/// transcript, never an empty success.
#[test]
fn crashed_or_silent_lammps_is_an_error() {
    let c = coeffs(0.8, 0.5, 0.5);
    let s = system(
        vec![
            disk(1, 0, 0.002, [0.02, 0.02], [0.3, 0.0], 0.0, Role::Free),
            disk(2, 0, 0.002, [0.025, 0.02], [-0.2, 0.0], 0.0, Role::Free),
        ],
        c,
        c,
        0.0,
    );
    let out = Outputs {
        n_steps: 10,
        intruder_every: 0,
        snapshot_every: 5,
        header: Default::default(),
        fields: Default::default(),
        tracers: Vec::new(),
    };
    for (binary, why) in [("false", "exited with"), ("true", "Total wall time")] {
        let dir = tempfile::tempdir().unwrap();
        let lmp = Lammps {
            binary: binary.into(),
            ..Lammps::default()
        };
        let e = format!("{:#}", lmp.run(&s, &out, dir.path()).unwrap_err());
        assert!(e.contains("LAMMPS run failed") && e.contains(why), "{e}");
    }
    let dir = tempfile::tempdir().unwrap();
    let lmp = Lammps {
        binary: "/nonexistent/lmp".into(),
        ..Lammps::default()
    };
    assert!(lmp.run(&s, &out, dir.path()).is_err());
}
