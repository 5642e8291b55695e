//! Corrupted AER streams: bit flips, dropped and inserted bytes, truncation, pure garbage.
//! Every frame that arrived intact is recovered, the counters add up, nothing panics.

use core_nostd::aer::events::{decode_events, EventEncoder};
use core_nostd::aer::frame::{Frame, FrameDecoder};
use core_nostd::aer::yaw::{YawDecoder, YawFrame};
use core_nostd::event::Event;
use core_nostd::fixed::types::I16F16;
use proptest::prelude::*;

/// A stream of frames with each frame's byte range and events.
struct Stream {
    wire: Vec<u8>,
    /// `(start, end, events)` per frame, sequence number = index.
    frames: Vec<(usize, usize, Vec<Event>)>,
}

fn stream(n_events: usize, seed: u32, max_payload: usize) -> Stream {
    stream_span(n_events, seed, max_payload, 2_000)
}

fn stream_span(n_events: usize, seed: u32, max_payload: usize, span_us: u32) -> Stream {
    let mut enc = EventEncoder::with_limits(max_payload, span_us);
    let mut wire = Vec::new();
    let mut frames: Vec<(usize, usize, Vec<Event>)> = Vec::new();
    let mut pending: Vec<Event> = Vec::new();
    let mut t = seed;
    let mut rng = seed | 1;
    let mut next = || {
        rng ^= rng << 13;
        rng ^= rng >> 17;
        rng ^= rng << 5;
        rng
    };
    let mut emit = |f: &[u8], pending: &mut Vec<Event>, wire: &mut Vec<u8>| {
        // Events of this frame: those decoded from it.
        let mut evs = Vec::new();
        FrameDecoder::new().push(f, |fr| {
            decode_events(fr.payload, |e| evs.push(e));
        });
        let start = wire.len();
        wire.extend_from_slice(f);
        let n = evs.len();
        pending.drain(..n.min(pending.len()));
        frames.push((start, wire.len(), evs));
    };
    for _ in 0..n_events {
        let r = next();
        t = t.wrapping_add(r % 400);
        let ev = Event {
            t_us: t,
            x: (r >> 8) as u16 & 0x7FF,
            y: (r >> 19) as u16 & 0x7FF,
            on: r & 1 == 0,
        };
        pending.push(ev);
        let mut done: Vec<Vec<u8>> = Vec::new();
        enc.push(ev, |f| done.push(f.to_vec())).unwrap();
        for f in done {
            emit(&f, &mut pending, &mut wire);
        }
    }
    let mut done: Vec<Vec<u8>> = Vec::new();
    enc.flush(|f| done.push(f.to_vec()));
    for f in done {
        emit(&f, &mut pending, &mut wire);
    }
    Stream { wire, frames }
}

#[derive(Clone, Debug)]
enum Op {
    Flip { pos: usize, bit: u8 },
    Delete { pos: usize, len: usize },
    Insert { pos: usize, bytes: Vec<u8> },
}

impl Op {
    fn pos(&self) -> usize {
        match self {
            Op::Flip { pos, .. } | Op::Delete { pos, .. } | Op::Insert { pos, .. } => *pos,
        }
    }
}

fn arb_op() -> impl Strategy<Value = Op> {
    // Positions are fractions of the stream length (scaled later).
    prop_oneof![
        (any::<u32>(), 0u8..8).prop_map(|(p, bit)| Op::Flip {
            pos: p as usize,
            bit
        }),
        (any::<u32>(), 1usize..40).prop_map(|(p, len)| Op::Delete {
            pos: p as usize,
            len
        }),
        (any::<u32>(), prop::collection::vec(any::<u8>(), 1..60)).prop_map(|(p, bytes)| {
            Op::Insert {
                pos: p as usize,
                bytes,
            }
        }),
        // Garbage made of sync-like bytes, the worst case for resynchronisation.
        (any::<u32>(), 1usize..30).prop_map(|(p, n)| Op::Insert {
            pos: p as usize,
            bytes: [0xA5, 0xE7].repeat(n)
        }),
    ]
}

