//! Payloads: AER events (kind 1) and raw EVT 3.0 words (kind 2), their encoders and decoders.
//!
//! AER event payload: a 32-bit time base, then 32-bit little-endian words.
//!
//! ```text
//! bytes 0..4   t_base: u32 µs (wrapping); the running time t starts here
//! then words:
//!   bit 31 = 0: event       bits 30..23 dt (0..=255 µs, t += dt), bit 22 polarity (1 = ON),
//!                           bits 21..11 y (0..=2047), bits 10..0 x (0..=2047); the event is at t
//!   bit 31 = 1: time step   bits 30..0 dt (µs, t += dt), no event
//! ```
//!
//! Every frame decodes on its own (the time base is absolute), so a lost frame costs only its
//! own events. Times within a frame never go back; the encoder starts a new frame when an
//! event's time goes back (or jumps forward by 2^31 µs or more), so any sequence of wrapping
//! `u32` times is carried exactly. 4 bytes per event while events are at most 255 µs apart.

use super::frame::{self, seal_frame, Frame, FrameDecoder, FrameStats, Kind};
use crate::event::Event;
use crate::evt::{DecodeStats, Evt3Decoder, StreamDecoder};

/// Largest coordinate an AER event can carry (11 bits: sensors up to 2048 x 2048).
pub const MAX_COORD: u16 = 0x7FF;
/// Largest time step (µs) inside an event word.
pub const MAX_EVENT_DT: u32 = 0xFF;
/// Largest time step (µs) of a time-step word.
pub const MAX_STEP_DT: u32 = 0x7FFF_FFFF;
/// Bit 31 of a word: time step.
const STEP: u32 = 1 << 31;
/// Bit 22 of an event word: ON polarity.
const ON: u32 = 1 << 22;

/// Decodes an AER event payload; returns the number of events. Any bytes are accepted:
/// a payload shorter than 4 bytes gives no events, and a trailing partial word is ignored.
pub fn decode_events<F: FnMut(Event)>(payload: &[u8], mut sink: F) -> u32 {
    let Some((base, words)) = payload.split_first_chunk::<4>() else {
        return 0;
    };
    let mut t = u32::from_le_bytes(*base);
    let mut n = 0;
    let (words, _) = words.as_chunks::<4>();
    for w in words {
        let w = u32::from_le_bytes(*w);
        if w & STEP != 0 {
            t = t.wrapping_add(w & MAX_STEP_DT);
        } else {
            t = t.wrapping_add((w >> 23) & MAX_EVENT_DT);
            sink(Event {
                t_us: t,
                x: (w & 0x7FF) as u16,
                y: ((w >> 11) & 0x7FF) as u16,
                on: w & ON != 0,
            });
            n += 1;
        }
    }
    n
}

/// Why an event could not be encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EncodeEventError {
    /// A coordinate above [`MAX_COORD`].
    AddressOutOfRange {
        /// Column.
        x: u16,
        /// Row.
        y: u16,
    },
}

impl core::fmt::Display for EncodeEventError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::AddressOutOfRange { x, y } => write!(
                f,
                "event at ({x}, {y}) does not fit the AER format (coordinates 0..=2047)"
            ),
        }
    }
}

/// Streaming AER encoder: events in, whole frames out (sequence numbers from 0, the first
/// frame flagged STREAM_START).
#[derive(Clone, Debug)]
pub struct EventEncoder {
    frame: FrameBuilder,
    /// Running time (µs) after the last word.
    t: u32,
    /// Time base of the open frame.
    t_first: u32,
    max_span_us: u32,
}

impl Default for EventEncoder {
    fn default() -> Self {
        Self::new()
    }
}

impl EventEncoder {
    /// Default for [`EventEncoder::with_limits`]: frames span at most 1 ms of event time, so a
    /// receiver never waits more than that (plus transfer) for an event.
    pub const DEFAULT_MAX_SPAN_US: u32 = 1_000;

    /// An encoder with full-size frames spanning at most [`Self::DEFAULT_MAX_SPAN_US`].
    #[must_use]
    pub const fn new() -> Self {
        Self::with_limits(frame::MAX_PAYLOAD, Self::DEFAULT_MAX_SPAN_US)
    }

