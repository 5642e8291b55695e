//! The time-gap policy of `host-sim run` and `host-sim aer-stream`: a recording is processed as
//! pieces of continuous time.
//!
//! The pipeline's clock is `u32` µs and orders two times only when they are less than 2^31 µs
//! (35.8 min) apart. A recording longer than that is fine as long as its events keep coming (the
//! clock wraps and every difference stays small), but a jump of the recording's own clock is
//! not. So, on the recording's `u64` clock:
//!
//! - a **gap**: an event more than [`RESTART_GAP_US`] (10 min) after the previous one;
//! - a **backward jump**: an event more than [`RESTART_BACK_US`] (100 ms) before the previous one
//!
//! ends the current piece and starts a new one at that event. Each piece is processed exactly as
//! if it were a recording of its own: fresh network and readout state, output grid starting at
//! its first event, samples up to its last event. Nothing is output for the time between two
//! pieces; the first sample of every piece after the first carries [`RESTART`]. So the output of
//! a recording is the output of its pieces run one by one, one after the other (after a backward
//! jump, sample times go back too: they stay on the recording's clock).
//!
//! Smaller steps back (events out of order by up to 100 ms) stay in their piece: the network
//! takes such a late event without decaying the pixel it lands on, and they are counted.

use anyhow::Result;

use crate::formats::{Event64, EventChunks};

/// A forward step between consecutive events above this (µs, 10 min) starts a new piece.
pub const RESTART_GAP_US: u64 = 600_000_000;

/// A backward step between consecutive events above this (µs, 100 ms) starts a new piece.
pub const RESTART_BACK_US: u64 = 100_000;

pub use core_nostd::flags::RESTART;

/// Counts of the recording's time discontinuities.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TimeJumps {
    /// Gaps over [`RESTART_GAP_US`] (each started a piece).
    pub gaps: u64,
    /// Backward jumps over [`RESTART_BACK_US`] (each started a piece).
    pub backward: u64,
    /// Events earlier than their predecessor by up to [`RESTART_BACK_US`] (kept in their
    /// piece).
    pub out_of_order: u64,
}

impl TimeJumps {
    /// Pieces after the first.
    #[must_use]
    pub fn restarts(&self) -> u64 {
        self.gaps + self.backward
    }
}

/// A recording's events, split into pieces of continuous time.
pub struct Pieces<'r> {
    reader: &'r mut dyn EventChunks,
    chunk: Vec<Event64>,
    pos: usize,
    prev: Option<u64>,
    /// The event that ended the current piece (the first of the next).
    pending: Option<Event64>,
    /// Discontinuities so far.
    pub jumps: TimeJumps,
    /// Events read so far.
    pub events: u64,
}

impl<'r> Pieces<'r> {
    /// Splits the events of `reader`.
    pub fn new(reader: &'r mut dyn EventChunks) -> Self {
        Self {
            reader,
            chunk: Vec::new(),
            pos: 0,
            prev: None,
            pending: None,
            jumps: TimeJumps::default(),
            events: 0,
        }
    }

    #[inline]
    fn pull(&mut self) -> Result<Option<Event64>> {
        if let Some(&e) = self.chunk.get(self.pos) {
            self.pos += 1;
            self.events += 1;
            return Ok(Some(e));
        }
        if !self.reader.next_chunk(&mut self.chunk)? {
            return Ok(None);
        }
        self.pos = 0;
        let e = self.chunk.first().copied();
        if e.is_some() {
            self.pos = 1;
            self.events += 1;
        }
        Ok(e)
    }

    /// The first event of the next piece, `None` at the end of the recording.
    ///
    /// # Errors
    /// When the recording cannot be read.
    pub fn next_piece(&mut self) -> Result<Option<Event64>> {
        if let Some(e) = self.pending.take() {
            return Ok(Some(e));
        }
        if self.prev.is_some() {
            return Ok(None);
        }
        let e = self.pull()?;
        self.prev = e.map(|e| e.t_us);
        Ok(e)
    }

