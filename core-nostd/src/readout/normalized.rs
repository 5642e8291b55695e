//! The paper's readout: `tau_A dA/dt = -A + Σ δ(right-to-left spike) - Σ δ(left-to-right spike)`
//! (signed so that positive = turning right, like the yaw rate). Each spike is weighted exactly,
//! `e^(-(T - t_spike)/tau_A)` at the output time `T`. Dividing by `max |A|` over the recording
//! (which needs the future) is left to the host.

use fixed::types::I16F16;

use super::Readout;
use crate::exp_table::ExpDecay;
use crate::layout::Dir;
use crate::network::{NetSink, Spike};
use crate::unit::elapsed_us;

/// Leaky integrator of spikes, in units of spikes (Q32.32).
pub struct Normalized {
    decay: ExpDecay,
    /// `A` at `t_last` in Q32.32.
    a: i64,
    t_last: u32,
    /// Contributions of spikes since `t_last`, already decayed to `next`.
    pending: i64,
    next: u32,
    period_us: u32,
    started: bool,
}

impl Normalized {
    /// A readout with time constant `tau_a_us` and output period `period_us`.
    pub fn new(tau_a_us: u32, period_us: u32) -> Self {
        Self {
            decay: ExpDecay::new(tau_a_us),
            a: 0,
            t_last: 0,
            pending: 0,
            next: 0,
            period_us,
            started: false,
        }
    }

    /// The integrator's raw value `A` (spikes) at the last output.
    pub fn value(&self) -> i64 {
        self.a
    }
}

impl NetSink for Normalized {
    const SPIKES: bool = true;

    fn spike(&mut self, s: Spike) {
        if !self.started {
            return;
        }
        let w = i64::from(self.decay.decay_bits(elapsed_us(s.t_us, self.next))) << 1; // Q32
        match s.dir {
            Dir::RightToLeft => self.pending += w,
            Dir::LeftToRight => self.pending -= w,
        }
    }
}

impl Readout for Normalized {
    fn output(&mut self, t_us: u32) -> (I16F16, u8) {
        if !self.started {
            self.started = true;
            self.t_last = t_us;
            self.next = t_us.wrapping_add(self.period_us);
            return (I16F16::ZERO, 0);
        }
        let k = i128::from(self.decay.decay_bits(elapsed_us(self.t_last, t_us)));
        self.a = ((i128::from(self.a) * k) >> 31) as i64 + self.pending;
        self.pending = 0;
        self.t_last = t_us;
        self.next = t_us.wrapping_add(self.period_us);
        let v = (self.a >> 16).clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
        (I16F16::from_bits(v), 0)
    }
}
