//! The application every board runs: bytes in -> AER frames -> events -> processing -> yaw
//! frames out at 1 kHz.
//!
//! ```text
//!  board ByteSource ──> input() ──frame queue──> processing() ──YawSink──> board output
//!  (SPI DMA ring,       frame decoder,           payload decoder,          (USART, semihosting)
//!   SPI flash, file)    whole frames only        Pipeline, 1 kHz samples
//! ```
//!
//! The input stage and the processing stage are separate tasks joined by a queue of whole,
//! checked frames ([`frame_queue`]): the input stage copies each frame once, from the link
//! receiver's buffer into a free slot of the queue, and processing decodes it there. The
//! input stage never waits for processing on a live link ([`Overload::DropFrames`]): when no
//! slot is free the newest frame is dropped whole and counted, so a slow consumer can cost
//! frames but never corrupt the byte stream. A replay from storage
//! ([`Overload::Backpressure`], QEMU) waits instead, so that every frame is processed and the
//! output is deterministic.
//!
//! Boards are thin: they provide a [`ByteSource`], a [`YawSink`], a cost counter
//! ([`CostMeter`]) and the executor; tasks are spawned by the board because embassy tasks
//! cannot be generic.

pub mod arena;
pub mod configured;
pub mod input;
pub mod processing;

use core::cell::Cell;
use core::sync::atomic::{AtomicU8, Ordering};

use core_nostd::aer::frame::{Frame, Kind, MAX_PAYLOAD};
use core_nostd::aer::link::LinkEvent;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::CriticalSectionMutex;
use embassy_sync::zerocopy_channel::{Channel, Receiver, Sender};
use static_cell::{ConstStaticCell, StaticCell};

/// Frames the queue between input and processing holds (each slot ~1 KiB).
pub const FRAME_QUEUE_LEN: usize = 8;

/// What the input stage does when the frame queue is full.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum Overload {
    /// Live link: drop the whole new frame and count it (never block the receiver).
    DropFrames,
    /// Replay from storage: wait for room (deterministic, nothing dropped).
    #[cfg_attr(not(feature = "board-qemu"), allow(dead_code))]
    Backpressure,
}

/// One slot of the frame queue, written and read in place: a checked frame, copied out of the
/// link receiver's buffer, or the end of the stream. All zero when empty (the slots are in
/// `.bss`).
pub struct FrameBuf {
    /// The payload's [`Kind`] as its header nibble; 0: the byte source ended (replays only:
    /// process what is queued, then stop).
    kind: u8,
    /// Header flags.
    flags: u8,
    /// Sequence counter.
    seq: u16,
    /// Payload length in bytes (`<= MAX_PAYLOAD`).
    len: u16,
    /// Payload bytes (`len` valid).
    payload: [u8; MAX_PAYLOAD],
}

impl FrameBuf {
    /// An empty slot.
    const EMPTY: Self = Self {
        kind: 0,
        flags: 0,
        seq: 0,
        len: 0,
        payload: [0; MAX_PAYLOAD],
    };

    /// Becomes a copy of `f` (its payload's `len` bytes only; a payload is at most
    /// [`MAX_PAYLOAD`] bytes, a longer one would be cut there).
    pub fn fill(&mut self, f: &Frame<'_>) {
        self.kind = f.kind as u8;
        self.flags = f.flags;
        self.seq = f.seq;
        let n = f.payload.len().min(MAX_PAYLOAD);
        let (Some(dst), Some(src)) = (self.payload.get_mut(..n), f.payload.get(..n)) else {
            self.len = 0;
            return;
        };
        dst.copy_from_slice(src);
        self.len = n as u16;
    }

    /// Becomes the end of the stream.
    pub fn set_end(&mut self) {
        self.kind = 0;
    }

    /// The frame, read in place; `None` at the end of the stream.
    pub fn frame(&self) -> Option<Frame<'_>> {
        Some(Frame {
            kind: Kind::from_nibble(self.kind)?,
            flags: self.flags,
            seq: self.seq,
            payload: self
                .payload
                .get(..usize::from(self.len))
                .unwrap_or_default(),
        })
    }
}

/// The input stage's end of the frame queue: it takes a free slot, fills it, sends it.
pub type FrameSender = Sender<'static, CriticalSectionRawMutex, FrameBuf>;

