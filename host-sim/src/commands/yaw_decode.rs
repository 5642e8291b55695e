//! `host-sim yaw-decode IN --out yaw.csv [--t0-us T]`: a captured yaw output stream (the
//! firmware's 14-byte yaw frames, `docs/wire-formats.md`) to CSV.
//!
//! Columns `t_s,yaw_rate_rad_s,flags`, formatted like `host-sim run` so that the two can be
//! compared line by line: `t_s` = `T + t` on the recording's clock (the frames' `u32` µs
//! unwrapped across wraps, plus `--t0-us`), yaw rate = the I16F16 value in rad/s. Corrupted
//! bytes are skipped (the decoder resynchronises at the next intact frame); the counts go to
//! stderr.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use core_nostd::aer::yaw::{YawDecoder, YawFrame, YawStats};

use crate::output::write_atomically;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Captured yaw stream (binary).
    pub input: PathBuf,
    /// Output CSV.
    #[arg(long)]
    pub out: PathBuf,
    /// Time origin in µs added to the frames' times (the recording's first event; printed by
    /// `cargo xtask qemu`).
    #[arg(long, default_value_t = 0)]
    pub t0_us: u64,
}

/// Decodes a yaw stream; frame times are unwrapped to `u64` µs (a step back of 2^31 µs or
/// more counts as a wrap forward).
pub fn decode(bytes: &[u8]) -> (Vec<(u64, YawFrame)>, YawStats) {
    let mut dec = YawDecoder::new();
    let mut frames = Vec::new();
    dec.push(bytes, |f| frames.push(f));
    dec.finish(|f| frames.push(f));
    let mut out = Vec::with_capacity(frames.len());
    let mut ext: Option<(u32, u64)> = None;
    for f in frames {
        let t = match ext {
            None => u64::from(f.t_us),
            Some((prev, e)) => {
                let d = f.t_us.wrapping_sub(prev);
                if d < 1 << 31 {
                    e + u64::from(d)
                } else {
                    e.saturating_sub(u64::from(prev.wrapping_sub(f.t_us)))
                }
            }
        };
        ext = Some((f.t_us, t));
        out.push((t, f));
    }
    (out, dec.stats())
}

/// Writes the CSV (see the module docs).
///
/// # Errors
/// When the file cannot be written.
pub fn write_csv(frames: &[(u64, YawFrame)], t0_us: u64, path: &Path) -> Result<()> {
    write_atomically(path, |w| {
        writeln!(w, "t_s,yaw_rate_rad_s,flags")?;
        for (t, f) in frames {
            let t_s = (t0_us + t) as f64 * 1e-6;
            let v = f64::from(f.yaw_rate.to_bits()) / 65536.0;
            writeln!(w, "{t_s:.6},{v:.6},{}", f.flags)?;
        }
        Ok(())
    })
}

pub fn run(args: Args) -> Result<()> {
    let bytes = std::fs::read(&args.input)
        .with_context(|| format!("cannot read {}", args.input.display()))?;
    let (frames, st) = decode(&bytes);
    write_csv(&frames, args.t0_us, &args.out)?;
    eprintln!(
        "{} yaw frames ({} bad, {} missing, {} bytes skipped) -> {}",
        st.ok,
        st.bad,
        st.dropped,
        st.skipped_bytes,
        args.out.display()
    );
    Ok(())
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
}
