//! Synthetic event-camera sequences with ground truth (`host-sim synth`).
//!
//! An ESIM-style simulator: a textured scene (a cylindrical panorama at infinity, optionally a
//! textured ground plane and independently moving objects, see [`objects`]) seen by a pinhole
//! camera that rotates (and optionally drives forward) along an analytic [`MotionSpec`]. The
//! log-intensity image is rendered at adaptively chosen times so that no pixel changes by more
//! than `max_change` x the mean threshold between two renders; each pixel's threshold crossings
//! are interpolated linearly between renders, which gives µs-accurate timestamps. An optional
//! [`Flicker`] burst adds a uniform, sinusoidal illumination change to every pixel (an event
//! storm, as under lamps on AC mains). Seeded with ChaCha streams: the same [`SynthConfig`]
//! always yields the same events, whatever the number of render threads.
//!
//! Library use: [`generate`] returns a [`Sequence`] in memory (events, ground truth, IMU,
//! intrinsics); [`write_sequence`] writes the folder layout of `../shared/data/synthetic`;
//! [`regime::preset`] builds the configuration of one of the motion regimes (car, drone, hover,
//! moving objects, pure rotation).

pub mod camera;
pub mod flicker;
pub mod motion;
pub mod objects;
pub mod output;
pub mod regime;
pub mod rng;
pub mod scene;
pub mod sensor;
pub mod texture;
pub mod truth;

use serde::{Deserialize, Serialize};

pub use camera::{CameraPose, Intrinsics, Preset};
pub use flicker::Flicker;
pub use motion::{MotionKind, MotionSpec, YawTerm};
pub use objects::{ObjectKind, ObjectSpec};
pub use output::write_sequence;
pub use regime::Regime;
pub use sensor::SensorParams;
pub use texture::TextureKind;
pub use truth::{GtRow, ImuParams, ImuRow};

use motion::Trajectory;
use objects::{MovingObject, ObjectTexture};
use scene::{Ground, Panorama, Renderer, Scene};
use sensor::{RawEvent, Sensor};

/// Generator name and version written to `meta.json`.
pub const GENERATOR: &str = concat!("host-sim synth ", env!("CARGO_PKG_VERSION"));

/// The events of a sequence: `t_us` from the start of the sequence, pixel, polarity (the
/// host's event type, as read from files).
pub use crate::formats::Event64 as Event;

/// Everything that defines a sequence. Defaults: DAVIS346, urban texture, sinusoidal yaw, 4 s,
/// seed 1.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SynthConfig {
    /// Sequence name (written to `meta.json`).
    pub name: String,
    /// Seed of every random choice.
    pub seed: u64,
    /// Sensor preset the intrinsics came from (informative once `intrinsics` is set).
    pub preset: Preset,
    /// Camera intrinsics.
    pub intrinsics: Intrinsics,
    /// Panorama texture.
    pub texture: TextureKind,
    /// Log-contrast multiplier of all textures (1 = nominal).
    pub contrast: f64,
    /// Panorama texels per pixel at the image centre.
    pub tex_res: f64,
    /// Gaussian pre-blur of the textures, texels (std).
    pub blur_texels: f64,
    /// Motion profile (its parameters are drawn from the seed unless `motion_spec` is set).
    pub motion: MotionKind,
    /// An explicit motion that overrides `motion`, `max_rate`, `speed_mps`, `pitch_roll_rad`.
    pub motion_spec: Option<MotionSpec>,
    /// Duration, s.
    pub duration_s: f64,
    /// Peak |yaw rate| of the profile, rad/s.
    pub max_rate: f64,
    /// Mean forward speed, m/s.
    pub speed_mps: f64,
    /// Amplitude of the pitch and roll oscillations, rad.
    pub pitch_roll_rad: f64,
    /// Whether the scene has a ground plane (needed for translation flow).
    pub ground: bool,
    /// Camera height above the ground plane, m.
    pub cam_height_m: f64,
    /// Pixel model.
    pub sensor: SensorParams,
    /// Largest allowed change of any pixel between two renders, as a fraction of the smaller of
    /// the mean ON/OFF thresholds.
    pub max_change: f64,
    /// Smallest render step, s.
    pub dt_min_s: f64,
    /// Largest render step, s.
    pub dt_max_s: f64,
    /// Ground-truth rate, Hz.
    pub gt_rate_hz: f64,
    /// IMU model.
    pub imu: ImuParams,
    /// Render threads (0 = all available, at most 4). Does not change the output.
    pub threads: usize,
    /// An optional burst of lighting flicker added to every pixel's log intensity (none by
    /// default). Absent from configurations written before it existed, and left out of the
    /// serialized form when `None`, so such `meta.json` files are unchanged.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flicker: Option<Flicker>,
    /// Number of independently moving objects drawn from the seed (0 = none, the default; at
    /// most [`MAX_OBJECTS`]). Left out of the serialized form when 0.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub objects: usize,
    /// Explicit moving objects that override `objects`. Left out of the serialized form when
    /// `None`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub object_specs: Option<Vec<ObjectSpec>>,
}

