//! Where `host-sim run` puts its samples, as they come: straight into the CSV (calibrated
//! readout), through a spill file that is divided by the peak at the end (normalized readout,
//! whose scale is only known then), or into memory (the library's [`crate::pipeline::run_pipeline`]);
//! plus a bounded copy for the plot.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::Path;

use anyhow::{Context, Result};

use crate::output::{scratch_dir, AtomicFile};

/// Points kept for a plot: beyond this, every other point is dropped and the step doubles, so
/// a plot of any length costs at most this many points (16 MiB).
pub const PLOT_POINTS: usize = 1 << 20;

/// Every `step`-th sample, at most [`PLOT_POINTS`] of them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Decimated {
    /// Times (s).
    pub t: Vec<f64>,
    /// Values.
    pub v: Vec<f64>,
    step: u64,
    seen: u64,
}

impl Decimated {
    /// Adds the next sample; decimators fed the same number of samples keep the same ones.
    pub fn push(&mut self, t: f64, v: f64) {
        if self.step == 0 {
            self.step = 1;
        }
        if self.seen.is_multiple_of(self.step) {
            if self.t.len() == PLOT_POINTS {
                keep_even(&mut self.t);
                keep_even(&mut self.v);
                self.step *= 2;
            }
            if self.seen.is_multiple_of(self.step) {
                self.t.push(t);
                self.v.push(v);
            }
        }
        self.seen += 1;
    }
}

fn keep_even(v: &mut Vec<f64>) {
    let mut i = 0;
    v.retain(|_| {
        i += 1;
        i % 2 == 1
    });
}

enum Sink {
    Memory(Vec<(f64, f64, u8)>),
    Csv(AtomicFile),
    Spill {
        csv: AtomicFile,
        spill: BufWriter<File>,
        spill_file: File,
    },
}

/// The samples of a run.
pub struct Samples {
    sink: Sink,
    plot: Option<Decimated>,
    /// Samples written.
    pub count: u64,
    peak: f64,
}

/// What [`Samples::finish`] hands back.
pub struct Finished {
    /// The samples, when kept in memory.
    pub kept: Vec<(f64, f64, u8)>,
    /// The plot points, when asked for.
    pub plot: Option<Decimated>,
    /// The CSV, written but not in place yet ([`AtomicFile::commit`]).
    pub csv: Option<AtomicFile>,
}

/// Bytes per sample in the spill file: `t_s` and the value, f64 little-endian.
const SPILL_BYTES: usize = 16;

impl Samples {
    /// Samples kept in memory (returned by [`Samples::finish`]).
    #[must_use]
    pub fn in_memory() -> Self {
        Self {
            sink: Sink::Memory(Vec::new()),
            plot: None,
            count: 0,
            peak: 0.0,
        }
    }

    /// Samples written to the CSV `path` (`t_s,yaw_rate_rad_s,flags`, or `t_s,yaw_norm` when
    /// `normalized`), which appears when [`Finished::csv`] is committed.
    ///
    /// # Errors
    /// When the files cannot be created.
    pub fn to_csv(path: &Path, normalized: bool, plot: bool) -> Result<Self> {
        let mut csv = AtomicFile::create(path)?;
        let sink = if normalized {
            writeln!(csv.writer(), "t_s,yaw_norm")
                .with_context(|| format!("cannot write {}", path.display()))?;
            let spill_file = tempfile_beside(path)?;
            let spill = BufWriter::with_capacity(
                1 << 16,
                spill_file
                    .try_clone()
                    .with_context(|| format!("cannot write beside {}", path.display()))?,
            );
            Sink::Spill {
                csv,
                spill,
                spill_file,
            }
        } else {
            writeln!(csv.writer(), "t_s,yaw_rate_rad_s,flags")
                .with_context(|| format!("cannot write {}", path.display()))?;
            Sink::Csv(csv)
        };
        Ok(Self {
            sink,
            plot: plot.then(Decimated::default),
            count: 0,
            peak: 0.0,
        })
    }

