//! MVSEC HDF5 (through the HDF5 C library, `hdf5-metno`): `*_data.hdf5` with
//! `davis/left/events` (N x 4 `[x, y, t_s, p]`, p = +1 ON / -1 OFF; also 0 = OFF accepted),
//! `davis/left/imu` (N x 6 `[ax ay az wx wy wz]`, m/s^2 and rad/s) with `davis/left/imu_ts` (s);
//! `*_gt.hdf5` with `davis/left/pose` (K x 4 x 4 `T_world_camera`) and `davis/left/pose_ts` (s).
//! Times in seconds are rounded to the nearest µs (real MVSEC uses ROS epoch seconds: the µs
//! stay absolute).

use std::fs::File;
use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};

use hdf5::{Hyperslab, SliceOrIndex};

use super::chunked;
use super::rotation::{CentralDifferences, Mat3};
use super::text::seconds_to_us;
use super::{Event64, GtSample, GyroSample};

fn open(path: &Path) -> Result<hdf5::File> {
    precheck(path)?;
    hdf5::File::open(path).map_err(|e| {
        let hint = if e.to_string().contains("unable to lock file") {
            LOCK_HINT
        } else {
            ""
        };
        anyhow!("{}: cannot open as HDF5: {e}{hint}", path.display())
    })
}

/// Added to the library's message when the file is locked: HDF5 writers lock their files, and
/// the library honours `HDF5_USE_FILE_LOCKING`.
const LOCK_HINT: &str = " (another process has it open for writing: close it there, or set \
    HDF5_USE_FILE_LOCKING=FALSE to read it anyway)";

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

/// Checks that dataset `name` reads as f64 (its element type converts), by reading one value:
/// a dataset that cannot is refused before its shape is looked at, as when it was read whole.
fn probe(ds: &hdf5::Dataset, path: &Path, name: &str) -> Result<()> {
    let shape = ds.shape();
    let read = if shape.iter().product::<usize>() <= 1 {
        ds.read_raw::<f64>().map(drop)
    } else {
        let first: Vec<SliceOrIndex> = (0..shape.len())
            .map(|i| if i == 0 { (0..1).into() } else { 0.into() })
            .collect();
        ds.read_slice_1d::<f64, _>(Hyperslab::from(first)).map(drop)
    };
    read.map_err(|e| anyhow!("{}: cannot read `{name}`: {e}", path.display()))
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
        // The element type must convert, also when there are no rows to read.
        probe(&ds, path, EVENTS)?;
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
    pub fn next_chunk(&mut self, out: &mut Vec<Event64>) -> Result<bool> {
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
        if self.file.link_exists(IMU) {
            Ok(Some(gyro_of(&self.file, &self.path)?))
        } else {
            Ok(None)
        }
    }
}

/// One event row `[x, y, t_s, p]`.
fn event(x: f64, y: f64, t: f64, p: f64) -> Option<Event64> {
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
    Some(Event64 { t_us, x, y, on })
}

/// A pixel coordinate stored as a float: a non-negative integer below 65536.
fn pixel(v: f64) -> Option<u16> {
    ((0.0..65536.0).contains(&v) && v.fract() == 0.0).then_some(v as u16)
}

fn gyro_of(file: &hdf5::File, path: &Path) -> Result<Vec<GyroSample>> {
    let mut r = ImuRates::of(file, path)?;
    chunked::collect(|out| r.next_chunk(out))
}

const IMU: &str = "davis/left/imu";
const IMU_TS: &str = "davis/left/imu_ts";
const POSE: &str = "davis/left/pose";
const POSE_TS: &str = "davis/left/pose_ts";

/// Checks dataset `name`'s storage and element type, and that its shape is `[n, cols...]`;
/// returns it and n.
fn rows_dataset(
    file: &hdf5::File,
    path: &Path,
    name: &str,
    cols: &[usize],
) -> Result<(hdf5::Dataset, usize)> {
    let ds = checked_dataset(file, path, name)?;
    probe(&ds, path, name)?;
    let n = rows(path, name, &ds.shape(), cols)?;
    Ok((ds, n))
}

/// Checks the times dataset `name` of `n` rows of `of`.
fn times_dataset(
    file: &hdf5::File,
    path: &Path,
    name: &str,
    n: usize,
    of: &str,
) -> Result<hdf5::Dataset> {
    let ds = checked_dataset(file, path, name)?;
    probe(&ds, path, name)?;
    let shape = ds.shape();
    if shape != [n] {
        bail!(
            "{}: `{name}` has shape {shape:?}, `{of}` has {n} rows",
            path.display()
        );
    }
    Ok(ds)
}

/// Reads rows `rows` of the 1-D dataset `name`.
fn read_times(
    ds: &hdf5::Dataset,
    path: &Path,
    name: &str,
    rows: std::ops::Range<usize>,
) -> Result<Vec<f64>> {
    ds.read_slice_1d::<f64, _>(rows)
        .map(|a| a.into_iter().collect())
        .map_err(|e| anyhow!("{}: cannot read `{name}`: {e}", path.display()))
}

