//! Regime presets: one configuration per kind of motion the yaw readout has to handle, with the
//! scene parameters (speed, camera height, moving objects) drawn from the seed. The same preset
//! is behind `host-sim synth --regime` (whose explicit flags then override single values).
//!
//! | regime | camera motion | speed, m/s | height, m | yaw rate, rad/s |
//! |---|---|---|---|---|
//! | `car` | bends, lane changes, pitch/roll 0.004 rad | 5-10 | 1.2-1.6 | peak 0.3-0.5 |
//! | `drone` | turns, pitch/roll wobble <= 4.3 deg at 1-6 Hz | 2-5 | 1.5-4 | up to 2 |
//! | `hover` | slow yaw segments, pauses at exactly 0 | drift 0.01-0.05 | 1-3 | 0.02-0.2 |
//! | `objects` | none (1-3 moving objects in view) | 0 | 1.2-2 | 0 |
//! | `rotation` | sinusoidal yaw (the default scene) | 0 | no ground | peak 0.35-0.5 |

use serde::{Deserialize, Serialize};

use super::camera::Preset;
use super::motion::MotionKind;
use super::rng;
use super::texture::TextureKind;
use super::SynthConfig;

/// A motion regime of the project issue "Yaw where drones and cars actually move".
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Regime {
    /// Driving: the `car` motion (bends of peak 0.3-0.5 rad/s and lane changes) at a mean
    /// speed of 5-10 m/s (drawn), ground plane 1.2-1.6 m below the camera (drawn), far
    /// scenery on the panorama.
    Car,
    /// Drone forward flight: the `drone` motion (yaw turns up to 2 rad/s, pitch and roll
    /// wobble of a few degrees at 1-6 Hz) at 2-5 m/s (drawn), 1.5-4 m above the ground (drawn).
    Drone,
    /// Hover: the `hover` motion (segments of 0.02-0.2 rad/s separated by pauses at exactly
    /// 0), a forward drift of 0.01-0.05 m/s (drawn), 1-3 m above the ground (drawn).
    Hover,
    /// Static camera (the `static` motion: no rotation, no translation), 1.2-2 m above the
    /// ground (drawn), with 1-3 moving objects (people or cars, drawn) crossing part of the view.
    Objects,
    /// Pure rotation: exactly the default scene of `host-sim synth` (sinusoidal yaw, peak
    /// 0.35-0.5 rad/s, no ground, no translation); `--motion steps` gives the yaw steps.
    Rotation,
}

impl Regime {
    /// Name as used on the command line and in sequence names.
    pub fn name(self) -> &'static str {
        match self {
            Regime::Car => "car",
            Regime::Drone => "drone",
            Regime::Hover => "hover",
            Regime::Objects => "objects",
            Regime::Rotation => "rotation",
        }
    }

    /// Every regime, in the order of the issue.
    pub const ALL: [Regime; 5] = [
        Regime::Car,
        Regime::Drone,
        Regime::Hover,
        Regime::Objects,
        Regime::Rotation,
    ];
}

/// The configuration of `regime` on the `sensor` preset with the urban texture, seeded by
/// `seed`, lasting `duration_s` seconds.
pub fn preset(regime: Regime, seed: u64, duration_s: f64, sensor: Preset) -> SynthConfig {
    preset_with_texture(regime, seed, duration_s, sensor, TextureKind::Urban)
}

/// Like [`preset`], with another panorama texture. Named `<sensor>_<texture>_<regime>`, except
/// `rotation`, which is the plain default configuration (named after its motion).
pub fn preset_with_texture(
    regime: Regime,
    seed: u64,
    duration_s: f64,
    sensor: Preset,
    texture: TextureKind,
) -> SynthConfig {
    let motion = match regime {
        Regime::Car => MotionKind::Car,
        Regime::Drone => MotionKind::Drone,
        Regime::Hover => MotionKind::Hover,
        Regime::Objects => MotionKind::Static,
        Regime::Rotation => MotionKind::Sinusoid,
    };
    let mut cfg = SynthConfig::new(sensor, texture, motion);
    cfg.seed = seed;
    cfg.duration_s = duration_s;
    if regime == Regime::Rotation {
        return cfg;
    }
    cfg.name = format!("{}_{}_{}", sensor.name(), texture.name(), regime.name());
    let mut r = rng::stream(seed, rng::Stream::Regime);
    let (speed, height) = match regime {
        Regime::Car => (
            rng::uniform(&mut r, 5.0, 10.0),
            rng::uniform(&mut r, 1.2, 1.6),
        ),
        Regime::Drone => (
            rng::uniform(&mut r, 2.0, 5.0),
            rng::uniform(&mut r, 1.5, 4.0),
        ),
        Regime::Hover => (
            rng::uniform(&mut r, 0.01, 0.05),
            rng::uniform(&mut r, 1.0, 3.0),
        ),
        _ => (0.0, rng::uniform(&mut r, 1.2, 2.0)),
    };
    cfg.speed_mps = speed;
    cfg.cam_height_m = height;
    cfg.ground = true;
    if regime == Regime::Objects {
        cfg.objects = 1 + (rng::uniform(&mut r, 0.0, 3.0) as usize).min(2);
    }
    cfg
}
