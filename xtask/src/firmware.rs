//! Firmware tasks: `firmware` (build + size), `flash` (probe-rs), `qemu` (a recording through
//! the emulated firmware: [`xtask::qemu`]), and the firmware part of `test`, whose QEMU system
//! checks are the tests in `xtask/tests/qemu.rs`.

use std::path::PathBuf;
use std::process::Command;

use anyhow::{bail, Context, Result};

use crate::{cargo, root, run};

/// The firmware's ELF for a board (see [`xtask::firmware_elf`]).
pub fn elf(board: Board) -> PathBuf {
    xtask::firmware_elf(board.name())
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Board {
    Qemu,
    Stm32f405,
    Stm32h743,
}

/// Every board, in build order.
pub const BOARDS: [Board; 3] = [Board::Qemu, Board::Stm32f405, Board::Stm32h743];

/// A memory region of a board: (section names that fill it, size in bytes, what it is).
type Region = (&'static [&'static str], u64, &'static str);

impl Board {
    fn parse(s: &str) -> Result<Self> {
        match s {
            "qemu" => Ok(Self::Qemu),
            "stm32f405" => Ok(Self::Stm32f405),
            "stm32h743" => Ok(Self::Stm32h743),
            _ => bail!("unknown board `{s}` (qemu, stm32f405, stm32h743)"),
        }
    }

    fn name(self) -> &'static str {
        match self {
            Self::Qemu => "qemu",
            Self::Stm32f405 => "stm32f405",
            Self::Stm32h743 => "stm32h743",
        }
    }

    fn cargo_args(self) -> &'static [&'static str] {
        match self {
            Self::Qemu => &["--features", "board-qemu"],
            Self::Stm32f405 => &["--no-default-features", "--features", "board-stm32f405"],
            Self::Stm32h743 => &["--no-default-features", "--features", "board-stm32h743"],
        }
    }

    /// The probe-rs chip name (hardware boards only).
    fn chip(self) -> Option<&'static str> {
        match self {
            Self::Qemu => None,
            Self::Stm32f405 => Some("STM32F405RGTx"),
            Self::Stm32h743 => Some("STM32H743VITx"),
        }
    }

    /// Flash and main RAM (stack, .data, .bss) in bytes, as in `firmware/boards/*/memory.x`.
    fn flash_ram(self) -> (u64, u64) {
        match self {
            Self::Qemu => (4 * 1024 * 1024, 4 * 1024 * 1024),
            Self::Stm32f405 => (1024 * 1024, 128 * 1024),
            Self::Stm32h743 => (2048 * 1024, 128 * 1024),
        }
    }

    /// The other RAM regions the firmware places sections in; a section larger than its
    /// region fails the size check.
    fn regions(self) -> &'static [Region] {
        match self {
            Self::Qemu => &[],
            Self::Stm32f405 => &[(&[".ccmram"], 64 * 1024, "CCM")],
            Self::Stm32h743 => &[
                (&[".axisram"], 512 * 1024, "AXI SRAM"),
                (&[".sram1"], 128 * 1024, "SRAM1"),
                (&[".sram23"], 160 * 1024, "SRAM2/3"),
            ],
        }
    }
}

