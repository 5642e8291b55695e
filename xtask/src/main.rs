//! `cargo xtask <task>`: the one front door for project tasks.
//!
//! - `test`:  everything CI runs — system packages, fmt, clippy, docs, every test, the example,
//!   the Cortex-M builds, the fuzz smoke runs.
//! - `demo`:  the main job on a built-in default input.
//! - `setup`: install what the other tasks need (system packages through apt when root).

use std::process::{Command, ExitCode};

use anyhow::{bail, Context, Result};

mod firmware;
mod fuzz;

pub use xtask::{cargo, root, run, TARGET};

/// Debian packages the host tools need to build and run.
const APT_PACKAGES: &[&str] = &[
    "pkg-config",
    "libhdf5-dev",
    // the emulated firmware (`cargo xtask qemu`, part of `test`) and its size report
    "qemu-system-arm",
    "binutils-arm-none-eabi",
];

/// Seed of the property tests under `cargo xtask test` (see `test`).
const PROPTEST_SEED: &str = "20261201";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("test") => test(),
        Some("demo") => demo(&args[1..]),
        Some("regimes") => regimes(&args[1..]),
        Some("setup") => setup(),
        Some("firmware") => firmware::firmware(&args[1..]),
        Some("fuzz") => fuzz::fuzz(&args[1..]),
        Some("flash") => firmware::flash(&args[1..]),
        Some("qemu") => firmware::qemu(&args[1..]),
        Some("firmware-test") => setup().and_then(|()| firmware::check()),
        Some("help") | Some("--help") | Some("-h") | None => {
            print_help();
            Ok(())
        }
        Some(other) => {
            print_help();
            Err(anyhow::anyhow!("unknown task `{other}`"))
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: error: {e:#}");
            ExitCode::from(2)
        }
    }
}

fn print_help() {
    eprintln!(
        "usage: cargo xtask <task>\n\n\
         tasks:\n  \
         test    fmt, clippy, docs, every test, the example, the Cortex-M builds, fuzz smoke\n          \
         runs (what CI runs)\n  \
         demo    the main job on the built-in default input; results in out/\n  \
         regimes [--seed N]   the readout in every flight regime (car, drone, hover, objects,\n          \
         rotation): rendered, run and judged, plots in out/regimes/\n  \
         setup   install the system packages the tools need (apt, when root)\n  \
         firmware [--board qemu|stm32f405|stm32h743]   build the firmware, print its flash/RAM use\n  \
         flash [--board stm32f405|stm32h743]   build and run on the board through probe-rs (defmt over RTT)\n  \
         qemu INPUT --out yaw.csv [options]  run a recording through the emulated firmware\n  \
         firmware-test   only the firmware part of `test` (every board, QEMU runs)\n  \
         fuzz [--seconds N] [--sanitizer address|none] [TARGET..]   the libFuzzer targets\n          \
         (nightly), N s each (5), with ASan unless `none`"
    );
}

/// Installs missing Debian packages when running as root; otherwise prints the exact command.
pub fn setup() -> Result<()> {
    check_dev_null()?;
    let missing: Vec<&str> = APT_PACKAGES
        .iter()
        .copied()
        .filter(|p| !deb_installed(p))
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    let list = missing.join(" ");
    if !is_root() {
        bail!("missing system packages; install them with:\n  sudo apt-get update && sudo apt-get install -y {list}");
    }
    let mut update = Command::new("apt-get");
    update.args(["update", "-qq"]);
    run("apt-get update", update)?;
    let mut install = Command::new("apt-get");
    install.args(["install", "-y", "-qq"]).args(&missing);
    install.env("DEBIAN_FRONTEND", "noninteractive");
    run(&format!("apt-get install {list}"), install)
}

