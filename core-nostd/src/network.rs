//! The TDE network: events in, spikes out, over a [`Layout`] with state in caller-provided cells.
//!
//! A [`Cell`] is 24 bytes: the pixel's FAC trace, the time the cell refers to, and the two units
//! the pixel triggers — 12 bytes per unit, FAC trace and clock included. State is stored exactly
//! as computed (see [`Trace`] for why 16-bit traces are not enough): the membrane word holds
//! `u / theta` in U1F31, or, with the top bit set, the remaining refractory time in µs (bits
//! 30..16) and its sub-µs lag (bits 15..0). Which units a cell has comes from the layout, and a
//! cell whose words are all zero is idle.
//!
//! Spikes are emitted when a unit is advanced: on every event at its TRG pixel, and by
//! [`Network::flush`] / the readout clock (see [`Network::advance_cells`]).

use fixed::types::U1F31;

use crate::event::Event;
use crate::layout::{Dir, Layout};
use crate::params::Trace;
use crate::unit::{elapsed_us, Kernel, UnitState};

/// Membrane word: top bit set = refractory (remaining µs in bits 30..16, lag in 15..0).
const REFRACTORY: u32 = 1 << 31;

/// State of one pixel: its FAC trace and the two units it triggers. 24 bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(C)]
pub struct Cell {
    /// Time (µs) the state refers to.
    t_us: u32,
    /// FAC trace ([`Trace`] bits).
    i_fac: u32,
    /// TRG traces of the left-to-right and right-to-left units ([`Trace`] bits).
    i_trg: [u32; 2],
    /// Membranes, see [`REFRACTORY`].
    mem: [u32; 2],
}

impl Cell {
    /// Whether the cell holds any state that still changes with time.
    #[inline]
    fn is_live(&self) -> bool {
        (self.i_fac | self.i_trg[0] | self.i_trg[1]) != 0 || (self.mem[0] | self.mem[1]) != 0
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

/// Where spikes go.
pub trait SpikeSink {
    /// One spike (spikes of one unit arrive in time order).
    fn spike(&mut self, spike: Spike);
}

impl<F: FnMut(Spike)> SpikeSink for F {
    fn spike(&mut self, spike: Spike) {
        self(spike)
    }
}

/// Counters of what the network saw.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NetStats {
    /// Events processed.
    pub events: u64,
    /// Events outside the sensor or the layout, ignored.
    pub ignored: u64,
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
}

impl core::fmt::Display for NetError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::TooFewCells { needed, given } => {
                write!(f, "layout needs {needed} cells, {given} given")
            }
        }
    }
}

/// The network over layout `L`, borrowing its kernel and its cell storage.
pub struct Network<'a, L: Layout> {
    kernel: &'a Kernel,
    layout: L,
    cells: &'a mut [Cell],
    stats: NetStats,
}

#[inline]
fn trace_to_store(x: Trace) -> u32 {
    x.to_bits()
}

#[inline]
fn trace_from_store(b: u32) -> Trace {
    Trace::from_bits(b)
}

