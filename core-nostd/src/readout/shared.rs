//! What the rad/s readouts ([`calibrated`](super::calibrated), [`spikes`](super::spikes))
//! share: the smallest drive that makes a burst, from a decoded crossing time to a rotation
//! rate, the [`Field`] over a layout, and the output gate (warm-up, refresh).

use fixed::types::{I16F16, U16F16};

use super::field::{
    Coverage, Field, FieldEstimate, FieldGeometry, FieldReading, FieldSettings, RecentAnswer,
    COL_BANDS,
};
use super::stride_choice::Stride;
use crate::flags;
use crate::layout::Layout;
use crate::log2::{exp2_q16, log2_q16};
use crate::params::{Trace, TAU_SLOW_US};
use crate::unit::Kernel;

/// `log2(1e6)` in Q16.16 (µs to s).
pub const LOG2_1E6: i32 = 1_306_235;

/// Outputs during this long after the first output (µs) say "no evidence": every pixel's first
/// event looks like an onset, so the first decodes time the order in which pixels woke up, not
/// edges crossing.
pub const WARMUP_US: u32 = 20_000;

/// A unit's drive must be at least `2^DOMINANCE_LOG2` times its twin's (the unit at the same
/// pixel facing the other way) to be decoded, in both rad/s readouts; and a vertical neighbour's
/// trace the other's to say where an edge came from ([`super::aperture`]).
pub const DOMINANCE_LOG2: u32 = 1;

/// The field is read at most this often (µs): every 4th output at 1 kHz. Reading it costs about
/// as much as a few hundred events on a Cortex-M4, and its histograms change over `tau_A`
/// (10 ms), not over one period.
pub const REFRESH_US: u32 = 4_000;

/// Readings (of [`REFRESH_US`] each) after its last answer within which [`Confirmation`]
/// takes an answer of that answer's sign at once, without waiting for a second reading: 12 ms
/// at 1 kHz. A brief gap in the evidence within a turn is not a new start; a gap that began
/// with the decodes stopping ([`FieldReading::stopped`]: a yaw step, the camera stopping) is:
/// there the histograms still remember the old rate for a few `tau_A`, and let through at once
/// it read the old direction for a reading or two after a step (DAVIS240 steps seed 8, +0.76
/// rad/s for -0.29 at 3.44 s: 8.3 → 7.7 % RMSE / peak).
pub const RESUME_READINGS: u8 = 3;

/// A rotation read right after "no evidence" is output once the next reading agrees with it:
/// the same sign, and neither more than this many times the other in size. The first decodes
/// after the warm-up time the order in which pixels woke up, and where they fill only a band's
/// top rows they can read ten times the turn for two readings in a row (drone seed 87 at half
/// contrast, spike readout: -9.3 rad/s for -0.05 over 29-35 ms, 11.3 → 29.0 % RMSE / peak once a
/// column band needed a value above the principal row; 10.6 % with this rule).
pub const HELD_AGREEMENT: i64 = 2;

/// Readings (of [`REFRESH_US`] each) answering one sign in a row after which the direction of
/// the motion counts as established ([`Confirmation::established`]): 100 ms at 1 kHz. Then a
/// region's decodes of the other sign are timing errors, whatever its count (see
/// [`Field::set_direction_established`]); before, the first decodes of a motion that has just
/// started decide, which overshoot (a hover's turn after a pause).
pub const ESTABLISHED_READINGS: u8 = 25;

/// Readings (of [`REFRESH_US`] each) after the last answer within which the motion counts as
/// recent ([`AnswerAge::last_answer`]): 100 ms at 1 kHz.
pub const RECENT_READINGS: u8 = 25;

pub use super::field::FRESH_READINGS;

/// Readings after an answer that say "no evidence" because the view is blind
/// ([`FieldReading::blind`]: the slow units' latest decodes split in sign) and leave that
/// answer's age as it was, at most: 200 ms at 1 kHz. After a turn's zero crossing over a
/// smooth texture the sensor fires little but background activity for 120-180 ms; the motion
/// goes on, and when the view comes back, the rules for the moment after an answer (a reversal's first
/// values of one sign on each side) still apply (dev01 19.4 → 18.7 % RMSE / peak, its answer
/// after the zero crossing at 1.43 s 36 ms sooner; 100 ms: 18.9 %). A longer blindness ages
/// the answer as any other "no evidence" does: a hover's pause with background activity ends
/// in a new start.
pub const BLIND_HOLD_READINGS: u8 = 50;

