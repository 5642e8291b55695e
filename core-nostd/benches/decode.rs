//! Decoding throughput (events/s) of the EVT 3.0 and EVT 2.0 stream decoders on synthetic
//! in-memory streams of 2 M events: a busy sensor's mix of single events and short same-row
//! runs (EVT 3.0 vectors), about one event per µs.

use core_nostd::event::Event64;
use core_nostd::evt::{evt2, Evt2Decoder, Evt3Decoder, Evt3Encoder, StreamDecoder};
use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};

const N: usize = 2_000_000;

/// A small deterministic generator (xorshift64*).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
}

/// `N` time-sorted events on a 1280x720 sensor: 70 % single events, 30 % in runs of 2-8 on
/// one row at one time; time advances 0-2 µs between groups.
fn events() -> Vec<Event64> {
    let mut r = Rng(0x1234_5678_9abc_def1);
    let mut t = 1_000u64;
    let mut out = Vec::with_capacity(N + 8);
    while out.len() < N {
        t += r.next() % 3;
        let x = (r.next() % 1200) as u16;
        let y = (r.next() % 720) as u16;
        let on = r.next() & 1 == 1;
        let run = if r.next() % 10 < 3 {
            2 + r.next() % 7
        } else {
            1
        };
        for k in 0..run as u16 {
            out.push(Event64 {
                t_us: t,
                x: x + 2 * k,
                y,
                on,
            });
        }
    }
    out.truncate(N);
    out
}

fn evt3_bytes(events: &[Event64]) -> Vec<u8> {
    let mut enc = Evt3Encoder::new();
    let mut bytes = Vec::new();
    for e in events {
        enc.push(*e, |w| bytes.extend_from_slice(&w.to_le_bytes()))
            .unwrap();
    }
    enc.finish(|w| bytes.extend_from_slice(&w.to_le_bytes()));
    bytes
}

/// EVT 2.0 as a sensor writes it: a TIME_HIGH whenever time bits 33..6 change, one CD word per
/// event.
fn evt2_bytes(events: &[Event64]) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut th = None;
    for e in events {
        if th != Some(e.t_us >> 6) {
            th = Some(e.t_us >> 6);
            bytes.extend_from_slice(&evt2::encode::time_high(e.t_us).to_le_bytes());
        }
        let w = evt2::encode::cd(e.on, (e.t_us & 63) as u8, e.x, e.y);
        bytes.extend_from_slice(&w.to_le_bytes());
    }
    bytes
}

/// Decodes `bytes` in 64 KiB chunks (as DMA buffers or file reads arrive); returns a checksum.
fn run<D: StreamDecoder>(mut d: D, bytes: &[u8]) -> u64 {
    let mut sum = 0u64;
    for chunk in bytes.chunks(64 * 1024) {
        d.push64(chunk, |e| {
            sum = sum.wrapping_add(e.t_us ^ u64::from(e.x) ^ (u64::from(e.y) << 16))
        });
    }
    sum
}

fn decode(c: &mut Criterion) {
    let ev = events();
    let b3 = evt3_bytes(&ev);
    let b2 = evt2_bytes(&ev);
    let mut n3 = 0usize;
    Evt3Decoder::new().push64(&b3, |_| n3 += 1);
    let mut n2 = 0usize;
    Evt2Decoder::new().push64(&b2, |_| n2 += 1);
    assert_eq!((n3, n2), (N, N));
    eprintln!(
        "EVT 3.0: {:.2} bytes/event, EVT 2.0: {:.2} bytes/event",
        b3.len() as f64 / N as f64,
        b2.len() as f64 / N as f64
    );

    let mut g = c.benchmark_group("decode");
    g.throughput(Throughput::Elements(N as u64));
    g.sample_size(30);
    g.bench_function("evt3", |b| {
        b.iter(|| run(Evt3Decoder::new(), black_box(&b3)))
    });
    g.bench_function("evt2", |b| {
        b.iter(|| run(Evt2Decoder::new(), black_box(&b2)))
    });
    g.finish();
}

criterion_group!(benches, decode);
criterion_main!(benches);
