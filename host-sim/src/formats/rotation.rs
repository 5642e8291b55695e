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

/// Yaw rates from camera-to-world orientations `(t_s, R_wc)` given one at a time, by central
/// differences at the interior samples: `log(R(t_{k-1})^T R(t_{k+1})) / (t_{k+1} - t_{k-1})` is
/// the camera-frame angular velocity at `t_k`; the yaw rate is its y component (camera y axis
/// points down; positive = turning right). The first and last samples use one-sided
/// differences. Holds the two latest poses: the rate at a pose is known once the next one came
/// ([`CentralDifferences::push`]), the last one's at the end ([`CentralDifferences::finish`]).
#[derive(Clone, Debug, Default)]
pub struct CentralDifferences {
    /// The pose before `at`.
    before: Option<(f64, Mat3)>,
    /// The latest pose.
    at: Option<(f64, Mat3)>,
    /// Poses so far.
    n: usize,
}

impl CentralDifferences {
    /// Adds the next pose: the yaw rate at the previous one, if any.
    ///
    /// # Errors
    /// When the times around the previous pose do not increase.
    pub fn push(&mut self, t: f64, r: Mat3) -> Result<Option<GtSample>> {
        self.n += 1;
        let rate = match self.at {
            Some(at) => Some(yaw_rate(self.before.unwrap_or(at), (t, r), at.0)?),
            None => None,
        };
        self.before = self.at;
        self.at = Some((t, r));
        Ok(rate)
    }

    /// After the last pose: the yaw rate at it.
    ///
    /// # Errors
    /// With fewer than 2 poses, or when the last two times do not increase.
    pub fn finish(&self) -> Result<Option<GtSample>> {
        match (self.before, self.at) {
            (Some(a), Some(b)) => Ok(Some(yaw_rate(a, b, b.0)?)),
            _ => bail!("needs at least 2 poses to differentiate, found {}", self.n),
        }
    }
}

/// The yaw rate at `t_k` from the poses `a` before and `b` after it.
fn yaw_rate((ta, ra): (f64, Mat3), (tb, rb): (f64, Mat3), t_k: f64) -> Result<GtSample> {
    let dt = tb - ta;
    if dt.is_nan() || dt <= 0.0 {
        bail!("pose times must increase (t = {ta} s then {tb} s)");
    }
    let w = ra.transpose_mul(&rb).log();
    Ok(GtSample {
        t_s: t_k,
        yaw_rate_rad_s: w[1] / dt,
    })
}

/// The derivation on a whole slice of poses, as the readers did before they streamed: the
/// reference of [`CentralDifferences`].
#[cfg(test)]
pub(super) fn yaw_rates_central(poses: &[(f64, Mat3)]) -> Result<Vec<GtSample>> {
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

    /// The poses given one at a time.
    fn streamed(poses: &[(f64, Mat3)]) -> Result<Vec<GtSample>> {
        let mut d = CentralDifferences::default();
        let mut out = Vec::new();
        for &(t, r) in poses {
            out.extend(d.push(t, r)?);
        }
        out.extend(d.finish()?);
        Ok(out)
    }

    #[test]
    fn streamed_equals_the_whole_slice_derivation() {
        let mut k = 0u64;
        let mut noise = || {
            k = k
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (k >> 11) as f64 / (1u64 << 53) as f64
        };
        for n in 0..12 {
            let mut t = 1.7e9 * (n % 2) as f64;
            let mut poses = Vec::new();
            for i in 0..n * 37 {
                // One repeated time (an interior one differentiates over two steps).
                if !(n % 4 == 1 && i == n * 18) {
                    t += 0.001 + 0.01 * noise();
                }
                let q = [noise() - 0.5, noise() - 0.5, noise() - 0.5, noise() + 0.1];
                poses.push((t, Mat3::from_quaternion(q[3], q[0], q[1], q[2]).unwrap()));
            }
            // Some with a time going back.
            if n % 3 == 2 {
                let i = poses.len() / 2;
                poses[i].0 -= 1.0;
            }
            match (yaw_rates_central(&poses), streamed(&poses)) {
                (Ok(a), Ok(b)) => assert_eq!(a, b, "{n}"),
                (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string(), "{n}"),
                (a, b) => panic!("{n}: {a:?} whole, {b:?} streamed"),
            }
        }
    }

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
