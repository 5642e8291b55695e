//! MVSEC HDF5 (through the HDF5 C library, `hdf5-metno`): `*_data.hdf5` with
//! `davis/left/events` (N x 4 `[x, y, t_s, p]`, p = +1 ON / -1 OFF; also 0 = OFF accepted),
//! `davis/left/imu` (N x 6 `[ax ay az wx wy wz]`, m/s^2 and rad/s) with `davis/left/imu_ts` (s);
//! `*_gt.hdf5` with `davis/left/pose` (K x 4 x 4 `T_world_camera`) and `davis/left/pose_ts` (s).
//! Times in seconds are rounded to the nearest µs (real MVSEC uses ROS epoch seconds: the µs
//! stay absolute).

use std::fs::File;
use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};

use super::rotation::{yaw_rates_central, Mat3};
use super::text::seconds_to_us;
use super::{Format, GtSample, GyroSample, HostEvent, Recording};

fn open(path: &Path) -> Result<hdf5::File> {
    precheck(path)?;
    hdf5::File::open(path).map_err(|e| anyhow!("{}: cannot open as HDF5: {e}", path.display()))
}

/// Checks the HDF5 signature and, from the superblock's end-of-file address, that the file is
/// complete, so that those errors name a byte offset (the HDF5 library's messages do not).
fn precheck(path: &Path) -> Result<()> {
    let p = path.display();
    let mut head = [0u8; 64];
    let mut f = File::open(path).with_context(|| format!("cannot open {p}"))?;
    let len = f.metadata().map(|m| m.len()).unwrap_or(0);
    let n = super::read_up_to(&mut f, &mut head).map_err(|e| anyhow!("cannot read {p}: {e}"))?;
    if !head.starts_with(super::HDF5_MAGIC) {
        bail!("{p}: not an HDF5 file (no HDF5 signature at byte 0)");
    }
    let byte = |i: usize| head.get(i).copied().map(usize::from);
    // Superblock version -> (offset of "size of offsets", end of the fixed part); the end-of-file
    // address follows the base address and one more address.
    let (size_at, fixed) = match byte(8) {
        Some(0) => (13, 24),
        Some(1) => (13, 28),
        Some(2 | 3) => (9, 12),
        _ => return Ok(()),
    };
    let Some(o) = byte(size_at).filter(|o| matches!(o, 2 | 4 | 8)) else {
        return Ok(());
    };
    let at = fixed + 2 * o;
    let Some(bytes) = head.get(at..at + o) else {
        return Ok(());
    };
    let eof = bytes
        .iter()
        .rev()
        .fold(0u64, |acc, &b| (acc << 8) | u64::from(b));
    if n >= at + o && eof != u64::MAX && len < eof {
        bail!("{p}: truncated HDF5 file at byte {len}: its superblock says it ends at byte {eof}");
    }
    Ok(())
}

/// How many values a dataset may declare per byte it stores in the file, plus
/// [`UNSTORED_VALUES`]. Parts of a dataset that were never written read as its fill value, so a
/// file of a few KiB can declare billions of rows; reading them would exhaust memory (or overflow
/// the size of the buffer). Compression of real data stays far below this ratio.
const VALUES_PER_STORED_BYTE: u64 = 1024;
/// Values a dataset may declare beyond [`VALUES_PER_STORED_BYTE`] (small unwritten datasets).
const UNSTORED_VALUES: u64 = 1 << 16;

/// Reads dataset `name` as f64 with its shape.
fn dataset(file: &hdf5::File, path: &Path, name: &str) -> Result<(Vec<f64>, Vec<usize>)> {
    let ds = file
        .dataset(name)
        .map_err(|e| anyhow!("{}: no dataset `{name}`: {e}", path.display()))?;
    let shape = ds.shape();
    let stored = ds.storage_size();
    let values = shape
        .iter()
        .try_fold(1u64, |n, &d| n.checked_mul(u64::try_from(d).ok()?));
    let limit = stored
        .saturating_mul(VALUES_PER_STORED_BYTE)
        .saturating_add(UNSTORED_VALUES);
    if values.is_none_or(|v| v > limit) {
        bail!(
            "{}: dataset `{name}` declares shape {shape:?} but stores only {stored} bytes",
            path.display()
        );
    }
    let data = ds
        .read_raw::<f64>()
        .map_err(|e| anyhow!("{}: cannot read `{name}`: {e}", path.display()))?;
    Ok((data, shape))
}