/// `davis/left/imu` + `imu_ts` of an MVSEC `*_data.hdf5` as gyro samples (rad/s), read a slice
/// of [`ROWS_PER_READ`] rows at a time.
pub(super) struct ImuRates {
    imu: hdf5::Dataset,
    ts: hdf5::Dataset,
    path: std::path::PathBuf,
    rows: usize,
    next: usize,
}

impl ImuRates {
    /// Opens the file and checks the datasets' storage, element types and shapes.
    pub(super) fn open(path: &Path) -> Result<Self> {
        Self::of(&open(path)?, path)
    }

    fn of(file: &hdf5::File, path: &Path) -> Result<Self> {
        let (imu, rows) = rows_dataset(file, path, IMU, &[6])?;
        let ts = times_dataset(file, path, IMU_TS, rows, IMU)?;
        Ok(Self {
            imu,
            ts,
            path: path.to_path_buf(),
            rows,
            next: 0,
        })
    }

    /// Replaces `out` with the samples of the next rows; false, with `out` empty, after the
    /// last row.
    pub(super) fn next_chunk(&mut self, out: &mut Vec<GyroSample>) -> Result<bool> {
        out.clear();
        if self.next >= self.rows {
            return Ok(false);
        }
        let end = (self.next + ROWS_PER_READ).min(self.rows);
        let p = self.path.display();
        let block = self
            .imu
            .read_slice_2d::<f64, _>((self.next..end, ..))
            .map_err(|e| anyhow!("{p}: cannot read `{IMU}`: {e}"))?;
        let data = block
            .as_slice()
            .ok_or_else(|| anyhow!("{p}: cannot read `{IMU}`: rows not contiguous"))?;
        let ts = read_times(&self.ts, &self.path, IMU_TS, self.next..end)?;
        let (imu, _) = data.as_chunks::<6>();
        out.extend(
            imu.iter()
                .zip(ts)
                .map(|(&[_, _, _, wx, wy, wz], t_s)| GyroSample { t_s, wx, wy, wz }),
        );
        self.next = end;
        Ok(true)
    }
}

/// `davis/left/pose` + `pose_ts` of an MVSEC `*_gt.hdf5`, read a slice of rows at a time, the
/// orientation differentiated as the poses come (see [`super::read_ground_truth`]).
pub(super) struct PoseRates {
    pose: hdf5::Dataset,
    ts: hdf5::Dataset,
    path: std::path::PathBuf,
    rows: usize,
    next: usize,
    /// Rows per read.
    step: usize,
    diff: CentralDifferences,
    /// The last pose's rate was given.
    done: bool,
}

impl PoseRates {
    /// Opens the file and checks the datasets' storage, element types and shapes.
    pub(super) fn open(path: &Path) -> Result<Self> {
        let file = open(path)?;
        let (pose, rows) = rows_dataset(&file, path, POSE, &[4, 4])?;
        let ts = times_dataset(&file, path, POSE_TS, rows, POSE)?;
        Ok(Self {
            pose,
            ts,
            path: path.to_path_buf(),
            rows,
            next: 0,
            // The rotation part of each pose: 3 rows of 4 values.
            step: ROWS_PER_READ / 4,
            diff: CentralDifferences::default(),
            done: false,
        })
    }

