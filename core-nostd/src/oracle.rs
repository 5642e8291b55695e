//! The f64 reference model ("oracle"): the same equations as the fixed-point core, exact in
//! continuous time. Decay between inputs is closed-form, `tau_T != tau_m` is supported
//! (difference of exponentials), and threshold crossings are located by a safeguarded Newton
//! iteration to about 1e-6 µs. Every fixed-point test compares against it. Host only (needs std).

#![allow(clippy::float_arithmetic)]

extern crate std;

use crate::params::TdeParams;

/// Convergence tolerance for crossing times, µs.
const CROSSING_TOL_US: f64 = 1e-6;

/// [`TdeParams`] as f64, times in µs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OracleParams {
    /// `tau_F` (µs).
    pub tau_fac: f64,
    /// `tau_T` (µs).
    pub tau_trg: f64,
    /// `tau_m` (µs).
    pub tau_mem: f64,
    /// `w_F`.
    pub w_fac: f64,
    /// `w_T`.
    pub w_trg: f64,
    /// `theta`.
    pub theta: f64,
    /// `g` per µs.
    pub gain_per_us: f64,
    /// `t_ref` (µs).
    pub t_ref: f64,
}

impl From<&TdeParams> for OracleParams {
    fn from(p: &TdeParams) -> Self {
        Self {
            tau_fac: f64::from(p.tau_fac_us),
            tau_trg: f64::from(p.tau_trg_us),
            tau_mem: f64::from(p.tau_mem_us),
            w_fac: p.w_fac.to_num(),
            w_trg: p.w_trg.to_num(),
            theta: p.theta.to_num(),
            gain_per_us: f64::from(p.gain_per_s) * 1e-6,
            t_ref: f64::from(p.t_ref_us),
        }
    }
}

impl Default for OracleParams {
    fn default() -> Self {
        Self::from(&TdeParams::DEFAULT)
    }
}

/// One unit's state in the oracle; the time it refers to is kept by the caller.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OracleUnit {
    /// TRG trace.
    pub i_trg: f64,
    /// Membrane potential `u` (not normalised).
    pub u: f64,
    /// Remaining refractory time (µs).
    pub refractory: f64,
}

impl OracleParams {
    /// `u(s)` and `u'(s)` for the closed-form evolution from `(u0, i0)`.
    fn membrane(&self, u0: f64, i0: f64, s: f64) -> (f64, f64) {
        let g = self.gain_per_us;
        let em = (-s / self.tau_mem).exp();
        let et = (-s / self.tau_trg).exp();
        if self.equal_taus() {
            let u = (u0 + g * i0 * s) * em;
            (u, g * i0 * em - u / self.tau_mem)
        } else {
            let a = g * i0 * self.tau_trg * self.tau_mem / (self.tau_trg - self.tau_mem);
            let u = (u0 - a) * em + a * et;
            (u, -(u0 - a) / self.tau_mem * em - a / self.tau_trg * et)
        }
    }

    fn equal_taus(&self) -> bool {
        (self.tau_trg - self.tau_mem).abs() <= 1e-9 * self.tau_trg.max(self.tau_mem)
    }

    /// Time from now (µs) of the first crossing of `theta` within `(0, window]`, if any.
    ///
    /// `u(s)` has at most one maximum (at a critical point `u'' = g I' < 0`) and is concave before
    /// it, so: no crossing if `u'(0) <= 0`; otherwise find the peak, and if it reaches `theta`,
    /// Newton from the left converges monotonically to the crossing (bisection guards it).
    pub fn next_crossing(&self, u0: f64, i0: f64, window: f64) -> Option<f64> {
        if u0 >= self.theta {
            return Some(0.0);
        }
        if i0 <= 0.0 || window <= 0.0 {
            return None;
        }
        let (_, d0) = self.membrane(u0, i0, 0.0);
        if d0 <= 0.0 {
            return None;
        }
        let peak = self.peak_time(u0, i0);
        let hi_end = peak.min(window);
        let (u_hi, _) = self.membrane(u0, i0, hi_end);
        if u_hi < self.theta {
            return None;
        }
        // Invariant: u(lo) < theta <= u(hi).
        let (mut lo, mut hi) = (0.0f64, hi_end);
        let mut s = 0.0f64;
        for _ in 0..200 {
            let (u, d) = self.membrane(u0, i0, s);
            if u >= self.theta {
                hi = s;
            } else {
                lo = s;
            }
            let newton = if d > 0.0 {
                s + (self.theta - u) / d
            } else {
                f64::NAN
            };
            let next = if newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
            if (next - s).abs() < CROSSING_TOL_US || hi - lo < CROSSING_TOL_US {
                return Some(next.min(hi));
            }
            s = next;
        }
        Some(hi)
    }