/// Most moving objects a configuration may ask for.
pub const MAX_OBJECTS: usize = 16;

/// For serde: true for 0.
fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl Default for SynthConfig {
    fn default() -> Self {
        Self::new(Preset::Davis346, TextureKind::Urban, MotionKind::Sinusoid)
    }
}

impl SynthConfig {
    /// The defaults for a preset, texture and motion profile (the profile's default peak rate,
    /// speed, pitch/roll, and a ground plane when it drives).
    pub fn new(preset: Preset, texture: TextureKind, motion: MotionKind) -> Self {
        let speed = motion.default_speed();
        Self {
            name: format!("{}_{}_{}", preset.name(), texture.name(), motion.name()),
            seed: 1,
            preset,
            intrinsics: preset.intrinsics(),
            texture,
            contrast: 1.0,
            tex_res: 1.0,
            blur_texels: 0.8,
            motion,
            motion_spec: None,
            duration_s: 4.0,
            max_rate: motion.default_max_rate(),
            speed_mps: speed,
            pitch_roll_rad: motion.default_pitch_roll(),
            ground: speed > 0.0,
            cam_height_m: 1.4,
            sensor: SensorParams::default(),
            max_change: 1.0 / 3.0,
            dt_min_s: 5e-6,
            dt_max_s: 2e-3,
            gt_rate_hz: 1000.0,
            imu: ImuParams::default(),
            threads: 0,
            flicker: None,
            objects: 0,
            object_specs: None,
        }
    }

    /// The motion this configuration produces (explicit, or drawn from the seed).
    pub fn resolve_motion(&self) -> MotionSpec {
        match &self.motion_spec {
            Some(m) => m.clone(),
            None => {
                let mut r = rng::stream(self.seed, rng::Stream::Motion);
                MotionSpec::random(
                    self.motion,
                    &mut r,
                    self.duration_s,
                    self.max_rate,
                    self.speed_mps,
                    self.pitch_roll_rad,
                )
            }
        }
    }

    /// The moving objects of this configuration (explicit, or drawn from the seed) for a camera
    /// that moves along `motion` with positions `trajectory` (`None` = it stays at the origin).
    pub fn resolve_objects(
        &self,
        motion: &MotionSpec,
        trajectory: Option<&Trajectory>,
    ) -> Vec<ObjectSpec> {
        if let Some(specs) = &self.object_specs {
            return specs.clone();
        }
        let mut r = rng::stream(self.seed, rng::Stream::Objects);
        let i = &self.intrinsics;
        let half_fov = (0.5 * f64::from(i.width) / i.fx).atan();
        let camera = |t: f64| {
            let pos = trajectory.map_or([0.0; 3], |tr| tr.position(t));
            (pos, motion.heading(t))
        };
        (0..self.objects)
            .map(|_| {
                ObjectSpec::random(
                    &mut r,
                    self.duration_s,
                    self.cam_height_m,
                    half_fov,
                    &camera,
                )
            })
            .collect()
    }

    /// Checks the parameters; an error names the first bad one.
    pub fn validate(&self) -> anyhow::Result<()> {
        use anyhow::ensure;
        let i = &self.intrinsics;
        ensure!(
            i.width >= 2 && i.height >= 2,
            "sensor must be at least 2 x 2 pixels"
        );
        ensure!(i.fx > 0.0 && i.fy > 0.0, "focal length must be positive");
        ensure!(
            self.duration_s > 0.0 && self.duration_s.is_finite(),
            "duration must be > 0"
        );
        ensure!(self.contrast >= 0.0, "contrast must be >= 0");
        ensure!(self.tex_res > 0.0, "tex_res must be > 0");
        ensure!(
            self.sensor.cp > 0.0 && self.sensor.cm > 0.0 && self.sensor.c_min > 0.0,
            "contrast thresholds must be > 0"
        );
        ensure!(self.sensor.noise_hz >= 0.0, "noise rate must be >= 0");
        ensure!(
            self.max_change > 0.0 && self.dt_min_s > 0.0 && self.dt_max_s >= self.dt_min_s,
            "bad time-step limits"
        );
        ensure!(
            self.gt_rate_hz > 0.0 && self.imu.rate_hz > 0.0,
            "rates must be > 0"
        );
        ensure!(
            self.cam_height_m > 0.0 && self.cam_height_m.is_finite(),
            "camera height must be > 0"
        );
        if let Some(f) = &self.flicker {
            f.validate(self.dt_min_s)?;
        }
        ensure!(
            self.objects <= MAX_OBJECTS,
            "at most {MAX_OBJECTS} moving objects (got {})",
            self.objects
        );
        if let Some(specs) = &self.object_specs {
            ensure!(
                specs.len() <= MAX_OBJECTS,
                "at most {MAX_OBJECTS} moving objects (got {})",
                specs.len()
            );
            for s in specs {
                s.validate()?;
            }
        }
        Ok(())
    }

