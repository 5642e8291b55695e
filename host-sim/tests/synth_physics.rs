//! Physical sanity of the generated events: image flow of a pure yaw, sign convention, event
//! rate against speed and contrast, ground truth and gyro.

use std::collections::HashMap;

use host_sim::synth::{self, Event, MotionKind, MotionSpec, Preset, SynthConfig, TextureKind};

/// A pure constant yaw at `w` rad/s on a small wide-angle sensor (128 x 96, f = 80 px).
fn constant_yaw(w: f64, duration_s: f64, texture: TextureKind) -> SynthConfig {
    let mut cfg = SynthConfig::new(Preset::Davis240, texture, MotionKind::Constant);
    cfg.intrinsics = synth::Intrinsics::centred(128, 96, 80.0);
    cfg.motion_spec = Some(MotionSpec::constant_yaw(w));
    cfg.duration_s = duration_s;
    cfg.sensor.noise_hz = 0.0;
    cfg.seed = 4;
    cfg
}

/// Signed event-count image (`[x][y]`, ON +1, OFF -1) of the events in `[t0, t1)` µs.
fn image(events: &[Event], t0: u64, t1: u64, w: usize, h: usize) -> Vec<Vec<f64>> {
    let mut img = vec![vec![0.0; h]; w];
    for e in events.iter().filter(|e| e.t_us >= t0 && e.t_us < t1) {
        img[usize::from(e.x)][usize::from(e.y)] += if e.on { 1.0 } else { -1.0 };
    }
    img
}

/// The image smoothed along x with a Gaussian of 1 px std (so that the sub-pixel peak of the
/// correlation is not pulled to whole pixels).
fn smooth_x(img: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let k: Vec<f64> = (-3i64..=3).map(|i| (-(i * i) as f64 / 2.0).exp()).collect();
    let w = img.len() as i64;
    let mut out = vec![vec![0.0; img[0].len()]; img.len()];
    for x in 0..w {
        for (j, kj) in k.iter().enumerate() {
            let xs = (x + j as i64 - 3).clamp(0, w - 1) as usize;
            for (o, v) in out[x as usize].iter_mut().zip(&img[xs]) {
                *o += kj * v;
            }
        }
    }
    out
}

/// Horizontal shift (px, sub-pixel) of the column band `[xa, xb]` between event images taken
/// `gap_us` apart, summing the cross-correlation over many window pairs.
fn measured_shift(events: &[Event], xa: usize, xb: usize, gap_us: u64, end_us: u64) -> f64 {
    let (w, h) = (128, 96);
    let max_s = 20i64;
    let mut corr = vec![0.0; (2 * max_s + 1) as usize];
    let win = 5_000;
    let mut t = 20_000;
    while t + gap_us + win <= end_us {
        let a = smooth_x(&image(events, t, t + win, w, h));
        let b = smooth_x(&image(events, t + gap_us, t + gap_us + win, w, h));
        for (k, s) in (-max_s..=max_s).enumerate() {
            for (x, col) in a.iter().enumerate().take(xb + 1).skip(xa) {
                let xs = x as i64 + s;
                if xs < 0 || xs >= w as i64 {
                    continue;
                }
                for (p, q) in col.iter().zip(&b[xs as usize]) {
                    corr[k] += p * q;
                }
            }
        }
        t += 10_000;
    }
    let (k, _) = corr
        .iter()
        .enumerate()
        .max_by(|p, q| p.1.total_cmp(q.1))
        .unwrap();
    assert!(
        k > 0 && k < corr.len() - 1,
        "peak at the edge of the search"
    );
    let (cm, c0, cp) = (corr[k - 1], corr[k], corr[k + 1]);
    let delta = 0.5 * (cm - cp) / (cm - 2.0 * c0 + cp);
    (k as i64 - max_s) as f64 + delta
}

