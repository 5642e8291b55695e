//! Shared plotting setup (PNG through plotters, with an embedded font so that no system font
//! library is needed).

use std::sync::Once;

/// Font family name registered for every plot.
pub const FONT: &str = "sans-serif";

static REGISTER: Once = Once::new();

/// Registers the embedded DejaVu Sans font with plotters (idempotent).
pub fn init_fonts() {
    REGISTER.call_once(|| {
        let _ = plotters::style::register_font(
            FONT,
            plotters::style::FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}
