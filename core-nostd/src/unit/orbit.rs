//! The burst tables: a burst as the orbit of one map, read out of a table in O(1) per spike.
//!
//! With `tau_T == tau_m == tau`, let `t*` be the time at which the drive `D(t) = q(t)·tau`
//! (`q = g I_T / theta` per µs) has decayed to 1, so `D(t) = e^((t* - t)/tau)`. A membrane that
//! starts charging from 0 at `t_e` follows `v(t) = D(t)·(t - t_e)/tau`, and reaches threshold
//! where the charging time equals `tau / D`: the spike at `t = t* - tau·r` has `D = e^r` and
//! `r + e^(-r) = L`, `L = ln D(t_e)`; it exists when `L >= 1` (below, the membrane peaks under
//! threshold). After it, the membrane restarts from 0 at `t + t_ref`, where `L = r - delta`
//! (`delta = t_ref/tau`). So a burst is the orbit `r -> h^-1(r - delta)`, `h(r) = r + e^(-r)`,
//! for as long as `r - delta >= 1`; one number, `r`, says where a unit is in its burst.
//!
//! The *Abel coordinate* `alpha(r)` turns that map into a step of one: `alpha(next r) =
//! alpha(r) - 1`. `build.rs` tabulates `r(alpha)` for the natural choice of `alpha` (analytic,
//! with `alpha = 0` at a tangent crossing); the spikes of a burst whose first spike has
//! `alpha_0` are `r(alpha_0), r(alpha_0 - 1), ...` for as long as `alpha >= 0` (so
//! `floor(alpha_0) + 1` spikes). Each spike is then one table lookup and one linear
//! interpolation (the fractional part of `alpha` is the same for all spikes of a burst), with no
//! search. The count of a burst is exact (its boundaries are grid points); `r` is within about
//! 1e-7 of the orbit (2 ns of spike time; measured in the tests), which the unit's state needs:
//! an input in a burst continues from the last spike's time, and near the end of a burst the
//! crossings are so flat that state errors grow by a factor of up to ~200 in the spike times.
//!
//! `alpha` is kept in Q32.32. The first spike after an input comes from the level `L`:
//! `alpha_0 = alpha(L + delta) - 1`, found by inverting the table's interpolation (a first
//! guess from `beta`, one division). The last spike of a burst (row 0, where `r` has a
//! square-root tip at the tangent) comes from its predecessor `r'` through `r + e^-r = r' -
//! delta`, tabulated as `r^2` (analytic there).
//!
//! Tables exist for the default `t_ref = 100 µs`, `tau = 20 ms`; they are generated at build time
//! (`build.rs`, in f64 on the build machine) and sit in flash (~110 kB; linked only where the
//! spiking network runs).

include!(concat!(env!("OUT_DIR"), "/orbit.rs"));

use super::div_u64;

/// A tier of [`ROWS`]: rows from `first` on, `2^log2` columns each (`2^log2 + 1` entries: the
/// last repeats the next row's first), starting at entry `offset`.
pub(super) struct Tier {
    first: usize,
    log2: u32,
    offset: usize,
}

/// `1.0` in Q32.32 (one step of `alpha`; also `L`, `r`, `u` in Q32.32).
pub(super) const ONE: u64 = 1 << 32;

/// `delta = T_REF_US / TAU_US` in Q5.27.
const DELTA_Q27: u64 = ((T_REF_US as u64) << 27) / TAU_US as u64;

/// `delta` in Q32.32.
pub(super) const DELTA_Q32: u64 = ((T_REF_US as u64) << 32) / TAU_US as u64;

const _: () = assert!(L_STEPS_PER_UNIT == 256 && ROW0_STEPS == 4096 && !TIERS.is_empty());

/// Entry `i` of `table`, 0 past its end (never reached for valid indices).
#[inline(always)]
fn at(table: &[u32], i: usize) -> u64 {
    u64::from(table.get(i).copied().unwrap_or(0))
}

impl Tier {
    /// Entries per row of this tier (the last repeats the next row's first).
    #[inline(always)]
    fn stride(&self) -> usize {
        (1 << self.log2) + 1
    }

