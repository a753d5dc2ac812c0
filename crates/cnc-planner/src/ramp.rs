//! The discrete braking limit shared by the executor and the coupling.

/// Highest speed `v1` for the end of a cycle of length `dt`, starting at speed `v`, such
/// that decelerating at `accel` still reaches speed `vx` within distance `dist`, with the
/// position advanced by the trapezoid rule `(v + v1) dt / 2`.
///
/// Solves `v1² + accel·dt·v1 = vx² + 2·accel·dist - accel·v·dt`; on the curve the speed drops
/// by exactly `accel·dt` per cycle, so following it never exceeds the deceleration limit.
pub(crate) fn brake_speed(vx: f64, accel: f64, dist: f64, v: f64, dt: f64) -> f64 {
    if !accel.is_finite() {
        return f64::INFINITY;
    }
    let adt = accel * dt;
    let rhs = vx * vx + 2.0 * accel * dist - adt * v;
    let disc = adt * adt + 4.0 * rhs;
    if disc <= 0.0 {
        return 0.0;
    }
    (0.5 * (disc.sqrt() - adt)).max(0.0)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::brake_speed;

    #[test]
    fn following_the_curve_decelerates_by_accel_dt() {
        // Start on the curve for vx = 0 and walk it: each cycle the speed falls by a*dt and the
        // distance covered equals v²/(2a) overall (hand derivation in the doc comment).
        let (a, dt) = (1000.0, 0.001);
        let mut v = 100.0;
        let mut dist = v * v / (2.0 * a) + 0.5 * v * dt; // curve point for the previous step
        let mut travelled = 0.0;
        let mut prev = v;
        for _ in 0..200 {
            let v1 = brake_speed(0.0, a, dist, v, dt);
            if v1 <= 0.0 {
                break;
            }
            assert!(prev - v1 <= a * dt * 1.000_001 + 1e-9, "{prev} -> {v1}");
            let ds = 0.5 * (v + v1) * dt;
            dist -= ds;
            travelled += ds;
            prev = v1;
            v = v1;
        }
        assert!(travelled < 100.0 * 100.0 / (2.0 * a) + 0.1);
    }
}
