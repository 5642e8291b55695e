//! The streaming evaluation: estimate samples pushed in one at a time, ground truth and gyro
//! pulled from their sources as far as the estimate has come, figures out at the end.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

use anyhow::{bail, ensure, Context, Result};

use super::inputs::{Checked, SampleSource, SeriesSource, TimeCheck};
use super::metrics::{value_at, Resample, T_EPS};
use super::running::Running;
use super::{EstimateKind, EvalOptions, FlagFigures, PlotPoints, Report, Series, TURNING_RAD_S};

/// Evaluates an estimate given sample by sample against the ground truth (and the gyro), in
/// memory that depends on none of their lengths.
///
/// The grid is the ground-truth times within the estimate's span (first to last sample, see the
/// module documentation). A ground-truth time is placed on the grid as soon as the estimate has
/// passed it (for both resamplings the estimate at a time is fixed by the last sample at or
/// before it and the first one after it), so only the latest estimate sample is kept, and the
/// ground truth and the gyro are read ([`SampleSource`], a chunk at a time) only as far as the
/// grid has come; the figures are accumulated by [`Running`], the figure's points by
/// [`crate::samples::Decimated`]. The ground truth's and the gyro's times are checked as they
/// are read ([`TimeCheck`]), and [`Evaluator::finish`] reads the rest of both through: a fault
/// anywhere in them is an error, however late it comes.
pub struct Evaluator<'a> {
    kind: EstimateKind,
    opts: EvalOptions,
    /// Names the evaluation in its own errors.
    label: Option<String>,
    gt: Checked<'a>,
    gyro: Option<Gyro<'a>>,
    /// The first estimate time, once a sample came.
    start: Option<f64>,
    /// First and last time on the grid.
    window: Option<(f64, f64)>,
    /// The latest estimate sample with a value.
    last: Option<(f64, f64)>,
    /// Its flags.
    last_flags: u8,
    /// Whether flags were given ([`Evaluator::push_flagged`]), and their tallies over the grid.
    flags: Option<FlagTally>,
    /// Samples pushed without a finite value.
    missing: usize,
    /// Largest |ground truth| on the grid.
    peak: f64,
    /// Figures of the estimate (before the scale fit for a normalized one).
    est: Running,
    /// A normalized estimate's grid, for the pass after the scale fit.
    spill: Option<Spill>,
    plot: Option<PlotPoints>,
}

/// Tallies of the flags over the grid (see [`FlagFigures`]).
#[derive(Clone, Copy, Debug, Default)]
struct FlagTally {
    points: usize,
    no_evidence: usize,
    turning: usize,
    turning_no_evidence: usize,
    /// Σ x² with "no evidence" samples as 0.
    answered_sq: f64,
    /// Points not flagged "no evidence", and their Σ (x - g)².
    answered: usize,
    answered_err_sq: f64,
}

impl FlagTally {
    /// The figures, `peak` being the largest |ground truth| on the grid; the answered samples'
    /// error only for a rad/s estimate (a normalized one's scale is fitted over the whole grid).
    fn figures(&self, peak: f64, kind: EstimateKind) -> FlagFigures {
        let share = |a: usize, b: usize| {
            if b == 0 {
                f64::NAN
            } else {
                a as f64 / b as f64
            }
        };
        let rmse_answered = if kind == EstimateKind::RadPerSec && self.answered > 0 {
            (self.answered_err_sq / self.answered as f64).sqrt()
        } else {
            f64::NAN
        };
        FlagFigures {
            no_evidence_share: share(self.no_evidence, self.points),
            no_evidence_while_turning: share(self.turning_no_evidence, self.turning),
            rms_answered_rad_s: (self.answered_sq / self.points.max(1) as f64).sqrt(),
            rmse_answered_rad_s: rmse_answered,
            rmse_answered_rel_peak: if peak > 0.0 {
                rmse_answered / peak
            } else {
                f64::NAN
            },
        }
    }
}

/// The ARRE window of `opts`, checked.
fn check_step(opts: &EvalOptions) -> Result<f64> {
    let step = opts.arre_step_s;
    ensure!(
        step.is_finite() && step > 0.0,
        "the ARRE window must be a positive number of seconds, not {step}"
    );
    Ok(step)
}

/// The gyro, linearly interpolated at the grid times (held at its first/last value outside its
/// span), and its figures.
struct Gyro<'a> {
    input: Checked<'a>,
    /// The latest sample at or before the latest grid time (+eps).
    last: Option<(f64, f64)>,
    fig: Running,
}

