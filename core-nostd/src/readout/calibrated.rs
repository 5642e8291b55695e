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
//! # Slow edges
//! A burst needs a drive of about `w_F / 14.7`, so the paper's units (`tau_F` = 20 ms) time
//! crossings up to ~54 ms: at stride 2 on a DAVIS346 (f = 226 px) nothing below about
//! 0.17 rad/s. Each pixel also feeds a slow FAC trace (`tau_F` = [`TAU_SLOW_US`], the same
//! unit otherwise) whose units time crossings up to ~270 ms. A trigger is decoded from the
//! paper's units when they burst and from the slow units only when they do not, so slow units
//! add the slow edges without weighing in where the fast ones see the edge (their longer memory
//! blurs accelerations). Slow traces near saturation (own trace >= 8) are not decoded.
//!
//! # From bursts to one rate
//! Decoded rates go to the [`field`](super::field) estimator: regions mirrored about the
//! principal point cancel forward translation, pitch and roll; the rotation must hold in
//! several column bands before it is reported (see its module documentation for the model).

use fixed::types::{I16F16, U16F16};

use super::field::{Field, FieldEstimate, FieldGeometry, FieldSettings, Population, COL_BANDS};
use super::Readout;
use crate::flags;
use crate::layout::Layout;
use crate::log2::log2_q16;
use crate::network::{NetSink, Trigger};
use crate::params::{Trace, TAU_SLOW_US};
use crate::unit::{Kernel, UnitState};

/// `log2(1e6)` in Q16.16 (µs to s).
const LOG2_1E6: i32 = 1_306_235;

/// The slow units are decoded only at pixels whose own fast FAC trace, after the event, is below
/// `w_F` plus this: the pixel had no onset in the last ~46 ms, so the scene moves slowly there.
/// Where edges pass fast, a fast unit that does not burst means its FAC pixel missed the edge,
/// and the slow trace would time an older edge instead.
const SLOW_SCENE_MARGIN: Trace = Trace::from_bits(0x00CC_CCCD); // 0.1

/// A unit's drive must be at least `2^DOMINANCE_LOG2` times its twin's (the unit at the same
/// pixel facing the other way) to be decoded.
const DOMINANCE_LOG2: u32 = 1;

/// Slow traces at or above this level are not decoded (they may have saturated).
const SLOW_TRACE_LIMIT: Trace = Trace::const_from_int(8);

/// Outputs during this long after the first output (µs) say "no evidence": every pixel's first
/// event looks like an onset, so the first decodes time the order in which pixels woke up, not
/// edges crossing.
pub const WARMUP_US: u32 = 20_000;

/// The field is read at most this often (µs): every 4th output at 1 kHz. Reading it costs about
/// as much as a few hundred events on a Cortex-M4, and its histograms change over `tau_A`
/// (10 ms), not over one period.
pub const REFRESH_US: u32 = 4_000;

/// Smallest histogram time constant of the slow units (µs): they see few edges per period.
pub const SLOW_TAU_A_US: u32 = 100_000;

/// Layouts with at least this many units (a whole DAVIS240 or DAVIS346 at stride 2) read the
/// field over `tau_A` = 10 ms.
pub const REFERENCE_UNITS: usize = 60_000;

/// Default readout time constant (µs) for a layout of `units` units: 10 ms from
/// [`REFERENCE_UNITS`] up, longer in proportion below (the field's regions see fewer edges per
/// millisecond), at most 100 ms: 60 ms for the STM32F405's 346 x 15 strip, 100 ms for the
/// paper's 200-unit boxes.
pub const fn default_tau_a_us(units: usize) -> u32 {
    let units = if units == 0 { 1 } else { units };
    let tau = 10_000u64 * REFERENCE_UNITS as u64 / units as u64;
    if tau < 10_000 {
        10_000
    } else if tau > 100_000 {
        100_000
    } else {
        tau as u32
    }
}

/// Settings of the calibrated readout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Calibration {
    /// Focal length (px).
    pub focal_px: U16F16,
    /// Principal point, column (px).
    pub cx: U16F16,
    /// Principal point, row (px).
    pub cy: U16F16,
    /// Leaky histogram time constant (µs).
    pub tau_a_us: u32,
    /// Output period (µs).
    pub period_us: u32,
    /// How the field's regions are combined (gates, spread).
    pub field: FieldSettings,
}

