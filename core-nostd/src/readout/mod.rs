//! Readouts: from the network's output to one yaw value per output period.
//!
//! - [`calibrated`]: the product's readout: yaw rate in rad/s, causal, from past events and the
//!   camera's focal length and principal point only.
//! - [`spikes`]: the same rates from the network's spikes alone (each unit's spike times),
//!   through the same field estimator.
//! - [`normalized`]: the paper's readout, a leaky integrator of right-to-left minus
//!   left-to-right spikes; divided by its maximum over the recording afterwards (host only).
//! - [`field`], [`shared`]: the rotation estimator and the pieces the rad/s readouts share;
//!   [`stride_choice`]: whether the calibrated readout decodes the near units or the layout's;
//!   [`aperture`]: which decodes time an edge that moves mostly vertically (not read).

pub mod aperture;
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

/// The spiking networks a readout may read beside the main one: the same layout and events.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// Slow units: `tau_F` = [`crate::params::TAU_SLOW_US`].
    Slow,
    /// Near units: the FAC pixel one pixel from the TRG pixel
    /// ([`crate::network::Network::near_units`]).
    Near,
}

/// A readout: consumes the network's output, produces a value at each output time.
pub trait Readout: NetSink {
    /// The value at output time `t_us` (called once per period, in order) and its flags.
    fn output(&mut self, t_us: u32) -> (I16F16, u8);

    /// Whether the readout also reads a network of slow units ([`Side::Slow`]); the pipeline
    /// then runs one and hands its spikes to [`Readout::side_spikes`].
    const SLOW_UNITS: bool = false;

    /// Whether the readout also reads a network of near units ([`Side::Near`]), when the
    /// layout's stride is above 1; the pipeline then runs one and hands its spikes to
    /// [`Readout::side_spikes`].
    const NEAR_UNITS: bool = false;

    /// With [`Readout::SLOW_UNITS`]: whether the slow units' network reads its FAC pixel one
    /// pixel from the TRG pixel (else at the layout's stride) for the events after the output
    /// just made; the pipeline asks after each output ([`crate::network::Network::set_near`]).
    fn slow_units_near(&self) -> bool {
        false
    }

    /// A run of spikes of one unit of the `side` network (as [`NetSink::spikes`] for the main
    /// network).
    fn side_spikes(&mut self, _side: Side, _cell: u32, _dir: Dir, _times: &[u32]) {}

    /// [`NetSink::resume`] of a side network (whose sink is as [`NetSink::SPARSE`] as the
    /// readout's own).
    fn side_resume(&mut self, _side: Side, _cell: u32, _dir: Dir) {}
}

/// The sink a side network writes to: the readout's [`Readout::side_spikes`].
pub struct SideSink<'r, R: Readout> {
    /// The readout.
    pub readout: &'r mut R,
    /// Which network writes.
    pub side: Side,
}

impl<R: Readout> NetSink for SideSink<'_, R> {
    const SPIKES: bool = true;
    const SPARSE: bool = R::SPARSE;

    #[inline]
    fn resume(&mut self, cell: u32, dir: Dir) {
        self.readout.side_resume(self.side, cell, dir);
    }

    #[inline]
    fn tail_memory_us(&self) -> u32 {
        self.readout.tail_memory_us()
    }

    #[inline]
    fn spike(&mut self, s: Spike) {
        self.readout
            .side_spikes(self.side, s.cell, s.dir, &[s.t_us]);
    }

    #[inline]
    fn spikes(&mut self, cell: u32, dir: Dir, times: &[u32]) {
        self.readout.side_spikes(self.side, cell, dir, times);
    }
}