impl Gyro<'_> {
    fn at(&mut self, t: f64) -> Result<f64> {
        while let Some(s) = self.input.peek()? {
            if s.0 > t + T_EPS {
                break;
            }
            self.last = Some(s);
            self.input.advance();
        }
        let next = self.input.peek()?;
        Ok(
            value_at(self.last, next, t, Resample::Linear).unwrap_or_else(|| match self.last {
                // Before the first sample: the first value.
                None => next.map_or(0.0, |s| s.1),
                // After the last: the last value.
                Some(s) => s.1,
            }),
        )
    }
}

impl<'a> Evaluator<'a> {
    /// An evaluation of an estimate of `kind` against `gt` (and `gyro`) in memory, both with
    /// finite times that never go back and span some time.
    ///
    /// # Errors
    /// When the ARRE window is not a positive number of seconds, the ground truth or the gyro
    /// has not as many times as values, times that are not finite or go backwards, or no time
    /// span, or (normalized estimate) the scratch file cannot be created.
    pub fn new(
        kind: EstimateKind,
        gt: &'a Series,
        gyro: Option<&'a Series>,
        opts: &EvalOptions,
    ) -> Result<Self> {
        check_step(opts)?;
        for (s, what, name) in [
            (Some(gt), "ground-truth", "the ground truth"),
            (gyro, "gyro", "the gyro"),
        ] {
            let Some(s) = s else { continue };
            ensure!(
                s.t.len() == s.v.len(),
                "{name} has {} times but {} values",
                s.t.len(),
                s.v.len()
            );
            let mut check = TimeCheck::new(what);
            for &t in &s.t {
                check.push(t)?;
            }
            check.end()?;
        }
        Self::from_sources(
            kind,
            Box::new(SeriesSource::new(gt)),
            gyro.map(|g| Box::new(SeriesSource::new(g)) as Box<dyn SampleSource>),
            opts,
        )
    }

    /// An evaluation of an estimate of `kind` against the ground truth and the gyro read from
    /// `gt` and `gyro` as the evaluation needs them (see [`Evaluator`]).
    ///
    /// # Errors
    /// When the ARRE window is not a positive number of seconds, or (normalized estimate) the
    /// scratch file cannot be created.
    pub fn from_sources(
        kind: EstimateKind,
        gt: Box<dyn SampleSource + 'a>,
        gyro: Option<Box<dyn SampleSource + 'a>>,
        opts: &EvalOptions,
    ) -> Result<Self> {
        let step = check_step(opts)?;
        let spill = match kind {
            EstimateKind::RadPerSec => None,
            EstimateKind::Normalized => Some(Spill::create()?),
        };
        let has_gyro = gyro.is_some();
        Ok(Self {
            kind,
            opts: *opts,
            label: None,
            gt: Checked::new(gt, "ground-truth"),
            gyro: gyro.map(|g| Gyro {
                input: Checked::new(g, "gyro"),
                last: None,
                fig: Running::new(step, None),
            }),
            start: None,
            window: None,
            last: None,
            last_flags: 0,
            flags: None,
            missing: 0,
            peak: 0.0,
            est: Running::new(step, None),
            spill,
            plot: opts.plot_points.then(|| PlotPoints {
                gyro: has_gyro.then(Default::default),
                gyro_heading: has_gyro.then(Default::default),
                ..PlotPoints::default()
            }),
        })
    }

    /// Names the evaluation (e.g. `yaw.csv vs gt.csv`) in the errors of its own checks (no
    /// overlap, ...); the errors of the ground truth and the gyro name their file.
    #[must_use]
    pub fn labelled(mut self, label: impl Into<String>) -> Self {
        self.label = Some(label.into());
        self
    }

    /// `r`, its error named by the label unless it came from an input.
    fn own<T>(&self, r: Result<T>) -> Result<T> {
        let from_input = || self.gt.failed || self.gyro.as_ref().is_some_and(|g| g.input.failed);
        match (r, &self.label) {
            (Err(e), Some(label)) if !from_input() => Err(e.context(label.clone())),
            (r, _) => r,
        }
    }

    /// Adds the estimate sample `(t, v)` (s; rad/s or normalized). Times must be finite and not
    /// go back; a sample without a finite value is counted as missing.
    ///
    /// # Errors
    /// On a time that is not finite or goes back, when the ground truth or the gyro read so far
    /// is faulty, or when the scratch file cannot be written.
    pub fn push(&mut self, t: f64, v: f64) -> Result<()> {
        let r = self.push_sample(t, v);
        self.own(r)
    }

