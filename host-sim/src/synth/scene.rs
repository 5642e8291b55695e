//! The scene (a textured cylindrical panorama at infinity, optionally a textured ground plane
//! and moving objects in front of them) and the renderer that turns a camera pose into a
//! log-intensity image.
//!
//! Image buffers are column-major: pixel `(x, y)` is at index `x * height + y`.

use super::camera::{CameraPose, Intrinsics};
use super::objects::{MovingObject, ObjectView};
use super::texture::Grid;

/// A cylindrical panorama at infinity, in log intensity.
///
/// A world ray `d` maps to azimuth `atan2(d.x, d.z)` (rad, 0 = initial heading, > 0 = right) and
/// cylinder height `h = d.y / hypot(d.x, d.z)` (> 0 = below the horizon). Texture coordinates:
/// `u = azimuth * w / 2pi` (periodic), `v = (h + h_max) * texels_per_h` (clamped); texel centres
/// at integer + 0.5; bilinear interpolation.
#[derive(Clone, Debug)]
pub struct Panorama {
    w: usize,
    h: usize,
    /// Column-major, `w + 1` columns (the last repeats the first) of `h` rows.
    data: Vec<f32>,
    /// Texels per rad of azimuth (`w / 2pi`).
    pub texels_per_rad: f64,
    /// Texel rows per unit of cylinder height.
    pub texels_per_h: f64,
    /// Half the cylinder height covered by the texture (`h` in `[-h_max, h_max]`).
    pub h_max: f64,
}

impl Panorama {
    /// Wraps a row-major log-intensity grid whose width spans 360 degrees and whose height spans
    /// `[-h_max, h_max]`.
    pub fn new(g: &Grid, h_max: f64) -> Self {
        let (w, h) = (g.w, g.h);
        let mut data = vec![0.0f32; (w + 1) * h];
        for u in 0..=w {
            for v in 0..h {
                data[u * h + v] = g.data[v * w + (u % w)];
            }
        }
        Self {
            w,
            h,
            data,
            texels_per_rad: w as f64 / std::f64::consts::TAU,
            texels_per_h: h as f64 / (2.0 * h_max),
            h_max,
        }
    }

    /// Texture size `(w, h)` in texels.
    pub fn size(&self) -> (usize, usize) {
        (self.w, self.h)
    }

    /// The row index and weight for texture coordinate `v` (clamped): value = `(1-f) T[j] + f
    /// T[j+1]`.
    #[inline]
    fn row(&self, v: f32) -> (usize, f32) {
        let vv = (v - 0.5).clamp(0.0, (self.h - 1) as f32 - 1e-3);
        let j = vv as usize;
        (j, vv - j as f32)
    }

    /// The column index (in `[0, w)`) and weight for texture coordinate `u` (any real).
    #[inline]
    fn col(&self, u: f64) -> (usize, f32) {
        let w = self.w as f64;
        let uu = u - 0.5;
        let uu = uu - w * floor_f64(uu / w);
        let i = (uu as usize).min(self.w - 1);
        (i, (uu - i as f64) as f32)
    }

    /// Bilinear sample at texture coordinates `u` (an azimuth in `[-pi, pi]` in texel units) and
    /// `v` (any, clamped). Integer conversions through i32 (cheaper than to usize).
    #[inline(always)]
    fn sample_uv(&self, u: f32, v: f32) -> f32 {
        let w = self.w as f32;
        let mut uu = u - 0.5;
        uu += if uu < 0.0 { w } else { 0.0 };
        uu -= if uu >= w { w } else { 0.0 };
        let i = (uu as i32).clamp(0, self.w as i32 - 1);
        let fu = uu - i as f32;
        let vv = (v - 0.5).clamp(0.0, (self.h - 1) as f32 - 1e-3);
        let j = vv as i32;
        let fv = vv - j as f32;
        self.lerp(i as usize, fu, j as usize, fv)
    }

