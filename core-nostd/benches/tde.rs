//! Cost of the fixed-point core per event: a FAC-only event, a TRG event that starts a burst
//! (including emitting the whole burst) with the stand-alone unit's Newton engine and with the
//! network's burst engine (per spike: the burst's spikes, emitted whole or one output period at a
//! time), and one event of the dense network.

use core_nostd::event::Event;
use core_nostd::layout::{Dense, Layout};
use core_nostd::network::{active_words, Cell, InputFilter, NetState, Network, Spike, UnitPair};
use core_nostd::unit::{fine, reported_by, BurstUnit, Kernel, Tde, WideTrace};
use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};

fn unit_events(c: &mut Criterion) {
    let k = Kernel::DEFAULT;
    let mut g = c.benchmark_group("unit");
    g.throughput(Throughput::Elements(1));

    // FAC-only: decay the trace over the elapsed time and add the weight.
    let mut tde = Tde::new(0);
    let mut t = 0u32;
    g.bench_function("fac_event", |b| {
        b.iter(|| {
            t = t.wrapping_add(1_237);
            tde.fac(&k, black_box(t));
        })
    });

    // A TRG 5 ms after a FAC starts a 26-spike burst; the event is charged with emitting it all.
    let mut t = 0u32;
    let mut spikes = 0u32;
    g.bench_function("trg_event_with_burst", |b| {
        b.iter(|| {
            let mut tde = Tde::new(t);
            tde.fac(&k, t);
            t = t.wrapping_add(5_000);
            tde.trg(&k, t, |_| spikes += 1);
            t = t.wrapping_add(200_000);
            tde.advance(&k, t, |_| spikes += 1);
        })
    });
    black_box(spikes);

    // The same TRG event without its burst (the burst is emitted later, by the clock).
    let mut t = 0u32;
    g.bench_function("trg_event_only", |b| {
        b.iter(|| {
            let mut tde = Tde::new(t);
            tde.fac(&k, t);
            t = t.wrapping_add(5_000);
            tde.trg(&k, black_box(t), |_| ());
        })
    });
    g.finish();
}

fn burst_engine(c: &mut Criterion) {
    let k = Kernel::DEFAULT;
    // A TRG event after a FAC trace of 0.25..1.25 (bursts of 20 to 130 spikes).
    let drive = |i: u32| WideTrace((1 << 22) + (i % 64) * (1 << 18));
    let spikes_per_burst = {
        let mut u = BurstUnit::IDLE;
        k.burst_input(&mut u, 0, drive(32));
        k.burst_emit(&mut u, fine(1_000_000), |_| ())
    };
    let mut g = c.benchmark_group("burst_engine");
    g.throughput(Throughput::Elements(u64::from(spikes_per_burst)));
    let mut i = 0u32;
    let mut spikes = 0u64;
    g.bench_function("input_and_whole_burst", |b| {
        b.iter(|| {
            i = i.wrapping_add(1);
            let mut u = BurstUnit::IDLE;
            let t = i.wrapping_mul(1_000_000);
            k.burst_input(&mut u, t, black_box(drive(32)));
            spikes += u64::from(k.burst_emit(&mut u, fine(t.wrapping_add(1_000_000)), |s| {
                black_box(s);
            }));
        })
    });
    // The same burst emitted one 1 ms tick at a time, as the network's clock does.
    g.bench_function("input_and_burst_by_ticks", |b| {
        b.iter(|| {
            i = i.wrapping_add(1);
            let mut u = BurstUnit::IDLE;
            let t = i.wrapping_mul(1_000_000);
            k.burst_input(&mut u, t, black_box(drive(32)));
            let mut tick = t;
            while u.pending() {
                tick = tick.wrapping_add(1_000);
                spikes += u64::from(k.burst_emit(&mut u, reported_by(tick), |s| {
                    black_box(s);
                }));
            }
        })
    });
    g.finish();
    black_box(spikes);
}

fn network_events(c: &mut Criterion) {
    let k = Kernel::DEFAULT;
    let layout = Dense::new(346, 260, 2).unwrap();
    let mut cells = vec![Cell::default(); layout.cell_count()];
    let mut units = vec![UnitPair::default(); layout.cell_count()];
    let mut active = vec![0u32; active_words(layout.cell_count())];
    let mut net = Network::new(
        &k,
        layout,
        NetState::spiking(&mut cells, &mut units, &mut active),
        InputFilter::All,
    )
    .unwrap();
    // An edge sweeping right at 200 px/s over every row: realistic neighbour timing.
    let mut events = Vec::new();
    for step in 0..20_000u32 {
        let x = (step % 346) as u16;
        let y = ((step * 7) % 260) as u16;
        events.push(Event {
            t_us: step * 50,
            x,
            y,
            on: true,
        });
    }
    let mut i = 0usize;
    let mut spikes = 0u64;
    let mut g = c.benchmark_group("network");
    g.throughput(Throughput::Elements(1));
    g.bench_function("dense_346x260_event", |b| {
        b.iter(|| {
            let mut ev = events[i % events.len()];
            ev.t_us = ev.t_us.wrapping_add((i / events.len()) as u32 * 1_000_000);
            net.event(ev, &mut |_: Spike| spikes += 1);
            i += 1;
        })
    });
    g.finish();
    black_box(spikes);
}

criterion_group!(benches, unit_events, burst_engine, network_events);
criterion_main!(benches);
