//! The spike readout: yaw rate in rad/s from the network's spikes alone (their times, per
//! unit), the camera geometry and the unit's known parameters.
//!
//! # What a spike train says
//! With `tau_T == tau_m == tau` (the fixed-point core's condition) the unit's membrane obeys
//! `d(v e^(s/tau))/ds = c I_T(s) e^(s/tau)` with `c = g / theta`: in the frame scaled by
//! `e^(s/tau)` the TRG current is a step function that jumps by `D e^(a/tau)` when a TRG event
//! delivers the drive `D` at time `a`, and the membrane is its integral. After each spike the
//! membrane restarts from 0 (after `t_ref`), so every interval between two spikes is a
//! measurement, in closed form:
//! - **Current from an interval.** If the membrane charges from 0 for `L` µs without a new
//!   input before it spikes, the current when it started charging was
//!   `x(L) = e^(L/tau) / (c L)` (only `L <= tau` is possible: the charge peaks at `tau`).
//! - **A burst from rest.** Spikes at `t1`, `t2` with `L = t2 - t1 - t_ref`: the drive and the
//!   TRG event's time are `D = x e^((Δ + t_ref)/tau)` and `t_trg = t1 - Δ`, with
//!   `Δ = 1 / (c x e^(t_ref/tau))` (the first spike's latency).
//! - **A drive during a burst.** Each interval predicts the next from the current it measured
//!   (`y = x e^(-(L + t_ref)/tau)`). When a spike comes early, a TRG event fell in its
//!   interval; the next interval measures the current after it, `x'`, and the early spike's
//!   interval `M` pins the event's time `a`: with `K = x' e^((M + t_ref)/tau) - y`,
//!   `M - a = (e^(M/tau)/c - y M) / K` and `D = K e^(-a/tau)`. The same holds after a burst has
//!   ended (`y` below the spiking level), for `M` up to 65 ms.
//! - **A lone spike.** A burst from rest has a second spike when its drive is at least
//!   `e^(delta + e^(-1 - delta))` (1.45) times the smallest that bursts (`delta = t_ref/tau`:
//!   its first spike's place on the burst orbit must leave a charge that reaches threshold;
//!   [`Kernel::second_spike_log2_q16`]), and the second spike comes within `tau + t_ref` of
//!   the first. A first spike with nothing after it for that long therefore says that the drive
//!   lay in that range ([`BurstDecoder::decode_lone`]): for the paper's units at a pixel with
//!   one onset, a crossing of 47-54 ms. Where the TRG event's time is known (an onset of the
//!   pixel that this unit did not decode, decoded by its twin or by the other network of the
//!   paper's units, within a clean charge before the spike), the latency gives the drive;
//!   else it is read as the middle of the range (in logarithm: the crossing time good to
//!   ±7 %) with that drive's latency. Without them the spike readout lost the slowest
//!   decodes the calibrated readout reads (which decodes a one-spike burst's drive): near the
//!   paper's units' floor a hover's turn read from a third of them (held-out hover seed 631:
//!   28.7 % RMSE / peak against the calibrated readout's 22.3 %; 24.6 % with them).
//!
//! Spike times are whole µs, so a decoded drive is good to about 0.1 % (a 2-spike burst from
//! rest: 0.15 %; test `spike_readout`). A drive is then an edge's travel time, as in the
//! calibrated readout: `dt = -tau_F ln(D / (w_T I_F(TRG, t+)))`, where the TRG pixel's own FAC
//! trace after the onset, `I_F(TRG, t+) = w_F (1 + Σ e^(-(t - t_k)/tau_F))` over its earlier
//! onsets, is rebuilt from the TRG event times decoded at that pixel (either unit; onsets
//! more than `3 tau_F` back are forgotten). Then `|w| = s / (dt (f + (x - c_x)^2 / f))`,
//! positive for right-to-left units, and the rate goes to the same [`field`](super::field)
//! estimator, read as often, as the calibrated readout. As there, only
//! drives that make a burst from rest count, and of the two units of a pixel that answer one
//! TRG event only the one whose drive is at least twice the other's: a decode waits (until an
//! output time, at most until a twin at rest could no longer answer within that range) for the
//! twin's first or early spike after the event, whose latency or interval gives its drive.
//!
//! # Slow units
//! The paper's units (`tau_F` = 20 ms) need a drive of about `w_F / 14.7` to burst, so edges
//! slower than ~47 ms per stride (a 2-spike burst) give them nothing to decode: below about
//! 0.2 rad/s on a DAVIS346. The pipeline therefore runs another network over the same layout
//! and events, of slow units ([`Kernel::SLOW`]: `tau_F` = [`crate::params::TAU_SLOW_US`], the
//! same TRG trace and membrane), whose spikes this readout decodes the same way (the drive then
//! reads with their `tau_F`) into the field's slow population, as the calibrated readout's slow
//! units. Where the paper's units time an edge the slow ones are not read (their 100 ms memory
//! blurs accelerations), by the calibrated readout's rules read from the slow units' own
//! decodes: a slow decode counts only when the crossing it times is longer than the paper's
//! units reach at a pixel without a recent onset (`tau_F ln(w_T w_F / D_min)`, 54 ms), and
//! when the pixel's previous decoded onset came more than `tau_F ln 10` (46 ms: the paper's
//! units' FAC trace is down to a tenth) before it. Their FAC pixel follows the choice between
//! the near units and the layout's (below), as the calibrated readout reads its slow traces:
//! one pixel from the TRG pixel while the near units are chosen, at the layout's stride
//! otherwise ([`crate::network::Network::set_near`]), so that they time, over the same
//! distance, the crossings the chosen units are too fast for.
//!
//! # Near units
//! As the calibrated readout, the spike readout reads near units where the layout has them: the
//! pipeline runs a third network of the paper's units with their FAC pixel one pixel from the TRG
//! pixel ([`crate::network::Network::near_units`]), whose spikes are decoded the same way (the rate
//! then reads over one pixel), and the same rule ([`stride_choice`](super::stride_choice)), fed
//! from both networks' decodes and this readout's answers, chooses between them. One thing
//! differs: a drive decoded from spikes is good to about 0.1 %, and the own trace it is divided
//! by, rebuilt from decoded onsets, to a few per cent, so close to its ceiling (`w_T` times the
//! own trace) the decoded crossing time is mostly error. With the near units chosen they are
//! therefore read only for drives up to [`NEAR_DRIVE_SHARE_LOG2`] of the ceiling (a one-pixel
//! crossing of at least 2.1 ms), and the
//! layout's units only for the onsets that the near unit facing the same way decoded above it: one
//! stride times each onset. Such an onset crossed one pixel faster than the floor, so its layout
//! decode reads no slower than twice the floor over the stride: the near units' decodes kept are
//! those below their ceiling, jitter included, and a layout decode read slower than the floor (its
//! own jitter, or the selection on the near decode's) would join them and sink the field's median
//! (drone seed 1: 10.0 → 9.3 % RMSE / peak with the clamp, seed 61 9.7 → 8.2 %). (Reading the
//! layout's units for every crossing of the stride under `stride` times that floor added a second
//! decode to onsets the near units had timed already, from the fast tail of the layout's decodes:
//! on drone seed 3, 162 k of them while |w| >= 0.6 rad/s, 109 k now.) The slow units read over the
//! chosen stride's distance; a decode of an input timed over the other one (just before the choice
//! changed) compares with the chosen units' reach over its own distance (one pixel in 54 ms is two
//! in 108 ms at stride 2). Nor is a near decode read where the layout's unit facing the same way
//! timed the same onset over its stride faster than the near unit over one pixel, and quickly
//! ([`OVERRULING_FLOORS`]): the near unit's FAC pixel missed that edge, and its decode times an
//! earlier one (drone seed 304, 1.8 rad/s: 13.4 → 11.6 % RMSE / peak; `SpikeCell::overrules`).
//!
//! Causal: the network hands a spike at `t` over by the first output time at or after `t`,
//! and an output at `T` uses the decodes of spikes up to `T`. A decode needs the burst's
//! second spike (1-15 ms after the TRG event), or, for a lone spike, `tau + t_ref` (20.1
//! ms) without one. Warm-up: TRG events in the first
//! [`WARMUP_US`] are not decoded (every pixel's first event looks like an onset), and the
//! outputs say "no evidence" for as long, as the calibrated readout's do; after it the field's
//! support rules decide when the first decodes answer. (Outputs held back until `WARMUP_US +
//! tau + tau_A`, 50 ms, cost scenes that start turning: rotation seed 7 read 27 % worse than
//! the calibrated readout, 10 % with the shared warm-up.)
//!
//! # Edges that move vertically
//! As the calibrated readout, a decode of the paper's units whose edge moves mostly vertically
//! is not read ([`aperture`]); what a vertical neighbour saw is the last onset decoded at that
//! pixel, by either network of the paper's units, at or before the decode's TRG event (a pixel
//! whose units did not burst says nothing: on a camera that only wobbles, with the onsets of
//! its own network alone, 22 % of the decodes found no onset at either neighbour, against 7 %
//! of the calibrated readout's, which reads their traces; counted once with a temporary
//! counter).
//!
//! # Which spikes it reads
//! A decode needs the first interval after a TRG event (from rest: its first two spikes; in
//! a burst: the early spike and the next), or the second when the event came so late in the
//! first that its first spike is hardly early (a third of the decodes on a Prophesee Gen3
//! recording), and the interval before it (what the early spike is early against). Between
//! two inputs a burst follows its orbit, and a spike there says nothing the interval before
//! it did not. So the readout is a sparse sink ([`NetSink::SPARSE`]): the network delivers the
//! first spikes after each input as they come (three after an input that reached the unit
//! mid-burst, for the late ones; two after one that started a burst: from rest, or after a
//! burst, where its first spike is early whenever it comes), and skips the rest, telling the
//! readout where it did ([`NetSink::resume`]: the next spike only marks where the membrane
//! restarts).
//! The last interval before the next input matters only to that input's decode, so the
//! burst's last two spikes before it are delivered when it comes (or when the unit's state is
//! freed, or at the end), and not at all when by then they are older than
//! `M_MAX_US + t_ref` ([`NetSink::tail_memory_us`]: a spike that long after the last starts
//! afresh whatever came before). An input noticed later still (a burst near the refractory
//! limit, whole-µs spike times) was decoded against the wrong interval with every spike; here
//! it is not decoded (0.2 % of the decodes on drone seed 1). On the STM32F405 strip at dev03's
//! rate this took the spiking pipeline from 761 to 347 instructions per event (at 07fb99b;
//! 288 at 6cb30ad with the savings since, `firmware/README.md`); RMSE / peak
//! moves by at most 0.6 points on 72 shared, regime and held-out scenes (two spikes after
//! every input instead: drone seed 1 9.3 → 9.0 %, but a held-out 1.6 rad/s turn 20.3 →
//! 22.5 %, and a third fewer decodes on the Gen3 recording; two only after an input that
//! starts a burst: 15 of 76 scenes better, by up to 0.9 points, 5 worse, by up to 0.4, the Gen3
//! recording 11 148 → 11 144 decodes).
//!
//! # State
//! One [`SpikeCell`] per pixel of the layout and network (three networks: 96 bytes per pixel),
//! from the caller (32 bytes each, on top of the spiking networks' own state): each unit's
//! burst in progress (where its membrane last started charging, 24 bits of µs; what the last
//! interval said; 8 bytes), the pixel's last decoded onset and own trace, each unit's decoded
//! drive for it, and its links in the queue of decodes waiting for a twin's answer and in the
//! queue of bursts waiting for their second spike. Nothing is
//! ever full and no spike goes untracked: a pool of bursts in progress would not be smaller,
//! as up to 45 % of the pixels burst at once on the shared sequences (a drone's fast turn), and
//! a pool that overflows drops decodes unevenly (a pixel that keeps bursting keeps its slot). A
//! sweep visits every cell every 4 s and forgets what is older than `M` (65 ms) or the
//! own-trace memory, so that no stored time is read across its wrap. Decodes waiting for a
//! twin's answer wait in a queue linked through the cells (each cell at most once), so none is
//! ever decided early for want of room; so do the bursts from rest waiting for their second
//! spike.

