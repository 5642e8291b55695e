//! The receiving end of the SPI link: raw bytes from an SPI slave and the link's events (end of
//! transaction, overrun, mode fault, DMA ring overrun) in, intact AER frames out.
//!
//! An SPI slave assembles bytes from bits with a bit counter that only the peripheral's reset
//! (disable / enable) clears. One spurious SCK edge (ringing on a long cable, a glitch while the
//! master boots) or a lost one shifts every later byte by a bit, and a byte-aligned sync search
//! never finds a frame again. [`LinkReceiver`] recovers from that two ways:
//!
//! - **At the next transaction.** The sender frames transactions with NSS and starts each one
//!   with a frame; the board re-arms the peripheral when NSS rises (which resets the bit
//!   counter) and reports [`LinkEvent::EndOfTransaction`] at that point of the byte stream: a
//!   frame still incomplete there is cut (counted), and the next byte is a frame start again.
//! - **At the next frame, inside a transaction.** Wherever a frame may start — between
//!   frames, after a broken one, and over the last 16 bytes of each frame (where the next one
//!   starts if bytes were lost) — table lookups look for the sync pattern at the seven other
//!   bit offsets; a hit whose 10-byte header then passes the header check (CRC-16, version,
//!   kind, length) moves the receiver to that bit offset: the broken frame is dropped (counted
//!   bad), the bytes from that header on are shifted back into place, and the frame decoder
//!   sees an intact frame. The rest of a frame whose header checked is not searched: its CRC
//!   is checked first, and only when it fails does the search go on, at the bytes after it.
//!   A false switch needs a sync pattern and a passing CRC-16 by chance at another offset
//!   (~1e-13 per searched byte). Cost in the QEMU replay: 20 instructions per byte for the
//!   whole input stage (framing, CRCs, search, copies), against 16 without the search.
//!
//! So one slip, one glitch on NSS or one overrun costs the frame it hits (and the bytes lost
//! while the peripheral was down), and the next whole frame is received. Overruns (SPI OVR, DMA
//! ring) lose bytes, not bits: the frame decoder's CRC and resync handle those; they are counted
//! here. Bits arrive MSB first (SPI mode 0, see `docs/wire-formats.md`).

use super::frame::{AerSpec, Frame, FrameDecoder, FrameStats, HEADER_BYTES, SYNC};
use super::framer::{FrameSpec, Header};

/// What the board's SPI peripheral reports besides bytes, at its place in the byte stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkEvent {
    /// NSS rose (the master ended a transaction); the board has re-armed the peripheral, so
    /// the next byte is bit-aligned and starts a frame.
    EndOfTransaction,
    /// The SPI overrun flag (OVR): bytes were lost near this point (the board cleared it).
    Overrun,
    /// Mode fault (MODF): the peripheral disabled itself; the board cleared the fault and
    /// re-armed it here (bytes were lost, the next byte may start anywhere in a frame).
    ModeFault,
    /// The DMA ring was overwritten before it was read: bytes were lost here.
    RingOverrun,
}

/// Counters of a [`LinkReceiver`], since its creation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Transactions ended ([`LinkEvent::EndOfTransaction`]).
    pub transactions: u64,
    /// Transactions that ended inside a frame (an NSS glitch, an aborted transfer): the cut
    /// frame is counted bad by the frame decoder as well.
    pub cut_transactions: u64,
    /// Times the receiver moved to another bit offset (a spurious or lost SCK edge inside a
    /// transaction, or a peripheral re-armed in the middle of a byte).
    pub bit_slips: u64,
    /// SPI overruns reported.
    pub overruns: u64,
    /// Mode faults reported.
    pub mode_faults: u64,
    /// DMA ring overruns reported.
    pub ring_overruns: u64,
}

/// Bytes the receiver realigns per [`LinkReceiver::feed`] call at a bit offset (at offset 0
/// the bytes go to the frame decoder as they are).
const STAGE: usize = 128;
/// Bytes searched per [`LinkReceiver::feed`] call outside a checked frame: a little more than
/// a header, so that a frame's header is checked after one or two calls.
const HUNT_STEP: usize = 16;

/// Sync-pattern tables: bit `s` of `FIRST[a] & MID[b] & LAST[c]` is set when the raw bytes
/// `a b c` hold the sync pattern starting at bit `s` of `a` (MSB first; `s = 0`: `a b` are the
/// pattern).
const FIRST: [u8; 256] = sync_table(Part::First);
const MID: [u8; 256] = sync_table(Part::Mid);
const LAST: [u8; 256] = sync_table(Part::Last);

/// Mask of the low `n` bits (`n <= 8`).
const fn low(n: u32) -> u32 {
    (1 << n) - 1
}

