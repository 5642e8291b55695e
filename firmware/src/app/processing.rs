//! The processing stage: checked frames -> events -> the pipeline [`Settings`] build -> yaw
//! frames.
//!
//! Yaw samples follow event time: the pipeline emits the samples due before each event, on the
//! 1 kHz grid of event timestamps, however fast the events are replayed; at the end of a replay
//! it is polled up to the last event's time (as `host-sim run` does). On a live link ([`Clock::Live`]) the MCU clock also drives the output when
//! no events arrive: after [`LIVE_MARGIN_US`] without a frame, event time is extrapolated from
//! the last event with the MCU clock (flag CLOCK), and the pipeline flags samples STALE once
//! 100 ms have passed without events.

use core::marker::PhantomData;
use core_nostd::aer::events::PayloadDecoder;
use core_nostd::aer::frame::Kind;
use core_nostd::aer::yaw::YawFrame;
use core_nostd::flags;
use core_nostd::readout::YawSample;

use core_nostd::layout::Layout;
use core_nostd::pipeline::Pipeline;
use core_nostd::readout::Readout;
use core_nostd::settings::{Built, Settings, WithPipeline};
use core_nostd::time::EventTime;
use embassy_futures::select::{select, Either};
use embassy_time::{Duration, Instant, Timer};
use fixed::types::I16F16;

use super::{take_flags, update_stats, CostMeter, FrameReceiver, YawSink};

/// How [`run`] ended (and so how `configured::run` ends).
pub enum Exit {
    /// The stream ended (replays).
    End,
    /// A different configuration arrived; run it next.
    Reconfigure(Settings),
}

/// Whether the MCU clock drives the output when no events arrive.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum Clock {
    /// Replay: output follows event time only (deterministic).
    #[cfg_attr(not(feature = "board-qemu"), allow(dead_code))]
    EventTimeOnly,
    /// Live link: the MCU clock takes over when events stop.
    Live,
}

/// On a live link, how long (µs) after the last frame the clock takes over. Frames span up to
/// 1 ms and take time to arrive, so the clock stays this far behind to not emit samples that
/// events still in flight belong to.
pub const LIVE_MARGIN_US: u32 = 5_000;

/// Output state: sequence counter and counters.
struct Out<'s, K: YawSink> {
    sink: &'s mut K,
    seq: u8,
}

impl<K: YawSink> Out<'_, K> {
    fn emit(&mut self, s: YawSample, extra: u8) {
        let frame = YawFrame {
            seq: self.seq,
            flags: s.flags | take_flags() | extra,
            t_us: s.t_us,
            yaw_rate: s.yaw_rate,
        };
        self.seq = self.seq.wrapping_add(1);
        if self.sink.write(&frame.encode()) {
            update_stats(|st| st.yaw_out += 1);
        } else {
            super::raise_flags(flags::OVERFLOW);
            update_stats(|st| st.yaw_dropped += 1);
        }
    }
}

/// Runs the processing stage on the frames of `queue` until the end of the stream (replays) or
/// a configuration frame that differs from `current` and that `accept`s (then the samples due
/// up to the last event are emitted first); forever on a live link otherwise. `seq` is the yaw frames' sequence
/// counter, carried over from and to the previous and next run.
pub async fn run<K: YawSink, M: CostMeter>(
    queue: &mut FrameReceiver,
    pipeline: &mut Built<'_>,
    sink: &mut K,
    clock: Clock,
    seq: &mut u8,
    current: &Settings,
    accept: &dyn Fn(&Settings) -> bool,
) -> Exit {
    let mut payload = PayloadDecoder::new();
    let mut out = Out { sink, seq: *seq };
    let mut decoder_errors = 0u64;
    // Live clock: last event time and when it was processed.
    let mut last: Option<(u32, Instant)> = None;
    let start = Instant::now();
    let mut idle_tick: u32 = 0;
    let meter_overhead_x1024 = M::overhead_x1024();
    update_stats(|st| st.meter_overhead_x1024 = meter_overhead_x1024);
    loop {
        // The frame is read in its slot, which is freed (`receive_done`) once it is used.
        let slot = match clock {
            Clock::EventTimeOnly => queue.receive().await,
            Clock::Live => {
                let deadline = Instant::now() + Duration::from_micros(u64::from(LIVE_MARGIN_US));
                match select(queue.receive(), Timer::at(deadline)).await {
                    Either::First(slot) => slot,
                    Either::Second(()) => {
                        clock_tick(pipeline, &mut out, last, start, &mut idle_tick);
                        continue;
                    }
                }
            }
        };
        let Some(f) = slot.frame() else {
            queue.receive_done();
            // As `host-sim run`: the samples due up to the last event's time.
            if let Some((t, _)) = last {
                pipeline.finish(t, &mut |s| out.emit(s, 0));
            }
            record_network(pipeline);
            *seq = out.seq;
            return Exit::End;
        };
        if f.kind == Kind::Config {
            let parsed = Settings::parse(f.payload);
            queue.receive_done();
            update_stats(|st| st.frames_processed += 1);
            match parsed {
                Ok(new) if new == *current => {}
                Ok(new) if accept(&new) => {
                    if let Some((t, _)) = last {
                        pipeline.finish(t, &mut |s| out.emit(s, 0));
                    }
                    record_network(pipeline);
                    update_stats(|st| st.configs_applied += 1);
                    *seq = out.seq;
                    return Exit::Reconfigure(new);
                }
                _ => {
                    defmt::warn!("configuration frame refused");
                    update_stats(|st| st.configs_refused += 1);
                }
            }
            continue;
        }
        let (cost, events, last_t) = pipeline.with(FrameEvents::<K, M> {
            payload: &mut payload,
            frame: &f,
            out: &mut out,
            meter: PhantomData,
        });
        queue.receive_done();
        if let Some(t) = last_t {
            last = Some((t, Instant::now()));
        }
        let e3 = payload.stats().evt3.invalid;
        if e3 != decoder_errors {
            decoder_errors = e3;
            super::raise_flags(flags::DECODER_ERRORS);
        }
        update_stats(|st| {
            st.frames_processed += 1;
            st.events = st.events.wrapping_add(events);
            let gross_x1024 = cost * u64::from(M::units_per_tick()) * 1024;
            let overhead = u64::from(events) * meter_overhead_x1024;
            st.cost_units += gross_x1024.saturating_sub(overhead) / 1024;
            st.decoder_errors = e3 as u32;
        });
        // Let the input stage run between frames.
        embassy_futures::yield_now().await;
    }
}

