//! The QEMU board: `qemu-system-arm -M mps2-an386` (Cortex-M4F, 25 MHz), no HAL.
//!
//! - Events in: the AER stream from an emulated `n25q128` SPI NOR flash on the PL022
//!   (`--input spi`, the default: the same byte path as a real SPI link, ~7 MB/s), or from a
//!   host file through semihosting (`--input file`, ~400 MB/s, for streams over 16 MiB).
//! - Yaw frames out: `yaw.bin` through semihosting; logs: defmt over semihosting (stdout);
//!   counters: `summary.txt`; exit code through semihosting (0 = ran to the end).
//! - Time: SysTick (see [`time`]); the executor idles in WFI (see [`executor`]).
//! - Replay (default): the input waits for the processing (deterministic, bit-exact with the
//!   host). `--live`: frames are dropped whole when processing falls behind and the clock
//!   drives stale output, as on the flight controller. `--paced`: frames become readable at
//!   the times in `schedule.bin` (see [`paced`]), so a live run sees the recording's event
//!   rate, bursts included, instead of a flood.
//!
//! Arguments (semihosting command line): `--settings HEX` (required: the run's settings as
//! the hex of their configuration payload, `docs/wire-formats.md`, which `host-sim aer-stream`
//! prints for the flags of `host-sim run`: the board decodes them with the code that reads a
//! configuration frame), `--input spi|file`, `--bytes N` (stream length in the flash),
//! `--live`, `--paced`, `--link-bps B` (link rate of a paced run, bytes/s; 0 = unlimited),
//! `--icount-shift N` (0..=3, the `-icount shift` QEMU runs with: 2^N ns per instruction;
//! sets the instruction counter's scale).

pub mod executor;
pub mod host;
pub mod paced;
pub mod pl022;
pub mod time;

use core::fmt::Write as _;
use core::mem::MaybeUninit;

use core_nostd::settings::Settings;
use core_nostd::unit::Kernel;
use defmt_semihosting as _;
use static_cell::StaticCell;

use crate::app::arena::{Arena, Region};
use crate::app::configured::{self, Exit, Memory};
use crate::app::processing::Clock;
use crate::app::{self, ByteSource, CostMeter, FrameReceiver, FrameSender, Overload, SourceError};
use time::SysTickMeter;

/// The network's cells: 3.5 MiB of the 4 MiB SRAM (the rest: the program's statics, ~75 KiB,
/// and the stack). Not zeroed at start (`.uninit`): each configuration initialises its slices.
const CELL_BYTES: usize = 3584 * 1024;
/// The units' state (pairs or a unit pool, the active bitset, the spike readout's cells): all
/// 16 MiB of the PSRAM; the cells too when they do not fit the SRAM.
const UNIT_BYTES: usize = 16 * 1024 * 1024;

#[link_section = ".uninit.CELLS"]
static mut CELLS: MaybeUninit<Region<CELL_BYTES>> = MaybeUninit::uninit();
#[link_section = ".psram"]
static mut UNITS: MaybeUninit<Region<UNIT_BYTES>> = MaybeUninit::uninit();

/// The default TDE parameters (tables computed at compile time).
static KERNEL: Kernel = Kernel::DEFAULT;

/// Exit codes.
mod exit {
    /// Ran to the end of the stream.
    pub const OK: i32 = 0;
    /// Bad command line or layout.
    pub const CONFIG: i32 = 2;
    /// The input could not be opened.
    pub const INPUT: i32 = 3;
    /// A panic (see the defmt log).
    pub const PANIC: i32 = 101;
}

/// Run configuration from the command line.
#[derive(Clone, Copy, Debug)]
struct Config {
    spi: bool,
    bytes: u32,
    /// What the pipeline runs (a configuration frame in the stream can change it).
    settings: Settings,
    live: bool,
    paced: bool,
    /// Link rate of a paced run, bytes per second (0 = unlimited).
    link_bps: u32,
    icount_shift: u8,
}