    /// [`Evaluator::push`] with the sample's status bits (`core_nostd::flags`): the report then
    /// also says how much of the grid is flagged "no evidence" ([`FlagFigures`]). Every sample
    /// of an evaluation must come through this or every one through [`Evaluator::push`].
    ///
    /// # Errors
    /// As [`Evaluator::push`].
    pub fn push_flagged(&mut self, t: f64, v: f64, flags: u8) -> Result<()> {
        self.flags.get_or_insert_with(FlagTally::default);
        let r = self.push_sample_flagged(t, v, flags);
        self.own(r)
    }

    fn push_sample(&mut self, t: f64, v: f64) -> Result<()> {
        self.push_sample_flagged(t, v, 0)
    }

    fn push_sample_flagged(&mut self, t: f64, v: f64, flags: u8) -> Result<()> {
        ensure!(t.is_finite(), "an estimate time is not finite ({t})");
        if let Some((last, _)) = self.last {
            ensure!(
                t >= last,
                "the estimate's time goes backwards ({t} s after {last} s)"
            );
        }
        if !v.is_finite() {
            self.missing += 1;
            return Ok(());
        }
        if self.start.is_none() {
            // The grid starts at the first ground-truth time at or after the estimate's start.
            while let Some((tg, _)) = self.gt.peek()? {
                if tg >= t - T_EPS {
                    break;
                }
                self.gt.advance();
            }
            self.start = Some(t);
        }
        // Ground-truth times this sample comes after: the estimate there is now known.
        while let Some((tg, g)) = self.gt.peek()? {
            if t <= tg + T_EPS {
                break;
            }
            let x = value_at(self.last, Some((t, v)), tg, self.opts.resample);
            self.grid_point(tg, g, x.unwrap_or(0.0))?;
            self.gt.advance();
        }
        self.last = Some((t, v));
        self.last_flags = flags;
        Ok(())
    }

    /// Places the ground-truth sample `(t, g)` on the grid, the estimate there being `x`.
    fn grid_point(&mut self, t: f64, g: f64, x: f64) -> Result<()> {
        self.window = Some((self.window.map_or(t, |w| w.0), t));
        self.peak = self.peak.max(g.abs());
        if let Some(f) = &mut self.flags {
            // The point holds the latest sample at or before it: its flags.
            let no_evidence = self.last_flags & core_nostd::flags::NO_EVIDENCE != 0;
            let turning = g.abs() >= TURNING_RAD_S;
            f.points += 1;
            f.no_evidence += usize::from(no_evidence);
            f.turning += usize::from(turning);
            f.turning_no_evidence += usize::from(turning && no_evidence);
            if !no_evidence {
                f.answered_sq += x * x;
                f.answered += 1;
                f.answered_err_sq += (x - g) * (x - g);
            }
        }
        self.est.push(t, g, x)?;
        if let Some(s) = &mut self.spill {
            s.write(t, g, x)?;
        }
        let gyro = match &mut self.gyro {
            Some(gy) => {
                let y = gy.at(t)?;
                gy.fig.push(t, g, y)?;
                Some((y, gy.fig.heading()))
            }
            None => None,
        };
        if let Some(p) = &mut self.plot {
            p.gt.push(t, g);
            p.gt_heading.push(t, self.est.gt_heading());
            if self.spill.is_none() {
                p.est.push(t, x);
                p.est_heading.push(t, self.est.heading());
            }
            if let (Some((y, h)), Some(pg), Some(ph)) = (gyro, &mut p.gyro, &mut p.gyro_heading) {
                pg.push(t, y);
                ph.push(t, h);
            }
        }
        Ok(())
    }

    /// Reads the rest of the ground truth and of the gyro (checking them).
    fn drain_inputs(&mut self) -> Result<()> {
        self.gt.drain()?;
        if let Some(gy) = &mut self.gyro {
            gy.input.drain()?;
        }
        Ok(())
    }

    /// The figures; `missing` rows without a value were skipped before the samples pushed.
    ///
    /// # Errors
    /// When the ground truth or the gyro is faulty anywhere, the estimate has no samples, it
    /// and the ground truth share fewer than two times, the gyro does not overlap the
    /// evaluation window, or the scratch file cannot be read.
    pub fn finish(mut self, missing: usize) -> Result<Report> {
        let r = self.figures(missing);
        match r {
            Ok(report) => Ok(report),
            Err(e) => self.own(Err(e)),
        }
    }

