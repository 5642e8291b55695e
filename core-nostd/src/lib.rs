//! The Time Difference Encoder (TDE) core: `no_std`, no heap, no panics on any input.
//!
//! - [`exp_table`]: `e^(-dt/tau)` over integer µs from three 256-entry tables built by `const fn`.
//! - [`params`]: the unit's parameters with the defaults of `shared/spec/model.md`.
//! - [`unit`](mod@unit): the fixed-point unit: traces, closed-form decay, exact threshold
//!   crossings.
//! - [`layout`], [`network`]: which pixels carry units; the network over compact 12-byte cells.
//! - [`settings`]: everything that decides a run, and the pipeline it builds.
//! - [`readout`], [`pipeline`]: from spikes and bursts to a yaw rate at 1 kHz.
//! - [`flags`]: the status bits of a yaw sample, one set from the readout to the wire.
//! - [`time`]: the wrapping µs event clock.
//! - [`log2`]: fixed-point log2/exp2 for the readout.
//! - `oracle` (feature `oracle`, host only): the same model in f64, exact in continuous time.
#![no_std]
// The core's own rules, on top of the workspace's lint set (Cargo.toml `[lints] workspace =
// true`, which admits no additions). As crate attributes they bind this library alone: its
// tests, benches and examples are separate crates, and `not(test)` frees its unit tests, so
// tests may unwrap, index and panic with no `allow` anywhere.
#![forbid(unsafe_code)]
#![warn(missing_docs)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing,
        clippy::unreachable,
        clippy::float_arithmetic
    )
)]

pub mod aer;
pub mod event;
pub mod evt;
pub mod exp_table;
pub mod flags;
pub mod layout;
pub mod log2;
pub mod network;
#[cfg(feature = "oracle")]
pub mod oracle;
pub mod params;
pub mod pipeline;
pub mod readout;
pub mod settings;
pub mod time;
pub mod unit;

pub use fixed;
