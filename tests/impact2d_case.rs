//! impact2d case files: the shipped cases load, paper units convert to SI as the
//! module documents, and bad input names file, field, value and reason.

mod common;

use granval::case::impact2d::{Friction, Impact2dCase};
use std::path::Path;

fn ci_text() -> String {
    std::fs::read_to_string(common::root().join("cases/impact2d/ci.toml")).unwrap()
}

fn err(text: &str) -> String {
    Impact2dCase::from_toml_str(text, Path::new("bad.toml"))
        .unwrap_err()
        .to_string()
}

/// Each edit (from, to, field, why) of `base`, made alone, is refused with an error
/// naming the file, the field and the reason.
fn assert_rejected(base: &str, edits: &[(&str, &str, &str, &str)]) {
    for (from, to, field, why) in edits {
        assert!(base.contains(from), "{from}");
        let e = err(&base.replacen(from, to, 1));
        assert!(
            e.contains("bad.toml") && e.contains(field) && e.contains(why),
            "{from} -> {to}: {e}"
        );
    }
}

#[test]
fn shipped_cases_load() {
    let cases = common::root().join("cases");
    let suite = granval::experiments::suite::load(&cases, "impact2d").unwrap();
    for e in &suite.cases {
        Impact2dCase::load(&e.path).unwrap_or_else(|e| panic!("{e}"));
    }
    // The suite takes every impact2d case file.
    let files = std::fs::read_dir(cases.join("impact2d"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "toml")
        })
        .count();
    assert_eq!(suite.cases.len(), files);
}

#[test]
fn paper_units_convert_to_si() {
    let c = Impact2dCase::from_toml_str(&ci_text(), Path::new("ci.toml")).unwrap();
    let s = c.scales;
    // tau_c = pi sqrt(d / (2 g k_n)), k = k_n m g / d (K Sec. II).
    let tau = std::f64::consts::PI * (0.004f64 / (2.0 * 9.81 * 4000.0)).sqrt();
    assert!((s.tau_c / tau - 1.0).abs() < 1e-14);
    let co = c.variants[0].grains.coeffs(&s);
    assert!((co.kn - 4000.0 * 1e-4 * 9.81 / 0.004).abs() < 1e-9);
    assert_eq!(co.kt, 0.0, "kinetic friction is k_t = 0");
    assert!((co.gamma_n - (-2.0 * 0.5f64.ln() / tau)).abs() < 1e-9);
    assert_eq!(co.gamma_t, 0.5 * co.gamma_n);
    assert!((c.variants[0].speed - 0.7 * 0.004 / tau).abs() < 1e-12);
    assert!((c.dt - 0.04 * tau).abs() < 1e-18);
    let st = granval::case::impact2d::Material2d {
        friction: Friction::Static,
        ..c.variants[0].grains
    }
    .coeffs(&s);
    assert_eq!(st.kt, 0.8 * st.kn);
    // Walls: K's mu 0.9, e_n 0.1.
    let w = c.variants[0].walls.coeffs(&s);
    assert_eq!(w.mu, 0.9);
    assert!((w.gamma_n - (-2.0 * 0.1f64.ln() / tau)).abs() < 1e-9);
}

#[test]
fn bad_inputs_name_file_field_value_and_reason() {
    let t = ci_text();
    assert_rejected(
        &t,
        &[
            ("\ne_n = 0.5", "\ne_n = 1.5", "grains.e_n", "(0, 1]"),
            ("k_n = 4000.0", "k_n = -1.0", "grains.k_n", "> 0"),
            ("dt = 0.04 ", "dt = 0.5 ", "simulation.dt", "tau_c/10"),
            (
                "polydispersity = 0.2",
                "polydispersity = 0.7",
                "bed.polydispersity",
                "[0, 0.5)",
            ),
            (
                "final_window = 200.0",
                "final_window = 5000.0",
                "analysis.final_window",
                "shorter",
            ),
            (
                "shape = \"disk\"",
                "shape = \"ellipse\"",
                "intruder.a",
                "semi-axes",
            ),
            (
                "energy_every = 1000",
                "energy_every = 1010",
                "simulation.energy_every",
                "multiple",
            ),
        ],
    );
    let e = err(&t.replace("friction = \"kinetic\"", "friction = \"sticky\""));
    assert!(e.contains("bad.toml") && e.contains("sticky"), "{e}");
    let e = err(&(t.clone() + "\n[sweep]\nparameter = \"colour\"\nvalues = [1, 2]\n"));
    assert!(e.contains("sweep.parameter") && e.contains("colour"), "{e}");
    let e = err(&(t.clone()
        + "\n[sweep]\nparameter = \"speed\"\nvalues = [0.4, 0.7]\n[claim]\nkind = \"linear\"\nfrom = 0.4\nr2_min = 0.9\n"));
    assert!(
        e.contains("claim.from") && e.contains("fewer than 3"),
        "{e}"
    );
    let e = err(&t.replace("[analysis]", "[analysis]\nwindow = 3.0"));
    assert!(e.contains("bad.toml") && e.contains("window"), "{e}");
    let e = err(&(t.clone() + "\n[claim]\nkind = \"increasing\"\n"));
    assert!(e.contains("claim") && e.contains("sweep"), "{e}");
    // A control that ignores a sweep the case does not have perturbs nothing.
    let e = err(&(t.clone()
        + "\n[[negative_control]]\nname = \"n\"\nmust_fail = [\"claim\"]\nperturbation = { sweep_ignored = true }\n"));
    assert!(e.contains("sweep_ignored") && e.contains("[sweep]"), "{e}");
    // energy_lost is read at a time, which must lie inside the run.
    let sweep = "\n[sweep]\nparameter = \"mu\"\nvalues = [0.0, 0.5]\n";
    let e = err(&(t.clone() + sweep + "[claim]\nkind = \"increasing\"\nof = \"energy_lost\"\n"));
    assert!(e.contains("claim.at") && e.contains("missing"), "{e}");
    let e = err(&(t.clone()
        + sweep
        + "[claim]\nkind = \"increasing\"\nof = \"energy_lost\"\nat = 1e9\n"));
    assert!(e.contains("claim.at") && e.contains("after the end"), "{e}");
}

