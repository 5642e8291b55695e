//! The paper's readout: `tau_A dA/dt = -A + Σ δ(right-to-left spike) - Σ δ(left-to-right spike)`
//! (signed so that positive = turning right, like the yaw rate). Each spike is weighted exactly,
//! `e^(-(T - t_spike)/tau_A)` at the output time `T`. Dividing by `max |A|` over the recording
//! (which needs the future) is left to the host.
//!
//! # Range
//! `A` is integrated in an `i64` with 24 fractional bits: it holds ±2^39 spikes, more than any
//! layout can produce (each unit adds at most `tau_A / t_ref + 1` to `|A|`: 10^4 for the
//! longest `tau_A`, 1 s, and 8.4 M units on the largest sensor).
//!
//! The output ([`YawSample::yaw_rate`](super::YawSample), I16F16) is `A` in units of `2^s`
//! spikes, `s = 10 + ceil(log2(tau_A / 10 ms))` ([`Normalized::output_shift`]): 1,024 spikes at
//! the default `tau_A` = 10 ms, resolution 1/64 spike. It saturates only beyond `2^(15 + s)`
//! spikes, which scales with `tau_A` as the bound above does: 33.5 M at 10 ms, more than a dense
//! DAVIS346 network (178,880 units) can produce at the refractory limit (18.2 M). Since the host
//! divides by the maximum over the recording, the scale cancels out of `host-sim run
//! --readout normalized`'s `yaw_norm`.
//!
//! # Spikes ahead of the clock
//! The readout takes spikes up to [`AHEAD_MAX_US`] (at most 14 output periods) beyond the
//! network's clock ([`NetSink::ahead_us`]), into one bin per output time, each spike weighted to
//! its own output time; a spike an input takes back ([`NetSink::retract`]) leaves its bin again.
//! An output adds only its own bin: it counts exactly the spikes up to its time. Outputs must
//! come once per period (as [`crate::pipeline::Pipeline`] calls them). A caller that reads its
//! recording ahead ([`crate::network::Network::event_in_ahead`]) has units emit up to 254
//! output periods ahead ([`NetSink::reach_us`]; on the host), the same spikes into the same
//! bins.

use fixed::types::I16F16;

use super::Readout;
use crate::exp_table::{ExpDecay, Part};
use crate::layout::Dir;
use crate::network::{NetSink, Spike};
use crate::settings::NORMALIZED_TAU_A_US;
use crate::unit::elapsed_us;

/// Fractional bits of the integrator.
const FRAC: u32 = 24;

/// Output periods the readout holds spikes for (the current one and those ahead): on the
/// host also those a recording read ahead emits at once ([`NetSink::reach_us`]: 254 periods,
/// 254 ms at 1 kHz, longer than nearly every burst).
#[cfg(not(target_os = "none"))]
const RING: usize = 256;

/// Output periods the readout holds spikes for (the current one and those ahead).
#[cfg(target_os = "none")]
const RING: usize = 16;

/// Spike-to-output distances (µs) whose weight at the default `tau_A` comes from a table of
/// its own ([`DEFAULT_NEAR`]): those of a spike in its own output period at 1 kHz.
const NEAR: usize = 1_024;

/// `e^(-d/tau_A)` (Q24) for `d` < [`NEAR`] µs at the default `tau_A`
/// ([`NORMALIZED_TAU_A_US`]), computed at compile time (in flash on the MCU): one look-up in
/// place of two and a product, the same bits as [`weight_from_tables`] (tested).
static DEFAULT_NEAR: [u32; NEAR] = near_weights(&ExpDecay::new(NORMALIZED_TAU_A_US));

/// [`weight_from_tables`] for `d` < [`NEAR`], at compile time.
// Compile-time only; `d < NEAR` (1 024) bounds the indices: `d & 0xFF` < 256, `d >> 8` < 4
// (`get` is not usable in const fn here).
#[allow(clippy::indexing_slicing)]
const fn near_weights(decay: &ExpDecay) -> [u32; NEAR] {
    let (lo, _) = decay.table(Part::Lo);
    let (mid, _) = decay.table(Part::Mid);
    let mut out = [0u32; NEAR];
    let mut d = 0;
    while d < NEAR {
        out[d] = lo_mid_weight(lo[d & 0xFF], mid[d >> 8]) as u32;
        d += 1;
    }
    out
}