/// Whether a reading of the field that shows a rotation is output, from the readings before
/// it (one rule for [`OutputGate`] and the f64 oracle's gate). A rotation read right after "no
/// evidence" is held back until the next reading shows a rotation of the same sign and a size
/// within [`HELD_AGREEMENT`] of it, unless it comes within [`RESUME_READINGS`] of the last
/// answer, has that answer's sign, and the gap did not begin with the decodes stopping.
/// Where motion
/// starts (a hover's turn after a pause, the first decodes after a reversal), the first
/// regions to fill decide the first reading, and a few of the paper's units timing an edge
/// near the end of their window (where they alias) can give it either sign; background
/// activity makes such readings too, now and then, in front of a still camera.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Confirmation {
    /// No answer, or none recent: a rotation read now is held.
    #[default]
    Waiting,
    /// A rotation was read right after "no evidence" and is held back.
    Held {
        /// Its rate (Q16 rad/s, not 0).
        rate_q16: i32,
    },
    /// The last reading was output, a rotation of this sign.
    Answering {
        /// Its sign.
        negative: bool,
        /// Readings in a row answering this sign (saturating).
        readings: u8,
    },
    /// "No evidence" for `readings` readings after an answer of this sign.
    Paused {
        /// The answer's sign.
        negative: bool,
        /// Readings of "no evidence" since it (1 to [`RESUME_READINGS`]).
        readings: u8,
    },
}

/// Whether a reading held back ([`Confirmation::Held`]) and the next one agree: the same sign,
/// and neither more than [`HELD_AGREEMENT`] times the other (Q16 rad/s).
fn agree(held: i32, rate: i32) -> bool {
    let (a, b) = (i64::from(held), i64::from(rate));
    (a < 0) == (b < 0) && a.abs() <= HELD_AGREEMENT * b.abs() && b.abs() <= HELD_AGREEMENT * a.abs()
}

impl Confirmation {
    /// Takes one reading (`Some(rate)`, Q16 rad/s: a rotation, which the field never gives as
    /// 0; `None`: no evidence; `stopped`: whether for want of decodes,
    /// [`FieldReading::stopped`]) and says whether it is output.
    pub fn read(&mut self, reading: Option<i32>, stopped: bool) -> bool {
        let answering = |negative, readings| Self::Answering { negative, readings };
        *self = match (*self, reading) {
            (_, None) if stopped => Self::Waiting,
            (
                Self::Answering {
                    negative: was,
                    readings,
                },
                Some(rate),
            ) if was == (rate < 0) => answering(rate < 0, readings.saturating_add(1)),
            (Self::Answering { .. }, Some(rate)) => answering(rate < 0, 1),
            (Self::Held { rate_q16: held }, Some(rate)) if agree(held, rate) => {
                answering(rate < 0, 1)
            }
            (Self::Paused { negative: was, .. }, Some(rate)) if was == (rate < 0) => {
                answering(rate < 0, 1)
            }
            (_, Some(rate)) => Self::Held { rate_q16: rate },
            (Self::Answering { negative, .. }, None) => Self::Paused {
                negative,
                readings: 1,
            },
            (Self::Paused { negative, readings }, None) if readings < RESUME_READINGS => {
                Self::Paused {
                    negative,
                    readings: readings + 1,
                }
            }
            (_, None) => Self::Waiting,
        };
        matches!(self, Self::Answering { .. })
    }

    /// Whether the last [`ESTABLISHED_READINGS`] readings in a row answered one sign.
    pub fn established(&self) -> bool {
        matches!(self, Self::Answering { readings, .. } if *readings >= ESTABLISHED_READINGS)
    }
}

/// Readings since the readout last answered on the field's own evidence (saturating;
/// `u8::MAX` before any), and that answer's rate: whether the motion is recent
/// ([`RECENT_READINGS`]), which way and how fast it went. An answer that needed the motion to be
/// recent ([`FieldReading::recent_needed`]) does not make it recent again: else people
/// walking past a drone that stopped turning, one sign on both sides of the view, kept the
/// readout answering in turns with "no evidence" (hover seed 501 with three objects: 16.1 →
/// 36.4 % of peak when the rule came, 17.8 % with this and the same-way reading limited to
/// [`FRESH_READINGS`]). Kept by [`Answers`] for both gates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AnswerAge {
    readings: u8,
    /// Blind readings since the last answer that left its age as it was (at most
    /// [`BLIND_HOLD_READINGS`]).
    blind_held: u8,
    /// The last answer (Q16 rad/s).
    rate_q16: i32,
}

