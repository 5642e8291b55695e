//! The spike readout: single bursts decode to the drive (and the edge's travel time) that
//! started them, drives that arrive during a burst too; rigid patterns of vertical edges sweeping
//! across a small sensor give back the yaw rate their speed implies (as the calibrated readout
//! does, `calibrated_readout.rs`), from the spikes alone; the settings ask for the readout's
//! memory and the configuration frame carries it; the f64 mirror agrees with the fixed-point
//! readout.

use core_nostd::event::Event;
use core_nostd::fixed::types::U16F16;
use core_nostd::flags;
use core_nostd::layout::{Dense, Layout};
use core_nostd::network::{Cell, NetState, UnitPair};
use core_nostd::oracle::{OracleParams, OracleSpikeYaw};
use core_nostd::pipeline::ONSET_GAP_US;
use core_nostd::readout::calibrated;
use core_nostd::readout::spikes::{BurstDecoder, Decoded, SpikeCell, Spikes};
use core_nostd::readout::YawSample;
use core_nostd::settings::{ReadoutChoice, Settings, SettingsError};
use core_nostd::unit::{Kernel, Tde};

/// `tau_F` of the default kernel (µs).
const TAU_F: f64 = 20_000.0;

/// The spikes of one unit: a FAC event at `t0`, TRG events at `trg` (each after its own FAC
/// event `dt` earlier: `(t_fac, t_trg)` pairs), run until the burst is over.
fn train(k: &Kernel, pairs: &[(u32, u32)]) -> Vec<u32> {
    let mut tde = Tde::new(0);
    let mut spikes = Vec::new();
    let mut inputs: Vec<(u32, bool)> = pairs
        .iter()
        .flat_map(|&(f, t)| [(f, true), (t, false)])
        .collect();
    inputs.sort();
    for (t, fac) in inputs {
        if fac {
            tde.advance(k, t, |s| spikes.push(s));
            tde.fac(k, t);
        } else {
            tde.trg(k, t, |s| spikes.push(s));
        }
    }
    let end = pairs.iter().map(|p| p.1).max().unwrap_or(0) + 2_000_000;
    tde.advance(k, end, |s| spikes.push(s));
    spikes
}

fn drive(d: &Decoded) -> f64 {
    (f64::from(d.log2_drive) / 65536.0).exp2()
}

#[test]
fn a_burst_from_rest_decodes_to_its_travel_time() {
    // One FAC event, one TRG event dt later: the burst's first two spikes give the drive
    // w_T w_F e^(-dt/tau_F), hence dt, and the TRG event's time. Spike times are whole µs, so
    // the drive is good to about 0.15 % (`tau_F` x 0.15 % = 30 µs of travel time).
    let k = Kernel::DEFAULT;
    let dec = BurstDecoder::new(&k);
    let (mut worst_d, mut worst_dt, mut worst_t) = (0.0f64, 0.0f64, 0u32);
    let mut last_decoded = 0;
    let mut dt_us = 50;
    while dt_us <= 50_000 {
        let t_fac = 10_000;
        let t_trg = t_fac + dt_us;
        let spikes = train(&k, &[(t_fac, t_trg)]);
        let mut got = Vec::new();
        dec.decode_train(&spikes, |d| got.push(d));
        if spikes.len() < 2 {
            // A single spike (dt above ~47 ms) has no interval: the readout reads it as a lone
            // spike (`a_lone_spike_decodes_to_the_middle_of_the_one_spike_range`).
            assert!(got.is_empty());
            assert!(dt_us > 45_000, "dt {dt_us} µs: {} spikes", spikes.len());
        } else {
            assert_eq!(got.len(), 1, "dt {dt_us} µs: {got:?}");
            let d = got[0];
            let rel = (drive(&d) / (-f64::from(dt_us) / TAU_F).exp()).ln().abs();
            let dt = -TAU_F * drive(&d).ln();
            worst_d = worst_d.max(rel);
            worst_dt = worst_dt.max((dt - f64::from(dt_us)).abs());
            worst_t = worst_t.max(d.t_us.abs_diff(t_trg));
            assert!(rel <= 0.0016, "dt {dt_us} µs: drive off by {rel:.2e}");
            assert!(
                (dt - f64::from(dt_us)).abs() <= 32.0,
                "dt {dt_us} µs decoded as {dt:.1} µs"
            );
            assert!(d.t_us.abs_diff(t_trg) <= 3, "TRG at {t_trg}: {}", d.t_us);
            last_decoded = dt_us;
        }
        dt_us += if dt_us < 2_000 { 50 } else { 500 };
    }
    eprintln!(
        "worst drive error {worst_d:.2e}, travel time {worst_dt:.1} µs, TRG time {worst_t} µs; \
         longest travel time decoded {last_decoded} µs"
    );
    assert!(last_decoded >= 45_000);
}

