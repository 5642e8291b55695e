//! Writes a [`Sequence`] in the folder layout of `../shared/data/synthetic/<name>/`:
//! `events.txt` (Event Camera Dataset text, `t[s] x y p`, 6 decimals, p 1/0), `gt.csv`,
//! `imu.txt` and `meta.json`. Each file is complete or absent (written to a temporary file and
//! renamed).

use std::io::Write;
use std::path::Path;

use anyhow::Context;

use super::Sequence;
use crate::output::write_atomically;

/// Creates `dir` if needed and writes the four files into it.
pub fn write_sequence(seq: &Sequence, dir: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    // `t[s] x y p` per line, `t` with exactly 6 decimals (integer µs, no rounding error).
    write_atomically(&dir.join("events.txt"), |w| {
        for e in &seq.events {
            writeln!(
                w,
                "{}.{:06} {} {} {}",
                e.t_us / 1_000_000,
                e.t_us % 1_000_000,
                e.x,
                e.y,
                u8::from(e.on)
            )?;
        }
        Ok(())
    })?;
    write_atomically(&dir.join("gt.csv"), |w| {
        writeln!(
            w,
            "t_s,wx,wy,wz,yaw_rad,heading_rad,pitch_rad,roll_rad,speed_mps"
        )?;
        for g in &seq.gt {
            writeln!(
                w,
                "{:.6},{:.9},{:.9},{:.9},{:.9},{:.9},{:.9},{:.9},{:.9}",
                g.t_s,
                g.w[0],
                g.w[1],
                g.w[2],
                g.yaw_rad,
                g.heading_rad,
                g.pitch_rad,
                g.roll_rad,
                g.speed_mps
            )?;
        }
        Ok(())
    })?;
    write_atomically(&dir.join("imu.txt"), |w| {
        for r in &seq.imu {
            writeln!(
                w,
                "{:.6} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9}",
                r.t_s, r.acc[0], r.acc[1], r.acc[2], r.gyro[0], r.gyro[1], r.gyro[2]
            )?;
        }
        Ok(())
    })?;
    write_atomically(&dir.join("meta.json"), |w| {
        serde_json::to_writer_pretty(&mut *w, &seq.meta)?;
        writeln!(w)?;
        Ok(())
    })
}
