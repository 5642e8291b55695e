//! CSV: events `t_us,x,y,p`, this project's ground truth `t_s,wx,wy,wz,...` and the AEDAT4 IMU
//! reference decode (`t_us,...,gyroscope_x,gyroscope_y,gyroscope_z,...` in deg/s).

use std::io::Write;
use std::path::Path;

use anyhow::{anyhow, Context, Result};

use super::text::{self, buf_line_error, csv_fields, Lines};
use super::{GtSample, GyroSample, HostEvent};

/// The header line written by [`write_csv`], identical to the reference decodes'.
pub const CSV_HEADER: &str = "t_us,x,y,p";

/// The line format of event CSV: `t_us,x,y,p` (header line optional; when present it names the
/// columns, in any order), `#` comments and blank lines skipped.
pub(super) const EVENTS: text::LineFormat = text::LineFormat {
    sep: text::Separator::Comma,
    time: text::parse_u64,
    header: true,
    expected: "`t_us,x,y,p` (integers, p = 0 or 1)",
};

/// Writes events as `t_us,x,y,p` with a header line, one line per event in the given order,
/// `p` = 1 for ON and 0 for OFF, `\n` line ends: the layout of the reference decodes in
/// `shared/data/real`. The file appears complete or not at all (temporary file, then rename).
///
/// # Errors
/// When the file cannot be written.
pub fn write_csv(events: &[HostEvent], out: &Path) -> Result<()> {
    crate::output::write_atomically(out, |w| {
        let mut csv = CsvWriter::new(w, out)?;
        csv.push(events)?;
        csv.finish()
    })
}

/// Writes events as CSV (see [`write_csv`]) to a byte stream, as they come.
pub struct CsvWriter<'w, W: Write> {
    w: &'w mut W,
    out: &'w Path,
    line: Vec<u8>,
}

impl<'w, W: Write> CsvWriter<'w, W> {
    /// Writes the header line into `w` (the content of `out`).
    ///
    /// # Errors
    /// When the file cannot be written.
    pub fn new(w: &'w mut W, out: &'w Path) -> Result<Self> {
        let mut line = Vec::with_capacity(64 * 1024);
        line.extend_from_slice(CSV_HEADER.as_bytes());
        line.push(b'\n');
        Ok(Self { w, out, line })
    }

    /// Writes the events.
    ///
    /// # Errors
    /// When the file cannot be written.
    pub fn push(&mut self, events: &[HostEvent]) -> Result<()> {
        let line = &mut self.line;
        for e in events {
            push_u64(line, e.t_us);
            line.push(b',');
            push_u64(line, u64::from(e.x));
            line.push(b',');
            push_u64(line, u64::from(e.y));
            line.extend_from_slice(if e.on { b",1\n" } else { b",0\n" });
            if line.len() >= 60 * 1024 {
                self.w
                    .write_all(line)
                    .with_context(|| format!("cannot write {}", self.out.display()))?;
                line.clear();
            }
        }
        Ok(())
    }

    /// Writes what is buffered.
    ///
    /// # Errors
    /// When the file cannot be written.
    pub fn finish(self) -> Result<()> {
        self.w
            .write_all(&self.line)
            .with_context(|| format!("cannot write {}", self.out.display()))
    }
}

/// Appends the decimal digits of `v`.
fn push_u64(out: &mut Vec<u8>, mut v: u64) {
    let mut digits = [0u8; 20];
    let mut n = 0;
    loop {
        if let Some(d) = digits.get_mut(n) {
            *d = b'0' + (v % 10) as u8;
        }
        n += 1;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    out.extend(digits.iter().take(n).rev());
}

/// Column index of `name` in a header.
fn column(names: &[String], name: &str) -> Option<usize> {
    names.iter().position(|n| n == name)
}

/// Reads a CSV with a header line and returns, for every data row, the numbers in the columns
/// named `wanted` (case-insensitive), in that order. `what` names those columns in errors.
fn read_columns<const N: usize>(
    path: &Path,
    wanted: [&str; N],
    what: &str,
) -> Result<Vec<[f64; N]>> {
    let buf = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut lines = Lines::new(&buf)
        .enumerate()
        .filter(|(_, (_, l))| !text::is_blank_or_comment(l));
    let (_, (_, header)) = lines
        .next()
        .ok_or_else(|| anyhow!("{}: empty file", path.display()))?;
    let names: Vec<String> = csv_fields(header)
        .map(|f| String::from_utf8_lossy(f).to_ascii_lowercase())
        .collect();
    let mut cols = [0usize; N];
    for (col, name) in cols.iter_mut().zip(wanted) {
        *col = column(&names, name)
            .ok_or_else(|| anyhow!("{}: header has no {what} columns", path.display()))?;
    }
    let mut out = Vec::new();
    for (line_no, (off, line)) in lines {
        let fields: Vec<&[u8]> = csv_fields(line).collect();
        let mut row = [0.0f64; N];
        for (v, &c) in row.iter_mut().zip(&cols) {
            *v = match fields.get(c).and_then(|f| text::parse_f64(f)) {
                Some(x) => x,
                None => {
                    return Err(buf_line_error(
                        path,
                        &buf,
                        off,
                        line_no + 1,
                        line,
                        &format!("numbers in the {what} columns"),
                    ))
                }
            };
        }
        out.push(row);
    }
    Ok(out)
}

/// Reads this project's `gt.csv`: yaw rate = `wy` (camera y axis, down; positive = turning
/// right).
pub(super) fn read_gt(path: &Path) -> Result<Vec<GtSample>> {
    Ok(read_columns(path, ["t_s", "wy"], "`t_s` and `wy`")?
        .into_iter()
        .map(|[t_s, wy]| GtSample {
            t_s,
            yaw_rate_rad_s: wy,
        })
        .collect())
}

/// Reads an IMU CSV with `t_us` and `gyroscope_x/y/z` (deg/s) columns.
pub(super) fn read_imu_csv(path: &Path) -> Result<Vec<GyroSample>> {
    let cols = ["t_us", "gyroscope_x", "gyroscope_y", "gyroscope_z"];
    Ok(read_columns(path, cols, "`t_us` and `gyroscope_x/y/z`")?
        .into_iter()
        .map(|[t, x, y, z]| GyroSample {
            t_s: t * 1e-6,
            wx: x.to_radians(),
            wy: y.to_radians(),
            wz: z.to_radians(),
        })
        .collect())
}
