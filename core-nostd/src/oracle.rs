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
    /// The smallest drive that makes a burst from rest (`q tau / e >= 1`, `q = g I / theta` per
    /// µs).
    fn min_drive(&self) -> f64 {
        core::f64::consts::E * self.theta / (self.gain_per_us * self.tau_trg)
    }

    /// The longest crossing (s) these units time at a pixel with one onset (own trace `w_F`):
    /// where `w_T w_F e^(-dt/tau_F)` falls to [`OracleParams::min_drive`].
    fn reach_s(&self) -> f64 {
        self.tau_fac * (self.w_trg * self.w_fac / self.min_drive()).ln() * 1e-6
    }

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

/// One output sample `(t_us, yaw rad/s, flags)` of the rad/s readouts at `t` (µs): the
/// readout's value and flags, plus [`crate::flags::STALE`] more than 100 ms after the last
/// event (`last_event`, µs).
fn sample(t: f64, last_event: f64, (v, flags): (f64, u8)) -> (f64, f64, u8) {
    let stale = if t - last_event > 100_000.0 {
        crate::flags::STALE
    } else {
        0
    };
    (t, v, flags | stale)
}

/// The calibrated pipeline in f64 (see [`crate::readout::calibrated`] and
/// [`crate::readout::field`] for the method): onset filter, fast and slow FAC traces,
/// per-trigger decoding with exact logarithms, leaky histograms per region decayed exactly each
/// period, the same mirrored-pair estimator. An independent implementation to check the
/// fixed-point one.
pub struct OracleYaw<L: crate::layout::Layout> {
    p: OracleParams,
    layout: L,
    focal: f64,
    cx: f64,
    /// Output period (µs).
    period: f64,
    /// Onset gap (µs).
    gap: f64,
    /// Slow FAC time constant (µs).
    tau_slow: f64,
    /// Per cell: FAC trace, slow trace, their time, last polarity.
    fac: std::vec::Vec<(f64, f64, f64, bool)>,
    /// The field of each population: 0 = the paper's units (over `tau_A`), 1 = the slow units
    /// (over at least `SLOW_TAU_A_US`).
    fields: [OracleField; 2],
    next_out: Option<f64>,
    /// What each output says.
    gate: OracleGate,
    last_event: f64,
    /// Whether the layout's units have twins ([`crate::readout::calibrated::has_twins`]).
    twins: bool,
    /// Whether the near units or the layout's are decoded.
    stride: OracleStrideChoice,
    /// Decoded bursts so far.
    pub samples: u64,
}

/// [`crate::readout::stride_choice`] in f64: the paper's units' decodes of both strides per
/// region and sign, decayed exactly each period; the near units answer while their sign
/// agreement is at least the layout's, the choice changing when the other leads by
/// [`crate::readout::stride_choice::SWITCH_MARGIN`].
struct OracleStrideChoice {
    /// Decodes `[near, layout][region][negative, positive]`.
    counts: [[[f64; 2]; crate::readout::field::REGIONS]; 2],
    /// Whether the sign counts choose the near units.
    near: bool,
    /// Whether the readout's answer says the image moves fast
    /// ([`crate::readout::stride_choice::FAST_IMAGE_SPEED_PX_S`]).
    fast: bool,
    /// Time since the start (µs).
    settled: f64,
    /// Outputs since the last look.
    outputs: u32,
}

impl OracleStrideChoice {
    /// No decodes yet; the near units decode first if the layout has them (`near`).
    fn new(near: bool) -> Self {
        Self {
            counts: [[[0.0; 2]; crate::readout::field::REGIONS]; 2],
            near,
            fast: false,
            settled: 0.0,
            outputs: 0,
        }
    }

    /// Whether the near units are decoded: the sign counts' choice, unless the image moves
    /// fast.
    fn near(&self) -> bool {
        self.near && !self.fast
    }

    /// The readout's answer at an output (`(rad/s, flags)`) with the focal length `focal` (px):
    /// whether the image moves fast at the principal point, with the fixed-point readouts'
    /// hysteresis.
    fn follow_answer(&mut self, (yaw, flags): (f64, u8), focal: f64) {
        let px_s = if flags & crate::flags::NO_EVIDENCE == 0 {
            // Whole px/s, as the fixed-point readouts compute it.
            (yaw.abs() * focal) as u64
        } else {
            0
        };
        self.fast = crate::readout::stride_choice::moves_fast(self.fast, px_s);
    }

    /// One decode of the paper's units (`near`: of the near units) in `region`, with its sign.
    fn add(&mut self, near: bool, region: usize, positive: bool) {
        if let Some(c) = self
            .counts
            .get_mut(usize::from(!near))
            .and_then(|r| r.get_mut(region))
            .and_then(|c| c.get_mut(usize::from(positive)))
        {
            *c += 1.0;
        }
    }

    fn agreement(&self, stride: usize) -> f64 {
        self.counts.get(stride).map_or(0.0, |regions| {
            regions.iter().map(|&[n, p]| sign_agreement(n, p)).sum()
        })
    }

    /// One output period of `period` µs (the counts are looked at every
    /// [`crate::readout::stride_choice::LOOK_EVERY`] outputs, as in the fixed-point readout).
    fn age(&mut self, period: f64) {
        use crate::readout::stride_choice::{LOOK_EVERY, MEMORY_US, SETTLE_US};
        self.settled += period;
        self.outputs += 1;
        if self.outputs < LOOK_EVERY {
            return;
        }
        self.outputs = 0;
        let period = period * f64::from(LOOK_EVERY);
        if self.settled >= f64::from(SETTLE_US) - 0.5 {
            let (near, layout) = (self.agreement(0), self.agreement(1));
            if near > 0.0 || layout > 0.0 {
                let margin = f64::from(crate::readout::stride_choice::SWITCH_MARGIN);
                self.near = if self.near {
                    layout <= near + margin
                } else {
                    near >= layout + margin
                };
            }
        }
        let keep = (-period / f64::from(MEMORY_US)).exp();
        for c in self.counts.iter_mut().flatten().flatten() {
            *c *= keep;
        }
    }
}

const ORACLE_BINS: usize = crate::readout::field::BINS;
const COLS: usize = crate::readout::field::COL_BANDS;
const SETTLED_MINORITY_LOG2: u32 = crate::readout::field::SETTLED_MINORITY_LOG2;
const ROWS: usize = crate::readout::field::ROW_BANDS;

