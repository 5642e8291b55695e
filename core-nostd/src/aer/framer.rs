//! Frame reassembly from a byte stream that arrives in chunks of any size and may be corrupted.
//!
//! A [`Framer`] buffers bytes until a whole frame is present, checks it, and hands it out. Its
//! one rule for corruption: **a rejected candidate moves the scan by one byte only**, and the
//! bytes after that position are kept and scanned again. So a frame that arrived intact is found
//! whatever came before it — garbage, a truncated frame whose length field swallowed it, a false
//! sync pattern inside a payload — as long as the buffer holds one maximal frame
//! (`CAP >= S::MAX_FRAME`).
//!
//! Cost: bytes are copied once into the buffer; a clean stream is checked once per frame (the
//! scan for the sync pattern only runs after a rejection). Garbage costs a sync search per byte.

use core::marker::PhantomData;

/// What a frame format tells the framer.
pub trait FrameSpec {
    /// The two bytes every frame starts with.
    const SYNC: [u8; 2];
    /// Bytes needed to know a frame's length (sync included).
    const HEADER: usize;
    /// Longest frame of the format in bytes (the framer's buffer must hold one).
    const MAX_FRAME: usize;
    /// Reads a header (`HEADER` bytes starting with the sync pattern).
    fn header(header: &[u8]) -> Header;
    /// Whether a whole candidate frame (of the length [`FrameSpec::header`] gave) is intact.
    fn check(frame: &[u8]) -> bool;
}

/// What a header says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Header {
    /// Not a header (its own check failed): the sync pattern was a coincidence.
    NotAFrame,
    /// A checked header with values the format does not allow (unknown version or kind, length
    /// too long or misaligned): counted as a bad frame.
    Invalid,
    /// A plausible frame of this many bytes in total (at most `MAX_FRAME`).
    Frame(usize),
}

/// Counters of a [`Framer`], since its creation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FramerStats {
    /// Bytes pushed.
    pub bytes: u64,
    /// Frames that passed their check and were handed out.
    pub frames: u64,
    /// Candidates with a valid header check but values the format does not allow.
    pub bad_header: u64,
    /// Candidates with a valid header whose frame check (CRC) failed, including frames cut
    /// short by lost bytes and frames still incomplete at [`Framer::finish`].
    pub bad_crc: u64,
    /// Bytes that were not part of a handed-out frame (garbage, rejected candidates).
    pub skipped_bytes: u64,
}

/// Streaming frame reassembler for format `S` with a `CAP`-byte buffer (`CAP >= S::MAX_FRAME`;
/// a smaller buffer rejects the frames that do not fit as bad).
#[derive(Clone, Debug)]
pub struct Framer<S: FrameSpec, const CAP: usize> {
    buf: [u8; CAP],
    /// First byte not yet consumed.
    start: usize,
    /// One past the last valid byte; `start <= end <= CAP`.
    end: usize,
    stats: FramerStats,
    spec: PhantomData<S>,
}

impl<S: FrameSpec, const CAP: usize> Default for Framer<S, CAP> {
    fn default() -> Self {
        Self::new()
    }
}

/// What one scan step found.
enum Step {
    /// More bytes are needed.
    NeedMore,
    /// A frame at `start`, `n` bytes long, passed its check.
    Frame(usize),
    /// Progress was made (bytes skipped); scan again.
    Again,
}

