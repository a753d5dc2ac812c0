//! Joint mechanics, one fixed step at a time: motor, gear, brake, gravity and end stops.
//!
//! - **Driven** (power stage on, brake released): the motor speed follows the controller's
//!   demand through a first-order speed loop (time constant `speed_loop_tau_ms`); the loop
//!   is stiff, so gravity does not move a driven joint. Joint speed = motor rpm x 6 / gear
//!   x speed sign (deg/s).
//! - **Free** (power stage off, brake released): the joint accelerates under gravity
//!   (`gravity_deg_s2 * sin(pitch)`, pitch = joint angle + the previous joint's pitch when
//!   `pitch_follows_previous`) against viscous damping, back-driving the motor.
//! - **Braked**: the brake sits on the motor shaft and stops a moving joint at
//!   `brake_decel_deg_s2`, then holds it; a driven motor stalls against it.
//! - **End stops** (joints with switches) stop the joint dead; a motor pushing into one stalls.

use crate::config::{JointConfig, Side};
use crate::controller::Drive;

/// Motor current per deg/s² of gravity the speed loop holds, mA.
const GRAVITY_MA_PER_DEG_S2: f64 = 2.0;
/// Motor current for friction while turning, mA.
const FRICTION_MA: f64 = 40.0;
/// Motor current per rpm/s of acceleration (rotor and gear inertia), mA.
const INERTIA_MA_PER_RPM_S: f64 = 0.005;
/// Demand below which a stalled motor is not pushing, rpm.
const STALL_RPM: f64 = 0.5;

/// The mechanical state of one joint.
#[derive(Debug, Clone)]
pub(crate) struct Joint {
    config: JointConfig,
    angle: f64,
    velocity: f64,
    motor_rpm: f64,
    motor_accel: f64,
    counts: f64,
    base_pitch: f64,
    stalled: bool,
}

impl Joint {
    /// A joint at rest at its initial angle.
    pub(crate) fn new(config: JointConfig) -> Self {
        let mut j = Self {
            config,
            angle: config.initial_angle_deg,
            velocity: 0.0,
            motor_rpm: 0.0,
            motor_accel: 0.0,
            counts: 0.0,
            base_pitch: 0.0,
            stalled: false,
        };
        j.clamp_to_end_stops();
        j
    }

    /// Joint angle, degrees (not wrapped: joints 4 and 6 turn endlessly).
    pub(crate) fn angle(&self) -> f64 {
        self.angle
    }

    /// Joint speed, deg/s.
    pub(crate) fn velocity(&self) -> f64 {
        self.velocity
    }

    /// Motor speed, rpm.
    pub(crate) fn motor_rpm(&self) -> f64 {
        self.motor_rpm
    }

    /// Motor encoder position, increments.
    pub(crate) fn counts(&self) -> f64 {
        self.counts
    }

    /// Pitch of the link this joint moves (for the next joint's gravity).
    pub(crate) fn pitch(&self) -> f64 {
        self.base_pitch + self.angle
    }

    /// Sets the pitch of the link carrying this joint.
    pub(crate) fn set_base_pitch(&mut self, deg: f64) {
        if self.config.pitch_follows_previous {
            self.base_pitch = deg;
        }
    }

    /// Puts the joint at `deg` at rest (test hook; end stops still apply).
    pub(crate) fn place(&mut self, deg: f64) {
        self.angle = deg;
        self.stop();
        self.clamp_to_end_stops();
    }

    /// Stops the joint dead (power loss: the brake or the gear holds it).
    pub(crate) fn stop(&mut self) {
        self.velocity = 0.0;
        self.motor_rpm = 0.0;
        self.motor_accel = 0.0;
    }

    /// The switch pressed at the current angle, if any.
    pub(crate) fn switch(&self) -> Option<Side> {
        let [lo, hi] = self.config.switch_positions_deg()?;
        if self.angle >= hi {
            Some(Side::Upper)
        } else if self.angle <= lo {
            Some(Side::Lower)
        } else {
            None
        }
    }

    /// What the controller sees, with the current for the given demand and current limits.
    pub(crate) fn drive(&self, demand: Option<f64>, limits: (f64, f64)) -> Drive {
        Drive {
            counts: self.counts,
            rpm: self.motor_rpm,
            current_ma: self.current_ma(demand, limits),
            switch: self.switch().is_some(),
        }
    }

