//! `host-sim demo`: the host path end to end on a built-in scene. Renders the default synthetic
//! sequence (urban texture, sinusoidal yaw, DAVIS346 geometry, seed 1), runs it through the
//! fixed-point pipeline, and evaluates the yaw rate against the ground truth and the simulated
//! gyro, with plots.

use std::path::PathBuf;

use anyhow::{Context, Result};

use crate::eval::{self, EstimateKind, EvalOptions, Series};
use crate::output::StagedDir;
use crate::pipeline::{run_pipeline, write_yaw_csv, RunOptions};
use crate::synth::{self, SynthConfig};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output folder (scene files, yaw.csv, eval.png).
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// Seed of the scene.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Duration of the scene (s).
    #[arg(long, default_value_t = 4.0)]
    pub duration: f64,
}

/// Runs `host-sim demo`. Every output is written into a staging folder inside `--out` and
/// moved into `--out` together at the end: a failure (a figure that cannot be drawn, a name
/// taken by a folder) leaves none of them.
pub fn run(args: Args) -> Result<()> {
    let staged = StagedDir::create(&args.out)?;
    let dir = staged.path();
    let cfg = SynthConfig {
        seed: args.seed,
        duration_s: args.duration,
        ..SynthConfig::default()
    };
    eprintln!(
        "demo: rendering the default scene ({} s, seed {})",
        args.duration, args.seed
    );
    let seq = synth::generate(&cfg)?;
    synth::write_sequence(&seq, dir)?;
    let gt = Series::from_pairs(&seq.gt_yaw_rate());
    let gyro = Series::from_pairs(&seq.gyro_yaw_rate());
    let rec = seq.into_recording();
    let yaw_csv = args.out.join("yaw.csv");
    let out = run_pipeline(&RunOptions::default(), &rec)?;
    write_yaw_csv(&dir.join("yaw.csv"), &out.samples, false)?;
    let report = eval::evaluate_samples(
        EstimateKind::RadPerSec,
        out.samples.iter().map(|s| (s.0, s.1)),
        0,
        &gt,
        Some(&gyro),
        &EvalOptions::default(),
    )?;
    let png = args.out.join("eval.png");
    eval::plot::plot_report(
        &report,
        "TDE yaw rate (fixed-point pipeline) vs ground truth and gyro",
        &dir.join("eval.png"),
    )
    .with_context(|| format!("cannot draw {}", png.display()))?;
    staged.commit()?;
    eprintln!(
        "demo: {} events, {} bursts decoded, {:.1} M events/s",
        out.events,
        out.outputs,
        out.events as f64 / out.seconds.max(1e-9) / 1e6
    );
    print!("{}", report.to_text());
    println!("wrote {} and {}", yaw_csv.display(), png.display());
    Ok(())
}
