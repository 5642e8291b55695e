//! The aperture gate: a horizontal unit's decode of an edge that moves mostly vertically is
//! not read as a rotation.
//!
//! # The model
//! Around a pixel, one edge's onset times form a plane: `T(x, y) = T0 + g_x x + g_y y` (`g` in
//! s/px), and the image flow `(u, v)` there satisfies `u g_x + v g_y = 1`. A horizontal unit
//! times `g_x` alone and reads `1 / g_x = u + v g_y / g_x`: the vertical flow leaks in, times
//! the edge's slope. Under pitch and roll a drone's view moves vertically at up to ~200 px/s
//! while it yaws slowly, and its near-horizontal edges (roofs, window rows: large `|g_y / g_x|`)
//! read as fast turns whose sign follows each edge's slant (the aperture problem; see the
//! README, "Known limits", and `docs/figures-history.md`, "Pitch and roll leak").
//!
//! # The rule
//! The FAC traces of the pixels `s_v` rows above and below (the layout's stride; what a vertical
//! unit pair would read) say when the edge passed there: the later of their onsets, `dt_v`
//! before this one, if its trace is at least `2^DOMINANCE_LOG2` times the other's (an edge
//! arrives from one side; two onsets at about the same time are an edge with `g_y ≈ 0`, or
//! two older edges). A decode timing `dt_h` over `s_h` pixels is dropped when
//! - `dt_v / s_v > STEEPNESS · dt_h / s_h`: the edge's normal is within `atan(1 / STEEPNESS)`
//!   (27°) of vertical,
//! - that neighbour's drive would make a burst of the paper's units (`dt_v` within their
//!   reach), and
//! - its onset came at least `tau_F ln 8` (42 ms at `tau_F` = 20 ms) after the pixel's own
//!   previous onset (its trace is above [`AFTER_OWN_LOG2`] times the pixel's own before this
//!   onset): an older onset there belongs to an earlier edge, and would drop fast decodes of
//!   a turn over dense texture at random.
//!
//! In a pure rotation the decodes it drops (edges steeper than that) read right: it costs
//! samples, not accuracy. Measured (`host-sim synth`, 4 s, calibrated readout): a camera that
//! stands still and only wobbles (`--motion static --pitch-roll 0.05 --ground false --seed 7`)
//! reads 0.17 rad/s RMS instead of 0.36; drone seed 7 without forward flight 17.0 → 8.9 %
//! RMSE / peak. Times are compared as log ratios to the pixel's ceiling (`log2(D / (w_T ·
//! own))`, Q16: `-dt / (tau_F ln 2)` for an onset `dt` ago), as both rad/s readouts have them.

use super::shared::DOMINANCE_LOG2;

/// An edge is steep when its time surface rises more than this many times faster per pixel
/// vertically than horizontally.
pub const STEEPNESS: i64 = 2;

/// The vertical neighbour's onset must be this much more recent (log2 of the trace ratio, Q16:
/// `tau_F ln 8` in time) than the pixel's own previous onset.
pub const AFTER_OWN_LOG2: i32 = 3 << 16;

/// What a decoded onset saw around it, each as `log2` of its ratio to the pixel's ceiling
/// `w_T · own` (Q16; own after the onset).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Around {
    /// Drives from the pixels `s_v` rows above and below (`None`: no onset there, or no such
    /// pixel in the layout).
    pub vertical: [Option<i32>; 2],
    /// The pixel's own trace before this onset (`None`: none left).
    pub own_before: Option<i32>,
    /// The smallest drive that makes a burst.
    pub reach: i32,
}

/// Whether a horizontal decode `l2_h` (its drive's `log2` ratio to the ceiling, Q16, below 0)
/// over `s_h` pixels times an edge that moves mostly vertically, seen with the vertical
/// neighbours `s_v` rows away of `around` (see the module documentation).
pub fn moves_vertically(l2_h: i32, [s_h, s_v]: [u16; 2], around: &Around) -> bool {
    let (later, other) = match around.vertical {
        [Some(a), Some(b)] => (a.max(b), Some(a.min(b))),
        [Some(a), None] | [None, Some(a)] => (a, None),
        [None, None] => return false,
    };
    let dominant =
        other.is_none_or(|o| i64::from(later) - i64::from(o) >= i64::from(DOMINANCE_LOG2 << 16));
    let in_reach = later >= around.reach;
    let after_own = around
        .own_before
        .is_none_or(|p| i64::from(later) >= i64::from(p) + i64::from(AFTER_OWN_LOG2));
    // dt_v / s_v > STEEPNESS dt_h / s_h, with dt ∝ -l2.
    let steep = -i64::from(later) * i64::from(s_h) > STEEPNESS * -i64::from(l2_h) * i64::from(s_v);
    dominant && in_reach && after_own && steep
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `log2` ratio (Q16) of an onset `dt_ms` ago, for `tau_F` = 20 ms.
    fn ago(dt_ms: f64) -> i32 {
        (-dt_ms / (20.0 * core::f64::consts::LN_2) * 65536.0) as i32
    }

    /// Whether a crossing of `dt_h_ms` over `s_h` px (the vertical stride 2) is dropped, with
    /// onsets `vertical` ms ago above and below and the own previous one `own_before_ms` ago.
    fn drops(
        dt_h_ms: f64,
        s_h: u16,
        vertical: [Option<f64>; 2],
        own_before_ms: Option<f64>,
    ) -> bool {
        let around = Around {
            vertical: vertical.map(|v| v.map(ago)),
            own_before: own_before_ms.map(ago),
            reach: ago(54.0),
        };
        moves_vertically(ago(dt_h_ms), [s_h, 2], &around)
    }

    #[test]
    fn an_edge_from_above_that_crossed_slowly_vertically_is_dropped() {
        // dt_h = 3 ms over 2 px, the pixel above 10 ms before: g_y / g_x = 3.3.
        assert!(drops(3.0, 2, [Some(10.0), None], None));
        // Over one pixel the same dt_h is twice as slow per pixel: g_y / g_x = 1.7.
        assert!(!drops(3.0, 1, [Some(10.0), None], None));
        // Below it: g_y / g_x = 1.7 at 6 ms.
        assert!(!drops(6.0, 2, [Some(10.0), None], None));
    }

    #[test]
    fn near_vertical_edges_and_ambiguous_neighbours_are_kept() {
        // The pixel above fired just before: g_y small.
        assert!(!drops(3.0, 2, [Some(0.5), None], None));
        // Both neighbours about as long ago: an older edge, or g_y ≈ 0.
        assert!(!drops(3.0, 2, [Some(10.0), Some(12.0)], None));
        // One clearly later than the other (trace ratio above 2: 13.9 ms apart).
        assert!(drops(3.0, 2, [Some(10.0), Some(25.0)], None));
        assert!(!drops(3.0, 2, [None, None], None));
    }

    #[test]
    fn a_neighbour_onset_out_of_reach_or_older_than_the_own_one_is_kept() {
        assert!(!drops(3.0, 2, [Some(60.0), None], None));
        // The pixel's own previous onset 40 ms ago: the neighbour's 10 ms ago is not 42 ms
        // later than it.
        assert!(!drops(3.0, 2, [Some(10.0), None], Some(40.0)));
        assert!(drops(3.0, 2, [Some(10.0), None], Some(60.0)));
    }
}
