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

/// A line plot of one or more `(t_s, value)` series against time.
pub fn time_series(
    path: &std::path::Path,
    title: &str,
    y_label: &str,
    series: &[(&str, &[(f64, f64)])],
) -> anyhow::Result<()> {
    use plotters::prelude::*;
    init_fonts();
    let pts = || series.iter().flat_map(|(_, s)| s.iter());
    let (t0, t1) = pts().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
        (a.min(p.0), b.max(p.0))
    });
    let (v0, v1) = pts().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
        (a.min(p.1), b.max(p.1))
    });
    let (t0, t1) = if t0 < t1 { (t0, t1) } else { (0.0, 1.0) };
    let pad = ((v1 - v0) * 0.05).max(1e-3);
    let (v0, v1) = if v0 <= v1 {
        (v0 - pad, v1 + pad)
    } else {
        (-1.0, 1.0)
    };
    let root = BitMapBackend::new(path, (1000, 420)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut c = ChartBuilder::on(&root)
        .caption(title, (FONT, 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(t0..t1, v0..v1)?;
    c.configure_mesh()
        .x_desc("time (s)")
        .y_desc(y_label)
        .label_style((FONT, 13))
        .draw()?;
    let colors = [RED, BLUE, GREEN, BLACK, MAGENTA];
    for (i, (name, s)) in series.iter().enumerate() {
        let color = colors[i % colors.len()];
        c.draw_series(LineSeries::new(s.iter().copied(), color.stroke_width(2)))?
            .label(*name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
    }
    c.configure_series_labels()
        .border_style(BLACK)
        .background_style(WHITE.mix(0.8))
        .label_font((FONT, 13))
        .draw()?;
    root.present()?;
    Ok(())
}
