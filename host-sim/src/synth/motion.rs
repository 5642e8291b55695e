//! Camera motion: heading (yaw), small pitch/roll oscillations and forward speed as analytic
//! functions of time, the camera-frame angular velocity, and the ground-truth trajectory.
//!
//! Conventions (those of `../shared/data/synthetic`): world frame gravity-aligned with y down,
//! origin and heading of the camera at t = 0. Camera-to-world rotation
//! `R_wc = Ry(heading) Rx(pitch) Rz(roll)`; heading > 0 = turned right, pitch > 0 = nose up,
//! roll > 0 = right side down. Angles in rad, rates in rad/s, times in s.

use rand::Rng;
use serde::{Deserialize, Serialize};

use super::rng;

/// One additive term of the heading rate `d heading / dt` (rad/s). Each term has a closed-form
/// integral, so the heading is exact at any time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum YawTerm {
    /// A constant rate.
    Constant {
        /// rad/s.
        rate: f64,
    },
    /// `amplitude * sin(2 pi freq_hz t + phase)`.
    Sine {
        /// rad/s.
        amplitude: f64,
        /// Hz (> 0).
        freq_hz: f64,
        /// rad.
        phase: f64,
    },
    /// A change of the rate by `delta` starting at `t0`, with a raised-cosine ramp of `ramp_s`
    /// (instantaneous when `ramp_s` is 0 or `t0 <= 0`).
    Step {
        /// s.
        t0: f64,
        /// rad/s.
        delta: f64,
        /// s.
        ramp_s: f64,
    },
    /// A turn: `peak * sin^2(pi (t - t0) / (t1 - t0))` on `[t0, t1]`, zero outside.
    Turn {
        /// s.
        t0: f64,
        /// s (> t0).
        t1: f64,
        /// rad/s.
        peak: f64,
    },
}

impl YawTerm {
    /// The rate contribution at `t` (rad/s).
    pub fn rate(&self, t: f64) -> f64 {
        use std::f64::consts::{PI, TAU};
        match *self {
            YawTerm::Constant { rate } => rate,
            YawTerm::Sine {
                amplitude,
                freq_hz,
                phase,
            } => amplitude * (TAU * freq_hz * t + phase).sin(),
            YawTerm::Step { t0, delta, ramp_s } => {
                if t0 <= 0.0 || ramp_s <= 0.0 {
                    if t >= t0 {
                        delta
                    } else {
                        0.0
                    }
                } else {
                    let u = ((t - t0) / ramp_s).clamp(0.0, 1.0);
                    delta * 0.5 * (1.0 - (PI * u).cos())
                }
            }
            YawTerm::Turn { t0, t1, peak } => {
                if t <= t0 || t >= t1 {
                    0.0
                } else {
                    let s = (PI * (t - t0) / (t1 - t0)).sin();
                    peak * s * s
                }
            }
        }
    }

    /// The integral of [`Self::rate`] from 0 to `t` (rad), `t >= 0`.
    pub fn integral(&self, t: f64) -> f64 {
        use std::f64::consts::{PI, TAU};
        match *self {
            YawTerm::Constant { rate } => rate * t,
            YawTerm::Sine {
                amplitude,
                freq_hz,
                phase,
            } => {
                let w = TAU * freq_hz;
                -amplitude / w * ((w * t + phase).cos() - phase.cos())
            }
            YawTerm::Step { t0, delta, ramp_s } => {
                if t0 <= 0.0 || ramp_s <= 0.0 {
                    delta * (t - t0.max(0.0)).max(0.0)
                } else if t <= t0 {
                    0.0
                } else if t <= t0 + ramp_s {
                    let u = (t - t0) / ramp_s;
                    delta * 0.5 * ramp_s * (u - (PI * u).sin() / PI)
                } else {
                    delta * (0.5 * ramp_s + (t - t0 - ramp_s))
                }
            }
            YawTerm::Turn { t0, t1, peak } => {
                let len = t1 - t0;
                let tau = (t - t0).clamp(0.0, len);
                peak * (0.5 * tau - len / (4.0 * PI) * (TAU * tau / len).sin())
            }
        }
    }
}

