//! One-dimensional trapezoidal trajectories with constant-acceleration segments, planned
//! from any initial position and velocity (simulators' trajectory generators and host-side
//! position loops sample them), and normalised profiles for synchronised multi-axis moves.

/// One constant-acceleration segment.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Segment {
    t0: f64,
    dur: f64,
    p0: f64,
    v0: f64,
    a: f64,
}

/// A planned motion: a few constant-acceleration segments ending at rest at `target`.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    segments: Vec<Segment>,
    target: f64,
    duration: f64,
}

impl Plan {
    /// Moves from `p0` with velocity `v0` to rest at `target`, with speed at most `vmax`
    /// (> 0) and acceleration `acc` (> 0). If the axis cannot stop in time it first
    /// decelerates to rest, then comes back.
    pub fn to_target(p0: f64, v0: f64, target: f64, vmax: f64, acc: f64) -> Plan {
        let mut plan = Plan { segments: Vec::with_capacity(4), target, duration: 0.0 };
        if !(vmax > 0.0 && acc > 0.0) {
            plan.target = p0;
            return plan;
        }
        let (mut p, mut v) = (p0, v0);
        let d = target - p;
        let dir = if d >= 0.0 { 1.0 } else { -1.0 };
        let stopping = v * v / (2.0 * acc);
        if v != 0.0 && (v.signum() != dir || stopping > d.abs()) {
            let dur = v.abs() / acc;
            plan.push(p, v, -v.signum() * acc, dur);
            p += v * dur / 2.0;
            v = 0.0;
        }
        let d = (target - p).abs();
        let dir = if target >= p { 1.0 } else { -1.0 };
        let u0 = v.abs();
        if u0 > vmax {
            let t1 = (u0 - vmax) / acc;
            let s1 = (u0 * u0 - vmax * vmax) / (2.0 * acc);
            plan.push(p, dir * u0, -dir * acc, t1);
            let s3 = vmax * vmax / (2.0 * acc);
            let s2 = (d - s1 - s3).max(0.0);
            plan.push(p + dir * s1, dir * vmax, 0.0, s2 / vmax);
            plan.push(p + dir * (s1 + s2), dir * vmax, -dir * acc, vmax / acc);
        } else {
            let vp = vmax.min((acc * d + u0 * u0 / 2.0).sqrt());
            let t1 = (vp - u0) / acc;
            let s1 = (vp * vp - u0 * u0) / (2.0 * acc);
            let s3 = vp * vp / (2.0 * acc);
            let s2 = (d - s1 - s3).max(0.0);
            if t1 > 0.0 {
                plan.push(p, dir * u0, dir * acc, t1);
            }
            if s2 > 0.0 && vp > 0.0 {
                plan.push(p + dir * s1, dir * vp, 0.0, s2 / vp);
            }
            if vp > 0.0 {
                plan.push(p + dir * (s1 + s2), dir * vp, -dir * acc, vp / acc);
            }
        }
        plan
    }

    /// Decelerates from `p0`, `v0` to rest at `acc`.
    pub fn stop(p0: f64, v0: f64, acc: f64) -> Plan {
        let mut plan = Plan { segments: Vec::new(), target: p0, duration: 0.0 };
        if v0 != 0.0 && acc > 0.0 {
            let dur = v0.abs() / acc;
            plan.push(p0, v0, -v0.signum() * acc, dur);
            plan.target = p0 + v0 * dur / 2.0;
        }
        plan
    }

    fn push(&mut self, p0: f64, v0: f64, a: f64, dur: f64) {
        if dur > 0.0 && dur.is_finite() {
            self.segments.push(Segment { t0: self.duration, dur, p0, v0, a });
            self.duration += dur;
        }
    }

    /// Total duration in seconds.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// Where the motion ends.
    pub fn target(&self) -> f64 {
        self.target
    }

