//! Fixed-point base-2 logarithm and exponential, from 257-entry tables built by `const fn`.
//!
//! Both work in Q16.16 (16 fractional bits). Error: below 3e-5 in `log2` over inputs up to 2^40
//! and below 3e-5 (relative above 1, absolute below) in `exp2`, measured in the tests: far finer than the
//! readout's 10 % histogram bins that use them.

/// `log2(1 + i/256)` in Q0.16 for `i` in 0..=256.
const LOG2_TABLE: [u32; 257] = log2_table();
/// `2^(i/256)` in Q1.30 (1.0 = 2^30) for `i` in 0..=256.
const EXP2_TABLE: [u32; 257] = exp2_table();

/// `ln(2)` in Q0.32.
pub const LN2_Q32: u64 = 2_977_044_472;

/// `log2(e)` in Q32 (1.4427 · 2^32).
pub const LOG2E_Q32: u64 = 6_196_328_019;

/// `log2(x / 2^frac_bits)` in Q16.16 for `x > 0`; `i32::MIN` for `x == 0`.
#[inline]
pub fn log2_q16(x: u64, frac_bits: u32) -> i32 {
    match u32::try_from(x) {
        // Most arguments are 32-bit values widened: 32-bit shifts on a Cortex-M.
        Ok(x) => log2_q16_u32(x, frac_bits),
        Err(_) => {
            // x >= 2^32: the mantissa's 24 fractional bits lie below the leading one.
            let msb = 63 - x.leading_zeros();
            log2_of_mantissa(msb, (x >> (msb - 24)) as u32, frac_bits)
        }
    }
}

/// [`log2_q16`] of a 32-bit `x` (the same result).
#[inline]
fn log2_q16_u32(x: u32, frac_bits: u32) -> i32 {
    if x == 0 {
        return i32::MIN;
    }
    let msb = 31 - x.leading_zeros(); // floor(log2 x)
    let m = if msb >= 24 {
        x >> (msb - 24)
    } else {
        x << (24 - msb)
    };
    log2_of_mantissa(msb, m, frac_bits)
}

/// `msb - frac_bits + log2(m / 2^24)` in Q16.16, from the mantissa `m` (its bit 24 the
/// leading one, bits above it ignored) of a number whose leading one is bit `msb`.
#[inline(always)]
fn log2_of_mantissa(msb: u32, m: u32, frac_bits: u32) -> i32 {
    let m = m & 0x00FF_FFFF;
    let idx = (m >> 16) as usize;
    let frac = m & 0xFFFF;
    let a = LOG2_TABLE.get(idx).copied().unwrap_or(0);
    let b = LOG2_TABLE.get(idx + 1).copied().unwrap_or(a);
    // b - a < 2^9 (one 256th of an octave in Q0.16): the product fits 32 bits.
    let interp = a + ((b.saturating_sub(a) * frac) >> 16);
    ((msb as i32 - frac_bits as i32) << 16).saturating_add(interp as i32)
}

/// `2^(y / 2^16)` as a Q16.16 `u32`, saturating at `u32::MAX`, 0 far below.
#[inline]
pub fn exp2_q16(y: i32) -> u32 {
    let int = y >> 16; // floor
    let frac = (y & 0xFFFF) as u32;
    let idx = (frac >> 8) as usize;
    let sub = frac & 0xFF;
    let a = EXP2_TABLE.get(idx).copied().unwrap_or(1 << 30);
    let b = EXP2_TABLE.get(idx + 1).copied().unwrap_or(a);
    // Q1.30, in [2^30, 2^31): b - a < 2^23 (a 256th of an octave), so the product fits 32
    // bits and the whole stays in 32-bit arithmetic on a Cortex-M.
    let m = a + ((b.saturating_sub(a) * sub) >> 8);
    // value = m * 2^int / 2^30, wanted in Q16.16: shift by int - 14.
    let shift = int - 14;
    if shift >= 0 {
        // m << shift fits 32 bits while the shift is at most m's leading zeros (m > 0).
        if shift as u32 > m.leading_zeros() {
            u32::MAX
        } else {
            m << shift
        }
    } else {
        m.checked_shr(shift.unsigned_abs()).unwrap_or(0)
    }
}

/// Natural log from a Q16.16 base-2 log: `ln(x) = log2(x) · ln 2`.
#[inline]
pub fn ln_from_log2_q16(l2: i32) -> i32 {
    ((i64::from(l2) * LN2_Q32 as i64) >> 32) as i32
}

// Compile-time only; `i <= 256` bounds the index (`get_mut` is not usable in const fn here).
#[allow(clippy::indexing_slicing)]
const fn log2_table() -> [u32; 257] {
    // log2(1 + t) by the series of ln(1 + t) in Q0.62 fixed point, t = i / 256 in [0, 1]; for
    // t > 0.5 use log2(1 + t) = 1 + log2((1 + t) / 2) with (1 + t)/2 - 1 in [-0.25, 0].
    let mut out = [0u32; 257];
    let mut i = 0;
    while i <= 256 {
        let v = log2_1p_q62(i as i128);
        out[i] = ((v + (1 << 45)) >> 46) as u32;
        i += 1;
    }
    out
}