/// `sum_i a_i sin(2 pi f_i t + phi_i)`: a small angle oscillation (pitch or roll), rad.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Oscillation {
    /// `[amplitude_rad, freq_hz, phase_rad]` per component.
    pub components: Vec<[f64; 3]>,
}

impl Oscillation {
    /// Angle at `t`, rad.
    pub fn angle(&self, t: f64) -> f64 {
        use std::f64::consts::TAU;
        self.components
            .iter()
            .map(|[a, f, p]| a * (TAU * f * t + p).sin())
            .sum()
    }

    /// Angular rate at `t`, rad/s.
    pub fn rate(&self, t: f64) -> f64 {
        use std::f64::consts::TAU;
        self.components
            .iter()
            .map(|[a, f, p]| a * TAU * f * (TAU * f * t + p).cos())
            .sum()
    }

    /// True when the angle is identically zero.
    pub fn is_zero(&self) -> bool {
        self.components.iter().all(|c| c[0] == 0.0)
    }
}

/// Forward speed along the heading, `mean_mps (1 + rel_amplitude sin(2 pi freq_hz t + phase))`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Speed {
    /// m/s (>= 0).
    pub mean_mps: f64,
    /// Relative modulation, in [0, 1).
    pub rel_amplitude: f64,
    /// Hz.
    pub freq_hz: f64,
    /// rad.
    pub phase: f64,
}

impl Speed {
    /// Speed at `t`, m/s.
    pub fn at(&self, t: f64) -> f64 {
        let w = std::f64::consts::TAU * self.freq_hz;
        self.mean_mps * (1.0 + self.rel_amplitude * (w * t + self.phase).sin())
    }

    /// Acceleration along the heading at `t`, m/s^2.
    pub fn accel(&self, t: f64) -> f64 {
        let w = std::f64::consts::TAU * self.freq_hz;
        self.mean_mps * self.rel_amplitude * w * (w * t + self.phase).cos()
    }
}

/// The complete, explicit motion of the camera. Written to `meta.json` under `motion`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MotionSpec {
    /// Profile name (a [`MotionKind::name`], or `custom`).
    pub profile: String,
    /// Heading rate = sum of these terms (rad/s).
    pub yaw: Vec<YawTerm>,
    /// Pitch angle (rad).
    pub pitch: Oscillation,
    /// Roll angle (rad).
    pub roll: Oscillation,
    /// Forward speed (m/s); zero for a camera that only rotates.
    pub speed: Speed,
}

/// A named motion profile whose parameters are drawn from the seed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum MotionKind {
    /// Constant yaw rate `max_rate` (useful for calibration).
    Constant,
    /// Sinusoidal yaw rate, amplitude 0.7-1.0 x max_rate, 0.25-0.6 Hz.
    Sinusoid,
    /// Piecewise-constant yaw rate with 30 ms raised-cosine ramps, a new rate every 0.5-1.1 s.
    Steps,
    /// Car-like: forward driving with gentle bends (sin^2 lobes of 1-2.5 s, peak 0.65-1.0 x
    /// (max_rate - wobble)) alternating with lane changes (an S-shaped yaw doublet `+r, -r` of
    /// 2-3 s in total that shifts the car by one lane, 3.0-3.7 m, unless `r` would exceed the
    /// peak bound), plus a lane-keeping wobble of 0.04 x max_rate. In a sequence of 4 s or more
    /// the first two manoeuvres are one bend and one lane change, in random order.
    Car,
    /// No rotation at all: the yaw rate is exactly 0 (a camera on a tripod, unless a speed or
    /// a pitch/roll amplitude is set).
    Static,
    /// Drone forward flight: yaw turns one after another (sin^2 lobes of 0.5-1.5 s, or held
    /// turns with 0.15-0.3 s ramps and a 0.2-0.8 s plateau), peak 0.25-1.0 x max_rate, 0.1-0.8 s
    /// apart, mostly alternating in direction; pitch and roll wobble of a few degrees at 1-6 Hz.
    Drone,
    /// Hovering: slow yaw drift in segments of constant rate (0.1-1.0 x max_rate, 0.5-1.5 s,
    /// raised-cosine ramps of 0.1-0.3 s) separated by pauses of 0.4-1.0 s at exactly 0 rad/s;
    /// the sequence starts with a pause. No pitch/roll by default.
    Hover,
}

