//! Contact snapshots (stress fields, Feng et al. eqs 6-9): grains and every force-carrying contact at one instant,
//! the engine-neutral input of the coarse-grained stress and velocity fields.
//!
//! **Convention (both engines, identical):** every contact is stored from the side of
//! grain `i`: `force` is the force ON grain `i`; `branch` runs from grain `i`'s centre
//! to grain `j`'s centre (grain-grain) or to the contact point (grain-wall,
//! grain-intruder). Grain-grain contacts appear once. Kinds stored: `pair` and
//! `intruder` from both engines; `wall` (primitive floor/container) only from the native
//! engine, because LIGGGHTS 3.8's `compute wall/gran/local` sees mesh walls only (its
//! own warning: "output will only happen for mesh wall - particle pairs"). The stress
//! analysis therefore uses `pair` + `intruder` for both engines and masks the cells the
//! container walls could reach (see `analysis::stress::Mask`).
//!
//! Files: `snapshot_KK.json` (meta), `snapshot_KK_grains.csv.zst`,
//! `snapshot_KK_contacts.csv.zst` (zstd-compressed CSV, which pandas and `zstdcat` read
//! as they are), `snapshot_KK_seal.json`; all SI, floats in Rust's shortest round-trip
//! `{:e}`. One snapshot is read at a time. Compressed because a paper-scale stress run
//! takes hundreds of snapshots of some 10^5 contacts each: the text compresses about
//! 2.5 times (a CI-scale native snapshot: contacts 7.75 -> 3.07 MB, grains 1.59 -> 0.71 MB), and a unit must fit a cluster node's scratch. A directory written before
//! (plain `.csv`) is still read.

use super::provenance::Sha256;
use crate::numerics::vec3::*;
use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use std::io::{BufRead, BufWriter, Write};
use std::path::{Path, PathBuf};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ContactKind {
    Pair,
    Intruder,
    Wall,
}

impl ContactKind {
    pub fn name(self) -> &'static str {
        match self {
            ContactKind::Pair => "pair",
            ContactKind::Intruder => "intruder",
            ContactKind::Wall => "wall",
        }
    }
    fn parse(s: &str) -> Option<ContactKind> {
        match s {
            "pair" => Some(ContactKind::Pair),
            "intruder" => Some(ContactKind::Intruder),
            "wall" => Some(ContactKind::Wall),
            _ => None,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grain {
    pub id: u64,
    pub x: V3,
    pub v: V3,
    pub radius: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    pub kind: ContactKind,
    pub i: u64,
    /// Second grain id for `pair`, 0 otherwise.
    pub j: u64,
    /// Centre of grain i.
    pub xi: V3,
    pub point: V3,
    /// x_j - x_i (pair) or point - x_i (wall, intruder).
    pub branch: V3,
    /// Force on grain i.
    pub force: V3,
}

impl Contact {
    /// Unit contact normal pointing from the contact partner towards grain i.
    pub fn normal(&self) -> V3 {
        let n = norm(self.branch);
        if n > 0.0 {
            scale(self.branch, -1.0 / n)
        } else {
            [0.0; 3]
        }
    }
}

/// Where and when a snapshot was taken, and what the analysis needs to know of the setup.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct SnapshotMeta {
    pub engine: String,
    pub step: u64,
    pub t: f64,
    /// Depth of the intruder's bottom below the bed surface, in intruder radii.
    pub h: f64,
    pub intruder_bottom_z: f64,
    pub intruder_radius: f64,
    /// Intruder velocity along z (negative: moving down), m/s.
    pub intruder_vz: f64,
    pub surface_z: f64,
    pub container_radius: f64,
    pub floor_z: f64,
    /// Grain material density, kg/m^3.
    pub density: f64,
    /// Packing fraction of the bed before penetration.
    pub psi: f64,
    pub mean_diameter: f64,
}

#[derive(Debug, Clone)]
pub struct Snapshot {
    pub meta: SnapshotMeta,
    pub grains: Vec<Grain>,
    pub contacts: Vec<Contact>,
}

impl Snapshot {
    /// The contact force with its tangential part removed: the negative control of the
    /// stress analysis (a stress from normal forces only must give a different phi).
    pub(crate) fn drop_tangential(&mut self) {
        for c in &mut self.contacts {
            let n = c.normal();
            c.force = scale(n, dot(c.force, n));
        }
    }

    /// Keeps only the contact kinds both engines report (`pair`, `intruder`).
    pub fn common_contacts(&self) -> impl Iterator<Item = &Contact> {
        self.contacts.iter().filter(|c| c.kind != ContactKind::Wall)
    }
}

fn meta_path(dir: &Path, k: usize) -> PathBuf {
    dir.join(format!("snapshot_{k:02}.json"))
}
fn grains_path(dir: &Path, k: usize) -> PathBuf {
    dir.join(format!("snapshot_{k:02}_grains.csv.zst"))
}
fn contacts_path(dir: &Path, k: usize) -> PathBuf {
    dir.join(format!("snapshot_{k:02}_contacts.csv.zst"))
}
/// The file to read for `written` (a `.csv.zst` path): itself, or the plain `.csv` of a
/// snapshot written before snapshots were compressed.
fn existing(written: PathBuf) -> PathBuf {
    let plain = written.with_extension("");
    if !written.exists() && plain.exists() {
        plain
    } else {
        written
    }
}
/// zstd level of the snapshot files: level 3 (zstd's default) compresses a 7.8 MB
/// contact file to 3.1 MB in about 0.1 s here, small beside the time to take it.
const ZSTD_LEVEL: i32 = 3;

/// A compressing writer for a snapshot file; [`finish`] must end it.
fn create(path: &Path) -> Result<BufWriter<zstd::stream::Encoder<'static, std::fs::File>>> {
    let f =
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let enc = zstd::stream::Encoder::new(f, ZSTD_LEVEL)
        .with_context(|| format!("cannot start zstd for {}", path.display()))?;
    Ok(BufWriter::new(enc))
}