/// Constant yaw at 1 rad/s: the events of a band of columns move left by what the pinhole
/// geometry predicts, i.e. at `w (f + (x - cx)^2 / f)` px/s, faster towards the image edges.
#[test]
fn yaw_flow_matches_geometry_and_sign() {
    let w = 1.0;
    let cfg = constant_yaw(w, 0.8, TextureKind::Urban);
    let seq = synth::generate(&cfg).unwrap();
    let intr = seq.intrinsics;
    let (f, cx) = (intr.fx, intr.cx);
    let end_us = (cfg.duration_s * 1e6) as u64;
    let mut speeds = Vec::new();
    for x0 in [cx - 40.0, cx, cx + 40.0] {
        let (xa, xb) = ((x0 - 10.0).round() as usize, (x0 + 10.0).round() as usize);
        // Several gaps, so that what is left of sub-pixel bias averages out.
        let (mut measured, mut exact, mut instantaneous) = (0.0, 0.0, 0.0);
        for gap_s in [0.04, 0.05, 0.06, 0.07] {
            let shift = measured_shift(&seq.events, xa, xb, (gap_s * 1e6) as u64, end_us);
            assert!(
                shift < 0.0,
                "positive yaw must move events left (x0 {x0}: {shift})"
            );
            measured += shift;
            // Exact displacement of a point at column x after the camera turned by w gap:
            // x' = cx + f tan(atan((x - cx) / f) - w gap), averaged over the band.
            let ex = (xa..=xb)
                .map(|x| {
                    let a = ((x as f64 - cx) / f).atan();
                    cx + f * (a - w * gap_s).tan() - x as f64
                })
                .sum::<f64>()
                / (xb - xa + 1) as f64;
            exact += ex;
            // The instantaneous flow -w (f + (x - cx)^2 / f) at the middle of the path.
            let xm = 0.5 * (xa + xb) as f64 + 0.5 * ex;
            instantaneous += intr.yaw_flow_px_s(xm, w) * gap_s;
        }
        assert!(
            (measured / exact - 1.0).abs() < 0.04,
            "x0 {x0}: measured shifts {measured:.3} px, geometry {exact:.3} px"
        );
        assert!(
            (measured / instantaneous - 1.0).abs() < 0.05,
            "x0 {x0}: measured {measured:.3} px, w (f + (x-cx)^2/f) gives {instantaneous:.3} px"
        );
        speeds.push(measured);
    }
    // The quadratic term: the bands 40 px off centre move 20-25 % faster than the centre.
    assert!(
        speeds[0] / speeds[1] > 1.15 && speeds[2] / speeds[1] > 1.15,
        "{speeds:?}"
    );
}

#[test]
fn event_rate_scales_with_speed() {
    // The same angle swept at two speeds: about the same events, so the rate doubles.
    let slow = synth::generate(&constant_yaw(0.5, 0.3, TextureKind::Urban)).unwrap();
    let fast = synth::generate(&constant_yaw(1.0, 0.15, TextureKind::Urban)).unwrap();
    let (ns, nf) = (slow.events.len() as f64, fast.events.len() as f64);
    assert!(ns > 1000.0, "{ns}");
    let ratio = (nf / 0.15) / (ns / 0.3);
    assert!(
        (1.8..2.2).contains(&ratio),
        "rate ratio {ratio} (slow {ns}, fast {nf})"
    );
}

/// Doubling the log contrast of the texture roughly doubles the events. Somewhat more than
/// double, because texture details below one threshold start to produce events.
#[test]
fn event_rate_scales_with_contrast() {
    for tex in [TextureKind::Urban, TextureKind::Noise] {
        let mut lo = constant_yaw(0.8, 0.15, tex);
        let mut hi = lo.clone();
        lo.contrast = 2.0;
        hi.contrast = 4.0;
        let n_lo = synth::generate(&lo).unwrap().events.len() as f64;
        let n_hi = synth::generate(&hi).unwrap().events.len() as f64;
        assert!(n_lo > 1000.0, "{n_lo}");
        let ratio = n_hi / n_lo;
        assert!(
            (1.8..2.8).contains(&ratio),
            "{tex:?}: contrast x2 gave x{ratio}"
        );
    }
}

#[test]
fn no_motion_no_signal_events() {
    let mut cfg = constant_yaw(0.0, 0.1, TextureKind::Urban);
    cfg.sensor.noise_hz = 1.0;
    let seq = synth::generate(&cfg).unwrap();
    assert_eq!(seq.stats.signal_events, 0);
    // 128 x 96 px x 1 Hz x 0.1 s = 1229 noise events expected.
    assert!(
        (1000..1450).contains(&seq.events.len()),
        "{}",
        seq.events.len()
    );
}

