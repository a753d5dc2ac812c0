//! Sensor calibration: sensor counts <-> metres <-> robot wheel increments.
//!
//! Seed 000, section 8.4: 10 cm of travel read 850 sensor counts on average, so
//! 8500 counts/m. One wheel revolution is 213 Inc = 37.7 cm (565 Inc/m); the seed rounds
//! to 6 Inc/cm and forms K = 85/6 = 14.17.
//!
//! **Correction**: K is *sensor counts per robot Inc* (850 counts / 60 Inc for 10 cm),
//! not robot Inc per count as the seed's sentence says; a count is 6/85 Inc. The seed's
//! own fusion rule divides the sensor value by K, which is the correct direction.

use serde::{Deserialize, Serialize};

/// Sensor counts per metre measured in the seed (850 counts per 10 cm).
pub const SEED_COUNTS_PER_METRE: f64 = 8500.0;
/// The seed's rounded wheel scale: 6 Inc per cm.
pub const SEED_INC_PER_METRE: f64 = 600.0;
/// The wheel scale from the drive data: 213 Inc per revolution of 37.7 cm (= 565 Inc/m).
pub const WHEEL_INC_PER_METRE: f64 = 213.0 / 0.377;
/// The seed's K = 85/6: sensor counts per robot Inc at 6 Inc/cm.
pub const SEED_K: f64 = 85.0 / 6.0;

/// Calibration of one sensor: counts per metre of travel (the same on both axes).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Sensor counts per metre of travel.
    pub counts_per_metre: f64,
}

impl Default for Calibration {
    /// The seed's measurement: 850 counts per 10 cm.
    fn default() -> Self {
        Calibration { counts_per_metre: SEED_COUNTS_PER_METRE }
    }
}

impl Calibration {
    /// Metres of travel for `counts`.
    #[must_use]
    pub fn counts_to_metres(&self, counts: f64) -> f64 {
        counts / self.counts_per_metre
    }

    /// Counts (fractional) for `metres` of travel.
    #[must_use]
    pub fn metres_to_counts(&self, metres: f64) -> f64 {
        metres * self.counts_per_metre
    }

    /// Sensor counts per robot Inc at a wheel scale of `inc_per_metre` (the seed's K for
    /// 600 Inc/m: 85/6).
    #[must_use]
    pub fn counts_per_inc(&self, inc_per_metre: f64) -> f64 {
        self.counts_per_metre / inc_per_metre
    }

    /// Robot Inc for `counts` at a wheel scale of `inc_per_metre` (`counts / K`).
    #[must_use]
    pub fn counts_to_inc(&self, counts: f64, inc_per_metre: f64) -> f64 {
        counts / self.counts_per_inc(inc_per_metre)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn seed_numbers() {
        let c = Calibration::default();
        // 10 cm = 850 counts (seed 8.4).
        assert!((c.metres_to_counts(0.1) - 850.0).abs() < 1e-9);
        assert!((c.counts_to_metres(850.0) - 0.1).abs() < 1e-12);
        // K = 85/6 = 14.1666 at 6 Inc/cm; 850 counts = 60 Inc.
        assert!((c.counts_per_inc(SEED_INC_PER_METRE) - 14.166_666).abs() < 1e-5);
        assert!((c.counts_to_inc(850.0, SEED_INC_PER_METRE) - 60.0).abs() < 1e-9);
        assert!((SEED_K - c.counts_per_inc(SEED_INC_PER_METRE)).abs() < 1e-12);
        // At the drive's 565 Inc/m: 10 cm = 56.5 Inc.
        assert!((c.counts_to_inc(850.0, WHEEL_INC_PER_METRE) - 56.498).abs() < 1e-3);
    }
}
