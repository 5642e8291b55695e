//! `host-sim eval --yaw yaw.csv --gt gt.csv [--imu imu.txt] [--plot FILE.png] [--json]`, or
//! `host-sim eval --yaw yaw.csv --imu rec.aedat4 ...` with the gyro as the reference.

use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::eval::{
    self, EstimateReader, EvalOptions, Evaluator, GyroYawReader, Resample, SampleSource,
    TruthReader,
};

/// Arguments of `host-sim eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Estimated yaw rate: CSV with a header, `t_s,yaw_rate_rad_s` (or `t_s,yaw_norm` for the
    /// normalized readout), optionally `flags` (`host-sim run`'s status bits); other columns are
    /// ignored. RMSE, correlation, ARRE and heading use the values as they are, flagged or not;
    /// with flags, the report adds the share flagged "no evidence" (overall and while
    /// |gt| >= 0.05 rad/s) and the RMS output with those samples as 0 (a static camera's figure).
    /// `-`: standard input (`host-sim run REC --out - | host-sim eval --yaw - --gt ...`).
    #[arg(long, value_parser = super::input_path)]
    pub yaw: PathBuf,
    /// Ground truth: `gt.csv` (`t_s,...,wy,...`), any ground-truth file the readers know (ECD
    /// `groundtruth.txt`, MVSEC `*_gt.hdf5`), or a CSV with `t_s,yaw_rate` columns. Without
    /// it, the gyro (`--imu`) is the reference: a recording with an IMU and no ground truth.
    #[arg(long, required_unless_present = "imu")]
    pub gt: Option<PathBuf>,
    /// Gyro to evaluate alongside the estimate (`imu.txt` `t ax ay az gx gy gz`, AEDAT4, MVSEC
    /// HDF5), or, without `--gt`, to evaluate the estimate against.
    #[arg(long)]
    pub imu: Option<PathBuf>,
    /// Draw estimate, ground truth (and gyro) yaw rate and integrated heading into this PNG.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print the figures as JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// How the estimate is evaluated at the ground-truth times.
    #[arg(long, value_enum, default_value = "hold")]
    pub resample: Resample,
}

/// Runs `host-sim eval`: the estimate, the ground truth and the gyro are all streamed in
/// chunks (constant memory whatever their lengths, see [`Evaluator`]); nothing is written or
/// printed before the whole of them has been read and checked.
pub fn run(args: Args) -> anyhow::Result<()> {
    // What the estimate is compared with: the ground truth, or without it the gyro.
    let reference: &Path = args
        .gt
        .as_deref()
        .or(args.imu.as_deref())
        .context("--gt or --imu is needed: the yaw rate to compare the estimate with")?;
    if let Some(p) = &args.plot {
        let mut inputs = vec![args.yaw.as_path(), reference];
        inputs.extend(args.imu.as_deref());
        crate::output::check_distinct(&inputs, &[("--plot", p)])?;
    }
    // The estimate's header first: a file that is not an estimate is the first error.
    let mut est = EstimateReader::open(&args.yaw)?;
    let (truth, gyro): (Box<dyn SampleSource>, _) = match &args.gt {
        Some(gt) => {
            let truth = Box::new(TruthReader::open(gt)?);
            let gyro = match args.imu.as_deref() {
                Some(p) => Some(Box::new(GyroYawReader::open(p)?) as Box<dyn SampleSource>),
                None => None,
            };
            (truth, gyro)
        }
        None => (Box::new(GyroYawReader::open(reference)?), None),
    };
    let opts = EvalOptions {
        resample: args.resample,
        plot_points: args.plot.is_some(),
        ..EvalOptions::default()
    };
    let context = format!("{} vs {}", args.yaw.display(), reference.display());
    let mut ev = Evaluator::from_sources(est.kind(), truth, gyro, &opts)
        .with_context(|| context.clone())?
        .labelled(context);
    let mut chunk = Vec::with_capacity(eval::CHUNK);
    let mut flags = Vec::with_capacity(eval::CHUNK);
    let flagged = est.has_flags();
    while est.next_chunk_flagged(&mut chunk, &mut flags)? {
        for (&(t, v), &f) in chunk.iter().zip(&flags) {
            if flagged {
                ev.push_flagged(t, v, f)?;
            } else {
                ev.push(t, v)?;
            }
        }
    }
    let report = ev.finish(est.missing())?;
    // The figure before the text: a figure that cannot be written is the only output.
    if let Some(p) = &args.plot {
        let title = format!(
            "{} vs {}",
            args.yaw.file_name().map_or_else(
                || args.yaw.display().to_string(),
                |n| n.to_string_lossy().into()
            ),
            reference.display()
        );
        eval::plot::plot_report(&report, &title, p)?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        if args.gt.is_none() {
            println!(
                "reference: the gyro of {} (no ground truth given; \"ground truth\" below is the gyro)",
                reference.display()
            );
        }
        print!("{}", report.to_text());
        if let Some(p) = &args.plot {
            println!("plot: {}", p.display());
        }
    }
    Ok(())
}
