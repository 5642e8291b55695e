//! One module per subcommand: its `Args` and its `run`.

pub mod convert;
pub mod demo;
pub mod eval;
pub mod run;
pub mod sweep;
pub mod synth;
pub mod yaw_decode;
