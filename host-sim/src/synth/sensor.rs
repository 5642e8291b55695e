//! The event-camera pixel model: per-pixel log-intensity threshold crossings with threshold
//! mismatch, a refractory period, background-activity noise and hot pixels.
//!
//! Between two rendered images at `t0` and `t1` each pixel's log intensity is taken to change
//! linearly; every crossing of the pixel's reference level `+-C` emits an event at the
//! interpolated time and moves the reference by `C` (so a change of `k C` gives `k` events).

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::rng;

/// Pixel and noise parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SensorParams {
    /// Mean ON threshold, log-intensity units.
    pub cp: f64,
    /// Mean OFF threshold, log-intensity units.
    pub cm: f64,
    /// Per-pixel threshold mismatch (std, log units), drawn independently for ON and OFF.
    pub sigma_c: f64,
    /// Lower bound of any pixel's threshold, log units.
    pub c_min: f64,
    /// Refractory period, µs: a pixel's event less than this after its previous event is
    /// dropped (its reference level still moves).
    pub refractory_us: u32,
    /// Background-activity rate per pixel, Hz (Poisson).
    pub noise_hz: f64,
    /// Fraction of noise events that are ON.
    pub noise_on_frac: f64,
    /// Number of hot pixels (random places).
    pub hot_pixels: u32,
    /// Range of hot-pixel rates, Hz (uniform).
    pub hot_rate_hz: [f64; 2],
}

impl Default for SensorParams {
    fn default() -> Self {
        Self {
            cp: 0.25,
            cm: 0.25,
            sigma_c: 0.03,
            c_min: 0.05,
            refractory_us: 100,
            noise_hz: 0.1,
            noise_on_frac: 0.5,
            hot_pixels: 0,
            hot_rate_hz: [20.0, 300.0],
        }
    }
}

/// One event before it is given image coordinates: time in µs, pixel index (column-major),
/// polarity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct RawEvent {
    /// µs.
    pub t_us: u64,
    /// `x * height + y`.
    pub pixel: u32,
    /// ON (true) / OFF.
    pub on: bool,
}

/// Counters reported in `meta.json`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SensorStats {
    /// Events from threshold crossings.
    pub signal_events: u64,
    /// Background-activity and hot-pixel events.
    pub noise_events: u64,
    /// Crossings dropped by the refractory period.
    pub refractory_drops: u64,
    /// Pixel-steps in which one pixel crossed more than one threshold.
    pub multi_crossing_events: u64,
}

/// A hot pixel: its index, rate (Hz) and next event time (s).
#[derive(Clone, Debug)]
struct Hot {
    pixel: u32,
    rate: f64,
    next_t: f64,
}

/// The state of every pixel.
#[derive(Clone, Debug)]
pub struct Sensor {
    params: SensorParams,
    cp: Vec<f32>,
    cm: Vec<f32>,
    reference: Vec<f32>,
    last_us: Vec<i64>,
    noise_rng: ChaCha8Rng,
    next_noise_t: f64,
    hot: Vec<Hot>,
    /// Counters.
    pub stats: SensorStats,
}

impl Sensor {
    /// Pixels initialised to the first image `l0` (their reference = their log intensity), with
    /// thresholds and hot pixels drawn from `mismatch_rng` and noise events from `noise_rng`.
    pub fn new(
        params: &SensorParams,
        l0: &[f32],
        mismatch_rng: &mut ChaCha8Rng,
        mut noise_rng: ChaCha8Rng,
    ) -> Self {
        let n = l0.len();
        let mut draw = |mean: f64| -> Vec<f32> {
            (0..n)
                .map(|_| {
                    (mean + params.sigma_c * rng::gauss(mismatch_rng)).max(params.c_min) as f32
                })
                .collect()
        };
        let cp = draw(params.cp);
        let cm = draw(params.cm);
        let mut hot = Vec::new();
        for _ in 0..params.hot_pixels.min(n as u32) {
            let rate = rng::uniform(mismatch_rng, params.hot_rate_hz[0], params.hot_rate_hz[1]);
            hot.push(Hot {
                pixel: mismatch_rng.gen_range(0..n as u32),
                rate,
                next_t: 0.0,
            });
        }
        for h in &mut hot {
            h.next_t = rng::exponential(&mut noise_rng, h.rate);
        }
        let next_noise_t = rng::exponential(&mut noise_rng, params.noise_hz * n as f64);
        Self {
            params: params.clone(),
            cp,
            cm,
            reference: l0.to_vec(),
            last_us: vec![i64::MIN / 2; n],
            noise_rng,
            next_noise_t,
            hot,
            stats: SensorStats::default(),
        }
    }

    /// Mean ON and OFF thresholds actually drawn.
    pub fn mean_thresholds(&self) -> (f64, f64) {
        let m = |v: &[f32]| v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len().max(1) as f64;
        (m(&self.cp), m(&self.cm))
    }

    /// Hot pixel indices (column-major).
    pub fn hot_pixels(&self) -> Vec<u32> {
        self.hot.iter().map(|h| h.pixel).collect()
    }

