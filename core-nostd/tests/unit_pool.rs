//! The unit pool (`network::pool`): while it has room a pooled network gives the same spikes
//! whatever its size, close to the dense network's (the rest rule drops drives below 1/16);
//! when it is full the lost inputs are counted and flagged and nothing else changes; slots
//! come back once their units are at rest.

use core_nostd::event::Event;
use core_nostd::flags;
use core_nostd::layout::{Dense, Layout};
use core_nostd::network::{
    active_words, Cell, InputFilter, NetSink, NetState, NetStats, Network, PoolUse, Spike, Trigger,
    UnitPair,
};
use core_nostd::settings::{LayoutChoice, ReadoutChoice, Settings};
use core_nostd::unit::Kernel;
use fixed::types::U16F16;
use proptest::prelude::*;

/// Events on a small grid: (gap µs, x, y, polarity).
fn grid_train(w: u16, h: u16) -> impl Strategy<Value = Vec<(u32, u16, u16, bool)>> {
    prop::collection::vec((0u32..6_000, 0..w, 0..h, any::<bool>()), 1..400)
}

/// Every spike of the network on `train` (ticking each ms, then flushed), in order of time,
/// cell and orientation (a tick visits cells in memory order, a pool's in slot order), with
/// the counters, the pool use and every trigger record; `pool`: `None` = one pair per cell,
/// else a pool of that many pairs.
fn run(
    layout: Dense,
    train: &[(u32, u16, u16, bool)],
    pool: Option<usize>,
) -> (Vec<Spike>, NetStats, Option<PoolUse>, Vec<Trigger>) {
    let k = Kernel::DEFAULT;
    let n = layout.cell_count();
    let pairs = pool.unwrap_or(n);
    let mut cells = vec![Cell::default(); n];
    let mut units = vec![UnitPair::default(); pairs];
    let mut owners = vec![0u32; pool.unwrap_or(0)];
    let mut active = vec![0u32; active_words(pairs)];
    let state = match pool {
        None => NetState::spiking(&mut cells, &mut units, &mut active),
        Some(_) => NetState::pooled(&mut cells, &mut units, &mut owners, &mut active),
    };
    let mut net = Network::new(&k, layout, state, InputFilter::All).unwrap();
    let mut sink = Record::default();
    let (mut t, mut tick) = (0u32, 1_000u32);
    for &(gap, x, y, on) in train {
        t += gap;
        while tick < t {
            net.tick(tick, &mut sink);
            tick += 1_000;
        }
        net.event(Event { t_us: t, x, y, on }, &mut sink);
    }
    // Long enough for every unit to come to rest and the sweep to pass every slot.
    for _ in 0..1_000 {
        net.tick(tick, &mut sink);
        tick += 1_000;
    }
    net.flush(tick, &mut sink);
    let Record {
        mut spikes,
        triggers,
    } = sink;
    spikes.sort_by_key(|s| (s.t_us, s.cell, s.dir.slot()));
    let stats = *net.stats();
    let pool_use = net.pool_use();
    (spikes, stats, pool_use, triggers)
}

/// A sink that keeps every spike and every trigger record.
#[derive(Default)]
struct Record {
    spikes: Vec<Spike>,
    triggers: Vec<Trigger>,
}

