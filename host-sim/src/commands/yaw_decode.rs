//! `host-sim yaw-decode IN --out yaw.csv [--t0-us T]`: a captured yaw output stream (the
//! firmware's 14-byte yaw frames, `docs/wire-formats.md`) to CSV.
//!
//! `host-sim yaw-decode --serial PORT [--baud 921600] [--out yaw.csv] [--frames N]
//! [--seconds S]`: the same, live, from a serial port (a USB-UART on the flight controller's
//! yaw output): the port is put in raw mode at the given baud rate (8N1, no flow control) and
//! each frame is printed as it arrives (to stdout, or appended to `--out`), until N frames or S
//! seconds (default: until interrupted).
//!
//! Columns `t_s,yaw_rate_rad_s,flags` (with `--normalized`: `t_s,yaw_norm`, divided by the
//! peak), formatted like `host-sim run` so that the two can be compared line by line: `t_s` = `T + t` on the recording's clock (the frames' `u32` µs
//! unwrapped across wraps, plus `--t0-us`), yaw rate = the I16F16 value in rad/s. Corrupted
//! bytes are skipped (the decoder resynchronises at the next intact frame); the counts go to
//! stderr.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use core_nostd::aer::yaw::{YawDecoder, YawFrame, YawStats};
use core_nostd::time::EventTime;

use crate::output::write_atomically;
use crate::samples::Samples;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Captured yaw stream (binary).
    #[arg(required_unless_present = "serial", conflicts_with = "serial")]
    pub input: Option<PathBuf>,
    /// Output CSV (needed for a capture; with `--serial` the default is stdout).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Time origin in µs added to the frames' times (the recording's first event; printed by
    /// `cargo xtask qemu`).
    #[arg(long, default_value_t = 0)]
    pub t0_us: u64,
    /// Serial port to read live (e.g. /dev/ttyUSB0).
    #[arg(long)]
    pub serial: Option<PathBuf>,
    /// Baud rate of the serial port (the firmware sends at 921 600).
    #[arg(long, default_value_t = 921_600, requires = "serial")]
    pub baud: u32,
    /// Stop after this many intact frames (serial only).
    #[arg(long, requires = "serial")]
    pub frames: Option<u64>,
    /// Stop after this many seconds (serial only).
    #[arg(long, requires = "serial")]
    pub seconds: Option<f64>,
    /// The stream is the paper's normalized readout: write `t_s,yaw_norm`, divided by the
    /// peak |value| over the capture, as `host-sim run --readout normalized` does.
    #[arg(long, conflicts_with = "serial")]
    pub normalized: bool,
}

/// Unwraps the frames' `u32` µs times to `u64` (a step back of 2^31 µs or more counts as a
/// wrap forward).
#[derive(Clone, Copy, Debug, Default)]
struct Unwrap {
    last: Option<(u32, u64)>,
}

impl Unwrap {
    fn next(&mut self, t_us: u32) -> u64 {
        let t = match self.last {
            None => u64::from(t_us),
            Some((prev, e)) => match EventTime::from_us(t_us).since(EventTime::from_us(prev)) {
                Some(d) => e + u64::from(d),
                None => e.saturating_sub(u64::from(prev.wrapping_sub(t_us))),
            },
        };
        self.last = Some((t_us, t));
        t
    }
}

/// Decodes a yaw stream; frame times are unwrapped to `u64` µs (see `Unwrap`).
pub fn decode(bytes: &[u8]) -> (Vec<(u64, YawFrame)>, YawStats) {
    let mut dec = YawDecoder::new();
    let mut frames = Vec::new();
    dec.push(bytes, |f| frames.push(f));
    dec.finish(|f| frames.push(f));
    let mut unwrap = Unwrap::default();
    let out = frames
        .into_iter()
        .map(|f| (unwrap.next(f.t_us), f))
        .collect();
    (out, dec.stats())
}

/// One CSV line (without the newline).
fn csv_line(t0_us: u64, t: u64, f: &YawFrame) -> String {
    let t_s = (t0_us + t) as f64 * 1e-6;
    let v = f64::from(f.yaw_rate.to_bits()) / 65536.0;
    format!("{t_s:.6},{v:.6},{}", f.flags)
}

/// Writes the CSV (see the module docs).
///
/// # Errors
/// When the file cannot be written.
pub fn write_csv(frames: &[(u64, YawFrame)], t0_us: u64, path: &Path) -> Result<()> {
    write_atomically(path, |w| {
        writeln!(w, "t_s,yaw_rate_rad_s,flags")?;
        for (t, f) in frames {
            writeln!(w, "{}", csv_line(t0_us, *t, f))?;
        }
        Ok(())
    })
}

