//! The triaxial test of docs/stress.md rule 5: one unit per seed and confining pressure,
//! each sample compacted natively (bed cache: `GRANVAL_BED_CACHE`), then sheared by both
//! engines from the very same state (positions, velocities, spins; walls where the
//! compaction left them; contact history and servo state reset in both).
//!
//! Output layout of `compare`: `OUT/<unit>/liggghts/` (the deck directory with
//! `walls.txt`), `OUT/<unit>/native/` (`walls.csv`, provenance), and in `OUT` the series
//! `series_<unit>_<engine>.csv` (eps_a, eps_v, the three stresses, phi_mob) and
//! `phi_mob_<unit>.svg`.

use super::reference::Verified;
use super::{DeckFiles, Derived, Estimate, Experiment, Options, Role, Run, Verdict};
use crate::analysis::triaxial::{self as at, Observables, Windows};
use crate::case::triaxial::TriaxialCase;
use crate::compare::Check;
use crate::engines::liggghts::triaxial as lt;
use crate::physics::dem::triaxial::{self as pt, Sample};
use crate::rundata::provenance::{
    EngineKind, Provenance, Sha256, read_provenance, write_provenance,
};
use crate::rundata::triaxial::{WallRecord, write_csv};
use anyhow::{Context, Result, ensure};
use std::io::Write as _;
use std::path::Path;

pub const PROVENANCE_FILE: &str = "provenance.json";
pub(crate) const WALLS_CSV: &str = "walls.csv";

pub struct Triaxial {
    pub case: TriaxialCase,
}

/// One sample: a seed at one confining pressure.
pub struct Unit {
    pub seed: u64,
    pub sigma_c: f64,
    pub sample: Sample,
    pub sample_hash: Sha256,
}

/// A shear run of either engine.
pub struct TriaxialRun {
    pub records: Vec<WallRecord>,
    pub provenance: Provenance,
}

impl Run for TriaxialRun {
    fn provenance(&self) -> &Provenance {
        &self.provenance
    }
}