    /// Time (µs) of the membrane's maximum when it is rising at 0.
    fn peak_time(&self, u0: f64, i0: f64) -> f64 {
        if self.equal_taus() {
            return (self.tau_mem - u0 / (self.gain_per_us * i0)).max(0.0);
        }
        // Bisection on u' (positive at 0, negative after the peak).
        let mut hi = self.tau_trg.max(self.tau_mem);
        while self.membrane(u0, i0, hi).1 > 0.0 && hi < 1e12 {
            hi *= 2.0;
        }
        let mut lo = 0.0;
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if self.membrane(u0, i0, mid).1 > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
            if hi - lo < 1e-9 {
                break;
            }
        }
        0.5 * (lo + hi)
    }

    /// Advances `unit` by `dt` µs starting at absolute time `t0` (µs), pushing spike times.
    pub fn advance(&self, unit: &mut OracleUnit, t0: f64, dt: f64, spikes: &mut impl Extend<f64>) {
        self.advance_grazing(unit, t0, dt, spikes, &mut Discard);
    }

    /// [`Self::advance`], also pushing the times of *grazes*: membrane peaks within
    /// [`GRAZE_MARGIN`] of the threshold, below it (a spike nearly happened) or above it (a spike
    /// nearly did not). Whether a graze spikes, and exactly when, is ill-conditioned: it depends
    /// on the state at the 1e-3 level and below, which sub-µs shifts of earlier spikes already move.
    pub fn advance_grazing(
        &self,
        unit: &mut OracleUnit,
        t0: f64,
        dt: f64,
        spikes: &mut impl Extend<f64>,
        grazes: &mut impl Extend<f64>,
    ) {
        let mut t = t0;
        let mut left = dt;
        loop {
            if unit.refractory > 0.0 {
                let r = unit.refractory;
                if left < r {
                    unit.i_trg *= (-left / self.tau_trg).exp();
                    unit.refractory = r - left;
                    return;
                }
                unit.i_trg *= (-r / self.tau_trg).exp();
                unit.refractory = 0.0;
                unit.u = 0.0;
                t += r;
                left -= r;
            }
            let peak = self.peak_within(unit.u, unit.i_trg, left);
            if let Some((tp, up)) = peak {
                if (up - self.theta).abs() <= GRAZE_MARGIN * self.theta {
                    grazes.extend(core::iter::once(t + tp));
                }
            }
            match self.next_crossing(unit.u, unit.i_trg, left) {
                Some(s) => {
                    t += s;
                    left -= s;
                    spikes.extend(core::iter::once(t));
                    unit.i_trg *= (-s / self.tau_trg).exp();
                    unit.u = 0.0;
                    unit.refractory = self.t_ref;
                }
                None => {
                    unit.u = self.membrane(unit.u, unit.i_trg, left).0;
                    unit.i_trg *= (-left / self.tau_trg).exp();
                    return;
                }
            }
        }
    }

    /// Time and value of the membrane's maximum within `(0, window]`, when it is rising at 0.
    fn peak_within(&self, u0: f64, i0: f64, window: f64) -> Option<(f64, f64)> {
        if i0 <= 0.0 || self.membrane(u0, i0, 0.0).1 <= 0.0 {
            return None;
        }
        let tp = self.peak_time(u0, i0).min(window);
        Some((tp, self.membrane(u0, i0, tp).0))
    }
}

/// Relative distance of a membrane peak from the threshold below which the oracle reports a
/// graze (see [`OracleParams::advance_grazing`]).
pub const GRAZE_MARGIN: f64 = 1e-3;

/// A sink that drops everything.
struct Discard;

impl<A> Extend<A> for Discard {
    fn extend<T: IntoIterator<Item = A>>(&mut self, _: T) {}
}

/// One stand-alone TDE in the oracle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct OracleTde {
    /// FAC trace value at `t_fac`.
    pub i_fac: f64,
    /// Time (µs) of `i_fac`.
    pub t_fac: f64,
    /// The unit.
    pub unit: OracleUnit,
    /// Time (µs) of the unit state.
    pub t: f64,
    /// Grazes so far (see [`OracleParams::advance_grazing`]).
    pub grazes: std::vec::Vec<f64>,
}

