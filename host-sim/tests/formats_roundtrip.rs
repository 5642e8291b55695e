//! Round trips through the public interface: `convert --to evt3` then back to CSV is identical
//! to the direct CSV (real recordings and the synthetic dev01); CSV in, CSV out is identical;
//! EVT 2.1 and EVT 2.0 streams encoded here from the format specification decode to the events
//! they were made from, whatever the header says about the sensor.

use std::io::Write;
use std::path::Path;

use core_nostd::evt::{evt2, evt21};
use host_sim::formats::{self, Event64, Format};
use host_sim::testdata::shared_data;

use crate::common::convert;

/// Direct CSV, and CSV after a trip through EVT 3.0, must be byte-identical.
fn round_trip(input: &Path, tmp: &Path) {
    let name = input.file_name().unwrap().to_string_lossy().into_owned();
    let direct = tmp.join(format!("{name}.csv"));
    let raw = tmp.join(format!("{name}.raw"));
    let back = tmp.join(format!("{name}.back.csv"));
    let again = tmp.join(format!("{name}.again.csv"));
    convert(input, "csv", &direct);
    convert(input, "evt3", &raw);
    convert(&raw, "csv", &back);
    convert(&direct, "csv", &again);
    let d = std::fs::read(&direct).unwrap();
    assert!(
        d == std::fs::read(&back).unwrap(),
        "{name}: CSV after EVT 3.0 differs"
    );
    assert!(
        d == std::fs::read(&again).unwrap(),
        "{name}: CSV -> CSV differs"
    );
}

#[test]
fn real_recordings_round_trip_through_evt3() {
    let Some(dir) = shared_data("real") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    for f in [
        "prophesee_gen3_evt2.raw",
        "prophesee_gen41_evt3_triggers.raw",
        "davis346_imu.aedat4",
    ] {
        round_trip(&dir.join(f), tmp.path());
    }
}

#[test]
fn dev01_round_trips_through_evt3() {
    let Some(dir) = shared_data("synthetic") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    round_trip(
        &dir.join("dev01_davis346_noise_sinusoid/events.txt"),
        tmp.path(),
    );
}

#[test]
fn evt3_writer_keeps_the_sensor_size_and_handles_long_gaps() {
    let tmp = tempfile::tempdir().unwrap();
    // Events far apart (several 2^24 µs wraps between them) and far from zero.
    let events: Vec<Event64> = [0u64, 5, 5, 17_000_000, 60_000_000, 60_000_001, 400_000_000]
        .iter()
        .enumerate()
        .map(|(i, &dt)| Event64 {
            t_us: 1_700_000_000_000_000 + dt,
            x: i as u16 * 3,
            y: 7,
            on: i % 2 == 0,
        })
        .collect();
    let out = tmp.path().join("gaps.raw");
    formats::write_evt3(&events, Some(640), Some(480), &out).unwrap();
    let rec = formats::read(&out, None).unwrap();
    assert_eq!(rec.format, Format::Evt3);
    assert_eq!((rec.width, rec.height), (Some(640), Some(480)));
    assert_eq!(rec.events, events);
    // Out of order: refused, and no output file.
    let bad = [events[1], events[0]];
    let out = tmp.path().join("bad.raw");
    let e = formats::write_evt3(&bad, None, None, &out)
        .unwrap_err()
        .to_string();
    assert!(e.contains("event 1"), "{e}");
    assert!(!out.exists());
}

/// Events for the EVT 2.x streams: 3 time groups with vectors and single pixels.
fn spec_events() -> (Vec<u64>, Vec<Event64>) {
    let t0 = 123_456_789u64;
    let t1 = t0 + 100; // next TIME_HIGH
    let mut words = vec![
        evt21::encode::time_high(t0),
        evt21::encode::vector(true, (t0 & 63) as u8, 32, 5, 0b1001), // x 32, 35
        evt21::encode::vector(false, (t0 & 63) as u8, 64, 6, 1 << 31), // x 95
        0xA000_0000_0000_0001,                                       // EXT_TRIGGER
        evt21::encode::time_high(t1),
        evt21::encode::vector(true, (t1 & 63) as u8, 0, 479, 0xFFFF_FFFF), // x 0..=31
    ];
    words.push(0xE000_0000_0000_0000); // OTHERS
    let mut events = vec![
        Event64 {
            t_us: t0,
            x: 32,
            y: 5,
            on: true,
        },
        Event64 {
            t_us: t0,
            x: 35,
            y: 5,
            on: true,
        },
        Event64 {
            t_us: t0,
            x: 95,
            y: 6,
            on: false,
        },
    ];
    events.extend((0..32).map(|x| Event64 {
        t_us: t1,
        x,
        y: 479,
        on: true,
    }));
    (words, events)
}

