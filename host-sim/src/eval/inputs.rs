//! The ground truth and the gyro as streams of `(t_s, rate)` samples for [`super::Evaluator`]:
//! read from their files a chunk at a time ([`TruthReader`], [`GyroYawReader`]) or handed out
//! from memory ([`SeriesSource`]), and checked as they come ([`Checked`]).

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use anyhow::{ensure, Context, Result};

use super::{CsvSeries, Series, CHUNK};
use crate::formats::{self, GtSample, GyroSample};

/// A signal in time order, a chunk of samples at a time.
pub trait SampleSource {
    /// Replaces `out` with the next samples `(t_s, value)`; false, with `out` empty, at the end.
    ///
    /// # Errors
    /// When the input cannot be read or is malformed.
    fn next_chunk(&mut self, out: &mut Vec<(f64, f64)>) -> Result<bool>;

    /// The file the samples come from, named in the errors about their times.
    fn name(&self) -> Option<&str> {
        None
    }
}

/// A [`Series`] in memory, handed out [`CHUNK`] samples at a time.
pub struct SeriesSource<'a> {
    series: &'a Series,
    next: usize,
}

impl<'a> SeriesSource<'a> {
    /// A source over `series` (as many times as values).
    #[must_use]
    pub fn new(series: &'a Series) -> Self {
        Self { series, next: 0 }
    }
}

impl SampleSource for SeriesSource<'_> {
    fn next_chunk(&mut self, out: &mut Vec<(f64, f64)>) -> Result<bool> {
        out.clear();
        let s = self.series;
        let end = (self.next + CHUNK).min(s.t.len()).min(s.v.len());
        let t = s.t.get(self.next..end).unwrap_or_default();
        let v = s.v.get(self.next..end).unwrap_or_default();
        out.extend(t.iter().copied().zip(v.iter().copied()));
        self.next = end.max(self.next);
        Ok(!out.is_empty())
    }
}

enum Truth {
    /// A file `formats::GroundTruthReader` reads.
    Format(formats::GroundTruthReader, Vec<GtSample>),
    /// A CSV with `t_s` and `yaw_rate` (or `yaw_rate_rad_s`) columns; `primary` is the error
    /// of reading the file as any other ground truth, reported if this reading fails too.
    Simple {
        csv: CsvSeries<BufReader<File>>,
        primary: Option<anyhow::Error>,
    },
}

/// Ground-truth yaw rate (rad/s), read a chunk at a time: any file
/// [`formats::GroundTruthReader`] reads (`gt.csv`, ECD `groundtruth.txt`, MVSEC `*_gt.hdf5`),
/// or else a CSV with `t_s` and `yaw_rate` (or `yaw_rate_rad_s`) columns (rows without a finite
/// value skipped). [`super::read_gt`] collects the same samples.
pub struct TruthReader {
    truth: Truth,
    name: String,
}

impl TruthReader {
    /// Opens `path` and reads its header.
    ///
    /// A file both readings accept (a header with `t_s` and `yaw_rate` that is also a
    /// ground-truth file of a known format, e.g. `gt.csv` with an extra `yaw_rate` column) is
    /// read as its format unless that fails anywhere in it, and then as the simple CSV: it is
    /// read through once here to tell (in constant memory).
    ///
    /// # Errors
    /// When the file is neither a known ground-truth file nor a simple CSV (the error of the
    /// former).
    pub fn open(path: &Path) -> Result<Self> {
        let simple = || {
            let f = File::open(path).ok()?;
            CsvSeries::new(
                BufReader::with_capacity(1 << 16, f),
                &["yaw_rate", "yaw_rate_rad_s"],
            )
            .ok()
        };
        let truth = match formats::GroundTruthReader::open(path) {
            Err(e) => match simple() {
                Some(csv) => Truth::Simple {
                    csv,
                    primary: Some(e),
                },
                None => return Err(e),
            },
            Ok(mut reader) => match simple() {
                None => Truth::Format(reader, Vec::new()),
                Some(csv) => {
                    let mut chunk = Vec::new();
                    let whole = loop {
                        match reader.next_chunk(&mut chunk) {
                            Ok(true) => {}
                            Ok(false) => break Ok(()),
                            Err(e) => break Err(e),
                        }
                    };
                    match whole {
                        Ok(()) => Truth::Format(formats::GroundTruthReader::open(path)?, chunk),
                        Err(e) => Truth::Simple {
                            csv,
                            primary: Some(e),
                        },
                    }
                }
            },
        };
        Ok(Self {
            truth,
            name: path.display().to_string(),
        })
    }
}

impl SampleSource for TruthReader {
    fn next_chunk(&mut self, out: &mut Vec<(f64, f64)>) -> Result<bool> {
        match &mut self.truth {
            Truth::Format(reader, chunk) => {
                out.clear();
                let more = reader.next_chunk(chunk)?;
                out.extend(chunk.iter().map(|g| (g.t_s, g.yaw_rate_rad_s)));
                Ok(more)
            }
            Truth::Simple { csv, primary } => csv.next_chunk(out).map_err(|e| {
                // As when the file was read whole: the simple reading failing, the error is
                // that of the other.
                primary.take().unwrap_or(e)
            }),
        }
    }

    fn name(&self) -> Option<&str> {
        Some(&self.name)
    }
}

/// Gyro yaw rate `wy` (rad/s) of any file [`formats::GyroReader`] reads, a chunk at a time.
/// [`super::read_gyro_yaw`] collects the same samples.
pub struct GyroYawReader {
    reader: formats::GyroReader,
    chunk: Vec<GyroSample>,
    name: String,
}

