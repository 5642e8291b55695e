//! Prophesee EVT 2.1: 64-bit little-endian words, type in bits 63..60.
//!
//! | type | name | payload |
//! |---|---|---|
//! | 0x0 | EVT_NEG | bits 59..54 time bits 5..0, 53..43 x (base), 42..32 y, 31..0 valid mask: an OFF event at x + i for every set bit i |
//! | 0x1 | EVT_POS | as EVT_NEG, ON events |
//! | 0x8 | EVT_TIME_HIGH | bits 59..32: time bits 33..6 |
//! | 0xA | EXT_TRIGGER | skipped (counted) |
//! | 0xE | OTHERS | skipped |
//! | 0xF | CONTINUED | skipped |
//!
//! Events of one vector word are emitted in increasing x. Some early Prophesee systems
//! (`endianness=legacy` in the `.raw` header) write the two 32-bit halves of each word in the
//! other order: [`Evt21Decoder::legacy`] reads those.

use super::{DecodeStats, StreamDecoder, TimeHigh, Truncated, Words};
use crate::event::Event64;

/// Word types (bits 63..60).
pub mod word {
    /// EVT_NEG (OFF vector).
    pub const NEG: u64 = 0x0;
    /// EVT_POS (ON vector).
    pub const POS: u64 = 0x1;
    /// EVT_TIME_HIGH.
    pub const TIME_HIGH: u64 = 0x8;
    /// EXT_TRIGGER.
    pub const EXT_TRIGGER: u64 = 0xA;
    /// OTHERS.
    pub const OTHERS: u64 = 0xE;
    /// CONTINUED.
    pub const CONTINUED: u64 = 0xF;
}

/// Streaming EVT 2.1 decoder (see the [module docs](self) and [`crate::evt`]).
#[derive(Clone, Debug)]
pub struct Evt21Decoder {
    words: Words<8>,
    legacy: bool,
    started: bool,
    th: TimeHigh,
    /// Extended TIME_HIGH << 6 (µs).
    base: u64,
    stats: DecodeStats,
}

impl Default for Evt21Decoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Evt21Decoder {
    /// A decoder at the start of a standard EVT 2.1 stream.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            words: Words::new(),
            legacy: false,
            started: false,
            th: TimeHigh { value: 0, wraps: 0 },
            base: 0,
            stats: DecodeStats::ZERO,
        }
    }

    /// A decoder for the legacy layout: the 32-bit half with the type comes first.
    #[must_use]
    pub const fn legacy() -> Self {
        let mut d = Self::new();
        d.legacy = true;
        d
    }

    #[inline(always)]
    fn word<F: FnMut(Event64)>(&mut self, w: u64, at: u64, sink: &mut F) {
        let kind = w >> 60;
        if kind <= word::POS && self.started {
            let t_us = self.base | ((w >> 54) & 0x3F);
            let x = ((w >> 43) & 0x7FF) as u16;
            let y = ((w >> 32) & 0x7FF) as u16;
            let on = kind == word::POS;
            let mut valid = w as u32;
            while valid != 0 {
                let bit = valid.trailing_zeros() as u16;
                self.stats.events += 1;
                sink(Event64 {
                    t_us,
                    x: x.wrapping_add(bit),
                    y,
                    on,
                });
                valid &= valid - 1;
            }
            return;
        }
        match kind {
            word::TIME_HIGH => {
                self.th.accept(
                    &mut self.started,
                    (w >> 32) & 0x0FFF_FFFF,
                    28,
                    &mut self.stats,
                );
                self.base = self.th.value << 6;
            }
            _ if !self.started => self.stats.before_time_high += 1,
            word::EXT_TRIGGER => self.stats.triggers += 1,
            word::OTHERS | word::CONTINUED => self.stats.others += 1,
            _ => self.stats.invalid_at(at),
        }
    }
}

impl StreamDecoder for Evt21Decoder {
    const WORD_BYTES: usize = 8;

    #[inline]
    fn push64<F: FnMut(Event64)>(&mut self, bytes: &[u8], mut sink: F) {
        // Work on a local copy so that the optimiser can keep the state in registers.
        let mut words = self.words;
        let mut d = self.clone();
        let legacy = self.legacy;
        words.feed(bytes, |b, at| {
            let w = u64::from_le_bytes(b);
            d.word(if legacy { w.rotate_left(32) } else { w }, at, &mut sink);
        });
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

/// Builds EVT 2.1 words from the specification (for tests and tools).
pub mod encode {
    use super::word;

    /// A vector word: events at `x + i` for every set bit `i` of `valid`, at time bits 5..0
    /// `t_low`, row `y`; `x`, `y` < 2048.
    #[must_use]
    pub const fn vector(on: bool, t_low: u8, x: u16, y: u16, valid: u32) -> u64 {
        let kind = if on { word::POS } else { word::NEG };
        (kind << 60)
            | ((t_low as u64 & 0x3F) << 54)
            | ((x as u64 & 0x7FF) << 43)
            | ((y as u64 & 0x7FF) << 32)
            | valid as u64
    }

    /// A TIME_HIGH word for the time `t_us` (its bits 33..6).
    #[must_use]
    pub const fn time_high(t_us: u64) -> u64 {
        (word::TIME_HIGH << 60) | (((t_us >> 6) & 0x0FFF_FFFF) << 32)
    }

    /// The legacy layout of a word (32-bit halves swapped).
    #[must_use]
    pub const fn to_legacy(w: u64) -> u64 {
        w.rotate_left(32)
    }
}
