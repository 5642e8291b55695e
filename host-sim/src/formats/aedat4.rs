//! iniVation AEDAT 4.0: `#!AER-DAT4.0\r\n`, a `u32` length and an `IOHeader` FlatBuffer
//! (compression, position of the file data table, XML description of the streams), then packets:
//! `i32` stream id, `i32` size, and a body (uncompressed, an LZ4 frame or a zstd frame) holding a
//! size-prefixed FlatBuffer whose identifier names its type (`EVTS`, `IMUS`, `FRME`, `TRIG`).
//!
//! Read here: the first event stream (`EVTS`: 16-byte structs `t: i64 µs, x: i16, y: i16,
//! on: bool`) with its `sizeX`/`sizeY`, and the first IMU stream (`IMUS`: tables with `t`,
//! temperature, accelerometer (g), gyroscope (deg/s), magnetometer). Other streams are skipped.
//! FlatBuffers are checked by the `flatbuffers` verifier before any field is read.

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};
use flatbuffers::{
    Follow, ForwardsUOffset, InvalidFlatbuffer, SimpleToVerifyInSlice, Table, Vector, Verifiable,
    Verifier, VerifierOptions,
};

use super::{Event64, GyroSample};

const MAGIC: &[u8] = b"#!AER-DAT4.0\r\n";

/// `IOHeader` table: compression (slot 4, i32), data table position (slot 6, i64, -1 = none),
/// description XML (slot 8, string).
struct IoHeader<'a>(Table<'a>);

impl<'a> Follow<'a> for IoHeader<'a> {
    type Inner = Self;
    unsafe fn follow(buf: &'a [u8], loc: usize) -> Self {
        // SAFETY: forwarded contract of `Follow::follow` (verified buffer).
        Self(unsafe { Table::new(buf, loc) })
    }
}

impl Verifiable for IoHeader<'_> {
    fn run_verifier(v: &mut Verifier, pos: usize) -> Result<(), InvalidFlatbuffer> {
        v.visit_table(pos)?
            .visit_field::<i32>("compression", 4, false)?
            .visit_field::<i64>("dataTablePosition", 6, false)?
            .visit_field::<ForwardsUOffset<&str>>("infoNode", 8, false)?
            .finish();
        Ok(())
    }
}

impl<'a> IoHeader<'a> {
    fn compression(&self) -> i32 {
        // SAFETY: the buffer was verified with `IoHeader::run_verifier`, slot 4 is an i32.
        unsafe { self.0.get::<i32>(4, Some(0)) }.unwrap_or(0)
    }
    fn data_table_position(&self) -> i64 {
        // SAFETY: verified, slot 6 is an i64.
        unsafe { self.0.get::<i64>(6, Some(-1)) }.unwrap_or(-1)
    }
    fn info(&self) -> Option<&'a str> {
        // SAFETY: verified, slot 8 is an offset to a UTF-8 string.
        unsafe { self.0.get::<ForwardsUOffset<&str>>(8, None) }
    }
}

/// One `Event` struct of an `EventPacket` (16 bytes: t i64, x i16, y i16, on bool, padding).
#[derive(Clone, Copy)]
#[repr(transparent)]
struct RawEvent([u8; 16]);

impl SimpleToVerifyInSlice for RawEvent {}

impl<'a> Follow<'a> for RawEvent {
    type Inner = Self;
    unsafe fn follow(buf: &'a [u8], loc: usize) -> Self {
        let mut b = [0u8; 16];
        if let Some(s) = buf.get(loc..loc.saturating_add(16)) {
            b.copy_from_slice(s);
        }
        Self(b)
    }
}

/// `EventPacket` table: elements (slot 4, vector of `Event` structs).
struct EventPacket<'a>(Table<'a>);

