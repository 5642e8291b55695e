//! AER-over-SPI frames: header, checks, encoding, and the streaming [`FrameDecoder`].
//!
//! ```text
//! offset  size  field
//!      0     2  sync 0xA5 0xE7
//!      2     1  version (bits 7..4, = 1) | payload kind (bits 3..0: 1 AER events, 2 EVT 3.0
//!               words, 3 configuration)
//!      3     1  flags: bit 0 SOURCE_OVERFLOW, bit 1 STREAM_START, bits 7..2 reserved (sent 0, ignored)
//!      4     2  sequence counter (u16 LE, +1 per frame, wraps)
//!      6     2  payload length in bytes (u16 LE, <= 1024; AER: 4 + 4k, EVT 3.0: even)
//!      8     2  header check: CRC-16/IBM-3740 of bytes 0..8 (LE)
//!     10     n  payload
//!   10+n     4  CRC-32/ISO-HDLC of bytes 0..10+n (LE)
//! ```
//!
//! The header check lets a receiver reject a false sync pattern at once instead of waiting for
//! the bytes of an invented length; the CRC-32 covers the whole frame.

use super::crc::{crc16, crc32};
use super::framer::{FrameSpec, Framer, FramerStats, Header};

/// The two bytes every AER frame starts with.
pub const SYNC: [u8; 2] = [0xA5, 0xE7];
/// Format version carried in every header.
pub const VERSION: u8 = 1;
/// Header bytes (sync to header check).
pub const HEADER_BYTES: usize = 10;
/// Trailer bytes (CRC-32).
pub const TRAILER_BYTES: usize = 4;
/// Bytes of a frame besides its payload.
pub const OVERHEAD_BYTES: usize = HEADER_BYTES + TRAILER_BYTES;
/// Largest payload in bytes.
pub const MAX_PAYLOAD: usize = 1024;
/// Largest frame in bytes.
pub const MAX_FRAME: usize = OVERHEAD_BYTES + MAX_PAYLOAD;

/// Header flags.
pub mod flags {
    /// The sender lost events before this frame (its own buffer overflowed).
    pub const SOURCE_OVERFLOW: u8 = 1 << 0;
    /// First frame of a stream: the receiver restarts its sequence tracking (no gap is counted)
    /// and its EVT 3.0 decoder.
    pub const STREAM_START: u8 = 1 << 1;
}

/// What a frame's payload holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kind {
    /// AER events (see [`super::events`]).
    Events = 1,
    /// Raw Prophesee EVT 3.0 bytes (16-bit LE words), decoded with [`crate::evt::Evt3Decoder`].
    Evt3 = 2,
    /// A configuration (camera, network, output rate; see [`super::config`]).
    Config = 3,
}

impl Kind {
    /// The kind of a header's low nibble.
    #[must_use]
    pub const fn from_nibble(n: u8) -> Option<Self> {
        match n {
            1 => Some(Self::Events),
            2 => Some(Self::Evt3),
            3 => Some(Self::Config),
            _ => None,
        }
    }

    /// Whether `len` payload bytes are allowed for this kind.
    #[must_use]
    pub const fn payload_len_ok(self, len: usize) -> bool {
        if len > MAX_PAYLOAD {
            return false;
        }
        match self {
            Self::Events => len >= 4 && len.is_multiple_of(4),
            Self::Evt3 => len.is_multiple_of(2),
            Self::Config => len >= 4 && len <= 64 && len.is_multiple_of(4),
        }
    }
}

/// One intact frame, borrowed from the decoder's buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame<'a> {
    /// Payload kind.
    pub kind: Kind,
    /// Header flags (see [`flags`]).
    pub flags: u8,
    /// Sequence counter.
    pub seq: u16,
    /// Payload bytes.
    pub payload: &'a [u8],
}

/// The frame format, for the [`Framer`].
#[derive(Clone, Copy, Debug)]
pub struct AerSpec;

fn le16(b: &[u8], at: usize) -> u16 {
    match b.get(at..at + 2) {
        Some(&[lo, hi]) => u16::from_le_bytes([lo, hi]),
        _ => 0,
    }
}

fn le32(b: &[u8], at: usize) -> u32 {
    match b.get(at..at + 4) {
        Some(&[a, b, c, d]) => u32::from_le_bytes([a, b, c, d]),
        _ => 0,
    }
}

impl FrameSpec for AerSpec {
    const SYNC: [u8; 2] = SYNC;
    const HEADER: usize = HEADER_BYTES;
    const MAX_FRAME: usize = MAX_FRAME;