    /// Bilinear sample at column `(i, fu)` and row `(j, fv)`.
    #[inline]
    fn lerp(&self, i: usize, fu: f32, j: usize, fv: f32) -> f32 {
        let a = i * self.h + j;
        let b = a + self.h;
        let c0 = self.data[a] + fv * (self.data[a + 1] - self.data[a]);
        let c1 = self.data[b] + fv * (self.data[b + 1] - self.data[b]);
        c0 + fu * (c1 - c0)
    }

    /// Log intensity seen along the azimuth `az` (rad) and cylinder height `h`.
    #[inline]
    pub fn sample(&self, az: f64, h: f32) -> f32 {
        let (i, fu) = self.col(az * self.texels_per_rad);
        let (j, fv) = self.row(((f64::from(h) + self.h_max) * self.texels_per_h) as f32);
        self.lerp(i, fu, j, fv)
    }
}

/// A horizontal textured ground plane `height_m` below the camera (world `y = height_m`), in log
/// intensity, periodic, with a mip pyramid so that distant ground is filtered, not aliased.
#[derive(Clone, Debug)]
pub struct Ground {
    /// Level 0 is `n x n` texels (n a power of two); level k is `n / 2^k`.
    levels: Vec<Grid>,
    /// Texel size at level 0, metres.
    pub texel_m: f64,
    /// Camera height above the ground, metres.
    pub height_m: f64,
}

impl Ground {
    /// Builds the pyramid (down to a single texel, the mean) from a periodic `n x n`
    /// log-intensity grid (`n` a power of two).
    pub fn new(g: Grid, texel_m: f64, height_m: f64) -> Self {
        assert!(
            g.w == g.h && g.w.is_power_of_two(),
            "ground texture must be 2^k square"
        );
        let mut levels = vec![g];
        while let Some(last) = levels.last() {
            if last.w <= 1 {
                break;
            }
            let n = last.w / 2;
            let mut next = Grid::filled(n, n, 0.0);
            for v in 0..n {
                for u in 0..n {
                    let s = |du: usize, dv: usize| last.data[(2 * v + dv) * last.w + 2 * u + du];
                    next.data[v * n + u] = 0.25 * (s(0, 0) + s(1, 0) + s(0, 1) + s(1, 1));
                }
            }
            levels.push(next);
        }
        Self {
            levels,
            texel_m,
            height_m,
        }
    }

    /// The texture period, metres.
    pub fn period_m(&self) -> f64 {
        self.levels[0].w as f64 * self.texel_m
    }

    /// Bilinear, periodic sample of level `l` at texel coordinates `(u, v)` of level 0.
    #[inline]
    fn bilinear(&self, l: usize, u: f32, v: f32) -> f32 {
        let g = &self.levels[l];
        let scale = 1.0 / (1u32 << l) as f32;
        let (uu, vv) = (u * scale - 0.5, v * scale - 0.5);
        let (iu, iv) = (floor_i32(uu), floor_i32(vv));
        let (fu, fv) = (uu - iu as f32, vv - iv as f32);
        let mask = g.w as i32 - 1;
        let (i0, j0) = ((iu & mask) as usize, (iv & mask) as usize);
        let (i1, j1) = ((i0 + 1) & mask as usize, (j0 + 1) & mask as usize);
        let n = g.w;
        let (r0, r1) = (&g.data[j0 * n..j0 * n + n], &g.data[j1 * n..j1 * n + n]);
        let a = r0[i0] + fu * (r0[i1] - r0[i0]);
        let b = r1[i0] + fu * (r1[i1] - r1[i0]);
        a + fv * (b - a)
    }

    /// A box filter `taps` footprints long along `step` (m, x and z): the weighted mean of
    /// trilinear samples for a footprint of `footprint_m` at `(x_m, z_m) + j step` for whole `j`,
    /// each weighted by the overlap of `[j - 1/2, j + 1/2]` with `[-taps/2, taps/2]`. The
    /// weights, hence the value, change continuously with `taps` (>= 1).
    #[inline]
    pub fn sample_along(
        &self,
        x_m: f32,
        z_m: f32,
        footprint_m: f32,
        step: (f32, f32),
        taps: f32,
    ) -> f32 {
        let inv = 1.0 / self.texel_m as f32;
        let lod = self.lod(footprint_m * inv);
        let (u, v) = (x_m * inv, z_m * inv);
        let centre = self.trilinear(u, v, lod);
        if taps <= 1.0 {
            return centre;
        }
        let (su, sv) = (step.0 * inv, step.1 * inv);
        let mut acc = centre;
        let mut j = 1.0f32;
        loop {
            let w = (0.5 * taps - (j - 0.5)).min(1.0);
            if w <= 0.0 {
                break;
            }
            let (du, dv) = (j * su, j * sv);
            acc += w * (self.trilinear(u + du, v + dv, lod) + self.trilinear(u - du, v - dv, lod));
            j += 1.0;
        }
        acc / taps
    }

