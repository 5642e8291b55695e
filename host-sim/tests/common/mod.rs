//! Helpers shared by the integration tests that run the `host-sim` binary.

use std::path::Path;
use std::process::Command;

/// The `host-sim` binary built for these tests.
pub fn host_sim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
}

/// `host-sim convert INPUT --to TO --out OUT`, which must succeed.
pub fn convert(input: &Path, to: &str, out: &Path) {
    let o = host_sim()
        .arg("convert")
        .arg(input)
        .args(["--to", to, "--out"])
        .arg(out)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "convert {} failed: {}",
        input.display(),
        String::from_utf8_lossy(&o.stderr)
    );
}
