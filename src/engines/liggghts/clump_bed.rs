//! A settled bed of rigid clumps (Feng et al. Sec. 3 (f), Fig 3(f)) handed to LIGGGHTS 3.8
//! exactly: every body is inserted where the native engine left it, with its orientation,
//! velocity and angular velocity, by its own `fix insert/pack` into a block one
//! floating-point step wide (the exact placement of [`super::clumps`]), all in one
//! `run 1`, after which the insertion fixes are removed.
//!
//! Why this way. LIGGGHTS 3.8 creates multisphere bodies only through `fix insert/*`
//! (`fix multisphere` cannot adopt atoms from `read_data` or `create_atoms`), and its
//! restart files are binary. Measured on this machine: 6000 dimers inserted in 13.5 s
//! (one step), after which the step costs what it costs without the fixes; a CI bed
//! (about 6700 dimers) takes well under a minute, against minutes of penetration.
//!
//! Exactness with MPI. The region's generator is reset to `seed + 12 + 2 rank` (the
//! insert fix's own seed is shifted by the rank, random.cpp with `proc_shift`, and the
//! region's again, region.cpp `reset_random`), and the rank whose subdomain holds the
//! block draws the point. Each body's prime seed is therefore chosen so that ranks 0 and 1 draw on the
//! same side of 1/2 in every coordinate: the placement is exact on one or two processes
//! ([`EXACT_RANKS`]); with more, a coordinate may land one ulp off. Every run dumps the
//! bodies at the start of the penetration ([`START_DUMP_FILE`]), and granval measures
//! the difference to the native start.
//!
//! Timeline. LIGGGHTS inserts at step 1 (forces with history, final half kick), then the
//! `run` boundary recomputes forces without history; `reset_timestep 0` makes its
//! penetration steps the native ones (`Simulation::setup_settled` does the same two
//! things).

use super::clumps::{NTRY_MC, RanPark, is_prime, read_body_dump, write_body_dump, write_templates};
use super::deck::{f, join};
use crate::case::clumps::{Clump, ClumpTemplate};
use crate::engines::deck_text;
use crate::rundata::frames::BodyState;
use anyhow::{Context, Result, bail};
use std::fmt::Write as _;
use std::io::BufRead;
use std::path::Path;

/// The bodies of the bed (not read by LIGGGHTS: its deck carries them; `granval
/// analyze` reads this file back to know the grains).
pub const BODIES_FILE: &str = "bodies.bed";
/// The bodies at step 0 of the penetration, as LIGGGHTS holds them.
pub(crate) const START_DUMP_FILE: &str = "bodies.start";
/// MPI processes for which the placement is exact.
pub(crate) const EXACT_RANKS: u64 = 2;

const BODIES_HEADER: &str = "# granval clump bed: id x y z qw qx qy qz vx vy vz wx wy wz (SI; centre of mass, unit quaternion, velocity, angular velocity)";

/// The bodies file: one line per body, every number in shortest round-trip form.
pub(crate) fn bodies_text(bodies: &[Clump]) -> String {
    let mut s = String::with_capacity(bodies.len() * 260);
    s.push_str(BODIES_HEADER);
    s.push('\n');
    for b in bodies {
        let nums: Vec<String> =
            b.x.iter()
                .chain(&b.orientation)
                .chain(&b.v)
                .chain(&b.omega)
                .map(|x| f(*x))
                .collect();
        let _ = writeln!(s, "{} {}", b.id, nums.join(" "));
    }
    s
}

