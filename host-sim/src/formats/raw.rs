//! Prophesee `.raw` files: a text header of `% ` lines, then EVT 2.0 / 2.1 / 3.0 words.
//!
//! Header keys read (as Metavision/OpenEB does):
//! - `format EVT3;height=720;width=1280` (also `EVT2`, `EVT21`, option `endianness=legacy`);
//! - legacy `evt 2.0` / `evt 2.1` / `evt 3.0`;
//! - `geometry WxH`;
//! - `system_ID N` (decimal): the sensor size and default format of Prophesee's cameras when the
//!   header has neither `format` nor `geometry` (for example `21` = Gen3 VGA, 640x480, EVT 2.0);
//! - `endianness legacy` (EVT 2.1 with swapped 32-bit halves; also inferred, as OpenEB does, for
//!   Prophesee systems older than `system_ID` 0x37);
//! - `tde_time_offset_us N`: written by this project's EVT 3.0 writer when the first event is
//!   at or after 2^24 µs; added to every decoded time (other readers ignore it and see the times
//!   modulo 2^24 µs).
//!
//! The header ends at `% end` or at the first line that does not start with `%`.

use std::fs::File;
use std::io::{Read, Write};
use std::path::Path;

use anyhow::{bail, Context, Result};
use core_nostd::evt::{
    DecodeStats, EncodeError, Evt21Decoder, Evt2Decoder, Evt3Decoder, Evt3Encoder, StreamDecoder,
};

use super::{Event64, Format, Recording};

/// What a `.raw` header says.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RawHeader {
    /// Event format (from `format`, `evt` or `system_ID`).
    pub format: Option<Format>,
    /// Sensor width in px.
    pub width: Option<u16>,
    /// Sensor height in px.
    pub height: Option<u16>,
    /// EVT 2.1 with the legacy word layout (32-bit halves swapped).
    pub evt21_legacy: bool,
    /// `system_ID`, when present.
    pub system_id: Option<u32>,
    /// Offset of the first data byte (= header length in bytes).
    pub data_offset: usize,
    /// Added to every decoded time (µs): the `tde_time_offset_us` key, else 0.
    pub time_offset_us: u64,
    /// Whether the header ended inside the bytes given (`% end`, a non-`%` line or the end of
    /// the file after a complete line).
    pub complete: bool,
}

/// Default format and sensor size of Prophesee systems by `system_ID` (OpenEB's table of
/// systems whose headers predate the `format` key).
pub fn system_id_info(id: u32) -> Option<(Format, u16, u16)> {
    const VGA: (u16, u16) = (640, 480);
    const HD: (u16, u16) = (1280, 720);
    let (f, (w, h)) = match id {
        // Gen3.0 / Gen3.1 VGA (CCAM3/4/5, VisionCam, EVK2), EVT 2.0
        0x15 | 0x17 | 0x97 | 0x19 | 0x99 | 0x1D | 0x1C | 0x23 | 0x21 | 0xA1 | 0x22 | 0xA2
        | 0x29 => (Format::Evt2, VGA),
        // Gen3.1 VGA on EVK3, EVT 3.0
        0x28 => (Format::Evt3, VGA),
        // Gen4.0 / Gen4.1 HD, EVT 2.0 (CCAM3 Gen4, EVK2 Gen4, EVK2 Gen4.1)
        0x1A | 0x1F | 0x27 => (Format::Evt2, HD),
        // Gen4.0 HD (CCAM5), Gen4.1 HD (EVK3), IMX636 HD (EVK2/EVK3), EVT 3.0
        0x1E | 0x2E | 0x30 | 0x31 | 0x32 => (Format::Evt3, HD),
        _ => return None,
    };
    Some((f, w, h))
}

fn format_name(name: &str) -> Option<Format> {
    match name.trim().to_ascii_uppercase().as_str() {
        "EVT2" | "EVT2.0" | "2.0" => Some(Format::Evt2),
        "EVT21" | "EVT2.1" | "2.1" => Some(Format::Evt21),
        "EVT3" | "EVT3.0" | "3.0" => Some(Format::Evt3),
        _ => None,
    }
}

