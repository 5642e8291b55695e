//! The calibrated readout on an analytic stimulus: a rigid pattern of vertical edges sweeping
//! across a small sensor at a known image speed gives back the yaw rate that speed implies.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic,
    missing_docs
)]

use core_nostd::event::Event;
use core_nostd::fixed::types::U16F16;
use core_nostd::layout::{Dense, Layout};
use core_nostd::network::{Cell, InputFilter, Network};
use core_nostd::pipeline::Pipeline;
use core_nostd::readout::calibrated::{Calibrated, Calibration};
use core_nostd::readout::{flags, YawSample};
use core_nostd::unit::Kernel;

/// Edges at pseudo-random spacing move at `u` px/s (negative = leftwards); each crossing of a
/// pixel gives `k` events of one polarity 200 µs apart, polarity alternating edge to edge.
fn events(w: u16, h: u16, u: f64, k: u32, duration_s: f64) -> Vec<Event> {
    let mut edges = Vec::new();
    let mut pos = 0.0;
    let mut seed = 12345u64;
    while pos < 4000.0 {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        pos += 3.0 + (seed >> 33) as f64 / (1u64 << 31) as f64 * 9.0;
        edges.push(pos);
    }
    let mut out = Vec::new();
    for (i, &e) in edges.iter().enumerate() {
        for x in 0..w {
            // Pattern coordinate of pixel x at time t: x - u t; the edge at pattern position e
            // crosses pixel x when x - u t = e - 2000.
            let t = (f64::from(x) - (e - 2000.0)) / u;
            if !(0.0..duration_s).contains(&t) {
                continue;
            }
            for j in 0..k {
                for y in 0..h {
                    out.push(Event {
                        t_us: (t * 1e6) as u32 + j * 200,
                        x,
                        y,
                        on: i % 2 == 0,
                    });
                }
            }
        }
    }
    out.sort_by_key(|e| e.t_us);
    out
}

fn run(u: f64, k: u32) -> Vec<YawSample> {
    let (w, h) = (64u16, 4u16);
    let kernel = Kernel::DEFAULT;
    let layout = Dense::new(w, h, 2).unwrap();
    let mut cells = vec![Cell::default(); layout.cell_count()];
    let net = Network::new(
        &kernel,
        layout,
        &mut cells,
        &mut [],
        &mut [],
        InputFilter::Onsets { gap_us: 50_000 },
    )
    .unwrap();
    let cal = Calibration::new(U16F16::from_num(200), U16F16::from_num(31.5));
    let readout = Calibrated::new(&kernel, 2, cal);
    let mut p = Pipeline::new(net, readout, 1000);
    let mut out = Vec::new();
    for ev in events(w, h, u, k, 2.0) {
        p.event(ev, &mut |s| out.push(s));
    }
    out
}

/// Mean output over the second half (steady state) and the expected yaw rate.
fn check(u: f64, k: u32) {
    let samples = run(u, k);
    let tail = &samples[samples.len() / 2..];
    let mean = tail
        .iter()
        .map(|s| f64::from(s.yaw_rate.to_bits()) / 65536.0)
        .sum::<f64>()
        / tail.len() as f64;
    // Leftward motion (u < 0) = turning right = positive yaw; |w| = |u| / G(x), and G(x) ranges
    // over f + (x - cx)^2 / f = 200 .. 205 px on this narrow sensor.
    let expected = -u / 202.5;
    let err = (mean - expected).abs() / expected.abs();
    eprintln!(
        "u = {u} px/s, {k} events/edge: mean {mean:.4} rad/s, expected {expected:.4} ({:.1} %)",
        err * 100.0
    );
    assert!(err < 0.1, "u = {u}, k = {k}: {mean} vs {expected}");
    assert!(tail.iter().all(|s| s.flags & flags::STALE == 0));
}

#[test]
fn recovers_the_rate_of_a_rigid_pattern() {
    for u in [-60.0, -150.0, 100.0, 300.0] {
        check(u, 1);
    }
}

#[test]
fn contrast_does_not_change_the_rate() {
    // Several events per edge and pixel (higher contrast): the onset filter and the
    // normalisation by the pixel's own trace keep the decoded rate.
    for k in [2, 4] {
        check(-120.0, k);
    }
}

#[test]
fn no_events_means_stale_and_zero() {
    let kernel = Kernel::DEFAULT;
    let layout = Dense::new(16, 2, 2).unwrap();
    let mut cells = vec![Cell::default(); layout.cell_count()];
    let net = Network::new(
        &kernel,
        layout,
        &mut cells,
        &mut [],
        &mut [],
        InputFilter::Onsets { gap_us: 50_000 },
    )
    .unwrap();
    let readout = Calibrated::new(
        &kernel,
        2,
        Calibration::new(U16F16::from_num(200), U16F16::from_num(8)),
    );
    let mut p = Pipeline::new(net, readout, 1000);
    let mut out = Vec::new();
    p.event(
        Event {
            t_us: 0,
            x: 3,
            y: 0,
            on: true,
        },
        &mut |s| out.push(s),
    );
    p.poll(300_000, &mut |s| out.push(s));
    assert_eq!(out.len(), 300);
    assert!(out[..99].iter().all(|s| s.flags & flags::STALE == 0));
    assert!(out[100..]
        .iter()
        .all(|s| s.flags & flags::STALE != 0 && s.yaw_rate == 0));
}
