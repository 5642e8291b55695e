//! Host side of the TDE egomotion project: recordings in every common event format, the network
//! run with the fixed-point core or the f64 oracle, evaluation against ground truth, plots,
//! synthetic scenes and the bridge to the emulated firmware.

pub mod aer_stream;
pub mod cli;
pub mod commands;
pub mod eval;
pub mod formats;
pub mod lookahead;
pub mod output;
pub mod pipeline;
pub mod plot;
pub mod samples;
pub mod synth;
pub mod testdata;
pub mod timeline;
