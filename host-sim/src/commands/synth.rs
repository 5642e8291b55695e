//! `host-sim synth --out DIR`: render a synthetic event sequence with ground truth and IMU.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;

use crate::synth::{self, Intrinsics, MotionKind, Preset, SynthConfig, TextureKind};

/// Arguments of `host-sim synth`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output folder (created): events.txt, gt.csv, imu.txt, meta.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Sensor geometry preset.
    #[arg(long, value_enum, default_value = "davis346")]
    pub preset: Preset,
    /// Panorama texture.
    #[arg(long, value_enum, default_value = "urban")]
    pub texture: TextureKind,
    /// Motion profile (parameters drawn from the seed).
    #[arg(long, value_enum, default_value = "sinusoid")]
    pub motion: MotionKind,
    /// Duration, s.
    #[arg(long, default_value_t = 4.0)]
    pub duration: f64,
    /// Seed of every random choice (same seed and flags = identical output).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Sensor width, px (default: the preset's).
    #[arg(long)]
    pub width: Option<u16>,
    /// Sensor height, px (default: the preset's).
    #[arg(long)]
    pub height: Option<u16>,
    /// Focal length, px (default: the preset's, scaled with --width).
    #[arg(long)]
    pub focal_px: Option<f64>,
    /// Principal point column, px (default: the centre).
    #[arg(long)]
    pub cx: Option<f64>,
    /// Principal point row, px (default: the centre).
    #[arg(long)]
    pub cy: Option<f64>,
    /// Peak |yaw rate|, rad/s (default: 0.5 constant/sinusoid, 1.2 steps, 0.6 car).
    #[arg(long)]
    pub max_rate: Option<f64>,
    /// Mean forward speed, m/s (default: 8 for car, else 0).
    #[arg(long)]
    pub speed: Option<f64>,
    /// Pitch/roll oscillation amplitude, rad (default: 0.004 for car, else 0).
    #[arg(long)]
    pub pitch_roll: Option<f64>,
    /// Textured ground plane (default: on when the camera drives).
    #[arg(long)]
    pub ground: Option<bool>,
    /// Texture log-contrast multiplier.
    #[arg(long, default_value_t = 1.0)]
    pub contrast: f64,
    /// Mean ON threshold (log intensity).
    #[arg(long, default_value_t = 0.25)]
    pub cp: f64,
    /// Mean OFF threshold (log intensity).
    #[arg(long, default_value_t = 0.25)]
    pub cm: f64,
    /// Per-pixel threshold mismatch (std, log intensity).
    #[arg(long, default_value_t = 0.03)]
    pub sigma_c: f64,
    /// Refractory period, µs.
    #[arg(long, default_value_t = 100)]
    pub refractory_us: u32,
    /// Background-activity rate per pixel, Hz.
    #[arg(long, default_value_t = 0.1)]
    pub noise_hz: f64,
    /// Number of hot pixels.
    #[arg(long, default_value_t = 0)]
    pub hot_pixels: u32,
    /// Sequence name in meta.json (default: <preset>_<texture>_<motion>).
    #[arg(long)]
    pub name: Option<String>,
    /// Render threads (0 = all cores, at most 4); the output does not depend on it.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

impl Args {
    /// The generator configuration these flags describe.
    pub fn config(&self) -> SynthConfig {
        let mut cfg = SynthConfig::new(self.preset, self.texture, self.motion);
        let p = self.preset.intrinsics();
        let width = self.width.unwrap_or(p.width);
        let height = self.height.unwrap_or(p.height);
        let f = self
            .focal_px
            .unwrap_or(p.fx * f64::from(width) / f64::from(p.width));
        let mut intr = Intrinsics::centred(width, height, f);
        if let Some(cx) = self.cx {
            intr.cx = cx;
        }
        if let Some(cy) = self.cy {
            intr.cy = cy;
        }
        cfg.intrinsics = intr;
        cfg.seed = self.seed;
        cfg.duration_s = self.duration;
        if let Some(r) = self.max_rate {
            cfg.max_rate = r;
        }
        if let Some(s) = self.speed {
            cfg.speed_mps = s;
            cfg.ground = s > 0.0;
        }
        if let Some(pr) = self.pitch_roll {
            cfg.pitch_roll_rad = pr;
        }
        if let Some(g) = self.ground {
            cfg.ground = g;
        }
        cfg.contrast = self.contrast;
        cfg.sensor.cp = self.cp;
        cfg.sensor.cm = self.cm;
        cfg.sensor.sigma_c = self.sigma_c;
        cfg.sensor.refractory_us = self.refractory_us;
        cfg.sensor.noise_hz = self.noise_hz;
        cfg.sensor.hot_pixels = self.hot_pixels;
        if let Some(name) = &self.name {
            cfg.name.clone_from(name);
        }
        cfg.threads = self.threads;
        cfg
    }
}

/// Runs `host-sim synth`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let cfg = args.config();
    cfg.validate()?;
    let bar = if std::io::stderr().is_terminal() {
        let bar = indicatif::ProgressBar::new((cfg.duration_s * 1000.0).round() as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "synth {bar:40} {pos}/{len} ms simulated [{elapsed_precise} < {eta}]",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    } else {
        indicatif::ProgressBar::hidden()
    };
    let start = Instant::now();
    let seq = synth::generate_with_progress(&cfg, &mut |t| bar.set_position((t * 1000.0) as u64))?;
    bar.finish_and_clear();
    let gen_s = start.elapsed().as_secs_f64();
    synth::write_sequence(&seq, &args.out)
        .with_context(|| format!("writing the sequence to {}", args.out.display()))?;
    let s = &seq.stats;
    println!(
        "wrote {}: {} events ({:.0} ev/s mean, {:.0} ev/s peak over 10 ms), {}x{} f={:.1} px, max |wy| {:.3} rad/s, {} renders, generated in {:.2} s",
        args.out.display(),
        s.events,
        s.mean_rate_ev_s,
        s.peak_rate_ev_s_10ms,
        seq.intrinsics.width,
        seq.intrinsics.height,
        seq.intrinsics.fx,
        s.max_abs_wy_rad_s,
        s.renders,
        gen_s
    );
    Ok(())
}
