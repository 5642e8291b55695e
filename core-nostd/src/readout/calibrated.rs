//! The calibrated readout: yaw rate in rad/s from the bursts' time codes and the camera geometry.
//!
//! # Decoding a burst
//! A unit's burst is a monotone function of the drive `w_T · I_F(t⁻)` its TRG event delivers
//! (the sweep shows it: more drive, more and earlier spikes), so each burst stands for one
//! drive, which the network reports with it ([`Trigger`]). With the onset filter a pixel's FAC
//! trace is a sum of one decaying term per passing edge. For a pattern moving rigidly across the
//! sensor, the TRG pixel sees the same onsets as the FAC pixel, `dt` later, so
//! `I_F(FAC, t⁻) = e^(-dt/tau_F) · I_F(TRG, t⁺)`: dividing the drive by the TRG pixel's own
//! trace cancels both the edge's contrast and the memory of earlier edges, and
//! `dt = -tau_F · ln(drive / (w_T · I_F(TRG, t⁺)))` is the time the edge took to cross the stride.
//! Only bursts that happen count (drive above the spiking level), and only the stronger of the
//! pixel's two units (the other one answers to the edge before).
//!
//! # From time to rotation
//! For a yaw rate `w` a point at column `x` moves at `|u| = |w| (f + (x - c_x)^2 / f)` px/s, so a
//! burst says `|w| = s / (dt (f + (x - c_x)^2 / f))`, positive (turning right) for right-to-left
//! units.
//!
//! # Robust aggregation
//! Decoded rates go into leaky histograms (time constant `tau_A`, 64 bins over `ln |w|` from
//! 0.02 to 20 rad/s), one per image half and sign. Per half: the sign with more mass wins, the
//! losing sign's histogram is subtracted bin by bin (clutter from noise and from the unit facing
//! the other way is about symmetric), and if the remaining mass is below `alpha` of all samples
//! the half reports 0; else its median. Translation moves the two halves in opposite directions
//! and rotation in the same one: the output is the mean of the halves when they agree in sign,
//! else 0 (flagged [`flags::NO_EVIDENCE`]).

use fixed::types::{I16F16, U16F16};

use super::{flags, Readout};
use crate::exp_table::{ExpDecay, ONE_Q31};
use crate::log2::{exp2_q16, log2_q16};
use crate::network::{NetSink, Trigger};
use crate::params::Trace;
use crate::unit::{Kernel, UnitState};

/// Histogram bins per image half and sign.
pub const BINS: usize = 64;

/// Lowest and highest |yaw rate| the histograms resolve (rad/s); outside values fall into the
/// end bins.
pub const RATE_RANGE: (f32, f32) = (0.02, 20.0);

/// `log2(0.02)` and `log2(20)` in Q16.16 (bin edges of the histograms).
const LOG2_LO: i32 = -369_876;
const LOG2_HI: i32 = 283_242;
/// Bin width in Q16.16 log2 units.
const BIN_W: i32 = (LOG2_HI - LOG2_LO) / BINS as i32;

/// `log2(1e6)` in Q16.16 (µs to s).
const LOG2_1E6: i32 = 1_306_235;

/// One sample's weight in the histograms (Q16).
const SAMPLE: u32 = 1 << 16;

/// Layouts with fewer units than this are sparse (see [`Calibration::for_units`]).
pub const SPARSE_UNITS: usize = 10_000;

/// Default readout time constant (µs) for a layout of `units` units: 10 ms, or 100 ms for
/// sparse layouts (see [`Calibration::for_units`]).
pub const fn default_tau_a_us(units: usize) -> u32 {
    if units < SPARSE_UNITS {
        100_000
    } else {
        10_000
    }
}

/// Settings of the calibrated readout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Calibration {
    /// Focal length (px).
    pub focal_px: U16F16,
    /// Principal point, column (px).
    pub cx: U16F16,
    /// Leaky histogram time constant (µs).
    pub tau_a_us: u32,
    /// Output period (µs).
    pub period_us: u32,
    /// Net-evidence gate: the winning sign must outweigh the losing one by this fraction of all
    /// samples in a half (Q16).
    pub alpha: U16F16,
    /// Mass at zero that a half's median must overcome, in samples.
    pub prior: U16F16,
}

