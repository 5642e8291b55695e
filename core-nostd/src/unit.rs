//! The fixed-point TDE unit: state, closed-form decay between inputs, and exact threshold crossings.
//!
//! Numbers: traces `I_F`, `I_T` are [`Trace`] (U5F27) saturating at [`TRACE_MAX`]; the membrane is kept
//! normalised, `v = u / theta` in `[0, 1)`, as U1F31. Time is `u32` µs and wraps; elapsed
//! times are wrapping differences, and a difference of 2^31 µs or more (an input "from the past")
//! counts as zero elapsed time.
//!
//! Between inputs the state evolves in closed form (`tau_T == tau_m == tau`):
//! `I_T(s) = I_T e^(-s/tau)`, `v(s) = (v + q s) e^(-s/tau)` with `q = g I_T / theta` per µs.
//! A spike is emitted at the whole microsecond nearest to where `v` reaches 1. The crossing is
//! found by Newton's method started at the left end: `v(s)` is concave up to its peak, so the iterates
//! increase monotonically towards the crossing and never pass it by more than the final 1 µs
//! rounding; a stall past the peak means there is no crossing. Typically 3–5 iterations.
//!
//! # Two engines
//! - [`Tde`], [`UnitState`], [`Kernel::advance`]: one unit, one Newton search per spike, traces
//!   saturating at 16. The stand-alone unit of the sweep and of the calibrated readout's burst
//!   test ([`Kernel::may_spike`]).
//! - [`BurstUnit`], [`Kernel::burst_input`], [`Kernel::burst_emit`]: the network's units. The
//!   TRG trace is kept as the drive level `D = q·tau` (Q32.32, no saturation below 2^32, about
//!   10^8 times the trace of one event), the membrane as the time `t_e` at which it started
//!   charging from 0 (`v(t) = D(t)·(t - t_e)/tau`, exact for the closed form above), and a burst
//!   as the time `t*` at which `D` falls to 1 plus the position of the next spike on the burst
//!   orbit (see `orbit`): every spike of a burst is one table lookup, and an input costs one
//!   logarithm and one division. Times are Q32.32 µs (sub-µs exact); a spike is reported at the
//!   nearest whole µs. With parameters the tables were not built for (`t_ref != 100 µs` or
//!   `tau != 20 ms`), each spike is found by Newton's method on the same orbit equation instead.

use fixed::types::U1F31;

use crate::exp_table::{scale_q31, ExpDecay, ONE_Q31};
use crate::log2::LOG2E_Q32;
use crate::params::{ParamError, TdeParams, Trace, TAU_SLOW_US, TRACE_MAX};

mod orbit;

/// `1.0` in Q32 (the format of normalised membrane values inside the solver).
const ONE_Q32: u64 = 1 << 32;

/// `ln 2` in Q0.32.
const LN2_Q32: u64 = 2_977_044_472;

/// `1/e` in Q0.32.
const INV_E_Q32: u128 = 1_580_030_169;

/// Most spikes one input takes back (far more than a burst emits ahead of the clock).
const MAX_RETRACT: u32 = 1 << 16;

/// Newton iterations allowed per crossing search (each at least halves the distance to a
/// tangential crossing, so this covers any window up to 2^24 µs).
const MAX_NEWTON_STEPS: u32 = 40;

pub use crate::time::elapsed_us;

/// Everything the fixed-point unit needs, precomputed from [`TdeParams`]: decay tables for
/// `tau_F` and `tau_T` (= `tau_m`) and the drive coefficient.
#[derive(Clone, Debug)]
pub struct Kernel {
    params: TdeParams,
    exp_fac: ExpDecay,
    exp_trg: ExpDecay,
    /// `g / (theta · 1e6)` in Q32: drive per µs per unit of `I_T`.
    drive_q32: u64,
    /// `2^48 / tau` (for `f / tau` without a division).
    inv_tau_q48: u64,
    /// Drive level `D = q·tau` per unit of `I_T`, in Q32 (`g·tau/theta`).
    d_per_trace_q32: u64,
    /// Whether the burst tables ([`orbit`]) were built for these `t_ref` and `tau`.
    orbit: bool,
    /// `tau · ln 2` in Q32.32 µs.
    ln2_tau_fine: u64,
    /// `2^64 / (tau · ln 2 · 2^32)`, for a first guess of a quotient by it.
    inv_ln2_tau_q64: u64,
    /// `REST_LEVEL_LOG2 · ln 2 · tau` in Q32.32 µs: how long after `t*` a pooled unit comes to
    /// rest.
    rest_after_fine: u64,
}

impl Kernel {
    /// The kernel for the default parameters, computed at compile time (tables in flash).
    pub const DEFAULT: Self = Self::from_valid(TdeParams::DEFAULT);

    /// The slow units' kernel: the default parameters with `tau_F` = [`TAU_SLOW_US`], for
    /// edges too slow for the paper's units (computed at compile time, tables in flash).
    pub const SLOW: Self = Self::from_valid(TdeParams {
        tau_fac_us: TAU_SLOW_US,
        ..TdeParams::DEFAULT
    });

    /// Builds the kernel, or says which parameter the fixed-point core cannot take.
    pub fn new(params: TdeParams) -> Result<Self, ParamError> {
        params.validate_fixed()?;
        Ok(Self::from_valid(params))
    }

    const fn from_valid(params: TdeParams) -> Self {
        let theta_bits = params.theta.to_bits() as u128;
        let denom = theta_bits * 1_000_000;
        let drive = ((params.gain_per_s as u128) << 48) / if denom == 0 { 1 } else { denom };
        let drive_q32 = if drive > u64::MAX as u128 {
            u64::MAX
        } else {
            drive as u64
        };
        let tau = if params.tau_trg_us == 0 {
            1
        } else {
            params.tau_trg_us
        };
        let d_per_trace =
            ((params.gain_per_s as u128 * tau as u128) << 48) / if denom == 0 { 1 } else { denom };
        let d_per_trace_q32 = if d_per_trace > u64::MAX as u128 {
            u64::MAX
        } else {
            d_per_trace as u64
        };
        Self {
            params,
            exp_fac: ExpDecay::new(params.tau_fac_us),
            exp_trg: ExpDecay::new(params.tau_trg_us),
            drive_q32,
            inv_tau_q48: (1u64 << 48) / tau as u64,
            d_per_trace_q32,
            orbit: params.t_ref_us == orbit::T_REF_US && params.tau_trg_us == orbit::TAU_US,
            ln2_tau_fine: tau as u64 * LN2_Q32,
            inv_ln2_tau_q64: ((1u128 << 64) / (tau as u128 * LN2_Q32 as u128)) as u64,
            rest_after_fine: REST_LEVEL_LOG2 as u64 * tau as u64 * LN2_Q32,
        }
    }

    /// The parameters this kernel was built from.
    pub fn params(&self) -> &TdeParams {
        &self.params
    }

    /// Decay table of the FAC trace.
    pub fn exp_fac(&self) -> &ExpDecay {
        &self.exp_fac
    }

    /// Decay table of the TRG trace and membrane.
    pub fn exp_trg(&self) -> &ExpDecay {
        &self.exp_trg
    }

    /// A FAC trace value decayed over `dt` µs.
    #[inline]
    pub fn decay_fac(&self, i_fac: Trace, dt_us: u32) -> Trace {
        Trace::from_bits(scale_q31(i_fac.to_bits(), self.exp_fac.decay_bits(dt_us)))
    }

    /// A FAC trace after one FAC event (already decayed to the event time).
    #[inline]
    pub fn fac_input(&self, i_fac_now: Trace) -> Trace {
        let w = Trace::saturating_from_num(self.params.w_fac);
        i_fac_now.saturating_add(w).min(TRACE_MAX)
    }