impl<L: crate::layout::Layout> OracleYaw<L> {
    /// The pipeline with the calibrated readout's default field settings, principal point
    /// `(cx, cy)`, readout time constant `tau_a_us`, onset gap `gap_us` and output period
    /// `period_us`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        p: OracleParams,
        layout: L,
        focal: f64,
        (cx, cy): (f64, f64),
        period_us: f64,
        gap_us: f64,
        tau_a_us: f64,
    ) -> Self {
        let n = layout.cell_count();
        let slow_tau = tau_a_us.max(f64::from(crate::readout::calibrated::SLOW_TAU_A_US));
        let field = |tau| OracleField::new(&layout, focal, (cx, cy), tau, period_us);
        let fields = [
            field(tau_a_us).stops_briefly(),
            field(slow_tau)
                .beyond_floor_over(tau_a_us)
                .stops_when_split(),
        ];
        let twins = crate::readout::calibrated::has_twins(&layout);
        let stride = OracleStrideChoice::new(crate::readout::calibrated::has_near(&layout));
        Self {
            p,
            layout,
            focal,
            cx,
            period: period_us,
            gap: gap_us,
            tau_slow: f64::from(crate::params::TAU_SLOW_US),
            fac: std::vec![(0.0, 0.0, 0.0, false); n],
            fields,
            next_out: None,
            gate: OracleGate::new(period_us, p, focal),
            last_event: 0.0,
            twins,
            stride,
            samples: 0,
        }
    }

    fn traces_at(&self, c: Option<usize>, t: f64) -> (f64, f64) {
        c.and_then(|c| self.fac.get(c))
            .map_or((0.0, 0.0), |&(i, s, t0, _)| {
                let dt = (t - t0).max(0.0);
                (
                    i * (-dt / self.p.tau_fac).exp(),
                    s * (-dt / self.tau_slow).exp(),
                )
            })
    }

    /// One event at time `t` (µs); pushes `(t_us, yaw rad/s, flags)` for every output before
    /// it (flags as [`crate::flags`]: stale, no evidence).
    pub fn event(
        &mut self,
        t: f64,
        x: u16,
        y: u16,
        on: bool,
        out: &mut std::vec::Vec<(f64, f64, u8)>,
    ) {
        match self.next_out {
            None => {
                self.next_out = Some(t + self.period);
            }
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
        let (own_now, own_slow_now) = self.traces_at(Some(c), t);
        let was_on = self.fac.get(c).is_some_and(|f| f.3);
        if let Some(f) = self.fac.get_mut(c) {
            f.3 = on;
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
        let zero = (0.0, 0.0);
        let lr = if mask & 1 != 0 {
            self.traces_at(nb(-s), t)
        } else {
            zero
        };
        let rl = if mask & 2 != 0 {
            self.traces_at(nb(s), t)
        } else {
            zero
        };
        // The near units' FAC pixels, one pixel away (when the stride is above 1).
        let near_at = |slot: u8, dx: i32| {
            if s > 1 && mask & (1 << slot) != 0 {
                self.traces_at(nb(dx), t)
            } else {
                zero
            }
        };
        let (near_lr, near_rl) = (near_at(0, -1), near_at(1, 1));
        let slow_onset = was_on != on
            || own_slow_now
                < self.p.w_fac
                    * (-f64::from(crate::network::SLOW_ONSET_GAP_US) / self.tau_slow).exp();
        let own = own_now + self.p.w_fac;
        let own_slow = own_slow_now + if slow_onset { self.p.w_fac } else { 0.0 };
        if let Some(f) = self.fac.get_mut(c) {
            *f = (own, own_slow, t, on);
        }
        if mask == 0 {
            return;
        }
        let min_drive = self.p.min_drive();
        let decode = |lr: f64, rl: f64, own: f64, tau: f64| -> Option<(f64, bool)> {
            let (drive, lose, positive) = if rl > lr {
                (self.p.w_trg * rl, self.p.w_trg * lr, true)
            } else {
                (self.p.w_trg * lr, self.p.w_trg * rl, false)
            };
            if lose * f64::from(1u32 << crate::readout::calibrated::DOMINANCE_LOG2) > drive {
                return None;
            }
            let ratio = drive / (self.p.w_trg * own);
            if drive < min_drive || !(ratio > 0.0 && ratio < 1.0) {
                return None;
            }
            Some((-tau * ratio.ln() * 1e-6, positive))
        };
        // The slow units' decode, where the pixel's scene is slow.
        let decode_slow = |lr: (f64, f64), rl: (f64, f64)| {
            if !slow_onset || own_slow >= 8.0 || own >= self.p.w_fac + 0.1 {
                None
            } else {
                decode(lr.1, rl.1, own_slow, self.tau_slow)
            }
        };
        let decode_stride = |lr: (f64, f64), rl: (f64, f64)| {
            decode(lr.0, rl.0, own, self.p.tau_fac)
                .map(|d| (d, 0))
                .or_else(|| decode_slow(lr, rl).map(|d| (d, 1)))
        };
        let far = decode_stride(lr, rl);
        let near = decode_stride(near_lr, near_rl);
        let [fast_field, _] = &self.fields;
        let region = fast_field.region_index(x, y);
        let counted = crate::readout::stride_choice::StrideChoice::counts_row(y);
        for (is_near, decoded) in [(true, near), (false, far)] {
            if let (Some(((_, positive), 0)), true) = (decoded, counted) {
                self.stride.add(is_near, region, positive);
            }
        }
        if self.gate.warmup_outputs > 0 {
            // The warm-up's bursts time the pixels waking up (the fixed-point readout's rule).
            return;
        }
        let (decoded, stride) = if self.stride.near() {
            (near, 1.0)
        } else {
            (far, f64::from(self.layout.stride()))
        };
        let Some(((dt_s, positive), pop)) = decoded else {
            return;
        };
        if pop == 0 {
            // An edge that moves mostly vertically (the paper's units' decodes), by the traces
            // of the pixels the stride above and below.
            let row = |dy: i32| {
                u16::try_from(i32::from(y) + dy)
                    .ok()
                    .and_then(|ny| self.layout.cell(x, ny))
            };
            let l2_h = -dt_s * 1e6 / (self.p.tau_fac * core::f64::consts::LN_2);
            if aperture_moves_vertically(
                l2_h,
                [stride, f64::from(self.layout.stride())],
                [row(-s), row(s)].map(|c| log2_to(self.traces_at(c, t).0, own)),
                log2_to(own_now, own),
                (min_drive / (self.p.w_trg * own)).log2(),
            ) {
                return;
            }
        }
        let dx = f64::from(x) - self.cx;
        let g = self.focal + dx * dx / self.focal;
        let w = stride / (dt_s * g);
        // Within an octave above the paper's units' floor (a crossing between half their reach
        // and their reach), of an onset the slow units decode too: beyond the slow units' floor.
        let reach = self.p.reach_s();
        if pop == 0 && dt_s >= reach / 2.0 {
            let slow = if self.stride.near() {
                decode_slow(near_lr, near_rl)
            } else {
                decode_slow(lr, rl)
            };
            if let (Some((_, slow_positive)), Some(slow_field)) = (slow, self.fields.get_mut(1)) {
                slow_field.add_beyond_floor(x, y, slow_positive, stride / (reach * g));
            }
        }
        if let Some(field) = self.fields.get_mut(pop) {
            field.add(x, y, if positive { w } else { -w });
            self.samples += 1;
        }
    }

    /// Emits every output up to `t` (µs) inclusive (end of the recording).
    pub fn finish(&mut self, t: f64, out: &mut std::vec::Vec<(f64, f64, u8)>) {
        self.emit_until(t, true, out);
    }

    fn emit_until(&mut self, t: f64, inclusive: bool, out: &mut std::vec::Vec<(f64, f64, u8)>) {
        let Some(mut next) = self.next_out else {
            return;
        };
        while next < t || (inclusive && next <= t) {
            self.stride.age(self.period);
            let value = self.gate.output(&mut self.fields, self.twins);
            self.stride.follow_answer(value, self.focal);
            out.push(sample(next, self.last_event, value));
            next += self.period;
        }
        self.next_out = Some(next);
    }
}

/// The intercept at `Y = 0` and its variance of a column band's fit over the halves in
/// `used` (above, below the principal row), from their [`OracleField::half_sums`], each half
/// with its own slope (prior 0.25 on `Σ w Y²`); `None` without weight.
fn oracle_fit(sums: &[[f64; 5]; 2], used: [bool; 2]) -> Option<(f64, f64)> {
    let halves = || sums.iter().zip(used).filter(|(_, u)| *u).map(|(h, _)| h);
    let (mut info, mut rhs) = halves().fold((0.0, 0.0), |(s, r), h| (s + h[0], r + h[1]));
    if info <= 0.0 {
        return None;
    }
    for &[_, _, sy, syy, sry] in halves() {
        if sy != 0.0 {
            info -= sy * sy / (syy + 0.25);
            rhs -= sy * sry / (syy + 0.25);
        }
    }
    if info <= 0.0 {
        return None;
    }
    Some((rhs / info, 1.0 / info))
}

/// [`crate::readout::shared::OutputGate`] in f64: "no evidence" for the first
/// [`crate::readout::shared::WARMUP_US`], then the field's estimate, read every
/// [`crate::readout::shared::REFRESH_US`] and repeated between, when
/// [`crate::readout::shared::Confirmation`] passes it.
struct OracleGate {
    /// Outputs still to suppress.
    warmup_outputs: u32,
    /// Outputs per reading of the field (at least 1).
    refresh: u32,
    /// Outputs since the last reading, modulo `refresh`.
    phase: u32,
    /// What the outputs say until the next reading (`None`: no evidence).
    last: Option<f64>,
    /// Whether the readings so far make an answer, and how long since the last (the
    /// fixed-point gate's rule).
    answers: crate::readout::shared::Answers,
}

impl OracleGate {
    /// The gate of units `p` behind a camera of focal length `focal` (px): the units' slowest
    /// rotation is a one-pixel crossing in the slow units' window at the principal point
    /// (`readout::shared::slowest_rate_q16`).
    fn new(period_us: f64, p: OracleParams, focal: f64) -> Self {
        let period = (period_us as u32).max(1);
        let slow = OracleParams {
            tau_fac: f64::from(crate::params::TAU_SLOW_US),
            ..p
        };
        let floor = 1.0 / (focal * slow.reach_s());
        Self {
            warmup_outputs: crate::readout::shared::WARMUP_US.div_ceil(period),
            refresh: (crate::readout::shared::REFRESH_US / period).max(1),
            phase: 0,
            last: None,
            answers: crate::readout::shared::Answers::new((floor * 65_536.0).round() as u32),
        }
    }

    /// One output period: reads the fields when due, ages them, and says what to output.
    fn output(&mut self, fields: &mut [OracleField; 2], twins: bool) -> (f64, u8) {
        if self.phase == 0 {
            for field in fields.iter_mut() {
                field.established = self.answers.established();
                field.recent_motion = self.answers.last_answer();
            }
            let reading = two_population_estimate(fields, twins);
            let answer = self.answers.read(&reading.fixed());
            self.last = reading.estimate.filter(|_| answer);
        }
        self.phase = (self.phase + 1) % self.refresh;
        for field in fields.iter_mut() {
            field.age();
        }
        let est = if self.warmup_outputs > 0 {
            self.warmup_outputs -= 1;
            None
        } else {
            self.last
        };
        est.map_or((0.0, crate::flags::NO_EVIDENCE), |v| (v, 0))
    }
}

/// What an [`OracleField`] shows: the fixed-point field's `FieldReading` with the rotation in
/// rad/s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OracleReading {
    /// The rotation (rad/s), if the field shows one.
    pub estimate: Option<f64>,
    /// It needed the readout's answer a moment ago to show it (`FieldReading::recent_needed`).
    pub recent_needed: bool,
    /// It shows none because its decodes stopped (`FieldReading::stopped`).
    pub stopped: bool,
    /// It shows none because the slow units' latest decodes split in sign
    /// (`FieldReading::blind`).
    pub blind: bool,
}

impl OracleReading {
    /// No rotation, for want of evidence.
    const NOTHING: Self = Self {
        estimate: None,
        recent_needed: false,
        stopped: false,
        blind: false,
    };

    /// The same reading in the fixed-point gate's units (Q16 rad/s; the estimate is clamped
    /// to 20 rad/s, so it fits).
    fn fixed(&self) -> crate::readout::field::FieldReading {
        use crate::readout::field::{FieldEstimate, FieldReading};
        FieldReading {
            estimate: self.estimate.map_or(FieldEstimate::NoEvidence, |v| {
                FieldEstimate::Rotation((v * 65536.0) as i32)
            }),
            recent_needed: self.recent_needed,
            stopped: self.stopped,
            blind: self.blind,
        }
    }
}

/// The estimate of the population (0: the paper's units, 1: the slow units) whose decodes
/// agree more in sign per unit of its time constant (`twins == false`, a layout without twin
/// units: that decodes more), the slow units' figure scaled up while their histograms fill
/// ([`OracleField::fill`]); the slow units' value scaled by their recent share of decodes.
/// With the reading's reasons ([`OracleField::reading`]).
fn two_population_estimate(fields: &[OracleField; 2], twins: bool) -> OracleReading {
    let [fast, slow] = fields;
    let by = |f: &OracleField| {
        if twins {
            f.consistent_rate()
        } else {
            f.rate()
        }
    };
    if by(fast) < by(slow) * slow.fill() {
        let reading = slow.reading();
        OracleReading {
            estimate: reading.estimate.map(|v| v * slow.recent_share()),
            ..reading
        }
    } else {
        fast.reading()
    }
}

