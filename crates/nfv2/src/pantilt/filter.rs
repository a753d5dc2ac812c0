//! The tracking filter: a discrete second-order limiter that follows a moving target with
//! a set-point whose speed and acceleration never exceed the limits.
//!
//! Each step of `dt` (the scheduler cycle):
//!
//! ```text
//! e      = target - p                                   (position error)
//! u      = sign(e) * min(|e| / dt, a dt * (sqrt(1/4 + 2|e| / (a dt²)) - 1/2))
//! v_want = clamp(target_velocity + u, -v_max, v_max)
//! v'     = v + clamp(v_want - v, -a dt, a dt)
//! p'     = p + v' dt
//! ```
//!
//! `u` is the largest speed relative to the target from which braking at `a`, one step of
//! `dt` at a time, stops exactly on it (time-optimal without chattering: within `a dt²`
//! of the target it is `e / dt`, reaching it in one step; far from it about
//! `sqrt(2 a |e|)`); the target's own velocity is fed forward. By construction `|v'| <= v_max` and `|v' - v| <= a dt`, so the set-point's
//! first and second differences, `(p' - p) / dt = v'` and `(v' - v) / dt`, stay within
//! the limits exactly (up to floating-point rounding). Braking over a fractional number of
//! steps may overshoot a fixed target by less than `a dt² / 2` (0.006 deg at 120 deg/s²
//! and 10 ms).

/// Speed and acceleration limits (positive, any unit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Largest speed.
    pub velocity: f64,
    /// Largest acceleration.
    pub acceleration: f64,
}

/// Position and velocity of the set-point.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FilterState {
    /// Position.
    pub position: f64,
    /// Velocity.
    pub velocity: f64,
}

/// The second-order limiter (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct SecondOrderLimiter {
    state: FilterState,
    limits: Limits,
    dt: f64,
}

impl SecondOrderLimiter {
    /// Starts at rest at `position`, stepping `dt` seconds. Non-positive limits or `dt`
    /// give a set-point that never moves.
    #[must_use]
    pub fn new(position: f64, limits: Limits, dt: f64) -> Self {
        SecondOrderLimiter { state: FilterState { position, velocity: 0.0 }, limits, dt }
    }

    /// The set-point now.
    #[must_use]
    pub fn state(&self) -> FilterState {
        self.state
    }

    /// The step.
    #[must_use]
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// One step towards `target` moving at `target_velocity`; returns the new set-point.
    pub fn step(&mut self, target: f64, target_velocity: f64) -> FilterState {
        let Limits { velocity: vmax, acceleration: a } = self.limits;
        let dt = self.dt;
        if !(vmax > 0.0 && a > 0.0 && dt > 0.0 && target.is_finite() && target_velocity.is_finite()) {
            self.state.velocity = 0.0;
            return self.state;
        }
        let FilterState { position: p, velocity: v } = self.state;
        let e = target - p;
        let adt = a * dt;
        let braking = adt * ((0.25 + 2.0 * e.abs() / (adt * dt)).sqrt() - 0.5);
        let u = e.signum() * braking.min(e.abs() / dt);
        let wanted = (target_velocity + u).clamp(-vmax, vmax);
        let next = v + (wanted - v).clamp(-adt, adt);
        self.state = FilterState { position: p + next * dt, velocity: next };
        self.state
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: Limits = Limits { velocity: 30.0, acceleration: 120.0 };
    const DT: f64 = 0.01;

    #[test]
    fn a_step_is_reached_without_overshoot_within_limits() {
        let mut f = SecondOrderLimiter::new(0.0, LIMITS, DT);
        let mut prev = f.state();
        let mut max_p: f64 = 0.0;
        for _ in 0..500 {
            let s = f.step(40.0, 0.0);
            assert!(s.velocity.abs() <= 30.0);
            assert!((s.velocity - prev.velocity).abs() <= 120.0 * DT * (1.0 + 1e-12));
            max_p = max_p.max(s.position);
            prev = s;
        }
        assert!((prev.position - 40.0).abs() < 1e-9, "{prev:?}");
        // Braking with a fractional number of steps may overshoot by a fraction of a dt².
        assert!(max_p <= 40.0 + 0.5 * 120.0 * DT * DT, "overshoot to {max_p}");
        // Time-optimal-ish: 40 deg at 30 deg/s and 120 deg/s² takes 1.58 s.
        let mut g = SecondOrderLimiter::new(0.0, LIMITS, DT);
        let steps = (0..500).take_while(|_| (g.step(40.0, 0.0).position - 40.0).abs() > 1e-6).count();
        assert!((158..=175).contains(&steps), "{steps} steps");
    }

    #[test]
    fn follows_a_slow_sine_closely_and_a_fast_one_within_limits() {
        for (amplitude, hz, tol) in [(20.0, 0.2, 0.05), (15.0, 0.8, f64::INFINITY)] {
            let w = std::f64::consts::TAU * hz;
            let mut f = SecondOrderLimiter::new(0.0, LIMITS, DT);
            let mut prev = f.state();
            let mut worst: f64 = 0.0;
            for k in 0..2000 {
                let t = f64::from(k) * DT;
                let s = f.step(amplitude * (w * t).sin(), amplitude * w * (w * t).cos());
                assert!(s.velocity.abs() <= 30.0 + 1e-12);
                assert!(((s.position - prev.position) / DT).abs() <= 30.0 * (1.0 + 1e-9));
                assert!((s.velocity - prev.velocity).abs() <= 120.0 * DT * (1.0 + 1e-12));
                if k > 200 {
                    let target_next = amplitude * (w * (t + DT)).sin();
                    worst = worst.max((s.position - target_next).abs());
                }
                prev = s;
            }
            assert!(worst <= tol, "amplitude {amplitude} at {hz} Hz: worst error {worst}");
        }
    }

    #[test]
    fn bad_limits_do_not_move() {
        let mut f = SecondOrderLimiter::new(1.0, Limits { velocity: 0.0, acceleration: 1.0 }, DT);
        assert_eq!(f.step(10.0, 0.0).position, 1.0);
        let mut g = SecondOrderLimiter::new(1.0, LIMITS, DT);
        assert_eq!(g.step(f64::NAN, 0.0).position, 1.0);
    }
}