/// `/dev/null` must be the null device: cargo hands it to rustc as the empty source of its
/// target probe. A regular file there (left by a program that renamed an output onto
/// `/dev/null` as root) holds whatever was written to it since, and every build then fails
/// with "failed to run `rustc` to learn about target-specific information". Recreated when
/// root, else the exact command.
fn check_dev_null() -> Result<()> {
    use std::os::unix::fs::FileTypeExt;
    const REPAIR: &str = "rm -f /dev/null && mknod -m 666 /dev/null c 1 3";
    let is_device = std::fs::metadata("/dev/null").is_ok_and(|m| m.file_type().is_char_device());
    if is_device {
        return Ok(());
    }
    if !is_root() {
        bail!("/dev/null is not the null device; recreate it with:\n  sudo sh -c '{REPAIR}'");
    }
    eprintln!("xtask: /dev/null is not the null device (a regular file is there): recreating it");
    let mut c = Command::new("sh");
    c.args(["-c", REPAIR]);
    run("recreate /dev/null", c)
}

fn deb_installed(pkg: &str) -> bool {
    Command::new("dpkg-query")
        .args(["-W", "-f=${Status}", pkg])
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).contains("install ok installed"))
        .unwrap_or(false)
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
        .unwrap_or(false)
}

fn test() -> Result<()> {
    setup()?;
    let mut c = cargo();
    c.args(["fmt", "--all", "--check"]);
    run("cargo fmt --check", c)?;
    // The dev profile, as `cargo doc` below: the dependencies are checked once for both.
    let mut c = cargo();
    c.args([
        "clippy",
        "--workspace",
        "--all-targets",
        "--",
        "-D",
        "warnings",
    ]);
    run("cargo clippy (workspace)", c)?;
    // The API docs build without a warning (broken or ambiguous links): the workspace, where
    // host-sim turns on the core's `oracle`, and the core alone, as a no_std user sees it.
    for (what, args) in [
        ("cargo doc (workspace)", &["--workspace"][..]),
        (
            "cargo doc (core-nostd, no features)",
            &["-p", "core-nostd"][..],
        ),
    ] {
        let mut c = cargo();
        c.args(["doc", "--no-deps"]).args(args);
        c.env("RUSTDOCFLAGS", "-D warnings");
        run(what, c)?;
    }
    // Release profile: the oracle comparisons and recordings are heavy in debug builds.
    // Overflow checks on, so that an arithmetic overflow anywhere fails the tests.
    let mut c = cargo();
    c.args(["test", "--workspace", "--release"]);
    c.env("CARGO_PROFILE_RELEASE_OVERFLOW_CHECKS", "true");
    // The property tests draw the same cases on every run of this command, so that a red run
    // is reproducible and a green one means the same thing every time. `cargo test` on its
    // own draws new cases each run (that is how the oracle's ill-conditioned trains were found).
    c.env("PROPTEST_RNG_SEED", PROPTEST_SEED);
    run("cargo test --workspace --release", c)?;
    // The example that walks the whole chain (`cargo test` only builds it). Built as the tests
    // were (the whole workspace, so the same features; the same profile settings), so that
    // nothing is built again, then run (`cargo run -p core-nostd` would resolve the core's
    // features alone and build it and its dependencies once more).
    let mut c = cargo();
    c.args([
        "build",
        "--workspace",
        "--release",
        "--example",
        "edge_sweep",
    ]);
    c.env("CARGO_PROFILE_RELEASE_OVERFLOW_CHECKS", "true");
    run("build example edge_sweep", c)?;
    let mut c = Command::new(xtask::target_dir().join("release/examples/edge_sweep"));
    c.current_dir(root());
    run(
        "example edge_sweep (events -> network -> readout -> yaw)",
        c,
    )?;
    firmware::ensure_target()?;
    // The core as the firmware gets it (no features: no std, no oracle), linted: the
    // workspace's clippy above sees it with the host's features (`oracle`), and the firmware's
    // builds below compile it for the board but lint only the firmware's own crate.
    let mut c = cargo();
    c.args(["clippy", "-p", "core-nostd", "--target", TARGET])
        .args(["--", "-D", "warnings"]);
    run("cargo clippy (core-nostd for thumbv7em-none-eabihf)", c)?;
    firmware::check()?;
    // A short smoke run of every fuzz target, without a sanitizer and at opt-level 1 (the long
    // run, with ASan and fully optimised: `cargo xtask fuzz --seconds 3600`).
    fuzz::smoke()?;
    eprintln!("xtask: all checks passed");
    Ok(())
}