    /// The drive a TRG event delivers to its unit: `w_T · I_F(t⁻)`, saturating at
    /// [`TRACE_MAX`] (what the unit's TRG trace receives, and what a burst encodes).
    #[inline]
    pub fn drive(&self, i_fac_now: Trace) -> Trace {
        let prod = self.drive_q27(i_fac_now.to_bits(), Trace::FRAC_NBITS);
        Trace::from_bits(prod.min(u64::from(TRACE_MAX.to_bits())) as u32)
    }

    /// `w_T · I_F` in Q27 without saturation, for `I_F` given as raw bits with `frac_bits`
    /// fractional bits (24 to 27): the one drive formula, [`Kernel::drive`] and the burst engine
    /// ([`WideTrace`]) both use it.
    #[inline]
    fn drive_q27(&self, i_fac_bits: u32, frac_bits: u32) -> u64 {
        let prod = u64::from(self.params.w_trg.to_bits()) * u64::from(i_fac_bits);
        prod >> (16 + frac_bits).saturating_sub(Trace::FRAC_NBITS)
    }

    /// A FAC trace of the spiking network after one FAC event ([`WideTrace`]).
    #[inline]
    pub fn fac_input_wide(&self, i_fac_now: WideTrace) -> WideTrace {
        let w = (u64::from(self.params.w_fac.to_bits()) << 8).min(u64::from(WIDE_MAX)) as u32;
        WideTrace(i_fac_now.0.saturating_add(w).min(WIDE_MAX))
    }

    /// Applies one TRG event to a unit already advanced to the event time: `I_T += drive`.
    #[inline]
    pub fn trg_input(&self, unit: &mut UnitState, i_fac_now: Trace) {
        unit.i_trg = unit
            .i_trg
            .saturating_add(self.drive(i_fac_now))
            .min(TRACE_MAX);
    }

    /// Advances `unit` by `dt` µs from absolute time `t0`, calling `on_spike(t)` for every spike in
    /// `(t0, t0 + dt]`, in order. Returns the number of spikes.
    ///
    /// Work is bounded: traces saturate at [`TRACE_MAX`] and spikes are at least `t_ref` apart, so
    /// one call emits at most a few hundred spikes with the default parameters.
    pub fn advance<F: FnMut(u32)>(
        &self,
        unit: &mut UnitState,
        t0: u32,
        dt: u32,
        mut on_spike: F,
    ) -> u32 {
        let mut t = t0;
        let mut left = dt;
        let mut spikes = 0;
        loop {
            if unit.refractory_us > 0 {
                let r = unit.refractory_us;
                if left < r {
                    unit.i_trg = self.decay_trg(unit.i_trg, left);
                    unit.refractory_us = r - left;
                    return spikes;
                }
                unit.i_trg = self.decay_trg(unit.i_trg, r);
                unit.refractory_us = 0;
                // The refractory period really ended `lag` µs before this whole µs: the membrane
                // has been charging since then.
                unit.v = self.charge_over_lag(unit.i_trg, unit.lag_q16);
                unit.lag_q16 = 0;
                t = t.wrapping_add(r);
                left -= r;
            }
            if left == 0 {
                return spikes;
            }
            match self.next_crossing(unit.i_trg, unit.v, left) {
                Some(c) => {
                    // Reported at the nearest whole µs; the refractory period starts at the exact
                    // crossing, `lag` µs before `whole_us`, and that sub-µs lag is carried so that
                    // rounding never accumulates along a burst.
                    let s = c.nearest_us();
                    t = t.wrapping_add(s);
                    left -= s;
                    on_spike(t);
                    spikes += 1;
                    unit.i_trg = self.decay_trg(unit.i_trg, s);
                    unit.v = U1F31::ZERO;
                    unit.refractory_us = self.params.t_ref_us + (c.whole_us - s);
                    unit.lag_q16 = (c.lag_q32 >> 16) as u16;
                }
                None => {
                    unit.v = self.membrane_after(unit.i_trg, unit.v, left);
                    unit.i_trg = self.decay_trg(unit.i_trg, left);
                    return spikes;
                }
            }
        }
    }

    /// Membrane charged from 0 over `lag_q16` (Q0.16) µs at the current drive: `q · lag`.
    #[inline]
    fn charge_over_lag(&self, i_trg: Trace, lag_q16: u16) -> U1F31 {
        let v32 = (self.drive_q48(i_trg) * u128::from(lag_q16)) >> 32;
        U1F31::from_bits((v32 >> 1).min(u128::from(ONE_Q31 - 1)) as u32)
    }

    /// Whether the unit, left alone, might still spike: a cheap upper bound. The membrane's
    /// future peak is at most `v + q·tau/e` (and `q` only falls), so `false` is certain.
    #[inline]
    pub fn may_spike(&self, unit: &UnitState) -> bool {
        let q48 = self.drive_q48(unit.i_trg);
        // q·tau/e in Q48, with 1/e in Q32.
        let peak48 = (q48 * u128::from(self.params.tau_trg_us) * INV_E_Q32) >> 32;
        let v48 = u128::from(unit.v.to_bits()) << 17;
        peak48 + v48 >= 1 << 48
    }

    /// Smallest TRG drive that makes a unit at rest burst (`q·tau/e >= 1`).
    pub fn min_burst_drive(&self) -> Trace {
        let (mut lo, mut hi) = (0u32, crate::params::TRACE_MAX.to_bits());
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            let u = UnitState {
                i_trg: Trace::from_bits(mid),
                ..UnitState::default()
            };
            if self.may_spike(&u) {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        Trace::from_bits(lo)
    }

    /// `log2` (Q16.16) of how much more drive than [`Kernel::min_burst_drive`] a burst from
    /// rest needs for a second spike: `(delta + e^(-1 - delta)) log2 e` with `delta = t_ref /
    /// tau` (the first spike's `r` must reach `1 + delta`: the burst orbit of `unit::orbit`).
    /// 0.535 at the defaults: a drive 1.45 times the smallest. For equal TRG and membrane time
    /// constants (the burst engine's condition).
    pub fn second_spike_log2_q16(&self) -> i32 {
        let p = &self.params;
        let delta_q32 = (u64::from(p.t_ref_us) << 32) / u64::from(p.tau_trg_us.max(1));
        let e_delta_q31 = u128::from(self.exp_trg.decay_bits(p.t_ref_us));
        let ln_q32 = u128::from(delta_q32) + ((INV_E_Q32 * e_delta_q31) >> 31);
        i32::try_from((ln_q32 * u128::from(LOG2E_Q32)) >> 48).unwrap_or(i32::MAX)
    }

    /// Whether the unit, left alone, will spike again (it is in a burst).
    pub fn will_spike(&self, unit: &UnitState) -> bool {
        if unit.refractory_us > 0 {
            let i = self.decay_trg(unit.i_trg, unit.refractory_us);
            let v = self.charge_over_lag(i, unit.lag_q16);
            return self.next_crossing(i, v, u32::MAX).is_some();
        }
        self.next_crossing(unit.i_trg, unit.v, u32::MAX).is_some()
    }

    #[inline]
    fn decay_trg(&self, i: Trace, dt: u32) -> Trace {
        Trace::from_bits(scale_q31(i.to_bits(), self.exp_trg.decay_bits(dt)))
    }

    /// Drive `q = g I_T / theta` per µs, in Q48.
    #[inline]
    fn drive_q48(&self, i_trg: Trace) -> u128 {
        ((self.drive_q32 as u128) * (i_trg.to_bits() as u128)) >> (Trace::FRAC_NBITS - 16)
    }

    /// `v(s)` in Q32 and `v'(s)` in Q32 per µs (may be negative), for the closed form.
    #[inline]
    fn membrane_q32(&self, q48: u128, v_q32: u64, s: u32) -> (u64, i64) {
        let e31 = self.exp_trg.decay_bits(s) as u128;
        let qs32 = (q48 * s as u128) >> 16;
        let f = ((v_q32 as u128 + qs32) * e31) >> 31;
        let f = if f > u64::MAX as u128 {
            u64::MAX
        } else {
            f as u64
        };
        let qe32 = (q48 * e31) >> 47;
        let f_over_tau = ((f as u128 * self.inv_tau_q48 as u128) >> 48) as i128;
        let slope = qe32 as i128 - f_over_tau;
        let slope = slope.clamp(i64::MIN as i128, i64::MAX as i128) as i64;
        (f, slope)
    }

    /// Normalised membrane after `dt` µs without a crossing (clamped below 1).
    fn membrane_after(&self, i_trg: Trace, v: U1F31, dt: u32) -> U1F31 {
        let (f, _) = self.membrane_q32(self.drive_q48(i_trg), (v.to_bits() as u64) << 1, dt);
        U1F31::from_bits((f >> 1).min(u64::from(ONE_Q31 - 1)) as u32)
    }

    /// The first crossing of `v = 1` within `1..=window` µs, if any.
    pub fn next_crossing(&self, i_trg: Trace, v: U1F31, window: u32) -> Option<Crossing> {
        if window == 0 {
            return None;
        }
        let q48 = self.drive_q48(i_trg);
        if q48 == 0 {
            return None;
        }
        let v32 = (v.to_bits() as u64) << 1;
        if v32 >= ONE_Q32 {
            return Some(Crossing {
                whole_us: 1,
                lag_q32: 0,
            });
        }
        let mut s: u32 = 0;
        for _ in 0..MAX_NEWTON_STEPS {
            let (f, slope) = self.membrane_q32(q48, v32, s);
            if f >= ONE_Q32 && s > 0 {
                // `s` is the first whole µs past the crossing, which lies `(f - 1) / slope` µs
                // earlier (less than 1 µs).
                let over = f - ONE_Q32;
                let lag = if slope > 0 {
                    ((u128::from(over) << 32) / slope as u128).min(u128::from(u32::MAX)) as u32
                } else {
                    0
                };
                return Some(Crossing {
                    whole_us: s,
                    lag_q32: lag,
                });
            }
            if slope <= 0 {
                return None;
            }
            let need = ONE_Q32.saturating_sub(f);
            let step = need.div_ceil(slope as u64).max(1);
            let next = u64::from(s) + step;
            if next > u64::from(window) {
                // Newton never passes the crossing: it lies beyond the window, unless it lies in
                // the window's last µs; check the end itself.
                let (f_end, _) = self.membrane_q32(q48, v32, window);
                return (f_end >= ONE_Q32).then_some(Crossing {
                    whole_us: window,
                    lag_q32: 0,
                });
            }
            s = next as u32;
        }
        None
    }
}

/// Where the membrane reaches threshold, relative to the last state update.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crossing {
    /// The first whole µs at or after the crossing (>= 1).
    pub whole_us: u32,
    /// How far (Q0.32 of a µs) the crossing lies before `whole_us`.
    pub lag_q32: u32,
}

