//! What the PNG plots share: their text is DejaVu Sans (from the `dejavu` crate; Bitstream
//! Vera / DejaVu font licence, free to embed and redistribute).

use plotters::style::FontStyle;
use std::sync::Once;

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
