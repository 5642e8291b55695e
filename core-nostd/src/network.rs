//! The TDE network: events in; trigger records and spikes out; over a [`Layout`], with all state
//! in caller-provided slices.
//!
//! State is kept per pixel in two slices: a [`Cell`] (12 bytes: the pixel's FAC traces and the
//! time they refer to) and a [`UnitPair`] (48 bytes: the two units the pixel triggers, in the
//! burst engine's form, see [`crate::unit::BurstUnit`]). The unit slice is only needed by sinks
//! that want spikes; the calibrated readout decodes bursts from their drives and runs with cells
//! alone. FAC traces are stored exactly as computed (see [`Trace`] for why 16 bits are not
//! enough): as [`Trace`]s (saturating at 16) without units, as [`WideTrace`]s (saturating at
//! 128: busy pixels of real sensors pass 16) when the units run. The top bit of the stored FAC
//! trace holds the polarity of the pixel's last event (for the onset filter). Which units a
//! pixel has comes from the layout.
//!
//! # What comes out
//! - For every event that triggers units, one [`Trigger`]: the drive `w_T · I_F(t⁻)` each of
//!   the pixel's two units receives, which is what its burst encodes (a burst from rest is a
//!   monotone function of it: the sweep), and the pixel's own FAC trace after the event.
//! - If the sink asks for them ([`NetSink::SPIKES`]), every spike of every unit, each at the
//!   whole µs nearest to its exact time. A TRG event computes where its unit's burst goes (the
//!   next spike's place on the burst orbit); the spikes themselves come out lazily, in order:
//!   those of a unit up to an event's time before that event acts on it, and all of them up to
//!   `t` at [`Network::tick`]`(t)`, which visits only the cells marked in the active bitset (a
//!   unit with a spike pending) and there only units with a spike due. Each spike costs one
//!   table lookup; a cell whose units cannot spike again is not visited. A sink that does not
//!   want spikes skips the units altogether.
//! - With a unit pool ([`NetState::pooled`]) only the cells whose units are not at rest hold
//!   unit state (see [`pool`]); while the pool has room the spikes are the same.
//! - A sink that can hold spikes for future outputs ([`NetSink::ahead_us`], the normalized
//!   readout) gets them up to that far beyond the clock, a unit in a dense burst being visited
//!   once per that span instead of once per tick; an event that changes a unit's burst takes
//!   back its spikes given beyond the event ([`NetSink::retract`]). The spikes that stay are
//!   exactly those of emission at the clock (tested).
//! - A sparse sink ([`NetSink::SPARSE`], the spike readout) gets the first three spikes of a
//!   unit after every input that reached it mid-burst, two after one that started a burst,
//!   as they come. Then the unit leaves the tick's schedule: its burst's last two spikes
//!   before what next acts on it (its next input, the pool freeing its slot, the round-robin
//!   settling it, the end of the recording) are delivered then, late, or not at all when they
//!   are older than the sink still reads ([`NetSink::tail_memory_us`]); the spikes between
//!   are counted, not computed one by one (their places on the orbit are known: the burst
//!   tables' rows). A burst of `n` spikes then costs at most three visits by the tick and
//!   five spikes delivered, not `n` (21 spikes per burst on the
//!   STM32F405's strip at dev03's rate). What the spike readout decodes from them is what it
//!   decodes from every spike, except inputs it would only have noticed after the second
//!   interval that followed them (tested).
//!
//! # Input filter
//! [`InputFilter::Onsets`] passes only the first event of each same-polarity run at a pixel (or
//! an event after `gap` without onset): one event per edge and pixel, which makes the drive an
//! unbiased code of the edge's travel time (see the readout).

use crate::event::Event;
use crate::exp_table::{scale_q31, ExpDecay};
use crate::layout::{Dir, Layout, UnitMask};
use crate::params::{Trace, TAU_SLOW_US};
use crate::time::EventTime;
use crate::unit::{elapsed_us, fine, is_late, reported_by, BurstUnit, FineTime, Kernel, WideTrace};

pub mod pool;

use pool::Pool;
pub use pool::PoolUse;

/// With the onset filter, a same-polarity event starts a new edge for the slow units only when
/// their last onset at the pixel is older than this (µs): a slow edge takes this long to pass a
/// pixel and leaves several same-polarity events on the way, which a shorter onset gap would
/// count as new edges.
pub const SLOW_ONSET_GAP_US: u32 = 250_000;

/// Decay table of the slow units' FAC traces (computed at compile time, in flash).
static SLOW_DECAY: ExpDecay = ExpDecay::new(TAU_SLOW_US);

/// A slow FAC trace decayed over `dt` µs.
#[inline]
fn decay_slow(i: Trace, dt_us: u32) -> Trace {
    Trace::from_bits(scale_q31(i.to_bits(), SLOW_DECAY.decay_bits(dt_us)))
}

/// The FAC traces of a pixel's units' FAC pixels at one distance, at an event's time.
#[derive(Clone, Copy, Debug, Default)]
struct Neighbours {
    /// Stored FAC trace bits (see [`Cell`]) of the left-to-right and right-to-left unit's FAC
    /// pixel (0 where the pixel has no such unit).
    fac: [u32; 2],
    /// Their slow FAC traces (zero unless the sink asks for them).
    slow: [Trace; 2],
}

/// Stored FAC trace: top bit = polarity of the pixel's last event (1 = ON).
const POLARITY: u32 = 1 << 31;

/// A pixel's FAC traces and clock. 12 bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(C)]
pub struct Cell {
    /// Time (µs) the state refers to (of the cell and of its [`UnitPair`]).
    t_us: u32,
    /// FAC trace ([`Trace`] bits) and, in the top bit, the last polarity.
    i_fac: u32,
    /// Without a unit pool: the FAC trace of the slow units (time constant [`TAU_SLOW_US`],
    /// [`Trace`] bits), kept only for sinks that ask for it ([`NetSink::SLOW`]), else 0.
    /// With a unit pool: the pool slot of the cell's units plus 1 (0: none).
    aux: u32,
}

/// The two units a pixel triggers (left-to-right, right-to-left). 48 bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(C, align(16))]
pub struct UnitPair {
    units: [BurstUnit; 2],
}

impl UnitPair {
    /// A unit pair at rest (for static arrays).
    pub const DEFAULT: Self = Self {
        units: [BurstUnit::IDLE; 2],
    };

    #[inline]
    fn is_live(&self) -> bool {
        self.units.iter().any(|u| !u.is_idle())
    }

    /// Whether a unit has a spike that a tick emits when it is due
    /// ([`BurstUnit::scheduled`]): the cell stays in the active set while one does.
    #[inline]
    fn scheduled(&self) -> bool {
        self.units.iter().any(BurstUnit::scheduled)
    }

    /// Whether both units are at rest at `t_us` ([`Kernel::burst_at_rest`]): a pool may free
    /// them.
    #[inline]
    fn at_rest(&self, kernel: &Kernel, t_us: u32) -> bool {
        self.units.iter().all(|u| kernel.burst_at_rest(u, t_us))
    }

    /// Whether a unit's next spike is reported at or before `t_us`.
    #[inline(always)]
    fn due(&self, t_us: u32) -> bool {
        let [lr, rl] = &self.units;
        lr.due(t_us) | rl.due(t_us)
    }

    /// The unit of orientation `dir`.
    pub fn unit(&self, dir: Dir) -> &BurstUnit {
        let [lr, rl] = &self.units;
        match dir {
            Dir::LeftToRight => lr,
            Dir::RightToLeft => rl,
        }
    }
}

impl Cell {
    /// A cell at rest (for static arrays).
    pub const DEFAULT: Self = Self {
        t_us: 0,
        i_fac: 0,
        aux: 0,
    };

