//! Time on the QEMU board: an embassy-time driver on SysTick, and the cost meter.
//!
//! SysTick runs from the 25 MHz core clock of `mps2-an386` and interrupts every 1 ms (reload
//! 25 000). `now()` = whole periods plus the counter's progress, in 1 µs embassy ticks. Timers
//! are checked in the 1 ms interrupt (resolution 1 ms, enough for a 1 kHz output); a timer
//! already due when scheduled is woken at once.
//!
//! Under `qemu-system-arm -icount shift=N,align=off,sleep=off` one instruction is 2^N ns of
//! virtual time, so one SysTick step (40 ns) is 40 / 2^N instructions: [`SysTickMeter`] counts
//! instructions with that resolution, and whole runs are deterministic. Replays use N = 0
//! (1 G instructions per virtual second: the fastest virtual time, the finest count); live
//! runs use N = 3 (125 M instructions/s, the order of an STM32F405 at 168 MHz).

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};
use core::task::Waker;

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::{SCB, SYST};
use cortex_m_rt::exception;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_time_driver::Driver;
use embassy_time_queue_utils::Queue;

use crate::app::CostMeter;

/// SysTick input clock (Hz): the core clock of mps2-an386.
const CORE_HZ: u32 = 25_000_000;
/// SysTick steps per interrupt (1 ms).
const RELOAD: u32 = CORE_HZ / 1_000;
/// SysTick steps per embassy tick (1 µs).
const STEPS_PER_US: u64 = (CORE_HZ / 1_000_000) as u64;

/// Largest `-icount shift` the meter supports (40 ns = 5 instructions at shift 3).
pub const MAX_ICOUNT_SHIFT: u32 = 3;

/// Instructions per SysTick step (40 >> shift).
static INSTRUCTIONS_PER_STEP: AtomicU32 = AtomicU32::new(40);

/// Whole 1 ms periods since start.
static PERIODS: AtomicU32 = AtomicU32::new(0);
static QUEUE: Mutex<CriticalSectionRawMutex, RefCell<Queue>> =
    Mutex::new(RefCell::new(Queue::new()));

/// SysTick steps at counter value `v` (counting down from `RELOAD - 1`) in period `p`.
#[inline(always)]
fn steps_at(p: u32, v: u32) -> u64 {
    u64::from(p) * u64::from(RELOAD) + u64::from(RELOAD - 1 - v.min(RELOAD - 1))
}

/// SysTick steps since start (25 MHz).
fn steps() -> u64 {
    critical_section::with(|_| {
        let mut p = PERIODS.load(Ordering::Relaxed);
        let mut v = SYST::get_current();
        if SCB::is_pendst_pending() {
            // The counter wrapped but the interrupt has not run yet: re-read after the wrap.
            p = p.wrapping_add(1);
            v = SYST::get_current();
        }
        steps_at(p, v)
    })
}

struct SysTickDriver;

impl Driver for SysTickDriver {
    fn now(&self) -> u64 {
        steps() / STEPS_PER_US
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        critical_section::with(|cs| {
            QUEUE.borrow(cs).borrow_mut().schedule_wake(at, waker);
        });
        if at <= self.now() {
            waker.wake_by_ref();
        }
    }
}

embassy_time_driver::time_driver_impl!(static DRIVER: SysTickDriver = SysTickDriver);

#[exception]
fn SysTick() {
    PERIODS.fetch_add(1, Ordering::Relaxed);
    let now = DRIVER.now();
    critical_section::with(|cs| {
        QUEUE.borrow(cs).borrow_mut().next_expiration(now);
    });
}

/// Starts SysTick: 1 ms interrupts from the core clock. `icount_shift` is the QEMU
/// `-icount shift` (clamped to [`MAX_ICOUNT_SHIFT`]), for the instruction counter.
pub fn init(mut syst: SYST, icount_shift: u8) {
    let ns_per_step = 1_000_000_000 / CORE_HZ;
    let shift = u32::from(icount_shift).min(MAX_ICOUNT_SHIFT);
    INSTRUCTIONS_PER_STEP.store(ns_per_step >> shift, Ordering::Relaxed);
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(RELOAD - 1);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

/// Counts instructions under `-icount` (40 >> shift per SysTick step).
pub struct SysTickMeter;

impl CostMeter for SysTickMeter {
    const UNIT: &'static str = "instructions";

    fn units_per_tick() -> u32 {
        INSTRUCTIONS_PER_STEP.load(Ordering::Relaxed)
    }

    /// SysTick steps since start, modulo 2^32 (wraps after 171 s; an interval is measured
    /// right while it is shorter): whole periods plus the counter's progress, so that an
    /// interval spanning 1 ms interrupts counts them all (the raw counter alone would count
    /// it modulo one period). Thread mode only: a period's interrupt runs at its wrap, so a
    /// wrap between the reads shows as a changed period count, and the reads are retried.
    #[inline(always)]
    fn now() -> u32 {
        loop {
            let p = PERIODS.load(Ordering::Relaxed);
            let v = SYST::get_current();
            if PERIODS.load(Ordering::Relaxed) == p {
                return steps_at(p, v) as u32;
            }
        }
    }
}
