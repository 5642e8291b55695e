//! Rotation from the whole field: decoded rates per region, a fit per column, mirrored sides.
//!
//! # The model
//! A camera that yaws at `w` and also moves (forward translation `T_z`, pitch rate `w_x`, roll
//! rate `w_z`) sees, at normalised image coordinates `X = (x - c_x)/f`, `Y = (y - c_y)/f` and
//! depth `Z`, a horizontal flow that a burst decodes as the rotation-equivalent rate
//! `r = -u / (f (1 + X²)) = w - (X T_z / Z + w_x X Y + w_z Y) / (1 + X²)`.
//! - Yaw is the same everywhere.
//! - Within one column band (`X` about fixed), roll and pitch are linear in `Y`, and so is the
//!   translation flow of a ground plane (`1/Z ∝ Y` below the horizon, 0 for far scenery above
//!   it): a fit of `r` against `Y` with separate slopes above and below the principal row has
//!   the yaw rate, plus what is odd in `X`, as its intercept at `Y = 0`.
//! - What is odd in `X` (forward translation of scenery that is not a ground plane: zero at the
//!   focus of expansion, opposite signs either side) cancels in the mean of a column band left
//!   of `c_x` and one right of it: exactly for mirrored bands, about for others.
//! - An object moving on its own moves only its part of the view, and a rotation moves all of
//!   it: the rotation must hold in several column bands on each side.
//!
//! Assumed: the principal point is known and the focus of expansion is near it (the camera
//! moves along its optical axis); mirrored columns see scenery at similar depths. Lateral
//! translation (side-slip) moves far scenery not at all and near scenery like a yaw: it is not
//! separated.
//!
//! # The estimator
//! - The field is cut into [`REGIONS`]: [`COL_BANDS`] bands of columns either side of `c_x`
//!   times [`ROW_BANDS`] bands of rows either side of `c_y`, mirror-symmetric about the
//!   principal point and spanning the layout's units.
//! - Each region keeps leaky histograms of the decoded `log2 |r|` per sign ([`BINS`] bins from
//!   0.01 to 20 rad/s), one set per [`Population`]. Its value is the signed median and its
//!   precision the interquartile range over the number of samples: where edges also move
//!   vertically (the ground under forward motion) a horizontal unit suffers the aperture
//!   problem and its decodes spread widely around the true horizontal flow, so such regions
//!   count little; so do regions whose decodes split in sign (their variance times
//!   `(P + N) / |P - N|`, at most [`SPLIT_VARIANCE_CAP`]). A region whose decodes agree in
//!   sign (at most a quarter the other way) and that holds [`SETTLED_SAMPLES_Q16`] (any
//!   count once the readout has answered one direction for 100 ms:
//!   [`Field::set_direction_established`]) reads the median of its majority sign instead:
//!   there the other sign's decodes are timing errors, which would pull the signed median
//!   towards slow rates (`majority_median`).
//! - Per column band and side: the inverse-variance weighted least-squares intercept of the
//!   region values against `Y` (slopes with a weak prior). When the fits of the band's rows
//!   above and below the principal row alone differ by more than [`HALVES_DISAGREE_SIGMAS`]
//!   standard deviations, or the rows below read more than [`HALVES_FASTER_BELOW`] times as
//!   fast as the rows above, the upper half's fit alone: far scenery above the horizon moves with
//!   the rotation, while below it the ground close under a flying drone (whose flow grows
//!   faster than linearly in `Y`) and people walking past move on their own. For the same
//!   reason a band whose rows above have no value has none (where the layout has mirrored
//!   bands and rows reaching [`FAR_ROWS_Q12`] above the principal row): as a turn ends and the
//!   far scenery's decodes thin out, people walking past below it would otherwise give the
//!   band values.
//! - Every left band's intercept is paired with every right band's (up to
//!   [`COL_BANDS`]² pairs); the output is the inverse-variance weighted median of the pairs'
//!   means when each side has an intercept in some band, and either `support` mirrored bands
//!   have both or at least half of the mirrored bands' sides have one; else "no rotation
//!   evidence". Pairing across bands keeps one wrong band from spoiling its mirror, and a side
//!   that sees no texture in some bands (sky, a blank wall) from silencing the field. (Objects
//!   crossing the view are told from a rotation mostly by the rows they reach, below: with
//!   that rule in place, a side needs one band, not `support`, and a view whose texture lies
//!   mostly on one side still answers.) Right after the readout answered
//!   ([`Field::set_recent_motion`]) a value on each side is enough when all have one sign:
//!   after a reversal the bands fill one by one, the first where the texture is richest, and
//!   a camera that stood still has not answered (rotation seed 401, texture in one band of
//!   its left side: "no evidence" on 17.9 % of the turning samples before, 7.7 % with this
//!   and the other rules for the moment after an answer).
//! - When one side has a value in no column band (no texture there: sky, a blank wall), the
//!   other side answers alone if at least [`LONE_SIDE_BANDS`] of its bands have values that
//!   agree as a rotation's ([`BAND_SPREAD`]; what is odd in `X` cannot cancel then, but it
//!   shows as a trend across the bands): the weighted median of that side's intercepts.
//!   Without it a pure rotation seen with texture on one side only read "no evidence" for as
//!   long (urban rotation seed 61: 27 % of the turning samples).
//! - An answer also needs values in at least [`ABOVE_SUPPORT`] of the row bands above the
//!   principal row, the topmost band among them: far scenery above the horizon moves with a
//!   rotation, while objects on the ground (people, cars crossing the view of a camera that
//!   stands still) and the ground under translation move the rows below it and the lower bands
//!   above it. Row bands are a third of the layout's rows on their own side of the principal
//!   row each (column bands are mirrored, row bands need not be: each half has its own
//!   slope), so the top band is the upper third of the rows above the principal row wherever
//!   the principal point lies ([`Coverage`]; none is asked for when no row lies above it).
//!   Assumed: the camera is upright and sees textured scenery in that band, unless every
//!   column band of the view has a value and they all agree ([`BAND_SPREAD`]): only a
//!   rotation moves the whole width at one rate (an object at one depth moving on its own
//!   reads about 30 % slower in the outer bands of a DAVIS346's view than in the inner ones),
//!   so a turn under a low skyline (sky in the top band) still answers. Nor is the top band
//!   needed when two row bands above have values in at least [`WIDE_UPPER_BAND_SIDES`] of the
//!   eight column band sides, all of one sign, the outer bands not slower than the inner ones
//!   ([`WIDE_FALLOFF_TENTHS`]): people walking past move a few column bands at a time, and a
//!   scene at half the usual contrast gets almost no decodes from its faint upper scenery.
//!   Nor is it needed right after the readout answered ([`Field::set_recent_motion`]) when all
//!   band values have the other sign: after a reversal the top band's regions fill last, a
//!   camera that stood still has not answered, and translation moves the halves opposite
//!   ways. (Not after an answer the same way: people walking on past a drone that has just
//!   stopped turning move that way too.) Nor, within 100 ms of an answer, when the band values
//!   are spread as a rotation's, of that answer's sign, in at least [`ABOVE_SUPPORT`] row
//!   bands above, and their estimate continues the answer's rate to within a fifth
//!   ([`BAND_SPREAD`]): a steady turn whose texture leaves the top row band (sky coming into
//!   view) goes on being read, where people walking on past a drone that stopped read at a
//!   rate of their own.
//! - When more than a quarter of that weight ([`SPLIT_SHARE`]) says the other direction, the
//!   field does not know which way the camera turns: "no rotation evidence" (just after a
//!   reversal; straight driving past scenery at different depths either side).
//! - The output comes from the population whose decodes agree in sign within their regions
//!   the more per second ([`RANDOM_AGREEMENT`]): the paper's units, or the slow units in a slow
//!   scene (where the paper's units time an edge near the end of their window they alias, and
//!   their decodes take either sign). The slow units' figure is scaled up by how much their
//!   decode rate over the last [`SHORT_TAU_US`] exceeds their histograms' average (at most
//!   their time constant over it, 5x): at a slow turn's start their 100 ms histograms are still
//!   filling, while the paper's units, timing only the fastest crossings, read high. The slow
//!   units' value is scaled by 5/4 of their decode rate over the last [`SHORT_TAU_US`] relative
//!   to their histograms' (at most 1): their 100 ms histograms remember a turn that is slowing
//!   down longer than it lasts. (Only a drop below 4/5 scales: the 20 ms rate's own scatter
//!   would otherwise bias a steady slow turn low.)
//! - The answering population says nothing when its decodes over the last [`SHORT_TAU_US`]
//!   have all but stopped (the camera stopped turning), and the paper's units also when their
//!   decodes over the last 0.3 `tau_A` ([`BRIEF_TAU_TENTHS`]) fall below half their
//!   histograms' rate ([`BRIEF_STOP_RATIO`], where that expects [`BRIEF_MIN_DECODES`] or
//!   more): when the image motion stops or reverses at once (a yaw step), no edge completes a
//!   crossing for a while, and their 10 ms histograms would repeat the old rate for 20-30 ms
//!   (DAVIS240 steps, seed 8: 10.7 → 8.4 % RMSE / peak). Such a reading says so
//!   ([`FieldReading::stopped`]), and the next answer is a new start, held for a second
//!   reading (`readout::shared::Confirmation`; seed 8 8.3 → 7.7 %). The slow units also say
//!   nothing (not a stop) while their decodes over the last [`SHORT_TAU_US`] split in sign more
//!   evenly than 60 / 40 ([`SPLIT_STOP_TENTHS`]): after a turn's zero crossing over a smooth
//!   texture only background activity decodes for 0.1-0.2 s, and their 100 ms histograms
//!   would answer the old direction.
//! - A new start (no answer within the last 100 ms) also says nothing unless at least 6 in 10
//!   of the answering population's decodes above the principal row over the last
//!   [`SHORT_TAU_US`] take its sign (`Field::start_against`): the first onsets after a pause
//!   come a random part of a crossing late and take either sign.
//! - A trigger goes to the slow units only where the paper's units do not burst, so the slow
//!   units' histograms end at the paper's units' floor (the slowest rotation they time: 0.08
//!   rad/s across one pixel at a DAVIS346's principal point), and a turn whose crossings
//!   straddle it reads low from them (hover seed 1 at 0.066 rad/s: the output read 0.80 of
//!   it over 1.2-2.2 s, test `regimes::a_hover_turn_straddling_the_paper_units_floor`; the
//!   decodes' medians, `docs/readout-notes.md`: slow units 0.82, paper's units 1.49). The
//!   paper's units' decodes within an octave above their floor at onsets the slow units decode
//!   too are counted per region and sign over the paper's units' time constant
//!   ([`Field::add_beyond_floor`]); once the direction is established, the slow units'
//!   median counts them at the floor, scaled to the slow units' time constant, and at
//!   most as many as the slow units decode in the octave below it (a distribution that goes on
//!   past the floor has about as much there; where the slow units' decodes thin out before it,
//!   the paper's units' decodes near the floor are aliases or an onset's wake-ups).
//! - A layout with no mirrored bands (such as two boxes placed at random) uses each band's side
//!   alone, with no spread gate.
//!
//! # Leaky histograms without touching every bin
//! Instead of decaying every bin each period, new samples get a weight that grows by
//! `e^(period/tau_A)` per period; when it passes 2, every bin and the weight are halved. The
//! ratios the estimator uses are those of histograms decayed every period, up to the halving's
//! truncation.

use crate::exp_table::ExpDecay;
use crate::log2::exp2_q16;
use crate::unit::div_u64;

/// Column bands either side of the principal point.
pub const COL_BANDS: usize = 4;
/// Row bands either side of the principal point.
pub const ROW_BANDS: usize = 3;
/// Regions of the field: 2 sides x [`COL_BANDS`] x 2 sides x [`ROW_BANDS`].
pub const REGIONS: usize = 4 * COL_BANDS * ROW_BANDS;
/// Row bands above the principal row (of [`ROW_BANDS`]) in which some region must have a value
/// before the field reports a rotation, the topmost band among them. Scenery above the horizon
/// is far: it moves with a rotation and hardly with a translation. An object standing on the
/// ground, `h` tall at distance `d` from a camera at height `c`, reaches `(h - c) / d · f`
/// above the principal row: a person 1.8 m tall at 2 m seen from 1.7 m 0.05 f, but seen from
/// 1.2 m (a drone hovering low) 0.3 f, into the second row band (row bands are a third of the
/// rows on their side each: with the principal point at the centre the top one starts 0.38 f
/// above on a DAVIS346, 0.30 f on a DAVIS240, out of a 1.9 m person's reach beyond 1.8 / 2.3
/// m from a camera at 1.2 m; with the principal point above the centre it starts lower). So
/// motion in the lower half and the lower row bands above only is an object's, or the
/// ground's under translation (which the fit cannot tell from a yaw where the ground's edges
/// suffer the aperture problem). Without the top band, people walking past 2-3 m from a
/// camera at 1.2 m read as 0.4-0.8 rad/s turns (`--regime objects`, seeds 51 and 52).
pub const ABOVE_SUPPORT: u32 = 2;

/// Which of the field's bands the layout's units reach (from the layout and the principal
/// point, once): the rules that ask for values spread over the view ask only for bands that
/// can have them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Coverage {
    /// Column bands with units on both sides of the principal point (0: the regions never
    /// mirror, and the field falls back to its unpaired estimate).
    pub paired_bands: u8,
    /// Row bands above the principal row that have units, from the principal row up (the
    /// topmost of them is the top row band of [`ABOVE_SUPPORT`]): [`ROW_BANDS`] when the
    /// layout has rows above the principal point (the bands above split those rows), 0 when
    /// it has none.
    pub above_bands: u8,
}

/// `|Y|` (Q12) that the centre of the top row band above the principal row must reach for the
/// rows below alone to give a column band no value (see [`Field`]): 0.1, about
/// 6° above the horizon. Closer to it the two halves see the same distant scenery and ground
/// (ground 0.1 f below the horizon lies ten camera heights away): on the STM32F405's 346 x 15
/// strip (7 rows above, 0.03 f) the rule left bands without values (drone seed 7 "no evidence"
/// while turning 8.2 → 24.3 %, `host-sim run --window 0:122:346:15`), on the STM32H743's 346 x
/// 126 window (0.23 f) it helps as on the whole sensor (0.48 f).
pub const FAR_ROWS_Q12: i64 = 410;

/// How far apart a region's quartile rates (same sign) must lie before a region whose decodes
/// agree in sign takes its other sign's decodes for the far side of the majority's spread (and
/// reads its median time difference): an octave. A factor of 2 tells a smooth texture's spread
/// from the skyline's aliases on the scenes measured (`docs/readout-notes.md`; over the
/// majority's own quartiles, 1.5 octaves left value noise at 0.4 rad/s as it was, half an
/// octave read the skyline 2 % fast).
pub const WIDE_MAJORITY_RATIO: u64 = 2;

/// Histogram bins per region and sign (at most 64: [`Field`] marks the occupied ones in a
/// `u64`).
pub const BINS: usize = 64;
const _: () = assert!(BINS <= 64);

/// Decoded bursts (leaky, Q16) from which a region whose decodes agree in sign reads the
/// median of that sign (`majority_median`); below, its signed median. Where motion has just
/// started (a hover's turn after a pause) a region's first decodes agree in sign and
/// overshoot; 32 is past them on the hover scenes. Once the readout has answered one direction
/// for 100 ms, the count no longer applies ([`Field::set_direction_established`]).
pub const SETTLED_SAMPLES_Q16: u32 = 32 << 16;

/// A region's decodes agree in sign when at most `2^-SETTLED_MINORITY_LOG2` of them (a
/// quarter) take the other sign (see `majority_median`).
pub const SETTLED_MINORITY_LOG2: u32 = 2;

/// A region's variance is multiplied by its decodes over their net sign count, `(P + N) / |P -
/// N|`, at most this much (`split_variance`): where its decodes split in sign (the ground
/// under forward flight and pitch, the aperture problem, noise) its signed median says less
/// about the rate than its spread over so many samples shows.
pub const SPLIT_VARIANCE_CAP: u64 = 4;

/// Lowest and highest |rate| the histograms resolve (rad/s); outside values fall into the end
/// bins.
pub const RATE_RANGE: (f32, f32) = (0.01, 20.0);
/// `log2(0.01)` and `log2(20)` in Q16.16 (the histograms' edges).
pub const LOG2_LO: i32 = -435_413;
/// See [`LOG2_LO`].
pub const LOG2_HI: i32 = 283_242;
/// Bin width in Q16.16 log2 units.
pub const BIN_W: i32 = (LOG2_HI - LOG2_LO) / BINS as i32;

/// Whole histogram bins per octave of rate (5; an octave is 5.8 bins): how far below the paper's
/// units' floor the slow units' decodes that bound [`Field::add_beyond_floor`]'s count reach.
pub const OCTAVE_BINS: usize = (65_536 / BIN_W) as usize;

/// Time constant of the recent decode rate (µs) that tells a stopped camera.
pub const SHORT_TAU_US: u32 = 20_000;
/// A population whose recent decode rate is below `1 / STOPPED_RATIO` of its histograms'
/// rate has stopped seeing motion.
pub const STOPPED_RATIO: u64 = 8;
/// Time constant of the paper's units' latest decode rate, in tenths of their histograms'
/// (`tau_A`; 3 ms for a whole DAVIS240/346 layout). It tells an abrupt stop or reversal of the
/// image motion: no edge completes a crossing then, and their decodes stop within a few ms
/// while their histograms still remember the old motion for `tau_A`. (A layout with fewer
/// units has a longer `tau_A`, for as many decodes: so has this.)
pub const BRIEF_TAU_TENTHS: u32 = 3;
/// The paper's units say nothing while their decode rate over the brief time constant
/// ([`BRIEF_TAU_TENTHS`]) is below `1 / BRIEF_STOP_RATIO` of their histograms' (a turn that
/// slows down smoothly does not halve its decode rate within their memory; with 1, any drop
/// below their rate, rotations, drones and hovers read up to 20 points of RMSE / peak worse).
/// The time constant and ratio were chosen on the design scenes: 2-4 ms and 2 read within 1.5
/// points of each other there, 3 ms and 8, or 5 ms and 4, changed little.
pub const BRIEF_STOP_RATIO: u64 = 2;
/// The paper's units' stop ([`BRIEF_STOP_RATIO`]) applies only where their histograms' rate
/// expects at least this many decodes over the brief time constant: with fewer, a gap between
/// decodes is chance, or the gap between two edges of a sparse texture (a count expected at 4
/// falls to half or less one time in four).
pub const BRIEF_MIN_DECODES: u64 = 16;

