//! The SPI link of the STM32 boards: SPI1 as a slave (mode 0, MSB first, hardware NSS on PA4),
//! received by DMA into a ring, with the peripheral's events put at their place in the byte
//! stream for the application's link receiver (`core_nostd::aer::link`).
//!
//! - **NSS rising** (EXTI line 4 on PA4, which stays the SPI's NSS input): the interrupt
//!   disables the SPI at once (SPE = 0), so no byte of the next transaction can enter the ring.
//!   The input task then reads what the DMA has put in the ring, reports
//!   `LinkEvent::EndOfTransaction` after those bytes, and re-enables the SPI: the shift
//!   register's bit counter starts again at the next SCK edge, so a spurious SCK edge in one
//!   transaction cannot shift the bytes of the next one.
//! - **OVR** (the DMA did not take a byte in time; every byte after it would be lost until the
//!   flag is cleared): the SPI error interrupt clears it at once and counts it; the input task
//!   reports `LinkEvent::Overrun` (the lost bytes are found by the frames' CRC).
//! - **MODF** (mode fault: the peripheral has disabled itself): cleared in the interrupt; the
//!   input task drains the ring, reports `LinkEvent::ModeFault` and re-enables the SPI.
//! - **Ring overrun** (the input task fell more than the ring behind): `LinkEvent::RingOverrun`.
//!
//! The master must keep NSS high long enough for the re-arm (see `docs/wire-formats.md`):
//! bytes it clocks while the SPI is disabled are lost.
//!
//! The register work differs between the F4 SPI (`spi_v2`) and the H7 SPI (`spi_v4`, with
//! FIFOs); the EXTI and SYSCFG registers are the same.

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use core_nostd::aer::link::LinkEvent;
use embassy_futures::select::select;
use embassy_stm32::dma::ReadableRingBuffer;
use embassy_stm32::interrupt::{self, InterruptExt, Priority};
use embassy_stm32::pac;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use embassy_time::Timer;

use crate::app::{ByteSource, SourceError};

/// NSS is PA4: EXTI line 4, port A (0) in SYSCFG_EXTICR.
const NSS_LINE: usize = 4;
const NSS_PORT: u8 = 0;
/// How often the input task looks at the ring when no interrupt wakes it (µs).
const POLL_US: u64 = 200;

/// NSS rose: the SPI is disabled until the input task has drained the ring.
static NSS_ROSE: AtomicBool = AtomicBool::new(false);
/// MODF happened: the SPI disabled itself.
static MODE_FAULT: AtomicBool = AtomicBool::new(false);
/// OVR flags cleared by the error interrupt.
static OVERRUNS: AtomicU32 = AtomicU32::new(0);
/// Wakes the input task.
static WAKE: Signal<CriticalSectionRawMutex, ()> = Signal::new();

#[embassy_stm32::interrupt]
unsafe fn EXTI4() {
    pac::EXTI.pr(0).write(|w| w.set_line(NSS_LINE, true));
    regs::disable();
    NSS_ROSE.store(true, Ordering::Release);
    WAKE.signal(());
}

#[embassy_stm32::interrupt]
unsafe fn SPI1() {
    let (ovr, modf) = regs::take_errors();
    if ovr {
        OVERRUNS.fetch_add(1, Ordering::Relaxed);
    }
    if modf {
        MODE_FAULT.store(true, Ordering::Release);
    }
    WAKE.signal(());
}

/// Enables RX DMA and the error interrupt on SPI1 (already configured as a slave by the HAL),
/// and the NSS edge interrupt. `priority` must be above the input task's executor.
pub fn arm(priority: Priority) {
    regs::configure();
    pac::SYSCFG
        .exticr(NSS_LINE / 4)
        .modify(|w| w.set_exti(NSS_LINE % 4, NSS_PORT));
    pac::EXTI.rtsr(0).modify(|w| w.set_line(NSS_LINE, true));
    pac::EXTI.ftsr(0).modify(|w| w.set_line(NSS_LINE, false));
    pac::EXTI.pr(0).write(|w| w.set_line(NSS_LINE, true));
    pac::EXTI.imr(0).modify(|w| w.set_line(NSS_LINE, true));
    interrupt::EXTI4.set_priority(priority);
    interrupt::SPI1.set_priority(priority);
    // SAFETY: both handlers are defined above and only touch SPI1, EXTI line 4 and atomics.
    unsafe {
        interrupt::EXTI4.enable();
        interrupt::SPI1.enable();
    }
}