    /// Trilinear sample at ground point `(x_m, z_m)` for a pixel footprint of `footprint_m`.
    #[inline]
    pub fn sample(&self, x_m: f32, z_m: f32, footprint_m: f32) -> f32 {
        let inv = 1.0 / self.texel_m as f32;
        self.trilinear(x_m * inv, z_m * inv, self.lod(footprint_m * inv))
    }

    /// The mip level `(l0, f)` (blend `f` of level `l0 + 1`) for a footprint of `texels`.
    #[inline]
    fn lod(&self, texels: f32) -> (usize, f32) {
        let top = (self.levels.len() - 1) as f32;
        let lod = fast_log2(texels.max(1.0)).min(top);
        let l0 = lod as usize;
        (l0, lod - l0 as f32)
    }

    /// Trilinear sample at level-0 texel coordinates `(u, v)` and mip level `lod`.
    #[inline]
    fn trilinear(&self, u: f32, v: f32, (l0, f): (usize, f32)) -> f32 {
        let a = self.bilinear(l0, u, v);
        if f <= 0.0 || l0 + 1 >= self.levels.len() {
            return a;
        }
        let b = self.bilinear(l0 + 1, u, v);
        a + f * (b - a)
    }
}

/// `floor(x)` as i32 without a libm call (valid for |x| < 2^31).
#[inline]
fn floor_i32(x: f32) -> i32 {
    let i = x as i32;
    if (i as f32) > x {
        i.saturating_sub(1)
    } else {
        i
    }
}

/// `floor(x)` without a libm call (valid for |x| < 2^62).
#[inline]
fn floor_f64(x: f64) -> f64 {
    let i = x as i64;
    let f = i as f64;
    if f > x {
        f - 1.0
    } else {
        f
    }
}

/// Continuous, monotonic piecewise-linear approximation of `log2(x)` for `x >= 1` normal
/// floats (exact at powers of two, error below 0.09): exponent plus mantissa fraction.
#[inline]
fn fast_log2(x: f32) -> f32 {
    let bits = x.to_bits();
    let exp = ((bits >> 23) & 0xff) as i32 - 127;
    let mant = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000); // in [1, 2)
    exp as f32 + (mant - 1.0)
}

/// The scene: a panorama, optionally a ground plane, and moving objects.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The panorama at infinity.
    pub panorama: Panorama,
    /// The ground plane, if any.
    pub ground: Option<Ground>,
    /// Independently moving objects (drawn over the panorama and the ground, far ones first).
    pub objects: Vec<MovingObject>,
}

/// Precomputed per-column and per-pixel terms for a camera that only yaws (no ground plane):
/// the azimuth of pixel `(x, y)` is `heading + atan((x - cx) / fx)` and its cylinder height
/// does not change over time.
#[derive(Clone, Debug)]
struct FastYaw {
    /// `atan((x - cx) / fx) * texels_per_rad` per column.
    col_u: Vec<f64>,
    /// Texture row and weight per pixel (column-major).
    rows: Vec<(u32, f32)>,
}

/// The camera rotation and position a background image was rendered for, and the image.
type Background = (([[f64; 3]; 3], [f64; 3]), Vec<f32>);

/// Renders log-intensity images of a [`Scene`] for a pinhole camera.
#[derive(Debug)]
pub struct Renderer {
    w: usize,
    h: usize,
    /// Camera-frame ray `((x-cx)/fx, (y-cy)/fy, 1)` per pixel (column-major): x components.
    ray_x: Vec<f32>,
    /// ... and y components.
    ray_y: Vec<f32>,
    fast: FastYaw,
    scene: Scene,
    intr: Intrinsics,
    /// The last background (panorama and ground) rendered under moving objects.
    background: std::sync::Mutex<Option<Background>>,
    /// Mean focal length, px.
    f: f32,
    threads: usize,
}

