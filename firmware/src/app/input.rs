//! The input stage: bytes and link events from the board's source -> the link receiver
//! (bit-slip, NSS, overrun and mode-fault recovery; frame checks) -> the frame queue.

use core_nostd::aer::frame::flags;
use core_nostd::aer::link::{LinkEvent, LinkReceiver};
use core_nostd::flags as yaw_flags;

use super::{raise_flags, update_stats, ByteSource, CostMeter, FrameSender, Overload, SourceError};

/// Bytes read from the source per call (at most: a live link's source returns what it has).
/// Each call costs the link receiver a few header checks and searches whatever its length, but
/// on QEMU's single executor the processing stage runs between reads: 1 KiB reads took a
/// replay's input from 13.5 to 11.8 instructions per byte, and the live overload run's output
/// after its storm from 0.5 % to 2.4 % of the peak off the replay (`xtask/tests/qemu.rs`).
const CHUNK: usize = 256;

/// Publishes the receiver's counters and raises INPUT_ERRORS when frames were lost.
fn publish(link: &LinkReceiver, errors_seen: &mut u64) {
    let st = link.frame_stats();
    let l = *link.stats();
    let errors = st.bad + st.dropped;
    if errors != *errors_seen {
        *errors_seen = errors;
        raise_flags(yaw_flags::INPUT_ERRORS);
    }
    update_stats(|s| {
        s.bytes = st.bytes as u32;
        s.frames_rx = st.ok as u32;
        s.frames_bad = st.bad as u32;
        s.frames_gap = st.dropped as u32;
        s.source_overflows = st.source_overflows as u32;
        s.skipped_bytes = st.skipped_bytes as u32;
        s.transactions = l.transactions as u32;
        s.cut_transactions = l.cut_transactions as u32;
        s.bit_slips = l.bit_slips as u32;
        s.spi_overruns = l.overruns as u32;
        s.mode_faults = l.mode_faults as u32;
    });
}

/// Hands every frame the receiver has complete to the processing stage, each copied once into
/// a free slot of the queue: on a live link ([`Overload::DropFrames`]) a frame that finds none
/// is dropped whole and counted; a replay ([`Overload::Backpressure`]) waits for one (the wait
/// is not part of `cost`).
async fn drain<M: CostMeter>(
    link: &mut LinkReceiver,
    queue: &mut FrameSender,
    mode: Overload,
    cost: &mut u64,
) {
    let mut a = M::now();
    while let Some(f) = link.next_frame() {
        if f.flags & flags::SOURCE_OVERFLOW != 0 {
            raise_flags(yaw_flags::OVERFLOW);
        }
        let slot = match mode {
            Overload::Backpressure => {
                *cost += u64::from(M::ticks(a, M::now()));
                let slot = queue.send().await;
                a = M::now();
                Some(slot)
            }
            Overload::DropFrames => queue.try_send(),
        };
        match slot {
            Some(slot) => {
                slot.fill(&f);
                queue.send_done();
            }
            None => {
                raise_flags(yaw_flags::OVERFLOW);
                update_stats(|s| s.frames_overflow += 1);
            }
        }
    }
    *cost += u64::from(M::ticks(a, M::now()));
}

/// Runs the input stage until the source ends (never, on a live link); then queues a slot
/// that says so ([`super::FrameBuf::set_end`]). The cost of decoding (framing, CRCs, the copy
/// into the queue; not the source's reads nor the waits for queue room) is added to
/// `Stats::input_cost_units`.
pub async fn run<S: ByteSource, M: CostMeter>(
    source: &mut S,
    queue: &mut FrameSender,
    mode: Overload,
) {
    let mut link = LinkReceiver::new();
    let mut chunk = [0u8; CHUNK];
    let mut errors_seen = 0u64;
    loop {
        let n = match source.read(&mut chunk).await {
            Ok(0) => break,
            Ok(n) => n,
            Err(SourceError(e)) => {
                // The frames before the event are handed out first.
                link.event(e);
                if e == LinkEvent::RingOverrun {
                    update_stats(|s| s.source_errors += 1);
                }
                if e != LinkEvent::EndOfTransaction {
                    raise_flags(yaw_flags::INPUT_ERRORS);
                }
                let mut cost = 0u64;
                drain::<M>(&mut link, queue, mode, &mut cost).await;
                update_stats(|s| s.input_cost_units += cost * u64::from(M::units_per_tick()));
                publish(&link, &mut errors_seen);
                continue;
            }
        };
        let mut rest = chunk.get(..n).unwrap_or_default();
        let mut cost = 0u64;
        while !rest.is_empty() {
            let a = M::now();
            let taken = link.feed(rest);
            rest = rest.get(taken..).unwrap_or_default();
            cost += u64::from(M::ticks(a, M::now()));
            drain::<M>(&mut link, queue, mode, &mut cost).await;
        }
        update_stats(|s| s.input_cost_units += cost * u64::from(M::units_per_tick()));
        publish(&link, &mut errors_seen);
    }
    link.end_of_stream();
    let mut cost = 0u64;
    drain::<M>(&mut link, queue, mode, &mut cost).await;
    publish(&link, &mut errors_seen);
    queue.send().await.set_end();
    queue.send_done();
}