/// The processing stage's end of the frame queue: it reads a slot in place, then frees it.
pub type FrameReceiver = Receiver<'static, CriticalSectionRawMutex, FrameBuf>;

/// The queue of whole frames between the input and the processing stage: its two ends, the
/// first time it is called (the board hands them to its tasks); `None` after that. The
/// [`FRAME_QUEUE_LEN`] slots are static (`.bss`); a frame is copied once, into its slot.
pub fn frame_queue() -> Option<(FrameSender, FrameReceiver)> {
    static SLOTS: ConstStaticCell<[FrameBuf; FRAME_QUEUE_LEN]> =
        ConstStaticCell::new([FrameBuf::EMPTY; FRAME_QUEUE_LEN]);
    static QUEUE: StaticCell<Channel<'static, CriticalSectionRawMutex, FrameBuf>> =
        StaticCell::new();
    let slots = SLOTS.try_take()?;
    Some(QUEUE.try_init(Channel::new(slots))?.split())
}

/// Transport flags (bits 4..=7 of the yaw frame's flags) raised since the last yaw frame.
static PENDING_FLAGS: AtomicU8 = AtomicU8::new(0);

/// Raises transport flags for the next yaw frame.
pub fn raise_flags(bits: u8) {
    PENDING_FLAGS.fetch_or(bits, Ordering::Relaxed);
}

/// Takes (and clears) the transport flags raised since the previous call.
pub fn take_flags() -> u8 {
    PENDING_FLAGS.swap(0, Ordering::Relaxed)
}

/// Counters of the whole application (32-bit: they wrap after 4e9).
#[derive(Clone, Copy, Debug, Default, defmt::Format)]
pub struct Stats {
    /// Bytes received from the source.
    pub bytes: u32,
    /// Intact frames received (by the frame decoder).
    pub frames_rx: u32,
    /// Frames rejected (CRC, header).
    pub frames_bad: u32,
    /// Frames missing from the sequence numbers.
    pub frames_gap: u32,
    /// Intact frames dropped because the queue was full.
    pub frames_overflow: u32,
    /// Frames that arrived with the sender's SOURCE_OVERFLOW flag.
    pub source_overflows: u32,
    /// Bytes that were not part of an intact frame.
    pub skipped_bytes: u32,
    /// Bytes lost by the source (DMA ring overruns).
    pub source_errors: u32,
    /// SPI transactions ended (NSS rising edges).
    pub transactions: u32,
    /// Transactions that ended inside a frame (NSS glitches, aborted transfers).
    pub cut_transactions: u32,
    /// Bit slips the receiver realigned (spurious or lost SCK edges).
    pub bit_slips: u32,
    /// SPI overruns (OVR).
    pub spi_overruns: u32,
    /// SPI mode faults (MODF).
    pub mode_faults: u32,
    /// Frames processed.
    pub frames_processed: u32,
    /// Events processed.
    pub events: u32,
    /// EVT 3.0 words of undefined types.
    pub decoder_errors: u32,
    /// Configuration frames that changed the running network.
    pub configs_applied: u32,
    /// Configuration frames refused (unknown version or values, a layout that does not fit).
    pub configs_refused: u32,
    /// Yaw frames written.
    pub yaw_out: u32,
    /// Yaw frames the sink had no room for.
    pub yaw_dropped: u32,
    /// Cost of the processing (pipeline calls only, the meter's own cost left out), in
    /// [`CostMeter`] units.
    pub cost_units: u64,
    /// Cost of the input stage's decoding (framing, CRCs, copies), in [`CostMeter`] units.
    pub input_cost_units: u64,
    /// The meter's cost of reading an empty interval, × 1024 (left out of `cost_units` once
    /// per event; [`CostMeter::overhead_x1024`]).
    pub meter_overhead_x1024: u64,
    /// Spikes of the network's units (spiking readouts), over all runs.
    pub spikes: u64,
    /// Unit pool: pairs in it (the last run's), most in use at once, events that found it full.
    pub pool_capacity: u32,
    pub pool_peak: u32,
    pub pool_full: u32,
}

