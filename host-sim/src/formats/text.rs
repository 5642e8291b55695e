//! Shared helpers for the text formats: classification from the first line, a line iterator
//! that knows byte offsets, and exact number parsing.

use std::path::Path;

use anyhow::{anyhow, bail, Error};

use super::Event64;

/// What the first meaningful line of a text file looks like.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// `t_us,x,y,p` header or 4 numeric comma-separated fields.
    EventsCsv,
    /// 4 numeric whitespace-separated fields (`t x y p`).
    EventsText,
    /// `t_s,...,wy,...` header (this project's ground truth).
    GtCsv,
    /// 7 numeric whitespace-separated fields (`t ax ay az gx gy gz`).
    ImuText,
    /// 8 numeric whitespace-separated fields (`t px py pz qx qy qz qw`).
    PoseText,
    /// A CSV header with `gyroscope_x` (AEDAT4 IMU reference decode).
    ImuCsv,
    /// Anything else.
    Unknown,
}

/// Classifies a text file from its first bytes.
pub fn classify(head: &[u8]) -> Kind {
    let Some((_, line)) = Lines::new(head).find(|(_, l)| !is_blank_or_comment(l)) else {
        return Kind::Unknown;
    };
    let Ok(line) = std::str::from_utf8(line) else {
        return Kind::Unknown;
    };
    if line.contains(',') {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.iter().all(|f| f.parse::<f64>().is_ok()) {
            return if fields.len() == 4 {
                Kind::EventsCsv
            } else {
                Kind::Unknown
            };
        }
        let names: Vec<String> = fields.iter().map(|f| f.to_ascii_lowercase()).collect();
        let has = |n: &str| names.iter().any(|f| f == n);
        if names
            .first()
            .is_some_and(|f| f == "t_us" || f == "t" || f == "timestamp")
            && has("x")
            && has("y")
            && (has("p") || has("polarity"))
        {
            return Kind::EventsCsv;
        }
        if names.first().is_some_and(|f| f == "t_s") && has("wy") {
            return Kind::GtCsv;
        }
        if has("gyroscope_x") && has("gyroscope_y") && has("gyroscope_z") {
            return Kind::ImuCsv;
        }
        return Kind::Unknown;
    }
    let fields: Vec<&str> = line.split_ascii_whitespace().collect();
    if !fields.iter().all(|f| f.parse::<f64>().is_ok()) {
        return Kind::Unknown;
    }
    match fields.len() {
        4 => Kind::EventsText,
        7 => Kind::ImuText,
        8 => Kind::PoseText,
        _ => Kind::Unknown,
    }
}

/// Whether a line is empty, whitespace or a `#` comment.
pub fn is_blank_or_comment(line: &[u8]) -> bool {
    match line.iter().position(|b| !b.is_ascii_whitespace()) {
        None => true,
        Some(i) => line.get(i) == Some(&b'#'),
    }
}

/// Lines of a byte buffer with the byte offset of each line's start; `\r\n` endings accepted.
pub struct Lines<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl<'a> Lines<'a> {
    pub fn new(buf: &'a [u8]) -> Self {
        Self { buf, pos: 0 }
    }
}

impl<'a> Iterator for Lines<'a> {
    type Item = (usize, &'a [u8]);

    fn next(&mut self) -> Option<Self::Item> {
        let rest = self.buf.get(self.pos..)?;
        if rest.is_empty() {
            return None;
        }
        let start = self.pos;
        let (line, advance) = match rest.iter().position(|&b| b == b'\n') {
            Some(i) => (rest.get(..i).unwrap_or_default(), i + 1),
            None => (rest, rest.len()),
        };
        self.pos += advance;
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        Some((start, line))
    }
}

/// Splits a line on ASCII whitespace.
pub fn ws_fields(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| *b == b' ' || *b == b'\t')
        .filter(|f| !f.is_empty())
}

/// Splits a line on commas, trimming spaces.
pub fn csv_fields(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| *b == b',').map(|f| f.trim_ascii())
}

