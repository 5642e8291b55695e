//! A run's settings: everything that decides its output, in one value, and the pipeline they
//! build from caller-provided storage.
//!
//! `host-sim run`, the QEMU board and the STM32 boards each resolve a [`Settings`] (from flags
//! and the recording, from a configuration frame, from the build's defaults) and call
//! [`Settings::build`]; nothing else about how a pipeline is put together lives outside this
//! module and [`crate::pipeline`]. The configuration frame (`crate::aer::config`) is the wire
//! form of the same value.
//!
//! ```text
//! Settings ──layout()──> SensorLayout (Dense | PaperBoxes); storage() ──> what to allocate
//!          ──build(kernel, NetState)──> Built: one Pipeline<layout, readout>
//! ```

use fixed::types::U16F16;

use crate::event::Event;
use crate::layout::{Dense, Layout, PaperBoxes, UnitMask};
use crate::network::{
    active_words, EventState, InputFilter, NetError, NetState, NetStats, Network, NextInput,
    PoolUse,
};
use crate::pipeline::{Pipeline, Sides, ONSET_GAP_US};
use crate::readout::calibrated::{default_tau_a_us, has_near, Calibrated, Calibration};
use crate::readout::normalized::Normalized;
use crate::readout::spikes::{SpikeCell, Spikes};
use crate::readout::{Readout, YawSample};
use crate::unit::Kernel;

/// The spike readout's slow units (computed at compile time, tables in flash).
static SLOW_UNITS: Kernel = Kernel::SLOW;

/// Largest sensor side (px): the 11-bit addresses of EVT 3.0 and of the AER stream.
pub const MAX_SENSOR_SIDE: u16 = 2048;

/// Time constant of the paper's normalized readout (µs): model.md's 10 ms.
pub const NORMALIZED_TAU_A_US: u32 = 10_000;

/// Longest readout time constant a run may ask for (µs).
pub const MAX_TAU_A_US: u32 = 1_000_000;

/// Largest unit pool a run may ask for (unit pairs).
pub const MAX_UNIT_POOL: u32 = 1 << 24;

/// Which network runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayoutChoice {
    /// Dense over the whole sensor.
    Dense,
    /// The paper's two 20 x 20 boxes (placement [`PaperBoxes::DEFAULT_SEED`]).
    PaperBoxes,
    /// Dense over a window of the sensor.
    Window {
        /// First column.
        x0: u16,
        /// First row.
        y0: u16,
        /// Columns.
        w: u16,
        /// Rows.
        h: u16,
    },
}

/// Which readout turns the network's output into samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReadoutChoice {
    /// Yaw rate in rad/s from the bursts' time codes and the camera geometry (the product's
    /// readout; needs cells only).
    Calibrated,
    /// The paper's leaky integrator of spikes (needs the spiking units; unscaled).
    Normalized,
    /// Yaw rate in rad/s from the spikes alone and the camera geometry (needs the spiking
    /// units and the readout's own memory: [`StorageNeeds::spike_cells`]).
    Spikes,
}

/// Everything that decides a run's output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Settings {
    /// Sensor width (px, 1..=[`MAX_SENSOR_SIDE`]).
    pub width: u16,
    /// Sensor height (px, 1..=[`MAX_SENSOR_SIDE`]).
    pub height: u16,
    /// Focal length (px, > 0).
    pub focal_px: U16F16,
    /// Principal point column (px).
    pub cx: U16F16,
    /// Principal point row (px).
    pub cy: U16F16,
    /// The network's layout.
    pub layout: LayoutChoice,
    /// FAC-to-TRG distance (px, >= 1).
    pub stride: u16,
    /// Output period (µs, >= 1; 1000 = 1 kHz).
    pub period_us: u32,
    /// The readout.
    pub readout: ReadoutChoice,
    /// Readout time constant `tau_A` (µs, 1..=[`MAX_TAU_A_US`]); `None` = the readout's
    /// default ([`Settings::tau_a_us`]).
    pub tau_a_us: Option<u32>,
    /// Spiking readouts: `Some(n)`: unit state in a pool of `n` unit pairs
    /// (1..=[`MAX_UNIT_POOL`]; see [`crate::network::pool`]); `None`: one pair per cell. The
    /// spike readout runs up to three networks ([`Settings::spike_networks`]), each with a
    /// pool of `n`. The calibrated readout runs no units and ignores it.
    pub unit_pool: Option<u32>,
}

