//! The seal of a penetration run's summary (`run-seal.json` beside `summary.json`), so
//! that claims across cases (`check --runs`, `--claims-only`) read only summaries that
//! follow from a run's outputs.
//!
//! A summary is what a claim is decided on (each engine's K_phi, its per-bed values, the
//! mean FDR), and it is a small JSON file anyone can write. The run seal names what it
//! was computed from: the case (name, canonical hash), every bed (number, seed, sha256,
//! surface height and packing fraction, the fingerprint of the reference engine's
//! input), the force file of each engine's run of each bed, and the sha256 of each of
//! those files and of the summary, with granval's version, its git commit when it was
//! built from a repository, and the run's own verdict. [`verify`] accepts a summary only
//! when every digest matches and the summary is computed again from the sealed force
//! files with the code the run used ([`super::summarize`]) and comes out the same, byte
//! for byte.
//!
//! The limit: the seal is written by the program that reads it, so a forger who writes
//! force files, recomputes the summary and the digests can make a seal that verifies.
//! What it stops is a summary that does not follow from the run's outputs: hand-written,
//! edited, copied from another case or version, or beside outputs that were changed.

use super::bed::{EngineRun, binner};
use super::{Unit, bed_dir_name};
use crate::case::penetration::PenetrationCase;
use crate::compare::sweep::{CaseSummary, SUMMARY_FILE};
use crate::compare::{Check, Status};
use crate::engines::liggghts::penetration as lp;
use crate::physics::dem::packing::Bed;
use crate::rundata::file_seal;
use crate::rundata::provenance::{EngineKind, Sha256};
use anyhow::{Context, Result, bail, ensure};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub(crate) const RUN_SEAL_FILE: &str = "run-seal.json";

/// Where a copy of a bed's reference force file is kept when the file itself lies
/// outside the run's directory (a sealed record, a deck directory, the main run's
/// directory seen from a negative control's).
pub(crate) const REFERENCE_FORCE_COPY: &str = "reference-force.txt";

/// `run-seal.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RunSeal {
    pub granval: String,
    /// The git commit granval was built from (absent when not built from a repository).
    #[serde(default)]
    pub git_commit: Option<String>,
    pub case: String,
    pub case_sha256: Sha256,
    pub beds: Vec<SealedBed>,
    /// Every file the summary is computed from, and the summary: path relative to this
    /// directory -> sha256.
    pub files: BTreeMap<String, Sha256>,
    /// The run's own verdict: its checks, each with its status.
    pub verdict: Vec<(String, Status)>,
    /// The reference engine whose force files `reference_force` names: LIGGGHTS
    /// (`force.txt`), or LAMMPS 2025 (`force.lammps.txt`, `compare --engine lammps`).
    /// Written only when it is not LIGGGHTS, so seals of LIGGGHTS runs, older ones
    /// included, are as they were.
    #[serde(default = "liggghts", skip_serializing_if = "is_liggghts")]
    pub reference_engine: EngineKind,
}

fn liggghts() -> EngineKind {
    EngineKind::Liggghts
}

fn is_liggghts(e: &EngineKind) -> bool {
    *e == EngineKind::Liggghts
}

/// One bed of a sealed run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SealedBed {
    pub bed: usize,
    pub seed: u64,
    pub bed_sha256: Sha256,
    /// The bed's surface height (m) and packing fraction: the scales of eq 5.
    pub surface_z: f64,
    pub psi: f64,
    /// Fingerprint of the reference engine's input for this bed.
    pub engine_input: Sha256,
    /// The native run's `force.csv` (none when the native engine did not run).
    #[serde(default)]
    pub native_force: Option<String>,
    /// The reference run's `force.txt` (SI).
    pub reference_force: String,
}

/// What one bed's runs left: the force files the summary is reduced from.
#[derive(Clone)]
pub(crate) struct BedRuns<'a> {
    pub unit: &'a Unit,
    pub engine_input: Sha256,
    pub native_force: Option<PathBuf>,
    pub reference_force: PathBuf,
}

pub(crate) use crate::rundata::provenance::git_commit;

