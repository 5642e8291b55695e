//! Semihosting: the command line, the AER stream from a host file, the yaw output file and the
//! summary file. Files are relative to QEMU's working directory.

use core::ffi::CStr;

use semihosting::fs::File;
use semihosting::io::{Read, Write};

use core_nostd::aer::link::LinkEvent;

use crate::app::{ByteSource, SourceError, YawSink};

/// The AER stream read through semihosting (`--input file`).
pub const EVENTS_FILE: &CStr = c"events.aer";
/// The yaw frames written by the firmware (binary, decoded by `host-sim yaw-decode`).
pub const YAW_FILE: &CStr = c"yaw.bin";
/// One line of counters for tools, written at the end.
pub const SUMMARY_FILE: &CStr = c"summary.txt";

/// The AER stream from a host file: ~400 MB/s, for streams larger than the 16 MiB flash.
pub struct HostFile {
    file: File,
}

impl HostFile {
    /// Opens [`EVENTS_FILE`].
    pub fn open() -> Option<Self> {
        File::open(EVENTS_FILE).ok().map(|file| Self { file })
    }
}

impl ByteSource for HostFile {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, SourceError> {
        self.file
            .read(buf)
            .map_err(|_| SourceError(LinkEvent::RingOverrun))
    }
}

/// Yaw frames into [`YAW_FILE`], through a 4 KiB buffer. Never drops (writes are synchronous).
pub struct YawFile {
    file: Option<File>,
    buf: heapless::Vec<u8, 4096>,
    /// Write errors (the host file could not be written).
    pub errors: u32,
}

impl YawFile {
    /// Creates (truncates) [`YAW_FILE`].
    pub fn create() -> Self {
        Self {
            file: File::create(YAW_FILE).ok(),
            buf: heapless::Vec::new(),
            errors: 0,
        }
    }

    /// Writes the buffered frames.
    pub fn flush(&mut self) {
        if let Some(f) = &mut self.file {
            if f.write_all(&self.buf).is_err() {
                self.errors += 1;
            }
        } else if !self.buf.is_empty() {
            self.errors += 1;
        }
        self.buf.clear();
    }
}

impl YawSink for YawFile {
    fn write(&mut self, frame: &[u8; core_nostd::aer::yaw::FRAME_BYTES]) -> bool {
        if self.buf.capacity() - self.buf.len() < frame.len() {
            self.flush();
        }
        self.buf.extend_from_slice(frame).is_ok()
    }
}

/// Writes `text` to [`SUMMARY_FILE`].
pub fn write_summary(text: &str) -> bool {
    semihosting::fs::write(SUMMARY_FILE, text.as_bytes()).is_ok()
}

/// Calls `f` with each command-line argument after the program name.
pub fn for_each_arg(mut f: impl FnMut(&str)) {
    let Ok(args) = semihosting::experimental::env::args::<1024>() else {
        return;
    };
    for arg in (&args).skip(1).flatten() {
        f(arg);
    }
}