    fn thread_count(&self) -> usize {
        if self.threads > 0 {
            self.threads
        } else {
            std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(1)
                .min(4)
        }
    }
}

/// Counters and rates of a generated sequence (written to `meta.json` under `stats`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Stats {
    /// Total events.
    pub events: u64,
    /// Threshold-crossing events.
    pub signal_events: u64,
    /// Background-activity and hot-pixel events.
    pub noise_events: u64,
    /// Crossings dropped by the refractory period.
    pub refractory_drops: u64,
    /// Pixel-steps with more than one crossing.
    pub multi_crossing_events: u64,
    /// Fraction of ON events.
    pub on_fraction: f64,
    /// Events per second over the whole sequence.
    pub mean_rate_ev_s: f64,
    /// Largest event rate over a 10 ms bin, events/s.
    pub peak_rate_ev_s_10ms: f64,
    /// Accepted renders.
    pub renders: u64,
    /// Renders rejected because some pixel changed by more than the limit.
    pub rejected_renders: u64,
    /// Steps accepted at `dt_min` although the limit was exceeded.
    pub dt_min_hits: u64,
    /// Smallest accepted render step, s.
    pub render_dt_min_s: f64,
    /// Largest accepted render step, s.
    pub render_dt_max_s: f64,
    /// max |wy| of the ground truth, rad/s.
    pub max_abs_wy_rad_s: f64,
    /// mean |wy| of the ground truth, rad/s.
    pub mean_abs_wy_rad_s: f64,
}

/// A generated sequence.
#[derive(Clone, Debug)]
pub struct Sequence {
    /// The configuration it was generated from.
    pub config: SynthConfig,
    /// Camera intrinsics.
    pub intrinsics: Intrinsics,
    /// The motion actually used.
    pub motion: MotionSpec,
    /// The moving objects actually used (they change the events only).
    pub objects: Vec<ObjectSpec>,
    /// Events, sorted by time (ties by row, then column).
    pub events: Vec<Event>,
    /// Ground truth at `config.gt_rate_hz`.
    pub gt: Vec<GtRow>,
    /// Simulated IMU at `config.imu.rate_hz`.
    pub imu: Vec<ImuRow>,
    /// Counters.
    pub stats: Stats,
    /// Everything for `meta.json`.
    pub meta: serde_json::Value,
}

impl Sequence {
    /// Ground-truth yaw rate `(t_s, wy rad/s)`.
    pub fn gt_yaw_rate(&self) -> Vec<(f64, f64)> {
        self.gt.iter().map(|g| (g.t_s, g.w[1])).collect()
    }

    /// Gyro yaw rate `(t_s, gy rad/s)` (with bias and noise).
    pub fn gyro_yaw_rate(&self) -> Vec<(f64, f64)> {
        self.imu.iter().map(|r| (r.t_s, r.gyro[1])).collect()
    }

    /// Its events as a recording in memory, with the sensor's size and intrinsics (the
    /// format of the `events.txt` that [`write_sequence`] writes), for the pipeline without a
    /// file.
    pub fn into_recording(self) -> crate::formats::Recording {
        let i = self.intrinsics;
        crate::formats::Recording {
            events: self.events,
            width: Some(i.width),
            height: Some(i.height),
            intrinsics: Some(crate::formats::Intrinsics::from(i)),
            gyro: None,
            format: crate::formats::Format::EcdText,
        }
    }
}

/// Generates the sequence described by `cfg`.
pub fn generate(cfg: &SynthConfig) -> anyhow::Result<Sequence> {
    generate_with_progress(cfg, &mut |_| {})
}