impl OracleTde {
    /// A unit at rest at time `t0` (µs).
    pub fn new(t0: f64) -> Self {
        Self {
            t_fac: t0,
            t: t0,
            ..Self::default()
        }
    }

    /// FAC trace at `t`.
    pub fn fac_at(&self, p: &OracleParams, t: f64) -> f64 {
        self.i_fac * (-(t - self.t_fac).max(0.0) / p.tau_fac).exp()
    }

    /// A FAC event at `t`.
    pub fn fac(&mut self, p: &OracleParams, t: f64) {
        self.i_fac = self.fac_at(p, t) + p.w_fac;
        self.t_fac = self.t_fac.max(t);
    }

    /// A TRG event at `t`, after emitting the spikes up to `t`.
    pub fn trg(&mut self, p: &OracleParams, t: f64, spikes: &mut impl Extend<f64>) {
        self.advance(p, t, spikes);
        self.unit.i_trg += p.w_trg * self.fac_at(p, t);
    }

    /// Emits the spikes up to `t` and moves the clock there.
    pub fn advance(&mut self, p: &OracleParams, t: f64, spikes: &mut impl Extend<f64>) {
        let dt = (t - self.t).max(0.0);
        p.advance_grazing(&mut self.unit, self.t, dt, spikes, &mut self.grazes);
        self.t += dt;
    }
}

/// Response of a fresh oracle unit to one FAC event at 0 and one TRG event `dt_us` later:
/// the number of spikes and the delay (µs) of the first spike after the TRG event.
pub fn pair_response(p: &OracleParams, dt_us: f64) -> (u32, Option<f64>) {
    let mut tde = OracleTde::new(0.0);
    tde.fac(p, 0.0);
    let mut spikes: std::vec::Vec<f64> = std::vec::Vec::new();
    tde.trg(p, dt_us, &mut spikes);
    tde.advance(
        p,
        dt_us + 20.0 * p.tau_trg.max(p.tau_mem) + 1e6,
        &mut spikes,
    );
    let first = spikes.first().map(|t| t - dt_us);
    (spikes.len() as u32, first)
}

/// The oracle over a whole layout: per-pixel FAC traces and per-unit state in f64, the same
/// wiring as [`crate::network::Network`]. Spikes are `(time µs, unit id)` with the unit id
/// `2 · cell + slot` of [`crate::network::Spike::unit_id`].
pub struct OracleNetwork<L: crate::layout::Layout> {
    p: OracleParams,
    layout: L,
    /// Per cell: FAC trace and its time.
    fac: std::vec::Vec<(f64, f64)>,
    /// Per unit (`2 · cell + slot`): state and its time.
    units: std::vec::Vec<(OracleUnit, f64)>,
    /// Grazes so far, `(time µs, unit id)` (see [`OracleParams::advance_grazing`]).
    pub grazes: std::vec::Vec<(f64, u32)>,
}

impl<L: crate::layout::Layout> OracleNetwork<L> {
    /// A network at rest at time 0.
    pub fn new(p: OracleParams, layout: L) -> Self {
        let n = layout.cell_count();
        Self {
            p,
            layout,
            fac: std::vec![(0.0, 0.0); n],
            units: std::vec![(OracleUnit::default(), 0.0); 2 * n],
            grazes: std::vec::Vec::new(),
        }
    }

    fn fac_at(&self, cell: Option<usize>, t: f64) -> f64 {
        cell.and_then(|c| self.fac.get(c)).map_or(0.0, |&(i, t0)| {
            i * (-(t - t0).max(0.0) / self.p.tau_fac).exp()
        })
    }

    /// One event at time `t` (µs) at pixel `(x, y)`.
    pub fn event(&mut self, t: f64, x: u16, y: u16, spikes: &mut std::vec::Vec<(f64, u32)>) {
        let (sw, sh) = self.layout.sensor();
        if x >= sw || y >= sh {
            return;
        }
        let Some(c) = self.layout.cell(x, y) else {
            return;
        };
        let mask = self.layout.units(c);
        let s = self.layout.stride();
        let inputs = [
            (
                0usize,
                x.checked_sub(s).and_then(|xx| self.layout.cell(xx, y)),
            ),
            (
                1usize,
                x.checked_add(s).and_then(|xx| self.layout.cell(xx, y)),
            ),
        ];
        for (slot, fac_cell) in inputs {
            if mask & (1 << slot) == 0 {
                continue;
            }
            let i_fac = self.fac_at(fac_cell, t);
            let id = 2 * c + slot;
            let p = self.p;
            if let Some((unit, tu)) = self.units.get_mut(id) {
                let dt = (t - *tu).max(0.0);
                let (mut out, mut graze) = (std::vec::Vec::new(), std::vec::Vec::new());
                p.advance_grazing(unit, *tu, dt, &mut out, &mut graze);
                spikes.extend(out.into_iter().map(|ts| (ts, id as u32)));
                self.grazes
                    .extend(graze.into_iter().map(|ts| (ts, id as u32)));
                *tu += dt;
                unit.i_trg += p.w_trg * i_fac;
            }
        }
        let now = self.fac_at(Some(c), t);
        if let Some(f) = self.fac.get_mut(c) {
            *f = (now + self.p.w_fac, f.1.max(t));
        }
    }