use fixed::types::I16F16;

use super::aperture::{self, Around};
use super::calibrated::{has_near, Calibration, SLOW_TAU_A_US};
use super::field::{Field, Population};
use super::shared::{
    field_over, slowest_rate_q16, window_log2_s, within_an_octave_of_reach, OutputGate,
    RateDecoder, DOMINANCE_LOG2, LOG2_1E6, WARMUP_US,
};
use super::stride_choice::{Stride, StrideChoice};
use super::{Readout, Side};
use crate::layout::{Dir, Layout};
use crate::log2::{exp2_q16, log2_q16, LOG2E_Q32};
use crate::network::{NetSink, Spike};
use crate::params::Trace;
use crate::time::EventTime;
use crate::unit::{div_u64, Kernel};

/// `log2` (Q16.16) of the largest share of its ceiling (`w_T` times the pixel's own trace) a
/// near unit's drive is read at: 0.9, a crossing of one pixel in `tau_F ln(10/9)` (2.1 ms for
/// the paper's units). Closer to the ceiling a drive decoded from spikes is not precise enough:
/// `dt` is `tau_F` times the logarithm of that share, and the own trace rebuilt from decoded
/// onsets is good to a few per cent, so the fastest edges would read slow. Those edges cross
/// two pixels in under twice that time, and the layout's units time them instead (the onsets
/// a near unit decoded above this share; see the module documentation, "Near units").
pub const NEAR_DRIVE_SHARE_LOG2: i32 = -9962;

/// How many near-unit floors per pixel of its stride a layout unit's crossing may take, at
/// most, to overrule a near unit's slower decode of the same onset (`SpikeCell::overrules`):
/// 4.2 ms per pixel for the paper's units, 8.4 ms over a stride of 2. Slower, the layout's
/// units time edges near the end of their window, where they alias (a hover's slow turns), and
/// the near decode is the one to keep.
pub const OVERRULING_FLOORS: i32 = 2;

/// `log2(e)` in Q16.
const LOG2E_Q16: i64 = (LOG2E_Q32 >> 16) as i64;
/// A clean interval of `L` µs matches the predicted current within `TOL_Q16 / L` (Q16.16
/// `log2`): 2 µs of timing, `log2(e) · 2 / L`.
const TOL_Q16: u32 = 2 * LOG2E_Q16 as u32;

/// [`SpikeCell::next`] of a cell that is not in its population's waiting queue.
const NOT_QUEUED: u32 = u32::MAX;
/// [`SpikeCell::next`] of the last cell of the waiting queue.
const QUEUE_END: u32 = u32::MAX - 1;

/// Two decodes of one pixel whose TRG event times differ by at most this (µs) answer the
/// same onset. Decoded times are mostly within a few µs of the true ones, but a decode during
/// a burst can be off by more than 50 µs, and at 50 µs one onset decoded by both units was
/// often counted twice on busy scenes: the own trace grew by a phantom onset and fast turns
/// read 15-25 % low (drone scenes). Distinct onsets of one pixel come at least ~1 ms apart (an
/// edge crossing a pixel at 2 rad/s on a DAVIS346 takes 1.4-2.2 ms).
pub const SAME_ONSET_US: u32 = 250;

/// [`SpikeCell::onset`]'s bit saying that the onset before the last one came within the busy
/// window before it.
const BUSY: u32 = 1 << 2;

/// Every cell is visited by the sweep at least this often (µs), well within the 2^23 µs a
/// 24-bit time can be told from.
const SWEEP_PERIOD_US: u32 = 4_000_000;

/// `log2` values are kept in 16 bits with 10 fractional bits.
const L2_SHIFT: u32 = 6;

/// Q16.16 to the stored Q5.10 (rounded, saturating; never `i16::MIN`, which means none).
#[inline]
fn l2_pack(v: i32) -> i16 {
    ((v.saturating_add(1 << (L2_SHIFT - 1))) >> L2_SHIFT).clamp(-i16::MAX as i32, i16::MAX as i32)
        as i16
}

/// The stored Q5.10 to Q16.16.
#[inline]
fn l2_unpack(v: i16) -> i32 {
    i32::from(v) << L2_SHIFT
}

/// µs from a 24-bit time `s` to `t`, when `t` is not before it (within 2^23 µs).
#[inline]
fn since24(t: u32, s: u32) -> Option<u32> {
    let d = t.wrapping_sub(s) & 0x00FF_FFFF;
    (d < 1 << 23).then_some(d)
}

/// States of a tracked unit (top 3 bits of [`Track::packed`]).
mod state {
    /// Nothing known: the next spike starts a burst from rest.
    pub const IDLE: u32 = 0;
    /// One spike of a burst from rest seen; the next interval decodes it.
    pub const REST: u32 = 1;
    /// A spike came early (a TRG event in its interval `M`); the next interval decodes it.
    pub const PERT: u32 = 2;
    /// The current at the last charging start is known (`l2y`).
    pub const CLEAN: u32 = 3;
    /// A spike with no usable history: the next interval measures the current, decodes
    /// nothing.
    pub const UNKNOWN: u32 = 4;
    /// The next spike follows spikes of the burst that were skipped
    /// ([`NetSink::resume`](crate::network::NetSink::resume)): it only marks where the
    /// membrane restarts (then as [`UNKNOWN`]).
    pub const RESUMED: u32 = 5;
}

/// `M` is kept in steps of `2^M_SHIFT` µs, up to [`M_MAX_US`].
const M_SHIFT: u32 = 3;
/// Longest early-spike interval kept (µs): 13 bits of 8 µs.
const M_MAX_US: u32 = ((1 << 13) - 1) << M_SHIFT;

/// One unit's burst in progress. 8 bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(C)]
struct Track {
    /// Bits 23..0: where the membrane last started charging, the last spike's time plus
    /// `t_ref` (µs, modulo 2^24); bits 31..24: one byte of the pixel's own trace (see
    /// [`SpikeCell`]).
    s_ref: u32,
    /// State (bits 31..29), `M` of a [`state::PERT`] in 8 µs steps (bits 28..16), and `log2`
    /// of the current (Q5.10, bits 15..0) at `s_ref` ([`state::CLEAN`]) or at the start of
    /// the early spike's interval ([`state::PERT`]).
    packed: u32,
}

impl Track {
    const IDLE: Self = Self {
        s_ref: 0,
        packed: 0,
    };

    #[inline]
    fn s_ref(&self) -> u32 {
        self.s_ref & 0x00FF_FFFF
    }

    #[inline]
    fn set_s_ref(&mut self, t: u32) {
        self.s_ref = (self.s_ref & 0xFF00_0000) | (t & 0x00FF_FFFF);
    }

    #[inline]
    fn state(&self) -> u32 {
        self.packed >> 29
    }

    /// `log2 y` (Q16.16).
    #[inline]
    fn l2y(&self) -> i32 {
        l2_unpack(self.packed as u16 as i16)
    }

    /// `M` (µs).
    #[inline]
    fn m_us(&self) -> u32 {
        ((self.packed >> 16) & 0x1FFF) << M_SHIFT
    }

    /// The unit's next spike follows skipped ones ([`state::RESUMED`]).
    #[inline]
    fn resume(&mut self) {
        self.set(state::RESUMED, 0, 0);
    }

    #[inline]
    fn set(&mut self, st: u32, m_us: u32, l2y: i32) {
        let m = (m_us.saturating_add(1 << (M_SHIFT - 1)) >> M_SHIFT).min(0x1FFF);
        self.packed = (st << 29) | (m << 16) | u32::from(l2_pack(l2y) as u16);
    }