impl Config {
    fn parse() -> Result<Self, &'static str> {
        let (mut spi, mut bytes, mut live, mut paced, mut link_bps, mut icount_shift) =
            (true, 0, false, false, 0, 0);
        let mut settings = None;
        let mut key: Option<heapless::String<16>> = None;
        let mut err = None;
        host::for_each_arg(|a| {
            let Some(k) = key.take() else {
                match a {
                    "--live" => live = true,
                    "--paced" => paced = true,
                    _ => key = heapless::String::try_from(a).ok(),
                }
                return;
            };
            let num = |s: &str| s.parse::<u32>().ok();
            let ok = match k.as_str() {
                "--input" => {
                    spi = a == "spi";
                    a == "spi" || a == "file"
                }
                "--bytes" => num(a).map(|v| bytes = v).is_some(),
                "--settings" => {
                    settings = Settings::parse_hex(a).ok();
                    settings.is_some()
                }
                "--link-bps" => num(a).map(|v| link_bps = v).is_some(),
                "--icount-shift" => num(a)
                    .filter(|v| *v <= time::MAX_ICOUNT_SHIFT)
                    .map(|v| icount_shift = v as u8)
                    .is_some(),
                _ => false,
            };
            if !ok {
                err = Some("bad argument");
            }
        });
        if let Some(e) = err {
            return Err(e);
        }
        let Some(settings) = settings else {
            return Err("--settings is required");
        };
        Ok(Config {
            spi,
            bytes,
            settings,
            live,
            paced,
            link_bps,
            icount_shift,
        })
    }
}

/// The two ways the stream comes in.
enum Source {
    Spi(pl022::SpiFlash),
    File(host::HostFile),
}

impl ByteSource for Source {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, SourceError> {
        match self {
            Source::Spi(s) => s.read(buf).await,
            Source::File(f) => f.read(buf).await,
        }
    }
}

fn quit(code: i32) -> ! {
    semihosting::process::exit(code)
}

#[embassy_executor::task]
async fn input_task(
    source: &'static mut paced::Paced<Source>,
    mut queue: FrameSender,
    mode: Overload,
) {
    app::input::run::<_, SysTickMeter>(source, &mut queue, mode).await;
}

fn config_error(msg: &str) -> ! {
    defmt::error!("{}", msg);
    quit(exit::CONFIG)
}

