//! Rigid multisphere clumps: templates (member spheres in the body frame) and bodies
//! (a template placed at a centre of mass with an orientation), as LIGGGHTS 3.8's
//! `fix particletemplate/multisphere` + `fix multisphere` simulate them.
//!
//! Mass properties. LIGGGHTS' default is a Monte-Carlo estimate of the union volume
//! (fix_template_multiplespheres.cpp `calc_center_of_mass`, fix_template_multisphere.cpp
//! `calc_inertia`): overlapping regions count once, but the estimate is off by ~1e-3 in
//! mass, rotates the principal frame arbitrarily about a symmetry axis, and Debian's
//! 3.8.0 carries a yz symmetrisation bug (fix_template_multisphere.cpp:428). granval
//! therefore uses the same *convention* (uniform density over the union of the member
//! spheres) but computes it exactly, and hands LIGGGHTS the numbers through
//! `mass M inertia_tensor ... use_density` (fix_template_multisphere.cpp `post_create`,
//! branch use_density: sphere coordinates used as given, no Monte Carlo in the physics),
//! so both engines integrate the same doubles (research report /work/research/clumps).
//!
//! Exact union integrals exist in closed form when the member centres lie on one line:
//! every cross-section perpendicular to the line is a disc whose radius is the largest of
//! the members' slice radii, so the union is a solid of revolution with a piecewise
//! quadratic squared profile. Members must therefore lie on the template's x axis; the
//! inertia tensor is then diagonal in the template frame (x the symmetry axis), which is
//! also what keeps LIGGGHTS' Jacobi step exact (a diagonal input returns the identity,
//! math_extra.cpp:152).

use super::error::{CaseError, Ctx};
use super::fields::{finite, positive, vec3};
use serde::{Deserialize, Serialize};

/// `[[clump_templates]]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawTemplate {
    pub name: String,
    #[serde(rename = "type")]
    pub type_: usize,
    pub density: f64,
    pub spheres: Vec<RawMember>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawMember {
    /// Centre in the body frame relative to the clump's centre of mass (m).
    pub offset: [f64; 3],
    pub radius: f64,
}

/// `[[clumps]]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawClump {
    pub id: u64,
    pub template: String,
    /// Centre of mass (m).
    pub x: [f64; 3],
    /// Unit quaternion (w, x, y, z) rotating the template frame into the space frame.
    #[serde(default = "identity")]
    pub orientation: [f64; 4],
    #[serde(default)]
    pub v: [f64; 3],
    /// Space-frame angular velocity (rad/s).
    #[serde(default)]
    pub omega: [f64; 3],
}

fn identity() -> [f64; 4] {
    [1.0, 0.0, 0.0, 0.0]
}

/// A validated template: members relative to the centre of mass, in the principal frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClumpTemplate {
    pub name: String,
    /// 0-based atom type of every member.
    pub type_: usize,
    pub density: f64,
    pub offsets: Vec<[f64; 3]>,
    pub radii: Vec<f64>,
    /// Union volume (m^3), mass (kg), principal moments about the centre of mass (kg m^2).
    pub volume: f64,
    pub mass: f64,
    pub inertia: [f64; 3],
    /// Radius of the sphere about the centre of mass that contains every member.
    pub bounding_radius: f64,
}

/// A validated body (also a settled grain of a penetration bed, hence `Deserialize`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Clump {
    pub id: u64,
    /// Index into [`Clumps::templates`].
    pub template: usize,
    pub x: [f64; 3],
    pub orientation: [f64; 4],
    pub v: [f64; 3],
    pub omega: [f64; 3],
}

#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Clumps {
    pub templates: Vec<ClumpTemplate>,
    pub bodies: Vec<Clump>,
}

impl Clumps {
    pub fn is_empty(&self) -> bool {
        self.bodies.is_empty()
    }
    pub(crate) fn template_of(&self, body: &Clump) -> &ClumpTemplate {
        &self.templates[body.template]
    }
}

/// Largest |q|^2 - 1 accepted. LIGGGHTS accepts 1e-10 and does not renormalise
/// (fix_insert.cpp:439-440); granval asks for a quaternion given to full precision.
pub(crate) const QUAT_NORM_TOL: f64 = 1e-12;

