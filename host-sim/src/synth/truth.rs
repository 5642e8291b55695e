//! Ground truth (angular velocity and attitude at a fixed rate) and the simulated IMU (gyro and
//! accelerometer with constant bias and white noise), both in the camera frame.

use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::motion::{mat_vec, transpose, MotionSpec};
use super::rng;

/// Standard gravity, m/s^2 (world +y is down).
pub const GRAVITY: f64 = 9.81;

/// One ground-truth sample (a row of `gt.csv`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GtRow {
    /// Time, s.
    pub t_s: f64,
    /// Camera-frame angular velocity, rad/s (x right, y down, z forward); `wy` is the yaw rate,
    /// > 0 = turning right.
    pub w: [f64; 3],
    /// Integral of `wy` from t = 0, rad.
    pub yaw_rad: f64,
    /// Heading (Euler angle about world y), rad.
    pub heading_rad: f64,
    /// Pitch, rad (> 0 nose up).
    pub pitch_rad: f64,
    /// Roll, rad (> 0 right side down).
    pub roll_rad: f64,
    /// Forward speed, m/s.
    pub speed_mps: f64,
}

/// One IMU sample (a row of `imu.txt`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImuRow {
    /// Time, s.
    pub t_s: f64,
    /// Specific force in the camera frame, m/s^2 (at rest: `(0, -9.81, 0)`).
    pub acc: [f64; 3],
    /// Angular velocity in the camera frame, rad/s.
    pub gyro: [f64; 3],
}

/// IMU error model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImuParams {
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Magnitude of the constant gyro bias per axis (random sign), rad/s.
    pub gyro_bias: f64,
    /// Gyro white-noise density, rad/s/sqrt(Hz).
    pub gyro_noise_density: f64,
    /// Magnitude of the constant accelerometer bias per axis (random sign), m/s^2.
    pub acc_bias: f64,
    /// Accelerometer white-noise density, m/s^2/sqrt(Hz).
    pub acc_noise_density: f64,
}

impl Default for ImuParams {
    fn default() -> Self {
        Self {
            rate_hz: 1000.0,
            gyro_bias: 0.01,
            gyro_noise_density: 0.00015,
            acc_bias: 0.05,
            acc_noise_density: 0.004,
        }
    }
}

/// Sample times `k / rate` for `k = 0 ..= round(duration * rate)`, s.
fn times(duration_s: f64, rate_hz: f64) -> impl Iterator<Item = f64> {
    let n = (duration_s * rate_hz).round() as u64;
    (0..=n).map(move |k| k as f64 / rate_hz)
}

/// Ground truth of `motion` at `rate_hz` over `[0, duration_s]`. `yaw_rad` integrates `wy` with
/// Simpson's rule on each sample interval.
pub fn ground_truth(motion: &MotionSpec, duration_s: f64, rate_hz: f64) -> Vec<GtRow> {
    let mut rows = Vec::new();
    let mut yaw = 0.0;
    let mut prev_t = 0.0;
    for t in times(duration_s, rate_hz) {
        if t > 0.0 {
            let mid = 0.5 * (prev_t + t);
            yaw += (t - prev_t) / 6.0
                * (motion.omega_cam(prev_t)[1]
                    + 4.0 * motion.omega_cam(mid)[1]
                    + motion.omega_cam(t)[1]);
        }
        prev_t = t;
        let [heading, pitch, roll] = motion.angles(t);
        rows.push(GtRow {
            t_s: t,
            w: motion.omega_cam(t),
            yaw_rad: yaw,
            heading_rad: heading,
            pitch_rad: pitch,
            roll_rad: roll,
            speed_mps: motion.speed.at(t),
        });
    }
    rows
}

/// The simulated IMU. Returns the samples and the drawn `(gyro_bias, acc_bias)` per axis.
pub fn imu(
    motion: &MotionSpec,
    duration_s: f64,
    params: &ImuParams,
    rng_imu: &mut ChaCha8Rng,
) -> (Vec<ImuRow>, [f64; 3], [f64; 3]) {
    let gb: [f64; 3] = std::array::from_fn(|_| params.gyro_bias * rng::sign(rng_imu));
    let ab: [f64; 3] = std::array::from_fn(|_| params.acc_bias * rng::sign(rng_imu));
    let gs = params.gyro_noise_density * params.rate_hz.sqrt();
    let as_ = params.acc_noise_density * params.rate_hz.sqrt();
    let rows = times(duration_s, params.rate_hz)
        .map(|t| {
            let w = motion.omega_cam(t);
            let a_w = motion.acceleration(t);
            let f_w = [a_w[0], a_w[1] - GRAVITY, a_w[2]];
            let f_c = mat_vec(&transpose(&motion.rotation(t)), &f_w);
            let gyro = std::array::from_fn(|i| w[i] + gb[i] + gs * rng::gauss(rng_imu));
            let acc = std::array::from_fn(|i| f_c[i] + ab[i] + as_ * rng::gauss(rng_imu));
            ImuRow { t_s: t, acc, gyro }
        })
        .collect();
    (rows, gb, ab)
}
