//! EVT 2.0 / 2.1 / 3.0 decoders and the EVT 3.0 encoder: word sequences written from the
//! format specifications, time wrap, chunk boundaries, counters, truncation; random bytes never
//! panic; encode -> decode gives the events back.

use core_nostd::event::Event64;
use core_nostd::evt::{
    evt2, evt21, evt3, Evt21Decoder, Evt2Decoder, Evt3Decoder, Evt3Encoder, StreamDecoder,
};
use proptest::prelude::*;

fn ev(t_us: u64, x: u16, y: u16, on: bool) -> Event64 {
    Event64 { t_us, x, y, on }
}

fn bytes16(words: &[u16]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

fn bytes32(words: &[u32]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

fn bytes64(words: &[u64]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

/// Decodes `bytes` in one push.
fn decode<D: StreamDecoder>(mut d: D, bytes: &[u8]) -> (Vec<Event64>, D) {
    let mut out = Vec::new();
    d.push64(bytes, |e| out.push(e));
    (out, d)
}

/// Decodes `bytes` pushed in pieces cut at `cuts` (sorted offsets).
fn decode_chunked<D: StreamDecoder>(mut d: D, bytes: &[u8], cuts: &[usize]) -> (Vec<Event64>, D) {
    let mut out = Vec::new();
    let mut start = 0;
    for &c in cuts.iter().chain(std::iter::once(&bytes.len())) {
        let c = c.clamp(start, bytes.len());
        d.push64(&bytes[start..c], |e| out.push(e));
        start = c;
    }
    (out, d)
}

/// EVT 3.0 word builders (spec: type in bits 15..12).
mod w3 {
    pub fn th(v: u16) -> u16 {
        0x8000 | (v & 0xFFF)
    }
    pub fn tl(v: u16) -> u16 {
        0x6000 | (v & 0xFFF)
    }
    pub fn y(v: u16) -> u16 {
        v & 0x7FF
    }
    pub fn x(v: u16, on: bool) -> u16 {
        0x2000 | if on { 0x800 } else { 0 } | (v & 0x7FF)
    }
    pub fn base(v: u16, on: bool) -> u16 {
        0x3000 | if on { 0x800 } else { 0 } | (v & 0x7FF)
    }
    pub fn v12(m: u16) -> u16 {
        0x4000 | (m & 0xFFF)
    }
    pub fn v8(m: u16) -> u16 {
        0x5000 | (m & 0xFF)
    }
}

#[test]
fn evt3_words_from_the_spec() {
    let words = [
        w3::y(7),        // before the first TIME_HIGH: ignored
        w3::x(1, true),  // ignored
        w3::th(0x123),   // time = 0x123000
        w3::y(10),       // y = 10
        w3::x(5, true),  // event (5, 10) ON at 0x123000
        w3::tl(0x456),   // time = 0x123456
        w3::x(6, false), // event (6, 10) OFF
        0xA001,          // EXT_TRIGGER: skipped
        0xE00F,          // OTHERS
        0xF123,          // CONTINUED_12
        0x7003,          // CONTINUED_4
        w3::base(100, true),
        w3::v12(0b1000_0000_0101), // 100, 102, 111
        w3::v8(0b1000_0001),       // base is now 112: 112, 119
        w3::v12(0),                // base 120, nothing
        w3::x(2047, false),
        0x9000, // undefined type
        w3::th(0x124),
        w3::x(0, true), // time = 0x124000 (time low reset by TIME_HIGH)
    ];
    let bytes = bytes16(&words);
    let (events, d) = decode(Evt3Decoder::new(), &bytes);
    let t0 = 0x123000;
    let t1 = 0x123456;
    assert_eq!(
        events,
        vec![
            ev(t0, 5, 10, true),
            ev(t1, 6, 10, false),
            ev(t1, 100, 10, true),
            ev(t1, 102, 10, true),
            ev(t1, 111, 10, true),
            ev(t1, 112, 10, true),
            ev(t1, 119, 10, true),
            ev(t1, 2047, 10, false),
            ev(0x124000, 0, 10, true),
        ]
    );
    let s = d.stats();
    assert_eq!(s.events, 9);
    assert_eq!(s.before_time_high, 2);
    assert_eq!(s.time_high, 2);
    assert_eq!(s.triggers, 1);
    assert_eq!(s.others, 3);
    assert_eq!(s.invalid, 1);
    assert_eq!(s.first_invalid_at, Some(16 * 2));
    assert!(d.finish().is_ok());
    assert_eq!(d.bytes_pushed(), bytes.len() as u64);
}

#[test]
fn evt3_time_wraps_every_2_pow_24_us() {
    // TIME_HIGH 4094, 4095, then 0, 1 (next period), and a small step back that is not a wrap.
    let words = [
        w3::th(4094),
        w3::y(1),
        w3::x(1, true),
        w3::th(4095),
        w3::tl(4095),
        w3::x(2, true),
        w3::th(0),
        w3::x(3, true),
        w3::th(1),
        w3::tl(1),
        w3::x(4, true),
        w3::th(4095),
        w3::x(5, true),
        w3::th(3),
        w3::x(6, true),
    ];
    let (events, d) = decode(Evt3Decoder::new(), &bytes16(&words));
    let t: Vec<u64> = events.iter().map(|e| e.t_us).collect();
    let p = 1u64 << 24;
    assert_eq!(
        t,
        vec![
            4094 << 12,
            (4095 << 12) + 4095,
            p,
            p + (1 << 12) + 1,
            p + (4095 << 12),
            2 * p + (3 << 12)
        ]
    );
    assert_eq!(d.stats().time_wraps, 2);
}

#[test]
fn evt3_truncated_word_is_reported() {
    let bytes = bytes16(&[w3::th(1), w3::y(2), w3::x(3, true)]);
    let mut d = Evt3Decoder::new();
    let mut n = 0;
    d.push64(&bytes[..5], |_| n += 1);
    let t = d.finish().unwrap_err();
    assert_eq!((t.offset, t.have, t.word_bytes), (4, 1, 2));
    d.push64(&bytes[5..], |_| n += 1);
    assert!(d.finish().is_ok());
    assert_eq!(n, 1);
}

#[test]
fn evt2_words_from_the_spec() {
    let t = 0x3_1234_5678u64; // 34 bits
    let words = [
        evt2::encode::cd(true, 1, 2, 3), // before TIME_HIGH: ignored
        evt2::encode::time_high(t),
        evt2::encode::cd(true, (t & 63) as u8, 639, 479),
        evt2::encode::cd(false, 63, 0, 0),
        0xA000_0001, // EXT_TRIGGER
        0xE000_0000, // OTHERS
        0xF000_0000, // CONTINUED
        0x5000_0000, // undefined
    ];
    let (events, d) = decode(Evt2Decoder::new(), &bytes32(&words));
    let base = t & !63;
    assert_eq!(
        events,
        vec![ev(t, 639, 479, true), ev(base | 63, 0, 0, false)]
    );
    let s = d.stats();
    assert_eq!(
        (s.before_time_high, s.triggers, s.others, s.invalid),
        (1, 1, 2, 1)
    );
    assert_eq!(s.first_invalid_at, Some(7 * 4));
}

#[test]
fn evt2_time_wraps_every_2_pow_34_us() {
    let top = (1u64 << 34) - 64;
    let words = [
        evt2::encode::time_high(top),
        evt2::encode::cd(true, 5, 1, 1),
        evt2::encode::time_high(0),
        evt2::encode::cd(true, 6, 1, 1),
    ];
    let (events, d) = decode(Evt2Decoder::new(), &bytes32(&words));
    assert_eq!(
        events.iter().map(|e| e.t_us).collect::<Vec<_>>(),
        vec![top + 5, (1 << 34) + 6]
    );
    assert_eq!(d.stats().time_wraps, 1);
}

#[test]
fn evt21_vectors_from_the_spec() {
    let t = 1_000_000u64;
    let words = [
        evt21::encode::vector(true, 0, 0, 0, 1), // before TIME_HIGH: ignored
        evt21::encode::time_high(t),
        evt21::encode::vector(true, (t & 63) as u8, 64, 9, 0x8000_0001), // x = 64 and 95
        evt21::encode::vector(false, 7, 32, 10, 0b1010),                 // x = 33, 35
        evt21::encode::vector(false, 7, 0, 11, 0),                       // nothing
        0xA000_0000_0000_0001,                                           // EXT_TRIGGER
        0xE000_0000_0000_0000,                                           // OTHERS
        0xF000_0000_0000_0000,                                           // CONTINUED
    ];
    let base = t & !63;
    let expect = vec![
        ev(t, 64, 9, true),
        ev(t, 95, 9, true),
        ev(base | 7, 33, 10, false),
        ev(base | 7, 35, 10, false),
    ];
    let (events, d) = decode(Evt21Decoder::new(), &bytes64(&words));
    assert_eq!(events, expect);
    let s = d.stats();
    assert_eq!(
        (
            s.before_time_high,
            s.triggers,
            s.others,
            s.invalid,
            s.events
        ),
        (1, 1, 2, 0, 4)
    );
    // The legacy layout: the same words with their 32-bit halves swapped.
    let legacy: Vec<u64> = words.iter().map(|&w| evt21::encode::to_legacy(w)).collect();
    let (events, _) = decode(Evt21Decoder::legacy(), &bytes64(&legacy));
    assert_eq!(events, expect);
}

#[test]
fn event64_to_u32() {
    let e = ev((1 << 32) + 5, 1, 2, true);
    assert_eq!(e.wrapping().t_us, 5);
    assert_eq!(e.relative_to(10).t_us, ((1u64 << 32) - 5) as u32);
    assert_eq!(ev(100, 0, 0, false).relative_to(40).t_us, 60);
}

#[test]
fn push_truncates_time_to_u32() {
    let words = [w3::th(0xFFF), w3::y(1), w3::x(2, true)];
    let mut d = Evt3Decoder::new();
    let mut out = Vec::new();
    d.push(&bytes16(&words), |e| out.push(e));
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].t_us, 0xFFF000);
}

/// Sorted events with runs on one row at one time (vectors), gaps up to `max_gap` µs.
fn event_stream(max_gap: u64) -> impl Strategy<Value = Vec<Event64>> {
    (
        0u64..(1 << 40),
        prop::collection::vec(
            (
                0..=max_gap,
                0u16..2048,
                0u16..2048,
                any::<bool>(),
                0usize..40,
            ),
            0..300,
        ),
    )
        .prop_map(|(t0, parts)| {
            let mut t = t0;
            let mut out = Vec::new();
            for (i, (gap, x, y, on, run)) in parts.into_iter().enumerate() {
                // Every third part is a zero-gap run of increasing x on one row.
                t += if i % 3 == 0 { 0 } else { gap };
                out.push(ev(t, x, y, on));
                let mut xx = x;
                for k in 0..run % 8 {
                    xx = xx.saturating_add(1 + (k as u16 % 5));
                    if xx >= 2048 {
                        break;
                    }
                    out.push(ev(t, xx, y, on));
                }
            }
            out
        })
}

fn encode(events: &[Event64]) -> Vec<u16> {
    let mut enc = Evt3Encoder::new();
    let mut words = Vec::new();
    for e in events {
        enc.push(*e, |w| words.push(w)).unwrap();
    }
    enc.finish(|w| words.push(w));
    words
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn evt3_encode_decode_round_trip(events in prop_oneof![event_stream(50), event_stream(5_000), event_stream(40_000_000)]) {
        let words = encode(&events);
        let (decoded, d) = decode(Evt3Decoder::new(), &bytes16(&words));
        let origin = events.first().map_or(0, |e| Evt3Encoder::time_origin(e.t_us));
        let expect: Vec<Event64> = events.iter().map(|e| Event64 { t_us: e.t_us - origin, ..*e }).collect();
        prop_assert_eq!(decoded, expect);
        prop_assert_eq!(d.stats().invalid, 0);
    }

    #[test]
    fn chunk_boundaries_do_not_matter(
        events in event_stream(5_000),
        cuts in prop::collection::vec(0usize..4000, 0..20),
    ) {
        let mut cuts = cuts;
        cuts.sort_unstable();
        let bytes = bytes16(&encode(&events));
        let (a, da) = decode(Evt3Decoder::new(), &bytes);
        let (b, db) = decode_chunked(Evt3Decoder::new(), &bytes, &cuts);
        prop_assert_eq!(a, b);
        prop_assert_eq!(da.stats(), db.stats());
        // EVT 2.0 and 2.1 on the same bytes (read as their words) must agree with themselves too.
        let (a, _) = decode(Evt2Decoder::new(), &bytes);
        let (b, _) = decode_chunked(Evt2Decoder::new(), &bytes, &cuts);
        prop_assert_eq!(a, b);
        let (a, _) = decode(Evt21Decoder::new(), &bytes);
        let (b, _) = decode_chunked(Evt21Decoder::new(), &bytes, &cuts);
        prop_assert_eq!(a, b);
    }

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..4096), cut in 0usize..4096) {
        let cut = cut.min(bytes.len());
        let check = |n: usize, s: core_nostd::evt::DecodeStats, len: u64, word: u64, fin: bool| {
            assert_eq!(n as u64, s.events);
            assert_eq!(fin, len.is_multiple_of(word));
        };
        let (e, d) = decode_chunked(Evt3Decoder::new(), &bytes, &[cut]);
        check(e.len(), d.stats(), bytes.len() as u64, 2, d.finish().is_ok());
        let (e, d) = decode_chunked(Evt2Decoder::new(), &bytes, &[cut]);
        check(e.len(), d.stats(), bytes.len() as u64, 4, d.finish().is_ok());
        let (e, d) = decode_chunked(Evt21Decoder::new(), &bytes, &[cut]);
        check(e.len(), d.stats(), bytes.len() as u64, 8, d.finish().is_ok());
        let (e, d) = decode_chunked(Evt21Decoder::legacy(), &bytes, &[cut]);
        check(e.len(), d.stats(), bytes.len() as u64, 8, d.finish().is_ok());
    }

    #[test]
    fn decoded_evt3_times_never_go_back_for_monotonic_time_high(steps in prop::collection::vec(0u16..=11, 1..2000)) {
        // TIME_HIGH advancing modulo 4096 by steps of at most 11 (Prophesee's wrap rule: a step
        // back by >= 4085 is a wrap) gives non-decreasing time across wraps.
        let mut th = 4000u16;
        let mut words = vec![w3::y(0)];
        for s in steps {
            th = (th + s) % 4096;
            words.push(w3::th(th));
            words.push(w3::x(1, true));
        }
        let (events, _) = decode(Evt3Decoder::new(), &bytes16(&words));
        prop_assert!(events.windows(2).all(|w| w[0].t_us <= w[1].t_us));
    }
}