/// Flushes and ends the zstd frame (an error here is a short file, so it is reported).
fn finish(w: BufWriter<zstd::stream::Encoder<'static, std::fs::File>>, path: &Path) -> Result<()> {
    let enc = w
        .into_inner()
        .map_err(|e| e.into_error())
        .with_context(|| format!("cannot write {}", path.display()))?;
    enc.finish()
        .map(drop)
        .with_context(|| format!("cannot finish {}", path.display()))
}
fn seal_path(dir: &Path, k: usize) -> PathBuf {
    dir.join(format!("snapshot_{k:02}_seal.json"))
}

/// What [`write`] wrote of snapshot `k` (`snapshot_KK_seal.json`): the number of grain
/// and contact rows and the sha256 of both files. [`read`] refuses a snapshot whose
/// files do not match it, so a truncated or edited snapshot (e.g. one reused with
/// `stress --reuse`, whose contact count decides the stress fields) is an error naming
/// the file, never a quietly different stress. Written by granval, it stops damage and
/// stale files, not a forger who rewrites it.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
struct SnapshotSeal {
    grains: usize,
    contacts: usize,
    grains_sha256: Sha256,
    contacts_sha256: Sha256,
}

const GRAIN_HEADER: &str = "id,x,y,z,vx,vy,vz,radius";
const CONTACT_HEADER: &str = "kind,i,j,xi_x,xi_y,xi_z,cx,cy,cz,bx,by,bz,fx,fy,fz";

/// Writes snapshot number `k` into `dir` (created if missing).
pub fn write(dir: &Path, k: usize, s: &Snapshot) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mp = meta_path(dir, k);
    std::fs::write(&mp, serde_json::to_string_pretty(&s.meta)?)
        .with_context(|| format!("cannot write {}", mp.display()))?;
    let gp = grains_path(dir, k);
    let mut w = create(&gp)?;
    writeln!(w, "{GRAIN_HEADER}")?;
    for g in &s.grains {
        writeln!(
            w,
            "{},{:e},{:e},{:e},{:e},{:e},{:e},{:e}",
            g.id, g.x[0], g.x[1], g.x[2], g.v[0], g.v[1], g.v[2], g.radius
        )?;
    }
    finish(w, &gp)?;
    let cp = contacts_path(dir, k);
    let mut w = create(&cp)?;
    writeln!(w, "{CONTACT_HEADER}")?;
    for c in &s.contacts {
        write!(w, "{},{},{}", c.kind.name(), c.i, c.j)?;
        for v in [c.xi, c.point, c.branch, c.force] {
            write!(w, ",{:e},{:e},{:e}", v[0], v[1], v[2])?;
        }
        writeln!(w)?;
    }
    finish(w, &cp)?;
    let seal = SnapshotSeal {
        grains: s.grains.len(),
        contacts: s.contacts.len(),
        grains_sha256: Sha256::of_file(&gp)?,
        contacts_sha256: Sha256::of_file(&cp)?,
    };
    let sp = seal_path(dir, k);
    std::fs::write(&sp, serde_json::to_string_pretty(&seal)? + "\n")
        .with_context(|| format!("cannot write {}", sp.display()))
}

