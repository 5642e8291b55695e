//! Writes a large EVT 3.0 recording for the constant-memory benchmark of `host-sim run`: the
//! events of INPUT (any format `host-sim` reads), repeated back to back, each copy shifted by
//! the input's duration plus 1 ms, until the output holds at least SIZE_GB gigabytes (10^9
//! bytes). Memory: the input's events (16 bytes each) and one write buffer, whatever the size.
//!
//! ```sh
//! cargo run --release -p host-sim --example tile_evt3 -- \
//!     ../shared/data/synthetic/dev03_davis346_urban_car/events.raw /tmp/big.raw 10
//! ```
//!
//! The sensor size is the input's (header or `meta.json`); prints the events written.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use host_sim::formats::raw::Evt3Writer;
use host_sim::formats::{self, Event64};

/// Counts the bytes that pass through.
struct Counting<W> {
    w: W,
    bytes: u64,
}

impl<W: Write> Write for Counting<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.w.write(buf)?;
        self.bytes += n as u64;
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.w.flush()
    }
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [input, out, gb] = args.as_slice() else {
        bail!("usage: tile_evt3 INPUT OUT.raw SIZE_GB");
    };
    let target: f64 = gb.parse().context("SIZE_GB must be a number")?;
    let target = (target * 1e9) as u64;
    let rec = formats::read(input, None)?;
    let (Some(first), Some(last)) = (rec.events.first(), rec.events.last()) else {
        bail!("{input}: no events");
    };
    let (w, h) = rec
        .size_or_extent()
        .context("cannot tell the sensor size")?;
    let period = last.t_us - first.t_us + 1000;
    let out = PathBuf::from(out);
    let file =
        std::fs::File::create(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut sink = Counting {
        w: std::io::BufWriter::with_capacity(1 << 20, file),
        bytes: 0,
    };
    let mut n = 0u64;
    {
        let mut writer = Evt3Writer::new(&mut sink, &out, w, h);
        let mut shifted: Vec<Event64> = Vec::with_capacity(rec.events.len());
        let mut k = 0u64;
        loop {
            shifted.clear();
            shifted.extend(rec.events.iter().map(|e| Event64 {
                t_us: e.t_us + k * period,
                ..*e
            }));
            writer.push(&shifted)?;
            n += shifted.len() as u64;
            k += 1;
            // `writer` holds `sink` mutably; its byte count is read through the file length.
            if std::fs::metadata(&out).map(|m| m.len()).unwrap_or(0) >= target {
                break;
            }
        }
        writer.finish()?;
    }
    sink.flush()?;
    println!(
        "{n} events, {} bytes, {:.1} s of recording, {w}x{h}: {}",
        sink.bytes,
        n as f64 / rec.events.len() as f64 * period as f64 * 1e-6,
        out.display()
    );
    Ok(())
}
