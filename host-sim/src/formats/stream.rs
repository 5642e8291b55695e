//! Reading a recording's events a chunk at a time, from every format, in memory bounded by the
//! chunk (never by the recording's length).
//!
//! The input is opened once: format detection reads its first 64 KiB and the decoder continues
//! from them, so a pipe (`<(...)`, a FIFO) is read exactly once. MVSEC HDF5 is the exception:
//! the HDF5 library opens the file by name and needs it seekable.

use std::fs::File;
use std::io::{Cursor, Read};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use super::aedat4::Aedat4Reader;
use super::meta::Needs;
use super::mvsec::MvsecEvents;
use super::raw::RawEvents;
use super::text::EventLines;
use super::{csv, ecd, Event64, Format, GyroSample, Intrinsics};

/// Events a text reader appends per chunk (the binary formats give one packet or one block of
/// words per chunk, at most about 800 k events).
pub const CHUNK_EVENTS: usize = 1 << 16;

/// What the file (and, after [`EventReader::complete_from_folder`], its folder) says about the
/// sensor, without the events.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordingInfo {
    /// Sensor width in px, when known.
    pub width: Option<u16>,
    /// Sensor height in px, when known.
    pub height: Option<u16>,
    /// Camera intrinsics, when known.
    pub intrinsics: Option<Intrinsics>,
    /// Gyro samples (rad/s), when asked for and the file or its folder has them.
    pub gyro: Option<Vec<GyroSample>>,
    /// The format the events are read from.
    pub format: Format,
}

/// The input: the bytes detection read, then the rest of the file.
type Input = std::io::Chain<Cursor<Vec<u8>>, File>;

enum Source {
    Raw(RawEvents<Input>),
    Lines(EventLines<Input>),
    Aedat4(Aedat4Reader<Input>),
    Mvsec(MvsecEvents),
}

/// A recording's events, a chunk at a time.
pub struct EventReader {
    source: Source,
    /// What the file says about the sensor (sidecar files not read yet).
    pub info: RecordingInfo,
    path: PathBuf,
    regular: bool,
    /// Gyro samples of an AEDAT 4.0 file's IMU stream, when asked for.
    aedat_gyro: Vec<GyroSample>,
}

impl EventReader {
    /// Opens `path` as `format` (detected from the content when `None`). With `gyro`, an AEDAT
    /// 4.0 file's IMU packets are collected too (see [`EventReader::take_gyro`]).
    ///
    /// # Errors
    /// When the file cannot be opened, its format is unknown, or its header is malformed.
    pub fn open(path: &Path, format: Option<Format>, gyro: bool) -> Result<Self> {
        let mut file =
            File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
        let meta = file.metadata().ok();
        let regular = meta.as_ref().is_some_and(std::fs::Metadata::is_file);
        let file_len = meta.filter(std::fs::Metadata::is_file).map(|m| m.len());
        let mut head = Vec::with_capacity(super::HEAD_BYTES);
        (&mut file)
            .take(super::HEAD_BYTES as u64)
            .read_to_end(&mut head)
            .with_context(|| format!("cannot read {}", path.display()))?;
        let format = match format {
            Some(f) => f,
            None => super::detected(path, super::sniff(path, &head)?)?,
        };
        let input: Input = Cursor::new(head).chain(file);
        let mut info = RecordingInfo {
            width: None,
            height: None,
            intrinsics: None,
            gyro: None,
            format,
        };
        let source = match format {
            Format::Csv => Source::Lines(EventLines::new(input, path, csv::EVENTS)),
            Format::EcdText => Source::Lines(EventLines::new(input, path, ecd::EVENTS)),
            Format::Evt2 | Format::Evt21 | Format::Evt3 => {
                let (raw, header) = RawEvents::open(input, path, format)?;
                info.width = header.width;
                info.height = header.height;
                Source::Raw(raw)
            }
            Format::Aedat4 => {
                let r = Aedat4Reader::open(input, path, file_len, true, gyro)?;
                info.width = r.size.map(|s| s.0);
                info.height = r.size.map(|s| s.1);
                Source::Aedat4(r)
            }
            Format::MvsecHdf5 => {
                if !regular {
                    bail!(
                        "{}: MVSEC HDF5 is read through the HDF5 library, which needs a regular file, not a pipe",
                        path.display()
                    );
                }
                let m = MvsecEvents::open(path)?;
                if gyro {
                    info.gyro = m.gyro()?;
                }
                Source::Mvsec(m)
            }
        };
        Ok(Self {
            source,
            info,
            path: path.to_path_buf(),
            regular,
            aedat_gyro: Vec::new(),
        })
    }