    /// The full time (µs) of the last spike, given a time `now` at or after it.
    #[inline]
    fn last_spike(&self, now: u32, t_ref: u32) -> u32 {
        now.wrapping_sub(now.wrapping_sub(self.s_ref()) & 0x00FF_FFFF)
            .wrapping_sub(t_ref)
    }
}

/// What the spike readout keeps of one pixel: its two units' bursts in progress, its last
/// decoded onset with its own trace, each unit's decoded drive for that onset, and its link in
/// the queues of decodes waiting for a twin's answer and of bursts waiting for their second
/// spike. 32 bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct SpikeCell {
    /// Its two units, in [`Dir`] slot order (their top bytes hold the own trace, U4F12:
    /// high byte in unit 0, low byte in unit 1; 0 = no onset).
    units: [Track; 2],
    /// Time of the last decoded onset (µs, bits 31..3), whether the onset before it came less
    /// than the readout's busy window earlier (bit 2; see [`Spikes::with_slow_units`]) and, in
    /// bit `u`, whether unit `u`'s
    /// decode of it waits for its twin.
    onset: u32,
    /// `log2 D` (Q5.10) each unit decoded for that onset; `i16::MIN` = none.
    l2d: [i16; 2],
    /// The next cell in the population's queue of decodes waiting for a twin's answer
    /// ([`QUEUE_END`]: the last; [`NOT_QUEUED`]: this cell is not in it).
    next: u32,
    /// The next cell in the population's queue of bursts from rest waiting for their second
    /// spike (the same markers).
    lone_next: u32,
}

impl SpikeCell {
    /// A pixel with nothing in progress (for static arrays).
    pub const EMPTY: Self = Self {
        units: [Track::IDLE; 2],
        onset: 0,
        l2d: [i16::MIN; 2],
        next: NOT_QUEUED,
        lone_next: NOT_QUEUED,
    };

    /// Bytes of one cell's state.
    pub const BYTES: usize = core::mem::size_of::<Self>();

    /// The own trace after the last onset (U4F12 bits; 0 = none).
    #[inline]
    fn own_bits(&self) -> u32 {
        let [a, b] = self.units;
        ((a.s_ref >> 24) << 8) | (b.s_ref >> 24)
    }

    #[inline]
    fn own(&self) -> Trace {
        Trace::from_bits(self.own_bits() << 15)
    }

    #[inline]
    fn set_own(&mut self, own: Option<Trace>) {
        let bits = own.map_or(0, |o| ((o.to_bits() + (1 << 14)) >> 15).clamp(1, 0xFFFF));
        let [a, b] = &mut self.units;
        a.s_ref = (a.s_ref & 0x00FF_FFFF) | ((bits >> 8) << 24);
        b.s_ref = (b.s_ref & 0x00FF_FFFF) | ((bits & 0xFF) << 24);
    }

    /// The last onset's time (µs, to 8 µs), if there is one.
    #[inline]
    fn t_onset(&self) -> Option<u32> {
        (self.own_bits() != 0).then_some(self.onset & !7)
    }

    /// Whether unit `u` decoded the onset at `t_trg` (the same TRG event, within
    /// [`SAME_ONSET_US`]) with a drive above [`NEAR_DRIVE_SHARE_LOG2`] of the pixel's ceiling
    /// (`log2_w_trg`: `log2(w_T)`, Q16.16): for the near units, an edge they cannot time.
    fn decoded_at_ceiling(&self, t_trg: u32, u: usize, log2_w_trg: i32) -> bool {
        self.decoded_share(t_trg, u, log2_w_trg)
            .is_some_and(|share| share > NEAR_DRIVE_SHARE_LOG2)
    }

    /// `log2` (Q16.16) of the share of the pixel's ceiling (`w_T` times its own trace;
    /// `log2_w_trg`: `log2(w_T)`) of the drive with which unit `u` decoded the onset at `t_trg`
    /// (the same TRG event, within [`SAME_ONSET_US`]), if it did.
    fn decoded_share(&self, t_trg: u32, u: usize, log2_w_trg: i32) -> Option<i32> {
        let (Some(t0), Some(&l2d)) = (self.t_onset(), self.l2d.get(u)) else {
            return None;
        };
        let apart = (t_trg.wrapping_sub(t0) as i32).unsigned_abs();
        if l2d == i16::MIN || apart > SAME_ONSET_US + 8 {
            return None;
        }
        Some(
            l2_unpack(l2d)
                .saturating_sub(log2_w_trg)
                .saturating_sub(log2_q16(u64::from(self.own().to_bits()), 27)),
        )
    }

    /// Whether this cell's layout unit `u` decoded the onset at `t_trg` as crossing its
    /// `stride` faster than the near unit facing the same way read one pixel (`near_share`: the
    /// near decode's `log2` share of its ceiling, Q16.16), and within [`OVERRULING_FLOORS`]
    /// near floors per pixel: the near unit's FAC pixel then missed this edge (an onset merged
    /// into its previous run), and its decode times an earlier one. On fast turns over dense
    /// texture those decodes read a fifth of the turn and sank whole regions (drone seed 304
    /// at 1.8 rad/s: the upper regions of the right outer band 0.36 rad/s).
    fn overrules(
        &self,
        t_trg: u32,
        u: usize,
        log2_w_trg: i32,
        near_share: i32,
        stride: u16,
    ) -> bool {
        let quick = NEAR_DRIVE_SHARE_LOG2.saturating_mul(OVERRULING_FLOORS * i32::from(stride));
        self.decoded_share(t_trg, u, log2_w_trg)
            .is_some_and(|share| share > near_share && share > quick)
    }

    /// Whether the onset before the last came within the busy window before it.
    #[inline]
    fn busy(&self) -> bool {
        self.onset & BUSY != 0
    }

    #[inline]
    fn waits(&self, u: usize) -> bool {
        self.onset & (1 << u) != 0
    }

    #[inline]
    fn set_waits(&mut self, u: usize, on: bool) {
        if on {
            self.onset |= 1 << u;
        } else {
            self.onset &= !(1 << u);
        }
    }
}

impl Default for SpikeCell {
    fn default() -> Self {
        Self::EMPTY
    }
}

/// A decoded TRG event: its time and the drive it delivered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Decoded {
    /// Time of the TRG event (µs).
    pub t_us: u32,
    /// `log2` of its drive `D = w_T I_F(FAC, t-)` (Q16.16).
    pub log2_drive: i32,
    /// Whether it started a burst from rest (else it came during or after one).
    pub from_rest: bool,
}

/// The unit's constants and the closed forms of the module documentation, in fixed point
/// (Q16.16 logarithms, integer µs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BurstDecoder {
    /// `tau = tau_T = tau_m` (µs).
    tau_us: u32,
    /// `t_ref` (µs).
    t_ref_us: u32,
    /// `log2(e) / tau` per µs, Q32.
    inv_tau_q32: u64,
    /// `log2 c`, `c = g / theta` per µs (Q16.16).
    log2_c: i32,
    /// `log2 e^(t_ref/tau)` (Q16.16).
    l2_tref: i32,
    /// `log2` of the smallest drive that makes a burst from rest (Q16.16).
    l2_min_drive: i32,
    /// `log2` of the drive a lone spike is read with (Q16.16): the middle of the one-spike
    /// range, [`Kernel::second_spike_log2_q16`] wide above `l2_min_drive`.
    l2_lone_drive: i32,
    /// The latency (µs) of a spike from rest with that drive: how long before a lone spike its
    /// TRG event is taken to have come, when no decoded onset of the pixel says when.
    lone_latency_us: u32,
}