impl Renderer {
    /// A renderer for `intr` using up to `threads` threads (1 = no threads).
    pub fn new(intr: &Intrinsics, scene: Scene, threads: usize) -> Self {
        let (w, h) = (usize::from(intr.width), usize::from(intr.height));
        let mut ray_x = Vec::with_capacity(w * h);
        let mut ray_y = Vec::with_capacity(w * h);
        let mut rows = Vec::with_capacity(w * h);
        let mut col_u = Vec::with_capacity(w);
        let pano = &scene.panorama;
        for x in 0..w {
            let dx = (x as f64 - intr.cx) / intr.fx;
            col_u.push(dx.atan() * pano.texels_per_rad);
            for y in 0..h {
                let dy = (y as f64 - intr.cy) / intr.fy;
                ray_x.push(dx as f32);
                ray_y.push(dy as f32);
                let hc = dy / (1.0 + dx * dx).sqrt();
                rows.push(pano.row(((hc + pano.h_max) * pano.texels_per_h) as f32));
            }
        }
        let rows = rows.into_iter().map(|(j, f)| (j as u32, f)).collect();
        Self {
            w,
            h,
            ray_x,
            ray_y,
            fast: FastYaw { col_u, rows },
            scene,
            intr: *intr,
            background: std::sync::Mutex::new(None),
            f: (0.5 * (intr.fx + intr.fy)) as f32,
            threads: threads.max(1),
        }
    }

    /// The scene being rendered.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Renders the log-intensity image for `pose` into `out` (column-major, `width * height`).
    pub fn render(&self, pose: &CameraPose, out: &mut [f32]) {
        assert_eq!(out.len(), self.w * self.h);
        let fast = pose.pure_yaw && self.scene.ground.is_none();
        if self.scene.objects.is_empty() {
            self.render_background(pose, fast, out);
            return;
        }
        // The background of a camera that has not moved since the last render is reused.
        let key = (pose.rot, pose.pos);
        let mut cache = self
            .background
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        match cache.as_ref() {
            Some((k, img)) if *k == key => out.copy_from_slice(img),
            _ => {
                self.render_background(pose, fast, out);
                *cache = Some((key, out.to_vec()));
            }
        }
        drop(cache);
        let mut views: Vec<ObjectView> = self
            .scene
            .objects
            .iter()
            .filter_map(|o| o.view(pose, &self.intr))
            .collect();
        views.sort_by(|a, b| b.distance.total_cmp(&a.distance));
        self.render_objects(&views, out);
    }

    /// Renders the panorama and the ground for `pose` into `out`.
    fn render_background(&self, pose: &CameraPose, fast: bool, out: &mut [f32]) {
        let cols_per_chunk = self.w.div_ceil(self.threads);
        // The pure-yaw path is too cheap per frame to pay for spawning threads.
        if fast || self.threads == 1 || self.w * self.h < 20_000 {
            self.render_cols(pose, fast, 0, out);
            return;
        }
        std::thread::scope(|s| {
            for (k, chunk) in out.chunks_mut(cols_per_chunk * self.h).enumerate() {
                s.spawn(move || self.render_cols(pose, fast, k * cols_per_chunk, chunk));
            }
        });
    }

    /// Renders the columns starting at `x0` into `out` (whole columns).
    fn render_cols(&self, pose: &CameraPose, fast: bool, x0: usize, out: &mut [f32]) {
        if fast {
            self.render_fast(pose.heading, x0, out);
        } else {
            self.render_generic(pose, x0, out);
        }
    }

    /// Draws the objects over the image, in the order given (far ones first).
    fn render_objects(&self, views: &[ObjectView], out: &mut [f32]) {
        let h = self.h;
        for v in views {
            for x in v.cols.0..v.cols.1 {
                let col = &mut out[x * h..(x + 1) * h];
                let (rx, ry) = (
                    &self.ray_x[x * h..(x + 1) * h],
                    &self.ray_y[x * h..(x + 1) * h],
                );
                for y in v.rows.0..v.rows.1 {
                    col[y] = v.shade(rx[y], ry[y], col[y]);
                }
            }
        }
    }

