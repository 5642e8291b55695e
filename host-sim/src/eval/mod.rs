//! Evaluation of an estimated yaw rate against ground truth (`host-sim eval`).
//!
//! Method (the same for the estimate and for the gyro):
//! 1. The evaluation grid is the ground-truth times that lie within the estimate's time span
//!    (first to last estimate sample).
//! 2. The estimate is resampled at those times, by default with a zero-order hold (the latest
//!    estimate at or before each time, what a causal consumer sees; [`Resample::Linear`] is the
//!    alternative). The gyro is always linearly interpolated (it is a sampled continuous signal).
//! 3. Figures on that grid: RMSE (rad/s), RMSE / peak |gt|, Pearson correlation, mean error
//!    (bias), ARRE (model.md, yaw only: mean over consecutive 50 ms windows of
//!    `|d psi_est - d psi_gt|`, `psi` the trapezoidal integral of the rate on the grid), and the
//!    final heading error (`psi_est - psi_gt` at the end of the grid).
//!
//! A `normalized` estimate (the paper's readout, unitless) cannot be compared in rad/s: its
//! correlation is reported as is, and every other figure is computed after a least-squares
//! scale fit to the ground truth (an oracle step, reported as `scale`).

pub mod metrics;
pub mod plot;

use std::path::Path;

use anyhow::{bail, ensure, Context, Result};
use serde::Serialize;

pub use metrics::Resample;

/// ARRE window length, s (the 50 ms steps).
pub const ARRE_STEP_S: f64 = 0.05;

/// A sampled signal: times (s, non-decreasing) and values.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Series {
    /// Sample times, s.
    pub t: Vec<f64>,
    /// Values (rad/s for rates).
    pub v: Vec<f64>,
}

impl Series {
    /// From `(t, v)` pairs.
    pub fn from_pairs(pairs: &[(f64, f64)]) -> Self {
        Self {
            t: pairs.iter().map(|p| p.0).collect(),
            v: pairs.iter().map(|p| p.1).collect(),
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True without samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

/// What the estimate's values mean.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum EstimateKind {
    /// Yaw rate in rad/s (`yaw_rate_rad_s` column).
    RadPerSec,
    /// The paper's normalized readout, unitless (`yaw_norm` column).
    Normalized,
}

/// An estimated yaw-rate series.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// Units of the values.
    pub kind: EstimateKind,
    /// The samples with a finite value.
    pub series: Series,
    /// Rows whose value was empty or not finite (skipped; e.g. "no events" outputs).
    pub missing: usize,
}

/// Reads `t_s,yaw_rate_rad_s` (or `t_s,yaw_norm`) CSV with a header line; other columns are
/// ignored. Rows with an empty or non-finite value are skipped and counted in `missing`.
pub fn read_estimate(path: &Path) -> Result<Estimate> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    parse_estimate(&text).with_context(|| format!("{}", path.display()))
}

/// [`read_estimate`] on text.
pub fn parse_estimate(text: &str) -> Result<Estimate> {
    let (column, series, missing) = parse_csv_series(text, &["yaw_rate_rad_s", "yaw_norm"])?;
    let kind = if column == "yaw_norm" {
        EstimateKind::Normalized
    } else {
        EstimateKind::RadPerSec
    };
    Ok(Estimate {
        kind,
        series,
        missing,
    })
}

/// Parses a CSV with a header holding `t_s` and the first of `columns` present. Returns the
/// column used, the samples with a finite value and the number of rows without one (empty,
/// `nan`, `inf`). Times must not decrease.
fn parse_csv_series(text: &str, columns: &[&str]) -> Result<(String, Series, usize)> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let Some((_, header)) = lines.next() else {
        bail!("empty file (expected a header `t_s,{}`)", columns[0]);
    };
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    let it = cols
        .iter()
        .position(|&c| c == "t_s")
        .context("no `t_s` column in the header")?;
    let Some((iv, name)) = columns
        .iter()
        .find_map(|&name| cols.iter().position(|&c| c == name).map(|i| (i, name)))
    else {
        bail!(
            "no `{}` column in the header `{header}`",
            columns.join("` or `")
        );
    };
    let mut series = Series::default();
    let mut missing = 0;
    for (ln, line) in lines {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let field = |i: usize| {
            fields
                .get(i)
                .copied()
                .with_context(|| format!("line {}: too few columns", ln + 1))
        };
        let t: f64 = field(it)?
            .parse()
            .with_context(|| format!("line {}: bad time", ln + 1))?;
        ensure!(t.is_finite(), "line {}: time is not finite", ln + 1);
        if let Some(&last) = series.t.last() {
            ensure!(t >= last, "line {}: time goes backwards", ln + 1);
        }
        let raw = field(iv)?;
        match raw.parse::<f64>() {
            Ok(v) if v.is_finite() => {
                series.t.push(t);
                series.v.push(v);
            }
            Ok(_) => missing += 1,
            Err(_) if raw.is_empty() => missing += 1,
            Err(_) => bail!("line {}: bad value `{raw}`", ln + 1),
        }
    }
    ensure!(!series.is_empty(), "no samples with a value");
    Ok((name.to_string(), series, missing))
}

