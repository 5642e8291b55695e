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
//! blurs accelerations). Slow traces near saturation (own trace >= 8) are not decoded. A decode
//! of the paper's units within an octave above their floor, of an onset the slow units decode
//! too, is counted beyond the slow units' floor ([`Field::add_beyond_floor`]): the slow units'
//! histograms end there.
//!
//! # Near units
//! Each TRG event is also decoded as if its FAC pixel were one pixel away (the same units with
//! stride 1, from the same FAC traces: no state of their own; the network hands their drives
//! over, [`NetSink::NEAR`]). Across one pixel an edge takes half as long, so they answer sooner
//! after the motion changes and time edges half as fast; where onsets do not mark edges
//! (smooth textures) their decodes take either sign. They are decoded instead of the layout's
//! units while their decodes agree in sign at least as much, and while the readout's answer
//! says the image moves slower than a pixel per 2.8 ms (their floor is 2.1 ms; see
//! [`stride_choice`](super::stride_choice)).
//!
//! # Edges that move vertically
//! A decode of the paper's units (either stride) whose edge, by the drives from the pixels the
//! stride above and below (the network hands them over, [`NetSink::VERTICAL`]), moves mostly
//! vertically is not read: under pitch and roll its horizontal crossing time is mostly the
//! vertical flow times the edge's slope (see [`aperture`]).
//!
//! # From bursts to one rate
//! Decoded rates go to the [`field`](super::field) estimator: regions mirrored about the
//! principal point cancel forward translation, pitch and roll; the rotation must hold in
//! several column bands before it is reported (see its module documentation for the model).
//!
//! # Warm-up
//! Over the first [`WARMUP_US`] the outputs say "no evidence", and bursts are not decoded into
//! the field (as in the spike readout): every pixel's first event looks like an onset, so the
//! first bursts time the order in which pixels woke up, not edges crossing, and the field's 10 ms
//! memory carried them into the first answers (a drone flying straight read -1.2 rad/s over
//! 20-40 ms). The stride choice still counts them: it changes nothing before its own settling time.

use fixed::types::{I16F16, U16F16};

use super::aperture::{self, Around};
use super::field::{Field, FieldSettings, Population};
use super::shared::{
    field_over, slowest_rate_q16, window_log2_s, within_an_octave_of_reach, OutputGate, RateDecoder,
};
use super::stride_choice::{Stride, StrideChoice};
use super::Readout;
use crate::layout::Layout;
use crate::log2::log2_q16;
use crate::network::{NetSink, Reads, Trigger};
use crate::params::{Trace, TAU_SLOW_US};
use crate::unit::Kernel;

pub use super::shared::{DOMINANCE_LOG2, REFRESH_US, WARMUP_US};

/// The slow units are decoded only at pixels whose own fast FAC trace, after the event, is below
/// `w_F` plus this: the pixel had no onset in the last ~46 ms, so the scene moves slowly there.
/// Where edges pass fast, a fast unit that does not burst means its FAC pixel missed the edge,
/// and the slow trace would time an older edge instead.
const SLOW_SCENE_MARGIN: Trace = Trace::from_bits(0x00CC_CCCD); // 0.1

/// Slow traces at or above this level are not decoded (they may have saturated).
const SLOW_TRACE_LIMIT: Trace = Trace::const_from_int(8);

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

/// Whether at least half of the layout's pixels with units have both (a unit and its twin
/// facing the other way, as in the dense layouts; the paper's boxes place one unit per pixel).
pub fn has_twins<L: Layout>(layout: &L) -> bool {
    let (mut with_units, mut with_both) = (0usize, 0usize);
    for c in 0..layout.cell_count() {
        let mask = layout.units(c);
        with_units += usize::from(mask != 0);
        with_both += usize::from(mask & 3 == 3);
    }
    2 * with_both >= with_units
}

/// Cells [`has_near`] looks at, at most (evenly spread): it runs when the pipeline is built,
/// which on a board happens while events arrive.
const NEAR_SAMPLE_CELLS: usize = 256;