    /// Whether a FAC trace still changes with time (`pooled`: the network has a unit pool, so
    /// `aux` is a slot, not a trace).
    #[inline]
    fn is_live(&self, pooled: bool) -> bool {
        (self.i_fac & !POLARITY) != 0 || (!pooled && self.aux != 0)
    }

    /// The slow FAC trace (networks without a unit pool).
    #[inline]
    fn slow(&self) -> Trace {
        Trace::from_bits(self.aux)
    }

    /// The pool slot of the cell's units (networks with a unit pool).
    #[inline]
    fn slot(&self) -> Option<usize> {
        (self.aux as usize).checked_sub(1)
    }

    #[inline]
    fn set_slot(&mut self, slot: Option<usize>) {
        self.aux = slot.map_or(0, |s| s as u32 + 1);
    }

    /// The FAC trace's bits: a [`Trace`], or a [`WideTrace`] when the units run.
    #[inline]
    fn fac(&self) -> u32 {
        self.i_fac & !POLARITY
    }

    #[inline]
    fn set_fac(&mut self, bits: u32) {
        self.i_fac = (self.i_fac & POLARITY) | (bits & !POLARITY);
    }
}

/// A spike of one unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Spike {
    /// Time (µs).
    pub t_us: u32,
    /// Cell (TRG pixel) of the unit.
    pub cell: u32,
    /// Orientation of the unit.
    pub dir: Dir,
}

impl Spike {
    /// A unit id unique within the layout: `2 · cell + slot`.
    pub fn unit_id(&self) -> u32 {
        self.cell
            .wrapping_mul(2)
            .wrapping_add(self.dir.slot() as u32)
    }
}

/// One event at a pixel that triggers units: what each of its units' bursts encodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Trigger {
    /// Event time (µs).
    pub t_us: u32,
    /// Pixel.
    pub x: u16,
    /// Pixel row.
    pub y: u16,
    /// Drive `w_T · I_F(t⁻)` to the left-to-right and right-to-left unit (0 where the layout has
    /// no such unit).
    pub drive: [Trace; 2],
    /// The pixel's own FAC trace just after this event.
    pub own_fac: Trace,
    /// The same for the slow units (FAC time constant [`TAU_SLOW_US`]): drives `w_T · I_S(t⁻)`
    /// of the pixel's two slow units and its own slow trace after the event. Zero unless the
    /// sink asks for them ([`NetSink::SLOW`]). Of the near slow units instead when the sink
    /// says so ([`NetSink::reads`]).
    pub slow_drive: [Trace; 2],
    /// The pixel's own slow FAC trace just after this event (see `slow_drive`).
    pub own_slow: Trace,
    /// Drives of the near units: the same two units with their FAC pixel one pixel away
    /// instead of the layout's stride. Zero unless the sink asks for them ([`NetSink::NEAR`])
    /// and the stride is above 1.
    pub near_drive: [Trace; 2],
    /// Drives `w_T · I_F(t⁻)` from the pixels the layout's stride above and below (what a
    /// vertical unit pair would receive; [`crate::readout::aperture`]). Zero unless the sink
    /// asks for them ([`NetSink::VERTICAL`]), for an onset none of whose drives (`drive`,
    /// `near_drive`) makes a burst, and where the layout has no such pixel.
    pub vertical_drive: [Trace; 2],
}

/// Most spikes the network hands a sink at once ([`NetSink::spikes`]). On the host, where a
/// recording read ahead has a unit emit its burst up to its next input at once, 128 takes
/// 0.91 of the time of 32 on dev03 with the normalized readout (median of 16 pairs; 256 and 512
/// were slower again); the output is the same for any length.
#[cfg(not(target_os = "none"))]
pub const SPIKE_RUN: usize = 128;

/// Most spikes the network hands a sink at once ([`NetSink::spikes`]). On the MCU, 128 instead
/// of 32 saves 3 instructions per event with the normalized readout on the F405 window but
/// costs the spike readout 4 (398 → 402, dev03 in QEMU).
#[cfg(target_os = "none")]
pub const SPIKE_RUN: usize = 32;

/// Where the network's output goes.
pub trait NetSink {
    /// Whether this sink wants individual spikes. When `false` the network does not run the
    /// units' membrane dynamics at all (their bursts are described by [`Trigger`]s).
    const SPIKES: bool;
    /// Whether this sink wants the slow units' drives in its [`Trigger`]s. When `false` the
    /// network keeps no slow traces (they cost three more decays per onset).
    const SLOW: bool = false;
    /// Whether this sink wants the near units' drives in its [`Trigger`]s (FAC pixel one pixel
    /// away). When `false` the network reads only the layout's stride (the near drives cost
    /// two more neighbour reads per onset).
    const NEAR: bool = false;
    /// Whether this sink wants the vertical drives in its [`Trigger`]s (two more neighbour
    /// reads per onset whose units burst).
    const VERTICAL: bool = false;
    /// With [`NetSink::NEAR`]: which FAC pixels to read for the next event, at row `y` (the
    /// drives of those not read are zero).
    fn reads(&self, _y: u16) -> Reads {
        Reads::LAYOUT
    }
    /// One triggering event.
    fn trigger(&mut self, _t: &Trigger) {}
    /// One spike (spikes of one unit arrive in time order; a spike at `t` arrives before any
    /// event after `t` and at the latest at the first [`Network::tick`] at or after `t`, or up
    /// to [`NetSink::ahead_us`] earlier, or [`NetSink::reach_us`] with
    /// [`Network::event_in_ahead`]).
    fn spike(&mut self, _s: Spike) {}
    /// A run of spikes of one unit (cell `cell`, orientation `dir`), at the whole µs in
    /// `times`, in time order: what [`NetSink::spike`] would get one by one, in the same order
    /// (the default does just that). The network hands a unit's spikes over in runs of up to
    /// [`SPIKE_RUN`], so that a sink can do per run what it would do per spike (find an
    /// output bin, say).
    #[inline]
    fn spikes(&mut self, cell: u32, dir: Dir, times: &[u32]) {
        for &t_us in times {
            self.spike(Spike { t_us, cell, dir });
        }
    }
    /// How far (µs) beyond the clock this sink takes spikes: [`Network::tick`]`(t)` then emits
    /// every spike up to `t + ahead_us()` (a unit in a dense burst is visited once per that
    /// much time rather than once per tick). An event that changes a unit's burst takes back
    /// ([`NetSink::retract`]) its spikes emitted beyond the event's time. 0 (the default): only
    /// spikes up to the clock, never taken back.
    fn ahead_us(&self) -> u32 {
        0
    }
    /// How far (µs) beyond the clock this sink takes spikes at all: where the caller knows
    /// the inputs to come ([`Network::event_in_ahead`]), a unit emits its spikes up to its
    /// cell's next event, at most this far ahead, right after an input. Default:
    /// [`NetSink::ahead_us`].
    fn reach_us(&self) -> u32 {
        self.ahead_us()
    }
    /// A spike emitted ahead of the clock that an event has cancelled (the same [`Spike`] as
    /// given to [`NetSink::spike`]; the latest of a unit first).
    fn retract(&mut self, _s: Spike) {}
    /// Whether this sink takes each burst sparsely: the first three spikes after each input
    /// that reached a unit mid-burst (two after one that started a burst) as they come; of
    /// the rest of the burst only the last two at or before what next acts on the unit (its
    /// next input, the pool freeing its state, the end of the recording), delivered then,
    /// after the spikes of other units that came before; and those not at all when they came
    /// more than [`NetSink::tail_memory_us`] before it. The
    /// skipped spikes are counted in [`NetStats`] (see [`Kernel::burst_emit_run`]). Between
    /// the spikes it gets, a burst follows its orbit: nothing acted on the unit. For a sink
    /// that reads the first intervals after each input and the one before it, not every
    /// spike; only without [`NetSink::ahead_us`].
    const SPARSE: bool = false;
    /// With [`NetSink::SPARSE`]: the next spike of unit `dir` at `cell` follows spikes of its
    /// burst that were skipped.
    fn resume(&mut self, _cell: u32, _dir: Dir) {}
    /// With [`NetSink::SPARSE`]: how long (µs) after a unit's last spike the sink still reads
    /// it (for the next spike's interval). A burst whose last spike is older than this when
    /// something next acts on the unit delivers nothing more. Default: forever.
    fn tail_memory_us(&self) -> u32 {
        u32::MAX
    }
}

