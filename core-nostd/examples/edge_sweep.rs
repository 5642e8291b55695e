//! The whole chain on a made-up stimulus: a grating of vertical edges slides left across a
//! small sensor (the view of a camera turning right), events go through the network and the
//! calibrated readout, and yaw-rate samples come out at 1 kHz.
//!
//! `cargo run --release -p core-nostd --example edge_sweep`
//!
//! The network state lives in a `Vec` here; the firmware hands the same `build` a static array.

use core_nostd::event::Event;
use core_nostd::fixed::types::U16F16;
use core_nostd::network::{Cell, NetState};
use core_nostd::settings::Settings;
use core_nostd::unit::Kernel;

/// Sensor: 96 x 24 px, focal length 400 px.
const W: u16 = 96;
const H: u16 = 24;
const FOCAL_PX: u16 = 400;
/// The grating: an edge every 8 px (alternating ON and OFF), moving left at 80 px/s.
const EDGE_SPACING_PX: u16 = 8;
const SPEED_PX_S: u32 = 80;
const DURATION_US: u32 = 1_500_000;

/// Every pixel crossing of every edge, one event per crossing, in time order.
fn grating_events() -> Vec<Event> {
    let us_per_px = 1_000_000 / SPEED_PX_S;
    let mut events = Vec::new();
    // The image moves left: pixel x sees pattern position x + speed * t, so the edge at
    // pattern position p crosses pixel x at t = (p - x) / speed (p >= x).
    let travel_px = (DURATION_US / us_per_px) as u16;
    for (k, p) in (0..W + travel_px)
        .step_by(EDGE_SPACING_PX.into())
        .enumerate()
    {
        for x in 0..W.min(p + 1) {
            let t_us = u32::from(p - x) * us_per_px;
            if t_us >= DURATION_US {
                continue;
            }
            for y in 0..H {
                events.push(Event {
                    t_us,
                    x,
                    y,
                    on: k % 2 == 0,
                });
            }
        }
    }
    events.sort_by_key(|e| e.t_us);
    events
}

fn main() {
    // 1. The run's settings: the defaults for this sensor (dense layout, stride 2, 1 kHz,
    //    calibrated readout, principal point at the centre).
    let settings = Settings::for_sensor(W, H, U16F16::from_num(FOCAL_PX));
    // 2. The storage the settings ask for, from the caller (no heap in the core).
    let needs = settings.storage().expect("valid settings");
    let mut cells = vec![Cell::default(); needs.cells];
    // 3. The pipeline: network + readout + output clock.
    let kernel = Kernel::DEFAULT;
    let mut pipeline = settings
        .build(&kernel, NetState::cells(&mut cells))
        .expect("storage as asked for");

    // 4. Events in, samples out.
    let events = grating_events();
    let mut samples = Vec::new();
    for &ev in &events {
        pipeline.event(ev, &mut |s| samples.push(s));
    }

    // A leftward image motion of u px/s is a right turn of about u / f rad/s.
    let expected = f64::from(SPEED_PX_S) / f64::from(FOCAL_PX);
    println!(
        "{} events, {} samples; expected yaw rate about {expected:.3} rad/s",
        events.len(),
        samples.len()
    );
    for s in samples.iter().step_by(100) {
        println!(
            "t = {:5} ms  yaw = {:+.3} rad/s  flags = {:#04x}",
            s.t_us / 1000,
            s.yaw_rate.to_num::<f64>(),
            s.flags
        );
    }
}
