//! `host-sim sweep`: one FAC→TRG pair, time difference swept from 0 to 100 ms in 0.1 ms steps.
//!
//! CSV columns: `dt_ms,spikes,first_spike_ms` — the number of spikes of the burst and the delay
//! of its first spike after the TRG event (empty when the pair does not spike). The plot shows
//! both models (fixed-point core and f64 oracle) side by side.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{ensure, Context, Result};
use core_nostd::oracle::{self, OracleParams};
use core_nostd::params::TdeParams;
use core_nostd::unit::{pair_response, Kernel};
use plotters::prelude::*;

use crate::output::{check_distinct, commit_all, render_staged, AtomicFile, Staged};
use crate::plot::{init_fonts, FONT};

pub use crate::pipeline::Model;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model to sweep.
    #[arg(long, value_enum, default_value_t = Model::Fixed)]
    pub model: Model,
    /// Output CSV (`dt_ms,spikes,first_spike_ms`; `-`: standard output).
    #[arg(long)]
    pub out: PathBuf,
    /// Also draw spike count and first-spike delay of both models against the time difference.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// One point of the sweep.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// FAC→TRG time difference (ms).
    pub dt_ms: f64,
    /// Spikes in the burst.
    pub spikes: u32,
    /// Delay of the first spike after the TRG event (ms).
    pub first_spike_ms: Option<f64>,
}

/// Time differences of the sweep, µs: 0 to 100 ms in 0.1 ms steps.
pub fn time_differences_us() -> impl Iterator<Item = u32> {
    (0..=1000u32).map(|i| i * 100)
}

/// The sweep for one model with the default parameters.
pub fn sweep(model: Model) -> Vec<Point> {
    match model {
        Model::Fixed => {
            let k = Kernel::DEFAULT;
            time_differences_us()
                .map(|dt| {
                    let r = pair_response(&k, 0, dt);
                    Point {
                        dt_ms: f64::from(dt) / 1000.0,
                        spikes: r.spikes,
                        first_spike_ms: r.first_spike_us.map(|f| f64::from(f) / 1000.0),
                    }
                })
                .collect()
        }
        Model::Float => {
            let p = OracleParams::from(&TdeParams::DEFAULT);
            time_differences_us()
                .map(|dt| {
                    let (spikes, first) = oracle::pair_response(&p, f64::from(dt));
                    Point {
                        dt_ms: f64::from(dt) / 1000.0,
                        spikes,
                        first_spike_ms: first.map(|f| f / 1000.0),
                    }
                })
                .collect()
        }
    }
}

/// Runs `host-sim sweep`: the CSV and the plot are put in place together, once both were
/// written (a plot that cannot be drawn leaves no CSV either).
pub fn run(args: Args) -> Result<()> {
    if let Some(plot) = &args.plot {
        ensure!(
            plot != &args.out,
            "--plot {} is also given to --out",
            plot.display()
        );
        check_distinct(&[], &[("--out", &args.out), ("--plot", plot)])?;
    }
    let points = sweep(args.model);
    let mut csv = AtomicFile::create(&args.out)?;
    write_csv(csv.writer(), &points)
        .with_context(|| format!("cannot write {}", args.out.display()))?;
    let mut outputs = vec![Staged::from(csv)];
    if let Some(plot) = &args.plot {
        let (fixed, float) = match args.model {
            Model::Fixed => (points.clone(), sweep(Model::Float)),
            Model::Float => (sweep(Model::Fixed), points.clone()),
        };
        let png = render_staged(plot, |tmp| draw(tmp, &fixed, &float))
            .with_context(|| format!("cannot draw {}", plot.display()))?;
        outputs.push(png.into());
    }
    commit_all(outputs)?;
    let spiking = points.iter().filter(|p| p.spikes > 0).count();
    let max = points.iter().map(|p| p.spikes).max().unwrap_or(0);
    eprintln!(
        "sweep ({:?}): {} points, spikes at {} of them, at most {} spikes; wrote {}",
        args.model,
        points.len(),
        spiking,
        max,
        args.out.display()
    );
    Ok(())
}

/// The CSV rows, with their header.
fn write_csv(w: &mut impl Write, points: &[Point]) -> std::io::Result<()> {
    writeln!(w, "dt_ms,spikes,first_spike_ms")?;
    for p in points {
        match p.first_spike_ms {
            Some(f) => writeln!(w, "{:.1},{},{:.3}", p.dt_ms, p.spikes, f)?,
            None => writeln!(w, "{:.1},{},", p.dt_ms, p.spikes)?,
        }
    }
    Ok(())
}

/// Two panels: spike count, and first-spike delay, against the time difference.
fn draw(path: &std::path::Path, fixed: &[Point], float: &[Point]) -> Result<()> {
    init_fonts();
    let root = BitMapBackend::new(path, (900, 760)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(380);
    let max_spikes = fixed
        .iter()
        .chain(float)
        .map(|p| p.spikes)
        .max()
        .unwrap_or(1);
    let mut c = ChartBuilder::on(&top)
        .caption("TDE burst size vs FAC→TRG time difference", (FONT, 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..100.0, 0.0..f64::from(max_spikes + 2))?;
    c.configure_mesh()
        .x_desc("time difference (ms)")
        .y_desc("spikes")
        .label_style((FONT, 13))
        .draw()?;
    for (pts, color, name, filled) in [
        (float, BLUE, "f64 oracle", false),
        (fixed, RED, "fixed-point core", true),
    ] {
        c.draw_series(pts.iter().step_by(5).map(|p| {
            // The oracle as wide rings, the core as dots inside them: both stay visible.
            Circle::new(
                (p.dt_ms, f64::from(p.spikes)),
                if filled { 2 } else { 6 },
                if filled {
                    color.filled()
                } else {
                    color.stroke_width(2)
                },
            )
        }))?
        .label(name)
        .legend(move |(x, y)| Circle::new((x, y), 4, color.filled()));
    }
    c.configure_series_labels()
        .border_style(BLACK)
        .background_style(WHITE.mix(0.8))
        .label_font((FONT, 13))
        .draw()?;

    let max_first = fixed
        .iter()
        .chain(float)
        .filter_map(|p| p.first_spike_ms)
        .fold(1.0f64, f64::max);
    let mut c = ChartBuilder::on(&bottom)
        .caption("Time to first spike after TRG", (FONT, 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..100.0, 0.0..max_first * 1.05)?;
    c.configure_mesh()
        .x_desc("time difference (ms)")
        .y_desc("first spike (ms)")
        .label_style((FONT, 13))
        .draw()?;
    for (pts, color, name, width) in [
        (float, BLUE.mix(0.5), "f64 oracle", 7),
        (fixed, RED.mix(1.0), "fixed-point core", 2),
    ] {
        c.draw_series(LineSeries::new(
            pts.iter()
                .filter_map(|p| p.first_spike_ms.map(|f| (p.dt_ms, f))),
            color.stroke_width(width),
        ))?
        .label(name)
        .legend(move |(x, y)| {
            PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(width))
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