impl NetSink for Record {
    const SPIKES: bool = true;
    fn trigger(&mut self, t: &Trigger) {
        self.triggers.push(*t);
    }
    fn spike(&mut self, s: Spike) {
        self.spikes.push(s);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 100, ..ProptestConfig::default() })]

    #[test]
    fn a_pool_with_room_gives_the_same_spikes_whatever_its_size(train in grid_train(10, 4)) {
        let layout = Dense::new(10, 4, 2).unwrap();
        let (large, large_stats, _, _) = run(layout, &train, Some(1_000));
        let (small, stats, pool, _) = run(layout, &train, Some(40));
        prop_assert_eq!(&small, &large);
        prop_assert_eq!(stats, large_stats);
        prop_assert_eq!(stats.pool_full, 0);
        let pool = pool.unwrap();
        prop_assert!(pool.peak <= 40);
        // Every slot is back once every unit is at rest.
        prop_assert_eq!(pool.used, 0);
        // Close to the dense network: the rest rule moves few spikes.
        let (dense, _, _, _) = run(layout, &train, None);
        let diff = (small.len() as f64 - dense.len() as f64).abs();
        prop_assert!(diff <= 0.02 * dense.len() as f64 + 3.0, "{} vs {}", small.len(), dense.len());
    }

    #[test]
    fn a_full_pool_loses_inputs_and_nothing_else(train in grid_train(10, 4)) {
        let layout = Dense::new(10, 4, 2).unwrap();
        let (spikes, stats, pool, triggers) = run(layout, &train, Some(3));
        let pool = pool.unwrap();
        prop_assert!(pool.peak <= 3);
        prop_assert_eq!(pool.used, 0);
        let (dense, dense_stats, _, dense_triggers) = run(layout, &train, Some(1_000));
        // The FAC traces and what each event delivers do not depend on the units.
        prop_assert_eq!(triggers, dense_triggers);
        if stats.pool_full == 0 {
            prop_assert_eq!(spikes, dense);
        } else {
            prop_assert_eq!(stats.events, dense_stats.events);
            prop_assert_eq!(stats.filtered, dense_stats.filtered);
        }
    }
}

/// An edge sweeping right over the first `n` pixels of row `y`, one pixel per 300 µs,
/// starting `t0` after the event before.
fn sweep(y: u16, n: u16, t0: u32) -> Vec<(u32, u16, u16, bool)> {
    (0..n)
        .map(|x| (if x == 0 { t0 } else { 300 }, x, y, true))
        .collect()
}

#[test]
fn when_the_pool_is_full_the_loss_is_counted_flagged_and_the_slots_come_back() {
    // Four edges sweeping four rows at once: 4 x 8 cells bursting together, a pool of 4.
    let mut train = Vec::new();
    for y in 0..4 {
        train.extend(sweep(y, 10, if y == 0 { 1_000 } else { 10 }));
    }
    let layout = Dense::new(10, 4, 2).unwrap();
    let (_, stats, pool, _) = run(layout, &train, Some(4));
    assert!(stats.pool_full > 0, "{stats:?}");
    assert_eq!(pool.unwrap().peak, 4);
    assert_eq!(pool.unwrap().used, 0, "slots back after the units rest");
    // After the storm a short edge (three units) gets slots again and spikes as in a pool
    // with room.
    let mut later = train.clone();
    later.extend(sweep(1, 5, 2_000_000));
    let (pooled, _, _, _) = run(layout, &later, Some(4));
    let (dense, _, _, _) = run(layout, &later, Some(1_000));
    let after = |s: &[Spike]| {
        s.iter()
            .filter(|s| s.t_us >= 2_000_000)
            .copied()
            .collect::<Vec<_>>()
    };
    assert!(!after(&dense).is_empty());
    assert_eq!(after(&pooled), after(&dense));

    // Through the pipeline: the sample after the loss carries OVERFLOW, later ones do not.
    let settings = Settings {
        readout: ReadoutChoice::Normalized,
        unit_pool: Some(4),
        layout: LayoutChoice::Dense,
        ..Settings::for_sensor(10, 4, U16F16::from_num(10))
    };
    let needs = settings.storage().unwrap();
    assert_eq!((needs.unit_pairs, needs.pool_owners), (4, 4));
    let k = Kernel::DEFAULT;
    let mut cells = vec![Cell::default(); needs.cells];
    let mut units = vec![UnitPair::default(); needs.unit_pairs];
    let mut owners = vec![0u32; needs.pool_owners];
    let mut active = vec![0u32; needs.active_words];
    let state = NetState::pooled(&mut cells, &mut units, &mut owners, &mut active);
    let mut p = settings.build(&k, state).unwrap();
    let mut samples = Vec::new();
    let mut t = 0u32;
    for &(gap, x, y, on) in &later {
        t += gap;
        p.event(Event { t_us: t, x, y, on }, &mut |s| samples.push(s));
    }
    let flagged: Vec<u32> = samples
        .iter()
        .filter(|s| s.flags & flags::OVERFLOW != 0)
        .map(|s| s.t_us)
        .collect();
    assert!(!flagged.is_empty());
    assert!(flagged.iter().all(|&t| t < 100_000), "{flagged:?}");
    assert!(p.net_stats().pool_full > 0);
}
