//! Plausible magnitudes of a case's SI inputs, and the warning that names the likely
//! unit mistake when a value lies outside them (a Young's modulus typed in GPa, a
//! density in g/cm^3, a radius in mm). Validation refuses only what cannot run; a value
//! that runs but is almost certainly in the wrong unit is a warning, printed on stderr
//! and kept in the report's notes, and it is appended to a validation error that it
//! probably caused (a density of 2.5 shrinks the Rayleigh time, and the error then
//! names the time step).
//!
//! Every bound is in this one place ([`Bounds`]); each says why it is where it is.

/// The bounds a value is checked against. A value outside them warns; the bounds are
/// deliberately wide (a factor of ten or more beyond any material granular DEM is used
/// for), so no real case warns and a unit slip (a factor 1e3 to 1e9) always does.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Bounds {
    pub min: f64,
    pub max: f64,
}

/// Young's or shear modulus (Pa). Below 1e5 Pa is softer than soft rubber or foam
/// (DEM's deliberately softened grains use 1e6 Pa and up); above 1e13 Pa is ten times
/// diamond (1.1e12 Pa). A modulus typed in GPa (`63` for glass) lands 1e9 too low.
pub(crate) const MODULUS_PA: Bounds = Bounds {
    min: 1e5,
    max: 1e13,
};

/// Grain density (kg/m^3). Below 100 is lighter than cork or any solid grain; above
/// 25 000 is denser than osmium (22 590), the densest element. A density typed in
/// g/cm^3 (`2.5`) lands 1e3 too low.
pub(crate) const DENSITY_KG_M3: Bounds = Bounds {
    min: 100.0,
    max: 25_000.0,
};

/// Grain or intruder size, radius or diameter (m). Below 1 um, van der Waals forces the
/// contact laws here ignore dominate; above 1 m is a boulder. A size typed in mm (`2`)
/// lands 1e3 too high, one typed in um 1e6.
pub(crate) const SIZE_M: Bounds = Bounds {
    min: 1e-6,
    max: 1.0,
};

/// Largest initial overlap of two spheres (or a sphere and a wall) as a fraction of the
/// smaller radius. A hand-placed start overlaps by round-off at most; 1 % already stores
/// an elastic energy comparable to an impact of a few m/s for stiff grains, released in
/// the first step (a typo in a coordinate, or radii in the wrong unit).
pub(crate) const MAX_INITIAL_OVERLAP_FRAC: f64 = 0.01;

use crate::numerics::fmt::typed as num;