impl MotionKind {
    /// Name as written in `meta.json`.
    pub fn name(self) -> &'static str {
        match self {
            MotionKind::Constant => "constant",
            MotionKind::Sinusoid => "sinusoid",
            MotionKind::Steps => "steps",
            MotionKind::Car => "car",
            MotionKind::Static => "static",
            MotionKind::Drone => "drone",
            MotionKind::Hover => "hover",
        }
    }

    /// Default peak |yaw rate| (rad/s) of the profile.
    pub fn default_max_rate(self) -> f64 {
        match self {
            MotionKind::Constant => 0.5,
            MotionKind::Sinusoid => 0.5,
            MotionKind::Steps => 1.2,
            MotionKind::Car => 0.5,
            MotionKind::Static => 0.0,
            MotionKind::Drone => 2.0,
            MotionKind::Hover => 0.2,
        }
    }

    /// Default forward speed (m/s): 8 for `car`, 3.5 for `drone`, 0 otherwise.
    pub fn default_speed(self) -> f64 {
        match self {
            MotionKind::Car => 8.0,
            MotionKind::Drone => 3.5,
            _ => 0.0,
        }
    }

    /// Default pitch/roll oscillation amplitude (rad): 0.004 for `car`, 0.05 (2.9 deg) for
    /// `drone`, 0 otherwise.
    pub fn default_pitch_roll(self) -> f64 {
        match self {
            MotionKind::Car => 0.004,
            MotionKind::Drone => 0.05,
            _ => 0.0,
        }
    }
}

impl MotionSpec {
    /// Draws the parameters of `kind` from `rng`. `max_rate` bounds |yaw rate| (rad/s),
    /// `speed_mps` is the mean forward speed, `pitch_roll` the amplitude of the pitch and roll
    /// oscillations (rad, 0 = none).
    pub fn random<R: Rng>(
        kind: MotionKind,
        rng: &mut R,
        duration_s: f64,
        max_rate: f64,
        speed_mps: f64,
        pitch_roll: f64,
    ) -> Self {
        use std::f64::consts::TAU;
        let yaw = match kind {
            MotionKind::Constant => vec![YawTerm::Constant { rate: max_rate }],
            MotionKind::Sinusoid => {
                let amplitude = rng::uniform(rng, 0.7, 1.0) * max_rate;
                let offset = rng::uniform(rng, -0.1, 0.1) * amplitude;
                // Keep |rate| <= max_rate.
                let amplitude = amplitude.min(max_rate - offset.abs());
                vec![
                    YawTerm::Constant { rate: offset },
                    YawTerm::Sine {
                        amplitude,
                        freq_hz: rng::uniform(rng, 0.25, 0.6),
                        phase: rng::uniform(rng, 0.0, TAU),
                    },
                ]
            }
            MotionKind::Steps => {
                let ramp_s = 0.03;
                let mut terms = Vec::new();
                let mut t = 0.0;
                let mut prev = 0.0;
                // The first rate applies from t = 0; later ones until 0.2 s before the end.
                while terms.is_empty() || t < duration_s - 0.2 {
                    let rate = if rng.gen::<f64>() < 0.15 {
                        0.0
                    } else {
                        rng::sign(rng) * rng::uniform(rng, 0.15, 1.0) * max_rate
                    };
                    terms.push(YawTerm::Step {
                        t0: t,
                        delta: rate - prev,
                        ramp_s,
                    });
                    prev = rate;
                    t += rng::uniform(rng, 0.5, 1.1);
                }
                terms
            }
            MotionKind::Car => car_yaw(rng, duration_s, max_rate, speed_mps),
            MotionKind::Static => Vec::new(),
            MotionKind::Drone => drone_yaw(rng, duration_s, max_rate),
            MotionKind::Hover => hover_yaw(rng, duration_s, max_rate),
        };
        let osc = |rng: &mut R| Oscillation {
            components: if pitch_roll > 0.0 {
                vec![
                    [
                        pitch_roll * rng::uniform(rng, 0.5, 1.0),
                        rng::uniform(rng, 0.8, 2.0),
                        rng::uniform(rng, 0.0, TAU),
                    ],
                    [
                        0.3 * pitch_roll * rng::uniform(rng, 0.5, 1.0),
                        rng::uniform(rng, 3.0, 6.0),
                        rng::uniform(rng, 0.0, TAU),
                    ],
                ]
            } else {
                Vec::new()
            },
        };
        let (pitch, roll) = match kind {
            MotionKind::Drone | MotionKind::Hover => {
                (drone_wobble(rng, pitch_roll), drone_wobble(rng, pitch_roll))
            }
            _ => (osc(rng), osc(rng)),
        };
        let speed = if speed_mps > 0.0 {
            Speed {
                mean_mps: speed_mps,
                rel_amplitude: 0.1,
                freq_hz: rng::uniform(rng, 0.1, 0.3),
                phase: rng::uniform(rng, 0.0, TAU),
            }
        } else {
            Speed::default()
        };
        Self {
            profile: kind.name().to_string(),
            yaw,
            pitch,
            roll,
            speed,
        }
    }