    /// Emits every spike up to `t`.
    pub fn flush(&mut self, t: f64, spikes: &mut std::vec::Vec<(f64, u32)>) {
        let p = self.p;
        for (id, (unit, tu)) in self.units.iter_mut().enumerate() {
            let dt = (t - *tu).max(0.0);
            let (mut out, mut graze) = (std::vec::Vec::new(), std::vec::Vec::new());
            p.advance_grazing(unit, *tu, dt, &mut out, &mut graze);
            spikes.extend(out.into_iter().map(|ts| (ts, id as u32)));
            self.grazes
                .extend(graze.into_iter().map(|ts| (ts, id as u32)));
            *tu += dt;
        }
    }
}

/// The calibrated pipeline in f64 (see [`crate::readout::calibrated`] for the method): onset
/// filter, FAC traces, per-trigger decoding with exact logarithms, leaky histograms over the
/// same bins, the same aggregation. An independent implementation to check the fixed-point one.
pub struct OracleYaw<L: crate::layout::Layout> {
    p: OracleParams,
    layout: L,
    focal: f64,
    cx: f64,
    /// Histogram time constant and output period (µs).
    tau_a: f64,
    period: f64,
    alpha: f64,
    prior: f64,
    /// Onset gap (µs).
    gap: f64,
    /// Per cell: FAC trace, its time, last polarity.
    fac: std::vec::Vec<(f64, f64, bool)>,
    hist: [[[f64; ORACLE_BINS]; 2]; 2],
    next_out: Option<f64>,
    last_event: f64,
    /// Decoded bursts so far.
    pub samples: u64,
}

const ORACLE_BINS: usize = 64;

impl<L: crate::layout::Layout> OracleYaw<L> {
    /// The pipeline with the calibrated readout's defaults (`alpha` 0.3, prior 3), readout time
    /// constant `tau_a_us`, onset gap `gap_us` and output period `period_us`.
    pub fn new(
        p: OracleParams,
        layout: L,
        focal: f64,
        cx: f64,
        period_us: f64,
        gap_us: f64,
        tau_a_us: f64,
    ) -> Self {
        let n = layout.cell_count();
        Self {
            p,
            layout,
            focal,
            cx,
            tau_a: tau_a_us,
            period: period_us,
            alpha: 0.3,
            prior: 3.0,
            gap: gap_us,
            fac: std::vec![(0.0, 0.0, false); n],
            hist: [[[0.0; ORACLE_BINS]; 2]; 2],
            next_out: None,
            last_event: 0.0,
            samples: 0,
        }
    }

    fn fac_at(&self, c: Option<usize>, t: f64) -> f64 {
        c.and_then(|c| self.fac.get(c)).map_or(0.0, |&(i, t0, _)| {
            i * (-(t - t0).max(0.0) / self.p.tau_fac).exp()
        })
    }