/// Writes the CSV of a normalized readout's stream (`t_s,yaw_norm`), through the same
/// normalisation as `host-sim run`.
///
/// # Errors
/// When the file cannot be written.
pub fn write_normalized_csv(frames: &[(u64, YawFrame)], t0_us: u64, path: &Path) -> Result<()> {
    let mut samples = Samples::to_csv(path, true, false)?;
    let rows: Vec<(f64, f64, u8)> = frames
        .iter()
        .map(|(t, f)| {
            let t_s = (t0_us + t) as f64 * 1e-6;
            (t_s, f64::from(f.yaw_rate.to_bits()) / 65536.0, f.flags)
        })
        .collect();
    samples.extend(&rows)?;
    if let Some(csv) = samples.finish(true)?.csv {
        csv.commit()?;
    }
    Ok(())
}

pub fn run(args: Args) -> Result<()> {
    if let Some(port) = &args.serial {
        return run_serial(&args, port);
    }
    let (Some(input), Some(out)) = (&args.input, &args.out) else {
        bail!("yaw-decode: a capture needs INPUT and --out (or use --serial PORT)");
    };
    let bytes = std::fs::read(input).with_context(|| format!("cannot read {}", input.display()))?;
    let (frames, st) = decode(&bytes);
    if args.normalized {
        write_normalized_csv(&frames, args.t0_us, out)?;
    } else {
        write_csv(&frames, args.t0_us, out)?;
    }
    eprintln!(
        "{} yaw frames ({} bad, {} missing, {} bytes skipped) -> {}",
        st.ok,
        st.bad,
        st.dropped,
        st.skipped_bytes,
        out.display()
    );
    Ok(())
}

fn run_serial(args: &Args, port: &Path) -> Result<()> {
    let limit = Limit {
        frames: args.frames,
        time: args.seconds.map(Duration::from_secs_f64),
    };
    let st = match &args.out {
        Some(path) => {
            let f = std::fs::File::create(path)
                .with_context(|| format!("cannot create {}", path.display()))?;
            let mut w = std::io::LineWriter::new(f);
            stream_serial(port, args.baud, limit, args.t0_us, &mut w)?
        }
        None => {
            let stdout = std::io::stdout();
            let mut w = stdout.lock();
            stream_serial(port, args.baud, limit, args.t0_us, &mut w)?
        }
    };
    eprintln!(
        "{} yaw frames ({} bad, {} missing, {} bytes skipped) from {}",
        st.ok,
        st.bad,
        st.dropped,
        st.skipped_bytes,
        port.display()
    );
    Ok(())
}

/// When a live decode stops.
#[derive(Clone, Copy, Debug, Default)]
pub struct Limit {
    /// After this many intact frames.
    pub frames: Option<u64>,
    /// After this long.
    pub time: Option<Duration>,
}

/// Opens `port` as a serial port: raw mode (no echo, no line editing, no CR/LF or flow-control
/// translation: every byte as it came), 8 data bits, no parity, one stop bit, receiver on,
/// modem lines ignored, `baud` bits/s; reads return after 100 ms without data.
fn open_serial(port: &Path, baud: u32) -> Result<std::fs::File> {
    use rustix::termios::{self, ControlModes, OptionalActions, SpecialCodeIndex};
    use std::os::unix::fs::OpenOptionsExt;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(rustix::fs::OFlags::NOCTTY.bits() as i32)
        .open(port)
        .with_context(|| format!("cannot open {}", port.display()))?;
    let mut t = termios::tcgetattr(&file)
        .with_context(|| format!("{} is not a serial port (tcgetattr)", port.display()))?;
    t.make_raw();
    t.control_modes |= ControlModes::CREAD | ControlModes::CLOCAL;
    t.control_modes &= !(ControlModes::CSTOPB | ControlModes::PARENB);
    t.set_speed(baud)
        .with_context(|| format!("{}: baud rate {baud} not supported", port.display()))?;
    t.special_codes[SpecialCodeIndex::VMIN] = 0;
    t.special_codes[SpecialCodeIndex::VTIME] = 1;
    termios::tcsetattr(&file, OptionalActions::Now, &t)
        .with_context(|| format!("cannot configure {}", port.display()))?;
    Ok(file)
}

/// Reads yaw frames from a serial port and writes one CSV line per intact frame (with the
/// header first) until `limit`; returns the decoder's counters.
///
/// # Errors
/// When the port cannot be opened, configured or read, or `out` cannot be written.
pub fn stream_serial(
    port: &Path,
    baud: u32,
    limit: Limit,
    t0_us: u64,
    out: &mut dyn Write,
) -> Result<YawStats> {
    let mut file = open_serial(port, baud)?;
    writeln!(out, "t_s,yaw_rate_rad_s,flags")?;
    out.flush()?;
    let start = Instant::now();
    let mut dec = YawDecoder::new();
    let mut unwrap = Unwrap::default();
    let mut buf = [0u8; 4096];
    let mut err = None;
    loop {
        if limit.frames.is_some_and(|n| dec.stats().ok >= n)
            || limit.time.is_some_and(|d| start.elapsed() >= d)
        {
            break;
        }
        let n = match file.read(&mut buf) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e).with_context(|| format!("cannot read {}", port.display())),
        };
        let chunk = buf.get(..n).unwrap_or_default();
        dec.push(chunk, |f| {
            if err.is_none() {
                let line = csv_line(t0_us, unwrap.next(f.t_us), &f);
                if let Err(e) = writeln!(out, "{line}") {
                    err = Some(e);
                }
            }
        });
        if let Some(e) = err.take() {
            return Err(e).context("cannot write the CSV");
        }
        out.flush()?;
    }
    Ok(dec.stats())
}