    /// A pure rotation at a constant yaw rate (rad/s).
    pub fn constant_yaw(rate: f64) -> Self {
        Self {
            profile: "constant".into(),
            yaw: vec![YawTerm::Constant { rate }],
            pitch: Oscillation::default(),
            roll: Oscillation::default(),
            speed: Speed::default(),
        }
    }

    /// Heading (rad) at `t`.
    pub fn heading(&self, t: f64) -> f64 {
        self.yaw.iter().map(|y| y.integral(t)).sum()
    }

    /// Heading rate (rad/s) at `t`.
    pub fn heading_rate(&self, t: f64) -> f64 {
        self.yaw.iter().map(|y| y.rate(t)).sum()
    }

    /// True when the camera only yaws (no pitch, roll or translation).
    pub fn is_pure_yaw(&self) -> bool {
        self.pitch.is_zero() && self.roll.is_zero() && self.speed.mean_mps == 0.0
    }

    /// `(heading, pitch, roll)` at `t`, rad.
    pub fn angles(&self, t: f64) -> [f64; 3] {
        [self.heading(t), self.pitch.angle(t), self.roll.angle(t)]
    }

    /// The camera-to-world rotation `R_wc = Ry(heading) Rx(pitch) Rz(roll)` at `t` (row-major).
    pub fn rotation(&self, t: f64) -> [[f64; 3]; 3] {
        let [h, p, r] = self.angles(t);
        mat_mul(&mat_mul(&rot_y(h), &rot_x(p)), &rot_z(r))
    }

    /// Angular velocity in the camera frame `(wx, wy, wz)` at `t`, rad/s: with `R = A B C`
    /// (A = Ry(heading), B = Rx(pitch), C = Rz(roll)), `w = C^T B^T (0, h', 0) + C^T (p', 0, 0)
    /// + (0, 0, r')`. `wy` is the yaw rate (> 0 = turning right).
    pub fn omega_cam(&self, t: f64) -> [f64; 3] {
        let [_, p, r] = self.angles(t);
        let hd = self.heading_rate(t);
        let pd = self.pitch.rate(t);
        let rd = self.roll.rate(t);
        let bt = transpose(&rot_x(p));
        let ct = transpose(&rot_z(r));
        let a = mat_vec(&ct, &mat_vec(&bt, &[0.0, hd, 0.0]));
        let b = mat_vec(&ct, &[pd, 0.0, 0.0]);
        [a[0] + b[0], a[1] + b[1], a[2] + b[2] + rd]
    }

    /// World-frame velocity (m/s) at `t`: `speed (sin h, 0, cos h)`.
    pub fn velocity(&self, t: f64) -> [f64; 3] {
        let h = self.heading(t);
        let v = self.speed.at(t);
        [v * h.sin(), 0.0, v * h.cos()]
    }

    /// World-frame acceleration (m/s^2) at `t`.
    pub fn acceleration(&self, t: f64) -> [f64; 3] {
        let h = self.heading(t);
        let hd = self.heading_rate(t);
        let v = self.speed.at(t);
        let a = self.speed.accel(t);
        [
            a * h.sin() + v * hd * h.cos(),
            0.0,
            a * h.cos() - v * hd * h.sin(),
        ]
    }
}

