//! Prophesee EVT 3.0: 16-bit little-endian words, type in bits 15..12.
//!
//! | type | name | payload |
//! |---|---|---|
//! | 0x0 | EVT_ADDR_Y | bits 10..0 y (bit 11: system type, ignored) |
//! | 0x2 | EVT_ADDR_X | bit 11 polarity, bits 10..0 x: one CD event at the current y and time |
//! | 0x3 | VECT_BASE_X | bit 11 polarity, bits 10..0 x: base of the next vector words |
//! | 0x4 | VECT_12 | 12 valid bits: events at base + i; then base += 12 |
//! | 0x5 | VECT_8 | 8 valid bits: events at base + i; then base += 8 |
//! | 0x6 | EVT_TIME_LOW | time bits 11..0 |
//! | 0x7 | CONTINUED_4 | skipped |
//! | 0x8 | EVT_TIME_HIGH | time bits 23..12 (and time low := 0) |
//! | 0xA | EXT_TRIGGER | skipped (counted) |
//! | 0xE | OTHERS | skipped |
//! | 0xF | CONTINUED_12 | skipped |
//!
//! The 24-bit time wraps every 2^24 µs = 16.777 s; the decoder extends it to 64 bits.

use super::{DecodeStats, StreamDecoder, TimeHigh, Truncated, Words};
use crate::event::Event64;

/// Word types (bits 15..12).
pub mod word {
    /// EVT_ADDR_Y.
    pub const ADDR_Y: u16 = 0x0;
    /// EVT_ADDR_X.
    pub const ADDR_X: u16 = 0x2;
    /// VECT_BASE_X.
    pub const VECT_BASE_X: u16 = 0x3;
    /// VECT_12.
    pub const VECT_12: u16 = 0x4;
    /// VECT_8.
    pub const VECT_8: u16 = 0x5;
    /// EVT_TIME_LOW.
    pub const TIME_LOW: u16 = 0x6;
    /// CONTINUED_4.
    pub const CONTINUED_4: u16 = 0x7;
    /// EVT_TIME_HIGH.
    pub const TIME_HIGH: u16 = 0x8;
    /// EXT_TRIGGER.
    pub const EXT_TRIGGER: u16 = 0xA;
    /// OTHERS.
    pub const OTHERS: u16 = 0xE;
    /// CONTINUED_12.
    pub const CONTINUED_12: u16 = 0xF;
}

/// Bits of the EVT 3.0 time (TIME_HIGH 12 + TIME_LOW 12).
pub const TIME_BITS: u32 = 24;
/// Period of the EVT 3.0 time in µs (16.777216 s).
pub const TIME_PERIOD_US: u64 = 1 << TIME_BITS;

/// Streaming EVT 3.0 decoder (see the [module docs](self) and [`crate::evt`]).
#[derive(Clone, Debug)]
pub struct Evt3Decoder {
    words: Words<2>,
    started: bool,
    th: TimeHigh,
    /// Current time in µs: extended TIME_HIGH << 12 | TIME_LOW.
    t: u64,
    y: u16,
    base_x: u16,
    vect_on: bool,
    stats: DecodeStats,
}