/// Allowed |centre of mass| of the offsets as a fraction of the largest radius: the
/// union COM is computed in floating point, so an exactly symmetric clump comes out at
/// ~1e-17 m, not 0.
pub(crate) const COM_TOL_FRAC: f64 = 1e-12;

/// Union volume, first moment along x, and the three second-moment integrals of the
/// union of collinear spheres (centres `c_k` on the x axis): returns
/// (V, int x dV, int (y^2+z^2) dV, int x^2 dV).
fn union_integrals(c: &[f64], r: &[f64]) -> (f64, f64, f64, f64) {
    let n = c.len();
    // Squared slice radius of member k at x: r_k^2 - (x - c_k)^2.
    let h = |k: usize, x: f64| r[k] * r[k] - (x - c[k]) * (x - c[k]);
    let mut cuts: Vec<f64> = Vec::new();
    for k in 0..n {
        cuts.push(c[k] - r[k]);
        cuts.push(c[k] + r[k]);
        for j in k + 1..n {
            if c[j] != c[k] {
                // h_k(x) = h_j(x) is linear in x: one crossing.
                cuts.push(
                    (r[k] * r[k] - r[j] * r[j] + c[j] * c[j] - c[k] * c[k]) / (2.0 * (c[j] - c[k])),
                );
            }
        }
    }
    cuts.sort_by(f64::total_cmp);
    let lo = (0..n).map(|k| c[k] - r[k]).fold(f64::INFINITY, f64::min);
    let hi = (0..n)
        .map(|k| c[k] + r[k])
        .fold(f64::NEG_INFINITY, f64::max);
    cuts.retain(|&x| x >= lo && x <= hi);
    cuts.dedup();
    let pi = std::f64::consts::PI;
    let (mut v, mut mx, mut iax, mut ix2) = (0.0, 0.0, 0.0, 0.0);
    for w in cuts.windows(2) {
        let (a, b) = (w[0], w[1]);
        if b <= a {
            continue;
        }
        let mid = 0.5 * (a + b);
        let Some(k) = (0..n)
            .filter(|&k| h(k, mid) > 0.0)
            .max_by(|&i, &j| h(i, mid).total_cmp(&h(j, mid)))
        else {
            continue; // a gap (cannot happen for connected members, kept for safety)
        };
        let (cc, rr) = (c[k], r[k]);
        let r2 = rr * rr;
        // Antiderivatives in u = x - c of the slice integrands (x = u + c).
        let p0 = |u: f64| r2 * u - u * u * u / 3.0;
        let p1 = |u: f64| r2 * u * u / 2.0 - u * u * u * u / 4.0;
        let p4 = |u: f64| r2 * r2 * u - 2.0 * r2 * u * u * u / 3.0 + u.powi(5) / 5.0;
        let p3 = |u: f64| r2 * u * u * u / 3.0 - u.powi(5) / 5.0;
        let (ua, ub) = (a - cc, b - cc);
        let d = |f: &dyn Fn(f64) -> f64| f(ub) - f(ua);
        let i0 = d(&p0); // int (r^2 - u^2)
        let i1 = d(&p1); // int u (r^2 - u^2)
        let i4 = d(&p4); // int (r^2 - u^2)^2
        let i3 = d(&p3); // int u^2 (r^2 - u^2)
        v += pi * i0;
        mx += pi * (i1 + cc * i0);
        // Disc of radius rho: int (y^2 + z^2) dA = pi rho^4 / 2.
        iax += 0.5 * pi * i4;
        ix2 += pi * (i3 + 2.0 * cc * i1 + cc * cc * i0);
    }
    (v, mx, iax, ix2)
}

/// Mass properties of the union of collinear members at `offsets` (all y = z = 0), density
/// `rho`: (volume, mass, principal moments [I_xx, I_yy, I_zz], x of the centre of mass).
pub(crate) fn union_mass_properties(
    xs: &[f64],
    radii: &[f64],
    rho: f64,
) -> (f64, f64, [f64; 3], f64) {
    let (v, mx, iax, ix2) = union_integrals(xs, radii);
    let com = mx / v;
    // About a transverse axis through the COM: int (x^2 + y^2) dm where int y^2 = iax/2;
    // parallel-axis shift of the x^2 part to the COM.
    let transverse = 0.5 * iax + ix2 - com * com * v;
    (
        v,
        rho * v,
        [rho * iax, rho * transverse, rho * transverse],
        com,
    )
}

