//! Reading a recording ahead: each event comes out with what is known of the next event at its
//! pixel ([`NextInput`]), so that the network's units can emit their spikes up to that event
//! at once instead of once per output period ([`core_nostd::network::Network::event_in_ahead`]).
//!
//! A live sensor cannot do this; a recording can. The events come out in stream order, each
//! [`LOOKAHEAD_US`] after it on the stream's clock (or at the end of the piece), so the
//! buffer holds about that much of the recording (~165 k events, 24 bytes each, on dev03, a
//! busy DAVIS346 scene at 0.65 M events/s).

use std::collections::VecDeque;

use core_nostd::network::NextInput;

use crate::formats::Event64;

/// How far ahead of the event it hands on the buffer reads (µs): the normalized readout's
/// reach on the host at its default 1 kHz (`NetSink::reach_us`, 254 output periods). At lower
/// output rates the readout reaches further and its units emit up to here at most; at higher
/// ones they emit as far as it reaches and the tick visits the rest.
pub const LOOKAHEAD_US: u64 = 254_000;

/// No event of the pixel buffered (in [`Lookahead::last`]).
const NONE: u32 = u32::MAX;

/// [`Lookahead::next`] of an event whose pixel has no later event read yet.
const UNKNOWN: u64 = u64::MAX;

/// In [`Lookahead::next`]: the pixel's next event comes after a later event (the stream went
/// back in time in between), so it is only a bound.
const AFTER: u64 = 1 << 63;

/// The read-ahead buffer of one piece of a recording (see the module docs).
pub struct Lookahead {
    width: usize,
    height: usize,
    /// Per pixel, the stream index (its low 32 bits) of its latest buffered event, or
    /// [`NONE`]: an entry is cleared when its event leaves the buffer, so every index held is
    /// within the buffer (4 bytes a pixel, to keep the table in cache).
    last: Vec<u32>,
    /// The buffered events, in stream order.
    buf: VecDeque<Event64>,
    /// Beside each, the time of its pixel's next event (or [`UNKNOWN`], with [`AFTER`]).
    next: VecDeque<u64>,
    /// Stream index of the front of `buf`.
    front_index: u64,
    /// Latest event time read.
    latest: u64,
}

impl Lookahead {
    /// A buffer for a `width` x `height` sensor (events outside it pass through unmatched).
    pub fn new(width: u16, height: u16) -> Self {
        let (width, height) = (usize::from(width), usize::from(height));
        Self {
            width,
            height,
            last: vec![NONE; width * height],
            buf: VecDeque::new(),
            next: VecDeque::new(),
            front_index: 0,
            latest: 0,
        }
    }

    /// The index of pixel `(x, y)` in [`Lookahead::last`], if it is on the sensor.
    #[inline]
    fn pixel(&self, x: u16, y: u16) -> Option<usize> {
        let (x, y) = (usize::from(x), usize::from(y));
        (x < self.width && y < self.height).then_some(y * self.width + x)
    }

    /// Asks for the table entry of pixel `(x, y)` to be brought into the cache: an event a few
    /// positions later in the input ([`prefetch`]).
    #[inline]
    pub fn prefetch_pixel(&self, x: u16, y: u16) {
        if let Some(slot) = self.pixel(x, y).and_then(|p| self.last.get(p..=p)) {
            prefetch(slot);
        }
    }

    /// Reads event `e` into the buffer.
    pub fn push(&mut self, e: Event64) {
        let len = self.buf.len();
        let index = (self.front_index + len as u64) as u32;
        if let Some(slot) = self.pixel(e.x, e.y).and_then(|p| self.last.get_mut(p)) {
            let prev = core::mem::replace(slot, index);
            // An index of `NONE` itself (one in 2^32) reads as none: its event then only
            // misses its next one (a bound instead, as at the end of the buffer).
            let at = prev.wrapping_sub(self.front_index as u32) as usize;
            if prev != NONE && at < len {
                if let Some(next) = self.next.get_mut(at) {
                    *next = if self.latest <= e.t_us {
                        e.t_us
                    } else {
                        e.t_us | AFTER
                    };
                }
            }
        }
        self.latest = if len == 0 {
            e.t_us
        } else {
            self.latest.max(e.t_us)
        };
        self.buf.push_back(e);
        self.next.push_back(UNKNOWN);
    }

    /// The pixel of the `k`-th buffered event after the front.
    pub fn peek(&self, k: usize) -> Option<(u16, u16)> {
        self.buf.get(k).map(|e| (e.x, e.y))
    }

    /// The front event, once the buffer has read [`LOOKAHEAD_US`] beyond it (or always, with
    /// `all`: the end of the piece), with its pixel's next event on the clock of a piece
    /// starting at `t0`.
    pub fn pop(&mut self, t0: u64, all: bool) -> Option<(Event64, NextInput)> {
        let &e = self.buf.front()?;
        if !all && e.t_us.saturating_add(LOOKAHEAD_US) > self.latest {
            return None;
        }
        self.buf.pop_front();
        let next = self.next.pop_front().unwrap_or(UNKNOWN);
        if next == UNKNOWN {
            // Still its pixel's latest event: the pixel has none buffered any more.
            let index = self.front_index as u32;
            if let Some(slot) = self.pixel(e.x, e.y).and_then(|p| self.last.get_mut(p)) {
                if *slot == index {
                    *slot = NONE;
                }
            }
        }
        self.front_index += 1;
        let clock = |t: u64| t.wrapping_sub(t0) as u32;
        let next = if next == UNKNOWN {
            NextInput::NotBefore(clock(self.latest))
        } else if next & AFTER != 0 {
            NextInput::NotBefore(clock(next & !AFTER))
        } else {
            NextInput::At(clock(next))
        };
        Some((e, next))
    }
}

