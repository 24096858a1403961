//! Case files: parsed once from TOML, validated once, then trusted by every later stage
//! (docs/architecture.md). All quantities in the validated [`Case`] are SI.

pub mod clumps;
mod error;
pub mod family;
mod fields;
pub mod impact2d;
mod parse;
pub mod penetration;
pub mod plausible;
pub(crate) mod schema;
pub mod triaxial;
pub(crate) mod validate;

pub use error::CaseError;
pub(crate) use family::{ContactFamily, LammpsModels, LammpsRolling};

mod control;

pub use control::{Gate, NegativeControl, Perturbation};

use crate::rundata::provenance::EngineKind;
use std::path::{Path, PathBuf};

/// What the runner needs of every validated case kind: its name and file (for reports
/// and errors), the hash its reference record is sealed to, and its negative controls.
pub trait ValidatedCase {
    fn name(&self) -> &str;
    fn source(&self) -> &Path;
    fn canonical_hash(&self) -> crate::rundata::provenance::Sha256;
    fn negative_controls(&self) -> &[NegativeControl];
}

/// Implements [`ValidatedCase`] for a case type with `name`, `source` and
/// `negative_controls` fields and an inherent `canonical_hash`.
macro_rules! validated_case {
    ($t:ty) => {
        impl $crate::case::ValidatedCase for $t {
            fn name(&self) -> &str {
                &self.name
            }
            fn source(&self) -> &std::path::Path {
                &self.source
            }
            fn canonical_hash(&self) -> $crate::rundata::provenance::Sha256 {
                <$t>::canonical_hash(self)
            }
            fn negative_controls(&self) -> &[$crate::case::NegativeControl] {
                &self.negative_controls
            }
        }
    };
}
pub(crate) use validated_case;

validated_case!(Case);

/// The text of a case file, or the error naming it: a regular file of at most
/// [`MAX_CASE_FILE`](crate::rundata::fsio::MAX_CASE_FILE) (`granval validate /dev/zero`
/// is an error, not a read without end).
pub(crate) fn read_case_file(path: &Path) -> Result<String, CaseError> {
    use crate::rundata::fsio;
    fsio::read_to_string(path, fsio::MAX_CASE_FILE, "a case file (TOML text)").map_err(|e| {
        let reason = e.reason();
        CaseError::Io {
            file: path.to_path_buf(),
            error: match e.problem {
                fsio::Problem::Io(error) => error,
                _ => std::io::Error::other(reason),
            },
        }
    })
}

/// A case file of any kind, its `[case] kind` read in this one place.
#[derive(Debug, Clone)]
pub enum AnyCase {
    Micro(Case),
    Penetration(penetration::PenetrationCase),
    Impact2d(impact2d::Impact2dCase),
    Triaxial(triaxial::TriaxialCase),
}

impl AnyCase {
    pub fn load(path: &Path) -> Result<AnyCase, CaseError> {
        let text = read_case_file(path)?;
        AnyCase::from_toml_str(&text, path)
    }

    pub fn from_toml_str(text: &str, path: &Path) -> Result<AnyCase, CaseError> {
        #[derive(serde::Deserialize)]
        struct Peek {
            case: PeekCase,
        }
        #[derive(serde::Deserialize)]
        struct PeekCase {
            kind: String,
        }
        let peek: Peek = parse::from_toml(text, path)?;
        match peek.case.kind.as_str() {
            "micro" => Case::from_toml_str(text, path).map(AnyCase::Micro),
            "penetration" => {
                penetration::PenetrationCase::from_toml_str(text, path).map(AnyCase::Penetration)
            }
            "impact2d" => impact2d::Impact2dCase::from_toml_str(text, path).map(AnyCase::Impact2d),
            "triaxial" => triaxial::TriaxialCase::from_toml_str(text, path).map(AnyCase::Triaxial),
            other => Err(error::Ctx {
                file: path.to_path_buf(),
            }
            .bad(
                "case.kind",
                other,
                "supported kinds: \"micro\", \"penetration\", \"impact2d\", \"triaxial\"",
            )),
        }
    }

