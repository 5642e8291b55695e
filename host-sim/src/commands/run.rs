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

use crate::formats::{self, EventChunks as Chunks, Format, HostEvent};
use crate::output::{write_atomically, AtomicFile};
use crate::samples::{Decimated, Samples};
use crate::timeline::{Pieces, TimeJumps, RESTART, RESTART_BACK_US, RESTART_GAP_US};

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
    /// With `--layout dense`: only a `W x H` window at `(X0, Y0)` of the sensor, as a board with
    /// little RAM runs it (`X0:Y0:W:H`, e.g. the STM32F405's `77:116:192:28`).
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
    /// Seconds spent in the pipeline (reading the input included).
    pub seconds: f64,
    /// Samples produced (also when they went to a file rather than into `samples`).
    pub sample_count: u64,
    /// Gaps and backward jumps of the recording's clock (see [`crate::timeline`]).
    pub jumps: TimeJumps,
    /// Points for a plot of the output (when asked for).
    pub plot: Option<Decimated>,
    /// The output CSV, written but not yet in place ([`AtomicFile::commit`] puts it there;
    /// dropping it removes it).
    pub csv: Option<AtomicFile>,
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

/// Largest sensor side the network takes (px): the 11-bit addresses of EVT 3.0 and of the
/// firmware's AER stream. Larger sizes are refused before anything is allocated.
pub const MAX_SENSOR_SIDE: u16 = 2048;

/// Largest focal length and principal point coordinate (px): what the pipeline's U16F16 holds.
pub const MAX_PX: f64 = 65535.0;

/// Checks a focal length (px) from a flag or a recording: finite, at least 1 px and at most
/// [`MAX_PX`].
fn check_focal(f: f64, source: &str) -> Result<f64> {
    if !(1.0..=MAX_PX).contains(&f) {
        bail!("{source} must be a focal length in [1, {MAX_PX}] px (got {f})");
    }
    Ok(f)
}

/// Checks a principal point coordinate (px): finite, in [0, [`MAX_PX`]].
fn check_px(v: f64, source: &str) -> Result<f64> {
    if !(0.0..=MAX_PX).contains(&v) {
        bail!("{source} must be a pixel coordinate in [0, {MAX_PX}] (got {v})");
    }
    Ok(v)
}

impl Camera {
    /// Resolves the geometry from the flags and the recording.
    ///
    /// # Errors
    /// When the size is unknown or larger than the network takes, or a focal length or
    /// principal point is not a finite number in range.
    pub fn resolve(
        size: Option<(u16, u16)>,
        focal_px: Option<f64>,
        (cx, cy): (Option<f64>, Option<f64>),
        rec: &formats::Recording,
    ) -> Result<Self> {
        let info = formats::RecordingInfo {
            width: rec.width,
            height: rec.height,
            intrinsics: rec.intrinsics,
            gyro: None,
            format: rec.format,
        };
        Self::resolve_with(size, focal_px, (cx, cy), &info, || Ok(rec.extent()))
    }

