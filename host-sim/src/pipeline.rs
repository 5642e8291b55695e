//! The pipeline over a recording: run options, the camera they resolve to, the core's
//! [`Settings`], pieces of continuous time in and yaw samples out (the library behind
//! `host-sim run`, `demo`, `aer-stream`, the benches and the tests).
//!
//! Output columns: `t_s,yaw_rate_rad_s,flags` with the calibrated readout (rad/s, positive =
//! turning right), or `t_s,yaw_norm` with the paper's normalized readout (divided by its
//! maximum over the recording). `t_s` is on the recording's own clock.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use core_nostd::event::Event;
use core_nostd::fixed::types::U16F16;
use core_nostd::layout::Layout;
use core_nostd::network::{Cell, NetState, NextInput, PoolUse, UnitPair};
use core_nostd::oracle::{OracleNetwork, OracleParams, OracleSpikeYaw, OracleYaw};
use core_nostd::params::TdeParams;
use core_nostd::readout::spikes::SpikeCell;
use core_nostd::readout::YawSample;
use core_nostd::settings::{Built, LayoutChoice, ReadoutChoice, Settings};
use core_nostd::unit::Kernel;

use crate::formats::{self, Event64, EventChunks as Chunks, Format};
use crate::lookahead::{prefetch, Lookahead, PREFETCH_DISTANCE};
use crate::output::{write_atomically, AtomicFile};
use crate::samples::{Decimated, Samples};
use crate::timeline::{Pieces, TimeJumps, RESTART};

pub use core_nostd::pipeline::ONSET_GAP_US;
pub use core_nostd::settings::MAX_SENSOR_SIDE;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LayoutKind {
    /// Every pixel pair at the stride, both orientations, over the whole sensor.
    Dense,
    /// The paper's on-chip layout: two 20x20 boxes, 100 units each.
    PaperBoxes,
}

/// Which implementation of the model runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Model {
    /// The fixed-point core that runs on the microcontroller.
    Fixed,
    /// The f64 oracle (exact in continuous time).
    Float,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ReadoutKind {
    /// Yaw rate in rad/s, causal, from the bursts' time codes and the intrinsics.
    Calibrated,
    /// The paper's leaky spike integrator, divided by its maximum over the recording.
    Normalized,
    /// Yaw rate in rad/s, causal, from the spikes alone (each burst's spike times) and the
    /// intrinsics.
    Spikes,
}

/// How to run a recording: what `host-sim run`'s flags say, before the recording is opened.
/// [`RunOptions::default`] is `host-sim run`'s defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct RunOptions {
    /// Input format (`None`: detected from the content).
    pub format: Option<Format>,
    /// Network layout.
    pub layout: LayoutKind,
    /// FAC-to-TRG distance (px).
    pub stride: u16,
    /// With [`LayoutKind::Dense`]: only this `(x0, y0, w, h)` window of the sensor.
    pub window: Option<(u16, u16, u16, u16)>,
    /// Readout.
    pub readout: ReadoutKind,
    /// Fixed-point core or f64 oracle.
    pub model: Model,
    /// Focal length (px; `None`: from the recording).
    pub focal_px: Option<f64>,
    /// Principal point column (px; `None`: from the recording, else the sensor centre).
    pub cx: Option<f64>,
    /// Principal point row (px; `None`: from the recording, else the sensor centre).
    pub cy: Option<f64>,
    /// Sensor width and height (px; `None`: from the recording).
    pub size: Option<(u16, u16)>,
    /// Output rate (Hz; must divide 1 MHz).
    pub rate_hz: u32,
    /// Readout time constant (ms; `None`: the readout's default).
    pub tau_a_ms: Option<f64>,
    /// Spiking readouts: unit state in a pool of this many unit pairs (`None`: one pair per
    /// cell; see `core_nostd::network::pool`).
    pub unit_pool: Option<u32>,
    /// Read the recording ahead ([`crate::lookahead`]): with the normalized readout, the
    /// units emit their spikes up to their pixel's next event at once. The same output either
    /// way; `false` runs each event as a live sensor's would come.
    pub read_ahead: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            format: None,
            layout: LayoutKind::Dense,
            stride: 2,
            window: None,
            readout: ReadoutKind::Calibrated,
            model: Model::Fixed,
            focal_px: None,
            cx: None,
            cy: None,
            size: None,
            rate_hz: 1000,
            unit_pool: None,
            tau_a_ms: None,
            read_ahead: true,
        }
    }
}