/// Adds the Cortex-M target through rustup when it is missing (rustup installs the targets of
/// `rust-toolchain.toml` only together with the toolchain). Without rustup nothing is checked.
pub fn ensure_target() -> Result<()> {
    let out = Command::new("rustup")
        .current_dir(root())
        .args(["target", "list", "--installed"])
        .output();
    let Ok(out) = out else {
        eprintln!(
            "xtask: rustup not found; assuming {} is installed",
            crate::TARGET
        );
        return Ok(());
    };
    if !out.status.success() {
        bail!(
            "rustup target list --installed failed: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    let installed = String::from_utf8_lossy(&out.stdout);
    if installed.lines().any(|l| l.trim() == crate::TARGET) {
        return Ok(());
    }
    let mut c = Command::new("rustup");
    c.current_dir(root()).args(["target", "add", crate::TARGET]);
    run(&format!("rustup target add {}", crate::TARGET), c)
}

fn firmware_cargo() -> Command {
    let mut c = cargo();
    c.current_dir(root().join("firmware"));
    // The firmware is its own workspace, built into its own target dir whatever the caller's
    // CARGO_TARGET_DIR says: `build` copies each board's image from there.
    c.env("CARGO_TARGET_DIR", xtask::firmware_target_dir());
    c
}

/// Whether a firmware build is also its clippy run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Lint {
    /// A plain `cargo build`.
    No,
    /// The firmware's own crate compiled by clippy's driver, warnings denied: what `cargo
    /// clippy -- -D warnings` reports, but from a build. `cargo clippy` only checks, so the
    /// dependencies (embassy, the STM32 register crates) would be compiled twice, once checked
    /// and once built: 278 s and 223 s for the three boards in two clean-clone runs of `cargo
    /// xtask test` on 2 cores, against 351 s for clippy and build.
    DenyWarnings,
}

/// Makes `c` (a firmware `cargo` command) compile the firmware's crate with clippy's driver,
/// as `cargo clippy` does: `RUSTC_WORKSPACE_WRAPPER` names the driver (it sits beside the
/// toolchain's `cargo`), `CLIPPY_ARGS` carries the lint flags the way `cargo clippy` hands them
/// over (each followed by `__CLIPPY_HACKERY__`).
fn lint_with_clippy(c: &mut Command) -> Result<()> {
    let cargo = PathBuf::from(
        std::env::var_os("CARGO").context("CARGO is not set: run this as `cargo xtask`")?,
    );
    let driver = cargo.with_file_name("clippy-driver");
    if !driver.exists() {
        bail!(
            "no clippy-driver beside {} (rustup component add clippy)",
            cargo.display()
        );
    }
    c.env("RUSTC_WORKSPACE_WRAPPER", driver).env(
        "CLIPPY_ARGS",
        "-D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__",
    );
    Ok(())
}

/// Builds the firmware for `board` (release) and copies its ELF to [`elf`]`(board)`.
pub fn build(board: Board) -> Result<()> {
    build_with(board, Lint::No)
}

/// [`build`], linted or not.
fn build_with(board: Board, lint: Lint) -> Result<()> {
    ensure_target()?;
    let mut c = firmware_cargo();
    c.args(["build", "--release"]).args(board.cargo_args());
    let what = match lint {
        Lint::No => format!("firmware build ({})", board.name()),
        Lint::DenyWarnings => {
            lint_with_clippy(&mut c)?;
            format!("firmware build and clippy ({})", board.name())
        }
    };
    run(&what, c)?;
    // Cargo puts every board's image at one path (a build that is up to date puts it there
    // again), so each board's is kept apart as soon as it is built.
    let (built, kept) = (xtask::firmware_built("tde-firmware"), elf(board));
    if let Some(dir) = kept.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    std::fs::copy(&built, &kept)
        .with_context(|| format!("cannot copy {} to {}", built.display(), kept.display()))?;
    Ok(())
}

/// Prints flash and RAM use of the last build (`arm-none-eabi-size -A`, summed per region);
/// fails when a region overflows.
pub fn size(board: Board) -> Result<()> {
    let out = Command::new("arm-none-eabi-size")
        .arg("-A")
        .arg(elf(board))
        .output()
        .context("cannot run arm-none-eabi-size (apt-get install binutils-arm-none-eabi)")?;
    if !out.status.success() {
        bail!("arm-none-eabi-size failed");
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let regions = board.regions();
    let mut used = vec![0u64; regions.len()];
    let (mut flash, mut ram, mut other) = (0u64, 0u64, Vec::new());
    for line in text.lines() {
        let f: Vec<&str> = line.split_whitespace().collect();
        let [name, size, addr] = f[..] else { continue };
        let (Ok(size), Ok(addr)) = (size.parse::<u64>(), addr.parse::<u64>()) else {
            continue;
        };
        if size == 0 || addr == 0 && name.starts_with(".debug") {
            continue;
        }
        if let Some(i) = regions.iter().position(|r| r.0.contains(&name)) {
            used[i] += size;
            continue;
        }
        match name {
            ".vector_table" | ".text" | ".rodata" => flash += size,
            ".data" => {
                flash += size;
                ram += size;
            }
            ".bss" | ".uninit" | ".stack" => ram += size,
            n if n.starts_with(".defmt") => flash += size,
            _ if addr > 0 => other.push(format!("{name} {size} B at {addr:#x}")),
            _ => {}
        }
    }
    let (flash_total, ram_total) = board.flash_ram();
    let pct = |a: u64, b: u64| 100.0 * a as f64 / b as f64;
    let mut line = format!(
        "xtask: {} firmware: flash {flash} B of {flash_total} ({:.1} %), RAM (static, without \
         stack) {ram} B of {ram_total} ({:.1} %)",
        board.name(),
        pct(flash, flash_total),
        pct(ram, ram_total)
    );
    for ((_, total, what), u) in regions.iter().zip(&used) {
        line.push_str(&format!(
            "; {what} {u} B of {total} ({:.1} %)",
            pct(*u, *total)
        ));
    }
    if !other.is_empty() {
        line.push_str("; other: ");
        line.push_str(&other.join(", "));
    }
    eprintln!("{line}");
    if flash > flash_total || ram + MIN_STACK > ram_total {
        bail!(
            "{} firmware does not fit: flash {flash} of {flash_total} B, RAM {ram} + {MIN_STACK} \
             B stack of {ram_total} B",
            board.name()
        );
    }
    for ((_, total, what), u) in regions.iter().zip(&used) {
        if u > total {
            bail!(
                "{} firmware: {what} overflows ({u} of {total} B)",
                board.name()
            );
        }
    }
    Ok(())
}

/// Stack the size check keeps free in main RAM (interrupt handlers and the executors run on
/// it; the tasks live in statics).
const MIN_STACK: u64 = 8 * 1024;

/// `cargo xtask firmware [--board qemu|stm32f405|stm32h743]`: build and size (every board by
/// default).
pub fn firmware(args: &[String]) -> Result<()> {
    let boards = match args {
        [] => BOARDS.to_vec(),
        [flag, b] if flag == "--board" => vec![Board::parse(b)?],
        _ => bail!("usage: cargo xtask firmware [--board qemu|stm32f405|stm32h743]"),
    };
    for b in boards {
        build(b)?;
        size(b)?;
    }
    Ok(())
}

/// `cargo xtask flash [--board stm32f405|stm32h743]` (default stm32f405): builds the board's
/// firmware and runs it on the board through probe-rs (defmt logs over RTT stream to the
/// terminal until Ctrl-C).
pub fn flash(args: &[String]) -> Result<()> {
    let board = match args {
        [] => Board::Stm32f405,
        [flag, b] if flag == "--board" => Board::parse(b)?,
        _ => bail!("usage: cargo xtask flash [--board stm32f405|stm32h743]"),
    };
    let Some(chip) = board.chip() else {
        bail!(
            "the {} board runs in QEMU: use `cargo xtask qemu`",
            board.name()
        );
    };
    build(board)?;
    size(board)?;
    let probe = Command::new("probe-rs").arg("--version").output();
    if probe.map(|o| !o.status.success()).unwrap_or(true) {
        bail!(
            "probe-rs is not installed; install it once with `cargo install probe-rs-tools --locked` (~15 min)"
        );
    }
    let mut c = Command::new("probe-rs");
    c.args(["run", "--chip", chip]).arg(elf(board));
    run(&format!("probe-rs run --chip {chip}"), c)
}

/// `cargo xtask qemu INPUT --out yaw.csv [options]` (see [`xtask::qemu::USAGE`]): builds the
/// QEMU firmware and runs it on INPUT; prints the firmware's counters, the last line being
/// `events=N frames_ok=N frames_bad=N frames_dropped=N instructions_per_event=N`.
pub fn qemu(args: &[String]) -> Result<()> {
    let q = xtask::qemu::Qemu::parse(args)?;
    crate::setup()?;
    build(Board::Qemu)?;
    let report = q.run()?;
    eprintln!("{}", report.summary.details());
    eprintln!(
        "t0_us={} (add to the firmware's times for the recording's clock)",
        report.t0_us
    );
    println!("{}", report.summary.counters());
    Ok(())
}

/// The firmware part of `cargo xtask test`: fmt, clippy, build and size check of every board,
/// the no-panic link check, then the QEMU system tests (`xtask/tests/qemu.rs`, ignored by a
/// plain `cargo test`: they need QEMU and the firmware just built).
pub fn check() -> Result<()> {
    ensure_target()?;
    let mut c = firmware_cargo();
    c.args(["fmt", "--check"]);
    run("firmware fmt --check", c)?;
    for board in BOARDS {
        build_with(board, Lint::DenyWarnings)?;
        size(board)?;
    }
    // The event path (link receiver + pipeline) must link no panic: this binary's panic handler
    // calls an undefined symbol (see firmware/src/bin/no-panic-check.rs). Built (and linted)
    // with the QEMU board above; linted here too, so that nothing is built again.
    let mut c = firmware_cargo();
    c.args(["build", "--release", "--bin", "no-panic-check"])
        .args(Board::Qemu.cargo_args());
    lint_with_clippy(&mut c)?;
    run("firmware no-panic-check (the event path links no panic)", c)?;
    // The release profile with overflow checks and the workspace's features (`--workspace`:
    // as the workspace tests of `test` resolve them; `-p xtask` alone would build the core
    // and `fixed` again without the oracle), so that nothing is built again. Two at a time,
    // each QEMU run on a core of its own: a run's output and counters do not depend on the
    // host's load, since QEMU runs with `-icount shift=N,sleep=off` (the emulated clock counts
    // instructions, also while the firmware idles), and the recordings the tests share are
    // made once, behind `OnceLock`s.
    let mut c = cargo();
    c.args(["test", "--release", "--workspace", "--test", "qemu", "--"])
        .args(["--ignored", "--test-threads=2", "--nocapture"]);
    c.env("CARGO_PROFILE_RELEASE_OVERFLOW_CHECKS", "true");
    run("QEMU system tests (xtask/tests/qemu.rs)", c)
}
