//! What the two STM32 boards share: the executors (the input task on an interrupt executor
//! driven by the otherwise unused UART4 interrupt), the yaw frame queue to the UART task, the
//! DWT cycle meter, the input and status tasks, and the camera they assume until a
//! configuration frame says otherwise.

use core_nostd::aer::yaw::FRAME_BYTES;
use core_nostd::fixed::types::U16F16;
use core_nostd::settings::{LayoutChoice, Settings};
use cortex_m::peripheral::DWT;
use embassy_executor::{Executor, InterruptExecutor, SpawnError, SpawnToken};
use embassy_stm32::interrupt::{self, InterruptExt, Priority};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_time::Timer;
use static_cell::StaticCell;

use super::stm32_link::SpiLink;
use crate::app::{self, CostMeter, FrameReceiver, FrameSender, Overload, YawSink};

/// Sensor the STM32 boards assume: DAVIS346, 346 x 260 px.
const SENSOR: (u16, u16) = (346, 260);

/// What a board runs until the AER stream sends a configuration frame
/// (`docs/wire-formats.md`): a DAVIS346 (f = 226 px, principal point at the sensor's centre),
/// stride 2, 1 kHz, on the widest dense layout `max_cells` cells hold: all 346 columns by as
/// many rows as fit, centred on the principal row (full width gives the readout every column
/// band; measured best on the F405, see `firmware/README.md`).
pub const fn davis346_full_width(max_cells: usize) -> Settings {
    let rows = (max_cells / SENSOR.0 as usize) as u16;
    let rows = if rows > SENSOR.1 { SENSOR.1 } else { rows };
    Settings {
        layout: LayoutChoice::Window {
            x0: 0,
            y0: (SENSOR.1 - rows) / 2,
            w: SENSOR.0,
            h: rows,
        },
        ..Settings::for_sensor(SENSOR.0, SENSOR.1, U16F16::const_from_int(226))
    }
}

/// Yaw frames waiting for the USART.
pub static YAW_OUT: Channel<CriticalSectionRawMutex, [u8; FRAME_BYTES], 64> = Channel::new();

pub static EXECUTOR_HIGH: InterruptExecutor = InterruptExecutor::new();
pub static EXECUTOR_LOW: StaticCell<Executor> = StaticCell::new();

#[embassy_stm32::interrupt]
unsafe fn UART4() {
    // SAFETY: UART4 is unused as a peripheral; its interrupt only runs this executor.
    unsafe { EXECUTOR_HIGH.on_interrupt() }
}

/// Yaw frames into [`YAW_OUT`] (dropped and counted when full).
pub struct UartSink;

impl YawSink for UartSink {
    fn write(&mut self, frame: &[u8; FRAME_BYTES]) -> bool {
        YAW_OUT.try_send(*frame).is_ok()
    }
}

/// Cycles of the DWT cycle counter.
pub struct CycleMeter;

impl CostMeter for CycleMeter {
    const UNIT: &'static str = "cycles";

    fn units_per_tick() -> u32 {
        1
    }

    fn now() -> u32 {
        DWT::cycle_count()
    }
}

#[embassy_executor::task]
pub async fn input_task(mut source: SpiLink, mut queue: FrameSender) {
    app::input::run::<_, CycleMeter>(&mut source, &mut queue, Overload::DropFrames).await;
}

/// Logs the counters once a second.
#[embassy_executor::task]
pub async fn status_task() {
    loop {
        Timer::after_secs(1).await;
        let s = app::stats();
        let per_event = s.cost_units / u64::from(s.events.max(1));
        defmt::info!("{} ({}/event: {})", s, CycleMeter::UNIT, per_event);
    }
}

/// Runs the board: the input task on the interrupt executor (UART4 at priority P6, so it
/// preempts processing), and the board's processing and output tasks and the status task on
/// the thread executor. `process` and `output` make the board's task tokens; `process` gets
/// the frame queue's receiving end.
pub fn run<P, O>(
    link: SpiLink,
    process: impl FnOnce(FrameReceiver) -> Result<SpawnToken<P>, SpawnError>,
    output: impl FnOnce() -> Result<SpawnToken<O>, SpawnError>,
) -> ! {
    interrupt::UART4.set_priority(Priority::P6);
    let high = EXECUTOR_HIGH.start(interrupt::UART4);
    let Some((tx, rx)) = app::frame_queue() else {
        defmt::panic!("frame queue taken")
    };
    match input_task(link, tx) {
        Ok(t) => high.spawn(t),
        Err(_) => defmt::panic!("spawn input"),
    }
    let executor = EXECUTOR_LOW.init(Executor::new());
    executor.run(|spawner| {
        match process(rx) {
            Ok(t) => spawner.spawn(t),
            Err(_) => defmt::panic!("spawn process"),
        }
        match output() {
            Ok(t) => spawner.spawn(t),
            Err(_) => defmt::panic!("spawn output"),
        }
        match status_task() {
            Ok(t) => spawner.spawn(t),
            Err(_) => defmt::panic!("spawn status"),
        }
    })
}

/// Sends the yaw frames of [`YAW_OUT`] on `tx`, as many per DMA transfer as `buf` holds.
pub async fn send_yaw_frames(
    tx: &mut embassy_stm32::usart::UartTx<'static, embassy_stm32::mode::Async>,
    buf: &mut [u8],
) -> ! {
    loop {
        let first = YAW_OUT.receive().await;
        let mut n = 0;
        for (dst, src) in buf
            .chunks_exact_mut(FRAME_BYTES)
            .zip(core::iter::once(first).chain(core::iter::from_fn(|| YAW_OUT.try_receive().ok())))
        {
            dst.copy_from_slice(&src);
            n += FRAME_BYTES;
        }
        if tx.write(buf.get(..n).unwrap_or_default()).await.is_err() {
            defmt::warn!("usart write failed");
        }
    }
}
