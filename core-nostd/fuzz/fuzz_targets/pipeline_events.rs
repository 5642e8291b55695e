//! The network (its units per cell and in a unit pool) and the three readouts on arbitrary events: coordinates out of range, time going
//! backwards, equal timestamps, huge bursts at one pixel, the u32 clock wrapping. No panic, the
//! calibrated output is a finite rate within the histograms' range, and the normalized readout
//! gives the same samples and spike count with its input read ahead as without.
#![no_main]

use core_nostd::event::Event;
use core_nostd::fixed::types::U16F16;
use core_nostd::layout::{Dense, Layout};
use core_nostd::network::{active_words, Cell, InputFilter, NetState, Network, NextInput, UnitPair};
use core_nostd::pipeline::Pipeline;
use core_nostd::readout::spikes::SpikeCell;
use core_nostd::readout::YawSample;
use core_nostd::settings::{LayoutChoice, ReadoutChoice, Settings};
use core_nostd::readout::normalized::Normalized;
use core_nostd::unit::Kernel;
use libfuzzer_sys::fuzz_target;

/// 7 bytes per event: time step (u16, or a jump back when the top bit is set), x, y, polarity.
fn events(data: &[u8]) -> impl Iterator<Item = Event> + '_ {
    let mut t: u32 = u32::MAX - 50_000; // start just before the wrap
    data.chunks_exact(7).map(move |b| {
        let step = u32::from(u16::from_le_bytes([b[0], b[1]]));
        t = if step & 0x8000 != 0 {
            t.wrapping_sub(step & 0x7FFF)
        } else {
            t.wrapping_add(step * 16)
        };
        Event {
            t_us: t,
            x: u16::from_le_bytes([b[2], b[3]]) % 80,
            y: u16::from_le_bytes([b[4], b[5]]) % 30,
            on: b[6] & 1 == 1,
        }
    })
}

/// Each event with what a reader of the whole input knows of the next event at its pixel:
/// `At` where no event in between is later (wrapping), else a bound.
fn read_ahead(evs: &[Event]) -> Vec<(Event, NextInput)> {
    let last = evs.last().map_or(0, |e| e.t_us);
    evs.iter()
        .enumerate()
        .map(|(i, e)| {
            let later = evs[i + 1..].iter().position(|f| (f.x, f.y) == (e.x, e.y));
            let next = match later.map(|k| i + 1 + k) {
                Some(j) => {
                    let t = evs[j].t_us;
                    if evs[..j].iter().all(|f| (f.t_us.wrapping_sub(t) as i32) <= 0) {
                        NextInput::At(t)
                    } else {
                        NextInput::NotBefore(t)
                    }
                }
                None => NextInput::NotBefore(last),
            };
            (*e, next)
        })
        .collect()
}

/// The product's pipeline with `layout` on a 64 x 24 (or 240 x 30) sensor, f = 60 px.
fn calibrated(width: u16, height: u16, layout: LayoutChoice, data: &[u8]) {
    let k = Kernel::DEFAULT;
    let settings = Settings {
        layout,
        ..Settings::for_sensor(width, height, U16F16::from_num(60))
    };
    let Ok(needs) = settings.storage() else {
        return;
    };
    let mut cells = vec![Cell::default(); needs.cells];
    let Ok(mut p) = settings.build(&k, NetState::cells(&mut cells)) else {
        return;
    };
    let mut check = |s: core_nostd::readout::YawSample| {
        assert!(
            s.yaw_rate.abs() <= U16F16::from_num(21u8).to_num::<core_nostd::fixed::types::I16F16>()
        );
    };
    let mut last = 0;
    for ev in events(data) {
        last = ev.t_us;
        p.event(ev, &mut check);
    }
    p.poll(last.wrapping_add(300_000), &mut check);
}

/// The paper's readout on the spiking dense network of a 64 x 24 sensor: its samples and spike
/// count, `evs` fed live or (`ahead`) each with its pixel's next event. `None` where the
/// network cannot be built.
fn normalized(evs: &[Event], ahead: bool) -> Option<(Vec<YawSample>, u64)> {
    let k = Kernel::DEFAULT;
    let layout = Dense::new(64, 24, 2)?;
    let n = layout.cell_count();
    let (mut cells, mut units, mut active) = (
        vec![Cell::default(); n],
        vec![UnitPair::default(); n],
        vec![0u32; active_words(n)],
    );
    let state = NetState::spiking(&mut cells, &mut units, &mut active);
    let net = Network::new(&k, layout, state, InputFilter::All).ok()?;
    let mut p = Pipeline::new(net, Normalized::new(10_000, 1_000), 1_000);
    let mut samples = Vec::new();
    let last = evs.last().map_or(0, |e| e.t_us);
    if ahead {
        for (ev, next) in read_ahead(evs) {
            p.event_ahead(ev, next, &mut |s| samples.push(s));
        }
    } else {
        for &ev in evs {
            p.event(ev, &mut |s| samples.push(s));
        }
    }
    p.finish(last, &mut |s| samples.push(s));
    Some((samples, p.spike_count()))
}

fuzz_target!(|data: &[u8]| {
    calibrated(64, 24, LayoutChoice::Dense, data);
    calibrated(240, 30, LayoutChoice::PaperBoxes, data);
    // The spiking network with the paper's readout: the same samples and spikes with the
    // events read ahead (`Network::event_in_ahead`) as live.
    let evs: Vec<Event> = events(data).collect();
    if let (Some(live), Some(ahead)) = (normalized(&evs, false), normalized(&evs, true)) {
        assert_eq!(ahead.1, live.1);
        assert_eq!(ahead.0, live.0);
    }
    let k = Kernel::DEFAULT;
    // The spike readout over a unit pool of 16 pairs (full most of the time).
    let settings = Settings {
        readout: ReadoutChoice::Spikes,
        unit_pool: Some(16),
        ..Settings::for_sensor(64, 24, U16F16::from_num(60))
    };
    let Ok(needs) = settings.storage() else {
        return;
    };
    let mut cells = vec![Cell::default(); needs.cells];
    let mut units = vec![UnitPair::default(); needs.unit_pairs];
    let mut owners = vec![0u32; needs.pool_owners];
    let mut active = vec![0u32; needs.active_words];
    let mut spike_cells = vec![SpikeCell::EMPTY; needs.spike_cells];
    let state = NetState::pooled(&mut cells, &mut units, &mut owners, &mut active);
    let Ok(mut p) = settings.build_with(&k, state, &mut spike_cells) else {
        return;
    };
    let mut last = 0;
    for ev in events(data) {
        last = ev.t_us;
        p.event(ev, &mut |_| {});
    }
    p.finish(last, &mut |_| {});
    let pool = p.pool_use().expect("a pool");
    assert!(pool.peak <= 16 && pool.used <= pool.peak);
});
