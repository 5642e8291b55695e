//! Ground truth and gyro read in time order a chunk at a time, from every format
//! [`super::read_ground_truth`] and [`super::read_gyro`] accept, in memory bounded by the
//! chunk ([`super::chunked::CHUNK`] lines of text, a slice of HDF5 rows, one AEDAT 4.0
//! packet), never by the file's length. The samples, their order and the errors are those of
//! the whole-file readers, which collect these.

use std::path::Path;

use anyhow::{bail, Result};

use super::chunked::fill;
use super::{aedat4, csv, ecd, mvsec, text, GtSample, GyroSample};

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
