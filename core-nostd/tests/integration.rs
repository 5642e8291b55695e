//! The core's integration tests, one module per file beside this one, built as one test binary:
//! as a binary each, every file compiled and optimised the network's generic code again (the
//! twelve took 82 s on 2 cores in the release profile of `cargo xtask test`, as one binary 25
//! s). A module's tests are named after its file: `cargo test --release -p core-nostd --test
//! integration -- unit_pool::`.

mod aer_config;
mod aer_corruption;
mod aer_link;
mod aer_roundtrip;
mod calibrated_readout;
mod clock_wraps;
mod evt_decode;
mod random_trains;
mod spike_readout;
mod table_error;
mod tde_vs_oracle;
mod unit_pool;