    /// Position and velocity at time `t` after the start.
    pub fn sample(&self, t: f64) -> (f64, f64) {
        if t >= self.duration {
            return (self.target, 0.0);
        }
        let seg = self.segments.iter().rev().find(|s| s.t0 <= t).or(self.segments.first());
        match seg {
            Some(s) => {
                let tau = (t - s.t0).clamp(0.0, s.dur);
                (s.p0 + s.v0 * tau + 0.5 * s.a * tau * tau, s.v0 + s.a * tau)
            }
            None => (self.target, 0.0),
        }
    }
}

/// A normalised profile `s(t)` from 0 to 1 such that every axis `i` moving by `d_i` along
/// `x_i(t) = x0_i + d_i * s(t)` stays within its velocity and acceleration limits, and all
/// axes arrive together. `limits` holds `(distance, vmax, acc)` per axis; axes with zero
/// distance are ignored. Returns `None` if no axis moves or a limit is not positive.
pub fn synchronised(limits: &[(f64, f64, f64)]) -> Option<Plan> {
    let mut sv = f64::INFINITY;
    let mut sa = f64::INFINITY;
    for &(d, v, a) in limits {
        if d == 0.0 {
            continue;
        }
        if !(v > 0.0 && a > 0.0 && d.is_finite()) {
            return None;
        }
        sv = sv.min(v / d.abs());
        sa = sa.min(a / d.abs());
    }
    if !sv.is_finite() {
        return None;
    }
    Some(Plan::to_target(0.0, 0.0, 1.0, sv, sa))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used)]
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn trapezoid_from_rest() {
        // 0 -> 1000 at vmax 100, acc 100: accel 1 s (50), cruise 9 s (900), decel 1 s (50).
        let p = Plan::to_target(0.0, 0.0, 1000.0, 100.0, 100.0);
        assert!((p.duration() - 11.0).abs() < 1e-9);
        assert!((p.sample(1.0).0 - 50.0).abs() < 1e-9);
        assert!((p.sample(10.0).0 - 950.0).abs() < 1e-9);
        assert_eq!(p.sample(11.5), (1000.0, 0.0));
    }

    #[test]
    fn reverses_when_it_cannot_stop() {
        let p = Plan::to_target(0.0, 100.0, 10.0, 100.0, 100.0);
        // Stops at 50 first, then comes back to 10.
        assert!((p.sample(1.0).0 - 50.0).abs() < 1e-9);
        assert_eq!(p.target(), 10.0);
    }

    #[test]
    fn synchronised_axes_arrive_together_within_limits() {
        let s = synchronised(&[(10.0, 5.0, 10.0), (-40.0, 5.0, 10.0), (0.0, 1.0, 1.0)]).unwrap();
        // The 40-unit axis sets the pace: 40 units at 5/s, 10/s^2 takes 8.5 s.
        assert!((s.duration() - 8.5).abs() < 1e-9);
        let (_, v) = s.sample(4.0);
        assert!((v * 40.0 - 5.0).abs() < 1e-9);
        assert!(synchronised(&[(0.0, 1.0, 1.0)]).is_none());
    }

    proptest! {
        #[test]
        fn respects_limits_and_ends_at_target(p0 in -1e5f64..1e5, v0 in -500f64..500.0, x in -1e5f64..1e5, vmax in 1f64..400.0, acc in 1f64..1e4) {
            let plan = Plan::to_target(p0, v0, x, vmax, acc);
            let n = 2000;
            let mut prev = plan.sample(0.0);
            prop_assert!((prev.0 - p0).abs() < 1e-6);
            for i in 1..=n {
                let t = plan.duration() * f64::from(i) / f64::from(n);
                let s = plan.sample(t);
                let dt = plan.duration() / f64::from(n);
                prop_assert!((s.1 - prev.1).abs() <= acc * dt * (1.0 + 1e-6) + 1e-6);
                prop_assert!(s.1.abs() <= vmax.max(v0.abs()) + 1e-6);
                prev = s;
            }
            let end = plan.sample(plan.duration());
            prop_assert!((end.0 - x).abs() < 1e-6 && end.1 == 0.0);
        }
    }
}
