//! The motion regimes of `host-sim synth --regime`: their motions have the documented ranges
//! (checked on many seeds without rendering), moving objects fire only where they pass and
//! change neither the ground truth nor the IMU, and everything is deterministic for a seed.

use std::process::Command;

use host_sim::synth::motion::{Trajectory, YawTerm};
use host_sim::synth::regime::{self, Regime};
use host_sim::synth::{
    self, truth, Intrinsics, MotionKind, ObjectKind, ObjectSpec, Preset, SynthConfig, TextureKind,
};

/// Ground-truth yaw rates `wy` at 1 kHz of a configuration (no rendering).
fn gt_wy(cfg: &SynthConfig) -> Vec<f64> {
    let motion = cfg.resolve_motion();
    truth::ground_truth(&motion, cfg.duration_s, 1000.0)
        .iter()
        .map(|g| g.w[1])
        .collect()
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

/// Car: 5-10 m/s, camera 1.2-1.6 m above the ground, peak |yaw rate| 0.3-0.5 rad/s, and every
/// 4 s scene holds a bend and a lane change that moves the car sideways by about one lane
/// (3-3.7 m, less when the peak bound limits the doublet).
#[test]
fn car_regime_ranges_bends_and_lane_changes() {
    for seed in 1..=40 {
        let cfg = regime::preset(Regime::Car, seed, 4.0, Preset::Davis346);
        assert_eq!(cfg.motion, MotionKind::Car);
        assert!((5.0..10.0).contains(&cfg.speed_mps), "{}", cfg.speed_mps);
        assert!((1.2..1.6).contains(&cfg.cam_height_m) && cfg.ground);
        let wy = gt_wy(&cfg);
        let peak = max_abs(&wy);
        assert!((0.3..=0.5).contains(&peak), "seed {seed}: peak {peak}");
        let m = cfg.resolve_motion();
        let turns: Vec<(f64, f64, f64)> = m
            .yaw
            .iter()
            .filter_map(|y| match *y {
                YawTerm::Turn { t0, t1, peak } => Some((t0, t1, peak)),
                _ => None,
            })
            .collect();
        let tr = Trajectory::new(&m, cfg.duration_s);
        let (mut lanes, mut bends, mut k) = (0, 0, 0);
        while k < turns.len() {
            let (t0, t1, p) = turns[k];
            let pair = turns.get(k + 1).filter(|b| b.0 == t1 && b.2 == -p);
            let Some(&(_, t2, _)) = pair else {
                assert!((0.3..=0.5).contains(&p.abs()), "seed {seed}: bend {p}");
                bends += 1;
                k += 1;
                continue;
            };
            lanes += 1;
            assert!((2.0..=3.0 + 1e-9).contains(&(t2 - t0)), "seed {seed}");
            // Sideways shift across the doublet, perpendicular to the heading before it.
            let (a, b) = (tr.position(t0), tr.position(t2));
            let h = m.heading(t0);
            let side = (b[0] - a[0]) * h.cos() - (b[2] - a[2]) * h.sin();
            // One lane is 3-3.7 m at the mean speed; the speed varies by 10 % and the
            // lane-keeping wobble turns the car by up to 0.03 rad on the way.
            let capped = p.abs() >= 0.5 * (1.0 - 0.04) - 1e-12;
            let (lo, hi) = if capped { (0.5, 4.0) } else { (2.4, 4.5) };
            assert!(
                (lo..hi).contains(&side.abs()),
                "seed {seed}: lane change of {side} m (peak {p}, {} s)",
                t2 - t0
            );
            k += 2;
        }
        assert!(
            lanes >= 1 && bends >= 1,
            "seed {seed}: {lanes} lane changes, {bends} bends"
        );
    }
}

/// Drone: 2-5 m/s at 1.5-4 m, heading rate up to 2 rad/s (reached closely on some seed), pitch
/// and roll of a few degrees at 1-6 Hz.
#[test]
fn drone_regime_ranges() {
    let mut best = 0.0f64;
    for seed in 1..=40 {
        let cfg = regime::preset(Regime::Drone, seed, 4.0, Preset::Davis346);
        assert!((2.0..5.0).contains(&cfg.speed_mps) && (1.5..4.0).contains(&cfg.cam_height_m));
        let m = cfg.resolve_motion();
        let mut peak = 0.0f64;
        let (mut pitch, mut roll) = (0.0f64, 0.0f64);
        for k in 0..=4000 {
            let t = k as f64 * 1e-3;
            peak = peak.max(m.heading_rate(t).abs());
            let [_, p, r] = m.angles(t);
            (pitch, roll) = (pitch.max(p.abs()), roll.max(r.abs()));
        }
        assert!(peak <= 2.0 + 1e-12 && peak > 0.4, "seed {seed}: {peak}");
        best = best.max(peak);
        // A few degrees: at most 1.5 x 0.05 rad = 4.3 deg.
        for a in [pitch, roll] {
            assert!(a > 0.01 && a < 0.076, "seed {seed}: {pitch} {roll}");
        }
        for c in m.pitch.components.iter().chain(&m.roll.components) {
            assert!((1.0..=6.0).contains(&c[1]), "seed {seed}: {c:?}");
        }
        // Camera-frame yaw rate: the heading rate, plus a little cross-coupling of the wobble.
        assert!(max_abs(&gt_wy(&cfg)) < 2.1);
    }
    assert!(best > 1.8, "largest turn {best}");
}

/// Hover: a drift of 1-5 cm/s, |yaw rate| <= 0.2 rad/s in segments of at least 0.02 rad/s,
/// separated by pauses at exactly 0, with smooth ramps.
#[test]
fn hover_regime_pauses_are_exactly_zero() {
    for seed in 1..=40 {
        let cfg = regime::preset(Regime::Hover, seed, 4.0, Preset::Davis346);
        assert!((0.01..0.05).contains(&cfg.speed_mps) && (1.0..3.0).contains(&cfg.cam_height_m));
        let wy = gt_wy(&cfg);
        assert_eq!(wy[0], 0.0, "seed {seed}: starts with a pause");
        let zero = wy.iter().filter(|w| **w == 0.0).count() as f64 / wy.len() as f64;
        assert!(zero > 0.2, "seed {seed}: {zero} of the samples at 0");
        // Runs of zero and non-zero samples: moving segments are bounded on both sides by
        // pauses (unless cut by the end), their plateau is 0.02-0.2 rad/s.
        let mut runs: Vec<(bool, f64)> = Vec::new();
        for w in &wy {
            match runs.last_mut() {
                Some((moving, m)) if *moving == (*w != 0.0) => *m = m.max(w.abs()),
                _ => runs.push((*w != 0.0, w.abs())),
            }
        }
        let segments: Vec<f64> = runs.iter().filter(|r| r.0).map(|r| r.1).collect();
        assert!(
            !segments.is_empty() && runs.len() >= 3,
            "seed {seed}: {runs:?}"
        );
        for (i, &(moving, m)) in runs.iter().enumerate() {
            if moving && i + 1 < runs.len() {
                assert!((0.02..=0.2).contains(&m), "seed {seed}: plateau {m}");
            }
        }
        let jump = wy
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f64::max);
        assert!(jump < 0.004, "seed {seed}: rate jumps by {jump} in 1 ms");
    }
}

