//! Link-time proof that the event path cannot panic.
//!
//! This binary runs the firmware's whole event path — raw SPI bytes and link events through the
//! link receiver (bit realignment, frame checks), the payloads through the payload decoder and
//! the configuration parser, the events through each readout's pipeline (network, spiking units
//! in a unit pool, readout, output clock), on both layouts —
//! on input read with volatile loads, so the compiler can assume nothing about it. Its panic
//! handler calls a function that exists nowhere: if any panic (unwrap, bounds check, division
//! by zero, explicit panic) were reachable from that path, the optimised, LTO'd binary would
//! fail to link with an undefined reference to `a_panic_is_reachable_from_the_event_path`.
//! `cargo xtask test` builds it; the firmware's other code (embassy, HAL) is not part of it.
#![no_std]
#![no_main]

use core::panic::PanicInfo;
use core::ptr::{addr_of, addr_of_mut, read_volatile, write_volatile};

use core_nostd::aer::events::PayloadDecoder;
use core_nostd::aer::link::{LinkEvent, LinkReceiver};
use core_nostd::fixed::types::U16F16;
use core_nostd::network::{Cell, NetState, UnitPair};
use core_nostd::readout::spikes::SpikeCell;
use core_nostd::readout::YawSample;
use core_nostd::settings::{LayoutChoice, ReadoutChoice, Settings};
use core_nostd::unit::Kernel;
use cortex_m_rt::entry;

static KERNEL: Kernel = Kernel::DEFAULT;

/// Input bytes and parameters the optimiser cannot see through.
static mut INPUT: [u8; 256] = [0; 256];
static mut PARAMS: [u32; 8] = [0; 8];
/// Where outputs go (so that nothing is optimised away).
static mut SINK: u32 = 0;

/// The pipeline's state: cells, a unit pool and its bookkeeping, the spike readout's cells.
struct State {
    cells: [Cell; CELLS],
    units: [UnitPair; POOL],
    owners: [u32; POOL],
    active: [u32; POOL / 32],
    spike_cells: [SpikeCell; CELLS],
}
const CELLS: usize = 2_000;
const POOL: usize = 256;
static mut STATE: State = State {
    cells: [Cell::DEFAULT; CELLS],
    units: [UnitPair::DEFAULT; POOL],
    owners: [0; POOL],
    active: [0; POOL / 32],
    spike_cells: [SpikeCell::EMPTY; CELLS],
};

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

/// A configuration frame's payload, as the processing stage reads it.
fn config(payload: &[u8]) {
    if let Ok(c) = Settings::parse(payload) {
        // SAFETY: as above.
        unsafe { write_volatile(addr_of_mut!(SINK), u32::from(c.width) ^ c.period_us) }
    }
}

/// The pipeline of settings read from the input, on `layout`, with `readout`.
fn run(layout: LayoutChoice, readout: ReadoutChoice, st: &mut State) {
    let settings = Settings {
        width: param(6) as u16,
        height: param(7) as u16,
        focal_px: U16F16::from_bits(param(0)),
        cx: U16F16::from_bits(param(1)),
        cy: U16F16::from_bits(param(4)),
        layout,
        stride: param(3) as u16,
        period_us: param(2),
        readout,
        tau_a_us: Some(param(3)),
        unit_pool: Some(param(5)),
    };
    let state = NetState::pooled(&mut st.cells, &mut st.units, &mut st.owners, &mut st.active);
    let Ok(mut p) = settings.build_with(&KERNEL, state, &mut st.spike_cells) else {
        return;
    };
    let mut link = LinkReceiver::new();
    let mut payload = PayloadDecoder::new();
    for i in 0..param(4) {
        let bytes = input();
        let mut rest = &bytes[..];
        while !rest.is_empty() {
            let n = link.feed(rest);
            rest = rest.get(n..).unwrap_or_default();
            while let Some(f) = link.next_frame() {
                payload.frame(&f, |ev| p.event(ev, &mut emit));
                config(f.payload);
            }
        }
        let event = match param(i as usize % 8) % 5 {
            0 => None,
            1 => Some(LinkEvent::EndOfTransaction),
            2 => Some(LinkEvent::Overrun),
            3 => Some(LinkEvent::ModeFault),
            _ => Some(LinkEvent::RingOverrun),
        };
        if let Some(e) = event {
            link.event(e);
            while let Some(f) = link.next_frame() {
                payload.frame(&f, |ev| p.event(ev, &mut emit));
                config(f.payload);
            }
        }
        p.poll(param(5), &mut emit);
    }
    link.end_of_stream();
    while let Some(f) = link.next_frame() {
        payload.frame(&f, |ev| p.event(ev, &mut emit));
        config(f.payload);
    }
}

#[entry]
fn main() -> ! {
    // SAFETY: STATE is only used here, by this single thread.
    let st: &mut State = unsafe { &mut *addr_of_mut!(STATE) };
    for readout in [
        ReadoutChoice::Calibrated,
        ReadoutChoice::Normalized,
        ReadoutChoice::Spikes,
    ] {
        run(LayoutChoice::PaperBoxes, readout, st);
        let window = LayoutChoice::Window {
            x0: param(1) as u16,
            y0: param(2) as u16,
            w: 40,
            h: 40,
        };
        run(window, readout, st);
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