impl BurstDecoder {
    /// The decoder of `kernel`'s unit.
    pub fn new(kernel: &Kernel) -> Self {
        let p = kernel.params();
        let tau = p.tau_trg_us.max(1);
        let mut d = Self {
            tau_us: tau,
            t_ref_us: p.t_ref_us,
            inv_tau_q32: LOG2E_Q32 / u64::from(tau),
            log2_c: log2_q16(u64::from(p.gain_per_s), 0)
                .saturating_sub(log2_q16(u64::from(p.theta.to_bits()), 16))
                .saturating_sub(LOG2_1E6),
            l2_tref: 0,
            l2_min_drive: log2_q16(u64::from(kernel.min_burst_drive().to_bits()), 27),
            l2_lone_drive: 0,
            lone_latency_us: 0,
        };
        d.l2_tref = d.l2_time(p.t_ref_us);
        d.l2_lone_drive = d
            .l2_min_drive
            .saturating_add(kernel.second_spike_log2_q16() / 2);
        // From rest the drive falls with the latency up to `tau` (`x(L)`): the first latency
        // whose drive is at most the lone spike's.
        let (mut lo, mut hi) = (1u32, tau);
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if d.l2x(mid) <= d.l2_lone_drive {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        d.lone_latency_us = lo;
        d
    }

    /// A unit's burst from rest whose first spike came at `t1` and no second one within
    /// `tau + t_ref` after it (it would have by then: a clean charge peaks at `tau`) had one
    /// spike: its drive lay between the smallest that bursts and
    /// [`Kernel::second_spike_log2_q16`] more (the paper's units: an edge's crossing 47-54 ms
    /// long at a pixel with one onset, past what a burst's first interval times). Where the
    /// first of the pixel's decoded onsets `onsets` that came within a clean charge before `t1`
    /// (1 µs to `tau`) was the TRG event, and the latency gives the drive; with none, the drive
    /// is taken at the middle of the range's logarithms (a crossing time good to ±7 %) and the
    /// event at that drive's latency.
    pub fn decode_lone(&self, t1: u32, onsets: impl IntoIterator<Item = u32>) -> Decoded {
        let exact = onsets.into_iter().find_map(|t0| {
            let lat = EventTime::from_us(t1)
                .since(EventTime::from_us(t0))
                .filter(|lat| (1..=self.tau_us).contains(lat))?;
            Some((t0, self.l2x(lat)))
        });
        let (t_us, log2_drive) =
            exact.unwrap_or((t1.wrapping_sub(self.lone_latency_us), self.l2_lone_drive));
        Decoded {
            t_us,
            log2_drive,
            from_rest: true,
        }
    }

    /// `log2 e^(us/tau)` (Q16.16) of a whole number of µs.
    #[inline]
    fn l2_time(&self, us: u32) -> i32 {
        let us = u64::from(us.min(1 << 24));
        ((us * self.inv_tau_q32) >> 16).min(i32::MAX as u64) as i32
    }

    /// `log2 e^(t/tau)` (Q16.16) of a time in Q16 µs (non-negative).
    #[inline]
    fn l2_time_q16(&self, t_q16: i64) -> i32 {
        let t = t_q16.clamp(0, 1 << 40) as u64;
        ((u128::from(t) * u128::from(self.inv_tau_q32)) >> 32).min(i32::MAX as u128) as i32
    }

    /// `log2 L` (Q16.16) of an interval of `L >= 1` µs, as [`BurstDecoder::l2x_of`] and
    /// [`BurstDecoder::l2y_of`] take it.
    #[inline]
    fn l2_interval(l_us: u32) -> i32 {
        log2_q16(u64::from(l_us.max(1)), 0)
    }

    /// `log2 x(L)`: the current at the start of a clean charge of `L >= 1` µs.
    #[inline]
    fn l2x(&self, l_us: u32) -> i32 {
        self.l2x_of(l_us, Self::l2_interval(l_us))
    }

    /// [`BurstDecoder::l2x`] with `log2 L` given (`l2_l`).
    #[inline]
    fn l2x_of(&self, l_us: u32, l2_l: i32) -> i32 {
        self.l2_time(l_us)
            .saturating_sub(self.log2_c)
            .saturating_sub(l2_l)
    }

    /// `log2 y`: the current at the next charging start after a clean charge of `L` µs.
    #[inline]
    fn l2y_after(&self, l_us: u32) -> i32 {
        self.l2y_of(Self::l2_interval(l_us))
    }

    /// [`BurstDecoder::l2y_after`] from `log2 L` (`l2_l`).
    #[inline]
    fn l2y_of(&self, l2_l: i32) -> i32 {
        self.log2_c
            .saturating_neg()
            .saturating_sub(l2_l)
            .saturating_sub(self.l2_tref)
    }

    /// How long (µs) after a unit's last spike the decoder still reads it: a spike more than
    /// `M_MAX_US` after the start of the charge before it (the last spike plus `t_ref`) starts
    /// afresh whatever came before, and one µs more covers the rounding of spike times
    /// ([`NetSink::tail_memory_us`]).
    pub fn tail_memory_us(&self) -> u32 {
        M_MAX_US.saturating_add(self.t_ref_us).saturating_add(1)
    }

    /// `log2` of the smallest drive that makes a burst from rest (Q16.16).
    pub fn log2_min_drive(&self) -> i32 {
        self.l2_min_drive
    }

    /// A burst from rest with first spike at `t1` and the next charge lasting `l_us`.
    fn burst_from_rest(&self, t1: u32, l_us: u32) -> Option<Decoded> {
        let l2x = self.l2x(l_us);
        // Δ = 1 / (c x e^(t_ref/tau)), µs Q16.
        let l2_delta = self
            .log2_c
            .saturating_add(l2x)
            .saturating_add(self.l2_tref)
            .saturating_neg();
        let delta_q16 = i64::from(exp2_q16(l2_delta));
        let l2d = l2x.saturating_add(
            self.l2_time_q16(delta_q16.saturating_add(i64::from(self.t_ref_us) << 16)),
        );
        let delta_us = ((delta_q16 + (1 << 15)) >> 16).clamp(0, i64::from(u32::MAX)) as u32;
        Some(Decoded {
            t_us: t1.wrapping_sub(delta_us),
            log2_drive: l2d,
            from_rest: true,
        })
    }

    /// A TRG event in the interval of `m_us` µs that started at `s0` with current `2^l2yb`,
    /// whose next charge (after the early spike) lasted `l_us`.
    fn perturbed(&self, s0: u32, m_us: u32, l2yb: i32, l_us: u32) -> Option<Decoded> {
        let l2x = self.l2x(l_us);
        let m = m_us.min(1 << 24);
        // K = x' e^((M + t_ref)/tau) - y  (Q16).
        let a_term = i64::from(exp2_q16(
            l2x.saturating_add(self.l2_time(m.saturating_add(self.t_ref_us))),
        ));
        let yb = i64::from(exp2_q16(l2yb));
        let k = a_term - yb;
        if k <= 0 {
            return None;
        }
        // N = e^(M/tau) / c - y M  (Q16, µs x current).
        let n = i64::from(exp2_q16(self.l2_time(m).saturating_sub(self.log2_c)))
            - yb.saturating_mul(i64::from(m));
        if n <= 0 {
            return None;
        }
        // M - a = N / K (Q16 µs); the event may have come during the refractory period before
        // the interval (a < 0), then it counts from the interval's start.
        // Both positive; a 32-bit quotient (M - a below 65.5 ms) takes the narrow division.
        let ma_q16 = div_u64((n as u64) << 16, k as u64) as i64;
        let a_q16 = ((i64::from(m) << 16) - ma_q16).max(0);
        let l2d = log2_q16(k as u64, 16).saturating_sub(self.l2_time_q16(a_q16));
        let a_us = ((a_q16 + (1 << 15)) >> 16).clamp(0, i64::from(m)) as u32;
        Some(Decoded {
            t_us: s0.wrapping_add(a_us),
            log2_drive: l2d,
            from_rest: false,
        })
    }

    /// `log2` of the drive of a TRG event at `t_trg` that moved a unit whose membrane started
    /// charging at `s0` with current `2^l2yb` (`-inf` for a unit at rest) to spike at `t`
    /// (the twin's answer to an event another unit decoded).
    fn drive_of_spike(&self, t_trg: u32, s0: Option<(u32, i32)>, t: u32) -> Option<i32> {
        let lat = EventTime::from_us(t).since(EventTime::from_us(t_trg))?;
        match s0 {
            None => {
                // From rest: c D lat e^(-lat/tau) = 1.
                (lat >= 1).then(|| self.l2x(lat))
            }
            Some((s0, l2yb)) => {
                let m = EventTime::from_us(t).since(EventTime::from_us(s0))?;
                let a = m.checked_sub(lat)?;
                // c e^(-M/tau) [y M + K (M - a)] = 1  =>  K = (e^(M/tau)/c - y M) / (M - a).
                let yb = i64::from(exp2_q16(l2yb));
                let n = i64::from(exp2_q16(self.l2_time(m).saturating_sub(self.log2_c)))
                    - yb.saturating_mul(i64::from(m));
                if n <= 0 || lat == 0 {
                    return None;
                }
                Some(
                    log2_q16(n as u64, 16)
                        .saturating_sub(log2_q16(u64::from(lat), 0))
                        .saturating_sub(self.l2_time(a)),
                )
            }
        }
    }

    /// The TRG events a unit's spike train (in time order, from rest) shows, by the rules of
    /// the readout (the unit tracked alone: no twin, no pixel memory).
    pub fn decode_train(&self, spikes: &[u32], out: impl FnMut(Decoded)) {
        self.decode_delivered(spikes.iter().map(|&t| (t, false)), out);
    }

    /// [`BurstDecoder::decode_train`] of the spikes a [`NetSink::SPARSE`] sink gets: each
    /// spike's time and whether it resumes after skipped spikes ([`NetSink::resume`]).
    pub fn decode_sparse_train(&self, spikes: &[(u32, bool)], out: impl FnMut(Decoded)) {
        self.decode_delivered(spikes.iter().copied(), out);
    }

    /// The decodes of a unit's spikes `(time, resumes after skipped spikes)`, from rest.
    fn decode_delivered(
        &self,
        spikes: impl Iterator<Item = (u32, bool)>,
        mut out: impl FnMut(Decoded),
    ) {
        let mut tr = Track::IDLE;
        for (t, resumed) in spikes {
            if resumed {
                tr.resume();
            }
            if let Some(d) = self.spike(&mut tr, t, true) {
                out(d);
            }
        }
    }

    /// One spike of a tracked unit at `t`; `fresh` says whether the unit may be taken to start
    /// from rest when it has no usable history. Returns the TRG event the spike completes, if
    /// any.
    fn spike(&self, tr: &mut Track, t: u32, fresh: bool) -> Option<Decoded> {
        let first = if fresh { state::REST } else { state::UNKNOWN };
        let s_prev = tr.s_ref();
        let since = since24(t, s_prev);
        tr.set_s_ref(t.wrapping_add(self.t_ref_us));
        if tr.state() == state::RESUMED {
            tr.set(state::UNKNOWN, 0, 0);
            return None;
        }
        let Some(since) = since.filter(|&s| s >= 1) else {
            // Within the refractory period, or out of order: nothing to measure.
            tr.set(state::UNKNOWN, 0, 0);
            return None;
        };
        let st = tr.state();
        if st == state::IDLE || since > M_MAX_US {
            tr.set(first, 0, 0);
            return None;
        }
        match st {
            state::REST | state::PERT | state::UNKNOWN => {
                if since > self.tau_us {
                    // Not a clean charge: the last spike ended its burst.
                    tr.set(first, 0, 0);
                    return None;
                }
                let (m, l2yb) = (tr.m_us(), tr.l2y());
                tr.set(state::CLEAN, 0, self.l2y_after(since));
                // Times from here on are whole µs of the event clock (the 24 bits of `s_ref`
                // are only ever compared with a spike less than 2^23 µs later).
                let t_prev = t.wrapping_sub(since).wrapping_sub(self.t_ref_us);
                match st {
                    state::REST => self.burst_from_rest(t_prev, since),
                    state::PERT => self.perturbed(t_prev.wrapping_sub(m), m, l2yb, since),
                    _ => None,
                }
            }
            _ => {
                // CLEAN: does the spike come when the measured current says it should? (Every
                // spike of a burst passes here: one logarithm, shared by `x` and `y`, and a
                // 32-bit division.)
                let l2_since = Self::l2_interval(since);
                let l2x = self.l2x_of(since, l2_since);
                let l2y = tr.l2y();
                let tol = (TOL_Q16 / since).min(1 << 16) as i32 + (1 << L2_SHIFT);
                if since <= self.tau_us && (l2x - l2y).abs() <= tol {
                    tr.set(state::CLEAN, 0, self.l2y_of(l2_since));
                } else if since <= self.tau_us && l2x < l2y - tol {
                    // Later than possible: the model lost track.
                    tr.set(state::UNKNOWN, 0, 0);
                } else {
                    tr.set(state::PERT, since, l2y);
                }
                None
            }
        }
    }
}

/// Appends `cell` to the queue `(first, last)` (`None`: empty) linked through the field of
/// [`SpikeCell`] that `link` picks, unless it is in it (its link is not [`NOT_QUEUED`]).
/// Returns whether it was appended.
#[inline]
fn append(
    cells: &mut [SpikeCell],
    queue: &mut Option<(u32, u32)>,
    cell: u32,
    link: impl Fn(&mut SpikeCell) -> &mut u32,
) -> bool {
    let Some(c) = cells.get_mut(cell as usize) else {
        return false;
    };
    if *link(c) != NOT_QUEUED {
        return false;
    }
    *link(c) = QUEUE_END;
    *queue = match *queue {
        None => Some((cell, cell)),
        Some((head, tail)) => {
            if let Some(t) = cells.get_mut(tail as usize) {
                *link(t) = cell;
            }
            Some((head, cell))
        }
    };
    true
}

/// One population's decoding: its units' kernel (the FAC time constant a drive is read
/// with), its per-pixel memory (borrowed) and the decodes waiting for a twin's answer.
struct Decoding<'a> {
    population: Population,
    /// Which units' FAC pixel distance: the near units' (1 px) or the layout's stride.
    stride: Stride,
    kernel: &'a Kernel,
    decoder: BurstDecoder,
    /// `log2(tau_F)` (µs, Q16.16).
    log2_tau_fac: i32,
    /// The own-trace memory, `3 tau_F` (µs).
    memory_us: u32,
    /// The slow units' rule (`None` for the paper's units).
    slow_rule: Option<SlowRule>,
    /// One per cell.
    cells: &'a mut [SpikeCell],
    /// The queue of cells with a decode waiting for the twin's answer, in the order they
    /// started waiting, linked through [`SpikeCell::next`]: first and last cell (`None`:
    /// empty), length.
    queue: Option<(u32, u32)>,
    queued: usize,
    /// The cells with a unit whose burst from rest has shown one spike, waiting for its second,
    /// in the order their spikes came, linked through [`SpikeCell::lone_next`]: first and last
    /// cell (`None`: empty). A unit waits `tau` after the charge that follows its spike
    /// starts (a clean charge peaks by then), then its spike is read as a lone one if it has
    /// shown nothing since ([`Decoding::lone`]): one visit per burst, not one per output.
    lone_queue: Option<(u32, u32)>,
}

