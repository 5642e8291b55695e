//! The AER stream from an emulated SPI NOR flash (`n25q128`) on the PL022 SPI at 0x4002_7000.
//!
//! QEMU wires no chip select to the flash, so it sees only the first command: one READ (0x03,
//! address 0) is sent, then every byte clocked out is the next byte of the flash. The PL022 is
//! the master here (QEMU has no device that could act as an SPI master towards the firmware);
//! on the real board the MCU is the slave and DMA fills a ring buffer (see `stm32f405`).
//! Throughput ~7 MB/s: about 1.7 M events/s of AER at 4 bytes per event.

use core::ptr::{read_volatile, write_volatile};

use core_nostd::aer::link::LinkEvent;

use crate::app::{ByteSource, SourceError};

const BASE: usize = 0x4002_7000;
const CR0: usize = BASE;
const CR1: usize = BASE + 0x04;
const DR: usize = BASE + 0x08;
const SR: usize = BASE + 0x0C;
const CPSR: usize = BASE + 0x10;
/// SR: transmit FIFO not full.
const SR_TNF: u32 = 1 << 1;
/// SR: receive FIFO not empty.
const SR_RNE: u32 = 1 << 2;
/// FIFO depth of the PL022.
const FIFO: usize = 8;
/// Polls without progress before the device is declared stuck.
const STUCK: u32 = 100_000;

fn rd(addr: usize) -> u32 {
    // SAFETY: a PL022 register of mps2-an386, always mapped.
    unsafe { read_volatile(addr as *const u32) }
}

fn wr(addr: usize, v: u32) {
    // SAFETY: as above.
    unsafe { write_volatile(addr as *mut u32, v) }
}

/// The flash as a byte stream of known length.
pub struct SpiFlash {
    left: u32,
}

impl SpiFlash {
    /// Configures the PL022 (master, 8-bit frames, SPI mode 0) and sends READ from address 0;
    /// the stream is `len` bytes long.
    pub fn start(len: u32) -> Self {
        wr(CR1, 0);
        wr(CR0, 0x7); // DSS = 8 bits, Motorola SPI, CPOL = CPHA = 0, SCR = 0
        wr(CPSR, 2);
        wr(CR1, 1 << 1); // SSE: enable, master
        let mut cmd = [0u8; 4];
        let mut me = Self { left: 4 };
        let _ = me.transfer(&[0x03, 0, 0, 0], &mut cmd);
        me.left = len;
        me
    }

    /// Clocks out `tx.len()` bytes and stores what comes back in `rx`.
    fn transfer(&mut self, tx: &[u8], rx: &mut [u8]) -> Result<(), SourceError> {
        let n = tx.len().min(rx.len());
        let (mut sent, mut got, mut idle) = (0usize, 0usize, 0u32);
        while got < n {
            let sr = rd(SR);
            if sent < n && sent - got < FIFO && sr & SR_TNF != 0 {
                wr(DR, u32::from(tx.get(sent).copied().unwrap_or(0)));
                sent += 1;
                idle = 0;
            } else if sr & SR_RNE != 0 {
                if let Some(b) = rx.get_mut(got) {
                    *b = rd(DR) as u8;
                }
                got += 1;
                idle = 0;
            } else {
                idle += 1;
                if idle > STUCK {
                    return Err(SourceError(LinkEvent::RingOverrun));
                }
            }
        }
        Ok(())
    }
}

impl ByteSource for SpiFlash {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, SourceError> {
        let n = buf.len().min(self.left as usize);
        if n == 0 {
            return Ok(0);
        }
        const ZEROS: [u8; 256] = [0; 256];
        let mut done = 0;
        while done < n {
            let k = (n - done).min(ZEROS.len());
            let Some(dst) = buf.get_mut(done..done + k) else {
                break;
            };
            self.transfer(ZEROS.get(..k).unwrap_or_default(), dst)?;
            done += k;
        }
        self.left -= done as u32;
        Ok(done)
    }
}
