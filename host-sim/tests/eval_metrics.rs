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

/// The figures as the in-memory evaluation computes them, every series whole, with the slice
/// functions of `metrics`: the reference of the streaming evaluation.
fn reference(
    kind: EstimateKind,
    est: &Series,
    gt: &Series,
    gyro: Option<&Series>,
    mode: Resample,
) -> (Vec<f64>, eval::Metrics, Option<eval::Metrics>) {
    let (e0, e1) = (est.t[0], est.t[est.len() - 1]);
    let keep: Vec<usize> = (0..gt.len())
        .filter(|&i| gt.t[i] >= e0 - metrics::T_EPS && gt.t[i] <= e1 + metrics::T_EPS)
        .collect();
    let t: Vec<f64> = keep.iter().map(|&i| gt.t[i]).collect();
    let g: Vec<f64> = keep.iter().map(|&i| gt.v[i]).collect();
    let mut x: Vec<f64> = metrics::resample(est, &t, mode)
        .into_iter()
        .map(|v| v.unwrap_or(0.0))
        .collect();
    let peak = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let correlation = metrics::pearson(&x, &g);
    let scale = match kind {
        EstimateKind::RadPerSec => None,
        EstimateKind::Normalized => {
            let k = metrics::scale_fit(&x, &g);
            let k = if k.is_finite() { k } else { 0.0 };
            x.iter_mut().for_each(|v| *v *= k);
            Some(k)
        }
    };
    let figures = |sig: &[f64], scale: Option<f64>| {
        let rmse = metrics::rmse(sig, &g);
        let heading = *metrics::integrate(&t, sig).last().unwrap();
        let gt_heading = *metrics::integrate(&t, &g).last().unwrap();
        eval::Metrics {
            n: t.len(),
            rmse_rad_s: rmse,
            rmse_rel_peak: rmse / peak,
            correlation: metrics::pearson(sig, &g),
            mean_error_rad_s: metrics::mean_error(sig, &g),
            arre_rad: metrics::arre(&t, sig, &g, eval::ARRE_STEP_S),
            heading_rad: heading,
            final_heading_error_rad: heading - gt_heading,
            scale,
        }
    };
    let mut m = figures(&x, scale);
    m.correlation = correlation;
    let gyro = gyro.map(|gs| {
        let (first, last) = (gs.v[0], gs.v[gs.len() - 1]);
        let y: Vec<f64> = metrics::resample(gs, &t, Resample::Linear)
            .into_iter()
            .zip(&t)
            .map(|(v, &ti)| v.unwrap_or(if ti < gs.t[0] { first } else { last }))
            .collect();
        figures(&y, None)
    });
    (t, m, gyro)
}

/// Streamed figures equal the in-memory ones: bit for bit, except the correlation (one pass
/// instead of two) to 1e-12.
fn assert_same(streamed: &eval::Metrics, reference: &eval::Metrics, what: &str) {
    let same = |a: f64, b: f64| a.to_bits() == b.to_bits();
    assert_eq!(streamed.n, reference.n, "{what}: n");
    for (name, a, b) in [
        ("rmse", streamed.rmse_rad_s, reference.rmse_rad_s),
        (
            "rmse / peak",
            streamed.rmse_rel_peak,
            reference.rmse_rel_peak,
        ),
        (
            "mean error",
            streamed.mean_error_rad_s,
            reference.mean_error_rad_s,
        ),
        ("arre", streamed.arre_rad, reference.arre_rad),
        ("heading", streamed.heading_rad, reference.heading_rad),
        (
            "final heading error",
            streamed.final_heading_error_rad,
            reference.final_heading_error_rad,
        ),
    ] {
        assert!(same(a, b), "{what}: {name} {a:e} streamed, {b:e} in memory");
    }
    assert_eq!(
        streamed.scale.map(f64::to_bits),
        reference.scale.map(f64::to_bits),
        "{what}: scale"
    );
    let (a, b) = (streamed.correlation, reference.correlation);
    assert!(
        (a.is_nan() && b.is_nan()) || close(a, b, 1e-12),
        "{what}: correlation {a} streamed, {b} in memory"
    );
}