/// Parses the header at the start of `bytes` (never fails: unknown keys are ignored).
#[must_use]
pub fn parse_header(bytes: &[u8]) -> RawHeader {
    let mut h = RawHeader::default();
    let mut fmt_key: Option<Format> = None;
    let mut evt_key: Option<Format> = None;
    let (mut fw, mut fh) = (None, None);
    let (mut gw, mut gh) = (None, None);
    let mut legacy = None;
    let mut integrator: Option<String> = None;
    let mut pos = 0;
    while let Some(rest) = bytes.get(pos..) {
        if rest.first() != Some(&b'%') {
            h.complete = true;
            break;
        }
        let Some(nl) = rest.iter().position(|&b| b == b'\n') else {
            // A header line without its newline: complete only if these are all the bytes.
            break;
        };
        let line = rest.get(1..nl).unwrap_or_default();
        pos += nl + 1;
        let line = String::from_utf8_lossy(line);
        let line = line.trim();
        if line == "end" {
            h.complete = true;
            break;
        }
        let (key, value) = line.split_once(char::is_whitespace).unwrap_or((line, ""));
        let value = value.trim();
        match key {
            "format" => {
                let mut parts = value.split(';');
                fmt_key = parts.next().and_then(format_name);
                for opt in parts {
                    let (k, v) = opt.split_once('=').unwrap_or((opt, ""));
                    match k.trim() {
                        "width" => fw = v.trim().parse().ok(),
                        "height" => fh = v.trim().parse().ok(),
                        "endianness" => legacy = Some(v.trim() == "legacy"),
                        _ => {}
                    }
                }
            }
            "evt" => evt_key = format_name(value),
            "geometry" => {
                if let Some((w, hh)) = value.split_once('x') {
                    gw = w.trim().parse().ok();
                    gh = hh.trim().parse().ok();
                }
            }
            "system_ID" => {
                h.system_id = value.strip_prefix("0x").map_or_else(
                    || value.parse().ok(),
                    |hex| u32::from_str_radix(hex, 16).ok(),
                );
            }
            "endianness" => legacy = Some(value == "legacy"),
            "integrator_name" => integrator = Some(value.to_owned()),
            "tde_time_offset_us" => h.time_offset_us = value.parse().unwrap_or(0),
            _ => {}
        }
    }
    h.data_offset = pos;
    if pos >= bytes.len() {
        h.complete = true;
    }
    let sys = h.system_id.and_then(system_id_info);
    h.format = fmt_key.or(evt_key).or(sys.map(|s| s.0));
    let (w, hh) = match (fw, fh, gw, gh) {
        (Some(w), Some(hh), _, _) | (_, _, Some(w), Some(hh)) => (Some(w), Some(hh)),
        _ => (sys.map(|s| s.1), sys.map(|s| s.2)),
    };
    h.width = w.filter(|&v| v > 0);
    h.height = hh.filter(|&v| v > 0);
    let prophesee = integrator.as_deref().is_none_or(|i| i == "Prophesee");
    h.evt21_legacy =
        legacy.unwrap_or(prophesee && h.system_id.is_some_and(|id| id > 0 && id < 0x37));
    h
}

/// Most header bytes read before the data (a header without `% end` in them is an error).
const HEADER_MAX: usize = 1 << 20;
/// Bytes decoded at a time: at most 12 events per 2-byte word (EVT 3.0 vectors), so a chunk
/// holds at most ~800 k events (12 MB).
const CHUNK: usize = 128 * 1024;

/// The decoder of each word format.
enum Decoder {
    Evt3(Evt3Decoder),
    Evt2(Evt2Decoder),
    Evt21(Evt21Decoder),
}

impl Decoder {
    fn push<F: FnMut(core_nostd::event::Event64)>(&mut self, bytes: &[u8], sink: F) {
        match self {
            Self::Evt3(d) => d.push64(bytes, sink),
            Self::Evt2(d) => d.push64(bytes, sink),
            Self::Evt21(d) => d.push64(bytes, sink),
        }
    }
    fn finish(&self) -> Result<(), core_nostd::evt::Truncated> {
        match self {
            Self::Evt3(d) => d.finish(),
            Self::Evt2(d) => d.finish(),
            Self::Evt21(d) => d.finish(),
        }
    }
    fn stats(&self) -> DecodeStats {
        match self {
            Self::Evt3(d) => d.stats(),
            Self::Evt2(d) => d.stats(),
            Self::Evt21(d) => d.stats(),
        }
    }
    fn bytes_pushed(&self) -> u64 {
        match self {
            Self::Evt3(d) => d.bytes_pushed(),
            Self::Evt2(d) => d.bytes_pushed(),
            Self::Evt21(d) => d.bytes_pushed(),
        }
    }
}