/// What a caller that reads its input ahead (a recording, not a live sensor) knows of the next
/// event at an event's cell ([`Network::event_in_ahead`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NextInput {
    /// The cell's next event comes at this time (µs), and no event between the two in the
    /// stream is later than it: every output tick up to it comes after that event.
    At(u32),
    /// No event at the cell is known before this time (µs; the end of what was read ahead).
    /// A hint: spikes emitted up to it that an earlier input cancels are taken back.
    NotBefore(u32),
}

/// Which FAC pixels the network reads for one event of a sink with [`NetSink::NEAR`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reads {
    /// The layout's units' (at its stride).
    pub layout: bool,
    /// The near units' (one pixel away).
    pub near: bool,
    /// Whether the slow traces are read at the near units' FAC pixels (else at the layout's):
    /// they are read at one distance only.
    pub slow_near: bool,
}

impl Reads {
    /// The layout's units only.
    pub const LAYOUT: Self = Self {
        layout: true,
        near: false,
        slow_near: false,
    };
}

/// Any `FnMut(Spike)` is a spike sink.
impl<F: FnMut(Spike)> NetSink for F {
    const SPIKES: bool = true;
    fn spike(&mut self, s: Spike) {
        self(s)
    }
}

/// Which events enter the network.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputFilter {
    /// Every event (the paper's network).
    All,
    /// Only onsets: an event whose polarity differs from the pixel's previous event, or that
    /// comes when the pixel's FAC trace shows no onset within `gap_us`.
    Onsets {
        /// Longest same-polarity run (µs) before an event counts as a new onset.
        gap_us: u32,
    },
}

/// Counters of what the network saw.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NetStats {
    /// Events processed: those inside the layout (all events offered: `events + ignored`).
    pub events: u64,
    /// Events outside the sensor or the layout, ignored (a pipeline offers its side networks
    /// only the events inside: [`crate::pipeline::Pipeline::event`]).
    pub ignored: u64,
    /// Events the input filter held back.
    pub filtered: u64,
    /// Events whose time lay before their cell's time (processed at the cell's time).
    pub out_of_order: u64,
    /// Spikes of left-to-right units emitted and not taken back. Spikes emitted ahead of the
    /// clock ([`NetSink::ahead_us`]) count from their emission; [`Network::flush`] takes back
    /// those beyond its time, so after it the counts are those of emission at the clock.
    pub spikes_lr: u64,
    /// Spikes of right-to-left units (as `spikes_lr`).
    pub spikes_rl: u64,
    /// Events whose units found the unit pool full (their drive was lost; see [`pool`]).
    pub pool_full: u64,
}

/// Why a network could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NetError {
    /// The cell slice is shorter than the layout needs.
    TooFewCells {
        /// Cells the layout needs.
        needed: usize,
        /// Cells provided.
        given: usize,
    },
    /// The unit slice is neither empty nor as long as the cell slice.
    TooFewUnits {
        /// Unit pairs needed (one per cell).
        needed: usize,
        /// Unit pairs provided.
        given: usize,
    },
    /// The unit pool has fewer owner words than unit pairs.
    TooFewOwners {
        /// Owner words needed (one per pair).
        needed: usize,
        /// Owner words provided.
        given: usize,
    },
    /// The active bitset is shorter than [`active_words`] of the unit pair count.
    TooFewActiveWords {
        /// Words needed.
        needed: usize,
        /// Words provided.
        given: usize,
    },
}

impl core::fmt::Display for NetError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::TooFewCells { needed, given } => {
                write!(f, "layout needs {needed} cells, {given} given")
            }
            Self::TooFewUnits { needed, given } => {
                write!(
                    f,
                    "layout needs {needed} unit pairs (or none), {given} given"
                )
            }
            Self::TooFewOwners { needed, given } => {
                write!(f, "unit pool needs {needed} owner words, {given} given")
            }
            Self::TooFewActiveWords { needed, given } => {
                write!(f, "active bitset needs {needed} words, {given} given")
            }
        }
    }
}

/// Words of the active bitset for `cells` cells.
pub const fn active_words(cells: usize) -> usize {
    cells.div_ceil(32)
}

/// The network over layout `L`, borrowing its kernel and its state.
pub struct Network<'a, L: Layout> {
    kernel: &'a Kernel,
    layout: L,
    /// FAC-to-TRG distance (px): the layout's stride, or 1 for a network of near units
    /// ([`Network::near_units`]).
    stride: u16,
    cells: &'a mut [Cell],
    /// Empty when no sink wants spikes; else one pair per cell, or the pool's slots.
    units: &'a mut [UnitPair],
    /// The unit pool's bookkeeping (`units` are its slots), if the network has one.
    pool: Option<Pool<'a>>,
    /// Unit pairs (cells, or pool slots) with a spike pending (one bit each).
    active: &'a mut [u32],
    filter: InputFilter,
    /// FAC trace level below which the last onset is older than the filter's gap (bits of the
    /// FAC trace's format: [`Trace`], or [`WideTrace`] when the units run).
    onset_level: u32,
    /// Slow FAC trace level below which the last slow onset is older than
    /// [`SLOW_ONSET_GAP_US`].
    slow_onset_level: Trace,
    /// Smallest drive that makes a unit at rest burst ([`Kernel::min_burst_drive`]).
    burst_drive: Trace,
    /// Next cell of the round-robin clock refresh.
    refresh: usize,
    /// The latest time up to which any unit's spikes have been emitted (`None`: none yet): an
    /// input at or after it has no spike to take back.
    emitted_until: Option<FineTime>,
    stats: NetStats,
    /// Scratch space for a unit's run of spikes on its way to the sink.
    run: [u32; SPIKE_RUN],
}

#[inline]
fn count(stats: &mut NetStats, dir: Dir, n: u32) {
    match dir {
        Dir::LeftToRight => stats.spikes_lr += u64::from(n),
        Dir::RightToLeft => stats.spikes_rl += u64::from(n),
    }
}

#[inline]
fn uncount(stats: &mut NetStats, dir: Dir) {
    match dir {
        Dir::LeftToRight => stats.spikes_lr = stats.spikes_lr.saturating_sub(1),
        Dir::RightToLeft => stats.spikes_rl = stats.spikes_rl.saturating_sub(1),
    }
}

/// The state an event at one pixel touches first ([`Network::state_at`]), for a caller that
/// reads its input ahead and asks for it to be brought into the cache early.
#[derive(Clone, Copy, Debug)]
pub struct EventState<'a> {
    /// The cells from its FAC neighbour on the left to the one on the right, at the layout's
    /// stride (its own cell in the middle; where it has no neighbour, the span ends at its
    /// own): the event reads their traces. At most `2 · stride + 1` cells, one row.
    pub cells: &'a [Cell],
    /// Its unit pair, where the units run.
    pub units: Option<&'a UnitPair>,
}

