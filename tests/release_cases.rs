//! The release cases (`cases/release/`) and the release suite load and say what
//! docs/stress.md's pre-registration ("Validating the estimator") fixed for them.

mod common;

use granval::case::AnyCase;
use granval::case::penetration::PenetrationCase;
use granval::compare::Gate;

fn penetration(rel: &str) -> PenetrationCase {
    match AnyCase::load(&common::root().join(rel)).unwrap_or_else(|e| panic!("{e}")) {
        AnyCase::Penetration(c) => c,
        _ => panic!("{rel}: not a penetration case"),
    }
}

fn impact2d(rel: &str) -> granval::case::impact2d::Impact2dCase {
    match AnyCase::load(&common::root().join(rel)).unwrap_or_else(|e| panic!("{e}")) {
        AnyCase::Impact2d(c) => c,
        _ => panic!("{rel}: not an impact2d case"),
    }
}

#[test]
fn release_suite_lists_the_frictionless_and_mid_scale_cases() {
    let s = granval::experiments::suite::load(&common::root().join("cases"), "release").unwrap();
    let find = |name: &str| {
        s.cases
            .iter()
            .find(|c| c.path.ends_with(name))
            .unwrap_or_else(|| panic!("{name} not in the release suite"))
    };
    let f = find("release/frictionless-ci.toml");
    assert!(
        f.stress && !f.theory,
        "frictionless: K_phi vs K(phi) reported (rule 1)"
    );
    let m = find("release/feng-table2-mid.toml");
    assert!(m.stress && m.theory, "mid scale: MALT gated against v2");
    for c in &s.cases {
        AnyCase::load(&c.path).unwrap_or_else(|e| panic!("{e}"));
    }
}

/// The pre-registered methods are gated on the release cases (new data) and not yet on
/// the CI case, whose gates stay v1 with the open fit range until the new-seed
/// judgement (docs/stress.md, "Implementation").
#[test]
fn release_cases_gate_rule3_and_v2_and_ci_does_not() {
    use granval::case::penetration::{KPhiRange, PhiEstimator};
    for rel in [
        "cases/release/ci-seeds-20261200.toml",
        "cases/release/frictionless-ci.toml",
        "cases/release/feng-table2-mid.toml",
    ] {
        let c = penetration(rel);
        assert_eq!(c.k_phi_range, KPhiRange::Rule3, "{rel}");
        assert_eq!(c.phi_estimator, PhiEstimator::V2, "{rel}");
    }
    let ci = penetration("cases/penetration/ci.toml");
    assert_eq!(ci.k_phi_range, KPhiRange::Open);
    assert_eq!(ci.phi_estimator, PhiEstimator::V1);
    let bad = std::fs::read_to_string(common::root().join("cases/penetration/ci.toml"))
        .unwrap()
        .replace("[analysis]\n", "[analysis]\nphi_estimator = \"v3\"\n");
    let e = PenetrationCase::from_toml_str(&bad, std::path::Path::new("x.toml")).unwrap_err();
    assert!(e.to_string().contains("analysis.phi_estimator"), "{e}");
}

/// The CI case on new seeds is the CI case but for its name and seed.
#[test]
fn ci_copy_differs_from_the_ci_case_only_in_seed_and_name() {
    let ci = penetration("cases/penetration/ci.toml");
    let new = penetration("cases/release/ci-seeds-20261200.toml");
    assert_eq!(new.seed, 20261200);
    assert_eq!(new.ensemble_beds, 3);
    let mut same = new.clone();
    same.seed = ci.seed;
    same.name = ci.name.clone();
    same.description = ci.description.clone();
    same.source = ci.source.clone();
    assert_eq!(same.canonical_hash(), ci.canonical_hash());
    assert_eq!(new.snapshot_h, ci.snapshot_h);
    assert_eq!(new.fit_h_min, ci.fit_h_min);
    assert_eq!(new.negative_controls.len(), ci.negative_controls.len());
}

