//! The AER-over-SPI byte stream on the host (format: `docs/wire-formats.md`,
//! `core_nostd::aer`): writing it from a recording (`host-sim aer-stream`, `convert --to aer`)
//! and reading it back.
//!
//! Event times on the wire are `u32` µs relative to the recording's first event (wrapping), the
//! clock `host-sim run` gives its pipeline; the first event's absolute time (`t0_us`) is
//! returned so that outputs can be put back on the recording's clock.

use std::io::Write;

use anyhow::{bail, Context, Result};
use core_nostd::aer::events::{EventEncoder, Receiver};
use core_nostd::aer::frame::{FrameStats, SYNC};
use core_nostd::event::Event;

use crate::formats;

/// When the sender can put one frame on the link: the frame ends at byte `end_byte` of the
/// stream (exclusive), and its last event happened `t_us` µs after the stream's first event.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Arrival {
    /// Stream offset just past the frame, bytes.
    pub end_byte: u64,
    /// Time of the frame's last event, µs from the stream's first event (not wrapped).
    pub t_us: u64,
}

impl Arrival {
    /// Bytes of one schedule entry on disk: `end_byte` then `t_us`, both u64 little-endian.
    pub const BYTES: usize = 16;

    /// The entry as written in the schedule file.
    pub fn to_bytes(self) -> [u8; Self::BYTES] {
        let mut b = [0u8; Self::BYTES];
        let (end, t) = b.split_at_mut(8);
        end.copy_from_slice(&self.end_byte.to_le_bytes());
        t.copy_from_slice(&self.t_us.to_le_bytes());
        b
    }

    /// An entry read back from the schedule file.
    pub fn from_bytes(b: [u8; Self::BYTES]) -> Self {
        let [e0, e1, e2, e3, e4, e5, e6, e7, t0, t1, t2, t3, t4, t5, t6, t7] = b;
        Self {
            end_byte: u64::from_le_bytes([e0, e1, e2, e3, e4, e5, e6, e7]),
            t_us: u64::from_le_bytes([t0, t1, t2, t3, t4, t5, t6, t7]),
        }
    }
}

/// Decodes an AER stream (any corruption tolerated) into events and the frame counters.
pub fn decode_aer(bytes: &[u8]) -> (Vec<Event>, FrameStats) {
    let mut rx = Receiver::new();
    let mut out = Vec::new();
    rx.push(bytes, |e| out.push(e));
    rx.finish(|e| out.push(e));
    (out, rx.frame_stats())
}

/// Whether `head` (the first bytes of a file) starts with an AER frame's sync pattern.
pub fn looks_like_aer(head: &[u8]) -> bool {
    head.starts_with(&SYNC)
}

