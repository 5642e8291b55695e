//! Which units the calibrated readout decodes: the near units (FAC pixel one pixel away) or the
//! layout's (the paper's stride 2).
//!
//! # Why near units
//! A burst times an edge across its stride. Across one pixel the crossing takes half as long as
//! across two, so the near units answer sooner after the motion changes (a reversal, the start
//! of a turn: a perfect stride-2 timer of the image motion at the principal point, with the
//! slow units' 270 ms reach, still misses by 7-11 % of peak on the pure-rotation scenes for that
//! reason alone, a stride-1 timer by 4-7 %) and time edges half as fast within the same window.
//!
//! # When not
//! That holds while a pixel's onset marks the edge's passage to within a fraction of the
//! crossing time: true for sharp edges (buildings, windows, poles), not for smooth textures (no
//! sharp edges). There a pixel reports the brightness once it has moved one contrast step from a
//! reference level of its own, so neighbouring pixels often fire on different features; the
//! decodes spread widely and many take the wrong sign, the more so the shorter the stride (on
//! `dev01`, smooth value noise, the output reads 0.78 of the truth at stride 2 and 0.45 at
//! stride 1, because the field's signed median sinks with the wrong-sign share).
//!
//! # The rule
//! The rule the field uses between its populations ([`sign_agreement`]):
//! the decodes that agree more in sign, per second, within the field's regions, answer. Here
//! the paper's units' decodes of both strides count, per region and sign, leaky over
//! [`MEMORY_US`]; the near units are decoded while their agreement `Σ max(0, (P - N)² / (P + N)
//! - RANDOM_AGREEMENT)` (P, N: decodes per sign in a region) is at least the layout's, else the
//! layout's units; the choice changes only when the other stride leads by [`SWITCH_MARGIN`].
//! Only onsets on one row in [`COUNT_ROWS`] are counted (elsewhere the stride not chosen is
//! not read at all). Over the first [`SETTLE_US`], and while neither stride agrees at all, the
//! choice stays as it was (at the start: near, on layouts that have near units,
//! [`super::calibrated::has_near`]).
//!
//! # Fast motion
//! Across one pixel a fast edge's crossing is short against the jitter of its onsets (a random
//! part of a contrast step's travel at each pixel), which the layout's stride halves, and the
//! fastest crossings reach the near units' floor (one pixel in 2.1 ms,
//! [`NEAR_FLOOR_IMAGE_SPEED_PX_S`]). While the readout's own answer says the image moves at
//! least [`FAST_IMAGE_SPEED_PX_S`] at the principal point (3/4 of that speed, where a fifth of
//! the one-pixel crossings reach the floor), the layout's units decode whatever the sign
//! counts say, until it falls below [`SLOW_AGAIN_PX_S`] or the readout has no evidence.
//! Constant turns over the skyline (`host-sim synth --motion constant`, seed 11, a DAVIS346)
//! at 3 / 4 / 6 / 8 rad/s read 0.97 / 0.90 / 0.78 / 0.72 of the turn with the near units,
//! 0.99 / 0.97 / 0.90 / 0.88 with the layout's; drone seed 304, turning at 1.8 rad/s while it
//! pitches and rolls, 5.8 / 4.5 % RMSE / peak (spike readout 8.6 / 5.4 %). Below 1.5 rad/s
//! the near units read as well, and answer sooner at a turn's start and reversals. The sign
//! counts go on meanwhile.

use fixed::types::I16F16;

use super::field::{sign_agreement, REGIONS};
use crate::exp_table::{scale_q31, ExpDecay};
use crate::flags;

/// Memory of the sign counts (µs).
pub const MEMORY_US: u32 = 1_000_000;

/// Image speed at the principal point (px/s) at which an edge crosses one pixel in the near
/// units' floor, 2.1 ms (`tau_F ln(10/9)` for the paper's units, the fastest crossing the
/// spike readout reads from them): 2.1 rad/s on a DAVIS346 (f = 226 px).
pub const NEAR_FLOOR_IMAGE_SPEED_PX_S: u64 = 476;

/// Image speed at the principal point (px/s, from the readout's answer) from which the
/// layout's units decode: 3/4 of [`NEAR_FLOOR_IMAGE_SPEED_PX_S`], where the fastest fifth of
/// the one-pixel crossings reach the near units' floor (onsets jitter: over the skyline at
/// 0.8-2 rad/s a fifth of the one-pixel crossings read 1.31 times the image speed or more).
/// One pixel per 2.8 ms, 1.58 rad/s on a DAVIS346. See "Fast motion".
pub const FAST_IMAGE_SPEED_PX_S: u64 = NEAR_FLOOR_IMAGE_SPEED_PX_S * 3 / 4;