    /// An encoder whose frames carry at most `max_payload` bytes (clamped to 8 ..=
    /// [`frame::MAX_PAYLOAD`], rounded down to whole words) and span at most `max_span_us` of
    /// event time from their first event.
    #[must_use]
    pub const fn with_limits(max_payload: usize, max_span_us: u32) -> Self {
        Self {
            frame: FrameBuilder::new(max_payload, 12, 4),
            t: 0,
            t_first: 0,
            max_span_us,
        }
    }

    /// Sets [`frame::flags::SOURCE_OVERFLOW`] on the next frame (the caller lost events).
    pub fn mark_overflow(&mut self) {
        self.frame.next_flags |= frame::flags::SOURCE_OVERFLOW;
    }

    /// Sequence number of the next frame.
    #[must_use]
    pub const fn next_seq(&self) -> u16 {
        self.frame.seq
    }

    /// Adds one event; `out` receives each frame completed on the way.
    ///
    /// # Errors
    /// [`EncodeEventError::AddressOutOfRange`] for coordinates above 2047; nothing is written.
    pub fn push<O: FnMut(&[u8])>(&mut self, ev: Event, mut out: O) -> Result<(), EncodeEventError> {
        if ev.x > MAX_COORD || ev.y > MAX_COORD {
            return Err(EncodeEventError::AddressOutOfRange { x: ev.x, y: ev.y });
        }
        let dt = ev.t_us.wrapping_sub(self.t);
        let span = ev.t_us.wrapping_sub(self.t_first);
        let words = if dt > MAX_EVENT_DT { 8 } else { 4 };
        let reopen = self.frame.len == 0
            || dt > MAX_STEP_DT
            || span > self.max_span_us
            || !self.frame.fits(words);
        let dt = if reopen {
            self.flush(&mut out);
            self.t = ev.t_us;
            self.t_first = ev.t_us;
            self.put(ev.t_us);
            0
        } else {
            dt
        };
        if dt > MAX_EVENT_DT {
            self.put(STEP | dt);
            self.t = ev.t_us;
            self.put_event(ev, 0);
        } else {
            self.t = ev.t_us;
            self.put_event(ev, dt);
        }
        Ok(())
    }

    fn put_event(&mut self, ev: Event, dt: u32) {
        let w = (dt << 23) | if ev.on { ON } else { 0 } | (u32::from(ev.y) << 11) | u32::from(ev.x);
        self.put(w);
    }

    fn put(&mut self, w: u32) {
        self.frame.put(&w.to_le_bytes());
    }

    /// Closes the open frame, if any, and hands it to `out`.
    pub fn flush<O: FnMut(&[u8])>(&mut self, out: O) {
        self.frame.flush(Kind::Events, out);
    }
}

/// The frame an encoder builds: payload words after room for the header, then sealed with
/// sequence number and flags. Shared by [`EventEncoder`] and [`Evt3Framer`].
#[derive(Clone, Debug)]
struct FrameBuilder {
    /// The frame being built; payload from `frame::HEADER_BYTES`.
    buf: [u8; frame::MAX_FRAME],
    /// Payload bytes so far; 0 = no open frame.
    len: usize,
    /// Sequence number of the next frame.
    seq: u16,
    /// Flags of the next frame (STREAM_START on the first).
    next_flags: u8,
    /// Largest payload, bytes: a whole number of words.
    max_payload: usize,
}

impl FrameBuilder {
    /// Payload limit `max_payload` clamped to `min ..= frame::MAX_PAYLOAD` and rounded down to
    /// whole words of `word` bytes (a power of two).
    const fn new(max_payload: usize, min: usize, word: usize) -> Self {
        let p = if max_payload > frame::MAX_PAYLOAD {
            frame::MAX_PAYLOAD
        } else if max_payload < min {
            min
        } else {
            max_payload
        };
        Self {
            buf: [0; frame::MAX_FRAME],
            len: 0,
            seq: 0,
            next_flags: frame::flags::STREAM_START,
            max_payload: p & !(word - 1),
        }
    }

    /// Whether `bytes` more fit the open frame.
    fn fits(&self, bytes: usize) -> bool {
        self.len + bytes <= self.max_payload
    }