/// Why settings cannot run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SettingsError {
    /// A sensor side is 0 or above [`MAX_SENSOR_SIDE`].
    Sensor,
    /// The focal length is 0.
    Focal,
    /// The output period is 0.
    Period,
    /// `tau_A` is 0 or above [`MAX_TAU_A_US`].
    TauA,
    /// The unit pool is 0 or above [`MAX_UNIT_POOL`].
    UnitPool,
    /// The layout (with its stride) does not fit the sensor.
    Layout,
    /// The storage given is smaller than the layout needs.
    Storage(NetError),
    /// The spike readout's memory is smaller than [`StorageNeeds::spike_cells`].
    SpikeCells {
        /// Cells needed.
        needed: usize,
        /// Cells given.
        given: usize,
    },
}

impl core::fmt::Display for SettingsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Sensor => write!(f, "sensor sides must be 1 to {MAX_SENSOR_SIDE} px"),
            Self::Focal => write!(f, "the focal length must be above 0"),
            Self::Period => write!(f, "the output period must be at least 1 µs"),
            Self::TauA => write!(f, "tau_A must be 1 µs to {MAX_TAU_A_US} µs"),
            Self::UnitPool => write!(f, "the unit pool must hold 1 to {MAX_UNIT_POOL} pairs"),
            Self::Layout => write!(f, "the layout (with its stride) does not fit the sensor"),
            Self::Storage(e) => write!(f, "{e}"),
            Self::SpikeCells { needed, given } => {
                write!(
                    f,
                    "the spike readout needs {needed} cells of state, {given} given"
                )
            }
        }
    }
}

/// The principal point coordinate of a sensor side's centre: `(side - 1) / 2` px (exact in
/// U16F16).
pub const fn centre_px(side: u16) -> U16F16 {
    U16F16::from_bits((side.saturating_sub(1) as u32) << 15)
}

impl Settings {
    /// The defaults for a `width` x `height` sensor with focal length `focal_px`: principal
    /// point at the centre, dense over the whole sensor, stride 2, 1 kHz, calibrated readout,
    /// its default `tau_A`.
    pub const fn for_sensor(width: u16, height: u16, focal_px: U16F16) -> Self {
        Self {
            width,
            height,
            focal_px,
            cx: centre_px(width),
            cy: centre_px(height),
            layout: LayoutChoice::Dense,
            stride: 2,
            period_us: 1_000,
            readout: ReadoutChoice::Calibrated,
            tau_a_us: None,
            unit_pool: None,
        }
    }

    /// The layout these settings run.
    ///
    /// # Errors
    /// When a value is out of range or the layout does not fit the sensor.
    pub fn layout(&self) -> Result<SensorLayout, SettingsError> {
        let side_ok = |s: u16| (1..=MAX_SENSOR_SIDE).contains(&s);
        if !side_ok(self.width) || !side_ok(self.height) {
            return Err(SettingsError::Sensor);
        }
        if self.focal_px == U16F16::ZERO {
            return Err(SettingsError::Focal);
        }
        if self.period_us == 0 {
            return Err(SettingsError::Period);
        }
        if self.tau_a_us.is_some_and(|t| t == 0 || t > MAX_TAU_A_US) {
            return Err(SettingsError::TauA);
        }
        if self.unit_pool.is_some_and(|n| n == 0 || n > MAX_UNIT_POOL) {
            return Err(SettingsError::UnitPool);
        }
        let (w, h, s) = (self.width, self.height, self.stride);
        let layout = match self.layout {
            LayoutChoice::Dense => Dense::new(w, h, s).map(SensorLayout::Dense),
            LayoutChoice::Window {
                x0,
                y0,
                w: ww,
                h: wh,
            } => Dense::window(w, h, x0, y0, ww, wh, s).map(SensorLayout::Dense),
            LayoutChoice::PaperBoxes => {
                PaperBoxes::with_stride(w, h, s, PaperBoxes::DEFAULT_SEED).map(SensorLayout::Boxes)
            }
        };
        layout.ok_or(SettingsError::Layout)
    }