impl Calibration {
    /// Defaults for a camera with focal length `focal_px` and principal column `cx`:
    /// `tau_A` = 10 ms (model.md), 1 kHz output, `alpha` = 0.3, a prior of 3 samples.
    pub fn new(focal_px: U16F16, cx: U16F16) -> Self {
        Self::with_tau_a(focal_px, cx, 10_000)
    }

    /// Defaults for a layout of `units` units: `tau_A` = 10 ms for dense layouts, and for
    /// sparse ones (fewer than [`SPARSE_UNITS`], like the paper's 200-unit boxes) 100 ms, since
    /// they see far fewer edges per millisecond.
    pub fn for_units(focal_px: U16F16, cx: U16F16, units: usize) -> Self {
        let tau = if units < SPARSE_UNITS {
            100_000
        } else {
            10_000
        };
        Self::with_tau_a(focal_px, cx, tau)
    }

    fn with_tau_a(focal_px: U16F16, cx: U16F16, tau_a_us: u32) -> Self {
        Self {
            focal_px,
            cx,
            tau_a_us,
            period_us: 1_000,
            alpha: U16F16::from_bits(19_661),
            prior: U16F16::from_num(3),
        }
    }
}

/// The calibrated readout's state: 4 x 64 histogram bins and the decoding constants.
pub struct Calibrated {
    cal: Calibration,
    /// `[half][sign][bin]`, sign 0 = negative (left-to-right), 1 = positive.
    hist: [[[u32; BINS]; 2]; 2],
    /// Per-period decay factor of the histograms (Q1.31).
    keep_q31: u32,
    /// `log2(tau_F)` (µs) in Q16.16.
    log2_tau_f: i32,
    /// `log2(stride)` in Q16.16.
    log2_stride: i32,
    /// `w_T` bits (U16F16) for the normalisation.
    w_trg: u32,
    /// `1 / f` in Q32.
    inv_f_q32: u64,
    /// Smallest drive that makes a burst from rest.
    min_drive: Trace,
    /// Decoded bursts so far.
    pub samples: u64,
}

impl Calibrated {
    /// A readout for the network of `kernel` with stride `stride`.
    pub fn new(kernel: &Kernel, stride: u16, cal: Calibration) -> Self {
        let p = kernel.params();
        let keep_q31 = ExpDecay::new(cal.tau_a_us).decay_bits(cal.period_us);
        let f_bits = u64::from(cal.focal_px.to_bits().max(1));
        Self {
            cal,
            hist: [[[0; BINS]; 2]; 2],
            keep_q31,
            log2_tau_f: log2_q16(u64::from(p.tau_fac_us), 0),
            log2_stride: log2_q16(u64::from(stride.max(1)), 0),
            w_trg: p.w_trg.to_bits(),
            inv_f_q32: (1u64 << 48) / f_bits,
            min_drive: min_burst_drive(kernel),
            samples: 0,
        }
    }

    /// `log2 |w|` (Q16.16) that a burst with this drive at column `x` stands for, if it decodes.
    fn decode(&self, drive: Trace, own_fac: Trace, x: u16) -> Option<i32> {
        if drive < self.min_drive || own_fac == Trace::ZERO {
            return None;
        }
        // l = log2(drive / (w_T · own)) < 0.
        let denom = (u64::from(self.w_trg) * u64::from(own_fac.to_bits())) >> 16;
        if denom == 0 {
            return None;
        }
        let l = log2_q16(u64::from(drive.to_bits()), 0).saturating_sub(log2_q16(denom, 0));
        if l >= 0 {
            return None;
        }
        // dt = tau_F · (-l) · ln 2 (µs); log2 dt = log2 tau_F + log2(-l · ln 2).
        let neg_l_ln2 = (u64::from(l.unsigned_abs()) * crate::log2::LN2_Q32) >> 32; // Q16
        if neg_l_ln2 == 0 {
            return None; // dt below the decoder's resolution (~1e-5 tau)
        }
        let log2_dt_us = self.log2_tau_f.saturating_add(log2_q16(neg_l_ln2, 16));
        let log2_dt_s = log2_dt_us.saturating_sub(LOG2_1E6);
        // G(x) = f + (x - cx)^2 / f in px, Q16.
        let dx = i64::from(u32::from(x) << 16) - i64::from(self.cal.cx.to_bits());
        let dx2 = dx.unsigned_abs().saturating_mul(dx.unsigned_abs()) >> 16; // Q16 px^2
        let g = u64::from(self.cal.focal_px.to_bits()).saturating_add(
            ((u128::from(dx2) * u128::from(self.inv_f_q32)) >> 32).min(u128::from(u64::MAX)) as u64,
        );
        Some(
            self.log2_stride
                .saturating_sub(log2_dt_s)
                .saturating_sub(log2_q16(g, 16)),
        )
    }