impl<'a> Follow<'a> for EventPacket<'a> {
    type Inner = Self;
    unsafe fn follow(buf: &'a [u8], loc: usize) -> Self {
        // SAFETY: forwarded contract of `Follow::follow` (verified buffer).
        Self(unsafe { Table::new(buf, loc) })
    }
}

impl Verifiable for EventPacket<'_> {
    fn run_verifier(v: &mut Verifier, pos: usize) -> Result<(), InvalidFlatbuffer> {
        v.visit_table(pos)?
            .visit_field::<ForwardsUOffset<Vector<'_, RawEvent>>>("elements", 4, false)?
            .finish();
        Ok(())
    }
}

impl<'a> EventPacket<'a> {
    /// The raw bytes of the elements vector (a multiple of 16).
    fn element_bytes(&self) -> &'a [u8] {
        // SAFETY: verified, slot 4 is an offset to a vector of 16-byte structs.
        unsafe { self.0.get::<ForwardsUOffset<Vector<'a, RawEvent>>>(4, None) }
            .map_or(&[][..], |v| v.bytes())
    }
}

/// `Imu` table: t (slot 4, i64 µs), temperature (6), accelerometer x/y/z (8, 10, 12, g),
/// gyroscope x/y/z (14, 16, 18, deg/s), magnetometer x/y/z (20, 22, 24); floats are f32.
struct Imu<'a>(Table<'a>);

impl<'a> Follow<'a> for Imu<'a> {
    type Inner = Self;
    unsafe fn follow(buf: &'a [u8], loc: usize) -> Self {
        // SAFETY: forwarded contract of `Follow::follow` (verified buffer).
        Self(unsafe { Table::new(buf, loc) })
    }
}

impl Verifiable for Imu<'_> {
    fn run_verifier(v: &mut Verifier, pos: usize) -> Result<(), InvalidFlatbuffer> {
        let mut t = v.visit_table(pos)?.visit_field::<i64>("t", 4, false)?;
        for slot in (6..=24).step_by(2) {
            t = t.visit_field::<f32>("float", slot, false)?;
        }
        t.finish();
        Ok(())
    }
}

impl Imu<'_> {
    fn t(&self) -> i64 {
        // SAFETY: verified, slot 4 is an i64.
        unsafe { self.0.get::<i64>(4, Some(0)) }.unwrap_or(0)
    }
    fn f(&self, slot: u16) -> f32 {
        // SAFETY: verified, slots 6..=24 are f32.
        unsafe { self.0.get::<f32>(slot, Some(0.0)) }.unwrap_or(0.0)
    }
}

/// `ImuPacket` table: elements (slot 4, vector of `Imu` tables).
struct ImuPacket<'a>(Table<'a>);

impl<'a> Follow<'a> for ImuPacket<'a> {
    type Inner = Self;
    unsafe fn follow(buf: &'a [u8], loc: usize) -> Self {
        // SAFETY: forwarded contract of `Follow::follow` (verified buffer).
        Self(unsafe { Table::new(buf, loc) })
    }
}

impl Verifiable for ImuPacket<'_> {
    fn run_verifier(v: &mut Verifier, pos: usize) -> Result<(), InvalidFlatbuffer> {
        v.visit_table(pos)?
            .visit_field::<ForwardsUOffset<Vector<'_, ForwardsUOffset<Imu<'_>>>>>(
                "elements", 4, false,
            )?
            .finish();
        Ok(())
    }
}

impl<'a> ImuPacket<'a> {
    fn elements(&self) -> Option<Vector<'a, ForwardsUOffset<Imu<'a>>>> {
        // SAFETY: verified, slot 4 is an offset to a vector of offsets to `Imu` tables.
        unsafe {
            self.0
                .get::<ForwardsUOffset<Vector<'a, ForwardsUOffset<Imu<'a>>>>>(4, None)
        }
    }
}

/// Stream kinds of the description.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Events,
    Imu,
    Other,
}

struct Stream {
    id: i32,
    kind: Kind,
    size: Option<(u16, u16)>,
}

