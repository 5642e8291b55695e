//! The STM32F405RG board (Crazyflie-class and many Betaflight flight controllers), 168 MHz.
//!
//! - Events in: SPI1 as a **slave** (the sensor bridge is the master; mode 0, MSB first; SCK
//!   PA5, MOSI PA7, MISO PA6, NSS PA4), received by DMA2 stream 0 (channel 3) in circular mode
//!   into a 4 KiB ring in SRAM (`dma::ReadableRingBuffer` on the SPI data register; RX DMA
//!   enabled through the PAC). NSS edges (EXTI4), OVR and MODF (SPI1 error interrupt) re-arm
//!   the peripheral and reach the link receiver at their place in the stream
//!   (`super::stm32_link`). The input task runs on a higher-priority interrupt executor, so
//!   processing never delays it.
//! - Yaw frames out: USART1 TX (PA9) at 921 600 baud by DMA2 stream 7 (14 kB/s needed).
//! - Logs: defmt over RTT; panics: panic-probe (reported over RTT by probe-rs).
//! - Memory: network cells in the 64 KiB CCM (CPU only); the spiking readouts' units (a unit
//!   pool), DMA buffers and everything else in the 128 KiB SRAM (`memory.x` at the repo root).
//! - Live link: whole frames are dropped when processing falls behind, and the clock drives
//!   stale output when no events arrive.
//!
//! Flash and run: `cargo xtask flash`, or `cargo f405-run` in `firmware/` (both use
//! `probe-rs run --chip STM32F405RGTx`; install with `cargo install probe-rs-tools --locked`).

use core::mem::MaybeUninit;

use core_nostd::aer::yaw::FRAME_BYTES;
use core_nostd::settings::Settings;
use core_nostd::unit::Kernel;
use defmt_rtt as _;
use embassy_stm32::dma::{self, ReadableRingBuffer, TransferOptions};
use embassy_stm32::interrupt::Priority;
use embassy_stm32::spi::BitOrder;
use embassy_stm32::time::Hertz;
use embassy_stm32::usart::{self, UartTx};
use embassy_stm32::{bind_interrupts, pac, peripherals, spi};
use panic_probe as _;
use static_cell::StaticCell;

use super::stm32_common::{self, CycleMeter, UartSink};
use super::stm32_link::{self, SpiLink};
use crate::app::arena::{Arena, Region};
use crate::app::configured::{self, Memory};
use crate::app::FrameReceiver;
use core_nostd::network::Cell;

bind_interrupts!(struct Irqs {
    DMA2_STREAM0 => dma::InterruptHandler<peripherals::DMA2_CH0>;
    DMA2_STREAM7 => dma::InterruptHandler<peripherals::DMA2_CH7>;
});

/// What runs until a configuration frame says otherwise: the full-width 346 x 15 dense strip of a
/// DAVIS346 (5190 cells of 12 bytes, 62 280 B, 10 020 units), chosen by measurement over the
/// paper's boxes and a 192 x 28 window (`firmware/README.md`).
const DEFAULTS: Settings = stm32_common::davis346_full_width(MAX_CELLS);
/// Cells reserved in CCM: as many as its 64 KiB hold (the dense window is the largest layout).
const MAX_CELLS: usize = 64 * 1024 / core::mem::size_of::<Cell>();
/// Bytes of the cells' region.
const CELL_BYTES: usize = MAX_CELLS * core::mem::size_of::<Cell>();
/// SPI DMA ring size (bytes): 4 KiB is ~2 ms at 2 MB/s.
const RING_BYTES: usize = 4096;
/// SPI1 RX request on DMA2 stream 0 (channel 3).
const SPI1_RX_REQUEST: u8 = 3;

/// SRAM for the spiking units (a unit pool of up to 628 pairs), leaving ~20 KiB for the stack.
const UNIT_BYTES: usize = 32 * 1024;

#[link_section = ".ccmram"]
static mut CELLS: MaybeUninit<Region<CELL_BYTES>> = MaybeUninit::uninit();
static mut UNITS: MaybeUninit<Region<UNIT_BYTES>> = MaybeUninit::uninit();
static mut RING: [u8; RING_BYTES] = [0; RING_BYTES];