impl Crossing {
    /// The whole µs nearest to the crossing (never 0): where the spike is reported.
    pub fn nearest_us(&self) -> u32 {
        if self.lag_q32 >= 1 << 31 && self.whole_us > 1 {
            self.whole_us - 1
        } else {
            self.whole_us
        }
    }
}

/// State of one unit between inputs (the time it refers to is kept by the caller).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UnitState {
    /// TRG trace `I_T`.
    pub i_trg: Trace,
    /// Normalised membrane `u / theta`, in `[0, 1)`.
    pub v: U1F31,
    /// Remaining refractory time (µs); `v` is held at 0 while it is non-zero.
    pub refractory_us: u32,
    /// While refractory: how far (Q0.16 µs) the true end of the refractory period lies before the
    /// whole µs at which `refractory_us` runs out.
    pub lag_q16: u16,
}

/// A FAC trace and the time it refers to. One per pixel in a network.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FacTrace {
    /// `I_F` at time `t_us`.
    pub i: Trace,
    /// Time (µs) of the last update.
    pub t_us: u32,
}

impl FacTrace {
    /// `I_F` at time `t` (just before any event at `t`).
    #[inline]
    pub fn at(&self, k: &Kernel, t: u32) -> Trace {
        k.decay_fac(self.i, elapsed_us(self.t_us, t))
    }

    /// Applies one FAC event at time `t`.
    #[inline]
    pub fn input(&mut self, k: &Kernel, t: u32) {
        let now = self.at(k, t);
        self.i = k.fac_input(now);
        if elapsed_us(self.t_us, t) > 0 {
            self.t_us = t;
        }
    }
}

/// One stand-alone TDE: a FAC input, a TRG input and the unit. Used by the sweep and the tests;
/// the network keeps the same pieces in compact form.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Tde {
    /// The FAC trace.
    pub fac: FacTrace,
    /// The unit.
    pub unit: UnitState,
    /// Time (µs) the unit state refers to.
    pub t_us: u32,
}

impl Tde {
    /// A unit at rest whose clock starts at `t0`.
    pub fn new(t0: u32) -> Self {
        Self {
            fac: FacTrace {
                i: Trace::ZERO,
                t_us: t0,
            },
            unit: UnitState::default(),
            t_us: t0,
        }
    }

    /// A FAC event at `t`.
    pub fn fac(&mut self, k: &Kernel, t: u32) {
        self.fac.input(k, t);
    }

    /// A TRG event at `t`; spikes up to `t` are emitted first.
    pub fn trg<F: FnMut(u32)>(&mut self, k: &Kernel, t: u32, on_spike: F) -> u32 {
        let n = self.advance(k, t, on_spike);
        let i_fac = self.fac.at(k, t);
        k.trg_input(&mut self.unit, i_fac);
        n
    }

    /// Emits the spikes up to `t` and moves the unit's clock there.
    pub fn advance<F: FnMut(u32)>(&mut self, k: &Kernel, t: u32, on_spike: F) -> u32 {
        let dt = elapsed_us(self.t_us, t);
        let n = k.advance(&mut self.unit, self.t_us, dt, on_spike);
        self.t_us = self.t_us.wrapping_add(dt);
        n
    }
}

/// Response of a fresh unit to one FAC event at `t0` and one TRG event `dt_us` later: the number
/// of spikes and the delay (µs) of the first spike after the TRG event. The unit is run until its
/// burst is over.
pub fn pair_response(k: &Kernel, t0: u32, dt_us: u32) -> PairResponse {
    let mut tde = Tde::new(t0);
    tde.fac(k, t0);
    let t_trg = t0.wrapping_add(dt_us);
    let mut count = 0u32;
    let mut first = None;
    let mut record = |t: u32| {
        count += 1;
        if first.is_none() {
            first = Some(t.wrapping_sub(t_trg));
        }
    };
    tde.trg(k, t_trg, &mut record);
    // A burst is over within ~14 time constants (<= 1 s each). Advance in 2^22 µs steps, so that
    // no single step comes near the 2^31 µs limit of a forward time difference.
    let mut t = t_trg;
    for _ in 0..4 {
        t = t.wrapping_add(1 << 22);
        tde.advance(k, t, &mut record);
    }
    PairResponse {
        spikes: count,
        first_spike_us: first,
    }
}

/// What one FAC→TRG pair produces (see [`pair_response`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PairResponse {
    /// Number of spikes in the burst.
    pub spikes: u32,
    /// Delay of the first spike after the TRG event (µs), if any.
    pub first_spike_us: Option<u32>,
}

/// `x · a / b` for `a <= b`, `b > 0` (to 2^-31 relative), with one 64-bit division.
#[inline]
fn scale_by_ratio(x: u64, a: u64, b: u64) -> u64 {
    // Both shifted so that b < 2^32: the ratio keeps 31 bits or more.
    let k = 32u32.saturating_sub(b.leading_zeros());
    let (a, b) = (a >> k, (b >> k).max(1));
    // Q32, <= 1 (a quotient below 2^32 unless a == b).
    let ratio = div_u64(a << 32, b);
    ((u128::from(x) * u128::from(ratio)) >> 32) as u64
}