impl Default for Evt3Decoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Evt3Decoder {
    /// A decoder at the start of a stream.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            words: Words::new(),
            started: false,
            th: TimeHigh { value: 0, wraps: 0 },
            t: 0,
            y: 0,
            base_x: 0,
            vect_on: false,
            stats: DecodeStats::ZERO,
        }
    }

    /// Current time in µs (the time the next event without a new time word would get).
    #[must_use]
    pub const fn time_us(&self) -> u64 {
        self.t
    }

    /// Decodes one word.
    ///
    /// The six common word types (ADDR_Y, ADDR_X, VECT_BASE_X, VECT_12, VECT_8, TIME_LOW) share
    /// one branch-light path: each word becomes state updates plus a pixel mask (ADDR_X: one
    /// bit), so that the random order of word types in a busy stream costs fewer mispredicted
    /// jumps; everything else takes `rare`.
    #[inline(always)]
    fn word<F: FnMut(Event64)>(&mut self, w: u16, at: u64, sink: &mut F) {
        /// Bit k set: word type k takes the common path.
        const COMMON: u16 = (1 << word::ADDR_Y)
            | (1 << word::ADDR_X)
            | (1 << word::VECT_BASE_X)
            | (1 << word::VECT_12)
            | (1 << word::VECT_8)
            | (1 << word::TIME_LOW);
        let kind = w >> 12;
        if (COMMON >> kind) & 1 == 0 || !self.started {
            self.rare(w, at);
            return;
        }
        let p = w & 0x0FFF;
        let addr = p & 0x7FF;
        let pol = p & 0x800 != 0;
        /// Per word type: mask of the payload's valid bits (vectors) and the base advance.
        const VECT_MASK: [u16; 16] = [0, 0, 0, 0, 0xFFF, 0xFF, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
        const VECT_ADVANCE: [u16; 16] = [0, 0, 0, 0, 12, 8, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
        let k = usize::from(kind & 0xF);
        let is_x = kind == word::ADDR_X;
        let mask = if is_x {
            1
        } else {
            p & VECT_MASK.get(k).copied().unwrap_or(0)
        };
        let x0 = if is_x { addr } else { self.base_x };
        let on = if is_x { pol } else { self.vect_on };
        let advance = VECT_ADVANCE.get(k).copied().unwrap_or(0);
        if kind == word::ADDR_Y {
            self.y = addr;
        }
        if kind == word::TIME_LOW {
            self.t = (self.th.value << 12) | u64::from(p);
        }
        if kind == word::VECT_BASE_X {
            self.base_x = addr;
            self.vect_on = pol;
        } else {
            self.base_x = self.base_x.wrapping_add(advance);
        }
        self.stats.events += u64::from(mask.count_ones());
        let mut m = mask;
        while m != 0 {
            let bit = m.trailing_zeros() as u16;
            sink(Event64 {
                t_us: self.t,
                x: x0.wrapping_add(bit),
                y: self.y,
                on,
            });
            m &= m - 1;
        }
    }

    /// TIME_HIGH, skipped and undefined words, and every word before the first TIME_HIGH.
    #[inline(always)]
    fn rare(&mut self, w: u16, at: u64) {
        let payload = w & 0x0FFF;
        match w >> 12 {
            word::TIME_HIGH => {
                self.th
                    .accept(&mut self.started, u64::from(payload), 12, &mut self.stats);
                self.t = self.th.value << 12;
            }
            _ if !self.started => self.stats.before_time_high += 1,
            word::EXT_TRIGGER => self.stats.triggers += 1,
            word::OTHERS | word::CONTINUED_4 | word::CONTINUED_12 => self.stats.others += 1,
            _ => self.stats.invalid_at(at),
        }
    }
}

impl StreamDecoder for Evt3Decoder {
    const WORD_BYTES: usize = 2;

    #[inline]
    fn push64<F: FnMut(Event64)>(&mut self, bytes: &[u8], mut sink: F) {
        // Work on a local copy so that the optimiser can keep the state in registers.
        let mut words = self.words;
        let mut d = self.clone();
        words.feed(bytes, |w, at| d.word(u16::from_le_bytes(w), at, &mut sink));
        d.words = words;
        *self = d;
    }

    fn finish(&self) -> Result<(), Truncated> {
        self.words.finish()
    }

    fn stats(&self) -> DecodeStats {
        self.stats
    }

    fn bytes_pushed(&self) -> u64 {
        self.words.bytes()
    }
}

/// Why an event cannot be encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EncodeError {
    /// Events must come in non-decreasing time order.
    TimeBackwards {
        /// The offending event's time (µs).
        t_us: u64,
        /// The previous event's time (µs).
        previous_us: u64,
    },
    /// x and y must fit the format's 11 bits (< 2048).
    AddressOutOfRange {
        /// Column.
        x: u16,
        /// Row.
        y: u16,
    },
}

/// A run of events on one row, at one time and polarity, with increasing x within 32 pixels
/// (written as one ADDR_X, or VECT_BASE_X + VECT_12/VECT_12/VECT_8).
#[derive(Clone, Copy, Debug)]
struct Run {
    t: u64,
    y: u16,
    on: bool,
    base_x: u16,
    /// Bit i: an event at base_x + i.
    mask: u32,
    /// Highest set bit of `mask`.
    last: u32,
}

/// Streaming EVT 3.0 encoder: events in, 16-bit words out.
///
/// Writes the minimal word sequence: TIME_HIGH when the time's bits 23..12 change (with extra
/// TIME_HIGH words so that a decoder sees every 24-bit wrap, however long the gap), TIME_LOW
/// after every TIME_HIGH and when bits 11..0 change, ADDR_Y when the row changes, and runs of
/// events on one row at one time and polarity with increasing x as vectors. Decoding the words
/// gives the events back in the same order, with times reduced by [`Evt3Encoder::time_origin`]
/// of the first event (a multiple of 2^24 µs: the stream starts in the decoder's first period).
#[derive(Clone, Copy, Debug, Default)]
pub struct Evt3Encoder {
    /// Extended TIME_HIGH (t >> 12) last written; `None` before the first word.
    th: Option<u64>,
    /// TIME_LOW currently in force in the decoder.
    tl: u16,
    /// ADDR_Y currently in force; `None` before the first.
    y: Option<u16>,
    /// Time origin (µs), set by the first event.
    origin: u64,
    /// Time of the last event pushed (µs).
    last_t: Option<u64>,
    run: Option<Run>,
}

