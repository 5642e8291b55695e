//! `host-sim run`: a recording through the fixed-point pipeline (the firmware's code), out as a
//! yaw-rate CSV.
//!
//! Columns: `t_s,yaw_rate_rad_s,flags` with the calibrated readout (rad/s, positive = turning
//! right), or `t_s,yaw_norm` with the paper's normalized readout (divided by its maximum over the
//! recording). `t_s` is on the recording's own clock.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use core_nostd::event::Event;
use core_nostd::fixed::types::U16F16;
use core_nostd::layout::{Dense, Layout, PaperBoxes};
use core_nostd::network::{active_words, Cell, InputFilter, Network, UnitPair};
use core_nostd::oracle::{OracleNetwork, OracleParams, OracleYaw};
use core_nostd::params::TdeParams;
use core_nostd::pipeline::Pipeline;
use core_nostd::readout::calibrated::{default_tau_a_us, Calibration};
use core_nostd::readout::normalized::Normalized;
use core_nostd::readout::{Readout, YawSample};
use core_nostd::unit::Kernel;

use crate::formats::{self, Format, HostEvent};
use crate::output::write_atomically;

pub use core_nostd::pipeline::ONSET_GAP_US;

/// Time constant of the paper's normalized readout (µs): model.md's 10 ms.
pub const NORMALIZED_TAU_A_US: u32 = 10_000;

/// Seed of the paper-boxes placement.
pub const BOXES_SEED: u64 = PaperBoxes::DEFAULT_SEED;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LayoutKind {
    /// Every pixel pair at the stride, both orientations, over the whole sensor.
    Dense,
    /// The paper's on-chip layout: two 20x20 boxes, 100 units each.
    PaperBoxes,
}

pub use crate::commands::sweep::Model;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ReadoutKind {
    /// Yaw rate in rad/s, causal, from the bursts' time codes and the intrinsics.
    Calibrated,
    /// The paper's leaky spike integrator, divided by its maximum over the recording.
    Normalized,
}

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input recording (any format `host-sim convert` reads).
    pub input: PathBuf,
    /// Input format (default: detected from the content).
    #[arg(long, value_enum)]
    pub format: Option<Format>,
    /// Network layout.
    #[arg(long, value_enum, default_value_t = LayoutKind::Dense)]
    pub layout: LayoutKind,
    /// FAC-to-TRG distance in pixels.
    #[arg(long, default_value_t = 2)]
    pub stride: u16,
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
    /// Principal point row in px (default: from the recording, else the sensor centre).
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
    /// Output CSV.
    #[arg(long)]
    pub out: PathBuf,
    /// Also plot the output against time.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// What a run produced.
pub struct RunOutput {
    /// `(t_s, value, flags)` per output period.
    pub samples: Vec<(f64, f64, u8)>,
    /// Events read.
    pub events: u64,
    /// Spikes (normalized readout) or decoded bursts (calibrated).
    pub outputs: u64,
    /// Events dropped as outside the sensor or layout.
    pub ignored: u64,
    /// Seconds spent in the pipeline.
    pub seconds: f64,
}

/// The sensor geometry a run uses: flags first, then the recording (its header, `meta.json` or
/// `calib.txt`), then the events' extent; the principal point defaults to the sensor centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Sensor width (px).
    pub width: u16,
    /// Sensor height (px).
    pub height: u16,
    /// Focal length (px), when known.
    pub focal: Option<f64>,
    /// Principal point column (px).
    pub cx: f64,
    /// Principal point row (px).
    pub cy: f64,
}

impl Camera {
    /// Resolves the geometry from the flags and the recording.
    pub fn resolve(
        size: Option<(u16, u16)>,
        focal_px: Option<f64>,
        cx: Option<f64>,
        cy: Option<f64>,
        rec: &formats::Recording,
    ) -> Result<Self> {
        let (width, height) = match size {
            Some(s) => s,
            None => rec
                .size_or_extent()
                .context("cannot tell the sensor size: pass --width and --height")?,
        };
        let focal = focal_px
            .or(rec.intrinsics.map(|i| i.fx))
            .filter(|f| *f > 0.0);
        let cx = cx
            .or(rec.intrinsics.map(|i| i.cx))
            .unwrap_or((f64::from(width) - 1.0) / 2.0);
        let cy = cy
            .or(rec.intrinsics.map(|i| i.cy))
            .unwrap_or((f64::from(height) - 1.0) / 2.0);
        Ok(Self {
            width,
            height,
            focal,
            cx,
            cy,
        })
    }
}

