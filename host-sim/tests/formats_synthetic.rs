//! The synthetic sequence dev01 in every format it ships (ECD text, EVT 3.0, AEDAT 4.0, MVSEC
//! HDF5) gives the same events; sensor size and intrinsics come from the files; gyro from
//! imu.txt, AEDAT4 and MVSEC agree; ground truth from gt.csv, MVSEC poses and ECD
//! groundtruth.txt agree on the yaw rate and its sign.

use std::io::Write;
use std::path::PathBuf;

use host_sim::formats::{self, Format, Intrinsics};
use host_sim::testdata::shared_data;

fn dev01() -> Option<PathBuf> {
    Some(shared_data("synthetic")?.join("dev01_davis346_noise_sinusoid"))
}

const DATA_H5: &str = "dev01_davis346_noise_sinusoid_data.hdf5";
const GT_H5: &str = "dev01_davis346_noise_sinusoid_gt.hdf5";

#[test]
fn dev01_every_format_gives_the_same_events() {
    let Some(dir) = dev01() else { return };
    let intr = Intrinsics {
        fx: 226.0,
        fy: 226.0,
        cx: 172.5,
        cy: 129.5,
    };
    let text = formats::read(dir.join("events.txt"), None).unwrap();
    assert_eq!(text.format, Format::EcdText);
    assert_eq!(text.events.len(), 582_933);
    assert_eq!(
        (text.width, text.height),
        (Some(346), Some(260)),
        "from meta.json"
    );
    assert_eq!(text.intrinsics, Some(intr), "from meta.json");
    assert_eq!(text.gyro.as_ref().map(Vec::len), Some(4001), "from imu.txt");
    for (file, format) in [
        ("events.raw", Format::Evt3),
        ("events.aedat4", Format::Aedat4),
        (DATA_H5, Format::MvsecHdf5),
    ] {
        let rec = formats::read(dir.join(file), None).unwrap();
        assert_eq!(rec.format, format, "{file}");
        assert!(
            rec.events == text.events,
            "{file}: events differ from events.txt"
        );
        assert_eq!((rec.width, rec.height), (Some(346), Some(260)), "{file}");
        assert_eq!(rec.intrinsics, Some(intr), "{file}");
        assert!(rec.gyro.is_some(), "{file}");
    }
}

#[test]
fn dev01_gyro_agrees_across_formats() {
    let Some(dir) = dev01() else { return };
    let txt = formats::read_gyro(dir.join("imu.txt")).unwrap();
    let h5 = formats::read_gyro(dir.join(DATA_H5)).unwrap();
    let ae = formats::read_gyro(dir.join("events.aedat4")).unwrap();
    assert_eq!(txt.len(), 4001);
    assert_eq!(h5.len(), txt.len());
    assert_eq!(ae.len(), txt.len());
    for ((a, b), c) in txt.iter().zip(&h5).zip(&ae) {
        assert!(
            (a.t_s - b.t_s).abs() < 1e-9 && (a.t_s - c.t_s).abs() < 1e-6,
            "{a:?} {b:?} {c:?}"
        );
        for (x, y, z) in [(a.wx, b.wx, c.wx), (a.wy, b.wy, c.wy), (a.wz, b.wz, c.wz)] {
            assert!((x - y).abs() < 1e-8, "{a:?} vs {b:?}");
            // AEDAT4 stores deg/s as f32.
            assert!((x - z).abs() < 1e-6, "{a:?} vs {c:?}");
        }
    }
}

#[test]
fn dev01_ground_truth_agrees_across_formats() {
    let Some(dir) = dev01() else { return };
    let csv = formats::read_ground_truth(dir.join("gt.csv")).unwrap();
    let h5 = formats::read_ground_truth(dir.join(GT_H5)).unwrap();
    assert_eq!(csv.len(), 4001);
    assert_eq!(h5.len(), csv.len());
    let mut max_err: f64 = 0.0;
    for (a, b) in csv.iter().zip(&h5) {
        assert!((a.t_s - b.t_s).abs() < 1e-9);
        max_err = max_err.max((a.yaw_rate_rad_s - b.yaw_rate_rad_s).abs());
    }
    // Central differences of 1 kHz poses (one-sided at both ends) vs the analytic rate.
    assert!(
        max_err < 2e-3,
        "max |gt.csv wy - pose-derived yaw rate| = {max_err}"
    );

    // An ECD groundtruth.txt holding the same motion: rotation about the camera's y axis by
    // yaw_rad (gt.csv column 5), position irrelevant.
    let text = std::fs::read_to_string(dir.join("gt.csv")).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("groundtruth.txt");
    let mut f = std::fs::File::create(&path).unwrap();
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
        let (t, yaw) = (v[0], v[4]);
        writeln!(
            f,
            "{t:.6} 0 0 {:.6} 0 {:.12} 0 {:.12}",
            t * 0.1,
            (yaw / 2.0).sin(),
            (yaw / 2.0).cos()
        )
        .unwrap();
    }
    drop(f);
    let ecd = formats::read_ground_truth(&path).unwrap();
    assert_eq!(ecd.len(), csv.len());
    let max_err = csv
        .iter()
        .zip(&ecd)
        .map(|(a, b)| (a.yaw_rate_rad_s - b.yaw_rate_rad_s).abs())
        .fold(0.0, f64::max);
    assert!(
        max_err < 2e-3,
        "max |gt.csv wy - groundtruth.txt yaw rate| = {max_err}"
    );
}

#[test]
fn ground_truth_and_gyro_files_are_not_events() {
    let Some(dir) = dev01() else { return };
    for file in ["gt.csv", "imu.txt"] {
        let e = formats::detect(dir.join(file)).unwrap_err().to_string();
        assert!(e.contains(file) && e.contains("not events"), "{e}");
    }
}
