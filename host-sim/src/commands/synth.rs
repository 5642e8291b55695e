//! `host-sim synth --out DIR`: render a synthetic event sequence with ground truth and IMU.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;

use crate::synth::{
    self, regime, Flicker, Intrinsics, MotionKind, Preset, Regime, SynthConfig, TextureKind,
};

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
    /// A preset for one motion regime: motion, speed, camera height, ground, moving objects and
    /// peak rate drawn from the seed (car: 5-10 m/s, bends and lane changes up to 0.3-0.5
    /// rad/s; drone: 2-5 m/s, turns up to 2 rad/s, pitch/roll wobble; hover: slow yaw with
    /// pauses at 0; objects: static camera, 1-3 moving objects; rotation: the default scene).
    /// Explicit flags override its values one by one (`--motion` changes only the profile, not
    /// the regime's peak rate, speed or pitch/roll).
    #[arg(long, value_enum)]
    pub regime: Option<Regime>,
    /// Motion profile (parameters drawn from the seed; default: sinusoid, or the regime's).
    #[arg(long, value_enum)]
    pub motion: Option<MotionKind>,
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
    /// Peak |yaw rate|, rad/s (default: 0.5 constant/sinusoid/car, 1.2 steps, 2 drone, 0.2
    /// hover, 0 static).
    #[arg(long)]
    pub max_rate: Option<f64>,
    /// Mean forward speed, m/s (default: 8 for car, 3.5 for drone, else 0).
    #[arg(long)]
    pub speed: Option<f64>,
    /// Pitch/roll oscillation amplitude, rad (default: 0.004 for car, 0.05 for drone, else 0).
    #[arg(long)]
    pub pitch_roll: Option<f64>,
    /// Textured ground plane (default: on when the camera drives).
    #[arg(long)]
    pub ground: Option<bool>,
    /// Camera height above the ground plane, m (default: 1.4, or the regime's).
    #[arg(long)]
    pub camera_height: Option<f64>,
    /// Number of independently moving objects (people, cars) crossing part of the view, drawn
    /// from the seed; they change the events, not the ground truth (default: 0, or the
    /// regime's).
    #[arg(long)]
    pub objects: Option<usize>,
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
    /// Sequence name in meta.json (default: <preset>_<texture>_<motion or regime>).
    #[allow(
        rustdoc::invalid_html_tags,
        reason = "the text is also `--help`'s, where <preset> reads as a placeholder"
    )]
    #[arg(long)]
    pub name: Option<String>,
    /// Render threads (0 = all cores, at most 4); the output does not depend on it.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// A burst of lighting flicker (an event storm): start and length in seconds, e.g.
    /// `0.4:0.1`. Every pixel's log intensity gets `A sin(2 pi f (t - start))` added; the length
    /// is rounded to a whole number of periods (at least one).
    #[arg(long, value_name = "START_S:DURATION_S", value_parser = parse_flicker_window)]
    pub flicker: Option<(f64, f64)>,
    /// Frequency f of the flicker, Hz (100 = lamps on 50 Hz mains).
    #[arg(long, default_value_t = 100.0, requires = "flicker")]
    pub flicker_hz: f64,
    /// Amplitude A of the flicker, log-intensity units (those of --cp/--cm): the log intensity
    /// swings by 2 A, so each pixel fires up to 4 A / threshold events per period (about two
    /// fewer, as the pixel's reference lags behind each crest and trough).
    #[arg(long, default_value_t = 0.5, requires = "flicker")]
    pub flicker_amplitude: f64,
}

/// Parses `START_S:DURATION_S` (seconds, start >= 0, duration > 0).
fn parse_flicker_window(s: &str) -> Result<(f64, f64), String> {
    let (start, duration) = s.split_once(':').ok_or_else(|| {
        format!("expected START_S:DURATION_S in seconds, e.g. 0.4:0.1 (got {s:?})")
    })?;
    let num = |what: &str, v: &str| -> Result<f64, String> {
        v.trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("{what} {v:?} is not a finite number of seconds"))
    };
    let (start, duration) = (num("start", start)?, num("duration", duration)?);
    if start < 0.0 {
        return Err(format!("start must be >= 0 s (got {start})"));
    }
    if duration <= 0.0 {
        return Err(format!("duration must be > 0 s (got {duration})"));
    }
    Ok((start, duration))
}

