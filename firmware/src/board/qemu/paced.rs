//! Paced replay (`--paced`): the stream's frames become readable at the times a live sender
//! could have sent them, measured on the MCU clock from the first read.
//!
//! The times come from `schedule.bin` (written by `host-sim aer-stream --schedule`): one
//! 16-byte entry per frame, `end_byte` then `t_us`, both u64 little-endian, meaning "the stream
//! up to byte `end_byte` is available `t_us` µs after the start". Between entries the source
//! has nothing to give and the input task sleeps, as on a real link. Bytes that are due are
//! handed out at once and without a yield: the input task drains everything that arrived before
//! the processing task gets the CPU back, as the F405's input task (interrupt priority) drains
//! its DMA ring. The input then sleeps until the next entry is due; the QEMU time driver
//! wakes timers on its 1 ms tick, so the input runs at most once per millisecond while frames
//! keep arriving, like a ring-buffer interrupt. The link itself is not rate-limited and the
//! backlog is not bounded (the F405's 4 KiB ring is): a burst costs frames in the queue, never
//! bytes on the link.
//!
//! The link has a finite rate (`--link-bps`, bytes per second; 0 = unlimited): frames go out
//! one after the other, each starting when it is ready and the previous one has been sent, and
//! becomes readable when its last byte has arrived. A burst faster than the link queues up at
//! the sender (emulated without bound) instead of reaching the MCU at once.
//!
//! Without a schedule the source passes the inner one through (plain replay).

use core::ffi::CStr;

use embassy_time::{Duration, Instant, Timer};
use semihosting::fs::File;
use semihosting::io::Read;

use crate::app::{ByteSource, SourceError};

/// The arrival schedule, relative to QEMU's working directory.
pub const SCHEDULE_FILE: &CStr = c"schedule.bin";

/// Bytes of one schedule entry.
const ENTRY: usize = 16;
/// Entries read from the host at a time.
const BATCH: usize = 64;

/// The arrival schedule, read through semihosting in batches.
pub struct Schedule {
    file: Option<File>,
    buf: [u8; ENTRY * BATCH],
    len: usize,
    at: usize,
}

impl Schedule {
    /// Opens [`SCHEDULE_FILE`].
    pub fn open() -> Option<Self> {
        File::open(SCHEDULE_FILE).ok().map(|f| Self {
            file: Some(f),
            buf: [0; ENTRY * BATCH],
            len: 0,
            at: 0,
        })
    }

    /// The next entry `(end_byte, t_us)`, or `None` at the end (or on a read error, after
    /// which the rest of the stream is released at once).
    fn next(&mut self) -> Option<(u64, u64)> {
        if self.at + ENTRY > self.len {
            let file = self.file.as_mut()?;
            // Keep a partial entry (a host read may stop anywhere).
            let keep = self.len.saturating_sub(self.at);
            self.buf.copy_within(self.at..self.len, 0);
            self.len = keep;
            self.at = 0;
            while self.len < ENTRY {
                match file.read(self.buf.get_mut(self.len..).unwrap_or_default()) {
                    Ok(0) | Err(_) => {
                        self.file = None;
                        return None;
                    }
                    Ok(n) => self.len += n,
                }
            }
        }
        let e = self.buf.get(self.at..self.at + ENTRY)?;
        let (a, b) = e.split_at(8);
        let end = u64::from_le_bytes(a.try_into().ok()?);
        let t = u64::from_le_bytes(b.try_into().ok()?);
        self.at += ENTRY;
        Some((end, t))
    }
}

/// A byte source released on a schedule (or passed through without one).
pub struct Paced<S> {
    inner: S,
    schedule: Option<Schedule>,
    /// The next frame not yet readable: `(end_byte, readable at, ns after start)`.
    next: Option<(u64, u64)>,
    /// Link rate, bytes per second (0 = unlimited).
    link_bps: u64,
    /// End of the previous frame: its byte offset and when its last byte arrived (ns).
    sent: (u64, u64),
    /// Bytes of the stream that may be read.
    released: u64,
    /// Bytes read so far.
    pos: u64,
    /// MCU time of the first read (the schedule's zero).
    start: Option<Instant>,
}

impl<S: ByteSource> Paced<S> {
    /// Paces `inner` with `schedule` over a link of `link_bps` bytes per second (0 =
    /// unlimited); `None` passes it through.
    pub fn new(inner: S, schedule: Option<Schedule>, link_bps: u64) -> Self {
        let released = if schedule.is_some() { 0 } else { u64::MAX };
        let mut p = Self {
            inner,
            schedule,
            next: None,
            link_bps,
            sent: (0, 0),
            released,
            pos: 0,
            start: None,
        };
        p.advance();
        p
    }

    /// Takes the next schedule entry and works out when its frame has crossed the link.
    fn advance(&mut self) {
        self.next = self
            .schedule
            .as_mut()
            .and_then(Schedule::next)
            .map(|(end, t_us)| {
                let (prev_end, prev_ns) = self.sent;
                let ready_ns = t_us.saturating_mul(1_000).max(prev_ns);
                let bytes = end.saturating_sub(prev_end);
                let on_wire_ns = match self.link_bps {
                    0 => 0,
                    bps => bytes.saturating_mul(1_000_000_000) / bps,
                };
                let arrived = ready_ns.saturating_add(on_wire_ns);
                self.sent = (end.max(prev_end), arrived);
                (end, arrived)
            });
    }

    /// Releases every frame readable by `now`; past the last entry everything is released.
    fn release(&mut self, start: Instant, now: Instant) {
        while let Some((end, at_ns)) = self.next {
            if start + Duration::from_nanos(at_ns) > now {
                return;
            }
            self.released = self.released.max(end);
            self.advance();
        }
        self.released = u64::MAX;
    }
}

impl<S: ByteSource> ByteSource for Paced<S> {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, SourceError> {
        if self.schedule.is_none() {
            return self.inner.read(buf).await;
        }
        let start = *self.start.get_or_insert_with(Instant::now);
        loop {
            self.release(start, Instant::now());
            if self.pos < self.released {
                let room = (self.released - self.pos).min(buf.len() as u64) as usize;
                let n = self
                    .inner
                    .read(buf.get_mut(..room).unwrap_or_default())
                    .await?;
                self.pos += n as u64;
                return Ok(n);
            }
            if let Some((_, at_ns)) = self.next {
                Timer::at(start + Duration::from_nanos(at_ns)).await;
            }
        }
    }
}
