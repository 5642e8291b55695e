//! The evaluation figures on analytic signals.

use host_sim::eval::{self, metrics, EstimateKind, EvalOptions, Resample, Series};

/// A 1 kHz ground truth over 4 s: 0.5 sin(2 pi 0.4 t) rad/s.
fn gt() -> Series {
    let t: Vec<f64> = (0..=4000).map(|k| k as f64 / 1000.0).collect();
    let v = t
        .iter()
        .map(|t| 0.5 * (std::f64::consts::TAU * 0.4 * t).sin())
        .collect();
    Series { t, v }
}

fn estimate(kind: EstimateKind, series: Series) -> eval::Estimate {
    eval::Estimate {
        kind,
        series,
        missing: 0,
    }
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn perfect_estimate() {
    let g = gt();
    let r = eval::evaluate(
        &estimate(EstimateKind::RadPerSec, g.clone()),
        &g,
        None,
        &EvalOptions::default(),
    )
    .unwrap();
    let m = &r.estimate;
    assert_eq!(m.n, 4001);
    assert!(m.rmse_rad_s.abs() < 1e-12);
    assert!(close(m.correlation, 1.0, 1e-12));
    assert!(m.arre_rad.abs() < 1e-12);
    assert!(m.final_heading_error_rad.abs() < 1e-12);
    assert!(close(r.peak_gt_rad_s, 0.5, 1e-6));
    assert!(r.gyro.is_none());
}

#[test]
fn scaled_estimate() {
    let g = gt();
    let k = 1.2;
    let e = Series {
        t: g.t.clone(),
        v: g.v.iter().map(|v| k * v).collect(),
    };
    let r = eval::evaluate(
        &estimate(EstimateKind::RadPerSec, e),
        &g,
        None,
        &EvalOptions::default(),
    )
    .unwrap();
    // RMSE = (k - 1) rms(gt) = 0.2 * 0.5 / sqrt(2) over whole periods (1.6 periods: close).
    let rms_gt = (g.v.iter().map(|v| v * v).sum::<f64>() / g.v.len() as f64).sqrt();
    assert!(close(r.estimate.rmse_rad_s, 0.2 * rms_gt, 1e-12));
    assert!(close(r.estimate.rmse_rel_peak, 0.2 * rms_gt / 0.5, 1e-9));
    assert!(close(r.estimate.correlation, 1.0, 1e-12));
    // Heading error = 0.2 x the integrated heading.
    assert!(close(
        r.estimate.final_heading_error_rad,
        0.2 * r.gt_heading_rad,
        1e-12
    ));
}

#[test]
fn constant_offset_arre() {
    let g = gt();
    let c = 0.03;
    let e = Series {
        t: g.t.clone(),
        v: g.v.iter().map(|v| v + c).collect(),
    };
    let r = eval::evaluate(
        &estimate(EstimateKind::RadPerSec, e),
        &g,
        None,
        &EvalOptions::default(),
    )
    .unwrap();
    assert!(
        close(r.estimate.arre_rad, c * 0.05, 1e-12),
        "{}",
        r.estimate.arre_rad
    );
    assert!(close(r.estimate.rmse_rad_s, c, 1e-12));
    assert!(close(r.estimate.mean_error_rad_s, c, 1e-12));
    assert!(close(r.estimate.final_heading_error_rad, c * 4.0, 1e-9));
    assert!(close(r.estimate.correlation, 1.0, 1e-12));
}

#[test]
fn normalized_estimate_is_scale_fitted() {
    let g = gt();
    let e = Series {
        t: g.t.clone(),
        v: g.v.iter().map(|v| v / 0.5).collect(),
    };
    let r = eval::evaluate(
        &estimate(EstimateKind::Normalized, e),
        &g,
        None,
        &EvalOptions::default(),
    )
    .unwrap();
    assert_eq!(r.kind, EstimateKind::Normalized);
    assert!(close(r.estimate.scale.unwrap(), 0.5, 1e-12));
    assert!(r.estimate.rmse_rad_s < 1e-12);
    assert!(close(r.estimate.correlation, 1.0, 1e-12));
    assert!(r.to_text().contains("least-squares scale fit"));
}

#[test]
fn hold_versus_linear_resampling() {
    let g = gt();
    // The estimate at 100 Hz, sampled exactly from the ground truth.
    let idx: Vec<usize> = (0..=400).map(|k| k * 10).collect();
    let e = Series {
        t: idx.iter().map(|&i| g.t[i]).collect(),
        v: idx.iter().map(|&i| g.v[i]).collect(),
    };
    let est = estimate(EstimateKind::RadPerSec, e);
    let hold = eval::evaluate(&est, &g, None, &EvalOptions::default()).unwrap();
    let linear = eval::evaluate(
        &est,
        &g,
        None,
        &EvalOptions {
            resample: Resample::Linear,
            ..EvalOptions::default()
        },
    )
    .unwrap();
    // Hold lags by up to 10 ms: rmse ~ |gt'| 4.5 ms ~ 1.26 * 0.0045 / sqrt(2) = 4 mrad/s.
    assert!(hold.estimate.rmse_rad_s > 2e-3 && hold.estimate.rmse_rad_s < 6e-3);
    // Linear interpolation of a smooth signal: far smaller.
    assert!(linear.estimate.rmse_rad_s < 1e-4);
}

#[test]
fn window_is_the_overlap_and_no_overlap_is_an_error() {
    let g = gt();
    let e = Series {
        t: vec![1.0, 2.0, 3.0],
        v: vec![0.0, 0.0, 0.0],
    };
    let r = eval::evaluate(
        &estimate(EstimateKind::RadPerSec, e),
        &g,
        None,
        &EvalOptions::default(),
    )
    .unwrap();
    assert_eq!(r.estimate.n, 2001);
    assert!(close(r.t_start_s, 1.0, 1e-9) && close(r.t_end_s, 3.0, 1e-9));
    let far = Series {
        t: vec![10.0, 11.0],
        v: vec![0.0, 0.0],
    };
    assert!(eval::evaluate(
        &estimate(EstimateKind::RadPerSec, far),
        &g,
        None,
        &EvalOptions::default()
    )
    .is_err());
}

#[test]
fn gyro_figures() {
    let g = gt();
    // A gyro at 200 Hz with a 0.01 rad/s bias.
    let gy = Series {
        t: (0..=800).map(|k| k as f64 / 200.0).collect(),
        v: (0..=800)
            .map(|k| 0.5 * (std::f64::consts::TAU * 0.4 * k as f64 / 200.0).sin() + 0.01)
            .collect(),
    };
    let r = eval::evaluate(
        &estimate(EstimateKind::RadPerSec, g.clone()),
        &g,
        Some(&gy),
        &EvalOptions::default(),
    )
    .unwrap();
    let m = r.gyro.unwrap();
    assert!(close(m.mean_error_rad_s, 0.01, 1e-4));
    assert!(close(m.arre_rad, 0.01 * 0.05, 1e-5));
    assert!(close(m.final_heading_error_rad, 0.04, 1e-4));
    assert!(m.correlation > 0.999);
}

#[test]
fn arre_definition() {
    // Directly: a step error of 0.1 rad/s during one 50 ms window only.
    let t: Vec<f64> = (0..=1000).map(|k| k as f64 / 1000.0).collect();
    let gt = vec![0.0; t.len()];
    let pred: Vec<f64> = t
        .iter()
        .map(|&t| if (0.2..=0.25).contains(&t) { 0.1 } else { 0.0 })
        .collect();
    // 20 windows: [0.2, 0.25] is off by 0.1 * 0.05; the trapezoid ramps on either side put
    // 0.1 * 0.001 / 2 into each neighbouring window.
    let a = metrics::arre(&t, &pred, &gt, 0.05);
    assert!(close(a, (0.1 * 0.05 + 0.1 * 0.001) / 20.0, 1e-12), "{a}");
}

#[test]
fn parse_estimate_columns() {
    let e = eval::parse_estimate("t_s,yaw_rate_rad_s,valid\n0.0,0.1,1\n0.001,,0\n0.002,0.3,1\n")
        .unwrap();
    assert_eq!(e.kind, EstimateKind::RadPerSec);
    assert_eq!(e.series.v, vec![0.1, 0.3]);
    assert_eq!(e.missing, 1);
    let n = eval::parse_estimate("t_s,yaw_norm\n0,0.5\n1,-1\n").unwrap();
    assert_eq!(n.kind, EstimateKind::Normalized);
    assert!(eval::parse_estimate("t,foo\n0,1\n").is_err());
    assert!(eval::parse_estimate("t_s,yaw_rate_rad_s\n1,0\n0,0\n").is_err());
}

#[test]
fn ground_truth_files() {
    let dir = tempfile::tempdir().unwrap();
    let simple = dir.path().join("simple.csv");
    std::fs::write(&simple, "t_s,yaw_rate\n0.0,0.1\n0.001,0.2\n").unwrap();
    let g = eval::read_gt(&simple).unwrap();
    assert_eq!(g.v, vec![0.1, 0.2]);
    let full = dir.path().join("gt.csv");
    std::fs::write(
        &full,
        "t_s,wx,wy,wz,yaw_rad,heading_rad,pitch_rad,roll_rad,speed_mps\n0.0,0,0.3,0,0,0,0,0,0\n0.001,0,0.4,0,0,0,0,0,0\n",
    )
    .unwrap();
    assert_eq!(eval::read_gt(&full).unwrap().v, vec![0.3, 0.4]);
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "a,b\n1,2\n").unwrap();
    assert!(eval::read_gt(&bad).is_err());
}
