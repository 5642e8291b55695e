//! Ground truth and gyro read in time order a chunk at a time, from every format
//! [`super::read_ground_truth`] and [`super::read_gyro`] accept, in memory bounded by the chunk
//! ([`CHUNK`] lines of text, a slice of HDF5 rows, one AEDAT 4.0 packet), never by the file's
//! length. The samples, their order and the errors are those of the whole-file readers, which
//! collect these.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use super::{aedat4, csv, ecd, mvsec, text, GtSample, GyroSample};

/// Samples a text reader hands out per chunk.
pub const CHUNK: usize = 1 << 13;

/// Longest line of a ground-truth or IMU text file (bytes): the reader holds one line at a
/// time, so a file without line ends is an error, not an unbounded allocation.
pub const MAX_LINE: usize = 1 << 20;

/// The lines of a text file, one at a time, numbered and located as [`text::Lines`] numbers
/// and locates those of a file read whole (every line counted, `\n` or `\r\n` endings); blank
/// lines and `#` comments are skipped.
pub(super) struct TextLines {
    r: BufReader<File>,
    path: PathBuf,
    /// The current line, without its line end.
    line: Vec<u8>,
    /// Byte offset and number (1-based) of the current line.
    offset: u64,
    line_no: usize,
    /// Whether the current line is the file's last and has no line end (reported as
    /// truncated).
    last: bool,
    /// Byte offset of the next line.
    next_offset: u64,
}

impl TextLines {
    /// Opens `path`.
    pub(super) fn open(path: &Path) -> Result<Self> {
        let file = File::open(path).with_context(|| format!("cannot read {}", path.display()))?;
        Ok(Self {
            r: BufReader::with_capacity(1 << 16, file),
            path: path.to_path_buf(),
            line: Vec::new(),
            offset: 0,
            line_no: 0,
            last: false,
            next_offset: 0,
        })
    }

    /// Reads the next line that is not blank or a comment ([`TextLines::line`]); false at the
    /// end of the file.
    pub(super) fn next_line(&mut self) -> Result<bool> {
        loop {
            self.line.clear();
            let n = (&mut self.r)
                .take(MAX_LINE as u64 + 1)
                .read_until(b'\n', &mut self.line)
                .with_context(|| format!("cannot read {}", self.path.display()))?;
            if n == 0 {
                return Ok(false);
            }
            self.offset = self.next_offset;
            self.next_offset += n as u64;
            self.line_no += 1;
            let newline = self.line.last() == Some(&b'\n');
            if !newline && n > MAX_LINE {
                bail!(
                    "{}: line {} at byte {} is longer than {MAX_LINE} bytes",
                    self.path.display(),
                    self.line_no,
                    self.offset
                );
            }
            if newline {
                self.line.pop();
            }
            let cr = self.line.last() == Some(&b'\r');
            if cr {
                self.line.pop();
            }
            self.last = !newline && !cr;
            if !text::is_blank_or_comment(&self.line) {
                return Ok(true);
            }
        }
    }

    /// The current line.
    pub(super) fn line(&self) -> &[u8] {
        &self.line
    }

    /// The error for the current line, which should hold `expected`.
    pub(super) fn error(&self, expected: &str) -> anyhow::Error {
        text::line_error(
            &self.path,
            self.offset,
            self.line_no,
            &self.line,
            expected,
            self.last,
        )
    }

    /// The file.
    pub(super) fn path(&self) -> &Path {
        &self.path
    }
}

/// Replaces `out` with up to [`CHUNK`] items of `next`; false, with `out` empty, when `next`
/// has none left.
pub(super) fn fill<T>(
    out: &mut Vec<T>,
    mut next: impl FnMut() -> Result<Option<T>>,
) -> Result<bool> {
    out.clear();
    while out.len() < CHUNK {
        match next()? {
            Some(s) => out.push(s),
            None => break,
        }
    }
    Ok(!out.is_empty())
}

enum Truth {
    Csv(csv::GtRows),
    Poses(ecd::PoseRates),
    Mvsec(mvsec::PoseRates),
}