/// Image speed (px/s) below which the sign counts choose again: 3/4 of
/// [`FAST_IMAGE_SPEED_PX_S`], so that an answer that hovers about it does not switch strides
/// at every output.
pub const SLOW_AGAIN_PX_S: u64 = FAST_IMAGE_SPEED_PX_S * 3 / 4;

/// Whether the image moves fast after an answer of `px_s` (whole px/s at the principal point;
/// 0 without evidence), given whether it did before: on from [`FAST_IMAGE_SPEED_PX_S`], off
/// below [`SLOW_AGAIN_PX_S`], as it was between. The f64 oracle applies the same rule.
pub fn moves_fast(was_fast: bool, px_s: u64) -> bool {
    px_s >= FAST_IMAGE_SPEED_PX_S || (was_fast && px_s >= SLOW_AGAIN_PX_S)
}

/// Time (µs) from the start before the rule changes the choice: each pixel's first onsets
/// after the start come from the level the sensor started with, not from an edge.
pub const SETTLE_US: u32 = MEMORY_US / 4;

/// Outputs between two looks at the counts (their decay is applied then, for the whole time
/// since the last look): the choice needs no faster answer than its 1 s memory, and a look
/// costs a division per region and stride.
pub const LOOK_EVERY: u32 = 64;

/// The rows whose onsets are counted: one in this many (`y % COUNT_ROWS == 0`). Elsewhere only
/// the chosen stride's FAC pixels are read, so the choice costs two FAC trace reads on one row
/// in four.
pub const COUNT_ROWS: u16 = 4;

/// The choice changes only when the other stride's agreement exceeds the current one's by
/// this many decodes' worth. After a pause the counts hold little more than the decodes of
/// pixels waking up as the motion starts (hover seed 33's first look after its pause: 1
/// against 5), which favour the layout's units (over two pixels the motion orders the wake-up
/// more often than over one) for about one look; the layout's units then time the hover's slow
/// edges near the end of their window, and its turn's first answers read 3-4 times too fast
/// (hover seed 33: 20.3 → 12.6 % RMSE / peak with the margin).
pub const SWITCH_MARGIN: u32 = 8;

/// Decay of the counts.
static MEMORY: ExpDecay = ExpDecay::new(MEMORY_US);

/// Which units to decode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stride {
    /// The near units (FAC pixel one pixel away).
    Near = 0,
    /// The layout's units (its stride).
    Layout = 1,
}

/// The leaky sign counts and the current choice.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StrideChoice {
    /// Decodes `[stride][region][sign]` (sign 1 = positive), leaky, Q8 samples.
    counts_q8: [[[u32; 2]; REGIONS]; 2],
    /// The sign counts' choice.
    choice: Stride,
    /// Whether the readout's answer says the image moves fast ("Fast motion").
    fast: bool,
    /// Time since the start (µs, up to [`SETTLE_US`]).
    settled_us: u32,
    /// Outputs since the last look, and their time (µs).
    outputs: u32,
    since_look_us: u32,
}

impl StrideChoice {
    /// No decodes yet: the near units decode if the layout has them (`near`), else the
    /// layout's, for good.
    pub const fn new(near: bool) -> Self {
        Self {
            counts_q8: [[[0; 2]; REGIONS]; 2],
            choice: if near { Stride::Near } else { Stride::Layout },
            fast: false,
            settled_us: 0,
            outputs: 0,
            since_look_us: 0,
        }
    }

    /// The units to decode now: the layout's while the image moves fast, else the sign
    /// counts' choice.
    pub fn choice(&self) -> Stride {
        if self.fast {
            Stride::Layout
        } else {
            self.choice
        }
    }

    /// The readout's output `(yaw, flags)` (rad/s; "no evidence" when flagged so), with the
    /// focal length `focal_bits` (px, U16F16 bits). It says how fast the image moves at the
    /// principal point (`|yaw| f` px/s): see "Fast motion".
    pub fn follow_answer(&mut self, (yaw, flags): (I16F16, u8), focal_bits: u32) {
        let px_s = if flags & flags::NO_EVIDENCE == 0 {
            (u64::from(yaw.to_bits().unsigned_abs()) * u64::from(focal_bits)) >> 32
        } else {
            0
        };
        self.fast = moves_fast(self.fast, px_s);
    }

