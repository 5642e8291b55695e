//! Runs the pipeline a [`Settings`] describes, and moves to another when the AER stream brings
//! different, valid settings in a configuration frame (`core_nostd::aer::config`).
//!
//! A board starts from its build-time defaults (or, in QEMU, its command line) and loops:
//! [`run`] returns [`Exit::Reconfigure`] with the new configuration, the board runs that. The
//! yaw stream's sequence counter carries over; the samples follow the new stream's event clock
//! from its first event on. A configuration that names an unknown layout or needs more cells
//! than the board has is refused and counted (`Stats::configs_refused`); the running network
//! goes on.

use core_nostd::network::{Cell, NetState};
use core_nostd::settings::{ReadoutChoice, Settings};
use core_nostd::unit::Kernel;

use super::processing::{self, Clock};
use super::{CostMeter, YawSink};

/// How [`run`] ended.
pub enum Exit {
    /// The stream ended (replays).
    End,
    /// A different configuration arrived; run it next.
    Reconfigure(Settings),
}

/// Why settings cannot run.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub enum Refused {
    /// The layout does not fit the sensor (or its stride), or a value is out of range.
    Layout,
    /// The layout needs more cells than the board has.
    Cells(usize),
    /// The readout needs memory the board does not give it (the spiking units).
    Readout,
}

/// The board's memory for network cells: a region used by nothing else, handed out (and
/// initialised) anew for each configuration.
pub struct CellStore {
    base: *mut Cell,
    cap: usize,
}

impl CellStore {
    /// # Safety
    /// `base` must point to memory for `cap` cells (aligned, in RAM) that nothing else uses
    /// for the rest of the program.
    pub const unsafe fn new(base: *mut Cell, cap: usize) -> Self {
        Self { base, cap }
    }

    /// Cells the region holds.
    pub fn capacity(&self) -> usize {
        self.cap
    }

    /// `n` fresh cells (the region's first `n`), while `self` is borrowed.
    fn take(&mut self, n: usize) -> Option<&mut [Cell]> {
        if n > self.cap {
            return None;
        }
        // SAFETY: the region holds `cap >= n` cells and is used by nothing else (`new`'s
        // contract); the cells are written before the slice over them is made, and the slice
        // borrows `self`, so no two slices over the region live at once.
        unsafe {
            for i in 0..n {
                self.base.add(i).write(Cell::default());
            }
            Some(core::slice::from_raw_parts_mut(self.base, n))
        }
    }
}

/// Cells the settings' pipeline needs, if the board can run it at all (a layout that fits, a
/// readout that needs cells only).
fn cells_needed(settings: &Settings) -> Result<usize, Refused> {
    let needs = settings.storage().map_err(|_| Refused::Layout)?;
    if settings.readout != ReadoutChoice::Calibrated || needs.unit_pairs != 0 {
        return Err(Refused::Readout);
    }
    Ok(needs.cells)
}

/// Runs the settings' pipeline until the stream ends or other settings that fit `cells` arrive.
/// `seq` is the yaw stream's sequence counter (carried across runs).
///
/// # Errors
/// When the settings cannot run (see [`Refused`]).
pub async fn run<K: YawSink, M: CostMeter>(
    kernel: &Kernel,
    settings: &Settings,
    cells: &mut CellStore,
    sink: &mut K,
    clock: Clock,
    seq: &mut u8,
) -> Result<Exit, Refused> {
    let needed = cells_needed(settings)?;
    let capacity = cells.capacity();
    let Some(cells) = cells.take(needed) else {
        return Err(Refused::Cells(needed));
    };
    let mut pipeline = settings
        .build(kernel, NetState::cells(cells))
        .map_err(|_| Refused::Layout)?;
    defmt::info!("processing: {} cells", needed);
    let accept = |new: &Settings| cells_needed(new).is_ok_and(|n| n <= capacity);
    Ok(processing::run::<_, M>(&mut pipeline, sink, clock, seq, settings, &accept).await)
}

/// A live board's processing: runs `defaults` (the build's constants), then each configuration
/// the stream brings. A configuration that cannot be built is refused and the one before runs
/// again (from a fresh state); the defaults must run.
#[cfg_attr(feature = "board-qemu", allow(dead_code))]
pub async fn serve<K: YawSink, M: CostMeter>(
    kernel: &Kernel,
    defaults: Settings,
    cells: &mut CellStore,
    sink: &mut K,
) {
    let (mut good, mut next) = (defaults, defaults);
    let mut seq = 0u8;
    loop {
        match run::<K, M>(kernel, &next, cells, sink, Clock::Live, &mut seq).await {
            Ok(Exit::End) => return,
            Ok(Exit::Reconfigure(c)) => {
                defmt::info!("new configuration: {} x {} px", c.width, c.height);
                good = next;
                next = c;
            }
            Err(e) if next != good => {
                defmt::warn!("configuration refused: {}", e);
                super::update_stats(|s| s.configs_refused += 1);
                next = good;
            }
            Err(e) => defmt::panic!("the build's configuration cannot run: {}", e),
        }
    }
}