/// Whether the low `8 - s` bits of `r` are the high `8 - s` bits of `p` (its first part at
/// offset `s`).
const fn head_matches(r: u32, p: u32, s: u32) -> bool {
    r & low(8 - s) == p >> s
}

/// Whether the high `s` bits of `r` are the low `s` bits of `p` (its second part at offset `s`).
const fn tail_matches(r: u32, p: u32, s: u32) -> bool {
    s == 0 || r >> (8 - s) == p & low(s)
}

/// Which raw byte of the three a table is for.
#[derive(Clone, Copy)]
enum Part {
    /// Holds the first sync byte's head.
    First,
    /// Holds the first sync byte's tail and the second one's head.
    Mid,
    /// Holds the second sync byte's tail.
    Last,
}

// Evaluated at compile time only: an index out of range would fail the build, not panic.
#[allow(clippy::indexing_slicing)]
const fn sync_table(part: Part) -> [u8; 256] {
    let (a, b) = (SYNC[0] as u32, SYNC[1] as u32);
    let mut t = [0u8; 256];
    let mut r = 0;
    while r < 256 {
        let mut s = 0;
        while s < 8 {
            let hit = match part {
                Part::First => head_matches(r, a, s),
                Part::Mid => tail_matches(r, a, s) && head_matches(r, b, s),
                Part::Last => tail_matches(r, b, s),
            };
            if hit {
                t[r as usize] |= 1 << s;
            }
            s += 1;
        }
        r += 1;
    }
    t
}

fn lookup(t: &[u8; 256], b: u32) -> u8 {
    t.get((b & 0xFF) as usize).copied().unwrap_or(0)
}

/// The byte that starts at bit `s` of `a` (MSB first), completed from `b`.
#[inline]
const fn combine(a: u8, b: u8, s: u8) -> u8 {
    if s == 0 {
        a
    } else {
        ((a as u32) << s | (b as u32) >> (8 - s)) as u8
    }
}

/// Raw bytes a header at a bit offset spans (the header, plus one for the offset's tail).
const SPAN: usize = HEADER_BYTES + 1;

/// Sync candidates collected at once (a false one, by chance in a payload, must not hide the
/// real header that follows it within a header's length).
const SLOTS: usize = 4;

/// A sync candidate at some bit offsets: the raw bytes from its first byte on.
#[derive(Clone, Copy, Debug)]
struct Candidate {
    bytes: [u8; SPAN],
    /// Bytes collected (0: slot free).
    len: usize,
    /// Bit offsets at which the bytes hold the sync pattern.
    mask: u8,
}

impl Candidate {
    const FREE: Self = Self {
        bytes: [0; SPAN],
        len: 0,
        mask: 0,
    };

    /// The header realigned at bit offset `s`.
    fn header(&self, s: u8) -> [u8; HEADER_BYTES] {
        let mut h = [0u8; HEADER_BYTES];
        for (out, pair) in h.iter_mut().zip(self.bytes.windows(2)) {
            if let [a, b] = *pair {
                *out = combine(a, b, s);
            }
        }
        h
    }
}

/// Looks for frame headers at the bit offsets the receiver is not using. Per searched byte: one
/// table lookup (the sync pattern's middle byte), and for 1 byte in 32 the full three-lookup
/// test; a sync candidate (by chance about one every 8 KiB of payload) collects the 8 raw bytes
/// its header still needs and is then checked.
#[derive(Clone, Debug)]
struct Hunter {
    /// The last three raw bytes (newest in the low byte). Zero after a reset: no table entry
    /// of a zero byte matches, so no candidate starts before three real bytes.
    window: u32,
    slots: [Candidate; SLOTS],
    /// Slots in use.
    pending: usize,
    /// The candidate whose header checked.
    found: Candidate,
}

impl Hunter {
    const fn new() -> Self {
        Self {
            window: 0,
            slots: [Candidate::FREE; SLOTS],
            pending: 0,
            found: Candidate::FREE,
        }
    }

    /// Scans raw bytes; returns the index of the first byte that completes a checked frame
    /// header at a bit offset other than `cur`, and that offset (the header's raw bytes are
    /// then in `found`). Bytes after that one are not looked at.
    #[inline]
    fn scan(&mut self, raw: &[u8], cur: u8) -> Option<(usize, u8)> {
        let others = !(1u8 << cur);
        let mut w = self.window;
        let mut hit = None;
        for (i, &b) in raw.iter().enumerate() {
            w = (w << 8) | u32::from(b);
            // The middle byte of a sync pattern at offset s is one of 8 values: one lookup
            // passes 1 byte in 32 on to the full test.
            if lookup(&MID, w >> 8) & others != 0 || self.pending != 0 {
                if let Some(s) = self.candidates(w, others, b, cur) {
                    hit = Some((i, s));
                    break;
                }
            }
        }
        self.window = w;
        hit
    }

