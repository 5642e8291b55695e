//! The STM32H743VI board (H743 flight controllers such as the Matek H743 and Kakute H7
//! class), 480 MHz Cortex-M7.
//!
//! - Events in: SPI1 as a **slave**, receive only (the sensor bridge is the master; mode 0,
//!   MSB first; SCK PA5, MOSI PA7, NSS PA4; MISO PA6 reserved), received by DMA1 stream 0
//!   (DMAMUX request SPI1_RX) in circular mode into a 4 KiB ring in SRAM1. NSS edges (EXTI4),
//!   OVR and MODF re-arm the peripheral and reach the link receiver at their place in the
//!   stream (`super::stm32_link`). The input task runs on a higher-priority interrupt
//!   executor, so processing never delays it.
//! - Yaw frames out: USART1 TX (PA9) at 921 600 baud by DMA1 stream 1 (14 kB/s needed).
//! - Logs: defmt over RTT; panics: panic-probe (reported over RTT by probe-rs).
//! - Memory (`boards/stm32h743/memory.x`): stack and statics in the 128 KiB DTCM (CPU only);
//!   the network cells fill the 512 KiB AXI SRAM; the DMA buffers sit in SRAM1 (DMA1 cannot
//!   reach the DTCM). The whole 346 x 260 dense network needs 89 960 cells x 8 B = 719 680 B
//!   in one piece, more than the largest SRAM block, so the board runs the largest dense
//!   window that fits the AXI SRAM: 346 x 126 (all columns, 126 of 260 rows, centred).
//! - Caches: the instruction cache is on; the data cache stays off, because the DMA buffers
//!   would need cache maintenance or an MPU region (cells in AXI SRAM run uncached).
//!
//! Flash and run: `cargo xtask flash --board stm32h743`, or `cargo h743-run` in `firmware/`
//! (both use `probe-rs run --chip STM32H743VITx`; install with
//! `cargo install probe-rs-tools --locked`).

use core::mem::MaybeUninit;

use core_nostd::aer::yaw::FRAME_BYTES;
use core_nostd::settings::Settings;
use core_nostd::unit::Kernel;
use defmt_rtt as _;
use embassy_stm32::dma::{self, ReadableRingBuffer, TransferOptions};
use embassy_stm32::interrupt::Priority;
use embassy_stm32::spi::{BitOrder, RxDma};
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
    DMA1_STREAM0 => dma::InterruptHandler<peripherals::DMA1_CH0>;
    DMA1_STREAM1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
});

/// What runs until a configuration frame says otherwise: the largest dense window of a DAVIS346
/// that fits the AXI SRAM, all 346 columns by 126 rows (43 596 cells of 12 bytes, 523 152 B,
/// 86 688 units).
const DEFAULTS: Settings = stm32_common::davis346_full_width(MAX_CELLS);
/// Cells the AXI SRAM holds (512 KiB of 12-byte cells).
const MAX_CELLS: usize = 512 * 1024 / core::mem::size_of::<Cell>();
/// Bytes of the cells' region.
const CELL_BYTES: usize = MAX_CELLS * core::mem::size_of::<Cell>();
/// SPI DMA ring size (bytes): 4 KiB is ~1 ms at 4 MB/s.
const RING_BYTES: usize = 4096;
/// Yaw frames per UART DMA transfer, at most.
const TX_FRAMES: usize = 16;

/// SRAM2 and SRAM3 (160 KiB, D2) for the spiking units: a unit pool of up to 3 143 pairs.
const UNIT_BYTES: usize = 160 * 1024;

#[link_section = ".axisram"]
static mut CELLS: MaybeUninit<Region<CELL_BYTES>> = MaybeUninit::uninit();
#[link_section = ".sram23"]
static mut UNITS: MaybeUninit<Region<UNIT_BYTES>> = MaybeUninit::uninit();
// DMA buffers: in SRAM1, which DMA1 reaches (it cannot reach the DTCM). Not loaded (NOLOAD):
// any bytes are valid, and DMA or the CPU writes them before they are read.
#[link_section = ".sram1"]
static mut RING: [u8; RING_BYTES] = [0; RING_BYTES];
#[link_section = ".sram1"]
static mut TX_BUF: [u8; FRAME_BYTES * TX_FRAMES] = [0; FRAME_BYTES * TX_FRAMES];