    /// The index in [`ROWS`] of column `col` of `row` (a row of this tier).
    #[inline(always)]
    fn entry(&self, row: usize, col: usize) -> usize {
        self.offset + (row - self.first) * self.stride() + col
    }
}

/// How many tiers start at or before `row` (0 for row 0). Counted from the first tier: a
/// burst's rows are mostly in the first (one comparison past it).
#[inline(always)]
fn tiers_up_to(row: usize) -> usize {
    TIERS.iter().take_while(|t| t.first <= row).count()
}

/// The tier holding `row` (`row >= 1`).
#[inline(always)]
fn tier_of(row: usize) -> &'static Tier {
    static NONE: Tier = Tier {
        first: 1,
        log2: 0,
        offset: 0,
    };
    TIERS
        .get(..tiers_up_to(row))
        .and_then(<[Tier]>::last)
        .unwrap_or(&NONE)
}

/// The table cell holding `alpha` (row >= 1, inside the table): its start (Q32.32), its width
/// (log2, in units of 2^-32), and `r` (Q5.27) at both ends.
#[inline]
fn cell(alpha: u64) -> (u64, u32, u64, u64) {
    let row = (alpha >> 32) as usize;
    let t = tier_of(row);
    let wbits = 32 - t.log2;
    let col = ((alpha & 0xFFFF_FFFF) >> wbits) as usize;
    let i = t.entry(row, col);
    let start = alpha & !((1u64 << wbits) - 1);
    (start, wbits, at(&ROWS, i), at(&ROWS, i + 1))
}

/// `r` (Q5.27; it may exceed 32 beyond the table) at `alpha` (Q32.32, `alpha >= 1`).
#[inline]
pub(super) fn r_at(alpha: u64) -> u64 {
    let row = (alpha >> 32) as usize;
    if row >= ROWS_END {
        // Beyond the table r grows by delta per row (the next term, e^-r, is below 3e-10).
        let last = (((ROWS_END - 1) as u64) << 32) | (alpha & 0xFFFF_FFFF);
        return r_at(last) + (row - (ROWS_END - 1)) as u64 * DELTA_Q27;
    }
    // As in `emit`: the weight `(alpha - start) / 2^wbits` in Q0.32, so that the product
    // is 32 x 32 bits and the shift the high word (the same value as `cell`'s interpolation).
    let t = tier_of(row);
    let frac = alpha & 0xFFFF_FFFF;
    let col = (frac >> (32 - t.log2)) as usize;
    let w32 = (frac << t.log2) as u32;
    let i = t.entry(row, col);
    let (a, b) = (at(&ROWS, i), at(&ROWS, i + 1));
    a + ((b.saturating_sub(a) * u64::from(w32)) >> 32)
}

/// `r^2` (Q2.30) of the last spike of a burst, from its predecessor `r_prev` (Q5.27).
#[inline]
fn r2_last(r_prev: u64) -> u64 {
    // u = r_prev - delta - 1 in Q32, in [0, 0.375).
    let u = (r_prev << 5).saturating_sub(DELTA_Q32 + ONE);
    let i = (u >> 19) as usize; // 8192 steps per unit of u
    let w = (u >> 3) & 0xFFFF;
    let (a, b) = (at(&ROW0, i), at(&ROW0, i + 1));
    a + ((b.saturating_sub(a) * w) >> 16)
}

/// `floor(sqrt(x))` to about 2e-6 relative, from a table (no loop, no division).
#[inline]
fn sqrt_approx(x: u64) -> u64 {
    if x == 0 {
        return 0;
    }
    // x · 4^k in [2^62, 2^64): its square root is a Q1.31 table value.
    let shift = x.leading_zeros() & !1;
    let xn = x << shift;
    let i = ((xn >> 55) - 128) as usize;
    let (a, b) = (at(&SQRT_1_4, i), at(&SQRT_1_4, i + 1));
    (a + ((b.saturating_sub(a) * ((xn >> 39) & 0xFFFF)) >> 16)) >> (shift / 2)
}

