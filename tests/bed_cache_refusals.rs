//! A bed from `GRANVAL_BED_CACHE` is used only when its seal names the bed's
//! specification and sha256 and the bed has the case's grain count: a 5-grain file
//! where the tiny case pours 300 grains is refused (exit 2, naming the file), sealed or
//! not, instead of being reported as "prepared natively"; a bed the cache stored itself
//! (the negative control) is used.

mod common;

use common::text;

use granval::case::Particle;
use granval::case::penetration::PenetrationCase;
use granval::experiments::bed_cache;
use granval::experiments::penetration::bed::bed_file_name;
use granval::physics::dem::packing::Bed;
use std::path::Path;
use std::process::Output;

fn deck(cache: &Path, out: &Path) -> Output {
    common::granval()
        .env("GRANVAL_BED_CACHE", cache)
        .arg("deck")
        .arg(common::root().join("tests/data/penetration-tiny.toml"))
        .arg("-o")
        .arg(out)
        .output()
        .unwrap()
}

#[test]
fn a_five_grain_cached_bed_is_refused() {
    let case =
        PenetrationCase::load(&common::root().join("tests/data/penetration-tiny.toml")).unwrap();
    let ck = case.realisation(0);
    let cache = tempfile::tempdir().unwrap();
    let file = cache.path().join(bed_file_name(&ck).unwrap());
    let spec = granval::case::ValidatedCase::canonical_hash(&ck.settling_case()).to_string();
    let five = Bed {
        particles: (0..5)
            .map(|i| Particle {
                id: i + 1,
                type_: 0,
                radius: 1e-3,
                density: 2500.0,
                x: [0.0, 0.0, 0.002 * (i as f64 + 1.0)],
                v: [0.0; 3],
                omega: [0.0; 3],
            })
            .collect(),
        bodies: Vec::new(),
        surface_z: 0.011,
        psi: 0.6,
        ke_ratio: 1e-9,
        settle_time: 0.1,
        ke_at_end_of_pour: 1.0,
    };
    // Sealed as granval seals a bed (a forger who rewrites the seal): the count refuses.
    bed_cache::store(Some(&file), &spec, &five);
    let out = tempfile::tempdir().unwrap();
    let o = deck(cache.path(), &out.path().join("d"));
    let t = text(&o);
    assert_eq!(o.status.code(), Some(2), "{t}");
    assert!(
        t.contains(&file.display().to_string()) && t.contains("a bed of 5 grains"),
        "{t}"
    );
    // The same file without its seal (written by hand): refused too.
    let mut seal = file.clone().into_os_string();
    seal.push(".seal.json");
    std::fs::remove_file(&seal).unwrap();
    let o = deck(cache.path(), &out.path().join("e"));
    let t = text(&o);
    assert_eq!(o.status.code(), Some(2), "{t}");
    assert!(t.contains("without a readable seal"), "{t}");
    // The negative control: with the file moved away, granval prepares the bed, stores
    // it sealed, and a second deck uses the cached bed.
    std::fs::remove_file(&file).unwrap();
    for d in ["f", "g"] {
        let o = deck(cache.path(), &out.path().join(d));
        assert!(o.status.success(), "{}", text(&o));
    }
    assert!(Path::new(&seal).exists());
    let hash = |d: &str| {
        let b = granval::experiments::penetration::deck_dir::read_bed(
            &ck,
            &out.path().join(d).join("bed-0"),
        )
        .unwrap();
        granval::experiments::penetration::bed::bed_hash(&b)
    };
    assert_eq!(hash("f"), hash("g"));
}
