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
//!
//! Memory: all three inputs are streamed, so inputs of any length cost constant memory. The
//! estimate is read in chunks ([`EstimateReader`]) and pushed into the [`Evaluator`], which
//! pulls the ground truth and the gyro ([`SampleSource`]: [`TruthReader`], [`GyroYawReader`],
//! read a chunk at a time by [`crate::formats::GroundTruthReader`] and
//! [`crate::formats::GyroReader`]) only as far as the estimate has come, merging the three in
//! time: each ground-truth time is placed on the grid as soon as the estimate has passed it, with
//! the gyro interpolated there, and the figures accumulated with [`running::Running`]. Their
//! times are checked as they come ([`TimeCheck`]); at the end the rest of both is read through,
//! so that a fault anywhere in them is still an error. The figure keeps a decimated copy of the
//! grid ([`Decimated`]). A normalized estimate is evaluated in two passes over the grid (the
//! scale fit first, then the figures after it), the grid (time, ground truth, estimate) kept in
//! an unlinked scratch file (24 bytes a point) between them.

mod evaluator;
mod inputs;
pub mod metrics;
pub mod plot;
pub mod running;

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use anyhow::{bail, ensure, Context, Result};
use serde::Serialize;

use crate::samples::Decimated;
pub use evaluator::Evaluator;
pub use inputs::{GyroYawReader, SampleSource, SeriesSource, TimeCheck, TruthReader};
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

/// Longest line the CSV readers accept, bytes: a file without line breaks is refused rather
/// than read whole into memory.
pub const MAX_LINE: usize = 1 << 20;

/// Samples per chunk of [`EstimateReader::next_chunk`].
pub const CHUNK: usize = 1 << 13;

/// A CSV with a header holding `t_s` and one of the value columns, read line by line: the
/// samples with a finite value, the rows without one counted (empty, `nan`, `inf`). Times must
/// not decrease.
struct CsvSeries<R> {
    input: R,
    line: String,
    /// Number of the line in `line` (1-based, blank lines counted).
    ln: usize,
    it: usize,
    iv: usize,
    column: String,
    /// Index of the optional `flags` column.
    iflags: Option<usize>,
    /// Flags of the latest sample returned (0 without a `flags` column).
    flags: u8,
    last_t: Option<f64>,
    missing: usize,
    samples: u64,
}

impl<R: BufRead> CsvSeries<R> {
    /// Reads the header; `columns` are the value columns accepted, the first present is used.
    fn new(input: R, columns: &[&str]) -> Result<Self> {
        let mut csv = Self {
            input,
            line: String::new(),
            ln: 0,
            it: 0,
            iv: 0,
            column: String::new(),
            iflags: None,
            flags: 0,
            last_t: None,
            missing: 0,
            samples: 0,
        };
        if !csv.next_line()? {
            bail!(
                "empty file (expected a header `t_s,{}`)",
                columns.first().copied().unwrap_or("value")
            );
        }
        let header = csv.line.trim_end_matches(['\n', '\r']);
        let cols: Vec<&str> = header.split(',').map(str::trim).collect();
        csv.it = cols
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
        csv.iv = iv;
        csv.column = name.to_string();
        csv.iflags = cols.iter().position(|&c| c == "flags");
        Ok(csv)
    }

    /// Reads the next line that is not blank into `self.line`; false at the end.
    fn next_line(&mut self) -> Result<bool> {
        loop {
            self.line.clear();
            let n = (&mut self.input)
                .take(MAX_LINE as u64 + 1)
                .read_line(&mut self.line)
                .with_context(|| format!("line {}: cannot read", self.ln + 1))?;
            if n == 0 {
                return Ok(false);
            }
            self.ln += 1;
            ensure!(
                self.line.len() <= MAX_LINE || self.line.ends_with('\n'),
                "line {}: longer than {MAX_LINE} bytes",
                self.ln
            );
            if !self.line.trim().is_empty() {
                return Ok(true);
            }
        }
    }

