//! The real recordings in `shared/data/real` convert to CSV byte-identical to their reference
//! decodes; the independent `evt3` crate agrees with our EVT 3.0 decoder and reads our EVT 3.0
//! writer's files; the AEDAT4 IMU matches its reference decode.

use std::path::{Path, PathBuf};

use host_sim::formats::{self, Event64, Format};
use host_sim::testdata::shared_data;

use crate::common::convert;

/// (recording, reference CSV, format, width, height, events)
const REAL: [(&str, &str, Format, u16, u16, usize); 3] = [
    (
        "prophesee_gen3_evt2.raw",
        "prophesee_gen3_evt2.events.csv",
        Format::Evt2,
        640,
        480,
        521_252,
    ),
    (
        "prophesee_gen41_evt3_triggers.raw",
        "prophesee_gen41_evt3_triggers.events.csv",
        Format::Evt3,
        1280,
        720,
        82_469,
    ),
    (
        "davis346_imu.aedat4",
        "davis346_imu.events.csv",
        Format::Aedat4,
        346,
        260,
        78_830,
    ),
];

fn real() -> Option<PathBuf> {
    shared_data("real")
}

#[test]
fn real_recordings_convert_to_their_reference_csv() {
    let Some(dir) = real() else { return };
    let tmp = tempfile::tempdir().unwrap();
    for (file, reference, ..) in REAL {
        let out = tmp.path().join(format!("{file}.csv"));
        convert(&dir.join(file), "csv", &out);
        let ours = std::fs::read(&out).unwrap();
        let theirs = std::fs::read(dir.join(reference)).unwrap();
        assert!(ours == theirs, "{file}: CSV differs from {reference}");
    }
}

#[test]
fn real_recordings_detect_format_size_and_count() {
    let Some(dir) = real() else { return };
    for (file, _, format, w, h, n) in REAL {
        let path = dir.join(file);
        assert_eq!(formats::detect(&path).unwrap(), format, "{file}");
        let rec = formats::read(&path, None).unwrap();
        assert_eq!(rec.format, format);
        assert_eq!((rec.width, rec.height), (Some(w), Some(h)), "{file}");
        assert_eq!(rec.events.len(), n, "{file}");
        assert!(
            rec.events.windows(2).all(|p| p[0].t_us <= p[1].t_us),
            "{file}: time order"
        );
        assert!(
            rec.events.iter().all(|e| e.x < w && e.y < h),
            "{file}: events inside the sensor"
        );
    }
}

/// Events of a `.raw` EVT 3.0 file decoded by the `evt3` crate.
fn evt3_crate(path: &Path) -> Vec<Event64> {
    let mut d = evt3::Evt3Decoder::new();
    let r = d.decode_file(path).unwrap();
    r.cd_events
        .iter()
        .map(|e| Event64 {
            t_us: e.timestamp,
            x: e.x,
            y: e.y,
            on: e.polarity != 0,
        })
        .collect()
}

#[test]
fn evt3_crate_agrees_on_the_real_evt3_file() {
    let Some(dir) = real() else { return };
    let path = dir.join("prophesee_gen41_evt3_triggers.raw");
    let ours = formats::read(&path, None).unwrap().events;
    assert_eq!(ours, evt3_crate(&path));
}

#[test]
fn evt3_crate_reads_our_evt3_files() {
    let Some(dir) = real() else { return };
    let tmp = tempfile::tempdir().unwrap();
    for (file, ..) in REAL {
        let rec = formats::read(dir.join(file), None).unwrap();
        let out = tmp.path().join(format!("{file}.evt3.raw"));
        formats::write_evt3(&rec.events, rec.width, rec.height, &out).unwrap();
        // The evt3 crate does not know our `tde_time_offset_us` header line: it sees the times
        // minus the offset (a multiple of 2^24 µs).
        let origin = rec.events[0].t_us & !((1u64 << 24) - 1);
        let theirs = evt3_crate(&out);
        let expect: Vec<Event64> = rec
            .events
            .iter()
            .map(|e| Event64 {
                t_us: e.t_us - origin,
                ..*e
            })
            .collect();
        assert_eq!(theirs, expect, "{file}");
        // And we read our own file back with absolute times.
        let back = formats::read(&out, None).unwrap();
        assert_eq!(back.events, rec.events, "{file}");
        assert_eq!((back.width, back.height), (rec.width, rec.height));
    }
}

#[test]
fn aedat4_imu_matches_its_reference_decode() {
    let Some(dir) = real() else { return };
    let ours = formats::read_gyro(dir.join("davis346_imu.aedat4")).unwrap();
    // The reference CSV (deg/s, `t_us` printed with 9 significant digits).
    let reference = formats::read_gyro(dir.join("davis346_imu.imu.csv")).unwrap();
    assert_eq!(ours.len(), 2363);
    assert_eq!(ours.len(), reference.len());
    for (a, b) in ours.iter().zip(&reference) {
        for (x, y) in [(a.wx, b.wx), (a.wy, b.wy), (a.wz, b.wz)] {
            assert!((x - y).abs() <= 1e-6 * y.abs().max(1e-3), "{a:?} vs {b:?}");
        }
        // The reference prints t_us with 9 significant digits (1.58916315e+15): 10 s resolution.
        assert!((a.t_s - b.t_s).abs() <= 10.0, "{a:?} vs {b:?}");
    }
    let rec = formats::read(dir.join("davis346_imu.aedat4"), None).unwrap();
    assert_eq!(rec.gyro.as_deref(), Some(&ours[..]));
}