/// Frictionless: mu = 0 for every pair, no rolling model, the CI geometry; phi = 9 +- 2
/// deg published; the control puts Table 2's friction back and must fail K_phi, the
/// published phi and (the built-in tangential control having nothing to drop) phi.
#[test]
fn frictionless_case_is_the_ci_geometry_without_friction() {
    let ci = penetration("cases/penetration/ci.toml");
    let f = penetration("cases/release/frictionless-ci.toml");
    assert!(f.pairs.friction.iter().all(|&m| m == 0.0), "{:?}", f.pairs);
    assert_eq!(f.rolling, granval::case::RollingModel::None);
    assert_eq!(f.seed, 20261300);
    assert_eq!(f.ensemble_beds, 3);
    for (a, b) in [
        (f.container_radius, ci.container_radius),
        (f.intruder_radius, ci.intruder_radius),
        (f.final_depth, ci.final_depth),
        (f.speed, ci.speed),
        (f.dt, ci.dt),
        (f.diameter.mean(), ci.diameter.mean()),
        (f.fit_h_min, ci.fit_h_min),
    ] {
        assert_eq!(a, b);
    }
    assert_eq!(f.count, ci.count);
    assert_eq!(f.snapshot_h, ci.snapshot_h);
    let p = f.published_phi.as_ref().expect("published phi");
    assert_eq!((p.phi_deg, p.abs_deg), (9.0, 2.0));
    let c = &f.negative_controls[0];
    assert!(c.must_fail.contains(&Gate::KPhi) && c.must_fail.contains(&Gate::Published));
    assert!(c.must_fail.contains(&Gate::Phi));
}

/// Mid scale: the paper's R / d = 7.5, container radius >= 4 R, one bed.
#[test]
fn mid_scale_case_has_the_papers_size_ratio() {
    let m = penetration("cases/release/feng-table2-mid.toml");
    assert!((m.intruder_radius / m.diameter.mean() - 7.5).abs() < 1e-12);
    assert!(m.container_radius >= 4.0 * m.intruder_radius);
    assert_eq!(m.ensemble_beds, 1);
}

/// The release suite records under `reference/release/`, the other tiers at the root.
#[test]
fn release_suite_records_under_reference_release() {
    let cases = common::root().join("cases");
    let base = std::path::Path::new("reference");
    let r = granval::experiments::suite::load(&cases, "release").unwrap();
    assert_eq!(r.reference_root(base), base.join("release"));
    let ci = granval::experiments::suite::load(&cases, "ci").unwrap();
    assert_eq!(ci.reference_root(base), base);
}

