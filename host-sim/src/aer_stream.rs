//! The AER-over-SPI byte stream on the host (format: `docs/wire-formats.md`,
//! `core_nostd::aer`): writing it from a recording, reading it back, and the hidden
//! `host-sim aer-stream` command that `cargo xtask qemu` uses to feed the emulated firmware.
//!
//! Event times on the wire are `u32` µs relative to the recording's first event (wrapping), the
//! clock `host-sim run` gives its pipeline; the first event's absolute time (`t0_us`) is
//! returned so that outputs can be put back on the recording's clock.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use core_nostd::aer::events::{EventEncoder, Receiver};
use core_nostd::aer::frame::{FrameStats, SYNC};
use core_nostd::event::Event;
use core_nostd::fixed::types::U16F16;

use crate::formats::{self, Format};

/// When the sender can put one frame on the link: the frame ends at byte `end_byte` of the
/// stream (exclusive), and its last event happened `t_us` µs after the stream's first event.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Arrival {
    /// Stream offset just past the frame, bytes.
    pub end_byte: u64,
    /// Time of the frame's last event, µs from the stream's first event (not wrapped).
    pub t_us: u64,
}

impl Arrival {
    /// Bytes of one schedule entry on disk: `end_byte` then `t_us`, both u64 little-endian.
    pub const BYTES: usize = 16;

    /// The entry as written in the schedule file.
    pub fn to_bytes(self) -> [u8; Self::BYTES] {
        let mut b = [0u8; Self::BYTES];
        let (end, t) = b.split_at_mut(8);
        end.copy_from_slice(&self.end_byte.to_le_bytes());
        t.copy_from_slice(&self.t_us.to_le_bytes());
        b
    }

    /// An entry read back from the schedule file.
    pub fn from_bytes(b: [u8; Self::BYTES]) -> Self {
        let [e0, e1, e2, e3, e4, e5, e6, e7, t0, t1, t2, t3, t4, t5, t6, t7] = b;
        Self {
            end_byte: u64::from_le_bytes([e0, e1, e2, e3, e4, e5, e6, e7]),
            t_us: u64::from_le_bytes([t0, t1, t2, t3, t4, t5, t6, t7]),
        }
    }
}

/// Decodes an AER stream (any corruption tolerated) into events and the frame counters.
pub fn decode_aer(bytes: &[u8]) -> (Vec<Event>, FrameStats) {
    let mut rx = Receiver::new();
    let mut out = Vec::new();
    rx.push(bytes, |e| out.push(e));
    rx.finish(|e| out.push(e));
    (out, rx.frame_stats())
}

/// Whether `head` (the first bytes of a file) starts with an AER frame's sync pattern.
pub fn looks_like_aer(head: &[u8]) -> bool {
    head.starts_with(&SYNC)
}

/// `host-sim aer-stream`: a recording to the AER stream, plus what the firmware needs to
/// process it like `host-sim run` (hidden; used by `cargo xtask qemu`).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input recording (any format `host-sim convert` reads).
    pub input: PathBuf,
    /// Input format (default: detected from the content).
    #[arg(long, value_enum)]
    pub format: Option<Format>,
    /// Output AER stream.
    #[arg(long)]
    pub out: PathBuf,
    /// Focal length in px (default: from the recording).
    #[arg(long)]
    pub focal_px: Option<f64>,
    /// Principal point column in px (default: from the recording, else the sensor centre).
    #[arg(long)]
    pub cx: Option<f64>,
    /// Principal point row in px (default: from the recording, else the sensor centre).
    #[arg(long)]
    pub cy: Option<f64>,
    /// Sensor width in px (default: from the recording).
    #[arg(long, requires = "height")]
    pub width: Option<u16>,
    /// Sensor height in px (default: from the recording).
    #[arg(long, requires = "width")]
    pub height: Option<u16>,
    /// Also write the arrival schedule (when each frame can be sent, for a paced replay;
    /// format in `docs/wire-formats.md`).
    #[arg(long)]
    pub schedule: Option<PathBuf>,
    /// Send a configuration frame first (sensor size, intrinsics, this layout, stride and
    /// output period; `docs/wire-formats.md`), so that the firmware runs what this stream needs
    /// whatever it was built or started with: `dense`, `paper-boxes` or a dense window
    /// `X0:Y0:W:H`. Needs the focal length; not with `--schedule`.
    #[arg(long, value_name = "LAYOUT", conflicts_with = "schedule")]
    pub config: Option<String>,
    /// Stride (px) of the configuration frame.
    #[arg(long, default_value_t = 2, requires = "config")]
    pub config_stride: u16,
    /// Output period (µs) of the configuration frame.
    #[arg(long, default_value_t = 1000, requires = "config")]
    pub config_period_us: u32,
}