    /// Replaces `out` with the yaw rates of the next rows; false, with `out` empty, after the
    /// last row.
    pub(super) fn next_chunk(&mut self, out: &mut Vec<GtSample>) -> Result<bool> {
        out.clear();
        let p = self.path.display().to_string();
        while out.is_empty() {
            if self.next >= self.rows {
                if self.done {
                    return Ok(false);
                }
                self.done = true;
                let last = self.diff.finish().map_err(|e| anyhow!("{p}: {e}"))?;
                out.extend(last);
                break;
            }
            let end = (self.next + self.step).min(self.rows);
            // Rows 0-2 of the 4 x 4 matrices, each [end - next, 4].
            let mut blocks = Vec::with_capacity(3);
            for i in 0..3 {
                let block = self
                    .pose
                    .read_slice_2d::<f64, _>((self.next..end, i, ..))
                    .map_err(|e| anyhow!("{p}: cannot read `{POSE}`: {e}"))?;
                blocks.push(block);
            }
            let mut r = blocks.iter().map(|b| {
                b.as_slice()
                    .map(|d| d.as_chunks::<4>().0)
                    .ok_or_else(|| anyhow!("{p}: cannot read `{POSE}`: rows not contiguous"))
            });
            let (Some(r0), Some(r1), Some(r2)) = (r.next(), r.next(), r.next()) else {
                bail!("{p}: cannot read `{POSE}`");
            };
            let (r0, r1, r2) = (r0?, r1?, r2?);
            let ts = read_times(&self.ts, &self.path, POSE_TS, self.next..end)?;
            for (((t, a), b), c) in ts.into_iter().zip(r0).zip(r1).zip(r2) {
                let m = Mat3([[a[0], a[1], a[2]], [b[0], b[1], b[2]], [c[0], c[1], c[2]]]);
                if let Some(s) = self.diff.push(t, m).map_err(|e| anyhow!("{p}: {e}"))? {
                    out.push(s);
                }
            }
            self.next = end;
        }
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::rotation::yaw_rates_central;

    /// Writes `name` as a chunked f64 dataset of `shape`.
    fn put(file: &hdf5::File, name: &str, shape: &[usize], values: &[f64]) {
        let chunk: Vec<usize> = shape.iter().map(|&d| d.clamp(1, 1000)).collect();
        let ds = file
            .new_dataset::<f64>()
            .chunk(chunk)
            .shape(shape)
            .create(name)
            .unwrap();
        ds.write_raw(values).unwrap();
    }

    /// The ground truth as it was read before it streamed: both datasets whole.
    fn gt_whole(path: &Path) -> Result<Vec<GtSample>> {
        let file = open(path)?;
        let pose = file.dataset(POSE)?.read_raw::<f64>()?;
        let ts = file.dataset(POSE_TS)?.read_raw::<f64>()?;
        let (mats, _) = pose.as_chunks::<16>();
        let poses: Vec<(f64, Mat3)> = mats
            .iter()
            .zip(ts)
            .map(|(m, t)| {
                let r = [[m[0], m[1], m[2]], [m[4], m[5], m[6]], [m[8], m[9], m[10]]];
                (t, Mat3(r))
            })
            .collect();
        yaw_rates_central(&poses).map_err(|e| anyhow!("{}: {e}", path.display()))
    }

    fn gyro_whole(path: &Path) -> Result<Vec<GyroSample>> {
        let file = open(path)?;
        let imu = file.dataset(IMU)?.read_raw::<f64>()?;
        let ts = file.dataset(IMU_TS)?.read_raw::<f64>()?;
        let (rows, _) = imu.as_chunks::<6>();
        Ok(rows
            .iter()
            .zip(ts)
            .map(|(&[_, _, _, wx, wy, wz], t_s)| GyroSample { t_s, wx, wy, wz })
            .collect())
    }

    fn gt_streamed(path: &Path) -> Result<Vec<GtSample>> {
        let mut r = PoseRates::open(path)?;
        chunked::collect(|out| r.next_chunk(out))
    }

    #[test]
    fn slices_read_what_the_whole_datasets_gave() {
        let dir = tempfile::tempdir().unwrap();
        // Several slices of rows each, and a last one that is not full.
        let (k, n) = (2 * ROWS_PER_READ / 4 + 777, 2 * ROWS_PER_READ + 555);
        let yaw = |i: usize| (i as f64 * 0.002).sin() + 0.1 * (i as f64 * 0.37).cos();
        let mut pose = Vec::with_capacity(k * 16);
        for i in 0..k {
            let (s, c) = yaw(i).sin_cos();
            let tilt = 0.01 * (i as f64 * 0.1).sin();
            pose.extend([
                c, tilt, s, 1.0, 0.0, 1.0, 0.0, 2.0, -s, 0.0, c, 3.0, 0.0, 0.0, 0.0, 1.0,
            ]);
        }
        let mut ts: Vec<f64> = (0..k).map(|i| 1.5e9 + i as f64 * 1e-3).collect();
        let imu: Vec<f64> = (0..n * 6).map(|i| (i as f64 * 0.013).sin()).collect();
        let imu_ts: Vec<f64> = (0..n).map(|i| i as f64 * 5e-3).collect();
        for case in ["in order", "time going back"] {
            if case == "time going back" {
                ts[ROWS_PER_READ / 4 + 3] -= 1.0;
            }
            let path = dir.path().join("gt.hdf5");
            let file = hdf5::File::create(&path).unwrap();
            put(&file, POSE, &[k, 4, 4], &pose);
            put(&file, POSE_TS, &[k], &ts);
            put(&file, IMU, &[n, 6], &imu);
            put(&file, IMU_TS, &[n], &imu_ts);
            file.close().unwrap();
            match (gt_streamed(&path), gt_whole(&path)) {
                (Ok(a), Ok(b)) => {
                    assert_eq!(case, "in order");
                    assert_eq!(a.len(), k);
                    assert!(a == b, "{case}: samples differ");
                }
                (Err(a), Err(b)) => {
                    assert_eq!(case, "time going back");
                    assert_eq!(format!("{a:#}"), format!("{b:#}"), "{case}");
                }
                (a, b) => panic!(
                    "{case}: {:?} vs {:?}",
                    a.map(|v| v.len()),
                    b.map(|v| v.len())
                ),
            }
            let mut r = ImuRates::open(&path).unwrap();
            let streamed = chunked::collect(|out| r.next_chunk(out)).unwrap();
            assert_eq!(streamed.len(), n);
            assert!(
                streamed == gyro_whole(&path).unwrap(),
                "{case}: gyro differs"
            );
        }
    }
}