    fn figures(&mut self, missing: usize) -> Result<Report> {
        let (Some((e1, _)), Some(e0)) = (self.last, self.start) else {
            self.drain_inputs()?;
            bail!("the estimate has no samples");
        };
        while let Some((tg, g)) = self.gt.peek()? {
            if tg > e1 + T_EPS {
                break;
            }
            let x = value_at(self.last, None, tg, self.opts.resample);
            self.grid_point(tg, g, x.unwrap_or(0.0))?;
            self.gt.advance();
        }
        self.drain_inputs()?;
        let n = self.est.len();
        let gt = self.gt.times();
        let window = self.window.filter(|_| n >= 2);
        let Some((w0, w1)) = window else {
            bail!(
                "the estimate ({e0:.3}-{e1:.3} s) and the ground truth ({:.3}-{:.3} s) do not overlap",
                gt.first(),
                gt.last()
            );
        };
        if let Some(gy) = &self.gyro {
            let (g0, g1) = (gy.input.times().first(), gy.input.times().last());
            ensure!(
                g0 < w1 && g1 > w0,
                "the gyro ({g0:.3}-{g1:.3} s) and the evaluation window ({w0:.3}-{w1:.3} s) do not overlap: are they on the same clock?"
            );
        }
        let peak = self.peak;
        let estimate = match self.spill.take() {
            None => self.est.metrics(peak),
            Some(spill) => {
                // Second pass: the figures after the least-squares scale fit; the correlation
                // stays that of the values as they are.
                let k = self.est.scale_fit();
                let k = if k.is_finite() { k } else { 0.0 };
                let mut fig = Running::new(self.opts.arre_step_s, Some(k));
                let mut grid = spill.replay()?;
                for _ in 0..n {
                    let (t, g, x) = grid.next_point()?;
                    fig.push(t, g, x)?;
                    if let Some(p) = &mut self.plot {
                        p.est.push(t, fig.last_value().unwrap_or(0.0));
                        p.est_heading.push(t, fig.heading());
                    }
                }
                let mut m = fig.metrics(peak);
                m.correlation = self.est.correlation();
                m
            }
        };
        Ok(Report {
            kind: self.kind,
            resample: self.opts.resample,
            t_start_s: w0,
            t_end_s: w1,
            arre_step_s: self.opts.arre_step_s,
            peak_gt_rad_s: peak,
            gt_heading_rad: self.est.gt_heading(),
            missing_estimates: missing.saturating_add(self.missing),
            estimate,
            flags: self.flags.map(|f| f.figures(peak, self.kind)),
            gyro: self.gyro.as_ref().map(|g| g.fig.metrics(peak)),
            plot: self.plot.take(),
        })
    }
}

/// The grid kept between the two passes of a normalized estimate: an unlinked file in the
/// temporary folder (removed by the system when closed), 24 bytes a point (time, ground truth,
/// estimate).
struct Spill {
    w: BufWriter<File>,
    dir: PathBuf,
    n: u64,
}

/// Distinguishes the scratch files of concurrent evaluations in one process.
static SPILLS: AtomicU64 = AtomicU64::new(0);

impl Spill {
    fn create() -> Result<Self> {
        let dir = std::env::temp_dir();
        let name = dir.join(format!(
            ".tde-eval-{}-{}",
            std::process::id(),
            SPILLS.fetch_add(1, Ordering::Relaxed)
        ));
        let f = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .open(&name)
            .with_context(|| format!("cannot create a scratch file in {}", dir.display()))?;
        let _ = std::fs::remove_file(&name);
        Ok(Self {
            w: BufWriter::with_capacity(1 << 16, f),
            dir,
            n: 0,
        })
    }

    fn error(&self) -> String {
        format!("cannot use a scratch file in {}", self.dir.display())
    }

    fn write(&mut self, t: f64, g: f64, x: f64) -> Result<()> {
        let mut b = [0u8; 24];
        for (dst, v) in b.chunks_exact_mut(8).zip([t, g, x]) {
            dst.copy_from_slice(&v.to_le_bytes());
        }
        self.w.write_all(&b).with_context(|| self.error())?;
        self.n += 1;
        Ok(())
    }

    fn replay(self) -> Result<Replay> {
        let err = self.error();
        let mut f = self
            .w
            .into_inner()
            .map_err(|e| e.into_error())
            .context(err.clone())?;
        f.rewind().context(err.clone())?;
        Ok(Replay {
            r: BufReader::with_capacity(1 << 16, f),
            err,
            left: self.n,
        })
    }
}

/// Reads back the points of a [`Spill`].
struct Replay {
    r: BufReader<File>,
    err: String,
    left: u64,
}

impl Replay {
    fn next_point(&mut self) -> Result<(f64, f64, f64)> {
        ensure!(self.left > 0, "{}: fewer points than written", self.err);
        let mut b = [0u8; 24];
        self.r.read_exact(&mut b).context(self.err.clone())?;
        self.left -= 1;
        let (v, _) = b.as_chunks::<8>();
        let [t, g, x] = [0, 1, 2].map(|i| v.get(i).map_or(f64::NAN, |&b| f64::from_le_bytes(b)));
        Ok((t, g, x))
    }
}