static KERNEL: Kernel = Kernel::DEFAULT;

#[embassy_executor::task]
async fn output_task(mut tx: UartTx<'static, embassy_stm32::mode::Async>) {
    let mut buf = [0u8; FRAME_BYTES * 16];
    stm32_common::send_yaw_frames(&mut tx, &mut buf[..]).await
}

#[embassy_executor::task]
async fn process_task(mut queue: FrameReceiver) {
    // SAFETY: CELLS and UNITS are used by these arenas only, for the rest of
    // the program.
    let mut memory = unsafe {
        Memory {
            cells: Arena::over(core::ptr::addr_of_mut!(CELLS)),
            units: Some(Arena::over(core::ptr::addr_of_mut!(UNITS))),
        }
    };
    configured::serve::<_, CycleMeter>(&mut queue, &KERNEL, DEFAULTS, &mut memory, &mut UartSink)
        .await;
}

fn rcc_config() -> embassy_stm32::Config {
    use embassy_stm32::rcc::*;
    let mut config = embassy_stm32::Config::default();
    config.rcc.hse = Some(Hse {
        freq: Hertz(8_000_000),
        mode: HseMode::Oscillator,
    });
    config.rcc.pll_src = PllSource::HSE;
    config.rcc.pll = Some(Pll {
        prediv: PllPreDiv::DIV4,
        mul: PllMul::MUL168,
        divp: Some(PllPDiv::DIV2), // 168 MHz
        divq: Some(PllQDiv::DIV7),
        divr: None,
    });
    config.rcc.ahb_pre = AHBPrescaler::DIV1;
    config.rcc.apb1_pre = APBPrescaler::DIV4;
    config.rcc.apb2_pre = APBPrescaler::DIV2;
    config.rcc.sys = Sysclk::PLL1_P;
    config
}

/// Entry point of the STM32F405 board.
pub fn main() -> ! {
    let p = embassy_stm32::init(rcc_config());
    if let Some(mut cp) = cortex_m::Peripherals::take() {
        cp.DCB.enable_trace();
        cp.DWT.enable_cycle_counter();
    }
    defmt::info!("stm32f405: TDE firmware");

    // SPI1 slave, RX by DMA into the ring.
    let mut spi_cfg = spi::Config::default();
    spi_cfg.mode = spi::MODE_0;
    spi_cfg.bit_order = BitOrder::MsbFirst;
    let spi = spi::Spi::new_blocking_slave(p.SPI1, p.PA5, p.PA7, p.PA6, p.PA4, spi_cfg);
    // The driver must stay alive (dropping it disables SPI1).
    static SPI: StaticCell<spi::Spi<'static, embassy_stm32::mode::Blocking, spi::mode::Slave>> =
        StaticCell::new();
    SPI.init(spi);
    // RX DMA, OVR/MODF interrupt, NSS edge interrupt: above the input executor (P6).
    stm32_link::arm(Priority::P5);
    let channel = dma::Channel::new(p.DMA2_CH0, Irqs);
    // SAFETY: RING is used by this DMA ring only, for the rest of the program; the peripheral
    // address is SPI1's data register.
    let mut ring = unsafe {
        ReadableRingBuffer::new(
            channel,
            SPI1_RX_REQUEST,
            pac::SPI1.dr().as_ptr() as *mut u8,
            &mut *core::ptr::addr_of_mut!(RING),
            TransferOptions::default(),
        )
    };
    ring.start();

    // USART1 TX by DMA.
    let mut uart_cfg = usart::Config::default();
    uart_cfg.baudrate = 921_600;
    let tx = match UartTx::new(p.USART1, p.PA9, p.DMA2_CH7, Irqs, uart_cfg) {
        Ok(tx) => tx,
        Err(_) => defmt::panic!("usart config"),
    };

    stm32_common::run(SpiLink::new(ring), process_task, move || output_task(tx))
}
