//! The IclA D065 motor and gear (specs/omni-robot.md): 12 increments per motor revolution
//! (Hall sensors), gear 160:9, so 213.33 Inc per output revolution; positions, speeds and
//! accelerations in Inc, Inc/s, Inc/s^2. The model: with the power stage enabled the shaft
//! follows the demand position with a first-order lag; a blocked load holds it still; with
//! the power stage off it stays where it is (0.7 Nm holding torque, no external load).
//!
//! Positions are kept in "world" increments (the physical shaft angle); the drive's
//! position counter is world + offset, so setting the position (homing, 0x200B) only moves
//! the offset and the simulated limit switches stay where they are.

/// Increments per motor revolution.
pub const INC_PER_MOTOR_REV: f64 = 12.0;
/// Gear ratio (motor revolutions per output revolution).
pub const GEAR_RATIO: f64 = 160.0 / 9.0;
/// Increments per output revolution (213.33).
pub const INC_PER_OUTPUT_REV: f64 = INC_PER_MOTOR_REV * GEAR_RATIO;

/// The shaft.
#[derive(Debug, Clone, PartialEq)]
pub struct Motor {
    world: f64,
    velocity: f64,
    offset: f64,
    lag: f64,
    blocked: bool,
}

impl Motor {
    /// A motor at drive position `position` with lag time constant `lag` (s).
    pub fn new(position: f64, lag: f64) -> Self {
        Self { world: position, velocity: 0.0, offset: 0.0, lag: lag.max(0.0), blocked: false }
    }

    /// The drive's actual position (Inc, not rounded).
    pub fn position(&self) -> f64 {
        self.world + self.offset
    }

    /// The physical shaft position (Inc).
    pub fn world(&self) -> f64 {
        self.world
    }

    /// Actual velocity (Inc/s).
    pub fn velocity(&self) -> f64 {
        self.velocity
    }

    /// Blocks or frees the load.
    pub fn set_blocked(&mut self, blocked: bool) {
        self.blocked = blocked;
    }

    /// Whether the load is blocked.
    pub fn blocked(&self) -> bool {
        self.blocked
    }

    /// Sets the drive position counter to `position` without moving the shaft.
    pub fn set_position(&mut self, position: f64) {
        self.offset = position - self.world;
    }

    /// Converts a drive position to the world frame.
    pub fn to_world(&self, position: f64) -> f64 {
        position - self.offset
    }

    /// One step of `dt` seconds toward the drive-frame `demand` (if powered).
    pub fn step(&mut self, demand: f64, powered: bool, dt: f64) {
        let before = self.world;
        if powered && !self.blocked {
            let target = demand - self.offset;
            let alpha = if self.lag <= dt { 1.0 } else { dt / self.lag };
            self.world += (target - self.world) * alpha;
            if (target - self.world).abs() < 1e-3 {
                self.world = target;
            }
        }
        self.velocity = if dt > 0.0 { (self.world - before) / dt } else { 0.0 };
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn gear_and_lag() {
        // 12 x 160 / 9 = 213.33 Inc per output revolution (spec: "about 213").
        assert!((INC_PER_OUTPUT_REV - 213.333).abs() < 1e-3);
        let mut m = Motor::new(0.0, 0.01);
        for _ in 0..200 {
            m.step(100.0, true, 0.001);
        }
        assert_eq!(m.position(), 100.0, "settles exactly on the demand");
        m.set_position(0.0);
        assert_eq!((m.position(), m.world()), (0.0, 100.0));
        m.set_blocked(true);
        m.step(50.0, true, 0.001);
        assert_eq!(m.position(), 0.0);
        m.set_blocked(false);
        m.step(50.0, false, 0.001);
        assert_eq!(m.position(), 0.0, "no power, no motion");
    }
}