/// Streams of the XML description: `<dv><node name="outInfo"><node name="ID">` with
/// `typeIdentifier` and `<node name="info">` `sizeX`/`sizeY`.
fn parse_streams(xml: &str) -> Result<Vec<Stream>, String> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| e.to_string())?;
    let attr = |n: roxmltree::Node, key: &str| {
        n.children()
            .find(|c| c.has_tag_name("attr") && c.attribute("key") == Some(key))
            .and_then(|c| c.text())
            .map(|t| t.trim().to_owned())
    };
    let out_info = doc
        .descendants()
        .find(|n| n.has_tag_name("node") && n.attribute("name") == Some("outInfo"))
        .ok_or("no `outInfo` node in the description")?;
    let mut streams = Vec::new();
    for node in out_info.children().filter(|n| n.has_tag_name("node")) {
        let Some(id) = node.attribute("name").and_then(|s| s.parse::<i32>().ok()) else {
            continue;
        };
        let identifier = attr(node, "typeIdentifier").unwrap_or_default();
        let kind = match identifier.as_str() {
            "EVTS" => Kind::Events,
            "IMUS" => Kind::Imu,
            _ => Kind::Other,
        };
        let info = node
            .children()
            .find(|n| n.has_tag_name("node") && n.attribute("name") == Some("info"));
        let size = info.and_then(|i| {
            let w = attr(i, "sizeX")?.parse::<u16>().ok()?;
            let h = attr(i, "sizeY")?.parse::<u16>().ok()?;
            Some((w, h))
        });
        streams.push(Stream { id, kind, size });
    }
    Ok(streams)
}

/// Most bytes one packet may hold, compressed or decompressed (64 MiB, 4 M events): a packet
/// that declares more is refused rather than allocated.
pub const MAX_PACKET_BYTES: usize = 64 << 20;

fn opts() -> VerifierOptions {
    VerifierOptions {
        max_tables: usize::MAX,
        max_apparent_size: usize::MAX,
        ..VerifierOptions::default()
    }
}

/// Decompresses one packet body into `plain`: the size prefix of its FlatBuffer first, then
/// exactly the bytes that prefix declares (at most [`MAX_PACKET_BYTES`]), so that a small
/// packet cannot expand into gigabytes.
fn decompress(
    mut dec: impl Read,
    plain: &mut Vec<u8>,
    what: &str,
    pos: u64,
) -> std::result::Result<(), String> {
    plain.clear();
    let mut len4 = [0u8; 4];
    let n = super::read_up_to(&mut dec, &mut len4)
        .map_err(|e| format!("corrupt {what} packet at byte {pos}: {e}"))?;
    if n < 4 {
        return Err(format!(
            "corrupt {what} packet at byte {pos}: {n} bytes of data, not even a FlatBuffer size"
        ));
    }
    let declared = u32::from_le_bytes(len4) as usize;
    if declared > MAX_PACKET_BYTES - 4 {
        return Err(format!(
            "{what} packet at byte {pos} declares {declared} bytes of data, more than the {MAX_PACKET_BYTES} this reader accepts"
        ));
    }
    plain.extend_from_slice(&len4);
    dec.take(declared as u64)
        .read_to_end(plain)
        .map_err(|e| format!("corrupt {what} packet at byte {pos}: {e}"))?;
    if plain.len() < declared + 4 {
        return Err(format!(
            "corrupt {what} packet at byte {pos}: decompresses to {} bytes, its FlatBuffer declares {declared}",
            plain.len() - 4
        ));
    }
    Ok(())
}