/// An unsigned decimal integer (no sign, no spaces).
pub fn parse_u64(s: &[u8]) -> Option<u64> {
    if s.is_empty() || s.len() > 20 {
        return None;
    }
    let mut v: u64 = 0;
    for &b in s {
        let d = b.wrapping_sub(b'0');
        if d > 9 {
            return None;
        }
        v = v.checked_mul(10)?.checked_add(u64::from(d))?;
    }
    Some(v)
}

/// A pixel coordinate (`0 ..= 65535`; a trailing `.0` is accepted).
pub fn parse_u16(s: &[u8]) -> Option<u16> {
    let s = s.strip_suffix(b".0").unwrap_or(s);
    parse_u64(s).and_then(|v| u16::try_from(v).ok())
}

/// A polarity: `1`/`+1`/`1.0`/`true` = ON, `0`/`-1`/`0.0`/`-1.0`/`false` = OFF.
pub fn parse_polarity(s: &[u8]) -> Option<bool> {
    match s {
        b"1" | b"+1" | b"1.0" | b"true" | b"True" => Some(true),
        b"0" | b"-1" | b"0.0" | b"-1.0" | b"false" | b"False" => Some(false),
        _ => None,
    }
}

/// A float.
pub fn parse_f64(s: &[u8]) -> Option<f64> {
    std::str::from_utf8(s)
        .ok()?
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
}

/// Non-negative seconds to µs: exact for plain decimals (digits beyond the 6th decimal round
/// half up), else through `f64` rounded to the nearest µs.
pub fn parse_seconds_us(s: &[u8]) -> Option<u64> {
    let (int, frac) = match s.iter().position(|&b| b == b'.') {
        Some(i) => (s.get(..i)?, s.get(i + 1..)?),
        None => (s, &b""[..]),
    };
    let plain = frac.iter().all(u8::is_ascii_digit) && int.iter().all(u8::is_ascii_digit);
    if plain && !(int.is_empty() && frac.is_empty()) {
        let whole = if int.is_empty() { 0 } else { parse_u64(int)? };
        let mut us: u64 = 0;
        for i in 0..6 {
            let d = frac.get(i).map_or(0, |b| u64::from(b - b'0'));
            us = us * 10 + d;
        }
        let round_up = frac.get(6).is_some_and(|&b| b >= b'5');
        return whole
            .checked_mul(1_000_000)?
            .checked_add(us + u64::from(round_up));
    }
    let v = parse_f64(s)?;
    seconds_to_us(v)
}

/// Non-negative finite seconds to µs, rounded to the nearest µs.
pub fn seconds_to_us(v: f64) -> Option<u64> {
    if v.is_nan() || v < 0.0 || !v.is_finite() {
        return None;
    }
    let us = (v * 1e6).round();
    if us >= 1.8e19 {
        return None;
    }
    Some(us as u64)
}

/// How the fields of an event line are separated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Separator {
    /// Commas ([`csv_fields`]).
    Comma,
    /// Spaces or tabs ([`ws_fields`]).
    Whitespace,
}

/// Longest line an event file may hold (bytes): the reader keeps at most this much of a line in
/// memory, so a file without line ends is an error, not an unbounded allocation.
pub const MAX_LINE: usize = 64 * 1024;

/// Bytes read from the file at a time.
const READ_BYTES: usize = 256 * 1024;

/// Where each of `T X Y P` sits in a line: `order[k]` is the field index of the k-th quantity.
type Columns = [usize; 4];

/// The columns of a CSV header naming `t_us` (or `t`, `timestamp`), `x`, `y` and `p` (or
/// `polarity`) in any order, case-insensitive; `None` when the line names anything else.
fn header_columns(line: &[u8]) -> Option<Columns> {
    let names: Vec<String> = csv_fields(line)
        .map(|f| String::from_utf8_lossy(f).to_ascii_lowercase())
        .collect();
    if names.len() != 4 {
        return None;
    }
    let find = |aliases: &[&str]| names.iter().position(|n| aliases.contains(&n.as_str()));
    let cols = [
        find(&["t_us", "t", "timestamp"])?,
        find(&["x"])?,
        find(&["y"])?,
        find(&["p", "polarity"])?,
    ];
    let mut seen = [false; 4];
    for &c in &cols {
        *seen.get_mut(c)? = true;
    }
    seen.iter().all(|&s| s).then_some(cols)
}

