//! LIGGGHTS 3.8 decks for micro cases with rigid multisphere clumps, and the parser of
//! their body dumps. Following the research report (/work/research/clumps/REPORT.md):
//!
//! - Mass properties go in explicitly: `fix particletemplate/multisphere ... mass M
//!   inertia_tensor Ixx 0 0 Iyy 0 Izz use_density` with COM-centred sphere coordinates
//!   (fix_template_multisphere.cpp `post_create`, use_density branch): LIGGGHTS uses the
//!   doubles granval computed (case::clumps), no Monte Carlo, body frame = template frame.
//! - A body can only be created by `fix insert/*` at a random point of a region. Each body
//!   gets its own `fix insert/pack` and a block region one ulp wide per coordinate; the
//!   region's Park-Miller generator is emulated ([`exact_region`]) so the interval is the
//!   one whose drawn point is exactly the requested centre of mass.
//! - Insertion happens in `pre_exchange` of step 1, which then gets only the final half
//!   kick. Dumps are written at steps 1, 1 + N, 1 + 2N ... (`dump_modify every v_...`)
//!   and read back as native steps 0, N, 2N ... (t = (step - 1) dt).
//! - Body state via `compute multisphere property` + `dump local` at %.17g; free spheres
//!   through `dump custom` of their group.
//! - `atom_modify sort 0 0.0` and one process fix the member summation order.

use super::deck::{f, join, model_keywords, write_contact_model, write_hardness};
use crate::case::{Case, Wall};
use crate::rundata::frames::{BodyState, Frame};
use anyhow::{Context, Result, bail};
use std::fmt::Write;
use std::io::{BufRead, BufReader};
use std::path::Path;

pub(crate) const BODY_DUMP_FILE: &str = "body.granval";

/// Points LIGGGHTS' region draws for its volume estimate before placing (region.cpp
/// `volume_mc`, 3 per try); `ntry_mc` of the insert fix, its minimum.
pub(super) const NTRY_MC: u64 = 1000;

/// Park-Miller minimal standard as LIGGGHTS' RanPark (random_park.cpp:54-80).
pub(super) struct RanPark(pub(super) i64);

impl RanPark {
    const IA: i64 = 16807;
    const IM: i64 = 2147483647;
    const IQ: i64 = 127773;
    const IR: i64 = 2836;
    pub(super) fn uniform(&mut self) -> f64 {
        let k = self.0 / Self::IQ;
        self.0 = Self::IA * (self.0 - k * Self::IQ) - Self::IR * k;
        if self.0 < 0 {
            self.0 += Self::IM;
        }
        (1.0 / Self::IM as f64) * self.0 as f64
    }
}

/// The one-ulp block `[lo, hi]` per coordinate in which `fix insert/pack seed SEED ...
/// ntry_mc NTRY_MC` on one process places its first (accepted) point exactly at `target`:
/// the region generator is reset to seed + 12 (fix_insert_pack.cpp:66, 204), draws
/// 3 ntry_mc numbers for the volume estimate (region.cpp:647-651), then pos = lo + u
/// (hi - lo) (region.cpp:531-544). With hi - lo one ulp, pos is lo for u < 1/2 and hi
/// for u > 1/2. Verified by the research runs for six bodies (bit-identical COM).
pub(crate) fn exact_region(seed: u64, target: [f64; 3]) -> Result<[(f64, f64); 3]> {
    let mut rng = RanPark(seed as i64 + 12);
    for _ in 0..3 * NTRY_MC {
        rng.uniform();
    }
    let mut out = [(0.0, 0.0); 3];
    for (c, t) in target.iter().enumerate() {
        let u = rng.uniform();
        let (lo, hi) = if u < 0.5 {
            (*t, t.next_up())
        } else if u > 0.5 {
            (t.next_down(), *t)
        } else {
            bail!("insert seed {seed}: region draw u = 0.5 exactly; pick another seed");
        };
        let p = lo + u * (hi - lo);
        if p != *t || *t == 0.0 {
            bail!(
                "cannot place coordinate {c} = {t:e} exactly with insert seed {seed} (draw u = {u}, point {p:e}): coordinates must be non-zero"
            );
        }
        out[c] = (lo, hi);
    }
    Ok(out)
}

