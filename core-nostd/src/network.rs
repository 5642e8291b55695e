//! The TDE network: events in; trigger records and spikes out; over a [`Layout`], with all state
//! in caller-provided slices.
//!
//! State is kept per pixel in two slices: a [`Cell`] (8 bytes: the pixel's FAC trace and the
//! time it refers to) and a [`UnitPair`] (16 bytes: the two units the pixel triggers). The unit
//! slice is only needed by sinks that want spikes; the calibrated readout decodes bursts from
//! their drives and runs with cells alone — 4 bytes per unit, where the spiking network takes
//! 12. State is stored exactly as computed (see [`Trace`] for why 16-bit traces are not enough):
//! the membrane word holds `u / theta` in U1F31, or, with the top bit set, the remaining
//! refractory time in µs (bits 30..16) and its sub-µs lag (bits 15..0). The top bit of the
//! stored FAC trace holds the polarity of the pixel's last event (for the onset filter). Which
//! units a pixel has comes from the layout; state whose words are all zero is idle.
//!
//! # What comes out
//! - For every event that triggers units, one [`Trigger`]: the drive `w_T · I_F(t⁻)` each of
//!   the pixel's two units receives, which is what its burst encodes (a burst from rest is a
//!   monotone function of it: the sweep), and the pixel's own FAC trace after the event.
//! - If the sink asks for them ([`NetSink::SPIKES`]), every spike of every unit. Units are
//!   advanced lazily (on their next input) and by [`Network::tick`], which advances the cells
//!   marked in the active bitset, so a spike is emitted at the latest at the first tick after it.
//!   A sink that does not want spikes skips the membrane dynamics altogether.
//!
//! # Input filter
//! [`InputFilter::Onsets`] passes only the first event of each same-polarity run at a pixel (or
//! an event after `gap` without onset): one event per edge and pixel, which makes the drive an
//! unbiased code of the edge's travel time (see the readout).

use fixed::types::U1F31;

use crate::event::Event;
use crate::exp_table::{scale_q31, ExpDecay};
use crate::layout::{Dir, Layout};
use crate::params::{Trace, TAU_SLOW_US};
use crate::time::EventTime;
use crate::unit::{elapsed_us, Kernel, UnitState};

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

/// Membrane word: top bit set = refractory (remaining µs in bits 30..16, lag in 15..0).
const REFRACTORY: u32 = 1 << 31;

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
    /// FAC trace of the slow units (time constant [`TAU_SLOW_US`], [`Trace`] bits); kept only
    /// for sinks that ask for it ([`NetSink::SLOW`]), else 0.
    i_slow: u32,
}

/// The two units a pixel triggers (left-to-right, right-to-left). 16 bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(C)]
pub struct UnitPair {
    /// TRG traces ([`Trace`] bits).
    i_trg: [u32; 2],
    /// Membranes, see [`REFRACTORY`].
    mem: [u32; 2],
}

impl UnitPair {
    /// A unit pair at rest (for static arrays).
    pub const DEFAULT: Self = Self {
        i_trg: [0; 2],
        mem: [0; 2],
    };

    #[inline]
    fn is_live(&self) -> bool {
        (self.i_trg[0] | self.i_trg[1] | self.mem[0] | self.mem[1]) != 0
    }
}

impl Cell {
    /// A cell at rest (for static arrays).
    pub const DEFAULT: Self = Self {
        t_us: 0,
        i_fac: 0,
        i_slow: 0,
    };

    /// Whether a FAC trace still changes with time.
    #[inline]
    fn is_live(&self) -> bool {
        (self.i_fac & !POLARITY) != 0 || self.i_slow != 0
    }

    #[inline]
    fn slow(&self) -> Trace {
        Trace::from_bits(self.i_slow)
    }

    #[inline]
    fn fac(&self) -> Trace {
        Trace::from_bits(self.i_fac & !POLARITY)
    }