/// Fingerprint of a sample (positions, velocities, spins, radii, walls), so a recorded
/// LIGGGHTS run is only ever compared with a native run from the very same state.
pub fn sample_hash(s: &Sample) -> Sha256 {
    let mut bytes = Vec::with_capacity(s.particles.len() * 80 + 24);
    for p in &s.particles {
        for v in p.x.iter().chain(&p.v).chain(&p.omega).chain([&p.radius]) {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    for v in s.hi {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    Sha256::of(&bytes)
}

/// Compacts (or reads from the bed cache) the sample of `seed` at `sigma_c`.
pub fn prepare(case: &TriaxialCase, seed: u64, sigma_c: f64, progress: bool) -> Result<Sample> {
    let key = (case.canonical_hash().to_string(), seed, sigma_c);
    let cache = super::bed_cache::file("triaxial", &key);
    let count = |s: &Sample| {
        anyhow::ensure!(
            s.particles.len() == case.grains && s.seed == seed && s.sigma_c == sigma_c,
            "a sample of {} grains, seed {}, sigma_c {} Pa; the case compacts {} grains, seed {seed}, to {sigma_c} Pa",
            s.particles.len(),
            s.seed,
            s.sigma_c,
            case.grains
        );
        Ok(())
    };
    if let Some(s) = super::bed_cache::load_cached::<Sample>(cache.as_deref(), &key, count)? {
        return Ok(s);
    }
    let bar = crate::report::progress::status(progress, "compaction");
    let s = pt::compact(case, seed, sigma_c, |t, r, ke| {
        bar.set_message(format!(
            "t = {t:.3} s, stresses / sigma_c {:.3} {:.3} {:.3}, KE / (sigma_c V) {ke:.1e}",
            r[0], r[1], r[2]
        ))
    })?;
    bar.finish_and_clear();
    super::bed_cache::store(cache.as_deref(), &key, &s);
    Ok(s)
}

/// The LIGGGHTS deck of a unit: the same sample, walls, servo and drive as the native run.
pub fn liggghts_deck(case: &TriaxialCase, u: &Unit) -> lt::TriaxialDeck {
    let s = &u.sample;
    let (lo, hi) = pt::domain(case, s.lattice_side);
    let (soft, hard) = crate::engines::liggghts::hardness(&case.materials);
    lt::TriaxialDeck {
        materials: case.materials.clone(),
        pairs: case.pairs.clone(),
        rolling: case.rolling,
        dt: case.dt,
        neighbor_skin: case.neighbor_skin,
        domain_lo: lo,
        domain_hi: hi,
        particles: s.particles.clone(),
        hi: s.hi,
        mesh_centre: pt::mesh_square(case, s.lattice_side).0,
        mesh_circumradius: pt::mesh_circumradius(case, s.lattice_side),
        wall_type: case.wall_type,
        sigma_c: u.sigma_c,
        servo: case.servo,
        z_speed: case.strain_rate * s.hi[2],
        n_steps: case.shear_steps(),
        output_every: case.output_every,
        soft_particles: soft,
        hard_particles: hard,
        header: crate::engines::deck_text::Header {
            title: format!(
                "granval triaxial case `{}`, sample seed {} at sigma_c = {} Pa: LIGGGHTS 3.8 input deck ({})",
                crate::engines::deck_text::safe(&case.name),
                u.seed,
                u.sigma_c,
                lt::DECK_FILE
            ),
            paragraphs: vec![
                crate::engines::deck_text::safe(&case.description),
                crate::engines::deck_text::safe(&s.note()),
            ],
        },
    }
}

fn unit_label(u: &Unit) -> String {
    format!("seed-{}-{}Pa", u.seed, u.sigma_c)
}

impl Triaxial {
    fn windows(&self) -> Windows {
        Windows {
            peak_window: self.case.peak_window,
            critical_state: self.case.critical_state,
            block: self.case.block,
            final_strain: self.case.final_strain,
        }
    }

    /// The outputs of a LIGGGHTS run in `dir`. `inputs_checked`: the caller proved the
    /// inputs are granval's (a run by hand); otherwise (a record, whose seal proves its
    /// fingerprint) a deck that reads differently from today's is noted.
    fn read_liggghts(&self, u: &Unit, dir: &Path, inputs_checked: bool) -> Result<TriaxialRun> {
        let d = liggghts_deck(&self.case, u);
        let (records, mut provenance) = lt::read_outputs(&d, dir)
            .with_context(|| format!("LIGGGHTS run in {}", dir.display()))?;
        if inputs_checked {
            // The fingerprint of what granval writes, without a declared visualisation
            // dump (which changes what is written, not what is computed).
            provenance.input_hash = lt::input_hash_of(&d)?;
        } else if let Ok(on_disk) = crate::rundata::fsio::read_to_string(
            &dir.join(lt::DECK_FILE),
            crate::rundata::fsio::max_engine_output(),
            "a LIGGGHTS deck",
        ) && !crate::engines::deck_text::same_input(&on_disk, &lt::deck_text(&d)?)
        {
            provenance.notes.push(format!(
                "{} differs from the deck granval writes for this case and sample (edited by hand?)",
                dir.join(lt::DECK_FILE).display()
            ));
        }
        provenance.notes.push(u.sample.note());
        Ok(TriaxialRun {
            records,
            provenance,
        })
    }
}

/// `eps_a,eps_v,s_xx,s_yy,s_zz,phi_mob` of a run.
fn write_series(path: &Path, pts: &[at::Point]) -> Result<()> {
    let mut w = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?,
    );
    writeln!(w, "eps_a,eps_v,s_xx,s_yy,s_zz,phi_mob_deg")?;
    for p in pts {
        writeln!(
            w,
            "{:e},{:e},{:e},{:e},{:e},{:e}",
            p.eps_a,
            p.eps_v,
            p.s[0],
            p.s[1],
            p.s[2],
            at::phi_deg(p.s)
        )?;
    }
    w.flush()?;
    Ok(())
}

impl Experiment for Triaxial {
    type Unit = Unit;
    type NativeRun = TriaxialRun;
    type RefRun = TriaxialRun;
    type Case = TriaxialCase;

    fn case(&self) -> &TriaxialCase {
        &self.case
    }
    fn kind(&self) -> &'static str {
        "triaxial"
    }
    fn reference_engine(&self) -> EngineKind {
        EngineKind::Liggghts
    }

    fn estimate(&self) -> Estimate {
        let c = &self.case;
        let n = c.grains as f64;
        let units = (c.seeds.len() * c.confining_pressures.len()) as f64;
        let steps = c.shear_steps() as f64;
        let controls = c.negative_controls.len() as f64;
        Estimate {
            particle_steps: units
                * n
                * (steps * (1.0 + controls) + 0.5 * c.max_compaction_time / c.dt),
            particles: n,
            output_bytes: units * (2.0 + controls) * 250.0 * steps / c.output_every as f64,
            memory_bytes: 3e3 * n + 2e8,
        }
    }

    fn preflight(&self) -> Result<()> {
        crate::engines::liggghts::check_materials(
            &self.case.source,
            &self.case.materials,
            &self.case.pairs,
        )
    }

    fn derived(&self) -> Vec<Derived> {
        let c = &self.case;
        let (side, n) = c.lattice_box();
        vec![
            Derived::new(
                "grains",
                c.grains.to_string(),
                format!(
                    "per sample; lattice {n}^3 in a cube of {:.4} mm (solid fraction {}); {} seed(s) x {} pressure(s) = {} unit(s)",
                    1e3 * side,
                    c.solid_fraction,
                    c.seeds.len(),
                    c.confining_pressures.len(),
                    c.seeds.len() * c.confining_pressures.len()
                ),
            ),
            Derived::new(
                "time step",
                format!("{:e} s", c.dt),
                format!(
                    "{:.2} % of the Rayleigh time {:.4e} s",
                    100.0 * c.dt / c.rayleigh_time,
                    c.rayleigh_time
                ),
            ),
            Derived::new(
                "shear",
                format!("{} steps", c.shear_steps()),
                format!(
                    "eps_dot {} /s to eps_a = {} ({:.4} s simulated); inertial numbers {}",
                    c.strain_rate,
                    c.final_strain,
                    c.shear_steps() as f64 * c.dt,
                    c.confining_pressures
                        .iter()
                        .map(|p| format!(
                            "{:.2e} at {p} Pa",
                            at::inertial_number(c.strain_rate, c.diameter, c.density, *p)
                        ))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ),
        ]
    }

    fn units(&self, opts: &Options) -> Result<Vec<Unit>> {
        let mut out = Vec::new();
        for &seed in &self.case.seeds {
            for &sigma_c in &self.case.confining_pressures {
                let sample = prepare(&self.case, seed, sigma_c, opts.progress)
                    .with_context(|| format!("preparing unit seed-{seed}-{sigma_c}Pa"))?;
                out.push(Unit {
                    seed,
                    sigma_c,
                    sample_hash: sample_hash(&sample),
                    sample,
                });
            }
        }
        Ok(out)
    }

    fn unit_name(&self, u: &Unit) -> String {
        unit_label(u)
    }

    fn fingerprint(&self, u: &Unit) -> Result<Sha256> {
        lt::input_hash_of(&liggghts_deck(&self.case, u))
    }
    fn engine_input(&self, u: &Unit) -> Result<Vec<(&'static str, String)>> {
        lt::inputs(&liggghts_deck(&self.case, u))
    }

    fn run_native(&self, u: &Unit, role: Role, dir: &Path, opts: &Options) -> Result<TriaxialRun> {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let steps = self.case.shear_steps();
        let bar = crate::report::progress::bar(opts.progress, steps, "native shear");
        let (records, mut provenance) = crate::engines::native::triaxial(
            &self.case,
            &u.sample,
            &role.perturbation(),
            steps,
            |s| bar.set_position(s),
        )?;
        bar.finish_and_clear();
        provenance.notes.push(u.sample.note());
        provenance
            .notes
            .push(format!("sample sha256 {}", u.sample_hash));
        write_csv(&dir.join(WALLS_CSV), &records)?;
        write_provenance(&dir.join(PROVENANCE_FILE), &provenance)?;
        Ok(TriaxialRun {
            records,
            provenance,
        })
    }

    fn write_deck(&self, u: &Unit, dir: &Path, opts: &Options) -> Result<()> {
        use crate::engines::viz_dump::{self, VizEngine};
        let d = liggghts_deck(&self.case, u);
        lt::write_deck_dir(&d, dir)?;
        if let Some(n) = opts.viz_every {
            let p = dir.join(lt::DECK_FILE);
            let text = std::fs::read_to_string(&p)
                .with_context(|| format!("cannot read {}", p.display()))?;
            std::fs::write(&p, viz_dump::add(&text, VizEngine::Liggghts, n, d.n_steps)?)
                .with_context(|| format!("cannot write {}", p.display()))?;
        }
        Ok(())
    }

    fn run_reference(&self, u: &Unit, dir: &Path, opts: &Options) -> Result<TriaxialRun> {
        let d = liggghts_deck(&self.case, u);
        let (records, mut provenance) = lt::run(
            &d,
            dir,
            opts.mpi_procs.max(1),
            &super::engine_limits(self, opts),
        )?;
        provenance.notes.push(u.sample.note());
        provenance
            .notes
            .push(format!("sample sha256 {}", u.sample_hash));
        write_provenance(&dir.join(PROVENANCE_FILE), &provenance)?;
        Ok(TriaxialRun {
            records,
            provenance,
        })
    }

    fn record(&self, _u: &Unit, run: &TriaxialRun, run_dir: &Path, rec: &Path) -> Result<()> {
        std::fs::create_dir_all(rec).with_context(|| format!("cannot create {}", rec.display()))?;
        for f in [
            lt::DECK_FILE,
            lt::DATA_FILE,
            lt::WALLS_FILE,
            lt::LOG_FILE,
            lt::STDOUT_FILE,
        ]
        .into_iter()
        .chain(lt::STL_FILES)
        {
            std::fs::copy(run_dir.join(f), rec.join(f))
                .with_context(|| format!("copying {f} into {}", rec.display()))?;
        }
        let mut p = run.provenance.clone();
        p.notes.retain(|n| !n.starts_with("run directory"));
        write_provenance(&rec.join(PROVENANCE_FILE), &p)
    }

    fn read_record(&self, u: &Unit, name: &str, seal: &Verified) -> Result<TriaxialRun> {
        for f in [lt::WALLS_FILE, lt::LOG_FILE, lt::DECK_FILE, PROVENANCE_FILE] {
            seal.file(name, f)?;
        }
        let recorded = read_provenance(&seal.file(name, PROVENANCE_FILE)?)?;
        ensure!(
            recorded.engine == EngineKind::Liggghts,
            "{}: not a LIGGGHTS record (engine {})",
            seal.root.display(),
            recorded.engine
        );
        let dir = seal.unit_files(name)?;
        let mut run = self.read_liggghts(u, &dir, false)?;
        run.provenance = recorded;
        Ok(run)
    }

    /// A run by hand is taken only from the inputs `granval deck` writes for this case
    /// and sample (deck, data file, the six wall meshes; comments and number notation
    /// aside), as every other kind's: an edited input is refused, naming the file.
    /// A deck written with `--viz N` declares its dump, and is checked as written with it.
    fn read_run_dir(&self, u: &Unit, dir: &Path) -> Result<TriaxialRun> {
        use crate::engines::viz_dump::{self, VizEngine};
        let d = liggghts_deck(&self.case, u);
        let mut viz = None;
        for (name, mut text) in lt::inputs(&d)? {
            if name == lt::DECK_FILE {
                (text, viz) =
                    viz_dump::expected_deck(dir, name, &text, VizEngine::Liggghts, d.n_steps)?;
            }
            crate::engines::deck_text::check_same_input(dir, name, &text, name == lt::DATA_FILE)?;
        }
        let mut run = self.read_liggghts(u, dir, true)?;
        run.provenance
            .notes
            .extend(viz.map(|n| viz_dump::note(n, VizEngine::Liggghts)));
        Ok(run)
    }

    fn deck_files(&self) -> DeckFiles {
        DeckFiles {
            binary: "liggghts",
            deck: lt::DECK_FILE,
            log: lt::LOG_FILE,
            inputs: &[
                (
                    lt::DATA_FILE,
                    "the compacted sample (read_data): box, per grain id, type, diameter, density, position, velocity, spin",
                ),
                (
                    "x_lo.stl ... z_hi.stl",
                    "the six walls, one triangle each with its edges far outside the box, at their start positions",
                ),
            ],
            outputs: &[
                (
                    lt::WALLS_FILE,
                    "every output_every steps: step, x_hi y_hi z_hi positions, the grains' force on the six walls along their axes",
                ),
                (
                    lt::LOG_FILE,
                    "LIGGGHTS' log (version, warnings, thermo lines)",
                ),
            ],
        }
    }

    fn drift(&self, previous: &TriaxialRun, now: &TriaxialRun) -> String {
        let last = |r: &TriaxialRun| r.records.last().map(|x| x.f_hi[2]);
        match (last(previous), last(now)) {
            (Some(a), Some(b)) => format!("final axial force {a:.6e} -> {b:.6e} N"),
            _ => "not comparable (empty record)".into(),
        }
    }

    fn checks(
        &self,
        units: &[Unit],
        native: &[TriaxialRun],
        reference: &[TriaxialRun],
        out: &Path,
        opts: &Options,
    ) -> Verdict {
        let c = &self.case;
        let w = self.windows();
        let mut notes = Vec::new();
        let mut checks = Vec::new();
        let _ = std::fs::create_dir_all(out);
        let (mut cs_n, mut cs_r) = (Vec::new(), Vec::new());
        for (k, u) in units.iter().enumerate() {
            let name = unit_label(u);
            notes.push(format!(
                "{name}: {}; I = {:.2e}",
                u.sample.note(),
                at::inertial_number(c.strain_rate, c.diameter, c.density, u.sigma_c)
            ));
            let mut curves: Vec<(EngineKind, Vec<(f64, f64)>)> = Vec::new();
            let mut obs: Vec<Option<Observables>> = Vec::new();
            for (label, run) in [("native", native.get(k)), ("liggghts", reference.get(k))] {
                let Some(run) = run else {
                    obs.push(None);
                    continue;
                };
                let pts = at::points(&run.records, u.sample.hi);
                if let Err(e) = write_series(&out.join(format!("series_{name}_{label}.csv")), &pts)
                {
                    notes.push(format!("series_{name}_{label}.csv not written: {e:#}"));
                }
                curves.push((
                    if label == "native" {
                        EngineKind::Native
                    } else {
                        self.reference_engine()
                    },
                    pts.iter().map(|p| (p.eps_a, at::phi_deg(p.s))).collect(),
                ));
                match at::observables(&pts, &w) {
                    Ok(o) => {
                        let (t_mean, t_max) =
                            at::tracking_error(&pts, u.sigma_c, 0.0, c.final_strain);
                        let (cs_mean, _) = at::tracking_error(
                            &pts,
                            u.sigma_c,
                            c.critical_state[0],
                            c.critical_state[1],
                        );
                        notes.push(format!(
                            "{name} {label}: phi_peak {:.3} deg (window from eps_a {:.2}), phi_cs {:.3} deg (block sd {:.3} deg), d eps_v / d eps_a {:+.4} over [{}, {}], critical-state stresses {:.1} / {:.1} / {:.1} Pa; lateral servo tracking |sigma / sigma_c - 1| mean {:.4} (critical state {:.4}), max {:.4}",
                            o.phi_peak,
                            o.peak_at,
                            o.phi_cs,
                            o.block_sd,
                            o.dilatancy,
                            c.critical_state[0],
                            c.critical_state[1],
                            o.s_cs[0],
                            o.s_cs[1],
                            o.s_cs[2],
                            t_mean,
                            cs_mean,
                            t_max
                        ));
                        obs.push(Some(o));
                    }
                    Err(e) => {
                        checks.push(Check::error_in(
                            format!("{}: {name} {label} observables", c.name),
                            crate::compare::Gate::Phi,
                            format!("{e:#}"),
                        ));
                        obs.push(None);
                    }
                }
            }
            if let [Some(a), Some(b)] = obs.as_slice() {
                cs_n.push(a.phi_cs);
                cs_r.push(b.phi_cs);
                notes.push(format!(
                    "{name}: phi_cs native - liggghts {:+.3} deg, phi_peak {:+.3} deg (reported)",
                    a.phi_cs - b.phi_cs,
                    a.phi_peak - b.phi_peak
                ));
            }
            let series: Vec<crate::report::overlay::Line> = curves
                .iter()
                .map(|(e, s)| crate::report::overlay::Line::new(e.label(), (*e).into(), s))
                .collect();
            if !series.is_empty()
                && let Err(e) = crate::report::svg_triaxial::phi_mob_overlay(
                    &out.join(format!("phi_mob_{name}.svg")),
                    &series,
                    &crate::report::plot::Caption::new(format!("{}: phi_mob, {name}", c.name))
                        .control(opts.control.as_deref()),
                )
            {
                notes.push(format!("phi_mob_{name}.svg not written: {e:#}"));
            }
        }
        // The critical-state angle per engine (mean over units, SE = sd / sqrt(n)) for the
        // suite's cross-scale MALT verdict (docs/stress.md rule 6).
        let angle = |engine: EngineKind, v: &[f64]| {
            let n = v.len() as f64;
            crate::compare::malt_points::IndependentAngle {
                label: format!("triaxial phi_cs, {engine}"),
                engine: Some(engine),
                phi_deg: v.iter().sum::<f64>() / n,
                se_deg: at::sample_sd(v) / n.sqrt(),
            }
        };
        if !cs_n.is_empty() {
            let angles = crate::compare::malt_points::IndependentAngles {
                case: c.name.clone(),
                canonical_hash: crate::case::ValidatedCase::canonical_hash(c).to_string(),
                angles: [
                    (EngineKind::Native, &cs_n),
                    (self.reference_engine(), &cs_r),
                ]
                .into_iter()
                .filter(|(_, v)| !v.is_empty())
                .map(|(e, v)| angle(e, v))
                .collect(),
            };
            if let Err(e) = angles.write(out) {
                notes.push(format!("{e:#}"));
            }
        }
        if !reference.is_empty() && checks.iter().all(|k| !k.is_error()) {
            checks.push(crate::compare::triaxial::phi_cs_gate(
                &c.name,
                &cs_n,
                &cs_r,
                c.tolerances.phi_abs_deg,
            ));
        }
        Verdict {
            checks,
            notes,
            ..Verdict::default()
        }
    }
}