    /// The next sample with a finite value; `None` at the end.
    fn next_sample(&mut self) -> Result<Option<(f64, f64)>> {
        while self.next_line()? {
            let ln = self.ln;
            let (mut ft, mut fv, mut ff) = (None, None, None);
            let last_col = self.it.max(self.iv).max(self.iflags.unwrap_or(0));
            for (i, f) in self.line.split(',').enumerate() {
                if i == self.it {
                    ft = Some(f.trim());
                }
                if i == self.iv {
                    fv = Some(f.trim());
                }
                if Some(i) == self.iflags {
                    ff = Some(f.trim());
                }
                if i >= last_col {
                    break;
                }
            }
            let too_few = || format!("line {ln}: too few columns");
            let t: f64 = ft
                .with_context(too_few)?
                .parse()
                .with_context(|| format!("line {ln}: bad time"))?;
            ensure!(t.is_finite(), "line {ln}: time is not finite");
            if let Some(last) = self.last_t {
                ensure!(t >= last, "line {ln}: time goes backwards");
            }
            let raw = fv.with_context(too_few)?;
            let flags = match (self.iflags, ff) {
                (None, _) => 0,
                (Some(_), None) => bail!("line {ln}: too few columns"),
                (Some(_), Some("")) => 0,
                (Some(_), Some(f)) => f
                    .parse::<u8>()
                    .with_context(|| format!("line {ln}: bad flags `{f}`"))?,
            };
            match raw.parse::<f64>() {
                Ok(v) if v.is_finite() => {
                    self.last_t = Some(t);
                    self.samples += 1;
                    self.flags = flags;
                    return Ok(Some((t, v)));
                }
                Ok(_) => self.missing += 1,
                Err(_) if raw.is_empty() => self.missing += 1,
                Err(_) => bail!("line {ln}: bad value `{raw}`"),
            }
        }
        ensure!(self.samples > 0, "no samples with a value");
        Ok(None)
    }

    /// Reads up to [`CHUNK`] samples into `out` (cleared first); false when there are none
    /// left.
    fn next_chunk(&mut self, out: &mut Vec<(f64, f64)>) -> Result<bool> {
        out.clear();
        while out.len() < CHUNK {
            match self.next_sample()? {
                Some(s) => out.push(s),
                None => break,
            }
        }
        Ok(!out.is_empty())
    }

    /// Reads up to [`CHUNK`] samples into `out` and their flags into `flags` (both cleared
    /// first); false when there are none left.
    fn next_chunk_flagged(
        &mut self,
        out: &mut Vec<(f64, f64)>,
        flags: &mut Vec<u8>,
    ) -> Result<bool> {
        out.clear();
        flags.clear();
        while out.len() < CHUNK {
            match self.next_sample()? {
                Some(s) => {
                    out.push(s);
                    flags.push(self.flags);
                }
                None => break,
            }
        }
        Ok(!out.is_empty())
    }

    /// All the remaining samples.
    fn into_series(mut self) -> Result<(String, Series, usize)> {
        let mut series = Series::default();
        while let Some((t, v)) = self.next_sample()? {
            series.t.push(t);
            series.v.push(v);
        }
        Ok((self.column, series, self.missing))
    }
}

/// An estimate CSV (`t_s,yaw_rate_rad_s` or `t_s,yaw_norm` with a header line; other columns
/// are ignored) read in chunks, in constant memory: the input of a streaming evaluation
/// ([`Evaluator`]). Rows with an empty or non-finite value are skipped and counted.
pub struct EstimateReader<'a> {
    csv: CsvSeries<Box<dyn BufRead + 'a>>,
    kind: EstimateKind,
    /// The file, named in errors.
    name: Option<String>,
}

impl<'a> EstimateReader<'a> {
    /// Opens `path` and reads its header.
    ///
    /// # Errors
    /// When the file cannot be opened or its header lacks the columns.
    pub fn open(path: &Path) -> Result<EstimateReader<'static>> {
        let file = File::open(path).with_context(|| format!("cannot read {}", path.display()))?;
        let input: Box<dyn BufRead> = Box::new(BufReader::with_capacity(1 << 16, file));
        let name = path.display().to_string();
        EstimateReader::new(input, Some(name.clone())).with_context(|| name)
    }

    /// Reads the header from `input`.
    ///
    /// # Errors
    /// When the header lacks the columns.
    pub fn from_reader(input: impl BufRead + 'a) -> Result<Self> {
        Self::new(Box::new(input), None)
    }

    fn new(input: Box<dyn BufRead + 'a>, name: Option<String>) -> Result<Self> {
        let csv = CsvSeries::new(input, &["yaw_rate_rad_s", "yaw_norm"])?;
        let kind = if csv.column == "yaw_norm" {
            EstimateKind::Normalized
        } else {
            EstimateKind::RadPerSec
        };
        Ok(Self { csv, kind, name })
    }

    /// Units of the values.
    #[must_use]
    pub fn kind(&self) -> EstimateKind {
        self.kind
    }

    /// Rows without a value so far.
    #[must_use]
    pub fn missing(&self) -> usize {
        self.csv.missing
    }

    /// Reads up to [`CHUNK`] samples `(t_s, value)` with a finite value into `out` (cleared
    /// first); false at the end of the file.
    ///
    /// # Errors
    /// On a malformed row, a time going backwards, or when the file has no sample with a value.
    pub fn next_chunk(&mut self, out: &mut Vec<(f64, f64)>) -> Result<bool> {
        let r = self.csv.next_chunk(out);
        match &self.name {
            Some(name) => r.with_context(|| name.clone()),
            None => r,
        }
    }

    /// Whether the estimate has a `flags` column (`host-sim run`'s status bits,
    /// `core_nostd::flags`).
    #[must_use]
    pub fn has_flags(&self) -> bool {
        self.csv.iflags.is_some()
    }

    /// [`EstimateReader::next_chunk`], and each sample's flags into `flags` (0 without a
    /// `flags` column or where it is empty).
    ///
    /// # Errors
    /// As [`EstimateReader::next_chunk`], and on flags that are not a number from 0 to 255.
    pub fn next_chunk_flagged(
        &mut self,
        out: &mut Vec<(f64, f64)>,
        flags: &mut Vec<u8>,
    ) -> Result<bool> {
        let r = self.csv.next_chunk_flagged(out, flags);
        match &self.name {
            Some(name) => r.with_context(|| name.clone()),
            None => r,
        }
    }

    /// The whole estimate, in memory.
    ///
    /// # Errors
    /// As [`EstimateReader::next_chunk`].
    pub fn into_estimate(self) -> Result<Estimate> {
        let kind = self.kind;
        let r = self.csv.into_series();
        let (_, series, missing) = match self.name {
            Some(name) => r.with_context(|| name)?,
            None => r?,
        };
        Ok(Estimate {
            kind,
            series,
            missing,
        })
    }
}

