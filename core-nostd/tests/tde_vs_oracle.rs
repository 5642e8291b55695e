//! The fixed-point unit against the f64 oracle, and the oracle against model.md's reference table.

use core_nostd::oracle::{self, OracleParams};
use core_nostd::params::TdeParams;
use core_nostd::unit::{pair_response, Kernel};

/// model.md: time difference (ms) -> (spikes, first spike after TRG in ms).
const REFERENCE: &[(f64, u32, Option<f64>)] = &[
    (0.0, 33, Some(0.513)),
    (10.0, 20, Some(0.861)),
    (20.0, 11, Some(1.463)),
    (30.0, 6, Some(2.545)),
    (40.0, 3, Some(4.666)),
    (50.0, 1, Some(10.087)),
    (55.0, 0, None),
    (60.0, 0, None),
    (100.0, 0, None),
];

#[test]
fn oracle_reproduces_reference_table() {
    let p = OracleParams::default();
    for &(dt_ms, spikes, first_ms) in REFERENCE {
        let (n, first) = oracle::pair_response(&p, dt_ms * 1000.0);
        assert_eq!(n, spikes, "spike count at {dt_ms} ms");
        match (first, first_ms) {
            (Some(f), Some(r)) => {
                // The table reports the first whole µs at or after the crossing (its values are the
                // ceilings of the exact times), so the exact time lies in (r - 1 µs, r].
                let r_us = r * 1000.0;
                assert!(
                    f > r_us - 1.0 && f <= r_us + 1e-6,
                    "first spike at {dt_ms} ms: {f} µs vs {r} ms"
                );
            }
            (None, None) => {}
            other => panic!("first spike at {dt_ms} ms: {other:?}"),
        }
    }
}

#[test]
fn oracle_unequal_time_constants_approach_equal_limit() {
    // As tau_m -> tau_T the difference-of-exponentials solution must approach the equal case.
    let base = OracleParams::default();
    let near = OracleParams {
        tau_mem: base.tau_mem * (1.0 + 1e-7),
        ..base
    };
    for dt in [0.0, 7_300.0, 25_000.0, 49_000.0] {
        let (n0, f0) = oracle::pair_response(&base, dt);
        let (n1, f1) = oracle::pair_response(&near, dt);
        assert_eq!(n0, n1, "dt={dt}");
        assert!((f0.unwrap() - f1.unwrap()).abs() < 0.05, "dt={dt}");
    }
    // A clearly different membrane constant changes the response in the expected direction:
    // a longer tau_m integrates more and never spikes less.
    let slow = OracleParams {
        tau_mem: 40_000.0,
        ..base
    };
    for dt in [0.0, 20_000.0, 45_000.0] {
        assert!(oracle::pair_response(&slow, dt).0 >= oracle::pair_response(&base, dt).0);
    }
}

#[test]
fn fixed_sweep_matches_oracle() {
    let k = Kernel::new(TdeParams::DEFAULT).unwrap();
    let p = OracleParams::default();
    let mut equal = 0;
    let mut total = 0;
    let mut worst_first = 0.0f64;
    for step in 0..=1000u32 {
        let dt_us = step * 100;
        let fixed = pair_response(&k, 12_345, dt_us);
        let (n, first) = oracle::pair_response(&p, f64::from(dt_us));
        total += 1;
        if fixed.spikes == n {
            equal += 1;
        }
        assert!(
            fixed.spikes.abs_diff(n) <= 1,
            "dt={dt_us}: fixed {} vs oracle {n}",
            fixed.spikes
        );
        if let (Some(a), Some(b)) = (fixed.first_spike_us, first) {
            let err = (f64::from(a) - b).abs();
            worst_first = worst_first.max(err);
            assert!(err <= 50.0, "dt={dt_us}: first spike {a} µs vs {b} µs");
        }
    }
    let share = f64::from(equal) / f64::from(total);
    eprintln!("sweep: spike counts equal at {equal}/{total} points, worst first-spike error {worst_first:.2} µs");
    assert!(share >= 0.99, "only {equal}/{total} counts equal");
}

#[test]
fn sweep_is_identical_across_clock_wrap() {
    let k = Kernel::DEFAULT;
    for step in (0..=1000u32).step_by(7) {
        let dt = step * 100;
        let a = pair_response(&k, 1_000, dt);
        // FAC just before the u32 wrap, TRG and burst after it.
        let b = pair_response(&k, u32::MAX - 40_000, dt);
        assert_eq!(a, b, "dt={dt}");
    }
}