/// Reads a [`bodies_text`] file back (every body of template 0).
pub(crate) fn parse_bodies(path: &Path) -> Result<Vec<Clump>> {
    let file = crate::rundata::fsio::open_engine_output(path, "a clump body list")?;
    let mut out = Vec::new();
    for (k, line) in std::io::BufReader::new(file).lines().enumerate() {
        let no = k + 1;
        let line = line.with_context(|| format!("{}:{no}: read error", path.display()))?;
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let tok: Vec<&str> = t.split_whitespace().collect();
        if tok.len() != 14 {
            bail!(
                "{}:{no}: {} columns, expected 14 (id x y z qw qx qy qz vx vy vz wx wy wz)",
                path.display(),
                tok.len()
            );
        }
        let id: u64 = tok[0]
            .parse()
            .with_context(|| format!("{}:{no}: bad id {:?}", path.display(), tok[0]))?;
        let v: Vec<f64> = tok[1..]
            .iter()
            .map(|s| s.parse::<f64>().ok().filter(|x| x.is_finite()))
            .collect::<Option<_>>()
            .with_context(|| {
                format!(
                    "{}:{no}: a number is unparsable or not finite",
                    path.display()
                )
            })?;
        out.push(Clump {
            id,
            template: 0,
            x: [v[0], v[1], v[2]],
            orientation: [v[3], v[4], v[5], v[6]],
            v: [v[7], v[8], v[9]],
            omega: [v[10], v[11], v[12]],
        });
    }
    if out.is_empty() {
        bail!("{}: no bodies", path.display());
    }
    Ok(out)
}

/// The side of 1/2 a one-ulp block must extend to so that a draw `u` lands on `t`.
fn side(u: f64) -> Option<bool> {
    (u != 0.5).then_some(u < 0.5)
}

/// The first draw of each coordinate after the volume estimate, for insert seed `seed`
/// on `rank` (see [`super::clumps::exact_region`]).
fn draws(seed: u64, rank: u64) -> [f64; 3] {
    let mut rng = RanPark((seed + 12 + 2 * rank) as i64);
    for _ in 0..3 * NTRY_MC {
        rng.uniform();
    }
    [rng.uniform(), rng.uniform(), rng.uniform()]
}

/// An insert seed (the next prime from `*next` on) and its one-ulp block whose drawn
/// point is exactly `target` on every rank below [`EXACT_RANKS`]; `*next` moves past it.
pub(crate) fn exact_placement(next: &mut u64, target: [f64; 3]) -> Result<(u64, [(f64, f64); 3])> {
    if let Some(c) = (0..3).find(|&c| target[c] == 0.0 || !target[c].is_finite()) {
        bail!(
            "coordinate {c} = {:e} cannot be placed exactly (a one-ulp block needs a finite, non-zero coordinate)",
            target[c]
        );
    }
    for _ in 0..100_000 {
        let seed = *next;
        *next += 1;
        if !is_prime(seed) {
            continue;
        }
        let d: Vec<[f64; 3]> = (0..EXACT_RANKS).map(|r| draws(seed, r)).collect();
        let mut block = [(0.0, 0.0); 3];
        let ok = (0..3).all(|c| {
            let Some(low) = side(d[0][c]) else {
                return false;
            };
            if d.iter().any(|dr| side(dr[c]) != Some(low)) {
                return false;
            }
            let t = target[c];
            block[c] = if low {
                (t, t.next_up())
            } else {
                (t.next_down(), t)
            };
            // The point LIGGGHTS computes, lo + u (hi - lo), on every rank.
            d.iter()
                .all(|dr| block[c].0 + dr[c] * (block[c].1 - block[c].0) == t)
        });
        if ok {
            return Ok((seed, block));
        }
    }
    bail!("no insert seed places {target:?} exactly (searched 100000 integers)")
}

/// First prime a clump deck uses (LIGGGHTS wants primes above 10000, distinct across
/// templates, distributions and insertions).
const FIRST_SEED: u64 = 15_485_863;