/// Reads `t_s,yaw_rate_rad_s` (or `t_s,yaw_norm`) CSV with a header line into memory; other
/// columns are ignored. Rows with an empty or non-finite value are skipped and counted in
/// `missing`. [`EstimateReader`] reads the same in chunks.
pub fn read_estimate(path: &Path) -> Result<Estimate> {
    EstimateReader::open(path)?.into_estimate()
}

/// [`read_estimate`] on text.
pub fn parse_estimate(text: &str) -> Result<Estimate> {
    EstimateReader::from_reader(text.as_bytes())?.into_estimate()
}

/// Ground-truth yaw rate (rad/s) from any file `formats::read_ground_truth` understands, or
/// else a CSV with `t_s` and `yaw_rate` (or `yaw_rate_rad_s`) columns, in memory: the samples
/// of [`TruthReader`], with the checks of [`TimeCheck`].
///
/// # Errors
/// When the file cannot be read or is malformed, or its times are not finite, go back or span
/// no time.
pub fn read_gt(path: &Path) -> Result<Series> {
    inputs::collect(TruthReader::open(path)?, "ground-truth")
}

/// Gyro yaw rate `wy` (rad/s) from any file `formats::read_gyro` understands, in memory: the
/// samples of [`GyroYawReader`], with the checks of [`TimeCheck`].
///
/// # Errors
/// As [`read_gt`].
pub fn read_gyro_yaw(path: &Path) -> Result<Series> {
    inputs::collect(GyroYawReader::open(path)?, "gyro")
}

/// Options of [`evaluate`] and [`Evaluator`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EvalOptions {
    /// How the estimate is resampled at the ground-truth times.
    pub resample: Resample,
    /// ARRE window, s (finite, > 0).
    pub arre_step_s: f64,
    /// Keep the points of the figure ([`Report::plot`]; at most
    /// [`crate::samples::PLOT_POINTS`] per line).
    pub plot_points: bool,
}