/// An AEDAT 4.0 stream read packet by packet (memory: one packet).
pub struct Aedat4Reader<R> {
    r: BufReader<R>,
    path: std::path::PathBuf,
    /// File length, when the input is a regular file (packet sizes are checked against it).
    file_len: Option<u64>,
    compression: i32,
    table_pos: i64,
    stream_ids: Vec<i32>,
    ev_id: Option<i32>,
    imu_id: Option<i32>,
    /// Sensor size of the event stream.
    pub size: Option<(u16, u16)>,
    /// Whether the file has an IMU stream.
    pub has_imu: bool,
    want_events: bool,
    want_imu: bool,
    pos: u64,
    body: Vec<u8>,
    plain: Vec<u8>,
    done: bool,
}

impl<R: Read> Aedat4Reader<R> {
    /// Reads the file header from `r` (the content of `path`, `file_len` bytes long when known).
    ///
    /// # Errors
    /// When the header is truncated or malformed, or the wanted stream is missing.
    pub fn open(
        r: R,
        path: &Path,
        file_len: Option<u64>,
        want_events: bool,
        want_imu: bool,
    ) -> Result<Self> {
        let p = path.display();
        let mut r = BufReader::with_capacity(1 << 20, r);
        let io = |e: std::io::Error| anyhow!("cannot read {p}: {e}");
        let mut magic = [0u8; 14];
        let n = super::read_up_to(&mut r, &mut magic).map_err(io)?;
        if n < MAGIC.len() || magic != MAGIC {
            bail!("{p}: not an AEDAT 4.0 file (no `#!AER-DAT4.0` line at byte 0)");
        }
        let mut len4 = [0u8; 4];
        if super::read_up_to(&mut r, &mut len4).map_err(io)? < 4 {
            bail!("{p}: truncated AEDAT 4.0 header at byte 14");
        }
        let header_len = u32::from_le_bytes(len4) as usize;
        let room = file_len.map_or(MAX_PACKET_BYTES as u64, |l| l.saturating_sub(18));
        if header_len as u64 > room {
            bail!("{p}: truncated AEDAT 4.0 header at byte 18: declares {header_len} bytes, the file has {room}");
        }
        // The header is a size-prefixed FlatBuffer starting at byte 14 (alignment counts from
        // there).
        let mut header = vec![0u8; header_len + 4];
        header
            .get_mut(..4)
            .unwrap_or_default()
            .copy_from_slice(&len4);
        if super::read_up_to(&mut r, header.get_mut(4..).unwrap_or_default()).map_err(io)?
            < header_len
        {
            bail!("{p}: truncated AEDAT 4.0 header at byte 18");
        }
        let ioh = flatbuffers::size_prefixed_root_with_opts::<IoHeader>(&opts(), &header)
            .map_err(|e| anyhow!("{p}: malformed AEDAT 4.0 header at byte 18: {e}"))?;
        let compression = ioh.compression();
        if !(0..=4).contains(&compression) {
            bail!("{p}: unknown AEDAT 4.0 compression {compression} in the header at byte 18");
        }
        let table_pos = ioh.data_table_position();
        let info = ioh.info().ok_or_else(|| {
            anyhow!("{p}: malformed AEDAT 4.0 header at byte 18: no stream description")
        })?;
        let streams = parse_streams(info)
            .map_err(|e| anyhow!("{p}: malformed AEDAT 4.0 stream description at byte 18: {e}"))?;
        let ev_stream = streams.iter().find(|s| s.kind == Kind::Events);
        let imu_stream = streams.iter().find(|s| s.kind == Kind::Imu);
        let ev_id = ev_stream.map(|s| s.id);
        let imu_id = imu_stream.map(|s| s.id);
        if want_events && ev_id.is_none() {
            bail!("{p}: the AEDAT 4.0 file has no event (EVTS) stream");
        }
        if want_imu && !want_events && imu_id.is_none() {
            bail!("{p}: the AEDAT 4.0 file has no IMU (IMUS) stream");
        }
        Ok(Self {
            r,
            path: path.to_path_buf(),
            file_len,
            compression,
            table_pos,
            stream_ids: streams.iter().map(|s| s.id).collect(),
            ev_id,
            imu_id,
            size: ev_stream.and_then(|s| s.size),
            has_imu: imu_id.is_some(),
            want_events,
            want_imu,
            pos: 18 + header_len as u64,
            body: Vec::new(),
            plain: Vec::new(),
            done: false,
        })
    }

