//! Readouts: from the network's output to one yaw value per output period.
//!
//! - [`calibrated`]: the product's readout: yaw rate in rad/s, causal, from past events and the
//!   camera's focal length and principal point only.
//! - [`spikes`]: the same rates from the network's spikes alone (each unit's spike times),
//!   through the same field estimator.
//! - [`normalized`]: the paper's readout, a leaky integrator of right-to-left minus
//!   left-to-right spikes; divided by its maximum over the recording afterwards (host only).
//! - [`field`], [`shared`]: the rotation estimator and the pieces the rad/s readouts share;
//!   [`stride_choice`]: whether the calibrated readout decodes the near units or the layout's.

pub mod calibrated;
pub mod field;
pub mod normalized;
pub mod shared;
pub mod spikes;
pub mod stride_choice;

use fixed::types::I16F16;

use crate::layout::Dir;
use crate::network::{NetSink, Spike};

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

    /// Whether the readout also reads a second network of slow units (the same layout and
    /// events, `tau_F` = [`crate::params::TAU_SLOW_US`]); the pipeline then runs one and hands
    /// its spikes to [`Readout::slow_spikes`].
    const SLOW_UNITS: bool = false;

    /// A run of spikes of one slow unit (as [`NetSink::spikes`] for the main network).
    fn slow_spikes(&mut self, _cell: u32, _dir: Dir, _times: &[u32]) {}
}

/// The sink the slow units' network writes to: the readout's [`Readout::slow_spikes`].
pub struct SlowSide<'r, R: Readout>(pub &'r mut R);

impl<R: Readout> NetSink for SlowSide<'_, R> {
    const SPIKES: bool = true;

    #[inline]
    fn spike(&mut self, s: Spike) {
        self.0.slow_spikes(s.cell, s.dir, &[s.t_us]);
    }

    #[inline]
    fn spikes(&mut self, cell: u32, dir: Dir, times: &[u32]) {
        self.0.slow_spikes(cell, dir, times);
    }
}