    #[inline]
    fn set_fac(&mut self, i: Trace) {
        self.i_fac = (self.i_fac & POLARITY) | (i.to_bits() & !POLARITY);
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
    /// sink asks for them ([`NetSink::SLOW`]).
    pub slow_drive: [Trace; 2],
    /// The pixel's own slow FAC trace just after this event (see `slow_drive`).
    pub own_slow: Trace,
}

/// Where the network's output goes.
pub trait NetSink {
    /// Whether this sink wants individual spikes. When `false` the network does not run the
    /// units' membrane dynamics at all (their bursts are described by [`Trigger`]s).
    const SPIKES: bool;
    /// Whether this sink wants the slow units' drives in its [`Trigger`]s. When `false` the
    /// network keeps no slow traces (they cost three more decays per onset).
    const SLOW: bool = false;
    /// One triggering event.
    fn trigger(&mut self, _t: &Trigger) {}
    /// One spike (spikes of one unit arrive in time order).
    fn spike(&mut self, _s: Spike) {}
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
    /// Events offered.
    pub events: u64,
    /// Events outside the sensor or the layout, ignored.
    pub ignored: u64,
    /// Events the input filter held back.
    pub filtered: u64,
    /// Events whose time lay before their cell's time (processed at the cell's time).
    pub out_of_order: u64,
    /// Spikes of left-to-right units.
    pub spikes_lr: u64,
    /// Spikes of right-to-left units.
    pub spikes_rl: u64,
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
    /// The active bitset is shorter than [`active_words`] of the cell count.
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
    cells: &'a mut [Cell],
    /// Empty when no sink wants spikes; else one pair per cell.
    units: &'a mut [UnitPair],
    active: &'a mut [u32],
    filter: InputFilter,
    /// FAC trace level below which the last onset is older than the filter's gap.
    onset_level: Trace,
    /// Slow FAC trace level below which the last slow onset is older than
    /// [`SLOW_ONSET_GAP_US`].
    slow_onset_level: Trace,
    /// Next cell of the round-robin clock refresh.
    refresh: usize,
    stats: NetStats,
}

#[inline]
fn unpack_unit(i_trg: u32, mem: u32) -> UnitState {
    if mem & REFRACTORY != 0 {
        UnitState {
            i_trg: Trace::from_bits(i_trg),
            v: U1F31::ZERO,
            refractory_us: (mem & !REFRACTORY) >> 16,
            lag_q16: mem as u16,
        }
    } else {
        UnitState {
            i_trg: Trace::from_bits(i_trg),
            v: U1F31::from_bits(mem),
            refractory_us: 0,
            lag_q16: 0,
        }
    }
}

#[inline]
fn pack_unit(u: &UnitState) -> (u32, u32) {
    let mem = if u.refractory_us > 0 {
        REFRACTORY | (u.refractory_us.min(0x7FFF) << 16) | u32::from(u.lag_q16)
    } else {
        u.v.to_bits().min(!REFRACTORY)
    };
    (u.i_trg.to_bits(), mem)
}

/// The state a network runs in, borrowed from the caller (no heap): one [`Cell`] per cell of
/// the layout and, when the units run (sinks that want spikes), one [`UnitPair`] per cell and
/// [`active_words`] of the cell count. Longer slices are fine (their front is used).
pub struct NetState<'a> {
    cells: &'a mut [Cell],
    units: &'a mut [UnitPair],
    active: &'a mut [u32],
}