impl Default for AnswerAge {
    fn default() -> Self {
        Self {
            readings: u8::MAX,
            blind_held: 0,
            rate_q16: 0,
        }
    }
}

impl AnswerAge {
    /// After one reading: `Some(rate)` (Q16 rad/s) when it was output on the field's own
    /// evidence, a rotation at that rate; `None` otherwise.
    pub fn after(&mut self, answered: Option<i32>) {
        *self = match answered {
            Some(rate_q16) => Self {
                readings: 0,
                blind_held: 0,
                rate_q16,
            },
            None => Self {
                readings: self.readings.saturating_add(1),
                ..*self
            },
        };
    }

    /// After one reading that said "no evidence" because the view is blind
    /// ([`FieldReading::blind`]): leaves the age as it was, for [`BLIND_HOLD_READINGS`]
    /// readings after a recent answer; then as [`AnswerAge::after`]`(None)`.
    pub fn after_blind(&mut self) {
        if self.blind_held < BLIND_HOLD_READINGS && self.last_answer().is_some() {
            self.blind_held += 1;
        } else {
            self.after(None);
        }
    }

    /// The last answer, when it came within [`RECENT_READINGS`] readings (0: the last reading
    /// answered): the camera was turning a moment ago (a reversal, a turn slowing through the
    /// paper's units' floor, a turn whose texture left the top row band), not standing still.
    pub fn last_answer(&self) -> Option<RecentAnswer> {
        (0..=RECENT_READINGS)
            .contains(&self.readings)
            .then_some(RecentAnswer {
                rate_q16: self.rate_q16,
                readings: self.readings,
            })
    }
}

/// The readings so far as both gates take them: whether they make an answer
/// ([`Confirmation`]) and how long since the field last answered on its own evidence
/// ([`AnswerAge`]). One rule for [`OutputGate`] and the f64 oracle's gate.
///
/// An answer slower than the slowest rotation the units time ([`slowest_rate_q16`]) makes the
/// motion recent only where it continues the answer of the reading before: on its own it is
/// no motion the units can show, but what background activity makes of a camera that stands
/// still, and the rules for the moment after an answer (a reversal: the other sign without
/// the rows above) would take the first readings of the next turn for the other side of a
/// reversal. (Hover seed 616 with 0.5 Hz of background activity per pixel, spike readout: an
/// answer of -0.008 rad/s in a pause let two readings from two regions of one row band through
/// as a reversal, 0.39 and 0.51 rad/s at a 0.05 rad/s turn; 25.9 → 20.1 % RMSE / peak.) A turn
/// that slows through the floor goes on counting, answer after answer (dev01's reversals).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Answers {
    confirmation: Confirmation,
    age: AnswerAge,
    /// The slowest rotation the units time (Q16 rad/s, >= 0): see [`slowest_rate_q16`].
    floor_q16: u32,
}

impl Answers {
    /// No readings yet, with the units' slowest rotation `floor_q16` (Q16 rad/s,
    /// [`slowest_rate_q16`]; 0: every answer counts as motion).
    pub fn new(floor_q16: u32) -> Self {
        Self {
            confirmation: Confirmation::default(),
            age: AnswerAge::default(),
            floor_q16,
        }
    }

    /// Takes one reading of the field (its rotation, whether that needed the answer a moment
    /// ago, [`FieldReading::recent_needed`], whether it shows none because the decodes
    /// stopped, [`FieldReading::stopped`], or because the view is blind,
    /// [`FieldReading::blind`]) and says whether it is output.
    pub fn read(&mut self, reading: &FieldReading) -> bool {
        let rate = match reading.estimate {
            FieldEstimate::Rotation(v) => Some(v),
            FieldEstimate::NoEvidence => None,
        };
        let answered = self.confirmation.read(rate, reading.stopped);
        let continues = self.age.readings == 0;
        let motion = |r: &i32| r.unsigned_abs() >= self.floor_q16 || continues;
        if reading.blind {
            self.age.after_blind();
        } else {
            self.age
                .after(rate.filter(|r| answered && !reading.recent_needed && motion(r)));
        }
        answered
    }

    /// Whether the last reading was output.
    pub fn answering(&self) -> bool {
        matches!(self.confirmation, Confirmation::Answering { .. })
    }

    /// See [`Confirmation::established`].
    pub fn established(&self) -> bool {
        self.confirmation.established()
    }