/// Encodes the events of `source` into `wire` (and the arrival schedule into `schedule`) as they
/// come, after the frames in `prefix` (a configuration frame, say: its arrival is at time 0);
/// returns the number of events and the time origin.
///
/// # Errors
/// When the recording cannot be read, an event does not fit the format, the recording's clock
/// jumps (see [`crate::commands::aer_stream::run`]), or the output cannot be written.
pub fn stream_aer(
    source: &mut dyn formats::EventChunks,
    wire: &mut crate::output::AtomicFile,
    mut schedule: Option<&mut crate::output::AtomicFile>,
    prefix: &[u8],
) -> Result<(u64, u64)> {
    use crate::timeline::{RESTART_BACK_US, RESTART_GAP_US};
    let mut enc = EventEncoder::new();
    let mut chunk = Vec::new();
    let (mut n, mut t0, mut prev, mut prev_rel, mut bytes) = (0u64, 0u64, 0u64, 0u64, 0u64);
    let mut frames: Vec<u8> = Vec::with_capacity(1 << 16);
    let mut arrivals: Vec<u8> = Vec::new();
    if !prefix.is_empty() {
        frames.extend_from_slice(prefix);
        bytes = prefix.len() as u64;
        arrivals.extend_from_slice(
            &Arrival {
                end_byte: bytes,
                t_us: 0,
            }
            .to_bytes(),
        );
    }
    let wire_path = wire.path().to_path_buf();
    let werr = || format!("cannot write {}", wire_path.display());
    while source.next_chunk(&mut chunk)? {
        for e in &chunk {
            if n == 0 {
                (t0, prev) = (e.t_us, e.t_us);
            }
            let jump = if e.t_us >= prev {
                e.t_us - prev > RESTART_GAP_US
            } else {
                prev - e.t_us > RESTART_BACK_US
            };
            if jump {
                bail!(
                    "event {n} at t = {} µs jumps from {prev} µs (more than {} min forward or {} ms back): `host-sim run` restarts there, the firmware cannot; cut the recording at the jump",
                    e.t_us,
                    RESTART_GAP_US / 60_000_000,
                    RESTART_BACK_US / 1000
                );
            }
            prev = e.t_us;
            let rel = e.t_us.wrapping_sub(t0);
            let ev = Event {
                t_us: rel as u32,
                x: e.x,
                y: e.y,
                on: e.on,
            };
            // Frames completed by `push(e)` hold the events before `e`.
            enc.push(ev, |f| {
                frames.extend_from_slice(f);
                bytes += f.len() as u64;
                arrivals.extend_from_slice(
                    &Arrival {
                        end_byte: bytes,
                        t_us: prev_rel,
                    }
                    .to_bytes(),
                );
            })
            .map_err(|err| anyhow::anyhow!("event {n}: {err}"))?;
            prev_rel = rel;
            n += 1;
        }
        wire.writer().write_all(&frames).with_context(werr)?;
        frames.clear();
        if let Some(s) = schedule.as_deref_mut() {
            let path = s.path().display().to_string();
            s.writer()
                .write_all(&arrivals)
                .with_context(|| format!("cannot write {path}"))?;
        }
        arrivals.clear();
    }
    enc.flush(|f| {
        frames.extend_from_slice(f);
        bytes += f.len() as u64;
        arrivals.extend_from_slice(
            &Arrival {
                end_byte: bytes,
                t_us: prev_rel,
            }
            .to_bytes(),
        );
    });
    wire.writer().write_all(&frames).with_context(werr)?;
    if let Some(s) = schedule {
        let path = s.path().display().to_string();
        s.writer()
            .write_all(&arrivals)
            .with_context(|| format!("cannot write {path}"))?;
    }
    Ok((n, t0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::{Event64, EventsInMemory};
    use crate::output::AtomicFile;

    /// `events` through [`stream_aer`]: the stream, its arrival schedule, the time origin.
    fn stream(events: &[Event64]) -> Result<(Vec<u8>, Vec<Arrival>, u64)> {
        let dir = tempfile::tempdir()?;
        let (wire_path, sched_path) = (dir.path().join("s.aer"), dir.path().join("s.sched"));
        let mut wire = AtomicFile::create(&wire_path)?;
        let mut sched = AtomicFile::create(&sched_path)?;
        let (_, t0) = stream_aer(
            &mut EventsInMemory::new(events),
            &mut wire,
            Some(&mut sched),
            &[],
        )?;
        wire.commit()?;
        sched.commit()?;
        let arrivals = std::fs::read(&sched_path)?
            .chunks_exact(Arrival::BYTES)
            .filter_map(|c| c.try_into().ok().map(Arrival::from_bytes))
            .collect();
        Ok((std::fs::read(&wire_path)?, arrivals, t0))
    }

    #[test]
    fn stream_round_trip_relative_to_first_event() {
        let events: Vec<Event64> = (0..5000u64)
            .map(|i| Event64 {
                t_us: 1_700_000_000_000_000 + i * 37 + (i / 1000) * 5_000_000,
                x: (i * 13 % 346) as u16,
                y: (i * 7 % 260) as u16,
                on: i % 3 == 0,
            })
            .collect();
        let (wire, _, t0) = stream(&events).unwrap();
        assert_eq!(t0, events[0].t_us);
        assert!(looks_like_aer(&wire));
        let (out, st) = decode_aer(&wire);
        assert_eq!(st.bad + st.dropped, 0);
        assert_eq!(out.len(), events.len());
        for (a, b) in out.iter().zip(&events) {
            assert_eq!(u64::from(a.t_us), b.t_us - t0);
            assert_eq!((a.x, a.y, a.on), (b.x, b.y, b.on));
        }
    }

    #[test]
    fn schedule_names_each_frames_end_and_last_event() {
        let events: Vec<Event64> = (0..20_000u64)
            .map(|i| Event64 {
                t_us: 5_000 + i * 3 + (i / 7000) * 40_000,
                x: (i % 300) as u16,
                y: (i % 200) as u16,
                on: i % 2 == 0,
            })
            .collect();
        let (wire, arrivals, _) = stream(&events).unwrap();
        assert_eq!(arrivals.last().unwrap().end_byte, wire.len() as u64);
        // Decoding frame by frame up to each entry's end gives events up to its time, and the
        // entry's time is that of the frame's last event.
        let mut seen = 0usize;
        let mut start = 0usize;
        for a in &arrivals {
            let (evs, st) = decode_aer(&wire[start..a.end_byte as usize]);
            assert_eq!(st.ok, 1, "one whole frame per entry");
            seen += evs.len();
            assert_eq!(u64::from(evs.last().unwrap().t_us), a.t_us);
            assert_eq!(events[seen - 1].t_us - 5_000, a.t_us);
            start = a.end_byte as usize;
        }
        assert_eq!(seen, events.len());
        assert!(arrivals.windows(2).all(|w| w[0].t_us <= w[1].t_us));
    }

    #[test]
    fn coordinates_beyond_2047_are_an_error() {
        let e = Event64 {
            t_us: 0,
            x: 4000,
            y: 0,
            on: true,
        };
        assert!(stream(&[e]).is_err());
    }
}
