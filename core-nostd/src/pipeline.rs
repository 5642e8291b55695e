//! The whole processing chain the firmware and `host-sim run` share: events in, network,
//! readout, one yaw sample per output period out.
//!
//! Output times form a fixed grid `t0 + k · period` on the event clock (`t0` = first event).
//! A sample at `T` is produced before any event later than `T` is processed, after the network
//! has been moved to `T` ([`Network::tick`]), so it depends only on events up to `T`. When no
//! events arrive, [`Pipeline::poll`] moves the clock from outside (the firmware's timer); after
//! [`STALE_AFTER_US`] without an event the samples carry [`flags::STALE`].

use crate::event::Event;
use crate::layout::Layout;
use crate::network::Network;
use crate::readout::{flags, Readout, YawSample};
use crate::unit::elapsed_us;

/// Samples are flagged stale after this long without an event (µs).
pub const STALE_AFTER_US: u32 = 100_000;

/// Network plus readout plus output clock.
pub struct Pipeline<'a, L: Layout, R: Readout> {
    net: Network<'a, L>,
    readout: R,
    period_us: u32,
    /// Next output time, once the first event has set the grid.
    next_out: Option<u32>,
    last_event: u32,
    /// Samples produced.
    pub samples: u64,
}

impl<'a, L: Layout, R: Readout> Pipeline<'a, L, R> {
    /// A pipeline producing one sample every `period_us` µs (at least 1).
    pub fn new(net: Network<'a, L>, readout: R, period_us: u32) -> Self {
        Self {
            net,
            readout,
            period_us: period_us.max(1),
            next_out: None,
            last_event: 0,
            samples: 0,
        }
    }

    /// The network.
    pub fn network(&self) -> &Network<'a, L> {
        &self.net
    }

    /// The readout.
    pub fn readout(&self) -> &R {
        &self.readout
    }

    /// Processes one event (stream order), first emitting every sample due before it.
    pub fn event<F: FnMut(YawSample)>(&mut self, ev: Event, out: &mut F) {
        match self.next_out {
            None => self.next_out = Some(ev.t_us.wrapping_add(self.period_us)),
            Some(_) => self.emit_until(ev.t_us, false, out),
        }
        self.last_event = ev.t_us;
        self.net.event(ev, &mut self.readout);
    }

    /// Moves the clock to `now_us` without an event, emitting every sample due up to it.
    pub fn poll<F: FnMut(YawSample)>(&mut self, now_us: u32, out: &mut F) {
        self.emit_until(now_us, true, out);
    }

    /// Emits samples at grid times `T < t` (or `T <= t` when `inclusive`).
    fn emit_until<F: FnMut(YawSample)>(&mut self, t: u32, inclusive: bool, out: &mut F) {
        let Some(mut next) = self.next_out else {
            return;
        };
        loop {
            let d = t.wrapping_sub(next);
            let due = if inclusive {
                d < 1 << 31
            } else {
                d != 0 && d < 1 << 31
            };
            if !due {
                break;
            }
            self.net.tick(next, &mut self.readout);
            let (yaw_rate, mut f) = self.readout.output(next);
            if elapsed_us(self.last_event, next) > STALE_AFTER_US {
                f |= flags::STALE;
            }
            out(YawSample {
                t_us: next,
                yaw_rate,
                flags: f,
            });
            self.samples += 1;
            next = next.wrapping_add(self.period_us);
        }
        self.next_out = Some(next);
    }
}

/// Onset gap of the product's pipeline (µs): a pixel whose last onset is older than this starts
/// a new edge even without a polarity change. Long enough that a slow edge (the slowest the
/// slow units time, ~0.03 rad/s on a DAVIS346, takes ~250 ms per pixel), whose passage leaves
/// several same-polarity events, counts once.
pub const ONSET_GAP_US: u32 = 250_000;

/// The product's pipeline, as the firmware and `host-sim run` both build it: the onset filter,
/// the network over `layout` (state in `cells`, 12 bytes per pixel: the calibrated readout needs
/// no unit state), the calibrated readout, one sample per `cal.period_us`.
pub fn calibrated<'a, L: Layout>(
    kernel: &'a crate::unit::Kernel,
    layout: L,
    cells: &'a mut [crate::network::Cell],
    cal: crate::readout::calibrated::Calibration,
) -> Result<Pipeline<'a, L, crate::readout::calibrated::Calibrated>, crate::network::NetError> {
    let readout = crate::readout::calibrated::Calibrated::new(kernel, &layout, cal);
    let net = Network::new(
        kernel,
        layout,
        cells,
        &mut [],
        &mut [],
        crate::network::InputFilter::Onsets {
            gap_us: ONSET_GAP_US,
        },
    )?;
    Ok(Pipeline::new(net, readout, cal.period_us))
}