/// Kondic et al. Fig 9 as registered: the five bodies in order of falling g on the Fig 2
/// bed at v = 1.0, with both claims (depth and time of the maximum), each with its
/// effect size.
#[test]
fn kondic_fig9_case_sweeps_five_gravities_with_two_claims() {
    use granval::case::impact2d::{Claim, ClaimQuantity};
    let c = impact2d("cases/release/kondic-fig9-gravity.toml");
    let g: Vec<f64> = c.variants.iter().map(|v| v.x).collect();
    assert_eq!(g.len(), 5);
    assert!(g.windows(2).all(|w| w[0] > w[1]), "{g:?}");
    assert!((g[0] * 980.0 - 2479.0).abs() < 0.01 && (g[4] * 980.0 - 62.0).abs() < 0.01);
    assert!(c.variants.iter().all(|v| v.speed == c.variants[0].speed));
    let steps: Vec<(ClaimQuantity, f64)> = c
        .claims
        .iter()
        .map(|k| match k {
            Claim::Increasing { min_step, of, .. } => (*of, *min_step),
            other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(
        steps,
        vec![
            (ClaimQuantity::FinalDepth, 1.0),
            (ClaimQuantity::TimeOfMaxDepth, 5.0)
        ]
    );
}

/// Kondic et al. Fig 9 on five seeds as registered: the one-bed case's physics on seeds
/// 1-5 of the Fig 2 bed (nothing else differs), with both claims read as trends over
/// ln g (depth and time of the maximum fall with g by 1 d and 5 tau_c per e-fold) and
/// both controls.
#[test]
fn kondic_fig9_five_seed_case_is_the_one_bed_case_on_seeds_1_to_5_with_two_trends() {
    use granval::case::impact2d::{Claim, ClaimQuantity, TrendDirection};
    let load = impact2d;
    let one = load("cases/release/kondic-fig9-gravity.toml");
    let five = load("cases/release/kondic-fig9-gravity-5seeds.toml");
    assert_eq!(five.seeds, [1, 2, 3, 4, 5]);
    assert_eq!(one.seed, 1);
    let values = |c: &granval::case::impact2d::Impact2dCase| {
        let mut x: Vec<f64> = c.variants.iter().map(|v| v.x).collect();
        x.dedup();
        x
    };
    assert_eq!(values(&one), values(&five));
    assert_eq!(five.variants.len(), 25);
    for v in &five.variants {
        let base = one
            .variants
            .iter()
            .find(|o| o.x == v.x)
            .expect("every value of the one-bed case");
        assert_eq!(v.speed, base.speed);
        assert_eq!(v.gravity, base.gravity);
        assert_eq!(
            serde_json::to_string(&v.grains).unwrap(),
            serde_json::to_string(&base.grains).unwrap()
        );
    }
    let trends: Vec<(ClaimQuantity, f64, bool, TrendDirection)> = five
        .claims
        .iter()
        .map(|k| match k {
            Claim::Trend {
                of,
                min_slope,
                log_x,
                direction,
                ..
            } => (*of, *min_slope, *log_x, *direction),
            other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(
        trends,
        vec![
            (ClaimQuantity::FinalDepth, 1.0, true, TrendDirection::Falls),
            (
                ClaimQuantity::TimeOfMaxDepth,
                5.0,
                true,
                TrendDirection::Falls
            )
        ]
    );
    assert_eq!(five.negative_controls.len(), 2);
}

/// Feng et al. Fig 3(b) as registered: four points differing only in mu_gg, on the
/// frictionless case's seeds, and three claims over them.
#[test]
fn fig3b_sweep_differs_only_in_mu_gg_and_carries_its_claims() {
    let cases = common::root().join("cases");
    let s = granval::experiments::suite::load(&cases, "release").unwrap();
    let names: Vec<&str> = s
        .claims
        .iter()
        .map(|c| c.name.as_str())
        .filter(|n| n.starts_with("Feng Fig 3(b)"))
        .collect();
    assert_eq!(names.len(), 3, "{names:?}");
    let pts: Vec<PenetrationCase> = ["0", "0.5", "1.1", "1.5"]
        .iter()
        .map(|m| penetration(&format!("cases/release/feng-fig3b-mugg-{m}.toml")))
        .collect();
    let base = &pts[1];
    for (c, mu) in pts.iter().zip([0.0, 0.5, 1.1, 1.5]) {
        assert_eq!(c.seed, 20261300);
        let t = &c.pairs;
        assert_eq!(t.friction[t.idx(0, 0)], mu);
        assert_eq!(t.friction[t.idx(0, 1)], 0.3);
        assert_eq!(t.rolling_friction[t.idx(0, 0)], 0.01);
        assert_eq!(c.intruder_radius, base.intruder_radius);
        assert_eq!(c.speed, base.speed);
        assert!(!c.negative_controls.is_empty());
    }
    assert_eq!(s.claims[0].cases.len(), 4);
}

/// `[[penetration_interactions]]`: the bed is prepared with `[[interactions]]` (the
/// settling case is the case without the override, down to its canonical hash, so both
/// penetrate the very same beds), the penetration uses the override, and a bad override
/// names its own field.
#[test]
fn penetration_interactions_change_the_intrusion_not_the_bed() {
    let base =
        std::fs::read_to_string(common::root().join("cases/release/feng-fig3b-mugg-0.5.toml"))
            .unwrap();
    let over = |e: &str| {
        format!(
            "{base}\n[[penetration_interactions]]\ntypes = [1, 1]\nrestitution = {e}\nfriction = 0.5\nrolling_friction = 0.01\n"
        )
    };
    let p = std::path::Path::new("x.toml");
    let plain = PenetrationCase::from_toml_str(&base, p).unwrap();
    let c = PenetrationCase::from_toml_str(&over("0.5"), p).unwrap();
    let ix = c.pairs.idx(0, 0);
    assert_eq!(c.pairs.restitution[ix], 0.5);
    assert_eq!(plain.pairs.restitution[ix], 0.8);
    assert_eq!(
        c.pairs.restitution[c.pairs.idx(0, 1)],
        0.8,
        "other pairs kept"
    );
    assert_ne!(c.canonical_hash(), plain.canonical_hash());
    assert_eq!(c.settling_case().canonical_hash(), plain.canonical_hash());
    let e = PenetrationCase::from_toml_str(&over("1.5"), p).unwrap_err();
    assert!(
        e.to_string()
            .contains("penetration_interactions[0].restitution"),
        "{e}"
    );
    let twice = format!(
        "{}\n[[penetration_interactions]]\ntypes = [1, 1]\nrestitution = 0.6\nfriction = 0.5\nrolling_friction = 0.01\n",
        over("0.5")
    );
    let e = PenetrationCase::from_toml_str(&twice, p).unwrap_err();
    assert!(e.to_string().contains("defined twice"), "{e}");
    // One LIGGGHTS deck cannot settle with one table and penetrate with another.
    assert!(granval::experiments::penetration::bed::liggghts_settle_deck(&c).is_err());
}

/// Feng et al. Table 3 as registered: the two slower points are the 2 cm/s point
/// (feng-fig3b-mugg-0.5) with only the speed changed, so all three penetrate the same
/// beds; the claim of no effect carries its tolerance and a control.
#[test]
fn table3_speed_points_differ_only_in_speed() {
    use granval::compare::sweep::SweepClaim;
    let at2 = penetration("cases/release/feng-fig3b-mugg-0.5.toml");
    for (v, speed) in [("0.5", 0.005), ("1", 0.01)] {
        let c = penetration(&format!("cases/release/feng-table3-speed-{v}.toml"));
        assert_eq!(c.speed, speed);
        let mut same = c.clone();
        same.speed = at2.speed;
        assert_eq!(same.canonical_hash(), at2.canonical_hash(), "{v} cm/s");
    }
    let s = granval::experiments::suite::load(&common::root().join("cases"), "release").unwrap();
    let claim = s
        .claims
        .iter()
        .find(|c| c.name.starts_with("Feng Table 3"))
        .expect("the speed claim");
    assert!(matches!(claim.claim, SweepClaim::Independent { max_rel, .. } if max_rel == 0.10));
    assert_eq!(claim.cases.len(), 3);
    assert_eq!(claim.controls.len(), 1);
}

/// Every recorded impact2d reference is sealed to its case's canonical hash: a field
/// added to the case schema must not move the hash of cases that do not use it (their
/// records would turn foreign).
#[test]
fn recorded_impact2d_seals_match_their_cases() {
    let mut seen = 0;
    for (dir, cases) in [
        ("reference/release/impact2d", "cases/release"),
        ("reference/impact2d", "cases/impact2d"),
    ] {
        let Ok(entries) = std::fs::read_dir(common::root().join(dir)) else {
            continue;
        };
        for e in entries.flatten() {
            let seal = e.path().join("seal.json");
            let Ok(text) = std::fs::read_to_string(&seal) else {
                continue;
            };
            let v: serde_json::Value = serde_json::from_str(&text).unwrap();
            let name = v["case_name"].as_str().unwrap();
            let case = common::root().join(cases).join(format!("{name}.toml"));
            let AnyCase::Impact2d(c) = AnyCase::load(&case).unwrap_or_else(|e| panic!("{e}"))
            else {
                panic!("{name}: not impact2d");
            };
            assert_eq!(
                c.canonical_hash().to_string(),
                v["case_sha256"].as_str().unwrap(),
                "{}",
                seal.display()
            );
            seen += 1;
        }
    }
    assert!(seen >= 4, "{seen} seals checked");
}

/// The Feng Fig 3(a), 3(d) and 3(g) points as registered: each is the Fig 3(b)
/// mu_gg = 0.5 point with only the stated edits (modulus and time step; grain diameter
/// and time step; the preparation's sliding friction), checked by making those edits to
/// that file's text and comparing canonical hashes; and the suite carries their claims.
#[test]
fn fig3a_3d_3g_points_differ_from_the_fig3b_point_only_as_registered() {
    use granval::compare::sweep::SweepClaim;
    let root = common::root();
    let base = std::fs::read_to_string(root.join("cases/release/feng-fig3b-mugg-0.5.toml"))
        .unwrap()
        .replace("beds = 3", "beds = 5");
    let p = std::path::Path::new("x.toml");
    let same_as = |rel: &str, edits: &[(&str, &str)]| {
        let mut text = base.clone();
        for (from, to) in edits {
            assert!(text.contains(from), "{rel}: `{from}` not in the base");
            text = text.replace(from, to);
        }
        let want = PenetrationCase::from_toml_str(&text, p).unwrap();
        let mut got = penetration(rel);
        got.name = want.name.clone();
        got.description = want.description.clone();
        got.source = want.source.clone();
        assert_eq!(got.canonical_hash(), want.canonical_hash(), "{rel}");
        got
    };
    same_as("cases/release/feng-fig3a-g-1.toml", &[]);
    for (rel, g, dt) in [
        ("cases/release/feng-fig3a-g-10.toml", "1.0e7", "9.5e-6"),
        ("cases/release/feng-fig3a-g-100.toml", "1.0e8", "3.0e-6"),
    ] {
        let c = same_as(
            rel,
            &[
                ("shear_modulus = 1.0e6", &format!("shear_modulus = {g}")),
                ("dt = 3.0e-5", &format!("dt = {dt}")),
            ],
        );
        // The paper's time-step rule: the same fraction of the Rayleigh time.
        assert!((c.dt / c.rayleigh_time - 0.1768).abs() < 0.001, "{rel}");
    }
    let d = same_as(
        "cases/release/feng-fig3d-dg-1.4.toml",
        &[
            ("value = 2.0e-3 }", "value = 1.4e-3 }"),
            ("dt = 3.0e-5", "dt = 2.1e-5"),
        ],
    );
    assert!((d.dt / d.rayleigh_time - 0.1768).abs() < 0.001);
    // The dense bed: settled with sliding friction 0.1 (longer settling allowed), then
    // penetrated with exactly the loose point's pair values.
    let loose = penetration("cases/release/feng-fig3b-mugg-0.5.toml");
    let dense = penetration("cases/release/feng-fig3g-psi-dense.toml");
    assert_eq!(dense.pairs, loose.pairs);
    let settle = dense.settle_pairs.as_ref().expect("a preparation table");
    assert_eq!(settle.friction[settle.idx(0, 0)], 0.1);
    assert_eq!(dense.seed, loose.seed);
    let s = granval::experiments::suite::load(&root.join("cases"), "release").unwrap();
    let claim = |prefix: &str| {
        s.claims
            .iter()
            .find(|c| c.name.starts_with(prefix))
            .unwrap_or_else(|| panic!("{prefix}: no such claim"))
    };
    for (prefix, n) in [("Feng Fig 3(a)", 3), ("Feng Fig 3(d)", 2)] {
        let c = claim(prefix);
        assert!(matches!(c.claim, SweepClaim::Independent { max_rel, .. } if max_rel == 0.10));
        assert_eq!((c.cases.len(), c.controls.len()), (n, 1), "{prefix}");
    }
    let g = claim("Feng Fig 3(g)");
    assert!(matches!(
        g.claim,
        SweepClaim::Increasing {
            min_step_se: None,
            quantity: granval::compare::sweep::Quantity::KPhi,
            ..
        }
    ));
    assert_eq!(g.controls.len(), 1);
}

/// Kondic et al. Fig 11 as registered: v = 1.0 on Fig 2 beds of two sizes (6000 and
/// 10 000 disks at L = 100 d), seeds 1-3 each; the first is the Fig 2 bed itself (the
/// same bed specification as `fig2-v0.7`, so the same prepared bed); the size claim at
/// 1 d, the engine gate control and the claim control (the second size at half speed);
/// K Fig 12's claim on the same runs (0.5, 0.05 d) with its frozen-floor controls.
#[test]
fn kondic_fig11_case_sweeps_two_sizes_of_three_seeds_from_the_fig2_bed() {
    use granval::case::impact2d::{Claim, Impact2dCase};
    use granval::physics::dem2d::impact::bed_spec;
    let load = impact2d;
    let c: Impact2dCase = load("cases/release/kondic-fig11-size.toml");
    let fig2 = load("cases/impact2d/fig2-v0.7.toml");
    let d = c.scales.d;
    let sizes: Vec<((usize, f64), Vec<u64>)> = c
        .size_groups()
        .into_iter()
        .map(|((n, l), g)| {
            (
                (n, l / d),
                g.iter().map(|&k| c.bed_of(&c.variants[k]).seed).collect(),
            )
        })
        .collect();
    assert_eq!(
        sizes,
        vec![
            ((6000, 100.0), vec![1, 2, 3]),
            ((10000, 100.0), vec![1, 2, 3])
        ]
    );
    let spec = |c: &Impact2dCase, v| serde_json::to_string(&bed_spec(c, &c.bed_of(v))).unwrap();
    assert_eq!(spec(&c, &c.variants[0]), spec(&fig2, &fig2.base));
    assert_eq!(c.variants[5].label, "count=10000,length=100,seed=3");
    assert!(
        c.variants
            .iter()
            .all(|v| (v.speed / c.scales.velocity() - 1.0).abs() < 1e-12)
    );
    assert_eq!(c.n_steps, fig2.n_steps);
    assert_eq!(c.final_window, fig2.final_window);
    assert!(matches!(
        c.claims[..],
        [
            Claim::SizeInsensitive { max_spread },
            Claim::InterfaceSteadies { max_ratio, min_amplitude }
        ] if max_spread == 1.0 && max_ratio == 0.5 && min_amplitude == 0.05
    ));
    assert!(c.track_interface);
    assert_eq!(c.tolerances.interface_rms, 0.1);
    let p: Vec<_> = c
        .negative_controls
        .iter()
        .map(|n| (n.perturbation, n.must_fail.clone()))
        .collect();
    assert_eq!(p.len(), 4);
    assert!(p[0].0.swap_friction_model && p[0].1 == vec![Gate::FinalDepth]);
    assert!(p[1].0.other_size_speed_factor == 0.5 && p[1].1 == vec![Gate::Claim]);
    // K Fig 12: the frozen floor, once for the claim and once for the s(t) check.
    let floor = granval::case::Perturbation {
        interface_frozen_floor: true,
        ..Default::default()
    };
    assert_eq!(p[2], (floor, vec![Gate::Claim]));
    assert_eq!(p[3], (floor, vec![Gate::InterfaceSeries]));
    let s = granval::experiments::suite::load(&common::root().join("cases"), "release").unwrap();
    assert!(
        s.cases
            .iter()
            .any(|e| e.path.ends_with("release/kondic-fig11-size.toml"))
    );
}

/// Kondic et al. Fig 12 at the paper's system as registered (before any W = 200 bed
/// existed; its settling time raised before any run of the claim): the Fig 11 case's
/// physics and rule at L = 100, W = 200 (20 000 disks), v =
/// 0.7, on seeds 1-3, with a 500 tau_c final window in a 1600 tau_c run; only the
/// interface claim (no size claim: one size); the friction-swap and two frozen-floor
/// controls; not in the release suite until it is recorded.
#[test]
fn kondic_fig12_case_is_the_fig11_recipe_at_w200_and_v07() {
    use granval::case::impact2d::Claim;
    use granval::physics::dem2d::impact::bed_spec;
    let fig11 = impact2d("cases/release/kondic-fig11-size.toml");
    let c = impact2d("cases/release/kondic-fig12-interface-w200.toml");
    let d = c.scales.d;
    let tau = c.scales.tau_c;
    let beds: Vec<(usize, f64, u64)> = c
        .variants
        .iter()
        .map(|v| {
            let b = c.bed_of(v);
            (b.count, b.length / d, b.seed)
        })
        .collect();
    assert_eq!(
        beds,
        vec![(20000, 100.0, 1), (20000, 100.0, 2), (20000, 100.0, 3)]
    );
    // Apart from the count and the time allowed to settle, every bed is poured and
    // settled as the Fig 11 (Fig 2) beds, to the same criterion (K's 1e-10 m g d). The
    // time allowed is 200 000 tau_c, raised from 30 000 after the seed-1 bed's kinetic
    // energy was traced (a decaying oscillation of the column, still falling at 30 000
    // tau_c; the case file and docs/release.md give the numbers); a bed that settles
    // earlier is the same bed whatever the cap.
    let spec = |c: &granval::case::impact2d::Impact2dCase, k: usize| {
        let mut b = c.bed_of(&c.variants[k]);
        b.count = 0;
        let mut spec = bed_spec(c, &b);
        spec.max_settle_time = 0.0;
        serde_json::to_string(&spec).unwrap()
    };
    assert_eq!(spec(&c, 0), spec(&fig11, 0));
    let cap = |c: &granval::case::impact2d::Impact2dCase| {
        bed_spec(c, &c.bed_of(&c.variants[0])).max_settle_time / c.scales.tau_c
    };
    assert!((cap(&fig11) - 30000.0).abs() < 1e-6, "{}", cap(&fig11));
    assert!((cap(&c) - 200000.0).abs() < 1e-6, "{}", cap(&c));
    assert!(
        c.variants
            .iter()
            .all(|v| (v.speed / c.scales.velocity() - 0.7).abs() < 1e-12)
    );
    for (v, w) in c.variants.iter().zip(&fig11.variants) {
        assert_eq!(v.gravity, w.gravity);
        assert_eq!(
            serde_json::to_string(&(&v.grains, &v.walls, &v.intruder)).unwrap(),
            serde_json::to_string(&(&w.grains, &w.walls, &w.intruder)).unwrap()
        );
    }
    assert_eq!(c.dt, fig11.dt);
    assert!((c.n_steps as f64 * c.dt / tau - 1600.0).abs() < 1e-9);
    assert!((c.final_window / tau - 500.0).abs() < 1e-9);
    assert!(matches!(
        c.claims[..],
        [Claim::InterfaceSteadies { max_ratio, min_amplitude }]
            if max_ratio == 0.5 && min_amplitude == 0.05
    ));
    assert!(c.track_interface);
    assert_eq!(c.tolerances.interface_rms, fig11.tolerances.interface_rms);
    let controls: Vec<_> = c
        .negative_controls
        .iter()
        .map(|n| (n.perturbation, n.must_fail.clone()))
        .collect();
    let fig11_controls: Vec<_> = fig11
        .negative_controls
        .iter()
        .filter(|n| n.perturbation.other_size_speed_factor == 1.0)
        .map(|n| (n.perturbation, n.must_fail.clone()))
        .collect();
    assert_eq!(controls.len(), 3);
    assert_eq!(controls, fig11_controls);
    let s = granval::experiments::suite::load(&common::root().join("cases"), "release").unwrap();
    assert!(
        !s.cases
            .iter()
            .any(|e| e.path.ends_with("release/kondic-fig12-interface-w200.toml")),
        "listed before it is recorded"
    );
}

/// Kondic et al. Figs 8(b) and 6 on five seeds as registered: each is fig2-speed.toml (the
/// Fig 2 bed) with only `seed = 1` turned into `seeds = [1, 2, 3, 4, 5]` (and, for Fig 6,
/// the friction sweep at v = 0.7 in place of the speed sweep), down to the canonical hash;
/// their claims and controls as the files say; and seeds 1-3 are exactly the W = 60 beds
/// of the Fig 11 case (same bed key and bed specification, so the bed cache shares them).
#[test]
fn kondic_five_seed_cases_are_the_fig2_bed_on_seeds_1_to_5_sharing_fig11_beds() {
    use granval::case::impact2d::{Claim, Impact2dCase};
    use granval::physics::dem2d::impact::bed_spec;
    let root = common::root();
    let load = impact2d;
    let fig2 = std::fs::read_to_string(root.join("cases/impact2d/fig2-speed.toml"))
        .unwrap()
        .replace("seed = 1\n", "seeds = [1, 2, 3, 4, 5]\n");
    let same_as = |rel: &str, edits: &[(&str, &str)]| {
        let mut text = fig2.clone();
        for (from, to) in edits {
            assert!(
                text.contains(from),
                "{rel}: `{from}` not in fig2-speed.toml"
            );
            text = text.replace(from, to);
        }
        let want = Impact2dCase::from_toml_str(&text, std::path::Path::new("x.toml")).unwrap();
        let got = load(rel);
        assert_eq!(got.canonical_hash(), want.canonical_hash(), "{rel}");
        assert_eq!(got.seeds, [1, 2, 3, 4, 5]);
        got
    };
    let speed = same_as("cases/release/kondic-fig8b-speed-5beds.toml", &[]);
    assert_eq!(speed.variants.len(), 30);
    assert_eq!(speed.variants[14].label, "speed=0.2,seed=5");
    assert!(
        matches!(speed.claims[..], [Claim::Linear { from, r2_min }] if from == 0.4 && r2_min == 0.9)
    );
    let friction = same_as(
        "cases/release/kondic-fig6-friction-5beds.toml",
        &[
            (
                "parameter = \"speed\"\nvalues = [0.05, 0.1, 0.2, 0.4, 0.7, 1.0]",
                "parameter = \"friction\"\nvalues = [\"static\", \"kinetic\"]",
            ),
            (
                "kind = \"linear\"\nfrom = 0.4\nr2_min = 0.9",
                "kind = \"increasing\"\nmin_step = 0.5",
            ),
        ],
    );
    let labels: Vec<&str> = friction
        .ensemble_groups()
        .iter()
        .map(|g| friction.variants[g.members[0]].label.as_str())
        .collect();
    assert_eq!(
        labels,
        ["friction=static,seed=1", "friction=kinetic,seed=1"]
    );
    assert!(matches!(friction.claims[..], [Claim::Increasing { min_step, .. }] if min_step == 0.5));
    for c in [&speed, &friction] {
        let p: Vec<_> = c
            .negative_controls
            .iter()
            .map(|n| (n.perturbation, n.must_fail.clone()))
            .collect();
        assert_eq!(p.len(), 2, "{}", c.name);
        assert!(p[0].0.swap_friction_model && p[0].1 == vec![Gate::FinalDepth]);
        assert!(p[1].0.sweep_ignored && p[1].1 == vec![Gate::Claim]);
    }
    // Seeds 1-3 are the Fig 11 case's W = 60 beds: same key, same specification.
    let fig11 = load("cases/release/kondic-fig11-size.toml");
    let spec = |c: &Impact2dCase, v| serde_json::to_string(&bed_spec(c, &c.bed_of(v))).unwrap();
    for c in [&speed, &friction] {
        for seed in 1..=3 {
            let mine = c
                .variants
                .iter()
                .find(|v| c.bed_of(v).seed == seed)
                .unwrap();
            let theirs = fig11
                .variants
                .iter()
                .find(|v| c.bed_of(v).seed == seed && fig11.bed_of(v).count == 6000)
                .unwrap();
            assert_eq!(
                c.bed_of(mine),
                fig11.bed_of(theirs),
                "{} seed {seed}",
                c.name
            );
            assert_eq!(
                spec(c, mine),
                spec(&fig11, theirs),
                "{} seed {seed}",
                c.name
            );
        }
    }
    let s = granval::experiments::suite::load(&root.join("cases"), "release").unwrap();
    for rel in [
        "release/kondic-fig8b-speed-5beds.toml",
        "release/kondic-fig6-friction-5beds.toml",
    ] {
        assert!(s.cases.iter().any(|e| e.path.ends_with(rel)), "{rel}");
    }
}

/// Every case of the release suite has a sealed LIGGGHTS/LAMMPS record under
/// `reference/release/<kind>/<case>/` made from this very case (its canonical hash), so
/// `check --suite release` without the engines re-runs only the native side. The two
/// paper-scale stress cases are the named exception: their LIGGGHTS runs take 1-2 h each
/// and were run live only (docs/release.md); a new case without a record fails here.
#[test]
fn every_release_case_has_a_record_of_its_own_version() {
    const LIVE_ONLY: [&str; 2] = ["feng-table2-mid", "feng-table4-mono-1bed"];
    let root = common::root();
    let suite = granval::experiments::suite::load(&root.join("cases"), "release").unwrap();
    let mut recorded = 0;
    for e in &suite.cases {
        let c = AnyCase::load(&e.path).unwrap_or_else(|err| panic!("{err}"));
        let (kind, hash) = match &c {
            AnyCase::Penetration(p) => ("penetration", p.canonical_hash()),
            AnyCase::Impact2d(p) => ("impact2d", p.canonical_hash()),
            AnyCase::Triaxial(p) => ("triaxial", p.canonical_hash()),
            AnyCase::Micro(p) => ("micro", p.canonical_hash()),
        };
        let seal = root
            .join("reference/release")
            .join(kind)
            .join(c.name())
            .join("seal.json");
        let stem = e.path.file_stem().unwrap().to_string_lossy().to_string();
        let Ok(text) = std::fs::read_to_string(&seal) else {
            assert!(
                LIVE_ONLY.contains(&stem.as_str()),
                "{}: no record at {}",
                e.path.display(),
                seal.display()
            );
            continue;
        };
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(
            v["case_sha256"].as_str().unwrap(),
            hash.to_string(),
            "{}: sealed for another version of the case",
            seal.display()
        );
        recorded += 1;
    }
    assert_eq!(recorded, suite.cases.len() - LIVE_ONLY.len());
}

/// docs/malt-trial.md (c): each triaxial case of a Feng friction material is
/// `triaxial-table2.toml` with only the registered edits: the grain pair's mu_gg and mu_r,
/// one confining pressure (4 kPa), three seeds (20261500-02) and a mu_gg control. Checked
/// on the parsed TOML values of both files, so no other setting (servo, compaction,
/// shear, analysis, the 1.5 deg gate, the walls) can drift from rule 5's protocol.
#[test]
fn malt_trial_triaxial_cases_differ_from_triaxial_table2_only_as_registered() {
    use granval::case::triaxial::TriaxialCase;
    let root = common::root();
    let read = |rel: &str| -> toml::Table {
        toml::from_str(&std::fs::read_to_string(root.join(rel)).unwrap()).unwrap()
    };
    let base = read("cases/release/triaxial-table2.toml");
    for (name, mu, mur, control) in [
        ("triaxial-mugg-0", 0.0, 0.01, 0.3),
        ("triaxial-mugg-1.5", 1.5, 0.01, 0.3),
        ("triaxial-mur-0.03", 0.5, 0.03, 0.1),
        ("triaxial-mugg-1.1", 1.1, 0.01, 0.3),
    ] {
        let rel = format!("cases/release/{name}.toml");
        let got = read(&rel);
        let mut want = base.clone();
        let case = want["case"].as_table_mut().unwrap();
        case.insert("name".into(), name.into());
        case.insert("description".into(), got["case"]["description"].clone());
        let grain_pair = want["interactions"].as_array_mut().unwrap()[0]
            .as_table_mut()
            .unwrap();
        assert_eq!(grain_pair["types"], toml::Value::from(vec![1, 1]));
        grain_pair.insert("friction".into(), mu.into());
        grain_pair.insert("rolling_friction".into(), mur.into());
        want["sample"].as_table_mut().unwrap().insert(
            "seeds".into(),
            vec![20261500_i64, 20261501, 20261502].into(),
        );
        want["shear"]
            .as_table_mut()
            .unwrap()
            .insert("confining_pressures".into(), vec![4000.0].into());
        let control_table: toml::Table = toml::from_str(&format!(
            "name = \"mu_gg = {control} instead of {mu:?}\"\nmust_fail = [\"phi\"]\n\
             perturbation = {{ pair_friction = {{ types = [1, 1], value = {control:?} }} }}"
        ))
        .unwrap();
        want.insert(
            "negative_control".into(),
            toml::Value::Array(vec![toml::Value::Table(control_table)]),
        );
        assert_eq!(
            got, want,
            "{rel}: differs from triaxial-table2 beyond the registered edits"
        );
        // And it loads as a case of that material and design.
        let c = TriaxialCase::load(&root.join(&rel)).unwrap_or_else(|e| panic!("{e}"));
        let k = c.pairs.idx(c.grain_type, c.grain_type);
        assert_eq!(
            (c.pairs.friction[k], c.pairs.rolling_friction[k]),
            (mu, mur)
        );
        assert_eq!(c.confining_pressures, vec![4000.0]);
        assert_eq!(c.seeds, vec![20261500, 20261501, 20261502]);
        assert_eq!(c.tolerances.phi_abs_deg, 1.5);
    }
}