#[inline]
fn unpack_unit(i_trg: u32, mem: u32) -> UnitState {
    if mem & REFRACTORY != 0 {
        UnitState {
            i_trg: trace_from_store(i_trg),
            v: U1F31::ZERO,
            refractory_us: (mem & !REFRACTORY) >> 16,
            lag_q16: mem as u16,
        }
    } else {
        UnitState {
            i_trg: trace_from_store(i_trg),
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
    (trace_to_store(u.i_trg), mem)
}

impl<'a, L: Layout> Network<'a, L> {
    /// A network at rest. `cells` must hold at least `layout.cell_count()` cells; they are reset.
    pub fn new(kernel: &'a Kernel, layout: L, cells: &'a mut [Cell]) -> Result<Self, NetError> {
        let needed = layout.cell_count();
        let given = cells.len();
        let Some(cells) = cells.get_mut(..needed) else {
            return Err(NetError::TooFewCells { needed, given });
        };
        cells.fill(Cell::default());
        Ok(Self {
            kernel,
            layout,
            cells,
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

    /// Size of one cell in bytes (state per pixel, holding two units).
    pub const CELL_BYTES: usize = core::mem::size_of::<Cell>();

    /// FAC trace of cell `c` at time `t` (0 for a missing cell).
    #[inline]
    fn fac_at(&self, c: Option<usize>, t: u32) -> Trace {
        match c.and_then(|c| self.cells.get(c)) {
            Some(cell) => self
                .kernel
                .decay_fac(trace_from_store(cell.i_fac), elapsed_us(cell.t_us, t)),
            None => Trace::ZERO,
        }
    }

    /// Processes one event: FAC input to its pixel, TRG input to the units the pixel triggers.
    /// Spikes of those units up to the event time are emitted first.
    pub fn event<S: SpikeSink>(&mut self, ev: Event, sink: &mut S) {
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
        let mask = self.layout.units(c);
        let s = self.layout.stride();
        let t = ev.t_us;
        // FAC traces of the neighbours, just before this event.
        let fac_lr = if mask & 1 != 0 {
            self.fac_at(
                ev.x.checked_sub(s).and_then(|x| self.layout.cell(x, ev.y)),
                t,
            )
        } else {
            Trace::ZERO
        };
        let fac_rl = if mask & 2 != 0 {
            self.fac_at(
                ev.x.checked_add(s).and_then(|x| self.layout.cell(x, ev.y)),
                t,
            )
        } else {
            Trace::ZERO
        };
        self.advance_cell(c, t, sink);
        let kernel = self.kernel;
        let Some(cell) = self.cells.get_mut(c) else {
            return;
        };
        cell.i_fac = trace_to_store(kernel.fac_input(trace_from_store(cell.i_fac)));
        for (dir, fac) in [(Dir::LeftToRight, fac_lr), (Dir::RightToLeft, fac_rl)] {
            if mask & (1 << dir.slot()) == 0 {
                continue;
            }
            let slot = dir.slot();
            let (Some(it), Some(mem)) = (cell.i_trg.get_mut(slot), cell.mem.get_mut(slot)) else {
                continue;
            };
            let mut u = unpack_unit(*it, *mem);
            kernel.trg_input(&mut u, fac);
            (*it, *mem) = pack_unit(&u);
        }
    }

    /// Advances cell `c` to time `t`, emitting its units' spikes in `(cell time, t]`.
    fn advance_cell<S: SpikeSink>(&mut self, c: usize, t: u32, sink: &mut S) {
        let kernel = self.kernel;
        let Some(cell) = self.cells.get_mut(c) else {
            return;
        };
        if !cell.is_live() {
            cell.t_us = t;
            return;
        }
        let dt = t.wrapping_sub(cell.t_us);
        if dt >= 1 << 31 {
            self.stats.out_of_order += 1;
            return;
        }
        if dt == 0 {
            return;
        }
        let t0 = cell.t_us;
        for dir in Dir::BOTH {
            let slot = dir.slot();
            let (Some(it), Some(mem)) = (cell.i_trg.get_mut(slot), cell.mem.get_mut(slot)) else {
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
            (*it, *mem) = pack_unit(&u);
        }
        cell.i_fac = trace_to_store(kernel.decay_fac(trace_from_store(cell.i_fac), dt));
        cell.t_us = t;
    }

    /// Advances every live cell to `t`, emitting all spikes up to `t`. Cost: one pass over the
    /// cells; used at the end of a recording and by tests.
    pub fn flush<S: SpikeSink>(&mut self, t: u32, sink: &mut S) {
        for c in 0..self.cells.len() {
            self.advance_cell(c, t, sink);
        }
    }

    /// Advances the cells `range` to `t` (the readout clock uses this to bound spike latency
    /// and to keep every cell's clock within 2^31 µs of the present).
    pub fn advance_cells<S: SpikeSink>(
        &mut self,
        range: core::ops::Range<usize>,
        t: u32,
        sink: &mut S,
    ) {
        let end = range.end.min(self.cells.len());
        for c in range.start.min(end)..end {
            self.advance_cell(c, t, sink);
        }
    }

    /// Number of cells.
    pub fn cell_count(&self) -> usize {
        self.cells.len()
    }
}