    /// Appends payload bytes (ignored past the buffer, which [`Self::fits`] prevents).
    fn put(&mut self, bytes: &[u8]) {
        let at = frame::HEADER_BYTES + self.len;
        if let Some(b) = self.buf.get_mut(at..at + bytes.len()) {
            b.copy_from_slice(bytes);
            self.len += bytes.len();
        }
    }

    /// Seals the open frame, if any, as `kind`, hands it to `out` and starts the next one.
    fn flush<O: FnMut(&[u8])>(&mut self, kind: Kind, mut out: O) {
        if self.len == 0 {
            return;
        }
        if let Ok(n) = seal_frame(kind, self.next_flags, self.seq, self.len, &mut self.buf) {
            if let Some(f) = self.buf.get(..n) {
                out(f);
            }
        }
        self.seq = self.seq.wrapping_add(1);
        self.next_flags = 0;
        self.len = 0;
    }
}

/// Packs a raw EVT 3.0 word stream into frames of kind 2.
///
/// Every frame after the first starts with the words the decoder's state depends on (the
/// current EVT_TIME_HIGH, EVT_TIME_LOW, EVT_ADDR_Y and VECT_BASE_X, as far as seen), so that a
/// lost frame does not give the next frame's events a wrong time, row or column.
#[derive(Clone, Debug)]
pub struct Evt3Framer {
    frame: FrameBuilder,
    /// Last TIME_HIGH, TIME_LOW, ADDR_Y words; VECT_BASE_X word with the base advanced past
    /// the vector words seen since.
    state: [Option<u16>; 4],
}

impl Default for Evt3Framer {
    fn default() -> Self {
        Self::new()
    }
}

impl Evt3Framer {
    /// A framer with full-size frames.
    #[must_use]
    pub const fn new() -> Self {
        Self::with_max_payload(frame::MAX_PAYLOAD)
    }

    /// A framer whose frames carry at most `max_payload` bytes (clamped to 16 ..=
    /// [`frame::MAX_PAYLOAD`], rounded down to whole words).
    #[must_use]
    pub const fn with_max_payload(max_payload: usize) -> Self {
        Self {
            frame: FrameBuilder::new(max_payload, 16, 2),
            state: [None; 4],
        }
    }

    /// Adds one word; `out` receives each frame completed on the way.
    pub fn push<O: FnMut(&[u8])>(&mut self, word: u16, mut out: O) {
        if !self.frame.fits(2) {
            self.flush(&mut out);
            let state = self.state;
            for w in state.into_iter().flatten() {
                self.put(w);
            }
        }
        self.put(word);
        self.track(word);
    }

    fn put(&mut self, w: u16) {
        self.frame.put(&w.to_le_bytes());
    }

    fn track(&mut self, w: u16) {
        use crate::evt::evt3::word;
        let [th, tl, y, base] = &mut self.state;
        match w >> 12 {
            word::TIME_HIGH => {
                *th = Some(w);
                *tl = None;
            }
            word::TIME_LOW => *tl = Some(w),
            word::ADDR_Y => *y = Some(w),
            word::VECT_BASE_X => *base = Some(w),
            word::VECT_12 | word::VECT_8 => {
                let step = if w >> 12 == word::VECT_12 { 12 } else { 8 };
                if let Some(b) = base {
                    let x = (*b & 0x7FF).wrapping_add(step) & 0x7FF;
                    *b = (*b & !0x7FF) | x;
                }
            }
            _ => {}
        }
    }

    /// Closes the open frame, if any, and hands it to `out`.
    pub fn flush<O: FnMut(&[u8])>(&mut self, out: O) {
        self.frame.flush(Kind::Evt3, out);
    }
}

/// Counters of a [`PayloadDecoder`], since its creation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PayloadStats {
    /// Events decoded (both kinds).
    pub events: u64,
    /// Frames of kind 1 (AER events) decoded.
    pub event_frames: u64,
    /// Frames of kind 2 (EVT 3.0) decoded.
    pub evt3_frames: u64,
    /// Frames of kind 3 (configuration) passed by (they carry no events).
    pub config_frames: u64,
    /// The EVT 3.0 decoder's own counters (invalid words, skipped words, wraps...), summed over
    /// its restarts.
    pub evt3: DecodeStats,
}