/// Snapshot numbers present in `dir`, ascending.
pub fn list(dir: &Path) -> Result<Vec<usize>> {
    let mut ks = Vec::new();
    for e in std::fs::read_dir(dir).with_context(|| format!("cannot read {}", dir.display()))? {
        let name = e?.file_name().to_string_lossy().to_string();
        if let Some(k) = name
            .strip_prefix("snapshot_")
            .and_then(|r| r.strip_suffix(".json"))
            .and_then(|r| r.parse::<usize>().ok())
        {
            ks.push(k);
        }
    }
    ks.sort_unstable();
    Ok(ks)
}

fn parse_fields<const N: usize>(
    path: &Path,
    lineno: usize,
    line: &str,
    toks: &[&str],
    names: &[&str; N],
) -> Result<[f64; N]> {
    let mut out = [0.0; N];
    for (k, name) in names.iter().enumerate() {
        let t = toks.get(k).copied().unwrap_or("");
        out[k] = t
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                anyhow::anyhow!(
                    "{}:{lineno}: column `{name}` = {t:?} is not a finite number (line {line:?})",
                    path.display()
                )
            })?;
    }
    Ok(out)
}

fn parse_id(path: &Path, lineno: usize, col: &str, t: &str) -> Result<u64> {
    t.parse::<u64>().with_context(|| {
        format!(
            "{}:{lineno}: column `{col}` = {t:?} is not a non-negative integer id",
            path.display()
        )
    })
}

/// Opens a CSV (zstd-compressed when its name ends in `.zst`), checks its header and
/// returns the remaining lines with 1-based numbers; a read error ends the iteration
/// with that error (never silently). The compressed file is bounded as every engine
/// output is, and what it decompresses to by the same size; it has matched its seal
/// before it is read.
fn lines(path: &Path, header: &str) -> Result<impl Iterator<Item = Result<(usize, String)>>> {
    let f = super::fsio::open_engine_output(path, "a snapshot CSV")?;
    let reader: Box<dyn BufRead> = if path.extension().is_some_and(|e| e == "zst") {
        let dec = zstd::stream::Decoder::new(f)
            .with_context(|| format!("{}: not a zstd stream", path.display()))?;
        Box::new(std::io::BufReader::new(std::io::Read::take(
            dec,
            super::fsio::max_engine_output(),
        )))
    } else {
        Box::new(std::io::BufReader::new(f))
    };
    let mut it = reader.lines();
    match it.next() {
        Some(Ok(h)) if h.trim() == header => {}
        Some(Ok(h)) => bail!("{}:1: header {h:?}, expected {header:?}", path.display()),
        Some(Err(e)) => return Err(e).with_context(|| format!("reading {}", path.display())),
        None => bail!(
            "{}: empty file (expected header {header:?})",
            path.display()
        ),
    }
    let p = path.to_path_buf();
    Ok(it.enumerate().map(move |(n, l)| {
        l.with_context(|| format!("{}:{}: read error", p.display(), n + 2))
            .map(|l| (n + 2, l))
    }))
}

/// The meta file of snapshot number `k` in `dir` (without its grains and contacts).
pub fn read_meta(dir: &Path, k: usize) -> Result<SnapshotMeta> {
    let mp = meta_path(dir, k);
    serde_json::from_str(&super::fsio::read_to_string(
        &mp,
        super::fsio::MAX_RECORD_JSON,
        "a snapshot meta file (JSON)",
    )?)
    .with_context(|| format!("{}: not a snapshot meta file", mp.display()))
}