/// Where the paper's units time an edge, the slow units' decode of it is not read: derived from
/// the paper's units' kernel.
#[derive(Clone, Copy)]
struct SlowRule {
    /// An onset within this long (µs) after the pixel's previous one marks the cell busy:
    /// `tau_F ln 10` of the paper's units (46 ms), the age at which their FAC trace has fallen
    /// to a tenth.
    busy_us: u32,
    /// `log2` (Q16.16, s) of the longest crossing the paper's units burst on at a pixel without
    /// a recent onset (own trace `w_F`): where `w_T w_F e^(-dt/tau_F)` falls to the smallest
    /// drive that makes a burst, `dt = tau_F ln(w_T w_F / D_min)` (54 ms).
    reach_log2_s: i32,
}

impl SlowRule {
    /// The rule for slow units beside the paper's units of `fast`.
    fn beside(fast: &Kernel) -> Self {
        let tau_us = fast.params().tau_fac_us;
        Self {
            busy_us: (u64::from(tau_us) * 23_026 / 10_000) as u32,
            reach_log2_s: window_log2_s(fast, log2_q16(u64::from(tau_us), 0)),
        }
    }
}

/// What the populations' decodes go to: the field estimator and the geometry.
struct Target<L: Layout> {
    layout: L,
    field: Field,
    rates: RateDecoder,
    /// `log2(w_T)` (Q16.16).
    log2_w_trg: i32,
    /// The latest time seen (µs).
    now: u32,
    /// TRG events before this time (µs) are not decoded: the warm-up after the first output
    /// (every pixel's first event looks like an onset).
    decode_from: Option<u32>,
    /// Decodes added to the field so far.
    samples: u64,
    /// Decodes dropped because the twin unit answered the same TRG event about as strongly.
    ambiguous: u64,
    /// Whether the near units' decodes or the layout's go to the field.
    stride: StrideChoice,
    /// `log2` (Q16.16, s) of the shortest crossing of one pixel read from the near units
    /// (with them: [`Spikes::with_near_units`]; `i32::MIN` without).
    near_floor_log2_s: i32,
    /// Which FAC pixel the slow units' network reads.
    slow_fac: SlowFacPixel,
}

/// Which FAC pixel the slow units' network reads: one pixel from the TRG pixel while the near
/// units are chosen, at the layout's stride otherwise (as the calibrated readout reads the
/// slow traces), so that the slow units time the crossings the chosen stride's paper's units
/// are too fast for, over the same distance. The choice changes at an output
/// ([`Readout::slow_units_near`]); a decode needs the distance that was in force at its TRG
/// event, up to a few ms before the last change (changes come at least
/// [`LOOK_EVERY`](super::stride_choice::LOOK_EVERY) outputs apart).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct SlowFacPixel {
    /// One pixel away for the events after `since_us`.
    near: bool,
    /// The output time (µs) of the last change.
    since_us: u32,
    /// The distance for the events up to `since_us`.
    before: bool,
}

impl SlowFacPixel {
    /// At the layout's stride (as the network starts).
    const LAYOUT: Self = Self {
        near: false,
        since_us: 0,
        before: false,
    };

    /// Whether a TRG event at `t_us` read the FAC pixel one pixel away.
    fn near_at(&self, t_us: u32) -> bool {
        if EventTime::from_us(t_us).is_after(EventTime::from_us(self.since_us)) {
            self.near
        } else {
            self.before
        }
    }

    /// The distance for the events after the output at `t_us`.
    fn follow(&mut self, near: bool, t_us: u32) {
        if near != self.near {
            *self = Self {
                near,
                since_us: t_us,
                before: self.near,
            };
        }
    }
}

/// The spike readout's state: each population's decoding, the field's histograms and the
/// decoding constants.
pub struct Spikes<'a, L: Layout> {
    cal: Calibration,
    gate: OutputGate,
    target: Target<L>,
    /// The paper's units (the main network).
    fast: Decoding<'a>,
    /// The slow units (a side network), if read.
    slow: Option<Decoding<'a>>,
    /// The near units (a side network of the paper's units with FAC pixels one pixel away),
    /// if read.
    near: Option<Decoding<'a>>,
    /// Cells swept per output, and the next one.
    sweep: (usize, usize),
}

impl<'a> Decoding<'a> {
    fn new(
        (population, stride): (Population, Stride),
        kernel: &'a Kernel,
        cells: &'a mut [SpikeCell],
        slow_rule: Option<SlowRule>,
    ) -> Self {
        cells.fill(SpikeCell::EMPTY);
        let p = kernel.params();
        Self {
            population,
            stride,
            kernel,
            decoder: BurstDecoder::new(kernel),
            log2_tau_fac: log2_q16(u64::from(p.tau_fac_us), 0),
            memory_us: p.tau_fac_us.saturating_mul(3),
            slow_rule,
            cells,
            queue: None,
            queued: 0,
            lone_queue: None,
        }
    }

    /// Appends `cell` to the waiting queue unless it is in it.
    fn enqueue(&mut self, cell: usize) {
        if append(self.cells, &mut self.queue, cell as u32, |c| &mut c.next) {
            self.queued += 1;
        }
    }

    /// Takes `cell` off the waiting queue, `prev` being the cell before it (`None`: it is
    /// the first) and `next` the one after it (`QUEUE_END`: it is the last).
    fn unlink(&mut self, prev: Option<u32>, cell: u32, next: u32) {
        let Some((head, tail)) = self.queue else {
            return;
        };
        if let Some(c) = self.cells.get_mut(cell as usize) {
            c.next = NOT_QUEUED;
        }
        let tail = if tail == cell { prev } else { Some(tail) };
        let head = match prev {
            None => (next != QUEUE_END).then_some(next),
            Some(p) => {
                if let Some(c) = self.cells.get_mut(p as usize) {
                    c.next = next;
                }
                Some(head)
            }
        };
        self.queue = head.zip(tail);
        self.queued = self.queued.saturating_sub(1);
    }

    /// Unit `dir` at `cell` resumes after skipped spikes of its burst ([`NetSink::resume`]).
    fn resume(&mut self, cell: u32, dir: Dir) {
        if let Some(tr) = self
            .cells
            .get_mut(cell as usize)
            .and_then(|c| c.units.get_mut(dir.slot()))
        {
            tr.resume();
        }
    }

    /// One spike of unit `dir` at `cell`.
    fn spike<L: Layout>(
        &mut self,
        target: &mut Target<L>,
        cell: u32,
        dir: Dir,
        t_us: u32,
        other: Option<&[SpikeCell]>,
    ) {
        if EventTime::from_us(t_us).is_after(EventTime::from_us(target.now)) {
            target.now = t_us;
        }
        let Self { decoder, cells, .. } = self;
        let Some(tr) = cells
            .get_mut(cell as usize)
            .and_then(|c| c.units.get_mut(dir.slot()))
        else {
            return;
        };
        let decoded = decoder.spike(tr, t_us, true);
        if tr.state() == state::REST {
            // A burst's first spike: it waits for its second (`Decoding::lone`).
            self.enqueue_lone(cell);
        }
        if let Some(d) = decoded {
            self.decoded(target, cell as usize, dir, d, other);
        }
    }