#[test]
fn a_lone_spike_decodes_to_the_middle_of_the_one_spike_range() {
    // Crossings too slow for a second spike (47-54 ms at a pixel with one onset) give a burst
    // of one: read as the middle of the drives that do, the travel time is good to the range's
    // half width (3.7 ms); where the TRG event's time is known (the pixel's onset, decoded by
    // the twin), its latency gives the drive.
    let k = Kernel::DEFAULT;
    let dec = BurstDecoder::new(&k);
    let mut lone = 0;
    let mut dt_us = 40_000;
    while dt_us <= 60_000 {
        let t_trg = 10_000 + dt_us;
        let spikes = train(&k, &[(10_000, t_trg)]);
        if let [t1] = spikes[..] {
            lone += 1;
            let d = dec.decode_lone(t1, None);
            let dt = -TAU_F * drive(&d).ln();
            assert!(
                (dt - f64::from(dt_us)).abs() <= 3_800.0,
                "dt {dt_us} µs read as {dt:.0}"
            );
            assert!(d.from_rest && d.t_us.abs_diff(t_trg) <= 10_000, "{d:?}");
            let e = dec.decode_lone(t1, Some(t_trg));
            let dt = -TAU_F * drive(&e).ln();
            assert!(
                (dt - f64::from(dt_us)).abs() <= 40.0,
                "dt {dt_us} µs: {dt:.0}"
            );
            assert_eq!(e.t_us, t_trg);
        } else {
            assert!(
                spikes.len() > 1 || dt_us > 53_000,
                "dt {dt_us} µs: {spikes:?}"
            );
        }
        dt_us += 250;
    }
    assert!(lone >= 25, "{lone}");
}

#[test]
fn a_drive_during_a_burst_is_decoded_too() {
    // A second edge crosses the pair while the first burst is still running (and after it
    // ended): the early spike and the interval after it give the second drive and its time.
    let k = Kernel::DEFAULT;
    let dec = BurstDecoder::new(&k);
    let mut worst = 0.0f64;
    for (dt1, gap, dt2) in [
        (2_000u32, 8_000u32, 2_000u32),
        (3_000, 15_000, 6_000),
        (1_000, 5_000, 12_000),
        (10_000, 25_000, 4_000),
        (4_000, 60_000, 4_000),
    ] {
        let t1 = 10_000;
        let t2 = t1 + dt1 + gap;
        let spikes = train(&k, &[(t1, t1 + dt1), (t2, t2 + dt2)]);
        let mut got = Vec::new();
        dec.decode_train(&spikes, |d| got.push(d));
        assert_eq!(got.len(), 2, "{dt1} {gap} {dt2}: {got:?}");
        // The second drive adds to what is left of the first FAC trace.
        let fac = |t: u32, t_fac: u32| (-f64::from(t - t_fac) / TAU_F).exp();
        let true_d2 = fac(t2 + dt2, t2) + fac(t2 + dt2, t1);
        let rel = (drive(&got[1]) / true_d2).ln().abs();
        worst = worst.max(rel);
        eprintln!(
            "dt1 {dt1} gap {gap} dt2 {dt2}: drive {:.5} vs {true_d2:.5}, TRG at {} vs {}",
            drive(&got[1]),
            got[1].t_us,
            t2 + dt2
        );
        assert!(rel < 0.005, "{dt1} {gap} {dt2}: {rel}");
        assert!(got[1].t_us.abs_diff(t2 + dt2) <= 10);
    }
    eprintln!("worst relative drive error {worst:.2e}");
}

/// Edges at pseudo-random spacing move at `u` px/s (negative = leftwards); each crossing of a
/// pixel gives one event, polarity alternating edge to edge (as in `calibrated_readout.rs`).
fn pattern(cols: std::ops::Range<u16>, h: u16, u: f64, duration_s: f64) -> Vec<Event> {
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
            let t = (f64::from(x) - (e - 2000.0)) / u;
            if !(0.0..duration_s).contains(&t) {
                continue;
            }
            for y in 0..h {
                out.push(Event {
                    t_us: (t * 1e6) as u32,
                    x,
                    y,
                    on: i % 2 == 0,
                });
            }
        }
    }
    out
}

/// Sensor of the tests: 96 x 24 px, f = 400 px, principal point at the centre.
const W: u16 = 96;
const H: u16 = 24;
const F: f64 = 400.0;
/// `G(x) = f + (x - c_x)^2 / f` at the middle of its range.
const G_MID: f64 = 403.0;

