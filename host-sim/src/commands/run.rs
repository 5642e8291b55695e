//! `host-sim run`: a recording through the fixed-point pipeline (the firmware's code), out as a
//! yaw-rate CSV. Parsing and printing only: the run is [`crate::pipeline`].

use std::path::PathBuf;

use anyhow::{Context, Result};

use crate::formats::Format;
use crate::pipeline::{open_recording, run_stream, LayoutKind, Model, ReadoutKind, RunOptions};
use crate::samples::Samples;
use crate::timeline::{RESTART, RESTART_BACK_US, RESTART_GAP_US};

/// Arguments of `host-sim run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input recording (any format `host-sim convert` reads; `-`: standard input).
    #[arg(value_parser = super::input_path)]
    pub input: PathBuf,
    /// How to run it.
    #[command(flatten)]
    pub run: RunFlags,
    /// Output CSV (`-`: standard output).
    #[arg(long)]
    pub out: PathBuf,
    /// Also plot the output against time.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// The flags that say how to run a recording ([`RunOptions`]); `host-sim aer-stream` takes
/// the same, so the firmware runs what `host-sim run` runs.
#[derive(Debug, clap::Args)]
pub struct RunFlags {
    /// Input format (default: detected from the content).
    #[arg(long, value_enum)]
    pub format: Option<Format>,
    /// Network layout.
    #[arg(long, value_enum, default_value_t = LayoutKind::Dense)]
    pub layout: LayoutKind,
    /// FAC-to-TRG distance in pixels.
    #[arg(long, default_value_t = 2)]
    pub stride: u16,
    /// With `--layout dense`: only a `W x H` window at `(X0, Y0)` of the sensor, as a board with
    /// little RAM runs it (`X0:Y0:W:H`, e.g. the STM32F405 default `0:122:346:15`: the full
    /// width of a DAVIS346 on its rows 122-136).
    #[arg(long, value_parser = parse_window)]
    pub window: Option<(u16, u16, u16, u16)>,
    /// Readout.
    #[arg(long, value_enum, default_value_t = ReadoutKind::Calibrated)]
    pub readout: ReadoutKind,
    /// Model: the fixed-point core (the firmware's code) or the f64 oracle.
    #[arg(long, value_enum, default_value_t = Model::Fixed)]
    pub model: Model,
    /// Focal length in px (default: from the recording).
    #[arg(long)]
    pub focal_px: Option<f64>,
    /// Principal point column in px (default: from the recording, else the sensor centre).
    #[arg(long)]
    pub cx: Option<f64>,
    /// Principal point row in px (kept for completeness; yaw does not use it).
    #[arg(long)]
    pub cy: Option<f64>,
    /// Sensor width in px (default: from the recording).
    #[arg(long, requires = "height")]
    pub width: Option<u16>,
    /// Sensor height in px (default: from the recording).
    #[arg(long, requires = "width")]
    pub height: Option<u16>,
    /// Output rate in Hz.
    #[arg(long, default_value_t = 1000)]
    pub rate_hz: u32,
    /// Readout time constant tau_A in ms (default: 10 for dense layouts and for the normalized
    /// readout; 100 for the calibrated readout on paper-boxes, whose 200 units see few edges).
    #[arg(long)]
    pub tau_a_ms: Option<f64>,
    /// Spiking readouts: keep unit state in a pool of N unit pairs, as a microcontroller does
    /// (default: one pair per cell; the spike readout's networks, the paper's units, the slow
    /// ones and the near ones, get N each). Inputs that find it full are lost, counted in the summary
    /// and flagged OVERFLOW (bit 2) on the next sample.
    #[arg(long, value_name = "N")]
    pub unit_pool: Option<u32>,
    /// Run each event as it would come from a live sensor, without reading the recording
    /// ahead. The output is the same; with the normalized readout the dense network then
    /// visits each unit in a burst once per output period instead of emitting its spikes up
    /// to its pixel's next event at once (slower; for comparison).
    #[arg(long)]
    pub no_read_ahead: bool,
}

impl RunFlags {
    /// The run options these flags give.
    pub fn options(&self) -> RunOptions {
        RunOptions {
            format: self.format,
            layout: self.layout,
            stride: self.stride,
            window: self.window,
            readout: self.readout,
            model: self.model,
            focal_px: self.focal_px,
            cx: self.cx,
            cy: self.cy,
            size: self.width.zip(self.height),
            rate_hz: self.rate_hz,
            tau_a_ms: self.tau_a_ms,
            unit_pool: self.unit_pool,
            read_ahead: !self.no_read_ahead,
        }
    }
}

/// Runs `host-sim run`.
///
/// # Errors
/// As [`run_stream`], and when an output cannot be written.
pub fn run(args: Args) -> Result<()> {
    let mut outputs = vec![("--out", args.out.as_path())];
    if let Some(p) = &args.plot {
        outputs.push(("--plot", p.as_path()));
    }
    crate::output::check_distinct(&[&args.input], &outputs)?;
    let opts = args.run.options();
    opts.check()?;
    let (mut reader, camera) = open_recording(&args.input, &opts)?;
    let normalized = opts.readout == ReadoutKind::Normalized;
    let samples = Samples::to_csv(&args.out, normalized, args.plot.is_some())?;
    let out = run_stream(&opts, camera, &mut reader, samples)?;
    if let (Some(plot), Some(points)) = (&args.plot, &out.plot) {
        let label = if normalized {
            "yaw (normalized)"
        } else {
            "yaw rate (rad/s)"
        };
        let line = crate::plot::Line {
            name: "estimate",
            values: &points.v,
            color: plotters::style::RGBColor(31, 119, 180),
            width: 1,
        };
        crate::plot::time_series(plot, "host-sim run", label, &points.t, &[line])
            .with_context(|| format!("cannot draw {}", plot.display()))?;
    }
    if let Some(csv) = out.csv {
        csv.commit()?;
    }
    let j = out.jumps;
    let jumps = if j.restarts() + j.out_of_order == 0 {
        String::new()
    } else {
        format!(
            "; time jumps: {} gaps over {} min and {} backward jumps over {} ms (the pipeline restarted at each, flag {RESTART}), {} events out of order",
            j.gaps,
            RESTART_GAP_US / 60_000_000,
            j.backward,
            RESTART_BACK_US / 1000,
            j.out_of_order
        )
    };
    let pool = match out.pool {
        Some(p) => format!(
            "; unit pool: peak {} of {} pairs, {} events lost to it full",
            p.peak, p.capacity, out.pool_full
        ),
        None => String::new(),
    };
    eprintln!(
        "{} events ({} outside the layout), {} {}, {:.1} M events/s; wrote {} samples to {}{jumps}{pool}",
        out.events,
        out.ignored,
        out.outputs,
        if normalized {
            "spikes"
        } else {
            "bursts decoded"
        },
        out.events as f64 / out.seconds.max(1e-9) / 1e6,
        out.sample_count,
        args.out.display()
    );
    Ok(())
}

/// Parses `X0:Y0:W:H` (pixels).
pub fn parse_window(s: &str) -> Result<(u16, u16, u16, u16), String> {
    let v: Vec<u16> = s
        .split(':')
        .map(|p| p.parse::<u16>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("`{s}`: expected X0:Y0:W:H in pixels"))?;
    match v[..] {
        [x0, y0, w, h] if w > 0 && h > 0 => Ok((x0, y0, w, h)),
        _ => Err(format!(
            "`{s}`: expected X0:Y0:W:H in pixels, W and H at least 1"
        )),
    }
}
