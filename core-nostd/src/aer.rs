//! The wire formats between the event sensor, the flight controller and the host: AER over SPI
//! in, yaw rate out. `no_std`, no heap, and no panic on any bytes. `docs/wire-formats.md` has
//! the tables.
//!
//! - [`config`]: the configuration frame (camera, network, output rate), versioned.
//! - [`crc`]: CRC-32 and CRC-16, tables built by `const fn`.
//! - [`framer`]: frame reassembly from chunks of any size, resynchronising after corruption
//!   without ever losing an intact frame.
//! - [`frame`]: the AER frame (sync, kind, flags, sequence, length, header check, CRC-32) and
//!   its [`FrameDecoder`](frame::FrameDecoder) with ok / bad / dropped counters.
//! - [`events`]: payloads: AER events (4 bytes each while events are at most 255 µs apart) or
//!   raw EVT 3.0 words decoded by [`crate::evt::Evt3Decoder`]; encoders and the
//!   [`Receiver`](events::Receiver) (bytes in, events out).
//! - [`link`]: the SPI link's receiver: bit-slip, NSS, overrun and mode-fault recovery in
//!   front of the frame decoder.
//! - [`yaw`]: the 14-byte yaw output frame and its streaming decoder.
//!
//! ```
//! use core_nostd::aer::events::{EventEncoder, Receiver};
//! use core_nostd::event::Event;
//!
//! let mut wire = Vec::new();
//! let mut enc = EventEncoder::new();
//! for i in 0..100u32 {
//!     let ev = Event { t_us: i * 37, x: (i % 7) as u16, y: 3, on: i % 2 == 0 };
//!     enc.push(ev, |f| wire.extend_from_slice(f)).unwrap();
//! }
//! enc.flush(|f| wire.extend_from_slice(f));
//!
//! let mut rx = Receiver::new();
//! let mut n = 0;
//! for chunk in wire.chunks(13) {
//!     rx.push(chunk, |_ev| n += 1);
//! }
//! assert_eq!(n, 100);
//! assert_eq!(rx.frame_stats().bad, 0);
//! ```

pub mod config;
pub mod crc;
pub mod events;
pub mod frame;
pub mod framer;
pub mod link;
pub mod yaw;