    /// [`Camera::resolve`] from what a recording's header and folder say; `extent` gives the
    /// events' extent when nothing else gives the size.
    ///
    /// # Errors
    /// As [`Camera::resolve`], and those of `extent`.
    pub fn resolve_with(
        size: Option<(u16, u16)>,
        focal_px: Option<f64>,
        (cx, cy): (Option<f64>, Option<f64>),
        info: &formats::RecordingInfo,
        extent: impl FnOnce() -> Result<Option<(u16, u16)>>,
    ) -> Result<Self> {
        let (width, height) = match (size, info.width.zip(info.height)) {
            (Some(s), _) | (None, Some(s)) => s,
            (None, None) => {
                extent()?.context("cannot tell the sensor size: pass --width and --height")?
            }
        };
        if width == 0 || height == 0 || width > MAX_SENSOR_SIDE || height > MAX_SENSOR_SIDE {
            bail!(
                "sensor size {width}x{height} is not one the network takes (1 to {MAX_SENSOR_SIDE} px a side: the 11-bit addresses of EVT 3.0 and the AER stream); pass --width and --height"
            );
        }
        let focal = match (focal_px, info.intrinsics) {
            (Some(f), _) => Some(check_focal(f, "--focal-px")?),
            (None, Some(i)) if i.fx > 0.0 => Some(check_focal(i.fx, "the recording's fx")?),
            _ => None,
        };
        let cx = match (cx, info.intrinsics) {
            (Some(c), _) => check_px(c, "--cx")?,
            (None, Some(i)) => check_px(i.cx, "the recording's cx")?,
            (None, None) => (f64::from(width) - 1.0) / 2.0,
        };
        let cy = match (cy, info.intrinsics) {
            (Some(c), _) => check_px(c, "--cy")?,
            (None, Some(i)) => check_px(i.cy, "the recording's cy")?,
            (None, None) => (f64::from(height) - 1.0) / 2.0,
        };
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
            window: None,
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

/// Checks the number options that do not depend on the recording; returns the output period
/// (µs) and tau_A (µs, when given).
fn check_options(args: &Args) -> Result<(u32, Option<u32>)> {
    if !(1..=1_000_000).contains(&args.rate_hz) || 1_000_000 % args.rate_hz != 0 {
        bail!("--rate-hz must divide 1000000 (got {})", args.rate_hz);
    }
    let tau_a_us = match args.tau_a_ms {
        Some(ms) if ms > 0.0 && ms <= 1000.0 => Some((ms * 1000.0).round() as u32),
        Some(ms) => bail!("--tau-a-ms must be in (0, 1000] (got {ms})"),
        None => None,
    };
    Ok((1_000_000 / args.rate_hz, tau_a_us))
}

/// Runs the pipeline over a recording held in memory with the given options, keeping the
/// samples in memory (the testable core of `run`).
///
/// # Errors
/// When the options do not fit the recording or it has no events.
pub fn run_pipeline(args: &Args, rec: &formats::Recording) -> Result<RunOutput> {
    let info = formats::RecordingInfo {
        width: rec.width,
        height: rec.height,
        intrinsics: rec.intrinsics,
        gyro: None,
        format: rec.format,
    };
    let camera = Camera::resolve_with(
        args.width.zip(args.height),
        args.focal_px,
        (args.cx, args.cy),
        &info,
        || Ok(rec.extent()),
    )?;
    let mut source = formats::EventsInMemory::new(&rec.events);
    run_stream(args, camera, &mut source, Samples::in_memory())
}

/// Runs the pipeline over the events of `source`, piece by piece (see [`crate::timeline`]),
/// sending the samples to `samples` as they come.
///
/// # Errors
/// When the options do not fit the recording, it has no events, or it cannot be read or the
/// samples written.
pub fn run_stream(
    args: &Args,
    camera: Camera,
    source: &mut dyn Chunks,
    samples: Samples,
) -> Result<RunOutput> {
    let (period_us, tau_a_us) = check_options(args)?;
    let Camera {
        width: w,
        height: h,
        focal,
        cx,
        cy,
    } = camera;
    let run = Run {
        args,
        focal,
        centre: (cx, cy),
        period_us,
        tau_a_us,
    };
    let mut pieces = Pieces::new(source);
    let start = Instant::now();
    let mut out = match args.layout {
        LayoutKind::Dense => {
            let layout = match args.window {
                None => Dense::new(w, h, args.stride).with_context(|| {
                    format!("stride {} does not fit a {w}x{h} sensor", args.stride)
                })?,
                Some((x0, y0, ww, wh)) => Dense::window(w, h, x0, y0, ww, wh, args.stride)
                    .with_context(|| {
                        format!(
                            "window {x0}:{y0}:{ww}:{wh} (stride {}) does not fit a {w}x{h} sensor",
                            args.stride
                        )
                    })?,
            };
            run.on_layout(layout, &mut pieces, samples)?
        }
        LayoutKind::PaperBoxes => {
            let layout =
                PaperBoxes::with_stride(w, h, args.stride, BOXES_SEED).with_context(|| {
                    format!(
                        "the paper boxes (stride {}) do not fit a {w}x{h} sensor",
                        args.stride
                    )
                })?;
            run.on_layout(layout, &mut pieces, samples)?
        }
    };
    if pieces.events == 0 {
        bail!("the recording has no events");
    }
    out.events = pieces.events;
    out.jumps = pieces.jumps;
    out.seconds = start.elapsed().as_secs_f64();
    Ok(out)
}

/// The options of one run, resolved.
struct Run<'a> {
    args: &'a Args,
    focal: Option<f64>,
    /// Principal point `(cx, cy)` in px.
    centre: (f64, f64),
    period_us: u32,
    tau_a_us: Option<u32>,
}

/// Samples of one piece, gathered between writes.
struct PieceOut<'s> {
    samples: &'s mut Samples,
    buf: Vec<(f64, f64, u8)>,
    /// Set [`RESTART`] on the piece's first sample.
    restart: bool,
}

