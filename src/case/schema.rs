//! The TOML shape of a case file, exactly as users write it. Every table denies unknown
//! fields so a typo (`restitutoin`) is an error instead of a silently ignored line.
//! Units are SI throughout the file; engines convert if they must (LIGGGHTS cgs).

use serde::Deserialize;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CaseFile {
    pub case: Meta,
    pub simulation: Simulation,
    pub models: Models,
    pub domain: Domain,
    pub materials: Vec<Material>,
    pub interactions: Vec<Interaction>,
    #[serde(default)]
    pub particles: Vec<Particle>,
    /// Rigid multisphere clump templates (`[[clump_templates]]`) and bodies (`[[clumps]]`).
    #[serde(default)]
    pub clump_templates: Vec<super::clumps::RawTemplate>,
    #[serde(default)]
    pub clumps: Vec<super::clumps::RawClump>,
    #[serde(default)]
    pub walls: Vec<Wall>,
    #[serde(default)]
    pub compare: Option<Compare>,
    #[serde(default)]
    pub negative_control: Vec<super::control::RawControl>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Meta {
    pub name: String,
    pub kind: String,
    #[serde(default)]
    pub description: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Simulation {
    /// Time step in s.
    pub dt: f64,
    /// Simulated time in s.
    pub duration: f64,
    /// Output every this many steps (step 0 is always written).
    pub output_every: u64,
    /// Gravitational acceleration vector in m/s^2.
    pub gravity: [f64; 3],
    /// Verlet skin in m. Optional: it changes cost, not physics (documented default:
    /// half the smallest particle radius).
    pub neighbor_skin: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Models {
    pub normal: String,
    pub tangential: String,
    pub rolling: String,
    /// Whose contact laws: "liggghts" (default: LIGGGHTS 3.8 `pair_style gran`) or
    /// "lammps" (LAMMPS' `pair_style granular` sub-models; micro cases only).
    pub family: Option<String>,
    /// LAMMPS family: the tangential damping ratio `xt` of `tangential mindlin NULL xt
    /// mu` (tangential damping = xt times the normal damping prefactor).
    pub tangential_damping: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Domain {
    /// Lower corner of the simulation box (m). Particles leaving it are an error in
    /// LIGGGHTS (`boundary f f f`), so the native engine treats it the same way.
    pub lo: [f64; 3],
    pub hi: [f64; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Atom type this material belongs to (1-based, contiguous), as in LIGGGHTS.
    #[serde(rename = "type")]
    pub type_: usize,
    pub youngs_modulus: Option<f64>,
    pub shear_modulus: Option<f64>,
    pub poisson_ratio: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Interaction {
    pub types: [usize; 2],
    pub restitution: f64,
    pub friction: f64,
    pub rolling_friction: f64,
    /// LAMMPS family, `rolling sds`: rolling spring stiffness k_roll (N/m).
    pub rolling_stiffness: Option<f64>,
    /// LAMMPS family, `rolling sds`: rolling damping gamma_roll (N s/m).
    pub rolling_damping: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Particle {
    pub id: u64,
    #[serde(rename = "type")]
    pub type_: usize,
    pub radius: f64,
    pub density: f64,
    pub x: [f64; 3],
    #[serde(default)]
    pub v: [f64; 3],
    #[serde(default)]
    pub omega: [f64; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "snake_case")]
pub enum Wall {
    /// Axis-aligned plane `axis = position`; it repels from both sides, as LIGGGHTS'
    /// `primitive xplane|yplane|zplane` does.
    Plane {
        axis: String,
        position: f64,
        #[serde(rename = "type")]
        type_: usize,
    },
    /// Inside of an infinite cylinder around an axis-parallel line through `center`
    /// (the two coordinates perpendicular to the axis), like `primitive zcylinder R cx cy`.
    Cylinder {
        axis: String,
        radius: f64,
        center: [f64; 2],
        #[serde(rename = "type")]
        type_: usize,
    },
}

/// Tolerances of the trajectory comparison. Defaults (documented in docs/cases.md) are the
/// project's acceptance criteria: 1e-6 relative in velocities and angular velocities,
/// 1e-6 of the smallest radius in positions.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Compare {
    pub velocity_rel: Option<f64>,
    pub position_frac_radius: Option<f64>,
    /// Clump cases: largest rotation angle (rad) between the engines' body orientations.
    pub orientation_rad: Option<f64>,
    /// What both runs must show for the gates to mean anything: `["contact"]` or `[]`.
    /// Default: `["contact"]` for two bodies approaching each other at t = 0, else `[]`.
    pub expect: Option<Vec<String>>,
}