    /// One half's estimate: `(log2 |w|, sign)` or `None` when its evidence does not pass.
    fn half_estimate(&self, half: &[[u32; BINS]; 2]) -> Option<(i32, bool)> {
        let [neg, pos] = half;
        let sum = |h: &[u32; BINS]| h.iter().map(|&b| u64::from(b)).sum::<u64>();
        let (sn, sp) = (sum(neg), sum(pos));
        let (win, lose, positive) = if sp >= sn {
            (pos, neg, true)
        } else {
            (neg, pos, false)
        };
        let mut net = [0u64; BINS];
        let mut net_sum = 0u64;
        for (n, (w, l)) in net.iter_mut().zip(win.iter().zip(lose.iter())) {
            *n = u64::from(w.saturating_sub(*l));
            net_sum += *n;
        }
        let gate = ((sn + sp) * u64::from(self.cal.alpha.to_bits())) >> 16;
        if net_sum == 0 || net_sum < gate {
            return None;
        }
        let prior = u64::from(self.cal.prior.to_bits()); // samples in Q16 = same scale as bins
        let half_mass = (net_sum + prior) / 2;
        if prior >= half_mass {
            return None;
        }
        let mut acc = prior;
        for (i, &m) in net.iter().enumerate() {
            if m > 0 && acc + m >= half_mass {
                let frac_q16 = ((half_mass - acc) << 16) / m;
                let pos_q16 = ((i as i64) << 16) + frac_q16 as i64;
                let l2 = i64::from(LOG2_LO) + ((pos_q16 * i64::from(BIN_W)) >> 16);
                return Some((l2 as i32, positive));
            }
            acc += m;
        }
        None
    }
}

/// Smallest TRG drive that makes a unit at rest burst (`q·tau/e >= 1`).
fn min_burst_drive(kernel: &Kernel) -> Trace {
    let (mut lo, mut hi) = (0u32, crate::params::TRACE_MAX.to_bits());
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        let u = UnitState {
            i_trg: Trace::from_bits(mid),
            ..UnitState::default()
        };
        if kernel.may_spike(&u) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    Trace::from_bits(lo)
}

impl NetSink for Calibrated {
    const SPIKES: bool = false;

    fn trigger(&mut self, t: &Trigger) {
        let [lr, rl] = t.drive;
        let (drive, positive) = if rl > lr { (rl, true) } else { (lr, false) };
        let Some(l2) = self.decode(drive, t.own_fac, t.x) else {
            return;
        };
        let bin = (l2.saturating_sub(LOG2_LO) / BIN_W).clamp(0, BINS as i32 - 1) as usize;
        let half = usize::from(u32::from(t.x) << 16 >= self.cal.cx.to_bits());
        if let Some(b) = self
            .hist
            .get_mut(half)
            .and_then(|h| h.get_mut(usize::from(positive)))
            .and_then(|h| h.get_mut(bin))
        {
            *b = b.saturating_add(SAMPLE);
            self.samples += 1;
        }
    }
}

impl Readout for Calibrated {
    fn output(&mut self, _t_us: u32) -> (I16F16, u8) {
        let est = [
            self.half_estimate(&self.hist[0]),
            self.half_estimate(&self.hist[1]),
        ];
        for b in self.hist.iter_mut().flatten().flatten() {
            *b = ((u64::from(*b) * u64::from(self.keep_q31) + u64::from(ONE_Q31 / 2)) >> 31) as u32;
        }
        match est {
            [Some((l, sl)), Some((r, sr))] if sl == sr => {
                let mean = (u64::from(exp2_q16(l)) + u64::from(exp2_q16(r))) / 2;
                let v = mean.min(i32::MAX as u64) as i32;
                (I16F16::from_bits(if sl { v } else { -v }), 0)
            }
            _ => (I16F16::ZERO, flags::NO_EVIDENCE),
        }
    }
}
