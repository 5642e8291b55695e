//! Runs the pipeline a [`Settings`] describes, and moves to another when the AER stream brings
//! different, valid settings in a configuration frame (`core_nostd::aer::config`).
//!
//! A board starts from its build-time defaults (or, in QEMU, its command line) and loops:
//! [`run`] returns [`Exit::Reconfigure`] with the new configuration, the board runs that. The
//! yaw stream's sequence counter carries over; the samples follow the new stream's event clock
//! from its first event on. A configuration that names an unknown layout or needs more RAM
//! than the board gives its state ([`Memory`]) is refused and counted
//! (`Stats::configs_refused`); the running network goes on.

use core_nostd::network::{Cell, NetState, UnitPair};
use core_nostd::readout::spikes::SpikeCell;
use core_nostd::settings::{Built, Settings, StorageNeeds};
use core_nostd::unit::Kernel;

use super::arena::{bytes_for, Arena};
pub use super::processing::Exit;
use super::processing::{self, Clock};
use super::{CostMeter, FrameReceiver, YawSink};

/// Why settings cannot run.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub enum Refused {
    /// The layout does not fit the sensor (or its stride), or a value is out of range.
    Layout,
    /// The state needs more RAM (bytes) than the board's region for it has.
    Memory(usize),
}

/// A board's RAM for pipeline state: the network's cells in `cells`; the spiking units (pairs
/// or a unit pool, the active bitset) and the spike readout's memory in `units` when the board
/// has a second region, else after the cells. When the cells do not fit their region but
/// everything fits the second one, everything goes there ([`Placement`]).
pub struct Memory {
    /// The cells' region (a fast one: CCM, AXI SRAM).
    pub cells: Arena,
    /// A second region for the units, if the board gives one.
    pub units: Option<Arena>,
}

/// Where a configuration's state goes in a board's [`Memory`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
enum Placement {
    /// The cells in the cells' region, the units' state in the second one.
    Split,
    /// Everything in the cells' region (a board with one region).
    AllInCells,
    /// Everything in the second region: the cells do not fit theirs (the QEMU board's 3.5 MiB
    /// of SRAM against its 16 MiB of PSRAM, for a large sensor's cells).
    AllInUnits,
}

/// The slices of the units' state, in carving order: `(count, size, align)`.
fn unit_slices(n: &StorageNeeds) -> [(usize, usize, usize); 4] {
    use core::mem::{align_of, size_of};
    [
        (n.unit_pairs, size_of::<UnitPair>(), align_of::<UnitPair>()),
        (n.pool_owners, 4, 4),
        (n.active_words, 4, 4),
        (
            n.spike_cells,
            size_of::<SpikeCell>(),
            align_of::<SpikeCell>(),
        ),
    ]
}

/// The sizes of a board's [`Memory`] regions (bytes).
#[derive(Clone, Copy)]
struct Capacity {
    cells: usize,
    units: Option<usize>,
}

impl Capacity {
    /// What the settings need of the board and where it goes, if they run on it at all.
    fn needs(&self, settings: &Settings) -> Result<(StorageNeeds, Placement), Refused> {
        use core::mem::{align_of, size_of};
        let needs = settings.storage().map_err(|_| Refused::Layout)?;
        let cells = (needs.cells, size_of::<Cell>(), align_of::<Cell>());
        let [a, b, c, d] = unit_slices(&needs);
        let fits = |bytes: Option<usize>, cap: usize| bytes.is_some_and(|b| b <= cap);
        let all = bytes_for(&[cells, a, b, c, d]);
        let Some(units_cap) = self.units else {
            return if fits(all, self.cells) {
                Ok((needs, Placement::AllInCells))
            } else {
                Err(Refused::Memory(all.unwrap_or(usize::MAX)))
            };
        };
        let (cell_bytes, unit_bytes) = (bytes_for(&[cells]), bytes_for(&[a, b, c, d]));
        if fits(cell_bytes, self.cells) && fits(unit_bytes, units_cap) {
            Ok((needs, Placement::Split))
        } else if fits(all, units_cap) {
            Ok((needs, Placement::AllInUnits))
        } else if !fits(cell_bytes, self.cells) {
            Err(Refused::Memory(cell_bytes.unwrap_or(usize::MAX)))
        } else {
            Err(Refused::Memory(unit_bytes.unwrap_or(usize::MAX)))
        }
    }
}