impl<S: FrameSpec, const CAP: usize> Framer<S, CAP> {
    /// An empty framer.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            buf: [0; CAP],
            start: 0,
            end: 0,
            stats: FramerStats {
                bytes: 0,
                frames: 0,
                bad_header: 0,
                bad_crc: 0,
                skipped_bytes: 0,
            },
            spec: PhantomData,
        }
    }

    /// Counters since creation.
    #[must_use]
    pub const fn stats(&self) -> &FramerStats {
        &self.stats
    }

    /// Bytes buffered and not yet handed out (an incomplete frame, or a partial sync pattern).
    #[must_use]
    pub const fn pending(&self) -> usize {
        self.end - self.start
    }

    /// Bytes [`Framer::feed`] takes now (`CAP - pending`, after moving the pending bytes to
    /// the front of the buffer).
    #[must_use]
    pub const fn room(&self) -> usize {
        CAP - self.pending()
    }

    /// Bytes still missing from the frame being collected, when the buffered bytes start with
    /// a header that passed its check; `None` otherwise (no frame started, header incomplete
    /// or rejected, or the frame complete).
    #[must_use]
    pub fn need(&self) -> Option<usize> {
        let w = self.buf.get(self.start..self.end)?;
        if !w.starts_with(&S::SYNC) {
            return None;
        }
        match S::header(w.get(..S::HEADER)?) {
            Header::Frame(n) if n <= CAP && n > w.len() => Some(n - w.len()),
            _ => None,
        }
    }

    /// Whether the buffered bytes start a frame (the sync pattern and more) that is not
    /// complete yet. Meaningful after [`Framer::next_frame`] returned `None`.
    #[must_use]
    pub fn partial_frame(&self) -> bool {
        self.buf
            .get(self.start..self.end)
            .is_some_and(|w| w.starts_with(&S::SYNC))
    }

    /// Drops the buffered bytes because they are known to be broken (the link lost its bit
    /// alignment): a candidate with a valid header is counted bad (cut short), the bytes
    /// skipped. Unlike [`Framer::next_frame_at_end`] nothing behind the candidate is rescanned.
    pub fn discard(&mut self) {
        let window = self.buf.get(self.start..self.end).unwrap_or_default();
        if window.starts_with(&S::SYNC)
            && matches!(
                window.get(..S::HEADER).map(S::header),
                Some(Header::Frame(_))
            )
        {
            self.stats.bad_crc += 1;
        }
        self.clear();
    }

    /// Forgets buffered bytes (counted as skipped) without touching the counters otherwise.
    pub fn clear(&mut self) {
        self.stats.skipped_bytes += self.pending() as u64;
        self.start = 0;
        self.end = 0;
    }

    /// Copies as much of `bytes` as fits into the buffer (continuing the previous call) and
    /// returns how many were taken. Frames are then taken out with [`Framer::next_frame`]; when
    /// the buffer is full, `next_frame` always makes room.
    pub fn feed(&mut self, bytes: &[u8]) -> usize {
        // `start <= end <= CAP` always holds; saying so lets the compiler drop copy_within's
        // range check (and its panic path: see firmware/src/bin/no-panic-check.rs).
        if self.start > 0
            && self.start <= self.end
            && self.end <= CAP
            && CAP - self.end < bytes.len()
        {
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.start = 0;
        }
        let take = (CAP - self.end).min(bytes.len());
        if let (Some(dst), Some(src)) = (
            self.buf.get_mut(self.end..self.end + take),
            bytes.get(..take),
        ) {
            dst.copy_from_slice(src);
            self.end += take;
            self.stats.bytes += take as u64;
            take
        } else {
            0
        }
    }

    /// The next intact frame among the buffered bytes (sync included), or `None` when more
    /// bytes are needed. The slice stays valid until the next [`Framer::feed`].
    pub fn next_frame(&mut self) -> Option<&[u8]> {
        let (a, b) = self.next_with(false)?;
        self.buf.get(a..b)
    }

    /// As [`Framer::next_frame`] once the stream has ended: a candidate still waiting for
    /// bytes is counted bad (truncated) and the bytes behind its sync are scanned again, so an
    /// intact frame after a truncated one is still found. `None` means the buffer is now empty.
    pub fn next_frame_at_end(&mut self) -> Option<&[u8]> {
        match self.next_with(true) {
            Some((a, b)) => self.buf.get(a..b),
            None => {
                self.clear();
                None
            }
        }
    }

    fn next_with(&mut self, at_end: bool) -> Option<(usize, usize)> {
        loop {
            match self.step(at_end) {
                Step::NeedMore => return None,
                Step::Again => {}
                Step::Frame(n) => {
                    self.stats.frames += 1;
                    let a = self.start;
                    self.start += n;
                    return Some((a, a + n));
                }
            }
        }
    }

    /// Consumes `bytes` and calls `on_frame` with every intact frame they complete, in stream
    /// order (the slice holds the whole frame, sync included).
    pub fn push<F: FnMut(&[u8])>(&mut self, bytes: &[u8], mut on_frame: F) {
        let mut rest = bytes;
        loop {
            let n = self.feed(rest);
            rest = rest.get(n..).unwrap_or_default();
            let mut found = false;
            while let Some((a, b)) = self.next_with(false) {
                found = true;
                if let Some(f) = self.buf.get(a..b) {
                    on_frame(f);
                }
            }
            if rest.is_empty() {
                return;
            }
            if n == 0 && !found {
                // Only with a buffer smaller than a header: never stall.
                self.clear();
            }
        }
    }

    /// Ends the stream (see [`Framer::next_frame_at_end`]) and hands out the frames left.
    /// Afterwards the framer is empty and can take a new stream.
    pub fn finish<F: FnMut(&[u8])>(&mut self, mut on_frame: F) {
        while let Some((a, b)) = self.next_with(true) {
            if let Some(f) = self.buf.get(a..b) {
                on_frame(f);
            }
        }
        self.clear();
    }

    fn skip(&mut self, n: usize) {
        let n = n.min(self.pending());
        self.start += n;
        self.stats.skipped_bytes += n as u64;
    }

    fn step(&mut self, at_end: bool) -> Step {
        let [s0, s1] = S::SYNC;
        let Some(window) = self.buf.get(self.start..self.end) else {
            return Step::NeedMore;
        };
        // Find the sync pattern.
        match window.windows(2).position(|w| w == [s0, s1]) {
            Some(0) => {}
            Some(i) => {
                self.skip(i);
                return Step::Again;
            }
            None => {
                // Keep a last byte that may be the first half of the pattern.
                let keep = usize::from(!at_end && window.last() == Some(&s0));
                self.skip(window.len() - keep);
                return Step::NeedMore;
            }
        }
        let have = window.len();
        if have < S::HEADER {
            if at_end {
                self.skip(have);
            }
            return Step::NeedMore;
        }
        let n = match S::header(window.get(..S::HEADER).unwrap_or_default()) {
            Header::NotAFrame => {
                self.skip(1);
                return Step::Again;
            }
            Header::Invalid => {
                self.stats.bad_header += 1;
                self.skip(1);
                return Step::Again;
            }
            Header::Frame(n) if n < S::HEADER || n > CAP => {
                self.stats.bad_header += 1;
                self.skip(1);
                return Step::Again;
            }
            Header::Frame(n) => n,
        };
        let Some(frame) = window.get(..n) else {
            if at_end {
                // Truncated by the end of the stream: bad, and look behind its sync.
                self.stats.bad_crc += 1;
                self.skip(1);
                return Step::Again;
            }
            return Step::NeedMore;
        };
        if S::check(frame) {
            Step::Frame(n)
        } else {
            self.stats.bad_crc += 1;
            self.skip(1);
            Step::Again
        }
    }
}
