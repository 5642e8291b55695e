//! Link-time proof that the event path cannot panic.
//!
//! This binary runs the firmware's whole event path — AER bytes through the frame receiver, the
//! events through the calibrated pipeline (network, readout, output clock), on both layouts —
//! on input read with volatile loads, so the compiler can assume nothing about it. Its panic
//! handler calls a function that exists nowhere: if any panic (unwrap, bounds check, division
//! by zero, explicit panic) were reachable from that path, the optimised, LTO'd binary would
//! fail to link with an undefined reference to `a_panic_is_reachable_from_the_event_path`.
//! `cargo xtask test` builds it; the firmware's other code (embassy, HAL) is not part of it.
#![no_std]
#![no_main]

use core::panic::PanicInfo;
use core::ptr::{addr_of, addr_of_mut, read_volatile, write_volatile};

use core_nostd::aer::events::Receiver;
use core_nostd::fixed::types::U16F16;
use core_nostd::layout::{Dense, Layout, PaperBoxes};
use core_nostd::network::Cell;
use core_nostd::pipeline;
use core_nostd::readout::calibrated::Calibration;
use core_nostd::readout::YawSample;
use core_nostd::unit::Kernel;
use cortex_m_rt::entry;

static KERNEL: Kernel = Kernel::DEFAULT;

/// Input bytes and parameters the optimiser cannot see through.
static mut INPUT: [u8; 256] = [0; 256];
static mut PARAMS: [u32; 8] = [0; 8];
/// Where outputs go (so that nothing is optimised away).
static mut SINK: u32 = 0;

static mut CELLS: [Cell; 2_000] = [Cell::DEFAULT; 2_000];

fn input() -> [u8; 256] {
    // SAFETY: a volatile read of a static that only this single-threaded program touches.
    unsafe { read_volatile(addr_of!(INPUT)) }
}

fn param(i: usize) -> u32 {
    // SAFETY: as above.
    unsafe { read_volatile(addr_of!(PARAMS)).get(i).copied().unwrap_or(0) }
}

fn emit(s: YawSample) {
    // SAFETY: as above.
    unsafe {
        write_volatile(
            addr_of_mut!(SINK),
            s.yaw_rate.to_bits() as u32 ^ u32::from(s.flags),
        )
    }
}

fn run<L: Layout>(layout: L, cells: &mut [Cell]) {
    let cal = Calibration::for_units(
        U16F16::from_bits(param(0)),
        U16F16::from_bits(param(1)),
        layout.unit_count(),
    );
    let cal = Calibration {
        period_us: param(2),
        tau_a_us: param(3),
        ..cal
    };
    let Ok(mut p) = pipeline::calibrated(&KERNEL, layout, cells, cal) else {
        return;
    };
    let mut rx = Receiver::new();
    for _ in 0..param(4) {
        let bytes = input();
        rx.push(&bytes, |ev| p.event(ev, &mut emit));
        p.poll(param(5), &mut emit);
    }
}

#[entry]
fn main() -> ! {
    // SAFETY: CELLS is only used here, by this single thread.
    let cells: &mut [Cell] = unsafe { &mut *addr_of_mut!(CELLS) };
    let (w, h) = (param(6) as u16, param(7) as u16);
    if let Some(l) = PaperBoxes::new(w, h, u64::from(param(0))) {
        run(l, cells);
    }
    if let Some(l) = Dense::window(
        w,
        h,
        param(1) as u16,
        param(2) as u16,
        40,
        40,
        param(3) as u16,
    ) {
        run(l, cells);
    }
    loop {
        cortex_m::asm::nop();
    }
}

#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    extern "C" {
        /// Deliberately defined nowhere (see the module docs).
        fn a_panic_is_reachable_from_the_event_path() -> !;
    }
    // SAFETY: never linked; reaching this call is exactly what the build rules out.
    unsafe { a_panic_is_reachable_from_the_event_path() }
}