impl Evt3Encoder {
    /// An encoder at the start of a stream.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            th: None,
            tl: 0,
            y: None,
            origin: 0,
            last_t: None,
            run: None,
        }
    }

    /// The time origin for a stream whose first event is at `first_t_us`: that time rounded down
    /// to a multiple of 2^24 µs. A decoder starting at this stream's first word reports
    /// `t_us - time_origin(first_t_us)`.
    #[must_use]
    pub const fn time_origin(first_t_us: u64) -> u64 {
        first_t_us & !(TIME_PERIOD_US - 1)
    }

    /// Encodes one event; `out` receives the words (possibly none yet: runs are written when
    /// they end, and [`Evt3Encoder::finish`] writes the last one).
    ///
    /// # Errors
    /// [`EncodeError`] when the event's time goes back or its address does not fit 11 bits;
    /// the encoder is then unchanged.
    pub fn push<O: FnMut(u16)>(&mut self, ev: Event64, mut out: O) -> Result<(), EncodeError> {
        if ev.x > 0x7FF || ev.y > 0x7FF {
            return Err(EncodeError::AddressOutOfRange { x: ev.x, y: ev.y });
        }
        match self.last_t {
            Some(prev) if ev.t_us < prev => {
                return Err(EncodeError::TimeBackwards {
                    t_us: ev.t_us,
                    previous_us: prev,
                });
            }
            None => self.origin = Self::time_origin(ev.t_us),
            Some(_) => {}
        }
        self.last_t = Some(ev.t_us);
        let t = ev.t_us - self.origin;
        if let Some(run) = &mut self.run {
            let fits = run.t == t
                && run.y == ev.y
                && run.on == ev.on
                && ev.x > run.base_x
                && u32::from(ev.x - run.base_x) > run.last
                && u32::from(ev.x - run.base_x) < 32;
            if fits {
                run.last = u32::from(ev.x - run.base_x);
                run.mask |= 1 << run.last;
                return Ok(());
            }
        }
        self.flush(&mut out);
        self.run = Some(Run {
            t,
            y: ev.y,
            on: ev.on,
            base_x: ev.x,
            mask: 1,
            last: 0,
        });
        Ok(())
    }

    /// Writes the pending run. Call once after the last event; the encoder can go on afterwards.
    pub fn finish<O: FnMut(u16)>(&mut self, mut out: O) {
        self.flush(&mut out);
    }

    fn flush<O: FnMut(u16)>(&mut self, out: &mut O) {
        let Some(run) = self.run.take() else { return };
        self.set_time(run.t, out);
        if self.y != Some(run.y) {
            out((word::ADDR_Y << 12) | run.y);
            self.y = Some(run.y);
        }
        let pol = if run.on { 0x800 } else { 0 };
        if run.mask == 1 {
            out((word::ADDR_X << 12) | pol | run.base_x);
            return;
        }
        out((word::VECT_BASE_X << 12) | pol | run.base_x);
        out((word::VECT_12 << 12) | (run.mask & 0xFFF) as u16);
        if run.last >= 12 {
            out((word::VECT_12 << 12) | ((run.mask >> 12) & 0xFFF) as u16);
        }
        if run.last >= 24 {
            out((word::VECT_8 << 12) | ((run.mask >> 24) & 0xFF) as u16);
        }
    }

    /// Brings the decoder's time to `t` (µs since the origin, non-decreasing).
    fn set_time<O: FnMut(u16)>(&mut self, t: u64, out: &mut O) {
        let th = t >> 12;
        let tl = (t & 0xFFF) as u16;
        let field = |v: u64| (word::TIME_HIGH << 12) | (v & 0xFFF) as u16;
        let new_th = match self.th {
            None => {
                out(field(th));
                true
            }
            Some(mut cur) if cur != th => {
                // A decoder sees a wrap only as a step from near the top of the 12-bit field to
                // near its bottom: walk through the top (4095) and the bottom (0) of every
                // period crossed.
                while (th >> 12) > (cur >> 12) {
                    let top = cur | 0xFFF;
                    if cur != top {
                        out(field(top));
                    }
                    cur = top + 1;
                    out(field(cur));
                }
                if cur != th {
                    out(field(th));
                }
                true
            }
            Some(_) => false,
        };
        // TIME_LOW is restated after every TIME_HIGH, so that decoders that keep the previous
        // TIME_LOW across a TIME_HIGH agree with those that reset it.
        if new_th || self.tl != tl {
            out((word::TIME_LOW << 12) | tl);
        }
        self.th = Some(th);
        self.tl = tl;
    }
}
