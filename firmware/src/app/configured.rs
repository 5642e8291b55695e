//! Runs the network a [`StreamConfig`] describes, and moves to another when the AER stream
//! brings a different, valid configuration frame (`core_nostd::aer::config`).
//!
//! A board starts from its build-time defaults (or, in QEMU, its command line) and loops:
//! [`run`] returns [`Exit::Reconfigure`] with the new configuration, the board runs that. The
//! yaw stream's sequence counter carries over; the samples follow the new stream's event clock
//! from its first event on. A configuration that names an unknown layout or needs more cells
//! than the board has is refused and counted (`Stats::configs_refused`); the running network
//! goes on.

use core_nostd::aer::config::{LayoutChoice, StreamConfig};
use core_nostd::layout::{Dense, Layout, PaperBoxes};
use core_nostd::unit::Kernel;

use super::process::{self, Cell, ProcessConfig};
use super::processing::{self, Clock};
use super::{CostMeter, YawSink};

/// How [`run`] ended.
pub enum Exit {
    /// The stream ended (replays).
    End,
    /// A different configuration arrived; run it next.
    Reconfigure(StreamConfig),
}

/// Why a configuration cannot run.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub enum Refused {
    /// The layout does not fit the sensor (or its stride).
    Layout,
    /// The layout needs more cells than the board has.
    Cells(usize),
    /// The network could not be built over the cells.
    Network,
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

/// The dense layout of a configuration (whole sensor or window), if it fits.
fn dense(cfg: &StreamConfig) -> Option<Dense> {
    let (x0, y0, w, h) = match cfg.layout {
        LayoutChoice::Window { x0, y0, w, h } => (x0, y0, w, h),
        _ => (0, 0, cfg.width, cfg.height),
    };
    Dense::window(cfg.width, cfg.height, x0, y0, w, h, cfg.stride)
}

/// The paper's boxes on the configuration's sensor (the placement `host-sim run` uses).
fn boxes(cfg: &StreamConfig) -> Option<PaperBoxes> {
    PaperBoxes::with_stride(cfg.width, cfg.height, cfg.stride, PaperBoxes::DEFAULT_SEED)
}

/// Cells the configuration's network needs; `None` when its layout does not fit.
pub fn cells_needed(cfg: &StreamConfig) -> Option<usize> {
    match cfg.layout {
        LayoutChoice::PaperBoxes => boxes(cfg).map(|l| l.cell_count()),
        _ => dense(cfg).map(|l| l.cell_count()),
    }
}

/// Runs the configuration's pipeline until the stream ends or another configuration that fits
/// `cells` arrives. `seq` is the yaw stream's sequence counter (carried across runs).
///
/// # Errors
/// When the configuration cannot run (see [`Refused`]).
pub async fn run<K: YawSink, M: CostMeter>(
    kernel: &Kernel,
    cfg: &StreamConfig,
    cells: &mut CellStore,
    sink: &mut K,
    clock: Clock,
    seq: &mut u8,
) -> Result<Exit, Refused> {
    match cfg.layout {
        LayoutChoice::PaperBoxes => match boxes(cfg) {
            Some(l) => run_layout::<_, K, M>(kernel, l, cfg, cells, sink, clock, seq).await,
            None => Err(Refused::Layout),
        },
        _ => match dense(cfg) {
            Some(l) => run_layout::<_, K, M>(kernel, l, cfg, cells, sink, clock, seq).await,
            None => Err(Refused::Layout),
        },
    }
}

async fn run_layout<L: Layout, K: YawSink, M: CostMeter>(
    kernel: &Kernel,
    layout: L,
    cfg: &StreamConfig,
    cells: &mut CellStore,
    sink: &mut K,
    clock: Clock,
    seq: &mut u8,
) -> Result<Exit, Refused> {
    let needed = layout.cell_count();
    let capacity = cells.capacity();
    let Some(cells) = cells.take(needed) else {
        return Err(Refused::Cells(needed));
    };
    let pc = ProcessConfig {
        focal_px: cfg.focal_px,
        cx: cfg.cx,
        cy: cfg.cy,
        period_us: cfg.period_us,
    };
    let mut pipeline = process::build(kernel, layout, cells, &pc).map_err(|_| Refused::Network)?;
    defmt::info!("processing: {} cells", needed);
    let accept = |new: &StreamConfig| cells_needed(new).is_some_and(|n| n <= capacity);
    Ok(processing::run::<_, _, M>(&mut pipeline, sink, clock, seq, cfg, &accept).await)
}

/// A live board's processing: runs `defaults` (the build's constants), then each configuration
/// the stream brings. A configuration that cannot be built is refused and the one before runs
/// again (from a fresh state); the defaults must run.
#[cfg_attr(feature = "board-qemu", allow(dead_code))]
pub async fn serve<K: YawSink, M: CostMeter>(
    kernel: &Kernel,
    defaults: StreamConfig,
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
