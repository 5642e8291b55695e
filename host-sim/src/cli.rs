//! Command-line front end: argument parsing and the one-line error / exit-code convention.
//!
//! Every failure prints a single `error: ...` line on stderr and exits with code 2.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::commands;

/// Exit code for every user-facing error (bad input, bad flags, I/O).
pub const EXIT_ERROR: u8 = 2;

#[derive(Debug, Parser)]
#[command(
    name = "host-sim",
    version,
    about = "TDE egomotion: run, evaluate and inspect event recordings on the host"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

impl Cli {
    /// Parses a command line (`argv[0]` the program's name), as `main` does.
    ///
    /// # Errors
    /// clap's error for a command line it refuses.
    pub fn parse_args<I, T>(argv: I) -> Result<Self, clap::Error>
    where
        I: IntoIterator<Item = T>,
        T: Into<std::ffi::OsString> + Clone,
    {
        <Self as Parser>::try_parse_from(argv)
    }
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Sweep one FAC->TRG pair over time differences 0-100 ms (the paper's Fig. 2b/c).
    Sweep(commands::sweep::Args),
    /// The host path end to end: a built-in synthetic scene, the fixed-point pipeline, evaluation.
    Demo(commands::demo::Args),
    /// Run a recording through the fixed-point pipeline (the firmware's code) to a yaw-rate CSV.
    Run(Box<commands::run::Args>),
    /// Convert a recording to CSV (`t_us,x,y,p`) or Prophesee EVT 3.0.
    Convert(commands::convert::Args),
    /// Render a synthetic event sequence with ground truth and a simulated IMU.
    Synth(commands::synth::Args),
    /// Compare an estimated yaw rate with ground truth (and the gyro): RMSE, correlation, ARRE.
    Eval(commands::eval::Args),
    /// Decode a captured yaw output stream (the firmware's yaw frames) to CSV.
    YawDecode(commands::yaw_decode::Args),
    /// Write a recording as the AER-over-SPI stream and print the firmware's settings
    /// (used by `cargo xtask qemu`).
    #[command(hide = true)]
    AerStream(commands::aer_stream::Args),
    /// Print the settings the flags of `run` give, without a recording (used by `cargo xtask
    /// qemu` for an AER stream input).
    #[command(hide = true)]
    Settings(commands::settings::Args),
}

/// Parses the arguments, runs the command, maps errors to one line and exit code 2.
pub fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let code = if e.use_stderr() { EXIT_ERROR } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    let result = match cli.command {
        Command::Sweep(args) => commands::sweep::run(args),
        Command::Demo(args) => commands::demo::run(args),
        Command::Run(args) => commands::run::run(*args),
        Command::Convert(args) => commands::convert::run(args),
        Command::Synth(args) => commands::synth::run(args),
        Command::Eval(args) => commands::eval::run(args),
        Command::YawDecode(args) => commands::yaw_decode::run(args),
        Command::AerStream(args) => commands::aer_stream::run(args),
        Command::Settings(args) => commands::settings::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", one_line(&e));
            ExitCode::from(EXIT_ERROR)
        }
    }
}

/// The error and its causes on one line.
pub fn one_line(e: &anyhow::Error) -> String {
    let mut s = String::new();
    for (i, cause) in e.chain().enumerate() {
        if i > 0 {
            s.push_str(": ");
        }
        s.push_str(&cause.to_string().replace('\n', " "));
    }
    s
}