/// The spike readout's pipeline, built from its settings, on the test sensor.
fn run_events(evs: &[Event]) -> Vec<YawSample> {
    let kernel = Kernel::DEFAULT;
    let settings = Settings {
        readout: ReadoutChoice::Spikes,
        ..Settings::for_sensor(W, H, U16F16::from_num(F))
    };
    let needs = settings.storage().unwrap();
    let mut cells = vec![Cell::default(); needs.cells];
    let mut units = vec![UnitPair::default(); needs.unit_pairs];
    let mut active = vec![0u32; needs.active_words];
    let mut spike_cells = vec![SpikeCell::EMPTY; needs.spike_cells];
    let state = NetState::spiking(&mut cells, &mut units, &mut active);
    let mut p = settings
        .build_with(&kernel, state, &mut spike_cells)
        .unwrap();
    let mut out = Vec::new();
    for &ev in evs {
        p.event(ev, &mut |s| out.push(s));
    }
    out
}

fn sorted(mut evs: Vec<Event>) -> Vec<Event> {
    evs.sort_by_key(|e| e.t_us);
    evs
}

fn rate(s: &YawSample) -> f64 {
    f64::from(s.yaw_rate.to_bits()) / 65536.0
}

/// Mean output over the second half (steady state).
fn tail_mean(samples: &[YawSample]) -> f64 {
    let tail = &samples[samples.len() / 2..];
    tail.iter().map(rate).sum::<f64>() / tail.len() as f64
}

#[test]
fn recovers_the_rate_of_a_rigid_pattern() {
    // Speeds whose 2-pixel crossing the paper's units time (up to ~47 ms: 43 px/s and up).
    for u in [-60.0, -80.0, -100.0, -150.0, -300.0, 100.0, 300.0] {
        let samples = run_events(&sorted(pattern(0..W, H, u, 2.0)));
        let tail = &samples[samples.len() / 2..];
        let mean = tail_mean(&samples);
        // Leftward motion (u < 0) = turning right = positive yaw; |w| = |u| / G(x).
        let expected = -u / G_MID;
        let err = (mean - expected).abs() / expected.abs();
        eprintln!(
            "u = {u} px/s: mean {mean:.4} rad/s, expected {expected:.4} ({:.1} %)",
            err * 100.0
        );
        assert!(err < 0.1, "u = {u}: {mean} vs {expected}");
        assert!(tail.iter().all(|s| s.flags & flags::NO_EVIDENCE == 0));
    }
}

#[test]
fn crossings_too_slow_for_a_second_spike_are_read() {
    // A one-pixel crossing of 48-53 ms gives the near units (chosen at such speeds) bursts of
    // one spike, and is too fast for the slow units (their decodes start at the paper's
    // units' reach, 54 ms): read from the lone spikes, to within the one-spike range's half
    // width (7 %).
    for u in [-20.5, 19.0] {
        let samples = run_events(&sorted(pattern(0..W, H, u, 2.0)));
        let tail = &samples[samples.len() / 2..];
        let answered: Vec<f64> = tail
            .iter()
            .filter(|s| s.flags & flags::NO_EVIDENCE == 0)
            .map(rate)
            .collect();
        let expected = -u / G_MID;
        let mean = answered.iter().sum::<f64>() / answered.len().max(1) as f64;
        eprintln!(
            "u = {u} px/s: {} of {} answered, mean {mean:.4} rad/s, expected {expected:.4}",
            answered.len(),
            tail.len()
        );
        assert!(answered.len() * 10 >= tail.len() * 9, "u = {u}");
        assert!(
            (mean - expected).abs() <= 0.1 * expected.abs(),
            "u = {u}: {mean}"
        );
    }
}

#[test]
fn translation_cancels_between_mirrored_sides() {
    // The halves move apart on top of the rotation: u = -w f -+ a.
    // (Both halves within the units' range: 2 px in at most ~40 ms.)
    for (w, a) in [(0.3, 40.0), (-0.25, 30.0)] {
        let mut evs = pattern(0..W / 2, H, -w * F - a, 2.0);
        evs.extend(pattern(W / 2..W, H, -w * F + a, 2.0));
        let mean = tail_mean(&run_events(&sorted(evs)));
        eprintln!("w = {w}, a = {a} px/s: mean {mean:.4} rad/s");
        assert!((mean - w).abs() < 0.05 + 0.1 * w.abs(), "w = {w}: {mean}");
    }
}

#[test]
fn motion_in_one_part_of_the_view_is_not_rotation() {
    let samples = run_events(&sorted(pattern(42..54, H, 120.0, 2.0)));
    assert!(!samples.is_empty());
    assert!(samples
        .iter()
        .all(|s| s.flags & flags::NO_EVIDENCE != 0 && s.yaw_rate == 0));
}