impl Args {
    /// The defaults of `host-sim run` for `input` (dense layout, stride 2, calibrated readout,
    /// fixed-point model, 1 kHz, geometry from the recording); `out` is only used by `run`.
    pub fn new(input: PathBuf, out: PathBuf) -> Self {
        Self {
            input,
            format: None,
            layout: LayoutKind::Dense,
            stride: 2,
            readout: ReadoutKind::Calibrated,
            model: Model::Fixed,
            focal_px: None,
            cx: None,
            cy: None,
            width: None,
            height: None,
            rate_hz: 1000,
            tau_a_ms: None,
            out,
            plot: None,
        }
    }
}

/// Runs the pipeline over a recording with the given options (the testable core of `run`).
pub fn run_pipeline(args: &Args, rec: &formats::Recording) -> Result<RunOutput> {
    if !(1..=1_000_000).contains(&args.rate_hz) || 1_000_000 % args.rate_hz != 0 {
        bail!("--rate-hz must divide 1000000 (got {})", args.rate_hz);
    }
    let period_us = 1_000_000 / args.rate_hz;
    let Camera {
        width: w,
        height: h,
        focal,
        cx,
        cy,
    } = Camera::resolve(
        args.width.zip(args.height),
        args.focal_px,
        args.cx,
        args.cy,
        rec,
    )?;
    let centre = (cx, cy);
    let tau_a_us = match args.tau_a_ms {
        Some(ms) if ms > 0.0 && ms <= 1000.0 => Some((ms * 1000.0).round() as u32),
        Some(ms) => bail!("--tau-a-ms must be in (0, 1000] (got {ms})"),
        None => None,
    };
    let kernel = Kernel::DEFAULT;
    match args.layout {
        LayoutKind::Dense => {
            let layout = Dense::new(w, h, args.stride)
                .with_context(|| format!("stride {} does not fit a {w}x{h} sensor", args.stride))?;
            match args.model {
                Model::Fixed => run_on_layout(
                    args, rec, &kernel, layout, focal, centre, period_us, tau_a_us,
                ),
                Model::Float => run_float(args, rec, layout, focal, centre, period_us, tau_a_us),
            }
        }
        LayoutKind::PaperBoxes => {
            let layout =
                PaperBoxes::with_stride(w, h, args.stride, BOXES_SEED).with_context(|| {
                    format!(
                        "the paper boxes (stride {}) do not fit a {w}x{h} sensor",
                        args.stride
                    )
                })?;
            match args.model {
                Model::Fixed => run_on_layout(
                    args, rec, &kernel, layout, focal, centre, period_us, tau_a_us,
                ),
                Model::Float => run_float(args, rec, layout, focal, centre, period_us, tau_a_us),
            }
        }
    }
}