/// The counters every board reads.
pub static STATS: CriticalSectionMutex<Cell<Stats>> = CriticalSectionMutex::new(Cell::new(Stats {
    bytes: 0,
    frames_rx: 0,
    frames_bad: 0,
    frames_gap: 0,
    frames_overflow: 0,
    source_overflows: 0,
    skipped_bytes: 0,
    source_errors: 0,
    transactions: 0,
    cut_transactions: 0,
    bit_slips: 0,
    spi_overruns: 0,
    mode_faults: 0,
    frames_processed: 0,
    events: 0,
    decoder_errors: 0,
    configs_applied: 0,
    configs_refused: 0,
    yaw_out: 0,
    yaw_dropped: 0,
    cost_units: 0,
    input_cost_units: 0,
    meter_overhead_x1024: 0,
    spikes: 0,
    pool_capacity: 0,
    pool_peak: 0,
    pool_full: 0,
}));

/// Changes the counters.
pub fn update_stats(f: impl FnOnce(&mut Stats)) {
    STATS.lock(|s| {
        let mut v = s.get();
        f(&mut v);
        s.set(v);
    });
}

/// A snapshot of the counters.
pub fn stats() -> Stats {
    STATS.lock(Cell::get)
}

/// Where the AER byte stream comes from.
pub trait ByteSource {
    /// Fills the front of `buf` with the next bytes; `Ok(0)` means the stream ended (a live
    /// link never ends); an error reports a link event at this point of the stream. May wait.
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, SourceError>;
}

/// Something happened on the link at this point of the byte stream (after the bytes returned
/// before, ahead of those returned after): the end of an SPI transaction, an overrun, a mode
/// fault, or lost bytes (a DMA ring overrun, a stuck emulated SPI). Reading goes on.
#[derive(Clone, Copy, Debug)]
pub struct SourceError(pub LinkEvent);

/// Where yaw frames go. Synchronous so the processing stage never waits on output: a sink
/// without room returns `false` and the frame is counted as dropped.
pub trait YawSink {
    /// Queues one encoded yaw frame.
    fn write(&mut self, frame: &[u8; core_nostd::aer::yaw::FRAME_BYTES]) -> bool;
}

/// A free-running counter to measure the processing cost.
pub trait CostMeter {
    /// What one unit counts ("instructions" under QEMU -icount, "cycles" on hardware).
    const UNIT: &'static str;
    /// Units of the raw counter's one step (QEMU: 40 >> shift instructions per SysTick step).
    fn units_per_tick() -> u32;
    /// The counter now: it must count every step of an interval however long the work (not
    /// modulo a timer period), up to its 32-bit wrap.
    fn now() -> u32;
    /// Ticks from `earlier` to `later` (across the counter's 32-bit wrap).
    #[inline(always)]
    fn ticks(earlier: u32, later: u32) -> u32 {
        later.wrapping_sub(earlier)
    }

    /// What the meter reads of an empty interval, in units × 1024 (the mean over many of
    /// them, × 1024): the cost of reading it, which the processing cost leaves out.
    ///
    /// A step of the raw counter can be longer than the interval (QEMU at shift 0: 40
    /// instructions), and a loop of identical intervals starts each at the same phase of the
    /// step, so that every one reads the same 0 or 1 step: the mean would be off by up to a
    /// step. Before each interval a padding of 0..[`CALIBRATION_PAD`] loop turns (coprime
    /// with the step) moves its start along the step, so that the mean of the reads is the
    /// interval's length to a fraction of a unit.
    fn overhead_x1024() -> u64 {
        let mut ticks = 0u64;
        for i in 0..CALIBRATION_ROUNDS * 1024 {
            for _ in 0..i % CALIBRATION_PAD {
                cortex_m::asm::nop();
            }
            let a = Self::now();
            core::hint::black_box(());
            let b = Self::now();
            ticks += u64::from(Self::ticks(a, b));
        }
        ticks * u64::from(Self::units_per_tick()) / u64::from(CALIBRATION_ROUNDS)
    }
}

/// Intervals read by [`CostMeter::overhead_x1024`], in units of 1024.
const CALIBRATION_ROUNDS: u32 = 16;
/// Largest padding before a calibration interval, in loop turns (a prime).
const CALIBRATION_PAD: u32 = 61;
