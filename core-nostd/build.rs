//! Generates the burst tables of the fixed-point core (`unit::orbit`) into `$OUT_DIR/orbit.rs`.
//!
//! This runs on the build machine, in f64: the library itself has no floats. What it computes
//! (see `src/unit/orbit.rs` for how the tables are used):
//!
//! - A burst of the TDE unit (`tau_T == tau_m == tau`, refractory `t_ref`) is the orbit of one
//!   map. Let `t*` be the time at which the drive `q(t) tau = g I_T(t) tau / theta` has decayed
//!   to 1. A spike at `t = t* - tau r` (so `q tau = e^r` there) is followed by the next at
//!   `t* - tau r'` with `r' + e^(-r') = r - delta`, `delta = t_ref / tau`, as long as
//!   `r - delta >= 1`. Going backwards is explicit: `r = r' + e^(-r') + delta`.
//! - The *Abel coordinate* `alpha(r)` turns that map into a shift by one: `alpha(r') =
//!   alpha(r) - 1`. We use the natural one, `alpha(r) = lim_k (r_k / delta - k) - C` over the
//!   backward orbit `r_k`, with `C` such that `alpha(0) = 0` (a spike exactly at a tangent
//!   crossing is the last of its burst). It is analytic for `r > 0`, so `r(alpha)` interpolates
//!   well; the spikes of a burst are `r(alpha_0), r(alpha_0 - 1), ...` down to `alpha >= 0`.
//! - Tables: `r(alpha)` for `alpha >= 1` on a grid (1024 columns per row in rows 1..16, fewer
//!   further on, see TIERS), within about 1e-7 of the orbit; the last spike of a burst (row 0,
//!   where `r` has a square-root tip) as `r^2` against its predecessor; `beta(L) = alpha(L +
//!   delta) - 1 - L / delta`, a first guess of the first spike's `alpha` from the level
//!   `L = ln(q tau)` at the start of charging. Also `ln(1 + i/256)` and `256 / (256 + i)` for the
//!   fixed-point logarithm, `sqrt(1 + i/128)` for a square root.
//!
//! The tables are for the default `t_ref = 100 µs`, `tau = 20 ms` (`delta = 1/200`); a kernel
//! with other values finds its spikes by Newton's method instead (`unit::Kernel::orbit`).

use std::fmt::Write as _;

/// `t_ref` (µs) and `tau` (µs) the tables are for: `TdeParams::DEFAULT`.
const T_REF_US: u32 = 100;
const TAU_US: u32 = 20_000;

/// Fundamental grid: `alpha` in 1/FUND steps on [0, 1].
const FUND: usize = 1024;
/// Tiers of the `r(alpha)` table: `(first row, end row, log2 of columns per row)`. The
/// interpolation error falls quickly with the row (the orbit straightens out), so far rows
/// need few columns; each tier keeps `r` within about 1e-7 of the orbit (2 ns of spike time).
const TIERS: [(usize, usize, u32); 6] = [
    (1, 16, 10),
    (16, 64, 6),
    (64, 200, 4),
    (200, 400, 2),
    (400, 1000, 1),
    (1000, 0, 0), // to the end of the table
];
/// The last spike of a burst (row 0), from `u = r_prev - delta - 1` (`r_prev` its predecessor):
/// `r^2` on `u` in [0, 1/2), ROW0_STEPS steps (`r^2` is analytic in `u`).
const ROW0_STEPS: usize = 4096;
/// Rows of the table are generated until `r` exceeds this; beyond, `r` grows by `delta` per
/// row (the next increment, `e^(-r)`, is below 3e-10).
const R_END: f64 = 22.0;
/// Grid step (in `L`) of the first-spike guess table, and its end.
const L_STEPS_PER_UNIT: usize = 256;
const L_END: f64 = 24.0;

/// Backward orbits are followed until `r` exceeds this; the rest of the sum is closed-form.
const R_TAIL: f64 = 24.0;

fn rinv(r: f64, d: f64) -> f64 {
    r + (-r).exp() + d
}

