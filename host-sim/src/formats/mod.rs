//! Reading and writing event recordings, ground truth and IMU data.
//!
//! | [`Format`] | files | sensor size | intrinsics | gyro |
//! |---|---|---|---|---|
//! | `csv` | `t_us,x,y,p` (header optional) | sibling `meta.json` | sibling `meta.json` / `calib.txt` | sibling `imu.txt` |
//! | `ecd-text` | Event Camera Dataset `events.txt` (`t[s] x y p`) | sibling `meta.json` | sibling `meta.json` / `calib.txt` | sibling `imu.txt` |
//! | `evt2`, `evt21`, `evt3` | Prophesee `.raw` (`% ` header, then words) | header (`format`, `geometry`, `system_ID`) | sibling `meta.json` / `calib.txt` | sibling `imu.txt` |
//! | `aedat4` | iniVation AEDAT 4.0 (uncompressed, LZ4, zstd) | the event stream's `sizeX`/`sizeY` | sibling files | the file's IMU stream (deg/s -> rad/s) |
//! | `mvsec-hdf5` | MVSEC `*_data.hdf5` (`davis/left/events` N x 4 `[x, y, t_s, p±1]`) | sibling `meta.json` | sibling files | `davis/left/imu` + `imu_ts` |
//!
//! Conventions:
//! - Times are `u64` µs on the host, as in the file: AEDAT4 keeps its Unix-epoch µs, seconds are
//!   converted exactly (decimal text) or rounded to the nearest µs (HDF5 `f64`).
//! - Polarity: `on = true` for ON (p = 1 in text and CSV, +1 in MVSEC).
//! - Gyro samples are in rad/s about the file's own axes (the synthetic sequences and MVSEC store
//!   the camera frame: x right, y down, z forward), with `t_s` on the same clock as the events
//!   (`t_us / 1e6`).
//! - Yaw rate (ground truth) is the angular velocity about the camera's y axis (down), positive
//!   when the camera turns right, i.e. the scene moves left in the image (see `read_ground_truth`).
//! - Errors name the file and, for malformed content, the byte offset; nothing here panics on
//!   bad input.
//! - [`EventReader`] reads the events of every format a chunk at a time (memory bounded by the
//!   chunk, not the recording); [`read`] collects them all, for recordings that fit in memory.
//!   [`GroundTruthReader`] and [`GyroReader`] do the same for ground truth and gyro;
//!   [`read_ground_truth`] and [`read_gyro`] collect theirs.

mod aedat4;
mod chunked;
mod csv;
mod ecd;
mod meta;
mod mvsec;
mod rates;
pub mod raw;
mod rotation;
pub mod stream;
mod text;

use std::fmt;
use std::fs::File;
use std::io::Read;
use std::path::Path;

use anyhow::{bail, Context, Result};

pub use csv::{write_csv, CsvWriter};
pub use meta::Needs;
pub use rates::{GroundTruthReader, GyroReader};
pub use raw::write_evt3;
pub use stream::{EventChunks, EventReader, EventsInMemory, RecordingInfo};

/// One event on the host: absolute time in µs (`u64`), pixel and polarity (the core's
/// decoder output type, used as is).
pub use core_nostd::event::Event64;

/// Pinhole intrinsics in pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    /// Focal length along x (px).
    pub fx: f64,
    /// Focal length along y (px).
    pub fy: f64,
    /// Principal point x (px, 0 = centre of the left column).
    pub cx: f64,
    /// Principal point y (px, 0 = centre of the top row).
    pub cy: f64,
}

/// One gyro sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GyroSample {
    /// Time in s, on the clock of the recording's events (`t_us / 1e6`).
    pub t_s: f64,
    /// Angular velocity about x (right) in rad/s.
    pub wx: f64,
    /// Angular velocity about y (down) in rad/s; positive = turning right.
    pub wy: f64,
    /// Angular velocity about z (forward) in rad/s.
    pub wz: f64,
}

/// One ground-truth sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GtSample {
    /// Time in s (the ground truth file's clock).
    pub t_s: f64,
    /// Angular velocity about the camera's y axis (down) in rad/s; positive = the camera turns
    /// right (clockwise seen from above), the scene moves left in the image.
    pub yaw_rate_rad_s: f64,
}

/// The event file formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, clap::ValueEnum)]
pub enum Format {
    /// CSV `t_us,x,y,p` (p = 1 ON, 0 OFF), with or without a header line.
    Csv,
    /// Event Camera Dataset text: `t[s] x y p` per line.
    EcdText,
    /// Prophesee EVT 2.0 (`.raw`).
    Evt2,
    /// Prophesee EVT 2.1 (`.raw`).
    Evt21,
    /// Prophesee EVT 3.0 (`.raw`).
    Evt3,
    /// iniVation AEDAT 4.0.
    Aedat4,
    /// MVSEC HDF5 (`davis/left/events`).
    MvsecHdf5,
}

