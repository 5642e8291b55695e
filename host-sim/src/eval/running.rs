//! The figures of [`super::metrics`], accumulated point by point in constant memory: a signal of
//! any length is evaluated as its points come, without keeping them.
//!
//! Each figure is computed with the same arithmetic, in the same order, as its slice function
//! (RMSE, mean error, least-squares scale, trapezoidal heading, ARRE with the windows of
//! [`super::metrics::step_indices`]), so the results are identical to those on the whole series,
//! except the Pearson correlation: it is accumulated with Welford's co-moment update (one pass,
//! numerically stable) instead of the two passes of [`super::metrics::pearson`], which differs
//! by a few units in the last place.

use anyhow::{ensure, Result};

use super::Metrics;

/// Most ARRE windows one evaluation may span (2^52): beyond this, window boundaries are no
/// longer exact in f64 (a span of 7 million years at 50 ms).
const MAX_WINDOWS: f64 = 4_503_599_627_370_496.0;

/// Figures of one signal against the ground truth on a common grid, fed one grid point at a time
/// (times non-decreasing).
#[derive(Clone, Debug)]
pub struct Running {
    /// Factor applied to each signal value first (a normalized estimate's scale fit).
    scale: Option<f64>,
    /// ARRE window, s.
    step: f64,
    n: u64,
    /// Sum of (x - g)^2, and of (x - g).
    sum_sq: f64,
    sum_err: f64,
    /// Welford: means, sums of squared deviations, co-moment.
    mean_x: f64,
    mean_g: f64,
    m2_x: f64,
    m2_g: f64,
    c_xg: f64,
    /// Sum of x g and of x^2 (least-squares scale).
    sum_xg: f64,
    sum_xx: f64,
    /// The previous point: time, signal, ground truth.
    prev: Option<(f64, f64, f64)>,
    /// Integrated headings of the signal and of the ground truth at the latest point, rad.
    psi_x: f64,
    psi_g: f64,
    /// Time of the first point (the first window boundary).
    t0: f64,
    /// The smallest window boundary not placed yet.
    next_k: i64,
    /// Where the latest boundary was placed: point index and the headings there.
    mark: Option<(u64, f64, f64)>,
    /// Sum over windows of |d psi_x - d psi_g|.
    arre_sum: f64,
}

impl Running {
    /// Figures with ARRE windows of `step_s` (finite, > 0; see [`Running::push`]), the signal
    /// multiplied by `scale` when given.
    #[must_use]
    pub fn new(step_s: f64, scale: Option<f64>) -> Self {
        Self {
            scale,
            step: step_s,
            n: 0,
            // Sums start at -0.0, the neutral element `Iterator::sum` starts from.
            sum_sq: -0.0,
            sum_err: -0.0,
            mean_x: 0.0,
            mean_g: 0.0,
            m2_x: 0.0,
            m2_g: 0.0,
            c_xg: 0.0,
            sum_xg: -0.0,
            sum_xx: -0.0,
            prev: None,
            psi_x: 0.0,
            psi_g: 0.0,
            t0: 0.0,
            next_k: 0,
            mark: None,
            arre_sum: 0.0,
        }
    }

    /// Points so far.
    #[must_use]
    pub fn len(&self) -> u64 {
        self.n
    }

    /// True before the first point.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Integrated heading of the (scaled) signal so far, rad.
    #[must_use]
    pub fn heading(&self) -> f64 {
        self.psi_x
    }

    /// Integrated heading of the ground truth so far, rad.
    #[must_use]
    pub fn gt_heading(&self) -> f64 {
        self.psi_g
    }

    /// The (scaled) signal value of the latest point.
    #[must_use]
    pub fn last_value(&self) -> Option<f64> {
        self.prev.map(|p| p.1)
    }

    /// Least-squares scale `k` minimising `sum (k x - g)^2` ([`super::metrics::scale_fit`]).
    #[must_use]
    pub fn scale_fit(&self) -> f64 {
        if self.sum_xx > 0.0 {
            self.sum_xg / self.sum_xx
        } else {
            f64::NAN
        }
    }

    /// Pearson correlation of the (scaled) signal with the ground truth; `NaN` when either is
    /// constant or there are fewer than two points.
    #[must_use]
    pub fn correlation(&self) -> f64 {
        if self.n < 2 || self.m2_x <= 0.0 || self.m2_g <= 0.0 {
            return f64::NAN;
        }
        self.c_xg / (self.m2_x * self.m2_g).sqrt()
    }