/// The CLI turns bad impact2d input into exit code 2 with file, field and reason,
/// before any simulation starts.
#[test]
fn cli_rejects_bad_impact2d_input_with_exit_code_2() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, ci_text().replacen("\ne_n = 0.5", "\ne_n = 1.5", 1)).unwrap();
    let exe = env!("CARGO_BIN_EXE_granval");
    let out = std::process::Command::new(exe)
        .args([
            "run",
            bad.to_str().unwrap(),
            "--out",
            dir.path().join("o").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("bad.toml") && err.contains("grains.e_n") && err.contains("1.5"),
        "{err}"
    );
    let ci = common::root().join("cases/impact2d/ci.toml");
    let out = std::process::Command::new(exe)
        .args([
            "run",
            ci.to_str().unwrap(),
            "--engine",
            "liggghts",
            "--out",
            dir.path().join("p").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("2D"));
}

/// What `granval check --suite ci` gates on K's Fig 2 bed (the checks of the former
/// tests/impact2d_fig2.rs): six speeds, each cross-checked against LAMMPS, and the
/// linearity claim for v >= 0.4 evaluated in each engine on at least three of them.
#[test]
fn fig2_speed_case_sweeps_six_speeds_with_the_linearity_claim() {
    let path = common::root().join("cases/impact2d/fig2-speed.toml");
    let c = Impact2dCase::load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(c.variants.len(), 6, "one final-depth cross-check per speed");
    let [granval::case::impact2d::Claim::Linear { from, r2_min }] = c.claims[..] else {
        panic!("fig2-speed.toml must claim linearity: {:?}", c.claims)
    };
    assert_eq!(from, 0.4);
    assert!(r2_min >= 0.9, "{r2_min}");
    assert!(
        c.variants.iter().filter(|v| v.x >= from).count() >= 3,
        "a line needs 3 speeds >= {from}"
    );
    let suite = granval::experiments::suite::load(&common::root().join("cases"), "ci").unwrap();
    for f in ["impact2d/fig2-speed.toml", "impact2d/fig2-v0.7.toml"] {
        assert!(suite.cases.iter().any(|e| e.path.ends_with(f)), "{f}");
    }
}

/// Kondic Figs 21-27: the friction_mu sweep, `[fields]` as steps, the new claims, and
/// their mistakes named by file, field, value and reason.
#[test]
fn field_and_force_claims_parse_and_name_their_mistakes() {
    let t = ci_text()
        .replace("duration = 1000.0", "duration = 50.0")
        .replace("final_window = 200.0", "final_window = 10.0");
    let sweep = "\n[sweep]\nparameter = \"friction_mu\"\nvalues = [{ mu = 0.0, friction = \"kinetic\" }, { mu = 0.5, friction = \"static\" }]\n";
    let fields = "\n[fields]\nnetwork_times = [12.0, 24.0]\naffine_time = 24.0\naffine_dt = 1.0\naffine_radius = 2.5\n";
    let claim = "[[claim]]\nkind = \"field_order\"\nquantity = \"d2min\"\nlarger = \"mu=0,kinetic\"\nsmaller = \"mu=0.5,static\"\nmin_ratio = 1.1\n";
    let ok = format!("{t}{fields}{sweep}{claim}");
    let c = Impact2dCase::from_toml_str(&ok, Path::new("ok.toml")).unwrap();
    assert_eq!(c.variants.len(), 2);
    assert_eq!(c.variants[0].label, "mu=0,kinetic");
    assert_eq!(c.variants[1].grains.friction, Friction::Static);
    assert_eq!(c.variants[1].grains.mu, 0.5);
    let f = c.fields.as_ref().unwrap();
    // dt = 0.04 tau_c: 12 tau_c = step 300, 24 = 600, 24 - 1 = 575.
    assert_eq!(f.network_steps, vec![300, 600]);
    assert_eq!(f.affine.map(|a| (a.0, a.1)), Some((575, 600)));
    assert_eq!(f.position_steps(), vec![300, 575, 600]);
    assert_rejected(
        &ok,
        &[
            (
                "larger = \"mu=0,kinetic\"",
                "larger = \"mu=9\"",
                "claim.larger",
                "no such variant",
            ),
            (
                "network_times = [12.0, 24.0]",
                "network_times = [12.01]",
                "fields.network_times[0]",
                "whole number",
            ),
            (
                "network_times = [12.0, 24.0]",
                "network_times = [24.0, 12.0]",
                "fields.network_times",
                "rise",
            ),
            (
                "affine_time = 24.0",
                "affine_time = 99.0",
                "fields.affine_time",
                "after the end",
            ),
            ("affine_dt = 1.0\n", "", "fields", "needs all three"),
            (
                "min_ratio = 1.1",
                "min_ratio = 1.1\nmax_ratio = 1.0",
                "claim.max_ratio",
                "exceed",
            ),
            (
                "mu = 0.0, friction = \"kinetic\"",
                "mu = 0.0, friction = \"sticky\"",
                "sweep.values[0]",
                "friction_mu takes",
            ),
        ],
    );
    // A B0 claim without network times.
    let e = err(&ok
        .replace("network_times = [12.0, 24.0]\n", "")
        .replace("\"d2min\"", "\"b0_normal\""));
    assert!(
        e.contains("claim.quantity") && e.contains("network_times"),
        "{e}"
    );
    // Force claims: a bin must hold two samples (output_every 25 x 0.04 = 1 tau_c).
    let force =
        "[[claim]]\nkind = \"force_impulsive\"\nbin = 1.0\npeak_within = 5.0\nhalf_within = 10.0\n";
    Impact2dCase::from_toml_str(
        &format!("{t}{sweep}{force}").replace("output_every = 25", "output_every = 5"),
        Path::new("ok.toml"),
    )
    .unwrap();
    let e = err(&format!("{t}{sweep}{force}"));
    assert!(
        e.contains("claim.bin") && e.contains("2 intruder samples"),
        "{e}"
    );
    // The release cases say what their headers register.
    for rel in [
        "cases/release/kondic-fig21-force.toml",
        "cases/release/kondic-fig22-25-poly-fields.toml",
        "cases/release/kondic-fig26-27-hex-fields.toml",
    ] {
        let c = Impact2dCase::load(&common::root().join(rel)).unwrap_or_else(|e| panic!("{e}"));
        assert!(
            !c.claims.is_empty() && c.negative_controls.len() == 2,
            "{rel}"
        );
        assert_eq!(c.tolerances.field_rel, 0.05);
    }
}

/// K Fig 11's `bed` sweep and `size_insensitive` claim: each value is its own bed (count,
/// length, seed; the rest of `[bed]` kept), the case hash sees them, and bad values,
/// claims and controls name their field.
#[test]
fn bed_sweep_and_size_claim_parse_and_name_their_mistakes() {
    use granval::case::impact2d::{BedSize, Claim};
    let t = ci_text();
    let d = 0.004;
    let sweep = "\n[sweep]\nparameter = \"bed\"\nvalues = [{ count = 450, length = 30, seed = 7 }, { count = 450, length = 30.0, seed = 8 }, { count = 600, length = 40, seed = 7 }, { count = 600, length = 40, seed = 8 }]\n";
    let claim = "[claim]\nkind = \"size_insensitive\"\nmax_spread = 1.0\n";
    let control = "[[negative_control]]\nname = \"slow\"\nmust_fail = [\"claim\"]\nperturbation = { other_size_speed_factor = 0.5 }\n";
    let ok = format!("{t}{sweep}{claim}{control}");
    let c = Impact2dCase::from_toml_str(&ok, Path::new("ok.toml")).unwrap();
    let labels: Vec<&str> = c.variants.iter().map(|v| v.label.as_str()).collect();
    assert_eq!(
        labels,
        [
            "count=450,length=30,seed=7",
            "count=450,length=30,seed=8",
            "count=600,length=40,seed=7",
            "count=600,length=40,seed=8"
        ]
    );
    assert_eq!(
        c.variants[2].bed,
        Some(BedSize {
            count: 600,
            length: 40.0 * d,
            seed: 7
        })
    );
    // The first variant's bed is `[bed]`'s own (count 450, L 30, seed 7).
    assert_eq!(c.bed_of(&c.variants[0]), c.bed_of(&c.base));
    assert!(c.variants.iter().all(|v| v.speed == c.base.speed));
    let groups: Vec<(usize, Vec<usize>)> = c
        .size_groups()
        .into_iter()
        .map(|((n, _), g)| (n, g))
        .collect();
    assert_eq!(groups, vec![(450, vec![0, 1]), (600, vec![2, 3])]);
    assert!(!c.is_other_size(&c.variants[1]) && c.is_other_size(&c.variants[3]));
    assert!(matches!(c.claims[0], Claim::SizeInsensitive { max_spread } if max_spread == 1.0));
    assert_eq!(
        c.negative_controls[1].perturbation.other_size_speed_factor,
        0.5
    );
    // Another seed is another case.
    let other = Impact2dCase::from_toml_str(
        &ok.replacen("seed = 8 }", "seed = 9 }", 1),
        Path::new("ok.toml"),
    )
    .unwrap();
    assert_ne!(other.canonical_hash(), c.canonical_hash());
    assert_rejected(
        &ok,
        &[
            (
                "count = 600, length = 40, seed = 7",
                "count = 0, length = 40, seed = 7",
                "sweep.values[2].count",
                "whole number >= 1",
            ),
            (
                "count = 600, length = 40, seed = 7",
                "count = 6.5, length = 40, seed = 7",
                "sweep.values[2].count",
                "whole number",
            ),
            (
                "count = 600, length = 40, seed = 7",
                "count = 600, length = 4, seed = 7",
                "sweep.values[2].length",
                ">= 5 d",
            ),
            (
                "count = 600, length = 40, seed = 7",
                "count = 600, length = 6, seed = 7",
                "sweep.values[2].length",
                "narrower than 0.8 L",
            ),
            (
                "count = 600, length = 40, seed = 7",
                "count = 600, length = \"x\", seed = 7",
                "sweep.values[2].length",
                "number",
            ),
            (
                "count = 600, length = 40, seed = 7",
                "count = 600, length = 40, seed = -1",
                "sweep.values[2].seed",
                "whole number >= 0",
            ),
            (
                "count = 600, length = 40, seed = 7",
                "count = 600, length = 40",
                "sweep.values[2].seed",
                "missing",
            ),
            (
                "count = 600, length = 40, seed = 7",
                "count = 600, length = 40, seed = 7, packing = \"hexagonal\"",
                "sweep.values[2].packing",
                "unknown field",
            ),
            (
                "{ count = 600, length = 40, seed = 7 }",
                "600",
                "sweep.values[2]",
                "tables",
            ),
            (
                "count = 600, length = 40, seed = 8",
                "count = 600, length = 40.0, seed = 7",
                "sweep.values[3]",
                "repeated",
            ),
            // One size: nothing to compare.
            (
                "count = 600, length = 40, seed = 7 }, { count = 600, length = 40, seed = 8",
                "count = 450, length = 30, seed = 9 }, { count = 450, length = 30, seed = 10",
                "claim.kind",
                "at least 2 sizes",
            ),
            // A size with one realization.
            (
                "count = 600, length = 40, seed = 8",
                "count = 700, length = 40, seed = 8",
                "claim.kind",
                "every size needs at least 2",
            ),
            (
                "max_spread = 1.0",
                "max_spread = 0.0",
                "claim.max_spread",
                "> 0",
            ),
            (
                "other_size_speed_factor = 0.5",
                "other_size_speed_factor = 1.0",
                "negative_control[1].perturbation.other_size_speed_factor",
                "not 1",
            ),
            (
                "other_size_speed_factor = 0.5",
                "other_size_speed_factor = -2.0",
                "negative_control[1].perturbation.other_size_speed_factor",
                "> 0",
            ),
            (
                "other_size_speed_factor = 0.5",
                "sweep_ignored = true",
                "negative_control[1].perturbation.sweep_ignored",
                "bed sweep",
            ),
            (
                "other_size_speed_factor = 0.5",
                "packing_ignored = true",
                "negative_control[1].perturbation.packing_ignored",
                "sweep] of `packing`",
            ),
        ],
    );
    // `packing_ignored` is the packing sweep's control.
    let packing = "\n[sweep]\nparameter = \"packing\"\nvalues = [\"hexagonal\", \"random\"]\n";
    let ignored = "[[negative_control]]\nname = \"one bed\"\nmust_fail = [\"claim\"]\nperturbation = { packing_ignored = true }\n";
    let c = Impact2dCase::from_toml_str(&format!("{t}{packing}{ignored}"), Path::new("ok.toml"))
        .unwrap();
    assert!(
        c.negative_controls
            .last()
            .unwrap()
            .perturbation
            .packing_ignored
    );
    // The claim and the slowing control need a bed sweep.
    let speed = "\n[sweep]\nparameter = \"speed\"\nvalues = [0.4, 0.7]\n";
    let e = err(&format!("{t}{speed}{claim}"));
    assert!(
        e.contains("claim.kind") && e.contains("sweep] of `bed`"),
        "{e}"
    );
    let e = err(&format!("{t}{speed}{control}"));
    assert!(
        e.contains("other_size_speed_factor") && e.contains("`bed`"),
        "{e}"
    );
    // A hexagonal bed needs a whole number of d in every variant's period.
    let e = err(&ok
        .replace("packing = \"random\"", "packing = \"hexagonal\"")
        .replace("length = 40,", "length = 40.5,"));
    assert!(
        e.contains("sweep.values[2].length") && e.contains("whole number of d"),
        "{e}"
    );
}

/// `[bed] seeds`: every sweep value runs once per seed on that seed's bed (`[bed]`'s
/// count and length), labelled `VALUE,seed=S` with x the swept value; the case hash sees
/// the seeds; bad ensembles name their field, value and reason.
#[test]
fn seed_ensemble_expands_every_value_per_seed_and_names_its_mistakes() {
    use granval::case::impact2d::{BedSize, EnsembleGroup};
    let t = ci_text();
    assert!(t.contains("seed = 7\n"));
    let d = 0.004;
    let ens = t.replace("seed = 7\n", "seeds = [7, 8, 9]\n");
    let sweep = "\n[sweep]\nparameter = \"friction\"\nvalues = [\"static\", \"kinetic\"]\n";
    let claim = "[claim]\nkind = \"increasing\"\nmin_step = 0.5\n";
    let control = "[[negative_control]]\nname = \"ignored\"\nmust_fail = [\"claim\"]\nperturbation = { sweep_ignored = true }\n";
    let ok = format!("{ens}{sweep}{claim}{control}");
    let c = Impact2dCase::from_toml_str(&ok, Path::new("ok.toml")).unwrap();
    assert!(c.is_ensemble());
    assert_eq!(c.seeds, [7, 8, 9]);
    let labels: Vec<(&str, f64)> = c.variants.iter().map(|v| (v.label.as_str(), v.x)).collect();
    assert_eq!(
        labels,
        [
            ("friction=static,seed=7", 0.0),
            ("friction=static,seed=8", 0.0),
            ("friction=static,seed=9", 0.0),
            ("friction=kinetic,seed=7", 1.0),
            ("friction=kinetic,seed=8", 1.0),
            ("friction=kinetic,seed=9", 1.0)
        ]
    );
    for (k, v) in c.variants.iter().enumerate() {
        assert_eq!(
            v.bed,
            Some(BedSize {
                count: 450,
                length: 30.0 * d,
                seed: 7 + k as u64 % 3
            })
        );
        let want = if k < 3 {
            Friction::Static
        } else {
            Friction::Kinetic
        };
        assert_eq!(v.grains.friction, want, "{}", v.label);
    }
    // Seed 7's bed is the one `seed = 7` gives: the same bed key as the single-bed case.
    let single =
        Impact2dCase::from_toml_str(&format!("{t}{sweep}{claim}"), Path::new("s.toml")).unwrap();
    assert_eq!(c.bed_of(&c.variants[3]), single.bed_of(&single.variants[1]));
    assert_eq!(
        c.ensemble_groups(),
        vec![
            EnsembleGroup {
                value: "friction=static".into(),
                x: 0.0,
                members: vec![0, 1, 2]
            },
            EnsembleGroup {
                value: "friction=kinetic".into(),
                x: 1.0,
                members: vec![3, 4, 5]
            }
        ]
    );
    assert!(single.ensemble_groups().is_empty() && !single.is_ensemble());
    // The seeds are part of what the runs depend on.
    assert_ne!(c.canonical_hash(), single.canonical_hash());
    let other = Impact2dCase::from_toml_str(
        &ok.replace("seeds = [7, 8, 9]", "seeds = [7, 8, 10]"),
        Path::new("ok.toml"),
    )
    .unwrap();
    assert_ne!(other.canonical_hash(), c.canonical_hash());
    // Without a sweep: the case itself once per seed.
    let plain = Impact2dCase::from_toml_str(&ens, Path::new("p.toml")).unwrap();
    let labels: Vec<&str> = plain.variants.iter().map(|v| v.label.as_str()).collect();
    assert_eq!(labels, ["seed=7", "seed=8", "seed=9"]);
    assert_eq!(plain.ensemble_groups()[0].value, "base");
    // A linear claim counts sweep values, not runs: 2 speeds >= from on 3 seeds is 2.
    let lin = format!(
        "{ens}\n[sweep]\nparameter = \"speed\"\nvalues = [0.2, 0.4, 0.7]\n[claim]\nkind = \"linear\"\nfrom = 0.4\nr2_min = 0.9\n"
    );
    let e = err(&lin);
    assert!(
        e.contains("claim.from") && e.contains("only 2 sweep values"),
        "{e}"
    );
    let bed_sweep = "\n[sweep]\nparameter = \"bed\"\nvalues = [{ count = 450, length = 30, seed = 1 }, { count = 450, length = 30, seed = 2 }]\n";
    let e = err(&format!("{ens}{bed_sweep}"));
    assert!(
        e.contains("bad.toml") && e.contains("bed.seeds") && e.contains("`bed` sweep"),
        "{e}"
    );
    assert_rejected(
        &ok,
        &[
            (
                "seeds = [7, 8, 9]",
                "seed = 7\nseeds = [7, 8, 9]",
                "bed.seeds",
                "not both",
            ),
            ("seeds = [7, 8, 9]", "", "bed.seed", "seed ensemble"),
            (
                "seeds = [7, 8, 9]",
                "seeds = [7]",
                "bed.seeds",
                "at least 2 seeds",
            ),
            (
                "seeds = [7, 8, 9]",
                "seeds = []",
                "bed.seeds",
                "at least 2 seeds",
            ),
            (
                "seeds = [7, 8, 9]",
                "seeds = [7, 8, 7]",
                "bed.seeds[2]",
                "repeated seed",
            ),
            (
                "seeds = [7, 8, 9]",
                "seeds = [7, -8, 9]",
                "bed.seeds[1]",
                "whole number >= 0",
            ),
            (
                "seeds = [7, 8, 9]",
                "seeds = [7, 8.5, 9]",
                "bed.seeds[1]",
                "whole number >= 0",
            ),
            (
                "kind = \"increasing\"\nmin_step = 0.5",
                "kind = \"energy_non_increasing\"\nmax_rise = 0.01",
                "claim.kind",
                "not defined on a seed ensemble",
            ),
            (
                "sweep_ignored = true",
                "other_size_speed_factor = 0.5",
                "negative_control[1].perturbation.other_size_speed_factor",
                "`bed`",
            ),
        ],
    );
}

/// K Fig 12's claim and its control: the claim turns on interface tracking (and so
/// moves the case hash), `[analysis] track_interface` does so without a claim, and bad
/// parameters, a frozen-floor control without tracking and an unknown or misplaced
/// perturbation name their field.
#[test]
fn interface_claim_and_frozen_floor_control_parse_and_name_their_mistakes() {
    use granval::case::Gate;
    use granval::case::impact2d::Claim;
    let t = ci_text();
    let sweep = "\n[sweep]\nparameter = \"speed\"\nvalues = [0.7, 1.0]\n";
    let claim = "[claim]\nkind = \"interface_steadies\"\nmax_ratio = 0.5\nmin_amplitude = 0.05\n";
    let control = "[[negative_control]]\nname = \"floor\"\nmust_fail = [\"claim\"]\nperturbation = { interface_frozen_floor = true }\n[[negative_control]]\nname = \"floor, s(t)\"\nmust_fail = [\"interface_series\"]\nperturbation = { interface_frozen_floor = true }\n";
    let ok = format!("{t}{sweep}{claim}{control}");
    let c = Impact2dCase::from_toml_str(&ok, Path::new("ok.toml")).unwrap();
    assert!(c.track_interface);
    assert!(matches!(
        c.claims[..],
        [Claim::InterfaceSteadies { max_ratio, min_amplitude }] if max_ratio == 0.5 && min_amplitude == 0.05
    ));
    // ci.toml's own control comes first.
    assert!(c.negative_controls[1].perturbation.interface_frozen_floor);
    assert_eq!(
        c.negative_controls[2].must_fail,
        vec![Gate::InterfaceSeries]
    );
    assert_eq!(c.tolerances.interface_rms, 0.1);
    // Tracking is part of what the runs depend on; the claim's numbers are not.
    let plain = Impact2dCase::from_toml_str(&format!("{t}{sweep}"), Path::new("ok.toml")).unwrap();
    assert!(!plain.track_interface);
    assert_ne!(plain.canonical_hash(), c.canonical_hash());
    let other =
        Impact2dCase::from_toml_str(&ok.replace("0.5\nmin", "0.3\nmin"), Path::new("ok.toml"))
            .unwrap();
    assert_eq!(other.canonical_hash(), c.canonical_hash());
    let opt = Impact2dCase::from_toml_str(
        &format!("{t}{sweep}").replace(
            "final_window = 200.0",
            "final_window = 200.0\ntrack_interface = true",
        ),
        Path::new("ok.toml"),
    )
    .unwrap();
    assert!(opt.track_interface && opt.claims.is_empty());
    assert_eq!(opt.canonical_hash(), c.canonical_hash());
    assert_rejected(
        &ok,
        &[
            (
                "max_ratio = 0.5",
                "max_ratio = 1.0",
                "claim.max_ratio",
                "must be < 1",
            ),
            (
                "max_ratio = 0.5",
                "max_ratio = 0.0",
                "claim.max_ratio",
                "> 0",
            ),
            (
                "min_amplitude = 0.05",
                "min_amplitude = -0.05",
                "claim.min_amplitude",
                "> 0",
            ),
        ],
    );
    let e = err(&format!(
        "{t}{sweep}{}",
        control.replace("\"claim\"", "\"final_depth\"")
    ));
    assert!(
        e.contains("negative_control[1].perturbation.interface_frozen_floor")
            && e.contains("does not track"),
        "{e}"
    );
    let e = err(&format!("{ok}[compare]\ninterface_rms = 0.0\n"));
    assert!(
        e.contains("compare.interface_rms") && e.contains("> 0"),
        "{e}"
    );
    // Only impact2d cases have an interface to freeze.
    let micro = std::fs::read_to_string(common::root().join("cases/micro/head-on-e05.toml"))
        .unwrap()
        + "\n[[negative_control]]\nname = \"x\"\nmust_fail = [\"position\"]\nperturbation = { interface_frozen_floor = true }\n";
    let e = granval::case::Case::from_toml_str(&micro, Path::new("bad.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("interface_frozen_floor") && e.contains("only impact2d"),
        "{e}"
    );
}

/// A malformed claim is named with its index and serde's reason (a missing or unknown
/// field, a kind that does not exist), not as a failed match of "one or many".
#[test]
fn malformed_claims_name_the_claim_and_the_field() {
    let t = ci_text();
    let sweep = "\n[sweep]\nparameter = \"speed\"\nvalues = [0.4, 0.7, 1.0]\n";
    let one = format!("{t}{sweep}[claim]\nkind = \"increasing\"\nmin_step = 0.5\n");
    let many = format!(
        "{t}{sweep}[[claim]]\nkind = \"increasing\"\nmin_step = 0.5\n[[claim]]\nkind = \"linear\"\nfrom = 0.4\nr2_min = 0.9\n"
    );
    assert_eq!(
        Impact2dCase::from_toml_str(&many, Path::new("ok.toml"))
            .unwrap()
            .claims
            .len(),
        2
    );
    assert_rejected(
        &one,
        &[
            (
                "kind = \"increasing\"\nmin_step = 0.5\n",
                "kind = \"linear\"\nr2_min = 0.9\n",
                "claim",
                "missing field `from`",
            ),
            (
                "min_step = 0.5\n",
                "min_step = 0.5\nslope = 1\n",
                "claim",
                "unknown field `slope`",
            ),
            (
                "\"increasing\"",
                "\"rising\"",
                "claim",
                "unknown variant `rising`",
            ),
        ],
    );
    assert_rejected(
        &many,
        &[("r2_min = 0.9\n", "", "claim[1]", "missing field `r2_min`")],
    );
}

/// `[bed] settled_with = "variant"` (K Figs 22-25 on five seeds, each friction model on
/// beds settled with its own law): the static variants get beds settled with static
/// friction (k_t = 0.8 k_n), the kinetic ones the Fig 2 beds of the five-seed Fig 6
/// case but for the time cap and the settling hold (both beds' criteria held 200
/// tau_c, so settled anew); the field
/// changes the canonical hash only when set; and every misuse is refused with the
/// field, the value and the reason.
#[test]
fn beds_settled_per_variant_follow_each_variants_grains() {
    use granval::experiments::bed_cache;
    use granval::physics::dem2d::impact::bed_spec;
    let root = common::root().join("cases/release");
    let own = Impact2dCase::load(&root.join("kondic-fig22-25-poly-fields-5seeds.toml")).unwrap();
    let fig6 = Impact2dCase::load(&root.join("kondic-fig6-friction-5beds.toml")).unwrap();
    assert!(own.beds_per_variant && !fig6.beds_per_variant);
    let name = |c: &Impact2dCase, label: &str| {
        let v = c.variants.iter().find(|v| v.label == label).unwrap();
        let key = c.bed_of(v);
        (
            key,
            bed_cache::name("impact2d", &bed_spec(c, &key)).unwrap(),
            bed_spec(c, &key),
        )
    };
    for seed in 1..=5 {
        let (k_kin, n_kin, s_kin) = name(&own, &format!("friction=kinetic,seed={seed}"));
        let (k_sta, n_sta, s_sta) = name(&own, &format!("friction=static,seed={seed}"));
        let (_, n_fig6, _) = name(&fig6, &format!("friction=kinetic,seed={seed}"));
        let (_, n_fig6_static, _) = name(&fig6, &format!("friction=static,seed={seed}"));
        assert_ne!(k_sta, k_kin, "seed {seed}: one bed key per model");
        assert_eq!((s_kin.coeffs[0].kt, s_kin.coeffs[1].kt), (0.0, 0.0));
        // The Fig 6 bed's specification but for the time cap and the hold (K's
        // one-check criterion there, 200 tau_c below it here): settled anew.
        assert_eq!(s_kin.settle_hold, 200.0 * own.scales.tau_c);
        assert_eq!(s_sta.settle_hold, s_kin.settle_hold);
        let uncapped = |mut s: granval::physics::dem2d::bed::BedSpec| {
            s.max_settle_time = 0.0;
            s.settle_hold = 0.0;
            serde_json::to_string(&s).unwrap()
        };
        let (_, _, s_fig6) = name(&fig6, &format!("friction=kinetic,seed={seed}"));
        assert_eq!(
            uncapped(s_kin.clone()),
            uncapped(s_fig6),
            "seed {seed}: the kinetic bed is the Fig 6 case's"
        );
        assert_ne!(n_kin, n_fig6, "the cap is part of the file name");
        assert_eq!(n_fig6_static, n_fig6, "Fig 6 hits one bed with both models");
        assert_ne!(n_sta, n_kin, "seed {seed}: the static bed is its own");
        assert_eq!(s_sta.coeffs[0].kt, 0.8 * s_sta.coeffs[0].kn);
        assert_eq!(
            s_sta.coeffs[1].kt,
            0.8 * s_sta.coeffs[1].kn,
            "walls static too"
        );
    }
    // The hash moves with the field, and not without it.
    let text =
        std::fs::read_to_string(root.join("kondic-fig22-25-poly-fields-5seeds.toml")).unwrap();
    let base_text = text.replace("settled_with = \"variant\"", "settled_with = \"base\"");
    let as_base = Impact2dCase::from_toml_str(&base_text, Path::new("b.toml")).unwrap();
    let absent = Impact2dCase::from_toml_str(
        &text.replace("settled_with = \"variant\"", ""),
        Path::new("c.toml"),
    )
    .unwrap();
    assert!(!as_base.beds_per_variant);
    assert_eq!(as_base.canonical_hash(), absent.canonical_hash());
    assert_ne!(as_base.canonical_hash(), own.canonical_hash());
    assert_rejected(
        &text,
        &[(
            "settled_with = \"variant\"\ninitial_speed",
            "settled_with = \"each\"\ninitial_speed",
            "bed.settled_with",
            "must be \"base\"",
        )],
    );
    // A sweep of the impact alone (here speed; its claims dropped) settles one set of
    // grains: refused.
    let claims = text.find("[[claim]]").unwrap()..text.find("[compare]").unwrap();
    let mut no_claims = text.clone();
    no_claims.replace_range(claims, "");
    let speed = no_claims.replace(
        "parameter = \"friction\"\nvalues = [\"kinetic\", \"static\"]",
        "parameter = \"speed\"\nvalues = [0.7, 1.0]",
    );
    let e = err(&speed);
    assert!(
        e.contains("bed.settled_with") && e.contains("needs a sweep of a grain property"),
        "{e}"
    );
    // With a sweep_ignored control, one value must keep the base's grains.
    let mu_sweep = no_claims.replace(
        "parameter = \"friction\"\nvalues = [\"kinetic\", \"static\"]",
        "parameter = \"mu\"\nvalues = [0.3, 0.7]",
    );
    let e = err(&mu_sweep);
    assert!(
        e.contains("bed.settled_with")
            && e.contains("one sweep value must keep the base case's grains"),
        "{e}"
    );
}

/// `[bed] settle_hold` (tau_c): converted to seconds, sealed (the hash moves with it
/// and not without it: a case written before it keeps its hash), and refused when
/// negative or not shorter than the time cap, naming the field, the value and why.
#[test]
fn the_settling_hold_is_sealed_and_checked() {
    let root = common::root().join("cases/release");
    let text =
        std::fs::read_to_string(root.join("kondic-fig22-25-poly-fields-5seeds.toml")).unwrap();
    let held = Impact2dCase::from_toml_str(&text, Path::new("a.toml")).unwrap();
    assert_eq!(held.settle_hold, 200.0 * held.scales.tau_c);
    let zero = Impact2dCase::from_toml_str(
        &text.replace("settle_hold = 200.0", "settle_hold = 0.0"),
        Path::new("b.toml"),
    )
    .unwrap();
    let absent = Impact2dCase::from_toml_str(
        &text.replace("settle_hold = 200.0", ""),
        Path::new("c.toml"),
    )
    .unwrap();
    assert_eq!(absent.settle_hold, 0.0);
    assert_eq!(zero.canonical_hash(), absent.canonical_hash());
    assert_ne!(held.canonical_hash(), absent.canonical_hash());
    assert_rejected(
        &text,
        &[
            (
                "settle_hold = 200.0",
                "settle_hold = -1.0",
                "bed.settle_hold",
                "-1",
            ),
            (
                "settle_hold = 200.0",
                "settle_hold = 200000.0",
                "bed.settle_hold",
                "must be shorter than bed.max_settle_time",
            ),
        ],
    );
}
