//! `host-sim synth` writes the documented files; `host-sim eval` prints the figures.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::host_sim;

fn run_ok(cmd: &mut Command) -> String {
    let out = cmd.output().expect("run host-sim");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("utf-8")
}

/// A small, short sequence (fast in debug builds).
fn synth(dir: &Path) {
    let out = run_ok(host_sim().args(["synth", "--out"]).arg(dir).args([
        "--width",
        "64",
        "--height",
        "48",
        "--focal-px",
        "45",
        "--duration",
        "0.3",
        "--motion",
        "sinusoid",
        "--max-rate",
        "1.0",
        "--seed",
        "3",
    ]));
    assert!(out.contains("events"), "{out}");
}

/// Writes `t_s,<column>` from the ground truth's wy, scaled.
fn estimate_from_gt(gt: &Path, out: &Path, column: &str, scale: f64) {
    let text = std::fs::read_to_string(gt).unwrap();
    let mut s = format!("t_s,{column}\n");
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let wy: f64 = f[2].parse().unwrap();
        s.push_str(&format!("{},{}\n", f[0], wy * scale));
    }
    std::fs::write(out, s).unwrap();
}

/// A rendered sequence in a temporary directory (kept while the first value lives), and an
/// estimate of its ground truth's yaw rate times `scale` as column `column`: the directory, the
/// sequence's path and the estimate's.
fn sequence_with_estimate(column: &str, scale: f64) -> (tempfile::TempDir, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("seq");
    synth(&seq);
    let yaw = dir.path().join("yaw.csv");
    estimate_from_gt(&seq.join("gt.csv"), &yaw, column, scale);
    (dir, seq, yaw)
}

#[test]
fn synth_writes_the_documented_files() {
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("seq");
    synth(&seq);
    let events = std::fs::read_to_string(seq.join("events.txt")).unwrap();
    let mut last = 0.0;
    let mut n = 0;
    for line in events.lines() {
        let f: Vec<&str> = line.split(' ').collect();
        assert_eq!(f.len(), 4, "{line}");
        assert_eq!(f[0].split('.').nth(1).map(str::len), Some(6), "{line}");
        let t: f64 = f[0].parse().unwrap();
        assert!(t >= last && t <= 0.3);
        last = t;
        assert!(f[1].parse::<u16>().unwrap() < 64 && f[2].parse::<u16>().unwrap() < 48);
        assert!(f[3] == "0" || f[3] == "1");
        n += 1;
    }
    assert!(n > 100, "{n} events");
    let gt = std::fs::read_to_string(seq.join("gt.csv")).unwrap();
    let mut lines = gt.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t_s,wx,wy,wz,yaw_rad,heading_rad,pitch_rad,roll_rad,speed_mps"
    );
    assert_eq!(lines.count(), 301);
    let imu = std::fs::read_to_string(seq.join("imu.txt")).unwrap();
    assert_eq!(imu.lines().next().unwrap().split(' ').count(), 7);
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(seq.join("meta.json")).unwrap()).unwrap();
    assert_eq!(meta["width"], 64);
    assert_eq!(meta["height"], 48);
    assert_eq!(meta["fx"], 45.0);
    assert_eq!(meta["cx"], 31.5);
    assert_eq!(meta["camera"]["fy"], 45.0);
    assert_eq!(meta["stats"]["events"], n);
    assert_eq!(meta["config"]["seed"], 3);
}