/// The configuration frame `--config` asks for (the principal point row is the sensor's
/// centre: the firmware's readout does not use it).
fn config_frame(
    args: &Args,
    layout: &str,
    w: u16,
    h: u16,
    focal: Option<f64>,
    (cx, cy): (f64, f64),
) -> Result<Vec<u8>> {
    use core_nostd::aer::config::{LayoutChoice, StreamConfig};
    let Some(focal) = focal else {
        bail!("--config: the focal length is unknown (give --focal-px)");
    };
    let layout = match layout {
        "dense" => LayoutChoice::Dense,
        "paper-boxes" => LayoutChoice::PaperBoxes,
        window => {
            let v: Vec<u16> = window.split(':').filter_map(|p| p.parse().ok()).collect();
            let [x0, y0, w, h] = v[..] else {
                bail!("--config {window}: not dense, paper-boxes or X0:Y0:W:H");
            };
            LayoutChoice::Window { x0, y0, w, h }
        }
    };
    let cfg = StreamConfig {
        width: w,
        height: h,
        focal_px: U16F16::saturating_from_num(focal),
        cx: U16F16::saturating_from_num(cx),
        cy: U16F16::saturating_from_num(cy),
        layout,
        stride: args.config_stride,
        period_us: args.config_period_us,
    };
    if cfg.validate().is_err() {
        bail!("--config: the configuration is out of range ({cfg:?})");
    }
    let mut buf = [0u8; core_nostd::aer::frame::MAX_FRAME];
    let flags = core_nostd::aer::frame::flags::STREAM_START;
    let n = cfg
        .encode(flags, 0, &mut buf)
        .map_err(|e| anyhow::anyhow!("--config: {e:?}"))?;
    Ok(buf[..n].to_vec())
}

/// Writes the stream and prints one line on stdout:
/// `events=N t0_us=T width=W height=H focal_bits=F cx_bits=C cy_bits=D` (intrinsics as U16F16 bits, the
/// values `host-sim run` would use; `focal_bits=0` when the focal length is unknown).
///
/// The events are read and encoded a chunk at a time. The firmware runs one pipeline over the
/// whole stream, so a recording that `host-sim run` would cut into pieces (a gap over
/// [`crate::timeline::RESTART_GAP_US`] or a backward jump over
/// [`crate::timeline::RESTART_BACK_US`]) is refused.
///
/// # Errors
/// When the recording cannot be read, its size is unknown, its clock jumps, or the stream cannot
/// be written.
pub fn run(args: Args) -> Result<()> {
    let mut outputs = vec![("--out", args.out.as_path())];
    if let Some(p) = &args.schedule {
        outputs.push(("--schedule", p.as_path()));
    }
    crate::output::check_distinct(&[&args.input], &outputs)?;
    let (mut reader, camera) = crate::commands::run::open_recording(
        &args.input,
        args.format,
        args.width.zip(args.height),
        args.focal_px,
        (args.cx, args.cy),
        true,
    )?;
    let crate::commands::run::Camera {
        width: w,
        height: h,
        focal,
        cx,
        cy,
    } = camera;
    let mut wire = crate::output::AtomicFile::create(&args.out)?;
    if let Some(layout) = &args.config {
        let frame = config_frame(&args, layout, w, h, focal, (cx, cy))?;
        wire.writer()
            .write_all(&frame)
            .with_context(|| format!("cannot write {}", args.out.display()))?;
    }
    let mut schedule = args
        .schedule
        .as_deref()
        .map(crate::output::AtomicFile::create)
        .transpose()?;
    let (events, t0) = stream_aer(&mut reader, &mut wire, schedule.as_mut())
        .with_context(|| format!("{} -> {}", args.input.display(), args.out.display()))?;
    if events == 0 {
        bail!("{}: the recording has no events", args.input.display());
    }
    wire.commit()?;
    if let Some(s) = schedule {
        s.commit()?;
    }
    let bits = |v: f64| U16F16::saturating_from_num(v).to_bits();
    println!(
        "events={events} t0_us={t0} width={w} height={h} focal_bits={} cx_bits={} cy_bits={}",
        focal.map_or(0, bits),
        bits(cx),
        bits(cy)
    );
    Ok(())
}