/// `n / d` when the quotient is below 2^32 (`n >> 32 < d`; `None` otherwise, and for `d = 0`).
/// Exact. On a 32-bit target it takes two 32-bit divisions (one instruction each on the
/// Cortex-M4, where a 64-bit division is a library routine of a few hundred instructions):
/// long division in base 2^16 after normalising `d` (Hacker's Delight, `divlu`).
#[inline]
pub(crate) fn div_narrow(n: u64, d: u32) -> Option<u32> {
    if n >> 32 >= u64::from(d) {
        return None;
    }
    if cfg!(target_pointer_width = "64") {
        n.checked_div(u64::from(d)).map(|q| q as u32)
    } else {
        Some(div_narrow_32(n, d))
    }
}

/// `n / d` for `d > 0` (0 for `d = 0`), exact: by [`div_narrow`] when `d` and the quotient fit
/// in 32 bits, else by a 64-bit division (a library routine on a 32-bit MCU).
#[inline]
pub(crate) fn div_u64(n: u64, d: u64) -> u64 {
    match u32::try_from(d).ok().and_then(|d32| div_narrow(n, d32)) {
        Some(q) => u64::from(q),
        None => n.checked_div(d).unwrap_or(0),
    }
}

/// [`div_narrow`] from 32-bit divisions (`n >> 32 < d` required; then `d > 0`).
#[inline]
fn div_narrow_32(n: u64, d: u32) -> u32 {
    const B: u32 = 1 << 16;
    // Normalised: v has its top bit set, so its top half vn1 is at least 2^15 and every
    // quotient digit estimate below is at most 2 too high.
    let s = d.leading_zeros();
    let v = d << s;
    let (vn1, vn0) = (v >> 16, v & 0xFFFF);
    // n · 2^s < v · 2^32: still 64 bits.
    let n = n << s;
    let un32 = (n >> 32) as u32;
    let (un1, un0) = ((n as u32) >> 16, (n as u32) & 0xFFFF);
    let digit = |top: u32, next: u32| -> u32 {
        let mut q = top.checked_div(vn1).unwrap_or(0);
        let mut rhat = top - q * vn1;
        while q >= B || q * vn0 > (rhat << 16) + next {
            q -= 1;
            rhat += vn1;
            if rhat >= B {
                break;
            }
        }
        q
    };
    let q1 = digit(un32, un1);
    // The remainder so far (below v, so mod 2^32 is exact).
    let un21 = (un32 << 16)
        .wrapping_add(un1)
        .wrapping_sub(q1.wrapping_mul(v));
    let q0 = digit(un21, un0);
    (q1 << 16) | q0
}

/// A FAC trace as the spiking network keeps it: U7F24 bits (saturating just below 128, where a
/// [`Trace`] saturates at 16: busy pixels of real sensors pass 16, and the TRG drive with them;
/// the calibrated pipeline keeps its [`Trace`]s). The top bit stays free for flags.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
pub struct WideTrace(pub u32);

/// Largest [`WideTrace`] bits.
const WIDE_MAX: u32 = 0x7FFF_FFFF;

impl WideTrace {
    /// Fractional bits.
    pub const FRAC_NBITS: u32 = 24;

    /// The same value as a [`Trace`], saturating at [`TRACE_MAX`].
    pub fn to_trace(self) -> Trace {
        Trace::from_bits((u64::from(self.0) << 3).min(u64::from(TRACE_MAX.to_bits())) as u32)
    }
}

/// A time on the event clock with 32 fractional bits (Q32.32 µs, wrapping: the top 32 bits are
/// the `u32` µs clock). Differences are taken wrapping, as `i64`.
pub type FineTime = u64;

/// `t_us` as a [`FineTime`].
#[inline]
pub const fn fine(t_us: u32) -> FineTime {
    (t_us as u64) << 32
}

/// The whole µs nearest to `t`.
#[inline]
pub const fn nearest_us(t: FineTime) -> u32 {
    (t.wrapping_add(1 << 31) >> 32) as u32
}

/// The latest [`FineTime`] reported at or before `t_us` (nearest whole µs <= `t_us`).
#[inline]
pub const fn reported_by(t_us: u32) -> FineTime {
    fine(t_us).wrapping_add((1 << 31) - 1)
}

/// Whether a spike at `t` comes after `until` (both fine times, wrapping).
#[inline]
pub(crate) fn is_late(until: FineTime, t: FineTime) -> bool {
    (until.wrapping_sub(t) as i64) < 0
}

/// No burst (see [`BurstUnit::next`]).
const NO_SPIKE: u64 = u64::MAX;

/// [`BurstUnit::next`] of a burst whose spikes have all been emitted (the low bits keep where
/// its last spike was, in case an input takes it back).
const DONE: u64 = 1 << 63;

/// [`BurstUnit::te_rel`] of a unit at rest (no drive).
const AT_REST: i32 = i32::MIN;

/// Bits of a pending [`BurstUnit::next`] above its orbit coordinate (`alpha` stays below 2^45:
/// rows up to `L / delta`, `L <= 22`) that hold a sparse delivery plan (see
/// [`Kernel::burst_emit_run`]). Bit 62: the spikes from the pending one on are being
/// skipped, and no tick visits the unit (`next_us` stays the pending spike's nearest µs): what
/// the sink needs of them is delivered when something next acts on the unit.
const SKIPPING: u64 = 1 << 62;
/// Bits 61..59 of a pending `next`: 0 for a unit delivered spike by spike, else
/// [`HEAD_DONE`] or the spikes still to deliver before skipping (up to [`HEAD_IN_BURST`]).
const HEAD_SHIFT: u32 = 59;
/// The head count's bits.
const HEAD: u64 = 7 << HEAD_SHIFT;
/// A sparse unit whose head is out.
const HEAD_DONE: u64 = 7;
/// Spikes delivered after an input that reached the unit mid-burst, before skipping: the
/// readout decodes such an input from the first interval after it, or from the second when
/// the input came so late in the first that its first spike is hardly early (a third of the
/// decodes on a Prophesee Gen3 recording).
const HEAD_IN_BURST: u64 = 3;
/// Spikes delivered after an input that started a burst, before skipping: its first interval
/// decodes it (from rest; or, within the readout's memory of an earlier burst, as a
/// perturbation of a decaying current that could no longer make a spike, which makes the
/// first spike early whenever it comes).
const HEAD_FROM_REST: u64 = 2;
/// Every plan bit.
const PLAN: u64 = SKIPPING | HEAD;

/// Largest drive level the burst engine represents: `D <= e^22` (`I_T` up to about 10^8
/// default events' worth); above, `t*` is held at 22 `tau` ahead.
const LN_D_MAX: u32 = 22;

/// `e^22` in Q32.32.
const E22_Q32: u64 = 15_397_083_433_145_465_870;

/// In a network with a unit pool, a unit whose burst is out is at rest once its drive level
/// has fallen below `2^-REST_LEVEL_LOG2` (`4 ln 2 · tau` = 55 ms after `t*` at the default
/// `tau`), and takes its next input as a unit at rest would (see [`Kernel::burst_at_rest`]):
/// its slot can be freed. What is dropped (a drive below 1/16 and the membrane it charged)
/// moves the total spike count on the shared recordings by less than 0.01 %.
pub const REST_LEVEL_LOG2: u32 = 4;