#[test]
fn eval_prints_the_figures_and_plots() {
    let (dir, seq, yaw) = sequence_with_estimate("yaw_rate_rad_s", 1.1);
    let png = dir.path().join("eval.png");
    let text = run_ok(
        host_sim()
            .args(["eval", "--yaw"])
            .arg(&yaw)
            .arg("--gt")
            .arg(seq.join("gt.csv"))
            .arg("--imu")
            .arg(seq.join("imu.txt"))
            .arg("--plot")
            .arg(&png),
    );
    for key in [
        "RMSE",
        "RMSE / peak",
        "correlation",
        "ARRE",
        "final heading error",
        "gyro:",
    ] {
        assert!(text.contains(key), "missing {key}: {text}");
    }
    let bytes = std::fs::read(&png).unwrap();
    assert!(bytes.starts_with(b"\x89PNG"));

    let json = run_ok(
        host_sim()
            .args(["eval", "--json", "--yaw"])
            .arg(&yaw)
            .arg("--gt")
            .arg(seq.join("gt.csv"))
            .arg("--imu")
            .arg(seq.join("imu.txt")),
    );
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let corr = v["estimate"]["correlation"].as_f64().unwrap();
    assert!((corr - 1.0).abs() < 1e-6, "{corr}");
    let rel = v["estimate"]["rmse_rel_peak"].as_f64().unwrap();
    assert!(rel > 0.01 && rel < 0.1, "{rel}");
    // The simulated gyro: 0.01 rad/s bias.
    let gyro_bias = v["gyro"]["mean_error_rad_s"].as_f64().unwrap();
    assert!((gyro_bias.abs() - 0.01).abs() < 0.003, "{gyro_bias}");
    // The estimate from standard input (`--yaw -`): the same report.
    let piped = run_ok(
        host_sim()
            .args(["eval", "--json", "--yaw", "-", "--gt"])
            .arg(seq.join("gt.csv"))
            .arg("--imu")
            .arg(seq.join("imu.txt"))
            .stdin(std::fs::File::open(&yaw).unwrap()),
    );
    assert_eq!(piped, json);
}

#[test]
fn without_ground_truth_the_gyro_is_the_reference() {
    // A recording with an IMU and no ground truth (a real camera's): the estimate against the
    // gyro, which reads the truth with a 0.01 rad/s bias.
    let (_dir, seq, yaw) = sequence_with_estimate("yaw_rate_rad_s", 1.0);
    let json = run_ok(
        host_sim()
            .args(["eval", "--json", "--yaw"])
            .arg(&yaw)
            .arg("--imu")
            .arg(seq.join("imu.txt")),
    );
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let corr = v["estimate"]["correlation"].as_f64().unwrap();
    assert!(corr > 0.99, "{corr}");
    let bias = v["estimate"]["mean_error_rad_s"].as_f64().unwrap();
    assert!((bias.abs() - 0.01).abs() < 0.003, "{bias}");
    assert!(v["gyro"].is_null(), "{json}");
    let text = run_ok(
        host_sim()
            .args(["eval", "--yaw"])
            .arg(&yaw)
            .arg("--imu")
            .arg(seq.join("imu.txt")),
    );
    assert!(text.starts_with("reference: the gyro of"), "{text}");
    // Neither: a one-line error naming both.
    let out = host_sim()
        .args(["eval", "--yaw"])
        .arg(&yaw)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--gt"), "{err}");
}

#[test]
fn eval_of_a_normalized_readout() {
    let (_dir, seq, yaw) = sequence_with_estimate("yaw_norm", 0.3);
    let text = run_ok(
        host_sim()
            .args(["eval", "--yaw"])
            .arg(&yaw)
            .arg("--gt")
            .arg(seq.join("gt.csv")),
    );
    assert!(text.contains("normalized"), "{text}");
    assert!(text.contains("after scale fit"), "{text}");
}