/// The state a network runs in, borrowed from the caller (no heap): one [`Cell`] per cell of
/// the layout and, when the units run (sinks that want spikes), one [`UnitPair`] per cell (or
/// per slot of a unit pool, with one owner word each) and [`active_words`] of the pair count.
/// Longer slices are fine (their front is used).
pub struct NetState<'a> {
    cells: &'a mut [Cell],
    units: &'a mut [UnitPair],
    /// `Some`: the units are a pool with these owner words.
    owners: Option<&'a mut [u32]>,
    active: &'a mut [u32],
}

impl<'a> NetState<'a> {
    /// Cells only: the FAC traces, for sinks that decode bursts from their drives (the
    /// calibrated readout); 12 bytes per pixel.
    pub fn cells(cells: &'a mut [Cell]) -> Self {
        Self {
            cells,
            units: &mut [],
            owners: None,
            active: &mut [],
        }
    }

    /// Cells, unit pairs and the active bitset: the spiking network.
    pub fn spiking(
        cells: &'a mut [Cell],
        units: &'a mut [UnitPair],
        active: &'a mut [u32],
    ) -> Self {
        Self {
            cells,
            units,
            owners: None,
            active,
        }
    }

    /// The same cells, without units (for sinks that want no spikes: the FAC traces then
    /// take their narrow format, and slow traces are kept).
    pub fn without_units(self) -> Self {
        Self::cells(self.cells)
    }

    /// Cells, a unit pool of `units.len()` pairs with as many `owners` words, and the active
    /// bitset ([`active_words`] of the pool size): the spiking network with unit state only
    /// for cells whose units are not at rest (see [`pool`]).
    pub fn pooled(
        cells: &'a mut [Cell],
        units: &'a mut [UnitPair],
        owners: &'a mut [u32],
        active: &'a mut [u32],
    ) -> Self {
        Self {
            cells,
            units,
            owners: Some(owners),
            active,
        }
    }
}

impl<'a> NetState<'a> {
    /// The state split in two: the first with `1 / parts` of every slice (rounded down), the
    /// second with the rest: room for `parts` networks over one layout (the spike readout's
    /// paper's units and its side networks), each with its share of the units or the pool,
    /// when the rest is split again.
    pub fn split_off(self, parts: usize) -> (Self, Self) {
        fn split<T>(s: &mut [T], parts: usize) -> (&mut [T], &mut [T]) {
            let first = s.len() / parts.max(1);
            s.split_at_mut_checked(first).unwrap_or((&mut [], &mut []))
        }
        let (c0, c1) = split(self.cells, parts);
        let (u0, u1) = split(self.units, parts);
        let (a0, a1) = split(self.active, parts);
        let (o0, o1) = match self.owners {
            Some(o) => {
                let (o0, o1) = split(o, parts);
                (Some(o0), Some(o1))
            }
            None => (None, None),
        };
        (
            Self {
                cells: c0,
                units: u0,
                owners: o0,
                active: a0,
            },
            Self {
                cells: c1,
                units: u1,
                owners: o1,
                active: a1,
            },
        )
    }
}

/// The pixel's own FAC traces just before an event, and whether the event came late.
struct OwnTraces {
    /// FAC trace bits (see [`Cell::fac`]).
    fac: u32,
    slow: Trace,
    late: bool,
}

impl<'a, L: Layout> Network<'a, L> {
    /// A network at rest over `layout`, with its state in `state` (reset here).
    ///
    /// # Errors
    /// When a slice of `state` is shorter than the layout needs.
    pub fn new(
        kernel: &'a Kernel,
        layout: L,
        state: NetState<'a>,
        filter: InputFilter,
    ) -> Result<Self, NetError> {
        let NetState {
            cells,
            units,
            owners,
            active,
        } = state;
        let needed = layout.cell_count();
        let given = cells.len();
        let Some(cells) = cells.get_mut(..needed) else {
            return Err(NetError::TooFewCells { needed, given });
        };
        let given_units = units.len();
        let (units, pool) = match owners {
            // A pool: as many slots as pairs given.
            Some(owners) => {
                let given = owners.len();
                let Some(owners) = owners.get_mut(..given_units) else {
                    return Err(NetError::TooFewOwners {
                        needed: given_units,
                        given,
                    });
                };
                (units, Some(Pool::new(owners)))
            }
            None if given_units == 0 => (units, None),
            None => match units.get_mut(..needed) {
                Some(u) => (u, None),
                None => {
                    return Err(NetError::TooFewUnits {
                        needed,
                        given: given_units,
                    })
                }
            },
        };
        let words = active_words(units.len());
        let given_words = active.len();
        let Some(active) = active.get_mut(..words) else {
            return Err(NetError::TooFewActiveWords {
                needed: words,
                given: given_words,
            });
        };
        cells.fill(Cell::default());
        units.fill(UnitPair::default());
        active.fill(0);
        let onset_level = match filter {
            InputFilter::All => 0,
            InputFilter::Onsets { gap_us } => {
                let w = if units.is_empty() {
                    kernel.fac_input(Trace::ZERO).to_bits()
                } else {
                    kernel.fac_input_wide(WideTrace(0)).0
                };
                kernel.decay_fac(Trace::from_bits(w), gap_us).to_bits()
            }
        };
        let slow_onset_level = decay_slow(kernel.fac_input(Trace::ZERO), SLOW_ONSET_GAP_US);
        Ok(Self {
            kernel,
            stride: layout.stride(),
            layout,
            cells,
            units,
            pool,
            active,
            filter,
            onset_level,
            slow_onset_level,
            burst_drive: kernel.min_burst_drive(),
            refresh: 0,
            emitted_until: None,
            stats: NetStats::default(),
            run: [0; SPIKE_RUN],
        })
    }

    /// The layout.
    pub fn layout(&self) -> &L {
        &self.layout
    }

    /// The same network with its units' FAC pixel one pixel from the TRG pixel instead of the
    /// layout's stride: the near units (see [`crate::readout::stride_choice`]).
    pub fn near_units(mut self) -> Self {
        self.set_near(true);
        self
    }

    /// Moves the units' FAC pixel to one pixel from the TRG pixel (`near`, as
    /// [`Network::near_units`]) or back to the layout's stride, for the inputs from now on (a
    /// burst under way keeps the drive it has): the spike readout's slow units follow its
    /// stride choice this way ([`crate::readout::Readout::slow_units_near`]).
    pub fn set_near(&mut self, near: bool) {
        self.stride = if near { 1 } else { self.layout.stride() };
    }

    /// The kernel.
    pub fn kernel(&self) -> &Kernel {
        self.kernel
    }

    /// Counters so far.
    pub fn stats(&self) -> &NetStats {
        &self.stats
    }

    /// The units of cell `c` (when the units run; with a unit pool, while they hold a slot).
    pub fn units(&self, c: usize) -> Option<&UnitPair> {
        self.units.get(self.slot(c)?)
    }

