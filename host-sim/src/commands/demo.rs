//! `host-sim demo`: the host path end to end on a built-in scene. Renders the default synthetic
//! sequence (urban texture, sinusoidal yaw, DAVIS346 geometry, seed 1), runs it through the
//! fixed-point pipeline, and evaluates the yaw rate against the ground truth and the simulated
//! gyro, with plots.

use std::path::PathBuf;

use anyhow::{Context, Result};

use crate::commands::run::{run_pipeline, Args as RunArgs};
use crate::eval::{self, Estimate, EstimateKind, EvalOptions, Series};
use crate::formats::{self, Format, Recording};
use crate::synth::{self, SynthConfig};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output folder (scene files, yaw.csv, yaw.png, eval.png).
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// Seed of the scene.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Duration of the scene (s).
    #[arg(long, default_value_t = 4.0)]
    pub duration: f64,
}

pub fn run(args: Args) -> Result<()> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
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
    synth::write_sequence(&seq, &args.out)?;
    let i = seq.intrinsics;
    let gt = Series::from_pairs(&seq.gt_yaw_rate());
    let gyro = Series::from_pairs(&seq.gyro_yaw_rate());
    let rec = Recording {
        events: seq.events,
        width: Some(i.width),
        height: Some(i.height),
        intrinsics: Some(formats::Intrinsics::from(i)),
        gyro: None,
        format: Format::EcdText,
    };
    let yaw_csv = args.out.join("yaw.csv");
    let run_args = RunArgs::new(args.out.join("events.txt"), yaw_csv.clone());
    let out = run_pipeline(&run_args, &rec)?;
    crate::commands::run::write_yaw_csv(&yaw_csv, &out.samples, false)?;
    let est = Estimate {
        kind: EstimateKind::RadPerSec,
        series: Series::from_pairs(&out.samples.iter().map(|s| (s.0, s.1)).collect::<Vec<_>>()),
        missing: 0,
    };
    let report = eval::evaluate(&est, &gt, Some(&gyro), &EvalOptions::default())?;
    let png = args.out.join("eval.png");
    eval::plot::plot_report(
        &report,
        "TDE yaw rate (fixed-point pipeline) vs ground truth and gyro",
        &png,
    )?;
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
