//! The yaw output frame: one yaw-rate sample, 14 bytes, at 1 kHz.
//!
//! ```text
//! offset  size  field
//!      0     2  sync 0x59 0xC3
//!      2     1  sequence counter (u8, +1 per frame, wraps)
//!      3     1  status flags (see [`crate::flags`])
//!      4     4  t: u32 µs (wrapping), on the event clock: the sample's time
//!      8     4  yaw rate: i32 LE, I16F16 rad/s (1/65536 rad/s per LSB, ±32768 rad/s);
//!               positive = the camera turns right (clockwise seen from above)
//!     12     2  CRC-16/IBM-3740 of bytes 0..12 (LE)
//! ```
//!
//! 14 kB/s at 1 kHz: a UART needs at least 230400 baud (8N1); the firmware uses 921600.

use fixed::types::I16F16;

use super::crc::crc16;
use super::framer::{FrameSpec, Framer, FramerStats, Header};

/// The two bytes every yaw frame starts with.
pub const SYNC: [u8; 2] = [0x59, 0xC3];
/// Bytes per yaw frame.
pub const FRAME_BYTES: usize = 14;

/// One yaw output sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct YawFrame {
    /// Sequence counter.
    pub seq: u8,
    /// Status flags ([`crate::flags`]).
    pub flags: u8,
    /// Sample time, µs on the event clock (wrapping).
    pub t_us: u32,
    /// Yaw rate in rad/s.
    pub yaw_rate: I16F16,
}

impl YawFrame {
    /// The frame's bytes.
    #[must_use]
    pub fn encode(&self) -> [u8; FRAME_BYTES] {
        let [s0, s1] = SYNC;
        let [t0, t1, t2, t3] = self.t_us.to_le_bytes();
        let [y0, y1, y2, y3] = self.yaw_rate.to_bits().to_le_bytes();
        let body = [s0, s1, self.seq, self.flags, t0, t1, t2, t3, y0, y1, y2, y3];
        let [c0, c1] = crc16(&body).to_le_bytes();
        [
            s0, s1, self.seq, self.flags, t0, t1, t2, t3, y0, y1, y2, y3, c0, c1,
        ]
    }

    /// Reads a frame that passed its check (`None` for a slice of another length).
    #[must_use]
    pub fn parse(frame: &[u8]) -> Option<Self> {
        let b: &[u8; FRAME_BYTES] = frame.try_into().ok()?;
        let [_, _, seq, flags, t0, t1, t2, t3, y0, y1, y2, y3, _, _] = *b;
        Some(Self {
            seq,
            flags,
            t_us: u32::from_le_bytes([t0, t1, t2, t3]),
            yaw_rate: I16F16::from_bits(i32::from_le_bytes([y0, y1, y2, y3])),
        })
    }
}

/// The yaw frame format, for the [`Framer`].
#[derive(Clone, Copy, Debug)]
pub struct YawSpec;

impl FrameSpec for YawSpec {
    const SYNC: [u8; 2] = SYNC;
    const HEADER: usize = FRAME_BYTES;
    const MAX_FRAME: usize = FRAME_BYTES;

    fn header(_: &[u8]) -> Header {
        Header::Frame(FRAME_BYTES)
    }

    fn check(frame: &[u8]) -> bool {
        match frame {
            [body @ .., c0, c1] => crc16(body) == u16::from_le_bytes([*c0, *c1]),
            _ => false,
        }
    }
}

/// Counters of a [`YawDecoder`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct YawStats {
    /// Intact frames.
    pub ok: u64,
    /// Candidates whose CRC failed (or cut short at the end).
    pub bad: u64,
    /// Frames missing from the sequence numbers between consecutive intact frames (gaps of
    /// 128 or more are taken as a restart and not counted).
    pub dropped: u64,
    /// Bytes that were not part of an intact frame.
    pub skipped_bytes: u64,
}

/// Streaming yaw frame decoder (bytes in any chunks; resynchronises after corruption).
#[derive(Clone, Debug, Default)]
pub struct YawDecoder {
    framer: Framer<YawSpec, FRAME_BYTES>,
    last_seq: Option<u8>,
    dropped: u64,
}

impl YawDecoder {
    /// A decoder at the start of a stream.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            framer: Framer::new(),
            last_seq: None,
            dropped: 0,
        }
    }

    fn track(last_seq: &mut Option<u8>, dropped: &mut u64, f: &YawFrame) {
        if let Some(last) = *last_seq {
            let gap = f.seq.wrapping_sub(last).wrapping_sub(1);
            if gap < 0x80 {
                *dropped += u64::from(gap);
            }
        }
        *last_seq = Some(f.seq);
    }

    /// Consumes `bytes` and calls `on_frame` for every intact frame they complete.
    pub fn push<F: FnMut(YawFrame)>(&mut self, bytes: &[u8], mut on_frame: F) {
        let Self {
            framer,
            last_seq,
            dropped,
        } = self;
        framer.push(bytes, |raw| {
            if let Some(f) = YawFrame::parse(raw) {
                Self::track(last_seq, dropped, &f);
                on_frame(f);
            }
        });
    }

    /// Ends the stream; intact frames behind an incomplete one are still handed out.
    pub fn finish<F: FnMut(YawFrame)>(&mut self, mut on_frame: F) {
        let Self {
            framer,
            last_seq,
            dropped,
        } = self;
        framer.finish(|raw| {
            if let Some(f) = YawFrame::parse(raw) {
                Self::track(last_seq, dropped, &f);
                on_frame(f);
            }
        });
    }

    /// Counters since creation.
    #[must_use]
    pub fn stats(&self) -> YawStats {
        let f: &FramerStats = self.framer.stats();
        YawStats {
            ok: f.frames,
            bad: f.bad_crc + f.bad_header,
            dropped: self.dropped,
            skipped_bytes: f.skipped_bytes,
        }
    }
}
