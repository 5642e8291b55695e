//! Independently moving objects: textured vertical rectangles ("people", "cars") standing on
//! the ground at a finite depth and sliding sideways at constant speed, in front of the
//! panorama and the ground plane, which they occlude.
//!
//! An object moves on its own: it changes the events, never the ground truth or the IMU (those
//! are the camera's motion). Geometry in the world frame of [`super::motion`] (y down, metres,
//! seconds): the ground is at `y = ground_y` (the camera's height above it at t = 0), an object's
//! rectangle spans `ground_y - height_m <= y <= ground_y`, faces the direction `facing_rad`
//! (normal `(sin f, 0, cos f)`) and slides along `(cos f, 0, -sin f)` (the camera's "right" when
//! the camera heading is `f`).

use rand::Rng;
use serde::{Deserialize, Serialize};

use super::camera::{CameraPose, Intrinsics};
use super::motion::{mat_vec, transpose};
use super::rng;
use super::texture::{self, Grid};

/// What an object looks like (sets its size, speed range and texture).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ObjectKind {
    /// A walker: 0.45-0.7 m wide, 1.6-1.9 m tall, 0.5-2 m/s, 2-10 m away.
    Person,
    /// A car seen from the side: 3.8-4.8 m long, 1.4-1.6 m tall, 1.5-3 m/s, 5-15 m away.
    Car,
}

/// One object, fully explicit (written to `meta.json` under `objects`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObjectSpec {
    /// Appearance.
    pub kind: ObjectKind,
    /// Extent along the direction of motion, m (> 0).
    pub width_m: f64,
    /// Height above the ground, m (> 0).
    pub height_m: f64,
    /// World position of the bottom centre at `t_ref_s`, m (`y` is the ground level).
    pub position_m: [f64; 3],
    /// The time of `position_m`, s.
    pub t_ref_s: f64,
    /// Direction the rectangle faces, rad (0 = the camera's initial heading).
    pub facing_rad: f64,
    /// Signed speed along `(cos facing, 0, -sin facing)`, m/s.
    pub speed_mps: f64,
}

impl ObjectSpec {
    /// Unit normal of the rectangle (world frame).
    pub fn normal(&self) -> [f64; 3] {
        let (s, c) = self.facing_rad.sin_cos();
        [s, 0.0, c]
    }

    /// Unit direction of motion for a positive speed (world frame).
    pub fn along(&self) -> [f64; 3] {
        let (s, c) = self.facing_rad.sin_cos();
        [c, 0.0, -s]
    }

    /// World position of the bottom centre at `t`, m.
    pub fn position(&self, t: f64) -> [f64; 3] {
        let e = self.along();
        let d = self.speed_mps * (t - self.t_ref_s);
        std::array::from_fn(|i| self.position_m[i] + d * e[i])
    }

    /// The four corners at `t` (world, m): bottom left, bottom right, top right, top left.
    pub fn corners(&self, t: f64) -> [[f64; 3]; 4] {
        let c = self.position(t);
        let e = self.along();
        let hw = 0.5 * self.width_m;
        let corner = |side: f64, up: f64| -> [f64; 3] {
            [c[0] + side * hw * e[0], c[1] - up, c[2] + side * hw * e[2]]
        };
        [
            corner(-1.0, 0.0),
            corner(1.0, 0.0),
            corner(1.0, self.height_m),
            corner(-1.0, self.height_m),
        ]
    }

    /// The image columns `(min, max)` (px, unclipped) the rectangle covers when the camera is
    /// at `pose`, or `None` when it is not entirely in front of the camera.
    pub fn columns(&self, pose: &CameraPose, intr: &Intrinsics) -> Option<(f64, f64)> {
        let b = project_bounds(&self.corners(pose.t_s), pose, intr)?;
        Some((b[0], b[1]))
    }

    /// Checks the parameters: finite position, time, facing and speed, a finite positive size.
    pub fn validate(&self) -> anyhow::Result<()> {
        let finite = self.position_m.iter().all(|v| v.is_finite())
            && self.t_ref_s.is_finite()
            && self.facing_rad.is_finite()
            && self.speed_mps.is_finite();
        let size = |v: f64| v > 0.0 && v.is_finite();
        anyhow::ensure!(
            finite && size(self.width_m) && size(self.height_m),
            "objects need a finite position, time, facing and speed and a finite positive size"
        );
        Ok(())
    }