impl Calibration {
    /// Defaults for a camera with focal length `focal_px` and principal point `(cx, cy)`:
    /// `tau_A` = 10 ms (model.md), 1 kHz output, [`FieldSettings::DEFAULT`].
    pub fn new(focal_px: U16F16, cx: U16F16, cy: U16F16) -> Self {
        Self {
            focal_px,
            cx,
            cy,
            tau_a_us: 10_000,
            period_us: 1_000,
            field: FieldSettings::DEFAULT,
        }
    }
}

/// The calibrated readout's state: the field's histograms and the decoding constants.
pub struct Calibrated {
    cal: Calibration,
    field: Field,
    /// `log2(tau_F)` of the paper's units and of the slow units (µs), Q16.16.
    log2_tau: [i32; 2],
    /// `log2(stride)` in Q16.16.
    log2_stride: i32,
    /// `w_T` bits (U16F16) for the normalisation.
    w_trg: u32,
    /// `1 / f` in Q32.
    inv_f_q32: u64,
    /// Smallest drive that makes a burst from rest.
    min_drive: Trace,
    /// Own fast trace (after the event) below which the slow units are decoded.
    slow_scene_own: Trace,
    /// Outputs still to suppress (see [`WARMUP_US`]).
    warmup_outputs: u32,
    /// Outputs per reading of the field (see [`REFRESH_US`]), at least 1.
    refresh: u32,
    /// Outputs since the last reading, modulo `refresh`.
    phase: u32,
    /// The last reading.
    last: (I16F16, u8),
    /// Decoded bursts so far.
    pub samples: u64,
    /// Of which from the slow units.
    pub slow_samples: u64,
}

impl Calibrated {
    /// A readout for the network of `kernel` over `layout`.
    pub fn new<L: Layout>(kernel: &Kernel, layout: &L, cal: Calibration) -> Self {
        let p = kernel.params();
        let f_bits = u64::from(cal.focal_px.to_bits().max(1));
        let (cx, cy) = (i64::from(cal.cx.to_bits()), i64::from(cal.cy.to_bits()));
        let (xs, ys) = unit_span(layout);
        let geometry = FieldGeometry::spanning(cx, cy, i64::from(cal.focal_px.to_bits()), xs, ys);
        let paired_bands = paired_bands(layout, &geometry);
        Self {
            cal,
            field: Field::new(
                geometry,
                cal.field,
                [cal.tau_a_us, cal.tau_a_us.max(SLOW_TAU_A_US)],
                cal.period_us,
                paired_bands,
            ),
            log2_tau: [
                log2_q16(u64::from(p.tau_fac_us), 0),
                log2_q16(u64::from(TAU_SLOW_US), 0),
            ],
            log2_stride: log2_q16(u64::from(layout.stride().max(1)), 0),
            w_trg: p.w_trg.to_bits(),
            inv_f_q32: (1u64 << 48) / f_bits,
            min_drive: min_burst_drive(kernel),
            slow_scene_own: Trace::saturating_from_num(p.w_fac).saturating_add(SLOW_SCENE_MARGIN),
            warmup_outputs: WARMUP_US.div_ceil(cal.period_us.max(1)),
            refresh: (REFRESH_US / cal.period_us.max(1)).max(1),
            phase: 0,
            last: (I16F16::ZERO, flags::NO_EVIDENCE),
            samples: 0,
            slow_samples: 0,
        }
    }

    /// The settings.
    pub fn calibration(&self) -> &Calibration {
        &self.cal
    }

    /// `log2 dt` (Q16.16, dt in s) that a burst with this drive codes for, with FAC time
    /// constant `2^log2_tau` µs, if it decodes.
    fn decode_dt(&self, drive: Trace, own_fac: Trace, log2_tau: i32) -> Option<i32> {
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
        // dt = tau · (-l) · ln 2 (µs); log2 dt = log2 tau + log2(-l · ln 2).
        let neg_l_ln2 = (u64::from(l.unsigned_abs()) * crate::log2::LN2_Q32) >> 32; // Q16
        if neg_l_ln2 == 0 {
            return None; // dt below the decoder's resolution (~1e-5 tau)
        }
        let log2_dt_us = log2_tau.saturating_add(log2_q16(neg_l_ln2, 16));
        Some(log2_dt_us.saturating_sub(LOG2_1E6))
    }