/// `log2(1 + i/256)` in Q0.62.
const fn log2_1p_q62(i: i128) -> i128 {
    const ONE: i128 = 1 << 62;
    // ln 2 in Q62
    const LN2: i128 = 3_196_577_161_300_663_915;
    // u = (1 + t) / 2 when t > 0.5, so that x = u - 1 is small.
    let (x, add) = if i > 128 {
        ((ONE * (256 + i) / 512) - ONE, ONE)
    } else {
        (ONE * i / 256, 0)
    };
    // ln(1 + x) with x in [-0.25, 0.5]: atanh form 2 * atanh(x / (2 + x)).
    let z = x * ONE / (2 * ONE + x);
    let z2 = z * z / ONE;
    let mut term = z;
    let mut sum = 0i128;
    let mut k = 1i128;
    while k < 80 {
        sum += term / k;
        term = term * z2 / ONE;
        k += 2;
        if term == 0 {
            break;
        }
    }
    let ln = 2 * sum;
    add + ln * ONE / LN2
}

// Compile-time only; `i <= 256` bounds the index.
#[allow(clippy::indexing_slicing)]
const fn exp2_table() -> [u32; 257] {
    // 2^(i/256) = e^(i ln2 / 256) by its Taylor series in Q62.
    const ONE: i128 = 1 << 62;
    const LN2: i128 = 3_196_577_161_300_663_915;
    let mut out = [0u32; 257];
    let mut i = 0;
    while i <= 256 {
        let x = LN2 * i as i128 / 256;
        let mut term = ONE;
        let mut sum = ONE;
        let mut k = 1i128;
        while k < 40 {
            term = term * x / ONE / k;
            sum += term;
            k += 1;
            if term == 0 {
                break;
            }
        }
        out[i] = ((sum + (1 << 31)) >> 32) as u32;
        i += 1;
    }
    out
}

#[cfg(test)]
#[allow(clippy::float_arithmetic, clippy::cast_precision_loss)]
mod tests {
    extern crate std;
    use super::*;

    #[test]
    fn log2_error_over_the_u32_range() {
        let mut worst = 0.0f64;
        let mut x: u64 = 1;
        while x < (1u64 << 40) {
            let got = f64::from(log2_q16(x, 16)) / 65536.0;
            let exact = (x as f64 / 65536.0).log2();
            worst = worst.max((got - exact).abs());
            x = x + x / 977 + 1;
        }
        std::eprintln!("log2 worst error {worst:.2e}");
        assert!(worst < 3e-5, "{worst}");
        assert_eq!(log2_q16(0, 0), i32::MIN);
    }

    #[test]
    fn a_number_and_its_shifted_copy_have_the_same_log2_on_either_side_of_2_pow_32() {
        // Up to 24 significant bits the mantissa is exact, so shifting by `k` and counting
        // `k` more fractional bits changes nothing, wherever the leading one lands.
        let mut x: u64 = 1;
        while x < (1 << 24) {
            for k in [0u32, 8, 20, 31, 32, 33, 39] {
                assert_eq!(log2_q16(x << k, 16 + k), log2_q16(x, 16), "{x} << {k}");
            }
            x = x * 3 / 2 + 1;
        }
        assert!(((64 << 16) - log2_q16(u64::MAX, 0)).abs() <= 1);
        assert_eq!(log2_q16(1 << 63, 63), 0);
    }

    #[test]
    fn exp2_in_32_bits_equals_the_same_interpolation_in_64() {
        // The interpolation and the shift carried out in 64 bits, saturating at the end.
        let wide = |y: i32| -> u32 {
            let (int, frac) = (y >> 16, (y & 0xFFFF) as usize);
            let a = u64::from(EXP2_TABLE[frac >> 8]);
            let b = u64::from(EXP2_TABLE[(frac >> 8) + 1]);
            let m = a + (((b - a) * (frac as u64 & 0xFF)) >> 8);
            let shift = int - 14;
            let v = if shift >= 0 {
                m.checked_shl(shift as u32).filter(|v| v >> shift == m)
            } else {
                Some(m.checked_shr(shift.unsigned_abs()).unwrap_or(0))
            };
            v.map_or(u32::MAX, |v| u32::try_from(v).unwrap_or(u32::MAX))
        };
        for y in (-50 * 65536..50 * 65536)
            .step_by(7)
            .chain([i32::MIN, i32::MAX, -1, 0])
        {
            assert_eq!(exp2_q16(y), wide(y), "{y}");
        }
    }

    #[test]
    fn exp2_relative_error() {
        let mut worst = 0.0f64;
        for y in (-15 * 65536..15 * 65536).step_by(97) {
            let got = f64::from(exp2_q16(y)) / 65536.0;
            let exact = (f64::from(y) / 65536.0).exp2();
            // Relative error where the Q16.16 result has at least 17 significant bits,
            // otherwise the quantisation step (2^-16) bounds the absolute error.
            let err = if exact >= 1.0 {
                (got - exact).abs() / exact
            } else {
                (got - exact).abs()
            };
            worst = worst.max(err);
        }
        std::eprintln!("exp2 worst error {worst:.2e}");
        assert!(worst < 3e-5, "{worst}");
        assert_eq!(exp2_q16(40 << 16), u32::MAX);
        assert_eq!(exp2_q16(-40 << 16), 0);
    }
}