    /// The state an event at pixel `(x, y)` will touch first ([`EventState`]).
    pub fn state_at(&self, x: u16, y: u16) -> Option<EventState<'_>> {
        let c = self.layout.cell(x, y)?;
        let s = i32::from(self.stride);
        let first = self.layout.neighbor(x, y, c, -s).map_or(c, |n| n.min(c));
        let last = self.layout.neighbor(x, y, c, s).map_or(c, |n| n.max(c));
        Some(EventState {
            cells: self.cells.get(first..=last)?,
            units: self.units(c),
        })
    }

    /// Unit pairs with a spike pending (marked in the active bitset).
    pub fn pending_cells(&self) -> usize {
        self.active.iter().map(|w| w.count_ones() as usize).sum()
    }

    /// How full the unit pool is (`None`: the network has no pool).
    pub fn pool_use(&self) -> Option<PoolUse> {
        self.pool.as_ref().map(Pool::usage)
    }

    /// Bytes of state per pixel: a [`Cell`], and a [`UnitPair`] when the units run.
    pub const CELL_BYTES: usize = core::mem::size_of::<Cell>();
    /// Bytes of one [`UnitPair`] (two units).
    pub const UNIT_PAIR_BYTES: usize = core::mem::size_of::<UnitPair>();

    /// Where cell `c`'s units are in `units`: the cell itself, or its pool slot.
    #[inline]
    fn slot(&self, c: usize) -> Option<usize> {
        match self.pool {
            None => Some(c),
            Some(_) => self.cells.get(c)?.slot(),
        }
    }

    /// The cell whose units are in slot `s` of `units`.
    #[inline]
    fn cell_of(&self, s: usize) -> Option<usize> {
        match &self.pool {
            None => Some(s),
            Some(p) => p.owner(s),
        }
    }

    /// Whether cells keep slow FAC traces: for sinks that want them, without a unit pool.
    #[inline]
    fn keeps_slow<S: NetSink>(&self) -> bool {
        S::SLOW && self.pool.is_none()
    }

    /// FAC trace (bits) of cell `c` at time `t` (0 for a missing cell).
    #[inline]
    fn fac_at(&self, c: Option<usize>, t: u32) -> u32 {
        match c.and_then(|c| self.cells.get(c)) {
            Some(cell) => self.decay_fac(cell.fac(), elapsed_us(cell.t_us, t)),
            None => 0,
        }
    }

    /// A FAC trace's bits (either format: decay is a scaling) decayed over `dt` µs.
    #[inline]
    fn decay_fac(&self, bits: u32, dt_us: u32) -> u32 {
        self.kernel
            .decay_fac(Trace::from_bits(bits), dt_us)
            .to_bits()
    }

    /// Whether FAC traces are [`WideTrace`]s (the network has units) or [`Trace`]s.
    #[inline]
    fn wide(&self) -> bool {
        !self.units.is_empty()
    }

    /// The FAC trace's bits as a [`Trace`] (for the [`Trigger`] record).
    #[inline]
    fn fac_trace(&self, bits: u32) -> Trace {
        if self.wide() {
            WideTrace(bits).to_trace()
        } else {
            Trace::from_bits(bits)
        }
    }

    /// Slow FAC trace of cell `c` at time `t` (0 for a missing cell).
    #[inline]
    fn slow_at(&self, c: Option<usize>, t: u32) -> Trace {
        match c.and_then(|c| self.cells.get(c)) {
            Some(cell) => decay_slow(cell.slow(), elapsed_us(cell.t_us, t)),
            None => Trace::ZERO,
        }
    }

    /// Whether the units run (a sink that wants spikes, and unit state to run them in).
    #[inline]
    fn spiking<S: NetSink>(&self) -> bool {
        S::SPIKES && !self.units.is_empty()
    }

    /// Processes one event. Spikes of the units it triggers, up to the event time, come first.
    #[inline]
    pub fn event<S: NetSink>(&mut self, ev: Event, sink: &mut S) {
        if let Some(c) = self.locate(ev) {
            self.event_in(ev, c, sink);
        }
    }

    /// The cell of the event's pixel, if the layout uses it; else the event is counted as
    /// ignored here. Networks over one layout find the same cell, so a
    /// pipeline locates each event once ([`crate::pipeline::Pipeline::event`]): most of a
    /// busy sensor's events fall outside a small board's window.
    #[inline]
    pub fn locate(&mut self, ev: Event) -> Option<usize> {
        let (sw, sh) = self.layout.sensor();
        let c = if ev.x < sw && ev.y < sh {
            self.layout.cell(ev.x, ev.y)
        } else {
            None
        };
        if c.is_none() {
            self.stats.ignored += 1;
        }
        c
    }

    /// Processes one event at cell `c` ([`Network::locate`]). Returns whether it went past the
    /// input filter (`false`: held back, or `c` outside the cells).
    pub fn event_in<S: NetSink>(&mut self, ev: Event, c: usize, sink: &mut S) -> bool {
        self.stats.events += 1;
        let Some(own) = self.own_traces::<S>(c, ev.t_us) else {
            return false;
        };
        let Some(slow_onset) = self.input_filter(c, ev.on, &own) else {
            return false;
        };
        if own.late {
            self.stats.out_of_order += 1;
        }
        let mask = self.layout.units_at(ev.x, ev.y, c);
        let stride = i32::from(self.stride);
        let reads = if S::NEAR && stride > 1 {
            sink.reads(ev.y)
        } else {
            Reads::LAYOUT
        };
        let slow_near = reads.slow_near;
        let far = self.neighbour_traces::<S>(
            ev,
            c,
            mask,
            stride,
            reads.layout || self.spiking::<S>(),
            !slow_near,
        );
        let near = self.neighbour_traces::<S>(ev, c, mask, 1, reads.near, slow_near);
        if self.spiking::<S>() {
            self.units_to_event::<S>(c, &own, ev.t_us, sink);
        }
        let slow = if slow_near { near.slow } else { far.slow };
        self.trigger_record(
            c,
            ev,
            mask,
            &own,
            slow_onset,
            [far.fac, near.fac],
            slow,
            sink,
        );
        if self.spiking::<S>() {
            self.unit_update(c, mask, &own, ev.t_us, far.fac, sink);
        }
        true
    }

    /// [`Network::event_in`] for a caller that reads its input ahead: then the units of the
    /// event's cell emit their spikes up to `next` (at most [`NetSink::reach_us`] beyond the
    /// event) at once, and a unit whose cell's next event is known ([`NextInput::At`]) is left
    /// out of [`Network::tick`]'s visits until that event. The spikes are the same as
    /// without, each in its own output period; only the visits to units in a burst go (one
    /// per output period and unit in a dense burst, without). Where it
    /// [reads ahead](Network::reads_ahead); elsewhere it is just [`Network::event_in`].
    pub fn event_in_ahead<S: NetSink>(
        &mut self,
        ev: Event,
        c: usize,
        next: NextInput,
        sink: &mut S,
    ) -> bool {
        let passed = self.event_in(ev, c, sink);
        if self.reads_ahead::<S>() {
            self.emit_ahead(c, ev.t_us, next, sink);
        }
        passed
    }

    /// Whether [`Network::event_in_ahead`] has units emit ahead with sink `S` (else it is
    /// [`Network::event_in`]): a spiking, unpooled network whose sink takes every spike. A
    /// caller reads its input ahead only for such a network.
    pub fn reads_ahead<S: NetSink>(&self) -> bool {
        self.spiking::<S>() && !S::SPARSE && self.pool.is_none()
    }

    /// The units of cell `c` (unpooled: slot `c`), after an event at `t`, emit their spikes up
    /// to `next`, at most [`NetSink::reach_us`] beyond `t`; they stay in the tick's visits
    /// only while spikes remain that no known event of theirs comes before.
    fn emit_ahead<S: NetSink>(&mut self, c: usize, t: u32, next: NextInput, sink: &mut S) {
        let (to, known) = match next {
            NextInput::At(to) => (to, true),
            NextInput::NotBefore(to) => (to, false),
        };
        let reach = sink.reach_us();
        // Nothing when `to` is not after `t` (an event out of order).
        let Ok(d) = u32::try_from(to.wrapping_sub(t) as i32) else {
            return;
        };
        if d == 0 || reach == 0 {
            return;
        }
        let h = t.wrapping_add(d.min(reach));
        let until = fine(h);
        self.emitting_until(until);
        let kernel = self.kernel;
        let Some(pair) = self.units.get_mut(c) else {
            return;
        };
        let (stats, run) = (&mut self.stats, &mut self.run);
        emit_pair::<S, _, true>(kernel, pair, c, h, until, sink, run, |dir, n| {
            count(stats, dir, n)
        });
        if pair.scheduled() && !(known && d <= reach) {
            self.mark_active(c);
        } else {
            // Done, or its cell's next event comes first and acts on it then.
            self.mark_idle(c);
        }
    }

    /// The pixel's own FAC traces just before the event (decayed once, used twice), and whether
    /// the event came before the cell's time (late: processed at the cell's time).
    #[inline]
    fn own_traces<S: NetSink>(&self, c: usize, t: u32) -> Option<OwnTraces> {
        let cell = self.cells.get(c)?;
        let since = EventTime::from_us(t).since(EventTime::from_us(cell.t_us));
        let pooled = self.pool.is_some();
        let late = since.is_none()
            && (cell.is_live(pooled)
                || (self.spiking::<S>() && self.units(c).is_some_and(UnitPair::is_live)));
        let since = since.unwrap_or(0);
        let slow = if self.keeps_slow::<S>() {
            decay_slow(cell.slow(), since)
        } else {
            Trace::ZERO
        };
        Some(OwnTraces {
            fac: self.decay_fac(cell.fac(), since),
            slow,
            late,
        })
    }

    /// The input filter: records the event's polarity and says whether the event goes on
    /// (`None`: held back), and if so whether it starts a new edge for the slow units too (see
    /// [`SLOW_ONSET_GAP_US`]).
    #[inline]
    fn input_filter(&mut self, c: usize, on: bool, own: &OwnTraces) -> Option<bool> {
        let InputFilter::Onsets { .. } = self.filter else {
            return Some(true);
        };
        let onset_level = self.onset_level;
        let cell = self.cells.get_mut(c)?;
        let was_on = cell.i_fac & POLARITY != 0;
        if on {
            cell.i_fac |= POLARITY;
        } else {
            cell.i_fac &= !POLARITY;
        }
        if was_on == on && own.fac >= onset_level {
            self.stats.filtered += 1;
            return None;
        }
        Some(was_on != on || own.slow < self.slow_onset_level)
    }

    /// The FAC traces (bits, if `fac`) and slow traces (if the sink wants them and `slow`) of
    /// the FAC pixels of the units in `mask` at distance `s`, at the event time: what the
    /// units' TRG input multiplies (zero where not read).
    #[inline(always)]
    fn neighbour_traces<S: NetSink>(
        &self,
        ev: Event,
        c: usize,
        mask: UnitMask,
        s: i32,
        fac: bool,
        slow: bool,
    ) -> Neighbours {
        let mut nbs = Neighbours::default();
        if !(fac || slow && self.keeps_slow::<S>()) {
            return nbs;
        }
        for (slot, dx) in [(0usize, -s), (1, s)] {
            if mask & (1 << slot) == 0 {
                continue;
            }
            let nb = self.layout.neighbor(ev.x, ev.y, c, dx);
            if fac {
                if let Some(f) = nbs.fac.get_mut(slot) {
                    *f = self.fac_at(nb, ev.t_us);
                }
            }
            if slow && self.keeps_slow::<S>() {
                if let Some(f) = nbs.slow.get_mut(slot) {
                    *f = self.slow_at(nb, ev.t_us);
                }
            }
        }
        nbs
    }

    /// The pixel's own traces take the event (its FAC trace `+= w_F`, the slow one on a slow
    /// onset), its clock moves to the event (unless late), and the sink gets the [`Trigger`].
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn trigger_record<S: NetSink>(
        &mut self,
        c: usize,
        ev: Event,
        mask: UnitMask,
        own: &OwnTraces,
        slow_onset: bool,
        [far, near]: [[u32; 2]; 2],
        mut slow: [Trace; 2],
        sink: &mut S,
    ) {
        let kernel = self.kernel;
        let wide = self.wide();
        let keeps_slow = self.keeps_slow::<S>();
        let drives = |fac: [u32; 2]| fac.map(|f| kernel.drive(self.fac_trace(f)));
        let drive = drives(far);
        let near_drive = if S::NEAR {
            drives(near)
        } else {
            [Trace::ZERO; 2]
        };
        let bursts = |d: &Trace| *d >= self.burst_drive;
        let vertical_drive = if S::VERTICAL && drive.iter().chain(&near_drive).any(bursts) {
            let s = i32::from(self.stride);
            let row = |dy: i32| {
                let y = u16::try_from(i32::from(ev.y) + dy).ok()?;
                self.layout.cell(ev.x, y)
            };
            drives([self.fac_at(row(-s), ev.t_us), self.fac_at(row(s), ev.t_us)])
        } else {
            [Trace::ZERO; 2]
        };
        let Some(cell) = self.cells.get_mut(c) else {
            return;
        };
        if !own.late {
            cell.t_us = ev.t_us;
        }
        let own_bits = if wide {
            kernel.fac_input_wide(WideTrace(own.fac)).0
        } else {
            kernel.fac_input(Trace::from_bits(own.fac)).to_bits()
        };
        cell.set_fac(own_bits);
        let own_fac = if wide {
            WideTrace(own_bits).to_trace()
        } else {
            Trace::from_bits(own_bits)
        };
        let own_slow = if keeps_slow {
            if slow_onset {
                let i = kernel.fac_input(own.slow);
                cell.aux = i.to_bits();
                i
            } else {
                cell.aux = own.slow.to_bits();
                // Not a new edge for the slow units: no slow drive, nothing to decode.
                slow = [Trace::ZERO; 2];
                Trace::ZERO
            }
        } else {
            Trace::ZERO
        };
        if mask != 0 {
            sink.trigger(&Trigger {
                t_us: ev.t_us,
                x: ev.x,
                y: ev.y,
                drive,
                own_fac,
                slow_drive: slow.map(|i| kernel.drive(i)),
                own_slow,
                near_drive,
                vertical_drive,
            });
        }
    }

    /// Before an event acts on cell `c`: its units' spikes up to the event come out, and their
    /// state moves to the event time with the cell's clock.
    #[inline]
    fn units_to_event<S: NetSink>(&mut self, c: usize, own: &OwnTraces, t: u32, sink: &mut S) {
        let kernel = self.kernel;
        let t_in = if own.late {
            // Processed at the cell's time.
            self.cells.get(c).map_or(t, |cell| cell.t_us)
        } else {
            t
        };
        self.emitting_until(fine(t_in));
        let Some(pair) = self.slot(c).and_then(|s| self.units.get_mut(s)) else {
            return;
        };
        let (stats, run) = (&mut self.stats, &mut self.run);
        emit_pair::<S, _, true>(kernel, pair, c, t_in, fine(t_in), sink, run, |dir, n| {
            count(stats, dir, n)
        });
    }

    /// The TRG input of the units in `mask`: each takes back its spikes emitted beyond the
    /// event, takes its drive `w_T · I_F(t⁻)`, and its burst is recomputed; the cell is marked
    /// active while a spike is pending.
    #[inline]
    fn unit_update<S: NetSink>(
        &mut self,
        c: usize,
        mask: UnitMask,
        own: &OwnTraces,
        t: u32,
        fac: [u32; 2],
        sink: &mut S,
    ) {
        let kernel = self.kernel;
        let t_in = if own.late {
            self.cells.get(c).map_or(t, |cell| cell.t_us)
        } else {
            t
        };
        let Some(s) = self.slot_for_input(c, mask, fac) else {
            return;
        };
        let pooled = self.pool.is_some();
        let sparse = S::SPARSE && sink.ahead_us() == 0;
        // Spikes were emitted after the input only if some emission reached past it.
        let retract = self.emitted_until.is_some_and(|e| is_late(fine(t_in), e));
        let Some(pair) = self.units.get_mut(s) else {
            return;
        };
        let cell = c as u32;
        for ((u, dir), f) in pair.units.iter_mut().zip(Dir::BOTH).zip(fac) {
            if mask & (1 << dir.slot()) == 0 {
                continue;
            }
            let stats = &mut self.stats;
            if S::SPARSE {
                kernel.burst_plan_end(u);
            }
            if retract {
                kernel.burst_retract(u, fine(t_in), |t_us| {
                    uncount(stats, dir);
                    sink.retract(Spike { t_us, cell, dir })
                });
            }
            if pooled && kernel.burst_at_rest(u, t_in) {
                // At rest in a pooled network: as if its slot had been freed (see `pool`).
                *u = BurstUnit::IDLE;
            }
            // Its spikes up to the input are out: one pending lies beyond it.
            let mid_burst = u.pending();
            kernel.burst_input(u, t_in, WideTrace(f));
            if sparse {
                kernel.burst_plan_sparse(u, mid_burst);
            }
        }
        if pair.scheduled() {
            self.mark_active(s);
        } else if pooled && pair.at_rest(kernel, t_in) {
            // An input too weak to leave anything behind.
            self.release(c, s);
        }
    }

    /// The slot an input to cell `c`'s units in `mask` (with FAC traces `fac`) goes to: the
    /// cell itself, its pool slot, or a free one it takes now. `None` when it has none and
    /// the input would not drive its units anyway, or when the pool is full (counted).
    #[inline]
    fn slot_for_input(&mut self, c: usize, mask: UnitMask, fac: [u32; 2]) -> Option<usize> {
        let Some(pool) = &mut self.pool else {
            return Some(c);
        };
        let cell = self.cells.get_mut(c)?;
        if let Some(s) = cell.slot() {
            return Some(s);
        }
        let drives = fac
            .iter()
            .zip(Dir::BOTH)
            .any(|(&f, dir)| f != 0 && mask & (1 << dir.slot()) != 0);
        if !drives {
            return None;
        }
        let Some(s) = pool.take(c) else {
            self.stats.pool_full += 1;
            return None;
        };
        cell.set_slot(Some(s));
        if let Some(pair) = self.units.get_mut(s) {
            *pair = UnitPair::DEFAULT;
        }
        Some(s)
    }

    /// Cell `c` gives its pool slot `s` back (its units are at rest).
    fn release(&mut self, c: usize, s: usize) {
        if let Some(cell) = self.cells.get_mut(c) {
            cell.set_slot(None);
        }
        if let Some(pool) = &mut self.pool {
            pool.give_back(s);
        }
        self.mark_idle(s);
    }

    /// Notes that spikes are being emitted up to `until`.
    #[inline]
    fn emitting_until(&mut self, until: FineTime) {
        if self.emitted_until.is_none_or(|e| is_late(e, until)) {
            self.emitted_until = Some(until);
        }
    }

    /// Slot `s` out of the tick's visits.
    #[inline]
    fn mark_idle(&mut self, s: usize) {
        if let Some(w) = self.active.get_mut(s / 32) {
            *w &= !(1 << (s % 32));
        }
    }

    #[inline]
    fn mark_active(&mut self, s: usize) {
        if let Some(w) = self.active.get_mut(s / 32) {
            *w |= 1 << (s % 32);
        }
    }

    /// Moves cell `c`'s clock (and its units' drive) forward to `t`; nothing when the cell is
    /// ahead of `t`. Units at rest are settled, or their slot freed.
    fn advance_cell<S: NetSink>(&mut self, c: usize, t: u32, sink: &mut S) {
        let kernel = self.kernel;
        let pooled = self.pool.is_some();
        let slot = self.slot(c);
        if let Some(s) = slot {
            self.finish_skipping(c, s, t, sink);
        }
        let Some(cell) = self.cells.get_mut(c) else {
            return;
        };
        let pair = slot.and_then(|s| self.units.get_mut(s));
        if !cell.is_live(pooled) && !pair.as_deref().is_some_and(UnitPair::is_live) {
            cell.t_us = t;
            return;
        }
        let Some(dt) = EventTime::from_us(t).since(EventTime::from_us(cell.t_us)) else {
            return;
        };
        if dt == 0 {
            return;
        }
        cell.set_fac(kernel.decay_fac(Trace::from_bits(cell.fac()), dt).to_bits());
        if !pooled {
            cell.aux = decay_slow(cell.slow(), dt).to_bits();
        }
        cell.t_us = t;
        let Some(pair) = pair else {
            return;
        };
        if !pooled {
            for u in &mut pair.units {
                kernel.burst_settle(u, t);
            }
        } else if let (true, Some(s)) = (pair.at_rest(kernel, t), slot) {
            self.release(c, s);
        }
    }

    /// Before the units of slot `s` (cell `c`) are settled or freed at `t`: a skipping unit
    /// whose burst is over ([`Kernel::burst_at_rest`]) delivers what its sparse sink still
    /// reads of it (a catch-up of [`Kernel::burst_emit_run`]).
    #[inline]
    fn finish_skipping<S: NetSink>(&mut self, c: usize, s: usize, t: u32, sink: &mut S) {
        if !S::SPARSE {
            return;
        }
        let kernel = self.kernel;
        let Some(pair) = self.units.get_mut(s) else {
            return;
        };
        if !pair
            .units
            .iter()
            .any(|u| u.skipping() && kernel.burst_at_rest(u, t))
        {
            return;
        }
        let (stats, run) = (&mut self.stats, &mut self.run);
        emit_pair::<S, _, true>(kernel, pair, c, t, fine(t), sink, run, |dir, n| {
            count(stats, dir, n)
        });
        self.emitting_until(fine(t));
    }

    /// The pool's sweep for this period: slots whose units are all at rest at `t` are freed.
    fn sweep_pool<S: NetSink>(&mut self, t: u32, sink: &mut S) {
        let Some(pool) = self.pool.as_mut() else {
            return;
        };
        let (start, count) = pool.sweep_range();
        // The range as two runs of slots that do not wrap (the second often empty).
        let first = count.min(pool.capacity().saturating_sub(start));
        for (from, end) in [(start, start + first), (0, count - first)] {
            let mut s = from;
            while let Some((found, c)) = self.next_at_rest(s, end, t) {
                self.finish_skipping(c, found, t, sink);
                self.release(c, found);
                s = found + 1;
            }
        }
    }

    /// The first slot of `from..end` in use whose units are all at rest at `t`, and the cell
    /// owning it. A scan over
    /// the owners and the units side by side: most of a sweep's work, most slots it passes
    /// being free or busy (with a test of each slot's bounds and owner apart, 29
    /// instructions per busy slot in the Cortex-M4 build, where this takes 14).
    #[inline]
    fn next_at_rest(&self, from: usize, end: usize, t: u32) -> Option<(usize, usize)> {
        let owners = self.pool.as_ref()?.owners();
        let end = end.min(owners.len()).min(self.units.len());
        let (owners, units) = (owners.get(from..end)?, self.units.get(from..end)?);
        let kernel = self.kernel;
        owners
            .iter()
            .zip(units)
            .enumerate()
            .find_map(|(i, (&o, pair))| {
                Pool::cell_of_word(o)
                    .filter(|_| pair.at_rest(kernel, t))
                    .map(|c| (from + i, c))
            })
    }

    /// Moves the network's clock to `t`: emits every pending spike reported at or before `t`
    /// (or `t +` [`NetSink::ahead_us`]), visiting only the cells in the active bitset, and
    /// there only units with a spike due (unmarking cells whose bursts are all out); and moves
    /// one more cell's clock, a round-robin sweep that keeps every cell's clock within 2^31 µs
    /// of the present.
    pub fn tick<S: NetSink>(&mut self, t: u32, sink: &mut S) {
        if self.spiking::<S>() {
            let ahead = sink.ahead_us();
            let horizon = t.wrapping_add(ahead);
            // A unit is visited when its next spike comes due, and then emits a whole horizon's
            // worth: a unit in a dense burst once per horizon, not once per tick.
            let due = t;
            let until = reported_by(horizon);
            self.emitting_until(until);
            let kernel = self.kernel;
            for (w, word) in self.active.iter_mut().enumerate() {
                if *word == 0 {
                    continue;
                }
                // First the cells of this word with a unit due (loads without branches on
                // them, so they overlap), then those.
                let base = w * 32;
                let mut due_bits = 0u32;
                let mut bits = *word;
                while bits != 0 {
                    let b = bits.trailing_zeros();
                    bits &= bits - 1;
                    if let Some(pair) = self.units.get(base + b as usize) {
                        due_bits |= u32::from(pair.due(due)) << b;
                    }
                }
                while due_bits != 0 {
                    let b = due_bits.trailing_zeros() as usize;
                    due_bits &= due_bits - 1;
                    let s = base + b;
                    let c = match &self.pool {
                        None => s,
                        Some(p) => p.owner(s).unwrap_or(s),
                    };
                    let Some(pair) = self.units.get_mut(s) else {
                        continue;
                    };
                    let (stats, run) = (&mut self.stats, &mut self.run);
                    emit_pair::<S, _, false>(kernel, pair, c, due, until, sink, run, |dir, n| {
                        count(stats, dir, n)
                    });
                    if !pair.scheduled() {
                        *word &= !(1 << b);
                    }
                }
            }
            self.sweep_pool(t, sink);
        }
        if !self.cells.is_empty() {
            let c = self.refresh % self.cells.len();
            self.refresh = c + 1;
            self.advance_cell(c, t, sink);
        }
    }

    /// Emits every pending spike reported at or before `t`, takes back any emitted beyond it
    /// (ahead of the clock), and moves every cell's clock to `t` (end of a recording).
    pub fn flush<S: NetSink>(&mut self, t: u32, sink: &mut S) {
        if self.spiking::<S>() {
            let until = reported_by(t);
            self.emitting_until(until);
            let kernel = self.kernel;
            for s in 0..self.units.len() {
                let Some(c) = self.cell_of(s) else {
                    continue;
                };
                let Some(pair) = self.units.get_mut(s) else {
                    continue;
                };
                let (stats, run) = (&mut self.stats, &mut self.run);
                emit_pair::<S, _, true>(kernel, pair, c, t, until, sink, run, |dir, n| {
                    count(stats, dir, n)
                });
                let cell = c as u32;
                for (u, dir) in pair.units.iter_mut().zip(Dir::BOTH) {
                    if S::SPARSE {
                        kernel.burst_plan_end(u);
                    }
                    kernel.burst_retract(u, until, |t_us| {
                        uncount(stats, dir);
                        sink.retract(Spike { t_us, cell, dir })
                    });
                }
                if pair.scheduled() {
                    self.mark_active(s);
                }
            }
        }
        for c in 0..self.cells.len() {
            self.advance_cell(c, t, sink);
        }
    }

    /// Number of cells.
    pub fn cell_count(&self) -> usize {
        self.cells.len()
    }
}