/// Objects: a static camera (no rotation at all), 1-3 objects; rotation: the default scene.
#[test]
fn objects_and_rotation_regimes() {
    for seed in 1..=20 {
        let cfg = regime::preset(Regime::Objects, seed, 4.0, Preset::Davis346);
        assert!((1..=3).contains(&cfg.objects) && cfg.ground && cfg.speed_mps == 0.0);
        let m = cfg.resolve_motion();
        for g in truth::ground_truth(&m, 4.0, 1000.0) {
            assert_eq!(g.w, [0.0; 3]);
        }
        let rot = regime::preset(Regime::Rotation, seed, 3.0, Preset::Davis240);
        let mut plain =
            SynthConfig::new(Preset::Davis240, TextureKind::Urban, MotionKind::Sinusoid);
        plain.seed = seed;
        plain.duration_s = 3.0;
        assert_eq!(rot, plain);
    }
    let counts: Vec<usize> = (1..=20)
        .map(|s| regime::preset(Regime::Objects, s, 4.0, Preset::Davis346).objects)
        .collect();
    assert!((1..=3).all(|n| counts.contains(&n)), "{counts:?}");
}

/// With a camera that drives on, a drawn object's plane stays at least its drawn depth (2 m or
/// more) ahead of the camera: the camera never drives through an object.
#[test]
fn objects_stay_ahead_of_a_driving_camera() {
    for regime in [Regime::Car, Regime::Drone] {
        for seed in 1..=20 {
            let mut cfg = regime::preset(regime, seed, 4.0, Preset::Davis346);
            cfg.objects = 3;
            let m = cfg.resolve_motion();
            let tr = Trajectory::new(&m, cfg.duration_s);
            let objects = cfg.resolve_objects(&m, Some(&tr));
            assert_eq!(objects.len(), 3);
            for o in &objects {
                assert_eq!(o.position_m[1], cfg.cam_height_m, "standing on the ground");
                let n = o.normal();
                for k in 0..=400 {
                    let t = k as f64 * 0.01;
                    let (c, p) = (o.position(t), tr.position(t));
                    let ahead: f64 = (0..3).map(|i| (c[i] - p[i]) * n[i]).sum();
                    // 1.9 m: the 10 ms grid the depth margin is computed on.
                    assert!(ahead > 1.9, "{regime:?} seed {seed} t {t}: {ahead} m");
                }
            }
        }
    }
}

