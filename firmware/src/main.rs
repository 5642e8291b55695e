//! TDE egomotion firmware: AER events in over SPI, yaw rate out at 1 kHz.
//!
//! One application ([`app`]) and thin boards ([`board`]), chosen by cargo feature:
//! `board-qemu` (default; QEMU `mps2-an386`) or `board-stm32f405` (flight controllers).
//! See `firmware/README.md` for building, running and flashing.
#![no_std]
#![no_main]

mod app;
mod board;

#[cortex_m_rt::entry]
fn main() -> ! {
    board::main()
}