/// Like [`generate`], calling `progress(t_s)` after each render step (`t_s` = simulated time
/// reached, up to `cfg.duration_s`).
pub fn generate_with_progress(
    cfg: &SynthConfig,
    progress: &mut dyn FnMut(f64),
) -> anyhow::Result<Sequence> {
    cfg.validate()?;
    let intr = cfg.intrinsics;
    let motion = cfg.resolve_motion();
    let trajectory =
        (motion.speed.mean_mps > 0.0).then(|| Trajectory::new(&motion, cfg.duration_s));
    let pure_yaw = motion.is_pure_yaw();
    let pose_at = |t: f64| CameraPose {
        rot: motion.rotation(t),
        heading: motion.heading(t),
        pos: trajectory.as_ref().map_or([0.0; 3], |tr| tr.position(t)),
        pure_yaw,
        t_s: t,
    };
    let object_specs = cfg.resolve_objects(&motion, trajectory.as_ref());
    let (objects, objects_meta) = build_objects(cfg, &object_specs, &pose_at);
    let (scene, scene_meta) = build_scene(cfg, &motion, objects);
    let renderer = Renderer::new(&intr, scene, cfg.thread_count());

    let n = intr.pixels();
    let h = usize::from(intr.height);
    let mut cur = vec![0.0f32; n];
    let mut next = vec![0.0f32; n];
    // The flicker's change of log intensity at `t`, added to a rendered image.
    let flicker = cfg.flicker.as_ref();
    let add_flicker = |t: f64, img: &mut [f32]| {
        let g = flicker.map_or(0.0, |f| f.offset(t)) as f32;
        if g != 0.0 {
            img.iter_mut().for_each(|v| *v += g);
        }
    };
    renderer.render(&pose_at(0.0), &mut cur);
    add_flicker(0.0, &mut cur);
    let mut mismatch_rng = rng::stream(cfg.seed, rng::Stream::Sensor);
    let noise_rng = rng::stream(cfg.seed, rng::Stream::Noise);
    let mut sensor = Sensor::new(&cfg.sensor, &cur, &mut mismatch_rng, noise_rng);
    let (cp_mean, cm_mean) = sensor.mean_thresholds();
    let target = (cfg.max_change * cp_mean.min(cm_mean)) as f32;

    let mut stats = Stats {
        render_dt_min_s: f64::INFINITY,
        ..Stats::default()
    };
    let mut events: Vec<Event> = Vec::new();
    let mut batch: Vec<RawEvent> = Vec::new();
    let to_event = |r: &RawEvent| Event {
        t_us: r.t_us,
        x: (r.pixel as usize / h) as u16,
        y: (r.pixel as usize % h) as u16,
        on: r.on,
    };
    let t_end = cfg.duration_s;
    let mut t = 0.0;
    let mut dt = cfg.dt_max_s.min(1e-3);
    while t < t_end {
        let proposal = dt.clamp(cfg.dt_min_s, cfg.dt_max_s);
        let (mut t1, mut last) = if t + proposal >= t_end - 1e-9 {
            (t_end, true)
        } else {
            (t + proposal, false)
        };
        // Never step across the flicker's start or one of its quarter-period points: the
        // flicker is monotonic between them, so the change check below sees all of it.
        let mut cut = false;
        if let Some(b) = flicker.and_then(|f| f.next_breakpoint(t)) {
            if b < t1 {
                t1 = b;
                last = false;
                cut = true;
            }
        }
        let step = t1 - t;
        renderer.render(&pose_at(t1), &mut next);
        add_flicker(t1, &mut next);
        let change = max_abs_diff(&cur, &next);
        if change > target && step > cfg.dt_min_s * 1.000_001 {
            stats.rejected_renders += 1;
            dt = (step * f64::from(0.8 * target / change)).max(cfg.dt_min_s);
            continue;
        }
        if change > target {
            stats.dt_min_hits += 1;
        }
        batch.clear();
        sensor.step(t, t1, &cur, &next, &mut batch);
        sensor.noise(t1, &mut batch);
        batch.sort_unstable_by_key(|e| (e.t_us, e.pixel % h as u32, e.pixel / h as u32, e.on));
        events.extend(batch.iter().map(to_event));
        std::mem::swap(&mut cur, &mut next);
        stats.renders += 1;
        if !last {
            stats.render_dt_min_s = stats.render_dt_min_s.min(step);
        }
        stats.render_dt_max_s = stats.render_dt_max_s.max(step);
        let grow = if change > 0.0 {
            f64::from(0.8 * target / change).clamp(0.5, 2.0)
        } else {
            2.0
        };
        // A step shortened by a flicker breakpoint says little about the right step size:
        // try the proposal again (a rejection shortens it if needed).
        dt = if cut { proposal } else { step * grow };
        t = t1;
        progress(t);
    }
    if !stats.render_dt_min_s.is_finite() {
        stats.render_dt_min_s = stats.render_dt_max_s;
    }

    let gt = truth::ground_truth(&motion, cfg.duration_s, cfg.gt_rate_hz);
    let mut imu_rng = rng::stream(cfg.seed, rng::Stream::Imu);
    let (imu, gyro_bias, acc_bias) = truth::imu(&motion, cfg.duration_s, &cfg.imu, &mut imu_rng);

    let s = &sensor.stats;
    stats.events = events.len() as u64;
    stats.signal_events = s.signal_events;
    stats.noise_events = s.noise_events;
    stats.refractory_drops = s.refractory_drops;
    stats.multi_crossing_events = s.multi_crossing_events;
    stats.on_fraction = events.iter().filter(|e| e.on).count() as f64 / events.len().max(1) as f64;
    stats.mean_rate_ev_s = events.len() as f64 / cfg.duration_s;
    stats.peak_rate_ev_s_10ms = peak_rate(&events, 10_000);
    stats.max_abs_wy_rad_s = gt.iter().map(|g| g.w[1].abs()).fold(0.0, f64::max);
    stats.mean_abs_wy_rad_s = gt.iter().map(|g| g.w[1].abs()).sum::<f64>() / gt.len().max(1) as f64;

    let hot: Vec<[u32; 2]> = sensor
        .hot_pixels()
        .iter()
        .map(|&p| [p / h as u32, p % h as u32])
        .collect();
    let mut meta = serde_json::json!({
        "generator": GENERATOR,
        "name": cfg.name,
        "seed": cfg.seed,
        "fx": intr.fx,
        "fy": intr.fy,
        "cx": intr.cx,
        "cy": intr.cy,
        "width": intr.width,
        "height": intr.height,
        "config": cfg,
        "camera": {
            "model": "pinhole",
            "width": intr.width,
            "height": intr.height,
            "fx": intr.fx,
            "fy": intr.fy,
            "cx": intr.cx,
            "cy": intr.cy,
            "k1": 0.0,
            "k2": 0.0,
            "sensor_like": cfg.preset.name(),
        },
        "conventions": {
            "camera_frame": "x right, y down, z forward",
            "omega": "camera-frame angular velocity (wx, wy, wz) in rad/s",
            "yaw_sign": "wy > 0 = camera turns right (clockwise seen from above) => scene moves left in image (du/dt < 0)",
            "pixel": "x = column (0 = left), y = row (0 = top)",
            "polarity": "1 = ON (log intensity increased), 0 = OFF",
            "time": "integer microseconds from 0 (events.txt in seconds with 6 decimals)",
            "imu_frame": "identical to camera frame; imu.txt: m/s^2 and rad/s",
            "pose": "world = gravity-aligned (y down along gravity), origin and heading of the camera at t=0; R_wc = Ry(heading) Rx(pitch) Rz(roll)",
            "euler": "heading > 0 = turned right, pitch > 0 = nose up, roll > 0 = right side down (rad)",
            "yaw_rad": "gt.csv yaw_rad = integral of camera-frame wy from t=0 (equals heading when pitch = roll = 0)",
        },
        "motion": motion,
        "scene": scene_meta,
        "sensor": {
            "hot_pixels": hot,
            "Cp_mean": cp_mean,
            "Cm_mean": cm_mean,
        },
        "imu": {
            "rate_hz": cfg.imu.rate_hz,
            "gyro_bias_rad_s": gyro_bias,
            "acc_bias_m_s2": acc_bias,
            "gyro_noise_density": cfg.imu.gyro_noise_density,
            "acc_noise_density": cfg.imu.acc_noise_density,
        },
        "stats": stats,
        "files": ["events.txt", "gt.csv", "imu.txt"],
    });
    if !object_specs.is_empty() {
        meta["objects"] = objects_meta;
    }
    if let Some(f) = flicker {
        meta["flicker"] = serde_json::json!({
            "model": "log intensity of every pixel + amplitude_log * sin(2 pi freq_hz (t - start_s)) for start_s <= t <= end_s",
            "start_s": f.start_s,
            "end_s": f.end_s(),
            "periods": f.periods(),
            "freq_hz": f.freq_hz,
            "amplitude_log": f.amplitude_log,
        });
    }

    Ok(Sequence {
        config: cfg.clone(),
        intrinsics: intr,
        motion,
        objects: object_specs,
        events,
        gt,
        imu,
        stats,
        meta,
    })
}