/// Ground-truth yaw rate (rad/s) from any file `formats::read_ground_truth` understands, or
/// else a CSV with `t_s` and `yaw_rate` (or `yaw_rate_rad_s`) columns.
pub fn read_gt(path: &Path) -> Result<Series> {
    let gt = match crate::formats::read_ground_truth(path) {
        Ok(gt) => gt,
        Err(e) => {
            let simple = std::fs::read_to_string(path)
                .ok()
                .and_then(|text| parse_csv_series(&text, &["yaw_rate", "yaw_rate_rad_s"]).ok());
            return match simple {
                Some((_, series, _)) => {
                    check_times(&series, "ground-truth")
                        .with_context(|| path.display().to_string())?;
                    Ok(series)
                }
                None => Err(e),
            };
        }
    };
    ensure!(
        !gt.is_empty(),
        "{}: no ground-truth samples",
        path.display()
    );
    let series = Series {
        t: gt.iter().map(|g| g.t_s).collect(),
        v: gt.iter().map(|g| g.yaw_rate_rad_s).collect(),
    };
    check_times(&series, "ground-truth").with_context(|| path.display().to_string())?;
    Ok(series)
}

/// Checks that a signal's times are finite, never go back and span some time: ground truth or
/// gyro that does not is refused rather than integrated into a meaningless heading.
fn check_times(s: &Series, what: &str) -> Result<()> {
    for (i, w) in s.t.windows(2).enumerate() {
        if let [a, b] = *w {
            ensure!(
                a.is_finite() && b.is_finite(),
                "{what} sample {} has a time that is not finite",
                i + 1
            );
            ensure!(
                b >= a,
                "{what} time goes backwards at sample {} ({b} s after {a} s)",
                i + 2
            );
        }
    }
    let (first, last) = (s.t.first().copied(), s.t.last().copied());
    if let (Some(a), Some(b)) = (first, last) {
        ensure!(
            b > a,
            "all {} {what} samples are at one time ({a} s): no time span to evaluate over",
            s.len()
        );
    }
    Ok(())
}

/// Gyro yaw rate `wy` (rad/s) from any file `formats::read_gyro` understands.
pub fn read_gyro_yaw(path: &Path) -> Result<Series> {
    let g = crate::formats::read_gyro(path)?;
    ensure!(!g.is_empty(), "{}: no gyro samples", path.display());
    let series = Series {
        t: g.iter().map(|s| s.t_s).collect(),
        v: g.iter().map(|s| s.wy).collect(),
    };
    check_times(&series, "gyro").with_context(|| path.display().to_string())?;
    Ok(series)
}

/// Options of [`evaluate`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EvalOptions {
    /// How the estimate is resampled at the ground-truth times.
    pub resample: Resample,
    /// ARRE window, s.
    pub arre_step_s: f64,
}

impl Default for EvalOptions {
    fn default() -> Self {
        Self {
            resample: Resample::Hold,
            arre_step_s: ARRE_STEP_S,
        }
    }
}

/// The figures for one signal against the ground truth.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Metrics {
    /// Samples on the evaluation grid.
    pub n: usize,
    /// RMSE, rad/s.
    pub rmse_rad_s: f64,
    /// RMSE / peak |gt yaw rate|.
    pub rmse_rel_peak: f64,
    /// Pearson correlation with the ground truth.
    pub correlation: f64,
    /// Mean error (signal - gt), rad/s.
    pub mean_error_rad_s: f64,
    /// ARRE over `arre_step_s` windows, rad.
    pub arre_rad: f64,
    /// Integrated heading of the signal at the end of the grid, rad.
    pub heading_rad: f64,
    /// Final heading error (signal - gt), rad.
    pub final_heading_error_rad: f64,
    /// Least-squares scale applied before these figures (normalized estimates only).
    pub scale: Option<f64>,
}

