//! Fast checks of the native penetration pieces on a tiny bed: preparation protocol,
//! packing fraction, intruder kinematics and the sign of the resistance.

use granval::case::penetration::PenetrationCase;
use std::path::Path;

fn tiny(extra: &str) -> String {
    format!(
        r#"
[case]
name = "tiny"
kind = "penetration"
[simulation]
dt = 4.0e-5
gravity = 9.81
[models]
normal = "hertz"
tangential = "history"
rolling = "cdt"
[[materials]]
type = 1
youngs_modulus = 5.2e6
poisson_ratio = 0.3
[[materials]]
type = 2
youngs_modulus = 5.2e6
poisson_ratio = 0.3
[[interactions]]
types = [1, 1]
restitution = 0.5
friction = 0.5
rolling_friction = 0.01
[[interactions]]
types = [1, 2]
restitution = 0.5
friction = 0.3
rolling_friction = 0.01
[[interactions]]
types = [2, 2]
restitution = 0.5
friction = 0.3
rolling_friction = 0.01
[container]
diameter = 0.032
height = 0.05
type = 1
[bed]
type = 1
density = 2500.0
diameter = {{ kind = "uniform", mean = 4.0e-3, half_width = 0.2e-3 }}
count = 300
seed = 7
[preparation]
settle_ke_ratio = 1.0e-6
max_settle_time = 1.0
[intruder]
diameter = 0.010
length = 0.03
type = 2
speed = 0.1
start_gap = 1.0e-3
final_depth = 0.006
force_every = 10
[analysis]
fit_h_min = 0.5
{extra}
"#
    )
}

#[test]
fn bed_settles_and_intruder_meets_resistance() {
    let case = PenetrationCase::from_toml_str(&tiny(""), Path::new("tiny.toml")).unwrap();
    let bed = granval::penetration::prepare_bed(&case, false).unwrap();
    eprintln!("{}", granval::dem::packing::bed_note(&case, &bed));
    assert!(bed.ke_ratio < 1e-6);
    assert!(
        bed.psi > 0.45 && bed.psi < 0.70,
        "implausible packing fraction {}",
        bed.psi
    );
    let top = bed
        .particles
        .iter()
        .map(|p| p.x[2] + p.radius)
        .fold(0.0, f64::max);
    assert!(bed.surface_z > 0.0 && bed.surface_z <= top);
    let run = granval::penetration::run_native(&case, &bed, Default::default(), false).unwrap();
    let s = &run.samples;
    // Constant-speed drive: z_bottom falls by v dt per step exactly (to round-off).
    let dz = (s[0].z_bottom - s.last().unwrap().z_bottom) / (s.last().unwrap().t - s[0].t);
    assert!(
        (dz / case.speed - 1.0).abs() < 1e-9,
        "intruder speed {dz} vs {}",
        case.speed
    );
    // Above the bed no force; deep in it the grains push back up (+z).
    assert_eq!(s[0].f, [0.0; 3]);
    let deep: Vec<f64> = s
        .iter()
        .filter(|x| x.z_bottom < bed.surface_z - 0.004)
        .map(|x| x.f[2])
        .collect();
    assert!(!deep.is_empty() && deep.iter().sum::<f64>() / deep.len() as f64 > 0.0);
}

#[test]
fn penetration_case_errors_name_field() {
    let bad = tiny("").replace("final_depth = 0.006", "final_depth = 0.05");
    let e = PenetrationCase::from_toml_str(&bad, Path::new("tiny.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("tiny.toml") && e.contains("intruder.final_depth") && e.contains("0.05"),
        "{e}"
    );
    let bad = tiny("").replace("friction = 0.5", "friction = -0.5");
    let e = PenetrationCase::from_toml_str(&bad, Path::new("tiny.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("interactions[0].friction"), "{e}");
}

#[test]
fn shipped_penetration_cases_load() {
    for p in granval::pipeline::suite_cases(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("cases"),
        "penetration",
    )
    .unwrap()
    {
        PenetrationCase::load(&p).unwrap_or_else(|e| panic!("{e}"));
    }
}
