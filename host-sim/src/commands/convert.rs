//! `host-sim convert INPUT --to csv|evt3|aer --out FILE [--format F]`.
//!
//! - `csv`: `t_us,x,y,p` with a header line (p = 1 ON, 0 OFF), one line per event in stream
//!   order, times as in the input (AEDAT4: absolute Unix µs): byte-identical to the reference
//!   decodes in `shared/data/real`.
//! - `evt3`: a Prophesee EVT 3.0 `.raw` file with a header (sensor size from the input, else the
//!   events' extent). Inputs whose first event is at or after 2^24 µs keep their absolute time
//!   through a `% tde_time_offset_us` header line that this tool reads back.
//! - `aer`: the firmware's AER-over-SPI stream (`docs/wire-formats.md`), times relative to the
//!   first event, as the firmware and `host-sim run` count them.
//!
//! The output is written to a temporary file and renamed: a failed run leaves no output.

use std::path::PathBuf;

use anyhow::{Context, Result};

use crate::formats::{self, Format};

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
    /// MVSEC HDF5); the format is detected from the content.
    pub input: PathBuf,
    /// Output format.
    #[arg(long, value_enum)]
    pub to: To,
    /// Output file.
    #[arg(long)]
    pub out: PathBuf,
    /// Input format, overriding detection.
    #[arg(long, value_enum)]
    pub format: Option<Format>,
}

pub fn run(args: Args) -> Result<()> {
    let rec = formats::read(&args.input, args.format)?;
    match args.to {
        To::Csv => formats::write_csv(&rec.events, &args.out),
        To::Evt3 => formats::write_evt3(&rec.events, rec.width, rec.height, &args.out),
        To::Aer => crate::aer_stream::write_aer(&rec.events, &args.out).map(|_| ()),
    }
    .with_context(|| format!("convert {} -> {}", args.input.display(), args.out.display()))
}