pub(super) fn is_prime(n: u64) -> bool {
    n >= 2
        && (2..)
            .take_while(|d| d * d <= n)
            .all(|d| !n.is_multiple_of(d))
}

/// Distinct primes for every seed of the deck: LIGGGHTS requires prime seeds above
/// 10000 (random.cpp:79-97), distinct across insert fixes, distributions and templates
/// (fix_insert.cpp:450-479). Deterministic, so the deck is reproducible.
pub(super) fn primes(n: usize) -> Vec<u64> {
    (15_485_863u64..).filter(|&k| is_prime(k)).take(n).collect()
}

/// Refuses what the clump deck cannot express.
fn check(case: &Case) -> Result<()> {
    if case.clumps.is_empty() {
        bail!("{}: not a clump case", case.source.display());
    }
    Ok(())
}

/// The deck of a clump case: free spheres (if any) through `create_atoms`, every body
/// through its own exact-placement insertion; dumps `BODY_DUMP_FILE` and `dump_file`.
pub(crate) fn write_clump_deck(case: &Case, dump_file: &str) -> Result<String> {
    super::deck::check_liggghts_limits(case)?;
    check(case)?;
    let cl = &case.clumps;
    let seeds = primes(2 * cl.templates.len() + cl.bodies.len());
    let mut s = String::new();
    write_clump_header(&mut s, case, dump_file);
    write_box_and_contact_law(&mut s, case)?;
    write_walls(&mut s, case)?;
    crate::engines::deck_text::block(
        &mut s,
        "Clump templates (fix particletemplate/multisphere): member spheres in the body frame, \
         with the mass and principal moments of the union of the spheres computed exactly by \
         granval and given explicitly (`mass ... inertia_tensor ... use_density`), so LIGGGHTS \
         uses these numbers instead of its Monte-Carlo estimate and both engines integrate the \
         same doubles.",
    );
    write_templates(&mut s, &cl.templates, &seeds)?;
    write_free_spheres(&mut s, case)?;
    write_bodies(&mut s, case, &seeds)?;
    write_output_and_run(&mut s, case, dump_file)?;
    Ok(s)
}

/// The header: what the run measures and why LIGGGHTS' steps are one ahead of the
/// native ones (insertion at step 1) and the run is on one process.
fn write_clump_header(s: &mut String, case: &Case, dump_file: &str) {
    let every = case.output_every;
    crate::engines::deck_text::write_header(
        s,
        &crate::engines::deck_text::Header {
            title: format!(
                "granval micro case `{}` with rigid clumps: LIGGGHTS 3.8 input deck",
                crate::engines::deck_text::safe(&case.name)
            ),
            paragraphs: vec![
                crate::engines::deck_text::safe(&case.description),
                format!(
                    "What the run measures: {} rigid multisphere bodies (fix multisphere) and {} free \
                     sphere(s); every {every} steps the bodies' centre of mass, orientation quaternion, \
                     velocity, angular velocity and force go to {BODY_DUMP_FILE} (dump local, 17 \
                     digits) and the free spheres to {dump_file}. granval runs the same case natively \
                     and compares body by body. Units: SI (m, kg, s, N, Pa).",
                    case.clumps.bodies.len(),
                    case.particles.len()
                ),
                "Steps: LIGGGHTS inserts the bodies at step 1 (fix insert/pack), so its step k + 1 \
                 is native step k; the dumps start at step 1. Run it on ONE process (processors 1 1 \
                 1): the members' force sums are then summed in the same order as natively."
                    .to_string(),
            ],
        },
    );
}