impl<'a> NetState<'a> {
    /// Cells only: the FAC traces, for sinks that decode bursts from their drives (the
    /// calibrated readout); 12 bytes per pixel.
    pub fn cells(cells: &'a mut [Cell]) -> Self {
        Self {
            cells,
            units: &mut [],
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
            active,
        }
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
            active,
        } = state;
        let needed = layout.cell_count();
        let given = cells.len();
        let Some(cells) = cells.get_mut(..needed) else {
            return Err(NetError::TooFewCells { needed, given });
        };
        let given_units = units.len();
        let units = if given_units == 0 {
            units
        } else {
            match units.get_mut(..needed) {
                Some(u) => u,
                None => {
                    return Err(NetError::TooFewUnits {
                        needed,
                        given: given_units,
                    })
                }
            }
        };
        let words = if units.is_empty() {
            0
        } else {
            active_words(needed)
        };
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
            InputFilter::All => Trace::ZERO,
            InputFilter::Onsets { gap_us } => {
                let w = kernel.fac_input(Trace::ZERO);
                kernel.decay_fac(w, gap_us)
            }
        };
        let slow_onset_level = decay_slow(kernel.fac_input(Trace::ZERO), SLOW_ONSET_GAP_US);
        Ok(Self {
            kernel,
            layout,
            cells,
            units,
            active,
            filter,
            onset_level,
            slow_onset_level,
            refresh: 0,
            stats: NetStats::default(),
        })
    }

    /// The layout.
    pub fn layout(&self) -> &L {
        &self.layout
    }

    /// The kernel.
    pub fn kernel(&self) -> &Kernel {
        self.kernel
    }

    /// Counters so far.
    pub fn stats(&self) -> &NetStats {
        &self.stats
    }

    /// Bytes of state per pixel: a [`Cell`], and a [`UnitPair`] when the units run.
    pub const CELL_BYTES: usize = core::mem::size_of::<Cell>();
    /// Bytes of one [`UnitPair`] (two units).
    pub const UNIT_PAIR_BYTES: usize = core::mem::size_of::<UnitPair>();

    /// FAC trace of cell `c` at time `t` (0 for a missing cell).
    #[inline]
    fn fac_at(&self, c: Option<usize>, t: u32) -> Trace {
        match c.and_then(|c| self.cells.get(c)) {
            Some(cell) => self.kernel.decay_fac(cell.fac(), elapsed_us(cell.t_us, t)),
            None => Trace::ZERO,
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

    /// Processes one event. Spikes of the units it triggers, up to the event time, come first.
    pub fn event<S: NetSink>(&mut self, ev: Event, sink: &mut S) {
        self.stats.events += 1;
        let (sw, sh) = self.layout.sensor();
        if ev.x >= sw || ev.y >= sh {
            self.stats.ignored += 1;
            return;
        }
        let Some(c) = self.layout.cell(ev.x, ev.y) else {
            self.stats.ignored += 1;
            return;
        };
        let t = ev.t_us;
        let kernel = self.kernel;
        // The pixel's own FAC trace just before the event (decayed once, used twice).
        let (own_now, own_slow_now, late) = match self.cells.get(c) {
            Some(cell) => {
                let since = EventTime::from_us(t).since(EventTime::from_us(cell.t_us));
                let late = since.is_none() && cell.is_live();
                let d = since.unwrap_or(0);
                let slow = if S::SLOW {
                    decay_slow(cell.slow(), d)
                } else {
                    Trace::ZERO
                };
                (kernel.decay_fac(cell.fac(), d), slow, late)
            }
            None => return,
        };
        // Whether this event starts a new edge for the slow units too (see `SLOW_ONSET_GAP_US`).
        let mut slow_onset = true;
        if let InputFilter::Onsets { .. } = self.filter {
            let onset_level = self.onset_level;
            let Some(cell) = self.cells.get_mut(c) else {
                return;
            };
            let was_on = cell.i_fac & POLARITY != 0;
            if ev.on {
                cell.i_fac |= POLARITY;
            } else {
                cell.i_fac &= !POLARITY;
            }
            if was_on == ev.on && own_now >= onset_level {
                self.stats.filtered += 1;
                return;
            }
            slow_onset = was_on != ev.on || own_slow_now < self.slow_onset_level;
        }
        if late {
            self.stats.out_of_order += 1;
        }
        let spiking = S::SPIKES && !self.units.is_empty();
        let mask = self.layout.units_at(ev.x, ev.y, c);
        let s = i32::from(self.layout.stride());
        let mut fac = [Trace::ZERO; 2];
        let mut slow = [Trace::ZERO; 2];
        for (slot, dx) in [(0usize, -s), (1, s)] {
            if mask & (1 << slot) == 0 {
                continue;
            }
            let nb = self.layout.neighbor(ev.x, ev.y, c, dx);
            if let Some(f) = fac.get_mut(slot) {
                *f = self.fac_at(nb, t);
            }
            if S::SLOW {
                if let Some(f) = slow.get_mut(slot) {
                    *f = self.slow_at(nb, t);
                }
            }
        }
        if spiking {
            self.advance_cell::<S>(c, t, sink);
        }
        let Some(cell) = self.cells.get_mut(c) else {
            return;
        };
        if !spiking && !late {
            cell.t_us = t;
        }
        let own = kernel.fac_input(if spiking { cell.fac() } else { own_now });
        cell.set_fac(own);
        let own_slow = if S::SLOW {
            let now = if spiking { cell.slow() } else { own_slow_now };
            if slow_onset {
                let i = kernel.fac_input(now);
                cell.i_slow = i.to_bits();
                i
            } else {
                cell.i_slow = now.to_bits();
                // Not a new edge for the slow units: no slow drive, nothing to decode.
                slow = [Trace::ZERO; 2];
                Trace::ZERO
            }
        } else {
            Trace::ZERO
        };
        if mask != 0 {
            let [lr, rl] = fac;
            let [slr, srl] = slow;
            sink.trigger(&Trigger {
                t_us: t,
                x: ev.x,
                y: ev.y,
                drive: [kernel.drive(lr), kernel.drive(rl)],
                own_fac: own,
                slow_drive: [kernel.drive(slr), kernel.drive(srl)],
                own_slow,
            });
        }
        if spiking {
            let Some(pair) = self.units.get_mut(c) else {
                return;
            };
            let mut may_spike = false;
            for dir in Dir::BOTH {
                let slot = dir.slot();
                if mask & (1 << slot) == 0 {
                    continue;
                }
                let (Some(it), Some(mem)) = (pair.i_trg.get_mut(slot), pair.mem.get_mut(slot))
                else {
                    continue;
                };
                let mut u = unpack_unit(*it, *mem);
                kernel.trg_input(&mut u, fac.get(slot).copied().unwrap_or(Trace::ZERO));
                may_spike |= kernel.may_spike(&u);
                (*it, *mem) = pack_unit(&u);
            }
            if may_spike {
                self.mark_active(c);
            }
        }
    }

    #[inline]
    fn mark_active(&mut self, c: usize) {
        if let Some(w) = self.active.get_mut(c / 32) {
            *w |= 1 << (c % 32);
        }
    }

    /// Advances cell `c` (and its units, when they run) to time `t`, emitting the units' spikes
    /// in `(cell time, t]`. Returns whether a unit may still spike without further input.
    fn advance_cell<S: NetSink>(&mut self, c: usize, t: u32, sink: &mut S) -> bool {
        let kernel = self.kernel;
        let Some(cell) = self.cells.get_mut(c) else {
            return false;
        };
        let pair = if S::SPIKES {
            self.units.get_mut(c)
        } else {
            None
        };
        if !cell.is_live() && !pair.as_deref().is_some_and(UnitPair::is_live) {
            cell.t_us = t;
            return false;
        }
        let Some(dt) = EventTime::from_us(t).since(EventTime::from_us(cell.t_us)) else {
            // The cell is ahead of `t` (an earlier event came late): nothing to advance.
            return true;
        };
        let t0 = cell.t_us;
        let mut may_spike = false;
        if let (Some(pair), true) = (pair, dt > 0) {
            for dir in Dir::BOTH {
                let slot = dir.slot();
                let (Some(it), Some(mem)) = (pair.i_trg.get_mut(slot), pair.mem.get_mut(slot))
                else {
                    continue;
                };
                if *it == 0 && *mem == 0 {
                    continue;
                }
                let mut u = unpack_unit(*it, *mem);
                let n = kernel.advance(&mut u, t0, dt, |ts| {
                    sink.spike(Spike {
                        t_us: ts,
                        cell: c as u32,
                        dir,
                    })
                });
                match dir {
                    Dir::LeftToRight => self.stats.spikes_lr += u64::from(n),
                    Dir::RightToLeft => self.stats.spikes_rl += u64::from(n),
                }
                may_spike |= kernel.may_spike(&u);
                (*it, *mem) = pack_unit(&u);
            }
        }
        if dt > 0 {
            cell.set_fac(kernel.decay_fac(cell.fac(), dt));
            if S::SLOW {
                cell.i_slow = decay_slow(cell.slow(), dt).to_bits();
            }
            cell.t_us = t;
        }
        may_spike
    }

    /// Moves the network's clock to `t`: advances every cell marked active (emitting its spikes
    /// up to `t`, unmarking it when no unit can spike any more) and one more cell of a
    /// round-robin sweep that keeps every cell's clock within 2^31 µs of the present.
    pub fn tick<S: NetSink>(&mut self, t: u32, sink: &mut S) {
        if S::SPIKES && !self.units.is_empty() {
            for w in 0..self.active.len() {
                let mut bits = self.active.get(w).copied().unwrap_or(0);
                while bits != 0 {
                    let b = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    let c = w * 32 + b;
                    if !self.advance_cell::<S>(c, t, sink) {
                        if let Some(word) = self.active.get_mut(w) {
                            *word &= !(1 << b);
                        }
                    }
                }
            }
        }
        if !self.cells.is_empty() {
            let c = self.refresh % self.cells.len();
            self.refresh = c + 1;
            if self.advance_cell::<S>(c, t, sink) {
                self.mark_active(c);
            }
        }
    }

    /// Advances every live cell to `t`, emitting all spikes up to `t` (end of a recording).
    pub fn flush<S: NetSink>(&mut self, t: u32, sink: &mut S) {
        for c in 0..self.cells.len() {
            self.advance_cell::<S>(c, t, sink);
        }
        self.active.fill(0);
    }

    /// Number of cells.
    pub fn cell_count(&self) -> usize {
        self.cells.len()
    }
}