impl Args {
    /// The generator configuration these flags describe.
    pub fn config(&self) -> SynthConfig {
        let mut cfg = match self.regime {
            Some(r) => {
                let mut cfg = regime::preset_with_texture(
                    r,
                    self.seed,
                    self.duration,
                    self.preset,
                    self.texture,
                );
                if let Some(m) = self.motion {
                    cfg.motion = m;
                }
                cfg
            }
            None => SynthConfig::new(
                self.preset,
                self.texture,
                self.motion.unwrap_or(MotionKind::Sinusoid),
            ),
        };
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
        if let Some(h) = self.camera_height {
            cfg.cam_height_m = h;
        }
        if let Some(n) = self.objects {
            cfg.objects = n;
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
        cfg.flicker = self.flicker.map(|(start_s, duration_s)| Flicker {
            start_s,
            duration_s,
            freq_hz: self.flicker_hz,
            amplitude_log: self.flicker_amplitude,
        });
        cfg
    }
}

/// Checks the number options the scene's geometry is built from: every one finite, the sensor
/// no larger than the 2048 x 2048 that EVT 3.0 addresses, the focal length and principal point
/// within what `host-sim run` takes (1 to 65535 px, 0 to 65535 px).
fn check_numbers(args: &Args) -> anyhow::Result<()> {
    use crate::pipeline::{MAX_PX, MAX_SENSOR_SIDE};
    let named = [
        ("--duration", Some(args.duration)),
        ("--max-rate", args.max_rate),
        ("--speed", args.speed),
        ("--pitch-roll", args.pitch_roll),
        ("--camera-height", args.camera_height),
        ("--contrast", Some(args.contrast)),
        ("--cp", Some(args.cp)),
        ("--cm", Some(args.cm)),
        ("--sigma-c", Some(args.sigma_c)),
        ("--noise-hz", Some(args.noise_hz)),
        ("--flicker-hz", Some(args.flicker_hz)),
        ("--flicker-amplitude", Some(args.flicker_amplitude)),
    ];
    for (flag, v) in named {
        if let Some(v) = v.filter(|v| !v.is_finite()) {
            anyhow::bail!("{flag} must be a finite number (got {v})");
        }
    }
    for (flag, v) in [("--width", args.width), ("--height", args.height)] {
        if let Some(v) = v.filter(|&v| v > MAX_SENSOR_SIDE) {
            anyhow::bail!("{flag} must be at most {MAX_SENSOR_SIDE} px (got {v})");
        }
    }
    if let Some(f) = args.focal_px.filter(|f| !(1.0..=MAX_PX).contains(f)) {
        anyhow::bail!("--focal-px must be a focal length in [1, {MAX_PX}] px (got {f})");
    }
    for (flag, v) in [("--cx", args.cx), ("--cy", args.cy)] {
        if let Some(v) = v.filter(|v| !(0.0..=MAX_PX).contains(v)) {
            anyhow::bail!("{flag} must be a pixel coordinate in [0, {MAX_PX}] (got {v})");
        }
    }
    Ok(())
}

/// Runs `host-sim synth`.
pub fn run(args: Args) -> anyhow::Result<()> {
    check_numbers(&args)?;
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

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    #[derive(Debug, clap::Parser)]
    struct Cli {
        #[command(flatten)]
        args: Args,
    }

    fn parse(extra: &[&str]) -> Result<Args, clap::Error> {
        let argv = ["synth", "--out", "/tmp/x"].iter().chain(extra);
        Cli::try_parse_from(argv).map(|c| c.args)
    }

    #[test]
    fn synth_flicker_flags() {
        assert_eq!(parse(&[]).unwrap().config().flicker, None);
        let cfg = parse(&["--flicker", "0.4:0.1"]).unwrap().config();
        assert_eq!(
            cfg.flicker,
            Some(Flicker {
                start_s: 0.4,
                duration_s: 0.1,
                freq_hz: 100.0,
                amplitude_log: 0.5,
            })
        );
        let cfg = parse(&[
            "--flicker",
            "0:2",
            "--flicker-hz",
            "120",
            "--flicker-amplitude",
            "0.3",
        ])
        .unwrap()
        .config();
        let f = cfg.flicker.unwrap();
        assert_eq!(
            (f.start_s, f.duration_s, f.freq_hz, f.amplitude_log),
            (0.0, 2.0, 120.0, 0.3)
        );
        for bad in [
            "0.4", "a:0.1", "0.4:", "-1:0.1", "0.4:0", "0.4:-0.1", "inf:1", "0.1:NaN",
        ] {
            let e = parse(&[&format!("--flicker={bad}")])
                .unwrap_err()
                .to_string();
            assert!(e.contains("--flicker"), "{bad}: {e}");
        }
        // The frequency and amplitude mean nothing without a window.
        assert!(parse(&["--flicker-hz", "50"]).is_err());
    }

    /// `--regime` gives the library's preset (`rotation`: exactly the default scene); explicit
    /// flags override single values of it.
    #[test]
    fn synth_regime_flags() {
        assert_eq!(
            parse(&["--regime", "rotation"]).unwrap().config(),
            parse(&[]).unwrap().config()
        );
        let cfg = parse(&["--regime", "hover", "--seed", "4", "--duration", "2"])
            .unwrap()
            .config();
        assert_eq!(cfg, regime::preset(Regime::Hover, 4, 2.0, Preset::Davis346));
        let cfg = parse(&[
            "--regime",
            "hover",
            "--seed",
            "4",
            "--duration",
            "2",
            "--motion",
            "steps",
            "--max-rate",
            "0.1",
            "--objects",
            "2",
            "--camera-height",
            "2.5",
        ])
        .unwrap()
        .config();
        let preset = regime::preset(Regime::Hover, 4, 2.0, Preset::Davis346);
        assert_eq!(cfg.motion, MotionKind::Steps);
        assert_eq!((cfg.max_rate, cfg.objects, cfg.cam_height_m), (0.1, 2, 2.5));
        assert_eq!(
            (cfg.speed_mps, cfg.ground),
            (preset.speed_mps, preset.ground)
        );
        assert_eq!(parse(&[]).unwrap().config().objects, 0);
        assert!(parse(&["--regime", "boat"]).is_err());
    }
}