    /// Reads packets up to the next wanted one and appends its events or gyro samples; returns
    /// `false` at the end of the file.
    ///
    /// # Errors
    /// When a packet is truncated, corrupt or malformed (the message names its byte offset).
    pub fn next_packet(
        &mut self,
        events: &mut Vec<Event64>,
        gyro: &mut Vec<GyroSample>,
    ) -> Result<bool> {
        let p = self.path.display();
        let io = |e: std::io::Error| anyhow!("cannot read {p}: {e}");
        loop {
            if self.done {
                return Ok(false);
            }
            let (pos, table_pos) = (self.pos, self.table_pos);
            if table_pos >= 0 && pos == table_pos as u64 {
                self.done = true;
                return Ok(false);
            }
            let mut ph = [0u8; 8];
            let got = super::read_up_to(&mut self.r, &mut ph).map_err(io)?;
            if got == 0 {
                if table_pos >= 0 && (table_pos as u64) > pos {
                    bail!("{p}: truncated AEDAT 4.0 file at byte {pos}: the header announces the file data table at byte {table_pos}");
                }
                self.done = true;
                return Ok(false);
            }
            if got < 8 {
                bail!("{p}: truncated AEDAT 4.0 packet header at byte {pos}");
            }
            let [a, b, c, d, e, f, g, h] = ph;
            let stream = i32::from_le_bytes([a, b, c, d]);
            let size = i32::from_le_bytes([e, f, g, h]);
            if size < 0 {
                bail!("{p}: malformed AEDAT 4.0 packet at byte {pos}: negative size {size}");
            }
            let size = size as usize;
            if let Some(len) = self.file_len {
                if pos + 8 + size as u64 > len {
                    bail!(
                        "{p}: truncated AEDAT 4.0 packet at byte {pos}: declares {size} bytes, the file has {} after its header",
                        len.saturating_sub(pos + 8)
                    );
                }
            }
            if !self.stream_ids.contains(&stream) {
                bail!("{p}: malformed AEDAT 4.0 packet at byte {pos}: stream id {stream} is not in the file's description");
            }
            let wanted = (self.want_events && Some(stream) == self.ev_id)
                || (self.want_imu && Some(stream) == self.imu_id);
            if !wanted {
                let skipped =
                    std::io::copy(&mut (&mut self.r).take(size as u64), &mut std::io::sink())
                        .map_err(io)?;
                if skipped < size as u64 {
                    bail!("{p}: truncated AEDAT 4.0 packet at byte {pos}");
                }
                self.pos += 8 + size as u64;
                continue;
            }
            if size > MAX_PACKET_BYTES {
                bail!("{p}: AEDAT 4.0 packet at byte {pos} declares {size} bytes, more than the {MAX_PACKET_BYTES} this reader accepts");
            }
            self.body.resize(size, 0);
            if super::read_up_to(&mut self.r, &mut self.body).map_err(io)? < size {
                bail!("{p}: truncated AEDAT 4.0 packet at byte {pos}");
            }
            let data: &[u8] = match self.compression {
                0 => &self.body,
                1 | 2 => {
                    decompress(
                        lz4_flex::frame::FrameDecoder::new(&self.body[..]),
                        &mut self.plain,
                        "LZ4",
                        pos,
                    )
                    .map_err(|e| anyhow!("{p}: {e}"))?;
                    &self.plain
                }
                _ => {
                    let dec = zstd::stream::read::Decoder::with_buffer(&self.body[..])
                        .map_err(|e| anyhow!("{p}: corrupt zstd packet at byte {pos}: {e}"))?;
                    decompress(dec, &mut self.plain, "zstd", pos)
                        .map_err(|e| anyhow!("{p}: {e}"))?;
                    &self.plain
                }
            };
            if Some(stream) == self.ev_id {
                events_of(data, events)
                    .map_err(|e| anyhow!("{p}: malformed AEDAT 4.0 packet at byte {pos}: {e}"))?;
            } else {
                gyro_of(data, gyro)
                    .map_err(|e| anyhow!("{p}: malformed AEDAT 4.0 packet at byte {pos}: {e}"))?;
            }
            self.pos += 8 + size as u64;
            return Ok(true);
        }
    }
}

