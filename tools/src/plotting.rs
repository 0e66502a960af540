//! What the PNG plots share: their text is DejaVu Sans (from the `dejavu` crate; Bitstream
//! Vera / DejaVu font licence, free to embed and redistribute), errors name the file, and
//! axes, legends and legend marks look the same in every figure.

use std::path::Path;
use std::sync::Once;

use plotters::coord::CoordTranslate;
use plotters::prelude::*;
use plotters::style::FontStyle;

/// An error drawing or writing a plot.
pub type PlotError = Box<dyn std::error::Error + Send + Sync>;

/// Register the plots' font under `"sans-serif"` (once per process).
pub fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bytes are a valid TrueType font shipped by the crate; a failure here would
        // only lose the text of the plots.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

/// Turn a plotting error into one that names the file being written.
pub fn write_error<E: std::fmt::Display>(path: &Path) -> impl FnOnce(E) -> PlotError + '_ {
    move |e| format!("writing {}: {e}", path.display()).into()
}

/// Draw the chart's legend at `position`: on a light box with a border, 13-point text.
pub fn draw_legend<'a, DB, CT>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
    path: &Path,
) -> Result<(), PlotError>
where
    DB: DrawingBackend + 'a,
    CT: CoordTranslate,
{
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .position(position)
        .draw()
        .map_err(write_error(path))?;
    Ok(())
}

/// A legend's mark for a line series: a 20-pixel stroke in `style`.
pub fn line_mark(style: ShapeStyle) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new([(x, y), (x + 20, y)], style)
}

/// A chart of two real axes on a PNG (time against a quantity, in most figures).
pub type TimeChart<'a> = ChartContext<
    'a,
    BitMapBackend<'a>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;