/// Builds the textures and the scene with `objects`. Returns the scene and its description for
/// `meta.json` (the objects are described by [`build_objects`]).
fn build_scene(
    cfg: &SynthConfig,
    motion: &MotionSpec,
    objects: Vec<MovingObject>,
) -> (Scene, serde_json::Value) {
    let intr = &cfg.intrinsics;
    let mut trng = rng::stream(cfg.seed, rng::Stream::Texture);
    let f = 0.5 * (intr.fx + intr.fy);
    let texel_rad = 1.0 / (f * cfg.tex_res);
    let w_tex = (std::f64::consts::TAU / texel_rad).round().max(16.0) as usize;
    // Largest |cylinder height| seen by the image, plus room for pitch and roll.
    let dy_max = (intr.cy.max(f64::from(intr.height) - 1.0 - intr.cy) + 1.0) / intr.fy;
    let tilt: f64 = motion
        .pitch
        .components
        .iter()
        .chain(&motion.roll.components)
        .map(|c| c[0].abs())
        .sum();
    let h_max = 1.3 * dy_max + 0.1 + 2.0 * tilt;
    let h_tex = (2.0 * h_max * f * cfg.tex_res).round().max(8.0) as usize;
    let horizon_v = h_tex as f64 / 2.0;
    let grid = match cfg.texture {
        TextureKind::Noise => {
            let mut g = texture::noise_panorama(&mut trng, w_tex, h_tex, cfg.contrast);
            g.blur(cfg.blur_texels, false);
            g
        }
        TextureKind::Urban => {
            let mut g = texture::urban_panorama(&mut trng, w_tex, h_tex, horizon_v, texel_rad);
            g.blur(cfg.blur_texels, false);
            texture::to_log(&mut g, cfg.contrast);
            g
        }
    };
    let panorama = Panorama::new(&grid, h_max);
    let (ground, ground_meta) = if cfg.ground {
        let n = 512;
        let texel_m: f64 = 0.1;
        let mut g = texture::ground_texture(&mut trng, n, (1.75 / texel_m).round() as usize);
        g.blur(cfg.blur_texels, true);
        texture::to_log(&mut g, cfg.contrast);
        let ground = Ground::new(g, texel_m, cfg.cam_height_m);
        let meta = serde_json::json!({
            "height_m": cfg.cam_height_m,
            "texel_m": texel_m,
            "period_m": ground.period_m(),
        });
        (Some(ground), meta)
    } else {
        (None, serde_json::Value::Null)
    };
    let meta = serde_json::json!({
        "panorama": {
            "type": "cylinder at infinity",
            "texture": cfg.texture.name(),
            "width_texels": w_tex,
            "height_texels": h_tex,
            "h_max": h_max,
        },
        "ground_plane": ground_meta,
        "fast_yaw_renderer": motion.is_pure_yaw() && ground.is_none(),
    });
    (
        Scene {
            panorama,
            ground,
            objects,
        },
        meta,
    )
}

