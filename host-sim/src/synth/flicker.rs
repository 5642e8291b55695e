//! A burst of lighting flicker: a uniform, sinusoidal change of the scene illumination, as
//! produced by lamps on an AC supply (100 Hz on 50 Hz mains). Every pixel sees the same change of
//! its log intensity, so all pixels fire together: an event storm that stresses the downstream
//! processing.
//!
//! Model: `g(t) = amplitude_log * sin(2 pi freq_hz (t - start_s))` inside the window
//! `[start_s, end_s]`, zero outside, added to every pixel's log intensity. The window holds a
//! whole number of periods (the requested duration rounded to the nearest number of periods,
//! at least one), so `g` is zero at both ends and continuous everywhere.
//!
//! A renderer that only compares images at its step ends could step over a short window or
//! over whole periods without seeing any change. [`Flicker::next_breakpoint`] gives the times
//! a render step must not cross: the window start and every quarter period up to the end. Between
//! two neighbouring breakpoints `g` is monotonic, so the change between two renders is the
//! largest change anywhere between them, and the adaptive step control stays valid.

use serde::{Deserialize, Serialize};

/// Tolerance (s) below which a time counts as lying on a breakpoint.
const TIME_EPS_S: f64 = 1e-9;

/// One flicker burst (see the module documentation for the model).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Flicker {
    /// Start of the burst, s from the start of the sequence (>= 0).
    pub start_s: f64,
    /// Requested length of the burst, s (> 0); rounded to a whole number of periods, at least
    /// one (see [`Flicker::end_s`]).
    pub duration_s: f64,
    /// Flicker frequency of the illumination, Hz (> 0).
    pub freq_hz: f64,
    /// Peak change of the log intensity (natural log units, >= 0); the log intensity swings
    /// by twice this value from trough to crest.
    pub amplitude_log: f64,
}

impl Flicker {
    /// Number of whole periods in the window: `duration_s * freq_hz` rounded, at least 1.
    pub fn periods(&self) -> u64 {
        ((self.duration_s * self.freq_hz).round() as u64).max(1)
    }

    /// A quarter of the flicker period, s.
    fn quarter_s(&self) -> f64 {
        0.25 / self.freq_hz
    }

    /// End of the window actually used, s: `start_s + periods() / freq_hz`.
    pub fn end_s(&self) -> f64 {
        self.start_s + (4 * self.periods()) as f64 * self.quarter_s()
    }

    /// The change of log intensity `g(t)` at time `t` (s), log units.
    pub fn offset(&self, t: f64) -> f64 {
        if t < self.start_s || t > self.end_s() {
            0.0
        } else {
            self.amplitude_log * (std::f64::consts::TAU * self.freq_hz * (t - self.start_s)).sin()
        }
    }

    /// The first breakpoint later than `t` (s): the window start, or one of the quarter-period
    /// points `start_s + k / (4 freq_hz)` up to and including the end. `None` after the window.
    /// A render step from `t` must not go past it.
    pub fn next_breakpoint(&self, t: f64) -> Option<f64> {
        let after = t + TIME_EPS_S;
        let last = 4 * self.periods();
        let first = if after < self.start_s {
            0
        } else {
            ((after - self.start_s) / self.quarter_s()).floor() as u64
        };
        (first..=last)
            .map(|k| self.start_s + k as f64 * self.quarter_s())
            .find(|&b| b > after)
    }

    /// Checks the parameters; the error names the command-line flag concerned. `dt_min_s` is
    /// the generator's smallest render step (s): a quarter period may not be shorter.
    pub fn validate(&self, dt_min_s: f64) -> anyhow::Result<()> {
        use anyhow::ensure;
        ensure!(
            self.start_s.is_finite() && self.start_s >= 0.0,
            "--flicker: the start must be a finite time >= 0 s (got {})",
            self.start_s
        );
        ensure!(
            self.duration_s.is_finite() && self.duration_s > 0.0,
            "--flicker: the duration must be a finite time > 0 s (got {})",
            self.duration_s
        );
        ensure!(
            self.freq_hz.is_finite() && self.freq_hz > 0.0,
            "--flicker-hz must be a finite frequency > 0 Hz (got {})",
            self.freq_hz
        );
        let max_hz = 0.25 / dt_min_s;
        ensure!(
            self.freq_hz <= max_hz,
            "--flicker-hz must be at most {max_hz} Hz (a quarter period no shorter than the \
             smallest render step of {dt_min_s} s; got {})",
            self.freq_hz
        );
        ensure!(
            self.amplitude_log.is_finite() && self.amplitude_log >= 0.0,
            "--flicker-amplitude must be a finite log-intensity change >= 0 (got {})",
            self.amplitude_log
        );
        Ok(())
    }
}

/// A burst of amplitude 0.5 for tests.
#[cfg(test)]
pub(crate) fn burst(start_s: f64, duration_s: f64, freq_hz: f64) -> Flicker {
    Flicker {
        start_s,
        duration_s,
        freq_hz,
        amplitude_log: 0.5,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The window is rounded to whole periods, at least one.
    #[test]
    fn flicker_window_is_whole_periods() {
        let f = burst(0.1, 0.05, 100.0);
        assert_eq!(f.periods(), 5);
        assert!((f.end_s() - 0.15).abs() < 1e-12);
        assert_eq!(burst(0.1, 0.0149, 100.0).periods(), 1);
        assert_eq!(burst(0.1, 0.001, 100.0).periods(), 1);
        assert!((burst(0.1, 0.001, 100.0).end_s() - 0.11).abs() < 1e-12);
        assert_eq!(burst(0.1, 0.016, 100.0).periods(), 2);
    }

    /// `g` is zero outside the window, continuous at its ends, and peaks at the amplitude.
    #[test]
    fn flicker_offset_shape() {
        let f = burst(0.2, 0.02, 100.0);
        assert_eq!(f.offset(0.0), 0.0);
        assert_eq!(f.offset(0.199_999), 0.0);
        assert_eq!(f.offset(0.220_001), 0.0);
        assert!(f.offset(0.2).abs() < 1e-12);
        assert!(f.offset(f.end_s()).abs() < 1e-12);
        assert!((f.offset(0.2025) - 0.5).abs() < 1e-9);
        assert!((f.offset(0.2075) + 0.5).abs() < 1e-9);
    }

    /// Breakpoints: the start, then every quarter period up to the end, then none.
    #[test]
    fn flicker_breakpoints() {
        let f = burst(0.1, 0.01, 100.0);
        let mut t = 0.0;
        let mut seen = Vec::new();
        while let Some(b) = f.next_breakpoint(t) {
            assert!(b > t);
            seen.push(b);
            t = b;
        }
        let want = [0.1, 0.1025, 0.105, 0.1075, 0.11];
        assert_eq!(seen.len(), want.len(), "{seen:?}");
        for (s, w) in seen.iter().zip(want) {
            assert!((s - w).abs() < 1e-12, "{seen:?}");
        }
        // From inside a quarter, the next quarter point.
        assert!((f.next_breakpoint(0.104).unwrap() - 0.105).abs() < 1e-12);
        assert_eq!(f.next_breakpoint(0.11), None);
        assert_eq!(f.next_breakpoint(5.0), None);
    }
}