/// Bytes of a cache line (x86-64).
const CACHE_LINE: usize = 64;

/// Asks the processor to bring every cache line of `items` into its cache, without waiting
/// for them: the state an event a few positions later will touch ([`PREFETCH_DISTANCE`]).
#[inline(always)]
pub fn prefetch<T>(items: &[T]) {
    let bytes = core::mem::size_of_val(items);
    let start = items.as_ptr().cast::<u8>();
    // Each line the items begin in, then the line of their last byte.
    let lines = (0..bytes).step_by(CACHE_LINE).chain(bytes.checked_sub(1));
    for offset in lines {
        prefetch_byte(start.wrapping_add(offset));
    }
}

/// Asks for the cache line of byte `p` (within an object: see [`prefetch`]).
#[inline(always)]
fn prefetch_byte(p: *const u8) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint that never faults and reads nothing into the program; `p`
    // lies within a borrowed object besides.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>(p.cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// How many events ahead of the one processed the state of one is prefetched: far enough that
/// a main-memory access (~100 ns) completes while the events in between are processed.
pub const PREFETCH_DISTANCE: usize = 8;

#[cfg(test)]
mod tests {
    use super::*;

    fn ev(t_us: u64, x: u16) -> Event64 {
        Event64 {
            t_us,
            x,
            y: 0,
            on: true,
        }
    }

    #[test]
    fn each_event_learns_its_pixels_next() {
        let mut la = Lookahead::new(4, 1);
        for e in [ev(0, 0), ev(10, 1), ev(20, 0), ev(15, 1), ev(300_000, 2)] {
            la.push(e);
        }
        // Pixel 0: next at 20, nothing later in between.
        assert_eq!(la.pop(0, false), Some((ev(0, 0), NextInput::At(20))));
        // Pixel 1: next at 15, after an event at 20 (out of order).
        assert_eq!(
            la.pop(0, false),
            Some((ev(10, 1), NextInput::NotBefore(15)))
        );
        // No later event of their pixels read: up to the latest event read.
        assert_eq!(
            la.pop(0, false),
            Some((ev(20, 0), NextInput::NotBefore(300_000)))
        );
        assert_eq!(
            la.pop(0, false),
            Some((ev(15, 1), NextInput::NotBefore(300_000)))
        );
        // Not read far enough ahead of it: only at the end of the piece.
        assert_eq!(la.pop(0, false), None);
        assert_eq!(
            la.pop(40_000, true),
            Some((ev(300_000, 2), NextInput::NotBefore(260_000)))
        );
        assert_eq!(la.pop(0, true), None);
    }

    /// Against a brute-force search over the whole stream: random events on a few pixels, out
    /// of order at times, pushed and popped interleaved, the buffer emptied twice.
    #[test]
    fn next_inputs_match_a_search_of_the_stream() {
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut rand = |n: u64| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed % n
        };
        let mut t = 0u64;
        let stream: Vec<Event64> = (0..20_000)
            .map(|_| {
                t += rand(40_000);
                let back = if rand(10) == 0 { rand(30_000) } else { 0 };
                ev(t.saturating_sub(back), rand(6) as u16)
            })
            .collect();
        let mut la = Lookahead::new(5, 1);
        let (mut pushed, mut popped) = (0usize, 0usize);
        let check = |la: &mut Lookahead, all: bool, pushed: usize, popped: &mut usize| {
            while let Some((e, next)) = la.pop(0, all) {
                let i = *popped;
                assert_eq!(e, stream[i]);
                let later = (i + 1..pushed).find(|&j| stream[j].x == e.x && e.x < 5);
                let latest = stream[..pushed].iter().map(|e| e.t_us).max().unwrap_or(0);
                let want = match later {
                    Some(j) if stream[..j].iter().all(|p| p.t_us <= stream[j].t_us) => {
                        NextInput::At(stream[j].t_us as u32)
                    }
                    Some(j) => NextInput::NotBefore(stream[j].t_us as u32),
                    None => NextInput::NotBefore(latest as u32),
                };
                assert_eq!(next, want, "event {i}");
                *popped += 1;
            }
        };
        for (k, &e) in stream.iter().enumerate() {
            la.push(e);
            pushed += 1;
            let all = k == 7_000 || k == 13_000;
            check(&mut la, all, pushed, &mut popped);
        }
        check(&mut la, true, pushed, &mut popped);
        assert_eq!(popped, stream.len());
    }

    #[test]
    fn events_outside_the_sensor_pass_through() {
        let mut la = Lookahead::new(2, 2);
        la.push(ev(5, 7));
        la.push(ev(6, 7));
        assert_eq!(la.pop(0, true), Some((ev(5, 7), NextInput::NotBefore(6))));
    }
}