    /// Emits (unsorted, into `out`) the threshold crossings of every pixel while its log
    /// intensity goes linearly from `l0` at `t0` to `l1` at `t1` (s).
    pub fn step(&mut self, t0: f64, t1: f64, l0: &[f32], l1: &[f32], out: &mut Vec<RawEvent>) {
        let dt = t1 - t0;
        let refr = i64::from(self.params.refractory_us);
        let mut emit =
            |i: usize, level: f32, a: f32, inv: f32, on: bool, stats: &mut SensorStats| {
                let frac = f64::from(((level - a) * inv).clamp(0.0, 1.0));
                let t_us = ((t0 + frac * dt) * 1e6).round() as i64;
                if t_us - self.last_us[i] < refr {
                    stats.refractory_drops += 1;
                } else {
                    self.last_us[i] = t_us;
                    stats.signal_events += 1;
                    out.push(RawEvent {
                        t_us: t_us as u64,
                        pixel: i as u32,
                        on,
                    });
                }
            };
        let stats = &mut self.stats;
        for i in 0..l1.len() {
            let (a, b) = (l0[i], l1[i]);
            let mut r = self.reference[i];
            let (cp, cm) = (self.cp[i], self.cm[i]);
            if b - r >= cp {
                let inv = 1.0 / (b - a);
                let mut k = 0;
                while b - r >= cp {
                    r += cp;
                    emit(i, r, a, inv, true, stats);
                    k += 1;
                }
                if k > 1 {
                    stats.multi_crossing_events += 1;
                }
                self.reference[i] = r;
            } else if r - b >= cm {
                let inv = 1.0 / (b - a);
                let mut k = 0;
                while r - b >= cm {
                    r -= cm;
                    emit(i, r, a, inv, false, stats);
                    k += 1;
                }
                if k > 1 {
                    stats.multi_crossing_events += 1;
                }
                self.reference[i] = r;
            }
        }
    }

    /// Emits the background-activity and hot-pixel events in `(t0, t1]` (s) into `out`. Noise
    /// events neither move the reference level nor start a refractory period.
    pub fn noise(&mut self, t1: f64, out: &mut Vec<RawEvent>) {
        let n = self.reference.len() as u32;
        let total_rate = self.params.noise_hz * f64::from(n);
        while self.next_noise_t <= t1 {
            let pixel = self.noise_rng.gen_range(0..n);
            let on = self.noise_rng.gen::<f64>() < self.params.noise_on_frac;
            out.push(RawEvent {
                t_us: (self.next_noise_t * 1e6).round() as u64,
                pixel,
                on,
            });
            self.stats.noise_events += 1;
            self.next_noise_t += rng::exponential(&mut self.noise_rng, total_rate);
        }
        for h in &mut self.hot {
            while h.next_t <= t1 {
                let on = self.noise_rng.gen::<bool>();
                out.push(RawEvent {
                    t_us: (h.next_t * 1e6).round() as u64,
                    pixel: h.pixel,
                    on,
                });
                self.stats.noise_events += 1;
                h.next_t += rng::exponential(&mut self.noise_rng, h.rate);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> SensorParams {
        SensorParams {
            sigma_c: 0.0,
            refractory_us: 0,
            noise_hz: 0.0,
            ..SensorParams::default()
        }
    }

    /// A linear ramp of 1.0 log unit over 1 ms crosses C = 0.25 at 250, 500, 750, 1000 µs.
    #[test]
    fn crossing_times_are_interpolated() {
        let mut r1 = rng::stream(1, rng::Stream::Sensor);
        let r2 = rng::stream(1, rng::Stream::Noise);
        let mut s = Sensor::new(&params(), &[0.0, 0.0], &mut r1, r2);
        let mut out = Vec::new();
        s.step(0.0, 0.001, &[0.0, 0.0], &[1.0, -0.6], &mut out);
        let on: Vec<u64> = out.iter().filter(|e| e.on).map(|e| e.t_us).collect();
        let off: Vec<u64> = out.iter().filter(|e| !e.on).map(|e| e.t_us).collect();
        assert_eq!(on, vec![250, 500, 750, 1000]);
        assert!(out.iter().filter(|e| e.on).all(|e| e.pixel == 0));
        // -0.6 crosses -0.25 at 417 µs and -0.5 at 833 µs.
        assert_eq!(off, vec![417, 833]);
        // The reference keeps the remainder: a further +0.1 gives nothing, +0.2 an ON event.
        out.clear();
        s.step(0.001, 0.002, &[1.0, -0.6], &[1.0, -0.2], &mut out);
        assert_eq!(out.len(), 1);
        assert!(out[0].on && out[0].pixel == 1);
    }

    /// Crossings closer than the refractory period are dropped.
    #[test]
    fn refractory_period_drops_events() {
        let p = SensorParams {
            refractory_us: 300,
            ..params()
        };
        let mut r1 = rng::stream(1, rng::Stream::Sensor);
        let r2 = rng::stream(1, rng::Stream::Noise);
        let mut s = Sensor::new(&p, &[0.0], &mut r1, r2);
        let mut out = Vec::new();
        s.step(0.0, 0.001, &[0.0], &[1.0], &mut out);
        let t: Vec<u64> = out.iter().map(|e| e.t_us).collect();
        assert_eq!(t, vec![250, 750]);
        assert_eq!(s.stats.refractory_drops, 2);
    }

    /// Background activity arrives at the configured rate.
    #[test]
    fn noise_rate() {
        let p = SensorParams {
            noise_hz: 5.0,
            ..params()
        };
        let mut r1 = rng::stream(1, rng::Stream::Sensor);
        let r2 = rng::stream(1, rng::Stream::Noise);
        let mut s = Sensor::new(&p, &vec![0.0; 1000], &mut r1, r2);
        let mut out = Vec::new();
        s.noise(2.0, &mut out);
        // Expected 10,000 +- 100 (Poisson).
        assert!((9_600..10_400).contains(&out.len()), "{}", out.len());
    }
}