/// A deterministic pseudo-random number in [0, 1) from `k`.
fn noise(k: u64) -> f64 {
    let mut z = k.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

#[test]
fn a_long_estimate_is_streamed_to_the_in_memory_figures() {
    // 3 million estimate samples at 1 kHz (50 min), generated as the evaluation takes them (it
    // keeps none); every 997th has no value. The ground truth at 1 kHz, offset by 0.25 ms and
    // longer than the estimate (3 million grid points: the figure is decimated); the gyro at
    // 200 Hz over part of it only (held at its ends).
    const N: u64 = 3_000_000;
    let rate = |t: f64| 0.5 * (std::f64::consts::TAU * 0.05 * t).sin();
    let est_at = |k: u64| {
        let t = 2.0 + k as f64 * 1e-3;
        let v = if k % 997 == 500 {
            f64::NAN
        } else {
            1.1 * rate(t) + 0.1 * (noise(k) - 0.5)
        };
        (t, v)
    };
    let gt_t: Vec<f64> = (0..3_010_000u64)
        .map(|k| k as f64 * 1e-3 + 0.00025)
        .collect();
    let gt = Series {
        v: gt_t.iter().map(|&t| rate(t)).collect(),
        t: gt_t,
    };
    let gy_t: Vec<f64> = (0..400_000u64).map(|k| 100.0 + k as f64 / 200.0).collect();
    let gyro = Series {
        v: gy_t
            .iter()
            .enumerate()
            .map(|(k, &t)| rate(t) + 0.01 + 0.02 * (noise(k as u64 + N) - 0.5))
            .collect(),
        t: gy_t,
    };
    // The same estimate in memory, for the reference.
    let mut est = Series::default();
    for (t, v) in (0..N).map(est_at).filter(|s| s.1.is_finite()) {
        est.t.push(t);
        est.v.push(v);
    }
    let missing = (N as usize) - est.len();
    for (kind, mode) in [
        (EstimateKind::RadPerSec, Resample::Hold),
        (EstimateKind::RadPerSec, Resample::Linear),
        (EstimateKind::Normalized, Resample::Hold),
    ] {
        let opts = EvalOptions {
            resample: mode,
            ..EvalOptions::default()
        };
        let r =
            eval::evaluate_samples(kind, (0..N).map(est_at), 0, &gt, Some(&gyro), &opts).unwrap();
        let (t, m, gm) = reference(kind, &est, &gt, Some(&gyro), mode);
        let what = format!("{kind:?} {mode:?}");
        assert_eq!(r.missing_estimates, missing, "{what}");
        assert_eq!((r.t_start_s, r.t_end_s), (t[0], t[t.len() - 1]), "{what}");
        assert_same(&r.estimate, &m, &what);
        assert_same(r.gyro.as_ref().unwrap(), gm.as_ref().unwrap(), &what);
        assert!(r.estimate.n > 2_900_000, "{}", r.estimate.n);
        // The figure: at most PLOT_POINTS per line, evenly spread over the grid, the same
        // times in every line.
        let p = r.plot.unwrap();
        let n = p.gt.t.len();
        assert!(n <= host_sim::samples::PLOT_POINTS && n > host_sim::samples::PLOT_POINTS / 2);
        for line in [&p.gt_heading, &p.est, &p.est_heading] {
            assert_eq!(line.t, p.gt.t);
        }
        assert_eq!(p.gyro.unwrap().t, p.gt.t);
        assert_eq!(p.gt.t[0], t[0]);
        let step = t.len().div_ceil(n);
        assert_eq!(p.gt.t[1], t[step], "{what}");
        // The heading in the figure ends near the final one (the last point kept is within
        // one decimation step of the end).
        let h = p.est_heading.v[n - 1];
        assert!((h - r.estimate.heading_rad).abs() < 1e-2, "{h}");
    }
}

#[test]
fn a_long_ground_truth_and_gyro_are_streamed_from_their_files() {
    // The estimate of the test above, against a ground truth of 3 million rows and a gyro of
    // 400 000 rows written to files: the evaluation reads them a chunk at a time (keeping
    // none), and gives the figures of the slice functions on the series in memory, and exactly
    // the report of the in-memory evaluation. The values are written in their shortest exact
    // form, so that the files hold the very series kept here.
    use std::io::Write;
    const N: u64 = 3_000_000;
    let rate = |t: f64| 0.5 * (std::f64::consts::TAU * 0.05 * t).sin();
    let est_at = |k: u64| {
        let t = 2.0 + k as f64 * 1e-3;
        (t, 1.1 * rate(t) + 0.1 * (noise(k) - 0.5))
    };
    let dir = tempfile::tempdir().unwrap();
    let gt_path = dir.path().join("gt.csv");
    let imu_path = dir.path().join("imu.txt");
    let mut gt = Series::default();
    let mut w = std::io::BufWriter::new(std::fs::File::create(&gt_path).unwrap());
    writeln!(w, "t_s,wx,wy,wz").unwrap();
    for k in 0..3_010_000u64 {
        let t = k as f64 * 1e-3 + 0.00025;
        let v = rate(t);
        writeln!(w, "{t},0,{v},0").unwrap();
        gt.t.push(t);
        gt.v.push(v);
    }
    w.flush().unwrap();
    drop(w);
    let mut gyro = Series::default();
    let mut w = std::io::BufWriter::new(std::fs::File::create(&imu_path).unwrap());
    for k in 0..400_000u64 {
        let t = 100.0 + k as f64 / 200.0;
        let v = rate(t) + 0.01 + 0.02 * (noise(k + N) - 0.5);
        writeln!(w, "{t} 0 0 9.81 0 {v} 0").unwrap();
        gyro.t.push(t);
        gyro.v.push(v);
    }
    w.flush().unwrap();
    drop(w);
    // The same estimate in memory, for the reference.
    let mut est = Series::default();
    for (t, v) in (0..N).map(est_at) {
        est.t.push(t);
        est.v.push(v);
    }
    for (kind, mode) in [
        (EstimateKind::RadPerSec, Resample::Hold),
        (EstimateKind::Normalized, Resample::Linear),
    ] {
        let opts = EvalOptions {
            resample: mode,
            ..EvalOptions::default()
        };
        let truth = eval::TruthReader::open(&gt_path).unwrap();
        let imu = eval::GyroYawReader::open(&imu_path).unwrap();
        let mut ev =
            eval::Evaluator::from_sources(kind, Box::new(truth), Some(Box::new(imu)), &opts)
                .unwrap();
        for (t, v) in (0..N).map(est_at) {
            ev.push(t, v).unwrap();
        }
        let r = ev.finish(0).unwrap();
        let (t, m, gm) = reference(kind, &est, &gt, Some(&gyro), mode);
        let what = format!("{kind:?} {mode:?}");
        assert_eq!((r.t_start_s, r.t_end_s), (t[0], t[t.len() - 1]), "{what}");
        assert!(r.estimate.n > 2_900_000, "{}", r.estimate.n);
        assert_same(&r.estimate, &m, &what);
        assert_same(r.gyro.as_ref().unwrap(), gm.as_ref().unwrap(), &what);
        let in_memory =
            eval::evaluate_samples(kind, (0..N).map(est_at), 0, &gt, Some(&gyro), &opts).unwrap();
        assert!(r == in_memory, "{what}: the files and the series differ");
    }
    // The files read whole give the same series.
    assert!(eval::read_gt(&gt_path).unwrap() == gt);
    assert!(eval::read_gyro_yaw(&imu_path).unwrap() == gyro);
}

#[test]
fn faults_of_the_ground_truth_and_the_gyro_are_found_wherever_they_are() {
    // Read as the evaluation goes, the ground truth and the gyro are still checked to their
    // end: a fault after the estimate's span (or before it) is an error, the one the whole file
    // gave, naming the file.
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let gt_path = dir.path().join("gt.csv");
    let imu_path = dir.path().join("imu.txt");
    let write_gt = |t_at: &dyn Fn(u64) -> String| {
        let mut w = std::io::BufWriter::new(std::fs::File::create(&gt_path).unwrap());
        writeln!(w, "t_s,wx,wy,wz").unwrap();
        for k in 0..50_000u64 {
            writeln!(w, "{},0,{},0", t_at(k), noise(k) - 0.5).unwrap();
        }
    };
    let write_imu = |t_at: &dyn Fn(u64) -> String| {
        let mut w = std::io::BufWriter::new(std::fs::File::create(&imu_path).unwrap());
        for k in 0..20_000u64 {
            writeln!(w, "{} 0 0 9.81 0 {} 0", t_at(k), noise(k + 7) - 0.5).unwrap();
        }
    };
    let evaluate = |imu: bool| -> Result<eval::Report, String> {
        let truth = eval::TruthReader::open(&gt_path).map_err(|e| format!("{e:#}"))?;
        let gyro = match imu {
            true => Some(Box::new(
                eval::GyroYawReader::open(&imu_path).map_err(|e| format!("{e:#}"))?,
            ) as Box<dyn eval::SampleSource>),
            false => None,
        };
        let mut ev = eval::Evaluator::from_sources(
            EstimateKind::RadPerSec,
            Box::new(truth),
            gyro,
            &EvalOptions::default(),
        )
        .map_err(|e| format!("{e:#}"))?;
        // The estimate covers 5-6 s of the 50 s.
        for k in 0..=1000 {
            ev.push(5.0 + k as f64 * 1e-3, 0.1)
                .map_err(|e| format!("{e:#}"))?;
        }
        ev.finish(0).map_err(|e| format!("{e:#}"))
    };
    let whole = |imu: bool| {
        let r = eval::read_gt(&gt_path).and_then(|_| match imu {
            true => eval::read_gyro_yaw(&imu_path).map(drop),
            false => Ok(()),
        });
        format!("{:#}", r.unwrap_err())
    };
    let ms = |k: u64| format!("{}", k as f64 * 1e-3);
    write_imu(&|k| format!("{}", k as f64 * 5e-3));
    write_gt(&ms);
    evaluate(true).unwrap();
    let gt_name = gt_path.display().to_string();
    let imu_name = imu_path.display().to_string();
    for (what, gt_t, imu_t, imu, needle, file) in [
        (
            "ground truth going back at 40 s",
            Box::new(|k: u64| if k == 40_000 { "39".to_string() } else { ms(k) })
                as Box<dyn Fn(u64) -> String>,
            None,
            false,
            "ground-truth time goes backwards at sample 40001",
            &gt_name,
        ),
        (
            "ground truth malformed at 45 s",
            Box::new(|k: u64| if k == 45_000 { "x".to_string() } else { ms(k) }),
            None,
            false,
            "malformed line 45002",
            &gt_name,
        ),
        (
            "ground truth at one time",
            Box::new(|_| "5.5".to_string()),
            None,
            false,
            "all 50000 ground-truth samples are at one time",
            &gt_name,
        ),
        (
            "gyro going back at 90 s",
            Box::new(ms),
            Some(Box::new(|k: u64| {
                if k == 18_000 {
                    "1".to_string()
                } else {
                    format!("{}", k as f64 * 5e-3)
                }
            }) as Box<dyn Fn(u64) -> String>),
            true,
            "gyro time goes backwards at sample 18001",
            &imu_name,
        ),
        (
            "gyro not finite at 1 s",
            Box::new(ms),
            Some(Box::new(|k: u64| {
                if k == 200 {
                    "nan".to_string()
                } else {
                    format!("{}", k as f64 * 5e-3)
                }
            })),
            true,
            "malformed line 201",
            &imu_name,
        ),
    ] {
        write_gt(&gt_t);
        if let Some(t) = &imu_t {
            write_imu(&**t);
        }
        let e = evaluate(imu).unwrap_err();
        assert!(
            e.contains(needle) && e.starts_with(file.as_str()),
            "{what}: {e}"
        );
        assert_eq!(e, whole(imu), "{what}");
        write_imu(&|k| format!("{}", k as f64 * 5e-3));
    }
}

#[test]
fn running_figures_equal_the_slice_functions_on_irregular_grids() {
    use host_sim::eval::running::Running;
    // Gaps of several ARRE windows, repeated times, steps just below and above the window, on
    // clocks from 0 and from the Unix epoch.
    let dts = [0.0, 1e-4, 1e-3, 0.01, 0.049, 0.05, 0.051, 0.3, 1.7];
    let mut k = 0u64;
    let mut next = || {
        k += 1;
        noise(k)
    };
    for case in 0..60 {
        let n = 2 + (next() * 3000.0) as usize;
        let t0 = if case % 2 == 0 { 0.0 } else { 1.7e9 + next() };
        let step = [0.05, 0.01, 0.2][case % 3];
        let mut t = vec![t0];
        for _ in 1..n {
            let dt = if next() < 0.5 {
                dts[(next() * dts.len() as f64) as usize]
            } else {
                next() * 0.2
            };
            let last = t[t.len() - 1];
            t.push(last + dt);
        }
        if t[n - 1] == t[0] {
            t[n - 1] += 1.0;
        }
        let g: Vec<f64> = (0..n).map(|_| next() - 0.5).collect();
        let x: Vec<f64> = g.iter().map(|g| g + 0.2 * (next() - 0.5)).collect();
        for scale in [None, Some(0.7)] {
            let mut r = Running::new(step, scale);
            for i in 0..n {
                r.push(t[i], g[i], x[i]).unwrap();
            }
            let xs: Vec<f64> = match scale {
                Some(k) => x.iter().map(|v| v * k).collect(),
                None => x.clone(),
            };
            let m = r.metrics(1.0);
            let what = format!("case {case}, n {n}, step {step}, scale {scale:?}");
            let same = |a: f64, b: f64, name: &str| {
                assert!(a.to_bits() == b.to_bits(), "{what}: {name} {a:e} vs {b:e}");
            };
            same(m.arre_rad, metrics::arre(&t, &xs, &g, step), "arre");
            same(m.rmse_rad_s, metrics::rmse(&xs, &g), "rmse");
            same(
                m.mean_error_rad_s,
                metrics::mean_error(&xs, &g),
                "mean error",
            );
            let heading = metrics::integrate(&t, &xs)[n - 1];
            same(m.heading_rad, heading, "heading");
            let gt_heading = metrics::integrate(&t, &g)[n - 1];
            same(
                m.final_heading_error_rad,
                heading - gt_heading,
                "heading error",
            );
            same(r.scale_fit(), metrics::scale_fit(&xs, &g), "scale fit");
            let (a, b) = (m.correlation, metrics::pearson(&xs, &g));
            assert!(close(a, b, 1e-12), "{what}: correlation {a} vs {b}");
        }
    }
}

#[test]
fn the_estimate_reader_streams_what_parse_estimate_reads() {
    // 2 million rows through the chunked reader, from a generator (never a string in memory),
    // against the same text parsed whole in pieces.
    struct Rows {
        k: u64,
        n: u64,
        buf: Vec<u8>,
        pos: usize,
    }
    fn row(k: u64) -> String {
        match k {
            0 => "t_s,flags,yaw_rate_rad_s\n".into(),
            k if k % 1000 == 7 => format!("{:.6},1,\n", k as f64 * 1e-3),
            k if k % 1000 == 8 => "\n".into(),
            k => format!("{:.6},0,{:.6}\r\n", k as f64 * 1e-3, noise(k) - 0.5),
        }
    }
    impl std::io::Read for Rows {
        fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
            if self.pos == self.buf.len() {
                if self.k == self.n {
                    return Ok(0);
                }
                self.buf = row(self.k).into_bytes();
                self.pos = 0;
                self.k += 1;
            }
            let m = out.len().min(self.buf.len() - self.pos);
            out[..m].copy_from_slice(&self.buf[self.pos..self.pos + m]);
            self.pos += m;
            Ok(m)
        }
    }
    const N: u64 = 2_000_000;
    let rows = Rows {
        k: 0,
        n: N,
        buf: Vec::new(),
        pos: 0,
    };
    let mut reader = eval::EstimateReader::from_reader(std::io::BufReader::new(rows)).unwrap();
    assert_eq!(reader.kind(), EstimateKind::RadPerSec);
    let mut chunk = Vec::new();
    let (mut count, mut first, mut last) = (0u64, None, (0.0, 0.0));
    while reader.next_chunk(&mut chunk).unwrap() {
        assert!(chunk.len() <= eval::CHUNK);
        for &s in &chunk {
            first.get_or_insert(s);
            last = s;
            count += 1;
        }
    }
    let missing = reader.missing();
    assert_eq!(missing, 2000);
    assert_eq!(count + missing as u64 + 2000, N - 1);
    // The same rows, parsed whole.
    let text: String = (0..4000).map(row).collect();
    let e = eval::parse_estimate(&text).unwrap();
    assert_eq!(first, Some((e.series.t[0], e.series.v[0])));
    let tail: String = std::iter::once(row(0))
        .chain((N - 10..N).map(row))
        .collect();
    let e = eval::parse_estimate(&tail).unwrap();
    let i = e.series.len() - 1;
    assert_eq!(last, (e.series.t[i], e.series.v[i]));
}