    /// Calls `f` on `first` and then on every further event of its piece, in order.
    ///
    /// # Errors
    /// When the recording cannot be read, or the first error of `f`.
    pub fn for_each<F: FnMut(&Event64) -> Result<()>>(
        &mut self,
        first: Event64,
        mut f: F,
    ) -> Result<()> {
        f(&first)?;
        loop {
            let slice = self.next_slice()?;
            if slice.is_empty() {
                return Ok(());
            }
            for e in slice {
                f(e)?;
            }
        }
    }

    /// The next events of the current piece (a slice of the chunk being read), empty at its
    /// end (the end of the recording, a gap or a backward jump).
    ///
    /// # Errors
    /// When the recording cannot be read.
    pub fn next_slice(&mut self) -> Result<&[Event64]> {
        if self.pending.is_some() {
            return Ok(&[]);
        }
        if self.pos >= self.chunk.len() {
            if !self.reader.next_chunk(&mut self.chunk)? {
                return Ok(&[]);
            }
            self.pos = 0;
        }
        let start = self.pos;
        let rest = self.chunk.get(start..).unwrap_or_default();
        let mut prev = self.prev.unwrap_or(rest.first().map_or(0, |e| e.t_us));
        let mut end = start + rest.len();
        for (i, e) in rest.iter().enumerate() {
            let t = e.t_us;
            if t < prev {
                if prev - t > RESTART_BACK_US {
                    self.jumps.backward += 1;
                    self.pending = Some(*e);
                    end = start + i;
                    prev = t;
                    break;
                }
                self.jumps.out_of_order += 1;
            } else if t - prev > RESTART_GAP_US {
                self.jumps.gaps += 1;
                self.pending = Some(*e);
                end = start + i;
                prev = t;
                break;
            }
            prev = t;
        }
        self.prev = Some(prev);
        // The event that ends the piece is consumed here and handed out by `next_piece`.
        self.pos = if self.pending.is_some() { end + 1 } else { end };
        self.events += (self.pos - start) as u64;
        Ok(self.chunk.get(start..end).unwrap_or_default())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Events from a list of times, handed out in chunks of three.
    struct Times(Vec<u64>);

    impl EventChunks for Times {
        fn next_chunk(&mut self, out: &mut Vec<Event64>) -> Result<bool> {
            out.clear();
            let n = self.0.len().min(3);
            out.extend(self.0.drain(..n).map(|t_us| Event64 {
                t_us,
                ..Event64::default()
            }));
            Ok(n > 0)
        }
    }

    #[test]
    fn pieces_split_at_gaps_and_jumps_back_only() {
        let times = vec![
            10,
            20,
            15, // 5 µs back: out of order, same piece
            30,
            30 + RESTART_GAP_US,     // exactly the limit: same piece
            31 + 2 * RESTART_GAP_US, // over it: new piece
            40 + 2 * RESTART_GAP_US,
            39 + 2 * RESTART_GAP_US - RESTART_BACK_US, // the limit + 1 µs back: new piece
            50 + 2 * RESTART_GAP_US,
        ];
        let mut src = Times(times.clone());
        let mut pieces = Pieces::new(&mut src);
        let mut got: Vec<Vec<u64>> = Vec::new();
        while let Some(first) = pieces.next_piece().unwrap() {
            let mut piece = Vec::new();
            pieces
                .for_each(first, |e| {
                    piece.push(e.t_us);
                    Ok(())
                })
                .unwrap();
            got.push(piece);
        }
        assert_eq!(
            got,
            vec![
                times[..5].to_vec(),
                times[5..7].to_vec(),
                times[7..].to_vec()
            ]
        );
        assert_eq!(
            pieces.jumps,
            TimeJumps {
                gaps: 1,
                backward: 1,
                out_of_order: 1
            }
        );
        assert_eq!(pieces.events, times.len() as u64);
    }
}