/// The estimate (and gyro) resampled on the evaluation grid, for plotting.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Aligned {
    /// Grid times, s.
    pub t: Vec<f64>,
    /// Ground-truth yaw rate, rad/s.
    pub gt: Vec<f64>,
    /// Estimate, rad/s (scaled by the least-squares fit for a normalized estimate).
    pub est: Vec<f64>,
    /// Gyro yaw rate, rad/s.
    pub gyro: Option<Vec<f64>>,
}

/// The result of an evaluation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    /// Units of the estimate.
    pub kind: EstimateKind,
    /// Resampling of the estimate.
    pub resample: Resample,
    /// Evaluation window start, s.
    pub t_start_s: f64,
    /// Evaluation window end, s.
    pub t_end_s: f64,
    /// ARRE window, s.
    pub arre_step_s: f64,
    /// Peak |gt yaw rate| over the window, rad/s.
    pub peak_gt_rad_s: f64,
    /// Integrated ground-truth heading at the end of the window, rad.
    pub gt_heading_rad: f64,
    /// Estimate rows skipped for a missing value.
    pub missing_estimates: usize,
    /// Figures of the estimate.
    pub estimate: Metrics,
    /// Figures of the gyro, when given.
    pub gyro: Option<Metrics>,
    /// The data on the grid (not serialized).
    #[serde(skip)]
    pub aligned: Aligned,
}

/// Figures of `sig` against `gt` on grid `t`.
fn metrics_on(
    t: &[f64],
    sig: &[f64],
    gt: &[f64],
    peak: f64,
    step: f64,
    scale: Option<f64>,
) -> Metrics {
    let rmse = metrics::rmse(sig, gt);
    let heading = metrics::integrate(t, sig).last().copied().unwrap_or(0.0);
    let gt_heading = metrics::integrate(t, gt).last().copied().unwrap_or(0.0);
    Metrics {
        n: t.len(),
        rmse_rad_s: rmse,
        rmse_rel_peak: if peak > 0.0 { rmse / peak } else { f64::NAN },
        correlation: metrics::pearson(sig, gt),
        mean_error_rad_s: metrics::mean_error(sig, gt),
        arre_rad: metrics::arre(t, sig, gt, step),
        heading_rad: heading,
        final_heading_error_rad: heading - gt_heading,
        scale,
    }
}