/// The yaw terms of [`MotionKind::Car`]: a lane-keeping wobble, then bends (sin^2 lobes) and
/// lane changes (two opposite lobes back to back) one after another. A doublet of peak `r` and
/// total length `T` at speed `v` moves the car sideways by `v r T^2 / 8` m, so `r` is chosen to
/// move it by one lane at `speed_mps` (at least 1 m/s assumed), capped at the peak bound.
fn car_yaw<R: Rng>(rng: &mut R, duration_s: f64, max_rate: f64, speed_mps: f64) -> Vec<YawTerm> {
    use std::f64::consts::TAU;
    let wobble = 0.04 * max_rate;
    let mut terms = vec![YawTerm::Sine {
        amplitude: wobble,
        freq_hz: rng::uniform(rng, 0.2, 0.5),
        phase: rng::uniform(rng, 0.0, TAU),
    }];
    let peak_max = max_rate - wobble;
    let v = speed_mps.max(1.0);
    let mut t = rng::uniform(rng, 0.1, 0.3);
    let mut lane = rng.gen::<bool>();
    let mut first = true;
    while t < duration_s - 0.8 {
        let gap = rng::uniform(rng, 0.1, 0.4);
        let sign = rng::sign(rng);
        let rest = duration_s - t;
        if lane && rest >= 2.0 {
            let mut len = rng::uniform(rng, 2.0, 3.0);
            if first {
                // Leave room for a bend of at least 1 s after it.
                len = len.min(rest - gap - 1.0);
            }
            let len = len.max(2.0).min(rest);
            let offset_m = rng::uniform(rng, 3.0, 3.7);
            let r = (8.0 * offset_m / (v * len * len)).min(peak_max);
            let mid = t + 0.5 * len;
            terms.push(YawTerm::Turn {
                t0: t,
                t1: mid,
                peak: sign * r,
            });
            terms.push(YawTerm::Turn {
                t0: mid,
                t1: t + len,
                peak: -sign * r,
            });
            t += len + gap;
        } else {
            let mut len = rng::uniform(rng, 1.0, 2.5);
            if first {
                // Leave room for a lane change of at least 2 s after it.
                len = len.min(rest - gap - 2.0);
            }
            let len = len.max(0.8).min(rest);
            terms.push(YawTerm::Turn {
                t0: t,
                t1: t + len,
                peak: sign * rng::uniform(rng, 0.65, 1.0) * peak_max,
            });
            t += len + gap;
        }
        lane = !lane;
        first = false;
    }
    terms
}

/// The yaw terms of [`MotionKind::Drone`]: turns one after another from 0.1-0.5 s on, each a
/// sin^2 lobe (60 %) or a held turn (ramp, plateau, ramp), |peak| <= `max_rate`.
fn drone_yaw<R: Rng>(rng: &mut R, duration_s: f64, max_rate: f64) -> Vec<YawTerm> {
    let mut terms = Vec::new();
    let mut t = rng::uniform(rng, 0.1, 0.5);
    let mut sign = rng::sign(rng);
    while t < duration_s - 0.3 {
        let peak = sign * rng::uniform(rng, 0.25, 1.0) * max_rate;
        if rng.gen::<f64>() < 0.6 {
            let len = rng::uniform(rng, 0.5, 1.5).min(duration_s - t);
            terms.push(YawTerm::Turn {
                t0: t,
                t1: t + len,
                peak,
            });
            t += len;
        } else {
            let ramp_s = rng::uniform(rng, 0.15, 0.3);
            let hold = rng::uniform(rng, 0.2, 0.8);
            terms.push(YawTerm::Step {
                t0: t,
                delta: peak,
                ramp_s,
            });
            terms.push(YawTerm::Step {
                t0: t + ramp_s + hold,
                delta: -peak,
                ramp_s,
            });
            t += 2.0 * ramp_s + hold;
        }
        if rng.gen::<f64>() < 0.7 {
            sign = -sign;
        }
        t += rng::uniform(rng, 0.1, 0.8);
    }
    terms
}

