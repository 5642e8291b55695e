//! Seeded random streams and the few distributions the simulator needs.
//!
//! Every purpose (texture, motion, sensor mismatch, noise events, IMU, moving objects, regime
//! presets) draws from its own ChaCha
//! stream derived from the one user seed, so changing e.g. the noise rate does not change the
//! texture. Normal and exponential variates are computed here (no `rand_distr`).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Independent random streams, one per purpose. Values are the ChaCha stream ids.
#[derive(Clone, Copy, Debug)]
pub enum Stream {
    /// Panorama and ground textures.
    Texture = 1,
    /// Motion profile parameters.
    Motion = 2,
    /// Per-pixel threshold mismatch and hot-pixel placement.
    Sensor = 3,
    /// Background-activity and hot-pixel events.
    Noise = 4,
    /// IMU bias and white noise.
    Imu = 5,
    /// Moving objects: kind, size, path.
    Objects = 6,
    /// Moving objects: textures.
    ObjectTexture = 7,
    /// The parameters a regime preset draws (speed, camera height, number of objects).
    Regime = 8,
}

/// The random generator for `stream` under `seed` (deterministic).
pub fn stream(seed: u64, stream: Stream) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream as u64);
    rng
}

/// A standard normal variate (Box-Muller; one of the pair is discarded for simplicity).
pub fn gauss<R: Rng>(rng: &mut R) -> f64 {
    // u1 in (0, 1] so that ln(u1) is finite.
    let u1: f64 = 1.0 - rng.gen::<f64>();
    let u2: f64 = rng.gen::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// An exponential variate with the given rate (1/s); `f64::INFINITY` for a zero rate.
pub fn exponential<R: Rng>(rng: &mut R, rate: f64) -> f64 {
    if rate <= 0.0 {
        return f64::INFINITY;
    }
    let u: f64 = 1.0 - rng.gen::<f64>();
    -u.ln() / rate
}

/// A uniform variate in `[lo, hi)`.
pub fn uniform<R: Rng>(rng: &mut R, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.gen::<f64>()
}

/// `+1.0` or `-1.0` with equal probability.
pub fn sign<R: Rng>(rng: &mut R) -> f64 {
    if rng.gen::<bool>() {
        1.0
    } else {
        -1.0
    }
}
