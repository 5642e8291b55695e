//! Rotations for ground truth: camera-frame angular velocity from a sequence of orientations.

use anyhow::{bail, Result};

use super::GtSample;

/// A 3x3 matrix, row-major.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mat3(pub [[f64; 3]; 3]);

impl Mat3 {
    /// The rotation of the unit quaternion `w + xi + yj + zk` (normalised here); `None` for a
    /// zero or non-finite quaternion.
    pub fn from_quaternion(w: f64, x: f64, y: f64, z: f64) -> Option<Self> {
        let n = (w * w + x * x + y * y + z * z).sqrt();
        if n.is_nan() || n <= 1e-12 || !n.is_finite() {
            return None;
        }
        let (w, x, y, z) = (w / n, x / n, y / n, z / n);
        Some(Self([
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - w * z),
                2.0 * (x * z + w * y),
            ],
            [
                2.0 * (x * y + w * z),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - w * x),
            ],
            [
                2.0 * (x * z - w * y),
                2.0 * (y * z + w * x),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ]))
    }

    /// `self^T * other`.
    pub fn transpose_mul(&self, other: &Self) -> Self {
        let a = &self.0;
        let b = &other.0;
        let mut out = [[0.0; 3]; 3];
        for (i, row) in out.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = (0..3).map(|k| a[k][i] * b[k][j]).sum();
            }
        }
        Self(out)
    }

    /// The rotation vector (axis * angle, rad) of a rotation matrix: its logarithm.
    pub fn log(&self) -> [f64; 3] {
        let m = &self.0;
        // v = sin(theta) * axis from the skew-symmetric part.
        let v = [
            (m[2][1] - m[1][2]) / 2.0,
            (m[0][2] - m[2][0]) / 2.0,
            (m[1][0] - m[0][1]) / 2.0,
        ];
        let s = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let c = ((m[0][0] + m[1][1] + m[2][2] - 1.0) / 2.0).clamp(-1.0, 1.0);
        let theta = s.atan2(c);
        let k = if s < 1e-12 { 1.0 } else { theta / s };
        [v[0] * k, v[1] * k, v[2] * k]
    }
}

/// Yaw rates from camera-to-world orientations `(t_s, R_wc)`, by central differences at the
/// interior samples: `log(R(t_{k-1})^T R(t_{k+1})) / (t_{k+1} - t_{k-1})` is the camera-frame
/// angular velocity at `t_k`; the yaw rate is its y component (camera y axis points down; positive
/// = turning right). The first and last samples use one-sided differences.
pub fn yaw_rates_central(poses: &[(f64, Mat3)]) -> Result<Vec<GtSample>> {
    if poses.len() < 2 {
        bail!(
            "needs at least 2 poses to differentiate, found {}",
            poses.len()
        );
    }
    let n = poses.len();
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
        let (Some((ta, ra)), Some((tb, rb)), Some((tk, _))) =
            (poses.get(a), poses.get(b), poses.get(k))
        else {
            continue;
        };
        let dt = tb - ta;
        if dt.is_nan() || dt <= 0.0 {
            bail!("pose times must increase (t = {ta} s then {tb} s)");
        }
        let w = ra.transpose_mul(rb).log();
        out.push(GtSample {
            t_s: *tk,
            yaw_rate_rad_s: w[1] / dt,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rotation about y by `a` (camera turning right for a > 0: z goes towards +x).
    fn ry(a: f64) -> Mat3 {
        Mat3([
            [a.cos(), 0.0, a.sin()],
            [0.0, 1.0, 0.0],
            [-a.sin(), 0.0, a.cos()],
        ])
    }

    #[test]
    fn constant_yaw_rate() {
        let poses: Vec<(f64, Mat3)> = (0..100)
            .map(|i| (i as f64 * 0.01, ry(0.3 * i as f64 * 0.01)))
            .collect();
        let gt = yaw_rates_central(&poses).unwrap();
        assert_eq!(gt.len(), 100);
        for s in gt {
            assert!((s.yaw_rate_rad_s - 0.3).abs() < 1e-9, "{s:?}");
        }
    }

    #[test]
    fn quaternion_about_y() {
        let a: f64 = 0.2;
        let q = Mat3::from_quaternion((a / 2.0).cos(), 0.0, (a / 2.0).sin(), 0.0).unwrap();
        let r = ry(a);
        for i in 0..3 {
            for j in 0..3 {
                assert!((q.0[i][j] - r.0[i][j]).abs() < 1e-12);
            }
        }
        assert!((r.log()[1] - a).abs() < 1e-12);
    }
}