/// Appends the events of a decompressed `EVTS` packet.
fn events_of(data: &[u8], out: &mut Vec<Event64>) -> std::result::Result<(), String> {
    if !flatbuffers::buffer_has_identifier(data, "EVTS", true) {
        return Err("stream says events, packet is not EVTS".into());
    }
    let pkt = flatbuffers::size_prefixed_root_with_opts::<EventPacket>(&opts(), data)
        .map_err(|e| e.to_string())?;
    let (chunks, _) = pkt.element_bytes().as_chunks::<16>();
    out.reserve(chunks.len());
    for ev in chunks {
        let [t0, t1, t2, t3, t4, t5, t6, t7, x0, x1, y0, y1, on, ..] = *ev;
        let t = i64::from_le_bytes([t0, t1, t2, t3, t4, t5, t6, t7]);
        let x = i16::from_le_bytes([x0, x1]);
        let y = i16::from_le_bytes([y0, y1]);
        let (Ok(t_us), Ok(x), Ok(y)) = (u64::try_from(t), u16::try_from(x), u16::try_from(y))
        else {
            return Err(format!(
                "event with negative time or address (t = {t}, x = {x}, y = {y})"
            ));
        };
        out.push(Event64 {
            t_us,
            x,
            y,
            on: on != 0,
        });
    }
    Ok(())
}

/// Appends the gyro samples (rad/s) of a decompressed `IMUS` packet.
fn gyro_of(data: &[u8], out: &mut Vec<GyroSample>) -> std::result::Result<(), String> {
    if !flatbuffers::buffer_has_identifier(data, "IMUS", true) {
        return Err("stream says IMU, packet is not IMUS".into());
    }
    let pkt = flatbuffers::size_prefixed_root_with_opts::<ImuPacket>(&opts(), data)
        .map_err(|e| e.to_string())?;
    for imu in pkt.elements().iter().flat_map(|v| v.iter()) {
        out.push(GyroSample {
            t_s: imu.t() as f64 * 1e-6,
            wx: f64::from(imu.f(14)).to_radians(),
            wy: f64::from(imu.f(16)).to_radians(),
            wz: f64::from(imu.f(18)).to_radians(),
        });
    }
    Ok(())
}

/// The IMU stream of an AEDAT 4.0 file as gyro samples (deg/s converted to rad/s), read a
/// packet at a time.
pub(super) struct GyroPackets {
    r: Aedat4Reader<File>,
    /// Never filled (the events are not read).
    events: Vec<Event64>,
}

impl GyroPackets {
    /// Opens `path` and reads its header.
    pub(super) fn open(path: &Path) -> Result<Self> {
        let file = File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
        let len = file
            .metadata()
            .ok()
            .filter(|m| m.is_file())
            .map(|m| m.len());
        Ok(Self {
            r: Aedat4Reader::open(file, path, len, false, true)?,
            events: Vec::new(),
        })
    }

    /// Replaces `out` with the samples of the next IMU packet that has any; false, with `out`
    /// empty, at the end of the file.
    pub(super) fn next_chunk(&mut self, out: &mut Vec<GyroSample>) -> Result<bool> {
        out.clear();
        while out.is_empty() {
            if !self.r.next_packet(&mut self.events, out)? {
                return Ok(false);
            }
        }
        Ok(true)
    }
}