/// Applies `ops` (positions in original coordinates) and returns the corrupted bytes and, per
/// frame, whether any op touched it.
fn corrupt(s: &Stream, mut ops: Vec<Op>) -> (Vec<u8>, Vec<bool>) {
    let len = s.wire.len().max(1);
    for op in &mut ops {
        let p = op.pos() % len;
        match op {
            Op::Flip { pos, .. } | Op::Delete { pos, .. } | Op::Insert { pos, .. } => *pos = p,
        }
    }
    // Dedupe positions so that ops do not overlap; apply from the end.
    ops.sort_by_key(|o| std::cmp::Reverse(o.pos()));
    let mut touched = vec![false; s.frames.len()];
    let mut wire = s.wire.clone();
    let mut limit = usize::MAX;
    for op in ops {
        let p = op.pos();
        let (a, b) = match &op {
            Op::Flip { .. } => (p, p + 1),
            Op::Delete { len, .. } => (p, (p + len).min(s.wire.len())),
            Op::Insert { .. } => (p, p),
        };
        if b > limit || (a == b && a == limit) {
            continue; // overlaps an op already applied
        }
        limit = a;
        for (i, (fs, fe, _)) in s.frames.iter().enumerate() {
            let hit = if a == b {
                a > *fs && a < *fe
            } else {
                a < *fe && b > *fs
            };
            if hit {
                touched[i] = true;
            }
        }
        match op {
            Op::Flip { bit, .. } => wire[p] ^= 1 << bit,
            Op::Delete { .. } => {
                wire.drain(a..b);
            }
            Op::Insert { bytes, .. } => {
                wire.splice(p..p, bytes);
            }
        }
    }
    (wire, touched)
}

fn decode(wire: &[u8], chunks: &[usize]) -> (Vec<(u16, Vec<Event>)>, FrameDecoder) {
    let mut dec = FrameDecoder::new();
    let mut out = Vec::new();
    let mut take = |f: &Frame<'_>| {
        let mut evs = Vec::new();
        decode_events(f.payload, |e| evs.push(e));
        out.push((f.seq, evs));
    };
    let mut rest = wire;
    let mut i = 0;
    while !rest.is_empty() {
        let n = chunks[i % chunks.len()].max(1).min(rest.len());
        let (a, b) = rest.split_at(n);
        dec.push(a, &mut take);
        rest = b;
        i += 1;
    }
    dec.finish(&mut take);
    (out, dec)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn intact_frames_survive_corruption(
        n in 50usize..1500,
        seed in any::<u32>(),
        max_payload in 16usize..1024,
        ops in prop::collection::vec(arb_op(), 0..12),
        chunks in prop::collection::vec(1usize..2000, 1..6),
    ) {
        let s = stream(n, seed, max_payload);
        let n_ops = ops.len();
        let (wire, touched) = corrupt(&s, ops);
        let (out, dec) = decode(&wire, &chunks);
        // Every decoded frame is an original frame, in order, with its events.
        let mut last: Option<u16> = None;
        for (seq, evs) in &out {
            let orig = &s.frames[usize::from(*seq)];
            prop_assert_eq!(evs, &orig.2);
            if let Some(l) = last { prop_assert!(*seq > l); }
            last = Some(*seq);
        }
        // Every frame that no corruption touched is recovered.
        let got: std::collections::HashSet<u16> = out.iter().map(|(q, _)| *q).collect();
        for (i, t) in touched.iter().enumerate() {
            if !t {
                prop_assert!(got.contains(&(i as u16)), "intact frame {} lost", i);
            }
        }
        // Counters: ok = frames out; ok + dropped spans first..=last decoded seq; a bad
        // candidate needs a corrupted frame (or inserted garbage).
        let st = dec.stats();
        prop_assert_eq!(st.ok, out.len() as u64);
        if let (Some(first), Some(last)) = (out.first(), out.last()) {
            prop_assert_eq!(st.ok + st.dropped, u64::from(last.0 - first.0) + 1);
        }
        let n_touched = touched.iter().filter(|t| **t).count() as u64;
        prop_assert!(st.bad <= n_touched + n_ops as u64, "bad {} > touched {} + ops {}", st.bad, n_touched, n_ops);
        prop_assert_eq!(st.bytes, wire.len() as u64);
        prop_assert_eq!(st.seq_restarts, 0);
    }

    #[test]
    fn any_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..5000),
                             chunk in 1usize..700) {
        let mut dec = FrameDecoder::new();
        let mut n = 0u64;
        for c in bytes.chunks(chunk) {
            dec.push(c, |f| { decode_events(f.payload, |_| {}); n += 1; });
        }
        dec.finish(|_| n += 1);
        prop_assert_eq!(dec.stats().ok, n);
        let mut yd = YawDecoder::new();
        for c in bytes.chunks(chunk) {
            yd.push(c, |_| {});
        }
        yd.finish(|_| {});
    }

    #[test]
    fn yaw_frames_survive_corruption(flips in prop::collection::vec((0usize..14 * 200, 0u8..8), 0..20),
                                     chunk in 1usize..50) {
        let frames: Vec<YawFrame> = (0..200u32).map(|i| YawFrame {
            seq: i as u8, flags: (i % 7) as u8, t_us: i * 1000, yaw_rate: I16F16::from_bits(i as i32 * 977 - 50_000),
        }).collect();
        let mut wire: Vec<u8> = frames.iter().flat_map(|f| f.encode()).collect();
        let mut hit = vec![false; frames.len()];
        for &(p, b) in &flips {
            wire[p] ^= 1 << b;
            hit[p / 14] = true;
        }
        let mut dec = YawDecoder::new();
        let mut out = Vec::new();
        for c in wire.chunks(chunk) {
            dec.push(c, |f| out.push(f));
        }
        dec.finish(|f| out.push(f));
        for (i, f) in frames.iter().enumerate() {
            if !hit[i] {
                prop_assert!(out.contains(f), "intact yaw frame {} lost", i);
            }
        }
        let s = dec.stats();
        prop_assert_eq!(s.ok, out.len() as u64);
    }
}

