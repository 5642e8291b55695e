//! `cargo xtask fuzz [--seconds N] [--sanitizer address|none] [TARGET ...]`: the libFuzzer
//! targets (cargo-fuzz, nightly) of the core (`core-nostd/fuzz`) and of the host tool
//! (`host-sim/fuzz`), each run for N seconds (default 5; use e.g. `--seconds 3600` for a long
//! run), built with AddressSanitizer (default) or without a sanitizer. Prints the executions
//! each target reached. Installs cargo-fuzz when missing; needs the nightly toolchain (`rustup
//! toolchain install nightly` where it is not there).
//!
//! The smoke run of `cargo xtask test` ([`smoke`]) builds at `opt-level` 1 ([`Build`]) and
//! without a sanitizer: the fuzzed code is safe Rust (the core forbids `unsafe`), so in its 5 s
//! per target the crashes it can find are panics, which libFuzzer catches either way. ASan's
//! instrumentation costs building time (at `opt-level` 3 the host tool's fuzz crate built from
//! scratch in 260 s with it, 163 s without). ASan is for the long runs, where unsafe code in
//! the dependencies (decompressors, flatbuffers) gets the time to meet a bad input.

use std::process::Command;

use anyhow::{bail, Context, Result};

use crate::{cargo, root, run};

/// The cargo-fuzz crates. Their targets are the files `<dir>/fuzz_targets/*.rs` (each also a
/// `[[bin]]` of `<dir>/Cargo.toml`).
const FUZZ_DIRS: &[&str] = &["core-nostd/fuzz", "host-sim/fuzz"];

/// A fuzz target and the cargo-fuzz crate it belongs to.
struct Target {
    dir: &'static str,
    name: String,
}

/// Every target of every fuzz crate, in directory then name order.
fn targets() -> Result<Vec<Target>> {
    let mut all = Vec::new();
    for &dir in FUZZ_DIRS {
        let src = root().join(dir).join("fuzz_targets");
        let mut names: Vec<String> = std::fs::read_dir(&src)
            .with_context(|| format!("cannot list {}", src.display()))?
            .filter_map(|e| Some(e.ok()?.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "rs"))
            .filter_map(|p| Some(p.file_stem()?.to_str()?.to_string()))
            .collect();
        names.sort();
        all.extend(names.into_iter().map(|name| Target { dir, name }));
    }
    Ok(all)
}

/// How the fuzz targets are built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Build {
    sanitizer: Sanitizer,
    /// The release profile's `opt-level`: [`Build::FULL_OPT_LEVEL`] for fuzzing, 1 for the
    /// smoke run of `cargo xtask test`. There the build is most of the cost and the 5 s runs
    /// barely notice: in four clean-clone runs on 2 cores the two crates built from scratch in
    /// 198-268 s against 277 s at 3 (one run), and `pipeline_events` ran 2 245-2 684 inputs
    /// in its 5 s against 3 613 (the other targets 0.7-1.3 times as many).
    opt_level: u8,
}

impl Build {
    /// Cargo's own `opt-level` of the release profile: the fuzzing builds', whose target
    /// folders keep their names from before the smoke run's level existed.
    const FULL_OPT_LEVEL: u8 = 3;

    /// The smoke run's build.
    const SMOKE: Self = Self {
        sanitizer: Sanitizer::None,
        opt_level: 1,
    };

    /// One target folder for both fuzz crates: what they share (libFuzzer, built from C++ by
    /// `libfuzzer-sys`, and the crates they both use) is built once. One per sanitizer and
    /// optimisation level (their flags apply to every crate), so that switching does not
    /// rebuild either.
    fn target_dir(self) -> std::path::PathBuf {
        let sanitizer = match self.sanitizer {
            Sanitizer::Address => "fuzz",
            Sanitizer::None => "fuzz-nosan",
        };
        let name = match self.opt_level {
            Self::FULL_OPT_LEVEL => sanitizer.to_string(),
            o => format!("{sanitizer}-o{o}"),
        };
        xtask::target_dir().join(name)
    }
}

/// `cargo fuzz <sub>` (`build` or `run`) of the fuzz crate in `dir`, built as `build` says,
/// in its target folder.
fn cargo_fuzz(sub: &str, dir: &str, build: Build) -> Command {
    let mut c = nightly_cargo();
    c.args(["fuzz", sub, "--fuzz-dir", dir, "-O"])
        .args(["--sanitizer", build.sanitizer.name(), "--target-dir"])
        .arg(build.target_dir());
    c.env(
        "CARGO_PROFILE_RELEASE_OPT_LEVEL",
        build.opt_level.to_string(),
    );
    c
}

