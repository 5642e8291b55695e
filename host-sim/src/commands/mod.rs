//! One module per subcommand: its `Args` and its `run`.

pub mod aer_stream;
pub mod convert;
pub mod demo;
pub mod eval;
pub mod run;
pub mod settings;
pub mod sweep;
pub mod synth;
pub mod yaw_decode;