/// `path` relative to `dir` when it lies inside it; otherwise a copy under `dir`
/// (`bed-K/`[`REFERENCE_FORCE_COPY`]), so a run directory holds all it is computed from.
fn inside_or_copy(dir: &Path, path: &Path, k: usize) -> Result<String> {
    let (d, p) = (
        dir.canonicalize()
            .with_context(|| format!("cannot resolve {}", dir.display()))?,
        path.canonicalize()
            .with_context(|| format!("cannot resolve {}", path.display()))?,
    );
    if let Ok(rel) = p.strip_prefix(&d) {
        let rel = rel.to_string_lossy().into_owned();
        file_seal::inside(&rel)?;
        return Ok(rel);
    }
    let rel = format!("{}/{REFERENCE_FORCE_COPY}", bed_dir_name(k));
    std::fs::create_dir_all(dir.join(bed_dir_name(k)))?;
    std::fs::copy(path, dir.join(&rel))
        .with_context(|| format!("cannot copy {} into {}", path.display(), dir.display()))?;
    Ok(rel)
}

/// The FDR of one force file of bed `u` written by `engine`: a native `force.csv`, a
/// LIGGGHTS `force.txt` (SI) or a LAMMPS 2025 `force.lammps.txt`, binned as the run
/// binned it.
fn fdr_of(
    u_case: &PenetrationCase,
    bed: &Bed,
    path: &Path,
    engine: EngineKind,
) -> Result<EngineRun> {
    let mut b = binner(u_case, bed)?;
    match engine {
        EngineKind::Native => {
            for s in crate::rundata::force::read_force_csv(path)? {
                b.push(s.z_bottom, s.f[2])?;
            }
        }
        EngineKind::Liggghts => {
            lp::for_each_force_sample(path, lp::Units::Si, |s| b.push(s.z_bottom, s.f[2]))?
        }
        EngineKind::Lammps => {
            for l in crate::engines::lammps3d_penetration::parse_force_file(path)? {
                b.push(l.z_bottom, l.f[2])?;
            }
        }
    }
    Ok(EngineRun {
        fdr: b.fdr(),
        samples: b.samples(),
        provenance: crate::rundata::provenance::Provenance {
            engine,
            version: String::new(),
            command: String::new(),
            input_hash: Sha256::of(b""),
            date: String::new(),
            wall_time_s: f64::NAN,
            threads: 0,
            case_file: path.display().to_string(),
            notes: Vec::new(),
        },
        force_file: Some(path.to_path_buf()),
    })
}

/// The summary the force files of `beds` give, by [`super::summarize`].
fn summary_from_files(
    case: &PenetrationCase,
    units: &[Unit],
    native: &[Option<PathBuf>],
    reference: &[PathBuf],
    reference_engine: EngineKind,
) -> Result<CaseSummary> {
    let mut n = Vec::new();
    let mut r = Vec::new();
    for (k, u) in units.iter().enumerate() {
        if let Some(p) = &native[k] {
            n.push(fdr_of(&u.case, &u.bed, p, EngineKind::Native)?);
        }
        r.push(fdr_of(&u.case, &u.bed, &reference[k], reference_engine)?);
    }
    ensure!(
        n.is_empty() || n.len() == units.len(),
        "a native force file for some beds only"
    );
    Ok(super::summarize(
        case,
        units,
        &n.iter().collect::<Vec<_>>(),
        &r.iter().collect::<Vec<_>>(),
        reference_engine,
    )
    .summary)
}

/// The summary text as `summary.json` holds it.
fn summary_text(s: &CaseSummary) -> Result<String> {
    Ok(serde_json::to_string_pretty(s)?)
}