impl PieceOut<'_> {
    #[inline]
    fn push(&mut self, t_s: f64, v: f64, mut flags: u8) {
        if std::mem::take(&mut self.restart) {
            flags |= RESTART;
        }
        self.buf.push((t_s, v, flags));
    }

    #[inline]
    fn flush_if_full(&mut self) -> Result<()> {
        if self.buf.len() >= 4096 {
            self.flush()?;
        }
        Ok(())
    }

    fn flush(&mut self) -> Result<()> {
        self.samples.extend(&self.buf)?;
        self.buf.clear();
        Ok(())
    }
}

impl Run<'_> {
    fn on_layout<L: Layout + Clone>(
        &self,
        layout: L,
        pieces: &mut Pieces<'_>,
        samples: Samples,
    ) -> Result<RunOutput> {
        match self.args.model {
            Model::Fixed => self.fixed(&Kernel::DEFAULT, layout, pieces, samples),
            Model::Float => self.float(layout, pieces, samples),
        }
    }

    /// The fixed-point pipeline (the firmware's code), one fresh pipeline per piece.
    fn fixed<L: Layout + Clone>(
        &self,
        kernel: &Kernel,
        layout: L,
        pieces: &mut Pieces<'_>,
        mut samples: Samples,
    ) -> Result<RunOutput> {
        let period_us = self.period_us;
        let mut cells = vec![Cell::default(); layout.cell_count()];
        let (mut outputs, mut ignored) = (0u64, 0u64);
        let normalized = self.args.readout == ReadoutKind::Normalized;
        let mut restart = false;
        match self.args.readout {
            ReadoutKind::Calibrated => {
                let f = self
                    .focal
                    .context("focal length unknown: pass --focal-px (and --cx)")?;
                let mut cal = Calibration {
                    period_us,
                    ..Calibration::for_units(
                        U16F16::saturating_from_num(f),
                        U16F16::saturating_from_num(self.centre.0),
                        U16F16::saturating_from_num(self.centre.1),
                        layout.unit_count(),
                    )
                };
                if let Some(tau) = self.tau_a_us {
                    cal.tau_a_us = tau;
                }
                while let Some(first) = pieces.next_piece()? {
                    cells.fill(Cell::default());
                    let mut p =
                        core_nostd::pipeline::calibrated(kernel, layout.clone(), &mut cells, cal)
                            .map_err(|e| anyhow::anyhow!("{e}"))?;
                    feed(&mut p, first, pieces, period_us, &mut samples, restart)?;
                    outputs += p.readout().samples;
                    ignored += p.network().stats().ignored;
                    restart = true;
                }
            }
            ReadoutKind::Normalized => {
                let mut units = vec![UnitPair::default(); layout.cell_count()];
                let mut active = vec![0u32; active_words(layout.cell_count())];
                while let Some(first) = pieces.next_piece()? {
                    cells.fill(Cell::default());
                    units.fill(UnitPair::default());
                    active.fill(0);
                    let readout =
                        Normalized::new(self.tau_a_us.unwrap_or(NORMALIZED_TAU_A_US), period_us);
                    let net = Network::new(
                        kernel,
                        layout.clone(),
                        &mut cells,
                        &mut units,
                        &mut active,
                        InputFilter::All,
                    )
                    .map_err(|e| anyhow::anyhow!("{e}"))?;
                    let mut p = Pipeline::new(net, readout, period_us);
                    feed(&mut p, first, pieces, period_us, &mut samples, restart)?;
                    let st = p.network().stats();
                    outputs += st.spikes_lr + st.spikes_rl;
                    ignored += st.ignored;
                    restart = true;
                }
            }
        }
        finish(samples, normalized, outputs, ignored)
    }

    /// The same run with the f64 oracle: exact exponentials and logarithms throughout.
    fn float<L: Layout + Clone>(
        &self,
        layout: L,
        pieces: &mut Pieces<'_>,
        mut samples: Samples,
    ) -> Result<RunOutput> {
        let p = OracleParams::from(&TdeParams::DEFAULT);
        let period = f64::from(self.period_us);
        let normalized = self.args.readout == ReadoutKind::Normalized;
        let (mut outputs, mut ignored) = (0u64, 0u64);
        let mut restart = false;
        let focal = match self.args.readout {
            ReadoutKind::Calibrated => Some(
                self.focal
                    .context("focal length unknown: pass --focal-px (and --cx)")?,
            ),
            ReadoutKind::Normalized => None,
        };
        while let Some(first) = pieces.next_piece()? {
            let t0 = first.t_us;
            // Times within a piece are at most RESTART_BACK_US before its first event.
            let rel = |t: u64| t as f64 - t0 as f64;
            let mut out = PieceOut {
                samples: &mut samples,
                buf: Vec::new(),
                restart,
            };
            match (self.args.readout, focal) {
                (ReadoutKind::Calibrated, Some(f)) => {
                    let tau = self
                        .tau_a_us
                        .unwrap_or(default_tau_a_us(layout.unit_count()));
                    let mut y = OracleYaw::new(
                        p,
                        layout.clone(),
                        f,
                        self.centre,
                        period,
                        f64::from(ONSET_GAP_US),
                        f64::from(tau),
                    );
                    let mut got = Vec::new();
                    let mut last = 0.0f64;
                    pieces.for_each(first, |ev| {
                        last = rel(ev.t_us);
                        y.event(last, ev.x, ev.y, ev.on, &mut got);
                        for &(t, v, flags) in &got {
                            out.push((t0 as f64 + t) * 1e-6, v, flags);
                        }
                        got.clear();
                        out.flush_if_full()
                    })?;
                    y.finish(last, &mut got);
                    for &(t, v, flags) in &got {
                        out.push((t0 as f64 + t) * 1e-6, v, flags);
                    }
                    outputs += y.samples;
                }
                _ => {
                    // The paper's readout: spikes of the whole piece, sorted, then integrated.
                    let (sw, sh) = layout.sensor();
                    let mut net = OracleNetwork::new(p, layout.clone());
                    let mut spikes = Vec::new();
                    let mut last = 0.0f64;
                    pieces.for_each(first, |ev| {
                        if ev.x >= sw || ev.y >= sh {
                            ignored += 1;
                        }
                        last = rel(ev.t_us);
                        net.event(last, ev.x, ev.y, &mut spikes);
                        Ok(())
                    })?;
                    net.flush(last + 1e6, &mut spikes);
                    spikes.sort_by(|a, b| a.0.total_cmp(&b.0));
                    // Spikes up to the last event, as the fixed pipeline counts them.
                    outputs += spikes.iter().filter(|s| s.0 <= last).count() as u64;
                    let tau_a = f64::from(self.tau_a_us.unwrap_or(NORMALIZED_TAU_A_US));
                    let (mut a, mut t_a, mut k) = (0.0f64, 0.0f64, 0usize);
                    let mut t = period;
                    while t <= last {
                        while let Some(&(ts, unit)) = spikes.get(k) {
                            if ts > t {
                                break;
                            }
                            // Right-to-left units (odd ids) count positive, as in the fixed
                            // readout.
                            a = a * (-(ts - t_a) / tau_a).exp()
                                + if unit % 2 == 1 { 1.0 } else { -1.0 };
                            t_a = ts;
                            k += 1;
                        }
                        out.push((t0 as f64 + t) * 1e-6, a * (-(t - t_a) / tau_a).exp(), 0);
                        out.flush_if_full()?;
                        t += period;
                    }
                }
            }
            out.flush()?;
            restart = true;
        }
        finish(samples, normalized, outputs, ignored)
    }
}