    /// Fills in sensor size, intrinsics and gyro from the files beside the recording
    /// (`meta.json`, `calib.txt`, `imu.txt`), reading only those that `needs` asks for.
    ///
    /// # Errors
    /// When a sidecar file that is read is malformed.
    pub fn complete_from_folder(&mut self, mut needs: Needs) -> Result<()> {
        if matches!(&self.source, Source::Aedat4(r) if r.has_imu) {
            // The file's own IMU stream is its gyro.
            needs.gyro = false;
        }
        super::meta::complete_from_folder(&self.path, &mut self.info, needs)
    }

    /// Whether the input is a regular file, which can be opened again for a second pass.
    #[must_use]
    pub fn is_regular_file(&self) -> bool {
        self.regular
    }

    /// The recording's path.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Replaces `out`'s content with the next events (in stream order); returns `false`, with
    /// `out` empty, once the recording is exhausted.
    ///
    /// # Errors
    /// When the file cannot be read or is malformed or truncated (the message names the file
    /// and the byte offset).
    pub fn next_chunk(&mut self, out: &mut Vec<Event64>) -> Result<bool> {
        out.clear();
        loop {
            let more = match &mut self.source {
                Source::Raw(r) => r.next_chunk(out)?,
                Source::Lines(r) => r.next_chunk(out, CHUNK_EVENTS)?,
                Source::Aedat4(r) => r.next_packet(out, &mut self.aedat_gyro)?,
                Source::Mvsec(r) => r.next_chunk(out)?,
            };
            // A chunk of words or a packet may hold no events: read on.
            if !more || !out.is_empty() {
                return Ok(more || !out.is_empty());
            }
        }
    }

    /// After the last chunk: the gyro samples of an AEDAT 4.0 file's IMU stream (when opened
    /// with `gyro` and the file has one), else the gyro found by `open` or the folder.
    pub fn take_gyro(&mut self) -> Option<Vec<GyroSample>> {
        match &self.source {
            Source::Aedat4(r) if r.has_imu => Some(std::mem::take(&mut self.aedat_gyro)),
            _ => self.info.gyro.take(),
        }
    }
}

/// A source of event chunks: a recording being read, or events in memory.
pub trait EventChunks {
    /// Replaces `out` with the next events (stream order); `false`, with `out` empty, at the
    /// end.
    ///
    /// # Errors
    /// When the input cannot be read or is malformed.
    fn next_chunk(&mut self, out: &mut Vec<Event64>) -> Result<bool>;
}

impl EventChunks for EventReader {
    fn next_chunk(&mut self, out: &mut Vec<Event64>) -> Result<bool> {
        Self::next_chunk(self, out)
    }
}

/// Events held in memory, handed out a chunk of [`CHUNK_EVENTS`] at a time.
pub struct EventsInMemory<'a> {
    events: &'a [Event64],
}

impl<'a> EventsInMemory<'a> {
    /// A source over `events`.
    pub fn new(events: &'a [Event64]) -> Self {
        Self { events }
    }
}

impl EventChunks for EventsInMemory<'_> {
    fn next_chunk(&mut self, out: &mut Vec<Event64>) -> Result<bool> {
        out.clear();
        let n = self.events.len().min(CHUNK_EVENTS);
        let (head, rest) = self.events.split_at(n);
        out.extend_from_slice(head);
        self.events = rest;
        Ok(n > 0)
    }
}
