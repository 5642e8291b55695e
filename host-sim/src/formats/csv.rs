//! CSV: events `t_us,x,y,p`, this project's ground truth `t_s,wx,wy,wz,...` and the AEDAT4 IMU
//! reference decode (`t_us,...,gyroscope_x,gyroscope_y,gyroscope_z,...` in deg/s).

use std::io::Write;
use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};

use super::chunked::TextLines;
use super::text::{self, csv_fields};
use super::{Event64, GtSample, GyroSample};

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
pub fn write_csv(events: &[Event64], out: &Path) -> Result<()> {
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
    pub fn push(&mut self, events: &[Event64]) -> Result<()> {
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

/// A CSV with a header line, read a row at a time: for every data row, the numbers in the
/// columns named `wanted` (case-insensitive), in that order; blank lines and `#` comments
/// skipped.
pub(super) struct ColumnRows<const N: usize> {
    lines: TextLines,
    cols: [usize; N],
    /// The columns, as named in errors.
    what: &'static str,
}

impl<const N: usize> ColumnRows<N> {
    /// Opens `path` and finds the columns in its header; `what` names them in errors.
    fn open(path: &Path, wanted: [&str; N], what: &'static str) -> Result<Self> {
        let mut lines = TextLines::open(path)?;
        if !lines.next_line()? {
            bail!("{}: empty file", path.display());
        }
        let names: Vec<String> = csv_fields(lines.line())
            .map(|f| String::from_utf8_lossy(f).to_ascii_lowercase())
            .collect();
        let mut cols = [0usize; N];
        for (col, name) in cols.iter_mut().zip(wanted) {
            *col = column(&names, name)
                .ok_or_else(|| anyhow!("{}: header has no {what} columns", path.display()))?;
        }
        Ok(Self { lines, cols, what })
    }

    /// The numbers of the next row; `None` at the end of the file.
    fn next_row(&mut self) -> Result<Option<[f64; N]>> {
        if !self.lines.next_line()? {
            return Ok(None);
        }
        let mut row = [None; N];
        let last = self.cols.iter().copied().max().unwrap_or(0);
        for (i, field) in csv_fields(self.lines.line()).enumerate().take(last + 1) {
            for (v, &c) in row.iter_mut().zip(&self.cols) {
                if c == i {
                    *v = text::parse_f64(field);
                }
            }
        }
        let mut out = [0.0f64; N];
        for (o, v) in out.iter_mut().zip(row) {
            *o = v.ok_or_else(|| {
                self.lines
                    .error(&format!("numbers in the {} columns", self.what))
            })?;
        }
        Ok(Some(out))
    }
}

/// This project's `gt.csv`, a row at a time: yaw rate = `wy` (camera y axis, down; positive =
/// turning right).
pub(super) struct GtRows(ColumnRows<2>);

impl GtRows {
    pub(super) fn open(path: &Path) -> Result<Self> {
        ColumnRows::open(path, ["t_s", "wy"], "`t_s` and `wy`").map(Self)
    }

    pub(super) fn next_sample(&mut self) -> Result<Option<GtSample>> {
        Ok(self.0.next_row()?.map(|[t_s, wy]| GtSample {
            t_s,
            yaw_rate_rad_s: wy,
        }))
    }
}

/// An IMU CSV with `t_us` and `gyroscope_x/y/z` (deg/s) columns, a row at a time.
pub(super) struct ImuCsvRows(ColumnRows<4>);

impl ImuCsvRows {
    pub(super) fn open(path: &Path) -> Result<Self> {
        let cols = ["t_us", "gyroscope_x", "gyroscope_y", "gyroscope_z"];
        ColumnRows::open(path, cols, "`t_us` and `gyroscope_x/y/z`").map(Self)
    }

    pub(super) fn next_sample(&mut self) -> Result<Option<GyroSample>> {
        Ok(self.0.next_row()?.map(|[t, x, y, z]| GyroSample {
            t_s: t * 1e-6,
            wx: x.to_radians(),
            wy: y.to_radians(),
            wz: z.to_radians(),
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::chunked;
    use crate::formats::text::{buf_line_error, Lines};

    /// The columns `wanted` of every row, the file read whole: how `gt.csv` and IMU CSVs were
    /// read before they streamed.
    fn read_columns<const N: usize>(
        path: &Path,
        wanted: [&str; N],
        what: &str,
    ) -> Result<Vec<[f64; N]>> {
        let buf = std::fs::read(path)?;
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
                *v = fields
                    .get(c)
                    .and_then(|f| text::parse_f64(f))
                    .ok_or_else(|| {
                        let expected = format!("numbers in the {what} columns");
                        buf_line_error(path, &buf, off, line_no + 1, line, &expected)
                    })?;
            }
            out.push(row);
        }
        Ok(out)
    }

    #[test]
    fn row_by_row_reads_what_the_whole_file_gave() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("gt.csv");
        let rows = |n: usize| -> String {
            (0..n)
                .map(|k| {
                    let end = if k % 999 == 3 { "\r\n" } else { "\n" };
                    let extra = if k % 5000 == 1 { "# comment\n\n" } else { "" };
                    format!(
                        "{extra}{:.6}, 0,{:.9} ,0,1{end}",
                        k as f64 * 1e-3,
                        (k as f64).sin()
                    )
                })
                .collect()
        };
        let header = "# made here\nt_s,wx,WY,wz,speed\n";
        let cases: [(&str, String, Option<&str>); 7] = [
            ("good", format!("{header}{}", rows(25_000)), None),
            ("empty", "\n# nothing\n".into(), Some("empty file")),
            (
                "no wy",
                format!("t_s,wx\n{}", rows(3)),
                Some("header has no"),
            ),
            (
                "short row",
                format!("{header}{}0.5,0\n", rows(20_000)),
                Some("malformed line"),
            ),
            (
                "truncated",
                format!("{header}{}0.5,0", rows(20_000)),
                Some("truncated line"),
            ),
            (
                "bad number",
                format!("{header}{}0.5,0,x,0\n{}", rows(9_000), rows(10)),
                Some("malformed line"),
            ),
            (
                "infinite",
                format!("{header}{}0.5,0,inf,0\n", rows(10)),
                Some("malformed line"),
            ),
        ];
        for (what, text, error) in cases {
            std::fs::write(&p, text).unwrap();
            let mut r = GtRows::open(&p);
            let streamed = r
                .as_mut()
                .map_err(|e| anyhow!("{e:#}"))
                .and_then(|r| chunked::collect(|out| chunked::fill(out, || r.next_sample())));
            let whole = read_columns(&p, ["t_s", "wy"], "`t_s` and `wy`");
            match (streamed, whole) {
                (Ok(a), Ok(b)) => {
                    assert!(error.is_none(), "{what}");
                    assert_eq!(a.len(), b.len(), "{what}");
                    assert!(a
                        .iter()
                        .zip(&b)
                        .all(|(s, &[t, wy])| s.t_s == t && s.yaw_rate_rad_s == wy));
                }
                (Err(a), Err(b)) => {
                    let (a, b) = (format!("{a:#}"), format!("{b:#}"));
                    assert_eq!(a, b, "{what}");
                    assert!(a.contains(error.unwrap()), "{what}: {a}");
                }
                (a, b) => panic!(
                    "{what}: {:?} vs {:?}",
                    a.map(|v| v.len()),
                    b.map(|v| v.len())
                ),
            }
        }
    }
}
