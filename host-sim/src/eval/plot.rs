//! The evaluation figure (like the paper's Fig. 6-7): yaw rate of the estimate, the ground truth
//! and the gyro over time on top, their integrated headings below, from the decimated points of
//! [`super::PlotPoints`]. PNG via plotters with the embedded font of [`crate::plot`], written to
//! a temporary file and renamed into place.

use std::path::Path;

use anyhow::{anyhow, Result};
use plotters::prelude::*;

use super::Report;
use crate::plot::{init_fonts, line_panel, Line};
use crate::samples::Decimated;

const EST_COLOR: RGBColor = RGBColor(31, 119, 180);
const GYRO_COLOR: RGBColor = RGBColor(255, 127, 14);

/// Draws the figure for `report` into `path` (PNG, 1200 x 800). `title` heads the figure.
pub fn plot_report(report: &Report, title: &str, path: &Path) -> Result<()> {
    crate::output::render_atomically(path, |tmp| draw_report(report, title, tmp, path))
}

/// [`plot_report`] into the file `tmp`; errors name `path`.
fn draw_report(report: &Report, title: &str, tmp: &Path, path: &Path) -> Result<()> {
    init_fonts();
    let Some(p) = &report.plot else {
        return Err(anyhow!("no plot points were kept for {}", path.display()));
    };
    let t = &p.gt.t;
    if t.len() < 2 {
        return Err(anyhow!("nothing to plot"));
    }
    let err = |e: &dyn std::fmt::Display| anyhow!("cannot draw {}: {e}", path.display());
    let root = BitMapBackend::new(tmp, (1200, 800)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let (top, bottom) = root.split_vertically(420);
    let est_label = match report.estimate.scale {
        Some(k) => format!("estimate (normalized x {k:.3}, LS fit)"),
        None => "estimate".to_string(),
    };

    // Yaw rate, and the integrated heading (degrees) of each line.
    let degrees = |d: &Decimated| -> Vec<f64> { d.v.iter().map(|v| v.to_degrees()).collect() };
    let mut series: Vec<(&str, &[f64], Vec<f64>, RGBColor)> =
        vec![("ground truth", &p.gt.v, degrees(&p.gt_heading), BLACK)];
    if let (Some(g), Some(h)) = (&p.gyro, &p.gyro_heading) {
        series.push(("gyro", &g.v, degrees(h), GYRO_COLOR));
    }
    series.push((&est_label, &p.est.v, degrees(&p.est_heading), EST_COLOR));
    let rates: Vec<Line<'_>> = series.iter().map(|(n, v, _, c)| line(n, v, *c)).collect();
    line_panel(&top, title, 22, "yaw rate [rad/s]", t, &rates, true).map_err(|e| err(&e))?;

    let m = &report.estimate;
    let note = format!(
        "RMSE {:.3} rad/s ({:.1} % of peak), corr {:.3}, ARRE {:.4} rad, final heading error {:+.2} deg",
        m.rmse_rad_s,
        100.0 * m.rmse_rel_peak,
        m.correlation,
        m.arre_rad,
        m.final_heading_error_rad.to_degrees()
    );
    let heading_lines: Vec<Line<'_>> = series
        .iter()
        .map(|(name, _, h, color)| line(name, h, *color))
        .collect();
    line_panel(
        &bottom,
        &note,
        16,
        "integrated heading [deg]",
        t,
        &heading_lines,
        false,
    )
    .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// A line of the figure: the ground truth drawn thicker.
fn line<'a>(name: &'a str, values: &'a [f64], color: RGBColor) -> Line<'a> {
    Line {
        name,
        values,
        color,
        width: if name == "ground truth" { 2 } else { 1 },
    }
}