    /// Draws an object that crosses part of the view of a camera moving along `camera`
    /// (`t -> (position m, heading rad)`), over `[0, duration_s]`. At `t_ref_s` (0.3-0.7 of the
    /// duration) it is at an azimuth of up to 0.6 half fields of view `half_fov_rad` off the
    /// camera's heading; its depth along that heading (the kind's range) is the closest the
    /// camera comes to its plane later on: a camera that drives forward stays that far away.
    pub fn random<R: Rng>(
        rng: &mut R,
        duration_s: f64,
        ground_y: f64,
        half_fov_rad: f64,
        camera: &dyn Fn(f64) -> ([f64; 3], f64),
    ) -> Self {
        let kind = if rng.gen::<f64>() < 0.6 {
            ObjectKind::Person
        } else {
            ObjectKind::Car
        };
        let (width_m, height_m, depth_m, speed) = match kind {
            ObjectKind::Person => (
                rng::uniform(rng, 0.45, 0.7),
                rng::uniform(rng, 1.6, 1.9),
                rng::uniform(rng, 2.0, 10.0),
                rng::uniform(rng, 0.5, 2.0),
            ),
            ObjectKind::Car => (
                rng::uniform(rng, 3.8, 4.8),
                rng::uniform(rng, 1.4, 1.6),
                rng::uniform(rng, 5.0, 15.0),
                rng::uniform(rng, 1.5, 3.0),
            ),
        };
        let speed_mps = rng::sign(rng) * speed;
        let t_ref_s = rng::uniform(rng, 0.3, 0.7) * duration_s;
        let azimuth = rng::uniform(rng, -0.6, 0.6) * half_fov_rad;
        let (p, facing_rad) = camera(t_ref_s);
        let (s, c) = facing_rad.sin_cos();
        let (n, e) = ([s, 0.0, c], [c, 0.0, -s]);
        // How much closer to the plane the camera gets after t_ref (10 ms grid).
        let mut ahead = 0.0f64;
        let mut t = t_ref_s;
        while t <= duration_s {
            let q = camera(t).0;
            ahead = ahead.max((0..3).map(|i| (q[i] - p[i]) * n[i]).sum());
            t += 0.01;
        }
        let dist = depth_m + ahead;
        let lateral = dist * azimuth.tan();
        let mut position_m: [f64; 3] = std::array::from_fn(|i| p[i] + dist * n[i] + lateral * e[i]);
        position_m[1] = ground_y;
        Self {
            kind,
            width_m,
            height_m,
            position_m,
            t_ref_s,
            facing_rad,
            speed_mps,
        }
    }
}