    /// Plausibility warnings of the file as written ([`plausible`]), each naming its
    /// field (the file is the caller's to name). Impact2d cases are dimensionless (units
    /// of d and m) and have none.
    pub fn warnings(&self) -> &[String] {
        match self {
            AnyCase::Micro(c) => &c.warnings,
            AnyCase::Penetration(c) => &c.warnings,
            AnyCase::Impact2d(_) => &[],
            AnyCase::Triaxial(c) => &c.warnings,
        }
    }

    pub fn name(&self) -> &str {
        match self {
            AnyCase::Micro(c) => &c.name,
            AnyCase::Penetration(c) => &c.name,
            AnyCase::Impact2d(c) => &c.name,
            AnyCase::Triaxial(c) => &c.name,
        }
    }

    /// The case's `kind` as its file writes it.
    pub fn kind(&self) -> &'static str {
        match self {
            AnyCase::Micro(_) => "micro",
            AnyCase::Penetration(_) => "penetration",
            AnyCase::Impact2d(_) => "impact2d",
            AnyCase::Triaxial(_) => "triaxial",
        }
    }

    /// Leaves out the case's quasi-static rerun (a penetration case's `[quasi_static]`),
    /// for a suite entry that says `quasi_static = false`; its speed (m/s) if it had one.
    pub fn drop_quasi_static(&mut self) -> Option<f64> {
        match self {
            AnyCase::Penetration(c) => c.quasi_static_speed.take(),
            AnyCase::Micro(_) | AnyCase::Impact2d(_) | AnyCase::Triaxial(_) => None,
        }
    }

    /// The reference engine the case is compared against unless a command says
    /// otherwise: the first of [`AnyCase::references`], the one table every command
    /// reads, so `validate`, `run`, `deck` and `compare` cannot disagree about it.
    pub fn reference_engine(&self) -> EngineKind {
        self.references().engines[0]
    }

    /// The reference engines the case can be compared against, its own first (the only
    /// one a sealed record exists for), and why these: LAMMPS 29 Sep 2021 for the 2D
    /// impact, LAMMPS 22 Jul 2025 for cases of LAMMPS' law family, LIGGGHTS 3.8
    /// otherwise; a LIGGGHTS-family penetration case also runs in LAMMPS 2025 on the same
    /// natively prepared beds (docs/lammps-laws.md, "Penetration in LAMMPS 2025").
    pub fn references(&self) -> References {
        const LIGGGHTS: References = References {
            engines: &[EngineKind::Liggghts],
            label: "LIGGGHTS 3.8",
            why: "a 3D case of LIGGGHTS' contact laws is compared against LIGGGHTS 3.8",
        };
        const LAMMPS_LAWS: References = References {
            engines: &[EngineKind::Lammps],
            label: "LAMMPS 22 Jul 2025",
            why: "models.family = \"lammps\": LAMMPS' pair_style granular laws run only against LAMMPS 2025, which LIGGGHTS' deck cannot write",
        };
        let lammps_laws = match self {
            AnyCase::Micro(c) => c.lammps().is_some(),
            AnyCase::Penetration(c) => matches!(c.family, family::ContactFamily::Lammps(_)),
            AnyCase::Impact2d(_) => {
                return References {
                    engines: &[EngineKind::Lammps],
                    label: "LAMMPS 29 Sep 2021",
                    why: "a 2D case is compared against LAMMPS (Debian's 29 Sep 2021)",
                };
            }
            AnyCase::Triaxial(_) => false,
        };
        match self {
            _ if lammps_laws => LAMMPS_LAWS,
            AnyCase::Penetration(_) => References {
                engines: &[EngineKind::Liggghts, EngineKind::Lammps],
                label: "LIGGGHTS 3.8",
                why: "a penetration case is compared against LIGGGHTS 3.8 (its records), or live against LAMMPS 2025 on the same natively prepared beds",
            },
            _ => LIGGGHTS,
        }
    }
}

/// The reference engines of a case ([`AnyCase::references`]).
#[derive(Debug, Clone, Copy)]
pub struct References {
    /// The engines, the case's own first.
    pub engines: &'static [EngineKind],
    /// The first engine as people name it, with its version.
    pub label: &'static str,
    /// Why these, for a refusal of another.
    pub why: &'static str,
}