/// The slow units say nothing while their decodes over the last [`SHORT_TAU_US`] split in
/// sign more evenly than this many parts in ten (net agreement `|P - N| / (P + N)` below
/// `2 · SPLIT_STOP_TENTHS - 10` tenths: more evenly than 60 / 40), over the whole field: their
/// 100 ms histograms then remember a motion the view no longer shows. After a turn's zero
/// crossing over a smooth texture the sensor fires little but background activity for 120-180
/// ms (every pixel's brightness must first move back through the level it kept), whose decodes
/// take either sign, and the histograms answered the old sign, unflagged (value-noise rotation
/// seed 7: 10.5 % of its turning samples the wrong way, 1.2 % with this rule; dev01 11.6 →
/// 2.8 %). The paper's units' 10 ms histograms do not outlive the motion so (and they have
/// their brief stop); and under forward motion their field splits in sign as a whole, the two
/// halves moving opposite ways (asking it of them too, at 65 / 35, took the design scenes
/// 11.68 → 12.77 % RMSE / peak, against 11.49 % for the slow units alone). The same share of
/// the latest decodes above the principal row decides whether a new start may answer
/// (`Field::start_against`).
pub const SPLIT_STOP_TENTHS: u64 = 6;
/// [`SPLIT_STOP_TENTHS`] applies from this many decodes over the last [`SHORT_TAU_US`] (fewer
/// are the stop's business, [`STOPPED_RATIO`]).
pub const SPLIT_STOP_MIN_DECODES: u64 = 4;

/// The rule of [`SPLIT_STOP_TENTHS`], for the fixed-point field and the f64 oracle's: whether
/// fewer than [`SPLIT_STOP_TENTHS`] in ten of `all` decodes take a sign, `agreeing` of them
/// (clamped to `all`), where `all` reaches `min_all` (the units' count of
/// [`SPLIT_STOP_MIN_DECODES`]).
pub(crate) fn short_of_sign<T>(all: T, agreeing: T, min_all: T) -> bool
where
    T: Copy + PartialOrd + core::ops::Mul<Output = T> + From<u8>,
{
    let agreeing = if agreeing < all { agreeing } else { all };
    all >= min_all && T::from(10) * agreeing < T::from(SPLIT_STOP_TENTHS as u8) * all
}

/// Whether `all` decodes, `positive` of them positive (clamped to `all`), split in sign more
/// evenly than [`SPLIT_STOP_TENTHS`] in ten: the majority sign falls short
/// ([`short_of_sign`]), where `all` reaches `min_all`.
pub(crate) fn splits_in_sign<T>(all: T, positive: T, min_all: T) -> bool
where
    T: Copy + PartialOrd + core::ops::Sub<Output = T> + core::ops::Mul<Output = T> + From<u8>,
{
    let positive = if positive < all { positive } else { all };
    let negative = all - positive;
    let more = if positive < negative {
        negative
    } else {
        positive
    };
    short_of_sign(all, more, min_all)
}

/// Net sign agreement `(P - N)² / (P + N)` (in samples) that a region of decodes with random
/// signs exceeds about one time in 20 (it is about half a sample times a χ² variable with one
/// degree of freedom, whose 95th percentile is 3.84): only what a region shows beyond it
/// counts as agreement.
pub const RANDOM_AGREEMENT: u32 = 2;

/// When more than `1 / SPLIT_SHARE` of the weight behind the field's value says the other
/// direction, the field does not say which way the camera turns: no rotation evidence. (Just
/// after the camera reverses, edges pass pixels they have just passed the other way and the
/// units time their way back as well; in straight driving the two sides' translation leaves
/// opposite signs where mirrored columns see different depths.)
pub const SPLIT_SHARE: u32 = 4;

/// Regions and bands are weighed by `WEIGHT_SCALE / variance` (variance in Q32 rad²/s²),
/// at most [`MAX_WEIGHT`] (a standard deviation of 0.004 rad/s).
const WEIGHT_SCALE: u64 = 1 << 36;
/// See [`WEIGHT_SCALE`].
const MAX_WEIGHT: u64 = 1 << 20;

/// The weight of a column band's value (or of a pair's mean) with variance `var` (Q32) in the
/// field's weighted median: `WEIGHT_SCALE / var`, at least 1.
fn band_weight(var: u64) -> u64 {
    div_u64(WEIGHT_SCALE, var.max(1)).max(1)
}

/// Prior information on the slopes of a column's fit (weight x Y² in Q12): a slope of 2 rad/s
/// per unit of `Y` is one standard deviation.
const SLOPE_PRIOR: i64 = ((WEIGHT_SCALE >> 34) << 12) as i64;

/// Column band sides (of `2 x` [`COL_BANDS`]) with a value above the principal row that let
/// the field answer without one in the top row band, when at least [`ABOVE_SUPPORT`] row bands
/// above have values and every column band value has one sign (`wide_upper_motion`). People
/// walking past a static camera 2-3 m away moved up to 6 of the 8 at once (`--regime objects`
/// seeds 51 and 52), a car passing below the horizon none; a rotation
/// seen at half the usual texture contrast, whose top row band gets almost no decodes, 7-8.
pub const WIDE_UPPER_BAND_SIDES: usize = 7;

/// In `wide_upper_motion`, the outer half of the column bands must move at least this many
/// tenths of the inner half's mean rate: an object at one depth moving on its own reads about
/// 30 % slower in the outer bands of a DAVIS346's view, a rotation the same in all.
pub const WIDE_FALLOFF_TENTHS: i64 = 9;

/// Column bands one side needs, when the other side has a value in none, to answer alone
/// (`lone_side`): texture on one side only (a skyline with sky on one side, a wall beside a
/// drone).
pub const LONE_SIDE_BANDS: usize = 3;

/// Column band values agree as a rotation's when they lie within `1 / BAND_SPREAD` of their
/// mid-range of each other, one sign (`bands_agree`). A rotation gives every band the same
/// rate. What is odd in `X` (forward translation), where the mirrored side cannot cancel it,
/// shows as a trend across the bands (for scenery at one depth `Z`, the translation term
/// `X T_z / (Z (1 + X²))` grows about fivefold from the inner band to the outer one); so does an
/// object crossing the view at a speed of its own: its rate-equivalent falls as `1 / (1 + X²)`,
/// by about 30 % from the inner bands to the outer ones on a DAVIS346.
pub const BAND_SPREAD: i64 = 5;

/// A column band's fit uses the rows above the principal row alone when its intercept from
/// them and its intercept from the rows below differ by more than this many standard
/// deviations of their difference (module documentation, "The estimator").
pub const HALVES_DISAGREE_SIGMAS: u64 = 3;

/// A column band's fit also uses the rows above the principal row alone when its intercept
/// from the rows below is more than this many times as fast as the one from the rows above,
/// however uncertain the two: a rotation gives both halves one rate, and what reads faster
/// below is the ground close under a moving camera or something moving near it on its own (a
/// person crossing 2.7 m in front of a hovering drone, whose image moves 13 times as fast as
/// the turn: the few decodes above the principal row left the difference within three
/// standard deviations, and the person's many below made the band read the person; module
/// documentation, "The estimator").
pub const HALVES_FASTER_BELOW: u64 = 2;

/// Weight of a sample when the histograms were last renormalised (Q16 = one sample).
const UNIT_WEIGHT: u32 = 1 << 16;

/// What a region's decodes of the two signs (`neg`, `pos`, in units of which one sample is
/// `sample`; both below 2^40) agree in sign beyond random signs: `(P - N)² / (P + N)` less
/// [`RANDOM_AGREEMENT`] samples, at least 0; 0 for an empty region. The rule by which a
/// population (or a stride, [`super::stride_choice`]) answers.
///
/// Most regions need no division (82 % of the calls on dev03's F405 window, where the 64-bit
/// division was the one hot library call of a field reading): a region of one sign gives
/// `d · 1`, and one with `d² <= random · t` gives 0, since `d · (d / t)` rounded down is at
/// most `d² / t` (the same values as the division: `sign_agreement_shortcuts_are_exact`).
#[inline]
pub fn sign_agreement(neg: u64, pos: u64, sample: u64) -> u64 {
    let (d, t) = (neg.abs_diff(pos), neg + pos);
    let random = u64::from(RANDOM_AGREEMENT) * sample;
    if d == t {
        // One sign (or none): d / t is one.
        return d.saturating_sub(random);
    }
    // In 32 x 32-bit products (the common case; larger masses take the division).
    if let (Ok(d), Ok(t), Ok(random)) = (u32::try_from(d), u32::try_from(t), u32::try_from(random))
    {
        if u64::from(d) * u64::from(d) <= u64::from(random) * u64::from(t) {
            return 0;
        }
    }
    agreement_by_division(d, t, random)
}

/// `d · (d / t)` less `random`, at least 0, with `d / t` in Q16 (`d <= t`); 0 for `t = 0`.
fn agreement_by_division(d: u64, t: u64, random: u64) -> u64 {
    (d << 16)
        .checked_div(t)
        .map_or(0, |share| ((d * share) >> 16).saturating_sub(random))
}

/// Settings of the field estimator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FieldSettings {
    /// Decoded bursts (leaky, Q16) a region needs before it has a value.
    pub min_samples_q16: u32,
    /// Smallest interquartile range a region is credited with (Q16 rad/s).
    pub spread_floor_q16: u32,
    /// Distinct column bands that must hold a mirrored pair before the field reports a
    /// rotation (capped by the bands the layout covers on both sides).
    pub support: u8,
}

impl FieldSettings {
    /// The product's settings: 4 samples per region, a spread floor of 0.02 rad/s, support in
    /// 2 column bands.
    pub const DEFAULT: Self = Self {
        min_samples_q16: 4 << 16,
        spread_floor_q16: 1_311,
        support: 2,
    };
}

/// Where the regions lie: the principal point and the band edges, in Q16 pixels. Built once;
/// placing a pixel takes comparisons only (no division on the per-event path).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FieldGeometry {
    /// Principal point (Q16 px).
    cx_q16: i64,
    /// Principal point row (Q16 px).
    cy_q16: i64,
    /// Inner edges of column bands 1.. (distance from `c_x`, Q16 px, increasing).
    col_edges: [u64; COL_BANDS - 1],
    /// Inner edges of row bands 1.. (distance from `c_y`, Q16 px, increasing), above and
    /// below the principal row.
    row_edges: [[u32; ROW_BANDS - 1]; 2],
    /// `|Y|` at the centre of each row band, Q12 (at most 2), above and below.
    row_centres_q12: [[i32; ROW_BANDS]; 2],
}

impl FieldGeometry {
    /// Bands that split the span `[x_min, x_max] x [y_min, y_max]` (pixels with units) either
    /// side of the principal point `(cx, cy)`, for a focal length `focal_q16` (all Q16 px):
    /// column bands mirrored about `c_x` (a [`COL_BANDS`]th of the longer half each, so that
    /// mirrored bands see mirrored flow), row bands a [`ROW_BANDS`]th of the rows on their own
    /// side of `c_y` each (so that the top band above the principal row is a full band
    /// wherever the principal point lies); every band at least 1 px.
    pub fn spanning(
        cx_q16: i64,
        cy_q16: i64,
        focal_q16: i64,
        x: (u16, u16),
        y: (u16, u16),
    ) -> Self {
        // The span's extent before and after the centre `c` (Q16 px).
        let halves = |c: i64, (lo, hi): (u16, u16)| -> [i64; 2] {
            let lo = i64::from(lo) << 16;
            let hi = (i64::from(hi) + 1) << 16;
            [c - lo, hi - c]
        };
        let [left, right] = halves(cx_q16, x);
        let col_w = (left.max(right) / COL_BANDS as i64).max(1 << 16);
        let row_h = halves(cy_q16, y).map(|h| (h / ROW_BANDS as i64).max(1 << 16));
        let focal = focal_q16.max(1 << 16);
        let mut col_edges = [0u64; COL_BANDS - 1];
        for (k, e) in col_edges.iter_mut().enumerate() {
            *e = (k as u64 + 1) * col_w.unsigned_abs();
        }
        // In 32-bit words: both halves' edges and centres take the room one set of 64-bit
        // words took (the field's size, and with it the code's layout, is unchanged).
        let row_edges = row_h.map(|h| {
            core::array::from_fn(|k| {
                u32::try_from((k as u64 + 1) * h.unsigned_abs()).unwrap_or(u32::MAX)
            })
        });
        let row_centres_q12 = row_h.map(|h| {
            core::array::from_fn(|k| {
                let dy = (2 * k as i64 + 1) * h / 2; // Q16 px
                ((dy << 12) / focal).clamp(0, 2 << 12) as i32
            })
        });
        Self {
            cx_q16,
            cy_q16,
            col_edges,
            row_edges,
            row_centres_q12,
        }
    }

    /// Normalised row `|Y| = |y - c_y| / f` at the centre of row band `row` above (`vside`
    /// 0) or below (1) the principal row, in Q12 (the half above uses its negative), at
    /// most 2.
    pub fn row_centre_abs_q12(&self, vside: usize, row: usize) -> i64 {
        self.row_centres_q12
            .get(vside)
            .and_then(|c| c.get(row))
            .map_or(0, |&c| i64::from(c))
    }

    /// `(side, band)` of column `x`: side 1 at or right of the principal point.
    #[inline]
    pub fn column(&self, x: u16) -> (usize, usize) {
        let dx = (i64::from(x) << 16) + (1 << 15) - self.cx_q16;
        let band = self
            .col_edges
            .iter()
            .filter(|&&e| dx.unsigned_abs() >= e)
            .count();
        (usize::from(dx >= 0), band)
    }

    /// `(vside, row band)` of row `y`: vside 1 at or below the principal point.
    #[inline]
    pub fn row(&self, y: u16) -> (usize, usize) {
        let dy = (i64::from(y) << 16) + (1 << 15) - self.cy_q16;
        let [above, below] = &self.row_edges;
        let edges = if dy >= 0 { below } else { above };
        let row = edges
            .iter()
            .filter(|&&e| dy.unsigned_abs() >= u64::from(e))
            .count();
        (usize::from(dy >= 0), row)
    }

    /// Region of pixel `(x, y)`: index `((side · COL_BANDS + band) · 2 + vside) · ROW_BANDS + row`.
    #[inline]
    pub fn region(&self, x: u16, y: u16) -> usize {
        let (side, band) = self.column(x);
        let (vside, row) = self.row(y);
        region_index(side, band, vside, row)
    }
}

/// Index of region (side, band, vside, row).
#[inline]
const fn region_index(side: usize, band: usize, vside: usize, row: usize) -> usize {
    ((side * COL_BANDS + band) * 2 + vside) * ROW_BANDS + row
}

/// Whether region `region` lies above the principal row (vertical side 0).
#[inline]
const fn is_above(region: usize) -> bool {
    (region / ROW_BANDS).is_multiple_of(2)
}

/// A region's signed median rate (Q16 rad/s) and the variance of that median (Q32, from the
/// interquartile range over the number of samples: the aperture problem makes decoded rates
/// spread where edges also move vertically, Cauchy-like around the true horizontal flow).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct RegionStats {
    median: i64,
    variance: u64,
}

/// What the field says at one output time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldEstimate {
    /// A rotation (rad/s, Q16, positive = turning right).
    Rotation(i32),
    /// No rotation evidence spread over the field: too few column bands carry one, or its
    /// weight is split in direction (see [`SPLIT_SHARE`]), or no region has a value, or the
    /// decodes have all but stopped. The rate is unknown, not zero.
    NoEvidence,
}

/// Readings (of [`crate::readout::shared::REFRESH_US`] each) after the last answer within
/// which it is fresh ([`RecentAnswer::fresh`]): 24 ms at 1 kHz. Within them the field reads
/// band values the same way as that answer without the rows above the principal row (faint
/// upper scenery drops out for a reading or two: rotation seed 73 at half contrast 34.6 →
/// 31.5 % of peak); later, only the other way (a reversal) or at that answer's rate
/// ([`RecentAnswer::continued_by`]): a turn that faded for longer may have stopped, and people
/// walking on past the drone move the same way (hover seed 501 with three people 36.4 → 17.8
/// %; 23.5 % at 100 ms, 16.2 % with none).
pub const FRESH_READINGS: u8 = 6;

/// The readout's last answer on the field's own evidence, when it came a moment ago
/// ([`crate::readout::shared::AnswerAge::last_answer`]; [`Field::set_recent_motion`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RecentAnswer {
    /// Its rate (Q16 rad/s, not 0).
    pub rate_q16: i32,
    /// Readings since (0: the last reading; at most
    /// [`crate::readout::shared::RECENT_READINGS`]).
    pub readings: u8,
}

impl RecentAnswer {
    /// Whether it was negative (turning left).
    pub fn negative(&self) -> bool {
        self.rate_q16 < 0
    }

    /// Whether the readout has paused since: it does not answer now.
    pub fn paused(&self) -> bool {
        self.readings > 0
    }

    /// Whether the readout has paused since for at most [`FRESH_READINGS`] readings.
    pub fn fresh(&self) -> bool {
        self.paused() && self.readings <= FRESH_READINGS
    }