    fn header(h: &[u8]) -> Header {
        if crc16(h.get(..8).unwrap_or_default()) != le16(h, 8) {
            return Header::NotAFrame;
        }
        let vk = h.get(2).copied().unwrap_or(0);
        let len = usize::from(le16(h, 6));
        match Kind::from_nibble(vk & 0x0F) {
            Some(kind) if vk >> 4 == VERSION && kind.payload_len_ok(len) => {
                Header::Frame(OVERHEAD_BYTES + len)
            }
            _ => Header::Invalid,
        }
    }

    fn check(frame: &[u8]) -> bool {
        let n = frame.len().saturating_sub(TRAILER_BYTES);
        crc32(frame.get(..n).unwrap_or_default()) == le32(frame, n)
    }
}

/// Parses a frame that passed [`AerSpec::check`].
fn parse(frame: &[u8]) -> Option<Frame<'_>> {
    let kind = Kind::from_nibble(frame.get(2)? & 0x0F)?;
    let len = usize::from(le16(frame, 6));
    Some(Frame {
        kind,
        flags: *frame.get(3)?,
        seq: le16(frame, 4),
        payload: frame.get(HEADER_BYTES..HEADER_BYTES + len)?,
    })
}

/// Why a frame could not be encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EncodeFrameError {
    /// The payload length is not allowed for its kind (see [`Kind::payload_len_ok`]).
    PayloadLength(usize),
    /// The output buffer is shorter than the frame.
    BufferTooSmall {
        /// Bytes the frame needs.
        needed: usize,
    },
}

/// Writes one frame into `out` and returns its length (`OVERHEAD_BYTES + payload.len()`).
///
/// # Errors
/// When the payload length is not allowed for `kind`, or `out` is too short.
pub fn encode_frame(
    kind: Kind,
    frame_flags: u8,
    seq: u16,
    payload: &[u8],
    out: &mut [u8],
) -> Result<usize, EncodeFrameError> {
    let len = payload.len();
    if !kind.payload_len_ok(len) {
        return Err(EncodeFrameError::PayloadLength(len));
    }
    let needed = OVERHEAD_BYTES + len;
    if out.len() < needed {
        return Err(EncodeFrameError::BufferTooSmall { needed });
    }
    if let Some(body) = out.get_mut(HEADER_BYTES..HEADER_BYTES + len) {
        body.copy_from_slice(payload);
    }
    seal_frame(kind, frame_flags, seq, len, out)
}

/// Completes a frame whose `len` payload bytes already sit at `frame[HEADER_BYTES..]`: writes
/// the header before them and the CRC-32 after them. Returns the frame length.
///
/// # Errors
/// As [`encode_frame`].
pub fn seal_frame(
    kind: Kind,
    frame_flags: u8,
    seq: u16,
    len: usize,
    frame: &mut [u8],
) -> Result<usize, EncodeFrameError> {
    if !kind.payload_len_ok(len) {
        return Err(EncodeFrameError::PayloadLength(len));
    }
    let needed = OVERHEAD_BYTES + len;
    let Some(frame) = frame.get_mut(..needed) else {
        return Err(EncodeFrameError::BufferTooSmall { needed });
    };
    let [s0, s1] = SYNC;
    let [q0, q1] = seq.to_le_bytes();
    let [l0, l1] = (len as u16).to_le_bytes();
    let vk = (VERSION << 4) | kind as u8;
    let h8 = [s0, s1, vk, frame_flags, q0, q1, l0, l1];
    let [c0, c1] = crc16(&h8).to_le_bytes();
    if let Some(h) = frame.get_mut(..HEADER_BYTES) {
        h.copy_from_slice(&[s0, s1, vk, frame_flags, q0, q1, l0, l1, c0, c1]);
    }
    let crc = crc32(frame.get(..HEADER_BYTES + len).unwrap_or_default());
    if let Some(t) = frame.get_mut(HEADER_BYTES + len..) {
        t.copy_from_slice(&crc.to_le_bytes());
    }
    Ok(needed)
}

/// Frame counters of a [`FrameDecoder`], since its creation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameStats {
    /// Intact frames handed out.
    pub ok: u64,
    /// Rejected candidates: header check passed but the CRC-32 failed or the frame was cut
    /// short (`bad_crc`), or the header's values are not allowed (`bad_header`).
    pub bad: u64,
    /// Frames missing from the sequence numbers between consecutive intact frames (lost on the
    /// way, including the bad ones). With an intact first and last frame, `ok + dropped` is the
    /// number of frames sent.
    pub dropped: u64,
    /// Times the sequence went backwards or jumped by 2^15 or more (a sender restart without
    /// the STREAM_START flag, or a duplicated frame): no gap is counted for those.
    pub seq_restarts: u64,
    /// Bytes that were not part of an intact frame.
    pub skipped_bytes: u64,
    /// Bytes pushed.
    pub bytes: u64,
    /// Frames that carried the SOURCE_OVERFLOW flag.
    pub source_overflows: u64,
}

