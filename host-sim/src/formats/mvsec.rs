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
use super::{GtSample, GyroSample, HostEvent};

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

/// Opens dataset `name` and checks that the rows it declares are stored (see
/// [`VALUES_PER_STORED_BYTE`]).
fn checked_dataset(file: &hdf5::File, path: &Path, name: &str) -> Result<hdf5::Dataset> {
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
    check_chunks(&ds, path, name, &shape)?;
    Ok(ds)
}

/// Refuses a chunked dataset with data but chunks missing from the file (never written, or
/// lost to a corrupted chunk index): the library would read them as the fill value, zeros that
/// pass for data. A dataset with no chunk at all is left to read as its fill value.
fn check_chunks(ds: &hdf5::Dataset, path: &Path, name: &str, shape: &[usize]) -> Result<()> {
    let (Some(chunk), Some(stored)) = (ds.chunk(), ds.num_chunks()) else {
        return Ok(());
    };
    let expected = shape
        .iter()
        .zip(&chunk)
        .try_fold(1usize, |n, (&d, &c)| n.checked_mul(d.div_ceil(c.max(1))));
    if let Some(expected) = expected {
        if stored > 0 && stored < expected {
            bail!(
                "{}: dataset `{name}` stores {stored} of its {expected} chunks: the others would read as zeros (incomplete or corrupt file)",
                path.display()
            );
        }
    }
    Ok(())
}

/// Reads dataset `name` as f64 with its shape.
fn dataset(file: &hdf5::File, path: &Path, name: &str) -> Result<(Vec<f64>, Vec<usize>)> {
    let ds = checked_dataset(file, path, name)?;
    let shape = ds.shape();
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

/// Rows of `davis/left/events` read at a time (2 MiB of `f64`).
const ROWS_PER_READ: usize = 1 << 16;

/// The events of an MVSEC `*_data.hdf5`, read a slice of rows at a time.
pub struct MvsecEvents {
    file: hdf5::File,
    ds: hdf5::Dataset,
    path: std::path::PathBuf,
    rows: usize,
    next: usize,
}

const EVENTS: &str = "davis/left/events";

impl MvsecEvents {
    /// Opens the file and checks the events dataset's shape and storage.
    ///
    /// # Errors
    /// When the file is not a readable HDF5 file or the dataset is missing or malformed.
    pub fn open(path: &Path) -> Result<Self> {
        let file = open(path)?;
        let ds = checked_dataset(&file, path, EVENTS)?;
        let rows = rows(path, EVENTS, &ds.shape(), &[4])?;
        Ok(Self {
            file,
            ds,
            path: path.to_path_buf(),
            rows,
            next: 0,
        })
    }

    /// Appends the events of the next rows to `out`; returns `false` after the last row.
    ///
    /// # Errors
    /// When the rows cannot be read or an event is malformed.
    pub fn next_chunk(&mut self, out: &mut Vec<HostEvent>) -> Result<bool> {
        if self.next >= self.rows {
            return Ok(false);
        }
        let end = (self.next + ROWS_PER_READ).min(self.rows);
        let p = self.path.display();
        let block = self
            .ds
            .read_slice_2d::<f64, _>((self.next..end, ..))
            .map_err(|e| anyhow!("{p}: cannot read `{EVENTS}`: {e}"))?;
        let data = block
            .as_slice()
            .ok_or_else(|| anyhow!("{p}: cannot read `{EVENTS}`: rows not contiguous"))?;
        let (chunks, _) = data.as_chunks::<4>();
        for (k, &[x, y, t, pol]) in chunks.iter().enumerate() {
            match event(x, y, t, pol) {
                Some(e) => out.push(e),
                None => bail!(
                    "{p}: malformed event {} in `{EVENTS}`: [{x}, {y}, {t}, {pol}]",
                    self.next + k
                ),
            }
        }
        self.next = end;
        Ok(true)
    }

    /// The file's IMU as gyro samples, when it has one.
    ///
    /// # Errors
    /// When the IMU datasets are malformed.
    pub fn gyro(&self) -> Result<Option<Vec<GyroSample>>> {
        if self.file.link_exists("davis/left/imu") {
            Ok(Some(gyro_of(&self.file, &self.path)?))
        } else {
            Ok(None)
        }
    }
}

/// One event row `[x, y, t_s, p]`.
fn event(x: f64, y: f64, t: f64, p: f64) -> Option<HostEvent> {
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