/// Ground truth as yaw-rate samples ([`super::read_ground_truth`] describes the formats and
/// the derivation from poses), read a chunk at a time.
pub struct GroundTruthReader(Truth);

impl GroundTruthReader {
    /// Opens `path`: detects its format and reads its header (the HDF5 datasets' shapes and
    /// element types).
    ///
    /// # Errors
    /// When the file cannot be read, is not a ground-truth file, or its header is malformed.
    pub fn open(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let head = super::read_head(path)?;
        if head.starts_with(super::HDF5_MAGIC) {
            return Ok(Self(Truth::Mvsec(mvsec::PoseRates::open(path)?)));
        }
        Ok(Self(match text::classify(&head) {
            text::Kind::GtCsv => Truth::Csv(csv::GtRows::open(path)?),
            text::Kind::PoseText => Truth::Poses(ecd::PoseRates::open(path)?),
            _ => bail!(
                "{}: not a ground-truth file (expected gt.csv `t_s,wx,wy,wz,...`, ECD groundtruth.txt `t px py pz qx qy qz qw` or MVSEC *_gt.hdf5)",
                path.display()
            ),
        }))
    }

    /// Replaces `out` with the next samples, in file order; false, with `out` empty, at the
    /// end.
    ///
    /// # Errors
    /// When the file cannot be read or is malformed (the message names the file and, for text,
    /// the line and its byte offset).
    pub fn next_chunk(&mut self, out: &mut Vec<GtSample>) -> Result<bool> {
        match &mut self.0 {
            Truth::Csv(r) => fill(out, || r.next_sample()),
            Truth::Poses(r) => fill(out, || r.next_sample()),
            Truth::Mvsec(r) => r.next_chunk(out),
        }
    }
}

enum Gyro {
    ImuText(ecd::ImuRows),
    ImuCsv(csv::ImuCsvRows),
    Aedat4(aedat4::GyroPackets),
    Mvsec(mvsec::ImuRates),
}

/// Gyro samples (rad/s; [`super::read_gyro`] describes the formats), read a chunk at a time.
pub struct GyroReader(Gyro);

impl GyroReader {
    /// Opens `path`: detects its format and reads its header.
    ///
    /// # Errors
    /// When the file cannot be read, is not a gyro file, or its header is malformed.
    pub fn open(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let head = super::read_head(path)?;
        if head.starts_with(super::AEDAT4_MAGIC) {
            return Ok(Self(Gyro::Aedat4(aedat4::GyroPackets::open(path)?)));
        }
        if head.starts_with(super::HDF5_MAGIC) {
            return Ok(Self(Gyro::Mvsec(mvsec::ImuRates::open(path)?)));
        }
        Ok(Self(match text::classify(&head) {
            text::Kind::ImuText => Gyro::ImuText(ecd::ImuRows::open(path)?),
            text::Kind::ImuCsv => Gyro::ImuCsv(csv::ImuCsvRows::open(path)?),
            _ => bail!(
                "{}: not a gyro file (expected imu.txt `t ax ay az gx gy gz`, AEDAT4 with IMU or MVSEC *_data.hdf5)",
                path.display()
            ),
        }))
    }

    /// Replaces `out` with the next samples, in file order; false, with `out` empty, at the
    /// end.
    ///
    /// # Errors
    /// When the file cannot be read or is malformed.
    pub fn next_chunk(&mut self, out: &mut Vec<GyroSample>) -> Result<bool> {
        match &mut self.0 {
            Gyro::ImuText(r) => fill(out, || r.next_sample()),
            Gyro::ImuCsv(r) => fill(out, || r.next_sample()),
            Gyro::Aedat4(r) => r.next_chunk(out),
            Gyro::Mvsec(r) => r.next_chunk(out),
        }
    }
}

/// Every sample of a chunked reader.
pub(super) fn collect<T>(
    mut next_chunk: impl FnMut(&mut Vec<T>) -> Result<bool>,
) -> Result<Vec<T>> {
    let mut all = Vec::new();
    let mut chunk = Vec::new();
    while next_chunk(&mut chunk)? {
        all.append(&mut chunk);
    }
    Ok(all)
}