/// The settings' configuration payload in hex (two lowercase digits per byte): how the QEMU
/// board's `--settings` takes them.
pub fn settings_hex(settings: &Settings) -> String {
    let (payload, len) = settings.payload();
    payload
        .get(..len)
        .unwrap_or_default()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
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
    /// With a unit pool: its size and the most slots in use at once (over all pieces).
    pub pool: Option<PoolUse>,
    /// Events whose units found the unit pool full.
    pub pool_full: u64,
    /// Points for a plot of the output (when asked for).
    pub plot: Option<Decimated>,
    /// The output CSV, written but not yet in place ([`AtomicFile::commit`] puts it there;
    /// dropping it removes it).
    pub csv: Option<AtomicFile>,
}

impl RunOutput {
    /// Pearson correlation of this run's output values with `other`'s, sample by sample over
    /// the samples both have (two runs of one recording on the same output grid: the fixed
    /// point pipeline against its f64 oracle).
    #[must_use]
    pub fn correlation_with(&self, other: &Self) -> f64 {
        let (a, b): (Vec<f64>, Vec<f64>) = self
            .samples
            .iter()
            .zip(&other.samples)
            .map(|(x, y)| (x.1, y.1))
            .unzip();
        crate::eval::metrics::pearson(&a, &b)
    }
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

impl RunOptions {
    /// Checks the number options that do not depend on the recording; returns the output
    /// period (µs) and `tau_A` (µs, when given).
    ///
    /// # Errors
    /// When the rate does not divide 1 MHz or `tau_A` is out of (0, 1000] ms.
    pub fn check(&self) -> Result<(u32, Option<u32>)> {
        if !(1..=1_000_000).contains(&self.rate_hz) || 1_000_000 % self.rate_hz != 0 {
            bail!("--rate-hz must divide 1000000 (got {})", self.rate_hz);
        }
        let tau_a_us = match self.tau_a_ms {
            Some(ms) if ms > 0.0 && ms <= 1000.0 => Some((ms * 1000.0).round().max(1.0) as u32),
            Some(ms) => bail!("--tau-a-ms must be in (0, 1000] (got {ms})"),
            None => None,
        };
        Ok((1_000_000 / self.rate_hz, tau_a_us))
    }

