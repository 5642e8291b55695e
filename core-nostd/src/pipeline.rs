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
use crate::network::{EventState, Network, NextInput, PoolUse};
use crate::readout::{Readout, Side, SideSink, YawSample};
use crate::time::EventTime;

/// Samples are flagged stale after this long without an event (µs).
pub const STALE_AFTER_US: u32 = 100_000;

/// The spiking networks beside the main one (see [`Side`]), for readouts that read them
/// ([`Readout::SLOW_UNITS`], [`Readout::NEAR_UNITS`]).
pub struct Sides<'a, L: Layout> {
    /// The slow units' network.
    pub slow: Option<Network<'a, L>>,
    /// The near units' network ([`Network::near_units`]).
    pub near: Option<Network<'a, L>>,
}

impl<L: Layout> Sides<'_, L> {
    /// None.
    pub const NONE: Self = Self {
        slow: None,
        near: None,
    };
}

/// Network plus readout plus output clock (plus, for readouts that read them, the side
/// networks: the same events, in the same order, after the main network's).
pub struct Pipeline<'a, L: Layout, R: Readout> {
    net: Network<'a, L>,
    sides: Sides<'a, L>,
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
        Self::with_sides(net, Sides::NONE, readout, period_us)
    }

    /// The same, with the side networks `sides` (each for a readout that reads it; others
    /// ignore it).
    pub fn with_sides(
        net: Network<'a, L>,
        sides: Sides<'a, L>,
        readout: R,
        period_us: u32,
    ) -> Self {
        Self {
            net,
            sides: Sides {
                slow: sides.slow.filter(|_| R::SLOW_UNITS),
                near: sides.near.filter(|_| R::NEAR_UNITS),
            },
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

    /// The networks: the main one, then the side networks that run.
    fn networks(&self) -> impl Iterator<Item = &Network<'a, L>> {
        core::iter::once(&self.net)
            .chain(self.sides.slow.as_ref())
            .chain(self.sides.near.as_ref())
    }

    /// Runs `f` on each side network that runs, with the sink it writes to (nothing at all,
    /// at compile time, for readouts that read none).
    #[inline]
    fn each_side(&mut self, mut f: impl FnMut(&mut Network<'a, L>, &mut SideSink<'_, R>)) {
        if !(R::SLOW_UNITS || R::NEAR_UNITS) {
            return;
        }
        let Self { sides, readout, .. } = self;
        for (net, side) in [(&mut sides.slow, Side::Slow), (&mut sides.near, Side::Near)] {
            if let Some(net) = net.as_mut() {
                f(net, &mut SideSink { readout, side });
            }
        }
    }

    /// How full the unit pool is; with side networks, whichever of the pools (each of the
    /// same size) had the higher peak. `None`: no pool.
    pub fn pool_use(&self) -> Option<PoolUse> {
        self.networks()
            .filter_map(Network::pool_use)
            .reduce(|a, b| if b.peak > a.peak { b } else { a })
    }

    /// Spikes emitted (and not taken back) by all networks.
    pub fn spike_count(&self) -> u64 {
        self.networks().fold(0u64, |n, net| {
            n.saturating_add(net.stats().spikes_lr)
                .saturating_add(net.stats().spikes_rl)
        })
    }

    /// Unit inputs lost to a full unit pool, in all networks.
    pub fn pool_full(&self) -> u64 {
        self.networks()
            .fold(0u64, |n, net| n.saturating_add(net.stats().pool_full))
    }

    /// The readout.
    pub fn readout(&self) -> &R {
        &self.readout
    }

    /// Processes one event (stream order), first emitting every sample due before it.
    ///
    /// Inline: the common cases (no sample due; an event outside a window's layout, which is
    /// only counted) cost a few instructions where the caller loops over events; the work of
    /// an event in the layout and of a sample is out of line.
    #[inline(always)]
    pub fn event<F: FnMut(YawSample)>(&mut self, ev: Event, out: &mut F) {
        self.clock_to_event(ev, out);
        // One layout: the side networks' cell is the main one's, and an event outside it is
        // counted by the main network alone.
        if let Some(c) = self.net.locate(ev) {
            // Without `AHEAD` the next input is not read.
            self.event_at::<false>(ev, c, NextInput::NotBefore(ev.t_us));
        }
    }

    /// [`Pipeline::event`] for a caller that reads its input ahead and knows `next`, the next
    /// event at this event's cell: the main network's units emit their spikes up to it at
    /// once ([`Network::event_in_ahead`]). The samples are the same.
    #[inline(always)]
    pub fn event_ahead<F: FnMut(YawSample)>(&mut self, ev: Event, next: NextInput, out: &mut F) {
        self.clock_to_event(ev, out);
        if let Some(c) = self.net.locate(ev) {
            self.event_at::<true>(ev, c, next);
        }
    }

    /// Whether [`Pipeline::event_ahead`] has the main network's units emit ahead
    /// ([`Network::reads_ahead`]): whether reading the input ahead serves this pipeline.
    pub fn reads_ahead(&self) -> bool {
        self.net.reads_ahead::<R>()
    }

    /// The main network's state an event at `(x, y)` will touch first
    /// ([`Network::state_at`]).
    pub fn state_at(&self, x: u16, y: u16) -> Option<EventState<'_>> {
        self.net.state_at(x, y)
    }

    /// Emits every sample due before event `ev`.
    #[inline(always)]
    fn clock_to_event<F: FnMut(YawSample)>(&mut self, ev: Event, out: &mut F) {
        let t = EventTime::from_us(ev.t_us);
        match self.next_out {
            None => self.next_out = Some(t.add_us(self.period_us)),
            // Most events come before the next sample is due.
            Some(next) if t.is_after(next) => self.emit_until(t, false, out),
            Some(_) => {}
        }
        self.last_event = t;
    }

    /// An event at cell `c` of the layout, through every network. The near units' network
    /// hears only the events the main network's input filter let through: it has the main
    /// network's kernel, and its cells follow the same events (an event held back changes
    /// neither), so its own filter would hold back the same ones (its cell clocks can differ
    /// only after an out-of-order event, by whether the cell's units were live). The slow
    /// units' filter is their own (another `tau_F`). The side networks are called by name, not
    /// through [`Pipeline::each_side`] with a test of the side: that cost the F405 window with
    /// the spike readout 3 instructions per event (QEMU, dev03).
    /// With `AHEAD`, the main network's units emit up to `next` ([`Network::event_in_ahead`]).
    #[inline(never)]
    fn event_at<const AHEAD: bool>(&mut self, ev: Event, c: usize, next: NextInput) {
        let passed = if AHEAD {
            self.net.event_in_ahead(ev, c, next, &mut self.readout)
        } else {
            self.net.event_in(ev, c, &mut self.readout)
        };
        if !(R::SLOW_UNITS || R::NEAR_UNITS) {
            return;
        }
        let Self { sides, readout, .. } = self;
        if let Some(net) = sides.slow.as_mut() {
            let side = Side::Slow;
            net.event_in(ev, c, &mut SideSink { readout, side });
        }
        if let Some(net) = sides.near.as_mut().filter(|_| passed) {
            let side = Side::Near;
            net.event_in(ev, c, &mut SideSink { readout, side });
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
        self.each_side(|net, sink| net.flush(now_us, sink));
    }

    /// Emits samples at grid times `T < t` (or `T <= t` when `inclusive`).
    fn emit_until<F: FnMut(YawSample)>(&mut self, t: EventTime, inclusive: bool, out: &mut F) {
        let Some(mut next) = self.next_out else {
            return;
        };
        while t.is_after(next) || (inclusive && t == next) {
            self.net.tick(next.as_us(), &mut self.readout);
            self.each_side(|net, sink| net.tick(next.as_us(), sink));
            let (yaw_rate, mut f) = self.readout.output(next.as_us());
            if R::SLOW_UNITS {
                if let Some(net) = self.sides.slow.as_mut() {
                    net.set_near(self.readout.slow_units_near());
                }
            }
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