/// A small static camera over the ground with one walker 4 m away crossing from left of centre
/// to the centre in 1 s.
fn walker_scene() -> SynthConfig {
    let mut cfg = SynthConfig::new(Preset::Davis346, TextureKind::Urban, MotionKind::Static);
    cfg.intrinsics = Intrinsics::centred(160, 120, 100.0);
    cfg.duration_s = 1.0;
    cfg.seed = 11;
    cfg.ground = true;
    cfg.cam_height_m = 1.5;
    cfg.sensor.noise_hz = 0.0;
    cfg.object_specs = Some(vec![ObjectSpec {
        kind: ObjectKind::Person,
        width_m: 0.5,
        height_m: 1.8,
        position_m: [-0.8, 1.5, 4.0],
        t_ref_s: 0.0,
        facing_rad: 0.0,
        speed_mps: 1.0,
    }]);
    cfg
}

/// A static camera sees events only where the walker is: in every 50 ms window, within two
/// pixels of the columns and rows it covers; nothing without it. The ground truth and the IMU
/// do not change, the object is recorded in meta.json.
#[test]
fn static_camera_objects_fire_only_where_they_pass() {
    let cfg = walker_scene();
    let seq = synth::generate(&cfg).unwrap();
    let spec = &cfg.object_specs.as_ref().unwrap()[0];
    let i = seq.intrinsics;
    let n = seq.events.len();
    assert!(n > 3000, "{n} events");
    let on = seq.events.iter().filter(|e| e.on).count();
    assert!(on > n / 5 && on < 4 * n / 5, "{on} ON of {n}");
    // The walker's rows: from 0.3 m above the camera to the ground 1.5 m below, at 4 m.
    let (r0, r1) = (i.cy - 100.0 * 0.3 / 4.0, i.cy + 100.0 * 1.5 / 4.0);
    let pose = |t: f64| synth::CameraPose {
        rot: synth::motion::rot_y(0.0),
        heading: 0.0,
        pos: [0.0; 3],
        pure_yaw: true,
        t_s: t,
    };
    let mut all = (f64::INFINITY, f64::NEG_INFINITY);
    for w in 0..20u64 {
        let (t0, t1) = (w * 50_000, (w + 1) * 50_000);
        let (a, _) = spec.columns(&pose(t0 as f64 * 1e-6), &i).unwrap();
        let (_, b) = spec.columns(&pose(t1 as f64 * 1e-6), &i).unwrap();
        all = (all.0.min(a), all.1.max(b));
        for e in seq.events.iter().filter(|e| (t0..t1).contains(&e.t_us)) {
            let (x, y) = (f64::from(e.x), f64::from(e.y));
            assert!(
                x > a - 2.0 && x < b + 2.0,
                "t {} us: x {x} outside {a}..{b}",
                e.t_us
            );
            assert!(
                y > r0 - 2.0 && y < r1 + 2.0,
                "t {} us: y {y} outside {r0}..{r1}",
                e.t_us
            );
        }
    }
    // The band it crosses is a part of the view: 37 of 160 columns.
    assert!(all.1 - all.0 < 0.3 * f64::from(i.width), "{all:?}");
    let covered = &seq.meta["objects"][0]["columns_covered"];
    assert!(
        (covered[0].as_f64().unwrap() - all.0).abs() < 1e-6,
        "{covered}"
    );
    assert_eq!(
        seq.meta["objects"][0]["spec"],
        serde_json::to_value(spec).unwrap()
    );
    assert_eq!(seq.objects, vec![spec.clone()]);

    let mut empty = cfg.clone();
    empty.object_specs = None;
    let still = synth::generate(&empty).unwrap();
    assert_eq!(still.events.len(), 0);
    assert!(still.meta.get("objects").is_none());
    assert_eq!(still.gt, seq.gt);
    assert_eq!(still.imu, seq.imu);
}