/// Checks that `shape` is `[n, cols...]` and returns n.
fn rows(path: &Path, name: &str, shape: &[usize], cols: &[usize]) -> Result<usize> {
    match shape.split_first() {
        Some((&n, rest)) if rest == cols => Ok(n),
        _ => bail!(
            "{}: dataset `{name}` has shape {shape:?}, expected [N, {cols:?}]",
            path.display()
        ),
    }
}

/// Reads the events of an MVSEC `*_data.hdf5` (and its IMU as gyro when present).
pub(super) fn read_events(path: &Path) -> Result<Recording> {
    let file = open(path)?;
    let name = "davis/left/events";
    let (data, shape) = dataset(&file, path, name)?;
    rows(path, name, &shape, &[4])?;
    let (chunks, _) = data.as_chunks::<4>();
    let mut events = Vec::with_capacity(chunks.len());
    for (i, &[x, y, t, p]) in chunks.iter().enumerate() {
        let ev = (|| {
            let t_us = seconds_to_us(t)?;
            let x = pixel(x)?;
            let y = pixel(y)?;
            let on = if p > 0.0 {
                true
            } else if p == -1.0 || p == 0.0 {
                false
            } else {
                return None;
            };
            Some(HostEvent { t_us, x, y, on })
        })();
        match ev {
            Some(e) => events.push(e),
            None => bail!(
                "{}: malformed event {i} in `{name}`: [{x}, {y}, {t}, {p}]",
                path.display()
            ),
        }
    }
    let gyro = if file.link_exists("davis/left/imu") {
        Some(gyro_of(&file, path)?)
    } else {
        None
    };
    Ok(Recording {
        events,
        width: None,
        height: None,
        intrinsics: None,
        gyro,
        format: Format::MvsecHdf5,
    })
}

/// A pixel coordinate stored as a float: a non-negative integer below 65536.
fn pixel(v: f64) -> Option<u16> {
    ((0.0..65536.0).contains(&v) && v.fract() == 0.0).then_some(v as u16)
}

fn gyro_of(file: &hdf5::File, path: &Path) -> Result<Vec<GyroSample>> {
    let (imu, shape) = dataset(file, path, "davis/left/imu")?;
    let n = rows(path, "davis/left/imu", &shape, &[6])?;
    let (ts, ts_shape) = dataset(file, path, "davis/left/imu_ts")?;
    if ts_shape != [n] {
        bail!(
            "{}: `davis/left/imu_ts` has shape {ts_shape:?}, `davis/left/imu` has {n} rows",
            path.display()
        );
    }
    let (chunks, _) = imu.as_chunks::<6>();
    Ok(chunks
        .iter()
        .zip(ts)
        .map(|(&[_, _, _, wx, wy, wz], t_s)| GyroSample { t_s, wx, wy, wz })
        .collect())
}

/// Reads `davis/left/imu` + `imu_ts` of an MVSEC `*_data.hdf5` as gyro samples (rad/s).
pub(super) fn read_gyro(path: &Path) -> Result<Vec<GyroSample>> {
    gyro_of(&open(path)?, path)
}

/// Reads `davis/left/pose` + `pose_ts` of an MVSEC `*_gt.hdf5` and differentiates the
/// orientation (see [`super::read_ground_truth`]).
pub(super) fn read_ground_truth(path: &Path) -> Result<Vec<GtSample>> {
    let file = open(path)?;
    let (pose, shape) = dataset(&file, path, "davis/left/pose")?;
    let n = rows(path, "davis/left/pose", &shape, &[4, 4])?;
    let (ts, ts_shape) = dataset(&file, path, "davis/left/pose_ts")?;
    if ts_shape != [n] {
        bail!(
            "{}: `davis/left/pose_ts` has shape {ts_shape:?}, `davis/left/pose` has {n} rows",
            path.display()
        );
    }
    let (mats, _) = pose.as_chunks::<16>();
    let poses: Vec<(f64, Mat3)> = mats
        .iter()
        .zip(ts)
        .map(|(m, t)| {
            (
                t,
                Mat3([[m[0], m[1], m[2]], [m[4], m[5], m[6]], [m[8], m[9], m[10]]]),
            )
        })
        .collect();
    yaw_rates_central(&poses).map_err(|e| anyhow!("{}: {e}", path.display()))
}