    /// Whether `estimate` continues it: a rotation within `1 / BAND_SPREAD` of its rate (the
    /// spread a rotation's band values keep, [`BAND_SPREAD`]).
    pub fn continued_by(&self, estimate: FieldEstimate) -> bool {
        let rate = i64::from(self.rate_q16);
        matches!(estimate, FieldEstimate::Rotation(v)
            if (i64::from(v) - rate).saturating_abs().saturating_mul(BAND_SPREAD) <= rate.abs())
    }
}

/// What the field shows ([`Field::reading`]) and whether it needed the readout's answer a
/// moment ago to show it ([`Field::set_recent_motion`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FieldReading {
    /// The estimate.
    pub estimate: FieldEstimate,
    /// A rotation that the field shows only because the readout answered a moment ago: the
    /// readout's answer then does not count as a recent one
    /// ([`crate::readout::shared::AnswerAge`]), so that what it lets through cannot keep
    /// letting itself through.
    pub recent_needed: bool,
    /// No evidence because the answering population's decodes stopped (`STOPPED_RATIO`,
    /// [`BRIEF_STOP_RATIO`]): the motion stopped or changed, so the next answer is a new
    /// start, not the end of a brief gap ([`crate::readout::shared::Confirmation`]).
    pub stopped: bool,
    /// No evidence because the slow units' decodes of the last [`SHORT_TAU_US`] split in sign
    /// ([`SPLIT_STOP_TENTHS`]): the view shows nothing of a motion that may go on (the blind
    /// stretch after a zero crossing), so the answer a moment ago stays recent
    /// ([`crate::readout::shared::BLIND_HOLD_READINGS`]).
    pub blind: bool,
}

impl FieldReading {
    /// No rotation evidence.
    const NOTHING: Self = Self::own(FieldEstimate::NoEvidence);

    /// No rotation evidence: the decodes stopped.
    const STOPPED: Self = Self {
        stopped: true,
        ..Self::NOTHING
    };

    /// An estimate the field makes on its own evidence.
    const fn own(estimate: FieldEstimate) -> Self {
        Self {
            estimate,
            recent_needed: false,
            stopped: false,
            blind: false,
        }
    }
}

/// One population's decodes by sign and place: `[positive, above the principal row, positive
/// above the principal row]` (all of them are [`Field`]'s `recent` / `short`).
type SignCounts = [u32; SIGN_COUNTS];

/// Entries of [`SignCounts`].
const SIGN_COUNTS: usize = 3;

/// Which units a decoded rate came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Population {
    /// The paper's units (`tau_F` = 20 ms).
    Fast = 0,
    /// The slow units (`tau_F` = [`crate::params::TAU_SLOW_US`]).
    Slow = 1,
}

/// The leaky per-region histograms, one set per [`Population`], and the estimator (48 KiB of
/// bins).
pub struct Field {
    geometry: FieldGeometry,
    settings: FieldSettings,
    /// Tests only: [`SETTLED_SAMPLES_Q16`], or more to compare with the signed median alone.
    /// (Not a field of the product's build: one more word in this struct costs the F405
    /// window 8 instructions per event in QEMU, from how the compiler then lays out and
    /// inlines the per-event path.)
    #[cfg(test)]
    settled_q16: u32,
    /// `[population][region][sign][bin]`, sign 0 = negative, 1 = positive.
    hist: [[[[u32; BINS]; 2]; REGIONS]; 2],
    /// Current weight of one sample per population (Q16; in `[1, 2)` samples after
    /// renormalisation).
    weight: [u32; 2],
    /// Per-period weight growth `e^(period / tau)` per population, in Q1.31 of half its value
    /// (so that values up to 4 fit).
    grow_half_q31: [u32; 2],
    /// Histogram time constant per population (µs).
    tau_us: [u32; 2],
    /// Decodes per population since the last output.
    recent: [u32; 2],
    /// Sum of each population's bins per region and sign (kept with the bins, so that no
    /// output has to add them all up).
    mass: [[[u64; 2]; REGIONS]; 2],
    /// Which bins of each histogram may hold weight (bit `i`: bin `i`), `[population][region]
    /// [sign]`. Invariant: a bin whose bit is clear is 0. The halving in [`Field::age`] visits
    /// only these bins: a region's decodes fill a few octaves of the 64 bins, and the halving,
    /// every `tau ln 2`, was the field's largest cost on a Cortex-M.
    occupied: [[[u64; 2]; REGIONS]; 2],
    /// Per region and sign: decodes of the paper's units within an octave above their floor at
    /// onsets the slow units decode too (the sign of the slow units' decode), in the paper's
    /// units' population's weight (halved with it). See [`Field::add_beyond_floor`].
    beyond_floor: [[u64; 2]; REGIONS],
    /// Per region: the histogram bin of the paper's units' floor (as last reported).
    floor_bin: [u8; REGIONS],
    /// Decodes per population, leaky over [`SHORT_TAU_US`] (Q16 samples).
    short: [u32; 2],
    /// Decodes per population since the last output by sign and place ([`SignCounts`]), and
    /// leaky as `short` (Q16 samples): for the slow units' split stop
    /// ([`Field::slow_split_lately`]) and a new start ([`Field::start_against`]).
    recent_signs: [SignCounts; 2],
    short_signs: [SignCounts; 2],
    /// Per-period decay of `short` (Q1.31).
    short_keep_q31: u32,
    /// The paper's units' decodes, leaky over `brief_tau_us` (Q16 samples).
    brief: u32,
    /// Per-period decay of `brief` (Q1.31).
    brief_keep_q31: u32,
    /// [`BRIEF_TAU_TENTHS`] of the paper's units' `tau_A` (µs, >= 1).
    brief_tau_us: u32,
    /// The bands the layout's units reach.
    coverage: Coverage,
    /// The population that answers is the one whose decodes agree more in sign (else the one
    /// that decodes more): see [`Field::choose_by_decode_rate`].
    by_agreement: bool,
    /// The readout has answered one direction for a while: see
    /// [`Field::set_direction_established`].
    established: bool,
    /// The readout answered a moment ago: see [`Field::set_recent_motion`].
    recent_motion: Option<RecentAnswer>,
}

impl Field {
    /// An empty field whose histograms have time constant `tau_us` per population (µs), aged
    /// by `period_us` per output; `coverage` the bands the layout's units reach.
    pub fn new(
        geometry: FieldGeometry,
        settings: FieldSettings,
        tau_us: [u32; 2],
        period_us: u32,
        coverage: Coverage,
    ) -> Self {
        let keep = |tau: u32| ExpDecay::new(tau).decay_bits(period_us);
        let keep_q31 = tau_us.map(keep);
        // grow = 1/keep; stored halved in Q1.31: 2^62 / keep / 2.
        let grow = |k: u32| ((1u64 << 61) / u64::from(k.max(1))).min(u64::from(u32::MAX)) as u32;
        let [fast, slow] = keep_q31;
        let [fast_tau, _] = tau_us;
        let brief_tau_us = (fast_tau / 10 * BRIEF_TAU_TENTHS).max(1);
        Self {
            geometry,
            settings,
            #[cfg(test)]
            settled_q16: SETTLED_SAMPLES_Q16,
            hist: [[[[0; BINS]; 2]; REGIONS]; 2],
            weight: [UNIT_WEIGHT; 2],
            grow_half_q31: [grow(fast), grow(slow)],
            tau_us,
            recent: [0; 2],
            mass: [[[0; 2]; REGIONS]; 2],
            occupied: [[[0; 2]; REGIONS]; 2],
            beyond_floor: [[0; 2]; REGIONS],
            floor_bin: [0; REGIONS],
            short: [0; 2],
            recent_signs: [[0; SIGN_COUNTS]; 2],
            short_signs: [[0; SIGN_COUNTS]; 2],
            short_keep_q31: keep(SHORT_TAU_US),
            brief: 0,
            brief_keep_q31: keep(brief_tau_us),
            brief_tau_us,
            coverage,
            by_agreement: true,
            established: false,
            recent_motion: None,
        }
    }

    /// Whether the readout has answered one direction for
    /// [`ESTABLISHED_READINGS`](super::shared::ESTABLISHED_READINGS) readings in
    /// a row (its output gate says so before each reading). While it has, every region with a
    /// value whose decodes agree in sign reads its majority's median, however few its decodes:
    /// the motion's direction is known, and the other sign's decodes are timing errors. (A
    /// region of the paper's units holds ~15 decodes over its 10 ms on a smooth texture, under
    /// [`SETTLED_SAMPLES_Q16`], and a fifth to a quarter of them take the other sign there,
    /// where TRG pixels fire before their FAC neighbours: its signed median read 0.65-0.83 of
    /// the turn on dev01.) Before, the settled count holds, as where motion has just started.
    pub fn set_direction_established(&mut self, established: bool) {
        self.established = established;
    }

    /// Tells the field the readout's answer a moment ago
    /// ([`crate::readout::shared::AnswerAge::last_answer`]); `None` otherwise. Once the
    /// readout has paused ([`RecentAnswer::paused`]), the rows above the principal row need
    /// not move as a rotation's where all band values have the other sign (a reversal: a pixel
    /// fires again only once its brightness has moved back through the level it kept, and the
    /// top row band's regions fill last), or one sign while the answer is fresh
    /// ([`RecentAnswer::fresh`]); nor need the column bands be spread as a rotation's beyond a
    /// value on each side, all of one sign. And band values spread as a rotation's, the same
    /// way, with values in [`ABOVE_SUPPORT`] row bands above the principal row, answer without
    /// the top one or the width when their estimate continues that answer's rate
    /// ([`RecentAnswer::continued_by`]): a turn whose texture leaves the top row band.
    pub fn set_recent_motion(&mut self, recent: Option<RecentAnswer>) {
        self.recent_motion = recent;
    }

    /// Chooses the population that answers by its decode rate instead of its decodes' sign
    /// agreement: for layouts whose units have no twin facing the other way at their pixel
    /// (the paper's boxes). A twin lets the stronger of the two units decode and the pattern's
    /// aliases (an edge timed against the edge after next) mostly lose; without one, a unit
    /// facing against the motion decodes them, and its population's decodes split in sign at
    /// any speed.
    pub fn choose_by_decode_rate(&mut self) {
        self.by_agreement = false;
    }

    /// The geometry.
    pub fn geometry(&self) -> &FieldGeometry {
        &self.geometry
    }

    /// Adds one decoded burst of population `pop` at pixel `(x, y)`: `log2 |r|` (Q16.16) and
    /// the sign of `r`.
    #[inline]
    pub fn add(&mut self, pop: Population, x: u16, y: u16, log2_rate: i32, positive: bool) {
        self.add_in(pop, self.geometry.region(x, y), log2_rate, positive);
    }

    /// [`Field::add`] for a pixel in region `region` ([`FieldGeometry::region`]; ignored if out
    /// of range).
    #[inline]
    pub fn add_in(&mut self, pop: Population, region: usize, log2_rate: i32, positive: bool) {
        let bin = bin_of(log2_rate);
        let w = self
            .weight
            .get(pop as usize)
            .copied()
            .unwrap_or(UNIT_WEIGHT);
        if let Some(b) = self
            .hist
            .get_mut(pop as usize)
            .and_then(|h| h.get_mut(region))
            .and_then(|h| h.get_mut(usize::from(positive)))
            .and_then(|h| h.get_mut(bin))
        {
            let before = *b;
            *b = b.saturating_add(w);
            if let Some(o) = self
                .occupied
                .get_mut(pop as usize)
                .and_then(|o| o.get_mut(region))
                .and_then(|o| o.get_mut(usize::from(positive)))
            {
                *o |= 1 << bin;
            }
            if let Some(m) = self
                .mass
                .get_mut(pop as usize)
                .and_then(|m| m.get_mut(region))
                .and_then(|m| m.get_mut(usize::from(positive)))
            {
                *m += u64::from(*b - before);
            }
        }
        if let Some(c) = self.recent.get_mut(pop as usize) {
            *c = c.saturating_add(1);
        }
        if let Some([pos, above, above_pos]) = self.recent_signs.get_mut(pop as usize) {
            let above_now = is_above(region);
            *pos = pos.saturating_add(u32::from(positive));
            *above = above.saturating_add(u32::from(above_now));
            *above_pos = above_pos.saturating_add(u32::from(above_now && positive));
        }
    }

    /// Counts a decode of the paper's units that lies within an octave above their floor
    /// (`floor_log2_rate`, Q16.16: the slowest rotation they time at the pixel, at the stride
    /// decoded) at an onset the slow units decode too, with the sign of the slow units' decode
    /// (region `region`; ignored if out of range). The slow units' decodes go to their
    /// histograms only where the paper's units do not burst, so those histograms end at the
    /// floor; what lies beyond it is counted here, for the slow units' region values (see the
    /// module documentation).
    pub fn add_beyond_floor(&mut self, region: usize, positive: bool, floor_log2_rate: i32) {
        if let Some(b) = self.floor_bin.get_mut(region) {
            *b = bin_of(floor_log2_rate) as u8;
        }
        let w = self.weight.first().copied().unwrap_or(UNIT_WEIGHT);
        if let Some(m) = self
            .beyond_floor
            .get_mut(region)
            .and_then(|m| m.get_mut(usize::from(positive)))
        {
            *m += u64::from(w);
        }
    }

    /// Ends one output period: ages everything seen so far by one period.
    pub fn age(&mut self) {
        let leak = |sum: u32, keep_q31: u32, added: u32| {
            ((u64::from(sum) * u64::from(keep_q31)) >> 31)
                .saturating_add(u64::from(added) << 16)
                .min(u64::from(u32::MAX)) as u32
        };
        let [fast, _] = self.recent;
        self.brief = leak(self.brief, self.brief_keep_q31, fast);
        for (short, recent) in self.short.iter_mut().zip(self.recent.iter_mut()) {
            *short = leak(*short, self.short_keep_q31, *recent);
            *recent = 0;
        }
        for (short, recent) in self
            .short_signs
            .iter_mut()
            .flatten()
            .zip(self.recent_signs.iter_mut().flatten())
        {
            *short = leak(*short, self.short_keep_q31, *recent);
            *recent = 0;
        }
        let mut shifts = [0u32; 2];
        for (((((weight, grow), hist), mass), occupied), halved) in self
            .weight
            .iter_mut()
            .zip(self.grow_half_q31.iter())
            .zip(self.hist.iter_mut())
            .zip(self.mass.iter_mut())
            .zip(self.occupied.iter_mut())
            .zip(shifts.iter_mut())
        {
            let mut w = (u64::from(*weight) * u64::from(*grow)) >> 30;
            // Halve as often as needed (more than once when the period exceeds tau ln 2).
            let mut shift = 0u32;
            while w >= u64::from(2 * UNIT_WEIGHT) && shift < 32 {
                w >>= 1;
                shift += 1;
            }
            if shift > 0 {
                for ((region, m), o) in hist.iter_mut().zip(mass.iter_mut()).zip(occupied) {
                    for ((bins, m), o) in region.iter_mut().zip(m.iter_mut()).zip(o) {
                        *m = shift_bins(bins, o, shift);
                    }
                }
            }
            *halved = shift;
            *weight = w.clamp(1, u64::from(2 * UNIT_WEIGHT)) as u32;
        }
        // Counted in the paper's units' weight: halved with it.
        let [fast_shift, _] = shifts;
        if fast_shift > 0 {
            for m in self.beyond_floor.iter_mut().flatten() {
                *m = m.checked_shr(fast_shift).unwrap_or(0);
            }
        }
    }

    /// What a region's slow units' histograms (`[neg, pos]`) leave out beyond the paper's
    /// units' floor, once the direction is established ([`Field::set_direction_established`]):
    /// per sign the decodes of [`Field::add_beyond_floor`], as many as the slow units would
    /// have decoded over their own time constant (`× tau_slow / tau_fast`), at most the slow
    /// units' own decodes in the octave below the floor, all in the floor's bin. Nothing for
    /// the paper's units, or before the direction is established (an onset's first decodes of
    /// the paper's units time the pixels waking up, not edges).
    ///
    /// The cap: a distribution that goes on past the floor has about as much mass just above
    /// it as just below; where the slow units' decodes thin out before the floor, the paper's
    /// units' decodes near it are aliases or wake-ups, not the slow units' tail.
    fn beyond_floor_mass(
        &self,
        pop: Population,
        region: usize,
        [neg, pos]: [&[u32; BINS]; 2],
    ) -> BeyondFloor {
        let none = BeyondFloor::default();
        if pop != Population::Slow || !self.established {
            return none;
        }
        let (Some(&[n, p]), Some(&bin)) =
            (self.beyond_floor.get(region), self.floor_bin.get(region))
        else {
            return none;
        };
        if n == 0 && p == 0 {
            return none;
        }
        let bin = usize::from(bin);
        let [w_fast, w_slow] = self.weight.map(|w| u64::from(w.max(1)));
        let [tau_fast, tau_slow] = [Population::Fast, Population::Slow].map(|p| self.tau_us(p));
        // Weights below 2^17 and time constants below 2^32: both products fit.
        let (num, den) = (w_slow * tau_slow, w_fast * tau_fast);
        let below = |h: &[u32; BINS]| -> u64 {
            h.get(bin.saturating_sub(OCTAVE_BINS)..bin)
                .map_or(0, |b| b.iter().map(|&m| u64::from(m)).sum())
        };
        // `m · num / den` exactly; in 64 bits whenever it fits (a 128-bit division costs a
        // Cortex-M a library call per region and reading).
        let scaled = |m: u64, h: &[u32; BINS]| -> u64 {
            let m = match m.checked_mul(num) {
                Some(p) => div_u64(p, den),
                None => (u128::from(m) * u128::from(num))
                    .checked_div(u128::from(den))
                    .map_or(u64::MAX, |q| u64::try_from(q).unwrap_or(u64::MAX)),
            };
            m.min(below(h))
        };
        BeyondFloor {
            bin,
            mass: [scaled(n, neg), scaled(p, pos)],
        }
    }

