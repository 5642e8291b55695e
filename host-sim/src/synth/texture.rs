//! Procedural textures: smooth fractal noise and "urban" edges/rectangles for the panorama, an
//! asphalt-like ground with lane markings, Gaussian pre-blur (so that edges are not aliased) and
//! the log conversion. Grids are generated in linear intensity, blurred, then stored as natural
//! log intensity (the quantity the pixels compare against their thresholds).

use rand::Rng;
use serde::{Deserialize, Serialize};

use super::rng;

/// Which texture covers the panorama.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum TextureKind {
    /// Smooth multi-octave value noise (no sharp edges).
    Noise,
    /// A skyline: buildings with windows, poles, sky and a ground strip (sharp edges, blurred).
    Urban,
}

impl TextureKind {
    /// Name as written in `meta.json`.
    pub fn name(self) -> &'static str {
        match self {
            TextureKind::Noise => "noise",
            TextureKind::Urban => "urban",
        }
    }
}

/// A row-major `w x h` grid of f32 values (`data[v * w + u]`), u = column, v = row.
#[derive(Clone, Debug)]
pub struct Grid {
    /// Columns.
    pub w: usize,
    /// Rows.
    pub h: usize,
    /// Values, row-major.
    pub data: Vec<f32>,
}

impl Grid {
    /// A grid filled with `value`.
    pub fn filled(w: usize, h: usize, value: f32) -> Self {
        Self {
            w,
            h,
            data: vec![value; w * h],
        }
    }

    /// Value at integer `(u, v)`, u wrapped, v clamped.
    fn at_wrap(&self, u: isize, v: isize) -> f32 {
        let u = u.rem_euclid(self.w as isize) as usize;
        let v = v.clamp(0, self.h as isize - 1) as usize;
        self.data[v * self.w + u]
    }

    /// Sets the rectangle `[u0, u1) x [v0, v1)` (u wraps around, v is clipped) to `value`.
    pub fn fill_rect(&mut self, u0: isize, v0: isize, u1: isize, v1: isize, value: f32) {
        let v0 = v0.clamp(0, self.h as isize) as usize;
        let v1 = v1.clamp(0, self.h as isize) as usize;
        for v in v0..v1 {
            for u in u0..u1 {
                let uu = u.rem_euclid(self.w as isize) as usize;
                self.data[v * self.w + uu] = value;
            }
        }
    }

    /// Mean value.
    pub fn mean(&self) -> f64 {
        self.data.iter().map(|&x| f64::from(x)).sum::<f64>() / self.data.len().max(1) as f64
    }

    /// Standard deviation.
    pub fn std(&self) -> f64 {
        let m = self.mean();
        let var = self
            .data
            .iter()
            .map(|&x| (f64::from(x) - m).powi(2))
            .sum::<f64>()
            / self.data.len().max(1) as f64;
        var.sqrt()
    }

    /// Separable Gaussian blur with standard deviation `sigma` texels; periodic in u, and in v
    /// when `periodic_v` (else clamped at the top and bottom rows). No-op for `sigma <= 0`.
    pub fn blur(&mut self, sigma: f64, periodic_v: bool) {
        if sigma <= 0.0 {
            return;
        }
        let r = (3.0 * sigma).ceil() as isize;
        let mut k: Vec<f32> = (-r..=r)
            .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
            .collect();
        let s: f32 = k.iter().sum();
        k.iter_mut().for_each(|x| *x /= s);
        let (w, h) = (self.w as isize, self.h as isize);
        let mut tmp = vec![0.0f32; self.data.len()];
        for v in 0..h {
            for u in 0..w {
                let mut acc = 0.0;
                for (j, kj) in k.iter().enumerate() {
                    acc += kj * self.at_wrap(u + j as isize - r, v);
                }
                tmp[(v * w + u) as usize] = acc;
            }
        }
        for v in 0..h {
            for u in 0..w {
                let mut acc = 0.0;
                for (j, kj) in k.iter().enumerate() {
                    let vv = v + j as isize - r;
                    let vv = if periodic_v {
                        vv.rem_euclid(h)
                    } else {
                        vv.clamp(0, h - 1)
                    };
                    acc += kj * tmp[(vv * w + u) as usize];
                }
                self.data[(v * w + u) as usize] = acc;
            }
        }
    }
}

