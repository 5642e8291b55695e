//! Prophesee EVT 2.0: 32-bit little-endian words, type in bits 31..28.
//!
//! | type | name | payload |
//! |---|---|---|
//! | 0x0 | CD_OFF | bits 27..22 time bits 5..0, bits 21..11 x, bits 10..0 y |
//! | 0x1 | CD_ON | as CD_OFF |
//! | 0x8 | EVT_TIME_HIGH | bits 27..0: time bits 33..6 |
//! | 0xA | EXT_TRIGGER | skipped (counted) |
//! | 0xE | OTHERS | skipped |
//! | 0xF | CONTINUED | skipped |
//!
//! The 34-bit time wraps every 2^34 µs = 4.77 h; the decoder extends it to 64 bits.

use super::{DecodeStats, StreamDecoder, TimeHigh, Truncated, Words};
use crate::event::Event64;

/// Word types (bits 31..28).
pub mod word {
    /// CD_OFF.
    pub const CD_OFF: u32 = 0x0;
    /// CD_ON.
    pub const CD_ON: u32 = 0x1;
    /// EVT_TIME_HIGH.
    pub const TIME_HIGH: u32 = 0x8;
    /// EXT_TRIGGER.
    pub const EXT_TRIGGER: u32 = 0xA;
    /// OTHERS.
    pub const OTHERS: u32 = 0xE;
    /// CONTINUED.
    pub const CONTINUED: u32 = 0xF;
}

/// Bits of the TIME_HIGH field (time bits 33..6).
pub const TIME_HIGH_BITS: u32 = 28;

/// Streaming EVT 2.0 decoder (see the [module docs](self) and [`crate::evt`]).
#[derive(Clone, Debug)]
pub struct Evt2Decoder {
    words: Words<4>,
    started: bool,
    th: TimeHigh,
    /// Extended TIME_HIGH << 6 (µs).
    base: u64,
    stats: DecodeStats,
}

impl Default for Evt2Decoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Evt2Decoder {
    /// A decoder at the start of a stream.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            words: Words::new(),
            started: false,
            th: TimeHigh { value: 0, wraps: 0 },
            base: 0,
            stats: DecodeStats::ZERO,
        }
    }

    #[inline(always)]
    fn word<F: FnMut(Event64)>(&mut self, w: u32, at: u64, sink: &mut F) {
        let kind = w >> 28;
        if kind <= word::CD_ON && self.started {
            self.stats.events += 1;
            sink(Event64 {
                t_us: self.base | u64::from((w >> 22) & 0x3F),
                x: ((w >> 11) & 0x7FF) as u16,
                y: (w & 0x7FF) as u16,
                on: kind == word::CD_ON,
            });
            return;
        }
        match kind {
            word::TIME_HIGH => {
                self.th.accept(
                    &mut self.started,
                    u64::from(w & 0x0FFF_FFFF),
                    TIME_HIGH_BITS,
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

impl StreamDecoder for Evt2Decoder {
    const WORD_BYTES: usize = 4;

    #[inline]
    fn push64<F: FnMut(Event64)>(&mut self, bytes: &[u8], mut sink: F) {
        // Work on a local copy so that the optimiser can keep the state in registers.
        let mut words = self.words;
        let mut d = self.clone();
        words.feed(bytes, |w, at| d.word(u32::from_le_bytes(w), at, &mut sink));
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

/// Builds EVT 2.0 words (for tests and tools).
pub mod encode {
    use super::word;

    /// A CD word: `t_low` = time bits 5..0, `x`, `y` < 2048.
    #[must_use]
    pub const fn cd(on: bool, t_low: u8, x: u16, y: u16) -> u32 {
        let kind = if on { word::CD_ON } else { word::CD_OFF };
        (kind << 28)
            | ((t_low as u32 & 0x3F) << 22)
            | ((x as u32 & 0x7FF) << 11)
            | (y as u32 & 0x7FF)
    }

    /// A TIME_HIGH word for the time `t_us` (its bits 33..6).
    #[must_use]
    pub const fn time_high(t_us: u64) -> u32 {
        (word::TIME_HIGH << 28) | ((t_us >> 6) as u32 & 0x0FFF_FFFF)
    }
}