/// The events of a `.raw` stream, decoded a chunk at a time (memory: the first MiB, which holds
/// the header, plus one chunk).
pub struct RawEvents<R> {
    r: R,
    path: std::path::PathBuf,
    format: Format,
    dec: Decoder,
    /// Data bytes read with the header, not yet decoded (from `head_pos`).
    head: Vec<u8>,
    head_pos: usize,
    data_start: usize,
    time_offset_us: u64,
    buf: Vec<u8>,
    done: bool,
}

impl<R: Read> RawEvents<R> {
    /// Reads the header from `r` (the content of `path`) and prepares to decode the data as
    /// `format` (which overrides the header's format).
    ///
    /// # Errors
    /// When the stream cannot be read or its header does not end within the first MiB.
    pub fn open(mut r: R, path: &Path, format: Format) -> Result<(Self, RawHeader)> {
        let mut buf = vec![0u8; HEADER_MAX];
        let first = super::read_up_to(&mut r, &mut buf)
            .with_context(|| format!("cannot read {}", path.display()))?;
        buf.truncate(first);
        let header = if buf.first() == Some(&b'%') {
            let h = parse_header(&buf);
            if !h.complete && first == HEADER_MAX {
                bail!(
                    "{}: Prophesee header longer than {HEADER_MAX} bytes (no `% end`)",
                    path.display()
                );
            }
            h
        } else {
            RawHeader {
                complete: true,
                ..RawHeader::default()
            }
        };
        let dec = match format {
            Format::Evt3 => Decoder::Evt3(Evt3Decoder::new()),
            Format::Evt2 => Decoder::Evt2(Evt2Decoder::new()),
            Format::Evt21 if header.evt21_legacy => Decoder::Evt21(Evt21Decoder::legacy()),
            Format::Evt21 => Decoder::Evt21(Evt21Decoder::new()),
            _ => bail!(
                "{}: {format} is not a Prophesee word format",
                path.display()
            ),
        };
        let data_start = header.data_offset.min(buf.len());
        let this = Self {
            r,
            path: path.to_path_buf(),
            format,
            dec,
            head: buf,
            head_pos: data_start,
            data_start,
            time_offset_us: header.time_offset_us,
            buf: Vec::new(),
            done: false,
        };
        Ok((this, header))
    }

    /// Appends the events of the next chunk of data to `out`; returns `false` at the end of the
    /// data (after checking that the stream ended cleanly).
    ///
    /// # Errors
    /// When the file cannot be read, or the stream is truncated or malformed (undefined word
    /// types, no TIME_HIGH): the message names the file and the byte offset.
    pub fn next_chunk(&mut self, out: &mut Vec<Event64>) -> Result<bool> {
        if self.done {
            return Ok(false);
        }
        let offset = self.time_offset_us;
        let mut sink = |e: core_nostd::event::Event64| {
            out.push(Event64 {
                t_us: e.t_us.wrapping_add(offset),
                x: e.x,
                y: e.y,
                on: e.on,
            });
        };
        if self.head_pos < self.head.len() {
            let end = (self.head_pos + CHUNK).min(self.head.len());
            self.dec.push(
                self.head.get(self.head_pos..end).unwrap_or_default(),
                &mut sink,
            );
            self.head_pos = end;
            if end == self.head.len() {
                self.head = Vec::new();
                self.head_pos = 0;
            }
        } else {
            self.buf.resize(CHUNK, 0);
            let n = super::read_up_to(&mut self.r, &mut self.buf)
                .with_context(|| format!("cannot read {}", self.path.display()))?;
            if n == 0 {
                self.done = true;
                self.check_end()?;
                return Ok(false);
            }
            self.dec
                .push(self.buf.get(..n).unwrap_or_default(), &mut sink);
        }
        let stats = self.dec.stats();
        if let Some(o) = stats.first_invalid_at {
            bail!(
                "{}: malformed {} stream: word of an undefined type at byte {} (wrong format?)",
                self.path.display(),
                self.format,
                o + self.data_start as u64
            );
        }
        Ok(true)
    }

