//! The whole processing chain the firmware and `host-sim run` share: events in, network,
//! readout, one yaw sample per output period out. [`crate::settings::Settings::build`] puts it
//! together.
//!
//! Output times form a fixed grid `t0 + k · period` on the event clock (`t0` = first event).
//! A sample at `T` is produced before any event later than `T` is processed, after the network
//! has been moved to `T` ([`Network::tick`]), so it depends only on events up to `T`. When no
//! events arrive, [`Pipeline::poll`] moves the clock from outside (the firmware's timer); after
//! [`STALE_AFTER_US`] without an event the samples carry [`flags::STALE`]; a sample after
//! unit inputs were lost to a full unit pool ([`crate::network::pool`]) carries
//! [`flags::OVERFLOW`].

use crate::event::Event;
use crate::flags;
use crate::layout::Layout;
use crate::network::{Network, PoolUse};
use crate::readout::{Readout, SlowSide, YawSample};
use crate::time::EventTime;

/// Samples are flagged stale after this long without an event (µs).
pub const STALE_AFTER_US: u32 = 100_000;

/// Network plus readout plus output clock (plus, for readouts with [`Readout::SLOW_UNITS`], the
/// network of slow units: the same events, in the same order, after the main network's).
pub struct Pipeline<'a, L: Layout, R: Readout> {
    net: Network<'a, L>,
    slow: Option<Network<'a, L>>,
    readout: R,
    period_us: u32,
    /// Next output time, once the first event has set the grid.
    next_out: Option<EventTime>,
    last_event: EventTime,
    /// The network's [`crate::network::NetStats::pool_full`] at the last sample.
    pool_full_seen: u64,
    /// Samples produced.
    pub samples: u64,
}

impl<'a, L: Layout, R: Readout> Pipeline<'a, L, R> {
    /// A pipeline producing one sample every `period_us` µs (at least 1).
    pub fn new(net: Network<'a, L>, readout: R, period_us: u32) -> Self {
        Self::with_slow_units(net, None, readout, period_us)
    }

    /// The same, with the network of slow units `slow` (for a readout with
    /// [`Readout::SLOW_UNITS`]; others ignore it).
    pub fn with_slow_units(
        net: Network<'a, L>,
        slow: Option<Network<'a, L>>,
        readout: R,
        period_us: u32,
    ) -> Self {
        Self {
            net,
            slow: if R::SLOW_UNITS { slow } else { None },
            readout,
            period_us: period_us.max(1),
            next_out: None,
            last_event: EventTime::from_us(0),
            pool_full_seen: 0,
            samples: 0,
        }
    }

    /// The network.
    pub fn network(&self) -> &Network<'a, L> {
        &self.net
    }

    /// How full the unit pool is; with the slow units' network, whichever of the two pools
    /// (each of the same size) had the higher peak. `None`: no pool.
    pub fn pool_use(&self) -> Option<PoolUse> {
        let main = self.net.pool_use();
        let slow = self.slow.as_ref().and_then(Network::pool_use);
        match (main, slow) {
            (Some(a), Some(b)) if b.peak > a.peak => Some(b),
            (None, b) => b,
            (a, _) => a,
        }
    }

    /// Spikes emitted (and not taken back) by both networks.
    pub fn spike_count(&self) -> u64 {
        let count = |n: &Network<'a, L>| n.stats().spikes_lr.saturating_add(n.stats().spikes_rl);
        let slow = self.slow.as_ref().map_or(0, count);
        count(&self.net).saturating_add(slow)
    }

    /// Unit inputs lost to a full unit pool, in both networks.
    pub fn pool_full(&self) -> u64 {
        let slow = self.slow.as_ref().map_or(0, |n| n.stats().pool_full);
        self.net.stats().pool_full.saturating_add(slow)
    }

    /// The readout.
    pub fn readout(&self) -> &R {
        &self.readout
    }

    /// Processes one event (stream order), first emitting every sample due before it.
    pub fn event<F: FnMut(YawSample)>(&mut self, ev: Event, out: &mut F) {
        let t = EventTime::from_us(ev.t_us);
        match self.next_out {
            None => self.next_out = Some(t.add_us(self.period_us)),
            Some(_) => self.emit_until(t, false, out),
        }
        self.last_event = t;
        self.net.event(ev, &mut self.readout);
        if let (true, Some(slow)) = (R::SLOW_UNITS, self.slow.as_mut()) {
            slow.event(ev, &mut SlowSide(&mut self.readout));
        }
    }

    /// Moves the clock to `now_us` without an event, emitting every sample due up to it.
    pub fn poll<F: FnMut(YawSample)>(&mut self, now_us: u32, out: &mut F) {
        self.emit_until(EventTime::from_us(now_us), true, out);
    }

    /// Ends the run at `now_us` (the last event's time): emits every sample due up to it, then
    /// settles the network there ([`Network::flush`]: its spike counts become exactly those
    /// up to `now_us`, none ahead of it).
    pub fn finish<F: FnMut(YawSample)>(&mut self, now_us: u32, out: &mut F) {
        self.poll(now_us, out);
        self.net.flush(now_us, &mut self.readout);
        if let (true, Some(slow)) = (R::SLOW_UNITS, self.slow.as_mut()) {
            slow.flush(now_us, &mut SlowSide(&mut self.readout));
        }
    }

    /// Emits samples at grid times `T < t` (or `T <= t` when `inclusive`).
    fn emit_until<F: FnMut(YawSample)>(&mut self, t: EventTime, inclusive: bool, out: &mut F) {
        let Some(mut next) = self.next_out else {
            return;
        };
        while t.is_after(next) || (inclusive && t == next) {
            self.net.tick(next.as_us(), &mut self.readout);
            if let (true, Some(slow)) = (R::SLOW_UNITS, self.slow.as_mut()) {
                slow.tick(next.as_us(), &mut SlowSide(&mut self.readout));
            }
            let (yaw_rate, mut f) = self.readout.output(next.as_us());
            if next.elapsed_since(self.last_event) > STALE_AFTER_US {
                f |= flags::STALE;
            }
            let pool_full = self.pool_full();
            if pool_full != self.pool_full_seen {
                // Unit inputs were lost to a full unit pool since the last sample.
                f |= flags::OVERFLOW;
                self.pool_full_seen = pool_full;
            }
            out(YawSample {
                t_us: next.as_us(),
                yaw_rate,
                flags: f,
            });
            self.samples += 1;
            next = next.add_us(self.period_us);
        }
        self.next_out = Some(next);
    }
}

/// Onset gap of the product's pipeline (µs): a pixel whose last onset is older than this starts
/// a new edge even without a polarity change. Long enough that a slow edge (the slowest the
/// slow units time, ~0.03 rad/s on a DAVIS346, takes ~250 ms per pixel), whose passage leaves
/// several same-polarity events, counts once.
pub const ONSET_GAP_US: u32 = 250_000;