    /// Adds the point at time `t` (s, not before the previous one): ground truth `g`, signal `x`
    /// (before the scale).
    ///
    /// # Errors
    /// When the points span more ARRE windows than f64 can place exactly (2^52).
    pub fn push(&mut self, t: f64, g: f64, x: f64) -> Result<()> {
        let x = match self.scale {
            Some(k) => x * k,
            None => x,
        };
        let i = self.n;
        self.n += 1;
        let d = x - g;
        self.sum_sq += d * d;
        self.sum_err += d;
        let nf = self.n as f64;
        let dx = x - self.mean_x;
        self.mean_x += dx / nf;
        let dg = g - self.mean_g;
        self.mean_g += dg / nf;
        self.m2_x += dx * (x - self.mean_x);
        self.m2_g += dg * (g - self.mean_g);
        self.c_xg += dx * (g - self.mean_g);
        self.sum_xg += x * g;
        self.sum_xx += x * x;

        let (psi_x_prev, psi_g_prev) = (self.psi_x, self.psi_g);
        match self.prev {
            None => {
                self.t0 = t;
                // Boundary 0 (and any that round to the first time) is the first point.
                self.mark = Some((0, 0.0, 0.0));
                self.next_k = self.last_boundary_at_or_before(t)? + 1;
            }
            Some((tp, xp, gp)) => {
                self.psi_x += 0.5 * (x + xp) * (t - tp);
                self.psi_g += 0.5 * (g + gp) * (t - tp);
                // The boundaries in (tp, t]: those nearer tp are placed on the previous point,
                // the others on this one (`step_indices`); nearness is monotone in k, so the
                // first and the last boundary tell which of the two points get any.
                let k_hi = self.last_boundary_at_or_before(t)?;
                let k_lo = self.next_k;
                if k_lo <= k_hi {
                    let to_this = |k: i64| {
                        let target = self.target(k);
                        (t - target).abs() < (target - tp).abs()
                    };
                    let (lo_here, hi_here) = (to_this(k_lo), to_this(k_hi));
                    if !lo_here {
                        self.place(i - 1, psi_x_prev, psi_g_prev);
                    }
                    if hi_here {
                        self.place(i, self.psi_x, self.psi_g);
                    }
                    self.next_k = k_hi + 1;
                }
            }
        }
        self.prev = Some((t, x, g));
        Ok(())
    }

    /// The figures, `peak` the largest |ground truth| on the grid.
    #[must_use]
    pub fn metrics(&self, peak: f64) -> Metrics {
        let n = self.n as f64;
        let (rmse, mean) = if self.n == 0 {
            (f64::NAN, f64::NAN)
        } else {
            ((self.sum_sq / n).sqrt(), self.sum_err / n)
        };
        Metrics {
            n: usize::try_from(self.n).unwrap_or(usize::MAX),
            rmse_rad_s: rmse,
            rmse_rel_peak: if peak > 0.0 { rmse / peak } else { f64::NAN },
            correlation: self.correlation(),
            mean_error_rad_s: mean,
            arre_rad: self.arre(),
            heading_rad: self.psi_x,
            final_heading_error_rad: self.psi_x - self.psi_g,
            scale: self.scale,
        }
    }

    /// ARRE ([`super::metrics::arre`]) over the points so far.
    fn arre(&self) -> f64 {
        let (Some((t_end, _, _)), Some((mark, mx, mg))) = (self.prev, self.mark) else {
            return f64::NAN;
        };
        let steps = ((t_end - self.t0) / self.step + 1e-6).floor();
        if !(1.0..=MAX_WINDOWS).contains(&steps) {
            return f64::NAN;
        }
        // Boundaries after the last point (within 1e-6 of a step) are placed on it.
        let n_steps = steps as i64;
        let mut sum = self.arre_sum;
        let last = self.n - 1;
        if self.next_k <= n_steps && mark != last {
            sum += ((self.psi_x - mx) - (self.psi_g - mg)).abs();
        }
        // `step_indices` counts boundaries by the end time; every boundary placed lies at or
        // before it, so `next_k - 1` exceeds `n_steps` only by rounding far below 1e-6 step.
        let windows = n_steps.max(self.next_k - 1);
        sum / windows as f64
    }

    /// Time of window boundary `k`, as [`super::metrics::step_indices`] computes it.
    fn target(&self, k: i64) -> f64 {
        self.t0 + k as f64 * self.step
    }

    /// Places a boundary on point `index`, whose headings are `px` and `pg`.
    fn place(&mut self, index: u64, px: f64, pg: f64) {
        if let Some((mark, mx, mg)) = self.mark {
            // Two boundaries on one point make an empty window: it adds exactly 0.
            if mark != index {
                self.arre_sum += ((px - mx) - (pg - mg)).abs();
            }
        }
        self.mark = Some((index, px, pg));
    }

    /// The largest boundary `k` with `target(k) <= t` (`t` not before the first point).
    fn last_boundary_at_or_before(&self, t: f64) -> Result<i64> {
        let q = ((t - self.t0) / self.step).floor();
        ensure!(
            q <= MAX_WINDOWS,
            "the evaluation spans {} s: too long for ARRE windows of {} s",
            t - self.t0,
            self.step
        );
        let guess = q.max(0.0) as i64;
        let at_or_before = |k: i64| self.target(k) <= t;
        // Bracket the answer between `lo` (at or before t) and `hi` (after it), galloping from
        // the guess, then bisect: exact whatever the rounding of `t0 + k step`.
        let (mut lo, mut hi);
        if at_or_before(guess) {
            lo = guess;
            let mut d = 1i64;
            loop {
                hi = lo.saturating_add(d);
                if !at_or_before(hi) || hi == i64::MAX {
                    break;
                }
                lo = hi;
                d = d.saturating_mul(2);
            }
        } else {
            hi = guess;
            let mut d = 1i64;
            loop {
                lo = (hi - d).max(0);
                if at_or_before(lo) || lo == 0 {
                    break;
                }
                hi = lo;
                d = d.saturating_mul(2);
            }
        }
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if at_or_before(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Ok(lo)
    }
}
