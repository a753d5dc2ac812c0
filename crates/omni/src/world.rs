//! A simulated world for the simulated robot: the **true** pose, moved by the wheels'
//! ground contact, with per-wheel slip.
//!
//! Slip model: a slip factor `k_i` (0 = none, 0.1 = the wheel's ground contact delivers
//! only 90 % of its travel) scales wheel `i`'s effective travel; the body then moves by
//! the forward kinematics of the effective travels (the three omni wheels fix the three
//! degrees of freedom). A call is one constant-twist step, so the translation it returns
//! is exactly what a sensor at the centre, aligned with the robot axes, measures.

use crate::kinematics::{Geometry, Motion, Pose};

/// The true state of the simulated robot.
#[derive(Debug, Clone)]
pub struct RobotWorld {
    geometry: Geometry,
    pose: Pose,
    slip: [f64; 3],
    wheel_travel: [f64; 3],
}

impl RobotWorld {
    /// A robot at `pose` without slip.
    #[must_use]
    pub fn new(geometry: Geometry, pose: Pose) -> RobotWorld {
        RobotWorld { geometry, pose, slip: [0.0; 3], wheel_travel: [0.0; 3] }
    }

    /// Sets the slip factors (each clamped to 0..=1).
    pub fn set_slip(&mut self, slip: [f64; 3]) {
        self.slip = slip.map(|k| if k.is_finite() { k.clamp(0.0, 1.0) } else { 0.0 });
    }

    /// The slip factors.
    #[must_use]
    pub fn slip(&self) -> [f64; 3] {
        self.slip
    }

    /// Turns the wheels by `ds` metres each (commanded travel): integrates the true pose
    /// and returns the true robot-frame motion (its x, y feed the mouse sensor).
    pub fn apply_wheel_motion(&mut self, ds: [f64; 3]) -> Motion {
        let mut effective = [0.0; 3];
        for (((e, d), k), total) in
            effective.iter_mut().zip(ds).zip(self.slip).zip(self.wheel_travel.iter_mut())
        {
            *e = d * (1.0 - k);
            *total += d;
        }
        let m = self.geometry.forward(effective);
        self.pose = self.pose.advance(m);
        m
    }

    /// [`RobotWorld::apply_wheel_motion`] with the travel in Inc.
    pub fn apply_wheel_inc(&mut self, ds_inc: [f64; 3]) -> Motion {
        let g = self.geometry;
        self.apply_wheel_motion(ds_inc.map(|d| g.inc_to_metres(d)))
    }

    /// The true pose.
    #[must_use]
    pub fn pose(&self) -> Pose {
        self.pose
    }

    /// Total commanded wheel travel so far, metres.
    #[must_use]
    pub fn wheel_travel(&self) -> [f64; 3] {
        self.wheel_travel
    }

    /// The geometry.
    #[must_use]
    pub fn geometry(&self) -> Geometry {
        self.geometry
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn slip_on_wheel_one_shortens_and_turns() {
        let g = Geometry::default();
        let mut w = RobotWorld::new(g, Pose::default());
        w.set_slip([0.1, 0.0, 0.0]);
        // Commanded 1 m forward: s = (1, -0.5, -0.5); effective (0.9, -0.5, -0.5):
        // x = (1.8 + 1)/3 = 0.9333, y = 0, theta = -0.1/(3 * 0.2) = -0.1667 rad (by hand).
        let m = w.apply_wheel_motion(g.inverse(Motion::new(1.0, 0.0, 0.0)));
        assert!((m.x - 0.933_333).abs() < 1e-6 && m.y.abs() < 1e-12);
        assert!((m.theta + 0.166_667).abs() < 1e-6);
        assert!((w.pose().heading + 0.166_667).abs() < 1e-6);
    }
}