/// One unit of the network's burst engine (see the module docs, "Two engines"). 24 bytes.
///
/// All of it is absolute time, so the state does not change between inputs and spikes: the
/// drive level is `D(t) = e^((t* - t)/tau)`, the membrane `v(t) = D(t)·(t - t_e)/tau` for
/// `t >= t_e` (0 before: refractory).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct BurstUnit {
    /// `t*`: when `D` is (or was) 1.
    ts: FineTime,
    /// The burst: the next spike to emit, at `t* - tau·r`, given by its Abel coordinate `alpha`
    /// (Q32.32; `r = r(alpha)`) with the burst tables, else by `r` itself (Q32.32), and for a
    /// sparse sink the delivery plan in bits 62..59 ([`SKIPPING`], [`HEAD`]); `DONE | alpha`
    /// (or `DONE | r`) of the last spike when all are out; `u64::MAX`: no burst.
    next: u64,
    /// `t_e - t*` in 1/256 µs ([`AT_REST`]: no drive at all), clamped to ±2^31: where the
    /// membrane started charging before the burst's first spike (or with no burst). Within a
    /// burst, `t_e` follows from the last spike.
    te_rel: i32,
    /// The nearest whole µs of the next spike to emit (while one is pending).
    next_us: u32,
}

/// What one [`Kernel::burst_emit_run`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Emission {
    /// Spikes written.
    pub n: usize,
    /// Spikes of the burst skipped (counted, not delivered).
    pub skipped: u32,
    /// The first spike written follows skipped ones: the sink must hear of it before that
    /// spike.
    pub resumed: bool,
}

impl Emission {
    /// Nothing done.
    pub const NONE: Self = Self {
        n: 0,
        skipped: 0,
        resumed: false,
    };
}

impl Default for BurstUnit {
    fn default() -> Self {
        Self::IDLE
    }
}

impl BurstUnit {
    /// A unit at rest.
    pub const IDLE: Self = Self {
        ts: 0,
        next: NO_SPIKE,
        te_rel: AT_REST,
        next_us: 0,
    };

    /// Whether a spike is pending: computed, not yet emitted.
    #[inline(always)]
    pub fn pending(&self) -> bool {
        self.next < DONE
    }

    /// Whether the unit is skipping spikes of its burst (see [`Kernel::burst_emit_run`]).
    #[inline(always)]
    pub fn skipping(&self) -> bool {
        self.pending() && self.next & SKIPPING != 0
    }

    /// Whether a spike is pending that a tick emits when it is due: pending, and not
    /// [skipping](BurstUnit::skipping).
    #[inline(always)]
    pub fn scheduled(&self) -> bool {
        self.next < SKIPPING
    }

    /// The nearest whole µs of the next spike to emit, if one is [scheduled](Self::scheduled).
    #[inline(always)]
    pub fn next_us(&self) -> Option<u32> {
        self.scheduled().then_some(self.next_us)
    }

    /// Whether no spike of the unit lies at or before `until`: none pending, or the pending
    /// one reported more than half a µs after `until` (its exact time is within half a µs of
    /// its reported one, for any plan).
    #[inline]
    pub fn none_due_by(&self, until: FineTime) -> bool {
        !self.pending() || is_late(until, fine(self.next_us).wrapping_sub(1 << 31))
    }

    /// Whether a spike is scheduled that is reported at or before `t_us` (no branch).
    #[inline(always)]
    pub fn due(&self, t_us: u32) -> bool {
        self.scheduled() & ((t_us.wrapping_sub(self.next_us) as i32) >= 0)
    }

    /// Whether the unit has no drive at all (the state [`BurstUnit::IDLE`]; see also
    /// [`Kernel::burst_at_rest`]).
    #[inline]
    pub fn is_idle(&self) -> bool {
        self.te_rel == AT_REST
    }

    /// The stored `t_e` (meaningless at rest).
    #[inline]
    fn te(&self) -> FineTime {
        self.ts
            .wrapping_add_signed(i64::from(self.te_rel).wrapping_mul(1 << 24))
    }

    /// Sets `t_e` (rounded to 1/256 µs).
    #[inline]
    fn set_te(&mut self, te: FineTime) {
        let rel = (te.wrapping_sub(self.ts) as i64) >> 24;
        self.te_rel = rel.clamp(i64::from(i32::MIN) + 1, i64::from(i32::MAX)) as i32;
    }

    /// `t*` (Q32.32 µs): the drive level is `D(t) = e^((t* - t)/tau)`.
    pub fn t_star(&self) -> Option<FineTime> {
        (!self.is_idle()).then_some(self.ts)
    }
}

impl Kernel {
    /// Whether this kernel's bursts come from the burst tables (default `t_ref` and `tau`) or
    /// from Newton's method.
    pub fn has_burst_tables(&self) -> bool {
        self.orbit
    }

    /// Whether the unit is at rest at `t_us`: idle, or its burst is out (or
    /// [skipping](BurstUnit::skipping): its spikes then all lie before `t*`) and its drive
    /// level is below `2^-`[`REST_LEVEL_LOG2`]. A network with a unit pool counts such a unit
    /// as [`BurstUnit::IDLE`] (an input starts it afresh) and frees its state, once a skipping
    /// unit has delivered what its sink needs ([`Kernel::burst_emit_run`] with a catch-up). No
    /// spike of its burst lies at or after `t_us`. `t_us` must not precede the unit's last
    /// input.
    #[inline]
    pub fn burst_at_rest(&self, u: &BurstUnit, t_us: u32) -> bool {
        if u.is_idle() {
            return true;
        }
        let rest_from = u.ts.wrapping_add(self.rest_after_fine);
        (!u.pending() || u.skipping()) && !is_late(fine(t_us), rest_from)
    }

    /// Brings a unit whose drive has become negligible (`D < 2^-32`) at `t_us` to rest, so
    /// that no stored time falls more than a few seconds behind the clock.
    #[inline]
    pub fn burst_settle(&self, u: &mut BurstUnit, t_us: u32) {
        if !u.is_idle() && !u.pending() && self.drive_level(u, fine(t_us)) == 0 {
            *u = BurstUnit::IDLE;
        }
    }

    /// The drive level `D(t) = e^((t* - t)/tau)` in Q32.32 (0 below 2^-32 and at rest).
    #[inline]
    fn drive_level(&self, u: &BurstUnit, t: FineTime) -> u64 {
        if u.is_idle() {
            return 0;
        }
        // (t* - t)/tau = n ln 2 + y, 0 <= y < ln 2: D = 2^(n+1) · e^(-(ln 2 - y)), the last
        // factor in (1/2, 1] from the TRG decay table.
        let ln2_tau = self.ln2_tau_fine as i64;
        let tau_fine = i64::from(self.params.tau_trg_us) << 32;
        let ahead = (u.ts.wrapping_sub(t) as i64).min(i64::from(LN_D_MAX) * tau_fine);
        let mut n = ((i128::from(ahead) * i128::from(self.inv_ln2_tau_q64)) >> 64) as i64;
        let mut rem = ahead - n * ln2_tau;
        while rem < 0 {
            n -= 1;
            rem += ln2_tau;
        }
        while rem >= ln2_tau {
            n += 1;
            rem -= ln2_tau;
        }
        let shift = n + 2; // a Q31 factor times 2^(n+1), wanted in Q32: << (n + 2)
        if shift <= -31 {
            return 0;
        }
        let dt = (ln2_tau - rem) as u64;
        let e = u64::from(self.exp_trg.decay_bits((dt >> 32) as u32));
        // e^(-f/tau) ~ 1 - f/tau for the fraction f < 1 µs (error below 2e-9).
        let frac_over_tau =
            ((u128::from(dt & 0xFFFF_FFFF) * u128::from(self.inv_tau_q48)) >> 48) as u64;
        let e = ((u128::from(e) * u128::from(ONE_Q32 - frac_over_tau)) >> 32) as u64; // Q31
        if shift >= 0 {
            e.checked_shl(shift as u32)
                .map_or(E22_Q32, |d| d.min(E22_Q32))
        } else {
            e >> (-shift) as u32
        }
    }

    /// `r` (Q5.27) of the spike at `next` (either engine), exactly as emitted.
    #[inline]
    fn r_emitted(&self, next: u64) -> u64 {
        if self.orbit {
            orbit::r_emitted(next)
        } else {
            next >> 5
        }
    }

