//! The pipeline across several wraps of the u32 µs clock (every 71.6 min): the same events
//! started just before a wrap give exactly the output of a run whose clock starts at 0.

use core_nostd::event::Event;
use core_nostd::fixed::types::U16F16;
use core_nostd::layout::{Dense, Layout};
use core_nostd::network::{Cell, NetState};
use core_nostd::readout::YawSample;
use core_nostd::settings::Settings;
use core_nostd::unit::Kernel;

/// Event times relative to the start (u64 µs): every 10 s, 400 ms of a rigid pattern of edges
/// (12 px apart, alternating polarity) sweeping left at 150 px/s over a 96 x 24 sensor; 3.6 hours
/// in all (three wraps of the u32 clock).
fn stream() -> Vec<(u64, u16, u16, bool)> {
    let (u, window_s) = (150.0f64, 0.4f64);
    let mut out = Vec::new();
    let mut burst = 0u64;
    while burst * 10_000_000 < 13_000_000_000 {
        let t0 = burst * 10_000_000;
        let phase = (burst % 7) as f64;
        for x in 0..96u16 {
            // Pixel x sees the pattern point x + u t; edge k sits at 12 k + phase.
            for k in 0..16u32 {
                let p = f64::from(12 * k) + phase;
                let t = (p - f64::from(x)) / u;
                if (0.0..window_s).contains(&t) {
                    for y in 0..24 {
                        out.push((t0 + (t * 1e6) as u64, x, y, k % 2 == 0));
                    }
                }
            }
        }
        burst += 1;
    }
    out.sort_by_key(|e| e.0);
    out
}

fn run(events: &[(u64, u16, u16, bool)], clock0: u32) -> Vec<YawSample> {
    let k = Kernel::DEFAULT;
    let layout = Dense::new(96, 24, 2).unwrap();
    let mut cells = vec![Cell::default(); layout.cell_count()];
    let settings = Settings {
        period_us: 100_000,
        ..Settings::for_sensor(96, 24, U16F16::from_num(200))
    };
    let mut p = settings.build(&k, NetState::cells(&mut cells)).unwrap();
    let mut out = Vec::new();
    for &(t, x, y, on) in events {
        let ev = Event {
            t_us: clock0.wrapping_add(t as u32),
            x,
            y,
            on,
        };
        p.event(ev, &mut |s| out.push(s));
    }
    out
}

#[test]
fn output_is_identical_across_three_wraps() {
    let events = stream();
    let span = events.last().unwrap().0;
    assert!(
        span > 3 * (1u64 << 32),
        "the stream must span three wraps ({span} µs)"
    );
    let plain = run(&events, 0);
    let clock0 = u32::MAX - 12_345;
    let wrapped = run(&events, clock0);
    assert_eq!(plain.len(), wrapped.len());
    assert!(plain.len() > 100_000);
    let moving = plain.iter().filter(|s| s.yaw_rate != 0).count();
    assert!(
        moving > 1_000,
        "the bursts must give a yaw rate ({moving} samples)"
    );
    for (a, b) in plain.iter().zip(&wrapped) {
        assert_eq!(a.yaw_rate, b.yaw_rate);
        assert_eq!(a.flags, b.flags);
        assert_eq!(a.t_us.wrapping_add(clock0), b.t_us);
    }
}
