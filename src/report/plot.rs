//! What every granval figure shares: one font, flattened plotters errors and the
//! boxed legend, so the FDR, impact and stress figures look alike.
//!
//! Text: without the `ttf` feature plotters estimates text extents with a crude
//! fixed-width rule and emits plain `<text>` elements with a generic font family,
//! which every SVG viewer renders; no font files are needed.

use anyhow::anyhow;
use plotters::coord::CoordTranslate;
use plotters::prelude::*;

pub const FONT: &str = "sans-serif";

/// plotters' drawing errors carry a backend type parameter; flatten them.
pub fn err<E: std::fmt::Debug>(what: &'static str) -> impl FnOnce(E) -> anyhow::Error {
    move |e| anyhow!("{what}: {e:?}")
}

/// The series legend in a white, black-bordered box at `position`.
pub fn legend<'a, DB, CT>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
    font_size: u32,
) -> anyhow::Result<()>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    CT: CoordTranslate,
{
    chart
        .configure_series_labels()
        .position(position)
        .label_font((FONT, font_size))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(err("legend"))
}