    /// The exact time of the spike at `next` (a pending or emitted spike of `u`'s burst).
    #[inline]
    fn spike_time(&self, u: &BurstUnit, next: u64) -> FineTime {
        self.orbit_time(u.ts, next)
    }

    /// The exact time of the spike at `next` of a burst with anchor `ts` (`t*`).
    #[inline]
    fn orbit_time(&self, ts: FineTime, next: u64) -> FineTime {
        ts.wrapping_sub(self.tau_times_r(self.r_emitted(next)))
    }

    /// The orbit point before `next` (pending spike): the spike emitted before it, or before the
    /// burst's first spike a virtual one exactly one refractory period before `t_e`.
    #[inline]
    fn previous(&self, next: u64) -> u64 {
        if self.orbit {
            next.saturating_add(orbit::ONE)
        } else {
            next + self.exp_neg_q32(next) + self.delta_q32()
        }
    }

    /// Emits the unit's pending spikes whose exact time is at or before `until`, in order,
    /// calling `on_spike` with each one's nearest whole µs. Returns how many.
    #[inline]
    pub fn burst_emit<F: FnMut(u32)>(
        &self,
        u: &mut BurstUnit,
        until: FineTime,
        mut on_spike: F,
    ) -> u32 {
        let mut run = [0u32; 32];
        let mut total = 0u32;
        loop {
            let n = self.burst_emit_into(u, until, &mut run);
            for &t in run.get(..n).unwrap_or_default() {
                on_spike(t);
            }
            total += n as u32;
            if n < run.len() {
                return total;
            }
        }
    }

    /// Writes the unit's pending spikes whose exact time is at or before `until` into `out`,
    /// in order, each at its nearest whole µs, until `out` is full. Returns how many (fewer
    /// than `out.len()`: all such spikes are out). For a unit delivered spike by spike (no
    /// plan of [`Kernel::burst_plan_sparse`]).
    #[inline]
    pub fn burst_emit_into(&self, u: &mut BurstUnit, until: FineTime, out: &mut [u32]) -> usize {
        if !u.pending() {
            return 0;
        }
        if !self.orbit {
            return self.burst_emit_newton(u, until, out);
        }
        let e = orbit::emit(u.ts, until, u.next, out);
        self.advance_past(u, &e);
        e.n
    }

    /// Moves a unit (its `next` an orbit coordinate without plan bits) past the spikes
    /// `e` emitted: to the next spike, with its nearest whole µs, or to the burst's end.
    /// Nothing when none was emitted.
    #[inline]
    fn advance_past(&self, u: &mut BurstUnit, e: &orbit::Emitted) {
        if e.n == 0 {
            return;
        }
        if e.next == u64::MAX {
            u.next = DONE | (u.next & 0xFFFF_FFFF);
        } else {
            u.next = e.next;
            u.next_us = e.next_us;
        }
    }

    /// Gives a unit that has just taken an input a sparse delivery plan (with the burst
    /// tables only; else nothing changes): its next three spikes (two when the input started
    /// the burst: `mid_burst` false) are delivered as they come, then the rest of its burst
    /// is skipped (see [`Kernel::burst_emit_run`]).
    #[inline]
    pub fn burst_plan_sparse(&self, u: &mut BurstUnit, mid_burst: bool) {
        if self.orbit && u.pending() {
            let head = if mid_burst {
                HEAD_IN_BURST
            } else {
                HEAD_FROM_REST
            };
            u.next = (u.next & !PLAN) | (head << HEAD_SHIFT);
        }
    }

    /// Ends a unit's sparse plan before an input acts on it (the spikes skipped up to the
    /// input must have been delivered first: [`Kernel::burst_emit_run`] with a catch-up).
    #[inline]
    pub fn burst_plan_end(&self, u: &mut BurstUnit) {
        if u.pending() {
            // A skipping unit's `next_us` is its pending spike's already.
            u.next &= !PLAN;
        }
    }

    /// [`Kernel::burst_emit_into`] for any unit, planned sparse or not ([`Emission`]).
    ///
    /// A sparse unit ([`Kernel::burst_plan_sparse`]) delivers the first three spikes after
    /// each input that reached it mid-burst, two after one that started a burst, as they
    /// come, then skips the rest of its burst: no tick visits it. A catch-up (`catch_up = Some(memory_us)`: before an input at `until`, before the unit's
    /// state is freed or settled, at the end of a recording) delivers the last two spikes at
    /// or before `until` instead, after skipping those before them; or nothing, when the
    /// burst's last spike came more than `memory_us` before `until` (the sink no longer reads
    /// it: [`crate::network::NetSink::tail_memory_us`]). A burst of `n` spikes thus costs at
    /// most five deliveries, not `n`; the skipped spikes are counted. A call that resumes after
    /// a skip says so ([`Emission::resumed`]) and writes the spikes that follow it: the sink
    /// must hear of the skip before them. Without a catch-up a skipping unit does nothing.
    #[inline]
    pub fn burst_emit_run(
        &self,
        u: &mut BurstUnit,
        until: FineTime,
        out: &mut [u32],
        catch_up: Option<u32>,
    ) -> Emission {
        if !u.pending() || u.next & PLAN == 0 {
            return Emission {
                n: self.burst_emit_into(u, until, out),
                ..Emission::NONE
            };
        }
        self.burst_emit_sparse(u, until, out, catch_up)
    }

    /// [`Kernel::burst_emit_run`] of a sparse unit.
    #[inline(never)]
    fn burst_emit_sparse(
        &self,
        u: &mut BurstUnit,
        until: FineTime,
        out: &mut [u32],
        catch_up: Option<u32>,
    ) -> Emission {
        let alpha = u.next & !PLAN;
        let frac = alpha & 0xFFFF_FFFF;
        let mut skip = Emission::NONE;
        if u.next & SKIPPING != 0 {
            let Some(memory_us) = catch_up else {
                return Emission::NONE;
            };
            let row = alpha >> 32;
            // The pending spike lies within half a µs of `next_us`: most catch-ups come
            // before it (an input to the unit's twin, say) and need no more.
            if u.none_due_by(until) {
                return Emission::NONE;
            }
            let at = |r: u64| self.orbit_time(u.ts, (r << 32) | frac);
            let near_us = fine(u.next_us).wrapping_add(1 << 31);
            let t_row = if is_late(until, near_us) {
                // Within half a µs of it: the exact time decides.
                let t = at(row);
                if is_late(until, t) {
                    return Emission::NONE;
                }
                t
            } else {
                // Due for sure. Its time within half a µs, which is all the row search below
                // takes from it (to interpolate; its comparisons are exact).
                fine(u.next_us)
            };
            // The row to deliver from: the second-to-last spike due.
            let t_last = at(0);
            let target = if is_late(until, t_last) {
                self.lowest_due_row(u.ts, frac, (0, t_last), (row, t_row), until)
                    .saturating_add(1)
            } else if until.wrapping_sub(t_last) > fine(memory_us) {
                // The burst is over, its last spike beyond the sink's memory: nothing to
                // deliver.
                u.next = DONE | frac;
                return Emission {
                    skipped: u32::try_from(row.saturating_add(1)).unwrap_or(u32::MAX),
                    ..Emission::NONE
                };
            } else {
                1
            };
            let target = target.min(row);
            skip = Emission {
                n: 0,
                skipped: u32::try_from(row.saturating_sub(target)).unwrap_or(u32::MAX),
                resumed: target < row,
            };
            u.next = (target << 32) | frac | (HEAD_DONE << HEAD_SHIFT);
        }
        let head = (u.next & HEAD) >> HEAD_SHIFT;
        let cap = if head == HEAD_DONE {
            out.len()
        } else {
            (head as usize).min(out.len())
        };
        u.next &= !PLAN;
        let e = orbit::emit(u.ts, until, u.next, out.get_mut(..cap).unwrap_or_default());
        let head = match head {
            HEAD_DONE => HEAD_DONE,
            h => match h.saturating_sub(e.n as u64) {
                0 => HEAD_DONE,
                left => left,
            },
        };
        // With the head out, skip the rest.
        let skips = head == HEAD_DONE && e.next != u64::MAX;
        self.advance_past(u, &e);
        if u.pending() {
            u.next |= head << HEAD_SHIFT;
            if skips {
                u.next |= SKIPPING;
            }
        }
        Emission { n: e.n, ..skip }
    }

