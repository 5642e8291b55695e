//! The configuration frame (AER frame kind 3): the camera and the network a receiver should
//! run, sent in the AER stream so that another camera, lens or layout needs no rebuild.
//!
//! ```text
//! payload (little-endian), format version 1, 36 bytes
//! offset size field
//!      0    1 format version (1); a receiver refuses other versions
//!      1    1 readout: 0 = calibrated (rad/s); other values are refused
//!      2    1 layout: 0 = dense over the whole sensor, 1 = the paper's boxes, 2 = dense window
//!      3    1 reserved (0)
//!      4    2 sensor width (px, 1..=2048)
//!      6    2 sensor height (px, 1..=2048)
//!      8    2 stride: FAC-to-TRG distance (px, >= 1)
//!     10    2 reserved (0)
//!     12    4 focal length (px, U16F16, > 0)
//!     16    4 principal point column cx (px, U16F16)
//!     20    4 principal point row cy (px, U16F16)
//!     24    2 window x0 (layout 2; else 0)
//!     26    2 window y0
//!     28    2 window width (> stride)
//!     30    2 window height (>= 1)
//!     32    4 output period (µs, >= 1; 1000 = 1 kHz)
//! ```
//!
//! The frame's CRC-32 (and header CRC-16) protect it like any frame; a later format version may
//! append fields (payloads up to 64 bytes are framed), which version-1 receivers refuse.

use super::frame::{encode_frame, EncodeFrameError, Kind};
use crate::fixed::types::U16F16;

/// The configuration format this code writes and reads.
pub const CONFIG_VERSION: u8 = 1;
/// Payload bytes of format version 1.
pub const CONFIG_BYTES: usize = 36;
/// Largest sensor side the AER format carries (11-bit coordinates).
const MAX_SIDE: u16 = 2048;

/// Which network the receiver runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayoutChoice {
    /// Dense over the whole sensor.
    Dense,
    /// The paper's two 20 x 20 boxes.
    PaperBoxes,
    /// Dense over a window of the sensor.
    Window {
        /// First column.
        x0: u16,
        /// First row.
        y0: u16,
        /// Columns.
        w: u16,
        /// Rows.
        h: u16,
    },
}

/// What a configuration frame says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamConfig {
    /// Sensor width in px.
    pub width: u16,
    /// Sensor height in px.
    pub height: u16,
    /// Focal length in px.
    pub focal_px: U16F16,
    /// Principal point column in px.
    pub cx: U16F16,
    /// Principal point row in px.
    pub cy: U16F16,
    /// The network.
    pub layout: LayoutChoice,
    /// FAC-to-TRG distance in px.
    pub stride: u16,
    /// Output period in µs.
    pub period_us: u32,
}

/// Why a configuration payload was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConfigError {
    /// A format version this receiver does not know.
    Version(u8),
    /// Shorter than its version's fields.
    Length(usize),
    /// A readout this receiver does not run.
    Readout(u8),
    /// An unknown layout code.
    Layout(u8),
    /// A value out of range (sizes, stride, focal length, window, period).
    Value,
}

fn le16(b: &[u8], at: usize) -> u16 {
    match b.get(at..at + 2) {
        Some(&[x, y]) => u16::from_le_bytes([x, y]),
        _ => 0,
    }
}

fn le32(b: &[u8], at: usize) -> u32 {
    match b.get(at..at + 4) {
        Some(&[a, b, c, d]) => u32::from_le_bytes([a, b, c, d]),
        _ => 0,
    }
}

impl StreamConfig {
    /// Checks the values (see the module docs).
    ///
    /// # Errors
    /// [`ConfigError::Value`] when a value is out of range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let side_ok = |s: u16| (1..=MAX_SIDE).contains(&s);
        let mut ok = side_ok(self.width)
            && side_ok(self.height)
            && self.stride >= 1
            && self.stride < self.width
            && self.focal_px > U16F16::ZERO
            && self.period_us >= 1;
        if let LayoutChoice::Window { x0, y0, w, h } = self.layout {
            ok &= w > self.stride
                && h >= 1
                && u32::from(x0) + u32::from(w) <= u32::from(self.width)
                && u32::from(y0) + u32::from(h) <= u32::from(self.height);
        }
        if ok {
            Ok(())
        } else {
            Err(ConfigError::Value)
        }
    }

    /// The version-1 payload.
    #[must_use]
    pub fn payload(&self) -> [u8; CONFIG_BYTES] {
        let (code, (x0, y0, w, h)) = match self.layout {
            LayoutChoice::Dense => (0u8, (0, 0, 0, 0)),
            LayoutChoice::PaperBoxes => (1, (0, 0, 0, 0)),
            LayoutChoice::Window { x0, y0, w, h } => (2, (x0, y0, w, h)),
        };
        let mut p = [0u8; CONFIG_BYTES];
        let fields: [(usize, &[u8]); 14] = [
            (0, &[CONFIG_VERSION]),
            (1, &[0]),
            (2, &[code]),
            (4, &self.width.to_le_bytes()),
            (6, &self.height.to_le_bytes()),
            (8, &self.stride.to_le_bytes()),
            (12, &self.focal_px.to_bits().to_le_bytes()),
            (16, &self.cx.to_bits().to_le_bytes()),
            (20, &self.cy.to_bits().to_le_bytes()),
            (24, &x0.to_le_bytes()),
            (26, &y0.to_le_bytes()),
            (28, &w.to_le_bytes()),
            (30, &h.to_le_bytes()),
            (32, &self.period_us.to_le_bytes()),
        ];
        for (at, bytes) in fields {
            if let Some(dst) = p.get_mut(at..at + bytes.len()) {
                dst.copy_from_slice(bytes);
            }
        }
        p
    }

    /// Reads and checks a configuration payload.
    ///
    /// # Errors
    /// An unknown version, readout or layout, a short payload, or values out of range.
    pub fn parse(p: &[u8]) -> Result<Self, ConfigError> {
        let version = p.first().copied().unwrap_or(0);
        if version != CONFIG_VERSION {
            return Err(ConfigError::Version(version));
        }
        if p.len() < CONFIG_BYTES {
            return Err(ConfigError::Length(p.len()));
        }
        let readout = p.get(1).copied().unwrap_or(0);
        if readout != 0 {
            return Err(ConfigError::Readout(readout));
        }
        let layout = match p.get(2).copied().unwrap_or(0) {
            0 => LayoutChoice::Dense,
            1 => LayoutChoice::PaperBoxes,
            2 => LayoutChoice::Window {
                x0: le16(p, 24),
                y0: le16(p, 26),
                w: le16(p, 28),
                h: le16(p, 30),
            },
            other => return Err(ConfigError::Layout(other)),
        };
        let cfg = Self {
            width: le16(p, 4),
            height: le16(p, 6),
            stride: le16(p, 8),
            focal_px: U16F16::from_bits(le32(p, 12)),
            cx: U16F16::from_bits(le32(p, 16)),
            cy: U16F16::from_bits(le32(p, 20)),
            layout,
            period_us: le32(p, 32),
        };
        cfg.validate()?;
        Ok(cfg)
    }

    /// Writes the configuration as a whole AER frame (kind 3) into `out`; returns its length.
    ///
    /// # Errors
    /// When `out` is too short.
    pub fn encode(
        &self,
        frame_flags: u8,
        seq: u16,
        out: &mut [u8],
    ) -> Result<usize, EncodeFrameError> {
        encode_frame(Kind::Config, frame_flags, seq, &self.payload(), out)
    }
}