    fn current_ma(&self, demand: Option<f64>, (peak, continuous): (f64, f64)) -> f64 {
        let Some(demand) = demand else { return 0.0 };
        if self.stalled {
            return continuous.copysign(demand);
        }
        let k = self.config.deg_s_per_rpm();
        let gravity = self.gravity_accel() * k.signum();
        let friction =
            if self.motor_rpm.abs() > STALL_RPM { FRICTION_MA.copysign(self.motor_rpm) } else { 0.0 };
        let current = friction + self.motor_accel * INERTIA_MA_PER_RPM_S - gravity * GRAVITY_MA_PER_DEG_S2;
        current.clamp(-peak, peak)
    }

    fn gravity_accel(&self) -> f64 {
        self.config.gravity_deg_s2 * self.pitch().to_radians().sin()
    }

    fn clamp_to_end_stops(&mut self) -> bool {
        let Some([lo, hi]) = self.config.end_stops_deg() else { return false };
        if self.angle > hi || self.angle < lo {
            self.angle = self.angle.clamp(lo, hi);
            self.stop();
            return true;
        }
        false
    }

    /// Advances `dt` seconds with the controller's `demand` (`None`: power stage off) and
    /// the brake `braked` (ignored for joints without a brake).
    pub(crate) fn step(&mut self, dt: f64, demand: Option<f64>, braked: bool) {
        let k = self.config.deg_s_per_rpm();
        let before = self.motor_rpm;
        let pushing = demand.is_some_and(|d| d.abs() > STALL_RPM);
        self.stalled = false;
        if braked && self.config.brake {
            let dv = self.config.brake_decel_deg_s2 * dt;
            self.velocity =
                if self.velocity.abs() <= dv { 0.0 } else { self.velocity - dv.copysign(self.velocity) };
            self.motor_rpm = self.velocity / k;
            self.stalled = pushing;
        } else if let Some(d) = demand {
            let alpha = 1.0 - (-dt * 1000.0 / self.config.speed_loop_tau_ms).exp();
            self.motor_rpm += (d - self.motor_rpm) * alpha;
            self.velocity = self.motor_rpm * k;
        } else {
            let accel = self.gravity_accel() - self.config.free_damping_per_s * self.velocity;
            self.velocity += accel * dt;
            self.motor_rpm = self.velocity / k;
        }
        let previous = self.angle;
        self.angle += self.velocity * dt;
        if self.clamp_to_end_stops() {
            // Only motion into the stop is clamped.
            self.stalled = pushing;
        }
        // Motor revolutions = joint degrees / (deg/s per rpm) / 60.
        self.counts += (self.angle - previous) / k / 60.0 * self.config.encoder_counts_per_rev;
        self.motor_accel = (self.motor_rpm - before) / dt;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 0.001;

    fn run(j: &mut Joint, seconds: f64, demand: Option<f64>, braked: bool) {
        for _ in 0..(seconds / DT).round() as usize {
            j.step(DT, demand, braked);
        }
    }

    #[test]
    fn speed_loop_is_first_order() {
        let mut j = Joint::new(JointConfig { initial_angle_deg: 0.0, ..JointConfig::spec(1) });
        // After one time constant (50 ms) the motor is at 1 - 1/e of the demand.
        run(&mut j, 0.05, Some(1000.0), false);
        assert!((j.motor_rpm() - 1000.0 * (1.0 - (-1.0f64).exp())).abs() < 1.0, "{}", j.motor_rpm());
        run(&mut j, 1.0, Some(1000.0), false);
        // 1000 rpm / 400 * 6 = 15 deg/s.
        assert!((j.velocity() - 15.0).abs() < 1e-6);
        // Motor turns (angle / 360 * gear) revolutions: 2048 counts each.
        let revs = j.angle() / 360.0 * 400.0;
        assert!((j.counts - revs * 2048.0).abs() < 1e-6);
    }

    #[test]
    fn free_joint_falls_and_brake_holds() {
        let mut j = Joint::new(JointConfig::spec(2));
        run(&mut j, 0.5, None, true);
        assert_eq!(j.angle(), 15.0, "the brake holds");
        run(&mut j, 0.5, None, false);
        assert!(j.angle() > 18.0, "falls: {}", j.angle());
        assert!(j.velocity() > 5.0);
        let fast = j.velocity();
        // Brake at 1500 deg/s²: stops within fast / 1500 s.
        run(&mut j, fast / 1500.0 + 0.002, None, true);
        assert_eq!(j.velocity(), 0.0);
    }

    #[test]
    fn end_stop_stalls_a_pushing_motor() {
        let mut j = Joint::new(JointConfig::spec(1));
        j.place(130.0);
        assert_eq!(j.switch(), Some(Side::Upper));
        run(&mut j, 1.0, Some(2000.0), false);
        assert_eq!(j.angle(), 133.0, "end stop = switch 125 + 8");
        assert!(j.stalled);
        assert_eq!(j.drive(Some(2000.0), (2000.0, 700.0)).current_ma, 700.0);
    }
}
