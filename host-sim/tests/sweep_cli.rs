//! `host-sim sweep`: the public CSV interface, the plot, and the error convention.

use crate::common::host_sim;

#[test]
fn sweep_writes_the_documented_csv_and_plot() {
    let dir = tempfile::tempdir().expect("tempdir");
    for model in ["fixed", "float"] {
        let csv = dir.path().join(format!("{model}.csv"));
        let png = dir.path().join(format!("{model}.png"));
        let out = host_sim()
            .args(["sweep", "--model", model, "--out"])
            .arg(&csv)
            .arg("--plot")
            .arg(&png)
            .output()
            .expect("run host-sim");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = std::fs::read_to_string(&csv).expect("csv");
        let rows: Vec<&str> = text.lines().collect();
        assert_eq!(rows[0], "dt_ms,spikes,first_spike_ms");
        assert_eq!(rows.len(), 1 + 1001, "0 to 100 ms in 0.1 ms steps");
        // model.md's reference points (first spike to the µs; the oracle's exact time rounds to
        // the same 3 decimals except where the table rounds up).
        let row = |dt: &str| {
            rows.iter()
                .find(|r| r.starts_with(&format!("{dt},")))
                .copied()
                .expect("row")
        };
        assert!(row("0.0").starts_with("0.0,33,0.51"), "{}", row("0.0"));
        assert!(row("20.0").starts_with("20.0,11,1.46"), "{}", row("20.0"));
        assert!(row("50.0").starts_with("50.0,1,10.08"), "{}", row("50.0"));
        assert_eq!(row("60.0"), "60.0,0,");
        assert_eq!(row("100.0"), "100.0,0,");
        let png_bytes = std::fs::read(&png).expect("png");
        assert_eq!(&png_bytes[..8], b"\x89PNG\r\n\x1a\n");
    }
}

#[test]
fn bad_flags_give_one_error_line_and_exit_code_2() {
    let out = host_sim()
        .args(["sweep", "--model", "quantum", "--out", "x.csv"])
        .output()
        .expect("run host-sim");
    assert_eq!(out.status.code(), Some(2));
    let out = host_sim()
        .args(["sweep", "--out", "/nonexistent-dir/x.csv"])
        .output()
        .expect("run host-sim");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with("error: "), "{err}");
}