/// The deck block that creates the bed: templates, `fix multisphere`, one exact
/// insertion per body, `run 1`, the insertion fixes removed, the clock reset, and the
/// start dump of the penetration run (`n_steps` long).
pub(crate) fn write_insertion(
    s: &mut String,
    template: &ClumpTemplate,
    bodies: &[Clump],
    n_steps: u64,
) -> Result<()> {
    let mut next = FIRST_SEED;
    let mut template_seeds = Vec::new();
    while template_seeds.len() < 2 {
        if is_prime(next) {
            template_seeds.push(next);
        }
        next += 1;
    }
    deck_text::block(
        s,
        "---- The grains: rigid clumps (Feng et al. Sec. 3 (f)) ----\n\
         The template (fix particletemplate/multisphere): member spheres in the body frame, \
         with the mass and principal moments of the union of the spheres computed exactly by \
         granval and given explicitly (`mass ... inertia_tensor ... use_density`), so LIGGGHTS \
         uses these numbers instead of its Monte-Carlo estimate and both engines integrate the \
         same doubles. `fix multisphere` integrates the bodies (no nve/sphere).",
    );
    write_templates(s, std::slice::from_ref(template), &template_seeds)?;
    writeln!(s, "fix ms all multisphere")?;
    deck_text::block(
        s,
        &format!(
            "The settled bed, body by body: each inserted once by fix insert/pack into a box one \
             floating-point step wide around its centre of mass (the random point LIGGGHTS draws \
             inside it is then the exact centre, on one or {EXACT_RANKS} MPI processes), with its \
             orientation, velocity and angular velocity. The bodies overlap as settled, so no \
             overlap check. {BODIES_FILE} lists the same bodies for granval."
        ),
    );
    let mut names = Vec::with_capacity(bodies.len());
    for (k, b) in bodies.iter().enumerate() {
        let (seed, r) =
            exact_placement(&mut next, b.x).with_context(|| format!("clump id {}", b.id))?;
        let name = format!("b{}", k + 1);
        writeln!(
            s,
            "region {name} block {} {} {} {} {} {} units box volume_limit 1e-300",
            f(r[0].0),
            f(r[0].1),
            f(r[1].0),
            f(r[1].1),
            f(r[2].0),
            f(r[2].1)
        )?;
        writeln!(
            s,
            "fix {name} all insert/pack seed {seed} distributiontemplate pdd1 insert_every once overlapcheck no all_in no vel constant {} omega constant {} orientation constant {} region {name} particles_in_region 1 ntry_mc {NTRY_MC}",
            join(b.v),
            join(b.omega),
            join(b.orientation)
        )?;
        names.push(name);
    }
    deck_text::comment(
        s,
        "Insert at step 1 (forces with history, final half kick of the bodies), then remove \
         the insertion fixes (each would cost time every step) and start the penetration's \
         clock at 0: its step k is the native engine's step k.",
    );
    writeln!(s, "thermo_style custom step atoms ke cpu")?;
    writeln!(s, "thermo_modify lost error")?;
    writeln!(s, "run 1")?;
    for n in &names {
        writeln!(s, "unfix {n}")?;
    }
    writeln!(s, "reset_timestep 0")?;
    deck_text::comment(
        s,
        &format!(
            "The bodies at step 0 of the penetration (the setup of its run), full precision, to \
             {START_DUMP_FILE}: granval compares them with the native start."
        ),
    );
    write_body_dump(s, "dstart", &(n_steps + 1).to_string(), START_DUMP_FILE, "")?;
    Ok(())
}

/// The bodies LIGGGHTS held at step 0 of the penetration, by the ids of `bodies`.
pub(crate) fn read_start(dir: &Path, bodies: &[Clump]) -> Result<Vec<BodyState>> {
    let ids: Vec<u64> = bodies.iter().map(|b| b.id).collect();
    let path = dir.join(START_DUMP_FILE);
    let frames = read_body_dump(&ids, &path)?;
    match frames.as_slice() {
        [(0, b)] => Ok(b.clone()),
        _ => bail!(
            "{}: expected one frame at step 0, found steps {:?}",
            path.display(),
            frames.iter().map(|f| f.0).collect::<Vec<_>>()
        ),
    }
}

/// Largest differences between two start states of the same bodies: position (m),
/// rotation angle (rad), velocity (m/s), angular velocity (rad/s), force (N).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct StartDifference {
    pub x: f64,
    pub angle: f64,
    pub v: f64,
    pub omega: f64,
    pub f: f64,
}