/// The spike readout in f64 (see [`crate::readout::spikes`] for the method), on the oracle's
/// own spikes: onset filter, exact FAC traces, units advanced by [`OracleParams::advance`]
/// (each output time moves every unit that may still spike to it, so that an output at `T`
/// sees exactly the spikes up to `T`, in time order), the closed-form decoding of each burst
/// in exact arithmetic, the pixel's own trace rebuilt from its decoded onsets, the twin rule,
/// and leaky histograms per region decayed exactly each period with the field estimator of
/// [`crate::readout::field`]. No pool: every unit is tracked. An independent implementation
/// to check the fixed-point one.
pub struct OracleSpikeYaw<L: crate::layout::Layout> {
    layout: L,
    focal: f64,
    cx: f64,
    period: f64,
    /// The paper's units (0), the slow units (1, `tau_F` = [`crate::params::TAU_SLOW_US`])
    /// and, on layouts that have them, the near units (2: the paper's units at stride 1).
    pops: std::vec::Vec<SpikePopulation>,
    /// The field of each population (as [`OracleYaw`]'s).
    fields: [OracleField; 2],
    twins: bool,
    /// A slow decode is dropped when the pixel's previous onset came up to this long (µs)
    /// before it (`tau_F ln 10` of the paper's units).
    busy_window: f64,
    /// Whether the near units or the layout's are read.
    stride: OracleStrideChoice,
    /// The shortest crossing of one pixel (s) read from the near units.
    near_floor_s: f64,
    next_out: Option<f64>,
    /// TRG events before this time (µs) are not decoded (the warm-up).
    decode_from: f64,
    /// What each output says.
    gate: OracleGate,
    last_event: f64,
    /// Spikes received (both populations).
    pub spikes: u64,
    /// Decodes added to the field.
    pub samples: u64,
}

/// One population of the spike readout's oracle: its network (onset filter, exact FAC traces,
/// units) and the decoder's view of its bursts.
struct SpikePopulation {
    p: OracleParams,
    /// FAC-to-TRG distance (px).
    stride: i32,
    /// Whether these are the near units (else the layout's stride).
    near: bool,
    /// Onset gap (µs).
    gap: f64,
    /// Per cell: FAC trace, its time, last polarity.
    fac: std::vec::Vec<(f64, f64, bool)>,
    /// Per unit (`2 · cell + slot`): the oracle's state and its time.
    units: std::vec::Vec<(OracleUnit, f64)>,
    /// Units that may still spike without input, and whether each is listed.
    active: std::vec::Vec<u32>,
    listed: std::vec::Vec<bool>,
    /// Spikes since the last output, `(time, unit)`.
    pending: std::vec::Vec<(f64, u32)>,
    /// Per unit: the decoder's view of its burst.
    tracks: std::vec::Vec<SpikeTrack>,
    /// Per cell: the last decoded onset `(time, own trace after it, whether the onset before
    /// it came within the busy window)`, and each unit's decoded drive for it and whether
    /// that decode waits for the twin.
    onsets: std::vec::Vec<Option<(f64, f64, bool)>>,
    decodes: std::vec::Vec<[(Option<f64>, bool); 2]>,
    /// Cells with a decode waiting, in order.
    waiting: std::collections::VecDeque<u32>,
    /// Cells with a unit whose burst from rest has shown one spike, in the order they came
    /// (each once: `lone_listed`), as the fixed readout's queue.
    lone_queue: std::collections::VecDeque<u32>,
    lone_listed: std::vec::Vec<bool>,
    /// A lone spike's drive and latency (µs) when no decoded onset says when its TRG event
    /// came: the middle of the one-spike range's drives (in logarithm), `x(latency)` = drive.
    lone_guess: (f64, f64),
    /// The slow units: the longest crossing (s) the paper's units time at a pixel without a
    /// recent onset; shorter crossings, and decodes at a pixel whose previous onset came
    /// within the busy window, are theirs. `None` for the paper's units.
    fast_reach_s: Option<f64>,
    /// The slow units' FAC pixel distance before the output time `stride_since` (µs), at
    /// which it became `stride` (it follows the stride choice: the fixed-point readout's
    /// `SlowFacPixel`).
    stride_before: i32,
    stride_since: f64,
}

/// A pixel's last decoded onset in a [`SpikePopulation`]: `(time, own trace after it, whether
/// the onset before it came within the busy window)`.
type DecodedOnset = Option<(f64, f64, bool)>;

/// What a population's decodes go to (the parts [`OracleSpikeYaw`] shares between them).
struct SpikeTarget<'t, L: crate::layout::Layout> {
    layout: &'t L,
    focal: f64,
    cx: f64,
    field: &'t mut OracleField,
    decode_from: f64,
    busy_window: f64,
    stride: &'t mut OracleStrideChoice,
    near_floor_s: f64,
    samples: &'t mut u64,
    /// For the paper's units beside near units: the other network's decoder state (the near
    /// units' for the layout's units, the layout's for the near units); its decoded onsets
    /// also serve the vertical neighbours.
    peer: Option<PeerView<'t>>,
}

/// What one network of the paper's units reads of the other's decoding beside it (the layout's
/// units of the near units', the near units of the layout's; see [`crate::readout::spikes`],
/// "Near units"): per cell the last decoded onset and each unit's decoded drive for it.
struct PeerView<'t> {
    onsets: &'t [DecodedOnset],
    decodes: &'t [[(Option<f64>, bool); 2]],
    /// The share of its ceiling above which a near unit's drive is not read.
    share: f64,
    w_trg: f64,
}

impl PeerView<'_> {
    /// The share of its ceiling of the drive with which unit `u` of `cell` decoded the onset
    /// at `t_trg`, if it did.
    fn decoded_share(&self, cell: usize, u: usize, t_trg: f64) -> Option<f64> {
        let (t0, own, _) = self.onsets.get(cell).copied().flatten()?;
        let d = self.decodes.get(cell)?.get(u)?.0?;
        ((t_trg - t0).abs() <= SAME_ONSET_F64).then(|| d / (self.w_trg * own))
    }

    /// Whether near unit `u` of `cell` decoded the onset at `t_trg` above its share of the
    /// ceiling: an edge the near units cannot time.
    fn decoded_at_ceiling(&self, cell: usize, u: usize, t_trg: f64) -> bool {
        self.decoded_share(cell, u, t_trg)
            .is_some_and(|share| share > self.share)
    }

    /// Whether layout unit `u` of `cell` decoded the onset at `t_trg` as crossing its `stride`
    /// faster than a near unit read one pixel at `near_share` of its ceiling, and quickly
    /// enough to overrule it (the fixed-point readout's `SpikeCell::overrules`).
    fn overrules(&self, cell: usize, u: usize, t_trg: f64, near_share: f64, stride: f64) -> bool {
        let floors = f64::from(crate::readout::spikes::OVERRULING_FLOORS);
        let quick = self.share.powf(floors * stride);
        self.decoded_share(cell, u, t_trg)
            .is_some_and(|share| share > near_share && share > quick)
    }
}

/// The decoder's view of one unit (see [`crate::readout::spikes`]).
#[derive(Clone, Copy, Debug, PartialEq)]
enum SpikeTrack {
    /// Nothing known.
    Idle,
    /// One spike of a burst from rest at `t1`.
    Rest { t1: f64 },
    /// An early spike at `t` ending an interval of `m` µs that started with current `y`.
    Pert { t: f64, m: f64, y: f64 },
    /// A spike at `t` after which the membrane charges with current `y`.
    Clean { t: f64, y: f64 },
    /// A spike at `t` with no usable history.
    Unknown { t: f64 },
}