/// The moving objects with their textures, and their description for `meta.json` (per object:
/// the spec, its closest distance to the camera, the texel size, and the range of image columns
/// it covers over the sequence, on a 10 ms grid, `null` if never entirely in front of the
/// camera). A texel is about a pixel where the object comes closest to the camera.
fn build_objects(
    cfg: &SynthConfig,
    specs: &[ObjectSpec],
    pose_at: &dyn Fn(f64) -> CameraPose,
) -> (Vec<MovingObject>, serde_json::Value) {
    let intr = &cfg.intrinsics;
    let f = 0.5 * (intr.fx + intr.fy);
    let mut trng = rng::stream(cfg.seed, rng::Stream::ObjectTexture);
    let steps = (cfg.duration_s / 0.01).ceil() as usize;
    let times = (0..=steps).map(|k| (k as f64 * 0.01).min(cfg.duration_s));
    let mut objects = Vec::new();
    let mut meta = Vec::new();
    for spec in specs {
        let mut closest = f64::INFINITY;
        let mut cols: Option<(f64, f64)> = None;
        for t in times.clone() {
            let pose = pose_at(t);
            let c = spec.position(t);
            let e = spec.along();
            // Closest point of the bottom edge, horizontally.
            let rel = [c[0] - pose.pos[0], c[2] - pose.pos[2]];
            let along =
                (rel[0] * e[0] + rel[1] * e[2]).clamp(-0.5 * spec.width_m, 0.5 * spec.width_m);
            let d = ((rel[0] - along * e[0]).powi(2) + (rel[1] - along * e[2]).powi(2)).sqrt();
            closest = closest.min(d);
            if let Some((a, b)) = spec.columns(&pose, intr) {
                let (a, b) = (a.max(0.0), b.min(f64::from(intr.width) - 1.0));
                if a <= b {
                    cols = Some(cols.map_or((a, b), |(lo, hi)| (lo.min(a), hi.max(b))));
                }
            }
        }
        let texel_m = (closest.max(0.3) / (f * cfg.tex_res)).max(0.003);
        let texture = ObjectTexture::new(&mut trng, spec, texel_m, cfg.blur_texels, cfg.contrast);
        meta.push(serde_json::json!({
            "spec": spec,
            "closest_m": closest,
            "texel_m": texture.texel_m,
            "columns_covered": cols.map(|(a, b)| [a, b]),
        }));
        objects.push(MovingObject {
            spec: spec.clone(),
            texture,
        });
    }
    (objects, serde_json::Value::Array(meta))
}

