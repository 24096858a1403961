//! K Fig 12's interface on a tiny bed (seconds): the tracers a real scene gets, s(t)
//! recorded by both engines at every intruder sample (LAMMPS live when `lmp` is
//! installed; there is no record of this test case, so without it only the native side
//! runs), the native vs LAMMPS s(t) check, the claim evaluated in each engine, and the
//! frozen-floor control (s = 0, D_rel = D). Nothing here is a physics result: the run
//! is 100 tau_c on a 300-disk bed settled to a loose criterion.

mod common;

use granval::case::Perturbation;
use granval::case::impact2d::Impact2dCase;
use granval::compare::{Gate, Status};
use granval::experiments::impact2d::{Impact2d, label_dir};
use granval::experiments::{Experiment, Options, Role, runner};
use granval::rundata::provenance::EngineKind;

/// cases/impact2d/ci.toml on 300 disks, L = 20 d, settled to 1e-6 m g d, run for 100
/// tau_c, plus `extra`; `analysis` is appended to its `[analysis]` table.
fn tiny_text(extra: &str, analysis: &str) -> String {
    std::fs::read_to_string(common::root().join("cases/impact2d/ci.toml"))
        .unwrap()
        .replace("name = \"ci\"", "name = \"tiny-interface\"")
        .replace("settle_ke = 1e-10", "settle_ke = 1e-6")
        .replace("count = 450", "count = 300")
        .replace("length = 30.0", "length = 20.0")
        .replace("duration = 1000.0", "duration = 100.0")
        .replace(
            "final_window = 200.0",
            &format!("final_window = 40.0\n{analysis}"),
        )
        + extra
}

