//! The evaluation figure (like the paper's Fig. 6-7): yaw rate of the estimate, the ground truth
//! and the gyro over time on top, their integrated headings below. PNG via plotters with the
//! embedded font of [`crate::plot`].

use std::path::Path;

use anyhow::{anyhow, Result};
use plotters::prelude::*;

use super::{metrics, Report};
use crate::plot::{init_fonts, FONT};

const EST_COLOR: RGBColor = RGBColor(31, 119, 180);
const GYRO_COLOR: RGBColor = RGBColor(255, 127, 14);

/// Draws the figure for `report` into `path` (PNG, 1200 x 800). `title` heads the figure.
pub fn plot_report(report: &Report, title: &str, path: &Path) -> Result<()> {
    init_fonts();
    let a = &report.aligned;
    if a.t.len() < 2 {
        return Err(anyhow!("nothing to plot"));
    }
    let err = |e: &dyn std::fmt::Display| anyhow!("cannot draw {}: {e}", path.display());
    let root = BitMapBackend::new(path, (1200, 800)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let (top, bottom) = root.split_vertically(420);
    let (t0, t1) = (a.t[0], a.t[a.t.len() - 1]);
    let est_label = match report.estimate.scale {
        Some(k) => format!("estimate (normalized x {k:.3}, LS fit)"),
        None => "estimate".to_string(),
    };

    // Yaw rate.
    let mut series: Vec<(&str, &[f64], RGBColor)> = vec![("ground truth", &a.gt, BLACK)];
    if let Some(g) = &a.gyro {
        series.push(("gyro", g, GYRO_COLOR));
    }
    series.push((&est_label, &a.est, EST_COLOR));
    let (lo, hi) = range(series.iter().flat_map(|s| s.1.iter().copied()));
    let mut chart = ChartBuilder::on(&top)
        .caption(title, (FONT, 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(t0..t1, lo..hi)
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("t [s]")
        .y_desc("yaw rate [rad/s]")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .draw()
        .map_err(|e| err(&e))?;
    for (name, v, color) in &series {
        let width = if *name == "ground truth" { 2 } else { 1 };
        chart
            .draw_series(LineSeries::new(
                a.t.iter().copied().zip(v.iter().copied()),
                color.stroke_width(width),
            ))
            .map_err(|e| err(&e))?
            .label(*name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .label_font((FONT, 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| err(&e))?;

    // Integrated heading, degrees.
    let headings: Vec<(&str, Vec<f64>, RGBColor)> = series
        .iter()
        .map(|(name, v, color)| {
            let h = metrics::integrate(&a.t, v)
                .into_iter()
                .map(f64::to_degrees)
                .collect();
            (*name, h, *color)
        })
        .collect();
    let m = &report.estimate;
    let note = format!(
        "RMSE {:.3} rad/s ({:.1} % of peak), corr {:.3}, ARRE {:.4} rad, final heading error {:+.2} deg",
        m.rmse_rad_s,
        100.0 * m.rmse_rel_peak,
        m.correlation,
        m.arre_rad,
        m.final_heading_error_rad.to_degrees()
    );
    let (lo, hi) = range(headings.iter().flat_map(|s| s.1.iter().copied()));
    let mut chart = ChartBuilder::on(&bottom)
        .caption(note, (FONT, 16))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(t0..t1, lo..hi)
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("t [s]")
        .y_desc("integrated heading [deg]")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .draw()
        .map_err(|e| err(&e))?;
    for (name, h, color) in &headings {
        let width = if *name == "ground truth" { 2 } else { 1 };
        chart
            .draw_series(LineSeries::new(
                a.t.iter().copied().zip(h.iter().copied()),
                color.stroke_width(width),
            ))
            .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// A padded `[lo, hi]` range covering the finite values (never empty).
fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
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