/// Smooth value noise: random values in [-1, 1] on a lattice with `cell` texels per lattice
/// step, interpolated with a quintic fade. Periodic in u (the lattice count is rounded so that
/// it tiles exactly), and in v when `periodic_v`.
pub fn value_noise<R: Rng>(rng: &mut R, w: usize, h: usize, cell: f64, periodic_v: bool) -> Grid {
    let nu = ((w as f64 / cell).round() as usize).max(1);
    let nv_cells = ((h as f64 / cell).round() as usize).max(1);
    let nv = if periodic_v { nv_cells } else { nv_cells + 2 };
    let lattice: Vec<f32> = (0..nu * nv)
        .map(|_| rng::uniform(rng, -1.0, 1.0) as f32)
        .collect();
    let su = nu as f64 / w as f64;
    let sv = nv_cells as f64 / h as f64;
    let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let mut g = Grid::filled(w, h, 0.0);
    for v in 0..h {
        let fv = (v as f64 + 0.5) * sv;
        let j0 = fv.floor() as usize;
        let tv = fade(fv - j0 as f64) as f32;
        let (j0, j1) = if periodic_v {
            (j0 % nv, (j0 + 1) % nv)
        } else {
            (j0.min(nv - 1), (j0 + 1).min(nv - 1))
        };
        for u in 0..w {
            let fu = (u as f64 + 0.5) * su;
            let i0 = fu.floor() as usize;
            let tu = fade(fu - i0 as f64) as f32;
            let (i0, i1) = (i0 % nu, (i0 + 1) % nu);
            let a = lattice[j0 * nu + i0] * (1.0 - tu) + lattice[j0 * nu + i1] * tu;
            let b = lattice[j1 * nu + i0] * (1.0 - tu) + lattice[j1 * nu + i1] * tu;
            g.data[v * w + u] = a * (1.0 - tv) + b * tv;
        }
    }
    g
}

/// Sum of value-noise octaves `(cell_texels, weight)`, normalised to zero mean and unit std.
pub fn fractal_noise<R: Rng>(
    rng: &mut R,
    w: usize,
    h: usize,
    octaves: &[(f64, f64)],
    periodic_v: bool,
) -> Grid {
    let mut g = Grid::filled(w, h, 0.0);
    for &(cell, weight) in octaves {
        let o = value_noise(rng, w, h, cell, periodic_v);
        for (a, b) in g.data.iter_mut().zip(&o.data) {
            *a += weight as f32 * b;
        }
    }
    let (m, s) = (g.mean() as f32, g.std().max(1e-12) as f32);
    g.data.iter_mut().for_each(|x| *x = (*x - m) / s);
    g
}

/// The smooth-noise panorama in log intensity: `ln 0.4 + 0.5 contrast n` with `n` unit-std
/// fractal noise with features from 3 to 96 texels.
pub fn noise_panorama<R: Rng>(rng: &mut R, w: usize, h: usize, contrast: f64) -> Grid {
    let octaves = [
        (96.0, 1.0),
        (48.0, 0.7),
        (24.0, 0.5),
        (12.0, 0.35),
        (6.0, 0.25),
        (3.0, 0.15),
    ];
    let mut g = fractal_noise(rng, w, h, &octaves, false);
    let base = 0.4f32.ln();
    let k = (0.5 * contrast) as f32;
    g.data.iter_mut().for_each(|x| *x = base + k * *x);
    g
}