impl Format {
    /// Human-readable name, as used in messages.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::Csv => "CSV",
            Self::EcdText => "Event Camera Dataset text",
            Self::Evt2 => "EVT 2.0",
            Self::Evt21 => "EVT 2.1",
            Self::Evt3 => "EVT 3.0",
            Self::Aedat4 => "AEDAT 4.0",
            Self::MvsecHdf5 => "MVSEC HDF5",
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A recording: its events in stream order and what the file (or its folder) says about the
/// sensor.
#[derive(Clone, Debug)]
pub struct Recording {
    /// Events in stream order (time-sorted in every well-formed file, not re-sorted here).
    pub events: Vec<Event64>,
    /// Sensor width in px, when known.
    pub width: Option<u16>,
    /// Sensor height in px, when known.
    pub height: Option<u16>,
    /// Camera intrinsics, when known.
    pub intrinsics: Option<Intrinsics>,
    /// Gyro samples (rad/s), when the file or its folder has them.
    pub gyro: Option<Vec<GyroSample>>,
    /// The format the events were read from.
    pub format: Format,
}

impl Recording {
    /// `(max x + 1, max y + 1)` over the events, `None` without events.
    #[must_use]
    pub fn extent(&self) -> Option<(u16, u16)> {
        let mx = self.events.iter().map(|e| e.x).max()?;
        let my = self.events.iter().map(|e| e.y).max()?;
        Some((mx.saturating_add(1), my.saturating_add(1)))
    }