/// Writes `summary.json` and `run-seal.json` into `dir` from the runs' force files.
/// `in_memory`: the summary the run computed while running (from the same samples):
/// the files must give exactly it, or the run's outputs do not hold what it reduced.
pub fn write(
    dir: &Path,
    case: &PenetrationCase,
    beds: &[BedRuns],
    in_memory: &CaseSummary,
    reference_engine: EngineKind,
    checks: &[Check],
) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut sealed = Vec::new();
    let mut names = Vec::new();
    for b in beds {
        let u = b.unit;
        let native = b
            .native_force
            .as_ref()
            .map(|p| inside_or_copy(dir, p, u.k))
            .transpose()?;
        let reference = inside_or_copy(dir, &b.reference_force, u.k)?;
        names.extend(native.clone());
        names.push(reference.clone());
        sealed.push(SealedBed {
            bed: u.k,
            seed: u.case.seed,
            bed_sha256: u.bed_hash.clone(),
            surface_z: u.bed.surface_z,
            psi: u.bed.psi,
            engine_input: b.engine_input.clone(),
            native_force: native,
            reference_force: reference,
        });
    }
    let units: Vec<Unit> = sealed.iter().map(|s| unit_of(case, s)).collect();
    let from_files = summary_from_files(
        case,
        &units,
        &sealed
            .iter()
            .map(|s| s.native_force.as_ref().map(|p| dir.join(p)))
            .collect::<Vec<_>>(),
        &sealed
            .iter()
            .map(|s| dir.join(&s.reference_force))
            .collect::<Vec<_>>(),
        reference_engine,
    )?;
    let text = summary_text(&from_files)?;
    if text != summary_text(in_memory)? {
        bail!(
            "{}: the run's force files do not reproduce the summary it computed while running: not sealed",
            dir.display()
        );
    }
    let path = dir.join(SUMMARY_FILE);
    std::fs::write(&path, &text).with_context(|| format!("cannot write {}", path.display()))?;
    names.push(SUMMARY_FILE.to_string());
    let seal = RunSeal {
        granval: env!("CARGO_PKG_VERSION").into(),
        git_commit: git_commit(),
        case: case.name.clone(),
        case_sha256: crate::case::ValidatedCase::canonical_hash(case),
        beds: sealed,
        files: file_seal::seal(dir, names.iter().map(String::as_str))?,
        verdict: checks.iter().map(|c| (c.name.clone(), c.status)).collect(),
        reference_engine,
    };
    let p = dir.join(RUN_SEAL_FILE);
    std::fs::write(&p, serde_json::to_string_pretty(&seal)? + "\n")
        .with_context(|| format!("cannot write {}", p.display()))
}

/// A unit standing for a sealed bed: its realisation of the case and the bed's scales
/// (the grains themselves are not needed to reduce a force file).
fn unit_of(case: &PenetrationCase, s: &SealedBed) -> Unit {
    Unit {
        k: s.bed,
        case: case.realisation(s.bed),
        bed: Bed {
            particles: Vec::new(),
            bodies: Vec::new(),
            surface_z: s.surface_z,
            psi: s.psi,
            ke_ratio: f64::NAN,
            settle_time: f64::NAN,
            ke_at_end_of_pour: f64::NAN,
        },
        bed_hash: s.bed_sha256.clone(),
        bed_from_record: false,
        plan: None,
        study_plan: None,
    }
}

/// A summary that verified, with what its seal says of the run.
#[derive(Debug, Clone)]
pub struct Verified {
    pub dir: PathBuf,
    pub summary: CaseSummary,
    pub seal: RunSeal,
}

impl Verified {
    /// One line for the report: where the summary came from and what the run said.
    pub(crate) fn describe(&self) -> String {
        let count = |s: Status| self.seal.verdict.iter().filter(|(_, v)| *v == s).count();
        format!(
            "{} from {} (run seal verified; granval {}{}; the run's own verdict: {} pass, {} fail, {} not compared, {} error)",
            self.summary.case,
            self.dir.display(),
            self.seal.granval,
            self.seal
                .git_commit
                .as_ref()
                .map_or(String::new(), |c| format!(" at {c}")),
            count(Status::Pass),
            count(Status::Fail),
            count(Status::NotCompared),
            count(Status::Error)
        )
    }
}