impl Memory {
    fn capacity(&self) -> Capacity {
        Capacity {
            cells: self.cells.capacity(),
            units: self.units.as_ref().map(Arena::capacity),
        }
    }

    /// The settings' pipeline over fresh state carved from the regions (while `self` is
    /// borrowed); `needs` and `placement` are what [`Capacity::needs`] said of them.
    fn build<'m>(
        &'m mut self,
        kernel: &'m Kernel,
        settings: &Settings,
        (needs, placement): (StorageNeeds, Placement),
    ) -> Result<Built<'m>, Refused> {
        let short = Refused::Memory(0);
        let mut cells_region = self.cells.carve();
        let mut units_region = self.units.as_mut().map(Arena::carve);
        let (first, second) = match (placement, units_region.as_mut()) {
            (Placement::Split, Some(units)) => (&mut cells_region, Some(units)),
            (Placement::AllInUnits, Some(units)) => (units, None),
            _ => (&mut cells_region, None),
        };
        let cells = first.take(needs.cells, Cell::DEFAULT).ok_or(short)?;
        let rest = second.unwrap_or(first);
        let units = rest
            .take(needs.unit_pairs, UnitPair::DEFAULT)
            .ok_or(short)?;
        let owners = rest.take(needs.pool_owners, 0u32).ok_or(short)?;
        let active = rest.take(needs.active_words, 0u32).ok_or(short)?;
        let spike_cells = rest
            .take(needs.spike_cells, SpikeCell::EMPTY)
            .ok_or(short)?;
        let state = if owners.is_empty() {
            NetState::spiking(cells, units, active)
        } else {
            NetState::pooled(cells, units, owners, active)
        };
        settings
            .build_with(kernel, state, spike_cells)
            .map_err(|_| Refused::Layout)
    }
}

/// Runs the settings' pipeline until the stream ends or other settings that fit `memory`
/// arrive. `seq` is the yaw stream's sequence counter (carried across runs).
///
/// # Errors
/// When the settings cannot run (see [`Refused`]).
pub async fn run<K: YawSink, M: CostMeter>(
    queue: &mut FrameReceiver,
    kernel: &Kernel,
    settings: &Settings,
    memory: &mut Memory,
    sink: &mut K,
    clock: Clock,
    seq: &mut u8,
) -> Result<Exit, Refused> {
    let capacity = memory.capacity();
    let (needs, placement) = capacity.needs(settings)?;
    let mut pipeline = memory.build(kernel, settings, (needs, placement))?;
    defmt::info!(
        "processing: {} cells, {} unit pairs, {} pool owners, placement {}",
        needs.cells,
        needs.unit_pairs,
        needs.pool_owners,
        placement
    );
    let accept = |new: &Settings| capacity.needs(new).is_ok();
    Ok(processing::run::<_, M>(queue, &mut pipeline, sink, clock, seq, settings, &accept).await)
}

/// A live board's processing: runs `defaults` (the build's constants), then each configuration
/// the stream brings. A configuration that cannot be built is refused and the one before runs
/// again (from a fresh state); the defaults must run.
#[cfg_attr(feature = "board-qemu", allow(dead_code))]
pub async fn serve<K: YawSink, M: CostMeter>(
    queue: &mut FrameReceiver,
    kernel: &Kernel,
    defaults: Settings,
    memory: &mut Memory,
    sink: &mut K,
) {
    let (mut good, mut next) = (defaults, defaults);
    let mut seq = 0u8;
    loop {
        match run::<K, M>(queue, kernel, &next, memory, sink, Clock::Live, &mut seq).await {
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