/// Largest `|a[i] - b[i]|`.
fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()))
}

/// Largest number of events in a bin of `bin_us`, as events/s.
fn peak_rate(events: &[Event], bin_us: u64) -> f64 {
    let mut best = 0usize;
    let mut start = 0usize;
    let mut bin = 0u64;
    for (i, e) in events.iter().enumerate() {
        let b = e.t_us / bin_us;
        if b != bin {
            best = best.max(i - start);
            start = i;
            bin = b;
        }
    }
    best = best.max(events.len() - start);
    best as f64 * 1e6 / bin_us as f64
}

#[cfg(test)]
mod tests {
    use super::flicker::burst;
    use super::*;

    /// A small, motionless, noise-free camera (only the flicker produces events).
    fn still(duration_s: f64) -> SynthConfig {
        let mut cfg = SynthConfig::new(Preset::Davis240, TextureKind::Urban, MotionKind::Constant);
        cfg.intrinsics = Intrinsics::centred(64, 48, 50.0);
        cfg.duration_s = duration_s;
        cfg.motion_spec = Some(MotionSpec::constant_yaw(0.0));
        cfg.sensor.noise_hz = 0.0;
        cfg.seed = 5;
        cfg
    }

    /// A still scene under a 100 Hz burst in [0.1, 0.15] s: every event lies inside the
    /// window, the pixels fire about 4 A / C times per period, ON and OFF balance.
    #[test]
    fn synth_flicker_storm_inside_window() {
        let mut cfg = still(0.25);
        cfg.flicker = Some(burst(0.1, 0.05, 100.0));
        let seq = generate(&cfg).unwrap();
        let inside = |e: &Event| (100_000..=150_000).contains(&e.t_us);
        let n_in = seq.events.iter().filter(|e| inside(e)).count();
        let n_out = seq.events.len() - n_in;
        assert_eq!(n_out, 0, "{n_out} events outside the window");
        // The log intensity travels 4 A = 2.0 per period, 4 A / C = 8 thresholds. A pixel's
        // reference lags behind each crest and trough by up to one threshold, so about one
        // crossing per half period is lost: 6 per pixel and period (measured: 92,176 events =
        // 6.00 x 3072 pixels x 5 periods). Bounds: 0.6 and 1.1 x 4 A / C.
        let expected = 64.0 * 48.0 * 5.0 * 4.0 * 0.5 / 0.25;
        assert!(
            n_in as f64 > 0.6 * expected && (n_in as f64) < 1.1 * expected,
            "{n_in} events in the window, expected about {expected}"
        );
        let on = seq.events.iter().filter(|e| e.on).count() as f64 / n_in as f64;
        assert!((0.47..0.53).contains(&on), "ON fraction {on}");
        // The storm shows in the 10 ms peak rate: > 1 M ev/s on 3072 pixels.
        assert!(
            seq.stats.peak_rate_ev_s_10ms > 1e6,
            "{}",
            seq.stats.peak_rate_ev_s_10ms
        );
        assert_eq!(seq.meta["flicker"]["periods"], 5);
        assert_eq!(seq.meta["config"]["flicker"]["freq_hz"], 100.0);
    }

    /// A window shorter than the largest render step (one 1 ms period at 1 kHz, placed between
    /// two 2 ms steps of a still scene) is still rendered finely, not stepped over.
    #[test]
    fn synth_flicker_short_window_is_not_skipped() {
        let mut cfg = still(0.1);
        cfg.flicker = Some(burst(0.0505, 0.001, 1000.0));
        // At 1 kHz the crossings near the zero crossings of the sine come 80 us apart, closer
        // than the default refractory period; count them all.
        cfg.sensor.refractory_us = 0;
        let seq = generate(&cfg).unwrap();
        assert!(seq.stats.render_dt_max_s >= 1.9e-3, "{:?}", seq.stats);
        let expected = 64.0 * 48.0 * 4.0 * 0.5 / 0.25;
        let n = seq.events.len() as f64;
        // A single period loses more to the quantisation of the reference level than a long
        // burst (about 5.5 of the 8 crossings per pixel); without the breakpoints there would be
        // none at all (the 2 ms renders land at 49 and 51 ms, where the sine is zero).
        assert!(n > 0.5 * expected, "{n} events, expected about {expected}");
        assert!(seq
            .events
            .iter()
            .all(|e| (50_500..=51_500).contains(&e.t_us)));
    }

