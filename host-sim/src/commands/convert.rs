//! `host-sim convert INPUT --to csv|evt3|aer --out FILE [--format F]`.
//!
//! - `csv`: `t_us,x,y,p` with a header line (p = 1 ON, 0 OFF), one line per event in stream
//!   order, times as in the input (AEDAT4: absolute Unix µs): byte-identical to the reference
//!   decodes in `shared/data/real`.
//! - `evt3`: a Prophesee EVT 3.0 `.raw` file with a header (sensor size from the input, else the
//!   events' extent). Inputs whose first event is at or after 2^24 µs keep their absolute time
//!   through a `% tde_time_offset_us` header line that this tool reads back.
//! - `aer`: the firmware's AER-over-SPI stream (`docs/wire-formats.md`), times relative to the
//!   first event, as the firmware and `host-sim run` count them; a recording whose clock jumps
//!   (see `crate::timeline`) is refused, as by `host-sim aer-stream`.
//!
//! Events are read and written a chunk at a time: memory does not grow with the recording. The
//! output is written to a temporary file and renamed: a failed run leaves no output, and an
//! output naming the input is refused.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use crate::formats::raw::Evt3Writer;
use crate::formats::{self, Format, Needs};
use crate::output::AtomicFile;

/// Output formats of `convert`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum To {
    /// CSV `t_us,x,y,p` with a header line.
    Csv,
    /// Prophesee EVT 3.0 `.raw`.
    Evt3,
    /// The firmware's AER-over-SPI stream (framed, CRC-checked).
    Aer,
}

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input recording (CSV, Event Camera Dataset text, Prophesee .raw EVT 2.0/2.1/3.0, AEDAT 4.0,
    /// MVSEC HDF5; `-`: standard input); the format is detected from the content.
    #[arg(value_parser = super::input_path)]
    pub input: PathBuf,
    /// Output format.
    #[arg(long, value_enum)]
    pub to: To,
    /// Output file (`-`: standard output).
    #[arg(long)]
    pub out: PathBuf,
    /// Input format, overriding detection.
    #[arg(long, value_enum)]
    pub format: Option<Format>,
}

pub fn run(args: Args) -> Result<()> {
    crate::output::check_distinct(&[&args.input], &[("--out", &args.out)])?;
    convert(&args)
        .with_context(|| format!("convert {} -> {}", args.input.display(), args.out.display()))
}

/// Streams the events of the input into the output, a chunk at a time.
fn convert(args: &Args) -> Result<()> {
    let mut reader = formats::EventReader::open(&args.input, args.format, false)?;
    let mut out = AtomicFile::create(&args.out)?;
    let mut chunk = Vec::new();
    match args.to {
        To::Csv => {
            let mut w = formats::CsvWriter::new(out.writer(), &args.out)?;
            while reader.next_chunk(&mut chunk)? {
                w.push(&chunk)?;
            }
            w.finish()?;
        }
        To::Evt3 => {
            reader.complete_from_folder(Needs {
                size: true,
                intrinsics: false,
                gyro: false,
            })?;
            let (w, h) = match (reader.info.width, reader.info.height) {
                (Some(w), Some(h)) => (w, h),
                _ => extent(args, reader.info.format, reader.is_regular_file())?,
            };
            let path = args.out.clone();
            let mut w = Evt3Writer::new(out.writer(), &path, w, h);
            while reader.next_chunk(&mut chunk)? {
                w.push(&chunk)?;
            }
            w.finish()?;
        }
        To::Aer => {
            crate::aer_stream::stream_aer(&mut reader, &mut out, None, &[])?;
        }
    }
    out.commit()
}

/// The events' extent `(max x + 1, max y + 1)`, from a first pass over the input (which must
/// then be a regular file); `(1, 1)` without events.
fn extent(args: &Args, format: Format, regular: bool) -> Result<(u16, u16)> {
    if !regular {
        bail!(
            "{}: the sensor size is not in the file or a meta.json beside it, and finding it in the events would need a second pass over a pipe",
            args.input.display()
        );
    }
    let mut reader = formats::EventReader::open(&args.input, Some(format), false)?;
    let mut chunk = Vec::new();
    let (mut w, mut h) = (1u16, 1u16);
    while reader.next_chunk(&mut chunk)? {
        for e in &chunk {
            w = w.max(e.x.saturating_add(1));
            h = h.max(e.y.saturating_add(1));
        }
    }
    Ok((w, h))
}
