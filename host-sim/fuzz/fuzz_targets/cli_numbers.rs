//! The number options of `host-sim run` (and through `Camera`, of `aer-stream`) on arbitrary
//! text: `--focal-px`, `--cx`, `--cy`, `--width`, `--height`, `--stride`, `--rate-hz`,
//! `--tau-a-ms`, with either model and layout and readout, on a small recording. Every value is
//! parsed by the command line and then runs or is refused with an error; never a panic, and a
//! run gives finite samples.
#![no_main]

use host_sim::cli::{Cli, Command};
use host_sim::pipeline::run_pipeline;
use host_sim::formats::{Format, Event64, Recording};
use libfuzzer_sys::fuzz_target;

const FLAGS: [&str; 8] = [
    "--focal-px",
    "--cx",
    "--cy",
    "--width",
    "--height",
    "--stride",
    "--rate-hz",
    "--tau-a-ms",
];

/// Values at the edges of what the options take.
const SPECIAL: [&str; 16] = [
    "nan", "inf", "-inf", "1e9", "1e-300", "-5", "0", "1", "65535", "65536", "2048", "2049",
    "1000000", "3", "-0", "1e308",
];

/// An edge sweeping right to left over a 64 x 32 sensor for 40 ms.
fn recording() -> Recording {
    let events = (0..400u64)
        .flat_map(|k| {
            (0..32u16).step_by(8).map(move |y| Event64 {
                t_us: 1000 + k * 100,
                x: 63 - (k / 8 % 60) as u16,
                y,
                on: k % 16 < 8,
            })
        })
        .collect();
    Recording {
        events,
        width: Some(64),
        height: Some(32),
        intrinsics: None,
        gyro: None,
        format: Format::Csv,
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&sel, rest)) = data.split_first() else {
        return;
    };
    let text = String::from_utf8_lossy(rest);
    let mut argv = vec![
        "host-sim".to_string(),
        "run".into(),
        "rec.csv".into(),
        "--out".into(),
        "y.csv".into(),
        "--model".into(),
        if sel & 1 == 0 { "fixed" } else { "float" }.into(),
        "--layout".into(),
        if sel & 2 == 0 { "dense" } else { "paper-boxes" }.into(),
        "--readout".into(),
        if sel & 4 == 0 {
            "calibrated"
        } else {
            "normalized"
        }
        .into(),
    ];
    for (flag, value) in FLAGS.iter().zip(text.split('\n')) {
        // A single control character stands for one of the values that broke runs before.
        let value = match value.as_bytes() {
            [b] if *b < 0x20 => SPECIAL[usize::from(*b) % SPECIAL.len()],
            _ => value,
        };
        if !value.is_empty() {
            argv.push(format!("{flag}={value}"));
        }
    }
    let Ok(cli) = Cli::parse_args(&argv) else {
        return;
    };
    let Command::Run(args) = cli.command else {
        return;
    };
    // The f64 oracle is slow on large sensors and at high rates: a time-out is not a finding.
    let opts = args.run.options();
    if sel & 1 == 1 && (opts.rate_hz > 100_000 || opts.size.is_some_and(|(w, _)| w > 256)) {
        return;
    }
    if let Ok(out) = run_pipeline(&opts, &recording()) {
        assert!(out
            .samples
            .iter()
            .all(|s| s.0.is_finite() && s.1.is_finite()));
    }
});