    /// One population's statistics in a region, or `None` with fewer than `min_samples`.
    fn population_value(&self, pop: Population, region: usize) -> Option<RegionStats> {
        let [neg, pos] = self.hist.get(pop as usize)?.get(region)?;
        let mut masses = *self.mass.get(pop as usize)?.get(region)?;
        let mut occupied = *self.occupied.get(pop as usize)?.get(region)?;
        let beyond = self.beyond_floor_mass(pop, region, [neg, pos]);
        if !beyond.is_empty() {
            for o in occupied.iter_mut() {
                *o |= 1 << beyond.bin;
            }
        }
        // With a count beyond the floor, a copy of the histograms with it in the floor's bin
        // (the walks below stay as they are for every other region).
        let with_beyond;
        let [neg, pos] = if beyond.is_empty() {
            [neg, pos]
        } else {
            let mut h = [*neg, *pos];
            for ((bins, m), extra) in h.iter_mut().zip(masses.iter_mut()).zip(beyond.mass) {
                if let Some(b) = bins.get_mut(beyond.bin) {
                    let before = *b;
                    *b = b.saturating_add(u32::try_from(extra).unwrap_or(u32::MAX));
                    *m += u64::from(*b - before);
                }
            }
            with_beyond = h;
            let [n, p] = &with_beyond;
            [n, p]
        };
        let total: u64 = masses.iter().sum();
        let weight = u64::from(
            self.weight
                .get(pop as usize)
                .copied()
                .unwrap_or(UNIT_WEIGHT),
        );
        let samples_q16 = div_u64(total << 16, weight.max(1));
        if total == 0 || samples_q16 < u64::from(self.settings.min_samples_q16) {
            return None;
        }
        // Quartiles of the signed rate: walk the negative bins from the largest |r| down, then
        // the positive bins up.
        let targets = [total / 4, total / 2, total - total / 4];
        let mut out = [0i64; 3];
        let mut found = 0usize;
        let mut acc = 0u64;
        let [occupied_neg, occupied_pos] = occupied;
        let signed_bins = marked_bins(occupied_neg, true)
            .map(|i| (i, neg, false))
            .chain(marked_bins(occupied_pos, false).map(|i| (i, pos, true)));
        for (i, bins, positive) in signed_bins {
            let m = u64::from(bins.get(i).copied().unwrap_or(0));
            while found < 3 && m > 0 && acc + m >= targets.get(found).copied().unwrap_or(0) {
                let need = targets.get(found).copied().unwrap_or(0).saturating_sub(acc);
                // The walk goes along increasing signed rate: up the positive bins, down the
                // negative ones.
                let v = bin_rate_q16(i, need, m, positive);
                if let Some(o) = out.get_mut(found) {
                    *o = if positive { v } else { -v };
                }
                found += 1;
            }
            acc += m;
            if found == 3 {
                break;
            }
        }
        let [q1, signed_median, q3] = out;
        #[cfg(test)]
        let settled_q16 = self.settled_q16;
        #[cfg(not(test))]
        let settled_q16 = SETTLED_SAMPLES_Q16;
        let median = if self.established || samples_q16 >= u64::from(settled_q16) {
            majority_median([neg, pos], occupied, masses, [q1, signed_median, q3])
                .unwrap_or(signed_median)
        } else {
            signed_median
        };
        let samples = (samples_q16 >> 16).max(1);
        let iqr = (q3 - q1)
            .unsigned_abs()
            .max(u64::from(self.settings.spread_floor_q16));
        Some(RegionStats {
            median,
            variance: split_variance(div_u64(iqr.saturating_mul(iqr), samples), masses),
        })
    }

    /// The estimate from everything seen so far, from the population whose decodes agree more
    /// in sign per second (see the module documentation): the paper's units where edges move
    /// fast, the slow units in a slow scene.
    pub fn estimate(&self) -> FieldEstimate {
        self.reading().estimate
    }

    /// [`Field::estimate`], and whether it needed the readout's answer a moment ago to show a
    /// rotation ([`Field::set_recent_motion`]).
    pub fn reading(&self) -> FieldReading {
        let by = |pop| {
            if self.by_agreement {
                self.consistent_samples_q16(pop)
            } else {
                self.samples_q16(pop)
            }
        };
        let tau = |pop| u128::from(self.tau_us(pop));
        // Per µs of each population's time constant, compared without rounding:
        // `fast / tau_fast >= slow / tau_slow` as `fast · tau_slow >= slow · tau_fast`.
        let fast = u128::from(by(Population::Fast)) * tau(Population::Slow);
        let slow =
            u128::from(self.filled(Population::Slow, by(Population::Slow))) * tau(Population::Fast);
        let pop = if fast >= slow {
            Population::Fast
        } else {
            Population::Slow
        };
        // When the decodes have all but stopped (the camera stopped turning), the histograms
        // still remember the motion for a few time constants: say nothing rather than repeat it.
        let short = self.short.get(pop as usize).copied().unwrap_or(0);
        let short_rate = u64::from(short) / u64::from(SHORT_TAU_US);
        let rate = self.rate(pop);
        if short_rate.saturating_mul(STOPPED_RATIO) < rate {
            return FieldReading::STOPPED;
        }
        if pop == Population::Slow && self.slow_split_lately() {
            return FieldReading {
                blind: true,
                ..FieldReading::NOTHING
            };
        }
        if pop == Population::Fast && self.stopped_at_once(rate) {
            return FieldReading::STOPPED;
        }
        let reading = self.population_estimate(pop);
        if let FieldEstimate::Rotation(v) = reading.estimate {
            if self.recent_motion.is_none() && self.start_against(pop, v < 0) {
                return FieldReading::NOTHING;
            }
        }
        let estimate = match (reading.estimate, pop) {
            // The slow units' histograms remember 100 ms, more than it takes a turn to slow
            // down through them: once their decodes thin out below 4/5 of the histograms'
            // rate, the rate they show shrinks in proportion (the decode rate follows the image
            // speed within SHORT_TAU_US; above 4/5 it may be the 20 ms rate's scatter).
            (FieldEstimate::Rotation(v), Population::Slow) if 5 * short_rate < 4 * rate => {
                // |v| < 2^31 and 5 short_rate < 4 rate, so the scaled value fits.
                let scaled = div_u64(
                    u64::from(v.unsigned_abs()) * 5 * short_rate,
                    (4 * rate).max(1),
                ) as i32;
                FieldEstimate::Rotation(if v < 0 { -scaled } else { scaled })
            }
            (est, _) => est,
        };
        FieldReading {
            estimate,
            ..reading
        }
    }

    /// Whether a new start of sign `negative` from `pop` lacks the support of its latest decodes
    /// above the principal row: fewer than [`SPLIT_STOP_TENTHS`] in ten of them, where there are
    /// [`SPLIT_STOP_MIN_DECODES`] or more over the last [`SHORT_TAU_US`], take that sign. A new
    /// start is one the readout did not answer within the last
    /// [`RECENT_READINGS`](crate::readout::shared::RECENT_READINGS) readings
    /// ([`Field::set_recent_motion`]); it then says "no evidence". When a hovering drone starts
    /// to turn after a pause, each pixel's first onset comes when its brightness has moved a
    /// contrast step from the level it kept through the pause, a random part of an edge's
    /// crossing late: the first decodes take either sign about evenly in every region, and a
    /// region's median of them has a random sign (hover seed 41, spike readout: 43 / 38
    /// decodes over the 20 ms before it answered +0.35 rad/s of a -0.11 rad/s turn). The rows
    /// above the principal row alone: people walking past below the horizon decode their own
    /// way while the camera turns (hover seed 631 with two people: the whole field's decodes
    /// 55-60 % with the turn, those above it 95 %).
    fn start_against(&self, pop: Population, negative: bool) -> bool {
        let Some(&[_, all, positive]) = self.short_signs.get(pop as usize) else {
            return false;
        };
        let (all, positive) = (u64::from(all), u64::from(positive));
        let agreeing = if negative {
            all.saturating_sub(positive)
        } else {
            positive
        };
        short_of_sign(all, agreeing, SPLIT_STOP_MIN_DECODES << 16)
    }

    /// Whether the slow units' decodes over the last [`SHORT_TAU_US`],
    /// [`SPLIT_STOP_MIN_DECODES`] or more, split in sign more evenly than
    /// [`SPLIT_STOP_TENTHS`] in ten.
    fn slow_split_lately(&self) -> bool {
        let slow = Population::Slow as usize;
        let (Some(&all), Some(&[positive, ..])) =
            (self.short.get(slow), self.short_signs.get(slow))
        else {
            return false;
        };
        splits_in_sign(
            u64::from(all),
            u64::from(positive),
            SPLIT_STOP_MIN_DECODES << 16,
        )
    }

    /// Whether the paper's units' decodes, at `rate` (Q16 samples per µs) over their
    /// histograms, stopped at once: over the brief time constant they come at less than
    /// `1 / `[`BRIEF_STOP_RATIO`] of it, where it expects [`BRIEF_MIN_DECODES`] or more.
    fn stopped_at_once(&self, rate: u64) -> bool {
        let tau = u64::from(self.brief_tau_us);
        let brief_rate = u64::from(self.brief).checked_div(tau).unwrap_or(0);
        rate.saturating_mul(tau) >= BRIEF_MIN_DECODES << 16
            && brief_rate.saturating_mul(BRIEF_STOP_RATIO) < rate
    }

    /// `score` of a population scaled by how much its decode rate over the last
    /// [`SHORT_TAU_US`] exceeds its histograms' average (at most their time constant over
    /// `SHORT_TAU_US`): histograms that are still filling. The ratio is taken of the samples
    /// themselves (`short · tau / (SHORT_TAU_US · samples)`), not of the rounded rates.
    fn filled(&self, pop: Population, score: u64) -> u64 {
        let short = u128::from(self.short.get(pop as usize).copied().unwrap_or(0));
        let tau = self.tau_us(pop);
        let num = short * u128::from(tau);
        let den = u128::from(self.samples_q16(pop)) * u128::from(SHORT_TAU_US);
        let cap = (tau / u64::from(SHORT_TAU_US)).max(1);
        if num > den && den > 0 {
            let scaled = u128::from(score) * num / den;
            u64::try_from(scaled)
                .unwrap_or(u64::MAX)
                .min(score.saturating_mul(cap))
        } else {
            score
        }
    }

    /// The samples in a population's histograms (Q16).
    fn samples_q16(&self, pop: Population) -> u64 {
        let i = pop as usize;
        let mass: u64 = self.mass.get(i).map_or(0, |m| m.iter().flatten().sum());
        let w = u64::from(self.weight.get(i).copied().unwrap_or(UNIT_WEIGHT).max(1));
        div_u64(mass << 16, w)
    }

    /// Decoded bursts per µs of a population, averaged over its histograms' time constant
    /// (Q16): the slow units may answer only where edges are mostly slow.
    fn rate(&self, pop: Population) -> u64 {
        div_u64(self.samples_q16(pop), self.tau_us(pop))
    }

    /// A population's histogram time constant (µs, at least 1).
    fn tau_us(&self, pop: Population) -> u64 {
        u64::from(self.tau_us.get(pop as usize).copied().unwrap_or(1).max(1))
    }

    /// Decodes of a population that agree in sign within their region, in its histograms (Q16
    /// samples; per µs of its time constant, what the choice of population compares): per
    /// region `(P - N)² / (P + N)` for the masses `P`
    /// and `N` of the two signs, i.e. its decodes times the square of their net agreement,
    /// less what random signs give ([`RANDOM_AGREEMENT`]; a region of the paper's units holds
    /// a few decodes over its 10 ms, and random signs alone would count).
    /// Where edges cross the stride in about the paper's units' whole window (~54 ms), those
    /// units still burst, but mostly on the edge after next (the pattern aliases: a decode of
    /// either sign); the slow units time the same edges with the right sign. Counting decodes
    /// alone would pick the paper's units there.
    fn consistent_samples_q16(&self, pop: Population) -> u64 {
        let i = pop as usize;
        let w = u64::from(self.weight.get(i).copied().unwrap_or(UNIT_WEIGHT).max(1));
        // A sample weighs `w` now (mass units); at most the population's mass, < 2^46.
        let agree: u64 = self
            .mass
            .get(i)
            .map_or(&[][..], |m| &m[..])
            .iter()
            .map(|&[neg, pos]| sign_agreement(neg, pos, w))
            .sum();
        div_u64(agree << 16, w)
    }

    /// One population's estimate.
    fn population_estimate(&self, pop: Population) -> FieldReading {
        let regions: [Option<RegionStats>; REGIONS] =
            core::array::from_fn(|region| self.population_value(pop, region));
        if self.coverage.paired_bands > 0 {
            return self.mirrored_estimate(&regions);
        }
        // (value, weight) per column band: the mean of its two sides' intercepts.
        let mut values = [(0i64, 0u64); COL_BANDS];
        let mut n = 0usize;
        for band in 0..COL_BANDS {
            let fit = |side: usize| self.column_intercept(&regions, side, band);
            // No mirrored regions: whichever side has units.
            let est = match (fit(0), fit(1)) {
                (Some(a), None) | (None, Some(a)) => Some(a),
                (Some((a, va)), Some((b, vb))) => Some(((a + b) / 2, (va + vb) / 4)),
                (None, None) => None,
            };
            if let (Some((v, var)), Some(slot)) = (est, values.get_mut(n)) {
                *slot = (v, band_weight(var));
                n += 1;
            }
        }
        FieldReading::own(weighted_median(values.get(..n).unwrap_or(&[])))
    }

    /// The estimate of a layout with mirrored column bands: every band's intercept on the
    /// left paired with every band's intercept on the right. The mean of a pair cancels what
    /// is odd in `X` (forward translation), exactly for mirrored bands and about for others,
    /// and the weighted median over all pairs lets neither one wrong band nor a side without
    /// texture in some bands silence the field (the mean of the mirrored pair alone does
    /// both). An answer needs a value in some column band on each side (what is odd in `X`
    /// must cancel), and either `support` mirrored bands with values on both sides or values
    /// in at least half of the mirrored bands' sides: a rotation moves the whole view, an
    /// object that crosses near the principal point a few bands either side of it. It also
    /// needs values in [`ABOVE_SUPPORT`] row bands above the principal row, the topmost among
    /// them, where objects on the ground hardly reach ([`spread_is_rotation`]).
    fn mirrored_estimate(&self, regions: &[Option<RegionStats>; REGIONS]) -> FieldReading {
        let sides: [[Option<(i64, u64)>; COL_BANDS]; 2] = core::array::from_fn(|side| {
            core::array::from_fn(|band| self.column_intercept(regions, side, band))
        });
        let upper = upper_coverage(|col, row| {
            regions
                .get(region_index(col % 2, col / 2, 0, row))
                .is_some_and(Option::is_some)
        });
        let values = sides.map(|fits| fits.map(|fit| fit.map(|(v, _)| v)));
        let (choice, recent_needed) = band_choice(
            &values,
            upper,
            self.settings.support,
            self.coverage,
            self.recent_motion,
        );
        let reading = |estimate| FieldReading {
            estimate,
            recent_needed,
            ..FieldReading::NOTHING
        };
        match choice {
            BandChoice::Nothing => return FieldReading::NOTHING,
            BandChoice::Side(side) => {
                let mut values = [(0i64, 0u64); COL_BANDS];
                let mut n = 0usize;
                let fits = sides.get(side).map_or(&[][..], |f| &f[..]);
                for (&(v, var), slot) in fits.iter().flatten().zip(values.iter_mut()) {
                    *slot = (v, band_weight(var));
                    n += 1;
                }
                return reading(weighted_median(values.get(..n).unwrap_or(&[])));
            }
            BandChoice::Pairs | BandChoice::Continuing => {}
        }
        let [left, right] = sides;
        let mut values = [(0i64, 0u64); COL_BANDS * COL_BANDS];
        let mut n = 0usize;
        for &(a, va) in left.iter().flatten() {
            for &(b, vb) in right.iter().flatten() {
                if let Some(slot) = values.get_mut(n) {
                    *slot = ((a + b) / 2, band_weight((va + vb) / 4));
                    n += 1;
                }
            }
        }
        let estimate = weighted_median(values.get(..n).unwrap_or(&[]));
        let continues = |r: RecentAnswer| r.continued_by(estimate);
        if choice == BandChoice::Continuing && !self.recent_motion.is_some_and(continues) {
            return FieldReading::NOTHING;
        }
        reading(estimate)
    }

    /// The rate at the principal row (`Y = 0`) of one column band on one side, and its
    /// variance (Q16 rad/s, Q32): a weighted least-squares fit of the region medians
    /// `r = w + a Y (above) + b Y (below)`. Roll (`∝ Y`), pitch (`∝ X Y`) and the translation
    /// flow of a ground plane (`∝ X Y` below the horizon) are all linear in `Y` within a
    /// column band, so the intercept is the yaw rate plus what stays odd in `X` (which the
    /// mirrored side cancels). The slopes have a prior ([`SLOPE_PRIOR`]) so that one row band
    /// per half still counts.
    ///
    /// The fit is over both halves of the band, or over the rows above the principal row alone
    /// when each half's own fit gives an intercept and the two differ by more than
    /// [`HALVES_DISAGREE_SIGMAS`] standard deviations, or the rows below read more than
    /// [`HALVES_FASTER_BELOW`] times as fast. Scenery above the horizon is far: it
    /// moves with the rotation (and pitch and roll, linear in `Y`) alone, while the rows below
    /// it see the ground, whose flow under translation grows faster than linearly in `Y` close
    /// to the camera, and people and cars on it: where the halves do not say the same rate,
    /// the lower half is what is wrong. For the same reason the rows below alone give no
    /// intercept ([`Field::lower_half_alone_counts`]).
    fn column_intercept(
        &self,
        regions: &[Option<RegionStats>; REGIONS],
        side: usize,
        band: usize,
    ) -> Option<(i64, u64)> {
        let sums = [0, 1].map(|vside| self.half_sums(regions, side, band, vside));
        let above = fit_intercept(&sums, [true, false]);
        if above.is_none() && !self.lower_half_alone_counts() {
            return None;
        }
        if let (Some((wa, va)), Some((wb, vb))) = (above, fit_intercept(&sums, [false, true])) {
            let d = (i128::from(wa) - i128::from(wb)).unsigned_abs();
            let limit = u128::from(HALVES_DISAGREE_SIGMAS * HALVES_DISAGREE_SIGMAS)
                * (u128::from(va) + u128::from(vb));
            let faster_below =
                wb.unsigned_abs() > HALVES_FASTER_BELOW.saturating_mul(wa.unsigned_abs());
            if d * d > limit || faster_below {
                return above;
            }
        }
        fit_intercept(&sums, [true, true])
    }