/// The summary in `dir`, accepted only when its run seal verifies: the case is `case`
/// as it is now (name, canonical hash), every sealed file has its digest, every bed of
/// the case is there with its seed, and the summary computed again from the sealed
/// force files is the summary in `dir`, byte for byte. Anything else is an error naming
/// the file.
pub fn verify(dir: &Path, case: &PenetrationCase) -> Result<Verified> {
    let seal_path = dir.join(RUN_SEAL_FILE);
    let summary_path = dir.join(SUMMARY_FILE);
    let remedy = "only a run's own summary counts: run the case again (`granval compare`, `check --only`, or `analyze` of its deck directory)";
    let text = std::fs::read_to_string(&seal_path).with_context(|| {
        format!(
            "{}: no run seal beside {}: a summary that names no run outputs is not evidence; {remedy}",
            seal_path.display(),
            summary_path.display()
        )
    })?;
    let seal: RunSeal = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a run seal; {remedy}", seal_path.display()))?;
    let hash = crate::case::ValidatedCase::canonical_hash(case);
    if seal.case != case.name || seal.case_sha256 != hash {
        bail!(
            "{}: sealed for case {} (sha256 {}), not {} as it is now (sha256 {hash}): a run of another case or of another version of it; {remedy}",
            seal_path.display(),
            seal.case,
            seal.case_sha256,
            case.name
        );
    }
    ensure!(
        seal.files.contains_key(SUMMARY_FILE),
        "{}: does not seal {SUMMARY_FILE}; {remedy}",
        seal_path.display()
    );
    let beds: Vec<usize> = seal.beds.iter().map(|b| b.bed).collect();
    if beds != (0..case.ensemble_beds).collect::<Vec<_>>() {
        bail!(
            "{}: seals beds {beds:?}, the case has {} bed(s); {remedy}",
            seal_path.display(),
            case.ensemble_beds
        );
    }
    for b in &seal.beds {
        let want = case.realisation(b.bed).seed;
        ensure!(
            b.seed == want,
            "{}: bed {} has seed {}, the case gives it {want}; {remedy}",
            seal_path.display(),
            b.bed,
            b.seed
        );
        for f in b.native_force.iter().chain([&b.reference_force]) {
            ensure!(
                seal.files.contains_key(f),
                "{}: bed {}'s force file {f} is not sealed; {remedy}",
                seal_path.display(),
                b.bed
            );
        }
    }
    file_seal::verify(dir, &seal.files, remedy)?;
    let units: Vec<Unit> = seal.beds.iter().map(|s| unit_of(case, s)).collect();
    let recomputed = summary_from_files(
        case,
        &units,
        &seal
            .beds
            .iter()
            .map(|s| s.native_force.as_ref().map(|p| dir.join(p)))
            .collect::<Vec<_>>(),
        &seal
            .beds
            .iter()
            .map(|s| dir.join(&s.reference_force))
            .collect::<Vec<_>>(),
        seal.reference_engine,
    )
    .with_context(|| format!("{}: the sealed force files", seal_path.display()))?;
    let stored = std::fs::read_to_string(&summary_path)
        .with_context(|| format!("cannot read {}", summary_path.display()))?;
    if stored != summary_text(&recomputed)? {
        bail!(
            "{}: does not follow from the run's sealed force files (computed again from them, the summary differs); {remedy}",
            summary_path.display()
        );
    }
    Ok(Verified {
        dir: dir.to_path_buf(),
        summary: recomputed,
        seal,
    })
}

/// Runs made of force curves, sealed by [`write`] as a real run is: for tests of what
/// reads sealed summaries (claims across cases). Bed `k` of `case` has its surface at
/// 0.05 m, psi 0.6, and both engines push back with `p(k, h)` (eq 5's normalised force
/// at depth `h` in intruder radii) at every sample of the case's travel.
#[cfg(test)]
pub(crate) fn sealed_test_run(
    case: &PenetrationCase,
    dir: &Path,
    p: impl Fn(usize, f64) -> f64,
) -> Result<()> {
    sealed_test_run_of(case, dir, EngineKind::Liggghts, p)
}