/// The SPI DMA ring and the link's events, as the application's byte source.
pub struct SpiLink {
    ring: ReadableRingBuffer<'static, u8>,
    overruns_seen: u32,
}

impl SpiLink {
    /// Takes the started ring of SPI1's RX DMA.
    pub fn new(ring: ReadableRingBuffer<'static, u8>) -> Self {
        Self {
            ring,
            overruns_seen: 0,
        }
    }
}

impl ByteSource for SpiLink {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, SourceError> {
        loop {
            // Read before the ring: when set, the SPI was already off, so the ring read below
            // holds every byte from before the edge (the DMA takes a byte within cycles).
            let stopped = NSS_ROSE.load(Ordering::Acquire) || MODE_FAULT.load(Ordering::Acquire);
            match self.ring.read(buf) {
                Ok((0, _)) => {}
                Ok((n, _)) => return Ok(n),
                Err(_) => {
                    self.ring.clear();
                    return Err(SourceError(LinkEvent::RingOverrun));
                }
            }
            if stopped {
                let event = if MODE_FAULT.swap(false, Ordering::AcqRel) {
                    LinkEvent::ModeFault
                } else {
                    LinkEvent::EndOfTransaction
                };
                NSS_ROSE.store(false, Ordering::Release);
                regs::rearm();
                return Err(SourceError(event));
            }
            let ovr = OVERRUNS.load(Ordering::Relaxed);
            if ovr != self.overruns_seen {
                self.overruns_seen = ovr;
                return Err(SourceError(LinkEvent::Overrun));
            }
            select(WAKE.wait(), Timer::after_micros(POLL_US)).await;
        }
    }
}

/// STM32F4 SPI (`spi_v2`): one data register, OVR cleared by reading DR then SR, MODF by
/// reading SR then writing CR1.
#[cfg(feature = "board-stm32f405")]
mod regs {
    use embassy_stm32::pac::SPI1;

    pub fn configure() {
        SPI1.cr2().modify(|w| {
            w.set_rxdmaen(true);
            w.set_errie(true);
        });
    }

    pub fn disable() {
        SPI1.cr1().modify(|w| w.set_spe(false));
    }

    pub fn rearm() {
        // The ring is drained and the SPI off: what DR holds was already taken by the DMA.
        let _ = SPI1.dr().read();
        let _ = SPI1.sr().read();
        // Writing CR1 after the SR read also clears a MODF.
        SPI1.cr1().modify(|w| w.set_spe(true));
    }

    /// Clears OVR and MODF; returns which were set.
    pub fn take_errors() -> (bool, bool) {
        let sr = SPI1.sr().read();
        if sr.ovr() {
            let _ = SPI1.dr().read();
            let _ = SPI1.sr().read();
        }
        if sr.modf() {
            // MODF cleared SPE; it stays off until the input task re-arms after draining.
            SPI1.cr1().modify(|w| w.set_spe(false));
        }
        (sr.ovr(), sr.modf())
    }
}

/// STM32H7 SPI (`spi_v4`): RX FIFO, flags cleared through IFCR, DMA and interrupt enables
/// writable only while SPE = 0.
#[cfg(feature = "board-stm32h743")]
mod regs {
    use embassy_stm32::pac::spi::vals::Comm;
    use embassy_stm32::pac::SPI1;

    pub fn configure() {
        SPI1.cr1().modify(|w| w.set_spe(false));
        SPI1.cfg1().modify(|w| w.set_rxdmaen(true));
        // Receive only: the slave never underruns a transmit FIFO nobody fills.
        SPI1.cfg2().modify(|w| w.set_comm(Comm::RECEIVER));
        SPI1.ier().modify(|w| {
            w.set_ovrie(true);
            w.set_modfie(true);
        });
        SPI1.cr1().modify(|w| w.set_spe(true));
    }

    pub fn disable() {
        SPI1.cr1().modify(|w| w.set_spe(false));
    }

    pub fn rearm() {
        SPI1.ifcr().write(|w| {
            w.set_ovrc(true);
            w.set_modfc(true);
            w.set_udrc(true);
        });
        SPI1.cr1().modify(|w| w.set_spe(true));
    }

    /// Clears OVR and MODF; returns which were set.
    pub fn take_errors() -> (bool, bool) {
        let sr = SPI1.sr().read();
        SPI1.ifcr().write(|w| {
            w.set_ovrc(sr.ovr());
            w.set_modfc(sr.modf());
        });
        if sr.modf() {
            SPI1.cr1().modify(|w| w.set_spe(false));
        }
        (sr.ovr(), sr.modf())
    }
}
