//! Penetration into a bed of rigid clumps (Feng et al. Sec. 3 (f), Fig 3(f)) on a tiny
//! bed of 160 dimers: the case schema and its refusals, the native pour and penetration,
//! and LIGGGHTS starting from exactly the same bodies.

mod common;

use granval::case::penetration::PenetrationCase;
use granval::experiments::penetration::bed::{liggghts_deck, prepare_bed};
use granval::rundata::provenance::EngineKind;
use std::path::Path;

fn text() -> String {
    std::fs::read_to_string(common::root().join("tests/data/penetration-dimers-tiny.toml")).unwrap()
}

fn case() -> PenetrationCase {
    PenetrationCase::from_toml_str(&text(), Path::new("dimers.toml")).unwrap()
}

#[test]
fn clump_bed_schema_and_refusals() {
    let c = case();
    let t = c.clump.as_ref().expect("a clump bed");
    assert_eq!((t.name.as_str(), t.radii.len()), ("dimer", 2));
    // Union of two r = 2 mm spheres 2 mm apart: 2 V_s - lens, lens = pi (4r + c)(2r - c)^2 / 12.
    let (r, cc) = (2e-3f64, 2e-3f64);
    let v = 2.0 * 4.0 / 3.0 * std::f64::consts::PI * r.powi(3)
        - std::f64::consts::PI * (4.0 * r + cc) * (2.0 * r - cc).powi(2) / 12.0;
    approx::assert_relative_eq!(t.volume, v, max_relative = 1e-12);
    // A clump bed hashes differently from the same spheres.
    let spheres = text()
        .replace("clump_template = \"dimer\"\n", "")
        .split("[[clump_templates]]")
        .next()
        .unwrap()
        .to_string();
    let s = PenetrationCase::from_toml_str(&spheres, Path::new("s.toml")).unwrap();
    assert!(s.clump.is_none());
    assert_ne!(s.canonical_hash(), c.canonical_hash());
    let refused = |from: &str, to: &str, field: &str, why: &str| {
        let bad = text().replacen(from, to, 1);
        assert_ne!(bad, text(), "{from}");
        let e = PenetrationCase::from_toml_str(&bad, Path::new("dimers.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("dimers.toml") && e.contains(field) && e.contains(why),
            "{field}: {e}"
        );
    };
    refused(
        "clump_template = \"dimer\"",
        "clump_template = \"trimer\"",
        "bed.clump_template",
        "must name the one",
    );
    refused(
        "clump_template = \"dimer\"\n",
        "",
        "clump_templates",
        "names none",
    );
    refused(
        "density = 2500.0\nspheres",
        "density = 2400.0\nspheres",
        "clump_templates[0].density",
        "bed's density",
    );
    refused(
        "radius = 2.0e-3 },\n    { offset = [0.001, 0.0, 0.0], radius = 2.0e-3 }",
        "radius = 1.9e-3 },\n    { offset = [0.001, 0.0, 0.0], radius = 1.9e-3 }",
        "clump_templates[0].spheres[0].radius",
        "half the bed's diameter",
    );
    refused(
        "diameter = { kind = \"constant\", value = 4.0e-3 }",
        "diameter = { kind = \"uniform\", mean = 4.0e-3, half_width = 0.2e-3 }",
        "bed.diameter",
        "constant diameter",
    );
    refused(
        "name = \"dimer\"\ntype = 1",
        "name = \"dimer\"\ntype = 2",
        "clump_templates[0].type",
        "bed's material type",
    );
}

/// The dimers pour, settle to the KE criterion and resist the intruder natively; the
/// bodies read back from the deck's bodies file are the bed, bit for bit.
#[test]
fn dimer_bed_settles_and_resists() {
    let c = case();
    let bed = prepare_bed(&c, false).unwrap();
    eprintln!("{}", granval::physics::dem::packing::bed_note(&c, &bed));
    assert_eq!((bed.bodies.len(), bed.particles.len()), (160, 0));
    assert!(bed.ke_ratio < c.settle_ke_ratio);
    assert!(bed.psi > 0.4 && bed.psi < 0.75, "psi {}", bed.psi);
    let spheres = bed.spheres(&c);
    assert_eq!(spheres.len(), 320);
    let top = spheres.iter().map(|(x, r)| x[2] + r).fold(0.0, f64::max);
    assert!(bed.surface_z > 0.0 && bed.surface_z <= top);
    // Settled: every body rests on the floor or on others, none above the heap.
    assert!(bed.bodies.iter().all(|b| b.x[2] < top));
    let (samples, _) = granval::engines::native::penetration(
        &c,
        &bed,
        &Default::default(),
        &[],
        |_| Ok(()),
        |_, _| {},
    )
    .unwrap();
    assert_eq!(samples[0].f, [0.0; 3]);
    let deep: Vec<f64> = samples
        .iter()
        .filter(|s| s.z_bottom < bed.surface_z - 0.004)
        .map(|s| s.f[2])
        .collect();
    assert!(!deep.is_empty() && deep.iter().sum::<f64>() / deep.len() as f64 > 0.0);

    let d = tempfile::tempdir().unwrap();
    let deck = liggghts_deck(&c, &bed).unwrap();
    granval::engines::liggghts::penetration::write_deck_dir(&deck, d.path()).unwrap();
    let back = granval::experiments::penetration::deck_dir::read_bed(&c, d.path()).unwrap();
    assert_eq!(
        granval::experiments::penetration::bed::bed_hash(&back),
        granval::experiments::penetration::bed::bed_hash(&bed)
    );
    assert_eq!(back.surface_z.to_bits(), bed.surface_z.to_bits());
}

/// LIGGGHTS inserts the settled bodies exactly and starts the penetration from the
/// native engine's state: the same position and orientation of every body, on one and
/// on two processes, and velocities, angular velocities and forces equal to round-off;
/// then penetrates.
#[test]
fn liggghts_starts_from_the_native_bodies() {
    if !common::live(
        EngineKind::Liggghts,
        "liggghts_starts_from_the_native_bodies",
    ) {
        return;
    }
    let c = case();
    let bed = prepare_bed(&c, false).unwrap();
    let mut deck = liggghts_deck(&c, &bed).unwrap();
    deck.n_steps = 200;
    for np in [1, 2] {
        let d = tempfile::tempdir().unwrap();
        let (samples, _) = granval::engines::liggghts::penetration::run(
            &deck,
            d.path(),
            np,
            &granval::engines::process::Limits::fixed(
                std::time::Duration::from_secs(600),
                "the test's limit",
            ),
        )
        .unwrap();
        assert_eq!(samples.len(), 200 / c.force_every as usize);
        let diff =
            granval::experiments::penetration::clump_start_difference(&c, &bed, d.path()).unwrap();
        eprintln!("np {np}: {}", diff.text());
        // Positions and orientations are the very doubles; velocities took one half kick
        // from forces the engines sum in their own order (round-off, ~1e-14 relative).
        assert_eq!((diff.x, diff.angle), (0.0, 0.0), "np {np}");
        assert!(
            diff.v < 1e-15 && diff.omega < 1e-12 && diff.f < 1e-15,
            "np {np}"
        );
    }
}
