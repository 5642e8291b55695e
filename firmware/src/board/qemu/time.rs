//! Time on the QEMU board: an embassy-time driver on SysTick, and the cost meter.
//!
//! SysTick runs from the 25 MHz core clock of `mps2-an386` and interrupts every 1 ms (reload
//! 25 000). `now()` = whole periods plus the counter's progress, in 1 µs embassy ticks. Timers
//! are checked in the 1 ms interrupt (resolution 1 ms, enough for a 1 kHz output); a timer
//! already due when scheduled is woken at once.
//!
//! Under `qemu-system-arm -icount shift=0,align=off,sleep=off` one instruction is 1 ns of
//! virtual time, so one SysTick step (40 ns) is 40 instructions: [`SysTickMeter`] counts
//! instructions with that resolution, and whole runs are deterministic.

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

/// Whole 1 ms periods since start.
static PERIODS: AtomicU32 = AtomicU32::new(0);
static QUEUE: Mutex<CriticalSectionRawMutex, RefCell<Queue>> =
    Mutex::new(RefCell::new(Queue::new()));

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
        u64::from(p) * u64::from(RELOAD) + u64::from(RELOAD - 1 - v.min(RELOAD - 1))
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

/// Starts SysTick: 1 ms interrupts from the core clock.
pub fn init(mut syst: SYST) {
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(RELOAD - 1);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

/// Counts instructions under `-icount shift=0` (40 per SysTick step).
pub struct SysTickMeter;

impl CostMeter for SysTickMeter {
    const UNIT: &'static str = "instructions";
    const UNITS_PER_TICK: u32 = 1_000_000_000 / CORE_HZ;

    #[inline(always)]
    fn now() -> u32 {
        SYST::get_current()
    }

    #[inline(always)]
    fn ticks(earlier: u32, later: u32) -> u32 {
        // A down counter from RELOAD - 1 to 0.
        if earlier >= later {
            earlier - later
        } else {
            earlier + RELOAD - later
        }
    }
}