#[test]
fn encoder_rejects_bad_events() {
    let mut enc = Evt3Encoder::new();
    let mut n = 0;
    assert!(enc.push(ev(10, 1, 1, true), |_| n += 1).is_ok());
    assert_eq!(
        enc.push(ev(9, 1, 1, true), |_| n += 1),
        Err(evt3::EncodeError::TimeBackwards {
            t_us: 9,
            previous_us: 10
        })
    );
    assert_eq!(
        enc.push(ev(11, 2048, 1, true), |_| n += 1),
        Err(evt3::EncodeError::AddressOutOfRange { x: 2048, y: 1 })
    );
    assert!(enc.push(ev(11, 2047, 2047, true), |_| n += 1).is_ok());
}

#[test]
fn encoder_uses_vectors_for_runs() {
    // 12 events at one time on one row with increasing x: VECT_BASE_X + VECT_12 (+ TIME/ADDR_Y).
    let events: Vec<Event64> = (0..12).map(|i| ev(5000, 100 + 2 * i, 7, true)).collect();
    let words = encode(&events);
    // TIME_HIGH, TIME_LOW, ADDR_Y, VECT_BASE_X, VECT_12, VECT_12
    assert_eq!(words.len(), 6, "{words:04x?}");
    let (decoded, _) = decode(Evt3Decoder::new(), &bytes16(&words));
    assert_eq!(decoded, events);
}
