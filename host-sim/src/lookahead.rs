//! Reading a recording ahead: each event comes out with what is known of the next event at its
//! pixel ([`NextInput`]), so that the network's units can emit their spikes up to that event
//! at once instead of once per output period ([`core_nostd::network::Network::event_in_ahead`]).
//!
//! A live sensor cannot do this; a recording can. The events come out in stream order, each
//! [`LOOKAHEAD_US`] after it on the stream's clock (or at the end of the piece), so the
//! buffer holds about that much of the recording (~40 k events for a busy DAVIS346 scene).

use std::collections::VecDeque;

use core_nostd::network::NextInput;

use crate::formats::Event64;

/// How far ahead of the event it hands on the buffer reads (µs): the normalized readout's
/// reach on the host (62 output periods at 1 kHz).
pub const LOOKAHEAD_US: u64 = 254_000;

/// No event of the pixel buffered.
const NONE: u64 = u64::MAX;

/// What is known of the next event at a buffered event's pixel, on the recording's clock.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Next {
    /// Not read yet.
    Unknown,
    /// At this time, with no event between the two later than it.
    At(u64),
    /// At this time, after some later event (the stream went back in time in between).
    After(u64),
}

/// The read-ahead buffer of one piece of a recording (see the module docs).
pub struct Lookahead {
    width: usize,
    height: usize,
    /// Per pixel, the stream index of its latest buffered event (or [`NONE`]).
    last: Vec<u64>,
    buf: VecDeque<(Event64, Next)>,
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
            front_index: 0,
            latest: 0,
        }
    }

    /// Reads event `e` into the buffer.
    pub fn push(&mut self, e: Event64) {
        let index = self.front_index + self.buf.len() as u64;
        let (x, y) = (usize::from(e.x), usize::from(e.y));
        if x < self.width && y < self.height {
            if let Some(last) = self.last.get_mut(y * self.width + x) {
                let prev = *last;
                *last = index;
                if prev != NONE && prev >= self.front_index {
                    let ordered = self.latest <= e.t_us;
                    if let Some((_, next)) = usize::try_from(prev - self.front_index)
                        .ok()
                        .and_then(|i| self.buf.get_mut(i))
                    {
                        *next = if ordered {
                            Next::At(e.t_us)
                        } else {
                            Next::After(e.t_us)
                        };
                    }
                }
            }
        }
        self.latest = if self.buf.is_empty() {
            e.t_us
        } else {
            self.latest.max(e.t_us)
        };
        self.buf.push_back((e, Next::Unknown));
    }

    /// The pixel of the `k`-th buffered event after the front.
    pub fn peek(&self, k: usize) -> Option<(u16, u16)> {
        self.buf.get(k).map(|(e, _)| (e.x, e.y))
    }

    /// The front event, once the buffer has read [`LOOKAHEAD_US`] beyond it (or always, with
    /// `all`: the end of the piece), with its pixel's next event on the clock of a piece
    /// starting at `t0`.
    pub fn pop(&mut self, t0: u64, all: bool) -> Option<(Event64, NextInput)> {
        let &(e, _) = self.buf.front()?;
        if !all && e.t_us.saturating_add(LOOKAHEAD_US) > self.latest {
            return None;
        }
        let (e, next) = self.buf.pop_front()?;
        self.front_index += 1;
        let clock = |t: u64| t.wrapping_sub(t0) as u32;
        let next = match next {
            Next::At(t) => NextInput::At(clock(t)),
            Next::After(t) => NextInput::NotBefore(clock(t)),
            Next::Unknown => NextInput::NotBefore(clock(self.latest)),
        };
        Some((e, next))
    }
}

/// Asks the processor to bring the memory of `r` into its cache, without waiting for it: the
/// state an event a few positions later will touch ([`PREFETCH_DISTANCE`]).
#[inline(always)]
pub fn prefetch<T>(r: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint that never faults and reads nothing into the program;
    // `r` is a valid reference besides.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>(std::ptr::from_ref(r).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = r;
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

    #[test]
    fn events_outside_the_sensor_pass_through() {
        let mut la = Lookahead::new(2, 2);
        la.push(ev(5, 7));
        la.push(ev(6, 7));
        assert_eq!(la.pop(0, true), Some((ev(5, 7), NextInput::NotBefore(6))));
    }
}