/// Whether the layout has near units: its stride is above 1 and, for at least half of its
/// units (of up to 256 cells spread over the layout), the pixel one pixel
/// from the TRG pixel towards the FAC pixel has state (a cell).
pub fn has_near<L: Layout>(layout: &L) -> bool {
    if layout.stride() < 2 {
        return false;
    }
    let (mut units, mut near) = (0usize, 0usize);
    let step = (layout.cell_count() / NEAR_SAMPLE_CELLS).max(1);
    for c in (0..layout.cell_count()).step_by(step) {
        let mask = layout.units(c);
        let (x, y) = layout.pixel(c);
        for (slot, dx) in [(0u8, -1i32), (1, 1)] {
            if mask & (1 << slot) != 0 {
                units += 1;
                near += usize::from(layout.neighbor(x, y, c, dx).is_some());
            }
        }
    }
    2 * near >= units && units > 0
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
    /// From a crossing time to a rotation rate.
    rates: RateDecoder,
    /// `w_T` bits (U16F16) for the normalisation.
    w_trg: u32,
    /// Smallest drive that makes a burst from rest.
    min_drive: Trace,
    /// Own fast trace (after the event) below which the slow units are decoded.
    slow_scene_own: Trace,
    /// `w_F`: what an onset adds to its pixel's own trace.
    w_fac: Trace,
    /// `log2` of [`Calibrated::min_drive`]'s bits (Q16).
    log2_min_drive: i32,
    /// `log2` (Q16.16, s) of the longest crossing the paper's units time at a pixel with one
    /// onset (own trace `w_F`): their reach, ~54 ms by default.
    reach_log2_s: i32,
    /// The layout's stride (px).
    stride_px: u16,
    /// Warm-up and refresh of the output.
    gate: OutputGate,
    /// Whether the near units or the layout's are decoded.
    stride: StrideChoice,
    /// Whether the layout has near units ([`has_near`]).
    near_units: bool,
    /// Decoded bursts so far.
    pub samples: u64,
    /// Of which from the slow units.
    pub slow_samples: u64,
}

impl Calibrated {
    /// A readout for the network of `kernel` over `layout`.
    pub fn new<L: Layout>(kernel: &Kernel, layout: &L, cal: Calibration) -> Self {
        let p = kernel.params();
        let mut field = field_over(
            layout,
            (cal.focal_px, cal.cx, cal.cy),
            cal.field,
            [cal.tau_a_us, cal.tau_a_us.max(SLOW_TAU_A_US)],
            cal.period_us,
        );
        if !has_twins(layout) {
            field.choose_by_decode_rate();
        }
        let near_units = has_near(layout);
        let min_drive = kernel.min_burst_drive();
        let log2_tau = [
            log2_q16(u64::from(p.tau_fac_us), 0),
            log2_q16(u64::from(TAU_SLOW_US), 0),
        ];
        let [log2_tau_fast, _] = log2_tau;
        let rates = RateDecoder::new(layout, cal.focal_px, cal.cx);
        Self {
            cal,
            field,
            log2_tau,
            rates,
            w_trg: p.w_trg.to_bits(),
            min_drive,
            slow_scene_own: Trace::saturating_from_num(p.w_fac).saturating_add(SLOW_SCENE_MARGIN),
            w_fac: Trace::saturating_from_num(p.w_fac),
            log2_min_drive: log2_q16(u64::from(min_drive.to_bits()), 0),
            reach_log2_s: window_log2_s(kernel, log2_tau_fast),
            stride_px: layout.stride(),
            gate: OutputGate::new(cal.period_us, WARMUP_US, slowest_rate_q16(kernel, &rates)),
            stride: StrideChoice::new(near_units),
            near_units,
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
        let ceiling = self.ceiling(own_fac);
        let l2c = (ceiling > 0).then(|| log2_q16(ceiling, 0))?;
        RateDecoder::log2_dt_s(self.log2_to_ceiling(drive, l2c)?, log2_tau)
    }

    /// `w_T` times the pixel's own trace `own` (Trace bits): the drive of an edge at no delay,
    /// which every decoded drive lies below.
    fn ceiling(&self, own: Trace) -> u64 {
        (u64::from(self.w_trg) * u64::from(own.to_bits())) >> 16
    }

    /// `log2(drive / ceiling)` (Q16, below 0 for a drive that codes a crossing) from the
    /// ceiling's `log2` `l2c`, if the drive makes a burst.
    fn log2_to_ceiling(&self, drive: Trace, l2c: i32) -> Option<i32> {
        (drive >= self.min_drive)
            .then(|| log2_q16(u64::from(drive.to_bits()), 0).saturating_sub(l2c))
    }

    /// Whether a decode of the paper's units (`log2` ratio `l2_h` to the ceiling, whose `log2`
    /// is `l2c`, at `stride`) times an edge that moves mostly vertically ([`aperture`]).
    fn moves_vertically(&self, t: &Trigger, l2_h: i32, stride: Stride, l2c: i32) -> bool {
        if t.vertical_drive == [Trace::ZERO; 2] {
            return false;
        }
        let ratio = |bits: u64| (bits > 0).then(|| log2_q16(bits, 0).saturating_sub(l2c));
        let around = Around {
            vertical: t.vertical_drive.map(|d| ratio(u64::from(d.to_bits()))),
            own_before: ratio(self.ceiling(t.own_fac.saturating_sub(self.w_fac))),
            reach: self.log2_min_drive.saturating_sub(l2c),
        };
        let s_h = match stride {
            Stride::Near => 1,
            Stride::Layout => self.stride_px,
        };
        aperture::moves_vertically(l2_h, [s_h, self.stride_px], &around)
    }

    /// The paper's units' drive (of the stronger unit) and direction (`true`: right-to-left),
    /// if it bursts and codes a crossing (below the pixel's `ceiling`): what
    /// [`Calibrated::decode_dt`] decodes, without the logarithms.
    fn fast_burst(&self, drive: [Trace; 2], ceiling: u64) -> Option<(Trace, bool)> {
        let (fast, positive) = stronger(drive);
        (fast >= self.min_drive && u64::from(fast.to_bits()) < ceiling).then_some((fast, positive))
    }

    /// A decode of the paper's units timing a crossing of `2^dt` s at `stride` (pixel `t`, in
    /// `region` if known): when it lies within an octave above their floor (a crossing
    /// between half their reach and their reach) and the slow units decode the onset too, the
    /// field counts it beyond the slow units' floor ([`Field::add_beyond_floor`]).
    fn count_beyond_floor(&mut self, t: &Trigger, dt: i32, stride: Stride, region: Option<usize>) {
        if !within_an_octave_of_reach(dt, self.reach_log2_s) {
            return;
        }
        let Some((_, positive)) = self.decode_slow(t) else {
            return;
        };
        let floor = self
            .rates
            .rotation_rate_over(stride, self.reach_log2_s, t.x);
        let region = region.unwrap_or_else(|| self.field.geometry().region(t.x, t.y));
        self.field.add_beyond_floor(region, positive, floor);
    }

    /// The same for the slow units (`t.slow_drive`, of the chosen stride), where the pixel's
    /// scene is slow.
    fn decode_slow(&self, t: &Trigger) -> Option<(i32, bool)> {
        if t.own_slow >= SLOW_TRACE_LIMIT || t.own_fac >= self.slow_scene_own {
            return None;
        }
        let (slow, positive) = stronger(t.slow_drive);
        let [_, tau_slow] = self.log2_tau;
        self.decode_dt(slow, t.own_slow, tau_slow)
            .map(|dt| (dt, positive))
    }
}

/// The stronger of a pixel's two units (drives `[left-to-right, right-to-left]`) and whether it
/// faces right-to-left, if it clearly dominates; else the pixel's two neighbours saw edges
/// about as recently and the direction is ambiguous: no drive.
fn stronger([lr, rl]: [Trace; 2]) -> (Trace, bool) {
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
}

impl NetSink for Calibrated {
    const SPIKES: bool = false;
    const SLOW: bool = true;
    const NEAR: bool = true;
    const VERTICAL: bool = true;