/// The main job: the firmware, emulated, on a built-in synthetic recording, its yaw rate judged
/// against the ground truth (and the simulated gyro). Results in `out/demo-firmware/`.
fn demo(_args: &[String]) -> Result<()> {
    setup()?;
    let out = root().join("out/demo-firmware");
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let scene = out.join("scene");
    let mut c = xtask::host_sim();
    c.args(["synth", "--duration", "4", "--seed", "1", "--out"])
        .arg(&scene);
    run(
        "host-sim synth (built-in scene: urban texture, sinusoidal yaw, 4 s)",
        c,
    )?;
    firmware::build(firmware::Board::Qemu)?;
    let yaw = out.join("yaw.csv");
    let a = xtask::qemu::Qemu::new(scene.join("events.txt"), &yaw, out.join("qemu"));
    eprintln!("xtask: running the firmware in QEMU (mps2-an386, Cortex-M4F)");
    let report = a.run()?;
    let summary = report.summary.counters();
    let mut c = xtask::host_sim();
    c.args(["eval", "--yaw"])
        .arg(&yaw)
        .arg("--gt")
        .arg(scene.join("gt.csv"))
        .arg("--imu")
        .arg(scene.join("imu.txt"))
        .arg("--plot")
        .arg(out.join("eval.png"));
    run(
        "host-sim eval (firmware yaw rate vs ground truth and gyro)",
        c,
    )?;
    println!("firmware: {summary}");
    println!(
        "xtask: demo done: {} and {}",
        yaw.display(),
        out.join("eval.png").display()
    );
    Ok(())
}

/// The readout in every flight regime: each scene rendered by `host-sim synth --regime R`
/// (seed `--seed`, default 1, 4 s, DAVIS346), run by `host-sim run` and judged by
/// `host-sim eval` against its ground truth. Results in `out/regimes/<regime>/` (`scene/`,
/// `yaw.csv`, `eval.png`).
fn regimes(args: &[String]) -> Result<()> {
    let seed = match args {
        [] => 1,
        [flag, n] if flag == "--seed" => n.parse().context("--seed: not a number")?,
        _ => bail!("usage: cargo xtask regimes [--seed N]"),
    };
    let out = root().join("out/regimes");
    for regime in ["car", "drone", "hover", "objects", "rotation"] {
        let dir = out.join(regime);
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        let scene = dir.join("scene");
        let mut c = xtask::host_sim();
        c.args(["synth", "--regime", regime, "--duration", "4", "--seed"])
            .arg(seed.to_string())
            .arg("--out")
            .arg(&scene);
        run(
            &format!("host-sim synth --regime {regime} --seed {seed}"),
            c,
        )?;
        let yaw = dir.join("yaw.csv");
        let mut c = xtask::host_sim();
        c.arg("run")
            .arg(scene.join("events.txt"))
            .arg("--out")
            .arg(&yaw);
        run(&format!("host-sim run ({regime})"), c)?;
        let mut c = xtask::host_sim();
        c.args(["eval", "--yaw"])
            .arg(&yaw)
            .arg("--gt")
            .arg(scene.join("gt.csv"))
            .arg("--plot")
            .arg(dir.join("eval.png"));
        run(&format!("host-sim eval ({regime})"), c)?;
    }
    println!("xtask: regimes done: {}", out.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `[workspace.lints.*]` tables of a manifest: their lines without comments and blanks.
    fn workspace_lints(manifest: &str) -> Vec<&str> {
        let mut inside = false;
        let mut lines = Vec::new();
        for l in manifest.lines().map(str::trim) {
            if l.starts_with('[') {
                inside = l.starts_with("[workspace.lints");
            }
            if inside && !l.is_empty() && !l.starts_with('#') {
                lines.push(l);
            }
        }
        lines
    }

    /// The firmware is its own workspace and cannot inherit the lint set: it keeps a copy.
    #[test]
    fn the_firmware_has_the_workspace_lints() {
        let read = |p: &str| std::fs::read_to_string(root().join(p)).unwrap();
        let (ws, fw) = (read("Cargo.toml"), read("firmware/Cargo.toml"));
        assert!(!workspace_lints(&ws).is_empty());
        assert_eq!(
            workspace_lints(&fw),
            workspace_lints(&ws),
            "firmware/Cargo.toml's [workspace.lints] must equal the root Cargo.toml's"
        );
    }
}