    /// Sensor size: the file's `(width, height)` when known, else [`Recording::extent`].
    #[must_use]
    pub fn size_or_extent(&self) -> Option<(u16, u16)> {
        match (self.width, self.height) {
            (Some(w), Some(h)) => Some((w, h)),
            _ => self.extent(),
        }
    }
}

/// The HDF5 file signature.
const HDF5_MAGIC: &[u8] = b"\x89HDF\r\n\x1a\n";
/// The AEDAT 4.0 magic line.
const AEDAT4_MAGIC: &[u8] = b"#!AER-DAT4.0\r\n";

/// What a file holds, from its first bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Content {
    Events(Format),
    /// Prophesee `% ` header without a format.
    RawUnknown,
    /// A text file of another kind (ground truth, IMU): the message says which.
    OtherText(&'static str),
    /// Nothing recognised.
    Unknown,
}

/// What the first bytes `head` of `path` hold.
fn sniff(path: &Path, head: &[u8]) -> Result<Content> {
    if head.starts_with(AEDAT4_MAGIC) {
        return Ok(Content::Events(Format::Aedat4));
    }
    if head.starts_with(b"#!AER-DAT") {
        let line = head.split(|&b| b == b'\n').next().unwrap_or_default();
        bail!(
            "{}: unsupported AEDAT version `{}` (only AEDAT 4.0 is read)",
            path.display(),
            String::from_utf8_lossy(line).trim()
        );
    }
    if head.starts_with(HDF5_MAGIC) {
        return Ok(Content::Events(Format::MvsecHdf5));
    }
    if head.first() == Some(&b'%') {
        let h = raw::parse_header(head);
        return Ok(h.format.map_or(Content::RawUnknown, Content::Events));
    }
    Ok(match text::classify(head) {
        text::Kind::EventsCsv => Content::Events(Format::Csv),
        text::Kind::EventsText => Content::Events(Format::EcdText),
        text::Kind::GtCsv => Content::OtherText("a ground-truth CSV (t_s,wx,wy,wz,...)"),
        text::Kind::ImuText => Content::OtherText("an IMU text file (t ax ay az gx gy gz)"),
        text::Kind::PoseText => {
            Content::OtherText("a ground-truth pose file (t px py pz qx qy qz qw)")
        }
        text::Kind::ImuCsv => Content::OtherText("an IMU CSV"),
        text::Kind::Unknown => Content::Unknown,
    })
}

/// Detects the event format of `path` from its content: AEDAT4 and HDF5 magic, the Prophesee
/// `% ` header (`format`, legacy `evt` and `system_ID` lines), or the first lines of text.
///
/// # Errors
/// When the file cannot be read or its content is not a known event format (the message says
/// what it looks like, and that `--format` overrides detection).
pub fn detect(path: impl AsRef<Path>) -> Result<Format> {
    let path = path.as_ref();
    detected(path, sniff(path, &read_head(path)?)?)
}

/// The event format of what [`sniff`] found, or the error saying what the file is instead.
fn detected(path: &Path, content: Content) -> Result<Format> {
    match content {
        Content::Events(f) => Ok(f),
        Content::RawUnknown => bail!(
            "{}: the Prophesee header names no event format (no `format`, `evt` or known `system_ID` line); pass --format evt2|evt21|evt3",
            path.display()
        ),
        Content::OtherText(what) => {
            bail!("{}: {what}, not events; pass --format to force one", path.display())
        }
        Content::Unknown => bail!(
            "{}: unknown format at byte 0 (no AEDAT 4.0 or HDF5 signature, no Prophesee `%` header, not CSV or text events); pass --format to force one",
            path.display()
        ),
    }
}

/// Reads a recording: detects the format (unless given), decodes all events and gathers sensor
/// size, intrinsics and gyro from the file and its folder (`meta.json`, `calib.txt`, `imu.txt`).
///
/// # Errors
/// When the file cannot be read, is malformed or truncated (the message names the file and the
/// byte offset), or a sibling file it uses is malformed.
pub fn read(path: impl AsRef<Path>, format: Option<Format>) -> Result<Recording> {
    let path = path.as_ref();
    let mut reader = EventReader::open(path, format, true)?;
    reader.complete_from_folder(Needs::ALL)?;
    let mut events = Vec::new();
    let mut chunk = Vec::new();
    while reader.next_chunk(&mut chunk)? {
        events.append(&mut chunk);
    }
    let gyro = reader.take_gyro();
    let info = reader.info;
    Ok(Recording {
        events,
        width: info.width,
        height: info.height,
        intrinsics: info.intrinsics,
        gyro,
        format: info.format,
    })
}

/// Reads ground truth as yaw rate samples, from:
/// - this project's `gt.csv` (`t_s,wx,wy,wz,...`): yaw rate = `wy`;
/// - Event Camera Dataset `groundtruth.txt` (`t px py pz qx qy qz qw`, the camera's pose in the
///   world): the camera-frame angular velocity from central differences of the orientation,
///   `R(t_{k-1})^T R(t_{k+1}) = exp([w] (t_{k+1} - t_{k-1}))`, yaw rate = `w.y`;
/// - MVSEC `*_gt.hdf5` (`davis/left/pose` K x 4 x 4 `T_world_camera`, `pose_ts`): the same.
///
/// The camera frame is x right, y down, z forward; a positive rotation about y (down) turns the
/// camera's forward axis towards its right.
///
/// [`GroundTruthReader`] reads the same a chunk at a time.
///
/// # Errors
/// When the file cannot be read or is not one of these formats, or is malformed.
pub fn read_ground_truth(path: impl AsRef<Path>) -> Result<Vec<GtSample>> {
    let mut r = GroundTruthReader::open(path)?;
    chunked::collect(|out| r.next_chunk(out))
}

/// Reads gyro samples (rad/s) from an Event Camera Dataset / synthetic `imu.txt`
/// (`t ax ay az gx gy gz`), an AEDAT4 file's IMU stream (deg/s, converted), an MVSEC
/// `*_data.hdf5` (`davis/left/imu` `[ax ay az wx wy wz]` + `imu_ts`), or an IMU CSV with
/// `t_us` and `gyroscope_x/y/z` columns in deg/s (the AEDAT4 reference decode).
///
/// [`GyroReader`] reads the same a chunk at a time.
///
/// # Errors
/// When the file cannot be read, is not one of these formats, or is malformed.
pub fn read_gyro(path: impl AsRef<Path>) -> Result<Vec<GyroSample>> {
    let mut r = GyroReader::open(path)?;
    chunked::collect(|out| r.next_chunk(out))
}

/// Bytes read for format detection.
const HEAD_BYTES: usize = 64 * 1024;

/// The first [`HEAD_BYTES`] of a file.
fn read_head(path: &Path) -> Result<Vec<u8>> {
    let mut head = Vec::with_capacity(HEAD_BYTES);
    File::open(path)
        .with_context(|| format!("cannot open {}", path.display()))?
        .take(HEAD_BYTES as u64)
        .read_to_end(&mut head)
        .with_context(|| format!("cannot read {}", path.display()))?;
    Ok(head)
}

/// Reads until `buf` is full or the input ends (retrying interrupted reads); returns the bytes
/// read, fewer than `buf.len()` only at the end of the input.
fn read_up_to(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while let Some(rest) = buf.get_mut(n..).filter(|b| !b.is_empty()) {
        match r.read(rest) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}