/// How far ahead of the clock (µs) the readout takes spikes, at most. The spikes that count
/// are the same for any horizon (tested); the horizon trades visits to units in a burst (a unit
/// in a dense burst is visited about once per horizon, or once per output period if that is
/// longer, each visit with its fixed cost) against spikes an input takes back (each about as
/// costly as a spike). Measured on dev03: 1 ms is the faster on the host (4 ms: 5 % slower).
#[cfg(not(target_os = "none"))]
pub const AHEAD_MAX_US: u32 = 1_000;

/// How far ahead of the clock (µs) the readout takes spikes, at most (see the host's value).
/// Measured in QEMU by the whole run's virtual time (`mcu_time_us` at `-icount shift=0`: one
/// instruction per ns; input and decoding, the same for every horizon, included) on dev03's
/// 192 x 40 window with a unit pool of 4 000: 3.68 s at 0.5 ms, 3.13 s at 2 ms; on a 245 k-event
/// slice of it 350 / 305 / 296 / 301 ms at 0.5 / 1 / 2 / 4 ms; the dense layout with a pool of
/// 50 000: 33.6 s at 0.5 ms, 27.4 s at 2 ms. (0.5 ms had been chosen with a per-event meter
/// that counted each event modulo one 1 ms SysTick period, undercounting the events whose
/// output tick emits spikes for longer; the meter now counts whole periods.)
#[cfg(target_os = "none")]
pub const AHEAD_MAX_US: u32 = 2_000;

/// Leaky integrator of spikes, in units of spikes (Q39.24).
pub struct Normalized {
    decay: ExpDecay,
    /// `near[d]` = [`weight_from_tables`]`(d)`, Q24: [`DEFAULT_NEAR`] at the default
    /// `tau_A`, else empty.
    near: &'static [u32],
    /// `A` at `t_last`, Q39.24.
    a: i64,
    t_last: u32,
    /// Contributions of spikes to the output at `next + k·period` (ring index `head + k`),
    /// each weighted to that time (Q39.24).
    bins: [i64; RING],
    head: usize,
    next: u32,
    /// Output period (µs, >= 1).
    period_us: u32,
    /// Output unit: `2^shift` spikes.
    shift: u32,
    started: bool,
}

impl Normalized {
    /// A readout with time constant `tau_a_us` and output period `period_us`.
    pub fn new(tau_a_us: u32, period_us: u32) -> Self {
        let period_us = period_us.max(1);
        let decay = ExpDecay::new(tau_a_us);
        let near: &'static [u32] = if decay.tau_us() == NORMALIZED_TAU_A_US {
            &DEFAULT_NEAR
        } else {
            &[]
        };
        Self {
            decay,
            near,
            a: 0,
            t_last: 0,
            bins: [0; RING],
            head: 0,
            next: 0,
            period_us,
            shift: output_shift(tau_a_us),
            started: false,
        }
    }

    /// Adds `sign ·` the weight of a spike at `t_us` to its output's bin.
    #[inline]
    fn add(&mut self, t_us: u32, negative: bool) {
        let (k, end) = self.period_of(t_us);
        let w = self.weight(end.wrapping_sub(t_us));
        self.add_to_bin(k, w, negative);
    }

    /// The output period of a spike at `t_us`, counted from the current one (`k`), and the
    /// output time it is weighted to, the end of that period: the current output time, or `k
    /// = ceil(d / period)` periods after it for a spike `d` µs after it.
    #[inline]
    fn period_of(&self, t_us: u32) -> (u32, u32) {
        let d = t_us.wrapping_sub(self.next) as i32;
        let k = if d <= 0 {
            0
        } else {
            // One 32-bit division (a single instruction on the Cortex-M4); the period is >= 1.
            (d as u32 - 1).checked_div(self.period_us).unwrap_or(0) + 1
        };
        (k, self.next.wrapping_add(k.wrapping_mul(self.period_us)))
    }

    /// The ring index of output period `k` (the last bin holds every period beyond the ring).
    #[inline]
    fn ring_index(&self, k: u32) -> usize {
        (self.head + (k as usize).min(RING - 1)) % RING
    }

    /// Adds `sum` (Q39.24), negated if `negative`, to output period `k`'s bin.
    #[inline]
    fn add_to_bin(&mut self, k: u32, sum: i64, negative: bool) {
        let i = self.ring_index(k);
        if let Some(b) = self.bins.get_mut(i) {
            if negative {
                *b -= sum;
            } else {
                *b += sum;
            }
        }
    }

    /// The integrator's raw value `A` at the last output, in spikes with 24 fractional bits.
    pub fn value(&self) -> i64 {
        self.a
    }

    /// The output is `A / 2^output_shift()` spikes (see the module docs).
    pub fn output_shift(&self) -> u32 {
        self.shift
    }

    /// `e^(-d/tau_A)` in Q24 for `d` µs.
    #[inline]
    fn weight(&self, d: u32) -> i64 {
        match self.near.get(d as usize) {
            Some(&w) => i64::from(w),
            None => weight_from_tables(&self.decay, d),
        }
    }
}