#[test]
fn ground_truth_and_gyro_are_consistent() {
    let mut cfg = SynthConfig::new(Preset::Davis240, TextureKind::Urban, MotionKind::Car);
    cfg.intrinsics = synth::Intrinsics::centred(48, 36, 40.0);
    cfg.duration_s = 0.5;
    let seq = synth::generate(&cfg).unwrap();
    assert_eq!(seq.gt.len(), 501);
    assert_eq!(seq.imu.len(), 501);
    // yaw_rad is the integral of wy.
    let mut psi = 0.0;
    for w in seq.gt.windows(2) {
        psi += 0.5 * (w[0].w[1] + w[1].w[1]) * (w[1].t_s - w[0].t_s);
        assert!((psi - w[1].yaw_rad).abs() < 1e-6);
    }
    // wy follows the heading rate (pitch and roll are small).
    for g in &seq.gt {
        let hr = seq.motion.heading_rate(g.t_s);
        assert!(
            (g.w[1] - hr).abs() < 0.02 * hr.abs() + 1e-3,
            "{g:?} vs {hr}"
        );
        assert!(g.speed_mps > 5.0);
    }
    // The gyro is wy plus a 0.01 rad/s bias plus noise (0.00015 * sqrt(1000) = 0.0047 rad/s).
    let n = seq.imu.len() as f64;
    let mean_err: f64 = seq
        .imu
        .iter()
        .zip(&seq.gt)
        .map(|(i, g)| i.gyro[1] - g.w[1])
        .sum::<f64>()
        / n;
    assert!((mean_err.abs() - 0.01).abs() < 0.002, "{mean_err}");
    // At (nearly) constant speed the accelerometer sees gravity up: ay ~ -9.81.
    let ay: f64 = seq.imu.iter().map(|i| i.acc[1]).sum::<f64>() / n;
    assert!((ay + 9.81).abs() < 0.1, "{ay}");
}

/// The adaptive time step is fine enough: ten times smaller steps move the timestamps of the
/// same events by about a µs (a few events near a turning point of the motion, where the
/// crossing time is ill-conditioned, move more).
#[test]
fn timestamps_converge_with_the_time_step() {
    let mut cfg = SynthConfig::new(Preset::Davis240, TextureKind::Urban, MotionKind::Sinusoid);
    cfg.intrinsics = synth::Intrinsics::centred(96, 72, 60.0);
    cfg.duration_s = 0.3;
    cfg.max_rate = 1.0;
    cfg.sensor.noise_hz = 0.0;
    cfg.sensor.refractory_us = 0;
    let coarse = synth::generate(&cfg).unwrap();
    cfg.max_change /= 10.0;
    cfg.dt_max_s /= 10.0;
    let fine = synth::generate(&cfg).unwrap();
    assert!(fine.stats.renders > 5 * coarse.stats.renders);
    let per_pixel = |ev: &[Event]| {
        let mut m: HashMap<(u16, u16), Vec<(u64, bool)>> = HashMap::new();
        for e in ev {
            m.entry((e.x, e.y)).or_default().push((e.t_us, e.on));
        }
        m
    };
    let (a, b) = (per_pixel(&coarse.events), per_pixel(&fine.events));
    let mut diffs = Vec::new();
    for (pixel, ea) in &a {
        let Some(eb) = b.get(pixel) else { continue };
        if ea.len() == eb.len() && ea.iter().zip(eb).all(|(p, q)| p.1 == q.1) {
            diffs.extend(ea.iter().zip(eb).map(|(p, q)| p.0.abs_diff(q.0)));
        }
    }
    let (na, nb) = (coarse.events.len() as f64, fine.events.len() as f64);
    assert!((na / nb - 1.0).abs() < 0.02, "{na} vs {nb} events");
    assert!(
        diffs.len() as f64 > 0.9 * na,
        "only {} events matched",
        diffs.len()
    );
    diffs.sort_unstable();
    let q = |f: f64| diffs[((diffs.len() - 1) as f64 * f) as usize];
    assert!(
        q(0.5) <= 2 && q(0.9) <= 10,
        "median {} µs, p90 {} µs",
        q(0.5),
        q(0.9)
    );
}
