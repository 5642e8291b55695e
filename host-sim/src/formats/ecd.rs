//! Event Camera Dataset text files (also used by the synthetic sequences): `events.txt`
//! (`t x y p`, t in s), `imu.txt` (`t ax ay az gx gy gz`, m/s^2 and rad/s), `groundtruth.txt`
//! (`t px py pz qx qy qz qw`, the camera's pose in the world) and `calib.txt`
//! (`fx fy cx cy k1 k2 p1 p2 k3`).

use std::path::Path;

use anyhow::{anyhow, Context, Result};

use super::chunked::{self, TextLines};
use super::rotation::{CentralDifferences, Mat3};
use super::text::{self, buf_line_error, ws_fields, Lines};
use super::{GtSample, GyroSample, Intrinsics};

/// The line format of `events.txt`: one `t[s] x y p` per line (p = 1 ON, 0 OFF), times
/// converted to µs exactly.
pub(super) const EVENTS: text::LineFormat = text::LineFormat {
    sep: text::Separator::Whitespace,
    time: text::parse_seconds_us,
    header: false,
    expected: "`t x y p` (t in s, p = 0 or 1)",
};

/// The `N` numbers of a whitespace-separated line; `None` unless it holds exactly `N` finite
/// numbers.
fn numbers<const N: usize>(line: &[u8]) -> Option<[f64; N]> {
    let mut out = [0.0f64; N];
    let mut n = 0;
    for field in ws_fields(line) {
        *out.get_mut(n)? = text::parse_f64(field)?;
        n += 1;
    }
    (n == N).then_some(out)
}

const IMU_LINE: &str = "`t ax ay az gx gy gz` (7 numbers)";
const POSE_LINE: &str = "`t px py pz qx qy qz qw` (8 numbers)";

/// `imu.txt` (`t ax ay az gx gy gz`) a line at a time: the gyro columns, rad/s.
pub(super) struct ImuRows(TextLines);

impl ImuRows {
    pub(super) fn open(path: &Path) -> Result<Self> {
        TextLines::open(path).map(Self)
    }

    pub(super) fn next_sample(&mut self) -> Result<Option<GyroSample>> {
        if !self.0.next_line()? {
            return Ok(None);
        }
        let [t, _, _, _, gx, gy, gz] =
            numbers(self.0.line()).ok_or_else(|| self.0.error(IMU_LINE))?;
        Ok(Some(GyroSample {
            t_s: t,
            wx: gx,
            wy: gy,
            wz: gz,
        }))
    }
}

/// Reads `imu.txt` (`t ax ay az gx gy gz`): the gyro columns, rad/s.
pub(super) fn read_imu(path: &Path) -> Result<Vec<GyroSample>> {
    let mut rows = ImuRows::open(path)?;
    chunked::collect(|out| chunked::fill(out, || rows.next_sample()))
}

/// `groundtruth.txt` (`t px py pz qx qy qz qw`, camera-to-world) a line at a time, the
/// orientation differentiated as the poses come: yaw rate = camera-frame angular velocity about
/// y (see [`super::read_ground_truth`]), one sample per pose.
pub(super) struct PoseRates {
    lines: TextLines,
    diff: CentralDifferences,
    /// The end of the file was reached (and the last pose's rate given).
    done: bool,
}

impl PoseRates {
    pub(super) fn open(path: &Path) -> Result<Self> {
        Ok(Self {
            lines: TextLines::open(path)?,
            diff: CentralDifferences::default(),
            done: false,
        })
    }

    pub(super) fn next_sample(&mut self) -> Result<Option<GtSample>> {
        let path = |lines: &TextLines| lines.path().display().to_string();
        while !self.done {
            if !self.lines.next_line()? {
                self.done = true;
                return self.diff.finish().with_context(|| path(&self.lines));
            }
            let [t, _, _, _, qx, qy, qz, qw] =
                numbers(self.lines.line()).ok_or_else(|| self.lines.error(POSE_LINE))?;
            let r = Mat3::from_quaternion(qw, qx, qy, qz)
                .ok_or_else(|| anyhow!("{}: zero quaternion at t = {t} s", path(&self.lines)))?;
            if let Some(s) = self.diff.push(t, r).with_context(|| path(&self.lines))? {
                return Ok(Some(s));
            }
        }
        Ok(None)
    }
}

