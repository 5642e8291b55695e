//! `host-sim eval --yaw yaw.csv --gt gt.csv [--imu imu.txt] [--plot FILE.png] [--json]`.

use std::path::PathBuf;

use anyhow::Context;

use crate::eval::{self, EvalOptions, Resample};

/// Arguments of `host-sim eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Estimated yaw rate: CSV with a header, `t_s,yaw_rate_rad_s` (or `t_s,yaw_norm` for the
    /// normalized readout); extra columns are ignored.
    #[arg(long)]
    pub yaw: PathBuf,
    /// Ground truth: `gt.csv` (`t_s,...,wy,...`), any ground-truth file the readers know (ECD
    /// `groundtruth.txt`, MVSEC `*_gt.hdf5`), or a CSV with `t_s,yaw_rate` columns.
    #[arg(long)]
    pub gt: PathBuf,
    /// Gyro to evaluate alongside (`imu.txt` `t ax ay az gx gy gz`, AEDAT4, MVSEC HDF5).
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

/// Runs `host-sim eval`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(p) = &args.plot {
        let mut inputs = vec![args.yaw.as_path(), args.gt.as_path()];
        inputs.extend(args.imu.as_deref());
        crate::output::check_distinct(&inputs, &[("--plot", p)])?;
    }
    let est = eval::read_estimate(&args.yaw)?;
    let gt = eval::read_gt(&args.gt)?;
    let gyro = args.imu.as_deref().map(eval::read_gyro_yaw).transpose()?;
    let opts = EvalOptions {
        resample: args.resample,
        ..EvalOptions::default()
    };
    let report = eval::evaluate(&est, &gt, gyro.as_ref(), &opts)
        .with_context(|| format!("{} vs {}", args.yaw.display(), args.gt.display()))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", report.to_text());
    }
    if let Some(p) = &args.plot {
        let title = format!(
            "{} vs {}",
            args.yaw.file_name().map_or_else(
                || args.yaw.display().to_string(),
                |n| n.to_string_lossy().into()
            ),
            args.gt.display()
        );
        eval::plot::plot_report(&report, &title, p)?;
        if !args.json {
            println!("plot: {}", p.display());
        }
    }
    Ok(())
}