    /// The lowest row of a burst (anchor `ts`, column `frac`) whose spike lies at or before
    /// `until`, within `(lo, hi]`, given each end's row and spike time (`lo`'s after `until`,
    /// `hi`'s not). Earlier spikes have higher rows. Found by interpolating the spike times,
    /// which fall about evenly over the rows, every other step halving instead (at most twice
    /// as many steps as halving alone).
    fn lowest_due_row(
        &self,
        ts: FineTime,
        frac: u64,
        (mut lo, mut t_lo): (u64, FineTime),
        (mut hi, mut t_hi): (u64, FineTime),
        until: FineTime,
    ) -> u64 {
        let mut halve = false;
        while hi.saturating_sub(lo) > 1 {
            let width = hi.saturating_sub(lo);
            let step = if halve {
                width / 2
            } else {
                // width · ahead / span, to 16 bits (a 32-bit division).
                let span = t_lo.wrapping_sub(t_hi).max(1);
                let cut = (64 - span.leading_zeros()).saturating_sub(16);
                let span = (span >> cut).max(1) as u32;
                let ahead = (t_lo.wrapping_sub(until) >> cut).min(u64::from(span));
                let width32 = u32::try_from(width).unwrap_or(u32::MAX);
                let step = width32.saturating_mul(ahead as u32).checked_div(span);
                u64::from(step.unwrap_or(0))
            };
            // Strictly inside (lo, hi).
            let mid = lo.saturating_add(step.max(1).min(width.saturating_sub(1)));
            halve = !halve;
            let t_mid = self.orbit_time(ts, (mid << 32) | frac);
            if is_late(until, t_mid) {
                (lo, t_lo) = (mid, t_mid);
            } else {
                (hi, t_hi) = (mid, t_mid);
            }
        }
        hi
    }

    /// [`Kernel::burst_emit_into`] without burst tables: each next spike by Newton's method.
    #[inline(never)]
    fn burst_emit_newton(&self, u: &mut BurstUnit, until: FineTime, out: &mut [u32]) -> usize {
        let delta = self.delta_q32();
        let mut n = 0;
        while u.pending() {
            let r = u.next;
            let t = self.spike_time(u, r);
            if (until.wrapping_sub(t) as i64) < 0 {
                break;
            }
            let Some(slot) = out.get_mut(n) else {
                break;
            };
            *slot = nearest_us(t);
            n += 1;
            u.next = r
                .checked_sub(delta)
                .and_then(|y| self.h_inv(y))
                .unwrap_or(DONE | r);
            if u.pending() {
                u.next_us = nearest_us(self.spike_time(u, u.next));
            }
        }
        n
    }

    /// Takes back the unit's emitted spikes whose exact time lies after `after` (they were
    /// emitted ahead of the clock; an input at `after` changes the burst), latest first,
    /// calling `on_retract` with each one's nearest whole µs. Returns how many.
    pub fn burst_retract<F: FnMut(u32)>(
        &self,
        u: &mut BurstUnit,
        after: FineTime,
        mut on_retract: F,
    ) -> u32 {
        if u.next == NO_SPIKE {
            return 0;
        }
        // The last emitted spike: the one before the pending one, or the burst's last.
        let mut last = if u.pending() {
            self.previous(u.next)
        } else {
            u.next & !DONE
        };
        let mut n = 0;
        while n < MAX_RETRACT {
            let t = self.spike_time(u, last);
            if (t.wrapping_sub(after) as i64) <= 0 {
                break;
            }
            // A virtual point before the burst's first spike lies before the input that
            // started the burst: the walk always ends there.
            on_retract(nearest_us(t));
            n += 1;
            u.next = last;
            u.next_us = nearest_us(t);
            last = self.previous(last);
        }
        n
    }

    /// `delta = t_ref / tau` in Q32.32.
    #[inline]
    fn delta_q32(&self) -> u64 {
        fine(self.params.t_ref_us) / u64::from(self.params.tau_trg_us.max(1))
    }

    /// When the unit's membrane started charging: after its last spike's refractory period if
    /// that spike belongs to the current burst, else the stored start.
    fn charging_start(&self, u: &BurstUnit) -> FineTime {
        let te = u.te();
        if u.next == NO_SPIKE {
            return te;
        }
        let last = if u.pending() {
            // The orbit point before the pending spike (precise, not as emitted).
            let prev = self.previous(u.next);
            let r = if self.orbit {
                orbit::r_at(prev)
            } else {
                prev >> 5
            };
            u.ts.wrapping_sub(self.tau_times_r(r))
        } else {
            // All spikes out (and in the past): the burst's last spike.
            let x = u.next & !DONE;
            let r = if self.orbit {
                orbit::r_last(orbit::r_at(x + orbit::ONE), true)
            } else {
                x >> 5
            };
            u.ts.wrapping_sub(self.tau_times_r(r))
        };
        let after = last.wrapping_add(fine(self.params.t_ref_us));
        if (after.wrapping_sub(te) as i64) > 0 {
            after
        } else {
            te
        }
    }

    /// Applies one TRG event at `t_us` to a unit, with the current FAC trace of its FAC pixel:
    /// `I_T += w_T·I_F(t⁻)` (the one drive formula of [`Kernel::drive`]), the membrane
    /// continuous, and the next spike recomputed. Spikes up to `t_us` must have been emitted,
    /// and any emitted after it taken back, first ([`Kernel::burst_emit`],
    /// [`Kernel::burst_retract`]).
    pub fn burst_input(&self, u: &mut BurstUnit, t_us: u32, i_fac_now: WideTrace) {
        let drive = u128::from(self.drive_q27(i_fac_now.0, WideTrace::FRAC_NBITS));
        let dd = (drive * u128::from(self.d_per_trace_q32)) >> Trace::FRAC_NBITS;
        let dd = u64::try_from(dd).unwrap_or(u64::MAX);
        if dd == 0 {
            return;
        }
        let tt = fine(t_us);
        let d0 = self.drive_level(u, tt);
        let d1 = d0.saturating_add(dd).min(E22_Q32);
        // The membrane is continuous: v = D·(t - t_e)/tau before and after, so the charging
        // start moves to t - (D/D')·(t - t_e). In a refractory period it stays.
        let te = if d0 == 0 {
            tt
        } else {
            let te_old = self.charging_start(u);
            let since = tt.wrapping_sub(te_old) as i64;
            if since > 0 {
                tt.wrapping_sub(scale_by_ratio(since as u64, d0, d1))
            } else {
                te_old
            }
        };
        let ln_d = orbit::ln_q32(d1).unwrap_or(i64::MIN / 2);
        u.ts = tt.wrapping_add_signed(ln_d.saturating_mul(i64::from(self.params.tau_trg_us)));
        u.set_te(te);
        u.next = NO_SPIKE;
        // Past the peak of v (charging for tau or longer) it can only fall.
        let charged = tt.wrapping_sub(te) as i64;
        if charged >= (i64::from(self.params.tau_trg_us) << 32) {
            return;
        }
        // L = ln D(t_e) = ln D(t) + (t - t_e)/tau.
        let l = if charged == 0 {
            // Charging starts at the input (a unit at rest): L = ln D(t).
            ln_d
        } else {
            ln_d + ((i128::from(charged) * i128::from(self.inv_tau_q48)) >> 48) as i64
        };
        let Ok(l) = u64::try_from(l) else {
            return;
        };
        if l < ONE_Q32 {
            return;
        }
        let first = if self.orbit {
            orbit::first_alpha(l)
        } else {
            self.h_inv(l)
        };
        if let Some(first) = first {
            u.next = first;
            u.next_us = nearest_us(self.spike_time(u, first));
        }
    }