/// The sanitizer the fuzz targets are built with (cargo-fuzz's `--sanitizer`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Sanitizer {
    /// AddressSanitizer: memory errors in unsafe code, at about half the speed.
    Address,
    /// None: panics, timeouts and running out of memory only.
    None,
}

impl Sanitizer {
    const ALL: [Self; 2] = [Self::Address, Self::None];

    /// The sanitizer of cargo-fuzz's name `s`.
    fn parse(s: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|z| z.name() == s)
            .with_context(|| format!("--sanitizer takes `address` or `none`, not `{s}`"))
    }

    /// cargo-fuzz's name for it.
    fn name(self) -> &'static str {
        match self {
            Self::Address => "address",
            Self::None => "none",
        }
    }
}

/// Seconds per target unless `--seconds` says otherwise: the smoke run's.
const SMOKE_SECONDS: u32 = 5;

/// The smoke run of `cargo xtask test`: every target for [`SMOKE_SECONDS`], built without a
/// sanitizer (see the module documentation) and at `opt-level` 1 ([`Build`]).
pub fn smoke() -> Result<()> {
    let all = targets()?;
    run_targets(&all.iter().collect::<Vec<_>>(), SMOKE_SECONDS, Build::SMOKE)
}

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

/// Runs the fuzz targets (all when `args` names none) for `seconds` each.
pub fn fuzz(args: &[String]) -> Result<()> {
    let all = targets()?;
    let mut seconds = SMOKE_SECONDS;
    let mut sanitizer = Sanitizer::Address;
    let mut chosen: Vec<&Target> = Vec::new();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if a == "--seconds" {
            seconds = it
                .next()
                .and_then(|s| s.parse().ok())
                .context("--seconds takes a whole number")?;
        } else if a == "--sanitizer" {
            sanitizer = Sanitizer::parse(it.next().map_or("", String::as_str))?;
        } else if let Some(t) = all.iter().find(|t| t.name == *a) {
            chosen.push(t);
        } else {
            let names: Vec<&str> = all.iter().map(|t| t.name.as_str()).collect();
            bail!(
                "unknown fuzz target or option `{a}` (targets: {})",
                names.join(", ")
            );
        }
    }
    if chosen.is_empty() {
        chosen = all.iter().collect();
    }
    let build = Build {
        sanitizer,
        opt_level: Build::FULL_OPT_LEVEL,
    };
    run_targets(&chosen, seconds, build)
}

/// Builds the fuzz crates of `chosen` as `build` says, then runs each target for `seconds`.
fn run_targets(chosen: &[&Target], seconds: u32, build: Build) -> Result<()> {
    ensure_tools()?;
    for &dir in FUZZ_DIRS {
        if !chosen.iter().any(|t| t.dir == dir) {
            continue;
        }
        let c = cargo_fuzz("build", dir, build);
        run(
            &format!(
                "cargo fuzz build {dir} (nightly, libFuzzer, sanitizer {}, opt-level {})",
                build.sanitizer.name(),
                build.opt_level
            ),
            c,
        )?;
    }
    for t in chosen {
        let name = &t.name;
        let mut c = cargo_fuzz("run", t.dir, build);
        c.args([name.as_str(), "--"])
            .arg(format!("-max_total_time={seconds}"))
            .arg("-rss_limit_mb=2048");
        eprintln!("xtask: fuzz {name} for {seconds} s");
        let out = c
            .output()
            .with_context(|| format!("cannot start cargo fuzz run {name}"))?;
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
            bail!(
                "fuzz target {name} found a crash (input saved under {}/artifacts/{name})",
                t.dir
            );
        }
        eprintln!("xtask: fuzz {name}: {done}, no crash");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// cargo-fuzz builds the `[[bin]]`s of the manifest: every file under `fuzz_targets/` must
    /// be one, named after the file, or `cargo xtask fuzz` would ask for a target that does not
    /// build.
    #[test]
    fn every_target_file_is_a_bin_of_its_crate() {
        for t in targets().unwrap() {
            let manifest = std::fs::read_to_string(root().join(t.dir).join("Cargo.toml")).unwrap();
            let bin = format!("name = \"{0}\"\npath = \"fuzz_targets/{0}.rs\"", t.name);
            assert!(
                manifest.contains(&bin),
                "{}/Cargo.toml lacks the [[bin]] `{bin}`",
                t.dir
            );
        }
    }
}
