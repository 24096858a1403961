//! LIGGGHTS unit systems for granval's decks (SI or cgs) and the conversion factors
//! from SI, with LIGGGHTS' range limits of Young's modulus in each.

use crate::case::Material;
use anyhow::{Result, bail};

/// LIGGGHTS' range check on `youngsModulus`, in Pa, identical in SI and cgs
/// (5e6..1e9 Pa = 5e7..1e10 barye), measured on LIGGGHTS 3.8.0.
pub(crate) const LIGGGHTS_MIN_E_PA: f64 = 5e6;

pub(crate) const LIGGGHTS_MAX_E_PA: f64 = 1e9;

/// The same limits as LIGGGHTS states them for `units cgs` (barye).
pub(crate) const LIGGGHTS_MIN_E_CGS: f64 = 5e7;

pub(crate) const LIGGGHTS_MAX_E_CGS: f64 = 1e10;

/// Unit system of a deck. Inputs are always SI; this is what gets written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Units {
    Si,
    Cgs,
}

impl Units {
    pub(crate) fn keyword(self) -> &'static str {
        match self {
            Units::Si => "si",
            Units::Cgs => "cgs",
        }
    }
    /// SI -> deck factor for lengths (m -> cm).
    pub fn length(self) -> f64 {
        match self {
            Units::Si => 1.0,
            Units::Cgs => 100.0,
        }
    }
    /// Velocities (m/s -> cm/s) and accelerations (m/s^2 -> cm/s^2): time is s in both.
    pub fn velocity(self) -> f64 {
        self.length()
    }
    /// Densities (kg/m^3 -> g/cm^3).
    pub fn density(self) -> f64 {
        match self {
            Units::Si => 1.0,
            Units::Cgs => 1e-3,
        }
    }
    /// Pressures / Young's modulus (Pa -> barye = dyn/cm^2).
    pub fn pressure(self) -> f64 {
        match self {
            Units::Si => 1.0,
            Units::Cgs => 10.0,
        }
    }
    /// Forces (N -> dyn).
    pub fn force(self) -> f64 {
        match self {
            Units::Si => 1.0,
            Units::Cgs => 1e5,
        }
    }
    /// Mass (kg -> g).
    pub fn mass(self) -> f64 {
        match self {
            Units::Si => 1.0,
            Units::Cgs => 1e3,
        }
    }
    pub(crate) fn length_unit(self) -> &'static str {
        match self {
            Units::Si => "m",
            Units::Cgs => "cm",
        }
    }
    pub(crate) fn velocity_unit(self) -> &'static str {
        match self {
            Units::Si => "m/s",
            Units::Cgs => "cm/s",
        }
    }
    pub(crate) fn density_unit(self) -> &'static str {
        match self {
            Units::Si => "kg/m^3",
            Units::Cgs => "g/cm^3",
        }
    }
    pub(crate) fn pressure_unit(self) -> &'static str {
        match self {
            Units::Si => "Pa",
            Units::Cgs => "barye",
        }
    }
    pub(crate) fn force_unit(self) -> &'static str {
        match self {
            Units::Si => "N",
            Units::Cgs => "dyn",
        }
    }
    pub(super) fn names(self) -> &'static str {
        match self {
            Units::Si => "SI: s, m, N",
            Units::Cgs => "cgs: s, cm, dyn",
        }
    }
    /// Young's modulus range LIGGGHTS accepts in this unit system, in that system's units.
    pub(crate) fn youngs_range(self) -> (f64, f64) {
        match self {
            Units::Si => (LIGGGHTS_MIN_E_PA, LIGGGHTS_MAX_E_PA),
            Units::Cgs => (LIGGGHTS_MIN_E_CGS, LIGGGHTS_MAX_E_CGS),
        }
    }
}

/// Si when LIGGGHTS accepts every Young's modulus in SI, else Cgs when it accepts them in
/// cgs, else an error naming the value. Measured on LIGGGHTS 3.8.0, both systems impose
/// the same physical range (5e6..1e9 Pa), so in practice this returns Si or an error; a
/// soft material (e.g. Table 2's G = 1 MPa, E = 2.6 MPa) needs `soft_particles = true`,
/// which disables LIGGGHTS' check without changing the material.
pub fn choose_units(materials: &[Material]) -> Result<Units> {
    'units: for u in [Units::Si, Units::Cgs] {
        let (lo, hi) = u.youngs_range();
        for m in materials {
            let e = m.youngs_modulus * u.pressure();
            if !(e >= lo && e <= hi) {
                continue 'units;
            }
        }
        return Ok(u);
    }
    for (t, m) in materials.iter().enumerate() {
        let e = m.youngs_modulus;
        if !(LIGGGHTS_MIN_E_PA..=LIGGGHTS_MAX_E_PA).contains(&e) {
            bail!(
                "material type {} has youngs_modulus = {e:e} Pa: LIGGGHTS 3.8 accepts 5e6..1e9 Pa in SI units and \
                 5e7..1e10 barye (the same 5e6..1e9 Pa) in cgs units, so no choice of units represents it; \
                 granval does not change materials — set soft_particles (E below the range) or hard_particles \
                 (above) on the deck to make LIGGGHTS skip its range check with the material unchanged",
                t + 1
            );
        }
    }
    bail!("no materials given")
}