/// Pixel bounds `[x_min, x_max, y_min, y_max]` (unclipped) of world points seen from `pose`,
/// or `None` unless all of them are at least 1 cm in front of the camera.
fn project_bounds(points: &[[f64; 3]], pose: &CameraPose, intr: &Intrinsics) -> Option<[f64; 4]> {
    let rt = transpose(&pose.rot);
    let mut b = [
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    for p in points {
        let rel = [p[0] - pose.pos[0], p[1] - pose.pos[1], p[2] - pose.pos[2]];
        let q = mat_vec(&rt, &rel);
        if q[2] < 0.01 {
            return None;
        }
        let (x, y) = (
            intr.cx + intr.fx * q[0] / q[2],
            intr.cy + intr.fy * q[1] / q[2],
        );
        b = [b[0].min(x), b[1].max(x), b[2].min(y), b[3].max(y)];
    }
    Some(b)
}

/// An object's texture in log intensity, with a mip pyramid (level k has texels of
/// `texel_m * 2^k`) so that a far object is filtered, not aliased. Row 0 is the top.
#[derive(Clone, Debug)]
pub struct ObjectTexture {
    levels: Vec<Grid>,
    /// Texel size at level 0, m.
    pub texel_m: f64,
}

impl ObjectTexture {
    /// Draws the texture of `spec` with texels of `texel_m` metres, blurred by `blur_texels`
    /// (std) and with the log contrast scaled by `contrast`.
    pub fn new<R: Rng>(
        rng: &mut R,
        spec: &ObjectSpec,
        texel_m: f64,
        blur_texels: f64,
        contrast: f64,
    ) -> Self {
        let w = ((spec.width_m / texel_m).ceil() as usize).clamp(4, 2048);
        let h = ((spec.height_m / texel_m).ceil() as usize).clamp(4, 2048);
        let texel_m = (spec.width_m / w as f64).max(spec.height_m / h as f64);
        let mut g = match spec.kind {
            ObjectKind::Person => person_texture(rng, w, h, texel_m),
            ObjectKind::Car => car_texture(rng, w, h, texel_m),
        };
        g.blur(blur_texels, false);
        texture::to_log(&mut g, contrast);
        let mut levels = vec![g];
        while let Some(last) = levels.last() {
            if last.w <= 2 || last.h <= 2 {
                break;
            }
            let (nw, nh) = (last.w.div_ceil(2), last.h.div_ceil(2));
            let mut next = Grid::filled(nw, nh, 0.0);
            for v in 0..nh {
                for u in 0..nw {
                    let s = |du: usize, dv: usize| {
                        let (uu, vv) = ((2 * u + du).min(last.w - 1), (2 * v + dv).min(last.h - 1));
                        last.data[vv * last.w + uu]
                    };
                    next.data[v * nw + u] = 0.25 * (s(0, 0) + s(1, 0) + s(0, 1) + s(1, 1));
                }
            }
            levels.push(next);
        }
        Self { levels, texel_m }
    }

    /// Bilinear sample of level `l` at level-0 texel coordinates `(u, v)` (clamped).
    #[inline]
    fn bilinear(&self, l: usize, u: f32, v: f32) -> f32 {
        let g = &self.levels[l];
        let scale = 1.0 / (1u32 << l) as f32;
        let uu = (u * scale - 0.5).clamp(0.0, (g.w - 1) as f32);
        let vv = (v * scale - 0.5).clamp(0.0, (g.h - 1) as f32);
        let (i0, j0) = (uu as usize, vv as usize);
        let (i1, j1) = ((i0 + 1).min(g.w - 1), (j0 + 1).min(g.h - 1));
        let (fu, fv) = (uu - i0 as f32, vv - j0 as f32);
        let at = |i: usize, j: usize| g.data[j * g.w + i];
        let a = at(i0, j0) + fu * (at(i1, j0) - at(i0, j0));
        let b = at(i0, j1) + fu * (at(i1, j1) - at(i0, j1));
        a + fv * (b - a)
    }

    /// Trilinear sample at `(u_m, v_m)` metres from the top-left corner, for a pixel footprint
    /// of `footprint_m`.
    #[inline]
    pub fn sample(&self, u_m: f32, v_m: f32, footprint_m: f32) -> f32 {
        let inv = 1.0 / self.texel_m as f32;
        let (u, v) = (u_m * inv, v_m * inv);
        let top = (self.levels.len() - 1) as f32;
        let lod = (footprint_m * inv).max(1.0).log2().min(top);
        let l0 = lod as usize;
        let f = lod - l0 as f32;
        let a = self.bilinear(l0, u, v);
        if f <= 0.0 || l0 + 1 >= self.levels.len() {
            return a;
        }
        a + f * (self.bilinear(l0 + 1, u, v) - a)
    }
}

/// Fills the texels `[u0, u1) x [v0, v1)` given as fractions of the grid (clipped).
fn fill_frac(g: &mut Grid, u0: f64, v0: f64, u1: f64, v1: f64, value: f64) {
    let (w, h) = (g.w as f64, g.h as f64);
    let r = |x: f64, n: f64| (x * n).round().clamp(0.0, n) as isize;
    let (a, b, c, d) = (r(u0, w), r(v0, h), r(u1, w), r(v1, h));
    g.fill_rect(a, b, c.max(a), d.max(b), value as f32);
}

/// Multiplies the grid by `exp(amount n)`, `n` unit-std fractal noise with features of
/// `feature_m` and a third of that.
fn grain<R: Rng>(rng: &mut R, g: &mut Grid, texel_m: f64, feature_m: f64, amount: f64) {
    let cell = (feature_m / texel_m).max(2.0);
    let n = texture::fractal_noise(rng, g.w, g.h, &[(cell, 1.0), (cell / 3.0, 0.5)], false);
    for (o, x) in g.data.iter_mut().zip(&n.data) {
        *o *= (amount as f32 * x).exp();
    }
}

/// A walker in linear intensity: hair and face, a shirt with sleeves at the sides, trousers
/// with the gap between the legs, shoes; fabric grain.
fn person_texture<R: Rng>(rng: &mut R, w: usize, h: usize, texel_m: f64) -> Grid {
    let mut g = Grid::filled(w, h, rng::uniform(rng, 0.15, 0.5) as f32);
    let shirt = rng::uniform(rng, 0.1, 0.9);
    let sleeve = shirt * rng::uniform(rng, 0.6, 0.85);
    let trousers = rng::uniform(rng, 0.05, 0.6);
    let skin = rng::uniform(rng, 0.3, 0.6);
    fill_frac(&mut g, 0.3, 0.0, 0.7, 0.05, rng::uniform(rng, 0.03, 0.3));
    fill_frac(&mut g, 0.3, 0.05, 0.7, 0.13, skin);
    fill_frac(&mut g, 0.0, 0.13, 1.0, 0.52, shirt);
    fill_frac(&mut g, 0.0, 0.15, 0.16, 0.5, sleeve);
    fill_frac(&mut g, 0.84, 0.15, 1.0, 0.5, sleeve);
    fill_frac(&mut g, 0.0, 0.5, 0.12, 0.56, skin);
    fill_frac(&mut g, 0.88, 0.5, 1.0, 0.56, skin);
    fill_frac(&mut g, 0.12, 0.52, 0.88, 0.95, trousers);
    fill_frac(&mut g, 0.45, 0.62, 0.55, 0.95, rng::uniform(rng, 0.1, 0.4));
    fill_frac(&mut g, 0.12, 0.95, 0.88, 1.0, rng::uniform(rng, 0.03, 0.15));
    grain(rng, &mut g, texel_m, 0.12, 0.15);
    g
}

/// A car seen from the side in linear intensity, front to the left: windows with pillars, body
/// with door seams and lights, two wheels with rims, the dark gap under the body; paint grain.
fn car_texture<R: Rng>(rng: &mut R, w: usize, h: usize, texel_m: f64) -> Grid {
    let mut g = Grid::filled(w, h, rng::uniform(rng, 0.2, 0.5) as f32);
    let body = rng::uniform(rng, 0.08, 0.9);
    let glass = rng::uniform(rng, 0.03, 0.12);
    fill_frac(&mut g, 0.18, 0.0, 0.82, 0.38, body);
    fill_frac(&mut g, 0.22, 0.04, 0.78, 0.36, glass);
    for c in [0.22, 0.5, 0.78] {
        fill_frac(&mut g, c - 0.02, 0.04, c + 0.02, 0.36, body);
    }
    fill_frac(&mut g, 0.0, 0.36, 1.0, 0.86, body);
    for c in [0.36, 0.62] {
        fill_frac(&mut g, c - 0.004, 0.4, c + 0.004, 0.82, 0.5 * body);
    }
    fill_frac(&mut g, 0.0, 0.42, 0.03, 0.52, rng::uniform(rng, 0.6, 0.95));
    fill_frac(&mut g, 0.97, 0.42, 1.0, 0.52, rng::uniform(rng, 0.15, 0.3));
    fill_frac(&mut g, 0.0, 0.86, 1.0, 1.0, rng::uniform(rng, 0.02, 0.08));
    // Wheels: radius 0.33 m, rims of 0.2 m, centred 0.33 m above the ground.
    let (tyre, rim) = (rng::uniform(rng, 0.02, 0.06), rng::uniform(rng, 0.35, 0.7));
    let (cw, ch) = (w as f64 * texel_m, h as f64 * texel_m);
    for cu in [0.18 * cw, 0.82 * cw] {
        let cv = ch - 0.33;
        for v in 0..h {
            for u in 0..w {
                let (x, y) = (
                    (u as f64 + 0.5) * texel_m - cu,
                    (v as f64 + 0.5) * texel_m - cv,
                );
                let r = (x * x + y * y).sqrt();
                if r < 0.33 {
                    g.data[v * w + u] = if r < 0.2 { rim } else { tyre } as f32;
                }
            }
        }
    }
    grain(rng, &mut g, texel_m, 0.3, 0.08);
    g
}

/// A [`ObjectSpec`] with its texture, as the renderer needs it.
#[derive(Clone, Debug)]
pub struct MovingObject {
    /// Geometry and motion.
    pub spec: ObjectSpec,
    /// Appearance.
    pub texture: ObjectTexture,
}

/// One object at one render: its geometry in the camera frame (f32), relative to the camera,
/// and the pixel box it may cover.
#[derive(Clone, Copy, Debug)]
pub struct ObjectView<'a> {
    texture: &'a ObjectTexture,
    /// Normal, direction of motion and world down, in the camera frame.
    n: [f32; 3],
    e: [f32; 3],
    down: [f32; 3],
    /// `c . n`, `c . e`, `c . down` with `c` = bottom centre - camera position (world).
    cn: f32,
    ce: f32,
    cd: f32,
    half_w: f32,
    height: f32,
    /// Mirror the texture (drawn facing `-e`) so that the object faces where it goes.
    mirror: bool,
    /// Inverse focal length, 1/px.
    inv_f: f32,
    /// Columns `x0..x1` and rows `y0..y1` that may be covered.
    pub cols: (usize, usize),
    /// Rows (see `cols`).
    pub rows: (usize, usize),
    /// Distance of the bottom centre from the camera, m (for drawing far objects first).
    pub distance: f64,
}

