//! The Time Difference Encoder (TDE) core: `no_std`, no heap, no panics on any input.
//!
//! - [`exp_table`]: `e^(-dt/tau)` over integer µs from three 256-entry tables built by `const fn`.
//! - [`params`]: the unit's parameters with the defaults of `shared/spec/model.md`.
//! - [`unit`]: the fixed-point unit: traces, closed-form decay, exact threshold crossings.
//! - [`layout`], [`network`]: which pixels carry units; the network over compact 24-byte cells.
//! - [`readout`], [`pipeline`]: from spikes and bursts to a yaw rate at 1 kHz.
//! - [`log2`]: fixed-point log2/exp2 for the readout.
//! - [`oracle`] (feature `oracle`, host only): the same model in f64, exact in continuous time.
#![no_std]
#![cfg_attr(not(test), deny(clippy::float_arithmetic))]

pub mod aer;
pub mod event;
pub mod evt;
pub mod exp_table;
pub mod layout;
pub mod log2;
pub mod network;
#[cfg(feature = "oracle")]
pub mod oracle;
pub mod params;
pub mod pipeline;
pub mod readout;
pub mod unit;

pub use fixed;
