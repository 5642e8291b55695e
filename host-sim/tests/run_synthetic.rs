//! The calibrated readout on the synthetic development sequences: the fixed-point pipeline (the
//! firmware's code) reaches correlation >= 0.88 with the ground-truth yaw rate and RMSE <= 25 %
//! of its peak on each, with no scaling of the output (measured: 0.938 / 0.971 / 0.898 and
//! 23.4 / 13.6 / 18.8 %; the noise texture of dev01 decodes about 20 % low, see the README's
//! figures), and the f64 oracle agrees.

use host_sim::eval::metrics::{pearson, resample, rmse, Resample};
use host_sim::eval::Series;
use host_sim::formats;
use host_sim::pipeline::{run_pipeline, Model, RunOptions};
use host_sim::testdata::shared_data;

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
        let out = run_pipeline(&RunOptions::default(), &rec).expect("run");
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
        // The f64 oracle on the same events: the fixed-point pipeline follows it.
        let float_args = RunOptions {
            model: Model::Float,
            ..RunOptions::default()
        };
        let float = run_pipeline(&float_args, &rec).expect("run float");
        let (a, b): (Vec<f64>, Vec<f64>) = out
            .samples
            .iter()
            .zip(&float.samples)
            .map(|(x, y)| (x.1, y.1))
            .unzip();
        let fixed_vs_float = pearson(&a, &b);
        eprintln!(
            "{name}: correlation {corr:.3}, RMSE {:.1} % of peak; fixed vs float {fixed_vs_float:.4}",
            err * 100.0
        );
        assert!(corr >= 0.88, "{name}: correlation {corr:.3}");
        assert!(err <= 0.25, "{name}: RMSE {:.1} % of peak", err * 100.0);
        assert!(
            fixed_vs_float >= 0.99,
            "{name}: fixed vs float {fixed_vs_float:.4}"
        );
    }
}
