//! Which engine family's contact laws a micro case uses (`[models] family`).
//!
//! `"liggghts"` (the default) is LIGGGHTS 3.8 `pair_style gran model hertz tangential
//! history` with CDT/EPSD2 rolling, reproduced by the native engine and checked against
//! LIGGGHTS. `"lammps"` is LAMMPS' `pair_style granular` with the sub-models
//! `hertz/material`, `damping coeff_restitution`, `tangential mindlin` and optionally
//! `rolling sds` (`twisting none`), reproduced natively by
//! [`crate::physics::dem::lammps_granular`] and checked against LAMMPS 2025
//! ([`crate::engines::lammps3d`]). docs/lammps-laws.md maps one family onto the other.

use super::error::{CaseError, Ctx};
use super::fields::finite;
use super::{Case, Particle, Wall, schema};
use crate::rundata::provenance::EngineKind;

/// The contact-law family of a case.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub enum ContactFamily {
    Liggghts,
    Lammps(LammpsModels),
}

/// LAMMPS `rolling` sub-model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum LammpsRolling {
    None,
    /// Spring-dashpot-slider, `rolling sds k_roll gamma_roll mu_roll`.
    Sds,
}

/// The LAMMPS sub-model coefficients beyond the shared materials and pair table.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LammpsModels {
    /// `xt` of `tangential mindlin NULL xt mu`.
    pub tangential_damping: f64,
    pub rolling: LammpsRolling,
    /// Per type pair (index [`super::PairTable::idx`]) `k_roll`, `gamma_roll` (0 without
    /// SDS).
    pub rolling_stiffness: Vec<f64>,
    pub rolling_damping: Vec<f64>,
}

impl Case {
    /// The LAMMPS sub-models when the case is of the LAMMPS family.
    pub fn lammps(&self) -> Option<&LammpsModels> {
        match &self.family {
            ContactFamily::Lammps(m) => Some(m),
            ContactFamily::Liggghts => None,
        }
    }

    /// The engine the case is compared against: LAMMPS 22 Jul 2025 for LAMMPS' laws,
    /// LIGGGHTS 3.8 for LIGGGHTS'.
    pub(crate) fn reference_engine(&self) -> EngineKind {
        if self.lammps().is_some() {
            EngineKind::Lammps
        } else {
            EngineKind::Liggghts
        }
    }
}

/// Whether `models.family` asks for LAMMPS (an unknown value is an error).
pub(super) fn is_lammps(ctx: &Ctx, models: &schema::Models) -> Result<bool, CaseError> {
    match models.family.as_deref() {
        None | Some("liggghts") => Ok(false),
        Some("lammps") => Ok(true),
        Some(other) => Err(ctx.bad(
            "models.family",
            other,
            "supported: \"liggghts\" (the default) or \"lammps\"",
        )),
    }
}

/// The model names a LAMMPS-family case must use (LAMMPS' own keywords).
pub(super) fn check_lammps_names(ctx: &Ctx, models: &schema::Models) -> Result<(), CaseError> {
    if models.normal != "hertz/material" {
        return Err(ctx.bad(
            "models.normal",
            &models.normal,
            "family \"lammps\" supports \"hertz/material\" (with damping coeff_restitution)",
        ));
    }
    if models.tangential != "mindlin" {
        return Err(ctx.bad(
            "models.tangential",
            &models.tangential,
            "family \"lammps\" supports \"mindlin\"",
        ));
    }
    if !matches!(models.rolling.as_str(), "none" | "sds") {
        return Err(ctx.bad(
            "models.rolling",
            &models.rolling,
            "family \"lammps\" supports \"none\" and \"sds\"",
        ));
    }
    Ok(())
}