    #[cold]
    fn candidates(&mut self, w: u32, others: u8, b: u8, cur: u8) -> Option<u8> {
        let mask = lookup(&FIRST, w >> 16) & lookup(&MID, w >> 8) & lookup(&LAST, w) & others;
        let mut hit = None;
        for c in self.slots.iter_mut().filter(|c| c.len != 0) {
            if let Some(dst) = c.bytes.get_mut(c.len) {
                *dst = b;
            }
            c.len += 1;
            if c.len == SPAN {
                c.len = 0;
                self.pending = self.pending.saturating_sub(1);
                let due = c.mask & !(1u8 << cur);
                let ok = (0..8u8).find(|&s| {
                    due & (1 << s) != 0 && matches!(AerSpec::header(&c.header(s)), Header::Frame(_))
                });
                if hit.is_none() && ok.is_some() {
                    hit = ok;
                    self.found = *c;
                }
            }
        }
        if hit.is_some() {
            self.slots = [Candidate::FREE; SLOTS];
            self.pending = 0;
            return hit;
        }
        if mask != 0 {
            if let Some(c) = self.slots.iter_mut().find(|c| c.len == 0) {
                let [_, x, y, z] = w.to_be_bytes();
                *c = Candidate {
                    bytes: [x, y, z, 0, 0, 0, 0, 0, 0, 0, 0],
                    len: 3,
                    mask,
                };
                self.pending += 1;
            }
        }
        None
    }

    /// Takes raw bytes without searching them (they belong to a frame whose header checked):
    /// drops the candidates in progress, keeps the last bytes for a search that starts next.
    #[inline]
    fn pass(&mut self, raw: &[u8]) {
        if self.pending != 0 {
            self.slots = [Candidate::FREE; SLOTS];
            self.pending = 0;
        }
        let tail = raw.get(raw.len().saturating_sub(3)..).unwrap_or_default();
        for &b in tail {
            self.window = (self.window << 8) | u32::from(b);
        }
    }

    /// After [`Hunter::scan`] found offset `s`: the stream realigned to `s` from the header on, up
    /// to the last byte pushed (10 bytes, or 11 for `s = 0`). Returns the byte count.
    fn burst(&self, s: u8, out: &mut [u8; SPAN]) -> usize {
        if s == 0 {
            *out = self.found.bytes;
            SPAN
        } else {
            if let Some(dst) = out.get_mut(..HEADER_BYTES) {
                dst.copy_from_slice(&self.found.header(s));
            }
            HEADER_BYTES
        }
    }

    fn reset(&mut self) {
        *self = Self::new();
    }
}

/// The SPI link's receiver: [`LinkReceiver::feed`] raw bytes, report the peripheral's events
/// with [`LinkReceiver::event`] at their place in the stream, take frames with
/// [`LinkReceiver::next_frame`]. No heap, no panic on any input.
#[derive(Clone, Debug)]
pub struct LinkReceiver {
    dec: FrameDecoder,
    hunter: Hunter,
    /// Bit offset of the frames in the raw stream (0 = byte-aligned).
    shift: u8,
    /// The previous raw byte (to realign at `shift != 0`).
    prev: u8,
    /// A transaction ended: hand out what is left of it before taking more bytes.
    flushing: bool,
    /// A header was found at this bit offset: move there on the next [`LinkReceiver::feed`]
    /// (after the frames completed before it have been taken out).
    switch: Option<u8>,
    stats: LinkStats,
}

impl Default for LinkReceiver {
    fn default() -> Self {
        Self::new()
    }
}