#[cfg(test)]
mod tests {
    use super::*;
    use core_nostd::fixed::types::I16F16;

    #[test]
    fn unwraps_times_and_skips_garbage() {
        let mut bytes = vec![0x59, 0xC3, 1, 2, 3];
        let ts = [u32::MAX - 1500, u32::MAX - 500, 499, 1499];
        for (i, &t) in ts.iter().enumerate() {
            let f = YawFrame {
                seq: i as u8,
                flags: 0,
                t_us: t,
                yaw_rate: I16F16::from_num(-0.5),
            };
            bytes.extend_from_slice(&f.encode());
        }
        let (frames, st) = decode(&bytes);
        assert_eq!(st.ok, 4);
        let t: Vec<u64> = frames.iter().map(|f| f.0).collect();
        let base = u64::from(u32::MAX - 1500);
        assert_eq!(t, vec![base, base + 1000, base + 2000, base + 3000]);
    }

    /// Frames whose bytes a terminal in its default (cooked) mode would change or swallow:
    /// CR (turned into LF), LF, ^C, ^D, ^Q/^S (flow control), ^Z, ^\\, DEL.
    fn awkward_frames() -> Vec<YawFrame> {
        let awkward = [
            0x0D, 0x0A, 0x03, 0x04, 0x11, 0x13, 0x1A, 0x1C, 0x7F, 0x15, 0x17,
        ];
        (0..40u32)
            .map(|i| {
                let b = |k: u32| awkward[((i + k) % awkward.len() as u32) as usize];
                YawFrame {
                    seq: b(0),
                    flags: b(1) & 0x3F,
                    t_us: u32::from_le_bytes([b(2), b(3), b(4), 0]) + i * 1000,
                    yaw_rate: I16F16::from_bits(i32::from_le_bytes([b(5), b(6), b(7), 0])),
                }
            })
            .collect()
    }

    #[test]
    fn serial_port_in_raw_mode() {
        use rustix::pty::{grantpt, openpt, ptsname, unlockpt, OpenptFlags};
        use rustix::termios::{tcgetattr, LocalModes};
        use std::io::Write;

        let master = openpt(OpenptFlags::RDWR | OpenptFlags::NOCTTY).unwrap();
        grantpt(&master).unwrap();
        unlockpt(&master).unwrap();
        let name = ptsname(&master, Vec::new()).unwrap();
        let path = PathBuf::from(name.to_str().unwrap());
        // A second handle on the port, to see when the decoder has configured it.
        let watch = std::fs::File::open(&path).unwrap();
        assert!(tcgetattr(&watch)
            .unwrap()
            .local_modes
            .contains(LocalModes::ICANON));
        let frames = awkward_frames();
        let n = frames.len() as u64;
        let reader = {
            let path = path.clone();
            std::thread::spawn(move || {
                let mut out = Vec::new();
                let limit = Limit {
                    frames: Some(n),
                    time: Some(Duration::from_secs(20)),
                };
                let st = stream_serial(&path, 921_600, limit, 0, &mut out).unwrap();
                (st, String::from_utf8(out).unwrap())
            })
        };
        let t0 = Instant::now();
        while tcgetattr(&watch)
            .unwrap()
            .local_modes
            .contains(LocalModes::ICANON)
        {
            assert!(
                t0.elapsed() < Duration::from_secs(10),
                "port never configured"
            );
            std::thread::sleep(Duration::from_millis(5));
        }
        let mut wire = vec![0x59, 0x0D, 0xC3];
        for f in &frames {
            wire.extend_from_slice(&f.encode());
        }
        let mut m = std::fs::File::from(master);
        for chunk in wire.chunks(7) {
            m.write_all(chunk).unwrap();
        }
        let (st, csv) = reader.join().unwrap();
        assert_eq!(st.ok, n, "{st:?}");
        assert_eq!(st.bad, 0);
        let mut want = String::from("t_s,yaw_rate_rad_s,flags\n");
        let mut unwrap = Unwrap::default();
        for f in &frames {
            want.push_str(&csv_line(0, unwrap.next(f.t_us), f));
            want.push('\n');
        }
        assert_eq!(csv, want);
    }
}
