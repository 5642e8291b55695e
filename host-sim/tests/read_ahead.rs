//! Reading a recording ahead (`host_sim::lookahead`, the default of `host-sim run`) changes
//! when the normalized readout's units emit their spikes, not which: every sample and the spike
//! count equal a run that takes each event as a live sensor's (`--no-read-ahead`), on a
//! generated scene (in order, with events out of order, across a backward jump that starts a
//! new piece) and on the shared sequences (skipped with a notice where absent).

use host_sim::formats::{self, Event64, Recording};
use host_sim::pipeline::{run_pipeline, ReadoutKind, RunOptions, RunOutput};
use host_sim::synth::{self, Intrinsics, MotionSpec, SynthConfig};
use host_sim::testdata::synthetic_sequences;

/// `rec` through the normalized readout, read ahead and not.
fn both(rec: &Recording) -> (RunOutput, RunOutput) {
    let opts = |read_ahead| RunOptions {
        readout: ReadoutKind::Normalized,
        read_ahead,
        ..RunOptions::default()
    };
    let ahead = run_pipeline(&opts(true), rec).expect("read ahead");
    let live = run_pipeline(&opts(false), rec).expect("live");
    (ahead, live)
}

fn assert_same(name: &str, ahead: &RunOutput, live: &RunOutput) {
    assert!(
        live.samples.len() > 100,
        "{name}: {} samples",
        live.samples.len()
    );
    assert_eq!(ahead.outputs, live.outputs, "{name}: spike counts");
    assert_eq!(
        ahead.samples.len(),
        live.samples.len(),
        "{name}: sample counts"
    );
    for (i, (a, b)) in ahead.samples.iter().zip(&live.samples).enumerate() {
        assert_eq!(a, b, "{name}: sample {i}");
    }
    eprintln!(
        "{name}: {} samples, {} spikes, read ahead and live alike",
        live.samples.len(),
        live.outputs
    );
}

/// A turning camera in front of the urban panorama, 96 x 48 px, 1.5 s.
fn scene() -> Recording {
    let cfg = SynthConfig {
        intrinsics: Intrinsics {
            width: 96,
            height: 48,
            fx: 80.0,
            fy: 80.0,
            cx: 47.5,
            cy: 23.5,
        },
        duration_s: 1.5,
        motion_spec: Some(MotionSpec::constant_yaw(1.2)),
        ..SynthConfig::default()
    };
    synth::generate(&cfg).expect("scene").into_recording()
}

#[test]
fn read_ahead_gives_the_live_output_on_a_generated_scene() {
    let rec = scene();
    assert!(rec.events.len() > 20_000, "{} events", rec.events.len());
    let (ahead, live) = both(&rec);
    assert!(live.outputs > 100_000, "{} spikes", live.outputs);
    assert_same("in order", &ahead, &live);
}

#[test]
fn read_ahead_gives_the_live_output_with_events_out_of_order_and_a_new_piece() {
    let mut rec = scene();
    // Every 97th event 3 ms early (out of order within its piece), and from the middle on the
    // recording 300 ms back in time (a backward jump: a new piece).
    let half = rec.events.len() / 2;
    for (i, e) in rec.events.iter_mut().enumerate() {
        if i % 97 == 0 {
            e.t_us = e.t_us.saturating_sub(3_000);
        }
        if i >= half {
            e.t_us = e.t_us.saturating_sub(300_000);
        }
    }
    let late = rec
        .events
        .windows(2)
        .filter(|w| w[1].t_us < w[0].t_us)
        .count();
    assert!(late > 100, "{late} events out of order");
    let (ahead, live) = both(&rec);
    assert_eq!(live.jumps.backward, 1, "one backward jump");
    assert_same("out of order", &ahead, &live);
}

#[test]
fn read_ahead_gives_the_live_output_on_the_shared_sequences() {
    let Some(seqs) = synthetic_sequences() else {
        return;
    };
    for (name, dir) in seqs {
        let rec = formats::read(dir.join("events.raw"), None).expect("read recording");
        let (ahead, live) = both(&rec);
        assert_same(&name, &ahead, &live);
    }
}

/// Events outside the sensor the lookahead tracks pass through it unmatched.
#[test]
fn read_ahead_passes_events_outside_its_pixels() {
    let mut rec = scene();
    rec.events.push(Event64 {
        t_us: rec.events.last().map_or(0, |e| e.t_us) + 10,
        x: 500,
        y: 7,
        on: true,
    });
    rec.width = None;
    rec.height = None;
    let opts = |read_ahead| RunOptions {
        readout: ReadoutKind::Normalized,
        read_ahead,
        size: Some((96, 48)),
        ..RunOptions::default()
    };
    let ahead = run_pipeline(&opts(true), &rec).expect("read ahead");
    let live = run_pipeline(&opts(false), &rec).expect("live");
    assert_eq!(
        live.ignored, 1,
        "the event outside the sensor is counted, not run"
    );
    assert_eq!(ahead.ignored, live.ignored);
    assert_same("outside", &ahead, &live);
}
