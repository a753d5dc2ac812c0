//! A simple servo-axis model: follows position set-points under speed and acceleration limits
//! (like cyclic synchronous position mode), and brakes at its braking deceleration on quick stop.

/// Limits and start state of a simulated drive (units, units/s, units/s²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveParams {
    /// Maximum speed.
    pub max_speed: f64,
    /// Maximum acceleration (and deceleration) while following.
    pub max_accel: f64,
    /// Braking deceleration on quick stop.
    pub brake_decel: f64,
    /// Position at power-up.
    pub initial_position: f64,
    /// When set, the drive runs only under a valid safety lease
    /// ([`motus_epl_protocol::SafetyLease`]) no longer ago than this: a revoke, or no renewal
    /// within this time, makes it quick-stop. `None`: leases are ignored.
    pub lease_timeout: Option<std::time::Duration>,
    /// Where the lease comes from (with [`DriveParams::lease_timeout`]): `Some(n)`, the PRes
    /// of safety node `n` (the supervisor as a CN: a renewal needs the RD flag and a lease
    /// counter that advanced; lease ASnds are ignored); `None`, the lease ASnd of node 253
    /// ([`motus_epl_protocol::LEASE_ASND_NODE_ID`]). A lease from any other node is ignored.
    pub safety_node: Option<u8>,
    /// When set, a drive beyond PRE_OPERATIONAL_1 whose SoC comes this long or longer after
    /// the previous one (it lost SoCs: its cable was pulled, the MN stopped) has a cycle error
    /// and drops to PRE_OPERATIONAL_1, to be booted again by the MN (`specs/powerlink.md` §5,
    /// "CN loss of SoC"; object 0x1C14). `None`: never.
    pub soc_loss_tolerance: Option<std::time::Duration>,
}

impl Default for DriveParams {
    /// The juggler's horizontal axes (`specs/juggler-safety.md`): 5000 deg/s = 50 000 units/s,
    /// 500 000 units/s², braking 1 600 000 units/s².
    fn default() -> Self {
        Self {
            max_speed: 50_000.0,
            max_accel: 500_000.0,
            brake_decel: 1_600_000.0,
            initial_position: 0.0,
            lease_timeout: None,
            safety_node: None,
            soc_loss_tolerance: None,
        }
    }
}

/// State of one simulated axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisModel {
    params: DriveParams,
    position: f64,
    speed: f64,
    last_target: Option<f64>,
}

impl AxisModel {
    /// An axis at rest at `params.initial_position`.
    pub fn new(params: DriveParams) -> Self {
        Self { params, position: params.initial_position, speed: 0.0, last_target: None }
    }

    /// Actual position (units).
    pub fn position(&self) -> f64 {
        self.position
    }

    /// Actual speed (units/s).
    pub fn speed(&self) -> f64 {
        self.speed
    }

    /// Advances by `dt` seconds toward `target`, or braking when `quick_stop` is set.
    /// Position integrates the mean speed over the step (exact for constant acceleration);
    /// an axis that brakes to rest within the step travels only until it stops, whatever
    /// the step's length (a stretched cycle must not lengthen the braking distance).
    pub fn step(&mut self, dt: f64, target: f64, quick_stop: bool) {
        if dt <= 0.0 {
            return;
        }
        let p = &self.params;
        let v0 = self.speed;
        let target_speed = self.last_target.map_or(0.0, |t| (target - t) / dt);
        self.last_target = (!quick_stop).then_some(target);
        let v1 = if quick_stop {
            let dv = p.brake_decel * dt;
            if v0.abs() <= dv {
                // At rest after |v0| / a_b: the distance v0² / (2 a_b), in v0's direction.
                if p.brake_decel > 0.0 {
                    self.position += v0 * v0.abs() / (2.0 * p.brake_decel);
                }
                self.speed = 0.0;
                return;
            }
            v0 - dv * v0.signum()
        } else {
            let e = target - self.position;
            // Feed-forward of the target's own speed, plus a correction that closes the error in
            // one step if allowed but never faster than a stop from max_accel would permit.
            let correction = e.signum() * (e.abs() / dt).min((2.0 * p.max_accel * e.abs()).sqrt());
            let v_cmd = (target_speed + correction).clamp(-p.max_speed, p.max_speed);
            v0 + (v_cmd - v0).clamp(-p.max_accel * dt, p.max_accel * dt)
        };
        self.position += 0.5 * (v0 + v1) * dt;
        self.speed = v1;
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn quick_stop_brakes_within_v2_over_2a() {
        // v0 = 40 000 units/s, a_b = 1 600 000 units/s²: distance v²/(2a) = 500 units
        // (computed by hand), reached in 25 ms = 62.5 steps of 400 us.
        let mut a = AxisModel::new(DriveParams::default());
        a.speed = 40_000.0;
        for _ in 0..100 {
            a.step(0.0004, 1e9, true);
        }
        assert_eq!(a.speed(), 0.0);
        // Trapezoidal integration over 62 full steps and one partial one overshoots the exact
        // 500 by at most one step's travel at the last speed (0.5 * 400 units/s * 400 us).
        assert!((a.position() - 500.0).abs() < 1.0, "{}", a.position());
    }

    #[test]
    fn a_long_step_brakes_no_further_than_v2_over_2a() {
        // A cycle stretched to 8 ms by the host: 2439 units/s stops in 1.5 ms, after
        // 2439² / (2 * 1 600 000) = 1.8589753125 units (by hand); the step's mean speed
        // would give 9.756.
        for v0 in [2439.0, -2439.0] {
            let mut a = AxisModel::new(DriveParams::default());
            a.speed = v0;
            a.step(0.008, 0.0, true);
            assert_eq!(a.speed(), 0.0);
            assert!((a.position() - v0.signum() * 1.858_975_312_5).abs() < 1e-9, "{}", a.position());
        }
    }

    #[test]
    fn follows_a_ramp_exactly_within_limits() {
        let mut a = AxisModel::new(DriveParams::default());
        // 10 000 units/s ramp, below max speed; acceleration phase first.
        // After the start transient (at most 10 000 / 500 000 s = 20 ms of acceleration plus
        // the catch-up), the axis tracks the ramp within one step's travel (10 units).
        for k in 1..=1000 {
            a.step(0.001, 10.0 * f64::from(k), false);
        }
        assert!((a.position() - 10_000.0).abs() <= 10.0, "{}", a.position());
        assert!((a.speed() - 10_000.0).abs() <= 500.0, "{}", a.speed());
    }
}
