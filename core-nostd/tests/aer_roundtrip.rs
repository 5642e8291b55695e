//! AER wire format round trips: events -> frames -> bytes in arbitrary chunks -> events.

use core_nostd::aer::events::{decode_events, EventEncoder, Evt3Framer, Receiver};
use core_nostd::aer::frame::{self, encode_frame, FrameDecoder, Kind};
use core_nostd::aer::yaw::{YawDecoder, YawFrame};
use core_nostd::event::{Event, Event64};
use core_nostd::evt::{Evt3Decoder, Evt3Encoder, StreamDecoder};
use core_nostd::fixed::types::I16F16;
use proptest::prelude::*;

fn encode_all(events: &[Event], enc: &mut EventEncoder) -> (Vec<u8>, usize) {
    let mut wire = Vec::new();
    let mut frames = 0;
    for &ev in events {
        enc.push(ev, |f| {
            wire.extend_from_slice(f);
            frames += 1;
        })
        .unwrap();
    }
    enc.flush(|f| {
        wire.extend_from_slice(f);
        frames += 1;
    });
    (wire, frames)
}

fn decode_chunked(wire: &[u8], chunks: &[usize]) -> (Vec<Event>, Receiver) {
    let mut rx = Receiver::new();
    let mut out = Vec::new();
    let mut rest = wire;
    let mut i = 0;
    while !rest.is_empty() {
        let n = chunks
            .get(i % chunks.len().max(1))
            .copied()
            .unwrap_or(64)
            .max(1);
        let (a, b) = rest.split_at(n.min(rest.len()));
        rx.push(a, |e| out.push(e));
        rest = b;
        i += 1;
    }
    rx.finish(|e| out.push(e));
    (out, rx)
}