#[embassy_executor::task]
async fn main_task(cfg: Config, mut queue: FrameReceiver) {
    // SAFETY: CELLS and UNITS are used by these arenas only, for the rest of the program.
    let mut memory = unsafe {
        Memory {
            cells: Arena::over(core::ptr::addr_of_mut!(CELLS)),
            units: Some(Arena::over(core::ptr::addr_of_mut!(UNITS))),
        }
    };
    let mut sink = host::YawFile::create();
    let clock = if cfg.live {
        Clock::Live
    } else {
        Clock::EventTimeOnly
    };
    let mut stream = cfg.settings;
    let mut seq = 0u8;
    loop {
        let run = configured::run::<_, SysTickMeter>(
            &mut queue,
            &KERNEL,
            &stream,
            &mut memory,
            &mut sink,
            clock,
            &mut seq,
        );
        match run.await {
            Ok(Exit::End) => break,
            Ok(Exit::Reconfigure(next)) => stream = next,
            Err(e) => {
                defmt::error!("cannot run the configuration: {}", e);
                config_error(
                    "bad layout (window outside the sensor), or more state than the SRAM and PSRAM hold",
                )
            }
        }
    }
    let needed = stream.storage().map_or(0, |n| n.cells);
    sink.flush();
    let s = app::stats();
    let per_event = if s.events == 0 {
        0
    } else {
        (s.cost_units + u64::from(s.events) / 2) / u64::from(s.events)
    };
    let per_byte_x100 = (s.input_cost_units * 100)
        .checked_div(u64::from(s.bytes))
        .unwrap_or(0);
    let overhead_x100 = s.meter_overhead_x1024 * 100 / 1024;
    let mut line: heapless::String<680> = heapless::String::new();
    let _ = write!(
        line,
        "events={} frames_ok={} frames_bad={} frames_dropped={} instructions_per_event={}\n\
         detail: bytes={} frames_received={} frames_gap={} frames_overflow={} source_overflows={} \
         skipped_bytes={} bit_slips={} configs_applied={} configs_refused={} source_errors={} \
         decoder_errors={} yaw_frames={} \
         yaw_dropped={} yaw_write_errors={} cells={} {}={} meter_overhead={}.{:02} \
         input_{}_per_byte={}.{:02} \
         mcu_time_us={} spikes={} pool_pairs={} pool_peak={} pool_full={}\n",
        s.events,
        s.frames_processed,
        s.frames_bad,
        s.frames_gap + s.frames_overflow,
        per_event,
        s.bytes,
        s.frames_rx,
        s.frames_gap,
        s.frames_overflow,
        s.source_overflows,
        s.skipped_bytes,
        s.bit_slips,
        s.configs_applied,
        s.configs_refused,
        s.source_errors,
        s.decoder_errors,
        s.yaw_out,
        s.yaw_dropped,
        sink.errors,
        needed,
        SysTickMeter::UNIT,
        s.cost_units,
        overhead_x100 / 100,
        overhead_x100 % 100,
        SysTickMeter::UNIT,
        per_byte_x100 / 100,
        per_byte_x100 % 100,
        embassy_time::Instant::now().as_micros(),
        s.spikes,
        s.pool_capacity,
        s.pool_peak,
        s.pool_full,
    );
    defmt::info!("{}", line.as_str());
    if !host::write_summary(&line) || sink.errors > 0 {
        defmt::error!("cannot write the output files");
        quit(exit::INPUT);
    }
    quit(exit::OK)
}

/// Entry point of the QEMU board.
pub fn main() -> ! {
    let Some(cp) = cortex_m::Peripherals::take() else {
        quit(exit::PANIC)
    };
    let cfg = match Config::parse() {
        Ok(c) => c,
        Err(e) => {
            defmt::error!("{}", e);
            quit(exit::CONFIG)
        }
    };
    defmt::info!(
        "qemu board: {} x {} px, spi={}, live={}, paced={}",
        cfg.settings.width,
        cfg.settings.height,
        cfg.spi,
        cfg.live,
        cfg.paced
    );
    time::init(cp.SYST, cfg.icount_shift);
    static SOURCE: StaticCell<paced::Paced<Source>> = StaticCell::new();
    let source = if cfg.spi {
        Source::Spi(pl022::SpiFlash::start(cfg.bytes))
    } else {
        match host::HostFile::open() {
            Some(f) => Source::File(f),
            None => {
                defmt::error!("cannot open events.aer");
                quit(exit::INPUT)
            }
        }
    };
    let schedule = if cfg.paced {
        match paced::Schedule::open() {
            Some(s) => Some(s),
            None => {
                defmt::error!("--paced: cannot open schedule.bin");
                quit(exit::INPUT)
            }
        }
    } else {
        None
    };
    let source = SOURCE.init(paced::Paced::new(source, schedule, u64::from(cfg.link_bps)));
    let mode = if cfg.live {
        Overload::DropFrames
    } else {
        Overload::Backpressure
    };
    let Some((tx, rx)) = app::frame_queue() else {
        quit(exit::PANIC)
    };
    executor::run(|spawner| {
        match input_task(source, tx, mode) {
            Ok(t) => spawner.spawn(t),
            Err(_) => quit(exit::PANIC),
        }
        match main_task(cfg, rx) {
            Ok(t) => spawner.spawn(t),
            Err(_) => quit(exit::PANIC),
        }
    })
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    defmt::error!("panic: {}", defmt::Display2Format(info));
    quit(exit::PANIC)
}