impl StartDifference {
    pub(crate) fn between(a: &[BodyState], b: &[BodyState]) -> Result<StartDifference> {
        if a.len() != b.len() {
            bail!("{} bodies against {}", a.len(), b.len());
        }
        let d = |p: [f64; 3], q: [f64; 3]| {
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        };
        let mut m = StartDifference {
            x: 0.0,
            angle: 0.0,
            v: 0.0,
            omega: 0.0,
            f: 0.0,
        };
        for (p, q) in a.iter().zip(b) {
            if p.id != q.id {
                bail!("body ids differ: {} and {}", p.id, q.id);
            }
            m.x = m.x.max(d(p.x, q.x));
            m.angle = m.angle.max(crate::numerics::quat::rotation_angle(p.q, q.q));
            m.v = m.v.max(d(p.v, q.v));
            m.omega = m.omega.max(d(p.omega, q.omega));
            m.f = m.f.max(d(p.f, q.f));
        }
        Ok(m)
    }

    pub fn text(&self) -> String {
        format!(
            "largest |dx| {:.3e} m, rotation {:.3e} rad, |dv| {:.3e} m/s, |dw| {:.3e} rad/s, |dF| {:.3e} N",
            self.x, self.angle, self.v, self.omega, self.f
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bodies file is the bed, bit for bit.
    #[test]
    fn bodies_read_back_bit_identical() {
        let awk = [
            0.1 + 0.2,
            1.0 / 3.0,
            -2.2250738585072014e-308,
            1e-300,
            5e-324,
        ];
        let bodies: Vec<Clump> = (0..5)
            .map(|i| Clump {
                id: 7 + i as u64,
                template: 0,
                x: [awk[i], -awk[(i + 1) % 5], 1e-3 / 7.0],
                orientation: crate::physics::dem::rigid::qnormalize([
                    0.3,
                    -0.1 * i as f64,
                    awk[i],
                    0.7,
                ]),
                v: [awk[(i + 2) % 5], -0.0, 0.0],
                omega: [1.0 / 7.0, awk[(i + 3) % 5], -3e5],
            })
            .collect();
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join(BODIES_FILE);
        std::fs::write(&p, bodies_text(&bodies)).unwrap();
        let back = parse_bodies(&p).unwrap();
        let bits = |b: &[Clump]| -> Vec<u64> {
            b.iter()
                .flat_map(|c| {
                    std::iter::once(c.id).chain(
                        c.x.iter()
                            .chain(&c.orientation)
                            .chain(&c.v)
                            .chain(&c.omega)
                            .map(|x| x.to_bits()),
                    )
                })
                .collect()
        };
        assert_eq!(bits(&bodies), bits(&back));
        std::fs::write(&p, "1 2 3\n").unwrap();
        let e = parse_bodies(&p).unwrap_err().to_string();
        assert!(e.contains("3 columns"), "{e}");
    }

    /// The chosen block gives the target on ranks 0 and 1, and seeds are distinct primes.
    #[test]
    fn placement_is_exact_on_two_ranks() {
        let mut next = FIRST_SEED;
        let mut seeds = Vec::new();
        for k in 0..50 {
            let t = [
                -0.0123 + 1e-4 * k as f64,
                0.0071 / (k + 1) as f64,
                3e-3 + 1e-5 * k as f64,
            ];
            let (seed, block) = exact_placement(&mut next, t).unwrap();
            assert!(is_prime(seed) && seeds.last().is_none_or(|&s| s < seed));
            seeds.push(seed);
            for rank in 0..EXACT_RANKS {
                let u = draws(seed, rank);
                for c in 0..3 {
                    let (lo, hi) = block[c];
                    assert!(hi > lo && lo.next_up() == hi);
                    assert_eq!(
                        lo + u[c] * (hi - lo),
                        t[c],
                        "body {k} rank {rank} coord {c}"
                    );
                }
            }
        }
        assert!(exact_placement(&mut next, [1e-3, 0.0, 1e-3]).is_err());
    }
}
