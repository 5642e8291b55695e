//! The generator is a pure function of its configuration: same seed => identical events.

use host_sim::synth::{self, MotionKind, Preset, SynthConfig, TextureKind};

fn small(motion: MotionKind, seed: u64) -> SynthConfig {
    let mut cfg = SynthConfig::new(Preset::Davis240, TextureKind::Urban, motion);
    cfg.intrinsics = synth::Intrinsics::centred(64, 48, 50.0);
    cfg.duration_s = 0.15;
    cfg.seed = seed;
    cfg.sensor.noise_hz = 2.0;
    cfg.sensor.hot_pixels = 2;
    cfg
}

#[test]
fn same_seed_gives_identical_output() {
    for motion in [MotionKind::Sinusoid, MotionKind::Car] {
        let a = synth::generate(&small(motion, 7)).unwrap();
        let b = synth::generate(&small(motion, 7)).unwrap();
        assert!(!a.events.is_empty(), "{motion:?}: no events");
        assert_eq!(a.events, b.events, "{motion:?}");
        assert_eq!(a.gt, b.gt);
        assert_eq!(a.imu, b.imu);
        assert_eq!(a.meta, b.meta);
    }
}

#[test]
fn different_seed_gives_different_output() {
    let a = synth::generate(&small(MotionKind::Steps, 1)).unwrap();
    let b = synth::generate(&small(MotionKind::Steps, 2)).unwrap();
    assert_ne!(a.events, b.events);
    assert_ne!(a.motion, b.motion);
}

#[test]
fn thread_count_does_not_change_the_events() {
    let mut cfg = small(MotionKind::Car, 3);
    // Big enough that the renderer really splits the work.
    cfg.intrinsics = synth::Intrinsics::centred(200, 120, 140.0);
    cfg.duration_s = 0.03;
    cfg.threads = 1;
    let a = synth::generate(&cfg).unwrap();
    cfg.threads = 3;
    let b = synth::generate(&cfg).unwrap();
    assert!(!a.events.is_empty());
    assert_eq!(a.events, b.events);
}

#[test]
fn events_are_sorted_inside_the_sensor_and_the_duration() {
    let cfg = small(MotionKind::Sinusoid, 5);
    let seq = synth::generate(&cfg).unwrap();
    let end_us = (cfg.duration_s * 1e6).round() as u64;
    for w in seq.events.windows(2) {
        assert!(w[0].t_us <= w[1].t_us);
    }
    for e in &seq.events {
        assert!(e.x < 64 && e.y < 48 && e.t_us <= end_us, "{e:?}");
    }
    assert_eq!(seq.stats.events as usize, seq.events.len());
    assert_eq!(
        seq.stats.events,
        seq.stats.signal_events + seq.stats.noise_events
    );
}