fn write_raw(path: &Path, header: &str, bytes: &[u8]) {
    let mut f = std::fs::File::create(path).unwrap();
    f.write_all(header.as_bytes()).unwrap();
    f.write_all(bytes).unwrap();
}

#[test]
fn evt21_streams_from_the_spec() {
    let tmp = tempfile::tempdir().unwrap();
    let (words, events) = spec_events();
    let le: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let p = tmp.path().join("evt21.raw");
    write_raw(
        &p,
        "% evt 2.1\n% format EVT21;height=480;width=640\n% end\n",
        &le,
    );
    assert_eq!(formats::detect(&p).unwrap(), Format::Evt21);
    let rec = formats::read(&p, None).unwrap();
    assert_eq!(rec.events, events);
    assert_eq!((rec.width, rec.height), (Some(640), Some(480)));
    // Legacy layout (32-bit halves swapped), announced in the format line.
    let legacy: Vec<u8> = words
        .iter()
        .flat_map(|w| evt21::encode::to_legacy(*w).to_le_bytes())
        .collect();
    let p = tmp.path().join("evt21_legacy.raw");
    write_raw(
        &p,
        "% format EVT21;endianness=legacy;height=480;width=640\n% end\n",
        &legacy,
    );
    assert_eq!(formats::read(&p, None).unwrap().events, events);
    // Through the binary: the CSV lists the same events.
    let csv = tmp.path().join("evt21.csv");
    convert(&tmp.path().join("evt21.raw"), "csv", &csv);
    let text = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(text.lines().count(), events.len() + 1);
    assert_eq!(text.lines().nth(1), Some("123456789,32,5,1"));
}

#[test]
fn evt2_stream_with_system_id_only() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, events) = spec_events();
    let mut words = Vec::new();
    let mut th = None;
    for e in &events {
        if th != Some(e.t_us >> 6) {
            th = Some(e.t_us >> 6);
            words.push(evt2::encode::time_high(e.t_us));
        }
        words.push(evt2::encode::cd(e.on, (e.t_us & 63) as u8, e.x, e.y));
    }
    let le: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let p = tmp.path().join("evt2.raw");
    // Header as Prophesee's Gen3 camera wrote it: no format, no geometry, system_ID 21.
    write_raw(
        &p,
        "% Date 2020-09-25 07:48:31\n% integrator_name Prophesee\n% system_ID 21\n% evt 2.0\n",
        &le,
    );
    let rec = formats::read(&p, None).unwrap();
    assert_eq!(rec.format, Format::Evt2);
    assert_eq!((rec.width, rec.height), (Some(640), Some(480)));
    assert_eq!(rec.events, events);
    // --format overrides the header.
    let e = formats::read(&p, Some(Format::Evt3));
    assert!(e.is_err() || e.unwrap().events != events);
}

#[test]
fn csv_with_and_without_header() {
    let tmp = tempfile::tempdir().unwrap();
    let with = tmp.path().join("with.csv");
    let without = tmp.path().join("without.csv");
    std::fs::write(&with, "t_us,x,y,p\n10,1,2,1\n11,3,4,0\n").unwrap();
    std::fs::write(&without, "10,1,2,1\r\n11,3,4,0\r\n").unwrap();
    let a = formats::read(&with, None).unwrap();
    let b = formats::read(&without, None).unwrap();
    assert_eq!(a.format, Format::Csv);
    assert_eq!(a.events, b.events);
    assert_eq!(
        a.events,
        vec![
            Event64 {
                t_us: 10,
                x: 1,
                y: 2,
                on: true
            },
            Event64 {
                t_us: 11,
                x: 3,
                y: 4,
                on: false
            }
        ]
    );
    assert_eq!(a.width, None);
    assert_eq!(a.size_or_extent(), Some((4, 5)));
}