/// The yaw terms of [`MotionKind::Hover`]: after a first pause, segments of constant rate
/// (a step up and the step back down, raised-cosine ramps), each followed by a pause. Between
/// segments every step has completed and the pairs cancel term by term, so the summed rate is
/// exactly 0.0 there.
fn hover_yaw<R: Rng>(rng: &mut R, duration_s: f64, max_rate: f64) -> Vec<YawTerm> {
    let mut terms = Vec::new();
    let mut t = rng::uniform(rng, 0.2, 0.8);
    while t < duration_s {
        let rate = rng::sign(rng) * rng::uniform(rng, 0.1, 1.0) * max_rate;
        let ramp_s = rng::uniform(rng, 0.1, 0.3);
        let hold = rng::uniform(rng, 0.5, 1.5);
        terms.push(YawTerm::Step {
            t0: t,
            delta: rate,
            ramp_s,
        });
        terms.push(YawTerm::Step {
            t0: t + ramp_s + hold,
            delta: -rate,
            ramp_s,
        });
        t += 2.0 * ramp_s + hold + rng::uniform(rng, 0.4, 1.0);
    }
    terms
}

/// A drone's attitude wobble about one axis: a component of `amplitude` x 0.5-1.0 at
/// 1-2.5 Hz and one of half that at 2.5-6 Hz (none when `amplitude` is 0).
fn drone_wobble<R: Rng>(rng: &mut R, amplitude: f64) -> Oscillation {
    use std::f64::consts::TAU;
    if amplitude <= 0.0 {
        return Oscillation::default();
    }
    Oscillation {
        components: vec![
            [
                amplitude * rng::uniform(rng, 0.5, 1.0),
                rng::uniform(rng, 1.0, 2.5),
                rng::uniform(rng, 0.0, TAU),
            ],
            [
                0.5 * amplitude * rng::uniform(rng, 0.5, 1.0),
                rng::uniform(rng, 2.5, 6.0),
                rng::uniform(rng, 0.0, TAU),
            ],
        ],
    }
}

/// Camera position over time, integrated from [`MotionSpec::velocity`] on a 1 ms grid (Simpson)
/// and interpolated with cubic Hermite splines (position error far below a millimetre).
#[derive(Clone, Debug)]
pub struct Trajectory {
    dt: f64,
    pos: Vec<[f64; 3]>,
    vel: Vec<[f64; 3]>,
}

impl Trajectory {
    /// Integrates the positions of `motion` over `[0, duration_s]`.
    pub fn new(motion: &MotionSpec, duration_s: f64) -> Self {
        let dt = 1e-3;
        let n = (duration_s / dt).ceil() as usize + 2;
        let mut pos = Vec::with_capacity(n);
        let mut vel = Vec::with_capacity(n);
        let mut p = [0.0; 3];
        for k in 0..n {
            let t = k as f64 * dt;
            let v0 = motion.velocity(t);
            pos.push(p);
            vel.push(v0);
            let vm = motion.velocity(t + 0.5 * dt);
            let v1 = motion.velocity(t + dt);
            for i in 0..3 {
                p[i] += dt / 6.0 * (v0[i] + 4.0 * vm[i] + v1[i]);
            }
        }
        Self { dt, pos, vel }
    }

    /// Position (m, world frame) at `t` (clamped to the integrated range).
    pub fn position(&self, t: f64) -> [f64; 3] {
        let last = self.pos.len() - 2;
        let s = (t / self.dt).max(0.0);
        let k = (s.floor() as usize).min(last);
        let u = (s - k as f64).min(1.0);
        let (h00, h10, h01, h11) = (
            (1.0 + 2.0 * u) * (1.0 - u) * (1.0 - u),
            u * (1.0 - u) * (1.0 - u),
            u * u * (3.0 - 2.0 * u),
            u * u * (u - 1.0),
        );
        let (p0, p1, v0, v1) = (self.pos[k], self.pos[k + 1], self.vel[k], self.vel[k + 1]);
        let mut out = [0.0; 3];
        for i in 0..3 {
            out[i] = h00 * p0[i] + h10 * self.dt * v0[i] + h01 * p1[i] + h11 * self.dt * v1[i];
        }
        out
    }
}