static KERNEL: Kernel = Kernel::DEFAULT;

#[embassy_executor::task]
async fn output_task(mut tx: UartTx<'static, embassy_stm32::mode::Async>) {
    // SAFETY: TX_BUF is used by this task only, for the rest of the program.
    let buf: &'static mut [u8; FRAME_BYTES * TX_FRAMES] =
        unsafe { &mut *core::ptr::addr_of_mut!(TX_BUF) };
    stm32_common::send_yaw_frames(&mut tx, buf).await
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
    config.rcc.pll1 = Some(Pll {
        source: PllSource::HSE,
        prediv: PllPreDiv::DIV1,
        mul: PllMul::MUL120,
        fracn: None,
        divp: Some(PllDiv::DIV2),
        divq: Some(PllDiv::DIV8),
        divr: None,
    });
    config.rcc.sys = Sysclk::PLL1_P;
    config.rcc.d1c_pre = AHBPrescaler::DIV1;
    config.rcc.ahb_pre = AHBPrescaler::DIV2;
    config.rcc.apb1_pre = APBPrescaler::DIV2;
    config.rcc.apb2_pre = APBPrescaler::DIV2;
    config.rcc.apb3_pre = APBPrescaler::DIV2;
    config.rcc.apb4_pre = APBPrescaler::DIV2;
    config.rcc.voltage_scale = VoltageScale::Scale0;
    config
}

/// Entry point of the STM32H743 board.
pub fn main() -> ! {
    let p = embassy_stm32::init(rcc_config());
    // SRAM1 holds the DMA buffers: keep it allocated to the CPU.
    pac::RCC.ahb2enr().modify(|w| w.set_sram1en(true));
    if let Some(mut cp) = cortex_m::Peripherals::take() {
        cp.SCB.enable_icache();
        cp.DCB.enable_trace();
        cp.DWT.enable_cycle_counter();
    }
    defmt::info!("stm32h743: TDE firmware");

    // SPI1 slave, RX by DMA into the ring.
    let mut spi_cfg = spi::Config::default();
    spi_cfg.mode = spi::MODE_0;
    spi_cfg.bit_order = BitOrder::MsbFirst;
    let rx_request = RxDma::<peripherals::SPI1>::request(&*p.DMA1_CH0);
    let spi = spi::Spi::new_blocking_slave(p.SPI1, p.PA5, p.PA7, p.PA6, p.PA4, spi_cfg);
    // The driver must stay alive (dropping it disables SPI1).
    static SPI: StaticCell<spi::Spi<'static, embassy_stm32::mode::Blocking, spi::mode::Slave>> =
        StaticCell::new();
    SPI.init(spi);
    // RX DMA, receive-only, OVR/MODF interrupt, NSS edge interrupt: above the input executor.
    stm32_link::arm(Priority::P5);
    let channel = dma::Channel::new(p.DMA1_CH0, Irqs);
    // SAFETY: RING is used by this DMA ring only, for the rest of the program; the peripheral
    // address is SPI1's receive data register.
    let mut ring = unsafe {
        ReadableRingBuffer::new(
            channel,
            rx_request,
            pac::SPI1.rxdr8().as_ptr(),
            &mut *core::ptr::addr_of_mut!(RING),
            TransferOptions::default(),
        )
    };
    ring.start();

    // USART1 TX by DMA.
    let mut uart_cfg = usart::Config::default();
    uart_cfg.baudrate = 921_600;
    let tx = match UartTx::new(p.USART1, p.PA9, p.DMA1_CH1, Irqs, uart_cfg) {
        Ok(tx) => tx,
        Err(_) => defmt::panic!("usart config"),
    };

    stm32_common::run(SpiLink::new(ring), process_task, move || output_task(tx))
}