    /// Checks every value (as [`Settings::layout`] does).
    ///
    /// # Errors
    /// As [`Settings::layout`].
    pub fn validate(&self) -> Result<(), SettingsError> {
        self.layout().map(|_| ())
    }

    /// The readout time constant for a layout of `units` units (µs): the one given, else
    /// [`default_tau_a_us`] for the calibrated and spike readouts (the same field) and
    /// [`NORMALIZED_TAU_A_US`] for the normalized one.
    pub const fn tau_a_us(&self, units: usize) -> u32 {
        match (self.tau_a_us, self.readout) {
            (Some(t), _) => t,
            (None, ReadoutChoice::Calibrated | ReadoutChoice::Spikes) => default_tau_a_us(units),
            (None, ReadoutChoice::Normalized) => NORMALIZED_TAU_A_US,
        }
    }

    /// The storage a run needs.
    ///
    /// # Errors
    /// As [`Settings::layout`].
    pub fn storage(&self) -> Result<StorageNeeds, SettingsError> {
        let layout = self.layout()?;
        let cells = layout.cell_count();
        let unit_pairs = self.unit_pool.map_or(cells, |n| n as usize);
        let pool_owners = self.unit_pool.map_or(0, |n| n as usize);
        Ok(match self.readout {
            ReadoutChoice::Calibrated => StorageNeeds {
                cells,
                unit_pairs: 0,
                pool_owners: 0,
                active_words: 0,
                spike_cells: 0,
            },
            ReadoutChoice::Normalized => StorageNeeds {
                cells,
                unit_pairs,
                pool_owners,
                active_words: active_words(unit_pairs),
                spike_cells: 0,
            },
            // Networks over the layout (the paper's units, the slow ones, the near ones), each
            // with the pool's size; `build` splits every slice among them
            // (`NetState::split_off`).
            ReadoutChoice::Spikes => {
                let n = Self::spike_networks(&layout);
                StorageNeeds {
                    cells: n * cells,
                    unit_pairs: n * unit_pairs,
                    pool_owners: n * pool_owners,
                    active_words: n * active_words(unit_pairs),
                    spike_cells: n * Spikes::cells_for(&layout),
                }
            }
        })
    }