#[test]
fn the_first_outputs_say_no_evidence() {
    let samples = run_events(&sorted(pattern(0..W, H, -150.0, 1.0)));
    // The calibrated readout's warm-up; after it the field answers as soon as its support
    // rules hold (the first decodes take up to tau, 20 ms).
    let warmup = (calibrated::WARMUP_US / 1000) as usize;
    assert!(samples[..warmup]
        .iter()
        .all(|s| s.flags & flags::NO_EVIDENCE != 0 && s.yaw_rate == 0));
    assert!(samples[warmup..2 * warmup]
        .iter()
        .any(|s| s.flags & flags::NO_EVIDENCE == 0));
}

#[test]
fn the_settings_ask_for_the_readouts_memory() {
    let kernel = Kernel::DEFAULT;
    let settings = Settings {
        readout: ReadoutChoice::Spikes,
        ..Settings::for_sensor(W, H, U16F16::from_num(F))
    };
    let needs = settings.storage().unwrap();
    let layout = Dense::new(W, H, 2).unwrap();
    // Three networks (the paper's units, the slow ones and the near ones), each with its
    // cells, units and the readout's memory.
    assert!(calibrated::has_near(&layout));
    assert_eq!(Settings::spike_networks(&layout), 3);
    assert_eq!(needs.cells, 3 * layout.cell_count());
    assert_eq!(needs.unit_pairs, 3 * layout.cell_count());
    assert_eq!(needs.spike_cells, 3 * Spikes::<Dense>::cells_for(&layout));
    assert_eq!(needs.spike_cells, 3 * layout.cell_count());
    // At stride 1 there are no near units: two networks.
    let stride_1 = Settings {
        stride: 1,
        ..settings
    };
    let layout_1 = Dense::new(W, H, 1).unwrap();
    assert_eq!(stride_1.storage().unwrap().cells, 2 * layout_1.cell_count());
    assert_eq!(SpikeCell::BYTES, 32);
    // Without the readout's memory the pipeline is refused, not built short.
    let mut cells = vec![Cell::default(); needs.cells];
    let mut units = vec![UnitPair::default(); needs.unit_pairs];
    let mut active = vec![0u32; needs.active_words];
    let state = NetState::spiking(&mut cells, &mut units, &mut active);
    assert!(matches!(
        settings.build(&kernel, state),
        Err(SettingsError::SpikeCells { .. })
    ));
    // The configuration frame carries the readout (code 2, format version 2).
    let (payload, len) = settings.payload();
    assert_eq!((payload[0], payload[1]), (2, 2));
    assert_eq!(Settings::parse(&payload[..len]), Ok(settings));
    let mut v1 = payload;
    v1[0] = 1;
    assert!(
        Settings::parse(&v1[..36]).is_err(),
        "version 1 has no spike readout"
    );
}

#[test]
fn the_f64_mirror_agrees_with_the_fixed_point_readout() {
    // A pattern whose speed changes halfway (the output must follow it), through both.
    let mut evs = pattern(0..W, H, -120.0, 1.0);
    evs.extend(pattern(0..W, H, 200.0, 1.0).into_iter().map(|e| Event {
        t_us: e.t_us + 1_000_000,
        ..e
    }));
    let evs = sorted(evs);
    let fixed = run_events(&evs);
    let layout = Dense::new(W, H, 2).unwrap();
    let mut y = OracleSpikeYaw::new(
        OracleParams::default(),
        layout,
        F,
        (47.5, 11.5),
        1000.0,
        f64::from(ONSET_GAP_US),
        f64::from(calibrated::default_tau_a_us(layout.unit_count())),
    );
    let mut float = Vec::new();
    let t0 = f64::from(evs[0].t_us);
    for e in &evs {
        y.event(f64::from(e.t_us) - t0, e.x, e.y, e.on, &mut float);
    }
    let n = fixed.len().min(float.len());
    let a: Vec<f64> = fixed[..n].iter().map(rate).collect();
    let b: Vec<f64> = float[..n].iter().map(|s| s.1).collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (ma, mb) = (mean(&a), mean(&b));
    let cov: f64 = a.iter().zip(&b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let var = |v: &[f64], m: f64| v.iter().map(|x| (x - m) * (x - m)).sum::<f64>();
    let corr = cov / (var(&a, ma) * var(&b, mb)).sqrt();
    let worst = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    eprintln!("fixed vs f64: correlation {corr:.5}, largest difference {worst:.4} rad/s");
    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
        if (i > 950 && i < 1300 && i % 10 == 0) || (x - y).abs() > 0.05 {
            eprintln!("DBG {i} {x:.3} {y:.3} {} {}", fixed[i].flags, float[i].2);
        }
    }
    assert!(corr > 0.99, "{corr}");
}