    /// Whether a column band whose rows above the principal row have no value takes its
    /// intercept from the rows below alone: only where the field cannot ask for the rows above
    /// (a layout without mirrored bands, or with no rows above the principal row), or where
    /// those rows lie close to the horizon ([`FAR_ROWS_Q12`]). Elsewhere
    /// the rows below alone are the ground and what moves on it: people walking past a
    /// hovering drone (hover seeds 631-634 with `--objects 2`/`3`: 34.8 / 13.6 / 33.7 / 68.6
    /// → 26.1 / 9.8 / 26.7 / 63.8 % RMSE / peak), whose column bands otherwise read their
    /// motion wherever the scenery above had no decode in that moment.
    fn lower_half_alone_counts(&self) -> bool {
        self.coverage.paired_bands == 0
            || self.coverage.above_bands == 0
            || self.geometry.row_centre_abs_q12(0, ROW_BANDS - 1) < FAR_ROWS_Q12
    }

    /// The weighted sums of one half of a column band's fit (`vside`: 0 above the principal
    /// row, 1 below).
    fn half_sums(
        &self,
        regions: &[Option<RegionStats>; REGIONS],
        side: usize,
        band: usize,
        vside: usize,
    ) -> HalfSums {
        // Fixed point without 128-bit division (costly on a Cortex-M): weights in
        // [0, MAX_WEIGHT], Y and r in Q12. The bounds keep every i64 in range.
        let mut sums = HalfSums::default();
        for row in 0..ROW_BANDS {
            let Some(st) = regions
                .get(region_index(side, band, vside, row))
                .copied()
                .flatten()
            else {
                continue;
            };
            let w = div_u64(WEIGHT_SCALE, st.variance.max(1)).min(MAX_WEIGHT) as i64;
            if w == 0 {
                continue;
            }
            let y_abs = self.geometry.row_centre_abs_q12(vside, row);
            let y = if vside == 0 { -y_abs } else { y_abs };
            let r = (st.median >> 4).clamp(-(1 << 21), 1 << 21);
            sums.w += w;
            sums.wr += w * r;
            sums.wy += w * y;
            sums.wyy += (w * y * y) >> 12;
            sums.wry += (w * r * y) >> 12;
        }
        sums
    }
}

/// One half of a column band's weighted fit (weights in [0, `MAX_WEIGHT`], `Y` and `r` in
/// Q12): `Σ w < 2^23`, `Σ w r < 2^45`, `Σ w Y < 2^36`, `Σ w Y² < 2^37` and `Σ w r Y < 2^46`
/// (the last two in Q12).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct HalfSums {
    w: i64,
    wr: i64,
    wy: i64,
    wyy: i64,
    wry: i64,
}

/// The intercept at `Y = 0` and its variance (Q16 rad/s, Q32) of the fit over the halves in
/// `used` (above, below the principal row), each with its own slope; `None` without weight.
fn fit_intercept(sums: &[HalfSums; 2], used: [bool; 2]) -> Option<(i64, u64)> {
    let (mut s, mut r_sum) = (0i64, 0i64);
    for (h, _) in sums.iter().zip(used).filter(|(_, u)| *u) {
        s += h.w;
        r_sum += h.wr;
    }
    if s == 0 {
        return None;
    }
    // Eliminate the slopes (Schur complement): each half takes k = Σ wY / (Σ wY² + prior)
    // and removes k Σ wY from the intercept's information (at most all of it, by
    // Cauchy-Schwarz) and k Σ wrY from its right-hand side.
    let (mut info, mut rhs) = (s << 12, r_sum); // weight x Q12, weight x r in Q12
    for (h, _) in sums.iter().zip(used).filter(|(_, u)| *u) {
        let denom = h.wyy.saturating_add(SLOPE_PRIOR);
        if h.wy == 0 || denom <= 0 {
            continue;
        }
        let k = (h.wy << 12) / denom; // Q12
        info -= ((i128::from(k) * i128::from(h.wy)) >> 12) as i64;
        rhs -= ((i128::from(k) * i128::from(h.wry)) >> 12).clamp(-(1 << 62), 1 << 62) as i64;
    }
    if info <= 0 {
        return None;
    }
    // omega = rhs / info (rhs in weight x Q12, info in weight x Q12), in Q12 then Q16.
    let omega_q12 = rhs.saturating_mul(1 << 12) / info;
    let variance = div_u64(WEIGHT_SCALE << 12, info.unsigned_abs()).max(1);
    Some((omega_q12.saturating_mul(16), variance))
}

/// Shifts a histogram's bins right by `shift` (any; 32 and more empty them) and returns their
/// new sum, visiting only the bins `occupied` marks and clearing the marks of those that reach
/// 0. Keeps the invariant of [`Field`]'s `occupied`: a bin whose mark is clear is 0.
fn shift_bins(bins: &mut [u32; BINS], occupied: &mut u64, shift: u32) -> u64 {
    let mut sum = 0u64;
    for i in marked_bins(*occupied, false) {
        if let Some(b) = bins.get_mut(i) {
            *b = b.checked_shr(shift).unwrap_or(0);
            if *b == 0 {
                *occupied &= !(1 << i);
            }
            sum += u64::from(*b);
        }
    }
    sum
}

/// The bins marked in `occupied` (bit `i`: bin `i`), lowest first, or highest first when
/// `descending`: the walks over a histogram skip the bins known to be empty.
fn marked_bins(occupied: u64, descending: bool) -> impl Iterator<Item = usize> {
    let mut rest = occupied;
    core::iter::from_fn(move || {
        if rest == 0 {
            return None;
        }
        let i = if descending {
            let i = 63 - rest.leading_zeros();
            rest ^= 1 << i;
            i
        } else {
            // Clears the lowest set bit without a 64-bit shift.
            let i = rest.trailing_zeros();
            rest &= rest - 1;
            i
        };
        Some(i as usize)
    })
}

/// |rate| (Q16 rad/s) `need` samples into bin `i`, which holds `m` (`need <= m < 2^32`),
/// walking it up (towards higher |rate|) or down; linear in `log2 |r|` within the bin.
fn bin_rate_q16(i: usize, need: u64, m: u64, up: bool) -> i64 {
    // Both cut to 16 bits so that the division is a 32-bit one, to 2^-15.
    let cut = (64 - m.leading_zeros()).saturating_sub(16);
    let frac_q16 = i64::from(
        (((need >> cut) as u32) << 16)
            .checked_div((m >> cut) as u32)
            .unwrap_or(0)
            .min(1 << 16),
    );
    let frac_up = if up { frac_q16 } else { (1 << 16) - frac_q16 };
    let pos_q16 = ((i as i64) << 16) + frac_up;
    let l2 = i64::from(LOG2_LO) + ((pos_q16 * i64::from(BIN_W)) >> 16);
    i64::from(exp2_q16(l2.clamp(i64::from(i32::MIN), 0x7FFF_FFFF) as i32))
}

/// The histogram bin of `log2 |r|` (Q16.16); rates outside [`RATE_RANGE`] fall into the end
/// bins.
#[inline]
fn bin_of(log2_rate: i32) -> usize {
    (log2_rate.saturating_sub(LOG2_LO) / BIN_W).clamp(0, BINS as i32 - 1) as usize
}

/// Mass a region's histograms leave out beyond the paper's units' floor (`mass`, per sign
/// `[neg, pos]`, in the histograms' units), to be counted in bin `bin`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct BeyondFloor {
    bin: usize,
    mass: [u64; 2],
}

impl BeyondFloor {
    /// Whether it adds nothing (compared word by word: an array comparison is a `memcmp` call).
    #[inline]
    fn is_empty(&self) -> bool {
        let [n, p] = self.mass;
        n | p == 0
    }
}

/// A region's `variance` (any unit) for its decodes' masses per sign `[n, p]`: times `(n + p) /
/// |n - p|`, at most [`SPLIT_VARIANCE_CAP`] times (see there).
///
/// On a drone turning at 1.8 rad/s while it pitches and rolls (seed 304), the regions below the
/// principal row read 0.1-0.3 rad/s from decodes split nearly evenly in sign (97 against 118),
/// and their many samples made them the most precise regions of their column bands, whose
/// intercepts then read 0.1 rad/s; the field read half the turn for 0.1 s at a time.
pub(crate) fn split_variance(variance: u64, [n, p]: [u64; 2]) -> u64 {
    let (total, net) = (n.saturating_add(p), n.abs_diff(p));
    if total >= net.saturating_mul(SPLIT_VARIANCE_CAP) {
        return variance.saturating_mul(SPLIT_VARIANCE_CAP);
    }
    // 1 <= total / net < SPLIT_VARIANCE_CAP here, in Q16 (no 128-bit division: it costs a
    // Cortex-M a library call per region and reading).
    let factor_q16 = div_u64(total.saturating_mul(1 << 16), net);
    let whole = (variance >> 16).saturating_mul(factor_q16);
    whole.saturating_add(((variance & 0xFFFF) * factor_q16) >> 16)
}

/// The median rate of a region's majority sign (Q16 rad/s, signed; histograms `[neg, pos]`, their
/// marks and their masses `[n, p]`), when at most a quarter of its decodes
/// ([`SETTLED_MINORITY_LOG2`]) take the other sign and it lies within half of the region's
/// signed median `signed` (same sign; `[q1, signed, q3]` the region's signed quartiles); else
/// `None`.
///
/// Where a region's decodes agree in sign, the few of the other sign are timing errors: a
/// TRG pixel that fires before its FAC neighbour for the same edge (threshold mismatch,
/// jitter) decodes a fast crossing the wrong way, and the signed median, which walks the
/// other sign first, moves by their share towards slow rates (fast constant turns read
/// 5-8 % low). For one peak of decodes that share moves the median by a fraction of the
/// peak's width; a larger move means the majority's decodes are not one peak (a lamp's
/// flicker decodes both very slow and very fast crossings at the view's edges) and the
/// signed median stays. Where the signs are mixed (the aperture problem under pitch and
/// roll, the ground under translation), its pull towards 0 is kept too: the region does not
/// know its direction.
///
/// Where the majority's decodes are wide (the region's quartiles [`WIDE_MAJORITY_RATIO`] or more
/// apart; both lie in the majority when at most a quarter take the other sign), the other
/// sign's are taken for the far side of that spread instead: over a smooth
/// texture a pixel's onset comes a random part of one contrast step's travel time late, so the
/// time differences spread around the crossing time and those below 0 decode the other sign.
/// The median of the time differences is then the majority's decode at rank half of *all*
/// decodes, counted from the slowest (value noise at 0.4 / 0.8 rad/s read 0.91 / 0.89 of the
/// turn, now 0.98 / 0.98; see `docs/readout-notes.md`). Over sharp edges the majority is
/// narrower and the few others are aliases of repeated structure, which this would read as
/// late crossings (1-2 % fast).
#[inline(never)]
fn majority_median(
    [neg, pos]: [&[u32; BINS]; 2],
    [occupied_neg, occupied_pos]: [u64; 2],
    [n, p]: [u64; 2],
    [q1, signed, q3]: [i64; 3],
) -> Option<i64> {
    let (bins, occupied, positive, majority) = if p >= n {
        (pos, occupied_pos, true, p)
    } else {
        (neg, occupied_neg, false, n)
    };
    let total = n + p;
    if majority == 0 || (total - majority) << SETTLED_MINORITY_LOG2 > total {
        return None;
    }
    let (slow, fast) = (
        q1.unsigned_abs().min(q3.unsigned_abs()),
        q1.unsigned_abs().max(q3.unsigned_abs()),
    );
    let wide = (q1 < 0) == (q3 < 0) && fast >= slow.saturating_mul(WIDE_MAJORITY_RATIO);
    let target = if wide { total / 2 } else { majority / 2 };
    let mut acc = 0u64;
    for i in marked_bins(occupied, false) {
        let m = u64::from(bins.get(i).copied().unwrap_or(0));
        if m > 0 && acc + m >= target {
            let v = bin_rate_q16(i, target.saturating_sub(acc), m, true);
            let v = if positive { v } else { -v };
            let one_peak =
                (v < 0) == (signed < 0) && v.abs_diff(signed) <= signed.unsigned_abs() / 2;
            return one_peak.then_some(v);
        }
        acc += m;
    }
    None
}

/// Which column band values a field's estimate is made of.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum BandChoice {
    /// None: no rotation evidence.
    Nothing,
    /// This side's bands alone (0: left): the other side has no value.
    Side(usize),
    /// Every left band's value paired with every right band's.
    Pairs,
    /// As `Pairs`, but an answer only if their estimate continues the readout's answer a
    /// moment ago ([`RecentAnswer::continued_by`]).
    Continuing,
}

/// The rule of [`Field`] and of the f64 oracle's field on the column band values
/// (`values[side][band]`, Q16 rad/s) and the regions above the principal row (`upper`, from
/// [`upper_coverage`]); see the module documentation, "The estimator". The rows above the
/// principal row must move as a rotation's (`above_is_rotation`), or every column band side
/// at one rate (an object at one depth reads about 30 % slower in the outer bands), or nearly
/// the whole width above the principal row one way (`wide_upper_motion`), or, right after the
/// readout answered one way (`recent_motion`), all band values be of the other (or of one
/// sign while that answer is fresh). Then a side with
/// values alone answers if its bands agree (`lone_side`, `bands_agree`); otherwise both
/// sides' values, paired, if they are spread as a rotation's (`spread_is_rotation`) or,
/// right after the readout answered, if each side has one and all have one sign. Where the
/// rows above fail only in their top row band or their width, values spread as a rotation's,
/// of the recent answer's sign, in [`ABOVE_SUPPORT`] row bands above may continue that answer
/// (`Continuing`: texture that leaves the top band in the middle of a turn). Also says whether
/// the choice needed the answer a moment ago (`Nothing` without it, something with it).
pub(crate) fn band_choice(
    values: &[[Option<i64>; COL_BANDS]; 2],
    (above, upper_band_sides): ([bool; ROW_BANDS], usize),
    support: u8,
    coverage: Coverage,
    recent_motion: Option<RecentAnswer>,
) -> (BandChoice, bool) {
    let (n, lo, hi) = range_of(values.iter().flatten().flatten().copied());
    let above_own = above_is_rotation(above, coverage)
        || (n == 2 * COL_BANDS && bands_agree(lo, hi))
        || wide_upper_motion(above, upper_band_sides, values, (lo, hi));
    // All values the other way from the answer a moment ago (a reversal), or one way while
    // the answer is fresh, once the readout has paused.
    let paused = recent_motion.filter(RecentAnswer::paused);
    let after_answer = paused
        .is_some_and(|r| all_one_way(!r.negative(), (lo, hi)) || (r.fresh() && one_sign(lo, hi)));
    let above_ok = above_own || after_answer;
    let bands = values.map(|side| side.map(|v| v.is_some()));
    if let Some(side) = lone_side(bands) {
        let fits = values.get(side).map_or(&[][..], |f| &f[..]);
        let (_, lo, hi) = range_of(fits.iter().flatten().copied());
        return if above_ok && bands_agree(lo, hi) {
            (BandChoice::Side(side), !above_own)
        } else {
            (BandChoice::Nothing, false)
        };
    }
    let spread_own = spread_is_rotation(bands, support, coverage);
    let on_both_sides_after_answer =
        paused.is_some() && one_sign(lo, hi) && bands.iter().all(|side| side.contains(&true));
    // The same way as the answer a moment ago, spread as a rotation's over the columns and
    // over the rows above short of the top band: the turn goes on (people walking on past a
    // drone that stopped turning read at a rate of their own, [`RecentAnswer::continued_by`]).
    let continuing = recent_motion.is_some_and(|r| all_one_way(r.negative(), (lo, hi)))
        && spread_own
        && rows_above_with_values(above, coverage) >= ABOVE_SUPPORT as usize;
    if above_ok && (spread_own || on_both_sides_after_answer) {
        (BandChoice::Pairs, !(above_own && spread_own))
    } else if continuing {
        (BandChoice::Continuing, true)
    } else {
        (BandChoice::Nothing, false)
    }
}

/// Which row bands above the principal row have a value in some column band side, and how
/// many column band sides have one in some row band there, from `has(col, row)`: whether the
/// region of column band side `col` (of `2 x` [`COL_BANDS`], in any order) and row band `row`
/// above the principal row has a value.
pub(crate) fn upper_coverage(has: impl Fn(usize, usize) -> bool) -> ([bool; ROW_BANDS], usize) {
    let grid: [[bool; ROW_BANDS]; 2 * COL_BANDS] =
        core::array::from_fn(|col| core::array::from_fn(|row| has(col, row)));
    let above = core::array::from_fn(|row| grid.iter().any(|rows| rows.get(row) == Some(&true)));
    let sides = grid.iter().filter(|rows| rows.contains(&true)).count();
    (above, sides)
}