impl<L: crate::layout::Layout> OracleSpikeYaw<L> {
    /// The pipeline with the spike readout's settings (those of the calibrated readout's field),
    /// principal point `(cx, cy)`, readout time constant `tau_a_us`, onset gap `gap_us` and
    /// output period `period_us`; the slow units are `p` with `tau_F` =
    /// [`crate::params::TAU_SLOW_US`].
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        p: OracleParams,
        layout: L,
        focal: f64,
        (cx, cy): (f64, f64),
        period_us: f64,
        gap_us: f64,
        tau_a_us: f64,
    ) -> Self {
        let n = layout.cell_count();
        let slow_tau = tau_a_us.max(f64::from(crate::readout::calibrated::SLOW_TAU_A_US));
        let field = |tau| OracleField::new(&layout, focal, (cx, cy), tau, period_us);
        let fields = [
            field(tau_a_us).stops_briefly(),
            field(slow_tau)
                .beyond_floor_over(tau_a_us)
                .stops_when_split(),
        ];
        let slow = OracleParams {
            tau_fac: f64::from(crate::params::TAU_SLOW_US),
            ..p
        };
        let stride = i32::from(layout.stride());
        let near = crate::readout::calibrated::has_near(&layout);
        let mut pops = std::vec![SpikePopulation::new(p, n, gap_us, stride), {
            let mut s = SpikePopulation::new(slow, n, gap_us, stride);
            s.fast_reach_s = Some(p.reach_s());
            s
        }];
        if near {
            let mut s = SpikePopulation::new(p, n, gap_us, 1);
            s.near = true;
            pops.push(s);
        }
        let share = (f64::from(crate::readout::spikes::NEAR_DRIVE_SHARE_LOG2) / 65_536.0).exp2();
        Self {
            focal,
            cx,
            period: period_us,
            pops,
            fields,
            twins: crate::readout::calibrated::has_twins(&layout),
            busy_window: p.tau_fac * core::f64::consts::LN_10,
            stride: OracleStrideChoice::new(near),
            near_floor_s: -p.tau_fac * share.ln() * 1e-6,
            next_out: None,
            decode_from: f64::INFINITY,
            gate: OracleGate::new(period_us, p, focal),
            last_event: 0.0,
            spikes: 0,
            samples: 0,
            layout,
        }
    }

    /// One event at time `t` (µs); pushes `(t_us, yaw rad/s, flags)` for every output before
    /// it.
    pub fn event(
        &mut self,
        t: f64,
        x: u16,
        y: u16,
        on: bool,
        out: &mut std::vec::Vec<(f64, f64, u8)>,
    ) {
        match self.next_out {
            None => {
                self.next_out = Some(t + self.period);
                self.decode_from = t + f64::from(crate::readout::shared::WARMUP_US);
            }
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
        for pop in &mut self.pops {
            pop.event(&self.layout, c, t, x, y, on);
        }
    }

    /// Emits every output up to `t` (µs) inclusive (end of the recording).
    pub fn finish(&mut self, t: f64, out: &mut std::vec::Vec<(f64, f64, u8)>) {
        self.emit_until(t, true, out);
    }

    fn emit_until(&mut self, t: f64, inclusive: bool, out: &mut std::vec::Vec<(f64, f64, u8)>) {
        let Some(mut next) = self.next_out else {
            return;
        };
        while next < t || (inclusive && next <= t) {
            // Every unit that may spike, to the output time; then the spikes in time order,
            // the paper's units' first; then the decodes whose twin has answered or can no
            // longer answer.
            for k in 0..self.pops.len() {
                let spikes = match self.pops.get_mut(k) {
                    Some(pop) => pop.advance_all(next),
                    None => continue,
                };
                self.spikes += spikes.len() as u64;
                for &(ts, id) in &spikes {
                    self.with_population(k, |pop, target| pop.spike(target, ts, id));
                }
            }
            for k in 0..self.pops.len() {
                self.with_population(k, |pop, target| pop.settle(target, next));
            }
            self.stride.age(self.period);
            // The slow units read the chosen stride's FAC pixel from here on.
            let near = self.pops.len() > 2 && self.stride.near();
            let px = if near {
                1
            } else {
                i32::from(self.layout.stride())
            };
            if let Some(slow) = self.pops.get_mut(1).filter(|s| s.stride != px) {
                slow.stride_before = slow.stride;
                slow.stride = px;
                slow.stride_since = next;
            }
            let value = self.gate.output(&mut self.fields, self.twins);
            self.stride.follow_answer(value, self.focal);
            out.push(sample(next, self.last_event, value));
            next += self.period;
        }
        self.next_out = Some(next);
    }

    /// Runs `f` on population `k` with its target (its field).
    fn with_population(
        &mut self,
        k: usize,
        f: impl FnOnce(&mut SpikePopulation, &mut SpikeTarget<'_, L>),
    ) {
        // Each network of the paper's units reads the other's decodes (split borrow).
        if k >= self.pops.len() {
            return;
        }
        let (head, rest) = self.pops.split_at_mut(k);
        let Some((pop, tail)) = rest.split_first_mut() else {
            return;
        };
        // The paper's units' peer: the other network of the paper's units (none for the slow
        // units).
        let other = if pop.fast_reach_s.is_none() {
            head.iter()
                .chain(tail.iter())
                .find(|q| q.fast_reach_s.is_none() && q.near != pop.near)
        } else {
            None
        };
        let peer = other.map(|q| PeerView {
            onsets: &q.onsets,
            decodes: &q.decodes,
            share: (f64::from(crate::readout::spikes::NEAR_DRIVE_SHARE_LOG2) / 65_536.0).exp2(),
            w_trg: q.p.w_trg,
        });
        // The near units' decodes go to the paper's units' field.
        let which = usize::from(pop.fast_reach_s.is_some());
        let Some(field) = self.fields.get_mut(which) else {
            return;
        };
        let mut target = SpikeTarget {
            layout: &self.layout,
            focal: self.focal,
            cx: self.cx,
            field,
            decode_from: self.decode_from,
            busy_window: self.busy_window,
            stride: &mut self.stride,
            near_floor_s: self.near_floor_s,
            samples: &mut self.samples,
            peer,
        };
        f(pop, &mut target);
    }
}

impl SpikePopulation {
    fn new(p: OracleParams, n: usize, gap: f64, stride: i32) -> Self {
        let mut pop = Self {
            p,
            stride,
            near: false,
            gap,
            fac: std::vec![(0.0, 0.0, false); n],
            units: std::vec![(OracleUnit::default(), 0.0); 2 * n],
            active: std::vec::Vec::new(),
            listed: std::vec![false; 2 * n],
            pending: std::vec::Vec::new(),
            tracks: std::vec![SpikeTrack::Idle; 2 * n],
            onsets: std::vec![None; n],
            decodes: std::vec![[(None, false); 2]; n],
            waiting: std::collections::VecDeque::new(),
            lone_queue: std::collections::VecDeque::new(),
            lone_listed: std::vec![false; n],
            lone_guess: (0.0, 0.0),
            fast_reach_s: None,
            stride_before: stride,
            stride_since: f64::NEG_INFINITY,
        };
        let delta = p.t_ref / p.tau_trg;
        let drive = pop.min_drive() * ((delta + (-1.0 - delta).exp()) / 2.0).exp();
        // `x` falls with the charge's length up to tau.
        let (mut lo, mut hi) = (0.0, p.tau_trg);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if pop.x_of(mid) > drive {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        pop.lone_guess = (drive, hi);
        pop
    }

    /// The FAC pixel distance (px) a TRG event at `t` (µs) was timed over.
    fn stride_at(&self, t: f64) -> i32 {
        if t > self.stride_since {
            self.stride
        } else {
            self.stride_before
        }
    }

    /// `c = g / theta` per µs.
    fn c(&self) -> f64 {
        self.p.gain_per_us / self.p.theta
    }

    /// The current at the start of a clean charge of `l` µs.
    fn x_of(&self, l: f64) -> f64 {
        (l / self.p.tau_trg).exp() / (self.c() * l)
    }

    /// Smallest drive that makes a burst from rest.
    fn min_drive(&self) -> f64 {
        core::f64::consts::E / (self.c() * self.p.tau_trg)
    }

    /// One event at cell `c`, pixel `(x, y)`: the onset filter, the units' inputs, the FAC
    /// trace.
    fn event<L: crate::layout::Layout>(
        &mut self,
        layout: &L,
        c: usize,
        t: f64,
        x: u16,
        y: u16,
        on: bool,
    ) {
        let p = self.p;
        let fac_at = |f: &(f64, f64, bool), t: f64| f.0 * (-(t - f.1).max(0.0) / p.tau_fac).exp();
        let Some(&own) = self.fac.get(c) else {
            return;
        };
        let own_now = fac_at(&own, t);
        if let Some(f) = self.fac.get_mut(c) {
            f.2 = on;
        }
        if own.2 == on && own_now >= p.w_fac * (-self.gap / p.tau_fac).exp() {
            return;
        }
        let mask = layout.units(c);
        let s = self.stride;
        for (slot, dx) in [(0usize, -s), (1usize, s)] {
            if mask & (1 << slot) == 0 {
                continue;
            }
            let nb = u16::try_from(i32::from(x) + dx)
                .ok()
                .and_then(|nx| layout.cell(nx, y));
            let i_fac = nb
                .and_then(|n| self.fac.get(n))
                .map_or(0.0, |f| fac_at(f, t));
            let id = 2 * c + slot;
            self.advance_unit(id, t);
            if let Some((u, _)) = self.units.get_mut(id) {
                u.i_trg += p.w_trg * i_fac;
            }
            if let Some(l) = self.listed.get_mut(id) {
                if !*l {
                    *l = true;
                    self.active.push(id as u32);
                }
            }
        }
        if let Some(f) = self.fac.get_mut(c) {
            *f = (own_now + p.w_fac, t, on);
        }
    }

    /// Moves unit `id` to `t`, keeping its spikes.
    fn advance_unit(&mut self, id: usize, t: f64) {
        let p = self.p;
        if let Some((u, tu)) = self.units.get_mut(id) {
            let dt = (t - *tu).max(0.0);
            let mut out: std::vec::Vec<f64> = std::vec::Vec::new();
            p.advance(u, *tu, dt, &mut out);
            *tu += dt;
            self.pending
                .extend(out.into_iter().map(|ts| (ts, id as u32)));
        }
    }

    /// Moves every unit that may spike to `t`; returns the spikes since the last call, in
    /// time order.
    fn advance_all(&mut self, t: f64) -> std::vec::Vec<(f64, u32)> {
        let active = core::mem::take(&mut self.active);
        let mut still = std::vec::Vec::with_capacity(active.len());
        for id in active {
            self.advance_unit(id as usize, t);
            let alive = self.units.get(id as usize).is_some_and(|(u, _)| {
                u.refractory > 0.0 || self.p.next_crossing(u.u, u.i_trg, 1e9).is_some()
            });
            if alive {
                still.push(id);
            } else if let Some(l) = self.listed.get_mut(id as usize) {
                *l = false;
            }
        }
        self.active = still;
        let mut spikes = core::mem::take(&mut self.pending);
        spikes.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        spikes
    }

    /// Decides, at `now`, what waits for a twin that has answered or can no longer answer.
    fn settle<L: crate::layout::Layout>(&mut self, target: &mut SpikeTarget<'_, L>, now: f64) {
        let wait = self.p.tau_trg + self.p.t_ref;
        while let Some(&c) = self.lone_queue.front() {
            // Which of its units have waited long enough, and whether another still waits.
            let (mut due, mut waiting) = ([None; 2], false);
            for (u, slot) in due.iter_mut().enumerate() {
                if let Some(&SpikeTrack::Rest { t1 }) = self.tracks.get(2 * c as usize + u) {
                    if now - t1 > wait {
                        *slot = Some(t1);
                    } else {
                        waiting = true;
                    }
                }
            }
            if due == [None; 2] && waiting {
                break;
            }
            self.lone_queue.pop_front();
            if let Some(l) = self.lone_listed.get_mut(c as usize) {
                *l = false;
            }
            for (u, t1) in due.into_iter().enumerate() {
                if let Some(t1) = t1 {
                    self.lone(target, c as usize, u, t1);
                }
            }
            if waiting {
                self.list_lone(c);
            }
        }
        for _ in 0..self.waiting.len() {
            let Some(c) = self.waiting.pop_front() else {
                break;
            };
            let mut done = true;
            for u in 0..2 {
                if !self.resolve(target, c as usize, u, Some(now)) {
                    done = false;
                }
            }
            if !done {
                self.waiting.push_back(c);
            }
        }
    }

    /// One spike of unit `id` at `t` (the fixed readout's state machine, in f64).
    fn spike<L: crate::layout::Layout>(
        &mut self,
        target: &mut SpikeTarget<'_, L>,
        t: f64,
        id: u32,
    ) {
        let p = self.p;
        let (tau, t_ref) = (p.tau_trg, p.t_ref);
        let c = self.c();
        let Some(&track) = self.tracks.get(id as usize) else {
            return;
        };
        // The last spike, and the charge since it ended its refractory period.
        let t_last = match track {
            SpikeTrack::Idle => None,
            SpikeTrack::Rest { t1: t0 }
            | SpikeTrack::Pert { t: t0, .. }
            | SpikeTrack::Unknown { t: t0 }
            | SpikeTrack::Clean { t: t0, .. } => Some(t0),
        };
        let l = t_last.map_or(f64::INFINITY, |t0| t - t0 - t_ref);
        let y_next = (-t_ref / tau).exp() / (c * l);
        let mut result = None;
        let next = match track {
            _ if l < 1.0 => SpikeTrack::Unknown { t },
            SpikeTrack::Idle => SpikeTrack::Rest { t1: t },
            _ if l > M_MAX_F64 => SpikeTrack::Rest { t1: t },
            SpikeTrack::Rest { .. } | SpikeTrack::Pert { .. } | SpikeTrack::Unknown { .. }
                if l > tau =>
            {
                SpikeTrack::Rest { t1: t }
            }
            SpikeTrack::Rest { t1 } => {
                let x = self.x_of(l);
                let delta = 1.0 / (c * x * (t_ref / tau).exp());
                result = Some((t1 - delta, x * ((delta + t_ref) / tau).exp()));
                SpikeTrack::Clean { t, y: y_next }
            }
            SpikeTrack::Pert { t: te, m, y } => {
                let x = self.x_of(l);
                let k = x * ((m + t_ref) / tau).exp() - y;
                let n = (m / tau).exp() / c - y * m;
                if k > 0.0 && n > 0.0 {
                    let a = (m - n / k).max(0.0);
                    result = Some((te - m + a, k * (-a / tau).exp()));
                }
                SpikeTrack::Clean { t, y: y_next }
            }
            SpikeTrack::Unknown { .. } => SpikeTrack::Clean { t, y: y_next },
            SpikeTrack::Clean { y, .. } => {
                let d = self.x_of(l).log2() - y.log2();
                let tol = 2.0 * core::f64::consts::LOG2_E / l + 1.0 / 1024.0;
                if l <= tau && d.abs() <= tol {
                    SpikeTrack::Clean { t, y: y_next }
                } else if l <= tau && d < -tol {
                    SpikeTrack::Unknown { t }
                } else {
                    SpikeTrack::Pert { t, m: l, y }
                }
            }
        };
        if let Some(tr) = self.tracks.get_mut(id as usize) {
            *tr = next;
        }
        if matches!(next, SpikeTrack::Rest { .. }) {
            self.list_lone(id / 2);
        }
        if let Some((t_trg, d)) = result {
            self.decoded(target, id as usize / 2, id as usize % 2, t_trg, d);
        }
    }

    /// Appends `cell` to the lone spikes' queue unless it is in it.
    fn list_lone(&mut self, cell: u32) {
        if let Some(l) = self.lone_listed.get_mut(cell as usize).filter(|l| !**l) {
            *l = true;
            self.lone_queue.push_back(cell);
        }
    }

    /// The lone spike at `t1` of unit `u` of `cell` (in `Rest`, waited long enough; the fixed
    /// readout's `Decoding::lone`): at the pixel's last onset this unit did not decode, or else
    /// the other network's, when it came within a clean charge before the spike, with the
    /// drive its latency gives; else with `lone_guess`.
    fn lone<L: crate::layout::Layout>(
        &mut self,
        target: &mut SpikeTarget<'_, L>,
        cell: usize,
        u: usize,
        t1: f64,
    ) {
        let p = self.p;
        if let Some(tr) = self.tracks.get_mut(2 * cell + u) {
            *tr = SpikeTrack::Idle;
        }
        let undecoded = self
            .decodes
            .get(cell)
            .and_then(|d| d.get(u))
            .is_some_and(|(d, _)| d.is_none());
        let in_range = |t0: f64| (1.0..=p.tau_trg).contains(&(t1 - t0));
        let own = self
            .onsets
            .get(cell)
            .copied()
            .flatten()
            .map(|(t0, _, _)| t0)
            .filter(|&t0| undecoded && in_range(t0));
        let peer = target
            .peer
            .as_ref()
            .and_then(|v| v.onsets.get(cell).copied().flatten())
            .map(|(t0, _, _)| t0)
            .filter(|&t0| in_range(t0));
        let (t_trg, d) = match own.or(peer) {
            Some(t0) => (t0, self.x_of(t1 - t0)),
            None => {
                let (d, latency) = self.lone_guess;
                (t1 - latency, d)
            }
        };
        self.decoded(target, cell, u, t_trg, d);
    }

    /// A decoded TRG event at `t_trg` with drive `d` of unit `u` of `cell`.
    fn decoded<L: crate::layout::Layout>(
        &mut self,
        target: &mut SpikeTarget<'_, L>,
        cell: usize,
        u: usize,
        t_trg: f64,
        d: f64,
    ) {
        let p = self.p;
        let memory = 3.0 * p.tau_fac;
        let last = self.onsets.get(cell).copied().flatten();
        let same = last.is_some_and(|(t0, _, _)| (t_trg - t0).abs() <= SAME_ONSET_F64);
        if let (Some((t0, own, busy)), false) = (last, same) {
            if t_trg < t0 {
                // An earlier onset decoded late: its memory joins the later one.
                if let Some(o) = self.onsets.get_mut(cell) {
                    *o = Some((t0, own + p.w_fac * (-(t0 - t_trg) / p.tau_fac).exp(), busy));
                }
                return;
            }
        }
        if !same {
            for v in 0..2 {
                self.resolve(target, cell, v, None);
            }
            let own = match last {
                Some((t0, own, _)) if t_trg - t0 <= memory => {
                    p.w_fac + own * (-(t_trg - t0) / p.tau_fac).exp()
                }
                _ => p.w_fac,
            };
            let busy = last.is_some_and(|(t0, _, _)| t_trg - t0 <= target.busy_window);
            if let Some(o) = self.onsets.get_mut(cell) {
                *o = Some((t_trg, own, busy));
            }
            if let Some(dd) = self.decodes.get_mut(cell) {
                *dd = [(None, false); 2];
            }
        }
        let gated = d >= self.min_drive();
        if let Some(e) = self.decodes.get_mut(cell).and_then(|dd| dd.get_mut(u)) {
            *e = (Some(d), gated);
        }
        if gated {
            self.waiting.push_back(cell as u32);
        }
    }

    /// Decides the waiting decode of unit `u` of `cell` (as the fixed readout does); `false`
    /// when it still waits.
    fn resolve<L: crate::layout::Layout>(
        &mut self,
        target: &mut SpikeTarget<'_, L>,
        cell: usize,
        u: usize,
        now: Option<f64>,
    ) -> bool {
        let p = self.p;
        let Some(&[e0, e1]) = self.decodes.get(cell) else {
            return true;
        };
        let ((mine, waits), (twin_d, _)) = if u == 0 { (e0, e1) } else { (e1, e0) };
        let (Some(d), true) = (mine, waits) else {
            return true;
        };
        let Some((t_trg, own, busy)) = self.onsets.get(cell).copied().flatten() else {
            return true;
        };
        let c = self.c();
        let answer = twin_d.or_else(|| match self.tracks.get(2 * cell + 1 - u).copied() {
            Some(SpikeTrack::Rest { t1 }) if t1 > t_trg => Some(self.x_of(t1 - t_trg)),
            Some(SpikeTrack::Pert { t, m, y }) if t > t_trg => {
                let lat = t - t_trg;
                let a = m - lat;
                let n = (m / p.tau_trg).exp() / c - y * m;
                (a >= 0.0 && n > 0.0).then(|| n / lat * (-a / p.tau_trg).exp())
            }
            _ => None,
        });
        let needed = d / 2.0;
        let add = match (answer, now) {
            (Some(a), _) => a <= needed,
            (None, None) => true,
            (None, Some(now)) => {
                let waited = now - t_trg;
                if waited < p.tau_trg && self.x_of(waited.max(1.0)) > needed {
                    return false;
                }
                true
            }
        };
        if let Some(e) = self.decodes.get_mut(cell).and_then(|dd| dd.get_mut(u)) {
            e.1 = false;
        }
        if !add || t_trg < target.decode_from {
            return true;
        }
        let ratio = d / (p.w_trg * own);
        if !(ratio > 0.0 && ratio < 1.0) {
            return true;
        }
        let dt_s = -p.tau_fac * ratio.ln() * 1e-6;
        let (x, y) = target.layout.pixel(cell);
        let dx = f64::from(x) - target.cx;
        let g = target.focal + dx * dx / target.focal;
        let near_chosen = target.stride.near();
        // The layout's units take `stride` times as long as the near units over one pixel.
        let stride = f64::from(target.layout.stride());
        // The distance (px) this input was timed over.
        let over = f64::from(self.stride_at(t_trg));
        // The crossing time read (as the fixed readout: the near units' floor bounds the
        // layout's decode of an onset they decoded at their ceiling).
        let dt_s = match self.fast_reach_s {
            Some(reach) => {
                // The chosen stride's paper's units' reach, over the distance `over`.
                let reach = reach * over / if near_chosen { 1.0 } else { stride };
                if busy || dt_s <= reach {
                    // The paper's units time this edge; within an octave of their reach it
                    // lies beyond the slow units' floor.
                    if !busy && dt_s >= reach / 2.0 {
                        let floor = over / (reach * g);
                        target.field.add_beyond_floor(x, y, u == 1, floor);
                    }
                    return true;
                }
                dt_s
            }
            None => {
                if crate::readout::stride_choice::StrideChoice::counts_row(y) {
                    let region = target.field.region_index(x, y);
                    target.stride.add(self.near, region, u == 1);
                }
                let read = match (near_chosen, self.near) {
                    (false, near) => (!near).then_some(dt_s),
                    // Not where the layout's unit overrules it (as the fixed-point readout).
                    (true, true) => {
                        let overruled = || {
                            target
                                .peer
                                .as_ref()
                                .is_some_and(|n| n.overrules(cell, u, t_trg, ratio, stride))
                        };
                        (dt_s >= target.near_floor_s && !overruled()).then_some(dt_s)
                    }
                    // One stride times each onset: the layout's units those the near units
                    // decoded at their ceiling, no slower than their floor.
                    (true, false) => target
                        .peer
                        .as_ref()
                        .is_some_and(|n| n.decoded_at_ceiling(cell, u, t_trg))
                        .then(|| dt_s.min(stride * target.near_floor_s)),
                };
                let Some(dt_s) = read else {
                    return true;
                };
                if self.moves_vertically(target, (x, y), t_trg, own, ratio.log2()) {
                    return true;
                }
                dt_s
            }
        };
        let w = over / (dt_s * g);
        target.field.add(x, y, if u == 1 { w } else { -w });
        *target.samples += 1;
        true
    }
}

/// [`crate::readout::aperture::moves_vertically`] on f64 values: `log2` ratios to the pixel's
/// ceiling of the decode (`l2_h`, over `s_h` px), of the drives from the pixels `s_v` rows
/// above and below (`None`: no onset), of the own trace before the onset and of the smallest
/// drive that bursts.
fn aperture_moves_vertically(
    l2_h: f64,
    [s_h, s_v]: [f64; 2],
    vertical: [Option<f64>; 2],
    own_before: Option<f64>,
    reach: f64,
) -> bool {
    // The rule itself, on the ratios rounded to its Q16 (an error of 2^-17 in log2, 0.0005 %).
    let q16 = |v: f64| {
        (v * 65_536.0)
            .round()
            .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
    };
    crate::readout::aperture::moves_vertically(
        q16(l2_h),
        [s_h, s_v].map(|s| s as u16),
        &crate::readout::aperture::Around {
            vertical: vertical.map(|v| v.map(q16)),
            own_before: own_before.map(q16),
            reach: q16(reach),
        },
    )
}

/// `log2(x / ceiling)`, `None` for no trace.
fn log2_to(x: f64, ceiling: f64) -> Option<f64> {
    (x > 0.0).then(|| (x / ceiling).log2())
}

impl SpikePopulation {
    /// [`crate::readout::spikes`]' aperture gate: the decode `l2_h` of the onset at `t_trg` of
    /// pixel `(x, y)` (own trace `own` after it) against the last onsets at or before it
    /// decoded by either population of the paper's units the stride above and below.
    fn moves_vertically<L: crate::layout::Layout>(
        &self,
        target: &SpikeTarget<'_, L>,
        (x, y): (u16, u16),
        t_trg: f64,
        own: f64,
        l2_h: f64,
    ) -> bool {
        let p = self.p;
        let s = i32::from(target.layout.stride());
        let last_before = |onsets: &[DecodedOnset], i: usize| {
            onsets
                .get(i)
                .copied()
                .flatten()
                .filter(|&(t0, _, _)| t0 <= t_trg)
                .map(|(t0, own, _)| (t_trg - t0, own))
        };
        let vertical = [-s, s].map(|dy| {
            let row = u16::try_from(i32::from(y) + dy).ok()?;
            let i = target.layout.cell(x, row)?;
            let (age, own_v) = [
                Some(&self.onsets[..]),
                target.peer.as_ref().map(|n| n.onsets),
            ]
            .into_iter()
            .flatten()
            .filter_map(|onsets| last_before(onsets, i))
            .min_by(|a, b| a.0.total_cmp(&b.0))?;
            log2_to(own_v * (-age / p.tau_fac).exp(), own)
        });
        let s_h = if self.near { 1.0 } else { f64::from(s) };
        aperture_moves_vertically(
            l2_h,
            [s_h, f64::from(s)],
            vertical,
            log2_to(own - p.w_fac, own),
            (self.min_drive() / (p.w_trg * own)).log2(),
        )
    }
}

/// Longest interval (µs) over which an early spike is decoded (as the fixed readout keeps it).
const M_MAX_F64: f64 = 65_528.0;
/// Decoded TRG events of one pixel at most this far apart (µs) are one onset.
const SAME_ONSET_F64: f64 = crate::readout::spikes::SAME_ONSET_US as f64;

/// [`crate::readout::field::sign_agreement`] in f64 (samples): `(P - N)² / (P + N)` less
/// [`crate::readout::field::RANDOM_AGREEMENT`], at least 0; 0 for an empty region.
fn sign_agreement(n: f64, p: f64) -> f64 {
    let random = f64::from(crate::readout::field::RANDOM_AGREEMENT);
    if n + p > 0.0 {
        ((p - n) * (p - n) / (p + n) - random).max(0.0)
    } else {
        0.0
    }
}

/// The histogram bin of a rate `|r|` (rad/s), as [`crate::readout::field`]'s: `ORACLE_BINS`
/// equal steps of `ln |r|` from 0.01 to 20 rad/s, rates outside in the end bins.
fn oracle_bin(rate: f64) -> usize {
    let (lo, hi) = (0.01f64.ln(), 20.0f64.ln());
    (((rate.ln() - lo) / ((hi - lo) / ORACLE_BINS as f64)).floor())
        .clamp(0.0, ORACLE_BINS as f64 - 1.0) as usize
}

/// Index of region `(side, column band, vertical side, row band)` (as the fixed-point field's).
fn index_of((side, b, v, r): (usize, usize, usize, usize)) -> usize {
    ((side * COLS + b) * 2 + v) * ROWS + r
}

/// The field estimator of [`crate::readout::field`] in f64, one population: leaky signed
/// histograms of `log2 |rate|` per region, decayed exactly each period; per region the median
/// and its variance from the interquartile range; per column band and side the intercept at
/// `Y = 0` of a weighted fit; the weighted median over the means of every left band's
/// intercept with every right band's, if each side has a value in some band and either
/// `support` mirrored bands have both or at least half of the mirrored bands' sides have
/// one, and if regions in at least
/// [`ABOVE_SUPPORT`](crate::readout::field::ABOVE_SUPPORT) row bands above the principal row,
/// the topmost among them, have values, and if neither sign holds more than a quarter of the
/// weight; no answer when the decodes have all but stopped (and, for the paper's units, when
/// their latest decodes fall below half the histograms' rate), nor a new start that its latest
/// decodes above the principal row do not support.
pub struct OracleField {
    focal: f64,
    cx: f64,
    cy: f64,
    tau_a: f64,
    period: f64,
    min_samples: f64,
    spread_floor: f64,
    support: u8,
    band: (f64, [f64; 2]),
    coverage: crate::readout::field::Coverage,
    /// `[region][sign][bin]`.
    hist: std::vec::Vec<[[f64; ORACLE_BINS]; 2]>,
    recent: f64,
    short: f64,
    /// Decodes since the last output `[positive, above the principal row, positive above
    /// it]`, and leaky as `short` (the fixed-point field's `SignCounts`).
    recent_signs: [f64; 3],
    short_signs: [f64; 3],
    /// Whether this field (the slow units') says nothing while its decodes of the last
    /// [`crate::readout::field::SHORT_TAU_US`] split in sign
    /// ([`crate::readout::field::SPLIT_STOP_TENTHS`]).
    split_stop: bool,
    /// Decodes leaky over [`OracleField::brief_tau`], and whether this field (the paper's
    /// units') stops answering when they fall below half its rate.
    brief: f64,
    brief_stop: bool,
    /// The readout has answered one direction for a while (see
    /// [`crate::readout::field::Field::set_direction_established`]).
    established: bool,
    /// The readout answered a moment ago (the fixed-point field's `set_recent_motion`).
    recent_motion: Option<crate::readout::field::RecentAnswer>,
    /// Per region: the paper's units' decodes beyond this (slow units') field's floor per
    /// sign, leaky over `beyond_tau`, and the floor's bin (see
    /// [`crate::readout::field::Field::add_beyond_floor`]).
    beyond: std::vec::Vec<([f64; 2], usize)>,
    /// The paper's units' histogram time constant (µs) `beyond` decays with (0: the paper's
    /// units' own field, which counts none; see [`OracleField::beyond_floor_over`]).
    beyond_tau: f64,
}

impl OracleField {
    /// The field over the units of `layout`.
    pub fn new<L: crate::layout::Layout>(
        layout: &L,
        focal: f64,
        (cx, cy): (f64, f64),
        tau_a_us: f64,
        period_us: f64,
    ) -> Self {
        let fs = crate::readout::field::FieldSettings::DEFAULT;
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for c in 0..layout.cell_count() {
            if layout.units(c) != 0 {
                let (x, y) = layout.pixel(c);
                x0 = x0.min(f64::from(x));
                x1 = x1.max(f64::from(x) + 1.0);
                y0 = y0.min(f64::from(y));
                y1 = y1.max(f64::from(y) + 1.0);
            }
        }
        let band = (
            ((cx - x0).max(x1 - cx).max(1.0) / COLS as f64).max(1.0),
            [cy - y0, y1 - cy].map(|h| (h / ROWS as f64).max(1.0)),
        );
        let mut me = Self {
            focal,
            cx,
            cy,
            tau_a: tau_a_us,
            period: period_us,
            min_samples: f64::from(fs.min_samples_q16) / 65536.0,
            spread_floor: f64::from(fs.spread_floor_q16) / 65536.0,
            support: fs.support,
            band,
            coverage: crate::readout::field::Coverage::default(),
            hist: std::vec![[[0.0; ORACLE_BINS]; 2]; 4 * COLS * ROWS],
            recent: 0.0,
            short: 0.0,
            recent_signs: [0.0; 3],
            short_signs: [0.0; 3],
            split_stop: false,
            brief: 0.0,
            brief_stop: false,
            established: false,
            recent_motion: None,
            beyond: std::vec![([0.0; 2], 0); 4 * COLS * ROWS],
            beyond_tau: 0.0,
        };
        let mut seen = [[false; COLS]; 2];
        let mut above_bands = 0u8;
        for c in 0..layout.cell_count() {
            if layout.units(c) != 0 {
                let (x, y) = layout.pixel(c);
                let (side, b, v, r) = me.region(x, y);
                if let Some(s) = seen.get_mut(side).and_then(|s| s.get_mut(b)) {
                    *s = true;
                }
                if v == 0 {
                    above_bands = above_bands.max(r as u8 + 1);
                }
            }
        }
        let [l, r] = seen;
        me.coverage = crate::readout::field::Coverage {
            paired_bands: l.iter().zip(r.iter()).filter(|(a, b)| **a && **b).count() as u8,
            above_bands,
        };
        me
    }

    /// `(side, column band, vertical side, row band)` of a pixel.
    fn region(&self, x: u16, y: u16) -> (usize, usize, usize, usize) {
        let dx = f64::from(x) + 0.5 - self.cx;
        let dy = f64::from(y) + 0.5 - self.cy;
        let b = ((dx.abs() / self.band.0) as usize).min(COLS - 1);
        let v = usize::from(dy >= 0.0);
        let h = self.band.1.get(v).copied().unwrap_or(1.0);
        let r = ((dy.abs() / h) as usize).min(ROWS - 1);
        (usize::from(dx >= 0.0), b, v, r)
    }

    /// Index of the region of a pixel (as [`crate::readout::field::FieldGeometry::region`]).
    fn region_index(&self, x: u16, y: u16) -> usize {
        index_of(self.region(x, y))
    }

    /// One decoded rate (rad/s, signed) at pixel `(x, y)`.
    pub fn add(&mut self, x: u16, y: u16, w: f64) {
        let bin = oracle_bin(w.abs());
        let region = self.region(x, y);
        let (_, _, v, _) = region;
        let idx = index_of(region);
        if let Some(bin) = self
            .hist
            .get_mut(idx)
            .and_then(|h| h.get_mut(usize::from(w > 0.0)))
            .and_then(|h| h.get_mut(bin))
        {
            *bin += 1.0;
            self.recent += 1.0;
            let (positive, above) = (w > 0.0, v == 0);
            for (count, counts) in
                self.recent_signs
                    .iter_mut()
                    .zip([positive, above, above && positive])
            {
                *count += f64::from(u8::from(counts));
            }
        }
    }

    /// This field (the slow units') says nothing while its latest decodes split in sign
    /// ([`OracleField::split_lately`]).
    fn stops_when_split(mut self) -> Self {
        self.split_stop = true;
        self
    }

    /// Whether the decodes of the last [`crate::readout::field::SHORT_TAU_US`], at least
    /// [`crate::readout::field::SPLIT_STOP_MIN_DECODES`], split in sign more evenly than
    /// [`crate::readout::field::SPLIT_STOP_TENTHS`] in ten.
    fn split_lately(&self) -> bool {
        use crate::readout::field::{splits_in_sign, SPLIT_STOP_MIN_DECODES};
        let [positive, ..] = self.short_signs;
        splits_in_sign(self.short, positive, SPLIT_STOP_MIN_DECODES as f64)
    }

    /// Whether a new start of sign `negative` lacks the support of the latest decodes above the
    /// principal row (the fixed-point field's `Field::start_against`).
    fn start_against(&self, negative: bool) -> bool {
        use crate::readout::field::{short_of_sign, SPLIT_STOP_MIN_DECODES};
        let [_, all, positive] = self.short_signs;
        let agreeing = if negative { all - positive } else { positive };
        short_of_sign(all, agreeing, SPLIT_STOP_MIN_DECODES as f64)
    }

    /// This field (the paper's units') says nothing while its decodes stop at once
    /// ([`OracleField::stopped_at_once`]).
    fn stops_briefly(mut self) -> Self {
        self.brief_stop = true;
        self
    }

    /// The brief time constant (µs): [`crate::readout::field::BRIEF_TAU_TENTHS`] of `tau_A`, as
    /// the fixed-point field takes it (whole µs).
    fn brief_tau(&self) -> f64 {
        let tenths = crate::readout::field::BRIEF_TAU_TENTHS;
        f64::from(((self.tau_a as u32) / 10 * tenths).max(1))
    }

    /// Whether the decodes over the brief time constant fell below
    /// `1 / `[`crate::readout::field::BRIEF_STOP_RATIO`] of the histograms' `rate` (decodes
    /// per µs), where that expects [`crate::readout::field::BRIEF_MIN_DECODES`] or more.
    fn stopped_at_once(&self, rate: f64) -> bool {
        use crate::readout::field::{BRIEF_MIN_DECODES, BRIEF_STOP_RATIO};
        let tau = self.brief_tau();
        rate * tau >= BRIEF_MIN_DECODES as f64
            && self.brief / tau * (BRIEF_STOP_RATIO as f64) < rate
    }

    /// This field (the slow units') counts the paper's units' decodes beyond its floor, leaky
    /// over the paper's units' histogram time constant `fast_tau_us`.
    fn beyond_floor_over(mut self, fast_tau_us: f64) -> Self {
        self.beyond_tau = fast_tau_us;
        self
    }

    /// A decode of the paper's units within an octave above their floor `floor` (rad/s) at
    /// pixel `(x, y)`, of an onset this field's (slow) units decode too with sign `positive`.
    pub fn add_beyond_floor(&mut self, x: u16, y: u16, positive: bool, floor: f64) {
        let idx = self.region_index(x, y);
        if let Some((m, b)) = self.beyond.get_mut(idx) {
            *b = oracle_bin(floor);
            if let Some(m) = m.get_mut(usize::from(positive)) {
                *m += 1.0;
            }
        }
    }

    /// One output period passes.
    pub fn age(&mut self) {
        let keep = (-self.period / self.tau_a).exp();
        for b in self.hist.iter_mut().flatten().flatten() {
            *b *= keep;
        }
        if self.beyond_tau > 0.0 {
            let keep = (-self.period / self.beyond_tau).exp();
            for (m, _) in self.beyond.iter_mut() {
                *m = m.map(|v| v * keep);
            }
        }
        let short_keep = (-self.period / f64::from(crate::readout::field::SHORT_TAU_US)).exp();
        self.short = self.short * short_keep + self.recent;
        for (short, recent) in self
            .short_signs
            .iter_mut()
            .zip(self.recent_signs.iter_mut())
        {
            *short = *short * short_keep + *recent;
            *recent = 0.0;
        }
        let brief_keep = (-self.period / self.brief_tau()).exp();
        self.brief = self.brief * brief_keep + self.recent;
        self.recent = 0.0;
    }

    /// Decodes per µs over the histograms' time constant.
    pub fn rate(&self) -> f64 {
        self.hist.iter().flatten().flatten().sum::<f64>() / self.tau_a
    }

    /// Decodes per µs that agree in sign within their region: `Σ max(0, (P - N)² / (P + N) - 2)`
    /// over the regions (2 samples: what random signs exceed one time in 20), over the
    /// histograms' time constant.
    pub fn consistent_rate(&self) -> f64 {
        let agree: f64 = self
            .hist
            .iter()
            .map(|[neg, pos]| sign_agreement(neg.iter().sum(), pos.iter().sum()))
            .sum();
        agree / self.tau_a
    }

    /// The decode rate of the last [`crate::readout::field::SHORT_TAU_US`] over that of the
    /// histograms, from 1 (steady or slowing) to `tau_A / SHORT_TAU_US` (histograms that have
    /// just begun to fill).
    pub fn fill(&self) -> f64 {
        let short_tau = f64::from(crate::readout::field::SHORT_TAU_US);
        let rate = self.rate();
        if rate > 0.0 {
            (self.short / short_tau / rate).clamp(1.0, (self.tau_a / short_tau).floor().max(1.0))
        } else {
            1.0
        }
    }

    /// 5/4 of the decode rate of the last [`crate::readout::field::SHORT_TAU_US`] over that of
    /// the histograms, at most 1.
    pub fn recent_share(&self) -> f64 {
        let short = self.short / f64::from(crate::readout::field::SHORT_TAU_US);
        let rate = self.rate();
        if rate > 0.0 {
            (1.25 * short / rate).min(1.0)
        } else {
            0.0
        }
    }

    /// The rotation the field shows, if it shows one, and why ([`OracleReading`]).
    pub fn reading(&self) -> OracleReading {
        let short_tau = f64::from(crate::readout::field::SHORT_TAU_US);
        let stopped_ratio = crate::readout::field::STOPPED_RATIO as f64;
        // The histograms' decode rate, summed over every bin once for both rules.
        let rate = self.rate();
        if self.short / short_tau * stopped_ratio < rate
            || (self.brief_stop && self.stopped_at_once(rate))
        {
            return OracleReading {
                stopped: true,
                ..OracleReading::NOTHING
            };
        }
        if self.split_stop && self.split_lately() {
            return OracleReading {
                blind: true,
                ..OracleReading::NOTHING
            };
        }
        let mut recent_needed = false;
        let estimate = self.estimate_noting(&mut recent_needed);
        if estimate.is_some_and(|v| self.recent_motion.is_none() && self.start_against(v < 0.0)) {
            return OracleReading::NOTHING;
        }
        OracleReading {
            estimate,
            recent_needed: recent_needed && estimate.is_some(),
            ..OracleReading::NOTHING
        }
    }

    /// [`OracleField::reading`]'s rotation, setting `recent_needed` when the bands were chosen
    /// only because the readout answered a moment ago; called only for a field whose decodes
    /// have not stopped.
    fn estimate_noting(&self, recent_needed: &mut bool) -> Option<f64> {
        let mut values: std::vec::Vec<(f64, f64)> = std::vec::Vec::new();
        // The answer a moment ago that the estimate must continue, if any.
        let mut to_continue = None;
        if self.coverage.paired_bands > 0 {
            // Every left band with every right band, when the values are spread as a
            // rotation's (the fixed-point field's rule).
            let sides: [[Option<(f64, f64)>; COLS]; 2] = core::array::from_fn(|side| {
                core::array::from_fn(|band| self.column_intercept(side, band))
            });
            // The fixed-point field's rule, on the band values in its units (Q16 rad/s) and the
            // regions above the principal row (v = 0).
            use crate::readout::field::{band_choice, upper_coverage, BandChoice};
            let upper =
                upper_coverage(|col, row| self.region_value(col * 2 * ROWS + row).is_some());
            let q16 = sides.map(|fits| fits.map(|fit| fit.map(|(v, _)| (v * 65536.0) as i64)));
            let (choice, needed) =
                band_choice(&q16, upper, self.support, self.coverage, self.recent_motion);
            *recent_needed = needed;
            match choice {
                BandChoice::Nothing => return None,
                BandChoice::Side(side) => {
                    // Texture on one side only: its bands alone.
                    let fits = sides.get(side).map_or(&[][..], |f| &f[..]);
                    values.extend(fits.iter().flatten().map(|&(v, var)| (v, 1.0 / var)));
                }
                BandChoice::Pairs | BandChoice::Continuing => {
                    if choice == BandChoice::Continuing {
                        to_continue = self.recent_motion;
                    }
                    let [left, right] = sides;
                    for &(a, va) in left.iter().flatten() {
                        for &(c, vc) in right.iter().flatten() {
                            values.push((0.5 * (a + c), 1.0 / (0.25 * (va + vc))));
                        }
                    }
                }
            }
        } else {
            for b in 0..COLS {
                let est = match [self.column_intercept(0, b), self.column_intercept(1, b)] {
                    [Some((a, va)), Some((c, vc))] => Some((0.5 * (a + c), 0.25 * (va + vc))),
                    [Some(a), None] | [None, Some(a)] => Some(a),
                    [None, None] => None,
                };
                values.extend(est.map(|(v, var)| (v, 1.0 / var)));
            }
        }
        let total: f64 = values.iter().map(|v| v.1).sum();
        if values.is_empty() || total <= 0.0 {
            return None;
        }
        values.sort_by(|a, b| a.0.total_cmp(&b.0));
        let signed = |positive: bool| -> f64 {
            values
                .iter()
                .filter(|v| if positive { v.0 > 0.0 } else { v.0 < 0.0 })
                .map(|v| v.1)
                .sum()
        };
        if signed(true).min(signed(false)) * f64::from(crate::readout::field::SPLIT_SHARE) > total {
            return None;
        }
        let mut acc = 0.0;
        let median = values
            .iter()
            .find(|&&(_, w)| {
                acc += w;
                2.0 * acc >= total
            })
            .or(values.last())
            .map(|v| v.0.clamp(-20.0, 20.0));
        match to_continue {
            // The fixed-point rule, on the median in its units (Q16 rad/s).
            Some(r) => median.filter(|&m| {
                r.continued_by(crate::readout::field::FieldEstimate::Rotation(
                    (m * 65536.0) as i32,
                ))
            }),
            None => median,
        }
    }

    /// Intercept at `Y = 0` of one column band's weighted fit on one side, and its variance:
    /// over both halves of the band, or the rows above the principal row alone where the
    /// halves' own fits disagree, none from the rows below alone where the field asks for
    /// the rows above (as `field::Field::column_intercept`).
    fn column_intercept(&self, side: usize, band: usize) -> Option<(f64, f64)> {
        let sums = [0, 1].map(|v| self.half_sums(side, band, v));
        let above = oracle_fit(&sums, [true, false]);
        if above.is_none() && !self.lower_half_alone_counts() {
            return None;
        }
        if let (Some((wa, va)), Some((wb, vb))) = (above, oracle_fit(&sums, [false, true])) {
            let sigmas = crate::readout::field::HALVES_DISAGREE_SIGMAS as f64;
            let faster = crate::readout::field::HALVES_FASTER_BELOW as f64;
            if (wa - wb) * (wa - wb) > sigmas * sigmas * (va + vb) || wb.abs() > faster * wa.abs() {
                return above;
            }
        }
        oracle_fit(&sums, [true, true])
    }

    /// Whether a column band's rows below the principal row alone give it an intercept (as
    /// `field::Field::lower_half_alone_counts`): without mirrored bands or rows above, or
    /// where the top row band's centre lies within `FAR_ROWS_Q12` of the horizon.
    fn lower_half_alone_counts(&self) -> bool {
        let far = crate::readout::field::FAR_ROWS_Q12 as f64 / 4096.0;
        self.coverage.paired_bands == 0
            || self.coverage.above_bands == 0
            || self.row_centre_abs(0, ROWS - 1) < far
    }

    /// `|Y|` (normalised) of the centre of row band `row` on half `v` (0 above the principal
    /// row, 1 below).
    fn row_centre_abs(&self, v: usize, row: usize) -> f64 {
        let h = self.band.1.get(v).copied().unwrap_or(1.0);
        (row as f64 + 0.5) * h / self.focal
    }

    /// The weighted sums `(Σ w, Σ w r, Σ w Y, Σ w Y², Σ w r Y)` of one half of a column
    /// band's fit (`v`: 0 above the principal row, 1 below), each region's median read once.
    fn half_sums(&self, side: usize, band: usize, v: usize) -> [f64; 5] {
        let mut sums = [0.0; 5];
        for row in 0..ROWS {
            let Some((m, var)) = self.region_value(((side * COLS + band) * 2 + v) * ROWS + row)
            else {
                continue;
            };
            let w = 1.0 / var;
            let y = self.row_centre_abs(v, row) * if v == 0 { -1.0 } else { 1.0 };
            for (sum, term) in sums.iter_mut().zip([w, w * m, w * y, w * y * y, w * m * y]) {
                *sum += term;
            }
        }
        sums
    }

    /// `(median, variance of the median)` in region `i`.
    fn region_value(&self, i: usize) -> Option<(f64, f64)> {
        let [mut neg, mut pos] = *self.hist.get(i)?;
        // What the slow units' histograms leave out beyond the paper's units' floor, once the
        // direction is established: at most their own decodes in the octave below the floor.
        if let (true, Some(&([bn, bp], bin))) = (
            self.established && self.beyond_tau > 0.0,
            self.beyond.get(i),
        ) {
            let octave = crate::readout::field::OCTAVE_BINS;
            for (h, m) in [(&mut neg, bn), (&mut pos, bp)] {
                let below: f64 = h
                    .get(bin.saturating_sub(octave)..bin)
                    .map_or(0.0, |b| b.iter().sum());
                if let Some(b) = h.get_mut(bin) {
                    *b += (m * self.tau_a / self.beyond_tau).min(below);
                }
            }
        }
        let (neg, pos) = (&neg, &pos);
        let (n, p): (f64, f64) = (neg.iter().sum(), pos.iter().sum());
        let total = n + p;
        if total <= 0.0 || total < self.min_samples {
            return None;
        }
        let (lo, hi) = (0.01f64.log2(), 20.0f64.log2());
        let bw = (hi - lo) / ORACLE_BINS as f64;
        // |rate| at position `at` (0..1, up the rates) within bin `i`.
        let rate = |i: usize, at: f64| (lo + (i as f64 + at) * bw).exp2();
        let signed = neg
            .iter()
            .enumerate()
            .rev()
            .map(|(i, &m)| (i, m, false))
            .chain(pos.iter().enumerate().map(|(i, &m)| (i, m, true)));
        let mut q = [
            (total / 4.0, 0.0f64),
            (total / 2.0, 0.0),
            (total * 0.75, 0.0),
        ];
        let mut pending = q.iter_mut().peekable();
        let mut acc = 0.0;
        for (i, m, positive) in signed {
            while let Some((target, value)) = pending.next_if(|(t, _)| m > 0.0 && acc + m >= *t) {
                let frac = (*target - acc) / m;
                let v = rate(i, if positive { frac } else { 1.0 - frac });
                *value = if positive { v } else { -v };
            }
            acc += m;
        }
        let [(_, q1), (_, median), (_, q3)] = q;
        // A region whose decodes agree in sign, in one peak, reads its majority sign's median
        // (see `field::majority_median`).
        let settled_samples = f64::from(crate::readout::field::SETTLED_SAMPLES_Q16) / 65536.0;
        let (bins, sign, majority) = if p >= n {
            (pos, 1.0, p)
        } else {
            (neg, -1.0, n)
        };
        let agree = (self.established || total >= settled_samples)
            && (total - majority) * f64::from(1u32 << SETTLED_MINORITY_LOG2) <= total;
        // Quartiles an octave or more apart: the other sign is the far side of the majority's
        // spread, and the median is at rank half of all decodes (`field::WIDE_MAJORITY_RATIO`).
        let wide = (q1 < 0.0) == (q3 < 0.0)
            && q1.abs().max(q3.abs())
                >= q1.abs().min(q3.abs()) * crate::readout::field::WIDE_MAJORITY_RATIO as f64;
        let rank = if wide { total / 2.0 } else { majority / 2.0 };
        let mut acc = 0.0;
        let majority_median = bins
            .iter()
            .enumerate()
            .take_while(|_| agree)
            .find_map(|(i, &m)| {
                let at = (rank - acc) / m;
                acc += m;
                (m > 0.0 && at <= 1.0).then(|| sign * rate(i, at))
            })
            .filter(|&r| (r < 0.0) == (median < 0.0) && (r - median).abs() <= median.abs() / 2.0);
        let median = majority_median.unwrap_or(median);
        let iqr = (q3 - q1).abs().max(self.spread_floor);
        // Decodes split in sign say less than their spread shows (`field::split_variance`).
        let cap = crate::readout::field::SPLIT_VARIANCE_CAP as f64;
        let split = (total / (n - p).abs().max(f64::MIN_POSITIVE)).min(cap);
        Some((median, iqr * iqr / total.floor().max(1.0) * split))
    }
}