impl GyroYawReader {
    /// Opens `path` and reads its header.
    ///
    /// # Errors
    /// When the file cannot be read, is not a gyro file, or its header is malformed.
    pub fn open(path: &Path) -> Result<Self> {
        Ok(Self {
            reader: formats::GyroReader::open(path)?,
            chunk: Vec::new(),
            name: path.display().to_string(),
        })
    }
}

impl SampleSource for GyroYawReader {
    fn next_chunk(&mut self, out: &mut Vec<(f64, f64)>) -> Result<bool> {
        out.clear();
        let more = self.reader.next_chunk(&mut self.chunk)?;
        out.extend(self.chunk.iter().map(|g| (g.t_s, g.wy)));
        Ok(more)
    }

    fn name(&self) -> Option<&str> {
        Some(&self.name)
    }
}

/// The checks on a ground truth's or a gyro's times, sample by sample: finite, never going
/// back, and (at the end) some samples spanning some time. A signal that fails is refused
/// rather than integrated into a meaningless heading.
#[derive(Clone, Debug)]
pub struct TimeCheck {
    /// `ground-truth` or `gyro`, in the messages.
    what: &'static str,
    n: u64,
    first: f64,
    last: f64,
}

impl TimeCheck {
    /// Checks of the signal `what` names.
    #[must_use]
    pub fn new(what: &'static str) -> Self {
        Self {
            what,
            n: 0,
            first: f64::NAN,
            last: f64::NAN,
        }
    }

    /// The next sample's time.
    ///
    /// # Errors
    /// When it or the previous time is not finite, or it is before the previous one.
    pub fn push(&mut self, t: f64) -> Result<()> {
        let what = self.what;
        if self.n == 0 {
            self.first = t;
        } else {
            let a = self.last;
            ensure!(
                a.is_finite() && t.is_finite(),
                "{what} sample {} has a time that is not finite",
                self.n
            );
            ensure!(
                t >= a,
                "{what} time goes backwards at sample {} ({t} s after {a} s)",
                self.n + 1
            );
        }
        self.n += 1;
        self.last = t;
        Ok(())
    }

    /// After the last sample.
    ///
    /// # Errors
    /// Without samples, or when they are all at one time.
    pub fn end(&self) -> Result<()> {
        let what = self.what;
        ensure!(self.n > 0, "no {what} samples");
        ensure!(
            self.last > self.first,
            "all {} {what} samples are at one time ({} s): no time span to evaluate over",
            self.n,
            self.first
        );
        Ok(())
    }

    /// Samples so far.
    #[must_use]
    pub fn len(&self) -> u64 {
        self.n
    }

    /// True before the first sample.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Time of the first sample (`NaN` before it).
    #[must_use]
    pub fn first(&self) -> f64 {
        self.first
    }

    /// Time of the latest sample (`NaN` before the first).
    #[must_use]
    pub fn last(&self) -> f64 {
        self.last
    }
}

/// A [`SampleSource`] read sample by sample, each chunk's times checked ([`TimeCheck`]) before
/// any of its samples is handed out; errors about the times name the source's file.
pub(super) struct Checked<'a> {
    src: Box<dyn SampleSource + 'a>,
    check: TimeCheck,
    chunk: Vec<(f64, f64)>,
    pos: usize,
    ended: bool,
    /// An error came from this input (it is then reported as it is).
    pub(super) failed: bool,
}

impl<'a> Checked<'a> {
    pub(super) fn new(src: Box<dyn SampleSource + 'a>, what: &'static str) -> Self {
        Self {
            src,
            check: TimeCheck::new(what),
            chunk: Vec::with_capacity(CHUNK),
            pos: 0,
            ended: false,
            failed: false,
        }
    }

    /// The next sample, without taking it; `None` at the end.
    pub(super) fn peek(&mut self) -> Result<Option<(f64, f64)>> {
        while self.pos >= self.chunk.len() && !self.ended {
            let r = self.refill();
            if r.is_err() {
                self.failed = true;
            }
            r?;
        }
        Ok(self.chunk.get(self.pos).copied())
    }

    /// Takes the sample [`Checked::peek`] gave.
    pub(super) fn advance(&mut self) {
        self.pos += 1;
    }

    /// Reads (and checks) the rest of the input.
    pub(super) fn drain(&mut self) -> Result<()> {
        while self.peek()?.is_some() {
            self.pos = self.chunk.len();
        }
        Ok(())
    }

    /// The checks so far (all of the input's times after [`Checked::drain`]).
    pub(super) fn times(&self) -> &TimeCheck {
        &self.check
    }

    fn refill(&mut self) -> Result<()> {
        self.pos = 0;
        if !self.src.next_chunk(&mut self.chunk)? {
            self.chunk.clear();
            self.ended = true;
            let r = self.check.end();
            return self.named(r);
        }
        for &(t, _) in &self.chunk {
            let r = self.check.push(t);
            if r.is_err() {
                return self.named(r);
            }
        }
        Ok(())
    }

    fn named(&self, r: Result<()>) -> Result<()> {
        match self.src.name() {
            Some(name) => r.with_context(|| name.to_string()),
            None => r,
        }
    }
}

/// Every sample of `src`, checked as [`Checked`] does.
pub(super) fn collect(src: impl SampleSource, what: &'static str) -> Result<Series> {
    let mut input = Checked::new(Box::new(src), what);
    let mut series = Series::default();
    while let Some((t, v)) = input.peek()? {
        series.t.push(t);
        series.v.push(v);
        input.advance();
    }
    Ok(series)
}
