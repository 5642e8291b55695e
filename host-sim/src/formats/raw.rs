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
use std::io::Write;
use std::path::Path;

use anyhow::{bail, Context, Result};
use core_nostd::evt::{
    DecodeStats, EncodeError, Evt21Decoder, Evt2Decoder, Evt3Decoder, Evt3Encoder, StreamDecoder,
};

use super::{Format, HostEvent, Recording};

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

/// Read size for streaming decode (bytes).
const CHUNK: usize = 1 << 20;

/// Reads a `.raw` file as `format` (which overrides the header's format) and returns the
/// decoder's counters too (skipped triggers, OTHERS/CONTINUED words, time wraps). Sensor size
/// comes from the header; intrinsics and gyro are left to the caller.
///
/// # Errors
/// When the file cannot be read, or the stream is truncated or malformed (undefined word types,
/// no TIME_HIGH): the message names the file and the byte offset.
pub fn read_raw(path: &Path, format: Format) -> Result<(Recording, DecodeStats)> {
    let mut file = File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let file_len = file.metadata().map(|m| m.len()).unwrap_or(0);
    let mut buf = vec![0u8; CHUNK];
    let first = super::read_up_to(&mut file, &mut buf)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let header = if buf.first() == Some(&b'%') && first > 0 {
        let h = parse_header(buf.get(..first).unwrap_or_default());
        if !h.complete && first == CHUNK {
            bail!(
                "{}: Prophesee header longer than {CHUNK} bytes (no `% end`)",
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
    let data_start = header.data_offset;
    let mut events = Vec::with_capacity((file_len.saturating_sub(data_start as u64) / 3) as usize);
    let offset = header.time_offset_us;
    let head_data = buf.get(data_start..first).unwrap_or_default().to_vec();
    let mut data = DataPart {
        path,
        format,
        file: &mut file,
        head: &head_data,
        data_start,
        time_offset_us: offset,
        events: &mut events,
    };
    let stats = match format {
        Format::Evt3 => data.decode(Evt3Decoder::new())?,
        Format::Evt2 => data.decode(Evt2Decoder::new())?,
        Format::Evt21 if header.evt21_legacy => data.decode(Evt21Decoder::legacy())?,
        Format::Evt21 => data.decode(Evt21Decoder::new())?,
        _ => bail!(
            "{}: {format} is not a Prophesee word format",
            path.display()
        ),
    };
    let rec = Recording {
        events,
        width: header.width,
        height: header.height,
        intrinsics: None,
        gyro: None,
        format,
    };
    Ok((rec, stats))
}

/// The data part of a `.raw` file: its first bytes (read with the header), the rest of the
/// file, and where the decoded events go.
struct DataPart<'a> {
    path: &'a Path,
    format: Format,
    file: &'a mut File,
    /// Data bytes already read with the header.
    head: &'a [u8],
    /// File offset of the first data byte.
    data_start: usize,
    /// Added to every event time (µs).
    time_offset_us: u64,
    events: &'a mut Vec<HostEvent>,
}

impl DataPart<'_> {
    /// Streams the data through `dec` into `events`.
    fn decode<D: StreamDecoder>(&mut self, mut dec: D) -> Result<DecodeStats> {
        let (path, format, data_start) = (self.path, self.format, self.data_start);
        let time_offset_us = self.time_offset_us;
        let events = &mut *self.events;
        let mut sink = |e: core_nostd::event::Event64| {
            events.push(HostEvent {
                t_us: e.t_us.wrapping_add(time_offset_us),
                x: e.x,
                y: e.y,
                on: e.on,
            });
        };
        dec.push64(self.head, &mut sink);
        let mut buf = vec![0u8; CHUNK];
        loop {
            let n = super::read_up_to(self.file, &mut buf)
                .with_context(|| format!("cannot read {}", path.display()))?;
            if n == 0 {
                break;
            }
            dec.push64(buf.get(..n).unwrap_or_default(), &mut sink);
        }
        let stats = dec.stats();
        let at = |o: u64| o + data_start as u64;
        if let Err(t) = dec.finish() {
            bail!(
                "{}: truncated {format} stream at byte {} ({} of {} bytes of the last word)",
                path.display(),
                at(t.offset),
                t.have,
                t.word_bytes
            );
        }
        if let Some(o) = stats.first_invalid_at {
            bail!(
                "{}: malformed {format} stream: word of an undefined type at byte {} ({} such words; wrong format?)",
                path.display(),
                at(o),
                stats.invalid
            );
        }
        if dec.bytes_pushed() > 0 && stats.time_high == 0 {
            bail!(
                "{}: malformed {format} stream: no TIME_HIGH word in {} bytes of data starting at byte {data_start}",
                path.display(),
                dec.bytes_pushed()
            );
        }
        Ok(stats)
    }
}

/// Writes events as a Prophesee EVT 3.0 `.raw` file with a header (`evt 3.0`,
/// `format EVT3;height=H;width=W`, `geometry WxH`, and `tde_time_offset_us` when the first event
/// is at or after 2^24 µs). The size is `width`/`height` when given, else the events' extent.
/// Events must be in non-decreasing time order with x, y < 2048. The file appears complete or not
/// at all.
///
/// # Errors
/// When an event cannot be encoded (the message names its index) or the file cannot be written.
pub fn write_evt3(
    events: &[HostEvent],
    width: Option<u16>,
    height: Option<u16>,
    out: &Path,
) -> Result<()> {
    let extent = |f: fn(&HostEvent) -> u16| {
        events
            .iter()
            .map(f)
            .max()
            .map_or(1, |m| m.saturating_add(1))
    };
    let w = width.unwrap_or_else(|| extent(|e| e.x));
    let h = height.unwrap_or_else(|| extent(|e| e.y));
    let origin = events
        .first()
        .map_or(0, |e| Evt3Encoder::time_origin(e.t_us));
    crate::output::write_atomically(out, |wr| {
        let mut head =
            format!("% evt 3.0\n% format EVT3;height={h};width={w}\n% geometry {w}x{h}\n");
        if origin != 0 {
            head.push_str(&format!("% tde_time_offset_us {origin}\n"));
        }
        head.push_str("% end\n");
        wr.write_all(head.as_bytes())
            .with_context(|| format!("cannot write {}", out.display()))?;
        let mut enc = Evt3Encoder::new();
        let mut bytes: Vec<u8> = Vec::with_capacity(64 * 1024 + 16);
        for (i, e) in events.iter().enumerate() {
            enc.push((*e).into(), |wd| bytes.extend_from_slice(&wd.to_le_bytes())).map_err(|err| match err {
                EncodeError::TimeBackwards { t_us, previous_us } => anyhow::anyhow!(
                    "event {i} at t = {t_us} µs is earlier than the previous event ({previous_us} µs): EVT 3.0 needs events in time order"
                ),
                EncodeError::AddressOutOfRange { x, y } => {
                    anyhow::anyhow!("event {i} at ({x}, {y}) does not fit EVT 3.0's 11-bit addresses")
                }
            })?;
            if bytes.len() >= 64 * 1024 {
                wr.write_all(&bytes)
                    .with_context(|| format!("cannot write {}", out.display()))?;
                bytes.clear();
            }
        }
        enc.finish(|wd| bytes.extend_from_slice(&wd.to_le_bytes()));
        wr.write_all(&bytes)
            .with_context(|| format!("cannot write {}", out.display()))?;
        Ok(())
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