/// Units, atom style and map (`fix multisphere` needs the map; no sorting keeps the
/// member summation order), one process, the empty box the bodies are inserted into,
/// neighbour lists, the contact law, time step and gravity.
fn write_box_and_contact_law(s: &mut String, case: &Case) -> Result<()> {
    crate::engines::deck_text::block(
        s,
        "Granular atoms in SI units in a closed box. fix multisphere needs the atom map; \
         `sort 0 0.0` keeps atoms in creation order, so member forces are summed in a fixed \
         order. newton off and ghost velocities as every granular LIGGGHTS run.",
    );
    writeln!(s, "units si")?;
    writeln!(s, "atom_style granular")?;
    // fix multisphere needs the atom map; no sorting keeps the member summation order.
    writeln!(s, "atom_modify map array sort 0 0.0")?;
    writeln!(s, "boundary f f f")?;
    writeln!(s, "newton off")?;
    writeln!(s, "communicate single vel yes")?;
    writeln!(s, "processors 1 1 1")?;
    let (soft, hard) = super::deck::hardness(&case.materials);
    write_hardness(s, &case.materials, soft, hard)?;
    writeln!(
        s,
        "region domain block {} {} {} {} {} {} units box",
        f(case.domain_lo[0]),
        f(case.domain_hi[0]),
        f(case.domain_lo[1]),
        f(case.domain_hi[1]),
        f(case.domain_lo[2]),
        f(case.domain_hi[2])
    )?;
    writeln!(s, "create_box {} domain", case.n_types())?;
    writeln!(s, "neighbor {} bin", f(case.neighbor_skin))?;
    writeln!(s, "neigh_modify delay 0")?;
    write_contact_model(s, &case.materials, &case.pairs, case.rolling, 1.0, "Pa")?;
    writeln!(s, "timestep {}", f(case.dt))?;
    let g = case.gravity;
    let gmag = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    if gmag > 0.0 {
        writeln!(s, "fix gravi all gravity {} vector {}", f(gmag), join(g))?;
    }
    Ok(())
}

/// The case's [[walls]] as `wall/gran` primitives with the contact law of the pair
/// style, as in the sphere deck.
fn write_walls(s: &mut String, case: &Case) -> Result<()> {
    let models = model_keywords(case.rolling);
    for (k, w) in case.walls.iter().enumerate() {
        let prim = match w {
            Wall::Plane { axis, position, .. } => format!("{}plane {}", axis.name(), f(*position)),
            Wall::Cylinder {
                axis,
                radius,
                center,
                ..
            } => format!(
                "{}cylinder {} {} {}",
                axis.name(),
                f(*radius),
                f(center[0]),
                f(center[1])
            ),
        };
        writeln!(
            s,
            "fix w{} all wall/gran {models} primitive type {} {prim}",
            k + 1,
            w.type_() + 1
        )?;
    }
    Ok(())
}

/// `fix multisphere`, then the case's free spheres (if any) as atoms of their own
/// group, integrated as spheres and dumped apart from the bodies.
fn write_free_spheres(s: &mut String, case: &Case) -> Result<()> {
    let free = !case.particles.is_empty();
    writeln!(
        s,
        "fix ms all multisphere{}",
        if free { " allow_group_and_set yes" } else { "" }
    )?;
    if free {
        // Created after fix multisphere so their body id is initialised to -1
        // (set_arrays); they get atom ids 1..n in case order.
        for p in &case.particles {
            writeln!(
                s,
                "create_atoms {} single {} units box",
                p.type_ + 1,
                join(p.x)
            )?;
        }
        for (k, p) in case.particles.iter().enumerate() {
            writeln!(
                s,
                "set atom {} diameter {} density {}",
                k + 1,
                f(2.0 * p.radius),
                f(p.density)
            )?;
        }
        let ids: Vec<String> = (1..=case.particles.len()).map(|k| k.to_string()).collect();
        writeln!(s, "group free id {}", ids.join(" "))?;
        writeln!(s, "fix integr free nve/sphere")?;
    }
    Ok(())
}

/// Every body inserted once, at exactly its centre of mass ([`exact_region`]), with its
/// velocity, angular velocity and orientation; the seeds after the templates'.
fn write_bodies(s: &mut String, case: &Case, seeds: &[u64]) -> Result<()> {
    let cl = &case.clumps;
    crate::engines::deck_text::block(
        s,
        "Bodies: each inserted once by fix insert/pack into a box one floating-point step wide \
         around its centre of mass (the random position LIGGGHTS draws inside it is then the \
         exact centre), with its velocity, angular velocity and orientation.",
    );
    let tseed = 2 * cl.templates.len();
    for (k, b) in cl.bodies.iter().enumerate() {
        let seed = seeds[tseed + k];
        let r = exact_region(seed, b.x)
            .with_context(|| format!("{}: clump id {}", case.source.display(), b.id))?;
        writeln!(
            s,
            "# clump id {}: centre of mass exactly ({})",
            b.id,
            join(b.x)
        )?;
        writeln!(
            s,
            "region ins{} block {} {} {} {} {} {} units box volume_limit 1e-300",
            k + 1,
            f(r[0].0),
            f(r[0].1),
            f(r[1].0),
            f(r[1].1),
            f(r[2].0),
            f(r[2].1)
        )?;
        writeln!(
            s,
            "fix ins{} all insert/pack seed {seed} distributiontemplate pdd{} insert_every once overlapcheck yes all_in no vel constant {} omega constant {} orientation constant {} region ins{} particles_in_region 1 ntry_mc {NTRY_MC}",
            k + 1,
            b.template + 1,
            join(b.v),
            join(b.omega),
            join(b.orientation),
            k + 1
        )?;
    }
    Ok(())
}