    /// The pipeline these settings describe, over `state` (at least [`Settings::storage`]).
    ///
    /// # Errors
    /// When the settings do not validate or `state` is too small.
    pub fn build<'a>(
        &self,
        kernel: &'a Kernel,
        state: NetState<'a>,
    ) -> Result<Built<'a>, SettingsError> {
        self.build_with(kernel, state, &mut [])
    }

    /// [`Settings::build`], with the spike readout's memory in `spike_cells` (at least
    /// [`StorageNeeds::spike_cells`]; the other readouts need none).
    ///
    /// # Errors
    /// When the settings do not validate or `state` or `spike_cells` is too small.
    pub fn build_with<'a>(
        &self,
        kernel: &'a Kernel,
        state: NetState<'a>,
        spike_cells: &'a mut [SpikeCell],
    ) -> Result<Built<'a>, SettingsError> {
        let layout = self.layout()?;
        // The rad/s readouts (calibrated, spikes) share the calibration and the onset filter.
        let cal = Calibration {
            tau_a_us: self.tau_a_us(layout.unit_count()),
            period_us: self.period_us,
            ..Calibration::new(self.focal_px, self.cx, self.cy)
        };
        let onsets = InputFilter::Onsets {
            gap_us: ONSET_GAP_US,
        };
        let state = self.state_for_readout(state);
        Ok(match self.readout {
            ReadoutChoice::Calibrated => {
                let readout = Calibrated::new(kernel, &layout, cal);
                Built::Calibrated(OnLayout::new(
                    kernel,
                    layout,
                    state,
                    onsets,
                    readout,
                    self.period_us,
                )?)
            }
            ReadoutChoice::Normalized => {
                let readout = Normalized::new(cal.tau_a_us, self.period_us);
                Built::Normalized(OnLayout::new(
                    kernel,
                    layout,
                    state,
                    InputFilter::All,
                    readout,
                    self.period_us,
                )?)
            }
            ReadoutChoice::Spikes => {
                let per_network = Spikes::cells_for(&layout);
                let networks = Self::spike_networks(&layout);
                let short = SettingsError::SpikeCells {
                    needed: per_network.saturating_mul(networks),
                    given: spike_cells.len(),
                };
                if spike_cells.len() < per_network.saturating_mul(networks) {
                    return Err(short);
                }
                let (fast_cells, rest) =
                    spike_cells.split_at_mut_checked(per_network).ok_or(short)?;
                let (slow_cells, near_cells) =
                    rest.split_at_mut_checked(per_network).ok_or(short)?;
                let (state, rest) = state.split_off(networks);
                let (slow_state, near_state) = match networks {
                    3 => {
                        let (slow, near) = rest.split_off(2);
                        (slow, Some(near))
                    }
                    _ => (rest, None),
                };
                let readout = Spikes::new(kernel, layout.clone(), cal, fast_cells)
                    .with_slow_units(&SLOW_UNITS, slow_cells)
                    .with_near_units(near_cells);
                Built::Spikes(OnLayout::with_sides(
                    kernel,
                    layout,
                    state,
                    SideStates {
                        slow: Some((&SLOW_UNITS, slow_state)),
                        near: near_state,
                    },
                    onsets,
                    readout,
                    self.period_us,
                )?)
            }
        })
    }
}

impl Settings {
    /// Spiking networks the spike readout runs over `layout`: the paper's units, the slow
    /// units and, where the layout has near units ([`has_near`]), the near units.
    pub fn spike_networks<L: Layout>(layout: &L) -> usize {
        2 + usize::from(has_near(layout))
    }

    /// `state` as the readout runs it: the calibrated readout runs no units (whatever unit
    /// memory `state` has stays unused).
    fn state_for_readout<'a>(&self, state: NetState<'a>) -> NetState<'a> {
        match self.readout {
            ReadoutChoice::Calibrated => state.without_units(),
            ReadoutChoice::Normalized | ReadoutChoice::Spikes => state,
        }
    }
}

/// What a run needs of the caller's memory (counts of [`crate::network::Cell`],
/// [`crate::network::UnitPair`] and `u32` words).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StorageNeeds {
    /// Cells (12 bytes each).
    pub cells: usize,
    /// Unit pairs ([`crate::network::Network::UNIT_PAIR_BYTES`] each): one per cell, or the
    /// pool's; 0 when the units do not run.
    pub unit_pairs: usize,
    /// Owner words (`u32`) of the unit pool ([`NetState::pooled`]); 0 without a pool.
    pub pool_owners: usize,
    /// Words of the active bitset; 0 when the units do not run.
    pub active_words: usize,
    /// The spike readout's per-pixel state ([`SpikeCell`]s, 24 bytes each); 0 for the other
    /// readouts.
    pub spike_cells: usize,
}

/// The layouts [`Settings`] choose from.
// One value per run, in place (no heap to box the boxes' placement table into).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SensorLayout {
    /// Dense, over the whole sensor or a window of it.
    Dense(Dense),
    /// The paper's boxes.
    Boxes(PaperBoxes),
}

/// Calls `$e` with `$l` bound to the inner layout.
macro_rules! each_layout {
    ($s:expr, $l:ident => $e:expr) => {
        match $s {
            SensorLayout::Dense($l) => $e,
            SensorLayout::Boxes($l) => $e,
        }
    };
}