    /// See [`AnswerAge::last_answer`].
    pub fn last_answer(&self) -> Option<RecentAnswer> {
        self.age.last_answer()
    }
}

/// The slowest rotation the units time (Q16 rad/s): a one-pixel crossing that takes the slow
/// units' whole window ([`window_log2_s`] with `tau_F` = [`TAU_SLOW_US`], ~270 ms), at the
/// principal point (`rates`): 3.7 px/s, 0.016 rad/s on a DAVIS346 (f = 226 px). Slower
/// answers are not motion the units show ([`Answers`]).
pub fn slowest_rate_q16(kernel: &Kernel, rates: &RateDecoder) -> u32 {
    let window = window_log2_s(kernel, log2_q16(u64::from(TAU_SLOW_US), 0));
    let cx = u16::try_from(rates.cx_bits.saturating_add(1 << 15) >> 16).unwrap_or(u16::MAX);
    exp2_q16(rates.rotation_rate_over(Stride::Near, window, cx))
}

/// Whether a crossing of `2^log2_dt_s` s lies within an octave below the paper's units' reach
/// `2^reach_log2_s` s (half of it or more; both Q16.16): a decode of that crossing lies within
/// an octave above their floor, past the end of the slow units' histograms
/// ([`Field::add_beyond_floor`]). One rule for both rad/s readouts.
pub fn within_an_octave_of_reach(log2_dt_s: i32, reach_log2_s: i32) -> bool {
    log2_dt_s >= reach_log2_s.saturating_sub(1 << 16)
}

/// `log2` of the window (s) of a unit with FAC time constant `2^log2_tau` µs: the longest
/// crossing it times, where the drive of an edge on a pixel with one onset falls to the smallest
/// that bursts (`tau_F ln(w_T w_F / min_drive)`: ~54 ms for the paper's units).
pub fn window_log2_s(kernel: &Kernel, log2_tau: i32) -> i32 {
    let w_trg = kernel.params().w_trg;
    let w_fac = kernel.fac_input(Trace::ZERO);
    let l = log2_q16(u64::from(kernel.min_burst_drive().to_bits()), 27)
        .saturating_sub(log2_q16(u64::from(w_trg.to_bits()), 16))
        .saturating_sub(log2_q16(u64::from(w_fac.to_bits()), 27));
    RateDecoder::log2_dt_s(l, log2_tau).unwrap_or(i32::MIN)
}

/// From the time an edge took to cross the stride to the rotation it implies, at a column.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RateDecoder {
    /// Focal length (px, U16F16 bits).
    focal_bits: u32,
    /// Principal point column (px, U16F16 bits).
    cx_bits: u32,
    /// `log2(stride)` in Q16.16.
    log2_stride: i32,
    /// `1 / f` in Q32.
    inv_f_q32: u64,
}

impl RateDecoder {
    /// For a camera with focal length `focal_px` and principal point column `cx`, and the
    /// layout's stride.
    pub fn new<L: Layout>(layout: &L, focal_px: U16F16, cx: U16F16) -> Self {
        let f_bits = u64::from(focal_px.to_bits().max(1));
        Self {
            focal_bits: focal_px.to_bits(),
            cx_bits: cx.to_bits(),
            log2_stride: log2_q16(u64::from(layout.stride().max(1)), 0),
            inv_f_q32: (1u64 << 48) / f_bits,
        }
    }

