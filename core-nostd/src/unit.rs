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

use fixed::types::U1F31;

use crate::exp_table::{scale_q31, ExpDecay, ONE_Q31};
use crate::params::{ParamError, TdeParams, Trace, TRACE_MAX};

/// `1.0` in Q32 (the format of normalised membrane values inside the solver).
const ONE_Q32: u64 = 1 << 32;

/// `1/e` in Q0.32.
const INV_E_Q32: u128 = 1_580_030_169;

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
}

impl Kernel {
    /// The kernel for the default parameters, computed at compile time (tables in flash).
    pub const DEFAULT: Self = Self::from_valid(TdeParams::DEFAULT);

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
        Self {
            params,
            exp_fac: ExpDecay::new(params.tau_fac_us),
            exp_trg: ExpDecay::new(params.tau_trg_us),
            drive_q32,
            inv_tau_q48: (1u64 << 48) / tau as u64,
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
        let prod = (u64::from(self.params.w_trg.to_bits()) * u64::from(i_fac_now.to_bits())) >> 16;
        Trace::from_bits(prod.min(u64::from(TRACE_MAX.to_bits())) as u32)
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
