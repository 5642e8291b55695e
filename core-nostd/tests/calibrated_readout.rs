//! The calibrated readout on analytic stimuli: rigid patterns of vertical edges sweeping across
//! a small sensor at known image speeds give back the yaw rate those speeds imply, translation
//! (the halves moving apart) cancels, slow edges are timed by the slow units, and motion in one
//! part of the view alone is not called a rotation.

use core_nostd::event::Event;
use core_nostd::fixed::types::U16F16;
use core_nostd::flags;
use core_nostd::layout::{Dense, Layout};
use core_nostd::network::{Cell, InputFilter, NetState, Network};
use core_nostd::pipeline::Pipeline;
use core_nostd::readout::calibrated::{self, Calibrated, Calibration};
use core_nostd::readout::YawSample;
use core_nostd::settings::Settings;
use core_nostd::unit::Kernel;

/// Edges at pseudo-random spacing move at `u` px/s (negative = leftwards); each crossing of a
/// pixel gives `k` events of one polarity 200 µs apart, polarity alternating edge to edge.
fn events(w: u16, h: u16, u: f64, k: u32, duration_s: f64) -> Vec<Event> {
    let mut out = pattern(0..w, h, u, k, duration_s);
    out.sort_by_key(|e| e.t_us);
    out
}

/// The same over columns `cols` only (unsorted).
fn pattern(cols: std::ops::Range<u16>, h: u16, u: f64, k: u32, duration_s: f64) -> Vec<Event> {
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
        for x in cols.clone() {
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
    out
}

/// Sensor of the tests: 96 x 24 px, f = 400 px, principal point at the centre, so that
/// `G(x) = f + (x - c_x)^2 / f` stays within 401 .. 406 px.
const W: u16 = 96;
const H: u16 = 24;
const F: f64 = 400.0;
/// `G(x)` at the middle of its range.
const G_MID: f64 = 403.0;

/// The product's pipeline on the test sensor.
fn run_events(evs: &[Event]) -> Vec<YawSample> {
    let (w, h) = (W, H);
    let kernel = Kernel::DEFAULT;
    let layout = Dense::new(w, h, 2).unwrap();
    let mut cells = vec![Cell::default(); layout.cell_count()];
    // 4,560 units: a sparse layout, so the readout integrates over 100 ms.
    let settings = Settings::for_sensor(w, h, U16F16::from_num(F));
    let mut p = settings
        .build(&kernel, NetState::cells(&mut cells))
        .unwrap();
    let mut out = Vec::new();
    for &ev in evs {
        p.event(ev, &mut |s| out.push(s));
    }
    out
}

fn run(u: f64, k: u32) -> Vec<YawSample> {
    run_events(&events(W, H, u, k, 2.0))
}

fn rate(s: &YawSample) -> f64 {
    f64::from(s.yaw_rate.to_bits()) / 65536.0
}

/// Mean output over the second half (steady state).
fn tail_mean(samples: &[YawSample]) -> f64 {
    let tail = &samples[samples.len() / 2..];
    tail.iter().map(rate).sum::<f64>() / tail.len() as f64
}

/// Mean output over the second half (steady state) against the expected yaw rate.
fn check(u: f64, k: u32) {
    let samples = run(u, k);
    let tail = &samples[samples.len() / 2..];
    let mean = tail_mean(&samples);
    // Leftward motion (u < 0) = turning right = positive yaw; |w| = |u| / G(x).
    let expected = -u / G_MID;
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
    for u in [
        -20.0, -30.0, -40.0, -60.0, -80.0, -100.0, -150.0, 100.0, 300.0,
    ] {
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
fn translation_cancels_between_mirrored_sides() {
    // Forward motion moves the halves apart (left half leftwards, right half rightwards) on top
    // of the rotation: u = -w f -+ a. Each half alone decodes w +- a / f.
    for (w, a) in [(0.3, 40.0), (-0.25, 60.0), (0.0, 50.0)] {
        let mut evs = pattern(0..W / 2, H, -w * F - a, 1, 2.0);
        evs.extend(pattern(W / 2..W, H, -w * F + a, 1, 2.0));
        evs.sort_by_key(|e| e.t_us);
        let mean = tail_mean(&run_events(&evs));
        eprintln!("w = {w}, a = {a} px/s: mean {mean:.4} rad/s");
        assert!((mean - w).abs() < 0.05 + 0.1 * w.abs(), "w = {w}: {mean}");
    }
}

#[test]
fn slow_edges_are_timed_by_the_slow_units() {
    // 10 px/s: a 2-pixel crossing takes 200 ms, beyond the 54 ms of the paper's units.
    for u in [-10.0, 16.0] {
        let samples = run_events(&events(W, H, u, 1, 6.0));
        let tail = &samples[samples.len() / 2..];
        let expected = -u / G_MID;
        let mean = tail_mean(&samples);
        eprintln!("u = {u} px/s: mean {mean:.4} rad/s, expected {expected:.4}");
        assert!(
            (mean - expected).abs() < 0.15 * expected.abs(),
            "{mean} vs {expected}"
        );
        let answered = tail
            .iter()
            .filter(|s| s.flags & flags::NO_EVIDENCE == 0)
            .count();
        assert!(
            answered * 10 >= tail.len() * 9,
            "{answered} of {}",
            tail.len()
        );
    }
}

#[test]
fn motion_in_one_part_of_the_view_is_not_rotation() {
    // A textured object crosses the middle eighth of the view; the rest is still.
    let mut evs = pattern(42..54, H, 120.0, 1, 2.0);
    evs.sort_by_key(|e| e.t_us);
    let samples = run_events(&evs);
    assert!(!samples.is_empty());
    assert!(
        samples
            .iter()
            .all(|s| s.flags & flags::NO_EVIDENCE != 0 && s.yaw_rate == 0),
        "an object moving on its own was read as a rotation"
    );
}

#[test]
fn the_first_outputs_say_no_evidence() {
    let samples = run(-150.0, 1);
    let warmup = (calibrated::WARMUP_US / 1000) as usize;
    assert!(samples[..warmup]
        .iter()
        .all(|s| s.flags & flags::NO_EVIDENCE != 0 && s.yaw_rate == 0));
    assert!(samples[warmup..2 * warmup]
        .iter()
        .any(|s| s.flags & flags::NO_EVIDENCE == 0));
}

/// A calibrated pipeline at 1 kHz over `layout` (onset filter, 50 ms gap), its cells in
/// `cells`, for a camera with focal length `f` and principal point `(cx, cy)` (px).
fn calibrated_pipeline<'a>(
    kernel: &'a Kernel,
    layout: Dense,
    cells: &'a mut [Cell],
    (f, cx, cy): (f64, f64, f64),
) -> Pipeline<'a, Dense, Calibrated> {
    let net = Network::new(
        kernel,
        layout,
        NetState::cells(cells),
        InputFilter::Onsets { gap_us: 50_000 },
    )
    .unwrap();
    let cal = Calibration::new(
        U16F16::from_num(f),
        U16F16::from_num(cx),
        U16F16::from_num(cy),
    );
    let readout = Calibrated::new(kernel, &layout, cal);
    Pipeline::new(net, readout, 1000)
}

#[test]
fn no_events_means_stale_and_zero() {
    let kernel = Kernel::DEFAULT;
    let layout = Dense::new(16, 2, 2).unwrap();
    let mut cells = vec![Cell::default(); layout.cell_count()];
    let mut p = calibrated_pipeline(&kernel, layout, &mut cells, (200.0, 8.0, 0.5));
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

/// Over the warm-up the bursts time the order in which pixels woke up: none is decoded into the
/// field, while the outputs say "no evidence"; after it they are.
#[test]
fn bursts_in_the_warm_up_are_not_decoded() {
    let kernel = Kernel::DEFAULT;
    let layout = Dense::new(W, H, 2).unwrap();
    let mut cells = vec![Cell::default(); layout.cell_count()];
    let centre = (f64::from(W) / 2.0 - 0.5, f64::from(H) / 2.0);
    let mut p = calibrated_pipeline(&kernel, layout, &mut cells, (F, centre.0, centre.1));
    let mut out = Vec::new();
    // Edges 3-12 px apart at 300 px/s cross the stride in under 7 ms: bursts from the start.
    let evs = events(W, H, -300.0, 1, 0.06);
    let warm_end = evs.first().map_or(0, |e| e.t_us) + calibrated::WARMUP_US - 1_000;
    for &ev in evs.iter().filter(|e| e.t_us < warm_end) {
        p.event(ev, &mut |s| out.push(s));
    }
    assert!(!out.is_empty() && out.iter().all(|s| s.flags & flags::NO_EVIDENCE != 0));
    assert_eq!(p.readout().samples, 0, "decoded in the warm-up");
    for &ev in evs.iter().filter(|e| e.t_us >= warm_end) {
        p.event(ev, &mut |s| out.push(s));
    }
    assert!(p.readout().samples > 0, "nothing decoded after the warm-up");
}