    /// Pure yaw over the panorama: one column lookup per image column, fixed rows.
    fn render_fast(&self, heading: f64, x0: usize, out: &mut [f32]) {
        let pano = &self.scene.panorama;
        let u_head = heading * pano.texels_per_rad;
        for (k, col) in out.chunks_mut(self.h).enumerate() {
            let x = x0 + k;
            let (i, fu) = pano.col(u_head + self.fast.col_u[x]);
            let rows = &self.fast.rows[x * self.h..(x + 1) * self.h];
            for (o, &(j, fv)) in col.iter_mut().zip(rows) {
                *o = pano.lerp(i, fu, j as usize, fv);
            }
        }
    }

    /// Any pose: rotate every ray, intersect the ground or look up the panorama. Two passes per
    /// column: the geometry (branch-free, so that it vectorises) into scratch buffers, then the
    /// texture lookups.
    fn render_generic(&self, pose: &CameraPose, x0: usize, out: &mut [f32]) {
        let pano = &self.scene.panorama;
        let r = pose.rot.map(|row| row.map(|v| v as f32));
        let tpr = pano.texels_per_rad as f32;
        let hoff = pano.h_max as f32;
        let tph = pano.texels_per_h as f32;
        let ground = self.scene.ground.as_ref().map(|g| {
            let p = g.period_m();
            let height = g.height_m - pose.pos[1];
            (
                g,
                pose.pos[0].rem_euclid(p) as f32,
                pose.pos[2].rem_euclid(p) as f32,
                height as f32,
                (height / f64::from(self.f)) as f32,
            )
        });
        // Ground/panorama blend over the 2.5 px above the horizon: the ground weight rises
        // (smoothstep) from 0 to 1 as sin(depression) = dy / |d| goes from 0 to `g_blend`.
        let g_blend = 2.5 / self.f;
        let h = self.h;
        let mut pu = vec![0.0f32; h];
        let mut pv = vec![0.0f32; h];
        let mut gx = vec![0.0f32; h];
        let mut gz = vec![0.0f32; h];
        let mut foot = vec![0.0f32; h];
        let mut gw = vec![0.0f32; h];
        let mut step_x = vec![0.0f32; h];
        let mut step_z = vec![0.0f32; h];
        let mut taps = vec![1.0f32; h];
        for (k, col) in out.chunks_mut(h).enumerate() {
            let x = x0 + k;
            let (rx, ry) = (
                &self.ray_x[x * h..(x + 1) * h],
                &self.ray_y[x * h..(x + 1) * h],
            );
            // Panorama coordinates of every pixel.
            for (((u, v), &ax), &ay) in pu.iter_mut().zip(pv.iter_mut()).zip(rx).zip(ry) {
                let dx = r[0][0] * ax + r[0][1] * ay + r[0][2];
                let dy = r[1][0] * ax + r[1][1] * ay + r[1][2];
                let dz = r[2][0] * ax + r[2][1] * ay + r[2][2];
                *u = fast_atan2(dx, dz) * tpr;
                *v = (dy / (dx * dx + dz * dz).sqrt() + hoff) * tph;
            }
            // Ground coordinates, footprint and weight of every pixel.
            if let Some((_, px, pz, height, foot_k)) = ground {
                for y in 0..h {
                    let (ax, ay) = (rx[y], ry[y]);
                    let dx = r[0][0] * ax + r[0][1] * ay + r[0][2];
                    let dy = r[1][0] * ax + r[1][1] * ay + r[1][2];
                    let dz = r[2][0] * ax + r[2][1] * ay + r[2][2];
                    let dyp = dy.max(1e-9);
                    let inv_dy = 1.0 / dyp;
                    let len = (dx * dx + dz * dz + dyp * dyp).sqrt();
                    // q = 1 / sin(depression); distance to the ground = height q. A pixel's
                    // footprint is height q / f across the ray and height q^2 / f along it:
                    // n = sqrt(q) (1 to 8) taps along the ray's horizontal direction cover the
                    // along extent, each filtered over 1/n of it (height q^1.5 / f for q <= 64,
                    // the geometric mean of the two extents).
                    let q = len * inv_dy;
                    let t = height * inv_dy;
                    let n = q.sqrt().clamp(1.0, 8.0);
                    let hl = (dx * dx + dz * dz).sqrt().max(1e-9);
                    gx[y] = px + t * dx;
                    gz[y] = pz + t * dz;
                    foot[y] = foot_k * q * q / n;
                    step_x[y] = foot[y] * dx / hl;
                    step_z[y] = foot[y] * dz / hl;
                    taps[y] = n;
                    let a = (dyp / (len * g_blend)).min(1.0);
                    let wgt = a * a * (3.0 - 2.0 * a);
                    gw[y] = if dy > 0.0 { wgt } else { 0.0 };
                }
            }
            for (y, o) in col.iter_mut().enumerate() {
                let w = if ground.is_some() { gw[y] } else { 0.0 };
                let pano_val = || pano.sample_uv(pu[y], pv[y]);
                *o = match ground {
                    Some((g, ..)) if w > 0.0 => {
                        let gv =
                            g.sample_along(gx[y], gz[y], foot[y], (step_x[y], step_z[y]), taps[y]);
                        if w >= 1.0 {
                            gv
                        } else {
                            let p = pano_val();
                            p + w * (gv - p)
                        }
                    }
                    _ => pano_val(),
                };
            }
        }
    }
}

