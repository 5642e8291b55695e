//! Firmware entry point (STM32F405). The full pipeline is built in the firmware issue; for now
//! this proves that the fixed-point core links for Cortex-M4F with its compile-time tables.
#![no_std]
#![no_main]

use core_nostd::event::Event;
use core_nostd::layout::{Dense, Layout};
use core_nostd::network::{active_words, Cell, InputFilter, Network};
use core_nostd::unit::Kernel;
use cortex_m_rt::entry;
use panic_halt as _;

static KERNEL: Kernel = Kernel::DEFAULT;

#[entry]
fn main() -> ! {
    let mut cells = [Cell::default(); 64 * 4];
    let mut active = [0u32; active_words(64 * 4)];
    let mut spikes = 0u32;
    if let Some(layout) = Dense::new(64, 4, 2) {
        if layout.cell_count() <= cells.len() {
            if let Ok(mut net) =
                Network::new(&KERNEL, layout, &mut cells, &mut active, InputFilter::All)
            {
                let mut t = 0u32;
                for x in 0..64u16 {
                    t = t.wrapping_add(5_000);
                    net.event(
                        Event {
                            t_us: t,
                            x,
                            y: 1,
                            on: true,
                        },
                        &mut |_| spikes += 1,
                    );
                }
            }
        }
    }
    loop {
        cortex_m::asm::nop();
        core::hint::black_box(spikes);
    }
}
