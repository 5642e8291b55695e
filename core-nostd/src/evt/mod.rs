//! Streaming decoders for the Prophesee event formats a sensor sends over SPI/USB: EVT 2.0,
//! EVT 2.1 and EVT 3.0; and an EVT 3.0 encoder.
//!
//! Every decoder is push-style, allocation-free and panic-free on any input:
//!
//! ```
//! use core_nostd::evt::{Evt3Decoder, StreamDecoder};
//! let mut dec = Evt3Decoder::new();
//! let mut n = 0;
//! // Bytes may arrive in chunks of any size (DMA buffers): a word split between two calls is
//! // completed by the next call.
//! for chunk in [&[0x00u8, 0x80][..], &[0x05], &[0x00, 0x02, 0x20]] {
//!     dec.push64(chunk, |ev| { assert_eq!((ev.x, ev.y, ev.on), (2, 5, false)); n += 1; });
//! }
//! assert_eq!(n, 1);
//! assert!(dec.finish().is_ok());
//! ```
//!
//! Common rules (as in Prophesee's reference decoders):
//! - Decoding starts at the first TIME_HIGH word; words before it are counted in
//!   [`DecodeStats::before_time_high`] and otherwise ignored.
//! - Time is extended to a monotonic `u64` count of µs: a TIME_HIGH that goes back by almost
//!   the whole period (EVT 3.0: 2^24 µs = 16.777 s; EVT 2.x: 2^34 µs = 4.77 h) is a wrap and
//!   adds one period. Smaller backward steps are kept as they are (the stream went back).
//! - EXT_TRIGGER, OTHERS and CONTINUED words are skipped and counted; word types that the format
//!   does not define are skipped and counted as [`DecodeStats::invalid`].
//! - Words are little-endian, as written by the sensors and in `.raw` files.

pub mod evt2;
pub mod evt21;
pub mod evt3;

pub use evt2::Evt2Decoder;
pub use evt21::Evt21Decoder;
pub use evt3::{EncodeError, Evt3Decoder, Evt3Encoder};

use crate::event::{Event, Event64};

/// Counters kept by every decoder since its creation (all counts, no units).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DecodeStats {
    /// CD (change-detection) events emitted.
    pub events: u64,
    /// Words skipped because no TIME_HIGH had been seen yet.
    pub before_time_high: u64,
    /// TIME_HIGH words decoded.
    pub time_high: u64,
    /// Times the time base wrapped (each adds one period to the 64-bit time).
    pub time_wraps: u64,
    /// EXT_TRIGGER words skipped.
    pub triggers: u64,
    /// OTHERS and CONTINUED words skipped (monitoring, IMU, padding...).
    pub others: u64,
    /// Words of a type the format does not define, skipped.
    pub invalid: u64,
    /// Byte offset (from the first byte pushed) of the first word counted in `invalid`.
    pub first_invalid_at: Option<u64>,
}

impl DecodeStats {
    /// All counters zero.
    pub const ZERO: Self = Self {
        events: 0,
        before_time_high: 0,
        time_high: 0,
        time_wraps: 0,
        triggers: 0,
        others: 0,
        invalid: 0,
        first_invalid_at: None,
    };

    /// Counts an invalid word at byte offset `at`.
    #[cold]
    pub(crate) fn invalid_at(&mut self, at: u64) {
        self.invalid += 1;
        if self.first_invalid_at.is_none() {
            self.first_invalid_at = Some(at);
        }
    }
}

/// The stream ended in the middle of a word.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Truncated {
    /// Offset in bytes, from the first byte pushed, of the incomplete word.
    pub offset: u64,
    /// Bytes of the incomplete word that were received (1 ..= word size - 1).
    pub have: u8,
    /// Word size of the format in bytes.
    pub word_bytes: u8,
}

/// What every stream decoder offers.
pub trait StreamDecoder {
    /// Size of one word of the format in bytes (2, 4 or 8).
    const WORD_BYTES: usize;

    /// Decodes `bytes` (any length, continuing the previous call) and calls `sink` once per CD
    /// event, in stream order.
    fn push64<F: FnMut(Event64)>(&mut self, bytes: &[u8], sink: F);

    /// As [`StreamDecoder::push64`], with the time truncated to a wrapping `u32`
    /// (see [`Event64::wrapping`]).
    #[inline]
    fn push<F: FnMut(Event)>(&mut self, bytes: &[u8], mut sink: F) {
        self.push64(bytes, |e| sink(e.wrapping()));
    }