impl Layout for SensorLayout {
    #[inline]
    fn cell_count(&self) -> usize {
        each_layout!(self, l => l.cell_count())
    }
    #[inline]
    fn unit_count(&self) -> usize {
        each_layout!(self, l => l.unit_count())
    }
    #[inline]
    fn stride(&self) -> u16 {
        each_layout!(self, l => l.stride())
    }
    #[inline]
    fn sensor(&self) -> (u16, u16) {
        each_layout!(self, l => l.sensor())
    }
    #[inline]
    fn cell(&self, x: u16, y: u16) -> Option<usize> {
        each_layout!(self, l => l.cell(x, y))
    }
    #[inline]
    fn units(&self, cell: usize) -> UnitMask {
        each_layout!(self, l => l.units(cell))
    }
    #[inline]
    fn pixel(&self, cell: usize) -> (u16, u16) {
        each_layout!(self, l => l.pixel(cell))
    }
    #[inline]
    fn units_at(&self, x: u16, y: u16, cell: usize) -> UnitMask {
        each_layout!(self, l => l.units_at(x, y, cell))
    }
    #[inline]
    fn neighbor(&self, x: u16, y: u16, cell: usize, dx: i32) -> Option<usize> {
        each_layout!(self, l => l.neighbor(x, y, cell, dx))
    }
}

/// A pipeline built from [`Settings`]: one variant per readout, each over either layout
/// (static dispatch: the per-event cost is two predictable branches, not a call through the
/// layout on every pixel lookup).
// One value per run, in place (no heap); the calibrated readout's histograms are most of it.
#[allow(clippy::large_enum_variant)]
pub enum Built<'a> {
    /// The calibrated readout (rad/s).
    Calibrated(OnLayout<'a, Calibrated>),
    /// The paper's normalized readout (unscaled).
    Normalized(OnLayout<'a, Normalized>),
    /// The spike readout (rad/s).
    Spikes(OnLayout<'a, Spikes<'a, SensorLayout>>),
}

/// The state of the side networks a pipeline is built with: the slow units' (their kernel and
/// state) and the near units' (the main kernel).
struct SideStates<'a> {
    slow: Option<(&'a Kernel, NetState<'a>)>,
    near: Option<NetState<'a>>,
}