/// The body and free-sphere dumps at LIGGGHTS steps 1, 1 + N, ... (native steps 0, N,
/// ...: [`clump_frames`] reads them back so), thermo, and the run one step longer for
/// the insertion step.
fn write_output_and_run(s: &mut String, case: &Case, dump_file: &str) -> Result<()> {
    let every = case.output_every;
    crate::engines::deck_text::block(
        s,
        "Output at LIGGGHTS steps 1, 1 + N, 1 + 2N, ... (native steps 0, N, 2N, ...), the body \
         state from compute multisphere at full precision.",
    );
    // Output at steps 1, 1 + N, 1 + 2N, ...: next(step) = floor((step-1)/N) N + N + 1.
    writeln!(
        s,
        "variable granval_next equal floor((step-1)/{every})*{every}+{every}+1"
    )?;
    write_body_dump(
        s,
        "db",
        &every.to_string(),
        BODY_DUMP_FILE,
        " every v_granval_next",
    )?;
    if !case.particles.is_empty() {
        let dc = super::DUMP_COLUMNS;
        writeln!(s, "dump d free custom {every} {dump_file} {}", dc.join(" "))?;
        let fmt = std::iter::once("%d")
            .chain(std::iter::repeat_n("%.17g", dc.len() - 1))
            .collect::<Vec<_>>()
            .join(" ");
        writeln!(
            s,
            "dump_modify d sort id format \"{fmt}\" every v_granval_next"
        )?;
    }
    writeln!(s, "thermo_style custom step atoms cpu")?;
    writeln!(s, "thermo_modify lost error")?;
    writeln!(s, "thermo {}", (case.n_steps / 20).max(1))?;
    writeln!(s, "run {}", case.n_steps + 1)?;
    Ok(())
}

/// A local dump `name` of every body's state at full precision (id, centre of mass,
/// quaternion, velocity, angular velocity, force), the columns `read_body_dump` reads,
/// written every `every` steps to `file`; `modify` ends its `dump_modify` line.
pub(super) fn write_body_dump(
    s: &mut String,
    name: &str,
    every: &str,
    file: &str,
    modify: &str,
) -> Result<()> {
    let props = [
        ("bid", "id_multisphere", 1),
        ("bx", "xcm", 3),
        ("bq", "quat", 4),
        ("bv", "vcm", 3),
        ("bw", "omega", 3),
        ("bf", "fcm", 3),
    ];
    let mut cols = Vec::new();
    for (c, prop, n) in props {
        writeln!(s, "compute {c} all multisphere property {prop}")?;
        if n == 1 {
            cols.push(format!("c_{c}"));
        } else {
            cols.extend((1..=n).map(|k| format!("c_{c}[{k}]")));
        }
    }
    writeln!(s, "dump {name} all local {every} {file} {}", cols.join(" "))?;
    let fmt = std::iter::once("%.0f")
        .chain(std::iter::repeat_n("%.17g", cols.len() - 1))
        .collect::<Vec<_>>()
        .join(" ");
    writeln!(s, "dump_modify {name} format \"{fmt}\"{modify}")?;
    Ok(())
}