impl MovingObject {
    /// The object as seen from `pose`, or `None` when it is entirely behind the camera.
    pub fn view(&self, pose: &CameraPose, intr: &Intrinsics) -> Option<ObjectView<'_>> {
        let s = &self.spec;
        let corners = s.corners(pose.t_s);
        let rt = transpose(&pose.rot);
        let behind = corners.iter().all(|p| {
            let rel = [p[0] - pose.pos[0], p[1] - pose.pos[1], p[2] - pose.pos[2]];
            mat_vec(&rt, &rel)[2] <= 0.0
        });
        if behind {
            return None;
        }
        let (w, h) = (usize::from(intr.width), usize::from(intr.height));
        let (cols, rows) = match project_bounds(&corners, pose, intr) {
            Some(b) => {
                // Two pixels of margin for the soft edges.
                let clip = |lo: f64, hi: f64, n: usize| {
                    let a = (lo - 2.0).floor().clamp(0.0, n as f64) as usize;
                    let b = ((hi + 3.0).floor().clamp(0.0, n as f64) as usize).max(a);
                    (a, b)
                };
                let (c, r) = (clip(b[0], b[1], w), clip(b[2], b[3], h));
                if c.0 == c.1 || r.0 == r.1 {
                    return None;
                }
                (c, r)
            }
            None => ((0, w), (0, h)),
        };
        let c = s.position(pose.t_s);
        let rel = [c[0] - pose.pos[0], c[1] - pose.pos[1], c[2] - pose.pos[2]];
        let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let (n, e, down) = (s.normal(), s.along(), [0.0, 1.0, 0.0]);
        let to_cam = |v: &[f64; 3]| mat_vec(&rt, v).map(|x| x as f32);
        Some(ObjectView {
            texture: &self.texture,
            n: to_cam(&n),
            e: to_cam(&e),
            down: to_cam(&down),
            cn: dot(&rel, &n) as f32,
            ce: dot(&rel, &e) as f32,
            cd: dot(&rel, &down) as f32,
            half_w: (0.5 * s.width_m) as f32,
            height: s.height_m as f32,
            mirror: s.speed_mps > 0.0,
            inv_f: (2.0 / (intr.fx + intr.fy)) as f32,
            cols,
            rows,
            distance: dot(&rel, &rel).sqrt(),
        })
    }
}