    /// `tau·r` as a fine duration, for `r` in Q5.27.
    #[inline]
    fn tau_times_r(&self, r_q27: u64) -> u64 {
        (u64::from(self.params.tau_trg_us) * r_q27) << 5
    }

    /// `r >= 0` with `r + e^(-r) = y` (Q32.32, `y >= 1`), by Newton's method from `r = y` (the
    /// function is convex and increasing there, so the iterates fall monotonically onto the
    /// root). For kernels without burst tables.
    fn h_inv(&self, y: u64) -> Option<u64> {
        if y < ONE_Q32 {
            return None;
        }
        let mut r = y;
        for _ in 0..MAX_NEWTON_STEPS {
            let e = self.exp_neg_q32(r);
            let g = (r + e).saturating_sub(y);
            let slope = ONE_Q32.saturating_sub(e);
            if g == 0 || slope == 0 {
                break;
            }
            let step = ((u128::from(g) << 32) / u128::from(slope)).max(1);
            let step = u64::try_from(step).unwrap_or(u64::MAX);
            if step >= r {
                r = 0;
                break;
            }
            r -= step;
        }
        Some(r)
    }

    /// `e^(-r)` in Q0.32 for `r` in Q32.32, from the TRG decay table (`r·tau` µs).
    fn exp_neg_q32(&self, r: u64) -> u64 {
        let x = u128::from(r) * u128::from(self.params.tau_trg_us);
        let whole = x >> 32;
        if whole >= u128::from(crate::exp_table::DECAY_HORIZON_US) {
            return 0;
        }
        let e = u128::from(self.exp_trg.decay_bits(whole as u32));
        // e^(-f/tau) ~ 1 - f/tau for the fraction f < 1 µs (error below 2e-9).
        let frac_over_tau = ((x & 0xFFFF_FFFF) * u128::from(self.inv_tau_q48)) >> 48;
        ((e * (u128::from(ONE_Q32) - frac_over_tau)) >> 31) as u64
    }
}

#[cfg(test)]
mod burst_tests {
    use super::*;

    #[test]
    fn drive_level_is_exp_of_t_star() {
        let k = Kernel::DEFAULT;
        for i in 0..4000i64 {
            let x = -22.0 + (i as f64) * 0.011; // (t* - t) / tau
            let u = BurstUnit {
                ts: fine(1_000_000).wrapping_add_signed((x * 20_000.0 * 4_294_967_296.0) as i64),
                next: NO_SPIKE,
                te_rel: 0,
                next_us: 0,
            };
            let d = k.drive_level(&u, fine(1_000_000)) as f64 / 4_294_967_296.0;
            let want = x.exp();
            assert!(
                (d - want).abs() <= 6e-9 * want + 2.0 / 4_294_967_296.0,
                "x {x}: {d} vs {want}"
            );
        }
    }

    #[test]
    fn narrow_division_is_exact() {
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        let mut cases = 0;
        for i in 0..200_000u32 {
            let d = match i % 4 {
                0 => next() as u32 | 1,
                1 => (next() as u32) >> (next() % 32),
                2 => u32::MAX - (next() as u32 & 0xFF),
                _ => 1 << (next() % 32),
            };
            if d == 0 {
                continue;
            }
            // Quotients of every size below 2^32, and the largest numerators allowed.
            let n = match i % 3 {
                0 => next() % (u64::from(d) << 32),
                1 => (u64::from(d) << 32) - 1 - (next() & 0xFFFF).min(u64::from(d) << 32 >> 1),
                _ => next() >> (next() % 64),
            };
            let want = n / u64::from(d);
            if want >> 32 == 0 {
                assert_eq!(u64::from(div_narrow_32(n, d)), want, "{n} / {d}");
                assert_eq!(div_narrow(n, d).map(u64::from), Some(want));
                cases += 1;
            } else {
                assert_eq!(div_narrow(n, d), None);
            }
        }
        assert!(cases > 150_000, "{cases}");
        assert_eq!(div_narrow(5, 0), None);
    }

    #[test]
    fn emission_in_small_runs_is_emission_in_one() {
        // A burst written out 3 spikes at a time, with a clock that stops mid-burst, gives
        // the spikes, the pending spike's time and the final state of one long run.
        for k in [
            Kernel::DEFAULT,
            Kernel::new(TdeParams {
                t_ref_us: 130,
                ..TdeParams::DEFAULT
            })
            .unwrap(),
        ] {
            let mut whole = BurstUnit::IDLE;
            k.burst_input(&mut whole, 1000, WideTrace(3 << 24));
            let mut parts = whole;
            let mut all = [0u32; 4096];
            let mut got = [0u32; 4096];
            let (mut n_all, mut n_got) = (0usize, 0usize);
            for until in [40_000u32, 41_000, 2_000_000] {
                n_all += k.burst_emit_into(&mut whole, fine(until), &mut all[n_all..]);
                loop {
                    let mut run = [0u32; 3];
                    let n = k.burst_emit_into(&mut parts, fine(until), &mut run);
                    got[n_got..n_got + n].copy_from_slice(&run[..n]);
                    n_got += n;
                    if n < run.len() {
                        break;
                    }
                }
                // (`next_us` means nothing once the burst is out.)
                let state = |u: &BurstUnit| (u.ts, u.next, u.te_rel, u.next_us());
                assert_eq!(state(&whole), state(&parts), "until {until}");
            }
            assert!(n_all > 30, "{n_all}");
            assert!(!whole.pending());
            assert_eq!(&all[..n_all], &got[..n_got]);
        }
    }

    #[test]
    fn a_second_spike_needs_the_drive_its_closed_form_says() {
        let k = Kernel::DEFAULT;
        // Spikes of a burst from rest after an input whose FAC trace is `bits` (WideTrace).
        let spikes = |bits: u32| {
            let mut u = BurstUnit::IDLE;
            k.burst_input(&mut u, 1000, WideTrace(bits));
            k.burst_emit(&mut u, fine(2_000_000), |_| {})
        };
        // The smallest trace (hence drive) that gives at least `n` spikes.
        let least = |n: u32| {
            let (mut lo, mut hi) = (1u32, 1 << 26);
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if spikes(mid) >= n {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            lo
        };
        let (one, two) = (least(1), least(2));
        assert!(spikes(two - 1) == 1 && spikes(one - 1) == 0);
        let measured = (f64::from(two) / f64::from(one)).log2();
        let delta = f64::from(k.params.t_ref_us) / f64::from(k.params.tau_trg_us);
        let closed = (delta + (-1.0f64 - delta).exp()) * core::f64::consts::LOG2_E;
        let got = f64::from(k.second_spike_log2_q16()) / 65_536.0;
        assert!((got - closed).abs() < 1e-4, "{got} vs {closed}");
        // The trace's resolution (2^-24 of ~0.06) and the burst tables' rounding.
        assert!((measured - closed).abs() < 2e-3, "{measured} vs {closed}");
    }

    #[test]
    fn a_strong_input_bursts_and_a_weak_one_does_not() {
        let k = Kernel::DEFAULT;
        let mut u = BurstUnit::IDLE;
        k.burst_input(&mut u, 1000, WideTrace(1 << 24 >> 5)); // 1/32
        assert!(!u.pending());
        k.burst_input(&mut u, 1000, WideTrace(1 << 24));
        assert!(u.pending());
        let (mut n, mut last) = (0u32, 0u32);
        k.burst_emit(&mut u, fine(2_000_000), |t| {
            assert!(n == 0 || t > last);
            n += 1;
            last = t;
        });
        assert!(!u.pending());
        assert!(n > 20, "{n}");
    }
}