/// Evaluates `est` (and optionally the gyro yaw rate) against the ground-truth yaw rate `gt`.
/// Errors when the estimate and the ground truth do not overlap in time.
pub fn evaluate(
    est: &Estimate,
    gt: &Series,
    gyro: Option<&Series>,
    opts: &EvalOptions,
) -> Result<Report> {
    let e = &est.series;
    let (Some(&e0), Some(&e1)) = (e.t.first(), e.t.last()) else {
        bail!("the estimate has no samples");
    };
    let keep: Vec<usize> = (0..gt.len())
        .filter(|&i| gt.t[i] >= e0 - metrics::T_EPS && gt.t[i] <= e1 + metrics::T_EPS)
        .collect();
    ensure!(
        keep.len() >= 2,
        "the estimate ({e0:.3}-{e1:.3} s) and the ground truth ({:.3}-{:.3} s) do not overlap",
        gt.t.first().copied().unwrap_or(f64::NAN),
        gt.t.last().copied().unwrap_or(f64::NAN)
    );
    let t: Vec<f64> = keep.iter().map(|&i| gt.t[i]).collect();
    let g: Vec<f64> = keep.iter().map(|&i| gt.v[i]).collect();
    let mut x: Vec<f64> = metrics::resample(e, &t, opts.resample)
        .into_iter()
        .map(|v| v.unwrap_or(0.0))
        .collect();
    let peak = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let step = opts.arre_step_s;
    let correlation = metrics::pearson(&x, &g);
    let scale = match est.kind {
        EstimateKind::RadPerSec => None,
        EstimateKind::Normalized => {
            let k = metrics::scale_fit(&x, &g);
            let k = if k.is_finite() { k } else { 0.0 };
            x.iter_mut().for_each(|v| *v *= k);
            Some(k)
        }
    };
    let mut estimate = metrics_on(&t, &x, &g, peak, step, scale);
    estimate.correlation = correlation;
    if let Some(gs) = gyro {
        let (g0, g1) = (
            gs.t.first().copied().unwrap_or(f64::NAN),
            gs.t.last().copied().unwrap_or(f64::NAN),
        );
        let (w0, w1) = (
            t.first().copied().unwrap_or(0.0),
            t.last().copied().unwrap_or(0.0),
        );
        ensure!(
            g0 < w1 && g1 > w0,
            "the gyro ({g0:.3}-{g1:.3} s) and the evaluation window ({w0:.3}-{w1:.3} s) do not overlap: are they on the same clock?"
        );
    }
    // The gyro, linearly interpolated; held at its first/last value outside its own span.
    let gyro_aligned = gyro.map(|gs| {
        let first = gs.v.first().copied().unwrap_or(0.0);
        let last = gs.v.last().copied().unwrap_or(0.0);
        let t0 = gs.t.first().copied().unwrap_or(0.0);
        metrics::resample(gs, &t, Resample::Linear)
            .into_iter()
            .zip(&t)
            .map(|(v, &ti)| v.unwrap_or(if ti < t0 { first } else { last }))
            .collect::<Vec<f64>>()
    });
    let gyro_metrics = gyro_aligned
        .as_ref()
        .map(|gy| metrics_on(&t, gy, &g, peak, step, None));
    Ok(Report {
        kind: est.kind,
        resample: opts.resample,
        t_start_s: t[0],
        t_end_s: t[t.len() - 1],
        arre_step_s: step,
        peak_gt_rad_s: peak,
        gt_heading_rad: metrics::integrate(&t, &g).last().copied().unwrap_or(0.0),
        missing_estimates: est.missing,
        estimate,
        gyro: gyro_metrics,
        aligned: Aligned {
            t,
            gt: g,
            est: x,
            gyro: gyro_aligned,
        },
    })
}

impl Report {
    /// The human-readable summary printed by `host-sim eval`.
    pub fn to_text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "window {:.3}-{:.3} s ({} ground-truth samples), peak |yaw rate| {:.4} rad/s, estimate resampled by {}",
            self.t_start_s,
            self.t_end_s,
            self.estimate.n,
            self.peak_gt_rad_s,
            match self.resample {
                Resample::Hold => "zero-order hold",
                Resample::Linear => "linear interpolation",
            }
        );
        if self.missing_estimates > 0 {
            let _ = writeln!(
                s,
                "{} estimate rows without a value were skipped (held over)",
                self.missing_estimates
            );
        }
        if let Some(k) = self.estimate.scale {
            let _ = writeln!(
                s,
                "estimate is the normalized readout (yaw_norm, unitless): correlation as is; RMSE, ARRE and heading after a least-squares scale fit to the ground truth (x {k:.4} rad/s, an oracle step)"
            );
        }
        let mut block = |name: &str, m: &Metrics| {
            let _ = writeln!(s, "{name}:");
            let fit = if m.scale.is_some() {
                " (after scale fit)"
            } else {
                ""
            };
            // `fitted`: the figure depends on the scale (so carries the fit label).
            let mut row = |label: &str, value: String, fitted: bool| {
                let note = if fitted { fit } else { "" };
                let _ = writeln!(s, "  {label:<21}{value}{note}");
            };
            row("RMSE", format!("{:.4} rad/s", m.rmse_rad_s), true);
            row(
                "RMSE / peak",
                format!("{:.1} %", 100.0 * m.rmse_rel_peak),
                true,
            );
            row("correlation", format!("{:.4}", m.correlation), false);
            row(
                "mean error",
                format!("{:+.4} rad/s", m.mean_error_rad_s),
                true,
            );
            row(
                &format!("ARRE ({:.0} ms)", self.arre_step_s * 1e3),
                format!("{:.5} rad ({:.3} deg)", m.arre_rad, m.arre_rad.to_degrees()),
                true,
            );
            row(
                "final heading error",
                format!(
                    "{:+.4} rad ({:+.2} deg; integrated {:+.4} vs gt {:+.4} rad)",
                    m.final_heading_error_rad,
                    m.final_heading_error_rad.to_degrees(),
                    m.heading_rad,
                    self.gt_heading_rad
                ),
                true,
            );
        };
        block("estimate", &self.estimate);
        if let Some(g) = &self.gyro {
            block("gyro", g);
        }
        s
    }
}