/// The `fix particletemplate/multisphere` and `fix particledistribution/discrete` of
/// every template, with seeds `seeds[2k]`, `seeds[2k + 1]`.
pub(super) fn write_templates(
    s: &mut String,
    templates: &[crate::case::clumps::ClumpTemplate],
    seeds: &[u64],
) -> Result<()> {
    for (k, t) in templates.iter().enumerate() {
        let spheres: Vec<String> = t
            .offsets
            .iter()
            .zip(&t.radii)
            .map(|(o, r)| format!("{} {}", join(*o), f(*r)))
            .collect();
        writeln!(
            s,
            "# template {}: union of the members, mass and principal moments computed by granval",
            super::deck::comment_safe(&t.name)
        )?;
        writeln!(
            s,
            "fix pts{} all particletemplate/multisphere {} atom_type {} density constant {} nspheres {} ntry 100000 spheres {} type {} mass {} inertia_tensor {} 0.0 0.0 {} 0.0 {} use_density",
            k + 1,
            seeds[2 * k],
            t.type_ + 1,
            f(t.density),
            t.radii.len(),
            spheres.join(" "),
            k + 1,
            f(t.mass),
            f(t.inertia[0]),
            f(t.inertia[1]),
            f(t.inertia[2])
        )?;
        writeln!(
            s,
            "fix pdd{} all particledistribution/discrete {} 1 pts{} 1.0",
            k + 1,
            seeds[2 * k + 1],
            k + 1
        )?;
    }
    Ok(())
}

/// The frames of a finished clump run in `dir`, mapped onto native steps: LIGGGHTS step
/// s is native step s - 1; LIGGGHTS body k (insertion order) is the case's k-th clump,
/// free atom k the case's k-th particle.
pub(crate) fn clump_frames(case: &Case, dir: &Path) -> Result<Vec<Frame>> {
    let ids: Vec<u64> = case.clumps.bodies.iter().map(|b| b.id).collect();
    let bodies = read_body_dump(&ids, &dir.join(BODY_DUMP_FILE))?;
    let free = if case.particles.is_empty() {
        None
    } else {
        Some(super::parse_dump(&dir.join(super::DUMP_FILE), case.dt)?)
    };
    let mut out = Vec::with_capacity(bodies.len());
    for (k, (step, bs)) in bodies.into_iter().enumerate() {
        if step == 0 {
            bail!(
                "{}: a body frame at step 0: bodies are inserted at step 1",
                dir.join(BODY_DUMP_FILE).display()
            );
        }
        let native = step - 1;
        let mut particles = Vec::new();
        if let Some(fr) = &free {
            let Some(fs) = fr.get(k) else {
                bail!(
                    "{}: {} frames, fewer than the body dump's",
                    dir.join(super::DUMP_FILE).display(),
                    fr.len()
                );
            };
            if fs.step != step {
                bail!(
                    "{}: frame {k} is step {}, the body dump's is {step}",
                    dir.join(super::DUMP_FILE).display(),
                    fs.step
                );
            }
            for p in &fs.particles {
                let Some(cp) = case.particles.get(p.id as usize - 1) else {
                    bail!("free atom id {} is not one of the case's particles", p.id);
                };
                let mut p = *p;
                p.id = cp.id;
                particles.push(p);
            }
            particles.sort_by_key(|p| p.id);
        }
        out.push(Frame {
            step: native,
            t: native as f64 * case.dt,
            particles,
            bodies: bs,
        });
    }
    Ok(out)
}