/// Reads snapshot number `k` from `dir`; errors name file, line, column and value. The
/// snapshot's files must match its seal ([`SnapshotSeal`]: row counts and sha256).
pub fn read(dir: &Path, k: usize) -> Result<Snapshot> {
    let meta = read_meta(dir, k)?;
    let sp = seal_path(dir, k);
    let seal: SnapshotSeal = std::fs::read_to_string(&sp)
        .map_err(anyhow::Error::from)
        .and_then(|t| Ok(serde_json::from_str(&t)?))
        .with_context(|| {
            format!(
                "{}: no readable seal of snapshot {k} (written by an older granval, or not by granval); run again without --reuse",
                sp.display()
            )
        })?;
    let gp = existing(grains_path(dir, k));
    let cp = existing(contacts_path(dir, k));
    for (path, want) in [(&gp, &seal.grains_sha256), (&cp, &seal.contacts_sha256)] {
        let got = Sha256::of_file(path)?;
        if &got != want {
            bail!(
                "{}: content differs from its seal {} (sha256 {got}, sealed {want}): truncated or edited; run again without --reuse",
                path.display(),
                sp.display()
            );
        }
    }
    let mut grains = Vec::new();
    for item in lines(&gp, GRAIN_HEADER)? {
        let (n, line) = item?;
        if line.trim().is_empty() {
            continue;
        }
        let t: Vec<&str> = line.split(',').collect();
        if t.len() != 8 {
            bail!("{}:{n}: {} columns, expected 8", gp.display(), t.len());
        }
        let id = parse_id(&gp, n, "id", t[0])?;
        let v = parse_fields(
            &gp,
            n,
            &line,
            &t[1..],
            &["x", "y", "z", "vx", "vy", "vz", "radius"],
        )?;
        if v[6] <= 0.0 {
            bail!("{}:{n}: radius = {:e} must be positive", gp.display(), v[6]);
        }
        grains.push(Grain {
            id,
            x: [v[0], v[1], v[2]],
            v: [v[3], v[4], v[5]],
            radius: v[6],
        });
    }
    let mut contacts = Vec::new();
    for item in lines(&cp, CONTACT_HEADER)? {
        let (n, line) = item?;
        if line.trim().is_empty() {
            continue;
        }
        let t: Vec<&str> = line.split(',').collect();
        if t.len() != 15 {
            bail!("{}:{n}: {} columns, expected 15", cp.display(), t.len());
        }
        let kind = ContactKind::parse(t[0]).ok_or_else(|| {
            anyhow::anyhow!(
                "{}:{n}: column `kind` = {:?}, expected pair, intruder or wall",
                cp.display(),
                t[0]
            )
        })?;
        let i = parse_id(&cp, n, "i", t[1])?;
        let j = parse_id(&cp, n, "j", t[2])?;
        let v = parse_fields(
            &cp,
            n,
            &line,
            &t[3..],
            &[
                "xi_x", "xi_y", "xi_z", "cx", "cy", "cz", "bx", "by", "bz", "fx", "fy", "fz",
            ],
        )?;
        contacts.push(Contact {
            kind,
            i,
            j,
            xi: [v[0], v[1], v[2]],
            point: [v[3], v[4], v[5]],
            branch: [v[6], v[7], v[8]],
            force: [v[9], v[10], v[11]],
        });
    }
    for (path, n, want) in [
        (gp, grains.len(), seal.grains),
        (cp, contacts.len(), seal.contacts),
    ] {
        if n != want {
            bail!(
                "{}: {n} rows, its seal {} says {want}: truncated or edited; run again without --reuse",
                path.display(),
                sp.display()
            );
        }
    }
    Ok(Snapshot {
        meta,
        grains,
        contacts,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn snapshot() -> Snapshot {
        let contact = |i: u64| Contact {
            kind: ContactKind::Pair,
            i,
            j: i + 1,
            xi: [0.0, 0.0, i as f64 * 1e-3],
            point: [0.0, 0.0, i as f64 * 1e-3 + 5e-4],
            branch: [0.0, 0.0, 1e-3],
            force: [0.0, 0.0, -0.1 * i as f64],
        };
        Snapshot {
            meta: SnapshotMeta {
                engine: "liggghts".into(),
                step: 100,
                t: 1e-3,
                h: 0.5,
                intruder_bottom_z: 0.01,
                intruder_radius: 0.005,
                intruder_vz: -0.01,
                surface_z: 0.012,
                container_radius: 0.02,
                floor_z: 0.0,
                density: 2500.0,
                psi: 0.6,
                mean_diameter: 1e-3,
            },
            grains: (1..=4)
                .map(|id| Grain {
                    id,
                    x: [0.0, 0.0, id as f64 * 1e-3],
                    v: [0.0; 3],
                    radius: 5e-4,
                })
                .collect(),
            contacts: (1..=3).map(contact).collect(),
        }
    }

    fn unzstd(path: &Path) -> String {
        String::from_utf8(zstd::decode_all(std::fs::File::open(path).unwrap()).unwrap()).unwrap()
    }

    /// Snapshots are written compressed and read back to the last bit; a directory
    /// written before, with plain CSV files sealed as they are, is still read, to the
    /// same values; the compressed files are smaller than the text they hold.
    #[test]
    fn compressed_and_plain_snapshots_read_the_same() {
        let d = tempfile::tempdir().unwrap();
        let s = snapshot();
        write(d.path(), 0, &s).unwrap();
        let back = read(d.path(), 0).unwrap();
        assert_eq!(back.grains, s.grains);
        assert_eq!(back.contacts, s.contacts);
        let cp = contacts_path(d.path(), 0);
        assert!(
            cp.to_string_lossy()
                .ends_with("snapshot_00_contacts.csv.zst")
        );
        assert!(unzstd(&cp).starts_with(CONTACT_HEADER));

        // The same snapshot as an older granval wrote it: plain CSV, sealed as such.
        let old = tempfile::tempdir().unwrap();
        std::fs::copy(meta_path(d.path(), 0), meta_path(old.path(), 0)).unwrap();
        let mut seal: SnapshotSeal =
            serde_json::from_str(&std::fs::read_to_string(seal_path(d.path(), 0)).unwrap())
                .unwrap();
        for (zst, sha) in [
            (grains_path(d.path(), 0), &mut seal.grains_sha256),
            (contacts_path(d.path(), 0), &mut seal.contacts_sha256),
        ] {
            let plain = old.path().join(zst.with_extension("").file_name().unwrap());
            std::fs::write(&plain, unzstd(&zst)).unwrap();
            *sha = Sha256::of_file(&plain).unwrap();
        }
        std::fs::write(
            seal_path(old.path(), 0),
            serde_json::to_string(&seal).unwrap(),
        )
        .unwrap();
        let plain = read(old.path(), 0).unwrap();
        assert_eq!(plain.grains, s.grains);
        assert_eq!(plain.contacts, s.contacts);

        // Many contacts: the compressed file is a fraction of its text.
        let mut big = snapshot();
        big.contacts = (1..=20_000)
            .map(|i| Contact {
                kind: ContactKind::Pair,
                i,
                j: i + 1,
                xi: [1e-3 * (i as f64).sin(), 2e-3, 1e-6 * i as f64],
                point: [0.0, 1e-4 * (i as f64).cos(), 3e-3],
                branch: [1e-3, 0.0, 0.0],
                force: [0.1 * (i as f64).sqrt(), 0.0, -0.2],
            })
            .collect();
        write(d.path(), 1, &big).unwrap();
        let text = unzstd(&contacts_path(d.path(), 1)).len() as f64;
        let packed = std::fs::metadata(contacts_path(d.path(), 1)).unwrap().len() as f64;
        assert!(packed < 0.6 * text, "{packed} of {text} bytes");
        assert_eq!(read(d.path(), 1).unwrap().contacts, big.contacts);
    }

    /// A snapshot is read only as it was written: the negative control reads back; a
    /// contact file cut after its second row (what a killed conversion or a careless
    /// copy leaves) is refused by its digest, and with the digest rewritten to match, by
    /// its row count; a snapshot without its seal is refused.
    #[test]
    fn a_truncated_contact_snapshot_is_refused() {
        let d = tempfile::tempdir().unwrap();
        write(d.path(), 0, &snapshot()).unwrap();
        let back = read(d.path(), 0).unwrap();
        assert_eq!((back.grains.len(), back.contacts.len()), (4, 3));

        let cp = contacts_path(d.path(), 0);
        let text = unzstd(&cp);
        let cut: String = text.lines().take(3).map(|l| format!("{l}\n")).collect();
        std::fs::write(&cp, zstd::encode_all(cut.as_bytes(), ZSTD_LEVEL).unwrap()).unwrap();
        let e = format!("{:#}", read(d.path(), 0).unwrap_err());
        assert!(
            e.contains("snapshot_00_contacts.csv") && e.contains("content differs from its seal"),
            "{e}"
        );

        let sp = seal_path(d.path(), 0);
        let mut seal: SnapshotSeal =
            serde_json::from_str(&std::fs::read_to_string(&sp).unwrap()).unwrap();
        seal.contacts_sha256 = Sha256::of_file(&cp).unwrap();
        std::fs::write(&sp, serde_json::to_string(&seal).unwrap()).unwrap();
        let e = format!("{:#}", read(d.path(), 0).unwrap_err());
        assert!(
            e.contains("snapshot_00_contacts.csv") && e.contains("2 rows, its seal"),
            "{e}"
        );

        std::fs::remove_file(&sp).unwrap();
        let e = format!("{:#}", read(d.path(), 0).unwrap_err());
        assert!(e.contains("no readable seal of snapshot 0"), "{e}");
    }
}