/// `r` (Q5.27) of the last spike of a burst from its predecessor's `r`, to 2e-6 relative
/// (`precise`: one Newton step more, to the table's own accuracy).
#[inline]
pub(super) fn r_last(r_prev: u64, precise: bool) -> u64 {
    let x = r2_last(r_prev) << 24; // r^2 in Q10.54: sqrt is Q5.27
    let r = sqrt_approx(x);
    if precise && r > 0 {
        (r + div_u64(x, r)) / 2
    } else {
        r
    }
}

/// `r` (Q5.27) at any `alpha >= 0` (Q32.32), to about 1e-7.
#[cfg(test)]
fn r_of(alpha: u64) -> u64 {
    if alpha >= ONE {
        r_at(alpha)
    } else {
        r_last(r_at(alpha + ONE), true)
    }
}

/// `r` (Q5.27) of the spike at `alpha` exactly as [`emit`] computes it (row 0 from its
/// predecessor, to 2e-6).
#[inline]
pub(super) fn r_emitted(alpha: u64) -> u64 {
    if alpha >= ONE {
        r_at(alpha)
    } else {
        r_last(r_at(alpha + ONE), false)
    }
}

/// What [`emit`] leaves behind: where the burst goes on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Emitted {
    /// The next pending `alpha` (`u64::MAX`: the burst is over).
    pub next: u64,
    /// Spikes written.
    pub n: usize,
    /// The nearest whole µs of the pending spike (beyond `until`, or the first that did not
    /// fit in `out`); meaningless when the burst is over.
    pub next_us: u32,
}

/// `tau` (µs) in the units of `tau · r` with `r` in Q5.27 and times in Q32.32.
const TAU32: u64 = (TAU_US as u64) << 5;

/// Emits the spikes of a burst with anchor `ts` (`t*`, Q32.32 µs) whose exact time is at or
/// before `until`, from the spike at `alpha` on, writing each one's nearest whole µs into
/// `out` (in order) until it is full. One row of the table per spike; the column and its
/// interpolation weight are the same for the whole burst, and the table rows' `r` and the
/// spike times are 32 x 32-bit products (cheap on a 32-bit MCU).
#[inline]
pub(super) fn emit(ts: u64, until: u64, alpha: u64, out: &mut [u32]) -> Emitted {
    // A spike at r (Q5.27) lies at t = ts - TAU32·r; it is due when until - t >= 0, and
    // reported at the whole µs nearest to t.
    let due_from = until.wrapping_sub(ts);
    let round = ts.wrapping_add(1 << 31);
    let due = |p: u64| (due_from.wrapping_add(p) as i64) >= 0;
    let reported = |p: u64| (round.wrapping_sub(p) >> 32) as u32;
    let frac = alpha & 0xFFFF_FFFF;
    let start = (alpha >> 32) as usize;
    let mut row = start;
    let mut n = 0usize;
    // Where the burst stands after `n` spikes, at `row`.
    let pending = |row: usize, n: usize, next_us: u32| Emitted {
        next: ((row as u64) << 32) | frac,
        n,
        next_us,
    };
    // r of the last spike emitted (the next one's predecessor), when known.
    let mut r_prev = None;
    if row >= ROWS_END {
        // Beyond the table: r falls by delta per row.
        let mut r = r_at(alpha);
        while row >= ROWS_END {
            let p = r.wrapping_mul(TAU32);
            let Some(slot) = out.get_mut(n).filter(|_| due(p)) else {
                return pending(row, n, reported(p));
            };
            *slot = reported(p);
            n += 1;
            r_prev = Some(r);
            r -= DELTA_Q27;
            row -= 1;
        }
    }
    for t in TIERS
        .get(..tiers_up_to(row))
        .unwrap_or_default()
        .iter()
        .rev()
    {
        // The interpolation weight in Q0.32: (b - a)·w >> wbits is the high word of
        // (b - a)·(w << log2).
        let w32 = (frac << t.log2) as u32;
        let stride = t.stride();
        let col = (frac >> (32 - t.log2)) as usize;
        let mut i = t.entry(row, col);
        while row >= t.first {
            let Some(&[a, b]) = ROWS.get(i..i + 2) else {
                break;
            };
            let r = a + ((u64::from(b.saturating_sub(a)) * u64::from(w32)) >> 32) as u32;
            let p = u64::from(r) * TAU32;
            let Some(slot) = out.get_mut(n).filter(|_| due(p)) else {
                return pending(row, n, reported(p));
            };
            *slot = reported(p);
            n += 1;
            r_prev = Some(u64::from(r));
            i = i.wrapping_sub(stride);
            row -= 1;
        }
    }
    // Row 0: the last spike, from its predecessor.
    let r_prev = r_prev.unwrap_or_else(|| r_at(alpha + ONE));
    let p = r_last(r_prev, false).wrapping_mul(TAU32);
    let Some(slot) = out.get_mut(n).filter(|_| due(p)) else {
        return pending(0, n, reported(p));
    };
    *slot = reported(p);
    Emitted {
        next: u64::MAX,
        n: n + 1,
        next_us: 0,
    }
}

