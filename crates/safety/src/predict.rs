//! Prediction of the positions an axis can still reach before it stands still.
//!
//! Generalises the seed's `PREDICT_AXIS` + `DECELERATABLE` (specs/juggler-safety.md).
//! Worst case toward the positive direction: the axis accelerates at `a_up` for the whole
//! horizon `T` (nobody has stopped it yet), then the quick stop brakes it at `b_up`:
//!
//! ```text
//! s1 = s0 + v0 T + a_up T^2 / 2          (position at the horizon)
//! v1 = v0 + a_up T                       (speed at the horizon)
//! hi = max(s0, s1 + max(v1, 0)^2 / (2 b_up))
//! ```
//!
//! and mirrored toward the negative direction:
//!
//! ```text
//! s1' = s0 + v0 T - a_down T^2 / 2,  v1' = v0 - a_down T
//! lo  = min(s0, s1' - max(-v1', 0)^2 / (2 b_down))
//! ```
//!
//! Every trajectory whose acceleration stays within `[-a_down, a_up]` until the horizon
//! and whose braking is at least `b` afterwards stays inside `[lo, hi]` until standstill:
//! the extreme trajectory is pointwise the highest (lowest), it is convex (concave) so its
//! maximum (minimum) over `[0, T]` is at an end, and the braking distance `v^2/(2b)` grows
//! with the speed. The `max(s0, ..)` term covers an axis moving away so fast that it cannot
//! turn back before the horizon. The seed's test "`|s_lim - s| > v^2 / (2 a_dec)`" is
//! exactly `hi < s_lim` for a limit above; its needed free distance
//! `v0 T + a T^2/2 + v t_b - a_b t_b^2/2` is `hi - s0`.
//!
//! Figures: with `a = 500 000`, `b = 1 600 000` units/s^2 (50 000 and 160 000 deg/s^2)
//! and `T = 9.6 ms`, the free distance at rest is `23.04 + 7.2 = 30.24` units = 3.02 deg
//! (the seed says "3.1 deg"). With 1 146 497 units/s^2 both ways the formula gives
//! 10.57 deg; the seed's "14.7 deg" does not follow from 9.6 ms (it matches T ~ 11.3 ms).

/// Reachable positions of one axis until standstill, and the predicted states at the
/// horizon for both worst-case directions (for diagnoses).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Reach {
    /// Lowest position reachable before standstill.
    pub lo: f64,
    /// Highest position reachable before standstill.
    pub hi: f64,
    /// Position at the horizon when accelerating toward positive (`s1`).
    pub up_position: f64,
    /// Speed at the horizon when accelerating toward positive (`v1`).
    pub up_speed: f64,
    /// Position at the horizon when accelerating toward negative (`s1'`).
    pub down_position: f64,
    /// Speed at the horizon when accelerating toward negative (`v1'`).
    pub down_speed: f64,
}

/// Worst-case dynamics used by the prediction (units/s^2, all finite; braking > 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dynamics {
    /// Worst-case acceleration toward positive.
    pub accel_up: f64,
    /// Worst-case acceleration toward negative (magnitude).
    pub accel_down: f64,
    /// Guaranteed deceleration when braking a positive motion.
    pub brake_up: f64,
    /// Guaranteed deceleration when braking a negative motion.
    pub brake_down: f64,
}

/// Predicts the reachable interval from position `s0` and speed `v0` with horizon `t`
/// (seconds: reaction time + age of the sample + one evaluation cycle).
pub fn predict(s0: f64, v0: f64, t: f64, d: &Dynamics) -> Reach {
    let up_position = s0 + v0 * t + d.accel_up * t * t / 2.0;
    let up_speed = v0 + d.accel_up * t;
    let down_position = s0 + v0 * t - d.accel_down * t * t / 2.0;
    let down_speed = v0 - d.accel_down * t;
    let vu = up_speed.max(0.0);
    let vd = (-down_speed).max(0.0);
    let hi = s0.max(up_position + vu * vu / (2.0 * d.brake_up));
    let lo = s0.min(down_position - vd * vd / (2.0 * d.brake_down));
    Reach { lo, hi, up_position, up_speed, down_position, down_speed }
}