/// Turns intact frames into events: AER payloads directly, EVT 3.0 payloads through one
/// [`Evt3Decoder`] that lives across frames (EVT 3.0 is stateful) and restarts at a
/// STREAM_START frame.
#[derive(Clone, Debug, Default)]
pub struct PayloadDecoder {
    evt3: Evt3Decoder,
    /// EVT 3.0 counters of decoders that were restarted.
    evt3_before: DecodeStats,
    events: u64,
    event_frames: u64,
    evt3_frames: u64,
    config_frames: u64,
}

fn add_stats(a: &DecodeStats, b: &DecodeStats) -> DecodeStats {
    DecodeStats {
        events: a.events + b.events,
        before_time_high: a.before_time_high + b.before_time_high,
        time_high: a.time_high + b.time_high,
        time_wraps: a.time_wraps + b.time_wraps,
        triggers: a.triggers + b.triggers,
        others: a.others + b.others,
        invalid: a.invalid + b.invalid,
        first_invalid_at: a.first_invalid_at.or(b.first_invalid_at),
    }
}

impl PayloadDecoder {
    /// A decoder at the start of a stream.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            evt3: Evt3Decoder::new(),
            evt3_before: DecodeStats::ZERO,
            events: 0,
            event_frames: 0,
            evt3_frames: 0,
            config_frames: 0,
        }
    }

    /// Decodes one intact frame's events into `sink`, in order; returns how many.
    pub fn frame<F: FnMut(Event)>(&mut self, f: &Frame<'_>, mut sink: F) -> u32 {
        let n = match f.kind {
            Kind::Events => {
                self.event_frames += 1;
                decode_events(f.payload, sink)
            }
            Kind::Evt3 => {
                self.evt3_frames += 1;
                if f.flags & frame::flags::STREAM_START != 0 && self.evt3.bytes_pushed() != 0 {
                    self.evt3_before = add_stats(&self.evt3_before, &self.evt3.stats());
                    self.evt3 = Evt3Decoder::new();
                }
                let mut n = 0u32;
                self.evt3.push(f.payload, |e| {
                    n += 1;
                    sink(e)
                });
                n
            }
            // Configuration frames carry no events; the caller reads them (`aer::config`).
            Kind::Config => {
                self.config_frames += 1;
                0
            }
        };
        self.events += u64::from(n);
        n
    }

    /// Counters since creation.
    #[must_use]
    pub fn stats(&self) -> PayloadStats {
        PayloadStats {
            events: self.events,
            event_frames: self.event_frames,
            evt3_frames: self.evt3_frames,
            config_frames: self.config_frames,
            evt3: add_stats(&self.evt3_before, &self.evt3.stats()),
        }
    }
}

/// Bytes in, events out: a [`FrameDecoder`] and a [`PayloadDecoder`] together.
#[derive(Clone, Debug, Default)]
pub struct Receiver {
    frames: FrameDecoder,
    payload: PayloadDecoder,
}

impl Receiver {
    /// A receiver at the start of a stream.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            frames: FrameDecoder::new(),
            payload: PayloadDecoder::new(),
        }
    }

    /// Consumes `bytes` (any chunk) and calls `sink` for every event of the intact frames they
    /// complete.
    pub fn push<F: FnMut(Event)>(&mut self, bytes: &[u8], mut sink: F) {
        let Self { frames, payload } = self;
        frames.push(bytes, |f| {
            payload.frame(f, &mut sink);
        });
    }

    /// Ends the stream: decodes what is left (see [`FrameDecoder::finish`]).
    pub fn finish<F: FnMut(Event)>(&mut self, mut sink: F) {
        let Self { frames, payload } = self;
        frames.finish(|f| {
            payload.frame(f, &mut sink);
        });
    }

    /// Frame counters.
    #[must_use]
    pub fn frame_stats(&self) -> FrameStats {
        self.frames.stats()
    }

    /// Payload counters.
    #[must_use]
    pub fn payload_stats(&self) -> PayloadStats {
        self.payload.stats()
    }
}