/// The run's output once every piece is done.
fn finish(samples: Samples, normalized: bool, outputs: u64, ignored: u64) -> Result<RunOutput> {
    let sample_count = samples.count;
    let crate::samples::Finished { kept, plot, csv } = samples.finish(normalized)?;
    Ok(RunOutput {
        samples: kept,
        events: 0,
        outputs,
        ignored,
        seconds: 0.0,
        sample_count,
        jumps: TimeJumps::default(),
        plot,
        csv,
    })
}

/// Feeds one piece (from its first event to its end) to a fresh pipeline on its u32 clock
/// (relative to the piece's first event, wrapping), sending samples with times back on the
/// recording's clock.
fn feed<L: Layout, R: Readout>(
    p: &mut Pipeline<'_, L, R>,
    first: HostEvent,
    pieces: &mut Pieces<'_>,
    period_us: u32,
    samples: &mut Samples,
    restart: bool,
) -> Result<()> {
    let t0 = first.t_us;
    let bar = progress_bar(0);
    let mut out = PieceOut {
        samples,
        buf: Vec::with_capacity(4096),
        restart,
    };
    let mut k: u64 = 0;
    let mut last = step(p, &first, t0, period_us, &mut k, &mut out);
    loop {
        let slice = pieces.next_slice()?;
        if slice.is_empty() {
            break;
        }
        for e in slice {
            last = step(p, e, t0, period_us, &mut k, &mut out);
            out.flush_if_full()?;
        }
        bar.set_position(pieces.events);
    }
    p.poll(last, &mut |s: YawSample| {
        k += 1;
        let t = t0 + k * u64::from(period_us);
        out.push(
            t as f64 * 1e-6,
            f64::from(s.yaw_rate.to_bits()) / 65536.0,
            s.flags,
        );
    });
    out.flush()?;
    bar.finish_and_clear();
    Ok(())
}