impl Default for EvalOptions {
    fn default() -> Self {
        Self {
            resample: Resample::Hold,
            arre_step_s: ARRE_STEP_S,
            plot_points: true,
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

/// What an estimate's flags say over the evaluation grid (each grid point takes the flags of
/// the estimate sample whose value it holds). The figures of [`Metrics`] use the estimate's
/// values as they are, flagged or not; these say how much of it a consumer that drops
/// [`core_nostd::flags::NO_EVIDENCE`] samples would have.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FlagFigures {
    /// Share of the grid flagged "no evidence".
    pub no_evidence_share: f64,
    /// Share flagged "no evidence" among the grid points where |ground truth| >=
    /// [`TURNING_RAD_S`] (NaN when there are none).
    pub no_evidence_while_turning: f64,
    /// RMS of the estimate with the samples flagged "no evidence" counted as 0, rad/s: what a
    /// static camera's output amounts to for such a consumer.
    pub rms_answered_rad_s: f64,
    /// RMSE over the grid points not flagged "no evidence", rad/s: how far the estimate is
    /// from the truth where it answers (NaN when it never does, and for a normalized estimate).
    pub rmse_answered_rad_s: f64,
    /// The same over the peak |ground truth|.
    pub rmse_answered_rel_peak: f64,
}

/// A figure as `show` writes it, or, where it has no value (NaN: nothing to divide by), why.
fn shown_or_why(v: f64, show: impl Fn(f64) -> String, why: impl Fn() -> String) -> String {
    if v.is_finite() {
        show(v)
    } else {
        why()
    }
}

/// |yaw rate| (rad/s) from which a grid point counts as turning in [`FlagFigures`].
pub const TURNING_RAD_S: f64 = 0.05;

/// The points of the evaluation figure: the grid decimated ([`Decimated`], the same times in
/// every line), each rate with its integrated heading (rad, integrated over the whole grid).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlotPoints {
    /// Ground-truth yaw rate, rad/s; its times are those of every line.
    pub gt: Decimated,
    /// Integrated ground-truth heading, rad.
    pub gt_heading: Decimated,
    /// Estimate, rad/s (scaled by the least-squares fit for a normalized estimate).
    pub est: Decimated,
    /// Integrated estimate heading, rad.
    pub est_heading: Decimated,
    /// Gyro yaw rate, rad/s.
    pub gyro: Option<Decimated>,
    /// Integrated gyro heading, rad.
    pub gyro_heading: Option<Decimated>,
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
    /// What the estimate's flags say, when it has a `flags` column
    /// ([`Evaluator::push_flagged`]).
    pub flags: Option<FlagFigures>,
    /// Figures of the gyro, when given.
    pub gyro: Option<Metrics>,
    /// The points of the figure, when [`EvalOptions::plot_points`] (not serialized).
    #[serde(skip)]
    pub plot: Option<PlotPoints>,
}

/// Evaluates `est` (and optionally the gyro yaw rate) against the ground-truth yaw rate `gt`:
/// [`evaluate_samples`] on an estimate in memory.
///
/// # Errors
/// When the estimate and the ground truth do not overlap in time, or see [`Evaluator`].
pub fn evaluate(
    est: &Estimate,
    gt: &Series,
    gyro: Option<&Series>,
    opts: &EvalOptions,
) -> Result<Report> {
    let samples = est
        .series
        .t
        .iter()
        .copied()
        .zip(est.series.v.iter().copied());
    evaluate_samples(est.kind, samples, est.missing, gt, gyro, opts)
}

/// Evaluates the estimate samples `(t_s, value)` of `samples`, taken one at a time (in constant
/// memory whatever their number), against `gt` (and the gyro); `missing` rows without a value
/// were skipped before (samples with a non-finite value are counted with them).
///
/// # Errors
/// See [`Evaluator`].
pub fn evaluate_samples(
    kind: EstimateKind,
    samples: impl IntoIterator<Item = (f64, f64)>,
    missing: usize,
    gt: &Series,
    gyro: Option<&Series>,
    opts: &EvalOptions,
) -> Result<Report> {
    let mut ev = Evaluator::new(kind, gt, gyro, opts)?;
    for (t, v) in samples {
        ev.push(t, v)?;
    }
    ev.finish(missing)
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
                shown_or_why(
                    m.rmse_rel_peak,
                    |v| format!("{:.1} %", 100.0 * v),
                    || "- (the truth is 0 throughout)".to_string(),
                ),
                true,
            );
            row(
                "correlation",
                shown_or_why(
                    m.correlation,
                    |v| format!("{v:.4}"),
                    || "- (the truth or the estimate is constant)".to_string(),
                ),
                false,
            );
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
        if let Some(f) = &self.flags {
            let while_turning = shown_or_why(
                f.no_evidence_while_turning,
                |v| format!("{:.1} % while |gt| >= {TURNING_RAD_S} rad/s", 100.0 * v),
                || format!("|gt| never reaches {TURNING_RAD_S} rad/s"),
            );
            let _ = writeln!(
                s,
                "estimate flags (values above are as output, flagged or not):\n  {:<21}{:.1} % of the grid, {while_turning}\n  {:<21}{:.4} rad/s (no-evidence samples as 0)",
                "no evidence",
                100.0 * f.no_evidence_share,
                "RMS output",
                f.rms_answered_rad_s
            );
            if f.rmse_answered_rad_s.is_finite() {
                let _ = writeln!(
                    s,
                    "  {:<21}{:.4} rad/s ({:.1} % of peak; no-evidence samples left out)",
                    "RMSE where answered",
                    f.rmse_answered_rad_s,
                    100.0 * f.rmse_answered_rel_peak
                );
            }
        }
        s
    }
}
