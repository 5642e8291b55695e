//! Puts the selected board's memory layout where the cortex-m-rt linker script finds it:
//! `boards/qemu/memory.x` for `board-qemu`, the repo-root `memory.x` (STM32F405) otherwise.
use std::path::PathBuf;

fn main() {
    let out = PathBuf::from(std::env::var_os("OUT_DIR").unwrap_or_default());
    let manifest = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default());
    let memory = if std::env::var_os("CARGO_FEATURE_BOARD_QEMU").is_some() {
        manifest.join("boards/qemu/memory.x")
    } else {
        manifest.join("../memory.x")
    };
    if let Err(e) = std::fs::copy(&memory, out.join("memory.x")) {
        panic!("cannot copy {}: {e}", memory.display());
    }
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", memory.display());
    println!("cargo:rerun-if-changed=build.rs");
}
