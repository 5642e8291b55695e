//! The host tool's integration tests, one module per file beside this one, built as one test
//! binary: one link instead of twenty, and the test threads take tests from every file at once
//! (a file with one long test no longer leaves the other core idle). A module's tests are named
//! after its file: `cargo test --release -p host-sim --test integration -- regimes::`.

mod common;

mod eval_cli;
mod eval_metrics;
mod formats_aedat4;
mod formats_errors;
mod formats_real;
mod formats_roundtrip;
mod formats_synthetic;
mod hostile_inputs;
mod mvsec_props;
mod read_ahead;
mod regimes;
mod run_normalized;
mod run_pieces;
mod run_synthetic;
mod spike_readout;
mod spiking_fidelity;
mod sweep_cli;
mod synth_determinism;
mod synth_physics;
mod synth_regimes;