fn tiny(extra: &str) -> Impact2dCase {
    Impact2dCase::from_toml_str(
        &tiny_text(extra, ""),
        std::path::Path::new("tiny-interface.toml"),
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

const CLAIM: &str = "
[sweep]
parameter = \"speed\"
values = [0.7, 1.0]

[claim]
kind = \"interface_steadies\"
max_ratio = 0.5
min_amplitude = 0.05

[[negative_control]]
name = \"interface = the frozen floor\"
must_fail = [\"claim\"]
perturbation = { interface_frozen_floor = true }
";

fn frozen_floor() -> Perturbation {
    Perturbation {
        interface_frozen_floor: true,
        ..Perturbation::default()
    }
}

/// The scene's tracers follow the rule (recomputed here from the bed), the native run
/// records their height at every sample into `intruder.csv`, and the frozen-floor
/// control records a constant (s = 0, D_rel = D).
#[test]
fn native_runs_record_the_interface_and_the_control_freezes_it() {
    let exp = Impact2d { case: tiny(CLAIM) };
    let c = &exp.case;
    assert!(c.track_interface);
    let (d, l) = (c.scales.d, c.length);
    let units = exp.units(&Options::default()).unwrap();
    let u = &units[0];
    let sys = &u.scene.sys;
    let want: Vec<usize> = (0..sys.disks.len())
        .filter(|&k| {
            let g = &sys.disks[k];
            let dx = (g.x[0] - 0.5 * l).abs();
            g.type_ == 0 && g.x[1] >= u.scene.surface - 2.0 * d && dx.min(l - dx) >= 0.25 * l
        })
        .collect();
    eprintln!("{} tracers of {} disks", want.len(), sys.disks.len());
    assert_eq!(u.scene.tracers, want);
    assert!(want.len() >= 10);
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().join("native");
    let run = exp
        .run_native(u, Role::Main, &dir, &Options::default())
        .unwrap();
    assert!(run.samples.iter().all(|s| s.interface_y.is_some()));
    let s = granval::analysis::interface::shift(&run.samples).unwrap();
    let moved = s.iter().map(|p| p.1.abs()).fold(0.0, f64::max) / d;
    eprintln!("largest |s| {moved:.3e} d");
    assert!(moved > 0.0, "the interface never moved");
    let head = std::fs::read_to_string(dir.join("intruder.csv")).unwrap();
    assert!(head.starts_with("t,step,x,y,vx,vy,fx,fy,depth,interface_y,interface_s\n"));
    let back = granval::rundata::impact::read_intruder_csv(&dir.join("intruder.csv")).unwrap();
    assert_eq!(back, run.samples);
    // The control: the floor never moves, so s = 0 and D_rel = D at every sample.
    let floor = exp
        .run_native(
            u,
            Role::Control(&frozen_floor()),
            &out.path().join("floor"),
            &Options::default(),
        )
        .unwrap();
    let s = granval::analysis::interface::shift(&floor.samples).unwrap();
    assert!(s.iter().all(|p| p.1 == 0.0));
    let (o, _) = granval::experiments::impact2d::observe(c, &u.variant, &u.scene, &floor).unwrap();
    let i = o.interface.unwrap();
    assert_eq!(i.depth.amplitude, i.relative.amplitude);
    // The same physics: only the tracked height differs from the main run.
    for (a, b) in run.samples.iter().zip(&floor.samples) {
        assert_eq!((a.x, a.v, a.f), (b.x, b.v, b.f));
    }
}

/// Both engines on the tiny case: LAMMPS' eighth column is the tracers' centre of mass
/// the native engine computes (s(t) within the 0.1 d gate, in fact to round-off while
/// the trajectories agree), and the claim is evaluated (not errored) in each engine.
#[test]
fn lammps_records_the_same_interface() {
    if !common::live(EngineKind::Lammps, "impact2d_interface") {
        common::engineless(
            "impact2d_interface",
            "SKIPPED: no lmp, and no record of this tiny case: nothing to compare",
        );
        return;
    }
    // The runner copies the case file next to its outputs: it must exist.
    let file = tempfile::tempdir().unwrap();
    let path = file.path().join("tiny-interface.toml");
    std::fs::write(&path, tiny_text(CLAIM, "")).unwrap();
    let exp = Impact2d {
        case: Impact2dCase::load(&path).unwrap(),
    };
    let out = tempfile::tempdir().unwrap();
    let r = runner::compare(&exp, &common::options(), out.path());
    common::show("tiny-interface", &r.checks);
    assert!(r.checks.iter().all(|k| !k.is_error()), "{:?}", r.checks);
    let cross: Vec<_> = r
        .checks
        .iter()
        .filter(|k| k.gate == Gate::InterfaceSeries)
        .collect();
    assert_eq!(cross.len(), 2);
    for k in &cross {
        assert_eq!(k.status, Status::Pass, "{k:?}");
        assert!(k.value < 1e-6, "{k:?}");
    }
    let claims: Vec<_> = r
        .checks
        .iter()
        .filter(|k| k.gate == Gate::Claim && k.name.contains("K Fig 12"))
        .collect();
    assert_eq!(claims.len(), 2, "native and lammps");
    let unit = label_dir(&exp.case.variants[0]);
    let lmp = runner::reference_out(out.path(), &unit, EngineKind::Lammps);
    let deck = std::fs::read_to_string(lmp.join("in.impact2d")).unwrap();
    assert!(deck.contains("variable sy equal xcm(iface,y)"));
    let line = std::fs::read_to_string(lmp.join("intruder.txt")).unwrap();
    let last = line.lines().last().unwrap();
    assert_eq!(last.split_whitespace().count(), 8, "{last}");
}

/// A case that tracks nothing has no tracers and writes no interface into its deck;
/// `[analysis] track_interface = true` tracks without a claim, and moves the case's
/// canonical hash (a record made without tracking is then foreign).
#[test]
fn tracking_is_opt_in() {
    let deck = |exp: &Impact2d| {
        let units = exp.units(&Options::default()).unwrap();
        let out = tempfile::tempdir().unwrap();
        exp.write_deck(&units[0], out.path(), &Options::default())
            .unwrap();
        (
            units[0].scene.tracers.len(),
            std::fs::read_to_string(out.path().join("in.impact2d")).unwrap(),
        )
    };
    let plain = Impact2d { case: tiny("") };
    assert!(!plain.case.track_interface);
    let (n, text) = deck(&plain);
    assert_eq!(n, 0);
    assert!(
        !text.contains("iface") && !text.contains("Fig 12"),
        "{text}"
    );
    let tracked = Impact2d {
        case: Impact2dCase::from_toml_str(
            &tiny_text("", "track_interface = true"),
            &plain.case.source,
        )
        .unwrap(),
    };
    assert!(tracked.case.track_interface && tracked.case.claims.is_empty());
    assert_ne!(tracked.case.canonical_hash(), plain.case.canonical_hash());
    let (n, text) = deck(&tracked);
    assert!(n >= 10);
    assert!(text.contains("variable sy equal xcm(iface,y)"), "{text}");
}

/// Every case that does not track the interface keeps its deck: today's LAMMPS input of
/// each recorded CI-size case (all variants, both packings; one 450-disk bed settled
/// here in seconds) is, command for command, the one its sealed record was made from.
#[test]
fn recorded_ci_decks_are_unchanged() {
    use granval::engines::deck_text::check_same_input;
    use granval::engines::lammps;
    let mut checked = 0;
    for name in [
        "ci",
        "ci-ellipse",
        "ci-friction",
        "ci-en",
        "ci-packing",
        "ci-speed",
    ] {
        let exp = Impact2d {
            case: Impact2dCase::load(&common::root().join(format!("cases/impact2d/{name}.toml")))
                .unwrap(),
        };
        assert!(!exp.case.track_interface);
        for u in exp.units(&Options::default()).unwrap() {
            let rec = common::root()
                .join("reference/impact2d")
                .join(name)
                .join(label_dir(&u.variant));
            let deck = lammps::deck::write_deck(&u.scene.sys, &exp.outputs(&u)).unwrap();
            check_same_input(&rec, lammps::DECK_FILE, &deck, false)
                .unwrap_or_else(|e| panic!("{name}: {e:#}"));
            let data = lammps::deck::write_data(&u.scene.sys);
            check_same_input(&rec, lammps::DATA_FILE, &data, true)
                .unwrap_or_else(|e| panic!("{name}: {e:#}"));
            assert!(!deck.contains("xcm(iface"));
            checked += 1;
        }
    }
    assert_eq!(checked, 15);
}
