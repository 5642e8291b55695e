//! The configuration frame (AER frame kind 3): the wire form of [`Settings`], sent in the AER
//! stream so that another camera, lens or layout needs no rebuild.
//!
//! ```text
//! payload (little-endian), format version 1 (36 bytes), 2 (40 bytes) or 3 (44 bytes)
//! offset size field
//!      0    1 format version (1, 2 or 3); a receiver refuses other versions
//!      1    1 readout: 0 = calibrated (rad/s), 1 = normalized, 2 = spikes (rad/s) (1, 2: version 2 only)
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
//!     36    4 readout time constant tau_A (µs; 0 = the readout's default) (version >= 2)
//!     40    4 unit pool: unit-pair slots of the spiking readouts (0 = one pair per cell)
//!           (version 3 only)
//! ```
//!
//! Settings are written in the oldest version that can say them: version 1 (calibrated
//! readout, default `tau_A`), so streams of earlier builds and of this one are the same bytes;
//! version 2 without a unit pool; else version 3. The frame's CRC-32 (and header CRC-16) protect it like any frame.

use super::frame::{encode_frame, EncodeFrameError, Kind};
use crate::fixed::types::U16F16;
use crate::settings::{LayoutChoice, ReadoutChoice, Settings, SettingsError};

/// The newest configuration format this code writes and reads.
pub const CONFIG_VERSION: u8 = 3;
/// Payload bytes of format version 1.
pub const CONFIG_BYTES_V1: usize = 36;
/// Payload bytes of format version 2.
pub const CONFIG_BYTES_V2: usize = 40;
/// Payload bytes of format version 3 (the largest payload).
pub const CONFIG_BYTES: usize = 44;

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
    /// Values that cannot run (sizes, stride, focal length, window, period, `tau_A`, pool).
    Value(SettingsError),
    /// Not the hex of a payload (an odd count or a non-hex digit, or longer than any payload).
    Hex,
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

impl Settings {
    /// The payload (in the oldest version that can say these settings) and its length.
    #[must_use]
    pub fn payload(&self) -> ([u8; CONFIG_BYTES], usize) {
        let (code, (x0, y0, w, h)) = match self.layout {
            LayoutChoice::Dense => (0u8, (0, 0, 0, 0)),
            LayoutChoice::PaperBoxes => (1, (0, 0, 0, 0)),
            LayoutChoice::Window { x0, y0, w, h } => (2, (x0, y0, w, h)),
        };
        let readout = match self.readout {
            ReadoutChoice::Calibrated => 0u8,
            ReadoutChoice::Normalized => 1,
            ReadoutChoice::Spikes => 2,
        };
        let tau = self.tau_a_us.unwrap_or(0);
        let pool = self.unit_pool.unwrap_or(0);
        let (version, len) = if pool != 0 {
            (3u8, CONFIG_BYTES)
        } else if readout == 0 && tau == 0 {
            (1, CONFIG_BYTES_V1)
        } else {
            (2, CONFIG_BYTES_V2)
        };
        let mut p = [0u8; CONFIG_BYTES];
        let fields: [(usize, &[u8]); 16] = [
            (0, &[version]),
            (1, &[readout]),
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
            (36, &tau.to_le_bytes()),
            (40, &pool.to_le_bytes()),
        ];
        for (at, bytes) in fields {
            if at < len {
                if let Some(dst) = p.get_mut(at..at + bytes.len()) {
                    dst.copy_from_slice(bytes);
                }
            }
        }
        (p, len)
    }

    /// Reads and checks a configuration payload.
    ///
    /// # Errors
    /// An unknown version, readout or layout, a short payload, or values that cannot run.
    pub fn parse(p: &[u8]) -> Result<Self, ConfigError> {
        let version = p.first().copied().unwrap_or(0);
        let len = match version {
            1 => CONFIG_BYTES_V1,
            2 => CONFIG_BYTES_V2,
            3 => CONFIG_BYTES,
            other => return Err(ConfigError::Version(other)),
        };
        if p.len() < len {
            return Err(ConfigError::Length(p.len()));
        }
        let readout = match (p.get(1).copied().unwrap_or(0), version) {
            (0, _) => ReadoutChoice::Calibrated,
            (1, 2 | 3) => ReadoutChoice::Normalized,
            (2, 2 | 3) => ReadoutChoice::Spikes,
            (other, _) => return Err(ConfigError::Readout(other)),
        };
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
        let tau = if version >= 2 { le32(p, 36) } else { 0 };
        let pool = if version >= 3 { le32(p, 40) } else { 0 };
        let settings = Self {
            width: le16(p, 4),
            height: le16(p, 6),
            stride: le16(p, 8),
            focal_px: U16F16::from_bits(le32(p, 12)),
            cx: U16F16::from_bits(le32(p, 16)),
            cy: U16F16::from_bits(le32(p, 20)),
            layout,
            period_us: le32(p, 32),
            readout,
            tau_a_us: (tau != 0).then_some(tau),
            unit_pool: (pool != 0).then_some(pool),
        };
        settings.validate().map_err(ConfigError::Value)?;
        Ok(settings)
    }

    /// Reads and checks a payload written as hex, two digits per byte (how a command line or
    /// `host-sim aer-stream` carries it).
    ///
    /// # Errors
    /// [`ConfigError::Hex`] when `hex` is not such a payload, else as [`Settings::parse`].
    pub fn parse_hex(hex: &str) -> Result<Self, ConfigError> {
        let digits = hex.as_bytes();
        let mut p = [0u8; CONFIG_BYTES];
        if !digits.len().is_multiple_of(2) || digits.len() / 2 > p.len() {
            return Err(ConfigError::Hex);
        }
        for (pair, byte) in digits.chunks_exact(2).zip(p.iter_mut()) {
            let s = core::str::from_utf8(pair).map_err(|_| ConfigError::Hex)?;
            *byte = u8::from_str_radix(s, 16).map_err(|_| ConfigError::Hex)?;
        }
        Self::parse(p.get(..digits.len() / 2).unwrap_or_default())
    }

    /// Writes the settings as a whole AER frame (kind 3) into `out`; returns its length.
    ///
    /// # Errors
    /// When `out` is too short.
    pub fn encode(
        &self,
        frame_flags: u8,
        seq: u16,
        out: &mut [u8],
    ) -> Result<usize, EncodeFrameError> {
        let (payload, len) = self.payload();
        encode_frame(
            Kind::Config,
            frame_flags,
            seq,
            payload.get(..len).unwrap_or(&payload),
            out,
        )
    }
}