    /// The core's settings for these options on `camera`: the one description of the run that
    /// the fixed-point pipeline, the firmware (through the configuration frame) and this tool
    /// share. Needs the focal length for the calibrated readout; without one (the normalized
    /// readout does not use it) the focal length is set to 1 px.
    ///
    /// # Errors
    /// When an option is out of range, the focal length is unknown for the calibrated readout,
    /// or the layout does not fit the sensor.
    pub fn settings(&self, camera: &Camera) -> Result<Settings> {
        let (period_us, tau_a_us) = self.check()?;
        let readout = match self.readout {
            ReadoutKind::Calibrated => ReadoutChoice::Calibrated,
            ReadoutKind::Normalized => ReadoutChoice::Normalized,
            ReadoutKind::Spikes => ReadoutChoice::Spikes,
        };
        let focal = match (camera.focal, readout) {
            (Some(f), _) => f,
            (None, ReadoutChoice::Normalized) => 1.0,
            (None, ReadoutChoice::Calibrated | ReadoutChoice::Spikes) => {
                bail!(
                    "focal length unknown: the {}x{} px recording does not give it (no \
                     intrinsics in its header, nor a meta.json or calib.txt beside it). Pass \
                     --focal-px F, the focal length over the pixel pitch (a 4.5 mm lens on a \
                     DAVIS346's 18.5 um pixels: 243), and --cx/--cy where the principal point \
                     is not the centre ({:.1}, {:.1}); or --readout normalized, which needs none",
                    camera.width,
                    camera.height,
                    camera.cx,
                    camera.cy
                )
            }
        };
        let layout = match (self.layout, self.window) {
            (LayoutKind::Dense, None) => LayoutChoice::Dense,
            (LayoutKind::Dense, Some((x0, y0, w, h))) => LayoutChoice::Window { x0, y0, w, h },
            (LayoutKind::PaperBoxes, None) => LayoutChoice::PaperBoxes,
            (LayoutKind::PaperBoxes, Some(_)) => bail!("--window needs --layout dense"),
        };
        let settings = Settings {
            width: camera.width,
            height: camera.height,
            focal_px: U16F16::saturating_from_num(focal),
            cx: U16F16::saturating_from_num(camera.cx),
            cy: U16F16::saturating_from_num(camera.cy),
            layout,
            stride: self.stride,
            period_us,
            readout,
            tau_a_us,
            unit_pool: self.unit_pool,
        };
        if settings.unit_pool.is_some() && readout == ReadoutChoice::Calibrated {
            bail!("--unit-pool needs a spiking readout (--readout normalized or spikes)");
        }
        match settings.layout() {
            Ok(_) => {}
            Err(core_nostd::settings::SettingsError::Layout) => {
                let (w, h) = (camera.width, camera.height);
                match self.window {
                    Some((x0, y0, ww, wh)) => bail!(
                        "window {x0}:{y0}:{ww}:{wh} (stride {}) does not fit a {w}x{h} sensor",
                        self.stride
                    ),
                    None if self.layout == LayoutKind::PaperBoxes => bail!(
                        "the paper boxes (stride {}) do not fit a {w}x{h} sensor",
                        self.stride
                    ),
                    None => bail!("stride {} does not fit a {w}x{h} sensor", self.stride),
                }
            }
            Err(e) => bail!("{e}"),
        }
        Ok(settings)
    }
}

/// Runs the pipeline over a recording held in memory with the given options, keeping the
/// samples in memory (the testable core of `run`).
///
/// # Errors
/// When the options do not fit the recording or it has no events.
pub fn run_pipeline(opts: &RunOptions, rec: &formats::Recording) -> Result<RunOutput> {
    let info = formats::RecordingInfo {
        width: rec.width,
        height: rec.height,
        intrinsics: rec.intrinsics,
        gyro: None,
        format: rec.format,
    };
    let camera = Camera::resolve_with(opts.size, opts.focal_px, (opts.cx, opts.cy), &info, || {
        Ok(rec.extent())
    })?;
    let mut source = formats::EventsInMemory::new(&rec.events);
    run_stream(opts, camera, &mut source, Samples::in_memory())
}

/// Runs the pipeline over the events of `source`, piece by piece (see [`crate::timeline`]),
/// sending the samples to `samples` as they come.
///
/// # Errors
/// When the options do not fit the recording, it has no events, or it cannot be read or the
/// samples written.
pub fn run_stream(
    opts: &RunOptions,
    camera: Camera,
    source: &mut dyn Chunks,
    samples: Samples,
) -> Result<RunOutput> {
    let settings = opts.settings(&camera)?;
    let mut pieces = Pieces::new(source);
    let start = Instant::now();
    let mut out = match opts.model {
        Model::Fixed => fixed(
            &settings,
            &Kernel::DEFAULT,
            &mut pieces,
            samples,
            opts.read_ahead,
        )?,
        Model::Float => float(&settings, &camera, &mut pieces, samples)?,
    };
    if pieces.events == 0 {
        bail!("the recording has no events");
    }
    out.events = pieces.events;
    out.jumps = pieces.jumps;
    out.seconds = start.elapsed().as_secs_f64();
    Ok(out)
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

/// The fixed-point pipeline (the firmware's code), built from `settings`, one fresh pipeline
/// per piece.
fn fixed(
    settings: &Settings,
    kernel: &Kernel,
    pieces: &mut Pieces<'_>,
    mut samples: Samples,
    read_ahead: bool,
) -> Result<RunOutput> {
    // The read-ahead buffer, for pipelines it serves (`Built::reads_ahead`).
    let mut ahead: Option<Lookahead> = None;
    let needs = settings.storage().map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut cells = vec![Cell::default(); needs.cells];
    let mut units = vec![UnitPair::default(); needs.unit_pairs];
    let mut owners = vec![0u32; needs.pool_owners];
    let mut active = vec![0u32; needs.active_words];
    let mut spike_cells = vec![SpikeCell::EMPTY; needs.spike_cells];
    let (mut outputs, mut ignored) = (0u64, 0u64);
    let (mut pool, mut pool_full) = (None::<PoolUse>, 0u64);
    let mut restart = false;
    while let Some(first) = pieces.next_piece()? {
        let state = if owners.is_empty() {
            NetState::spiking(&mut cells, &mut units, &mut active)
        } else {
            NetState::pooled(&mut cells, &mut units, &mut owners, &mut active)
        };
        let mut p = settings
            .build_with(kernel, state, &mut spike_cells)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        if read_ahead && ahead.is_none() && p.reads_ahead() {
            ahead = Some(Lookahead::new(settings.width, settings.height));
        }
        feed(
            &mut p,
            first,
            pieces,
            settings.period_us,
            &mut samples,
            restart,
            ahead.as_mut(),
        )?;
        outputs += p.outputs();
        ignored += p.net_stats().ignored;
        pool_full += p.pool_full();
        if let Some(u) = p.pool_use() {
            let peak = pool.map_or(0, |q| q.peak).max(u.peak);
            pool = Some(PoolUse { peak, ..u });
        }
        restart = true;
    }
    let mut out = finish(samples, is_normalized(settings), outputs, ignored)?;
    out.pool = pool;
    out.pool_full = pool_full;
    Ok(out)
}

fn is_normalized(settings: &Settings) -> bool {
    settings.readout == ReadoutChoice::Normalized
}

/// The same run with the f64 oracle: exact exponentials and logarithms throughout, on the
/// camera's unquantized geometry.
fn float(
    settings: &Settings,
    camera: &Camera,
    pieces: &mut Pieces<'_>,
    mut samples: Samples,
) -> Result<RunOutput> {
    let layout = settings.layout().map_err(|e| anyhow::anyhow!("{e}"))?;
    let p = OracleParams::from(&TdeParams::DEFAULT);
    let period = f64::from(settings.period_us);
    let tau_a = f64::from(settings.tau_a_us(layout.unit_count()));
    let normalized = is_normalized(settings);
    let (mut outputs, mut ignored) = (0u64, 0u64);
    let mut restart = false;
    while let Some(first) = pieces.next_piece()? {
        let t0 = first.t_us;
        // Times within a piece are at most RESTART_BACK_US before its first event.
        let rel = |t: u64| t as f64 - t0 as f64;
        let mut out = PieceOut {
            samples: &mut samples,
            buf: Vec::new(),
            restart,
        };
        match (settings.readout, camera.focal) {
            (ReadoutChoice::Spikes, Some(f)) => {
                let y = OracleSpikeYaw::new(
                    p,
                    layout.clone(),
                    f,
                    (camera.cx, camera.cy),
                    period,
                    f64::from(ONSET_GAP_US),
                    tau_a,
                );
                outputs += oracle_piece(y, first, pieces, &mut out)?;
            }
            (ReadoutChoice::Calibrated, Some(f)) => {
                let y = OracleYaw::new(
                    p,
                    layout.clone(),
                    f,
                    (camera.cx, camera.cy),
                    period,
                    f64::from(ONSET_GAP_US),
                    tau_a,
                );
                outputs += oracle_piece(y, first, pieces, &mut out)?;
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

/// The f64 oracle of a rad/s readout: events in, `(t_us, yaw, flags)` samples out.
trait OracleReadout {
    fn event(&mut self, t: f64, x: u16, y: u16, on: bool, out: &mut Vec<(f64, f64, u8)>);
    fn finish(&mut self, t: f64, out: &mut Vec<(f64, f64, u8)>);
    /// Bursts decoded.
    fn decoded(&self) -> u64;
}

macro_rules! oracle_readout {
    ($t:ident) => {
        impl<L: Layout> OracleReadout for $t<L> {
            fn event(&mut self, t: f64, x: u16, y: u16, on: bool, out: &mut Vec<(f64, f64, u8)>) {
                $t::event(self, t, x, y, on, out);
            }
            fn finish(&mut self, t: f64, out: &mut Vec<(f64, f64, u8)>) {
                $t::finish(self, t, out);
            }
            fn decoded(&self) -> u64 {
                self.samples
            }
        }
    };
}
oracle_readout!(OracleYaw);
oracle_readout!(OracleSpikeYaw);

/// Runs one piece (from `first` to its end) through the oracle readout `y`, its samples back
/// on the recording's clock; returns the bursts it decoded.
fn oracle_piece(
    mut y: impl OracleReadout,
    first: Event64,
    pieces: &mut Pieces<'_>,
    out: &mut PieceOut<'_>,
) -> Result<u64> {
    let t0 = first.t_us;
    // Times within a piece are at most RESTART_BACK_US before its first event.
    let rel = |t: u64| t as f64 - t0 as f64;
    let mut got = Vec::new();
    let mut last = 0.0f64;
    let flush = |got: &mut Vec<(f64, f64, u8)>, out: &mut PieceOut<'_>| {
        for &(t, v, flags) in got.iter() {
            out.push((t0 as f64 + t) * 1e-6, v, flags);
        }
        got.clear();
    };
    pieces.for_each(first, |ev| {
        last = rel(ev.t_us);
        y.event(last, ev.x, ev.y, ev.on, &mut got);
        flush(&mut got, out);
        out.flush_if_full()
    })?;
    y.finish(last, &mut got);
    flush(&mut got, out);
    Ok(y.decoded())
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
        pool: None,
        pool_full: 0,
        plot,
        csv,
    })
}

/// Feeds one piece (from its first event to its end) to a fresh pipeline on its u32 clock
/// (relative to the piece's first event, wrapping), sending samples with times back on the
/// recording's clock; through `ahead` when given (read ahead: see [`crate::lookahead`]).
#[allow(clippy::too_many_arguments)]
fn feed(
    p: &mut Built<'_>,
    first: Event64,
    pieces: &mut Pieces<'_>,
    period_us: u32,
    samples: &mut Samples,
    restart: bool,
    mut ahead: Option<&mut Lookahead>,
) -> Result<()> {
    let t0 = first.t_us;
    let bar = progress_bar(0);
    let mut out = PieceOut {
        samples,
        buf: Vec::with_capacity(4096),
        restart,
    };
    let mut k: u64 = 0;
    let mut last = first.t_us.wrapping_sub(t0) as u32;
    match ahead.as_deref_mut() {
        Some(la) => la.push(first),
        None => last = step(p, &first, None, t0, period_us, &mut k, &mut out),
    }
    loop {
        let slice = pieces.next_slice()?;
        if slice.is_empty() {
            break;
        }
        match ahead.as_deref_mut() {
            Some(la) => {
                for (i, e) in slice.iter().enumerate() {
                    if let Some(later) = slice.get(i + PREFETCH_DISTANCE) {
                        la.prefetch_pixel(later.x, later.y);
                    }
                    la.push(*e);
                    last = drain(p, la, false, t0, period_us, &mut k, &mut out).unwrap_or(last);
                    out.flush_if_full()?;
                }
            }
            None => {
                for e in slice {
                    last = step(p, e, None, t0, period_us, &mut k, &mut out);
                    out.flush_if_full()?;
                }
            }
        }
        bar.set_position(pieces.events);
    }
    if let Some(la) = ahead {
        last = drain(p, la, true, t0, period_us, &mut k, &mut out).unwrap_or(last);
    }
    p.finish(last, &mut |s: YawSample| {
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

/// Feeds the events the read-ahead buffer hands on (all of them with `all`: the end of the
/// piece), each with its pixel's next event, the state of the one [`PREFETCH_DISTANCE`] later
/// asked into the cache first; returns the last one's time on the pipeline's clock.
fn drain(
    p: &mut Built<'_>,
    la: &mut Lookahead,
    all: bool,
    t0: u64,
    period_us: u32,
    k: &mut u64,
    out: &mut PieceOut<'_>,
) -> Option<u32> {
    let mut last = None;
    while let Some((e, next)) = la.pop(t0, all) {
        let later = la.peek(PREFETCH_DISTANCE);
        if let Some((x, y)) = later {
            // Its pixel's entry, which the buffer reads when it hands the event on.
            la.prefetch_pixel(x, y);
        }
        if let Some(state) = later.and_then(|(x, y)| p.state_at(x, y)) {
            // Every line of its cells and its unit pair, not only the first of its own cell
            // and pair: 0.95-0.98 of the time on dev03 (normalized readout, three sets of
            // 16-20 pairs).
            prefetch(state.cells);
            if let Some(u) = state.units {
                prefetch(core::slice::from_ref(u));
            }
        }
        last = Some(step(p, &e, Some(next), t0, period_us, k, out));
    }
    last
}

/// Feeds one event of a piece starting at `t0` (µs) to the pipeline (with what is known of its
/// pixel's next event, when read ahead), sending the samples due before it (the `k`-th of the
/// piece at `t0 + k` periods); returns its time on the pipeline's clock.
#[inline]
fn step(
    p: &mut Built<'_>,
    e: &Event64,
    next: Option<NextInput>,
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
    let mut sample = |s: YawSample| {
        *k += 1;
        let t = t0 + *k * u64::from(period_us);
        out.push(
            t as f64 * 1e-6,
            f64::from(s.yaw_rate.to_bits()) / 65536.0,
            s.flags,
        );
    };
    match next {
        Some(next) => p.event_ahead(ev, next, &mut sample),
        None => p.event(ev, &mut sample),
    }
    ev.t_us
}

/// Writes the run's CSV: `t_s,yaw_rate_rad_s,flags`, or `t_s,yaw_norm` for the normalized
/// readout.
///
/// # Errors
/// When the file cannot be written.
pub fn write_yaw_csv(path: &Path, samples: &[(f64, f64, u8)], normalized: bool) -> Result<()> {
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
pub fn open_recording(input: &Path, opts: &RunOptions) -> Result<(formats::EventReader, Camera)> {
    let (size, focal_px, centre) = (opts.size, opts.focal_px, (opts.cx, opts.cy));
    let needs_focal = matches!(opts.readout, ReadoutKind::Calibrated | ReadoutKind::Spikes);
    let mut reader = formats::EventReader::open(input, opts.format, false)?;
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