    fn reads(&self, y: u16) -> Reads {
        if !self.near_units {
            return Reads::LAYOUT;
        }
        let near = self.stride.choice() == Stride::Near;
        let both = StrideChoice::counts_row(y);
        Reads {
            layout: both || !near,
            near: both || near,
            slow_near: near,
        }
    }

    fn trigger(&mut self, t: &Trigger) {
        let ceiling = self.ceiling(t.own_fac);
        let far = self.fast_burst(t.drive, ceiling);
        let near = self.fast_burst(t.near_drive, ceiling);
        // The pixel's region, found once, and only for a burst.
        let region =
            (far.is_some() || near.is_some()).then(|| self.field.geometry().region(t.x, t.y));
        if let (Some(region), true) = (region, StrideChoice::counts_row(t.y)) {
            for (stride, burst) in [(Stride::Near, near), (Stride::Layout, far)] {
                if let Some((_, positive)) = burst {
                    self.stride.add(stride, region, positive);
                }
            }
        }
        let stride = self.stride.choice();
        let fast = match stride {
            Stride::Near => near,
            Stride::Layout => far,
        };
        if self.gate.warming_up() {
            return;
        }
        let [tau_fast, _] = self.log2_tau;
        let fast = match fast {
            // A burst lies below its ceiling (so the ceiling is above 0) and makes a burst.
            Some((drive, positive)) => {
                let l2c = log2_q16(ceiling, 0);
                let l = log2_q16(u64::from(drive.to_bits()), 0).saturating_sub(l2c);
                match RateDecoder::log2_dt_s(l, tau_fast) {
                    // An edge that moves mostly vertically says little about the rotation.
                    Some(_) if self.moves_vertically(t, l, stride, l2c) => return,
                    dt => dt.map(|dt| (dt, positive)),
                }
            }
            None => None,
        };
        let (dt, positive, pop) = match fast {
            Some((dt, positive)) => {
                self.count_beyond_floor(t, dt, stride, region);
                (dt, positive, Population::Fast)
            }
            None => {
                let Some((dt, positive)) = self.decode_slow(t) else {
                    return;
                };
                self.slow_samples += 1;
                (dt, positive, Population::Slow)
            }
        };
        let l2 = self.rates.rotation_rate_over(stride, dt, t.x);
        let region = region.unwrap_or_else(|| self.field.geometry().region(t.x, t.y));
        self.field.add_in(pop, region, l2, positive);
        self.samples += 1;
    }
}

impl Readout for Calibrated {
    fn output(&mut self, _t_us: u32) -> (I16F16, u8) {
        self.stride.age(self.cal.period_us);
        let out = self.gate.output(&mut self.field);
        self.stride.follow_answer(out, self.rates.focal_bits());
        out
    }
}