/// Which contact models a case uses; names follow LIGGGHTS' `pair_style gran` keywords.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum RollingModel {
    None,
    /// Constant directional torque, `rolling_friction cdt` (Feng eq 4).
    Cdt,
    /// Elastic-plastic spring-dashpot without the dashpot, `rolling_friction epsd2`.
    Epsd2,
}

impl RollingModel {
    pub(crate) fn liggghts_keyword(self) -> Option<&'static str> {
        match self {
            RollingModel::None => None,
            RollingModel::Cdt => Some("cdt"),
            RollingModel::Epsd2 => Some("epsd2"),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Axis {
    X = 0,
    Y = 1,
    Z = 2,
}

impl Axis {
    pub fn index(self) -> usize {
        self as usize
    }
    pub fn name(self) -> &'static str {
        ["x", "y", "z"][self as usize]
    }
}

/// Elastic constants of one atom type, both forms kept so nobody re-derives them.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Material {
    pub youngs_modulus: f64,
    pub shear_modulus: f64,
    pub poisson_ratio: f64,
}

/// Per type-pair coefficients, symmetric, indexed by 0-based type.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PairTable {
    pub n_types: usize,
    pub restitution: Vec<f64>,
    pub friction: Vec<f64>,
    pub rolling_friction: Vec<f64>,
}

impl PairTable {
    pub fn idx(&self, a: usize, b: usize) -> usize {
        a * self.n_types + b
    }
}

#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Particle {
    pub id: u64,
    /// 0-based type (the file's type minus one).
    pub type_: usize,
    pub radius: f64,
    pub density: f64,
    pub x: [f64; 3],
    pub v: [f64; 3],
    pub omega: [f64; 3],
}

impl Particle {
    /// Mass as LIGGGHTS computes it from diameter and density for a 3D sphere.
    pub fn mass(&self) -> f64 {
        4.0 * std::f64::consts::PI / 3.0 * self.radius * self.radius * self.radius * self.density
    }
}

#[derive(Debug, Clone, serde::Serialize)]
pub enum Wall {
    Plane {
        axis: Axis,
        position: f64,
        type_: usize,
    },
    Cylinder {
        axis: Axis,
        radius: f64,
        center: [f64; 2],
        type_: usize,
    },
}

impl Wall {
    pub fn type_(&self) -> usize {
        match self {
            Wall::Plane { type_, .. } | Wall::Cylinder { type_, .. } => *type_,
        }
    }
}

#[derive(Debug, Clone, serde::Serialize)]
pub struct Tolerances {
    pub velocity_rel: f64,
    pub position_frac_radius: f64,
    /// Largest angle (rad) of the rotation between two bodies' orientations.
    pub orientation_rad: f64,
}

/// A validated case. Outside this crate it can only come from [`Case::load`] /
/// [`Case::from_toml_str`] (`non_exhaustive`); inside it, besides the validator, only the
/// generated packings of `physics::dem::packing` (a penetration bed's container, the
/// bench lattice) build one. The fields are public for reading.
#[derive(Debug, Clone, serde::Serialize)]
#[non_exhaustive]
pub struct Case {
    pub name: String,
    pub kind: String,
    pub description: String,
    /// Where the case came from; errors and reports name it.
    pub source: PathBuf,
    pub dt: f64,
    pub n_steps: u64,
    pub output_every: u64,
    pub gravity: [f64; 3],
    pub neighbor_skin: f64,
    pub rolling: RollingModel,
    /// Whose contact laws (LIGGGHTS' by default; LAMMPS' `pair_style granular`).
    pub family: ContactFamily,
    pub domain_lo: [f64; 3],
    pub domain_hi: [f64; 3],
    pub materials: Vec<Material>,
    pub pairs: PairTable,
    pub particles: Vec<Particle>,
    pub walls: Vec<Wall>,
    /// Rigid multisphere clumps (empty for sphere-only cases).
    pub clumps: clumps::Clumps,
    pub tolerances: Tolerances,
    /// Rayleigh time of the smallest/softest grain (Feng Sec. 2), for reports.
    pub rayleigh_time: f64,
    pub negative_controls: Vec<NegativeControl>,
    /// What the comparison must observe for its gates to mean anything
    /// (`[compare] expect`; see [`Observation`]).
    pub expect: Vec<Observation>,
    /// Plausibility warnings of the file as written ([`plausible`]): values that run but
    /// are probably in the wrong unit. Not part of the case's physics or hash.
    #[serde(skip)]
    pub warnings: Vec<String>,
}