/// One frame's events through the pipeline (inside [`Built::with`]: the pipeline's layout and
/// readout are known, no dispatch per event), each timed with the cost meter `M`.
struct FrameEvents<'x, 's, 'p, K: YawSink, M: CostMeter> {
    payload: &'x mut PayloadDecoder,
    frame: &'x core_nostd::aer::frame::Frame<'p>,
    out: &'x mut Out<'s, K>,
    meter: PhantomData<M>,
}

impl<K: YawSink, M: CostMeter> WithPipeline for FrameEvents<'_, '_, '_, K, M> {
    /// Cost (meter ticks), events, the last event's time.
    type Output = (u64, u32, Option<u32>);

    fn run<L: Layout, R: Readout>(self, p: &mut Pipeline<'_, L, R>) -> Self::Output {
        let (mut cost, mut events, mut last_t) = (0u64, 0u32, None);
        let out = self.out;
        self.payload.frame(self.frame, |ev| {
            let a = M::now();
            p.event(ev, &mut |s| out.emit(s, 0));
            let b = M::now();
            cost += u64::from(M::ticks(a, b));
            events += 1;
            last_t = Some(ev.t_us);
        });
        (cost, events, last_t)
    }
}

/// Adds a finished run's network counters (spikes of both networks, unit pool) to the stats.
fn record_network(pipeline: &Built<'_>) {
    let (spikes, pool_full) = (pipeline.spike_count(), pipeline.pool_full());
    let pool = pipeline.pool_use();
    update_stats(|st| {
        st.spikes += spikes;
        st.pool_full = st
            .pool_full
            .saturating_add(u32::try_from(pool_full).unwrap_or(u32::MAX));
        if let Some(p) = pool {
            st.pool_capacity = p.capacity as u32;
            st.pool_peak = st.pool_peak.max(p.peak as u32);
        }
    });
}

/// Live clock without frames: extrapolates event time from the last event and polls.
fn clock_tick<K: YawSink>(
    pipeline: &mut Built<'_>,
    out: &mut Out<'_, K>,
    last: Option<(u32, Instant)>,
    start: Instant,
    idle_tick: &mut u32,
) {
    match last {
        Some((t, at)) => {
            let since = (Instant::now() - at).as_micros();
            let since = since.saturating_sub(u64::from(LIVE_MARGIN_US));
            let est = t.wrapping_add(since.min(u64::from(u32::MAX >> 1)) as u32);
            pipeline.poll(est, &mut |s| out.emit(s, flags::CLOCK));
        }
        None => {
            // No event yet: stale samples on the MCU clock, yaw rate 0.
            let now_us = (Instant::now() - start).as_micros() as u32;
            let now = EventTime::from_us(now_us);
            while now.since(EventTime::from_us(*idle_tick)).is_some() {
                out.emit(
                    YawSample {
                        t_us: *idle_tick,
                        yaw_rate: I16F16::ZERO,
                        flags: flags::STALE,
                    },
                    flags::CLOCK,
                );
                *idle_tick = idle_tick.wrapping_add(1_000);
            }
        }
    }
}
