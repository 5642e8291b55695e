//! Cost of the fixed-point core per event: a FAC-only event, a TRG event that starts a burst
//! (including emitting the whole burst), and one event of the dense network.

use core_nostd::event::Event;
use core_nostd::layout::{Dense, Layout};
use core_nostd::network::{active_words, Cell, InputFilter, NetState, Network, Spike, UnitPair};
use core_nostd::unit::{Kernel, Tde};
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

criterion_group!(benches, unit_events, network_events);
criterion_main!(benches);