/// The event of one line: exactly four fields, in the order `cols` gives; `time` parses the
/// time field to µs.
fn event_of<'l>(
    f: impl Iterator<Item = &'l [u8]>,
    cols: &Columns,
    time: fn(&[u8]) -> Option<u64>,
) -> Option<Event64> {
    let mut fields: [&[u8]; 4] = [&[]; 4];
    let mut n = 0;
    for field in f {
        *fields.get_mut(n)? = field;
        n += 1;
    }
    if n != 4 {
        return None;
    }
    let [ct, cx, cy, cp] = *cols;
    let t_us = time(fields.get(ct)?)?;
    let x = parse_u16(fields.get(cx)?)?;
    let y = parse_u16(fields.get(cy)?)?;
    let on = parse_polarity(fields.get(cp)?)?;
    Some(Event64 { t_us, x, y, on })
}

/// What an event-line file looks like: the separator, the time parser, whether a CSV header
/// line may come first, and what a line should hold (for errors).
#[derive(Clone, Copy, Debug)]
pub struct LineFormat {
    /// Field separator.
    pub sep: Separator,
    /// Turns the time field into µs.
    pub time: fn(&[u8]) -> Option<u64>,
    /// A first line starting with a letter is a header naming the columns (CSV).
    pub header: bool,
    /// What a line should hold, for error messages.
    pub expected: &'static str,
}

/// Reads one event per line (`T X Y P` in the order of the header, if any; blank lines and `#`
/// comments skipped) from any byte stream, a chunk at a time, in memory bounded by
/// [`MAX_LINE`] plus the read buffer. A bad line is an error naming the file, line and byte
/// offset.
pub struct EventLines<R> {
    r: R,
    path: std::path::PathBuf,
    fmt: LineFormat,
    cols: Columns,
    buf: Vec<u8>,
    /// Start of the unconsumed bytes in `buf`.
    pos: usize,
    /// File offset of `buf[0]`.
    base: u64,
    line_no: usize,
    first: bool,
    eof: bool,
}

impl<R: std::io::Read> EventLines<R> {
    /// A reader of `r` (the content of `path`).
    pub fn new(r: R, path: &Path, fmt: LineFormat) -> Self {
        Self {
            r,
            path: path.to_path_buf(),
            fmt,
            cols: [0, 1, 2, 3],
            buf: Vec::with_capacity(READ_BYTES + MAX_LINE),
            pos: 0,
            base: 0,
            line_no: 0,
            first: true,
            eof: false,
        }
    }

    /// Appends up to `max` events to `out`; returns `false` once the input is exhausted and
    /// nothing was appended.
    pub fn next_chunk(&mut self, out: &mut Vec<Event64>, max: usize) -> anyhow::Result<bool> {
        let start_len = out.len();
        while out.len() - start_len < max {
            let rest = self.buf.get(self.pos..).unwrap_or_default();
            let (line, advance, last) = match rest.iter().position(|&b| b == b'\n') {
                Some(i) => (rest.get(..i).unwrap_or_default(), i + 1, false),
                None if self.eof => {
                    if rest.is_empty() {
                        break;
                    }
                    (rest, rest.len(), true)
                }
                None => {
                    self.refill()?;
                    continue;
                }
            };
            let offset = self.base + self.pos as u64;
            self.line_no += 1;
            let line = line.strip_suffix(b"\r").unwrap_or(line);
            if !is_blank_or_comment(line) {
                let is_first = std::mem::replace(&mut self.first, false);
                let parsed = match self.fmt.sep {
                    Separator::Comma => event_of(csv_fields(line), &self.cols, self.fmt.time),
                    Separator::Whitespace => event_of(ws_fields(line), &self.cols, self.fmt.time),
                };
                match parsed {
                    Some(e) => out.push(e),
                    None if self.fmt.header
                        && is_first
                        && line.first().is_some_and(u8::is_ascii_alphabetic) =>
                    {
                        self.cols = header_columns(line).ok_or_else(|| {
                            let shown: String =
                                String::from_utf8_lossy(line).chars().take(60).collect();
                            anyhow!(
                                "{}: malformed header line {} at byte {offset}: expected the four columns t_us, x, y, p (in any order), found `{shown}`",
                                self.path.display(),
                                self.line_no
                            )
                        })?;
                    }
                    None => {
                        return Err(line_error(
                            &self.path,
                            offset,
                            self.line_no,
                            line,
                            self.fmt.expected,
                            last,
                        ))
                    }
                }
            }
            self.pos += advance;
        }
        Ok(out.len() > start_len)
    }