fn arb_events() -> impl Strategy<Value = Vec<Event>> {
    // Time steps: mostly small, sometimes large, sometimes backwards (wrapping).
    let step = prop_oneof![
        6 => 0u32..300,
        2 => 0u32..5_000,
        1 => any::<u32>(),
    ];
    (
        any::<u32>(),
        prop::collection::vec((step, 0u16..2048, 0u16..2048, any::<bool>()), 0..2000),
    )
        .prop_map(|(t0, v)| {
            let mut t = t0;
            v.into_iter()
                .map(|(dt, x, y, on)| {
                    t = t.wrapping_add(dt);
                    Event { t_us: t, x, y, on }
                })
                .collect()
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn events_round_trip(events in arb_events(),
                         chunks in prop::collection::vec(1usize..3000, 1..8),
                         max_payload in 8usize..1100,
                         span in prop_oneof![Just(1000u32), Just(u32::MAX), 0u32..100]) {
        let mut enc = EventEncoder::with_limits(max_payload, span);
        let (wire, frames) = encode_all(&events, &mut enc);
        let (out, rx) = decode_chunked(&wire, &chunks);
        prop_assert_eq!(&out, &events);
        let s = rx.frame_stats();
        prop_assert_eq!(s.ok, frames as u64);
        prop_assert_eq!(s.bad, 0);
        prop_assert_eq!(s.dropped, 0);
        prop_assert_eq!(s.skipped_bytes, 0);
        prop_assert_eq!(s.bytes, wire.len() as u64);
    }

    #[test]
    fn yaw_round_trip(samples in prop::collection::vec((any::<u32>(), any::<i32>(), any::<u8>()), 0..300),
                      chunk in 1usize..40) {
        let frames: Vec<YawFrame> = samples.iter().enumerate().map(|(i, &(t, y, f))| YawFrame {
            seq: i as u8, flags: f, t_us: t, yaw_rate: I16F16::from_bits(y),
        }).collect();
        let wire: Vec<u8> = frames.iter().flat_map(|f| f.encode()).collect();
        let mut dec = YawDecoder::new();
        let mut out = Vec::new();
        for c in wire.chunks(chunk) {
            dec.push(c, |f| out.push(f));
        }
        dec.finish(|f| out.push(f));
        prop_assert_eq!(&out, &frames);
        let s = dec.stats();
        prop_assert_eq!((s.ok, s.bad, s.dropped, s.skipped_bytes), (frames.len() as u64, 0, 0, 0));
    }
}

#[test]
fn four_bytes_per_dense_event() {
    let events: Vec<Event> = (0..255u32)
        .map(|i| Event {
            t_us: 1_000_000 + i,
            x: (i * 7 % 2048) as u16,
            y: 5,
            on: true,
        })
        .collect();
    let (wire, frames) = encode_all(&events, &mut EventEncoder::new());
    assert_eq!(frames, 1);
    assert_eq!(wire.len(), frame::OVERHEAD_BYTES + 4 + 4 * 255);
    assert_eq!(wire.len(), frame::MAX_FRAME);
}

#[test]
fn wrap_and_backwards_times_are_exact() {
    let ts = [
        u32::MAX - 10,
        u32::MAX,
        3,
        300,
        299,
        299,
        0x8000_0000 + 299,
        5,
    ];
    let events: Vec<Event> = ts
        .iter()
        .map(|&t| Event {
            t_us: t,
            x: 2047,
            y: 2047,
            on: false,
        })
        .collect();
    let (wire, _) = encode_all(&events, &mut EventEncoder::with_limits(1024, u32::MAX));
    let (out, _) = decode_chunked(&wire, &[5]);
    assert_eq!(out, events);
}

#[test]
fn out_of_range_address_is_an_error() {
    let mut enc = EventEncoder::new();
    let r = enc.push(
        Event {
            t_us: 0,
            x: 2048,
            y: 0,
            on: true,
        },
        |_| {},
    );
    assert!(r.is_err());
}

#[test]
fn evt3_payload_matches_direct_decode() {
    // Events -> EVT 3.0 words -> small frames -> receiver; compare with decoding the words.
    let mut evts = Vec::new();
    let mut t = 5u64;
    for i in 0..5000u64 {
        t += i % 13;
        evts.push(Event64 {
            t_us: t,
            x: ((i * 31) % 640) as u16,
            y: ((i / 3) % 480) as u16,
            on: i % 3 == 0,
        });
    }
    let mut words = Vec::new();
    let mut e3 = Evt3Encoder::new();
    for &e in &evts {
        e3.push(e, |w| words.push(w)).unwrap();
    }
    e3.finish(|w| words.push(w));
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let mut direct = Vec::new();
    let mut d = Evt3Decoder::new();
    d.push(&bytes, |e| direct.push(e));

    let mut fr = Evt3Framer::with_max_payload(100);
    let mut wire = Vec::new();
    for &w in &words {
        fr.push(w, |f| wire.extend_from_slice(f));
    }
    fr.flush(|f| wire.extend_from_slice(f));
    let (out, rx) = decode_chunked(&wire, &[17, 1, 400]);
    assert_eq!(out, direct);
    assert_eq!(out.len(), evts.len());
    assert_eq!(rx.payload_stats().evt3_frames, rx.frame_stats().ok);
    assert_eq!(rx.payload_stats().evt3.invalid, 0);
}

#[test]
fn evt3_frame_loss_does_not_corrupt_later_frames() {
    // Drop every third frame: the events of every other frame still come out exactly.
    let mut words = Vec::new();
    let mut e3 = Evt3Encoder::new();
    let mut evts = Vec::new();
    for i in 0..3000u64 {
        let e = Event64 {
            t_us: 100 + i * 9,
            x: ((i * 17) % 600) as u16,
            y: ((i * 5) % 400) as u16,
            on: i % 2 == 0,
        };
        evts.push(e);
        e3.push(e, |w| words.push(w)).unwrap();
    }
    e3.finish(|w| words.push(w));
    let mut fr = Evt3Framer::with_max_payload(64);
    let mut frames: Vec<Vec<u8>> = Vec::new();
    for &w in &words {
        fr.push(w, |f| frames.push(f.to_vec()));
    }
    fr.flush(|f| frames.push(f.to_vec()));
    // Events of each frame decoded alone after the state prefix = reference.
    let mut kept = Vec::new();
    let mut reference = Vec::new();
    let mut ref_dec = FrameDecoder::new();
    for (i, f) in frames.iter().enumerate() {
        let mut d = Evt3Decoder::new();
        let mut evs = Vec::new();
        ref_dec.push(f, |fr| d.push(fr.payload, |e| evs.push(e)));
        if i % 3 != 1 {
            kept.extend_from_slice(f);
            if i > 0 {
                reference.extend(evs);
            }
        }
    }
    let mut rx = Receiver::new();
    let mut out = Vec::new();
    rx.push(&kept, |e| out.push(e));
    // The first frame is decoded with the stream's state; compare from the second kept frame on.
    let first_n = {
        let mut d = Evt3Decoder::new();
        let mut n = 0;
        FrameDecoder::new().push(&frames[0], |fr| d.push(fr.payload, |_| n += 1));
        n
    };
    assert_eq!(&out[first_n..], &reference[..]);
    // Gaps are seen between intact frames: a lost last frame is not counted.
    let lost = (0..frames.len() - 1).filter(|i| i % 3 == 1).count() as u64;
    assert_eq!(rx.frame_stats().dropped, lost);
}

#[test]
fn explicit_frame_encoding_and_header_rules() {
    let mut buf = [0u8; frame::MAX_FRAME];
    assert!(encode_frame(Kind::Events, 0, 1, &[0; 3], &mut buf).is_err());
    assert!(encode_frame(Kind::Evt3, 0, 1, &[0; 3], &mut buf).is_err());
    assert!(encode_frame(Kind::Evt3, 0, 1, &[0; 1026], &mut buf).is_err());
    let n = encode_frame(
        Kind::Events,
        frame::flags::SOURCE_OVERFLOW,
        7,
        &[1, 0, 0, 0, 0x05, 0, 0, 0],
        &mut buf,
    )
    .unwrap();
    let mut dec = FrameDecoder::new();
    let mut seen = 0;
    dec.push(&buf[..n], |f| {
        assert_eq!(
            (f.kind, f.seq, f.flags),
            (Kind::Events, 7, frame::flags::SOURCE_OVERFLOW)
        );
        let mut evs = Vec::new();
        decode_events(f.payload, |e| evs.push(e));
        assert_eq!(
            evs,
            vec![Event {
                t_us: 1,
                x: 5,
                y: 0,
                on: false
            }]
        );
        seen += 1;
    });
    assert_eq!(seen, 1);
    assert_eq!(dec.stats().source_overflows, 1);
}

#[test]
fn sequence_gaps_and_restarts() {
    let mut buf = [0u8; 64];
    let mut wire = Vec::new();
    for (seq, fl) in [
        (10u16, 0u8),
        (11, 0),
        (14, 0),
        (65535, 0),
        (0, 0),
        (3, frame::flags::STREAM_START),
        (3, 0),
    ] {
        let n = encode_frame(Kind::Evt3, fl, seq, &[], &mut buf).unwrap();
        wire.extend_from_slice(&buf[..n]);
    }
    let mut dec = FrameDecoder::new();
    dec.push(&wire, |_| {});
    let s = dec.stats();
    assert_eq!(s.ok, 7);
    // 11->14: 2 missing; 14->65535: backwards jump (restart); 65535->0: none; 0->3: START;
    // 3->3: duplicate (restart).
    assert_eq!(s.dropped, 2);
    assert_eq!(s.seq_restarts, 2);
}
