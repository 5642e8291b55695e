//! `cargo xtask fuzz [--seconds N] [TARGET ...]`: the libFuzzer targets in `host-sim/fuzz`
//! (cargo-fuzz, nightly), each run for N seconds (default 10: the smoke run of `cargo xtask
//! test`; use e.g. `--seconds 3600` for a long run). Prints the executions each target reached.
//! Installs cargo-fuzz when missing; needs the nightly toolchain (`rustup toolchain install
//! nightly` where it is not there).

use std::process::Command;

use anyhow::{bail, Context, Result};

use crate::{cargo, root, run};

/// The targets (`host-sim/fuzz/fuzz_targets/*.rs`).
pub const TARGETS: &[&str] = &[
    "evt_decoders",
    "aer_receiver",
    "pipeline_events",
    "host_formats",
    "mvsec_hdf5",
    "cli_numbers",
    "eval_inputs",
];

/// `cargo` of the nightly toolchain, whatever toolchain runs this xtask.
fn nightly_cargo() -> Command {
    let mut c = Command::new("rustup");
    c.args(["run", "nightly", "cargo"]);
    c.current_dir(root());
    for v in [
        "CARGO",
        "RUSTUP_TOOLCHAIN",
        "RUSTC",
        "RUSTDOC",
        "RUSTC_WRAPPER",
    ] {
        c.env_remove(v);
    }
    c
}

fn ensure_tools() -> Result<()> {
    let has_nightly = Command::new("rustup")
        .args(["toolchain", "list"])
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).contains("nightly"))
        .unwrap_or(false);
    if !has_nightly {
        let mut c = Command::new("rustup");
        c.args(["toolchain", "install", "nightly", "--profile", "minimal"]);
        run("rustup toolchain install nightly (for cargo-fuzz)", c)?;
    }
    let has_fuzz = nightly_cargo()
        .args(["fuzz", "--version"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !has_fuzz {
        let mut c = cargo();
        c.args(["install", "cargo-fuzz", "--locked", "--version", "0.13.2"]);
        run("cargo install cargo-fuzz", c)?;
    }
    Ok(())
}

/// Runs the fuzz targets (all when `targets` is empty) for `seconds` each.
pub fn fuzz(args: &[String]) -> Result<()> {
    let mut seconds = 10u32;
    let mut targets: Vec<String> = Vec::new();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--seconds" => {
                seconds = it
                    .next()
                    .and_then(|s| s.parse().ok())
                    .context("--seconds takes a whole number")?;
            }
            t if TARGETS.contains(&t) => targets.push(t.to_string()),
            other => bail!(
                "unknown fuzz target or option `{other}` (targets: {})",
                TARGETS.join(", ")
            ),
        }
    }
    if targets.is_empty() {
        targets = TARGETS.iter().map(|t| t.to_string()).collect();
    }
    ensure_tools()?;
    let mut c = nightly_cargo();
    c.args(["fuzz", "build", "--fuzz-dir", "host-sim/fuzz", "-O"]);
    run("cargo fuzz build (nightly, libFuzzer + ASan)", c)?;
    for t in &targets {
        let mut c = nightly_cargo();
        c.args(["fuzz", "run", "--fuzz-dir", "host-sim/fuzz", "-O", t, "--"])
            .arg(format!("-max_total_time={seconds}"))
            .arg("-rss_limit_mb=2048");
        eprintln!("xtask: fuzz {t} for {seconds} s");
        let out = c
            .output()
            .with_context(|| format!("cannot start cargo fuzz run {t}"))?;
        let err = String::from_utf8_lossy(&out.stderr);
        let done = err
            .lines()
            .rev()
            .find(|l| l.starts_with("Done ") && l.contains(" runs in "))
            .unwrap_or("(no summary)")
            .to_string();
        if !out.status.success() {
            let tail: Vec<&str> = err.lines().rev().take(30).collect();
            for l in tail.iter().rev() {
                eprintln!("{l}");
            }
            bail!("fuzz target {t} found a crash (input saved under host-sim/fuzz/artifacts/{t})");
        }
        eprintln!("xtask: fuzz {t}: {done}, no crash");
    }
    Ok(())
}