/// Drawn objects: the same seed gives the same objects and events whatever the thread count;
/// another seed other objects. Every object is recorded in meta.json.
#[test]
fn drawn_objects_are_deterministic() {
    let mut cfg = regime::preset(Regime::Objects, 5, 0.3, Preset::Davis346);
    cfg.intrinsics = Intrinsics::centred(200, 120, 130.0);
    cfg.objects = 2;
    cfg.threads = 1;
    let a = synth::generate(&cfg).unwrap();
    cfg.threads = 3;
    let b = synth::generate(&cfg).unwrap();
    assert!(!a.events.is_empty());
    assert_eq!(a.events, b.events);
    assert_eq!(a.meta["objects"], b.meta["objects"]);
    assert_eq!(a.meta["stats"], b.meta["stats"]);
    assert_eq!(a.objects.len(), 2);
    assert_eq!(a.meta["objects"].as_array().unwrap().len(), 2);
    assert_eq!(a.meta["config"]["objects"], 2);
    cfg.seed = 6;
    let c = synth::generate(&cfg).unwrap();
    assert_ne!(a.objects, c.objects);
    assert_ne!(a.events, c.events);
}

/// Objects with a moving camera: a hovering camera with a walker gives the hover's ground
/// truth and more events than without the walker, in the walker's columns.
#[test]
fn objects_with_a_moving_camera() {
    let mut cfg = regime::preset(Regime::Hover, 3, 1.5, Preset::Davis346);
    cfg.intrinsics = Intrinsics::centred(128, 96, 84.0);
    cfg.sensor.noise_hz = 0.0;
    let plain = synth::generate(&cfg).unwrap();
    cfg.objects = 1;
    let with = synth::generate(&cfg).unwrap();
    assert_eq!(plain.gt, with.gt);
    assert_eq!(plain.imu, with.imu);
    let cols = &with.meta["objects"][0]["columns_covered"];
    let (a, b) = (cols[0].as_f64().unwrap(), cols[1].as_f64().unwrap());
    let inside = |s: &synth::Sequence| {
        s.events
            .iter()
            .filter(|e| f64::from(e.x) >= a && f64::from(e.x) <= b)
            .count()
    };
    assert!(
        inside(&with) > inside(&plain) + 500,
        "{} vs {} events in columns {a}..{b}",
        inside(&with),
        inside(&plain)
    );
}

/// `host-sim synth --regime` writes the regime's scene; explicit flags override its values.
#[test]
fn regime_flag_and_overrides() {
    let dir = tempfile::tempdir().unwrap();
    let run = |out: &str, extra: &[&str]| -> serde_json::Value {
        let path = dir.path().join(out);
        let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args([
                "synth",
                "--width",
                "64",
                "--height",
                "48",
                "--focal-px",
                "42",
            ])
            .args(["--duration", "0.2", "--seed", "3", "--out"])
            .arg(&path)
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        for f in ["events.txt", "gt.csv", "imu.txt"] {
            assert!(path.join(f).is_file(), "{f}");
        }
        let text = std::fs::read_to_string(path.join("meta.json")).unwrap();
        serde_json::from_str(&text).unwrap()
    };
    let m = run("objects", &["--regime", "objects"]);
    let expected = regime::preset(Regime::Objects, 3, 0.2, Preset::Davis346);
    assert_eq!(m["name"], "davis346_urban_objects");
    assert_eq!(m["config"]["objects"], expected.objects);
    assert_eq!(m["objects"].as_array().unwrap().len(), expected.objects);
    let height = m["config"]["cam_height_m"].as_f64().unwrap();
    assert!((height - expected.cam_height_m).abs() < 1e-12, "{height}");
    assert_eq!(m["motion"]["profile"], "static");

    let m = run(
        "car",
        &[
            "--regime",
            "car",
            "--speed",
            "7",
            "--camera-height",
            "2",
            "--objects",
            "1",
        ],
    );
    assert_eq!(m["config"]["motion"], "car");
    assert_eq!(m["config"]["speed_mps"], 7.0);
    assert_eq!(m["config"]["cam_height_m"], 2.0);
    assert_eq!(m["config"]["max_rate"], 0.5);
    assert_eq!(m["objects"].as_array().unwrap().len(), 1);
    assert_eq!(m["scene"]["ground_plane"]["height_m"], 2.0);
}