pub(super) fn templates(
    ctx: &Ctx,
    raw: &[RawTemplate],
    n_types: usize,
) -> Result<Vec<ClumpTemplate>, CaseError> {
    let mut out: Vec<ClumpTemplate> = Vec::new();
    for (k, t) in raw.iter().enumerate() {
        let f = |name: &str| format!("clump_templates[{k}].{name}");
        if t.name.is_empty() || out.iter().any(|o| o.name == t.name) {
            return Err(ctx.bad(
                f("name"),
                &t.name,
                "template names must be non-empty and unique",
            ));
        }
        if t.type_ < 1 || t.type_ > n_types {
            return Err(ctx.bad(f("type"), t.type_, format!("must be in 1..={n_types}")));
        }
        let density = positive(ctx, &f("density"), t.density)?;
        if t.spheres.len() < 2 {
            return Err(ctx.bad(
                f("spheres"),
                t.spheres.len(),
                "a clump needs at least 2 member spheres (a single sphere is a [[particles]] entry)",
            ));
        }
        let mut offsets = Vec::new();
        let mut radii = Vec::new();
        for (m, s) in t.spheres.iter().enumerate() {
            let g = |name: &str| format!("clump_templates[{k}].spheres[{m}].{name}");
            let o = vec3(ctx, &g("offset"), s.offset)?;
            if o[1] != 0.0 || o[2] != 0.0 {
                return Err(ctx.bad(
                    g("offset"),
                    o,
                    "member centres must lie on the template x axis (y = z = 0): exact union mass properties are implemented for collinear members only",
                ));
            }
            offsets.push(o);
            radii.push(positive(ctx, &g("radius"), s.radius)?);
        }
        // Members must form one connected cluster (each touching or overlapping another):
        // otherwise the "union" is two bodies joined by nothing.
        let n = offsets.len();
        let mut reached = vec![false; n];
        reached[0] = true;
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            for j in 0..n {
                let d = (offsets[i][0] - offsets[j][0]).abs();
                if !reached[j] && d <= radii[i] + radii[j] {
                    reached[j] = true;
                    stack.push(j);
                }
            }
        }
        if let Some(j) = reached.iter().position(|r| !r) {
            return Err(ctx.bad(
                format!("clump_templates[{k}].spheres[{j}].offset"),
                offsets[j],
                "member does not touch or overlap the other members (|c_i - c_j| > r_i + r_j for all)",
            ));
        }
        for i in 0..n {
            for j in i + 1..n {
                if offsets[i] == offsets[j] && radii[i] == radii[j] {
                    return Err(ctx.bad(
                        format!("clump_templates[{k}].spheres[{j}]"),
                        offsets[j],
                        format!("duplicates member {i}"),
                    ));
                }
            }
        }
        let xs: Vec<f64> = offsets.iter().map(|o| o[0]).collect();
        let (volume, mass, inertia, com) = union_mass_properties(&xs, &radii, density);
        let rmax = radii.iter().copied().fold(0.0, f64::max);
        if com.abs() > COM_TOL_FRAC * rmax {
            return Err(ctx.bad(
                f("spheres"),
                xs,
                format!(
                    "offsets must be relative to the clump's centre of mass (uniform density over the union of the members), which is at x = {com:e} m: subtract it from every offset"
                ),
            ));
        }
        let bounding_radius = (0..n)
            .map(|i| offsets[i][0].abs() + radii[i])
            .fold(0.0, f64::max);
        out.push(ClumpTemplate {
            name: t.name.clone(),
            type_: t.type_ - 1,
            density,
            offsets,
            radii,
            volume,
            mass,
            inertia,
            bounding_radius,
        });
    }
    Ok(out)
}