impl ObjectView<'_> {
    /// The log intensity along the camera-frame ray `(ax, ay, 1)`: the object where it covers
    /// the ray, blended over about one pixel at its edges, else `behind`.
    #[inline]
    pub fn shade(&self, ax: f32, ay: f32, behind: f32) -> f32 {
        let dn = self.n[0] * ax + self.n[1] * ay + self.n[2];
        if dn.abs() < 1e-6 {
            return behind;
        }
        let s = self.cn / dn;
        if s <= 0.0 {
            return behind;
        }
        let a = s * (self.e[0] * ax + self.e[1] * ay + self.e[2]) - self.ce;
        let b = s * (self.down[0] * ax + self.down[1] * ay + self.down[2]) - self.cd;
        // Footprint of a pixel at the hit point, m.
        let foot = s * (1.0 + ax * ax + ay * ay).sqrt() * self.inv_f;
        let inside = (self.half_w - a.abs()).min(-b).min(self.height + b);
        let k = (inside / foot + 0.5).clamp(0.0, 1.0);
        if k <= 0.0 {
            return behind;
        }
        let alpha = k * k * (3.0 - 2.0 * k);
        let u = if self.mirror {
            self.half_w - a
        } else {
            a + self.half_w
        };
        let v = self.texture.sample(u, b + self.height, foot);
        behind + alpha * (v - behind)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::motion::rot_y;

    fn still_pose(t_s: f64) -> CameraPose {
        CameraPose {
            rot: rot_y(0.0),
            heading: 0.0,
            pos: [0.0; 3],
            pure_yaw: true,
            t_s,
        }
    }

    fn walker() -> ObjectSpec {
        ObjectSpec {
            kind: ObjectKind::Person,
            width_m: 0.5,
            height_m: 1.8,
            position_m: [-1.0, 1.5, 6.0],
            t_ref_s: 0.0,
            facing_rad: 0.0,
            speed_mps: 1.0,
        }
    }

    /// The projected columns follow the pinhole model and move right for a positive speed.
    #[test]
    fn columns_follow_the_pinhole_projection() {
        let intr = Intrinsics::centred(346, 260, 226.0);
        let s = walker();
        let (a, b) = s.columns(&still_pose(0.0), &intr).unwrap();
        assert!((a - (intr.cx + 226.0 * -1.25 / 6.0)).abs() < 1e-9, "{a}");
        assert!((b - (intr.cx + 226.0 * -0.75 / 6.0)).abs() < 1e-9, "{b}");
        let (a2, _) = s.columns(&still_pose(1.0), &intr).unwrap();
        assert!((a2 - a - 226.0 / 6.0).abs() < 1e-9, "{a2}");
    }

    /// Rendering one object over a flat background: the texture inside the rectangle, the
    /// background outside, a blend within a pixel of the edges.
    #[test]
    fn shade_covers_exactly_the_rectangle() {
        let intr = Intrinsics::centred(346, 260, 226.0);
        let mut r = rng::stream(3, rng::Stream::ObjectTexture);
        let s = walker();
        let obj = MovingObject {
            texture: ObjectTexture::new(&mut r, &s, 6.0 / 226.0, 0.8, 1.0),
            spec: s.clone(),
        };
        let pose = still_pose(0.0);
        let v = obj.view(&pose, &intr).unwrap();
        let (x0, x1) = s.columns(&pose, &intr).unwrap();
        let behind = 100.0;
        for x in 0..346 {
            let ax = ((x as f64 - intr.cx) / 226.0) as f32;
            // Row of the object's middle height (y = 1.5 - 0.9 = 0.6 m below the camera).
            let y = intr.cy + 226.0 * 0.6 / 6.0;
            let ay = ((y - intr.cy) / 226.0) as f32;
            let out = v.shade(ax, ay, behind);
            let xf = x as f64;
            if xf < x0 - 1.0 || xf > x1 + 1.0 {
                assert_eq!(out, behind, "x {x}");
            } else if xf > x0 + 1.0 && xf < x1 - 1.0 {
                assert!(out < 10.0, "x {x}: {out}");
            }
        }
        // Above the head and below the feet: background.
        let ax = 0.0f32;
        let above = ((1.5 - 1.8 - 0.1) / 6.0) as f32;
        let below = ((1.5 + 0.1) / 6.0) as f32;
        let v0 = obj.view(&still_pose(1.0), &intr).unwrap();
        assert_eq!(v0.shade(ax, above, behind), behind);
        assert_eq!(v0.shade(ax, below, behind), behind);
        assert!(v0.shade(ax, 0.1, behind) < 10.0);
    }
}
