//! Error of the exponential lookup tables against `f64::exp`, over every table entry and over the
//! composed decay for every input below the horizon.

use core_nostd::exp_table::{ExpDecay, Part, DECAY_HORIZON_US, ONE_Q31};

const Q31: f64 = ONE_Q31 as f64;

struct Err {
    max: f64,
    rms: f64,
}

fn measure(e: &ExpDecay, inputs: impl Iterator<Item = u32>, value: impl Fn(u32) -> u32) -> Err {
    let tau = f64::from(e.tau_us());
    let (mut max, mut sum2, mut n) = (0.0f64, 0.0f64, 0u64);
    for dt in inputs {
        let exact = (-f64::from(dt) / tau).exp();
        let err = (f64::from(value(dt)) / Q31 - exact).abs();
        max = max.max(err);
        sum2 += err * err;
        n += 1;
    }
    Err {
        max,
        rms: (sum2 / n as f64).sqrt(),
    }
}

#[test]
fn every_table_entry_is_within_one_lsb() {
    for tau in [1, 100, 20_000, 10_000, 750_000, 1_000_000] {
        let e = ExpDecay::new(tau);
        for part in [Part::Lo, Part::Mid, Part::Hi] {
            let (table, step) = e.table(part);
            let err = measure(&e, (0..256u32).map(|i| i * step), |dt| {
                table[(dt / step) as usize]
            });
            // Each entry is e^(-i·step/tau) rounded to Q1.31: within 1 LSB (4.7e-10).
            eprintln!(
                "tau={tau} µs {part:?}: max {:.2e}, rms {:.2e}",
                err.max, err.rms
            );
            assert!(
                err.max <= 1.0 / Q31,
                "tau={tau} {part:?}: max error {:.3e}",
                err.max
            );
        }
    }
}

#[test]
fn composed_decay_over_the_whole_input_range() {
    for tau in [20_000, 10_000, 100, 1_000_000] {
        let e = ExpDecay::new(tau);
        // Every input below 2^22 µs, then every 61st up to the horizon (2^24).
        let inputs = (0..(1u32 << 22)).chain(((1u32 << 22)..DECAY_HORIZON_US).step_by(61));
        let err = measure(&e, inputs, |dt| e.decay_bits(dt));
        eprintln!(
            "tau={tau} µs composed: max {:.2e}, rms {:.2e}",
            err.max, err.rms
        );
        // Two roundings of products plus three entries: within 3 LSB of Q1.31.
        assert!(err.max <= 3.0 / Q31, "tau={tau}: max error {:.3e}", err.max);
    }
    // At and past the horizon the decay is exactly 0; the true value there is below 5.6e-8
    // for the largest allowed tau (1 s).
    let e = ExpDecay::new(1_000_000);
    assert_eq!(e.decay_bits(DECAY_HORIZON_US), 0);
    assert!((-f64::from(DECAY_HORIZON_US) / 1e6).exp() < 5.6e-8);
}
