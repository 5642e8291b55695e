//! Puts the selected board's memory layout where the cortex-m-rt linker script finds it:
//! `boards/<board>/memory.x`, except the STM32F405's, which is the workspace's top-level
//! `memory.x` (the flight controller the project targets first).
use std::path::PathBuf;

fn main() {
    let out = PathBuf::from(std::env::var_os("OUT_DIR").unwrap_or_default());
    let manifest = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default());
    let board = if std::env::var_os("CARGO_FEATURE_BOARD_QEMU").is_some() {
        "qemu"
    } else if std::env::var_os("CARGO_FEATURE_BOARD_STM32H743").is_some() {
        "stm32h743"
    } else {
        "stm32f405"
    };
    let layout = |b: &str| {
        if b == "stm32f405" {
            manifest.join("..").join("memory.x")
        } else {
            manifest.join("boards").join(b).join("memory.x")
        }
    };
    let memory = layout(board);
    if let Err(e) = std::fs::copy(&memory, out.join("memory.x")) {
        panic!("cannot copy {}: {e}", memory.display());
    }
    println!("cargo:rustc-link-search={}", out.display());
    for b in ["qemu", "stm32f405", "stm32h743"] {
        println!("cargo:rerun-if-changed={}", layout(b).display());
    }
    println!("cargo:rerun-if-changed=build.rs");
}