    /// `log2 dt` (Q16.16, dt in s) of a crossing whose drive was `2^l` (`l < 0`, Q16.16) of
    /// what an edge at no delay would give, with FAC time constant `2^log2_tau` µs:
    /// `dt = -tau · ln(2^l)`. `None` for `l >= 0` and below the decoder's resolution.
    pub fn log2_dt_s(l: i32, log2_tau: i32) -> Option<i32> {
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

    /// `log2 |w|` (Q16.16) of a crossing of the stride in `2^log2_dt_s` s at column `x`:
    /// `|w| = s / (dt (f + (x - c_x)^2 / f))`.
    pub fn rotation_rate(&self, log2_dt_s: i32, x: u16) -> i32 {
        // G(x) = f + (x - cx)^2 / f in px, Q16.
        let dx = i64::from(u32::from(x) << 16) - i64::from(self.cx_bits);
        let dx2 = dx.unsigned_abs().saturating_mul(dx.unsigned_abs()) >> 16; // Q16 px^2
        let g = u64::from(self.focal_bits).saturating_add(
            ((u128::from(dx2) * u128::from(self.inv_f_q32)) >> 32).min(u128::from(u64::MAX)) as u64,
        );
        self.log2_stride
            .saturating_sub(log2_dt_s)
            .saturating_sub(log2_q16(g, 16))
    }

    /// The focal length (px, U16F16 bits).
    pub fn focal_bits(&self) -> u32 {
        self.focal_bits
    }

    /// `log2` of the layout's stride (px, Q16.16): how much longer the layout's units' crossing
    /// takes than the near units' one-pixel crossing.
    pub fn log2_stride(&self) -> i32 {
        self.log2_stride
    }

    /// `log2 |w|` (Q16.16) of a crossing in `2^log2_dt_s` s at column `x` by the units of
    /// `stride`: the layout's stride ([`RateDecoder::rotation_rate`]) or one pixel (the near
    /// units').
    pub fn rotation_rate_over(&self, stride: Stride, log2_dt_s: i32, x: u16) -> i32 {
        let rate = self.rotation_rate(log2_dt_s, x);
        match stride {
            Stride::Near => rate.saturating_sub(self.log2_stride),
            Stride::Layout => rate,
        }
    }
}

/// The [`Field`] over the units of `layout` for a camera with focal length `focal_px` and
/// principal point `(cx, cy)`: regions spanning the pixels that have units, mirrored about the
/// principal point; histogram time constants `tau_us` per population, aged by `period_us`.
pub fn field_over<L: Layout>(
    layout: &L,
    (focal_px, cx, cy): (U16F16, U16F16, U16F16),
    settings: FieldSettings,
    tau_us: [u32; 2],
    period_us: u32,
) -> Field {
    let (cx, cy) = (i64::from(cx.to_bits()), i64::from(cy.to_bits()));
    let (xs, ys) = unit_span(layout);
    let geometry = FieldGeometry::spanning(cx, cy, i64::from(focal_px.to_bits()), xs, ys);
    let coverage = coverage(layout, &geometry);
    Field::new(geometry, settings, tau_us, period_us, coverage)
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

/// The bands the layout's units reach: column bands with units on both sides of the principal
/// point (0 when its regions never mirror, which switches the field to its unpaired fallback),
/// and row bands above the principal row, up to the topmost with units.
fn coverage<L: Layout>(layout: &L, g: &FieldGeometry) -> Coverage {
    let mut seen = [[false; COL_BANDS]; 2];
    let mut above_bands = 0u8;
    for c in 0..layout.cell_count() {
        if layout.units(c) == 0 {
            continue;
        }
        let (x, y) = layout.pixel(c);
        let (side, band) = g.column(x);
        if let Some(s) = seen.get_mut(side).and_then(|s| s.get_mut(band)) {
            *s = true;
        }
        if let (0, row) = g.row(y) {
            above_bands = above_bands.max(row as u8 + 1);
        }
    }
    let [l, r] = seen;
    Coverage {
        paired_bands: l.iter().zip(r.iter()).filter(|(a, b)| **a && **b).count() as u8,
        above_bands,
    }
}

/// When the field is read and what an output says: nothing during the warm-up (at least
/// [`WARMUP_US`]), then the field's estimate, read every [`REFRESH_US`] and repeated between.
/// A [`FieldEstimate::Rotation`] that [`Confirmation`] passes is output unflagged; anything
/// else as 0 flagged [`flags::NO_EVIDENCE`] (unknown, not zero rate).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OutputGate {
    /// Outputs still to suppress (see [`WARMUP_US`]).
    warmup_outputs: u32,
    /// Outputs per reading of the field (see [`REFRESH_US`]), at least 1.
    refresh: u32,
    /// Outputs since the last reading, modulo `refresh`.
    phase: u32,
    /// The last reading's rate, output while `answers` answers.
    value: I16F16,
    /// Whether the readings so far make an answer, and how long since the last.
    answers: Answers,
}

impl OutputGate {
    /// The gate of a readout with output period `period_us` that says "no evidence" for the
    /// first `warmup_us` (at least [`WARMUP_US`]), over units whose slowest rotation is
    /// `floor_q16` (Q16 rad/s, [`slowest_rate_q16`]).
    pub fn new(period_us: u32, warmup_us: u32, floor_q16: u32) -> Self {
        Self {
            warmup_outputs: warmup_us.max(WARMUP_US).div_ceil(period_us.max(1)),
            refresh: (REFRESH_US / period_us.max(1)).max(1),
            phase: 0,
            value: I16F16::ZERO,
            answers: Answers::new(floor_q16),
        }
    }