/// Seed's `DECELERATABLE(distance, speed, decel)`: true iff an axis moving at `speed`
/// toward an obstacle `distance` away stops before it (`distance > v^2 / (2 decel)`;
/// a speed away from the obstacle (negative) always can).
pub fn deceleratable(distance: f64, speed: f64, decel: f64) -> bool {
    let v = speed.max(0.0);
    distance > v * v / (2.0 * decel)
}

/// Needed free distance in front of an axis moving at `v0 >= 0` (seed's `s_safe`).
pub fn free_distance(v0: f64, t: f64, accel: f64, brake: f64) -> f64 {
    let d = Dynamics { accel_up: accel, accel_down: accel, brake_up: brake, brake_down: brake };
    predict(0.0, v0, t, &d).hi
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    const ARM: Dynamics = Dynamics {
        accel_up: 500_000.0,
        accel_down: 500_000.0,
        brake_up: 1_600_000.0,
        brake_down: 1_600_000.0,
    };
    const T: f64 = 0.0096;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-6
    }

    #[test]
    fn at_rest() {
        // By hand: a T^2/2 = 500000 * 9.216e-5 / 2 = 23.04; v1 = 4800;
        // 4800^2 / 3.2e6 = 7.2; total 30.24 units = 3.024 deg.
        let r = predict(0.0, 0.0, T, &ARM);
        assert!(close(r.hi, 30.24), "{r:?}");
        assert!(close(r.lo, -30.24), "{r:?}");
        assert!(close(r.up_speed, 4800.0));
        assert!(close(free_distance(0.0, T, 500_000.0, 1_600_000.0), 30.24));
    }

    #[test]
    fn moving_up_fast() {
        // v0 = 10000: s1 = 96 + 23.04 = 119.04, v1 = 14800, 14800^2/3.2e6 = 68.45
        // -> hi = 187.49. Down: v1' = 5200 > 0 so the axis cannot go below s0: lo = 0.
        let r = predict(0.0, 10_000.0, T, &ARM);
        assert!(close(r.hi, 187.49), "{r:?}");
        assert!(close(r.lo, 0.0), "{r:?}");
        let r = predict(100.0, -10_000.0, T, &ARM);
        assert!(close(r.lo, 100.0 - 187.49), "{r:?}");
        assert!(close(r.hi, 100.0), "{r:?}");
    }

    #[test]
    fn slow_axis_can_turn_back() {
        // v0 = 2000: down s1' = 19.2 - 23.04 = -3.84, v1' = -2800,
        // 2800^2/3.2e6 = 2.45 -> lo = -6.29.
        let r = predict(0.0, 2_000.0, T, &ARM);
        assert!(close(r.lo, -6.29), "{r:?}");
        assert!(close(r.down_position, -3.84));
    }

    #[test]
    fn asymmetric_dynamics() {
        // a_up = 0 (axis can only coast), b_up = 1000: v0 = 100, T = 1:
        // s1 = 100, hi = 100 + 100^2/2000 = 105.
        let d = Dynamics { accel_up: 0.0, accel_down: 10.0, brake_up: 1000.0, brake_down: 1.0 };
        let r = predict(0.0, 100.0, 1.0, &d);
        assert!(close(r.hi, 105.0));
        // Down: s1' = 100 - 5 = 95, v1' = 90 > 0 -> lo = s0 = 0.
        assert!(close(r.lo, 0.0));
    }

    #[test]
    fn deceleratable_matches_hi() {
        // Seed test: limit 1000 above s = 0, predicted v = 4800 at s1 = 23.04:
        // 976.96 > 7.2 -> true; limit at 30 -> 6.96 < 7.2 -> false.
        assert!(deceleratable(1000.0 - 23.04, 4800.0, 1_600_000.0));
        assert!(!deceleratable(30.0 - 23.04, 4800.0, 1_600_000.0));
        assert!(deceleratable(1.0, -5000.0, 1.0));
    }
}