/// Something a micro comparison must see happen, or its gates are NOT COMPARED.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Observation {
    /// A contact forms (some frame of each run carries a contact force): a collision
    /// case whose grains miss each other has compared free flight, not a contact law.
    Contact,
}

impl Observation {
    pub fn name(self) -> &'static str {
        match self {
            Observation::Contact => "contact",
        }
    }
}

impl Case {
    pub fn load(path: &Path) -> Result<Case, CaseError> {
        let text = read_case_file(path)?;
        Case::from_toml_str(&text, path)
    }

    pub fn from_toml_str(text: &str, path: &Path) -> Result<Case, CaseError> {
        let raw: schema::CaseFile = parse::from_toml(text, path)?;
        let warnings = plausible::micro(&raw);
        let mut case = validate::validate(raw, path).map_err(|e| e.noting(&warnings))?;
        case.warnings = warnings;
        Ok(case)
    }

    pub fn n_types(&self) -> usize {
        self.materials.len()
    }

    /// What a run of this case depends on, in a fixed form: the physics, not the name,
    /// description, file location, tolerances or controls. A recorded reference is
    /// sealed to its sha256, so a reformatted case file keeps its record while a changed
    /// friction coefficient (or another case's record) is refused.
    ///
    /// The struct is destructured exhaustively: a field added to [`Case`] does not compile
    /// until it is either placed in the view or named below as not physics, so nothing a
    /// run depends on can be left out of the seal by oversight.
    pub fn canonical_hash(&self) -> crate::rundata::provenance::Sha256 {
        let Case {
            dt,
            n_steps,
            output_every,
            gravity,
            neighbor_skin,
            rolling,
            family,
            domain_lo,
            domain_hi,
            materials,
            pairs,
            particles,
            walls,
            clumps,
            // Not physics: labels, where the file is, how the runs are judged, and a
            // quantity derived from the sealed materials and particles.
            name: _,
            kind: _,
            description: _,
            source: _,
            tolerances: _,
            rayleigh_time: _,
            negative_controls: _,
            expect: _,
            warnings: _,
        } = self;
        let mut view = serde_json::json!({
            "kind": "micro",
            "dt": dt,
            "n_steps": n_steps,
            "output_every": output_every,
            "gravity": gravity,
            "neighbor_skin": neighbor_skin,
            "rolling": rolling,
            "domain": [domain_lo, domain_hi],
            "materials": materials,
            "pairs": pairs,
            "particles": particles,
            "walls": walls,
        });
        // Only LAMMPS-family cases carry the key, so every LIGGGHTS seal stays valid.
        if let ContactFamily::Lammps(m) = family {
            view["lammps"] = serde_json::json!(m);
        }
        // Only clump cases carry the key, so every sphere-only seal stays valid.
        if !clumps.is_empty() {
            view["clumps"] = serde_json::json!(clumps);
        }
        crate::rundata::provenance::Sha256::of(view.to_string().as_bytes())
    }

    /// Smallest sphere radius, clump members included.
    pub(crate) fn min_radius(&self) -> f64 {
        self.particles
            .iter()
            .map(|p| p.radius)
            .chain(
                self.clumps
                    .templates
                    .iter()
                    .flat_map(|t| t.radii.iter().copied()),
            )
            .fold(f64::INFINITY, f64::min)
    }

    /// Mass of every free sphere and every clump body by id (bodies: the whole body).
    pub(crate) fn mass_by_id(&self) -> std::collections::HashMap<u64, f64> {
        self.particles
            .iter()
            .map(|p| (p.id, p.mass()))
            .chain(
                self.clumps
                    .bodies
                    .iter()
                    .map(|b| (b.id, self.clumps.template_of(b).mass)),
            )
            .collect()
    }
}

/// Rayleigh time step `pi R sqrt(rho/G) / (0.1631 nu + 0.8766)` (Feng Sec. 2, ref 32).
pub fn rayleigh_time(radius: f64, density: f64, shear_modulus: f64, poisson: f64) -> f64 {
    std::f64::consts::PI * radius * (density / shear_modulus).sqrt() / (0.1631 * poisson + 0.8766)
}
