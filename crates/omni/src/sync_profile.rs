//! Synchronised wheel profiles: all three wheels of a move start together (one SYNC) and,
//! with velocity, acceleration and deceleration all scaled by `|s_i| / |s_max|`, follow
//! the same trapezoid timing and finish together: for a trapezoid the phase durations are
//! `v/a`, `v/d` and `(s - v^2/2a - v^2/2d)/v`, all invariant under scaling `s, v, a, d`
//! by one factor (and the triangular peak `sqrt(2 s a d / (a + d))` scales likewise).
//!
//! The drives take whole Inc/s and Inc/s^2 (0x6081, 0x6083, 0x6084): rounding to integers
//! (minimum 1) makes the durations differ slightly; [`duration_spread`] reports by how much.

use serde::{Deserialize, Serialize};

use crate::programs::Ramp;

/// A wheel's profile before rounding, Inc/s and Inc/s^2.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ScaledProfile {
    /// Inc/s.
    pub velocity: f64,
    /// Inc/s^2.
    pub acceleration: f64,
    /// Inc/s^2.
    pub deceleration: f64,
}

/// What a drive is given: profile velocity 0x6081 (Inc/s), acceleration 0x6083 and
/// deceleration 0x6084 (Inc/s^2), each at least 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct WheelProfile {
    /// Inc/s.
    pub velocity: u32,
    /// Inc/s^2.
    pub acceleration: u32,
    /// Inc/s^2.
    pub deceleration: u32,
}

impl WheelProfile {
    /// The smallest profile a drive accepts (a wheel that does not move gets it).
    pub const MINIMUM: WheelProfile = WheelProfile { velocity: 1, acceleration: 1, deceleration: 1 };
}

fn to_u32(v: f64) -> u32 {
    if v.is_finite() {
        // Clamped into u32's range first: the cast is exact.
        v.round().clamp(1.0, f64::from(u32::MAX)) as u32
    } else {
        1
    }
}

impl ScaledProfile {
    /// Rounded to whole units, at least 1 each.
    #[must_use]
    pub fn to_wheel(&self) -> WheelProfile {
        WheelProfile {
            velocity: to_u32(self.velocity),
            acceleration: to_u32(self.acceleration),
            deceleration: to_u32(self.deceleration),
        }
    }
}

/// Per-wheel profiles for wheel travels `travel` (Inc, any sign), `base` applying to the
/// longest one. A wheel with zero travel gets zeros (use [`WheelProfile::MINIMUM`] on the
/// wire). An invalid `base` gives zeros everywhere.
#[must_use]
pub fn synchronise(travel: [f64; 3], base: Ramp) -> [ScaledProfile; 3] {
    let max = travel.iter().fold(0.0f64, |m, s| m.max(s.abs()));
    travel.map(|s| {
        let k = if max > 0.0 && base.is_valid() && s.is_finite() { s.abs() / max } else { 0.0 };
        ScaledProfile {
            velocity: base.velocity * k,
            acceleration: base.acceleration * k,
            deceleration: base.deceleration * k,
        }
    })
}

/// [`synchronise`], rounded for the drives.
#[must_use]
pub fn wheel_profiles(travel: [f64; 3], base: Ramp) -> [WheelProfile; 3] {
    synchronise(travel, base).map(|p| p.to_wheel())
}

/// Duration (s) of a trapezoidal move of `distance` (any sign) from rest to rest with
/// peak velocity `v`, acceleration `a`, deceleration `d` (all > 0; else 0).
#[must_use]
pub fn trapezoid_duration(distance: f64, v: f64, a: f64, d: f64) -> f64 {
    let s = distance.abs();
    if s == 0.0 || !(v > 0.0 && a > 0.0 && d > 0.0) {
        return 0.0;
    }
    let ramps = v * v / (2.0 * a) + v * v / (2.0 * d);
    if s >= ramps {
        v / a + v / d + (s - ramps) / v
    } else {
        let vp = (2.0 * s * a * d / (a + d)).sqrt();
        vp / a + vp / d
    }
}

/// Duration of the move with the rounded profiles: the longest wheel's, and the spread
/// (longest minus shortest among the moving wheels), seconds.
#[must_use]
pub fn duration_spread(travel: [f64; 3], profiles: &[WheelProfile; 3]) -> (f64, f64) {
    let ds: Vec<f64> = travel
        .iter()
        .zip(profiles)
        .filter(|(s, _)| s.abs() > 0.0)
        .map(|(s, p)| {
            trapezoid_duration(
                *s,
                f64::from(p.velocity),
                f64::from(p.acceleration),
                f64::from(p.deceleration),
            )
        })
        .collect();
    let max = ds.iter().copied().fold(0.0, f64::max);
    let min = ds.iter().copied().fold(f64::INFINITY, f64::min);
    (max, if min.is_finite() { max - min } else { 0.0 })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn trapezoid_by_hand() {
        // 1065 Inc at 248 Inc/s, 1000 and 400 Inc/s^2: ramps 30.752 + 76.88 = 107.632 Inc,
        // t = 0.248 + 0.62 + (1065 - 107.632)/248 = 0.868 + 3.86035 = 4.72835 s.
        let t = trapezoid_duration(1065.0, 248.0, 1000.0, 400.0);
        assert!((t - 4.728_355).abs() < 1e-5, "{t}");
        // Triangular: 10 Inc at a = d = 100: vp = sqrt(2*10*100*100/200) = 31.62, t = 0.6325.
        let t = trapezoid_duration(-10.0, 248.0, 100.0, 100.0);
        assert!((t - 0.632_456).abs() < 1e-6, "{t}");
    }

    #[test]
    fn zero_travel_wheels() {
        let p = synchronise([0.0, 100.0, -50.0], Ramp::SEED);
        assert_eq!(p[0].velocity, 0.0);
        assert_eq!(p[0].to_wheel(), WheelProfile::MINIMUM);
        assert_eq!(p[1].velocity, 248.0);
        assert_eq!(p[2].to_wheel(), WheelProfile { velocity: 124, acceleration: 500, deceleration: 200 });
        let all_zero = wheel_profiles([0.0; 3], Ramp::SEED);
        assert_eq!(all_zero, [WheelProfile::MINIMUM; 3]);
    }
}