    /// Adds samples `(t_s, value, flags)`.
    ///
    /// # Errors
    /// When the output cannot be written.
    pub fn extend(&mut self, samples: &[(f64, f64, u8)]) -> Result<()> {
        self.count += samples.len() as u64;
        for &(t, v, _) in samples {
            self.peak = self.peak.max(v.abs());
            if let Some(p) = &mut self.plot {
                p.push(t, v);
            }
        }
        match &mut self.sink {
            Sink::Memory(all) => all.extend_from_slice(samples),
            Sink::Csv(csv) => {
                let path = csv.path().to_path_buf();
                let w = csv.writer();
                for (t, v, f) in samples {
                    writeln!(w, "{t:.6},{v:.6},{f}")
                        .with_context(|| format!("cannot write {}", path.display()))?;
                }
            }
            Sink::Spill { spill, .. } => {
                for &(t, v, _) in samples {
                    spill.write_all(&t.to_le_bytes())?;
                    spill.write_all(&v.to_le_bytes())?;
                }
            }
        }
        Ok(())
    }

    /// The kept samples (in memory) and the plot points; for a normalized CSV, divides the
    /// spilled samples by their peak |value| (the paper's normalisation over the whole
    /// recording) into the CSV. The CSV is not in place until [`AtomicFile::commit`].
    ///
    /// # Errors
    /// When the output cannot be written.
    pub fn finish(mut self, normalized: bool) -> Result<Finished> {
        let peak = self.peak;
        let scale = |v: f64| if peak > 0.0 { v / peak } else { v };
        if let (Some(p), true) = (&mut self.plot, normalized) {
            p.v.iter_mut().for_each(|v| *v = scale(*v));
        }
        match self.sink {
            Sink::Memory(mut all) => {
                if normalized {
                    for s in &mut all {
                        s.1 = scale(s.1);
                    }
                }
                Ok(Finished {
                    kept: all,
                    plot: self.plot,
                    csv: None,
                })
            }
            Sink::Csv(csv) => Ok(Finished {
                kept: Vec::new(),
                plot: self.plot,
                csv: Some(csv),
            }),
            Sink::Spill {
                mut csv,
                spill,
                spill_file,
            } => {
                let path = csv.path().to_path_buf();
                let err = || format!("cannot write {}", path.display());
                drop(
                    spill
                        .into_inner()
                        .map_err(|e| e.into_error())
                        .with_context(err)?,
                );
                use std::io::Seek;
                let mut f = spill_file;
                f.seek(std::io::SeekFrom::Start(0)).with_context(err)?;
                let mut r = BufReader::with_capacity(1 << 16, f);
                let w = csv.writer();
                let mut rec = [0u8; SPILL_BYTES];
                for _ in 0..self.count {
                    r.read_exact(&mut rec).with_context(err)?;
                    let (tb, vb) = rec.split_at(8);
                    let t = f64::from_le_bytes(tb.try_into().unwrap_or_default());
                    let v = f64::from_le_bytes(vb.try_into().unwrap_or_default());
                    writeln!(w, "{t:.6},{:.6}", scale(v)).with_context(err)?;
                }
                Ok(Finished {
                    kept: Vec::new(),
                    plot: self.plot,
                    csv: Some(csv),
                })
            }
        }
    }
}

/// An anonymous temporary file in the output's scratch folder ([`scratch_dir`]; removed by the
/// system when closed).
fn tempfile_beside(path: &Path) -> Result<File> {
    let dir = scratch_dir(path);
    let name = dir.join(format!(".spill-{}", std::process::id()));
    let f = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create_new(true)
        .open(&name)
        .with_context(|| format!("cannot create {}", name.display()))?;
    let _ = std::fs::remove_file(&name);
    Ok(f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plot_points_stay_bounded_and_evenly_spaced() {
        let mut d = Decimated::default();
        let n = 3 * PLOT_POINTS as u64 + 17;
        for i in 0..n {
            d.push(i as f64, -(i as f64));
        }
        assert!(d.t.len() <= PLOT_POINTS && d.t.len() > PLOT_POINTS / 2);
        let step = d.t[1] - d.t[0];
        assert_eq!(step, 4.0);
        assert!(d.t.iter().enumerate().all(|(k, &t)| t == k as f64 * step));
        assert!(d.t.iter().zip(&d.v).all(|(t, v)| *v == -*t));
        // Short series are kept whole.
        let mut d = Decimated::default();
        for i in 0..1000 {
            d.push(f64::from(i), 0.0);
        }
        assert_eq!(d.t.len(), 1000);
    }
}