    /// Reads the lone spikes of the bursts from rest queued before `now` - `tau` whose unit has
    /// shown nothing since ([`BurstDecoder::decode_lone`]).
    fn lone_spikes<L: Layout>(
        &mut self,
        target: &mut Target<L>,
        now: u32,
        other: Option<&[SpikeCell]>,
    ) {
        let tau = self.decoder.tau_us;
        while let Some((head, tail)) = self.lone_queue {
            let Some(c) = self.cells.get_mut(head as usize) else {
                break;
            };
            // Which of its units have waited long enough, and whether another still waits.
            let (mut due, mut waiting) = ([false; 2], false);
            for (tr, due) in c.units.iter().zip(due.iter_mut()) {
                if tr.state() == state::REST {
                    if since24(now, tr.s_ref()).is_some_and(|d| d > tau) {
                        *due = true;
                    } else {
                        waiting = true;
                    }
                }
            }
            if due == [false; 2] && waiting {
                // The oldest still waits: so do those after it.
                break;
            }
            let next = c.lone_next;
            c.lone_next = NOT_QUEUED;
            self.lone_queue = (next != QUEUE_END).then_some((next, tail));
            for (u, _) in due.into_iter().enumerate().filter(|&(_, due)| due) {
                self.lone(target, head as usize, u, other);
            }
            if waiting {
                self.enqueue_lone(head);
            }
        }
    }

    /// Appends `cell` to the lone spikes' queue unless it is in it.
    fn enqueue_lone(&mut self, cell: u32) {
        append(self.cells, &mut self.lone_queue, cell, |c| &mut c.lone_next);
    }

    /// Decodes the lone spike of unit `u` at `cell` (in [`state::REST`], waited long enough). As
    /// the TRG event's time it takes the pixel's last onset that this unit did not decode, as
    /// decoded here, else as decoded by the other network of the paper's units (`other`: the
    /// same pixel's events), when it came within a clean charge before the spike.
    fn lone<L: Layout>(
        &mut self,
        target: &mut Target<L>,
        cell: usize,
        u: usize,
        other: Option<&[SpikeCell]>,
    ) {
        let t_ref = self.decoder.t_ref_us;
        let Some(c) = self.cells.get_mut(cell) else {
            return;
        };
        let undecoded = c.l2d.get(u).is_some_and(|&l| l == i16::MIN);
        let own = c.t_onset().filter(|_| undecoded);
        let Some(tr) = c.units.get_mut(u) else {
            return;
        };
        let t1 = tr.last_spike(target.now, t_ref);
        // Its next spike starts afresh.
        tr.set(state::IDLE, 0, 0);
        let peer = other.and_then(|o| o.get(cell)).and_then(SpikeCell::t_onset);
        let d = self.decoder.decode_lone(t1, own.into_iter().chain(peer));
        if let Some(&dir) = Dir::BOTH.get(u) {
            self.decoded(target, cell, dir, d, other);
        }
    }

    /// The own trace just after an onset at `t` of a pixel whose last onset was `(t0, own)`.
    fn own_after(&self, last: Option<(u32, Trace)>, t: u32) -> Trace {
        let w_fac = self.kernel.fac_input(Trace::ZERO);
        match last {
            Some((t0, own)) => match EventTime::from_us(t).since(EventTime::from_us(t0)) {
                Some(age) if age <= self.memory_us => {
                    self.kernel.fac_input(self.kernel.decay_fac(own, age))
                }
                _ => w_fac,
            },
            None => w_fac,
        }
    }

    /// A decoded TRG event of unit `dir` at `cell`: the pixel's own trace, the gate, then the
    /// decode waits for the twin's answer. `other`: the other network of the paper's units'
    /// cells (see [`Decoding::resolve`]).
    fn decoded<L: Layout>(
        &mut self,
        target: &mut Target<L>,
        cell: usize,
        dir: Dir,
        d: Decoded,
        other: Option<&[SpikeCell]>,
    ) {
        let Some(c) = self.cells.get(cell).copied() else {
            return;
        };
        let last = c.t_onset();
        let dt = last.map_or(i32::MAX, |l| d.t_us.wrapping_sub(l) as i32);
        let same = dt.unsigned_abs() <= SAME_ONSET_US + 8;
        if !same && dt < 0 {
            // An earlier onset decoded late: its memory joins the later one.
            let w_fac = self.kernel.fac_input(Trace::ZERO);
            let own = c
                .own()
                .saturating_add(self.kernel.decay_fac(w_fac, dt.unsigned_abs()));
            if let Some(c) = self.cells.get_mut(cell) {
                c.set_own(Some(own));
            }
            return;
        }
        if !same {
            // A new onset: what waits for the last one is decided now.
            for u in 0..2 {
                if c.waits(u) {
                    self.resolve(target, cell, u, None, other);
                }
            }
            let own = self.own_after(last.map(|t0| (t0, c.own())), d.t_us);
            if let Some(c) = self.cells.get_mut(cell) {
                let busy = self
                    .slow_rule
                    .is_some_and(|r| last.is_some_and(|l| d.t_us.wrapping_sub(l) <= r.busy_us));
                c.onset = (d.t_us & !7) | if busy { BUSY } else { 0 };
                c.set_own(Some(own));
                c.l2d = [i16::MIN; 2];
            }
        }
        let u = dir.slot();
        let Some(c) = self.cells.get_mut(cell) else {
            return;
        };
        if let Some(l) = c.l2d.get_mut(u) {
            *l = l2_pack(d.log2_drive);
        }
        if d.log2_drive < self.decoder.l2_min_drive {
            return;
        }
        c.set_waits(u, true);
        self.enqueue(cell);
    }

    /// Decides the decode waiting at `cell`, unit `u`: added to the field when the twin
    /// answered the same TRG event at most half as strongly, dropped when it answered more
    /// strongly; with no answer yet, added once a twin at rest could no longer answer within
    /// that range (at `now`), else left waiting (`false`). `now = None`: decide now. `other`:
    /// the cells of the other network of the paper's units, if the layout has near units (the
    /// near units' for the layout's units, the layout's for the near units; `None` for the slow
    /// units): with the near units chosen, a layout unit's decode is read only for an onset
    /// the near unit facing the same way decoded at its ceiling; and both read the onsets
    /// either network decoded at their vertical neighbours ([`Decoding::moves_vertically`]).
    fn resolve<L: Layout>(
        &mut self,
        target: &mut Target<L>,
        cell: usize,
        u: usize,
        now: Option<u32>,
        other: Option<&[SpikeCell]>,
    ) -> bool {
        let decoder = self.decoder;
        // Calls from `settle` find one of a queued cell's units often waiting for nothing (a
        // new onset asks only the units that wait): the cell is copied only when it waits.
        let c = match self.cells.get(cell) {
            Some(c) if c.waits(u) => *c,
            _ => return true,
        };
        let (Some(&l2d), Some(&twin_l2d), Some(twin), Some(t_trg)) = (
            c.l2d.get(u),
            c.l2d.get(1 - u),
            c.units.get(1 - u),
            c.t_onset(),
        ) else {
            return true;
        };
        let answer = if twin_l2d != i16::MIN {
            Some(l2_unpack(twin_l2d))
        } else {
            let t_spike = twin.last_spike(target.now, decoder.t_ref_us);
            let after = EventTime::from_us(t_spike).is_after(EventTime::from_us(t_trg));
            match twin.state() {
                state::REST if after => decoder.drive_of_spike(t_trg, None, t_spike),
                state::PERT if after => {
                    let s0 = t_spike.wrapping_sub(twin.m_us());
                    decoder.drive_of_spike(t_trg, Some((s0, twin.l2y())), t_spike)
                }
                _ => None,
            }
        };
        let l2d = l2_unpack(l2d);
        let needed = l2d.saturating_sub((DOMINANCE_LOG2 << 16) as i32);
        let add = match (answer, now) {
            (Some(l2), _) => l2 <= needed,
            (None, None) => true,
            (None, Some(now)) => {
                // A twin at rest with a drive above `needed` would have spiked by now.
                let waited = EventTime::from_us(now).elapsed_since(EventTime::from_us(t_trg));
                if waited < decoder.tau_us && decoder.l2x(waited.max(1)) > needed {
                    return false;
                }
                true
            }
        };
        if let Some(c) = self.cells.get_mut(cell) {
            c.set_waits(u, false);
        }
        if !add {
            target.ambiguous += 1;
            return true;
        }
        let warm = target
            .decode_from
            .is_some_and(|f| !EventTime::from_us(f).is_after(EventTime::from_us(t_trg)));
        if !warm {
            return true;
        }
        // dt = -tau_F ln(D / (w_T own)), then the rotation at the pixel's column.
        let log2_own = log2_q16(u64::from(c.own().to_bits()), 27);
        let l = l2d
            .saturating_sub(target.log2_w_trg)
            .saturating_sub(log2_own);
        let Some(l2dt) = RateDecoder::log2_dt_s(l, self.log2_tau_fac) else {
            return true;
        };
        let positive = u == Dir::RightToLeft.slot();
        let chosen = target.stride.choice();
        // The layout's units take `stride` times as long over their stride as the near units
        // over one pixel: their reach and the near units' floor, in the layout's terms.
        let log2_stride = target.rates.log2_stride();
        let (x, y) = target.layout.pixel(cell);
        let mut region = None;
        // The distance the input was timed over: the slow units' FAC pixel as it was at the
        // TRG event ([`SlowFacPixel`]).
        let over = match self.slow_rule {
            Some(_) if target.slow_fac.near_at(t_trg) => Stride::Near,
            Some(_) => Stride::Layout,
            None => self.stride,
        };
        // The crossing time read (`l2dt`, or the near units' floor for the layout's decode of
        // an onset they decoded at their ceiling, below).
        let l2dt = match self.slow_rule {
            Some(rule) => {
                // The chosen stride's paper's units' reach, over the distance `over`.
                let reach = match (chosen, over) {
                    (Stride::Near, Stride::Layout) => rule.reach_log2_s.saturating_add(log2_stride),
                    (Stride::Layout, Stride::Near) => rule.reach_log2_s.saturating_sub(log2_stride),
                    _ => rule.reach_log2_s,
                };
                if c.busy() || l2dt <= reach {
                    // The paper's units time this edge: it crossed within their reach, or the
                    // pixel had another onset shortly before. Within an octave of their reach
                    // it lies beyond the slow units' floor ([`Field::add_beyond_floor`]).
                    if !c.busy() && within_an_octave_of_reach(l2dt, reach) {
                        let floor = target.rates.rotation_rate_over(over, reach, x);
                        let region = target.field.geometry().region(x, y);
                        target.field.add_beyond_floor(region, positive, floor);
                    }
                    return true;
                }
                l2dt
            }
            None => {
                // The paper's units of either stride: counted for the choice between them.
                // With the near units chosen they time the edges slower than the floor and
                // the layout's units the faster ones (see [`NEAR_DRIVE_SHARE_LOG2`]).
                if StrideChoice::counts_row(y) {
                    let r = target.field.geometry().region(x, y);
                    target.stride.add(self.stride, r, positive);
                    region = Some(r);
                }
                let read = match (chosen, self.stride) {
                    (Stride::Layout, Stride::Layout) => Some(l2dt),
                    (Stride::Layout, Stride::Near) => None,
                    // Not where the layout's unit facing the same way timed the same onset over
                    // its stride faster than this one over a pixel (`SpikeCell::overrules`).
                    (Stride::Near, Stride::Near) => {
                        // Looked up only for a decode that would be read.
                        let overruled = || {
                            let stride = target.layout.stride();
                            other.and_then(|n| n.get(cell)).is_some_and(|n| {
                                n.overrules(t_trg, u, target.log2_w_trg, l, stride)
                            })
                        };
                        (l2dt >= target.near_floor_log2_s && !overruled()).then_some(l2dt)
                    }
                    // The onsets the near units decoded at their ceiling, whatever the layout's
                    // units read: one stride times each onset. Such an onset crossed one pixel
                    // faster than the floor, so its layout decode reads no slower than twice
                    // the floor over the stride: read slower (its own jitter) it would rank
                    // among the near units' slower decodes, and the field's median would sink.
                    (Stride::Near, Stride::Layout) => other
                        .and_then(|n| n.get(cell))
                        .filter(|n| n.decoded_at_ceiling(t_trg, u, target.log2_w_trg))
                        .map(|_| l2dt.min(target.near_floor_log2_s.saturating_add(log2_stride))),
                };
                let Some(l2dt) = read else {
                    return true;
                };
                if self.moves_vertically(target, (x, y), t_trg, (c.own(), log2_own), l, other) {
                    return true;
                }
                l2dt
            }
        };
        let l2 = target.rates.rotation_rate_over(over, l2dt, x);
        let region = region.unwrap_or_else(|| target.field.geometry().region(x, y));
        target.field.add_in(self.population, region, l2, positive);
        target.samples += 1;
        true
    }