#[test]
fn eval_errors_are_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let yaw = dir.path().join("yaw.csv");
    std::fs::write(&yaw, "time,value\n0,1\n").unwrap();
    let out = host_sim()
        .args(["eval", "--yaw"])
        .arg(&yaw)
        .arg("--gt")
        .arg(dir.path().join("missing.csv"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.starts_with("error: "), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
}

#[test]
fn eval_reads_the_flags() {
    // Ground truth 0 then 1 rad/s; the estimate is 0.5 everywhere, flagged "no evidence" (2)
    // over the first half. RMSE takes the values as they are; the flag figures count the
    // flagged half, the RMS output takes it as 0, and the RMSE where answered leaves it out.
    let dir = tempfile::tempdir().unwrap();
    let (gt, yaw) = (dir.path().join("gt.csv"), dir.path().join("yaw.csv"));
    let (mut g, mut y) = (
        String::from("t_s,yaw_rate\n"),
        String::from("t_s,yaw_rate_rad_s,flags\n"),
    );
    for i in 0..100 {
        let t = f64::from(i) * 0.01;
        g.push_str(&format!("{t},{}\n", if i < 50 { 0.0 } else { 1.0 }));
        y.push_str(&format!("{t},0.5,{}\n", if i < 50 { 2 } else { 0 }));
    }
    std::fs::write(&gt, g).unwrap();
    std::fs::write(&yaw, y).unwrap();
    let json = run_ok(
        host_sim()
            .args(["eval", "--json", "--yaw"])
            .arg(&yaw)
            .arg("--gt")
            .arg(&gt),
    );
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let rmse = v["estimate"]["rmse_rad_s"].as_f64().unwrap();
    assert!((rmse - 0.5).abs() < 1e-9, "{rmse}");
    let f = &v["flags"];
    let share = f["no_evidence_share"].as_f64().unwrap();
    assert!((share - 0.5).abs() < 0.02, "{share}");
    assert_eq!(f["no_evidence_while_turning"].as_f64().unwrap(), 0.0);
    let rms = f["rms_answered_rad_s"].as_f64().unwrap();
    assert!((rms - 0.5 * 0.5f64.sqrt()).abs() < 0.01, "{rms}");
    // Where it answers (the second half, 1 rad/s), it is 0.5 off: half the peak.
    let answered = f["rmse_answered_rad_s"].as_f64().unwrap();
    assert!((answered - 0.5).abs() < 0.02, "{answered}");
    let rel = f["rmse_answered_rel_peak"].as_f64().unwrap();
    assert!((rel - 0.5).abs() < 0.02, "{rel}");
    // Without a flags column there are no flag figures.
    let plain = dir.path().join("plain.csv");
    let text = std::fs::read_to_string(&yaw).unwrap();
    let body: String = text
        .lines()
        .skip(1)
        .map(|l| l.rsplit_once(',').unwrap().0.to_string() + "\n")
        .collect();
    std::fs::write(&plain, format!("t_s,yaw_rate_rad_s\n{body}")).unwrap();
    let json = run_ok(
        host_sim()
            .args(["eval", "--json", "--yaw"])
            .arg(&plain)
            .arg("--gt")
            .arg(&gt),
    );
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert!(v["flags"].is_null(), "{}", v["flags"]);
}

#[test]
fn a_static_truth_says_which_figures_it_has_no_value_for() {
    // A static camera's ground truth and an estimate flagged "no evidence" throughout: the
    // figures relative to the peak and to turning samples have no value, and say why.
    let dir = tempfile::tempdir().unwrap();
    let gt = dir.path().join("gt.csv");
    let yaw = dir.path().join("yaw.csv");
    let mut truth = String::from("t_s,yaw_rate\n");
    let mut estimate = String::from("t_s,yaw_rate_rad_s,flags\n");
    for k in 0..200 {
        let t = f64::from(k) * 1e-3;
        truth.push_str(&format!("{t},0\n"));
        estimate.push_str(&format!("{t},0,2\n"));
    }
    std::fs::write(&gt, truth).unwrap();
    std::fs::write(&yaw, estimate).unwrap();
    let out = run_ok(
        host_sim()
            .args(["eval", "--yaw"])
            .arg(&yaw)
            .arg("--gt")
            .arg(&gt),
    );
    assert!(!out.contains("NaN"), "{out}");
    assert!(out.contains("the truth is 0 throughout"), "{out}");
    assert!(out.contains("|gt| never reaches 0.05 rad/s"), "{out}");
    assert!(out.contains("100.0 % of the grid"), "{out}");
}