/// [`sealed_test_run`] with `reference` as the reference engine (its force file in
/// `bed-K/<engine>/`, in the columns LIGGGHTS and LAMMPS 2025 both write).
#[cfg(test)]
pub(crate) fn sealed_test_run_of(
    case: &PenetrationCase,
    dir: &Path,
    reference_engine: EngineKind,
    p: impl Fn(usize, f64) -> f64,
) -> Result<()> {
    use crate::rundata::force::{ForceSample, write_force_csv};
    let mut units = Vec::new();
    let mut runs = Vec::new();
    for k in 0..case.ensemble_beds {
        let ck = case.realisation(k);
        let bed = Bed {
            particles: Vec::new(),
            bodies: Vec::new(),
            surface_z: 0.05,
            psi: 0.6,
            ke_ratio: f64::NAN,
            settle_time: f64::NAN,
            ke_at_end_of_pour: f64::NAN,
        };
        let scale =
            ck.density * bed.psi * ck.gravity * std::f64::consts::PI * ck.intruder_radius.powi(3);
        let z0 = bed.surface_z + ck.start_gap;
        let every = ck.dt * ck.speed * ck.force_every as f64;
        let n = ((ck.start_gap + ck.final_depth) / every).ceil() as u64;
        let steps: Vec<u64> = (1..=n).map(|i| i * ck.force_every).collect();
        let samples: Vec<ForceSample> = steps
            .iter()
            .map(|&step| {
                let z = z0 - ck.speed * ck.dt * step as f64;
                let h = (bed.surface_z - z) / ck.intruder_radius;
                let f = if h > 0.0 { scale * p(k, h) } else { 0.0 };
                ForceSample {
                    t: step as f64 * ck.dt,
                    z_bottom: z,
                    f: [0.0, 0.0, f],
                }
            })
            .collect();
        let bdir = dir.join(bed_dir_name(k));
        std::fs::create_dir_all(bdir.join("native"))?;
        std::fs::create_dir_all(bdir.join(reference_engine.key()))?;
        let native = bdir.join("native").join(super::FORCE_CSV);
        write_force_csv(&native, &samples)?;
        let reference = bdir
            .join(reference_engine.key())
            .join(match reference_engine {
                EngineKind::Lammps => crate::engines::lammps3d_penetration::FORCE_FILE,
                _ => lp::FORCE_FILE,
            });
        let mut text = String::from(
            "# step t z_bottom fx fy fz (units SI: s, m, N; f = force of the grains on the intruder)\n",
        );
        for (step, s) in steps.iter().zip(&samples) {
            text += &format!("{step} {:e} {:e} 0 0 {:e}\n", s.t, s.z_bottom, s.f[2]);
        }
        std::fs::write(&reference, text)?;
        units.push(Unit {
            k,
            bed_hash: Sha256::of(format!("bed {k}").as_bytes()),
            case: ck,
            bed,
            bed_from_record: false,
            plan: None,
            study_plan: None,
        });
        runs.push((native, reference));
    }
    let in_memory = summary_from_files(
        case,
        &units,
        &runs.iter().map(|r| Some(r.0.clone())).collect::<Vec<_>>(),
        &runs.iter().map(|r| r.1.clone()).collect::<Vec<_>>(),
        reference_engine,
    )?;
    let beds: Vec<BedRuns> = units
        .iter()
        .zip(&runs)
        .map(|(u, (n, r))| BedRuns {
            unit: u,
            engine_input: Sha256::of(b"deck"),
            native_force: Some(n.clone()),
            reference_force: r.clone(),
        })
        .collect();
    write(dir, case, &beds, &in_memory, reference_engine, &[])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn case() -> PenetrationCase {
        let p =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/release/feng-table3-speed-1.toml");
        PenetrationCase::load(&p).unwrap()
    }

    fn sealed() -> (tempfile::TempDir, PenetrationCase) {
        let d = tempfile::tempdir().unwrap();
        let c = case();
        sealed_test_run(&c, d.path(), |b, h| (20.0 + b as f64) * h + 3.0).unwrap();
        (d, c)
    }

    fn refused(d: &Path, c: &PenetrationCase, needles: &[&str]) {
        let e = format!("{:#}", verify(d, c).unwrap_err());
        for n in needles {
            assert!(e.contains(n), "missing {n:?} in {e}");
        }
    }

    /// A run against LAMMPS 2025 seals its engine: the summary's reference side is
    /// keyed `lammps` and verifies from the LAMMPS force files; a LIGGGHTS seal does not
    /// write the field (its bytes are as before); and the same force files claimed as
    /// LIGGGHTS' do not verify as a LAMMPS run's summary.
    #[test]
    fn a_lammps_run_seals_its_engine() {
        let d = tempfile::tempdir().unwrap();
        let c = case();
        sealed_test_run_of(&c, d.path(), EngineKind::Lammps, |b, h| {
            (20.0 + b as f64) * h + 3.0
        })
        .unwrap();
        let v = verify(d.path(), &c).unwrap();
        assert_eq!(v.seal.reference_engine, EngineKind::Lammps);
        assert!(v.summary.engines.contains_key("lammps"));
        assert!(!v.summary.engines.contains_key("liggghts"));
        let text = std::fs::read_to_string(d.path().join(RUN_SEAL_FILE)).unwrap();
        assert!(text.contains("\"reference_engine\": \"lammps\""), "{text}");
        let (l, _) = sealed();
        let text = std::fs::read_to_string(l.path().join(RUN_SEAL_FILE)).unwrap();
        assert!(!text.contains("reference_engine"), "{text}");
        // The seal edited to say LIGGGHTS: the summary (keyed lammps) no longer follows.
        let p = d.path().join(RUN_SEAL_FILE);
        let mut seal: RunSeal =
            serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
        seal.reference_engine = EngineKind::Liggghts;
        std::fs::write(&p, serde_json::to_string(&seal).unwrap()).unwrap();
        refused(d.path(), &c, &["does not follow"]);
    }

    /// The negative control: a run's own sealed summary verifies, and verification gives
    /// back the very summary the run wrote.
    #[test]
    fn a_sealed_run_verifies() {
        let (d, c) = sealed();
        let v = verify(d.path(), &c).unwrap();
        let stored = CaseSummary::read(d.path()).unwrap();
        assert_eq!(v.summary, stored);
        let k = v.summary.engines["liggghts"].k_phi;
        assert!(
            (k - 21.0).abs() < 0.5,
            "K_phi {k} of beds with slopes 20, 21, 22"
        );
        assert!(
            v.describe().contains("run seal verified"),
            "{}",
            v.describe()
        );
    }

    /// A summary written by hand, without a seal, is not evidence.
    #[test]
    fn a_summary_without_a_seal_is_refused() {
        let (d, c) = sealed();
        std::fs::remove_file(d.path().join(RUN_SEAL_FILE)).unwrap();
        refused(d.path(), &c, &["run-seal.json", "no run seal"]);
    }

    /// The summary edited (K_phi doubled) with its digest in the seal updated to match:
    /// every digest verifies, but the summary does not follow from the force files.
    #[test]
    fn an_edited_summary_is_refused_even_with_its_digest_resealed() {
        let (d, c) = sealed();
        let mut s = CaseSummary::read(d.path()).unwrap();
        for e in s.engines.values_mut() {
            e.k_phi *= 2.0;
        }
        s.write(d.path()).unwrap();
        let text = std::fs::read_to_string(d.path().join(RUN_SEAL_FILE)).unwrap();
        let mut seal: RunSeal = serde_json::from_str(&text).unwrap();
        // First with the old digest: the digest check names the summary.
        std::fs::write(
            d.path().join(RUN_SEAL_FILE),
            serde_json::to_string(&seal).unwrap(),
        )
        .unwrap();
        refused(
            d.path(),
            &c,
            &["summary.json", "content differs from its seal"],
        );
        seal.files.insert(
            SUMMARY_FILE.into(),
            Sha256::of_file(&d.path().join(SUMMARY_FILE)).unwrap(),
        );
        std::fs::write(
            d.path().join(RUN_SEAL_FILE),
            serde_json::to_string(&seal).unwrap(),
        )
        .unwrap();
        refused(
            d.path(),
            &c,
            &[
                "summary.json",
                "does not follow from the run's sealed force files",
            ],
        );
    }

    /// A force file changed after sealing is named; a seal that points outside the run
    /// directory, or to a file it does not seal, is refused before anything is read.
    #[test]
    fn changed_or_unsealed_outputs_are_refused() {
        let (d, c) = sealed();
        let f = d.path().join("bed-1/liggghts/force.txt");
        let text = std::fs::read_to_string(&f).unwrap();
        std::fs::write(&f, text.replacen(" 0 0 0", " 0 0 1", 1)).unwrap();
        refused(
            d.path(),
            &c,
            &["bed-1/liggghts/force.txt", "content differs"],
        );

        let (d, c) = sealed();
        let p = d.path().join(RUN_SEAL_FILE);
        let mut seal: RunSeal =
            serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
        seal.beds[0].reference_force = "../../etc/passwd".into();
        seal.files
            .insert("../../etc/passwd".into(), Sha256::of(b""));
        std::fs::write(&p, serde_json::to_string(&seal).unwrap()).unwrap();
        refused(d.path(), &c, &["not a path inside"]);

        let (d, c) = sealed();
        let p = d.path().join(RUN_SEAL_FILE);
        let mut seal: RunSeal =
            serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
        seal.files.remove("bed-0/native/force.csv");
        std::fs::write(&p, serde_json::to_string(&seal).unwrap()).unwrap();
        refused(d.path(), &c, &["bed-0/native/force.csv", "is not sealed"]);
    }

    /// A sealed run of another case, or of another version of this one, is refused.
    #[test]
    fn a_run_of_another_case_version_is_refused() {
        let (d, _) = sealed();
        // The speed-0.5 point of Table 3: the same bed, another speed.
        let other = PenetrationCase::load(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/release/feng-table3-speed-0.5.toml"),
        )
        .unwrap();
        refused(
            d.path(),
            &other,
            &["sealed for case", "another case or of another version"],
        );
    }
}