/// Validates the bodies; `lo`/`hi` the domain, `taken` the ids of free spheres.
pub(super) fn bodies(
    ctx: &Ctx,
    raw: &[RawClump],
    templates: &[ClumpTemplate],
    lo: [f64; 3],
    hi: [f64; 3],
    taken: &std::collections::HashSet<u64>,
) -> Result<Vec<Clump>, CaseError> {
    let mut out = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for (k, b) in raw.iter().enumerate() {
        let f = |name: &str| format!("clumps[{k}].{name}");
        if b.id == 0 || taken.contains(&b.id) || !seen.insert(b.id) {
            return Err(ctx.bad(
                f("id"),
                b.id,
                "ids must be positive and unique among clumps and particles",
            ));
        }
        let Some(t) = templates.iter().position(|t| t.name == b.template) else {
            return Err(ctx.bad(
                f("template"),
                &b.template,
                format!(
                    "no such clump template; defined: {:?}",
                    templates.iter().map(|t| &t.name).collect::<Vec<_>>()
                ),
            ));
        };
        let x = vec3(ctx, &f("x"), b.x)?;
        // LIGGGHTS places a body only through random insertion; granval's exact placement
        // uses a one-ulp-wide region around each coordinate, which underflows at 0.
        if let Some(c) = (0..3).find(|&c| x[c] == 0.0) {
            return Err(ctx.bad(
                format!("clumps[{k}].x[{c}]"),
                0.0,
                "a clump centre coordinate of exactly 0 cannot be placed exactly in LIGGGHTS (one-ulp insertion region underflows): shift the scene",
            ));
        }
        let rb = templates[t].bounding_radius;
        for c in 0..3 {
            if x[c] - rb < lo[c] || x[c] + rb > hi[c] {
                return Err(ctx.bad(
                    f("x"),
                    x,
                    format!(
                        "the clump's bounding sphere (radius {rb:e} m) must lie inside the domain box: LIGGGHTS refuses insertion within r_bound of the box"
                    ),
                ));
            }
        }
        let q = b.orientation;
        for (c, v) in q.iter().enumerate() {
            finite(ctx, &format!("clumps[{k}].orientation[{c}]"), *v)?;
        }
        let n2 = q.iter().map(|v| v * v).sum::<f64>();
        if (n2 - 1.0).abs() > QUAT_NORM_TOL {
            return Err(ctx.bad(
                f("orientation"),
                q,
                format!(
                    "must be a unit quaternion (w, x, y, z) to |q|^2 - 1 <= {QUAT_NORM_TOL:e}; |q|^2 = {n2:.17}"
                ),
            ));
        }
        out.push(Clump {
            id: b.id,
            template: t,
            x,
            orientation: q,
            v: vec3(ctx, &f("v"), b.v)?,
            omega: vec3(ctx, &f("omega"), b.omega)?,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The research report's exact rational values (tools/union_inertia.py) for r = 1 mm,
    /// rho = 2500: dimer with centres 1 mm apart, trimer with centres 1 mm apart.
    #[test]
    #[allow(clippy::excessive_precision)] // the report's %.17g values, verbatim
    fn union_matches_exact_rational_integration() {
        let (_, m, i, com) = union_mass_properties(&[-0.0005, 0.0005], &[1e-3, 1e-3], 2500.0);
        approx::assert_relative_eq!(m, 1.7671458676442589e-05, max_relative = 1e-14);
        approx::assert_relative_eq!(i[0], 7.5103699374880988e-12, max_relative = 1e-13);
        approx::assert_relative_eq!(i[1], 1.3032700773876408e-11, max_relative = 1e-13);
        assert!(com.abs() < 1e-18);
        let (_, m, i, _) =
            union_mass_properties(&[-0.001, 0.0, 0.001], &[1e-3, 1e-3, 1e-3], 2500.0);
        approx::assert_relative_eq!(m, 2.4870941840919194e-05, max_relative = 1e-14);
        approx::assert_relative_eq!(i[0], 1.0831949670189807e-11, max_relative = 1e-13);
        approx::assert_relative_eq!(i[1], 3.0712340681187716e-11, max_relative = 1e-13);
    }

    #[test]
    fn separate_spheres_are_two_spheres() {
        // Touching members: the union is the sum, I_yy by the parallel-axis theorem.
        let (v, _, i, _) = union_mass_properties(&[-1.0, 1.0], &[1.0, 1.0], 1.0);
        let pi = std::f64::consts::PI;
        approx::assert_relative_eq!(v, 8.0 * pi / 3.0, max_relative = 1e-14);
        approx::assert_relative_eq!(i[0], 2.0 * 0.4 * 4.0 * pi / 3.0, max_relative = 1e-14);
        approx::assert_relative_eq!(
            i[1],
            2.0 * (0.4 + 1.0) * 4.0 * pi / 3.0,
            max_relative = 1e-14
        );
    }
}
