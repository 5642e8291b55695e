//! The evaluation figure (like the paper's Fig. 6-7): yaw rate of the estimate, the ground truth
//! and the gyro over time on top, their integrated headings below. PNG via plotters with the
//! embedded font of [`crate::plot`].

use std::path::Path;

use anyhow::{anyhow, Result};
use plotters::prelude::*;

use super::{metrics, Report};
use crate::plot::{init_fonts, line_panel, Line};

const EST_COLOR: RGBColor = RGBColor(31, 119, 180);
const GYRO_COLOR: RGBColor = RGBColor(255, 127, 14);

/// Draws the figure for `report` into `path` (PNG, 1200 x 800). `title` heads the figure.
pub fn plot_report(report: &Report, title: &str, path: &Path) -> Result<()> {
    crate::output::render_atomically(path, |tmp| draw_report(report, title, tmp, path))
}

/// [`plot_report`] into the file `tmp`; errors name `path`.
fn draw_report(report: &Report, title: &str, tmp: &Path, path: &Path) -> Result<()> {
    init_fonts();
    let a = &report.aligned;
    if a.t.len() < 2 {
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

    // Yaw rate.
    let mut series: Vec<(&str, &[f64], RGBColor)> = vec![("ground truth", &a.gt, BLACK)];
    if let Some(g) = &a.gyro {
        series.push(("gyro", g, GYRO_COLOR));
    }
    series.push((&est_label, &a.est, EST_COLOR));
    let rates: Vec<Line<'_>> = series.iter().map(|&(n, v, c)| line(n, v, c)).collect();
    line_panel(&top, title, 22, "yaw rate [rad/s]", &a.t, &rates, true).map_err(|e| err(&e))?;

    // Integrated heading, degrees.
    let headings: Vec<Vec<f64>> = series
        .iter()
        .map(|(_, v, _)| {
            metrics::integrate(&a.t, v)
                .into_iter()
                .map(f64::to_degrees)
                .collect()
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
    let heading_lines: Vec<Line<'_>> = series
        .iter()
        .zip(&headings)
        .map(|(&(name, _, color), h)| line(name, h, color))
        .collect();
    line_panel(
        &bottom,
        &note,
        16,
        "integrated heading [deg]",
        &a.t,
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