/// `atan2(y, x)` in f32 with an error below 2e-6 rad (odd polynomial in the ratio of the smaller
/// to the larger magnitude, fitted by weighted least squares for this project).
#[inline]
pub fn fast_atan2(y: f32, x: f32) -> f32 {
    use std::f32::consts::{FRAC_PI_2, PI};
    let (ax, ay) = (x.abs(), y.abs());
    let mn = ax.min(ay);
    let mx = ax.max(ay).max(f32::MIN_POSITIVE);
    let a = mn / mx;
    let s = a * a;
    let p = 0.999_977_2
        + s * (-0.332_622_85
            + s * (0.193_540_44 + s * (-0.116_426_51 + s * (0.052_647_315 + s * -0.011_719_104))));
    let r = a * p;
    let r = if ay > ax { FRAC_PI_2 - r } else { r };
    let r = if x < 0.0 { PI - r } else { r };
    if y < 0.0 {
        -r
    } else {
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::motion::rot_y;
    use crate::synth::{rng, texture};

    /// For a pure yaw, the general renderer (rotated rays, atan2) and the fast path (shifted
    /// precomputed columns) give the same image.
    #[test]
    fn generic_and_fast_paths_agree() {
        let intr = Intrinsics::centred(40, 30, 30.0);
        let mut r = rng::stream(9, rng::Stream::Texture);
        let (w, h) = (188, 60);
        let mut g = texture::urban_panorama(&mut r, w, h, 30.0, std::f64::consts::TAU / w as f64);
        g.blur(0.8, false);
        texture::to_log(&mut g, 1.0);
        let scene = Scene {
            panorama: Panorama::new(&g, 1.0),
            ground: None,
            objects: Vec::new(),
        };
        let renderer = Renderer::new(&intr, scene, 1);
        for heading in [0.0, 0.3, -2.5, 3.1] {
            let mut pose = CameraPose {
                rot: rot_y(heading),
                heading,
                pos: [0.0; 3],
                pure_yaw: true,
                t_s: 0.0,
            };
            let mut fast = vec![0.0; intr.pixels()];
            let mut generic = vec![0.0; intr.pixels()];
            renderer.render(&pose, &mut fast);
            pose.pure_yaw = false;
            renderer.render(&pose, &mut generic);
            let worst = fast
                .iter()
                .zip(&generic)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            assert!(worst < 2e-3, "heading {heading}: max difference {worst}");
        }
    }

    /// A ground texture like `build_scene`'s: 512 x 512 texels of 0.1 m, in log intensity.
    fn ground(height_m: f64) -> Ground {
        let mut r = rng::stream(4, rng::Stream::Texture);
        let mut g = texture::ground_texture(&mut r, 512, 18);
        g.blur(0.8, true);
        texture::to_log(&mut g, 1.0);
        Ground::new(g, 0.1, height_m)
    }

    /// The along-the-ray filter: one tap is a plain sample, the value changes continuously with
    /// the number of taps, and a footprint beyond the texture's period gives its mean.
    #[test]
    fn ground_filter_is_continuous() {
        let g = ground(1.5);
        let (x, z, foot, step) = (3.3f32, 17.9f32, 0.12f32, (0.05f32, 0.11f32));
        assert_eq!(g.sample_along(x, z, foot, step, 1.0), g.sample(x, z, foot));
        for n in [2.0f32, 3.0, 4.0, 7.0] {
            let below = g.sample_along(x, z, foot, step, n - 1e-4);
            let above = g.sample_along(x, z, foot, step, n + 1e-4);
            assert!((below - above).abs() < 1e-3, "{n}: {below} vs {above}");
        }
        let mean = g.levels.last().unwrap().data[0];
        assert_eq!(g.levels.last().unwrap().data.len(), 1);
        for (x, z) in [(0.0, 0.0), (13.0, -40.0), (1e4, 2e4)] {
            assert!((g.sample(x, z, 1e3) - mean).abs() < 1e-5);
        }
    }

    /// A small pitch step moves the rendered ground by a small amount everywhere, also near the
    /// horizon, where a point of the ground moves by `height q^2` per radian (q = 1 / sin of
    /// the depression): the ground is filtered over each pixel's whole footprint, so it does
    /// not alias there (a camera 3.4 m up, 0.1 mrad = 0.023 px at f = 226 px). Measured: at most
    /// 0.040, as much as the sharpest panorama edges change; 0.163 with one sample per pixel
    /// over the geometric mean of the footprint's extents.
    #[test]
    fn ground_near_the_horizon_does_not_alias() {
        use crate::synth::motion::{mat_mul, rot_x};
        let intr = Intrinsics::centred(346, 260, 226.0);
        let mut r = rng::stream(9, rng::Stream::Texture);
        let (w, h) = (1417, 300);
        let mut g = texture::urban_panorama(&mut r, w, h, 150.0, std::f64::consts::TAU / w as f64);
        g.blur(0.8, false);
        texture::to_log(&mut g, 1.0);
        let scene = Scene {
            panorama: Panorama::new(&g, 0.66),
            ground: Some(ground(3.4)),
            objects: Vec::new(),
        };
        let renderer = Renderer::new(&intr, scene, 1);
        let mut worst = 0.0f32;
        for k in 0..20 {
            let pitch = -0.03 + 0.003 * f64::from(k);
            let image = |p: f64| {
                let mut out = vec![0.0; intr.pixels()];
                let pose = CameraPose {
                    rot: mat_mul(&rot_y(0.3), &rot_x(p)),
                    heading: 0.3,
                    pos: [0.0; 3],
                    pure_yaw: false,
                    t_s: 0.0,
                };
                renderer.render(&pose, &mut out);
                out
            };
            let (a, b) = (image(pitch), image(pitch + 1e-4));
            let d = a
                .iter()
                .zip(&b)
                .map(|(p, q)| (p - q).abs())
                .fold(0.0, f32::max);
            worst = worst.max(d);
        }
        assert!(worst < 0.06, "largest change {worst}");
    }

    #[test]
    fn fast_atan2_is_accurate() {
        let mut worst = 0.0f64;
        for k in 0..10_000 {
            let a = k as f64 / 10_000.0 * std::f64::consts::TAU - std::f64::consts::PI;
            for r in [0.3, 1.0, 7.0] {
                let (y, x) = ((r * a.sin()) as f32, (r * a.cos()) as f32);
                let e = f64::from(fast_atan2(y, x)) - f64::from(y).atan2(f64::from(x));
                let e = (e + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                    - std::f64::consts::PI;
                worst = worst.max(e.abs());
            }
        }
        assert!(worst < 4e-6, "worst error {worst}");
    }
}