/// The urban panorama in linear intensity (before blur and log): sky above the horizon row
/// `horizon_v`, a row of buildings with windows, poles, and a darker ground strip below.
/// `texel_rad` is the angular size of a texel (sets the scale of the buildings).
pub fn urban_panorama<R: Rng>(
    rng: &mut R,
    w: usize,
    h: usize,
    horizon_v: f64,
    texel_rad: f64,
) -> Grid {
    // Scale so that building sizes are the same angles whatever the texture resolution.
    let s = 0.0044 / texel_rad;
    let px = |x: f64| (x * s).round() as isize;
    let mut g = Grid::filled(w, h, 0.0);
    // Sky: bright, brighter towards the top, with faint clouds.
    let clouds = fractal_noise(rng, w, h, &[(80.0 * s, 1.0), (30.0 * s, 0.5)], false);
    let hz = horizon_v as isize;
    for v in 0..h {
        let elev = (horizon_v - v as f64) / h as f64;
        for u in 0..w {
            let c = clouds.data[v * w + u];
            g.data[v * w + u] = (0.75 + 0.2 * elev) as f32 + 0.04 * c;
        }
    }
    // Ground strip: dark with texture.
    let grit = fractal_noise(rng, w, h, &[(12.0 * s, 1.0), (3.0 * s, 0.6)], false);
    for v in (hz.max(0) as usize)..h {
        for u in 0..w {
            g.data[v * w + u] = 0.2 * (1.0 + 0.08 * grit.data[v * w + u]);
        }
    }
    // Buildings.
    let mut u = 0isize;
    let wi = w as isize;
    while u < wi {
        let bw = px(rng::uniform(rng, 25.0, 220.0)).max(4);
        if rng.gen::<f64>() < 0.12 {
            // A gap showing the sky.
            u += bw / 2;
            continue;
        }
        let top = hz - px(rng::uniform(rng, 25.0, 180.0));
        let base = hz + px(rng::uniform(rng, 2.0, 10.0));
        let wall = rng::uniform(rng, 0.15, 0.6) as f32;
        let bw = bw.min(wi - u).max(1);
        g.fill_rect(u, top, u + bw, base, wall);
        // Windows on a regular grid.
        if rng.gen::<f64>() < 0.8 {
            let ww = px(rng::uniform(rng, 4.0, 12.0)).max(2);
            let wh = px(rng::uniform(rng, 5.0, 14.0)).max(2);
            let pu = ww + px(rng::uniform(rng, 3.0, 12.0)).max(1);
            let pv = wh + px(rng::uniform(rng, 4.0, 12.0)).max(1);
            // Windows: darker or lighter than the wall by a moderate factor, some lit.
            let dark = rng.gen::<bool>();
            let mut wv = top + pv / 2;
            while wv + wh < base - px(6.0) {
                let mut wu = u + (pu - ww) / 2 + 1;
                while wu + ww < u + bw {
                    let lit = rng.gen::<f64>() < 0.15;
                    let factor = if lit {
                        rng::uniform(rng, 1.5, 2.5)
                    } else if dark {
                        rng::uniform(rng, 0.45, 0.75)
                    } else {
                        rng::uniform(rng, 1.2, 1.5)
                    };
                    let val = (f64::from(wall) * factor).min(0.95) as f32;
                    g.fill_rect(wu, wv, wu + ww, wv + wh, val);
                    wu += pu;
                }
                wv += pv;
            }
        }
        u += bw;
    }
    // Poles and trunks in front.
    let n_poles = (w as f64 / (90.0 * s)).round() as usize;
    for _ in 0..n_poles {
        let pu = rng.gen_range(0..wi);
        let pw = px(rng::uniform(rng, 2.0, 6.0)).max(1);
        let top = hz - px(rng::uniform(rng, 30.0, 120.0));
        let val = rng::uniform(rng, 0.08, 0.2) as f32;
        g.fill_rect(pu, top, pu + pw, hz + px(12.0), val);
    }
    g
}

/// The ground texture in linear intensity: `n x n` texels, periodic in both directions. Asphalt
/// grain and patches, and dashed lane markings along v (world z) at `+-lane_texels` from u = 0.
pub fn ground_texture<R: Rng>(rng: &mut R, n: usize, lane_texels: usize) -> Grid {
    let grain = fractal_noise(
        rng,
        n,
        n,
        &[(64.0, 1.0), (16.0, 0.6), (4.0, 0.5), (1.5, 0.4)],
        true,
    );
    let mut g = Grid::filled(n, n, 0.0);
    for (o, gr) in g.data.iter_mut().zip(&grain.data) {
        *o = 0.22 * (0.3 * gr).exp();
    }
    // Dark patches.
    for _ in 0..(n * n / 5_000).max(1) {
        let u = rng.gen_range(0..n) as isize;
        let v = rng.gen_range(0..n) as isize;
        let (a, b) = (rng.gen_range(2..20), rng.gen_range(2..20));
        g.fill_rect(u, v, u + a, v + b, rng::uniform(rng, 0.06, 0.12) as f32);
    }
    // Dashed lane markings: 2 texels wide, dash 3/8 of a period of n/8 texels.
    let period = (n / 8).max(1);
    for &lu in &[lane_texels as isize, n as isize - lane_texels as isize] {
        for k in 0..8 {
            let v0 = (k * period) as isize;
            for v in v0..v0 + (3 * period / 8) as isize {
                for u in lu..=lu + 1 {
                    let (uu, vv) = (u.rem_euclid(n as isize), v.rem_euclid(n as isize));
                    g.data[vv as usize * n + uu as usize] = 0.75;
                }
            }
        }
    }
    g
}

/// Converts linear intensity to natural log, then scales the contrast around the mean log
/// intensity: `L' = mean + contrast (L - mean)`.
pub fn to_log(g: &mut Grid, contrast: f64) {
    g.data.iter_mut().for_each(|x| *x = x.max(1e-4).ln());
    let m = g.mean() as f32;
    let k = contrast as f32;
    g.data.iter_mut().for_each(|x| *x = m + k * (*x - m));
}