impl LinkReceiver {
    /// A receiver at the start of a stream.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            dec: FrameDecoder::new(),
            hunter: Hunter::new(),
            shift: 0,
            prev: 0,
            flushing: false,
            switch: None,
            stats: LinkStats {
                transactions: 0,
                cut_transactions: 0,
                bit_slips: 0,
                overruns: 0,
                mode_faults: 0,
                ring_overruns: 0,
            },
        }
    }

    /// Takes raw bytes as they came off the wire and returns how many were taken (0 while the
    /// frames before an event are still to be taken out). Take frames with
    /// [`LinkReceiver::next_frame`] after each call, until it returns `None`.
    pub fn feed(&mut self, raw: &[u8]) -> usize {
        if self.flushing {
            return 0;
        }
        if let Some(s) = self.switch.take() {
            // The bytes before the header belong to the old alignment: the frame they hold is
            // broken. Then the header, realigned (the decoder is empty: it has room).
            self.dec.discard();
            let mut burst = [0u8; SPAN];
            let k = self.hunter.burst(s, &mut burst);
            self.dec.feed(burst.get(..k).unwrap_or_default());
            self.shift = s;
            self.stats.bit_slips += 1;
        }
        let room = if self.shift == 0 {
            self.dec.room()
        } else {
            self.dec.room().min(STAGE)
        };
        // Inside a frame whose header checked, its bytes go in unsearched but for the last
        // HUNT_STEP (where the next frame starts if bytes of this one were lost), and no
        // further: its CRC is checked before the bytes after it are looked at. Otherwise
        // (between frames, after a broken one) a few bytes at a time are searched at the other
        // bit offsets, until a header checks again.
        let (limit, search) = match self.dec.need() {
            Some(k) if k > HUNT_STEP => (k - HUNT_STEP, false),
            Some(k) => (k, true),
            None => (HUNT_STEP, true),
        };
        let raw = raw
            .get(..raw.len().min(room).min(limit))
            .unwrap_or_default();
        let cur = self.shift;
        let used = if !search {
            self.hunter.pass(raw);
            raw.len()
        } else {
            // Up to and including a byte that completes a header at another bit offset.
            match self.hunter.scan(raw, cur) {
                Some((i, s)) => {
                    self.switch = Some(s);
                    i + 1
                }
                None => raw.len(),
            }
        };
        let raw = raw.get(..used).unwrap_or_default();
        if cur == 0 {
            self.dec.feed(raw);
        } else {
            // Byte k of the frames is complete with raw byte k + 1.
            let mut stage = [0u8; STAGE];
            let mut prev = self.prev;
            for (dst, &b) in stage.iter_mut().zip(raw) {
                *dst = combine(prev, b, cur);
                prev = b;
            }
            self.dec.feed(stage.get(..raw.len()).unwrap_or_default());
        }
        if let Some(&last) = raw.last() {
            self.prev = last;
        }
        used
    }

    /// Reports a link event at the current point of the byte stream (after the bytes fed so
    /// far, before the next ones).
    pub fn event(&mut self, e: LinkEvent) {
        match e {
            LinkEvent::EndOfTransaction => {
                self.stats.transactions += 1;
                if self.dec.partial_frame() {
                    self.stats.cut_transactions += 1;
                }
                self.restart();
            }
            LinkEvent::ModeFault => {
                self.stats.mode_faults += 1;
                self.restart();
            }
            LinkEvent::Overrun => self.stats.overruns += 1,
            LinkEvent::RingOverrun => self.stats.ring_overruns += 1,
        }
    }

    /// The stream ended (a replay from storage): hand out what is left, as at the end of a
    /// transaction, without counting one.
    pub fn end_of_stream(&mut self) {
        self.restart();
    }

    /// The peripheral was re-armed: byte-aligned again, and the bytes before are closed.
    fn restart(&mut self) {
        self.flushing = true;
        self.switch = None;
        self.shift = 0;
        self.hunter.reset();
    }

    /// The next intact frame, or `None` when more bytes are needed.
    pub fn next_frame(&mut self) -> Option<Frame<'_>> {
        if self.flushing {
            let f = self.dec.next_frame_at_end();
            if f.is_none() {
                self.flushing = false;
            }
            f
        } else {
            self.dec.next_frame()
        }
    }

    /// The link's counters.
    #[must_use]
    pub const fn stats(&self) -> &LinkStats {
        &self.stats
    }

    /// The frame decoder's counters (intact, bad, missing frames; skipped bytes).
    #[must_use]
    pub fn frame_stats(&self) -> FrameStats {
        self.dec.stats()
    }

    /// Bit offset in use (0 = byte-aligned).
    #[must_use]
    pub const fn bit_offset(&self) -> u8 {
        self.shift
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tables find the sync pattern at every bit offset whatever the bits around it, and
    /// report no other offset for a window that holds it once.
    #[test]
    fn sync_tables() {
        let pat = u32::from(u16::from_be_bytes(SYNC));
        let mut x = 0x1234_5678u32;
        for _ in 0..2000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            for s in 0..8u32 {
                // 24 bits: s random bits, the 16-bit pattern, 8 - s random bits.
                let w = ((x >> 8) & !low(24 - s) & 0xFF_FFFF) | (pat << (8 - s)) | (x & low(8 - s));
                let m = lookup(&FIRST, w >> 16) & lookup(&MID, w >> 8) & lookup(&LAST, w);
                assert_ne!(m & (1 << s), 0, "offset {s}, window {w:#08x}");
                for t in 0..8u32 {
                    let at_t = (w >> (8 - t)) & 0xFFFF == pat;
                    assert_eq!(m & (1 << t) != 0, at_t, "offset {t}, window {w:#08x}");
                }
            }
        }
    }

    #[test]
    fn combine_shifts_msb_first() {
        assert_eq!(combine(0b1010_0101, 0b1110_0111, 0), 0b1010_0101);
        assert_eq!(combine(0b1010_0101, 0b1110_0111, 1), 0b0100_1011);
        assert_eq!(combine(0b1010_0101, 0b1110_0111, 7), 0b1111_0011);
    }
}