/// A pipeline with readout `R` over one of the layouts [`Settings`] choose from.
// One value per run, in place (no heap).
#[allow(clippy::large_enum_variant)]
pub enum OnLayout<'a, R: Readout> {
    /// Dense, over the whole sensor or a window of it.
    Dense(Pipeline<'a, Dense, R>),
    /// The paper's boxes.
    Boxes(Pipeline<'a, PaperBoxes, R>),
}

/// Calls `$e` with `$p` bound to the inner pipeline.
macro_rules! each_layout_pipeline {
    ($s:expr, $p:ident => $e:expr) => {
        match $s {
            OnLayout::Dense($p) => $e,
            OnLayout::Boxes($p) => $e,
        }
    };
}

impl<'a, R: Readout> OnLayout<'a, R> {
    /// The pipeline over `layout`, with `readout` and state in `state`.
    #[inline(never)]
    fn new(
        kernel: &'a Kernel,
        layout: SensorLayout,
        state: NetState<'a>,
        filter: InputFilter,
        readout: R,
        period_us: u32,
    ) -> Result<Self, SettingsError> {
        let sides = SideStates {
            slow: None,
            near: None,
        };
        Self::with_sides(kernel, layout, state, sides, filter, readout, period_us)
    }

    /// The same, with side networks in `sides` (same layout and input filter).
    #[inline(never)]
    fn with_sides(
        kernel: &'a Kernel,
        layout: SensorLayout,
        state: NetState<'a>,
        sides: SideStates<'a>,
        filter: InputFilter,
        readout: R,
        period_us: u32,
    ) -> Result<Self, SettingsError> {
        fn nets<'a, L: Layout + Clone>(
            kernel: &'a Kernel,
            l: L,
            state: NetState<'a>,
            sides: SideStates<'a>,
            filter: InputFilter,
        ) -> Result<(Network<'a, L>, Sides<'a, L>), SettingsError> {
            let net = |k, s| Network::new(k, l.clone(), s, filter).map_err(SettingsError::Storage);
            let slow = sides.slow.map(|(k, s)| net(k, s)).transpose()?;
            let near = sides
                .near
                .map(|s| net(kernel, s).map(Network::near_units))
                .transpose()?;
            Ok((net(kernel, state)?, Sides { slow, near }))
        }
        Ok(match layout {
            SensorLayout::Dense(l) => {
                let (net, sides) = nets(kernel, l, state, sides, filter)?;
                OnLayout::Dense(Pipeline::with_sides(net, sides, readout, period_us))
            }
            SensorLayout::Boxes(l) => {
                let (net, sides) = nets(kernel, l, state, sides, filter)?;
                OnLayout::Boxes(Pipeline::with_sides(net, sides, readout, period_us))
            }
        })
    }

    /// Processes one event (see [`Pipeline::event`]).
    #[inline]
    pub fn event<F: FnMut(YawSample)>(&mut self, ev: Event, out: &mut F) {
        each_layout_pipeline!(self, p => p.event(ev, out));
    }

    /// Processes one event whose cell's next event is known (see [`Pipeline::event_ahead`]).
    #[inline]
    pub fn event_ahead<F: FnMut(YawSample)>(&mut self, ev: Event, next: NextInput, out: &mut F) {
        each_layout_pipeline!(self, p => p.event_ahead(ev, next, out));
    }

    /// The state an event at `(x, y)` will touch first (see [`Pipeline::state_at`]).
    pub fn state_at(&self, x: u16, y: u16) -> Option<EventState<'_>> {
        each_layout_pipeline!(self, p => p.state_at(x, y))
    }

    /// Whether reading the input ahead serves this pipeline (see [`Pipeline::reads_ahead`]).
    pub fn reads_ahead(&self) -> bool {
        each_layout_pipeline!(self, p => p.reads_ahead())
    }

    /// Moves the clock to `now_us` without an event (see [`Pipeline::poll`]).
    pub fn poll<F: FnMut(YawSample)>(&mut self, now_us: u32, out: &mut F) {
        each_layout_pipeline!(self, p => p.poll(now_us, out));
    }

    /// Ends the run at `now_us` (see [`Pipeline::finish`]).
    pub fn finish<F: FnMut(YawSample)>(&mut self, now_us: u32, out: &mut F) {
        each_layout_pipeline!(self, p => p.finish(now_us, out));
    }

    /// The network's counters.
    pub fn net_stats(&self) -> &NetStats {
        each_layout_pipeline!(self, p => p.network().stats())
    }

    /// How full the unit pool is (`None`: no pool).
    pub fn pool_use(&self) -> Option<PoolUse> {
        each_layout_pipeline!(self, p => p.pool_use())
    }

    /// Unit inputs lost to a full unit pool (all networks of the spike readout).
    pub fn pool_full(&self) -> u64 {
        each_layout_pipeline!(self, p => p.pool_full())
    }

    /// Spikes of all networks (see [`Pipeline::spike_count`]).
    pub fn spike_count(&self) -> u64 {
        each_layout_pipeline!(self, p => p.spike_count())
    }

    /// The readout.
    pub fn readout(&self) -> &R {
        each_layout_pipeline!(self, p => p.readout())
    }

    /// Samples produced.
    pub fn samples(&self) -> u64 {
        each_layout_pipeline!(self, p => p.samples)
    }
}

/// Calls `$e` with `$p` bound to the [`OnLayout`] of each readout.
macro_rules! each_pipeline {
    ($s:expr, $p:ident => $e:expr) => {
        match $s {
            Built::Calibrated($p) => $e,
            Built::Normalized($p) => $e,
            Built::Spikes($p) => $e,
        }
    };
}

