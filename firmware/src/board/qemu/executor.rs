//! The executor of the QEMU board: embassy's raw executor with an idle that sleeps in WFI.
//!
//! The stock Cortex-M executor idles with WFE, which QEMU treats as a no-op: the host CPU would
//! spin and, under `-icount`, virtual time would crawl. Here the idle check and the WFI run
//! with interrupts masked, so a wake-up between "no work" and "sleep" is never missed: WFI
//! returns on any pending interrupt even while masked, and the interrupt runs right after.

use core::sync::atomic::{AtomicBool, Ordering};

use embassy_executor::raw;
use embassy_executor::Spawner;
use static_cell::StaticCell;

/// Set by the pender when a task was woken.
static WORK: AtomicBool = AtomicBool::new(true);

#[export_name = "__pender"]
fn pender(_context: *mut ()) {
    WORK.store(true, Ordering::Release);
}

/// Runs the executor forever after `init` spawned the first tasks.
pub fn run(init: impl FnOnce(Spawner)) -> ! {
    static EXECUTOR: StaticCell<raw::Executor> = StaticCell::new();
    let executor: &'static raw::Executor = EXECUTOR.init(raw::Executor::new(core::ptr::null_mut()));
    init(executor.spawner());
    loop {
        WORK.store(false, Ordering::Release);
        // SAFETY: `poll` is only called from this one thread-mode loop, never re-entrantly.
        unsafe { executor.poll() };
        cortex_m::interrupt::free(|_| {
            if !WORK.load(Ordering::Acquire) {
                cortex_m::asm::wfi();
            }
        });
    }
}
