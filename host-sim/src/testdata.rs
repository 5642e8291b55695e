//! Locating `../shared/data` for tests that use the real recordings and synthetic sequences.
//!
//! The data is beside the repository in development and CI, never in a user's clone. Tests call
//! [`shared_data`]: when the folder is absent it prints a visible notice and the test returns
//! early (skips) — unless the `CI` environment variable is set, in which case absence is a failure.

use std::path::PathBuf;

/// Environment variable that overrides where the shared data lives.
pub const DATA_ENV: &str = "TDE_SHARED_DATA";

/// The shared data folder (`$TDE_SHARED_DATA`, else `<repo>/../shared/data`), or `None` with a
/// notice on stderr when it is absent. Panics (fails the test) when absent and `CI` is set.
pub fn shared_data(sub: &str) -> Option<PathBuf> {
    let base = std::env::var_os(DATA_ENV)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"));
    let dir = base.join(sub);
    if dir.is_dir() {
        return Some(dir);
    }
    let ci = std::env::var_os("CI").is_some_and(|v| !v.is_empty() && v != "false" && v != "0");
    assert!(
        !ci,
        "shared data folder {} is missing and CI is set: the test cannot be skipped",
        dir.display()
    );
    eprintln!(
        "NOTICE: skipping: shared data folder {} not found (set {DATA_ENV} to point at it)",
        dir.display()
    );
    None
}

/// The synthetic sequences of the shared data (folders of `synthetic/` with `events.raw` and
/// `gt.csv`), as `(name, folder)` sorted by name; `None` (skipped) as [`shared_data`]. Panics
/// when the folder cannot be read or holds no sequence.
pub fn synthetic_sequences() -> Option<Vec<(String, PathBuf)>> {
    let dir = shared_data("synthetic")?;
    let mut seqs: Vec<(String, PathBuf)> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", dir.display()))
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.join("events.raw").is_file() && p.join("gt.csv").is_file())
        .map(|p| {
            let name = p
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            (name, p)
        })
        .collect();
    seqs.sort();
    assert!(!seqs.is_empty(), "no sequences in {}", dir.display());
    Some(seqs)
}