/// Work on the one pipeline a [`Built`] holds, with its layout and readout known at compile
/// time: a loop over many events inside [`WithPipeline::run`] dispatches on them once
/// ([`Built::with`]), not once per event.
pub trait WithPipeline {
    /// What the work gives back.
    type Output;
    /// Does the work on `p`.
    fn run<L: Layout, R: Readout>(self, p: &mut Pipeline<'_, L, R>) -> Self::Output;
}

impl Built<'_> {
    /// Runs `work` on the pipeline (one dispatch on the readout and layout).
    #[inline]
    pub fn with<W: WithPipeline>(&mut self, work: W) -> W::Output {
        match self {
            Built::Calibrated(OnLayout::Dense(p)) => work.run(p),
            Built::Calibrated(OnLayout::Boxes(p)) => work.run(p),
            Built::Normalized(OnLayout::Dense(p)) => work.run(p),
            Built::Normalized(OnLayout::Boxes(p)) => work.run(p),
            Built::Spikes(OnLayout::Dense(p)) => work.run(p),
            Built::Spikes(OnLayout::Boxes(p)) => work.run(p),
        }
    }

    /// Processes one event (see [`Pipeline::event`]).
    #[inline]
    pub fn event<F: FnMut(YawSample)>(&mut self, ev: Event, out: &mut F) {
        each_pipeline!(self, p => p.event(ev, out));
    }

    /// Processes one event whose cell's next event is known (see [`Pipeline::event_ahead`]).
    #[inline]
    pub fn event_ahead<F: FnMut(YawSample)>(&mut self, ev: Event, next: NextInput, out: &mut F) {
        each_pipeline!(self, p => p.event_ahead(ev, next, out));
    }

    /// The state an event at `(x, y)` will touch first (see [`Pipeline::state_at`]).
    pub fn state_at(&self, x: u16, y: u16) -> Option<EventState<'_>> {
        each_pipeline!(self, p => p.state_at(x, y))
    }

    /// Whether reading the input ahead serves this pipeline (see [`Pipeline::reads_ahead`]).
    pub fn reads_ahead(&self) -> bool {
        each_pipeline!(self, p => p.reads_ahead())
    }

    /// Moves the clock to `now_us` without an event (see [`Pipeline::poll`]).
    pub fn poll<F: FnMut(YawSample)>(&mut self, now_us: u32, out: &mut F) {
        each_pipeline!(self, p => p.poll(now_us, out));
    }

    /// Ends the run at `now_us` (see [`Pipeline::finish`]).
    pub fn finish<F: FnMut(YawSample)>(&mut self, now_us: u32, out: &mut F) {
        each_pipeline!(self, p => p.finish(now_us, out));
    }

    /// The network's counters.
    pub fn net_stats(&self) -> &NetStats {
        each_pipeline!(self, p => p.net_stats())
    }

    /// How full the unit pool is (`None`: no pool).
    pub fn pool_use(&self) -> Option<PoolUse> {
        each_pipeline!(self, p => p.pool_use())
    }

    /// Unit inputs lost to a full unit pool (all networks of the spike readout).
    pub fn pool_full(&self) -> u64 {
        each_pipeline!(self, p => p.pool_full())
    }

    /// Spikes of the network, and of the side networks for the spike readout.
    pub fn spike_count(&self) -> u64 {
        each_pipeline!(self, p => p.spike_count())
    }

    /// What the readout consumed: bursts decoded (calibrated, spikes) or spikes (normalized).
    pub fn outputs(&self) -> u64 {
        match self {
            Built::Calibrated(p) => p.readout().samples,
            Built::Normalized(p) => {
                let s = p.net_stats();
                s.spikes_lr + s.spikes_rl
            }
            Built::Spikes(p) => p.readout().samples(),
        }
    }

    /// Samples produced.
    pub fn samples(&self) -> u64 {
        each_pipeline!(self, p => p.samples())
    }
}