/// The LAMMPS family of a micro case: coefficients read and checked, and the parts of
/// a case LAMMPS' deck cannot express refused (clumps; cylinder walls; walls with more
/// than one particle type, since `fix wall/gran` carries one material).
pub(super) fn lammps_models(
    ctx: &Ctx,
    models: &schema::Models,
    interactions: &[schema::Interaction],
    n_types: usize,
    particles: &[Particle],
    walls: &[Wall],
    has_clumps: bool,
) -> Result<LammpsModels, CaseError> {
    check_lammps_names(ctx, models)?;
    if has_clumps {
        return Err(ctx.bad(
            "models.family",
            "lammps",
            "clumps are LIGGGHTS' fix multisphere; the LAMMPS family has spheres only",
        ));
    }
    for (k, w) in walls.iter().enumerate() {
        if matches!(w, Wall::Cylinder { .. }) {
            return Err(ctx.bad(
                format!("walls[{k}].kind"),
                "cylinder",
                "the LAMMPS family supports plane walls (fix wall/gran ... xplane/yplane/zplane)",
            ));
        }
    }
    if !walls.is_empty() {
        let mut types: Vec<usize> = particles.iter().map(|p| p.type_).collect();
        types.sort_unstable();
        types.dedup();
        if types.len() > 1 {
            return Err(ctx.bad(
                "walls",
                format!("{} particle types", types.len()),
                "LAMMPS' fix wall/gran has one set of coefficients for every particle: \
                 with walls, the LAMMPS family needs all particles of one type",
            ));
        }
    }
    let xt = match models.tangential_damping {
        Some(x) => finite(ctx, "models.tangential_damping", x)?,
        None => {
            return Err(ctx.bad(
                "models.tangential_damping",
                "missing",
                "family \"lammps\" needs the tangential damping ratio xt of `tangential mindlin NULL xt mu`",
            ));
        }
    };
    if xt < 0.0 {
        return Err(ctx.bad("models.tangential_damping", xt, "must be >= 0"));
    }
    let rolling = if models.rolling == "sds" {
        LammpsRolling::Sds
    } else {
        LammpsRolling::None
    };
    let nn = n_types * n_types;
    let (mut kr, mut gr) = (vec![0.0; nn], vec![0.0; nn]);
    for (k, it) in interactions.iter().enumerate() {
        let f = |name: &str| format!("interactions[{k}].{name}");
        let (a, b) = (it.types[0] - 1, it.types[1] - 1);
        let get = |name: &str, v: Option<f64>, out: &mut Vec<f64>| match (rolling, v) {
            (LammpsRolling::Sds, Some(v)) => {
                let v = finite(ctx, &f(name), v)?;
                if v < 0.0 {
                    return Err(ctx.bad(f(name), v, "must be >= 0"));
                }
                out[a * n_types + b] = v;
                out[b * n_types + a] = v;
                Ok(())
            }
            (LammpsRolling::Sds, None) => Err(ctx.bad(
                f(name),
                "missing",
                "rolling \"sds\" needs rolling_stiffness and rolling_damping on every interaction",
            )),
            (LammpsRolling::None, Some(v)) => Err(ctx.bad(
                f(name),
                v,
                "only rolling \"sds\" (family \"lammps\") reads it",
            )),
            (LammpsRolling::None, None) => Ok(()),
        };
        get("rolling_stiffness", it.rolling_stiffness, &mut kr)?;
        get("rolling_damping", it.rolling_damping, &mut gr)?;
    }
    Ok(LammpsModels {
        tangential_damping: xt,
        rolling,
        rolling_stiffness: kr,
        rolling_damping: gr,
    })
}

/// A LIGGGHTS-family case must not carry LAMMPS-only fields (they would be ignored).
pub(super) fn refuse_lammps_fields(
    ctx: &Ctx,
    models: &schema::Models,
    interactions: &[schema::Interaction],
) -> Result<(), CaseError> {
    if let Some(x) = models.tangential_damping {
        return Err(ctx.bad(
            "models.tangential_damping",
            x,
            "only family \"lammps\" reads it (LIGGGHTS' tangential damping follows from e)",
        ));
    }
    for (k, it) in interactions.iter().enumerate() {
        for (name, v) in [
            ("rolling_stiffness", it.rolling_stiffness),
            ("rolling_damping", it.rolling_damping),
        ] {
            if let Some(v) = v {
                return Err(ctx.bad(
                    format!("interactions[{k}].{name}"),
                    v,
                    "only family \"lammps\" with rolling \"sds\" reads it",
                ));
            }
        }
    }
    Ok(())
}