    /// Whether a decode `l` (`log2(D / (w_T own))`, Q16) of the onset at `t_trg` of pixel
    /// `(x, y)`, whose own trace after it is `own` (and its `log2`, Q16), times an edge that
    /// moves mostly vertically ([`aperture`]), as the onsets decoded at the pixels the layout's
    /// stride above and below by this network or `other` say (their traces rebuilt as the
    /// pixel's own; a neighbour whose last decoded onset came after `t_trg` says nothing).
    fn moves_vertically<L: Layout>(
        &self,
        target: &Target<L>,
        (x, y): (u16, u16),
        t_trg: u32,
        (own, log2_own): (Trace, i32),
        l: i32,
        other: Option<&[SpikeCell]>,
    ) -> bool {
        let s = target.layout.stride();
        let ratio = |t: Trace| {
            (t.to_bits() > 0).then(|| log2_q16(u64::from(t.to_bits()), 27).saturating_sub(log2_own))
        };
        let w_fac = self.kernel.fac_input(Trace::ZERO);
        // The pixel's last onset decoded by either population of the paper's units, at or
        // before `t_trg`: how long before it, and the own trace after it.
        let last_before = |cells: &[SpikeCell], i: usize| {
            let c = cells.get(i)?;
            let age = EventTime::from_us(t_trg).since(EventTime::from_us(c.t_onset()?))?;
            Some((age, c.own()))
        };
        let vertical = [-i32::from(s), i32::from(s)].map(|dy| {
            let row = u16::try_from(i32::from(y) + dy).ok()?;
            let i = target.layout.cell(x, row)?;
            let (age, own) = [Some(&*self.cells), other]
                .into_iter()
                .flatten()
                .filter_map(|cells| last_before(cells, i))
                .min_by_key(|&(age, _)| age)?;
            ratio(self.kernel.decay_fac(own, age))
        });
        if vertical == [None, None] {
            return false;
        }
        let around = Around {
            vertical,
            own_before: ratio(own.saturating_sub(w_fac)),
            reach: self
                .decoder
                .l2_min_drive
                .saturating_sub(target.log2_w_trg)
                .saturating_sub(log2_own),
        };
        let s_h = match self.stride {
            Stride::Near => 1,
            Stride::Layout => s,
        };
        aperture::moves_vertically(l, [s_h, s], &around)
    }

    /// Decides what waits for a twin that has answered or can no longer answer by `t_us`
    /// (`other`: as for [`Decoding::resolve`]).
    fn settle<L: Layout>(
        &mut self,
        target: &mut Target<L>,
        t_us: u32,
        other: Option<&[SpikeCell]>,
    ) {
        // Lone spikes first: their decodes wait for the twin too (decided in this walk).
        self.lone_spikes(target, t_us, other);
        // The queue is walked in place: the decided cells leave it, the others keep their
        // order (deciding never adds to it). At most its length in steps.
        let mut prev = None;
        let mut cur = self.queue.map(|(head, _)| head);
        for _ in 0..self.queued {
            let Some(cell) = cur else {
                break;
            };
            let Some(next) = self.cells.get(cell as usize).map(|c| c.next) else {
                break;
            };
            let mut done = true;
            for u in 0..2 {
                if !self.resolve(target, cell as usize, u, Some(t_us), other) {
                    done = false;
                }
            }
            if done {
                self.unlink(prev, cell, next);
            } else {
                prev = Some(cell);
            }
            cur = (next != QUEUE_END && next != NOT_QUEUED).then_some(next);
        }
    }

    /// Forgets bursts and onsets too old to matter in `count` cells from `next` on (so that
    /// each is visited long before its times wrap); returns the next cell.
    fn sweep(&mut self, t_us: u32, count: usize, mut next: usize) -> usize {
        let memory = self.memory_us;
        for _ in 0..count.min(self.cells.len()) {
            if next >= self.cells.len() {
                next = 0;
            }
            if let Some(c) = self.cells.get_mut(next) {
                for u in c.units.iter_mut() {
                    if u.state() != state::IDLE
                        && since24(t_us, u.s_ref()).is_none_or(|d| d > M_MAX_US)
                    {
                        u.packed = 0;
                    }
                }
                let old = c.t_onset().is_some_and(|t0| {
                    EventTime::from_us(t_us)
                        .since(EventTime::from_us(t0))
                        .is_none_or(|a| a > memory)
                });
                if old && !c.waits(0) && !c.waits(1) {
                    c.set_own(None);
                    c.l2d = [i16::MIN; 2];
                }
            }
            next += 1;
        }
        next
    }
}

impl<'a, L: Layout> Spikes<'a, L> {
    /// The decoding of side network `side`, if it runs, and the target it decodes into.
    fn side(&mut self, side: Side) -> (Option<&mut Decoding<'a>>, &mut Target<L>) {
        let decoding = match side {
            Side::Slow => self.slow.as_mut(),
            Side::Near => self.near.as_mut(),
        };
        (decoding, &mut self.target)
    }

    /// [`SpikeCell`]s the readout needs for `layout` per population (one per cell).
    pub fn cells_for(layout: &L) -> usize {
        layout.cell_count()
    }

    /// A readout for the network of `kernel` over `layout`, with its memory in `cells` (at
    /// least [`Spikes::cells_for`]; pixels beyond the slice are not decoded).
    pub fn new(
        kernel: &'a Kernel,
        layout: L,
        cal: Calibration,
        cells: &'a mut [SpikeCell],
    ) -> Self {
        let len = Self::cells_for(&layout).min(cells.len());
        let cells = cells.get_mut(..len).unwrap_or_default();
        let p = kernel.params();
        let per_output = cells
            .len()
            .div_ceil((SWEEP_PERIOD_US / cal.period_us.max(1)).max(1) as usize)
            .max(1);
        let field = field_over(
            &layout,
            (cal.focal_px, cal.cx, cal.cy),
            cal.field,
            [cal.tau_a_us, cal.tau_a_us.max(SLOW_TAU_A_US)],
            cal.period_us,
        );
        let rates = RateDecoder::new(&layout, cal.focal_px, cal.cx);
        let floor_q16 = slowest_rate_q16(kernel, &rates);
        Self {
            target: Target {
                rates,
                log2_w_trg: log2_q16(u64::from(p.w_trg.to_bits()), 16),
                layout,
                field,
                now: 0,
                decode_from: None,
                samples: 0,
                ambiguous: 0,
                stride: StrideChoice::new(false),
                near_floor_log2_s: i32::MIN,
                slow_fac: SlowFacPixel::LAYOUT,
            },
            // The warm-up's onsets are not decoded; after it the field's own rules say when
            // its first decodes are evidence enough (as for the calibrated readout).
            gate: OutputGate::new(cal.period_us, WARMUP_US, floor_q16),
            fast: Decoding::new((Population::Fast, Stride::Layout), kernel, cells, None),
            slow: None,
            near: None,
            sweep: (per_output, 0),
            cal,
        }
    }