/// Rotation about x by `a` (rad).
pub fn rot_x(a: f64) -> [[f64; 3]; 3] {
    let (s, c) = a.sin_cos();
    [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]
}

/// Rotation about y by `a` (rad).
pub fn rot_y(a: f64) -> [[f64; 3]; 3] {
    let (s, c) = a.sin_cos();
    [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
}

/// Rotation about z by `a` (rad).
pub fn rot_z(a: f64) -> [[f64; 3]; 3] {
    let (s, c) = a.sin_cos();
    [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
}

/// `a b`.
pub fn mat_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

/// `a^T`.
pub fn transpose(a: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = a[j][i];
        }
    }
    m
}

/// `a v`.
pub fn mat_vec(a: &[[f64; 3]; 3], v: &[f64; 3]) -> [f64; 3] {
    [
        a[0][0] * v[0] + a[0][1] * v[1] + a[0][2] * v[2],
        a[1][0] * v[0] + a[1][1] * v[1] + a[1][2] * v[2],
        a[2][0] * v[0] + a[2][1] * v[1] + a[2][2] * v[2],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every term's closed-form integral matches a numerical integral of its rate.
    #[test]
    fn integrals_match_rates() {
        let terms = [
            YawTerm::Constant { rate: 0.3 },
            YawTerm::Sine {
                amplitude: 0.4,
                freq_hz: 0.5,
                phase: 1.0,
            },
            YawTerm::Step {
                t0: 0.5,
                delta: -0.7,
                ramp_s: 0.03,
            },
            YawTerm::Step {
                t0: 0.0,
                delta: 0.2,
                ramp_s: 0.03,
            },
            YawTerm::Turn {
                t0: 0.2,
                t1: 1.4,
                peak: 0.6,
            },
        ];
        for term in &terms {
            let n = 200_000;
            let dt = 2.0 / n as f64;
            let mut acc = 0.0;
            for k in 0..n {
                let t = (k as f64 + 0.5) * dt;
                acc += term.rate(t) * dt;
            }
            assert!((acc - term.integral(2.0)).abs() < 1e-6, "{term:?}");
        }
    }

    /// Pure heading rotation: the camera-frame y rate equals the heading rate.
    #[test]
    fn pure_yaw_omega() {
        let m = MotionSpec::constant_yaw(0.8);
        let w = m.omega_cam(1.0);
        assert!((w[1] - 0.8).abs() < 1e-12 && w[0].abs() < 1e-12 && w[2].abs() < 1e-12);
    }

    /// The camera-frame angular velocity is consistent with R^T dR/dt.
    #[test]
    fn omega_matches_rotation_derivative() {
        let mut rng = super::super::rng::stream(3, super::super::rng::Stream::Motion);
        let m = MotionSpec::random(MotionKind::Car, &mut rng, 4.0, 0.6, 8.0, 0.05);
        for &t in &[0.3, 1.7, 2.9] {
            let h = 1e-6;
            let r0 = m.rotation(t - h);
            let r1 = m.rotation(t + h);
            let r = m.rotation(t);
            let mut d = [[0.0; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    d[i][j] = (r1[i][j] - r0[i][j]) / (2.0 * h);
                }
            }
            let s = mat_mul(&transpose(&r), &d);
            let w = m.omega_cam(t);
            assert!((s[2][1] - w[0]).abs() < 1e-6);
            assert!((s[0][2] - w[1]).abs() < 1e-6);
            assert!((s[1][0] - w[2]).abs() < 1e-6);
        }
    }

    /// The integrated trajectory matches the velocity.
    #[test]
    fn trajectory_integrates_velocity() {
        let mut rng = super::super::rng::stream(5, super::super::rng::Stream::Motion);
        let m = MotionSpec::random(MotionKind::Car, &mut rng, 4.0, 0.6, 8.0, 0.0);
        let tr = Trajectory::new(&m, 4.0);
        let t = 2.3456;
        let h = 1e-4;
        let p0 = tr.position(t - h);
        let p1 = tr.position(t + h);
        let v = m.velocity(t);
        for i in 0..3 {
            assert!(((p1[i] - p0[i]) / (2.0 * h) - v[i]).abs() < 1e-3);
        }
    }
}