/// `e^(-d/tau_A)` in Q24 for `d` µs, from the decay tables (at most `2^24`).
#[inline]
fn weight_from_tables(decay: &ExpDecay, d: u32) -> i64 {
    if d < 1 << 16 {
        let (lo, _) = decay.table(Part::Lo);
        let (mid, _) = decay.table(Part::Mid);
        let l = lo.get((d & 0xFF) as usize).copied().unwrap_or(0);
        let m = mid.get((d >> 8) as usize).copied().unwrap_or(0);
        lo_mid_weight(l, m)
    } else {
        i64::from(decay.decay_bits(d) >> (31 - FRAC))
    }
}

/// The product of a low-byte and a mid-byte decay entry (Q1.31 each) as a weight in Q24 (at
/// most `2^24`).
#[inline]
const fn lo_mid_weight(lo: u32, mid: u32) -> i64 {
    ((lo as u64 * mid as u64) >> (62 - FRAC)) as i64
}

/// `s = 10 + ceil(log2(tau_a_us / 10_000))`, at least 0: the output unit is `2^s` spikes.
const fn output_shift(tau_a_us: u32) -> u32 {
    // The smallest k with 10 ms · 2^k >= tau_A, for k from -10 up.
    let mut s = 0u32;
    while s < 30 && ((10_000u64 << s) >> 10) < tau_a_us as u64 {
        s += 1;
    }
    s
}

impl NetSink for Normalized {
    const SPIKES: bool = true;

    #[inline]
    fn spike(&mut self, s: Spike) {
        if self.started {
            self.add(s.t_us, s.dir == Dir::LeftToRight);
        }
    }

    fn ahead_us(&self) -> u32 {
        AHEAD_MAX_US.min(self.reach_us())
    }

    /// `RING - 2` output periods (the ring's last bin holds nothing beyond), once started.
    fn reach_us(&self) -> u32 {
        if self.started {
            self.period_us.saturating_mul(RING as u32 - 2)
        } else {
            0
        }
    }

    /// A unit's run of spikes (in time order): per output bin one step to the next bin (a
    /// division only where a run skips bins), per spike one weight.
    #[inline]
    fn spikes(&mut self, _cell: u32, dir: Dir, times: &[u32]) {
        if !self.started {
            return;
        }
        let Some(&first) = times.first() else {
            return;
        };
        let negative = dir == Dir::LeftToRight;
        let (mut k, mut end) = self.period_of(first);
        let mut sum = 0i64;
        for &t in times {
            if (end.wrapping_sub(t) as i32) < 0 {
                self.add_to_bin(k, sum, negative);
                sum = 0;
                // Mostly the next period; else the division finds it.
                k += 1;
                end = end.wrapping_add(self.period_us);
                if (end.wrapping_sub(t) as i32) < 0 {
                    (k, end) = self.period_of(t);
                }
            }
            sum += self.weight(end.wrapping_sub(t));
        }
        self.add_to_bin(k, sum, negative);
    }

    #[inline]
    fn retract(&mut self, s: Spike) {
        if self.started {
            self.add(s.t_us, s.dir == Dir::RightToLeft);
        }
    }
}

