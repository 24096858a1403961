//! phi_mob(eps_a) of triaxial runs (docs/stress.md rule 5): the mobilised friction angle
//! of the wall stresses against the axial strain, one line per engine, with the
//! difference panel of [`super::overlay`].

use super::overlay::{Axes, Line, overlay};
use super::plot::Caption;
use anyhow::Result;
use std::path::Path;

/// A line of (eps_a, phi_mob in degrees).
pub(crate) type PhiSeries<'a> = Line<'a>;

pub(crate) fn phi_mob_overlay(
    path: &Path,
    series: &[PhiSeries<'_>],
    caption: &Caption,
) -> Result<()> {
    overlay(
        path,
        caption,
        &Axes {
            x: "axial strain eps_a",
            y: "phi_mob (deg)",
            unit: "deg",
            y_down: false,
        },
        series,
        &[],
    )
}
