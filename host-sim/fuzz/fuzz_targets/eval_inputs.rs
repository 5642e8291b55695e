//! `host-sim eval` on arbitrary files: an estimate CSV, a ground-truth file and a gyro file cut
//! from the input, read and evaluated with either resampling and several ARRE windows (down to
//! 1 ns: millions of windows per second of data). Every read and the evaluation give a result or
//! an error; never a panic. All three files go the way `host-sim eval` takes them (read in
//! chunks, streamed through `Evaluator`), and the same files read whole and evaluated in memory
//! give the same answer.
#![no_main]

use std::path::{Path, PathBuf};

use host_sim::eval::{
    self, EstimateReader, EvalOptions, Evaluator, GyroYawReader, Resample, SampleSource,
    TruthReader,
};
use libfuzzer_sys::fuzz_target;

fn scratch(name: &str) -> PathBuf {
    let dir = if std::path::Path::new("/dev/shm").is_dir() {
        PathBuf::from("/dev/shm")
    } else {
        std::env::temp_dir()
    };
    dir.join(format!("tde-fuzz-eval-{}-{name}", std::process::id()))
}

/// An error with its causes.
fn text(e: impl std::fmt::Display) -> String {
    format!("{e:#}")
}

/// The CLI's path: every file streamed in chunks.
fn streamed(
    yaw: &Path,
    gt: &Path,
    imu: Option<&Path>,
    opts: &EvalOptions,
) -> Result<eval::Report, String> {
    let mut est = EstimateReader::open(yaw).map_err(text)?;
    let truth = TruthReader::open(gt).map_err(text)?;
    let gyro = match imu {
        Some(p) => Some(Box::new(GyroYawReader::open(p).map_err(text)?) as Box<dyn SampleSource>),
        None => None,
    };
    let mut ev = Evaluator::from_sources(est.kind(), Box::new(truth), gyro, opts).map_err(text)?;
    let mut chunk = Vec::new();
    while est.next_chunk(&mut chunk).map_err(text)? {
        for &(t, v) in &chunk {
            ev.push(t, v).map_err(text)?;
        }
    }
    ev.finish(est.missing()).map_err(text)
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
    let truth = eval::read_gt(&gt);
    let gyro = eval::read_gyro_yaw(&imu);
    if let Ok(truth) = truth {
        let opts = EvalOptions {
            resample: if sel & 1 == 0 {
                Resample::Hold
            } else {
                Resample::Linear
            },
            arre_step_s: [eval::ARRE_STEP_S, 1e-3, 1e-9, 10.0][usize::from(sel >> 1) & 3],
            plot_points: sel & 8 != 0,
        };
        // A gyro file that does not read is left out of both.
        let stream = streamed(&yaw, &gt, gyro.is_ok().then_some(imu.as_path()), &opts);
        let whole = eval::read_estimate(&yaw)
            .and_then(|est| eval::evaluate(&est, &truth, gyro.as_ref().ok(), &opts));
        match (&stream, &whole) {
            (Ok(a), Ok(b)) => {
                // NaN figures (a constant signal's correlation) compare by their text.
                assert_eq!(format!("{a:?}"), format!("{b:?}"), "streamed vs in memory");
                let _ = a.to_text();
            }
            (Err(_), Err(_)) => {}
            _ => panic!(
                "streamed {:?} but in memory {:?}",
                stream.as_ref().map(|_| ()),
                whole.as_ref().map(|_| ())
            ),
        }
    }
    for p in [&yaw, &gt, &imu] {
        let _ = std::fs::remove_file(p);
    }
});
