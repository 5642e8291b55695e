//! Error metrics between an estimated and a ground-truth yaw rate on a common time grid.
//!
//! All functions take equally long slices sampled at the same times `t` (s, increasing); rates
//! are rad/s, angles rad. They do not panic on empty input: they return `NaN` (or 0 samples).

use super::Series;

/// Tolerance when comparing times, s (timestamps are printed with µs resolution).
pub const T_EPS: f64 = 1e-9;

/// How an estimate given at its own times is evaluated at the ground-truth times.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Resample {
    /// Zero-order hold: the latest estimate at or before the time (what a causal consumer of the
    /// estimate would have). The default.
    #[default]
    Hold,
    /// Linear interpolation between the two neighbouring estimates.
    Linear,
}

/// `src` evaluated at each of `at` (s). Times before the first sample of `src` (and, for
/// `Linear`, after the last) give `None`; `Hold` keeps the last value after the end.
pub fn resample(src: &Series, at: &[f64], mode: Resample) -> Vec<Option<f64>> {
    let mut out = Vec::with_capacity(at.len());
    let mut k = 0usize; // number of src samples with t <= current time (+eps)
    for &t in at {
        while k < src.t.len() && src.t[k] <= t + T_EPS {
            k += 1;
        }
        let sample = |i: usize| Some((src.t[i], src.v[i]));
        let last = k.checked_sub(1).and_then(sample);
        let next = (k < src.t.len()).then_some(k).and_then(sample);
        out.push(value_at(last, next, t, mode));
    }
    out
}

/// A signal at time `t` from its `last` sample at or before `t` (+[`T_EPS`]) and the `next` one
/// after it (`None` at the end): the rule of [`resample`], for callers that hold only these two
/// samples of a stream.
#[must_use]
pub fn value_at(
    last: Option<(f64, f64)>,
    next: Option<(f64, f64)>,
    t: f64,
    mode: Resample,
) -> Option<f64> {
    let (t0, v0) = last?;
    match (mode, next) {
        (Resample::Hold, _) => Some(v0),
        (Resample::Linear, None) => (t0 >= t - T_EPS).then_some(v0),
        (Resample::Linear, Some((t1, v1))) => {
            if t1 - t0 <= T_EPS {
                Some(v1)
            } else {
                Some(v0 + (v1 - v0) * ((t - t0) / (t1 - t0)).clamp(0.0, 1.0))
            }
        }
    }
}

/// Root-mean-square of `a - b`.
pub fn rmse(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    if n == 0 {
        return f64::NAN;
    }
    let s: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
    (s / n as f64).sqrt()
}

/// Mean of `a - b`.
pub fn mean_error(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    if n == 0 {
        return f64::NAN;
    }
    a.iter().zip(b).map(|(x, y)| x - y).sum::<f64>() / n as f64
}

/// Pearson correlation of `a` and `b`; `NaN` when either is constant.
pub fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    if n < 2 {
        return f64::NAN;
    }
    let ma = a.iter().take(n).sum::<f64>() / n as f64;
    let mb = b.iter().take(n).sum::<f64>() / n as f64;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        let (da, db) = (x - ma, y - mb);
        sab += da * db;
        saa += da * da;
        sbb += db * db;
    }
    if saa <= 0.0 || sbb <= 0.0 {
        return f64::NAN;
    }
    sab / (saa * sbb).sqrt()
}

/// Least-squares scale `k` minimising `sum (k a - b)^2`: `sum a b / sum a^2` (`NaN` if `a` is
/// all zero).
pub fn scale_fit(a: &[f64], b: &[f64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
    let den: f64 = a.iter().map(|x| x * x).sum();
    if den > 0.0 {
        num / den
    } else {
        f64::NAN
    }
}

/// Running trapezoidal integral of `v` over `t`, starting at 0 (rad for a rate in rad/s).
pub fn integrate(t: &[f64], v: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(t.len());
    let mut acc = 0.0;
    for i in 0..t.len().min(v.len()) {
        if i > 0 {
            acc += 0.5 * (v[i] + v[i - 1]) * (t[i] - t[i - 1]);
        }
        out.push(acc);
    }
    out
}

/// Indices of `t` that start consecutive windows of `step_s` from `t[0]`: for each boundary time
/// `t[0] + k step_s` (k = 0, 1, ... while within `t`), the sample nearest to it.
pub fn step_indices(t: &[f64], step_s: f64) -> Vec<usize> {
    let Some((&t0, &t_end)) = t.first().zip(t.last()) else {
        return Vec::new();
    };
    let n_steps = ((t_end - t0) / step_s + 1e-6).floor() as usize;
    (0..=n_steps)
        .map(|k| {
            let target = t0 + k as f64 * step_s;
            let i = t.partition_point(|&x| x < target);
            match i {
                0 => 0,
                i if i >= t.len() => t.len() - 1,
                i if (t[i] - target).abs() < (target - t[i - 1]).abs() => i,
                i => i - 1,
            }
        })
        .collect()
}

/// The paper's ARRE for yaw only: the mean over consecutive windows of `step_s` of
/// `|d psi_pred - d psi_gt|`, where `psi` is the trapezoidal integral of the rate (rad).
/// For a constant rate offset `c` it equals `|c| step_s`. `NaN` with fewer than one window.
pub fn arre(t: &[f64], pred: &[f64], gt: &[f64], step_s: f64) -> f64 {
    let pp = integrate(t, pred);
    let pg = integrate(t, gt);
    let idx = step_indices(t, step_s);
    if idx.len() < 2 {
        return f64::NAN;
    }
    let sum: f64 = idx
        .windows(2)
        .map(|w| ((pp[w[1]] - pp[w[0]]) - (pg[w[1]] - pg[w[0]])).abs())
        .sum();
    sum / (idx.len() - 1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(t: &[f64], v: &[f64]) -> Series {
        Series {
            t: t.to_vec(),
            v: v.to_vec(),
        }
    }

    #[test]
    fn hold_and_linear() {
        let s = series(&[0.0, 1.0, 2.0], &[0.0, 10.0, 20.0]);
        let at = [-0.5, 0.0, 0.5, 1.0, 2.0, 2.5];
        assert_eq!(
            resample(&s, &at, Resample::Hold),
            vec![
                None,
                Some(0.0),
                Some(0.0),
                Some(10.0),
                Some(20.0),
                Some(20.0)
            ]
        );
        assert_eq!(
            resample(&s, &at, Resample::Linear),
            vec![None, Some(0.0), Some(5.0), Some(10.0), Some(20.0), None]
        );
    }

    #[test]
    fn step_indices_on_a_1khz_grid() {
        let t: Vec<f64> = (0..=1000).map(|k| k as f64 / 1000.0).collect();
        let idx = step_indices(&t, 0.05);
        assert_eq!(idx.len(), 21);
        assert_eq!(idx[1], 50);
        assert_eq!(idx[20], 1000);
    }
}