    /// The decoder's counters so far (skipped triggers, OTHERS/CONTINUED words, time wraps).
    pub fn stats(&self) -> DecodeStats {
        self.dec.stats()
    }

    fn check_end(&self) -> Result<()> {
        let (path, format, data_start) = (self.path.display(), self.format, self.data_start);
        if let Err(t) = self.dec.finish() {
            bail!(
                "{path}: truncated {format} stream at byte {} ({} of {} bytes of the last word)",
                t.offset + data_start as u64,
                t.have,
                t.word_bytes
            );
        }
        if self.dec.bytes_pushed() > 0 && self.dec.stats().time_high == 0 {
            bail!(
                "{path}: malformed {format} stream: no TIME_HIGH word in {} bytes of data starting at byte {data_start}",
                self.dec.bytes_pushed()
            );
        }
        Ok(())
    }
}

/// Reads a whole `.raw` file as `format` (which overrides the header's format) and returns the
/// decoder's counters too. Sensor size comes from the header; intrinsics and gyro are left to
/// the caller.
///
/// # Errors
/// As [`RawEvents::next_chunk`].
pub fn read_raw(path: &Path, format: Format) -> Result<(Recording, DecodeStats)> {
    let file = File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let (mut raw, header) = RawEvents::open(file, path, format)?;
    let mut events = Vec::new();
    while raw.next_chunk(&mut events)? {}
    let rec = Recording {
        events,
        width: header.width,
        height: header.height,
        intrinsics: None,
        gyro: None,
        format,
    };
    Ok((rec, raw.stats()))
}

/// Largest step between consecutive event times that [`Evt3Writer`] encodes (2^40 µs, 12.7
/// days): EVT 3.0 spells a gap out as two TIME_HIGH words per 2^24 µs, so this caps one gap at
/// 256 KiB of output.
pub const MAX_EVT3_GAP_US: u64 = 1 << 40;

/// Writes events as Prophesee EVT 3.0 to a byte stream, as they come: the header (`evt 3.0`,
/// `format EVT3;height=H;width=W`, `geometry WxH`, and `tde_time_offset_us` when the first event
/// is at or after 2^24 µs), then the words.
pub struct Evt3Writer<'w, W: Write> {
    w: &'w mut W,
    out: &'w Path,
    width: u16,
    height: u16,
    enc: Option<Evt3Encoder>,
    bytes: Vec<u8>,
    index: u64,
    last_t: u64,
}

impl<'w, W: Write> Evt3Writer<'w, W> {
    /// A writer of a `width` x `height` recording into `w` (the content of `out`).
    pub fn new(w: &'w mut W, out: &'w Path, width: u16, height: u16) -> Self {
        Self {
            w,
            out,
            width,
            height,
            enc: None,
            bytes: Vec::with_capacity(64 * 1024 + 16),
            index: 0,
            last_t: 0,
        }
    }

    fn start(&mut self, first_t: u64) -> Result<Evt3Encoder> {
        let (w, h) = (self.width, self.height);
        let origin = Evt3Encoder::time_origin(first_t);
        let mut head =
            format!("% evt 3.0\n% format EVT3;height={h};width={w}\n% geometry {w}x{h}\n");
        if origin != 0 {
            head.push_str(&format!("% tde_time_offset_us {origin}\n"));
        }
        head.push_str("% end\n");
        self.w
            .write_all(head.as_bytes())
            .with_context(|| format!("cannot write {}", self.out.display()))?;
        Ok(Evt3Encoder::new())
    }