/// Feeds one event of a piece starting at `t0` (µs) to the pipeline, sending the samples due
/// before it (the `k`-th of the piece at `t0 + k` periods); returns its time on the pipeline's
/// clock.
#[inline]
fn step<L: Layout, R: Readout>(
    p: &mut Pipeline<'_, L, R>,
    e: &HostEvent,
    t0: u64,
    period_us: u32,
    k: &mut u64,
    out: &mut PieceOut<'_>,
) -> u32 {
    let ev = Event {
        t_us: e.t_us.wrapping_sub(t0) as u32,
        x: e.x,
        y: e.y,
        on: e.on,
    };
    p.event(ev, &mut |s: YawSample| {
        *k += 1;
        let t = t0 + *k * u64::from(period_us);
        out.push(
            t as f64 * 1e-6,
            f64::from(s.yaw_rate.to_bits()) / 65536.0,
            s.flags,
        );
    });
    ev.t_us
}

/// Writes the run's CSV: `t_s,yaw_rate_rad_s,flags`, or `t_s,yaw_norm` for the normalized
/// readout.
///
/// # Errors
/// When the file cannot be written.
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
    if let Ok(style) = indicatif::ProgressStyle::with_template("{spinner} {pos} events ({elapsed})")
    {
        bar.set_style(style);
    }
    bar
}

/// Opens the recording and resolves the camera: sidecar files are read only for values the
/// flags do not give; the events' extent (a first pass over the file) only when nothing gives
/// the sensor size.
///
/// # Errors
/// When the recording cannot be opened, a needed sidecar is malformed, or the geometry is
/// unknown or out of range.
pub fn open_recording(
    input: &std::path::Path,
    format: Option<Format>,
    size: Option<(u16, u16)>,
    focal_px: Option<f64>,
    centre: (Option<f64>, Option<f64>),
    needs_focal: bool,
) -> Result<(formats::EventReader, Camera)> {
    let mut reader = formats::EventReader::open(input, format, false)?;
    reader.complete_from_folder(formats::Needs {
        size: size.is_none(),
        intrinsics: (needs_focal && focal_px.is_none()) || centre.0.is_none() || centre.1.is_none(),
        gyro: false,
    })?;
    let camera = Camera::resolve_with(size, focal_px, centre, &reader.info, || {
        if !reader.is_regular_file() {
            bail!(
                "cannot tell the sensor size of {} without reading it twice, and it is not a regular file: pass --width and --height",
                input.display()
            );
        }
        let mut again = formats::EventReader::open(input, Some(reader.info.format), false)?;
        let mut chunk = Vec::new();
        let (mut mx, mut my, mut any) = (0u16, 0u16, false);
        while again.next_chunk(&mut chunk)? {
            for e in &chunk {
                mx = mx.max(e.x);
                my = my.max(e.y);
            }
            any = true;
        }
        Ok(any.then(|| (mx.saturating_add(1), my.saturating_add(1))))
    })?;
    Ok((reader, camera))
}

pub fn run(args: Args) -> Result<()> {
    let mut outputs = vec![("--out", args.out.as_path())];
    if let Some(p) = &args.plot {
        outputs.push(("--plot", p.as_path()));
    }
    crate::output::check_distinct(&[&args.input], &outputs)?;
    check_options(&args)?;
    let needs_focal = args.readout == ReadoutKind::Calibrated;
    let (mut reader, camera) = open_recording(
        &args.input,
        args.format,
        args.width.zip(args.height),
        args.focal_px,
        (args.cx, args.cy),
        needs_focal,
    )?;
    let normalized = args.readout == ReadoutKind::Normalized;
    let samples = Samples::to_csv(&args.out, normalized, args.plot.is_some())?;
    let out = run_stream(&args, camera, &mut reader, samples)?;
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
    eprintln!(
        "{} events ({} outside the layout), {} {}, {:.1} M events/s; wrote {} samples to {}{jumps}",
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
fn parse_window(s: &str) -> Result<(u16, u16, u16, u16), String> {
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
