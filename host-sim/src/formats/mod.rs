//! Reading and writing event recordings, ground truth and IMU data.
