//! `host-sim`: the host command-line tool. See `host-sim --help` and the README.

use std::process::ExitCode;

fn main() -> ExitCode {
    host_sim::cli::main()
}