/// The same run with the f64 oracle: exact exponentials and logarithms throughout.
#[allow(clippy::too_many_arguments)]
fn run_float<L: Layout>(
    args: &Args,
    rec: &formats::Recording,
    layout: L,
    focal: Option<f64>,
    (cx, cy): (f64, f64),
    period_us: u32,
    tau_a_us: Option<u32>,
) -> Result<RunOutput> {
    let Some(first) = rec.events.first() else {
        bail!("the recording has no events");
    };
    let t0 = first.t_us;
    let p = OracleParams::from(&TdeParams::DEFAULT);
    let period = f64::from(period_us);
    let start = Instant::now();
    let bar = progress_bar(rec.events.len() as u64);
    let last = rec.events.last().map_or(0.0, |e| (e.t_us - t0) as f64);
    let (samples, outputs, ignored) = match args.readout {
        ReadoutKind::Calibrated => {
            let f = focal.context("focal length unknown: pass --focal-px (and --cx)")?;
            let tau = tau_a_us.unwrap_or(default_tau_a_us(layout.unit_count()));
            let mut y = OracleYaw::new(
                p,
                layout,
                f,
                (cx, cy),
                period,
                f64::from(ONSET_GAP_US),
                f64::from(tau),
            );
            let mut out = Vec::new();
            for (i, e) in rec.events.iter().enumerate() {
                y.event((e.t_us - t0) as f64, e.x, e.y, e.on, &mut out);
                if i % 65_536 == 0 {
                    bar.set_position(i as u64);
                }
            }
            y.finish(last, &mut out);
            let samples = out
                .iter()
                .map(|&(t, v, flags)| ((t0 as f64 + t) * 1e-6, v, flags))
                .collect();
            (samples, y.samples, 0)
        }
        ReadoutKind::Normalized => {
            let (sw, sh) = layout.sensor();
            let mut net = OracleNetwork::new(p, layout);
            let mut spikes = Vec::new();
            let mut ignored = 0u64;
            for (i, e) in rec.events.iter().enumerate() {
                if e.x >= sw || e.y >= sh {
                    ignored += 1;
                }
                net.event((e.t_us - t0) as f64, e.x, e.y, &mut spikes);
                if i % 65_536 == 0 {
                    bar.set_position(i as u64);
                }
            }
            net.flush(last + 1e6, &mut spikes);
            spikes.sort_by(|a, b| a.0.total_cmp(&b.0));
            // Spikes up to the last event, as the fixed pipeline counts them.
            let n = spikes.iter().filter(|s| s.0 <= last).count() as u64;
            let tau_a = f64::from(tau_a_us.unwrap_or(NORMALIZED_TAU_A_US));
            let (mut a, mut t_a, mut k) = (0.0f64, 0.0f64, 0usize);
            let mut samples = Vec::new();
            let mut t = period;
            while t <= last {
                while let Some(&(ts, unit)) = spikes.get(k) {
                    if ts > t {
                        break;
                    }
                    // Right-to-left units (odd ids) count positive, as in the fixed readout.
                    a = a * (-(ts - t_a) / tau_a).exp() + if unit % 2 == 1 { 1.0 } else { -1.0 };
                    t_a = ts;
                    k += 1;
                }
                samples.push(((t0 as f64 + t) * 1e-6, a * (-(t - t_a) / tau_a).exp(), 0u8));
                t += period;
            }
            normalize(&mut samples);
            (samples, n, ignored)
        }
    };
    bar.finish_and_clear();
    Ok(RunOutput {
        samples,
        events: rec.events.len() as u64,
        outputs,
        ignored,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Divides by the largest |value| (the paper's normalisation over the whole recording).
fn normalize(samples: &mut [(f64, f64, u8)]) {
    let peak = samples.iter().map(|s| s.1.abs()).fold(0.0f64, f64::max);
    if peak > 0.0 {
        for s in samples {
            s.1 /= peak;
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn run_on_layout<L: Layout>(
    args: &Args,
    rec: &formats::Recording,
    kernel: &Kernel,
    layout: L,
    focal: Option<f64>,
    (cx, cy): (f64, f64),
    period_us: u32,
    tau_a_us: Option<u32>,
) -> Result<RunOutput> {
    let mut cells = vec![Cell::default(); layout.cell_count()];
    match args.readout {
        ReadoutKind::Calibrated => {
            let f = focal.context("focal length unknown: pass --focal-px (and --cx)")?;
            let mut cal = Calibration {
                period_us,
                ..Calibration::for_units(
                    U16F16::saturating_from_num(f),
                    U16F16::saturating_from_num(cx),
                    U16F16::saturating_from_num(cy),
                    layout.unit_count(),
                )
            };
            if let Some(tau) = tau_a_us {
                cal.tau_a_us = tau;
            }
            let mut p = core_nostd::pipeline::calibrated(kernel, layout, &mut cells, cal)
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            let mut out = feed(&mut p, &rec.events, period_us)?;
            out.outputs = p.readout().samples;
            out.ignored = p.network().stats().ignored;
            Ok(out)
        }
        ReadoutKind::Normalized => {
            let readout = Normalized::new(tau_a_us.unwrap_or(NORMALIZED_TAU_A_US), period_us);
            let mut units = vec![UnitPair::default(); layout.cell_count()];
            let mut active = vec![0u32; active_words(layout.cell_count())];
            let net = Network::new(
                kernel,
                layout,
                &mut cells,
                &mut units,
                &mut active,
                InputFilter::All,
            )
            .map_err(|e| anyhow::anyhow!("{e}"))?;
            let mut p = Pipeline::new(net, readout, period_us);
            let mut out = feed(&mut p, &rec.events, period_us)?;
            let st = p.network().stats();
            out.outputs = st.spikes_lr + st.spikes_rl;
            out.ignored = st.ignored;
            normalize(&mut out.samples);
            Ok(out)
        }
    }
}

/// Feeds events (host µs, u64) to a pipeline on its u32 clock (relative to the first event,
/// wrapping), collecting samples with times back on the recording's clock.
fn feed<L: Layout, R: Readout>(
    p: &mut Pipeline<'_, L, R>,
    events: &[HostEvent],
    period_us: u32,
) -> Result<RunOutput> {
    let Some(first) = events.first() else {
        bail!("the recording has no events");
    };
    let t0 = first.t_us;
    let bar = progress_bar(events.len() as u64);
    let start = Instant::now();
    let mut samples = Vec::new();
    let mut k: u64 = 0;
    let mut collect = |s: YawSample| {
        k += 1;
        let t = t0 + k * u64::from(period_us);
        samples.push((
            t as f64 * 1e-6,
            f64::from(s.yaw_rate.to_bits()) / 65536.0,
            s.flags,
        ));
    };
    for (i, e) in events.iter().enumerate() {
        let ev = Event {
            t_us: e.t_us.wrapping_sub(t0) as u32,
            x: e.x,
            y: e.y,
            on: e.on,
        };
        p.event(ev, &mut collect);
        if i % 65_536 == 0 {
            bar.set_position(i as u64);
        }
    }
    let last = events.last().map_or(0, |e| e.t_us.wrapping_sub(t0) as u32);
    p.poll(last, &mut collect);
    bar.finish_and_clear();
    Ok(RunOutput {
        samples,
        events: events.len() as u64,
        outputs: 0,
        ignored: 0,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Writes the run's CSV: `t_s,yaw_rate_rad_s,flags`, or `t_s,yaw_norm` for the normalized
/// readout.
pub fn write_yaw_csv(
    path: &std::path::Path,
    samples: &[(f64, f64, u8)],
    normalized: bool,
) -> Result<()> {
    write_atomically(path, |w| {
        if normalized {
            writeln!(w, "t_s,yaw_norm")?;
            for (t, v, _) in samples {
                writeln!(w, "{t:.6},{v:.6}")?;
            }
        } else {
            writeln!(w, "t_s,yaw_rate_rad_s,flags")?;
            for (t, v, f) in samples {
                writeln!(w, "{t:.6},{v:.6},{f}")?;
            }
        }
        Ok(())
    })
}

/// A progress bar on a terminal, hidden otherwise.
pub fn progress_bar(len: u64) -> indicatif::ProgressBar {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(len);
    if let Ok(style) =
        indicatif::ProgressStyle::with_template("{spinner} {bar:40} {pos}/{len} events ({eta})")
    {
        bar.set_style(style);
    }
    bar
}

pub fn run(args: Args) -> Result<()> {
    let rec = formats::read(&args.input, args.format)?;
    let out = run_pipeline(&args, &rec)?;
    let normalized = args.readout == ReadoutKind::Normalized;
    write_yaw_csv(&args.out, &out.samples, normalized)?;
    if let Some(plot) = &args.plot {
        let label = if normalized {
            "yaw (normalized)"
        } else {
            "yaw rate (rad/s)"
        };
        let t: Vec<f64> = out.samples.iter().map(|s| s.0).collect();
        let v: Vec<f64> = out.samples.iter().map(|s| s.1).collect();
        let line = crate::plot::Line {
            name: "estimate",
            values: &v,
            color: plotters::style::RGBColor(31, 119, 180),
            width: 1,
        };
        crate::plot::time_series(plot, "host-sim run", label, &t, &[line])
            .with_context(|| format!("cannot draw {}", plot.display()))?;
    }
    eprintln!(
        "{} events ({} outside the layout), {} {}, {:.1} M events/s; wrote {} samples to {}",
        out.events,
        out.ignored,
        out.outputs,
        if normalized {
            "spikes"
        } else {
            "bursts decoded"
        },
        out.events as f64 / out.seconds.max(1e-9) / 1e6,
        out.samples.len(),
        args.out.display()
    );
    Ok(())
}
