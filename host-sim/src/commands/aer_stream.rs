//! `host-sim aer-stream`: a recording to the AER stream, plus the settings the firmware needs
//! to process it as `host-sim run` does with the same flags (hidden; used by `cargo xtask
//! qemu`).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use super::run::RunFlags;
use crate::aer_stream::stream_aer;
use crate::output::{check_distinct, AtomicFile};
use crate::pipeline::open_recording;

/// Arguments of `host-sim aer-stream`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input recording (any format `host-sim convert` reads; `-`: standard input).
    #[arg(value_parser = super::input_path)]
    pub input: PathBuf,
    /// How the firmware should run it: the flags of `host-sim run`.
    #[command(flatten)]
    pub run: RunFlags,
    /// Output AER stream (`-`: standard output).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the arrival schedule (when each frame can be sent, for a paced replay;
    /// format in `docs/wire-formats.md`).
    #[arg(long)]
    pub schedule: Option<PathBuf>,
    /// Send the settings as a configuration frame first (`docs/wire-formats.md`), so that the
    /// firmware runs what this stream needs whatever it was built or started with.
    #[arg(long)]
    pub config: bool,
}

/// Writes the stream and prints one line on stdout: `events=N t0_us=T settings=HEX`, where
/// `HEX` is the configuration payload of the settings `host-sim run` would use with the same
/// flags (the QEMU board's `--settings`).
///
/// The events are read and encoded a chunk at a time. The firmware runs one pipeline over the
/// whole stream, so a recording that `host-sim run` would cut into pieces (a gap over
/// [`crate::timeline::RESTART_GAP_US`] or a backward jump over
/// [`crate::timeline::RESTART_BACK_US`]) is refused.
///
/// # Errors
/// When the recording cannot be read, its settings cannot run, its clock jumps, or the stream
/// cannot be written.
pub fn run(args: Args) -> Result<()> {
    let mut outputs = vec![("--out", args.out.as_path())];
    if let Some(p) = &args.schedule {
        outputs.push(("--schedule", p.as_path()));
    }
    check_distinct(&[&args.input], &outputs)?;
    let opts = args.run.options();
    let (mut reader, camera) = open_recording(&args.input, &opts)?;
    let settings = opts.settings(&camera)?;
    let mut config = Vec::new();
    if args.config {
        let mut buf = [0u8; core_nostd::aer::frame::MAX_FRAME];
        let flags = core_nostd::aer::frame::flags::STREAM_START;
        let n = settings
            .encode(flags, 0, &mut buf)
            .map_err(|e| anyhow::anyhow!("--config: {e:?}"))?;
        config.extend_from_slice(buf.get(..n).unwrap_or_default());
    }
    let mut wire = AtomicFile::create(&args.out)?;
    let mut schedule = args
        .schedule
        .as_deref()
        .map(AtomicFile::create)
        .transpose()?;
    let (events, t0) = stream_aer(&mut reader, &mut wire, schedule.as_mut(), &config)
        .with_context(|| format!("{} -> {}", args.input.display(), args.out.display()))?;
    if events == 0 {
        bail!("{}: the recording has no events", args.input.display());
    }
    wire.commit()?;
    if let Some(s) = schedule {
        s.commit()?;
    }
    let hex = crate::pipeline::settings_hex(&settings);
    let mut stdout = std::io::stdout().lock();
    writeln!(stdout, "events={events} t0_us={t0} settings={hex}")?;
    Ok(())
}