/// Emits the spikes of both units of cell `c` whose exact time is at or before `until`, for
/// units whose next spike is reported at or before `due`, in runs of up to [`SPIKE_RUN`] per
/// unit ([`NetSink::spikes`], through the scratch buffer `run`); `tally(dir, n)` counts them.
/// With `CATCH_UP`, skipping units deliver what they skipped up to `until` too
/// ([`Kernel::burst_emit_run`], with the sink's [`NetSink::tail_memory_us`]).
#[allow(clippy::too_many_arguments)]
#[inline]
fn emit_pair<S: NetSink, T: FnMut(Dir, u32), const CATCH_UP: bool>(
    kernel: &Kernel,
    pair: &mut UnitPair,
    c: usize,
    due: u32,
    until: FineTime,
    sink: &mut S,
    run: &mut [u32; SPIKE_RUN],
    mut tally: T,
) {
    let cell = c as u32;
    let [lr, rl] = &mut pair.units;
    // Each unit by name (an array of the two would be iterated by index on every visit).
    let mut unit = |u: &mut BurstUnit, dir: Dir| {
        if S::SPARSE {
            // A skipping unit is never due; with `CATCH_UP` it delivers what it skipped.
            if !(u.due(due) || (CATCH_UP && u.skipping())) {
                return;
            }
            let memory = CATCH_UP.then(|| sink.tail_memory_us());
            loop {
                let e = kernel.burst_emit_run(u, until, run, memory);
                if e.resumed {
                    sink.resume(cell, dir);
                }
                if let Some(spikes) = run.get(..e.n).filter(|s| !s.is_empty()) {
                    sink.spikes(cell, dir, spikes);
                }
                let total = (e.n as u32).saturating_add(e.skipped);
                if total > 0 {
                    tally(dir, total);
                }
                if (e.n == 0 && !e.resumed)
                    || (!CATCH_UP && !u.due(due))
                    || (CATCH_UP && u.none_due_by(until))
                {
                    break;
                }
            }
            return;
        }
        if !u.due(due) {
            return;
        }
        loop {
            let n = kernel.burst_emit_into(u, until, run);
            let Some(spikes) = run.get(..n) else {
                break;
            };
            if n > 0 {
                sink.spikes(cell, dir, spikes);
                tally(dir, n as u32);
            }
            if n < SPIKE_RUN {
                break;
            }
        }
    };
    unit(lr, Dir::LeftToRight);
    unit(rl, Dir::RightToLeft);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::Dense;

    /// The cells [`Network::state_at`] names are those from the pixel's FAC neighbour on the
    /// left to the one on the right, at the layout's stride, and its units are its own.
    #[test]
    fn an_events_state_spans_its_neighbours_at_the_stride() {
        let k = Kernel::DEFAULT;
        let layout = Dense::new(8, 2, 2).unwrap();
        let n = layout.cell_count();
        let (mut cells, mut units, mut active) =
            ([Cell::default(); 16], [UnitPair::default(); 16], [0u32; 1]);
        assert_eq!(n, cells.len());
        let state = NetState::spiking(&mut cells, &mut units, &mut active);
        let net = Network::new(&k, layout, state, InputFilter::All).unwrap();
        let span = |x: u16, y: u16| {
            let s = net.state_at(x, y).unwrap();
            let own = layout.cell(x, y).unwrap();
            let at = |c: usize| core::ptr::from_ref(net.cells.get(c).unwrap());
            let units = s.units.map(core::ptr::from_ref);
            let own_units = net.units(own).map(core::ptr::from_ref);
            assert_eq!(units, own_units, "({x}, {y})");
            let offset = (s.cells.as_ptr() as usize - at(0) as usize) / size_of::<Cell>();
            (offset, s.cells.len())
        };
        // Row 1 starts at cell 8: a left edge, the middle, a right edge.
        assert_eq!(span(0, 1), (8, 3));
        assert_eq!(span(4, 1), (10, 5));
        assert_eq!(span(7, 1), (13, 3));
        assert!(net.state_at(8, 0).is_none());
        // A network of cells only (the calibrated readout's) has no units.
        let mut cells = [Cell::default(); 16];
        let net = Network::new(&k, layout, NetState::cells(&mut cells), InputFilter::All).unwrap();
        assert!(net.state_at(4, 1).unwrap().units.is_none());
        assert_eq!(net.state_at(4, 1).unwrap().cells.len(), 5);
    }
}