/// Whether a field's values are spread over the view as a rotation's are: a value in some
/// column band on each side of the principal point (what is odd in `X` must cancel), and
/// either `support` mirrored bands (at most the paired bands the layout covers) or at least
/// half of the mirrored bands' sides. `bands[side][band]`: that band's side has a value.
fn spread_is_rotation(bands: [[bool; COL_BANDS]; 2], support: u8, coverage: Coverage) -> bool {
    let count = |flags: &[bool]| flags.iter().filter(|&&f| f).count();
    let [left, right] = bands;
    let (n_left, n_right) = (count(&left), count(&right));
    let mirrored = left.iter().zip(&right).filter(|(a, b)| **a && **b).count();
    let paired = coverage.paired_bands;
    let need = usize::from(support.min(paired).max(1));
    n_left > 0 && n_right > 0 && (mirrored >= need || n_left + n_right >= usize::from(paired))
}

/// How many `values` there are, and the least and the greatest.
fn range_of(values: impl Iterator<Item = i64>) -> (usize, i64, i64) {
    values.fold((0, i64::MAX, i64::MIN), |(n, lo, hi), v| {
        (n + 1, lo.min(v), hi.max(v))
    })
}

/// Whether the row bands above the principal row with values (`above[row]`: some region of
/// row band `row` above it has one) are spread as a rotation's: at least [`ABOVE_SUPPORT`] of
/// those the layout reaches (its `above_bands`), the topmost among them; none asked for when
/// the layout has no row above the principal point.
fn above_is_rotation(above: [bool; ROW_BANDS], coverage: Coverage) -> bool {
    let reach = usize::from(coverage.above_bands).min(ROW_BANDS);
    let above_need = (ABOVE_SUPPORT as usize).min(reach);
    rows_above_with_values(above, coverage) >= above_need
        && above
            .get(..reach)
            .and_then(<[bool]>::last)
            .copied()
            .unwrap_or(true)
}

/// How many of the row bands the layout reaches above the principal row (`above[row]`) have
/// values.
fn rows_above_with_values(above: [bool; ROW_BANDS], coverage: Coverage) -> usize {
    let reach = usize::from(coverage.above_bands).min(ROW_BANDS);
    above
        .get(..reach)
        .map_or(0, |a| a.iter().filter(|&&f| f).count())
}

/// Whether the motion above the principal row is as wide as only a rotation's: values in at
/// least [`ABOVE_SUPPORT`] row bands above it (`above[row]`) and in at least
/// [`WIDE_UPPER_BAND_SIDES`] column band sides there (`upper_band_sides`), and column band
/// values (`values[side][band]`, least and greatest `lo`, `hi`) of one sign whose outer half is
/// not slower than their inner half ([`WIDE_FALLOFF_TENTHS`]). Where the top row band sees no
/// texture (sky, or scenery too faint to fire at half the usual contrast), a rotation still
/// moves the rows below it across the whole width at one rate; people walking past move a few
/// column bands at a time, and a bus passing close by, at one depth, reads about 30 % slower
/// in the outer bands.
fn wide_upper_motion(
    above: [bool; ROW_BANDS],
    upper_band_sides: usize,
    values: &[[Option<i64>; COL_BANDS]; 2],
    (lo, hi): (i64, i64),
) -> bool {
    if above.iter().filter(|&&f| f).count() < ABOVE_SUPPORT as usize
        || upper_band_sides < WIDE_UPPER_BAND_SIDES
    {
        return false;
    }
    // (count, sum of |value|) of the inner and the outer half of the bands.
    let mut halves = [(0i64, 0i64); 2];
    for side in values {
        for (band, v) in side.iter().enumerate() {
            if let (Some(v), Some(h)) = (v, halves.get_mut(2 * band / COL_BANDS)) {
                h.0 += 1;
                h.1 = h.1.saturating_add(v.saturating_abs());
            }
        }
    }
    let [(n_in, sum_in), (n_out, sum_out)] = halves;
    one_sign(lo, hi)
        && n_in > 0
        && n_out > 0
        && sum_out.saturating_mul(10).saturating_mul(n_in)
            >= sum_in
                .saturating_mul(WIDE_FALLOFF_TENTHS)
                .saturating_mul(n_out)
}

/// The side (0: left) that has values in at least [`LONE_SIDE_BANDS`] column bands while the
/// other has a value in none (`bands[side][band]`), if any.
fn lone_side(bands: [[bool; COL_BANDS]; 2]) -> Option<usize> {
    let count = |flags: &[bool; COL_BANDS]| flags.iter().filter(|&&f| f).count();
    match bands.map(|b| count(&b)) {
        [0, n] if n >= LONE_SIDE_BANDS => Some(1),
        [n, 0] if n >= LONE_SIDE_BANDS => Some(0),
        _ => None,
    }
}

/// Whether values from `lo` to `hi` (the least and the greatest) all have one sign (none 0).
fn one_sign(lo: i64, hi: i64) -> bool {
    lo > 0 || hi < 0
}

/// Whether values from `lo` to `hi` (the least and the greatest) are all negative
/// (`negative`) or all positive.
fn all_one_way(negative: bool, (lo, hi): (i64, i64)) -> bool {
    if negative {
        hi < 0
    } else {
        lo > 0
    }
}

/// Whether column band values from `lo` to `hi` (any unit) agree as a rotation's: one sign,
/// and `hi - lo` within `1 / BAND_SPREAD` of `|lo + hi| / 2`.
fn bands_agree(lo: i64, hi: i64) -> bool {
    let mid = (lo / 2).saturating_add(hi / 2).saturating_abs();
    one_sign(lo, hi) && hi.saturating_sub(lo).saturating_mul(BAND_SPREAD) <= mid
}