    /// Checks that the stream ended on a word boundary. Does not change the decoder.
    ///
    /// # Errors
    /// [`Truncated`] when bytes of an incomplete word are pending.
    fn finish(&self) -> Result<(), Truncated>;

    /// Counters since creation.
    fn stats(&self) -> DecodeStats;

    /// Bytes pushed since creation.
    fn bytes_pushed(&self) -> u64;
}

/// Assembles `N`-byte little-endian words from chunks of any length.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Words<const N: usize> {
    /// Bytes of a word split across two pushes (`len` of them valid).
    carry: [u8; N],
    /// Valid bytes in `carry`, always `< N`.
    len: usize,
    /// Bytes pushed since creation.
    bytes: u64,
}

impl<const N: usize> Words<N> {
    pub(crate) const fn new() -> Self {
        Self {
            carry: [0; N],
            len: 0,
            bytes: 0,
        }
    }

    /// Calls `word(w, at)` on every complete word `w` starting at byte offset `at` (from the
    /// first byte ever pushed), keeping an incomplete tail for the next call.
    #[inline(always)]
    pub(crate) fn feed<W: FnMut([u8; N], u64)>(&mut self, bytes: &[u8], mut word: W) {
        let start = self.bytes;
        self.bytes = self.bytes.wrapping_add(bytes.len() as u64);
        let mut rest = bytes;
        if self.len != 0 {
            let at = start.wrapping_sub(self.len as u64);
            while self.len < N {
                let Some((&b, tail)) = rest.split_first() else {
                    return;
                };
                if let Some(slot) = self.carry.get_mut(self.len) {
                    *slot = b;
                }
                self.len += 1;
                rest = tail;
            }
            word(self.carry, at);
            self.len = 0;
        }
        let mut at = self.bytes.wrapping_sub(rest.len() as u64);
        let (words, tail) = rest.as_chunks::<N>();
        for w in words {
            word(*w, at);
            at = at.wrapping_add(N as u64);
        }
        for &b in tail {
            if let Some(slot) = self.carry.get_mut(self.len) {
                *slot = b;
                self.len += 1;
            }
        }
    }

    pub(crate) fn finish(&self) -> Result<(), Truncated> {
        if self.len == 0 {
            Ok(())
        } else {
            Err(Truncated {
                offset: self.bytes.wrapping_sub(self.len as u64),
                have: self.len as u8,
                word_bytes: N as u8,
            })
        }
    }

    pub(crate) const fn bytes(&self) -> u64 {
        self.bytes
    }
}

/// Extends a TIME_HIGH field of `bits` bits to a monotonic counter of TIME_HIGH units.
///
/// Prophesee's rule: a new value below the previous one by at least `2^bits - 1 - 10` units is a
/// wrap (one period later); any other value is taken as it is.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct TimeHigh {
    /// Extended value of the last TIME_HIGH, in units of the field (wraps * 2^bits + field).
    pub(crate) value: u64,
    /// Wraps seen.
    pub(crate) wraps: u64,
}

impl TimeHigh {
    /// Takes a new field value; returns `true` on a wrap.
    #[inline(always)]
    pub(crate) fn update(&mut self, field: u64, bits: u32) -> bool {
        let period = 1u64 << bits;
        let threshold = period - 1 - 10;
        let mut v = self.wraps.wrapping_mul(period).wrapping_add(field);
        let wrapped = self.value > v && self.value - v >= threshold;
        if wrapped {
            v = v.wrapping_add(period);
            self.wraps = self.wraps.wrapping_add(1);
        }
        self.value = v;
        wrapped
    }

    /// Applies a TIME_HIGH word's field (`bits` wide): the first one starts the clock (and
    /// `started`), later ones extend it across wraps. Counts the word and any wrap in `stats`.
    #[inline(always)]
    pub(crate) fn accept(
        &mut self,
        started: &mut bool,
        field: u64,
        bits: u32,
        stats: &mut DecodeStats,
    ) {
        if *started {
            if self.update(field, bits) {
                stats.time_wraps += 1;
            }
        } else {
            *started = true;
            *self = TimeHigh {
                value: field,
                wraps: 0,
            };
        }
        stats.time_high += 1;
    }
}
