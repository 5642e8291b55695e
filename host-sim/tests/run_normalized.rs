//! The paper's normalized readout: the fixed-point network with its spikes follows the f64
//! oracle network (the paper's method) on a small generated scene.

use host_sim::eval::metrics::pearson;
use host_sim::pipeline::{run_pipeline, Model, ReadoutKind, RunOptions};
use host_sim::synth::{self, Intrinsics, MotionSpec, SynthConfig};

#[test]
fn fixed_normalized_readout_follows_the_float_oracle_network() {
    let cfg = SynthConfig {
        intrinsics: Intrinsics {
            width: 64,
            height: 24,
            fx: 60.0,
            fy: 60.0,
            cx: 31.5,
            cy: 11.5,
        },
        duration_s: 1.0,
        motion_spec: Some(MotionSpec::constant_yaw(0.8)),
        ..SynthConfig::default()
    };
    let seq = synth::generate(&cfg).expect("scene");
    assert!(seq.events.len() > 5_000, "{} events", seq.events.len());
    let rec = seq.into_recording();
    let args = |model| RunOptions {
        readout: ReadoutKind::Normalized,
        model,
        ..RunOptions::default()
    };
    let fixed = run_pipeline(&args(Model::Fixed), &rec).expect("fixed");
    let float = run_pipeline(&args(Model::Float), &rec).expect("float");
    let n = fixed.samples.len().min(float.samples.len());
    assert!(n > 900, "{n} samples");
    let a: Vec<f64> = fixed.samples[..n].iter().map(|s| s.1).collect();
    let b: Vec<f64> = float.samples[..n].iter().map(|s| s.1).collect();
    let corr = pearson(&a, &b);
    let spikes_ratio = fixed.outputs as f64 / float.outputs as f64;
    eprintln!(
        "normalized readout: fixed vs float correlation {corr:.4}; spikes {} vs {}",
        fixed.outputs, float.outputs
    );
    assert!(corr >= 0.99, "correlation {corr}");
    assert!(
        (spikes_ratio - 1.0).abs() < 0.01,
        "spikes {} vs {}",
        fixed.outputs,
        float.outputs
    );
    // Turning right moves the scene left: right-to-left units dominate, the readout is positive.
    assert!(a[n / 2..].iter().sum::<f64>() > 0.0);
}
