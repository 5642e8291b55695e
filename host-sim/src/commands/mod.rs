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

/// An input recording's path as given on the command line: `-` is standard input
/// (`/dev/stdin`; the recording is read once, as from a FIFO).
///
/// # Errors
/// Never: every string is a path.
pub fn input_path(arg: &str) -> Result<std::path::PathBuf, std::convert::Infallible> {
    Ok(if arg == "-" {
        "/dev/stdin".into()
    } else {
        arg.into()
    })
}