/// Reads `calib.txt` (`fx fy cx cy [k1 k2 p1 p2 k3]`): the pinhole part.
pub(super) fn read_calib(path: &Path) -> Result<Intrinsics> {
    let buf = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let (line_no, (off, line)) = Lines::new(&buf)
        .enumerate()
        .find(|(_, (_, l))| !text::is_blank_or_comment(l))
        .ok_or_else(|| anyhow!("{}: empty calibration file", path.display()))?;
    let v: Option<Vec<f64>> = ws_fields(line).map(text::parse_f64).collect();
    match v.as_deref() {
        Some([fx, fy, cx, cy, ..]) if *fx > 0.0 && *fy > 0.0 => Ok(Intrinsics {
            fx: *fx,
            fy: *fy,
            cx: *cx,
            cy: *cy,
        }),
        _ => Err(buf_line_error(
            path,
            &buf,
            off,
            line_no + 1,
            line,
            "`fx fy cx cy k1 k2 p1 p2 k3`",
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::rotation::yaw_rates_central;

    /// The numeric rows of a whitespace-separated file with exactly `n` columns, the file read
    /// whole: how `imu.txt` and `groundtruth.txt` were read before they streamed.
    fn rows_whole(path: &Path, n: usize, expected: &str) -> Result<Vec<Vec<f64>>> {
        let buf = std::fs::read(path)?;
        let mut out = Vec::new();
        for (line_no, (off, line)) in Lines::new(&buf).enumerate() {
            if text::is_blank_or_comment(line) {
                continue;
            }
            let row: Option<Vec<f64>> = ws_fields(line).map(text::parse_f64).collect();
            match row {
                Some(r) if r.len() == n => out.push(r),
                _ => return Err(buf_line_error(path, &buf, off, line_no + 1, line, expected)),
            }
        }
        Ok(out)
    }

    fn imu_whole(path: &Path) -> Result<Vec<GyroSample>> {
        Ok(rows_whole(path, 7, IMU_LINE)?
            .iter()
            .map(|r| GyroSample {
                t_s: r[0],
                wx: r[4],
                wy: r[5],
                wz: r[6],
            })
            .collect())
    }

    fn gt_whole(path: &Path) -> Result<Vec<GtSample>> {
        let mut poses = Vec::new();
        for r in rows_whole(path, 8, POSE_LINE)? {
            let m = Mat3::from_quaternion(r[7], r[4], r[5], r[6])
                .ok_or_else(|| anyhow!("{}: zero quaternion at t = {} s", path.display(), r[0]))?;
            poses.push((r[0], m));
        }
        yaw_rates_central(&poses).with_context(|| path.display().to_string())
    }

    fn gt_streamed(path: &Path) -> Result<Vec<GtSample>> {
        let mut r = PoseRates::open(path)?;
        chunked::collect(|out| chunked::fill(out, || r.next_sample()))
    }

    /// Same samples, or errors with the same text (returned).
    fn same<T: PartialEq>(a: Result<Vec<T>>, b: Result<Vec<T>>, what: &str) -> Option<String> {
        match (a, b) {
            (Ok(a), Ok(b)) => {
                assert!(a == b, "{what}: samples differ");
                None
            }
            (Err(a), Err(b)) => {
                assert_eq!(format!("{a:#}"), format!("{b:#}"), "{what}");
                Some(format!("{a:#}"))
            }
            (a, b) => panic!(
                "{what}: {:?} streamed, {:?} whole",
                a.map(|v| v.len()).map_err(|e| e.to_string()),
                b.map(|v| v.len()).map_err(|e| e.to_string())
            ),
        }
    }

    #[test]
    fn line_by_line_reads_what_the_whole_file_gave() {
        let dir = tempfile::tempdir().unwrap();
        let imu = |k: usize| {
            format!(
                "{:.6} 0.1 -9.8 0.2 0.01 {:.9} -0.02",
                k as f64 * 0.005,
                (k as f64 * 0.01).sin()
            )
        };
        let pose = |k: usize| {
            let a = (k as f64 * 0.003).sin();
            format!(
                "{:.6} 1 2 3 0 {:.12} 0 {:.12}",
                k as f64 * 0.001,
                (a / 2.0).sin(),
                (a / 2.0).cos()
            )
        };
        let body = |f: &dyn Fn(usize) -> String, n: usize, end: &str| -> String {
            let mut s = String::from("# comment\n\n");
            for k in 0..n {
                s.push_str(&f(k));
                s.push_str(if k % 1000 == 7 { "\r\n" } else { end });
                if k % 4096 == 5 {
                    s.push_str("  \t\n# more\n");
                }
            }
            s
        };
        // (case, content, part of the error)
        let mut cases: Vec<(&str, String, Option<&str>)> = vec![
            ("good", body(&imu, 30_000, "\n"), None),
            ("crlf", body(&imu, 30_000, "\r\n"), None),
            (
                "no final newline",
                body(&imu, 20_000, "\n").trim_end().to_string(),
                None,
            ),
            (
                "truncated",
                body(&imu, 20_000, "\n") + "12.5 1 2",
                Some("truncated line"),
            ),
            (
                "cr at the end",
                body(&imu, 20_000, "\n") + "12.5 1 2\r",
                Some("malformed line"),
            ),
            ("empty", String::new(), None),
        ];
        let mut bad = body(&imu, 20_000, "\n");
        let at = bad.len() / 2;
        bad.insert_str(bad[at..].find('\n').unwrap() + at + 1, "1.0 x 2\n");
        cases.push(("malformed", bad, Some("malformed line 100")));
        for (what, text, error) in &cases {
            let p = dir.path().join("imu.txt");
            std::fs::write(&p, text).unwrap();
            let e = same(read_imu(&p), imu_whole(&p), what);
            assert_eq!(e.is_some(), error.is_some(), "{what}: {e:?}");
            if let (Some(e), Some(part)) = (e, error) {
                assert!(e.contains(part), "{what}: {e}");
            }
        }
        let mut cases: Vec<(&str, String, Option<&str>)> = vec![
            ("poses", body(&pose, 30_000, "\n"), None),
            ("one pose", pose(0), Some("needs at least 2 poses")),
            (
                "truncated",
                body(&pose, 20_000, "\n") + "12.5 1 2",
                Some("truncated line"),
            ),
        ];
        let mut back = body(&pose, 20_000, "\n");
        back.push_str(&pose(10));
        back.push('\n');
        back.push_str(&body(&pose, 100, "\n"));
        cases.push(("time going back", back, Some("pose times must increase")));
        let mut zero = body(&pose, 20_000, "\n");
        zero.push_str("30.0 0 0 0 0 0 0 0\n");
        cases.push(("zero quaternion", zero, Some("zero quaternion at t = 30 s")));
        for (what, text, error) in &cases {
            let p = dir.path().join("groundtruth.txt");
            std::fs::write(&p, text).unwrap();
            let e = same(gt_streamed(&p), gt_whole(&p), what);
            assert_eq!(e.is_some(), error.is_some(), "{what}: {e:?}");
            if let (Some(e), Some(part)) = (e, error) {
                assert!(e.contains(part), "{what}: {e}");
            }
        }
    }
}
