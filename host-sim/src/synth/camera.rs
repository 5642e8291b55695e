//! Pinhole camera intrinsics, the camera's pose at an instant, and the sensor presets.

use serde::{Deserialize, Serialize};

/// Pinhole intrinsics of the simulated sensor (no distortion).
///
/// Pixel `(x, y)`: `x` = column (0 = left), `y` = row (0 = top). A pixel centre at `(x, y)` looks
/// along the camera-frame ray `((x - cx) / fx, (y - cy) / fy, 1)` (x right, y down, z forward).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point column, pixels.
    pub cx: f64,
    /// Principal point row, pixels.
    pub cy: f64,
    /// Sensor width, pixels.
    pub width: u16,
    /// Sensor height, pixels.
    pub height: u16,
}

impl Intrinsics {
    /// Square pixels, focal `f` px, principal point at the sensor centre `((W-1)/2, (H-1)/2)`.
    pub fn centred(width: u16, height: u16, f: f64) -> Self {
        Self {
            fx: f,
            fy: f,
            cx: (f64::from(width) - 1.0) / 2.0,
            cy: (f64::from(height) - 1.0) / 2.0,
            width,
            height,
        }
    }

    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        usize::from(self.width) * usize::from(self.height)
    }

    /// Horizontal image speed (px/s, signed) at column `x` for a pure yaw rate `wy` (rad/s):
    /// `-wy (fx + (x - cx)^2 / fx)` (positive yaw = turning right = scene moves left).
    pub fn yaw_flow_px_s(&self, x: f64, wy: f64) -> f64 {
        let dx = x - self.cx;
        -wy * (self.fx + dx * dx / self.fx)
    }
}

impl From<Intrinsics> for crate::formats::Intrinsics {
    fn from(i: Intrinsics) -> Self {
        Self {
            fx: i.fx,
            fy: i.fy,
            cx: i.cx,
            cy: i.cy,
        }
    }
}

/// A sensor geometry like a real event camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// iniVation DAVIS346: 346 x 260 px, f = 226 px (about 75 deg horizontal field of view).
    Davis346,
    /// iniVation DAVIS240C: 240 x 180 px, f = 200 px.
    Davis240,
}

impl Preset {
    /// The preset's intrinsics (principal point at the centre).
    pub fn intrinsics(self) -> Intrinsics {
        match self {
            Preset::Davis346 => Intrinsics::centred(346, 260, 226.0),
            Preset::Davis240 => Intrinsics::centred(240, 180, 200.0),
        }
    }

    /// Name as written in `meta.json` (`davis346`, `davis240`).
    pub fn name(self) -> &'static str {
        match self {
            Preset::Davis346 => "davis346",
            Preset::Davis240 => "davis240",
        }
    }
}

/// The camera pose at one instant, as the renderer needs it.
#[derive(Clone, Copy, Debug)]
pub struct CameraPose {
    /// Camera-to-world rotation (row-major).
    pub rot: [[f64; 3]; 3],
    /// Heading, rad (used by the pure-yaw fast path).
    pub heading: f64,
    /// Camera position in the world, metres.
    pub pos: [f64; 3],
    /// True when `rot` is a pure rotation about the world y axis by `heading`.
    pub pure_yaw: bool,
    /// Time, s (where the moving objects are).
    pub t_s: f64,
}