impl Readout for Normalized {
    /// The value at `t_us`, which must be the next output time (one period after the last).
    fn output(&mut self, t_us: u32) -> (I16F16, u8) {
        if !self.started {
            self.started = true;
            self.t_last = t_us;
            self.next = t_us.wrapping_add(self.period_us);
            return (I16F16::ZERO, 0);
        }
        let k = i128::from(self.decay.decay_bits(elapsed_us(self.t_last, t_us)));
        let bin = self.bins.get_mut(self.head).map_or(0, core::mem::take);
        self.a = ((i128::from(self.a) * k) >> 31) as i64 + bin;
        self.head = (self.head + 1) % RING;
        self.t_last = t_us;
        self.next = t_us.wrapping_add(self.period_us);
        // A (Q39.24) in units of 2^shift spikes, as Q16.16 bits.
        let v = self.a >> (FRAC + self.shift - 16).min(63);
        let v = v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
        (I16F16::from_bits(v), 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_unit_scales_with_tau_a() {
        assert_eq!(output_shift(10_000), 10);
        assert_eq!(output_shift(10_001), 11);
        assert_eq!(output_shift(20_000), 11);
        assert_eq!(output_shift(1_000), 7);
        assert_eq!(output_shift(1_000_000), 17);
        assert_eq!(output_shift(1), 0);
    }

    #[test]
    fn a_run_of_spikes_weighs_as_its_spikes_one_by_one() {
        // Runs that start before the current output time, cross several periods, skip some
        // and reach past the ring, for both orientations: the same bins, bit for bit.
        let mut run = Normalized::new(10_000, 1_000);
        let mut single = Normalized::new(10_000, 1_000);
        run.output(5_000);
        single.output(5_000);
        let mut t = 5_400u32;
        let mut times = [0u32; 40];
        for (k, slot) in times.iter_mut().enumerate() {
            t += 97 + (k as u32 * 37) % 700;
            if k % 9 == 8 {
                t += 3_500;
            }
            if k == 39 {
                t += RING as u32 * 1_000;
            }
            *slot = t;
        }
        for (dir, part) in [
            (Dir::RightToLeft, &times[..25]),
            (Dir::LeftToRight, &times[7..]),
        ] {
            run.spikes(3, dir, part);
            for &t_us in part {
                single.spike(Spike { t_us, cell: 3, dir });
            }
        }
        assert_ne!(run.bins, [0; RING]);
        assert!(
            times[39] > 6_000 + (RING as u32 - 1) * 1_000,
            "the last spike falls past the ring"
        );
        assert_eq!(run.bins, single.bins);
        for k in 1..20 {
            assert_eq!(
                run.output(5_000 + k * 1_000),
                single.output(5_000 + k * 1_000)
            );
        }
    }

    #[test]
    fn the_default_near_table_holds_the_weights_of_the_decay_tables() {
        let decay = ExpDecay::new(NORMALIZED_TAU_A_US);
        for (d, &w) in (0u32..).zip(DEFAULT_NEAR.iter()) {
            assert_eq!(i64::from(w), weight_from_tables(&decay, d), "d {d}");
        }
        assert_eq!(Normalized::new(NORMALIZED_TAU_A_US, 1_000).near.len(), NEAR);
        assert!(Normalized::new(20_000, 1_000).near.is_empty());
    }

    #[test]
    fn weights_are_within_four_units_of_the_last_place() {
        // Q24 weights against e^(-d/tau_A), inside the near table, across its edge, and
        // from the decay tables far beyond it.
        for tau_a_us in [1_000, 10_000, 100_000] {
            let r = Normalized::new(tau_a_us, 1_000);
            for d in (0..3_000u32).chain((3_000..2_000_000).step_by(997)) {
                let exact = (-f64::from(d) / f64::from(tau_a_us)).exp() * f64::from(1u32 << FRAC);
                let w = r.weight(d) as f64;
                assert!(
                    (w - exact).abs() <= 4.0,
                    "tau_A {tau_a_us} d {d}: {w} vs {exact}"
                );
            }
        }
    }

    #[test]
    fn many_spikes_do_not_saturate() {
        // 400 k net right-to-left spikes within one period: far beyond the old +-32,768.
        let mut r = Normalized::new(10_000, 1_000);
        r.output(0);
        for i in 0..400_000u32 {
            r.spike(Spike {
                t_us: 1 + i % 999,
                cell: 0,
                dir: Dir::RightToLeft,
            });
        }
        let (v, _) = r.output(1_000);
        let spikes = f64::from(v.to_bits()) / 65536.0 * 1024.0;
        let exact: f64 = (0..400_000u32)
            .map(|i| (-(f64::from(999 - i % 999)) / 10_000.0).exp())
            .sum();
        assert!((spikes - exact).abs() < 1.0, "{spikes} vs {exact}");
        assert!((r.value() as f64 / 16_777_216.0 - exact).abs() < 0.1);
    }
}