/// `alpha` (Q32.32) at which `r(alpha) = y` (Q5.27, `y >= 1 + delta`, so `alpha >= 1`),
/// inverting the table's interpolation exactly; `guess` (Q32.32, >= 1) is a first guess.
fn alpha_at(y: u64, guess: u64) -> u64 {
    // Beyond the table r grows by delta per row: come back into its last row.
    let base = r_at(((ROWS_END - 1) as u64) << 32);
    if y >= base + DELTA_Q27 {
        let k = (y - base) / DELTA_Q27;
        let inner = alpha_at(y - k * DELTA_Q27, ((ROWS_END - 1) as u64) << 32);
        return inner + (k << 32);
    }
    let mut alpha = guess.clamp(ONE, (ROWS_END as u64) << 32);
    // Walk to the cell holding y (the guess is within a cell or two).
    for _ in 0..64 {
        let (start, wbits, a, b) = cell(alpha.min(((ROWS_END as u64) << 32) - 1));
        if y < a && start > ONE {
            alpha = start - 1;
        } else if y >= b && (start + (1 << wbits)) >> 32 < ROWS_END as u64 {
            alpha = start + (1 << wbits);
        } else {
            let span = b.saturating_sub(a).max(1);
            let num = y.saturating_sub(a);
            // Below one cell's span the quotient is below 2^wbits <= 2^32.
            let q = div_u64(num << wbits, span);
            return start + q.min((1 << wbits) - 1);
        }
    }
    alpha
}

/// `alpha` (Q32.32) of the first spike of a burst whose membrane starts charging at level
/// `L = ln D(t_e)` (Q32.32, `L >= 1`): `alpha(L + delta) - 1`. `None` below 1 (no spike).
#[inline]
pub(super) fn first_alpha(l_q32: u64) -> Option<u64> {
    let x = l_q32.checked_sub(ONE)?;
    // First guess: L/delta + beta(L), beta on a 1/256 grid of L (Q16.16).
    let j = (x >> 24) as usize;
    let w = ((x >> 8) & 0xFFFF) as i64;
    let beta = match (BETA.get(j), BETA.get(j + 1)) {
        (Some(&a), Some(&b)) => i64::from(a) + (((i64::from(b) - i64::from(a)) * w) >> 16),
        _ => i64::from(BETA_INF),
    };
    let l_over_delta = ((u128::from(l_q32) * u128::from(TAU_US)) / u128::from(T_REF_US)) >> 16;
    let guess = (i64::try_from(l_over_delta).ok()? + beta + (1 << 16)).max(1 << 16) as u64;
    let y = (l_q32 + DELTA_Q32) >> 5;
    Some(alpha_at(y, guess << 16).saturating_sub(ONE))
}

