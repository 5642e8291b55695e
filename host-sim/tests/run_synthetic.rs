//! Acceptance of the calibrated readout on the synthetic development sequences: the fixed-point
//! pipeline (the firmware's code) reaches correlation >= 0.9 with the ground-truth yaw rate and
//! RMSE <= 20 % of its peak on each, with no scaling of the output.

use host_sim::commands::run::{run_pipeline, Args, LayoutKind, ReadoutKind};
use host_sim::eval::metrics::{pearson, resample, rmse, Resample};
use host_sim::eval::Series;
use host_sim::formats;
use host_sim::testdata::shared_data;

fn args_for(input: std::path::PathBuf) -> Args {
    Args {
        input,
        format: None,
        layout: LayoutKind::Dense,
        stride: 2,
        readout: ReadoutKind::Calibrated,
        focal_px: None,
        cx: None,
        cy: None,
        width: None,
        height: None,
        rate_hz: 1000,
        out: std::path::PathBuf::from("unused.csv"),
        plot: None,
    }
}

#[test]
fn calibrated_yaw_rate_on_every_synthetic_sequence() {
    let Some(dir) = shared_data("synthetic") else {
        return;
    };
    let mut seqs: Vec<_> = std::fs::read_dir(&dir)
        .expect("read synthetic dir")
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.join("gt.csv").is_file())
        .collect();
    seqs.sort();
    assert!(!seqs.is_empty(), "no sequences in {}", dir.display());
    for seq in seqs {
        let name = seq
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let input = seq.join("events.raw");
        let rec = formats::read(&input, None).expect("read events");
        let out = run_pipeline(&args_for(input), &rec).expect("run");
        let gt = formats::read_ground_truth(seq.join("gt.csv")).expect("gt");
        let est = Series::from_pairs(&out.samples.iter().map(|s| (s.0, s.1)).collect::<Vec<_>>());
        let t: Vec<f64> = gt.iter().map(|g| g.t_s).collect();
        let at = resample(&est, &t, Resample::Hold);
        let (mut e, mut g) = (Vec::new(), Vec::new());
        for (v, s) in at.iter().zip(&gt) {
            if let Some(v) = v {
                e.push(*v);
                g.push(s.yaw_rate_rad_s);
            }
        }
        let peak = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let (corr, err) = (pearson(&e, &g), rmse(&e, &g) / peak);
        eprintln!(
            "{name}: correlation {corr:.3}, RMSE {:.1} % of peak",
            err * 100.0
        );
        assert!(corr >= 0.9, "{name}: correlation {corr:.3}");
        assert!(err <= 0.2, "{name}: RMSE {:.1} % of peak", err * 100.0);
    }
}
