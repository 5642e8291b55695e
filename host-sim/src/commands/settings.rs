//! `host-sim settings`: the settings the flags of `host-sim run` give, without a recording
//! (hidden; used by `cargo xtask qemu` for an input that already is an AER stream, which
//! carries no sensor size or intrinsics).

use std::io::Write;

use anyhow::Result;

use super::run::RunFlags;
use crate::formats::RecordingInfo;
use crate::pipeline::Camera;
use core_nostd::settings::Settings;

/// Arguments of `host-sim settings`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The run: the flags of `host-sim run`. Without a recording, the sensor size
    /// (`--width`, `--height`) and, for the calibrated readout, `--focal-px` are needed; the
    /// principal point defaults to the sensor centre.
    #[command(flatten)]
    pub run: RunFlags,
}

/// The settings the flags give, the camera resolved as `host-sim run` resolves it for a
/// recording that says nothing about its sensor.
///
/// # Errors
/// When the flags do not say the sensor size, or give settings that cannot run.
pub fn settings(args: &Args) -> Result<Settings> {
    let opts = args.run.options();
    // No recording: only the flags say anything (the format is not used to resolve the
    // camera).
    let nothing_known = RecordingInfo {
        width: None,
        height: None,
        intrinsics: None,
        gyro: None,
        format: opts.format.unwrap_or(crate::formats::Format::Csv),
    };
    let camera = Camera::resolve_with(
        opts.size,
        opts.focal_px,
        (opts.cx, opts.cy),
        &nothing_known,
        || Ok(None),
    )?;
    opts.settings(&camera)
}

/// Prints one line on stdout: `settings=HEX`, the configuration payload of the settings (the
/// QEMU board's `--settings`), as `host-sim aer-stream` prints it for a recording.
///
/// # Errors
/// As [`settings`], and when stdout cannot be written.
pub fn run(args: Args) -> Result<()> {
    let hex = crate::pipeline::settings_hex(&settings(&args)?);
    writeln!(std::io::stdout().lock(), "settings={hex}")?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cli::{Cli, Command};

    fn args(flags: &[&str]) -> Args {
        let argv = ["host-sim", "settings"].iter().chain(flags);
        match Cli::parse_args(argv).map(|c| c.command) {
            Ok(Command::Settings(args)) => args,
            other => panic!("not the settings command: {other:?}"),
        }
    }

    #[test]
    fn the_flags_alone_give_what_run_gives_for_a_recording_of_that_camera() {
        // What a recording of a 346 x 260 sensor, f = 226 px, says about its camera.
        let camera = Camera {
            width: 346,
            height: 260,
            focal: Some(226.0),
            cx: 172.5,
            cy: 129.5,
        };
        let size = ["--width", "346", "--height", "260", "--focal-px", "226"];
        for layout in [&[][..], &["--layout", "paper-boxes", "--stride", "3"][..]] {
            let a = args(&[&size[..], layout].concat());
            let from_recording = a.run.options().settings(&camera).unwrap();
            assert_eq!(settings(&a).unwrap(), from_recording);
        }
    }

    #[test]
    fn without_a_recording_the_size_and_focal_length_are_needed() {
        assert!(settings(&args(&["--focal-px", "226"])).is_err());
        assert!(settings(&args(&["--width", "346", "--height", "260"])).is_err());
        let normalized = [
            "--width",
            "346",
            "--height",
            "260",
            "--readout",
            "normalized",
        ];
        assert!(settings(&args(&normalized)).is_ok());
    }
}