/// The first of `units` (name, factor to SI) that brings `v` inside `b`.
fn likely_unit(v: f64, b: Bounds, units: &[(&'static str, f64)]) -> Option<(&'static str, f64)> {
    units
        .iter()
        .map(|&(name, f)| (name, v * f))
        .find(|&(_, si)| si >= b.min && si <= b.max)
}

/// A warning for a modulus field (`what`: "E" or "G"), if implausible.
pub fn modulus(field: &str, what: &str, v: f64) -> Option<String> {
    let b = MODULUS_PA;
    if !v.is_finite() || (v >= b.min && v <= b.max) {
        return None;
    }
    // GPa first: moduli of grains are GPa (glass 63, steel 200); MPa for soft ones.
    let hint = if v < b.min {
        match likely_unit(
            v,
            Bounds {
                min: 1e6,
                max: 1e12,
            },
            &[("GPa", 1e9), ("MPa", 1e6)],
        ) {
            Some((u, si)) => format!("did you mean {} {u} = {} Pa?", num(v), num(si)),
            None => "softer than any solid grain material".into(),
        }
    } else {
        "stiffer than any material (diamond: 1.1e12 Pa); check the exponent".into()
    };
    Some(format!(
        "{field}: {what} = {} Pa: {hint} (plausible: {} to {} Pa)",
        num(v),
        num(b.min),
        num(b.max)
    ))
}

/// A warning for a density field, if implausible.
pub fn density(field: &str, v: f64) -> Option<String> {
    let b = DENSITY_KG_M3;
    if !v.is_finite() || (v >= b.min && v <= b.max) {
        return None;
    }
    let hint = if v < b.min {
        match likely_unit(v, b, &[("g/cm^3", 1e3)]) {
            Some((u, si)) => format!("in {u}? {} {u} = {} kg/m^3", num(v), num(si)),
            None => "lighter than any solid grain material".into(),
        }
    } else {
        "denser than any element (osmium: 22 590 kg/m^3)".into()
    };
    Some(format!(
        "{field} = {} kg/m^3: {hint} (plausible: {} to {} kg/m^3)",
        num(v),
        num(b.min),
        num(b.max)
    ))
}

/// A warning for a grain size field (a radius or a diameter, in m), if implausible.
pub fn size(field: &str, v: f64) -> Option<String> {
    let b = SIZE_M;
    if !v.is_finite() || v <= 0.0 || (v >= b.min && v <= b.max) {
        return None;
    }
    let hint = if v > b.max {
        match likely_unit(v, b, &[("mm", 1e-3), ("um", 1e-6)]) {
            Some((u, si)) => format!("in {u}? {} {u} = {} m", num(v), num(si)),
            None => "larger than any grain".into(),
        }
    } else {
        "smaller than any grain these contact laws describe".into()
    };
    Some(format!(
        "{field} = {} m: {hint} (plausible: {} to {} m)",
        num(v),
        num(b.min),
        num(b.max)
    ))
}

/// A warning for an initial overlap `delta` (m) of a sphere of radius `r` (the smaller
/// of the two) with another body named in `what`, if above [`MAX_INITIAL_OVERLAP_FRAC`].
pub fn overlap(what: &str, delta: f64, r: f64) -> Option<String> {
    (delta > MAX_INITIAL_OVERLAP_FRAC * r).then(|| {
        format!(
            "{what} overlap by {} m = {:.1} % of the smaller radius at t = 0 (plausible: at most {} %); a coordinate or a radius may be mistyped",
            num(delta),
            100.0 * delta / r,
            100.0 * MAX_INITIAL_OVERLAP_FRAC
        )
    })
}

/// Warnings for the materials of a case (`materials[k]`).
pub(super) fn materials(raw: &[super::schema::Material]) -> Vec<String> {
    raw.iter()
        .enumerate()
        .flat_map(|(k, m)| {
            [
                m.youngs_modulus
                    .and_then(|e| modulus(&format!("materials[{k}].youngs_modulus"), "E", e)),
                m.shear_modulus
                    .and_then(|g| modulus(&format!("materials[{k}].shear_modulus"), "G", g)),
            ]
        })
        .flatten()
        .collect()
}

/// Warnings for clump templates (`clump_templates[k]`): density and member radii.
pub(super) fn templates(raw: &[super::clumps::RawTemplate]) -> Vec<String> {
    let mut w = Vec::new();
    for (k, t) in raw.iter().enumerate() {
        w.extend(density(&format!("clump_templates[{k}].density"), t.density));
        for (j, s) in t.spheres.iter().enumerate() {
            w.extend(size(
                &format!("clump_templates[{k}].spheres[{j}].radius"),
                s.radius,
            ));
        }
    }
    w
}

/// Warnings for a micro case as written: materials, particles (size, density, overlaps
/// with each other and with the walls) and clump templates.
pub(super) fn micro(raw: &super::schema::CaseFile) -> Vec<String> {
    use super::schema::Wall;
    let mut w = materials(&raw.materials);
    let ps = &raw.particles;
    for (k, p) in ps.iter().enumerate() {
        w.extend(size(&format!("particles[{k}].radius"), p.radius));
        w.extend(density(&format!("particles[{k}].density"), p.density));
    }
    // The first pair only, found on a hash grid (O(N): a case of 1e5 grains is checked
    // as fast as one of two).
    let x: Vec<[f64; 3]> = ps.iter().map(|p| p.x).collect();
    let r: Vec<f64> = ps.iter().map(|p| p.radius).collect();
    if let Some((i, j, delta)) =
        crate::numerics::overlap::first_overlap(&x, &r, MAX_INITIAL_OVERLAP_FRAC)
    {
        let (i, j) = (i.min(j), i.max(j));
        w.extend(overlap(
            &format!("particles[{i}] and particles[{j}]"),
            delta,
            r[i].min(r[j]),
        ));
    }
    let axis = |s: &str| match s {
        "x" => Some(0),
        "y" => Some(1),
        "z" => Some(2),
        _ => None,
    };
    for (k, wall) in raw.walls.iter().enumerate() {
        for (i, p) in ps.iter().enumerate() {
            let delta = match wall {
                Wall::Plane {
                    axis: a, position, ..
                } => axis(a).map(|c| p.radius - (p.x[c] - position).abs()),
                Wall::Cylinder {
                    axis: a,
                    radius,
                    center,
                    ..
                } => axis(a).filter(|&c| c == 2).map(|_| {
                    let rho = ((p.x[0] - center[0]).powi(2) + (p.x[1] - center[1]).powi(2)).sqrt();
                    rho + p.radius - radius
                }),
            };
            if let Some(delta) = delta {
                w.extend(overlap(
                    &format!("particles[{i}] and walls[{k}]"),
                    delta,
                    p.radius,
                ));
            }
        }
    }
    w.extend(templates(&raw.clump_templates));
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_modulus_in_gpa_is_named() {
        let w = modulus("materials[0].youngs_modulus", "E", 63.0).unwrap();
        assert!(
            w.contains("E = 63 Pa: did you mean 63 GPa = 6.3e10 Pa?"),
            "{w}"
        );
        let w = modulus("m", "E", 5000.0).unwrap();
        assert!(w.contains("did you mean 5000 MPa = 5e9 Pa?"), "{w}");
        assert!(modulus("m", "E", 2e14).unwrap().contains("diamond"));
        assert!(modulus("m", "E", 6.3e10).is_none());
        assert!(modulus("m", "E", 1e5).is_none());
    }

    #[test]
    fn a_density_in_g_per_cm3_is_named() {
        let w = density("bed.density", 2.5).unwrap();
        assert!(
            w.contains("2.5 kg/m^3: in g/cm^3? 2.5 g/cm^3 = 2500 kg/m^3"),
            "{w}"
        );
        assert!(density("d", 0.01).unwrap().contains("lighter"));
        assert!(density("d", 3e4).unwrap().contains("osmium"));
        assert!(density("d", 2500.0).is_none());
    }

    #[test]
    fn a_size_in_mm_is_named() {
        let w = size("particles[0].radius", 2.0).unwrap();
        assert!(w.contains("2 m: in mm? 2 mm = 0.002 m"), "{w}");
        assert!(size("r", 1e-9).unwrap().contains("smaller"));
        assert!(size("r", 1e-3).is_none());
    }

    #[test]
    fn overlaps_above_one_percent_warn() {
        assert!(overlap("a and b", 0.011e-3, 1e-3).is_some());
        assert!(overlap("a and b", 0.009e-3, 1e-3).is_none());
        assert!(overlap("a and b", -1.0, 1e-3).is_none());
    }
}
