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

/// One line of a panel: its legend name, values (at the panel's times), colour and width.
pub struct Line<'a> {
    /// Legend entry.
    pub name: &'a str,
    /// Values, one per time.
    pub values: &'a [f64],
    /// Colour.
    pub color: plotters::style::RGBColor,
    /// Stroke width (px).
    pub width: u32,
}

/// `(lo, hi)` of the finite values with 8 % padding; `(-1, 1)` when there are none.
pub fn padded_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.08).max(1e-3);
    (lo - pad, hi + pad)
}

/// Draws `lines` against the times `t` (s) on `area`, with a caption, axis labels and, when
/// `legend`, a legend.
pub fn line_panel<DB: plotters::prelude::DrawingBackend>(
    area: &plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    caption: &str,
    caption_size: u32,
    y_desc: &str,
    t: &[f64],
    lines: &[Line<'_>],
    legend: bool,
) -> anyhow::Result<()> {
    use plotters::prelude::*;
    init_fonts();
    let err = |e: &dyn std::fmt::Display| anyhow::anyhow!("{e}");
    let (t0, t1) = match (t.first(), t.last()) {
        (Some(&a), Some(&b)) if a < b => (a, b),
        _ => (0.0, 1.0),
    };
    let (lo, hi) = padded_range(lines.iter().flat_map(|l| l.values.iter().copied()));
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FONT, caption_size))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(t0..t1, lo..hi)
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("t [s]")
        .y_desc(y_desc)
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .draw()
        .map_err(|e| err(&e))?;
    for l in lines {
        let color = l.color;
        chart
            .draw_series(LineSeries::new(
                t.iter().copied().zip(l.values.iter().copied()),
                color.stroke_width(l.width),
            ))
            .map_err(|e| err(&e))?
            .label(l.name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    if legend {
        chart
            .configure_series_labels()
            .label_font((FONT, 14))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| err(&e))?;
    }
    Ok(())
}

/// A PNG line plot of one or more series sampled at the times `t` (s), written to a temporary
/// file and renamed into place.
pub fn time_series(
    path: &std::path::Path,
    title: &str,
    y_label: &str,
    t: &[f64],
    lines: &[Line<'_>],
) -> anyhow::Result<()> {
    use plotters::prelude::*;
    crate::output::render_atomically(path, |tmp| {
        let root = BitMapBackend::new(tmp, (1000, 420)).into_drawing_area();
        root.fill(&WHITE)?;
        line_panel(&root, title, 20, y_label, t, lines, true)?;
        root.present()?;
        Ok(())
    })
}
