//! Bed preparation (K Sec. II) on small beds: the random bed's diameters, settling
//! criterion, smoothing and packing fraction; the hexagonal lattice; and the impact
//! scene built on top (release height, walls, LAMMPS data file round trip).

use granval::physics::dem2d::bed::{self, BedSpec, Packing};
use granval::physics::dem2d::contact::Coeffs;

fn spec(packing: Packing) -> BedSpec {
    let d = 0.004;
    let c = Coeffs {
        kn: 400.0,
        kt: 0.0,
        gamma_n: 1500.0,
        gamma_t: 750.0,
        mu: 0.5,
    };
    let w = Coeffs {
        kn: 400.0,
        kt: 0.0,
        gamma_n: 4000.0,
        gamma_t: 2000.0,
        mu: 0.9,
    };
    BedSpec {
        packing,
        count: 160,
        length: 16.0 * d,
        d,
        polydispersity: 0.2,
        areal_density: 1e-4 / (std::f64::consts::PI * 0.25 * d * d),
        wall_d: d,
        seed: 11,
        initial_speed: 0.05,
        settle_ke: 1e-8 * 1e-4 * 9.81 * d,
        max_settle_time: 30.0,
        dt: 2e-5,
        skin: 0.3 * d,
        gravity: 9.81,
        coeffs: [c, w, w, w],
    }
}

fn max_overlap(b: &bed::Bed, l: f64) -> f64 {
    let mut worst = 0.0f64;
    let all: Vec<_> = b.grains.iter().chain(&b.wall).collect();
    for (i, a) in all.iter().enumerate() {
        for c in &all[i + 1..] {
            let mut dx = (a.x[0] - c.x[0]).abs();
            dx = dx.min(l - dx);
            let dy = a.x[1] - c.x[1];
            worst = worst
                .max((a.radius + c.radius - (dx * dx + dy * dy).sqrt()) / (a.radius + c.radius));
        }
    }
    worst
}

#[test]
fn random_bed_is_polydisperse_settled_smoothed() {
    let s = spec(Packing::Random);
    let b = bed::prepare(&s, |_, _| {}).unwrap();
    let d = s.d;
    for g in &b.grains {
        let dia = 2.0 * g.radius;
        assert!(
            dia >= d * 0.8 - 1e-15 && dia <= d * 1.2 + 1e-15,
            "diameter {dia}"
        );
        assert!(g.x[1] > b.floor, "grain below the floor");
    }
    let (lo, hi) = b.grains.iter().fold((f64::INFINITY, 0.0f64), |(a, c), g| {
        (a.min(g.radius), c.max(g.radius))
    });
    assert!(hi / lo > 1.2, "not polydisperse: radii {lo}..{hi}");
    assert!(
        b.final_ke < s.settle_ke,
        "{} >= {}",
        b.final_ke,
        s.settle_ke
    );
    assert!(b.removed > 0 && b.grains.len() + b.removed == s.count);
    // Smoothing: the surface, sampled every d/4 across L, varies by little more than a grain.
    let tops: Vec<f64> = (0..64)
        .map(|k| b.surface_at(k as f64 * s.length / 64.0, s.length))
        .filter(|v| v.is_finite())
        .collect();
    let (tmin, tmax) = tops
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, c), &v| {
            (a.min(v), c.max(v))
        });
    eprintln!(
        "random bed: {} grains, surface {:.3}..{:.3} d, phi {:.3}, settled {:.3} s",
        b.grains.len(),
        tmin / d,
        tmax / d,
        b.packing_fraction,
        b.settle_time
    );
    assert!(
        tmax - tmin < 1.6 * d,
        "rough surface: {} d",
        (tmax - tmin) / d
    );
    assert!(
        (0.78..0.9).contains(&b.packing_fraction),
        "phi {}",
        b.packing_fraction
    );
    assert!(max_overlap(&b, s.length) < 0.02);
}

#[test]
fn hexagonal_bed_is_a_compressed_lattice() {
    let s = spec(Packing::Hexagonal);
    let s = BedSpec {
        polydispersity: 0.0,
        initial_speed: 0.0,
        ..s
    };
    let b = bed::prepare(&s, |_, _| {}).unwrap();
    assert_eq!(b.grains.len(), s.count);
    assert!(b.grains.iter().all(|g| g.radius == 0.5 * s.d));
    // Rows stay rows: every height within 0.1 d of its lattice row (the soft test
    // springs compress the 10-row column by a few % of d).
    let row = s.d * 3f64.sqrt() / 2.0;
    for g in &b.grains {
        let k = ((g.x[1] - b.floor + 0.5 * s.wall_d) / row).round();
        assert!(
            (g.x[1] - (b.floor - 0.5 * s.wall_d + k * row)).abs() < 0.1 * s.d,
            "grain off its row at {}",
            g.x[1]
        );
    }
    eprintln!("hexagonal bed: phi {:.3}", b.packing_fraction);
    assert!(b.packing_fraction > 0.88, "phi {}", b.packing_fraction);
}

#[test]
fn bed_preparation_is_reproducible_for_a_seed_and_differs_across_seeds() {
    let s = BedSpec {
        settle_ke: 1e300,
        ..spec(Packing::Random)
    };
    let a = bed::prepare(&s, |_, _| {}).unwrap();
    let b = bed::prepare(&s, |_, _| {}).unwrap();
    let c = bed::prepare(
        &BedSpec {
            seed: 12,
            ..s.clone()
        },
        |_, _| {},
    )
    .unwrap();
    let key = |b: &bed::Bed| {
        b.grains
            .iter()
            .map(|g| (g.radius, g.x, g.v))
            .collect::<Vec<_>>()
    };
    assert_eq!(key(&a), key(&b));
    assert_ne!(key(&a), key(&c));
}