/// The natural Abel coordinate before normalisation, and its derivative.
fn abel_raw(mut r: f64, d: f64) -> (f64, f64) {
    let mut k = 0.0f64;
    let mut deriv = 1.0f64 / d;
    while r < R_TAIL {
        deriv *= 1.0 - (-r).exp();
        r = rinv(r, d);
        k += 1.0;
    }
    // Remaining increments e^(-r_j) / delta with r_j ~ r + j delta.
    let tail = (-r).exp() / (d * (1.0 - (-d).exp()));
    (r / d - k + tail, deriv)
}

/// `r` in `[0, 1 + delta]` with `alpha(r) = target` (`alpha` normalised to `alpha(0) = 0`).
fn solve_fundamental(target: f64, c: f64, d: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 1.0 + d);
    let mut r = (1.0 + d) * target.sqrt();
    for _ in 0..200 {
        let (a, da) = abel_raw(r, d);
        let f = a - c - target;
        if f > 0.0 {
            hi = r;
        } else {
            lo = r;
        }
        let mut next = if da > 0.0 { r - f / da } else { f64::NAN };
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        if (next - r).abs() < 1e-15 || hi - lo < 1e-15 {
            return next;
        }
        r = next;
    }
    r
}

fn q(v: f64, frac_bits: u32) -> i64 {
    (v * (1u64 << frac_bits) as f64).round() as i64
}

fn emit_u32(out: &mut String, name: &str, values: &[i64], doc: &str) {
    let _ = writeln!(out, "/// {doc}");
    let _ = writeln!(out, "pub(super) static {name}: [u32; {}] = [", values.len());
    for chunk in values.chunks(8) {
        let line: Vec<String> = chunk
            .iter()
            .map(|v| u32::try_from(*v).expect("table entry fits u32").to_string())
            .collect();
        let _ = writeln!(out, "    {},", line.join(", "));
    }
    let _ = writeln!(out, "];");
}

