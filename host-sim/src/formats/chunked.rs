//! Reading in chunks: text files a line at a time ([`TextLines`]), a reader's samples
//! [`CHUNK`] at a time ([`fill`]), and back into one vector ([`collect`]). Shared by the
//! ground-truth and gyro readers of every format ([`super::rates`]), so that the whole-file
//! readers are the chunked ones collected.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use super::text;

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
