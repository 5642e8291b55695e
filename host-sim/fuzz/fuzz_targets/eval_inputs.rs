//! `host-sim eval` on arbitrary files: an estimate CSV, a ground-truth file and a gyro file cut
//! from the input, read and evaluated with either resampling. Every read and the evaluation
//! give a result or an error; never a panic.
#![no_main]

use std::path::PathBuf;

use host_sim::eval::{self, EvalOptions, Resample};
use libfuzzer_sys::fuzz_target;

fn scratch(name: &str) -> PathBuf {
    let dir = if std::path::Path::new("/dev/shm").is_dir() {
        PathBuf::from("/dev/shm")
    } else {
        std::env::temp_dir()
    };
    dir.join(format!("tde-fuzz-eval-{}-{name}", std::process::id()))
}

fuzz_target!(|data: &[u8]| {
    let Some((&sel, rest)) = data.split_first() else {
        return;
    };
    // Three files separated by 0xFF bytes (which no text file holds).
    let mut parts = rest.splitn(3, |&b| b == 0xFF);
    let (yaw, gt, imu) = (scratch("yaw"), scratch("gt"), scratch("imu"));
    for p in [&yaw, &gt, &imu] {
        if std::fs::write(p, parts.next().unwrap_or_default()).is_err() {
            return;
        }
    }
    let est = eval::read_estimate(&yaw);
    let truth = eval::read_gt(&gt);
    let gyro = eval::read_gyro_yaw(&imu);
    if let (Ok(est), Ok(truth)) = (est, truth) {
        let opts = EvalOptions {
            resample: if sel & 1 == 0 {
                Resample::Hold
            } else {
                Resample::Linear
            },
            ..EvalOptions::default()
        };
        if let Ok(report) = eval::evaluate(&est, &truth, gyro.as_ref().ok(), &opts) {
            let _ = report.to_text();
        }
    }
    for p in [&yaw, &gt, &imu] {
        let _ = std::fs::remove_file(p);
    }
});