    /// The same readout also decoding the slow units of `kernel` (a network with
    /// `tau_F` = [`crate::params::TAU_SLOW_US`]: [`Kernel::SLOW`]), with their memory in
    /// `cells` (at least [`Spikes::cells_for`]). Their decodes go to the field's slow
    /// population.
    pub fn with_slow_units(mut self, kernel: &'a Kernel, cells: &'a mut [SpikeCell]) -> Self {
        let len = Self::cells_for(&self.target.layout).min(cells.len());
        let cells = cells.get_mut(..len).unwrap_or_default();
        let rule = SlowRule::beside(self.fast.kernel);
        self.slow = Some(Decoding::new(
            (Population::Slow, Stride::Layout),
            kernel,
            cells,
            Some(rule),
        ));
        self
    }

    /// The same readout also decoding the near units (the paper's units with their FAC pixel
    /// one pixel away: [`crate::network::Network::near_units`]), with their memory in `cells`
    /// (at least [`Spikes::cells_for`]), if the layout has them
    /// ([`has_near`]). Their decodes or the layout's units' go to
    /// the field's paper's-units population, as the calibrated readout chooses
    /// ([`stride_choice`](super::stride_choice)).
    pub fn with_near_units(mut self, cells: &'a mut [SpikeCell]) -> Self {
        if !has_near(&self.target.layout) {
            return self;
        }
        let len = Self::cells_for(&self.target.layout).min(cells.len());
        let cells = cells.get_mut(..len).unwrap_or_default();
        let kernel = self.fast.kernel;
        self.target.near_floor_log2_s =
            RateDecoder::log2_dt_s(NEAR_DRIVE_SHARE_LOG2, self.fast.log2_tau_fac)
                .unwrap_or(i32::MIN);
        self.near = Some(Decoding::new(
            (Population::Fast, Stride::Near),
            kernel,
            cells,
            None,
        ));
        self.target.stride = StrideChoice::new(true);
        self
    }

    /// The settings.
    pub fn calibration(&self) -> &Calibration {
        &self.cal
    }

    /// Decodes added to the field so far.
    pub fn samples(&self) -> u64 {
        self.target.samples
    }

    /// Decodes dropped because the twin unit answered the same TRG event about as strongly.
    pub fn ambiguous(&self) -> u64 {
        self.target.ambiguous
    }
}

impl<L: Layout> NetSink for Spikes<'_, L> {
    const SPIKES: bool = true;
    /// A spike in a burst whose unit no input has reached since its last two spikes says
    /// nothing new: it comes where those two put it (the `CLEAN` state's check). The readout
    /// reads the first intervals after each input and the last one before the next input, so
    /// the network skips the rest.
    const SPARSE: bool = true;

    fn resume(&mut self, cell: u32, dir: Dir) {
        self.fast.resume(cell, dir);
    }

    /// [`BurstDecoder::tail_memory_us`] (the three networks' units have one `t_ref`).
    fn tail_memory_us(&self) -> u32 {
        self.fast.decoder.tail_memory_us()
    }

    fn spike(&mut self, s: Spike) {
        self.spikes(s.cell, s.dir, &[s.t_us]);
    }

    fn spikes(&mut self, cell: u32, dir: Dir, times: &[u32]) {
        let near = self.near.as_ref().map(|n| &*n.cells);
        for &t in times {
            self.fast.spike(&mut self.target, cell, dir, t, near);
        }
    }
}

impl<L: Layout> Readout for Spikes<'_, L> {
    const SLOW_UNITS: bool = true;
    const NEAR_UNITS: bool = true;

    fn side_spikes(&mut self, side: Side, cell: u32, dir: Dir, times: &[u32]) {
        // The near units read the layout's units' decoded onsets too (the vertical
        // neighbours of [`Decoding::moves_vertically`]). (Spelled out here, not through
        // `Spikes::side` returning them as well: that cost the F405 window 5 instructions per
        // event in QEMU, 400 -> 405, the same output.)
        let (decoding, other) = match side {
            Side::Slow => (self.slow.as_mut(), None),
            Side::Near => (self.near.as_mut(), Some(&*self.fast.cells)),
        };
        let Some(decoding) = decoding else {
            return;
        };
        for &t in times {
            decoding.spike(&mut self.target, cell, dir, t, other);
        }
    }

    fn side_resume(&mut self, side: Side, cell: u32, dir: Dir) {
        if let (Some(decoding), _) = self.side(side) {
            decoding.resume(cell, dir);
        }
    }

    fn output(&mut self, t_us: u32) -> (I16F16, u8) {
        let target = &mut self.target;
        if EventTime::from_us(t_us).is_after(EventTime::from_us(target.now)) {
            target.now = t_us;
        }
        if target.decode_from.is_none() {
            // The first output comes one period after the first event.
            target.decode_from = Some(
                t_us.wrapping_sub(self.cal.period_us)
                    .wrapping_add(WARMUP_US),
            );
        }
        // Every spike up to `t_us` is in: decide what waits for a twin that has answered or can
        // no longer answer.
        let near = self.near.as_ref().map(|n| &*n.cells);
        self.fast.settle(target, t_us, near);
        if let Some(slow) = self.slow.as_mut() {
            slow.settle(target, t_us, None);
        }
        if let Some(near) = self.near.as_mut() {
            near.settle(target, t_us, Some(&*self.fast.cells));
        }
        // Forget bursts and onsets too old to matter (a few cells per output).
        let (per_output, next) = self.sweep;
        let after = self.fast.sweep(t_us, per_output, next);
        for side in [self.slow.as_mut(), self.near.as_mut()]
            .into_iter()
            .flatten()
        {
            side.sweep(t_us, per_output, next);
        }
        self.sweep = (per_output, after);
        target.stride.age(self.cal.period_us);
        let near = self.near.is_some() && target.stride.choice() == Stride::Near;
        target.slow_fac.follow(near, t_us);
        let out = self.gate.output(&mut target.field);
        target.stride.follow_answer(out, target.rates.focal_bits());
        out
    }

    fn slow_units_near(&self) -> bool {
        self.target.slow_fac.near
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The image speed the stride choice's fast motion is measured against is one pixel per
    /// near units' floor for the paper's units (the crossing of [`NEAR_DRIVE_SHARE_LOG2`] of
    /// the ceiling, `tau_F ln(10/9)`), to 1 %: one rule for "too fast to time across a pixel".
    #[test]
    fn the_near_floor_image_speed_is_a_pixel_per_near_floor() {
        use crate::params::TdeParams;
        use crate::readout::stride_choice::NEAR_FLOOR_IMAGE_SPEED_PX_S;
        let tau_s = f64::from(TdeParams::DEFAULT.tau_fac_us) * 1e-6;
        let floor_s =
            -tau_s * f64::from(NEAR_DRIVE_SHARE_LOG2) / 65_536.0 * core::f64::consts::LN_2;
        let px_s = 1.0 / floor_s;
        let off = (px_s / NEAR_FLOOR_IMAGE_SPEED_PX_S as f64 - 1.0).abs();
        assert!(
            off < 0.01,
            "{px_s:.1} px/s against {NEAR_FLOOR_IMAGE_SPEED_PX_S}"
        );
    }

    /// A near cell whose unit 1 decoded the onset at 10 ms with `share` of its ceiling
    /// (`log2_w_trg`: `w_T` = 2; own trace 1.5).
    fn near_cell(share: f64, log2_w_trg: i32) -> SpikeCell {
        let mut c = SpikeCell::EMPTY;
        let own = Trace::from_num(1.5);
        c.set_own(Some(own));
        c.onset = 10_000;
        let l2 = log2_w_trg
            + log2_q16(u64::from(c.own().to_bits()), 27)
            + (share.log2() * 65_536.0) as i32;
        c.l2d = [i16::MIN, l2_pack(l2)];
        c
    }

    #[test]
    fn a_slow_decode_reads_the_fac_pixel_in_force_at_its_trg_event() {
        let mut f = SlowFacPixel::LAYOUT;
        assert!(!f.near_at(5_000));
        f.follow(true, 10_000);
        // Events up to the output at 10 ms read the layout's stride, those after it one pixel.
        assert!(!f.near_at(9_000) && !f.near_at(10_000));
        assert!(f.near_at(10_001));
        // The same choice again changes nothing.
        f.follow(true, 74_000);
        assert!(!f.near_at(10_000) && f.near_at(20_000));
        // Back to the layout's stride: the decodes of inputs before the change still read one
        // pixel.
        f.follow(false, 138_000);
        assert!(f.near_at(100_000) && !f.near_at(140_000));
        // Across the clock's wrap.
        f.follow(true, u32::MAX - 10);
        assert!(!f.near_at(u32::MAX - 20) && f.near_at(5));
    }

    #[test]
    fn the_layout_reads_an_onset_only_where_the_near_unit_decoded_it_at_its_ceiling() {
        let log2_w_trg = 1 << 16;
        let at = near_cell(0.95, log2_w_trg);
        assert!(at.decoded_at_ceiling(10_000, 1, log2_w_trg));
        // The same onset, its decode times within SAME_ONSET_US of each other.
        assert!(at.decoded_at_ceiling(10_000 + SAME_ONSET_US, 1, log2_w_trg));
        // The near units time this one themselves.
        assert!(!near_cell(0.85, log2_w_trg).decoded_at_ceiling(10_000, 1, log2_w_trg));
        // The other unit decoded nothing; another onset 1 ms later is not this one.
        assert!(!at.decoded_at_ceiling(10_000, 0, log2_w_trg));
        assert!(!at.decoded_at_ceiling(11_000, 1, log2_w_trg));
        assert!(!SpikeCell::EMPTY.decoded_at_ceiling(10_000, 1, log2_w_trg));
    }
}