    /// `log2 |w|` (Q16.16) of a crossing of the stride in `2^log2_dt_s` s at column `x`.
    fn rotation_rate(&self, log2_dt_s: i32, x: u16) -> i32 {
        // G(x) = f + (x - cx)^2 / f in px, Q16.
        let dx = i64::from(u32::from(x) << 16) - i64::from(self.cal.cx.to_bits());
        let dx2 = dx.unsigned_abs().saturating_mul(dx.unsigned_abs()) >> 16; // Q16 px^2
        let g = u64::from(self.cal.focal_px.to_bits()).saturating_add(
            ((u128::from(dx2) * u128::from(self.inv_f_q32)) >> 32).min(u128::from(u64::MAX)) as u64,
        );
        self.log2_stride
            .saturating_sub(log2_dt_s)
            .saturating_sub(log2_q16(g, 16))
    }
}

/// Bounding box of the pixels that have units: `((x_min, x_max), (y_min, y_max))`.
fn unit_span<L: Layout>(layout: &L) -> ((u16, u16), (u16, u16)) {
    let (mut x0, mut x1, mut y0, mut y1) = (u16::MAX, 0u16, u16::MAX, 0u16);
    for c in 0..layout.cell_count() {
        if layout.units(c) == 0 {
            continue;
        }
        let (x, y) = layout.pixel(c);
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x0 > x1 {
        return ((0, 0), (0, 0));
    }
    ((x0, x1), (y0, y1))
}

/// Column bands in which the layout has units on both sides of the principal point (0 when
/// its regions never mirror, which switches the field to its unpaired fallback).
fn paired_bands<L: Layout>(layout: &L, g: &FieldGeometry) -> u8 {
    let mut seen = [[false; COL_BANDS]; 2];
    for c in 0..layout.cell_count() {
        if layout.units(c) == 0 {
            continue;
        }
        let (side, band) = g.column(layout.pixel(c).0);
        if let Some(s) = seen.get_mut(side).and_then(|s| s.get_mut(band)) {
            *s = true;
        }
    }
    let [l, r] = seen;
    l.iter().zip(r.iter()).filter(|(a, b)| **a && **b).count() as u8
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
    const SLOW: bool = true;

    fn trigger(&mut self, t: &Trigger) {
        // The stronger unit, if it clearly dominates (else the pixel's two neighbours saw
        // edges about as recently and the direction is ambiguous: no decode).
        let stronger = |[lr, rl]: [Trace; 2]| {
            let (win, lose, positive) = if rl > lr {
                (rl, lr, true)
            } else {
                (lr, rl, false)
            };
            if lose.to_bits() > win.to_bits() >> DOMINANCE_LOG2 {
                (Trace::ZERO, positive)
            } else {
                (win, positive)
            }
        };
        let (drive, positive) = stronger(t.drive);
        let [tau_fast, tau_slow] = self.log2_tau;
        let (dt, positive, pop) = match self.decode_dt(drive, t.own_fac, tau_fast) {
            Some(dt) => (dt, positive, Population::Fast),
            None => {
                if t.own_slow >= SLOW_TRACE_LIMIT || t.own_fac >= self.slow_scene_own {
                    return;
                }
                let (drive, positive) = stronger(t.slow_drive);
                let Some(dt) = self.decode_dt(drive, t.own_slow, tau_slow) else {
                    return;
                };
                self.slow_samples += 1;
                (dt, positive, Population::Slow)
            }
        };
        let l2 = self.rotation_rate(dt, t.x);
        self.field.add(pop, t.x, t.y, l2, positive);
        self.samples += 1;
    }
}

impl Readout for Calibrated {
    fn output(&mut self, _t_us: u32) -> (I16F16, u8) {
        // The field is read every `refresh` outputs (its histograms change over tau_A, not
        // over one period); the outputs between repeat the last reading.
        if self.phase == 0 {
            self.last = match self.field.estimate() {
                FieldEstimate::Rotation(v) => (I16F16::from_bits(v), 0),
                FieldEstimate::NoEvidence => (I16F16::ZERO, flags::NO_EVIDENCE),
            };
        }
        self.phase += 1;
        if self.phase >= self.refresh {
            self.phase = 0;
        }
        self.field.age();
        if self.warmup_outputs > 0 {
            self.warmup_outputs -= 1;
            return (I16F16::ZERO, flags::NO_EVIDENCE);
        }
        self.last
    }
}