    /// Encodes the events (in non-decreasing time order, x and y < 2048).
    ///
    /// # Errors
    /// When an event cannot be encoded (the message names its index) or the file cannot be
    /// written.
    pub fn push(&mut self, events: &[Event64]) -> Result<()> {
        for e in events {
            let i = self.index;
            let mut enc = match self.enc.take() {
                Some(enc) => enc,
                None => {
                    self.last_t = e.t_us;
                    self.start(e.t_us)?
                }
            };
            let gap = e.t_us.saturating_sub(self.last_t);
            if gap > MAX_EVT3_GAP_US {
                bail!(
                    "event {i} at t = {} µs comes {gap} µs after the previous one: EVT 3.0 spells a gap out word by word, and gaps over {MAX_EVT3_GAP_US} µs (12.7 days) are refused",
                    e.t_us
                );
            }
            let bytes = &mut self.bytes;
            let pushed = enc.push(*e, |wd| bytes.extend_from_slice(&wd.to_le_bytes()));
            self.enc = Some(enc);
            pushed.map_err(|err| match err {
                EncodeError::TimeBackwards { t_us, previous_us } => anyhow::anyhow!(
                    "event {i} at t = {t_us} µs is earlier than the previous event ({previous_us} µs): EVT 3.0 needs events in time order"
                ),
                EncodeError::AddressOutOfRange { x, y } => {
                    anyhow::anyhow!("event {i} at ({x}, {y}) does not fit EVT 3.0's 11-bit addresses")
                }
            })?;
            self.last_t = e.t_us;
            self.index += 1;
            if self.bytes.len() >= 64 * 1024 {
                self.flush_bytes()?;
            }
        }
        Ok(())
    }

    fn flush_bytes(&mut self) -> Result<()> {
        self.w
            .write_all(&self.bytes)
            .with_context(|| format!("cannot write {}", self.out.display()))?;
        self.bytes.clear();
        Ok(())
    }

    /// Writes the last run (and the header, for a recording without events).
    ///
    /// # Errors
    /// When the file cannot be written.
    pub fn finish(mut self) -> Result<()> {
        let mut enc = match self.enc.take() {
            Some(enc) => enc,
            None => self.start(0)?,
        };
        let bytes = &mut self.bytes;
        enc.finish(|wd| bytes.extend_from_slice(&wd.to_le_bytes()));
        self.flush_bytes()
    }
}

/// Writes events as a Prophesee EVT 3.0 `.raw` file (see [`Evt3Writer`]). The size is
/// `width`/`height` when given, else the events' extent. The file appears complete or not at
/// all.
///
/// # Errors
/// When an event cannot be encoded (the message names its index) or the file cannot be written.
pub fn write_evt3(
    events: &[Event64],
    width: Option<u16>,
    height: Option<u16>,
    out: &Path,
) -> Result<()> {
    let extent = |f: fn(&Event64) -> u16| {
        events
            .iter()
            .map(f)
            .max()
            .map_or(1, |m| m.saturating_add(1))
    };
    let w = width.unwrap_or_else(|| extent(|e| e.x));
    let h = height.unwrap_or_else(|| extent(|e| e.y));
    crate::output::write_atomically(out, |wr| {
        let mut writer = Evt3Writer::new(wr, out, w, h);
        writer.push(events)?;
        writer.finish()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_keys() {
        let head = b"% evt 3.0\n% format EVT3;height=720;width=1280\n% geometry 1280x720\n% end\n";
        let h = parse_header(&[&head[..], b"\x00\x80"].concat());
        assert_eq!(h.format, Some(Format::Evt3));
        assert_eq!((h.width, h.height), (Some(1280), Some(720)));
        assert!(h.complete);
        assert_eq!(h.data_offset, head.len());
        let head = b"% Date 2020\n% system_ID 21\n% evt 2.0\n";
        let h = parse_header(&[&head[..], b"\xd0\xd8"].concat());
        assert_eq!(h.format, Some(Format::Evt2));
        assert_eq!((h.width, h.height), (Some(640), Some(480)));
        assert_eq!(h.data_offset, head.len());
        let h = parse_header(b"% geometry 346x260\n% format EVT21\n% end\n");
        assert_eq!(h.format, Some(Format::Evt21));
        assert_eq!((h.width, h.height), (Some(346), Some(260)));
        assert!(!h.evt21_legacy);
        let h = parse_header(b"% format EVT21;endianness=legacy;width=10;height=20\n");
        assert!(h.evt21_legacy);
        assert_eq!((h.width, h.height), (Some(10), Some(20)));
        let h = parse_header(b"% Date 2020\n");
        assert_eq!(h.format, None);
    }
}
