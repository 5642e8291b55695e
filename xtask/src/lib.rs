//! What `cargo xtask` and the QEMU system tests (`xtask/tests/qemu.rs`) share: running the
//! host tool and the emulated firmware, and reading what they write.
//!
//! - [`qemu`]: a recording (or an AER stream) through the QEMU firmware, as `cargo xtask qemu`
//!   runs it; the firmware's summary.
//! - [`yaw`]: the yaw outputs (CSV rows, the sequence counters of `yaw.bin`).
//!
//! Nothing here knows the run's defaults: the flags of `host-sim run` go to `host-sim` as they
//! are, and the firmware gets the settings `host-sim` prints for them.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context, Result};

pub mod profile;
pub mod qemu;
pub mod yaw;

/// The Cortex-M target of the firmware and of the no_std core.
pub const TARGET: &str = "thumbv7em-none-eabihf";

/// The workspace root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// The workspace's target folder: `CARGO_TARGET_DIR` when set, else `target/` in the root.
pub fn target_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| root().join("target"), PathBuf::from)
}

/// `cargo` (the one running this, when there is one), in the workspace root.
pub fn cargo() -> Command {
    let mut c = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    c.current_dir(root());
    c
}

/// Runs `cmd` (its output to the terminal); fails unless it exits with 0. Says how long it
/// took (where a `cargo xtask test` run spends its time).
pub fn run(what: &str, mut cmd: Command) -> Result<()> {
    eprintln!("xtask: {what}");
    let start = std::time::Instant::now();
    let status = cmd
        .status()
        .with_context(|| format!("cannot start: {what}"))?;
    if !status.success() {
        bail!("failed: {what} ({status})");
    }
    eprintln!(
        "xtask: {what}: done in {:.1} s",
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Runs `cmd` and returns its stdout; fails with its stderr unless it exits with 0.
pub fn output(what: &str, mut cmd: Command) -> Result<String> {
    eprintln!("xtask: {what}");
    let out = cmd
        .output()
        .with_context(|| format!("cannot start: {what}"))?;
    if !out.status.success() {
        bail!(
            "failed: {what} ({}): {}",
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// `host-sim` through cargo (release).
pub fn host_sim() -> Command {
    let mut c = cargo();
    c.args(["run", "--quiet", "--release", "-p", "host-sim", "--"]);
    c
}

/// `host-sim run INPUT --out OUT FLAGS..`: what the firmware's output is compared with.
pub fn host_sim_run<S: AsRef<std::ffi::OsStr>>(
    input: &Path,
    flags: &[S],
    out: &Path,
) -> Result<()> {
    let mut c = host_sim();
    c.arg("run").arg(input).args(flags).arg("--out").arg(out);
    run(&format!("host-sim run {}", input.display()), c)
}

/// The firmware workspace's target dir, `firmware/target`, one for every board: what the
/// boards share (the build scripts, the proc macros, the crates built with the same features)
/// is built once.
pub fn firmware_target_dir() -> PathBuf {
    root().join("firmware/target")
}

/// The firmware's ELF for a board (`qemu`, `stm32f405`, `stm32h743`): the boards share the
/// target triple and the binary name, so cargo's `firmware/target/thumbv7em-none-eabihf/
/// release/tde-firmware` is the last board built; each board's build is copied to
/// `firmware/target/<board>/tde-firmware`.
pub fn firmware_elf(board: &str) -> PathBuf {
    firmware_target_dir().join(board).join("tde-firmware")
}

/// Where cargo puts the firmware binary `bin` of the last board built.
pub fn firmware_built(bin: &str) -> PathBuf {
    firmware_target_dir().join(TARGET).join("release").join(bin)
}

/// The value of `k` in a line of `key=value` fields.
pub fn field<'a>(line: &'a str, k: &str) -> Option<&'a str> {
    line.split_whitespace()
        .find_map(|kv| kv.strip_prefix(k)?.strip_prefix('='))
}
