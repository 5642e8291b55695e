//! Readouts: from the network's output to one yaw value per output period.
//!
//! - [`calibrated`]: the product's readout: yaw rate in rad/s, causal, from past events and the
//!   camera's focal length and principal point only.
//! - [`spikes`]: the same rates from the network's spikes alone (each unit's spike times),
//!   through the same field estimator.
//! - [`normalized`]: the paper's readout, a leaky integrator of right-to-left minus
//!   left-to-right spikes; divided by its maximum over the recording afterwards (host only).
//! - [`field`], [`shared`]: the rotation estimator and the pieces the rad/s readouts share.

pub mod calibrated;
pub mod field;
pub mod normalized;
pub mod shared;
pub mod spikes;

use fixed::types::I16F16;

use crate::network::NetSink;

/// One output sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct YawSample {
    /// Output time (µs, the event clock).
    pub t_us: u32,
    /// Yaw rate in rad/s (positive = turning right), or the normalized readout's raw value.
    pub yaw_rate: I16F16,
    /// See [`crate::flags`].
    pub flags: u8,
}

/// A readout: consumes the network's output, produces a value at each output time.
pub trait Readout: NetSink {
    /// The value at output time `t_us` (called once per period, in order) and its flags.
    fn output(&mut self, t_us: u32) -> (I16F16, u8);
}