/// Encodes the events of `source` into `wire` (and the arrival schedule into `schedule`) as they
/// come; returns the number of events and the time origin.
///
/// # Errors
/// When the recording cannot be read, an event does not fit the format, the recording's clock
/// jumps (see [`run`]), or the output cannot be written.
pub(crate) fn stream_aer(
    source: &mut dyn formats::EventChunks,
    wire: &mut crate::output::AtomicFile,
    mut schedule: Option<&mut crate::output::AtomicFile>,
) -> Result<(u64, u64)> {
    use crate::timeline::{RESTART_BACK_US, RESTART_GAP_US};
    let mut enc = EventEncoder::new();
    let mut chunk = Vec::new();
    let (mut n, mut t0, mut prev, mut prev_rel, mut bytes) = (0u64, 0u64, 0u64, 0u64, 0u64);
    let mut frames: Vec<u8> = Vec::with_capacity(1 << 16);
    let mut arrivals: Vec<u8> = Vec::new();
    let wire_path = wire.path().to_path_buf();
    let werr = || format!("cannot write {}", wire_path.display());
    while source.next_chunk(&mut chunk)? {
        for e in &chunk {
            if n == 0 {
                (t0, prev) = (e.t_us, e.t_us);
            }
            let jump = if e.t_us >= prev {
                e.t_us - prev > RESTART_GAP_US
            } else {
                prev - e.t_us > RESTART_BACK_US
            };
            if jump {
                bail!(
                    "event {n} at t = {} µs jumps from {prev} µs (more than {} min forward or {} ms back): `host-sim run` restarts there, the firmware cannot; cut the recording at the jump",
                    e.t_us,
                    RESTART_GAP_US / 60_000_000,
                    RESTART_BACK_US / 1000
                );
            }
            prev = e.t_us;
            let rel = e.t_us.wrapping_sub(t0);
            let ev = Event {
                t_us: rel as u32,
                x: e.x,
                y: e.y,
                on: e.on,
            };
            // Frames completed by `push(e)` hold the events before `e`.
            enc.push(ev, |f| {
                frames.extend_from_slice(f);
                bytes += f.len() as u64;
                arrivals.extend_from_slice(
                    &Arrival {
                        end_byte: bytes,
                        t_us: prev_rel,
                    }
                    .to_bytes(),
                );
            })
            .map_err(|err| anyhow::anyhow!("event {n}: {err}"))?;
            prev_rel = rel;
            n += 1;
        }
        wire.writer().write_all(&frames).with_context(werr)?;
        frames.clear();
        if let Some(s) = schedule.as_deref_mut() {
            let path = s.path().display().to_string();
            s.writer()
                .write_all(&arrivals)
                .with_context(|| format!("cannot write {path}"))?;
        }
        arrivals.clear();
    }
    enc.flush(|f| {
        frames.extend_from_slice(f);
        bytes += f.len() as u64;
        arrivals.extend_from_slice(
            &Arrival {
                end_byte: bytes,
                t_us: prev_rel,
            }
            .to_bytes(),
        );
    });
    wire.writer().write_all(&frames).with_context(werr)?;
    if let Some(s) = schedule {
        let path = s.path().display().to_string();
        s.writer()
            .write_all(&arrivals)
            .with_context(|| format!("cannot write {path}"))?;
    }
    Ok((n, t0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::{EventsInMemory, HostEvent};
    use crate::output::AtomicFile;

    /// `events` through [`stream_aer`]: the stream, its arrival schedule, the time origin.
    fn stream(events: &[HostEvent]) -> Result<(Vec<u8>, Vec<Arrival>, u64)> {
        let dir = tempfile::tempdir()?;
        let (wire_path, sched_path) = (dir.path().join("s.aer"), dir.path().join("s.sched"));
        let mut wire = AtomicFile::create(&wire_path)?;
        let mut sched = AtomicFile::create(&sched_path)?;
        let (_, t0) = stream_aer(
            &mut EventsInMemory::new(events),
            &mut wire,
            Some(&mut sched),
        )?;
        wire.commit()?;
        sched.commit()?;
        let arrivals = std::fs::read(&sched_path)?
            .chunks_exact(Arrival::BYTES)
            .filter_map(|c| c.try_into().ok().map(Arrival::from_bytes))
            .collect();
        Ok((std::fs::read(&wire_path)?, arrivals, t0))
    }

    #[test]
    fn stream_round_trip_relative_to_first_event() {
        let events: Vec<HostEvent> = (0..5000u64)
            .map(|i| HostEvent {
                t_us: 1_700_000_000_000_000 + i * 37 + (i / 1000) * 5_000_000,
                x: (i * 13 % 346) as u16,
                y: (i * 7 % 260) as u16,
                on: i % 3 == 0,
            })
            .collect();
        let (wire, _, t0) = stream(&events).unwrap();
        assert_eq!(t0, events[0].t_us);
        assert!(looks_like_aer(&wire));
        let (out, st) = decode_aer(&wire);
        assert_eq!(st.bad + st.dropped, 0);
        assert_eq!(out.len(), events.len());
        for (a, b) in out.iter().zip(&events) {
            assert_eq!(u64::from(a.t_us), b.t_us - t0);
            assert_eq!((a.x, a.y, a.on), (b.x, b.y, b.on));
        }
    }

    #[test]
    fn schedule_names_each_frames_end_and_last_event() {
        let events: Vec<HostEvent> = (0..20_000u64)
            .map(|i| HostEvent {
                t_us: 5_000 + i * 3 + (i / 7000) * 40_000,
                x: (i % 300) as u16,
                y: (i % 200) as u16,
                on: i % 2 == 0,
            })
            .collect();
        let (wire, arrivals, _) = stream(&events).unwrap();
        assert_eq!(arrivals.last().unwrap().end_byte, wire.len() as u64);
        // Decoding frame by frame up to each entry's end gives events up to its time, and the
        // entry's time is that of the frame's last event.
        let mut seen = 0usize;
        let mut start = 0usize;
        for a in &arrivals {
            let (evs, st) = decode_aer(&wire[start..a.end_byte as usize]);
            assert_eq!(st.ok, 1, "one whole frame per entry");
            seen += evs.len();
            assert_eq!(u64::from(evs.last().unwrap().t_us), a.t_us);
            assert_eq!(events[seen - 1].t_us - 5_000, a.t_us);
            start = a.end_byte as usize;
        }
        assert_eq!(seen, events.len());
        assert!(arrivals.windows(2).all(|w| w[0].t_us <= w[1].t_us));
    }

    #[test]
    fn coordinates_beyond_2047_are_an_error() {
        let e = HostEvent {
            t_us: 0,
            x: 4000,
            y: 0,
            on: true,
        };
        assert!(stream(&[e]).is_err());
    }
}