    /// One event at time `t` (µs); pushes `(t_us, yaw rad/s, stale)` for every output before it.
    pub fn event(
        &mut self,
        t: f64,
        x: u16,
        y: u16,
        on: bool,
        out: &mut std::vec::Vec<(f64, f64, bool)>,
    ) {
        match self.next_out {
            None => self.next_out = Some(t + self.period),
            Some(_) => self.emit_until(t, false, out),
        }
        self.last_event = t;
        let (sw, sh) = self.layout.sensor();
        if x >= sw || y >= sh {
            return;
        }
        let Some(c) = self.layout.cell(x, y) else {
            return;
        };
        let own_now = self.fac_at(Some(c), t);
        let was_on = self.fac.get(c).is_some_and(|f| f.2);
        if let Some(f) = self.fac.get_mut(c) {
            f.2 = on;
        }
        if was_on == on && own_now >= self.p.w_fac * (-self.gap / self.p.tau_fac).exp() {
            return;
        }
        let mask = self.layout.units(c);
        let s = i32::from(self.layout.stride());
        let nb = |dx: i32| {
            u16::try_from(i32::from(x) + dx)
                .ok()
                .and_then(|nx| self.layout.cell(nx, y))
        };
        let lr = if mask & 1 != 0 {
            self.p.w_trg * self.fac_at(nb(-s), t)
        } else {
            0.0
        };
        let rl = if mask & 2 != 0 {
            self.p.w_trg * self.fac_at(nb(s), t)
        } else {
            0.0
        };
        let own = own_now + self.p.w_fac;
        if let Some(f) = self.fac.get_mut(c) {
            *f = (own, t, on);
        }
        if mask == 0 {
            return;
        }
        let (drive, positive) = if rl > lr { (rl, true) } else { (lr, false) };
        // A burst from rest needs q tau / e >= 1 with q = g I / theta per µs.
        let min_drive = core::f64::consts::E * self.p.theta / (self.p.gain_per_us * self.p.tau_trg);
        let ratio = drive / (self.p.w_trg * own);
        if drive < min_drive || !(ratio > 0.0 && ratio < 1.0) {
            return;
        }
        let dt_s = -self.p.tau_fac * ratio.ln() * 1e-6;
        let dx = f64::from(x) - self.cx;
        let g = self.focal + dx * dx / self.focal;
        let w = f64::from(self.layout.stride()) / (dt_s * g);
        let (lo, hi) = (0.02f64.ln(), 20.0f64.ln());
        let bin = (((w.ln() - lo) / ((hi - lo) / ORACLE_BINS as f64)).floor())
            .clamp(0.0, ORACLE_BINS as f64 - 1.0) as usize;
        let half = usize::from(f64::from(x) >= self.cx);
        if let Some(b) = self
            .hist
            .get_mut(half)
            .and_then(|h| h.get_mut(usize::from(positive)))
            .and_then(|h| h.get_mut(bin))
        {
            *b += 1.0;
            self.samples += 1;
        }
    }

    /// Emits every output up to `t` (µs) inclusive (end of the recording).
    pub fn finish(&mut self, t: f64, out: &mut std::vec::Vec<(f64, f64, bool)>) {
        self.emit_until(t, true, out);
    }

    fn emit_until(&mut self, t: f64, inclusive: bool, out: &mut std::vec::Vec<(f64, f64, bool)>) {
        let Some(mut next) = self.next_out else {
            return;
        };
        while next < t || (inclusive && next <= t) {
            let est = [self.half(0), self.half(1)];
            let keep = (-self.period / self.tau_a).exp();
            for b in self.hist.iter_mut().flatten().flatten() {
                *b *= keep;
            }
            let v = match est {
                [Some((l, sl)), Some((r, sr))] if sl == sr => {
                    let m = 0.5 * (l + r);
                    if sl {
                        m
                    } else {
                        -m
                    }
                }
                _ => 0.0,
            };
            out.push((next, v, next - self.last_event > 100_000.0));
            next += self.period;
        }
        self.next_out = Some(next);
    }

    fn half(&self, h: usize) -> Option<(f64, bool)> {
        let [neg, pos] = self.hist.get(h)?;
        let (sn, sp): (f64, f64) = (neg.iter().sum(), pos.iter().sum());
        let (win, lose, positive) = if sp >= sn {
            (pos, neg, true)
        } else {
            (neg, pos, false)
        };
        let net: std::vec::Vec<f64> = win
            .iter()
            .zip(lose)
            .map(|(w, l)| (w - l).max(0.0))
            .collect();
        let net_sum: f64 = net.iter().sum();
        if net_sum == 0.0 || net_sum < self.alpha * (sn + sp) {
            return None;
        }
        let half_mass = 0.5 * (net_sum + self.prior);
        if self.prior >= half_mass {
            return None;
        }
        let (lo, hi) = (0.02f64.ln(), 20.0f64.ln());
        let bw = (hi - lo) / ORACLE_BINS as f64;
        let mut acc = self.prior;
        for (i, &m) in net.iter().enumerate() {
            if m > 0.0 && acc + m >= half_mass {
                let frac = (half_mass - acc) / m;
                return Some(((lo + (i as f64 + frac) * bw).exp(), positive));
            }
            acc += m;
        }
        None
    }
}