#[test]
fn a_truncated_frame_does_not_swallow_the_next() {
    let s = stream_span(2000, 7, 1024, u32::MAX);
    assert!(s.frames.len() > 5);
    assert!(s.frames[2].1 - s.frames[2].0 > 1000);
    // Cut 600 bytes out of frame 2's payload: its header is intact and its length now reaches
    // into frames 3 and 4, which must still come out.
    let (fs, _, _) = s.frames[2];
    let mut wire = s.wire.clone();
    wire.drain(fs + 20..fs + 620);
    let (out, dec) = decode(&wire, &[4096]);
    let seqs: Vec<u16> = out.iter().map(|(q, _)| *q).collect();
    let expect: Vec<u16> = (0..s.frames.len() as u16).filter(|&q| q != 2).collect();
    assert_eq!(seqs, expect);
    let st = dec.stats();
    assert_eq!((st.bad, st.dropped), (1, 1));
}

#[test]
fn single_bit_flips_count_exactly() {
    let s = stream(3000, 99, 512);
    let mut wire = s.wire.clone();
    // One flip in the payload of every fifth frame.
    let mut flipped = 0;
    for (i, (fs, fe, _)) in s.frames.iter().enumerate() {
        if i % 5 == 2 && i + 1 < s.frames.len() {
            wire[(fs + fe) / 2] ^= 0x10;
            flipped += 1;
        }
    }
    let (out, dec) = decode(&wire, &[333]);
    let st = dec.stats();
    assert_eq!(st.bad, flipped);
    assert_eq!(st.dropped, flipped);
    assert_eq!(st.ok as usize, s.frames.len() - flipped as usize);
    assert_eq!(out.len() as u64, st.ok);
}

#[test]
fn truncated_stream_end() {
    let s = stream(1000, 3, 256);
    let cut = s.wire.len() - 7;
    let (out, dec) = decode(&s.wire[..cut], &[100]);
    assert_eq!(out.len(), s.frames.len() - 1);
    assert_eq!(dec.stats().bad, 1);
}
