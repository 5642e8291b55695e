//! Event Camera Dataset text files (also used by the synthetic sequences): `events.txt`
//! (`t x y p`, t in s), `imu.txt` (`t ax ay az gx gy gz`, m/s^2 and rad/s), `groundtruth.txt`
//! (`t px py pz qx qy qz qw`, the camera's pose in the world) and `calib.txt`
//! (`fx fy cx cy k1 k2 p1 p2 k3`).

use std::path::Path;

use anyhow::{anyhow, Context, Result};

use super::rotation::{yaw_rates_central, Mat3};
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

/// Reads the numeric rows of a whitespace-separated file with exactly `n` columns.
fn rows(path: &Path, n: usize, expected: &str) -> Result<Vec<Vec<f64>>> {
    let buf = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
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

/// Reads `imu.txt` (`t ax ay az gx gy gz`): the gyro columns, rad/s.
pub(super) fn read_imu(path: &Path) -> Result<Vec<GyroSample>> {
    let rows = rows(path, 7, "`t ax ay az gx gy gz` (7 numbers)")?;
    Ok(rows
        .iter()
        .filter_map(|r| match r.as_slice() {
            [t, _, _, _, gx, gy, gz] => Some(GyroSample {
                t_s: *t,
                wx: *gx,
                wy: *gy,
                wz: *gz,
            }),
            _ => None,
        })
        .collect())
}

/// Reads `groundtruth.txt` (`t px py pz qx qy qz qw`, camera-to-world) and differentiates the
/// orientation: yaw rate = camera-frame angular velocity about y (see
/// [`super::read_ground_truth`]).
pub(super) fn read_ground_truth(path: &Path) -> Result<Vec<GtSample>> {
    let rows = rows(path, 8, "`t px py pz qx qy qz qw` (8 numbers)")?;
    let mut poses = Vec::with_capacity(rows.len());
    for r in &rows {
        if let [t, _, _, _, qx, qy, qz, qw] = r.as_slice() {
            let r = Mat3::from_quaternion(*qw, *qx, *qy, *qz)
                .ok_or_else(|| anyhow!("{}: zero quaternion at t = {t} s", path.display()))?;
            poses.push((*t, r));
        }
    }
    yaw_rates_central(&poses).with_context(|| path.display().to_string())
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