fn emit_i32(out: &mut String, name: &str, values: &[i64], doc: &str) {
    let _ = writeln!(out, "/// {doc}");
    let _ = writeln!(out, "pub(super) static {name}: [i32; {}] = [", values.len());
    for chunk in values.chunks(8) {
        let line: Vec<String> = chunk
            .iter()
            .map(|v| i32::try_from(*v).expect("table entry fits i32").to_string())
            .collect();
        let _ = writeln!(out, "    {},", line.join(", "));
    }
    let _ = writeln!(out, "];");
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let d = f64::from(T_REF_US) / f64::from(TAU_US);
    let c = abel_raw(0.0, d).0;

    // Fundamental points: r at alpha = i / FUND.
    let fund: Vec<f64> = (0..=FUND)
        .map(|i| match i {
            0 => 0.0,
            i if i == FUND => 1.0 + d,
            i => solve_fundamental(i as f64 / FUND as f64, c, d),
        })
        .collect();
    // The rows, tier by tier, each row 2^log2 + 1 entries (the last = next row's first).
    let mut rows = Vec::new();
    let mut tier_decl = Vec::new();
    let mut end_row = 0usize;
    for (first, end, log2) in TIERS {
        let cols = 1usize << log2;
        let step = FUND / cols;
        let mut col: Vec<f64> = (0..=cols).map(|j| fund[j * step]).collect();
        for _ in 0..first {
            col.iter_mut().for_each(|r| *r = rinv(*r, d));
        }
        let offset = rows.len();
        let mut row = first;
        loop {
            rows.extend(col.iter().map(|r| q(*r, 27)));
            row += 1;
            col.iter_mut().for_each(|r| *r = rinv(*r, d));
            let done = if end == 0 { col[0] > R_END } else { row >= end };
            if done {
                break;
            }
        }
        end_row = row;
        tier_decl.push(format!(
            "Tier {{ first: {first}, log2: {log2}, offset: {offset} }}"
        ));
    }
    // Row 0: r^2 (Q2.30) of the last spike against u = r_prev - delta - 1 (Q32), r_prev its
    // predecessor: r + e^-r = 1 + u.
    let row0: Vec<i64> = (0..=ROW0_STEPS)
        .map(|i| {
            let u = i as f64 * 0.5 / ROW0_STEPS as f64;
            let mut r = (2.0 * u).sqrt();
            for _ in 0..100 {
                let g = r + (-r).exp() - 1.0 - u;
                let dg = 1.0 - (-r).exp();
                if dg <= 0.0 || g.abs() < 1e-16 {
                    break;
                }
                r -= g / dg;
            }
            q(r * r, 30)
        })
        .collect();
    // sqrt(1 + i/128) in Q1.31 over [1, 4] (the last, 2.0, held just below).
    let sqrt_tab: Vec<i64> = (0..=384)
        .map(|i| q((1.0 + i as f64 / 128.0).sqrt(), 31).min(i64::from(u32::MAX)))
        .collect();

    // First-spike table: beta(L) = alpha(L + delta) - 1 - L / delta, Q16.16, L = 1 + j / 256.
    let n_l = ((L_END - 1.0) * L_STEPS_PER_UNIT as f64) as usize + 1;
    let beta: Vec<i64> = (0..n_l)
        .map(|j| {
            let l = 1.0 + j as f64 / L_STEPS_PER_UNIT as f64;
            let alpha = abel_raw(l + d, d).0 - c;
            q(alpha - 1.0 - l / d, 16)
        })
        .collect();
    let beta_inf = q(-c, 16);

    // Logarithm tables: ln(1 + i/256) in Q0.32 (i = 0..=256), 256/(256 + i) in Q1.31.
    let ln_tab: Vec<i64> = (0..=256)
        .map(|i| q((1.0 + i as f64 / 256.0).ln(), 32))
        .collect();
    let inv_tab: Vec<i64> = (0..256)
        .map(|i| q(256.0 / (256.0 + i as f64), 31))
        .collect();

    let mut out = String::new();
    let _ = writeln!(out, "// Generated by core-nostd/build.rs: do not edit.");
    let consts = [
        (
            "`t_ref` (µs) the burst tables are for.",
            format!("T_REF_US: u32 = {T_REF_US}"),
        ),
        (
            "`tau` (µs) the burst tables are for.",
            format!("TAU_US: u32 = {TAU_US}"),
        ),
        (
            "Rows in the table; beyond, r grows by delta per row.",
            format!("ROWS_END: usize = {end_row}"),
        ),
        (
            "Tiers of ROWS, by first row (log2 of columns per row, offset of the first entry).",
            format!(
                "TIERS: [Tier; {}] = [{}]",
                tier_decl.len(),
                tier_decl.join(", ")
            ),
        ),
        (
            "Steps of ROW0 over u in [0, 1/2).",
            format!("ROW0_STEPS: usize = {ROW0_STEPS}"),
        ),
        (
            "`beta` at large `L` (Q16.16).",
            format!("BETA_INF: i32 = {beta_inf}"),
        ),
        (
            "Steps per unit of `L` in BETA.",
            format!("L_STEPS_PER_UNIT: u32 = {L_STEPS_PER_UNIT}"),
        ),
    ];
    for (doc, decl) in consts {
        let _ = writeln!(out, "/// {doc}\npub(super) const {decl};");
    }
    emit_u32(
        &mut out,
        "ROWS",
        &rows,
        "`r(alpha)` in Q5.27, tier by tier, row by row (2^log2 + 1 entries a row).",
    );
    emit_u32(
        &mut out,
        "ROW0",
        &row0,
        "Row 0: `r^2` (Q2.30) at `u = i / (2 ROW0_STEPS)`, `r + e^-r = 1 + u`.",
    );
    emit_u32(
        &mut out,
        "SQRT_1_4",
        &sqrt_tab,
        "`sqrt(1 + i/128)` in Q1.31.",
    );
    emit_i32(
        &mut out,
        "BETA",
        &beta,
        "`beta(L) = alpha(L + delta) - 1 - L / delta` in Q16.16 at `L = 1 + j / L_STEPS_PER_UNIT`.",
    );
    emit_u32(&mut out, "LN_1P", &ln_tab, "`ln(1 + i/256)` in Q0.32.");
    emit_u32(&mut out, "INV_1P", &inv_tab, "`256 / (256 + i)` in Q1.31.");
    let path = std::path::Path::new(&std::env::var("OUT_DIR").expect("OUT_DIR")).join("orbit.rs");
    std::fs::write(path, out).expect("write orbit.rs");
}
