//! The yaw outputs: the CSV `host-sim run` and `host-sim yaw-decode` write
//! (`t_s,yaw_rate_rad_s,flags`), and the firmware's yaw frames (`yaw.bin`).

use std::path::Path;

use anyhow::{bail, Context, Result};

/// One row of a yaw CSV.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Time (s).
    pub t_s: f64,
    /// Yaw rate (rad/s).
    pub yaw: f64,
    /// The sample's flags (`core_nostd::flags`).
    pub flags: u8,
    /// The row after the time, as written (`yaw_rate_rad_s,flags`).
    pub rest: String,
}

/// The rows of a yaw CSV (after its header).
///
/// # Errors
/// When the file cannot be read or a row is not `t_s,yaw_rate_rad_s,flags`.
pub fn read_csv(path: &Path) -> Result<Vec<Row>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut rows = Vec::new();
    for (i, l) in text.lines().enumerate().skip(1) {
        let row = (|| {
            let (t, rest) = l.split_once(',')?;
            let (yaw, flags) = rest.split_once(',')?;
            Some(Row {
                t_s: t.parse().ok()?,
                yaw: yaw.parse().ok()?,
                flags: flags.parse().ok()?,
                rest: rest.to_string(),
            })
        })();
        let Some(row) = row else {
            bail!("{}:{}: not t_s,yaw_rate_rad_s,flags", path.display(), i + 1);
        };
        rows.push(row);
    }
    Ok(rows)
}

/// The sequence counters of the yaw frames in `yaw.bin`, in order.
///
/// # Errors
/// When the file cannot be read.
pub fn sequence(yaw_bin: &Path) -> Result<Vec<u8>> {
    let bytes =
        std::fs::read(yaw_bin).with_context(|| format!("cannot read {}", yaw_bin.display()))?;
    let (mut dec, mut seqs) = (core_nostd::aer::yaw::YawDecoder::new(), Vec::new());
    dec.push(&bytes, |f| seqs.push(f.seq));
    Ok(seqs)
}