    /// One output period: reads `field` when due, ages it by one period, and says what to
    /// output.
    pub fn output(&mut self, field: &mut Field) -> (I16F16, u8) {
        // The field is read every `refresh` outputs (its histograms change over tau_A, not
        // over one period); the outputs between repeat the last reading.
        if self.phase == 0 {
            field.set_direction_established(self.answers.established());
            field.set_recent_motion(self.answers.last_answer());
            self.read(field.reading());
        }
        self.phase += 1;
        if self.phase >= self.refresh {
            self.phase = 0;
        }
        field.age();
        if self.warmup_outputs > 0 {
            self.warmup_outputs -= 1;
            return (I16F16::ZERO, flags::NO_EVIDENCE);
        }
        self.said()
    }

    /// Whether the outputs are still in the warm-up ([`WARMUP_US`] from the first): what the
    /// network triggers now times the order in which pixels woke up.
    pub fn warming_up(&self) -> bool {
        self.warmup_outputs > 0
    }

    /// What the outputs say until the next reading.
    fn said(&self) -> (I16F16, u8) {
        if self.answers.answering() {
            (self.value, 0)
        } else {
            (I16F16::ZERO, flags::NO_EVIDENCE)
        }
    }

    /// Takes one reading of the field. Not inlined: once every [`REFRESH_US`], it stays out of
    /// the event path's code.
    #[inline(never)]
    fn read(&mut self, field: FieldReading) {
        self.answers.read(&field);
        self.value = match field.estimate {
            FieldEstimate::Rotation(v) => I16F16::from_bits(v),
            FieldEstimate::NoEvidence => I16F16::ZERO,
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reading of the field: `rate` (Q16 rad/s; `None`: no evidence, not for want of
    /// decodes), needing the answer a moment ago or not.
    fn reading_of(rate: Option<i32>, recent_needed: bool) -> FieldReading {
        FieldReading {
            estimate: rate.map_or(FieldEstimate::NoEvidence, FieldEstimate::Rotation),
            recent_needed,
            stopped: false,
            blind: false,
        }
    }

    #[test]
    fn an_answer_after_no_evidence_waits_for_a_second_reading_of_its_sign_unless_it_resumes() {
        const NE: (I16F16, u8) = (I16F16::ZERO, flags::NO_EVIDENCE);
        let r = |v: f32| FieldEstimate::Rotation(I16F16::from_num(v).to_bits());
        let out = |v: f32| (I16F16::from_num(v), 0u8);
        let mut gate = OutputGate::new(1_000, WARMUP_US, 0);
        let steps = [
            (FieldEstimate::NoEvidence, NE),
            // The first reading after none is held; the next of its sign answers.
            (r(0.5), NE),
            (r(0.25), out(0.25)),
            // While answering, every reading is output, a change of sign too.
            (r(-0.125), out(-0.125)),
            // After a longer gap than `RESUME_READINGS`, readings that flip sign never agree
            // twice: no answer.
            (FieldEstimate::NoEvidence, NE),
            (FieldEstimate::NoEvidence, NE),
            (FieldEstimate::NoEvidence, NE),
            (FieldEstimate::NoEvidence, NE),
            (r(-0.5), NE),
            (r(0.5), NE),
            (r(-0.5), NE),
            (r(-0.75), out(-0.75)),
            // A gap of up to `RESUME_READINGS` readings: the answer's sign resumes at once, the
            // other sign waits.
            (FieldEstimate::NoEvidence, NE),
            (r(-0.5), out(-0.5)),
            (FieldEstimate::NoEvidence, NE),
            (FieldEstimate::NoEvidence, NE),
            (FieldEstimate::NoEvidence, NE),
            (r(-0.5), out(-0.5)),
            (FieldEstimate::NoEvidence, NE),
            (r(0.5), NE),
            (FieldEstimate::NoEvidence, NE),
            // A longer gap is a new start.
            (FieldEstimate::NoEvidence, NE),
            (FieldEstimate::NoEvidence, NE),
            (FieldEstimate::NoEvidence, NE),
            (r(-0.5), NE),
            (r(-0.5), out(-0.5)),
        ];
        for (k, (reading, want)) in steps.into_iter().enumerate() {
            gate.read(FieldReading {
                estimate: reading,
                recent_needed: false,
                stopped: false,
                blind: false,
            });
            assert_eq!(gate.said(), want, "reading {k}");
        }
    }

    #[test]
    fn the_motion_is_recent_for_its_readings_after_the_last_answer() {
        let mut age = AnswerAge::default();
        // Never answered: nothing recent, however long it waits.
        for _ in 0..300 {
            age.after(None);
            assert_eq!(age.last_answer(), None);
        }
        age.after(Some(-1 << 15));
        let answering = RecentAnswer {
            rate_q16: -1 << 15,
            readings: 0,
        };
        assert_eq!(age.last_answer(), Some(answering));
        for k in 1..=RECENT_READINGS {
            age.after(None);
            let recent = RecentAnswer {
                rate_q16: -1 << 15,
                readings: k,
            };
            assert_eq!(age.last_answer(), Some(recent), "reading {k}");
        }
        age.after(None);
        assert_eq!(age.last_answer(), None);
        // Through the gates' rule: after a pause in the answers, a reading of the other sign
        // is held back, and the motion is still recent, the other way (a reversal).
        let mut a = Answers::new(0);
        for reading in [Some(1 << 16), Some(1 << 15), None, Some(-1 << 16)] {
            a.read(&reading_of(reading, false));
        }
        assert_eq!(a.confirmation, Confirmation::Held { rate_q16: -1 << 16 });
        assert_eq!(a.last_answer().map(|r| r.rate_q16), Some(1 << 15));
        // Answers that needed the motion to be recent are output, but do not make it recent
        // again: it ends RECENT_READINGS after the last answer on the field's own evidence.
        let mut a = Answers::new(0);
        for _ in 0..2 {
            a.read(&reading_of(Some(1 << 16), false));
        }
        for k in 1..=RECENT_READINGS {
            // In turns: "no evidence", then a rotation that needed the motion to be recent.
            let needed = k % 2 == 0;
            assert_eq!(
                a.read(&reading_of(needed.then_some(1 << 16), needed)),
                needed,
                "reading {k}"
            );
            assert!(a.last_answer().is_some(), "reading {k}");
        }
        a.read(&reading_of(Some(1 << 16), true));
        assert!(a.answering());
        assert_eq!(a.last_answer(), None, "{a:?}");
    }

    #[test]
    fn a_blind_stretch_leaves_the_last_answer_recent_for_a_while() {
        // A turn at 0.25 rad/s, then "no evidence": blind readings (the slow units' latest
        // decodes split in sign) leave the answer's age as it was for BLIND_HOLD_READINGS
        // readings after it, then age it; other "no evidence" readings age it at once.
        let blind = FieldReading {
            blind: true,
            ..reading_of(None, false)
        };
        let turn = |a: &mut Answers| {
            for _ in 0..3 {
                a.read(&reading_of(Some(1 << 14), false));
            }
        };
        let mut a = Answers::new(0);
        turn(&mut a);
        for _ in 0..BLIND_HOLD_READINGS {
            a.read(&blind);
        }
        assert_eq!(a.last_answer().map(|r| r.readings), Some(0));
        for _ in 0..RECENT_READINGS {
            a.read(&blind);
        }
        assert_eq!(a.last_answer().map(|r| r.readings), Some(RECENT_READINGS));
        a.read(&blind);
        assert_eq!(a.last_answer(), None);
        // Other "no evidence" ages it reading by reading.
        let mut b = Answers::new(0);
        turn(&mut b);
        for _ in 0..=RECENT_READINGS {
            b.read(&reading_of(None, false));
        }
        assert_eq!(b.last_answer(), None);
        // The hold counts from the last answer, not from the last other reading: blind
        // stretches broken by single "no evidence" readings (a hover's pause with background
        // activity) age it once BLIND_HOLD_READINGS blind readings have passed.
        let mut c = Answers::new(0);
        turn(&mut c);
        for _ in 0..3 {
            for _ in 0..BLIND_HOLD_READINGS - 1 {
                c.read(&blind);
            }
            c.read(&reading_of(None, false));
        }
        assert_eq!(c.last_answer(), None);
    }

    #[test]
    fn answers_slower_than_the_units_floor_make_no_motion_on_their_own() {
        // A floor of 0.0156 rad/s. A still camera's background activity: answers of -0.008
        // rad/s after a pause are output, but the motion is not recent (no reversal can
        // follow from them).
        let floor = 1 << 10;
        let mut a = Answers::new(floor);
        for _ in 0..3 {
            a.read(&reading_of(Some(-1 << 9), false));
        }
        assert!(a.answering());
        assert_eq!(a.last_answer(), None);
        // Without a floor they would make it recent.
        let mut any = Answers::new(0);
        for _ in 0..3 {
            any.read(&reading_of(Some(-1 << 9), false));
        }
        assert_eq!(any.last_answer().map(|r| r.rate_q16), Some(-1 << 9));
        // A turn that slows through the floor goes on counting, answer after answer.
        let mut b = Answers::new(floor);
        for rate in [1 << 14, 1 << 14, 1 << 12, 1 << 9, 1 << 8] {
            b.read(&reading_of(Some(rate), false));
        }
        assert_eq!(b.last_answer().map(|r| r.rate_q16), Some(1 << 8));
        // After a gap, a slow answer (resumed at once) does not count again.
        b.read(&reading_of(None, false));
        assert!(b.read(&reading_of(Some(1 << 8), false)));
        let r = b.last_answer().map(|r| (r.rate_q16, r.readings));
        assert_eq!(r, Some((1 << 8, 2)));
    }

    #[test]
    fn the_units_slowest_rotation_is_a_pixel_in_the_slow_units_window() {
        // DAVIS346: f = 226 px, principal point (172.5, 129.5); the slow units time a crossing
        // of up to ~270 ms, so 3.7 px/s, 0.0164 rad/s at the principal point.
        let layout = crate::layout::Dense::new(346, 260, 2).unwrap();
        let f = U16F16::from_num(226);
        let rates = RateDecoder::new(&layout, f, U16F16::from_num(172.5));
        let floor = slowest_rate_q16(&Kernel::DEFAULT, &rates) as f64 / 65_536.0;
        let window = window_log2_s(&Kernel::DEFAULT, log2_q16(u64::from(TAU_SLOW_US), 0));
        let window_s = exp2_q16(window) as f64 / 65_536.0;
        assert!((0.25..0.29).contains(&window_s), "{window_s} s");
        let want = 1.0 / (226.0 * window_s);
        assert!((floor / want - 1.0).abs() < 0.01, "{floor} against {want}");
        assert!((0.0155..0.0175).contains(&floor), "{floor}");
    }

    #[test]
    fn a_reading_after_no_evidence_waits_for_the_next_to_agree_in_sign_and_size() {
        let one = 1 << 16;
        // The next reading twice the held one (or half of it) agrees; its sign must too.
        for (held, next, answers) in [
            (-one, -2 * one, true),
            (-one, -one / 2, true),
            (one, -one, false),
            // The first decodes after the warm-up, in one band's top rows: -9.3 rad/s.
            (-one, -9 * one, false),
            (-9 * one, -one, false),
        ] {
            let mut c = Confirmation::Waiting;
            assert!(!c.read(Some(held), false));
            assert_eq!(c.read(Some(next), false), answers, "{held} then {next}");
        }
        // A reading that does not agree is held in turn, and the next is measured against it.
        let mut c = Confirmation::Waiting;
        for (reading, answers) in [(-9 * one, false), (-one, false), (-one, true)] {
            assert_eq!(c.read(Some(reading), false), answers, "{reading}");
        }
        // Within RESUME_READINGS of an answer, its sign alone resumes it, at any size.
        c.read(None, false);
        assert!(c.read(Some(-9 * one), false));
        // Not after the decodes stopped (a yaw step, the camera stopping): the histograms'
        // memory of the old rate is not a turn going on, so it waits for a second reading.
        c.read(None, true);
        assert!(!c.read(Some(-9 * one), false));
        assert!(!c.read(None, false), "the held reading is dropped");
        c.read(Some(-one), false);
        assert!(c.read(Some(-one), false));
    }

    #[test]
    fn the_direction_is_established_after_answering_one_sign_for_its_readings() {
        let mut c = Confirmation::Waiting;
        // Held, then answering: established after ESTABLISHED_READINGS answers in a row.
        c.read(Some(-1 << 16), false);
        for k in 1..=ESTABLISHED_READINGS {
            assert!(!c.established(), "answer {k}");
            c.read(Some(-1 << 16), false);
        }
        assert!(c.established());
        // A change of sign starts over; so does a gap, even one the answer resumes after.
        c.read(Some(1 << 16), false);
        assert!(!c.established());
        for _ in 0..ESTABLISHED_READINGS {
            c.read(Some(1 << 16), false);
        }
        assert!(c.established());
        c.read(None, false);
        assert!(!c.established());
        c.read(Some(1 << 16), false);
        assert!(c.read(Some(1 << 16), false) && !c.established());
    }
}