/// The weighted median of `(value Q16 rad/s, weight)` pairs: the smallest value whose weight,
/// with that of all values below it, reaches half the total (no sort: at most
/// `COL_BANDS²` values, and no panic path); clamped to the histograms' range (the fits
/// extrapolate to `Y = 0`, and nothing outside that range is measured). No evidence without
/// values, or when both signs hold more than `1 / SPLIT_SHARE` of the weight.
fn weighted_median(v: &[(i64, u64)]) -> FieldEstimate {
    let signed = |positive: bool| -> u64 {
        v.iter()
            .filter(|&&(x, _)| if positive { x > 0 } else { x < 0 })
            .map(|&(_, w)| w)
            .fold(0u64, u64::saturating_add)
    };
    let total: u64 = v.iter().map(|&(_, w)| w).fold(0u64, u64::saturating_add);
    if total == 0
        || signed(true)
            .min(signed(false))
            .saturating_mul(u64::from(SPLIT_SHARE))
            > total
    {
        return FieldEstimate::NoEvidence;
    }
    let mut best: Option<i64> = None;
    for &(x, _) in v {
        let below: u64 = v
            .iter()
            .filter(|&&(y, _)| y <= x)
            .map(|&(_, w)| w)
            .fold(0u64, u64::saturating_add);
        if below >= total - total / 2 && best.is_none_or(|b| x < b) {
            best = Some(x);
        }
    }
    let m = best.unwrap_or(0);
    let max = i64::from(exp2_q16(LOG2_HI));
    FieldEstimate::Rotation(m.clamp(-max, max) as i32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log2::log2_q16;

    /// The readout's answer a moment ago: its sign (`true`: negative) and whether it is fresh.
    fn recent(negative: bool, fresh: bool) -> Option<RecentAnswer> {
        let readings = if fresh { 1 } else { FRESH_READINGS + 1 };
        let rate_q16 = if negative { -1 << 16 } else { 1 << 16 };
        Some(RecentAnswer { rate_q16, readings })
    }

    proptest::proptest! {
        /// The shortcuts of [`sign_agreement`] give what the division gives, over the documented
        /// range (both masses below 2^40) and the samples' weights the field and the stride
        /// choice use (2^8 to 2^17).
        #[test]
        fn sign_agreement_shortcuts_are_exact(
            neg in 0u64..1 << 40,
            pos in 0u64..1 << 40,
            sample in 1u64 << 8..1 << 17,
            small in proptest::bool::ANY,
        ) {
            // Half the cases near a split region's floor: masses of a few samples.
            let (neg, pos) = if small {
                (neg % (64 * sample), pos % (64 * sample))
            } else {
                (neg, pos)
            };
            let (d, t) = (neg.abs_diff(pos), neg + pos);
            let random = u64::from(RANDOM_AGREEMENT) * sample;
            let by_division = agreement_by_division(d, t, random);
            proptest::prop_assert_eq!(sign_agreement(neg, pos, sample), by_division);
        }
    }

    /// The halving visits only the bins marked occupied: over random decodes, with 1 ms periods
    /// and with 12 ms ones (longer than the paper's units' `tau ln 2`: often two halvings at
    /// once), every histogram equals a copy halved bin by bin, its mass is its bins' sum, and a
    /// bin without its mark is 0.
    #[test]
    fn the_halving_over_occupied_bins_equals_halving_every_bin() {
        for period_us in [1_000, 12_000] {
            halving_over_occupied_bins(period_us);
        }
    }

    /// [`the_halving_over_occupied_bins_equals_halving_every_bin`] with `period_us`.
    fn halving_over_occupied_bins(period_us: u32) {
        let mut f = field_over((0, 259), period_us);
        let mut plain = f.hist;
        let mut halvings = [0u32; 4];
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = |n: u64| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed % n
        };
        for _ in 0..3_000 {
            for _ in 0..next(12) {
                let pop = if next(4) == 0 {
                    Population::Slow
                } else {
                    Population::Fast
                };
                let region = next(REGIONS as u64) as usize;
                let log2 = log2_rate(10 + next(4_000)) + (next(1 << 16) as i32 - (1 << 15));
                let positive = next(3) != 0;
                f.add_in(pop, region, log2, positive);
                let (bin, w) = (bin_of(log2), f.weight[pop as usize]);
                let b = &mut plain[pop as usize][region][usize::from(positive)][bin];
                *b = b.saturating_add(w);
            }
            let weights = f.weight;
            f.age();
            for (p, (before, after)) in weights.iter().zip(f.weight).enumerate() {
                // The halvings: the octaves between the grown weight and the one kept.
                let grown = (u64::from(*before) * u64::from(f.grow_half_q31[p])) >> 30;
                let shift = 64 - u64::from(after).leading_zeros();
                let shift = (64 - grown.leading_zeros()).saturating_sub(shift);
                for b in plain[p].iter_mut().flatten().flatten() {
                    *b = b.checked_shr(shift).unwrap_or(0);
                }
                if let Some(h) = halvings.get_mut(shift as usize) {
                    *h += 1;
                }
            }
            assert_eq!(f.hist, plain);
        }
        // Both cases ran: single halvings, and double ones with the longer period.
        assert!(halvings[1] > 0);
        assert_eq!(halvings[2] > 0, period_us > 10_000 * 7 / 10);
        for p in 0..2 {
            for r in 0..REGIONS {
                for sign in 0..2 {
                    let bins = &f.hist[p][r][sign];
                    let sum: u64 = bins.iter().map(|&b| u64::from(b)).sum();
                    assert_eq!(f.mass[p][r][sign], sum);
                    for (i, &b) in bins.iter().enumerate() {
                        assert!(b == 0 || f.occupied[p][r][sign] & (1 << i) != 0);
                    }
                }
            }
        }
    }

    /// The same on a grid of up to 40 samples of each sign, one sign alone and empty regions
    /// included, at the smallest and largest weights of a sample.
    #[test]
    fn sign_agreement_shortcuts_are_exact_on_a_grid() {
        for sample in [1u64 << 8, 3 << 15, 1 << 17] {
            let random = u64::from(RANDOM_AGREEMENT) * sample;
            for n in 0..=160 {
                for p in 0..=160 {
                    let (neg, pos) = (n * sample / 4, p * sample / 4);
                    let (d, t) = (neg.abs_diff(pos), neg + pos);
                    assert_eq!(
                        sign_agreement(neg, pos, sample),
                        agreement_by_division(d, t, random)
                    );
                }
            }
        }
    }

    /// A DAVIS346-like field (346 x 260, f = 226 px, principal point at the centre), all four
    /// column bands mirrored, `tau_A` = 10 ms, 1 ms periods.
    fn field() -> Field {
        field_over_rows((0, 259))
    }

    /// [`field`] with units on the rows `rows` alone (first, last).
    fn field_over_rows(rows: (u16, u16)) -> Field {
        field_over(rows, 1_000)
    }

    /// [`field_over_rows`] aged by `period_us` per output.
    fn field_over(rows: (u16, u16), period_us: u32) -> Field {
        let g = FieldGeometry::spanning(173 << 16, 130 << 16, 226 << 16, (0, 345), rows);
        let coverage = Coverage {
            paired_bands: 4,
            above_bands: 3,
        };
        Field::new(
            g,
            FieldSettings::DEFAULT,
            [10_000, 100_000],
            period_us,
            coverage,
        )
    }

    /// A pixel in column band `band` on `side` (0 left, 1 right), row band `row` above (`up`)
    /// or below the principal point.
    fn pixel(side: usize, band: usize, up: bool, row: usize) -> (u16, u16) {
        let dx = 43 * band as i32 + 21;
        let dy = 43 * row as i32 + 21;
        let x = if side == 0 { 173 - dx - 1 } else { 173 + dx };
        let y = if up { 130 - dy - 1 } else { 130 + dy };
        (x as u16, y as u16)
    }

    /// `log2 |r|` of a rate in rad/s (Q16.16), from its value in thousandths.
    fn log2_rate(milli: u64) -> i32 {
        log2_q16(milli, 0) - log2_q16(1_000, 0)
    }

    /// Feeds 30 ms of decodes of the paper's units: in every listed column band (side, band,
    /// rate in mrad/s, signed), two per row band and period, all at the same rate.
    fn feed(f: &mut Field, bands: &[(usize, usize, i64)]) {
        let mut halves = [(0, 0, 0, 0); 2 * COL_BANDS];
        for (slot, &(side, band, rate)) in halves.iter_mut().zip(bands) {
            *slot = (side, band, rate, rate);
        }
        feed_halves(f, &halves[..bands.len().min(halves.len())]);
    }

    /// [`feed`] with a rate (mrad/s, signed) per half of each listed column band: `(side,
    /// band, above the principal row, below it)`.
    fn feed_halves(f: &mut Field, bands: &[(usize, usize, i64, i64)]) {
        let mut rows = [(0, 0, None, None); 2 * COL_BANDS];
        for (slot, &(side, band, above, below)) in rows.iter_mut().zip(bands) {
            *slot = (side, band, Some(above), Some(below));
        }
        feed_rows(f, &rows[..bands.len().min(rows.len())]);
    }

    /// [`feed_halves`] with either half left without decodes (`None`).
    fn feed_rows(f: &mut Field, bands: &[(usize, usize, Option<i64>, Option<i64>)]) {
        for _ in 0..30 {
            for &(side, band, above, below) in bands {
                for row in 0..ROW_BANDS {
                    for (up, rate) in [(false, below), (true, above)] {
                        let Some(rate) = rate else {
                            continue;
                        };
                        let (x, y) = pixel(side, band, up, row);
                        for _ in 0..2 {
                            let l2 = log2_rate(rate.unsigned_abs());
                            f.add(Population::Fast, x, y, l2, rate > 0);
                        }
                    }
                }
            }
            f.age();
        }
    }

    /// Every column band on both sides, at the rate `rate(side, band)` (mrad/s, signed).
    fn all_bands(rate: impl Fn(usize, usize) -> i64) -> [(usize, usize, i64); 2 * COL_BANDS] {
        core::array::from_fn(|i| (i % 2, i / 2, rate(i % 2, i / 2)))
    }

    fn rad_s(e: FieldEstimate) -> Option<f64> {
        match e {
            FieldEstimate::Rotation(v) => Some(f64::from(v) / 65536.0),
            FieldEstimate::NoEvidence => None,
        }
    }

    /// Asserts that `f` answers exactly when `answers`, and then that it reads `want` rad/s to
    /// within `tol`; `case` names the case in a failure.
    fn assert_answer(
        f: &Field,
        answers: bool,
        (want, tol): (f64, f64),
        case: &dyn core::fmt::Debug,
    ) {
        let v = rad_s(f.estimate());
        assert_eq!(v.is_some(), answers, "{case:?}: {v:?}");
        if let Some(v) = v {
            assert!((v - want).abs() < tol, "{case:?}: {v}");
        }
    }

    /// Feeds 400 ms of a slow turn to the right seen by the slow units only: in every region,
    /// per period, one slow decode at each rate of `slow` (mrad/s) and `beyond` decodes of the
    /// paper's units within an octave above their floor `floor` (mrad/s); returns the estimate
    /// (rad/s).
    fn slow_turn(established: bool, slow: &[u64], beyond: usize, floor: u64) -> f64 {
        let mut f = field();
        f.set_direction_established(established);
        for _ in 0..400 {
            for side in 0..2 {
                for band in 0..COL_BANDS {
                    for row in 0..ROW_BANDS {
                        for up in [false, true] {
                            let (x, y) = pixel(side, band, up, row);
                            let region = f.geometry().region(x, y);
                            for &rate in slow {
                                f.add(Population::Slow, x, y, log2_rate(rate), true);
                            }
                            for _ in 0..beyond {
                                f.add_beyond_floor(region, true, log2_rate(floor));
                            }
                        }
                    }
                }
            }
            f.age();
        }
        rad_s(f.estimate()).expect("a rotation")
    }

    #[test]
    fn the_slow_units_read_past_the_paper_units_floor_once_the_direction_is_established() {
        // A turn whose crossings straddle the paper's units' floor (80 mrad/s): the slow units
        // decode only the slower ones (their histograms end at the floor), the paper's units
        // the rest.
        let slow = [45, 50, 55, 60, 65, 70, 75];
        let censored = slow_turn(true, &slow, 0, 80);
        let starting = slow_turn(false, &slow, 4, 80);
        let read = slow_turn(true, &slow, 4, 80);
        assert!(
            (censored - 0.06).abs() < 0.005,
            "censored median {censored}"
        );
        // Before the direction is established (an onset) the count is not read.
        assert!(
            (starting - censored).abs() < 1e-4,
            "{starting} vs {censored}"
        );
        // 4 per 1 ms period over the paper's units' 10 ms, 400 over the slow units' 100 ms,
        // beside their 700: the median is 550 of 1 100 up, in the slow units' upper decodes.
        assert!(
            read > censored * 1.08 && read < 0.08,
            "read {read}, censored {censored}"
        );
    }

    #[test]
    fn past_the_floor_counts_no_more_than_the_slow_units_decode_just_below_it() {
        // The slow units' decodes lie more than an octave below the floor: the paper's units'
        // decodes near it are not their tail (aliases, wake-ups), and change nothing.
        let slow = [20, 22, 24, 26, 28, 30, 32];
        let alone = slow_turn(true, &slow, 0, 80);
        let with = slow_turn(true, &slow, 4, 80);
        assert!((alone - with).abs() < 1e-4, "{alone} vs {with}");
        // Two of seven in the octave below the floor, and ten times as many counted past it
        // as the slow units decode: the count is cut to those two, and the median stays among
        // the slow units' decodes (uncut, it would lie at the floor).
        let slow = [30, 32, 34, 36, 38, 42, 70];
        let alone = slow_turn(true, &slow, 0, 80);
        let capped = slow_turn(true, &slow, 70, 80);
        assert!(
            capped > alone && capped < 0.04,
            "capped {capped}, alone {alone}"
        );
    }

    #[test]
    fn a_side_without_texture_in_some_bands_still_answers() {
        // Left bands 2, 3 and right bands 0, 1, 2 see texture: only band 2 is mirrored, but
        // five of the eight band sides agree on 0.3 rad/s.
        let mut f = field();
        feed(
            &mut f,
            &[
                (0, 2, 300),
                (0, 3, 300),
                (1, 0, 300),
                (1, 1, 300),
                (1, 2, 300),
            ],
        );
        let v = rad_s(f.estimate()).expect("a rotation");
        assert!((v - 0.3).abs() < 0.01, "{v}");
    }

    #[test]
    fn a_side_alone_answers_where_its_bands_agree_as_a_rotation() {
        // Texture on the right side only (sky on the left): three or four bands at one rate
        // answer it, alone.
        for n in [3, 4] {
            let mut f = field();
            let bands: [(usize, usize, i64); COL_BANDS] = core::array::from_fn(|b| (1, b, -350));
            feed(&mut f, &bands[..n]);
            let v = rad_s(f.estimate()).expect("a rotation");
            assert!((v + 0.35).abs() < 0.05, "{n} bands: {v}");
        }
        // Two bands are too few to tell a rotation from an object.
        let mut f = field();
        feed(&mut f, &[(0, 0, 350), (0, 1, 350)]);
        assert_eq!(f.estimate(), FieldEstimate::NoEvidence);
        // A trend across the bands (translation, or an object's rate falling as 1 / (1 + X²)
        // outwards): no evidence. Rates within a fifth of their mid-range still answer.
        for (rates, answers) in [([300, 280, 250, 220], false), ([300, 290, 280, 270], true)] {
            let mut f = field();
            let bands: [(usize, usize, i64); COL_BANDS] =
                core::array::from_fn(|b| (0, b, rates[b]));
            feed(&mut f, &bands);
            assert_eq!(
                f.estimate() != FieldEstimate::NoEvidence,
                answers,
                "{rates:?}"
            );
        }
    }

    #[test]
    fn bands_agree_within_a_fifth_of_their_mid_range_and_one_sign() {
        assert!(bands_agree(900, 1_000));
        assert!(bands_agree(-1_000, -900));
        assert!(!bands_agree(800, 1_000));
        assert!(!bands_agree(-10, 10));
        assert!(!bands_agree(0, 0));
        assert!(!bands_agree(i64::MIN, i64::MAX));
        assert_eq!(
            lone_side([[false; COL_BANDS], [true, true, true, false]]),
            Some(1)
        );
        assert_eq!(lone_side([[true; COL_BANDS], [false; COL_BANDS]]), Some(0));
        assert_eq!(
            lone_side([[true, true, false, false], [false; COL_BANDS]]),
            None
        );
        assert_eq!(
            lone_side([[true; COL_BANDS], [true, false, false, false]]),
            None
        );
    }

    /// Feeds 60 ms of decodes of the paper's units into every region: every `every`
    /// periods, one decode per listed rate (mrad/s, signed).
    fn feed_everywhere(f: &mut Field, rates: &[i64], every: usize) {
        for period in 0..60 {
            if period % every != 0 {
                f.age();
                continue;
            }
            for (side, band) in all_bands(|_, _| 0).map(|(s, b, _)| (s, b)) {
                for row in 0..ROW_BANDS {
                    for up in [false, true] {
                        let (x, y) = pixel(side, band, up, row);
                        for &rate in rates {
                            let l2 = log2_rate(rate.unsigned_abs());
                            f.add(Population::Fast, x, y, l2, rate > 0);
                        }
                    }
                }
            }
            f.age();
        }
    }

    /// The estimates after [`feed_everywhere`] of the product's field and of one that always
    /// reads the signed median.
    fn with_and_without_majority(rates: &[i64], every: usize) -> (FieldEstimate, FieldEstimate) {
        let (mut f, mut g) = (field(), field());
        g.settled_q16 = u32::MAX;
        feed_everywhere(&mut f, rates, every);
        feed_everywhere(&mut g, rates, every);
        (f.estimate(), g.estimate())
    }

    #[test]
    fn a_region_agreeing_in_sign_reads_its_majority_median() {
        // Nine decodes spread evenly (in log) around 1 rad/s and one fast decode of the other
        // sign (a TRG pixel that fired before its FAC neighbour), per region and period.
        let rates = [800, 850, 900, 950, 1000, 1050, 1110, 1170, 1250, -3000];
        let (majority, signed) = with_and_without_majority(&rates, 1);
        let v = rad_s(majority).expect("a rotation");
        assert!((v - 1.0).abs() < 0.02, "majority median {v}");
        // The signed median walks the other sign first and reads the 40th percentile of the
        // majority: 5 % low here.
        let w = rad_s(signed).expect("a rotation");
        assert!(w < 0.975 && w > 0.9, "signed median {w}");
    }

    #[test]
    fn a_majority_spread_over_an_octave_reads_the_median_time_difference() {
        // Twenty crossings of one edge at 1 rad/s whose time differences spread evenly from
        // -0.37 to 2.48 times the true one (a smooth texture's onsets): three come out with the
        // other sign, the region's quartiles lie more than an octave apart. Their median
        // time difference (1.0-1.13 of the true one) is a rate of 0.89-1.02.
        let rates: [i64; 20] = core::array::from_fn(|k| {
            let dt_milli = -370 + 150 * k as i64;
            1_000_000 / dt_milli
        });
        let (majority, signed) = with_and_without_majority(&rates, 1);
        let v = rad_s(majority).expect("a rotation");
        assert!(v > 0.87 && v < 1.03, "median time difference {v}");
        // The signed median counts the other sign as slower than all of the majority: 0.63-0.7.
        let w = rad_s(signed).expect("a rotation");
        assert!(w < 0.72, "signed median {w}");
    }

    #[test]
    fn a_majority_in_two_peaks_keeps_the_signed_median() {
        // Agreeing in sign (one decode in ten the other way), but the majority's decodes lie in
        // two clusters, 0.5 and 6 rad/s: its median jumps between them, 12 times the signed
        // median.
        let rates = [480, 500, 520, 540, 6000, 6200, 6400, 6600, 6800, -7000];
        let (majority, signed) = with_and_without_majority(&rates, 1);
        assert_eq!(majority, signed);
    }

    #[test]
    fn mixed_signs_or_few_decodes_keep_the_signed_median() {
        // Three of ten decodes the other way: the region does not know its direction.
        let mixed = [800, 900, 1000, 1100, 1200, 1300, 1400, -900, -1000, -1100];
        let (majority, signed) = with_and_without_majority(&mixed, 1);
        assert_eq!(majority, signed);
        // Decodes agreeing in sign, but about 14 in each region's memory (the settled count
        // is 32), as where motion has just started.
        let few = [900, 1000, 1100, -3000];
        let (majority, signed) = with_and_without_majority(&few, 3);
        assert_eq!(majority, signed);
        // The same decodes every period (about 42) do read the majority.
        let (majority, signed) = with_and_without_majority(&few, 1);
        assert_ne!(majority, signed);
    }

    #[test]
    fn once_the_direction_is_established_a_region_with_few_decodes_reads_its_majority() {
        // About 25 decodes per region (under the settled count), one in five a fast one of the
        // other sign (TRG pixels firing before their FAC neighbours on a smooth texture).
        let few = [800, 850, 900, 950, 1000, 1050, 1110, 1170, -3000, -3500];
        let read = |established: bool| {
            let mut f = field();
            f.set_direction_established(established);
            feed_everywhere(&mut f, &few, 4);
            rad_s(f.estimate()).expect("a rotation")
        };
        // The signed median walks the other sign first, a quarter of the way up the majority;
        // the majority's median is its middle.
        let (starting, established) = (read(false), read(true));
        assert!(starting < 0.93, "signed median {starting}");
        assert!(
            (established - 0.975).abs() < 0.03,
            "majority median {established}"
        );
    }

    #[test]
    fn where_the_halves_disagree_the_rows_above_the_principal_row_decide() {
        // Far scenery above the principal row turns at 0.3 rad/s; below it something else
        // reads 0.9 in every band (people walking past, the ground close under a drone): the
        // fit over both halves would put the intercept between the two.
        let mut f = field();
        feed_halves(
            &mut f,
            &all_bands(|_, _| 0).map(|(s, b, _)| (s, b, 300, 900)),
        );
        let v = rad_s(f.estimate()).expect("a rotation");
        assert!((v - 0.3).abs() < 0.01, "{v}");
        // Halves that agree are fitted together.
        let mut g = field();
        feed_halves(
            &mut g,
            &all_bands(|_, _| 0).map(|(s, b, _)| (s, b, 300, 300)),
        );
        let w = rad_s(g.estimate()).expect("a rotation");
        assert!((w - 0.3).abs() < 0.01, "{w}");
    }

    #[test]
    fn rows_below_faster_than_twice_the_rows_above_leave_the_rows_above_to_decide() {
        // A hover turning at 0.06 rad/s: above the principal row, the top two row bands of
        // each column band have decodes, a few, spread from 0.02 to 0.2 rad/s; below it a
        // person walking past close by reads 0.6 in every row band, from many decodes (hover
        // seed 1101 with `--objects 2`). The difference lies within three standard deviations
        // of the halves' intercepts (the fit over both halves read 0.60), yet the rows below
        // read ten times the rows above.
        let mut f = field();
        for period in 0..30 {
            for (side, band, _) in all_bands(|_, _| 0) {
                // One decode every other period in each region: 20, 60, 200 mrad/s in turn.
                for row in (1..ROW_BANDS).filter(|_| period % 2 == 0) {
                    let (x, y) = pixel(side, band, true, row);
                    let milli = [20u64, 60, 200][period / 2 % 3];
                    f.add(Population::Fast, x, y, log2_rate(milli), true);
                }
                for row in 0..ROW_BANDS {
                    let (x, y) = pixel(side, band, false, row);
                    for _ in 0..4 {
                        f.add(Population::Fast, x, y, log2_rate(600), true);
                    }
                }
            }
            f.age();
        }
        let v = rad_s(f.estimate()).expect("a rotation");
        assert!((0.03..0.12).contains(&v), "{v}");
    }

    #[test]
    fn the_rows_below_alone_give_a_column_band_no_value() {
        // A turn at -0.08 rad/s that is ending, right after the readout answered it: the far
        // scenery above the principal row still has decodes in the third column band on each
        // side; in the inner two bands only the rows below have any, people walking past at
        // -0.3 rad/s (hover seed 631 at 1.73 s). With those rows as the inner bands'
        // intercepts, the pairs' median read the people.
        // Where the field cannot ask for the rows above (no rows there), or they lie close
        // to the horizon (a 15-row strip: 0.03 f), the rows below alone still count.
        // Bands 0 and 1 on either side: the rows below alone; band 2: both halves.
        let bands: [(usize, usize, Option<i64>, Option<i64>); 6] = core::array::from_fn(|i| {
            let (side, band) = (i % 2, i / 2);
            match band {
                2 => (side, band, Some(-80), Some(-80)),
                _ => (side, band, None, Some(-300)),
            }
        });
        for (case, lower_alone) in [(0, false), (1, true), (2, true)] {
            let mut f = match case {
                2 => field_over_rows((123, 137)),
                _ => field(),
            };
            if case == 1 {
                f.coverage.above_bands = 0;
            }
            f.set_recent_motion(recent(true, true));
            feed_rows(&mut f, &bands);
            let v = rad_s(f.estimate()).expect("a rotation");
            if lower_alone {
                assert!(v < -0.15, "case {case}: {v}");
            } else {
                assert!((v + 0.08).abs() < 0.005, "{v}");
            }
        }
    }

    #[test]
    fn one_wrong_band_does_not_spoil_its_mirror() {
        // Band 1 on the left says -0.6 rad/s, everything else 0.3: the mean of band 1's
        // mirrored pair would be -0.15; the median over all pairs is not moved by it.
        let mut f = field();
        let bands = all_bands(|side, band| if (side, band) == (0, 1) { -600 } else { 300 });
        feed(&mut f, &bands);
        let v = rad_s(f.estimate()).expect("a rotation");
        assert!((v - 0.3).abs() < 0.05, "{v}");
    }

    #[test]
    fn half_of_the_band_sides_answer_fewer_do_not() {
        // Column bands (side, band) that see texture moving at 0.4 rad/s, in every row band.
        let cases: [(&[(usize, usize)], bool); 5] = [
            // Three of the eight band sides, one mirrored band: an object near the centre.
            (&[(0, 1), (0, 2), (1, 0)], false),
            // Half of the band sides.
            (&[(0, 1), (0, 2), (1, 0), (1, 1)], true),
            // Texture mostly on one side (a blank wall or sky on the other): still half.
            (&[(0, 0), (1, 1), (1, 2), (1, 3)], true),
            // One side only, every band at one rate: that side alone (see
            // `a_side_alone_answers_where_its_bands_agree_as_a_rotation`).
            (&[(1, 0), (1, 1), (1, 2), (1, 3)], true),
            // Two mirrored bands.
            (&[(0, 0), (0, 1), (1, 0), (1, 1)], true),
        ];
        for (bands, answers) in cases {
            let mut f = field();
            let mut with_rate = [(0, 0, 0); 2 * COL_BANDS];
            for (slot, &(side, band)) in with_rate.iter_mut().zip(bands) {
                *slot = (side, band, 400);
            }
            feed(&mut f, with_rate.get(..bands.len()).unwrap_or_default());
            assert_answer(&f, answers, (0.4, 0.05), &bands);
        }
    }

    #[test]
    fn motion_that_misses_the_top_row_band_above_the_centre_is_no_rotation() {
        // Every column band moves in the lower half and in the listed row bands above the
        // principal row, at 0.3 rad/s times `1 / (1 + X²)` (an object at one depth moving on
        // its own, 30 % slower in the outer bands). Objects on the ground and the ground under
        // translation reach the lower bands above (a person close to a camera flying low the
        // second one too): no rotation without the top band. Far scenery reaches the top band:
        // with it and one more band above, a rotation.
        let object = object_rate_milli;
        let rotation = |_: usize| 300;
        for (above, rate, answers) in [
            (&[0][..], &object as &dyn Fn(usize) -> u64, false),
            (&[0, 1][..], &object, false),
            (&[2][..], &object, false),
            (&[0, 2][..], &object, true),
            (&[1, 2][..], &object, true),
            (&[0, 1, 2][..], &object, true),
            // One rate across the whole width is a rotation's, top band or not (sky above a
            // low skyline).
            (&[0][..], &rotation, true),
            (&[0, 1][..], &rotation, true),
        ] {
            let mut f = field();
            for _ in 0..30 {
                for (side, band, _) in all_bands(|_, _| 0) {
                    for row in 0..ROW_BANDS {
                        for up in [false, true] {
                            if up && !above.contains(&row) {
                                continue;
                            }
                            let (x, y) = pixel(side, band, up, row);
                            for _ in 0..2 {
                                f.add(Population::Fast, x, y, log2_rate(rate(band)), true);
                            }
                        }
                    }
                }
                f.age();
            }
            assert_answer(&f, answers, (0.3, 0.06), &("row bands above", above));
        }
    }

    #[test]
    fn wide_motion_without_the_top_row_band_is_a_rotation() {
        // Row bands 0 and 1 above the principal row move (the top one sees no texture, as a
        // faint skyline at half the usual contrast), in the listed column band sides; the
        // band values scatter by more than a fifth (few decodes), one sign.
        let wide = |side: usize, band: usize| [300, 240, 330, 270][(band + side) % 4];
        let all: [(usize, usize); 2 * COL_BANDS] = core::array::from_fn(|i| (i % 2, i / 2));
        let object = |_: usize, band: usize| object_rate_milli(band) as i64;
        for (sides, rate, answers) in [
            // Seven of the eight band sides at one rate, give or take: a rotation.
            (&all[1..], &wide as &dyn Fn(usize, usize) -> i64, true),
            (&all[..], &wide, true),
            // Six: as wide as people walking past have moved.
            (&all[2..], &wide, false),
            // An object at one depth as wide as the view (a bus passing close by): its rate
            // falls as 1 / (1 + X²) outwards.
            (&all[..], &object, false),
            (&all[1..], &object, false),
            // Both signs: not one rotation.
            (
                &all[1..],
                &|side, band| {
                    if band == 3 {
                        -wide(side, band)
                    } else {
                        wide(side, band)
                    }
                },
                false,
            ),
        ] {
            let mut f = field();
            for _ in 0..30 {
                for &(side, band) in sides {
                    for row in 0..2 {
                        let (x, y) = pixel(side, band, true, row);
                        let r = rate(side, band);
                        for _ in 0..2 {
                            f.add(Population::Fast, x, y, log2_rate(r.unsigned_abs()), r > 0);
                        }
                    }
                }
                f.age();
            }
            assert_answer(&f, answers, (0.285, 0.05), &("band sides", sides.len()));
        }
    }

    #[test]
    fn right_after_an_answer_the_other_way_the_rows_above_need_not_move_as_a_rotation() {
        // Every column band side moves below the principal row and in the lowest row band
        // above it, none in the top ones (after a reversal they fill last); the band values
        // scatter by more than a fifth. Standing still before, that is no rotation; right
        // after the readout answered the other way, it is, if all of one sign, and right after
        // an answer the same way while it is fresh; not later (people walking on after the
        // camera stopped), nor where one band moves the other way (forward translation with
        // its focus of expansion off the principal point, as a car's right after a bend).
        let wide = |side: usize, band: usize| [300, 240, 330, 270][(band + side) % 4];
        let translation = |side: usize, band: usize| {
            let r = wide(side, band);
            if side == 0 && band == COL_BANDS - 1 {
                -r
            } else {
                r
            }
        };
        for (rate, recent, answers) in [
            (&wide as &dyn Fn(usize, usize) -> i64, None, false),
            (&wide, recent(true, false), true),
            (&wide, recent(false, false), false),
            (&wide, recent(false, true), true),
            (&translation, recent(true, false), false),
            (&translation, recent(false, true), false),
        ] {
            let mut f = field();
            f.set_recent_motion(recent);
            for _ in 0..30 {
                for (side, band, _) in all_bands(|_, _| 0) {
                    let r = rate(side, band);
                    for (up, rows) in [(false, 0..ROW_BANDS), (true, 0..1)] {
                        for row in rows {
                            let (x, y) = pixel(side, band, up, row);
                            for _ in 0..2 {
                                f.add(Population::Fast, x, y, log2_rate(r.unsigned_abs()), r > 0);
                            }
                        }
                    }
                }
                f.age();
            }
            assert_answer(&f, answers, (0.285, 0.05), &("recent", recent));
        }
    }

    #[test]
    fn a_turn_goes_on_when_its_texture_leaves_the_top_row_band() {
        // A turn at about 0.29 rad/s with every column band side moving below the principal
        // row and in the two lower row bands above it, none in the top one (sky came into
        // view), the left outer band read low (the outer half more than a tenth slower than
        // the inner: not `wide_upper_motion`). On its own evidence that is no rotation; it
        // continues an answer a moment ago of that sign and about that rate (within a fifth),
        // whether the last reading answered or not, but not one of another rate or sign, nor
        // with one row band above the principal row alone.
        let rate = |side: usize, band: usize| match (side, band) {
            (0, 3) => 120,
            _ => [300, 280, 320, 290][(band + side) % 4],
        };
        let answer = |milli: i32, readings: u8| {
            Some(RecentAnswer {
                rate_q16: milli * 65_536 / 1_000,
                readings,
            })
        };
        for (recent, rows_above, answers) in [
            (None, 2, false),
            (answer(290, 0), 2, true),
            // The last reading of `shared::RECENT_READINGS` (25).
            (answer(290, 25), 2, true),
            (answer(260, 3), 2, true),
            (answer(400, 0), 2, false),
            (answer(-290, 0), 2, false),
            (answer(290, 0), 1, false),
        ] {
            let mut f = field();
            f.set_recent_motion(recent);
            for _ in 0..30 {
                for (side, band, _) in all_bands(|_, _| 0) {
                    let r = rate(side, band);
                    for (up, rows) in [(false, 0..ROW_BANDS), (true, 0..rows_above)] {
                        for row in rows {
                            let (x, y) = pixel(side, band, up, row);
                            for _ in 0..2 {
                                f.add(Population::Fast, x, y, log2_rate(r), true);
                            }
                        }
                    }
                }
                f.age();
            }
            assert_answer(&f, answers, (0.29, 0.03), &("recent", recent, rows_above));
        }
    }

    #[test]
    fn right_after_an_answer_one_band_on_each_side_is_spread_enough() {
        // Texture in the inner band on the left and in two bands on the right (a blank wall
        // covers the rest), every row band: too few bands to tell a rotation from objects
        // crossing near the principal point, unless the readout answered a moment ago and all
        // the values have one sign.
        let textured = |side: usize, band: usize| match side {
            0 => band == 0,
            _ => band == 0 || band == COL_BANDS - 1,
        };
        for (recent, outer_sign, answers) in [
            (None, 1, false),
            (recent(false, false), 1, true),
            (recent(true, false), 1, true),
            (recent(false, true), -1, false),
        ] {
            let mut f = field();
            f.set_recent_motion(recent);
            for _ in 0..30 {
                for (side, band, _) in all_bands(|_, _| 0) {
                    if !textured(side, band) {
                        continue;
                    }
                    let r: i64 = if side == 1 && band == COL_BANDS - 1 {
                        300 * outer_sign
                    } else {
                        300
                    };
                    for up in [false, true] {
                        for row in 0..ROW_BANDS {
                            let (x, y) = pixel(side, band, up, row);
                            for _ in 0..2 {
                                f.add(Population::Fast, x, y, log2_rate(r.unsigned_abs()), r > 0);
                            }
                        }
                    }
                }
                f.age();
            }
            assert_answer(
                &f,
                answers,
                (0.3, 0.05),
                &("recent", recent, "outer sign", outer_sign),
            );
        }
    }

    #[test]
    fn split_signs_widen_a_region_s_variance_up_to_the_cap() {
        assert_eq!(split_variance(100, [0, 50]), 100);
        assert_eq!(split_variance(100, [10, 30]), 200);
        assert_eq!(split_variance(100, [50, 50]), 100 * SPLIT_VARIANCE_CAP);
        // No decodes at all (a region then has no value): the cap.
        assert_eq!(split_variance(100, [0, 0]), 100 * SPLIT_VARIANCE_CAP);
        assert_eq!(split_variance(u64::MAX, [u64::MAX, 0]), u64::MAX);
        assert_eq!(split_variance(u64::MAX, [1, 2]), u64::MAX);
        assert_eq!(split_variance(1 << 40, [1 << 45, 1 << 46]), 3 << 40);
    }

    #[test]
    fn regions_whose_decodes_split_in_sign_count_less() {
        // A fast turn (1.6 rad/s) seen by the two upper row bands of every column band side,
        // while the rows below the principal row and the row band just above it (the ground
        // under forward flight and pitch) read about 0.1 rad/s from two and a half times as many
        // decodes split 60 / 40 in sign: those regions are the most precise of their bands by
        // their spread alone, and drew the band intercepts to a fraction of the turn.
        let mut f = field();
        for _ in 0..30 {
            for (side, band, _) in all_bands(|_, _| 0) {
                for (up, row) in [(true, 0), (false, 0), (false, 1), (false, 2)] {
                    let (x, y) = pixel(side, band, up, row);
                    for k in 0..10 {
                        let rate = 80 + 5 * (k % 9);
                        f.add(Population::Fast, x, y, log2_rate(rate), k % 10 < 6);
                    }
                }
                for row in 1..ROW_BANDS {
                    let (x, y) = pixel(side, band, true, row);
                    for k in 0..4 {
                        f.add(Population::Fast, x, y, log2_rate(1_550 + 30 * k), true);
                    }
                }
            }
            f.age();
        }
        // 0.81 rad/s with their variance widened, 0.14 without (the fits' slopes take up
        // the rest: the upper rows alone lean on the slope prior).
        let v = rad_s(f.estimate()).expect("a rotation");
        assert!(v > 0.6, "{v}");
    }

    /// The rate (mrad/s) an object at one depth moving on its own shows in column band `band`
    /// ([`pixel`]'s columns, f = 226 px), 0.3 rad/s at the principal point: `1 / (1 + X²)`
    /// of it, 30 % less in the outer bands than in the inner ones.
    fn object_rate_milli(band: usize) -> u64 {
        let x = (43.0 * band as f64 + 21.0) / 226.0;
        (300.0 / (1.0 + x * x)) as u64
    }

    /// The field of the calibrated readout over a dense 346 x 260 layout (stride 2, f = 226
    /// px) with its principal point at column 173 and row `cy`.
    fn field_with_principal_row(cy: u16) -> Field {
        use fixed::types::U16F16;
        let layout = crate::layout::Dense::new(346, 260, 2).expect("a valid layout");
        let camera = (
            U16F16::from_num(226),
            U16F16::from_num(173),
            U16F16::from_num(cy),
        );
        crate::readout::shared::field_over(
            &layout,
            camera,
            FieldSettings::DEFAULT,
            [10_000, 100_000],
            1_000,
        )
    }

    #[test]
    fn the_top_row_band_is_the_upper_third_of_the_rows_above_the_principal_point() {
        // Row bands are a third of the rows on their own side each: wherever the principal
        // row lies, the rows above it make three bands (none when it is at the top).
        for (cy, bands) in [(130, 3), (110, 3), (100, 3), (40, 3), (0, 0)] {
            let f = field_with_principal_row(cy);
            assert_eq!(f.coverage.above_bands, bands, "principal row {cy}");
            assert_eq!(f.coverage.paired_bands, COL_BANDS as u8);
        }
        // Every column band moves below the principal row and in the listed rows above it, as
        // an object would ([`object_rate_milli`]: a rotation's one rate across the whole width
        // answers without the top band). Principal row 100 (bands of 33 rows above): row 90
        // lies in the first band, row 50 in the second, row 20 in the top one; principal row 110 (bands of 37 rows
        // above, where bands mirrored from the 150 rows below were 50 rows and the top one a
        // 10-row sliver): row 80 in the first band, row 50 in the second, row 30 in the top
        // one. The top band with one more makes a rotation; with the principal point at the
        // top, the rows below do.
        for (cy, above, answers) in [
            (100, &[90u16, 20][..], true),
            (100, &[90, 50][..], false),
            (100, &[90][..], false),
            (100, &[20][..], false),
            (110, &[80, 30][..], true),
            (110, &[80, 50][..], false),
            (0, &[][..], true),
        ] {
            let mut f = field_with_principal_row(cy);
            for _ in 0..30 {
                for (side, band, _) in all_bands(|_, _| 0) {
                    let (x, _) = pixel(side, band, false, 0);
                    for &y in above.iter().chain(&[150, 200, 250]) {
                        for _ in 0..2 {
                            let l2 = log2_rate(object_rate_milli(band));
                            f.add(Population::Fast, x, y, l2, true);
                        }
                    }
                }
                f.age();
            }
            assert_answer(
                &f,
                answers,
                (0.26, 0.06),
                &("principal row, rows", cy, above),
            );
        }
    }

    #[test]
    fn a_field_split_in_direction_is_no_evidence() {
        // Every left band says +0.3 rad/s and every right band -0.3: translation that the
        // mirrored sides do not cancel, or the moment after a reversal.
        let mut f = field();
        let bands = all_bands(|side, band| if side == 1 && band < 2 { -300 } else { 300 });
        feed(&mut f, &bands);
        assert_eq!(f.estimate(), FieldEstimate::NoEvidence);
        // With one right band of the other sign, three quarters agree: an answer.
        let mut f = field();
        let bands = all_bands(|side, band| if (side, band) == (1, 0) { -300 } else { 300 });
        feed(&mut f, &bands);
        assert!(rad_s(f.estimate()).is_some_and(|v| v > 0.2));
    }

    #[test]
    fn slow_units_still_filling_their_histograms_answer_a_turns_start() {
        // A slow turn starts: the paper's units have decoded for 60 ms, reading high (they
        // time only the fastest crossings, 0.15 rad/s); the slow units began 20 ms ago, at the
        // true 0.066 rad/s, and their 100 ms histograms hold a fifth of what a steady turn
        // leaves there. Averaged over the histograms, the paper's units agree more per second;
        // over the last 20 ms, the slow units: they answer.
        let mut f = field();
        for period in 0..60u32 {
            for side in 0..2 {
                for band in 0..COL_BANDS {
                    for row in 0..ROW_BANDS {
                        for up in [false, true] {
                            let (x, y) = pixel(side, band, up, row);
                            f.add(Population::Fast, x, y, log2_rate(150), true);
                            if period >= 40 {
                                for _ in 0..2 {
                                    f.add(Population::Slow, x, y, log2_rate(66), true);
                                }
                            }
                        }
                    }
                }
            }
            f.age();
        }
        // Agreeing decodes per µs of each population's time constant (10 ms, 100 ms).
        let per_tau =
            |pop| u128::from(f.consistent_samples_q16(pop)) * 1_000_000 / u128::from(f.tau_us(pop));
        let (fast, slow) = (per_tau(Population::Fast), per_tau(Population::Slow));
        assert!(
            fast > slow,
            "the histograms' averages alone would pick the paper's units"
        );
        let v = rad_s(f.estimate()).expect("a rotation");
        assert!((v - 0.066).abs() < 0.007, "{v}");
    }

    #[test]
    fn the_paper_units_say_nothing_once_their_decodes_stop_at_once() {
        // A steady turn at 0.5 rad/s (30 ms of decodes in every region), then 6 ms of: no
        // decodes (a yaw step: no edge completes a crossing), decodes at half the rate (a turn
        // slowing down), or at the same rate. Their 10 ms histograms still hold 0.5 rad/s in
        // all three, and the rule for a stopped camera (its 20 ms rate below an eighth of the
        // histograms') has not fired.
        for (per_period, answers) in [(0, false), (1, true), (2, true)] {
            let mut f = field();
            feed(&mut f, &all_bands(|_, _| 500));
            for _ in 0..6 {
                for (side, band, _) in all_bands(|_, _| 500) {
                    for row in 0..ROW_BANDS {
                        for up in [false, true] {
                            let (x, y) = pixel(side, band, up, row);
                            for _ in 0..per_period {
                                f.add(Population::Fast, x, y, log2_rate(500), true);
                            }
                        }
                    }
                }
                f.age();
            }
            assert_answer(&f, answers, (0.5, 0.05), &per_period);
            // The reading says why it has no evidence: the gate takes the next answer as a
            // new start (`shared::Confirmation`).
            assert_eq!(f.reading().stopped, !answers, "{per_period}");
        }
    }

    #[test]
    fn the_slow_units_say_nothing_while_their_latest_decodes_split_in_sign() {
        // 400 ms of a slow turn to the right (60 mrad/s, one slow decode per region and
        // period), then 40 ms at the same decode rate with signs `positive(k)`: all positive,
        // two in three (the turn goes on, noisily), or one in two (background activity after a
        // zero crossing). The slow units' 100 ms histograms still hold the turn in all three,
        // and the stop for a camera that stopped (their rate over the last 20 ms) has no
        // reason to fire.
        type Signs = fn(u32) -> bool;
        let cases: [(&str, Signs, bool); 3] = [
            ("all positive", |_| true, true),
            ("two in three", |k| k % 3 < 2, true),
            ("one in two", |k| k.is_multiple_of(2), false),
        ];
        for (case, positive, answers) in cases {
            let mut f = field();
            for period in 0..440u32 {
                for side in 0..2 {
                    for band in 0..COL_BANDS {
                        for row in 0..ROW_BANDS {
                            for up in [false, true] {
                                let (x, y) = pixel(side, band, up, row);
                                let k = period + (side + band + row) as u32 + u32::from(up);
                                let sign = period < 400 || positive(k);
                                f.add(Population::Slow, x, y, log2_rate(60), sign);
                            }
                        }
                    }
                }
                f.age();
            }
            assert_answer(&f, answers, (0.06, 0.03), &case);
            assert!(!f.reading().stopped, "{case}");
        }
    }

    #[test]
    fn a_new_start_needs_most_of_the_latest_decodes_above_the_principal_row_on_its_side() {
        // 30 ms of the paper's units at 0.3 rad/s: every region below the principal row all
        // positive, every region above it `positive` in 9 positive (each region's signed median
        // then lies on the positive side whenever `positive` >= 5).
        let cases = [
            (5, None, false),
            (5, recent(false, false), true),
            (6, None, true),
            (9, None, true),
        ];
        for (positive, recent_motion, answers) in cases {
            let mut f = field();
            f.set_recent_motion(recent_motion);
            for _ in 0..30 {
                for side in 0..2 {
                    for band in 0..COL_BANDS {
                        for row in 0..ROW_BANDS {
                            for k in 0..9 {
                                let (x, y) = pixel(side, band, true, row);
                                f.add(Population::Fast, x, y, log2_rate(300), k < positive);
                                let (x, y) = pixel(side, band, false, row);
                                f.add(Population::Fast, x, y, log2_rate(300), true);
                            }
                        }
                    }
                }
                f.age();
            }
            let case = (positive, recent_motion);
            assert_answer(&f, answers, (0.3, 0.05), &case);
            assert!(!f.reading().stopped && !f.reading().blind, "{case:?}");
        }
    }

    #[test]
    fn agreement_picks_the_population_and_random_signs_do_not_count() {
        // The paper's units decode twice as often as the slow units, with random signs; the
        // slow units agree on 0.1 rad/s: they answer, scaled by nothing (steady decodes).
        let mut f = field();
        for period in 0..300u32 {
            for band in 0..COL_BANDS {
                for side in 0..2 {
                    for row in 0..ROW_BANDS {
                        let (x, y) = pixel(side, band, period % 2 == 0, row);
                        let sign =
                            (period / 2 + band as u32 + side as u32 + row as u32).is_multiple_of(2);
                        for _ in 0..2 {
                            f.add(Population::Fast, x, y, log2_rate(900), sign);
                        }
                        f.add(Population::Slow, x, y, log2_rate(100), true);
                    }
                }
            }
            f.age();
        }
        assert!(f.rate(Population::Fast) > f.rate(Population::Slow));
        let v = rad_s(f.estimate()).expect("a rotation");
        assert!((v - 0.1).abs() < 0.01, "{v}");
        // Choosing by decode rate (a layout without twin units) takes the paper's units.
        f.choose_by_decode_rate();
        assert!(rad_s(f.estimate()).is_none_or(|v| (v - 0.1).abs() > 0.05));
    }
}