    /// The same configuration with flicker gives the same events.
    #[test]
    fn synth_flicker_is_deterministic() {
        let mut cfg = still(0.12);
        cfg.motion_spec = None;
        cfg.motion = MotionKind::Sinusoid;
        cfg.sensor.noise_hz = 2.0;
        cfg.flicker = Some(burst(0.03, 0.05, 120.0));
        let a = generate(&cfg).unwrap();
        let b = generate(&cfg).unwrap();
        assert!(!a.events.is_empty());
        assert_eq!(a.events, b.events);
        assert_eq!(a.stats, b.stats);
        assert_eq!(a.meta, b.meta);
    }

    /// Adding the field changes nothing for sequences without flicker: no flicker and a burst
    /// after the end of the sequence give the same events, and the same `meta.json` apart from
    /// the flicker entries.
    #[test]
    fn synth_without_flicker_is_unchanged() {
        let mut cfg = still(0.12);
        cfg.motion_spec = None;
        cfg.motion = MotionKind::Sinusoid;
        cfg.max_rate = 1.0;
        cfg.sensor.noise_hz = 2.0;
        cfg.sensor.hot_pixels = 2;
        let plain = generate(&cfg).unwrap();
        assert!(plain.events.len() > 1000, "{}", plain.events.len());
        assert!(plain.meta.get("flicker").is_none());
        assert!(plain.meta["config"].get("flicker").is_none());
        for start in [0.12, 0.5] {
            cfg.flicker = Some(burst(start, 0.05, 100.0));
            let late = generate(&cfg).unwrap();
            assert_eq!(plain.events, late.events, "start {start}");
            assert_eq!(plain.stats, late.stats);
            assert_eq!(plain.gt, late.gt);
            assert_eq!(plain.imu, late.imu);
        }
    }

    /// Bad flicker parameters are rejected with the flag's name.
    #[test]
    fn synth_flicker_validation() {
        let ok = burst(0.1, 0.05, 100.0);
        let mut cfg = still(0.2);
        cfg.flicker = Some(ok.clone());
        cfg.validate().unwrap();
        cfg.flicker = Some(Flicker {
            amplitude_log: 0.0,
            ..ok.clone()
        });
        cfg.validate().unwrap();
        let bad = [
            Flicker {
                start_s: -0.1,
                ..ok.clone()
            },
            Flicker {
                start_s: f64::NAN,
                ..ok.clone()
            },
            Flicker {
                start_s: f64::INFINITY,
                ..ok.clone()
            },
            Flicker {
                duration_s: 0.0,
                ..ok.clone()
            },
            Flicker {
                duration_s: -1.0,
                ..ok.clone()
            },
            Flicker {
                duration_s: f64::INFINITY,
                ..ok.clone()
            },
            Flicker {
                freq_hz: 0.0,
                ..ok.clone()
            },
            Flicker {
                freq_hz: -50.0,
                ..ok.clone()
            },
            Flicker {
                freq_hz: f64::NAN,
                ..ok.clone()
            },
            Flicker {
                freq_hz: 1e6,
                ..ok.clone()
            },
            Flicker {
                amplitude_log: -0.1,
                ..ok.clone()
            },
            Flicker {
                amplitude_log: f64::INFINITY,
                ..ok.clone()
            },
        ];
        for f in bad {
            cfg.flicker = Some(f.clone());
            let e = cfg.validate().unwrap_err().to_string();
            assert!(e.contains("--flicker"), "{f:?}: {e}");
            assert!(generate(&cfg).is_err());
        }
    }

    /// Configurations written before the flicker existed still load (as no flicker); with a
    /// flicker the configuration survives a JSON round trip.
    #[test]
    fn synth_config_serde_without_flicker() {
        let cfg = SynthConfig::default();
        let mut v = serde_json::to_value(&cfg).unwrap();
        assert!(v.get("flicker").is_none());
        let obj = v.as_object_mut().unwrap();
        obj.remove("flicker");
        let back: SynthConfig = serde_json::from_value(v).unwrap();
        assert_eq!(back, cfg);
        assert_eq!(back.flicker, None);

        let mut with = cfg.clone();
        with.flicker = Some(burst(0.4, 0.1, 100.0));
        let text = serde_json::to_string(&with).unwrap();
        let back: SynthConfig = serde_json::from_str(&text).unwrap();
        assert_eq!(back, with);

        // And the config inside a generated meta.json reads back.
        let seq = generate(&{
            let mut c = still(0.02);
            c.flicker = Some(burst(0.005, 0.01, 100.0));
            c
        })
        .unwrap();
        let back: SynthConfig = serde_json::from_value(seq.meta["config"].clone()).unwrap();
        assert_eq!(back, seq.config);
    }
}