    /// Whether onsets at row `y` are counted (both strides' FAC pixels are read there).
    pub fn counts_row(y: u16) -> bool {
        y.is_multiple_of(COUNT_ROWS)
    }

    /// One decode of the paper's units of `stride` in field region `region`, with its sign.
    pub fn add(&mut self, stride: Stride, region: usize, positive: bool) {
        if let Some(c) = self
            .counts_q8
            .get_mut(stride as usize)
            .and_then(|r| r.get_mut(region))
            .and_then(|s| s.get_mut(usize::from(positive)))
        {
            *c = c.saturating_add(1 << 8);
        }
    }

    /// Sign agreement of a stride's decodes: `Σ max(0, (P - N)² / (P + N) - RANDOM_AGREEMENT)`
    /// over the regions, in Q8 samples.
    fn agreement_q8(&self, stride: Stride) -> u64 {
        self.counts_q8.get(stride as usize).map_or(0, |regions| {
            regions
                .iter()
                .map(|&[n, p]| sign_agreement(u64::from(n), u64::from(p), 1 << 8))
                .sum()
        })
    }

    /// `dt_us` of time passed (once per output); every [`LOOK_EVERY`] outputs the choice
    /// follows the counts, which decay.
    pub fn age(&mut self, dt_us: u32) {
        self.settled_us = self.settled_us.saturating_add(dt_us).min(SETTLE_US);
        self.since_look_us = self.since_look_us.saturating_add(dt_us);
        self.outputs += 1;
        if self.outputs < LOOK_EVERY {
            return;
        }
        let dt_us = core::mem::take(&mut self.since_look_us);
        self.outputs = 0;
        if self.settled_us >= SETTLE_US {
            let near = self.agreement_q8(Stride::Near);
            let layout = self.agreement_q8(Stride::Layout);
            if near > 0 || layout > 0 {
                let margin = u64::from(SWITCH_MARGIN) << 8;
                self.choice = match self.choice {
                    Stride::Near if layout > near.saturating_add(margin) => Stride::Layout,
                    Stride::Layout if near >= layout.saturating_add(margin) => Stride::Near,
                    kept => kept,
                };
            }
        }
        let keep = MEMORY.decay_bits(dt_us);
        for c in self.counts_q8.iter_mut().flatten().flatten() {
            *c = scale_q31(*c, keep);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Outputs of 1 ms over `us`, then enough more for a look.
    fn look_after(c: &mut StrideChoice, us: u32) {
        for _ in 0..us / 1_000 {
            c.age(1_000);
        }
        while c.outputs != 0 {
            c.age(0);
        }
    }

    /// `n` decodes of `stride` in `region`, `positive` of them positive.
    fn decodes(c: &mut StrideChoice, stride: Stride, region: usize, n: u32, positive: u32) {
        for k in 0..n {
            c.add(stride, region, k < positive);
        }
    }

    #[test]
    fn the_stride_whose_decodes_agree_more_answers() {
        let mut c = StrideChoice::new(true);
        assert_eq!(c.choice(), Stride::Near);
        // Sharp edges: near decodes as many and as one-signed as the layout's.
        for r in 0..8 {
            decodes(&mut c, Stride::Near, r, 100, 95);
            decodes(&mut c, Stride::Layout, r, 100, 95);
        }
        look_after(&mut c, SETTLE_US);
        assert_eq!(c.choice(), Stride::Near);
        // A smooth texture: near decodes take either sign.
        let mut c = StrideChoice::new(true);
        for r in 0..8 {
            decodes(&mut c, Stride::Near, r, 100, 60);
            decodes(&mut c, Stride::Layout, r, 100, 85);
        }
        look_after(&mut c, SETTLE_US);
        assert_eq!(c.choice(), Stride::Layout);
    }

    #[test]
    fn no_change_before_settling_or_without_agreement() {
        let mut c = StrideChoice::new(true);
        decodes(&mut c, Stride::Layout, 3, 1_000, 1_000);
        look_after(&mut c, SETTLE_US - 1_000);
        assert_eq!(c.choice(), Stride::Near);
        look_after(&mut c, 1_000);
        assert_eq!(c.choice(), Stride::Layout);
        // Random signs on both sides: nothing to go by, the choice stays.
        let mut c = StrideChoice::new(true);
        decodes(&mut c, Stride::Near, 0, 100, 50);
        decodes(&mut c, Stride::Layout, 0, 100, 50);
        look_after(&mut c, SETTLE_US);
        assert_eq!(c.choice(), Stride::Near);
        assert_eq!(StrideChoice::new(false).choice(), Stride::Layout);
    }

    #[test]
    fn a_few_decodes_do_not_change_the_choice() {
        // One region of the layout's units with 5 decodes of one sign (3 beyond random
        // signs) against nothing: the pixels waking up after a pause. The near units stay.
        let mut c = StrideChoice::new(true);
        decodes(&mut c, Stride::Layout, 0, 5, 5);
        look_after(&mut c, SETTLE_US);
        assert_eq!(c.choice(), Stride::Near);
        // A lead of the margin changes it; back to the near units takes the margin too.
        decodes(
            &mut c,
            Stride::Layout,
            1,
            SWITCH_MARGIN + 3,
            SWITCH_MARGIN + 3,
        );
        look_after(&mut c, 64_000);
        assert_eq!(c.choice(), Stride::Layout);
        let mut c = StrideChoice::new(true);
        decodes(&mut c, Stride::Layout, 0, 100, 100);
        look_after(&mut c, SETTLE_US);
        assert_eq!(c.choice(), Stride::Layout);
        // A region of n one-signed decodes agrees by n - RANDOM_AGREEMENT: the near units
        // lead by half the margin, then by the margin and a half.
        let layout = (c.agreement_q8(Stride::Layout) >> 8) as u32;
        let n = layout + 2 + SWITCH_MARGIN / 2;
        decodes(&mut c, Stride::Near, 1, n, n);
        look_after(&mut c, 1_000);
        assert_eq!(c.choice(), Stride::Layout, "a lead below the margin");
        decodes(
            &mut c,
            Stride::Near,
            2,
            SWITCH_MARGIN + 2,
            SWITCH_MARGIN + 2,
        );
        look_after(&mut c, 1_000);
        assert_eq!(c.choice(), Stride::Near);
    }

    #[test]
    fn counts_forget_over_the_memory() {
        let mut c = StrideChoice::new(true);
        decodes(&mut c, Stride::Near, 0, 1_000, 1_000);
        for _ in 0..3_000 {
            c.age(1_000);
        }
        let left = c.counts_q8[0][0][1] >> 8;
        // e^-3 of 1000.
        assert!((45..=55).contains(&left), "{left}");
    }

    #[test]
    fn counts_decay_only_at_looks() {
        let mut c = StrideChoice::new(true);
        decodes(&mut c, Stride::Near, 0, 100, 100);
        for _ in 0..LOOK_EVERY - 1 {
            c.age(1_000);
        }
        assert_eq!(c.counts_q8[0][0][1], 100 << 8);
        c.age(1_000);
        assert!(c.counts_q8[0][0][1] < 100 << 8);
    }

    #[test]
    fn fast_answers_choose_the_layout_units_until_they_slow_down() {
        // f = 226 px: 1.58 rad/s is 357 px/s, 1.18 rad/s 267 px/s.
        let focal = 226 << 16;
        let rad_s = |w: f64| (I16F16::from_num(w), 0);
        let mut c = StrideChoice::new(true);
        c.follow_answer(rad_s(1.5), focal);
        assert_eq!(c.choice(), Stride::Near, "below the fast speed");
        c.follow_answer(rad_s(-1.7), focal);
        assert_eq!(c.choice(), Stride::Layout, "either sign");
        c.follow_answer(rad_s(1.25), focal);
        assert_eq!(
            c.choice(),
            Stride::Layout,
            "between the two speeds it stays"
        );
        c.follow_answer(rad_s(1.1), focal);
        assert_eq!(c.choice(), Stride::Near);
        c.follow_answer(rad_s(4.0), focal);
        c.follow_answer((I16F16::from_num(4.0), flags::NO_EVIDENCE), focal);
        assert_eq!(c.choice(), Stride::Near, "no evidence: not fast");
        // The sign counts' own choice is kept underneath.
        decodes(&mut c, Stride::Layout, 0, 100, 100);
        look_after(&mut c, SETTLE_US);
        assert_eq!(c.choice(), Stride::Layout);
        c.follow_answer(rad_s(4.0), focal);
        c.follow_answer(rad_s(0.5), focal);
        assert_eq!(c.choice(), Stride::Layout);
        // A layout without near units: the layout's, whatever the answer.
        let mut c = StrideChoice::new(false);
        c.follow_answer(rad_s(0.1), focal);
        assert_eq!(c.choice(), Stride::Layout);
    }

    #[test]
    fn out_of_range_regions_are_ignored() {
        let mut c = StrideChoice::new(true);
        c.add(Stride::Near, REGIONS, true);
        assert_eq!(c.agreement_q8(Stride::Near), 0);
    }
}