    /// Drops the consumed bytes and reads more; errors on a line longer than [`MAX_LINE`].
    fn refill(&mut self) -> anyhow::Result<()> {
        use anyhow::Context;
        self.buf.drain(..self.pos);
        self.base += self.pos as u64;
        self.pos = 0;
        if self.buf.len() > MAX_LINE {
            bail!(
                "{}: line {} at byte {} is longer than {MAX_LINE} bytes (not a text event file?)",
                self.path.display(),
                self.line_no + 1,
                self.base
            );
        }
        let have = self.buf.len();
        self.buf.resize(have + READ_BYTES, 0);
        let n = super::read_up_to(&mut self.r, self.buf.get_mut(have..).unwrap_or_default())
            .with_context(|| format!("cannot read {}", self.path.display()));
        let n = match n {
            Ok(n) => n,
            Err(e) => {
                self.buf.truncate(have);
                return Err(e);
            }
        };
        self.buf.truncate(have + n);
        if n == 0 {
            self.eof = true;
        }
        Ok(())
    }
}

/// Error for a malformed line: names the file, the line number (1-based) and its byte offset;
/// `last` (the file's last line, without its newline) is reported as truncated.
pub fn line_error(
    path: &Path,
    offset: u64,
    line_no: usize,
    line: &[u8],
    expected: &str,
    last: bool,
) -> Error {
    let shown: String = String::from_utf8_lossy(line).chars().take(60).collect();
    let what = if last { "truncated" } else { "malformed" };
    anyhow!(
        "{}: {what} line {line_no} at byte {offset}: expected {expected}, found `{shown}`",
        path.display()
    )
}

/// [`line_error`] for a line of a file read whole into `buf`.
pub fn buf_line_error(
    path: &Path,
    buf: &[u8],
    offset: usize,
    line_no: usize,
    line: &[u8],
    expected: &str,
) -> Error {
    let last = offset.saturating_add(line.len()) >= buf.len() && !buf.ends_with(b"\n");
    line_error(path, offset as u64, line_no, line, expected, last)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seconds_exact() {
        assert_eq!(parse_seconds_us(b"0.000204"), Some(204));
        assert_eq!(parse_seconds_us(b"1.5"), Some(1_500_000));
        assert_eq!(parse_seconds_us(b"12"), Some(12_000_000));
        assert_eq!(parse_seconds_us(b"0.0000005"), Some(1));
        assert_eq!(parse_seconds_us(b"0.0000004999"), Some(0));
        assert_eq!(
            parse_seconds_us(b"1403636579.758555"),
            Some(1_403_636_579_758_555)
        );
        assert_eq!(parse_seconds_us(b"2.04e-4"), Some(204));
        assert_eq!(parse_seconds_us(b"-1"), None);
        assert_eq!(parse_seconds_us(b"."), None);
        assert_eq!(parse_seconds_us(b"abc"), None);
    }

    #[test]
    fn classify_lines() {
        assert_eq!(classify(b"t_us,x,y,p\n1,2,3,1\n"), Kind::EventsCsv);
        assert_eq!(classify(b"1,2,3,1\n"), Kind::EventsCsv);
        assert_eq!(classify(b"0.000204 283 244 1\n"), Kind::EventsText);
        assert_eq!(classify(b"t_s,wx,wy,wz,yaw_rad\n"), Kind::GtCsv);
        assert_eq!(classify(b"0.0 1 2 3 4 5 6\n"), Kind::ImuText);
        assert_eq!(classify(b"0.0 1 2 3 0 0 0 1\n"), Kind::PoseText);
        assert_eq!(classify(b"\x00\x01binary"), Kind::Unknown);
    }
}