/// `dump local` of the body computes: (LIGGGHTS step, bodies with case ids, sorted).
/// LIGGGHTS body k (insertion order) is `ids[k - 1]`; every step must hold them all.
pub(super) fn read_body_dump(ids: &[u64], path: &Path) -> Result<Vec<(u64, Vec<BodyState>)>> {
    let file = crate::rundata::fsio::open_engine_output(path, "a LIGGGHTS body dump")?;
    let mut lines = BufReader::new(file).lines().enumerate();
    let mut out = Vec::new();
    // Set at the end of the file: only there may the steps end; a read error is an error.
    let eof = std::cell::Cell::new(false);
    let mut next = |what: &str| -> Result<(usize, String)> {
        match lines.next() {
            Some((no, l)) => Ok((
                no + 1,
                l.with_context(|| format!("{}: line {}: read error", path.display(), no + 1))?,
            )),
            None => {
                eof.set(true);
                bail!("{}: file ends where {what} was expected", path.display())
            }
        }
    };
    let want = [
        "c_bid", "c_bx[1]", "c_bx[2]", "c_bx[3]", "c_bq[1]", "c_bq[2]", "c_bq[3]", "c_bq[4]",
        "c_bv[1]", "c_bv[2]", "c_bv[3]", "c_bw[1]", "c_bw[2]", "c_bw[3]", "c_bf[1]", "c_bf[2]",
        "c_bf[3]",
    ];
    loop {
        let (no, l) = match next("ITEM: TIMESTEP") {
            Ok(x) => x,
            Err(_) if eof.get() => break,
            Err(e) => return Err(e),
        };
        if l.trim().is_empty() {
            continue;
        }
        if l.trim() != "ITEM: TIMESTEP" {
            bail!(
                "{}: line {no}: expected ITEM: TIMESTEP, found {l:?}",
                path.display()
            );
        }
        let (no, l) = next("a timestep")?;
        let step: u64 = l
            .trim()
            .parse()
            .with_context(|| format!("{}: line {no}: bad timestep {l:?}", path.display()))?;
        next("ITEM: NUMBER OF ENTRIES")?;
        let (no, l) = next("an entry count")?;
        let n: usize = l
            .trim()
            .parse()
            .with_context(|| format!("{}: line {no}: bad entry count {l:?}", path.display()))?;
        let (_, l) = next("ITEM: BOX BOUNDS")?;
        if !l.starts_with("ITEM: BOX BOUNDS") {
            bail!("{}: expected ITEM: BOX BOUNDS, found {l:?}", path.display());
        }
        for _ in 0..3 {
            next("a box bound")?;
        }
        let (no, header) = next("ITEM: ENTRIES")?;
        let cols: Vec<&str> = header
            .strip_prefix("ITEM: ENTRIES")
            .with_context(|| format!("{}: line {no}: expected ITEM: ENTRIES", path.display()))?
            .split_whitespace()
            .collect();
        let idx: Vec<usize> = want
            .iter()
            .map(|w| {
                cols.iter().position(|c| c == w).with_context(|| {
                    format!("{}: line {no}: no column {w} in {cols:?}", path.display())
                })
            })
            .collect::<Result<_>>()?;
        let mut bodies = Vec::with_capacity(n);
        for _ in 0..n {
            let (no, l) = next("a body line")?;
            let v: Vec<f64> = l
                .split_whitespace()
                .map(|x| x.parse::<f64>())
                .collect::<std::result::Result<_, _>>()
                .with_context(|| format!("{}: line {no}: not numbers: {l:?}", path.display()))?;
            if v.len() != cols.len() || v.iter().any(|x| !x.is_finite()) {
                bail!(
                    "{}: line {no}: {} values for {} columns, or a non-finite one (the run blew up?)",
                    path.display(),
                    v.len(),
                    cols.len()
                );
            }
            let c = |k: usize| v[idx[k]];
            let lid = c(0) as usize;
            let Some(id) = ids.get(lid.wrapping_sub(1)) else {
                bail!(
                    "{}: line {no}: body id {lid}, the case has {} clumps",
                    path.display(),
                    ids.len()
                );
            };
            bodies.push(BodyState {
                id: *id,
                x: [c(1), c(2), c(3)],
                q: [c(4), c(5), c(6), c(7)],
                v: [c(8), c(9), c(10)],
                omega: [c(11), c(12), c(13)],
                f: [c(14), c(15), c(16)],
            });
        }
        bodies.sort_by_key(|b| b.id);
        if bodies.len() != ids.len() {
            bail!(
                "{}: step {step} has {} bodies, the case has {} (an insertion failed?)",
                path.display(),
                bodies.len(),
                ids.len()
            );
        }
        out.push((step, bodies));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The research decks' regions (tools/exact_region.py, verified by live runs).
    #[test]
    #[allow(clippy::excessive_precision)]
    fn exact_region_matches_the_research_decks() {
        let r = exact_region(32452843, [0.003, 0.004, 0.004]).unwrap();
        assert_eq!(
            r,
            [
                (0.0029999999999999996, 0.003),
                (0.004, 0.004000000000000001),
                (0.004, 0.004000000000000001)
            ]
        );
        let r = exact_region(49979687, [0.0075, 0.0045, 0.004]).unwrap();
        assert_eq!(
            r,
            [
                (0.007499999999999999, 0.0075),
                (0.0045, 0.0045000000000000005),
                (0.003999999999999999, 0.004)
            ]
        );
    }
}