/// `ln(x / 2^32)` in Q32.32 for `x > 0` (error below 2e-9); `None` for 0.
#[inline]
pub(super) fn ln_q32(x: u64) -> Option<i64> {
    if x == 0 {
        return None;
    }
    let lz = x.leading_zeros();
    let exponent = 31 - lz as i64; // floor(log2(x / 2^32))
    let m = x << lz; // mantissa in Q1.63, top bit set
    let i = ((m >> 55) & 0xFF) as usize;
    let rest = m & ((1u64 << 55) - 1);
    // u = rest / (2^63 · (1 + i/256)) in Q0.32: `rest · inv >> 62` with `rest < 2^55` and
    // `inv <= 2^31` (Q1.31), below 2^24, from two 32 x 32-bit products (the same value).
    let inv = at(&INV_1P, i);
    let u = (((rest >> 32) * inv + (((rest & 0xFFFF_FFFF) * inv) >> 32)) >> 30) as u32;
    // u^2 below 2^16, u^3 below 2^8 (Q0.32): the series in 32 bits (u >= u^2 / 2), so the
    // division by 3 is a multiplication on a Cortex-M, not a 64-bit division's call.
    let u2 = ((u64::from(u) * u64::from(u)) >> 32) as u32;
    let u3 = ((u64::from(u2) * u64::from(u)) >> 32) as u32;
    let ln_1p_u = i64::from(u - u2 / 2 + u3 / 3);
    Some(exponent * LN2_Q32 + at(&LN_1P, i) as i64 + ln_1p_u)
}

/// `ln 2` in Q32.32.
const LN2_Q32: i64 = 2_977_044_472;

#[cfg(test)]
mod tests {
    use super::*;

    const Q27: f64 = (1u64 << 27) as f64;
    const Q32: f64 = 4_294_967_296.0;

    #[test]
    fn ln_is_accurate() {
        for k in 1..2000u64 {
            let x = k * 2_654_435_761 % (1u64 << 44) + 1;
            let got = ln_q32(x).unwrap() as f64 / Q32;
            let want = (x as f64 / Q32).ln();
            assert!((got - want).abs() < 3e-9, "ln({x}) = {got} vs {want}");
        }
    }

    #[test]
    fn orbit_rows_follow_the_backward_map() {
        // r(alpha + 1) = r + e^-r + delta, for columns of every row, to about 1e-7.
        let delta = f64::from(T_REF_US) / f64::from(TAU_US);
        for row in 0..(ROWS_END as u64 + 40) {
            for f in [0u64, 1, 0x1234_5678, 0x8000_0000, 0xFFFF_FFFF] {
                let a = (row << 32) | f;
                let r0 = r_of(a) as f64 / Q27;
                let r1 = r_of(a + ONE) as f64 / Q27;
                let want = r0 + (-r0).exp() + delta;
                // Row 0 near its tangent tip (small r) is as ill-conditioned as the spike.
                let tol = if row == 0 { 2e-6 / r0.max(0.01) } else { 3e-7 };
                assert!((r1 - want).abs() < tol, "row {row} f {f:x}: {r1} vs {want}");
            }
        }
    }

    #[test]
    fn emission_follows_the_table() {
        // The spikes emit() reports are r_of() at alpha, alpha - 1, ... to the last.
        let alpha = (37u64 << 32) | 0x9ABC_DEF0;
        let ts = 1u64 << 60;
        let mut got = [0u32; 38];
        let e = emit(ts, u64::MAX >> 1, alpha, &mut got);
        assert_eq!((e.next, e.n), (u64::MAX, 38));
        for (k, t) in got.iter().enumerate() {
            let r = r_of(alpha - ((k as u64) << 32));
            let want = ts.wrapping_sub((20_000 * r) << 5);
            let want = (want.wrapping_add(1 << 31) >> 32) as u32;
            assert!(t.abs_diff(want) <= 1, "spike {k}: {t} vs {want}");
        }
    }

    #[test]
    fn first_alpha_inverts_the_orbit() {
        // The first spike from level L has r + e^-r = L.
        for k in 0..2000u64 {
            let l = 1.0 + k as f64 * 0.01137;
            let alpha = first_alpha((l * Q32) as u64).unwrap();
            let r = r_of(alpha) as f64 / Q27;
            let h = r + (-r).exp();
            let tol = if alpha < ONE {
                2e-6 / r.max(0.01)
            } else {
                3e-7
            };
            assert!((h - l).abs() < tol, "L {l}: r {r}, h(r) {h}");
        }
        assert_eq!(first_alpha(0), None);
        assert!(first_alpha(ONE).unwrap() < 1 << 16);
    }
}