/// Streaming AER frame decoder: bytes in any chunks, intact frames out, counters.
#[derive(Clone, Debug)]
pub struct FrameDecoder {
    framer: Framer<AerSpec, MAX_FRAME>,
    seq: SeqTracker,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    /// A decoder at the start of a stream.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            framer: Framer::new(),
            seq: SeqTracker::new(),
        }
    }

    /// Copies as much of `bytes` as fits into the buffer and returns how many were taken; take
    /// the frames out with [`FrameDecoder::next_frame`] (which always makes room).
    pub fn feed(&mut self, bytes: &[u8]) -> usize {
        self.framer.feed(bytes)
    }

    /// The next intact frame among the buffered bytes, or `None` when more bytes are needed.
    pub fn next_frame(&mut self) -> Option<Frame<'_>> {
        let raw = self.framer.next_frame()?;
        let f = parse(raw)?;
        self.seq.track(&f);
        Some(f)
    }

    /// As [`FrameDecoder::next_frame`] once the stream has ended: an incomplete frame is counted
    /// bad and intact frames behind it are still found; `None` means nothing is left.
    pub fn next_frame_at_end(&mut self) -> Option<Frame<'_>> {
        let raw = self.framer.next_frame_at_end()?;
        let f = parse(raw)?;
        self.seq.track(&f);
        Some(f)
    }

    /// Consumes `bytes` and calls `on_frame` for every intact frame they complete.
    pub fn push<F: FnMut(&Frame<'_>)>(&mut self, bytes: &[u8], mut on_frame: F) {
        let Self { framer, seq } = self;
        framer.push(bytes, |raw| {
            if let Some(f) = parse(raw) {
                seq.track(&f);
                on_frame(&f);
            }
        });
    }

    /// Ends the stream (see [`FrameDecoder::next_frame_at_end`]) and hands out what is left.
    pub fn finish<F: FnMut(&Frame<'_>)>(&mut self, mut on_frame: F) {
        let Self { framer, seq } = self;
        framer.finish(|raw| {
            if let Some(f) = parse(raw) {
                seq.track(&f);
                on_frame(&f);
            }
        });
    }

    /// Bytes buffered and not yet handed out.
    #[must_use]
    pub const fn pending(&self) -> usize {
        self.framer.pending()
    }

    /// Bytes [`FrameDecoder::feed`] takes now.
    #[must_use]
    pub const fn room(&self) -> usize {
        self.framer.room()
    }

    /// Bytes still missing from a frame whose header checked (see [`Framer::need`]).
    #[must_use]
    pub fn need(&self) -> Option<usize> {
        self.framer.need()
    }

    /// Whether an incomplete frame is buffered (see [`Framer::partial_frame`]).
    #[must_use]
    pub fn partial_frame(&self) -> bool {
        self.framer.partial_frame()
    }

    /// Drops the buffered bytes as broken (see [`Framer::discard`]).
    pub fn discard(&mut self) {
        self.framer.discard();
    }

    /// Counters since creation.
    #[must_use]
    pub fn stats(&self) -> FrameStats {
        let f: &FramerStats = self.framer.stats();
        FrameStats {
            ok: f.frames,
            bad: f.bad_crc + f.bad_header,
            dropped: self.seq.dropped,
            seq_restarts: self.seq.restarts,
            skipped_bytes: f.skipped_bytes,
            bytes: f.bytes,
            source_overflows: self.seq.source_overflows,
        }
    }

    /// The lower-level counters (bad frames split by cause).
    #[must_use]
    pub fn framer_stats(&self) -> &FramerStats {
        self.framer.stats()
    }
}

/// Sequence-number bookkeeping over intact frames.
#[derive(Clone, Copy, Debug, Default)]
struct SeqTracker {
    last: Option<u16>,
    dropped: u64,
    restarts: u64,
    source_overflows: u64,
}

impl SeqTracker {
    const fn new() -> Self {
        Self {
            last: None,
            dropped: 0,
            restarts: 0,
            source_overflows: 0,
        }
    }

    fn track(&mut self, f: &Frame<'_>) {
        if f.flags & flags::SOURCE_OVERFLOW != 0 {
            self.source_overflows += 1;
        }
        if let (Some(last), false) = (self.last, f.flags & flags::STREAM_START != 0) {
            let gap = f.seq.wrapping_sub(last).wrapping_sub(1);
            if gap < 0x8000 {
                self.dropped += u64::from(gap);
            } else {
                self.restarts += 1;
            }
        }
        self.last = Some(f.seq);
    }
}
