//! Geometry and kinematics of the 3-wheel omni base (specs/omni-robot.md, "Kinematics").
//!
//! Robot frame: x forward along wheel 1's drive direction, y to the left, theta
//! counter-clockwise. Each wheel's **positive drive direction** is a unit vector `u_i`;
//! the spec's corrected formulas fix them:
//!
//! | wheel | drive direction `u_i` | mounted at (angle from the centre, radius `R`) |
//! |---|---|---|
//! | 1 | 0 deg: ( 1, 0) | 270 deg: (0, -R) |
//! | 2 | 240 deg: (-1/2, -sqrt3/2) | 150 deg |
//! | 3 | 120 deg: (-1/2, +sqrt3/2) | 30 deg |
//!
//! i.e. the drive directions are 0/240/120 deg (wheels 120 deg apart) and every positive
//! drive direction is tangential, counter-clockwise about the centre (`u_i = z x p_i / R`).
//! A contact point moves by `t + dtheta z x p_i` for a body displacement `t` and a small
//! rotation `dtheta`, so wheel `i` travels `s_i = u_i . t + R dtheta`:
//!
//! * s1 = sx + R dth
//! * s2 = -sx/2 - (sqrt3/2) sy + R dth
//! * s3 = -sx/2 + (sqrt3/2) sy + R dth
//!
//! and, since `sum u_i = 0` and `sum u_i u_i^T = 3/2 I`, the exact inverse (forward
//! kinematics): sx = (2 s1 - s2 - s3)/3, sy = (s3 - s2)/sqrt3, dth = (s1+s2+s3)/(3R).
//! The seed's `sqrt(3/2)` is corrected to `sqrt(3)/2` and its inverse (an average of two
//! single-wheel estimates that ignores rotation) replaced.
//!
//! Scale: 213 Inc per wheel revolution of 37.7 cm, 565 Inc/m (the seed rounds to 6 Inc/cm).

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// sqrt(3).
pub const SQRT3: f64 = 1.732_050_807_568_877_2;
/// Increments per wheel (output shaft) revolution of the IclA D065 (gear 160:9).
pub const INC_PER_WHEEL_REV: f64 = 213.0;
/// Wheel circumference, metres (37.7 cm).
pub const WHEEL_CIRCUMFERENCE_M: f64 = 0.377;
/// Default centre-to-wheel distance, metres. The seed gives no figure; 0.2 m is a
/// typical radius for a chassis carrying three 65 mm drives and 12 cm wheels.
pub const DEFAULT_RADIUS_M: f64 = 0.2;
/// Positive drive directions of wheels 1, 2, 3 in the robot frame, degrees.
pub const DRIVE_DIRECTION_DEG: [f64; 3] = [0.0, 240.0, 120.0];
/// Where wheels 1, 2, 3 are mounted, as angles from the centre in the robot frame, degrees.
pub const MOUNT_ANGLE_DEG: [f64; 3] = [270.0, 150.0, 30.0];

/// A rigid displacement in the robot frame (at its start): translation x, y (metres)
/// and rotation theta (radians). With synchronised wheels (every wheel at the same
/// fraction of its travel at every instant) the robot moves with a constant twist, so a
/// `Motion` with rotation follows a circular arc in the world.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Motion {
    /// Forward, metres.
    pub x: f64,
    /// Left, metres.
    pub y: f64,
    /// Counter-clockwise rotation, radians.
    pub theta: f64,
}

impl Motion {
    /// A motion.
    #[must_use]
    pub fn new(x: f64, y: f64, theta: f64) -> Motion {
        Motion { x, y, theta }
    }

    /// Length of the translation, metres.
    #[must_use]
    pub fn distance(&self) -> f64 {
        self.x.hypot(self.y)
    }
}

/// A pose in the world frame: position (metres) and heading (radians, counter-clockwise
/// from the world x axis to the robot x axis).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// World x, metres.
    pub x: f64,
    /// World y, metres.
    pub y: f64,
    /// Heading, radians.
    pub heading: f64,
}

/// `sin(a)/a`, exact near 0.
fn sinc(a: f64) -> f64 {
    if a.abs() < 1e-6 {
        1.0 - a * a / 6.0
    } else {
        a.sin() / a
    }
}

/// Wraps an angle to (-pi, pi].
#[must_use]
pub fn wrap_angle(a: f64) -> f64 {
    let r = a.rem_euclid(2.0 * PI);
    if r > PI {
        r - 2.0 * PI
    } else {
        r
    }
}

/// A robot-frame vector in the world frame, for a robot at `heading`.
#[must_use]
pub fn robot_to_world(x: f64, y: f64, heading: f64) -> (f64, f64) {
    let (s, c) = heading.sin_cos();
    (c * x - s * y, s * x + c * y)
}

/// A world-frame vector in the robot frame, for a robot at `heading`.
#[must_use]
pub fn world_to_robot(x: f64, y: f64, heading: f64) -> (f64, f64) {
    robot_to_world(x, y, -heading)
}

impl Pose {
    /// A pose.
    #[must_use]
    pub fn new(x: f64, y: f64, heading: f64) -> Pose {
        Pose { x, y, heading }
    }

    /// The pose after `m` (a constant twist in the robot frame). This is the midpoint
    /// rule — the translation rotated by the heading at mid-rotation — with the chord
    /// length factor `sinc(theta/2)`, which makes it exact for a constant twist.
    #[must_use]
    pub fn advance(&self, m: Motion) -> Pose {
        let mid = self.heading + m.theta / 2.0;
        let k = sinc(m.theta / 2.0);
        let (wx, wy) = robot_to_world(m.x * k, m.y * k, mid);
        Pose { x: self.x + wx, y: self.y + wy, heading: self.heading + m.theta }
    }

    /// The robot-frame motion that takes this pose exactly to `target` on one arc (the
    /// inverse of [`Pose::advance`]); the rotation is the shortest one.
    #[must_use]
    pub fn motion_to(&self, target: Pose) -> Motion {
        let theta = wrap_angle(target.heading - self.heading);
        let k = sinc(theta / 2.0);
        let (x, y) = world_to_robot(target.x - self.x, target.y - self.y, self.heading + theta / 2.0);
        Motion { x: x / k, y: y / k, theta }
    }

    /// Distance to another pose's position, metres.
    #[must_use]
    pub fn distance_to(&self, other: &Pose) -> f64 {
        (self.x - other.x).hypot(self.y - other.y)
    }
}

/// The base's geometry: centre-to-wheel distance and wheel scale.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Geometry {
    /// Centre-to-wheel distance R, metres.
    pub radius: f64,
    /// Wheel increments per metre of wheel travel (213 / 0.377 = 565).
    pub inc_per_metre: f64,
}

impl Default for Geometry {
    fn default() -> Self {
        Geometry { radius: DEFAULT_RADIUS_M, inc_per_metre: INC_PER_WHEEL_REV / WHEEL_CIRCUMFERENCE_M }
    }
}

impl Geometry {
    /// Wheel travels (metres) for a robot-frame motion.
    #[must_use]
    pub fn inverse(&self, m: Motion) -> [f64; 3] {
        let r = self.radius * m.theta;
        let h = SQRT3 / 2.0;
        [m.x + r, -m.x / 2.0 - h * m.y + r, -m.x / 2.0 + h * m.y + r]
    }

    /// Robot-frame motion for wheel travels (metres).
    #[must_use]
    pub fn forward(&self, s: [f64; 3]) -> Motion {
        let [s1, s2, s3] = s;
        Motion {
            x: (2.0 * s1 - s2 - s3) / 3.0,
            y: (s3 - s2) / SQRT3,
            theta: (s1 + s2 + s3) / (3.0 * self.radius),
        }
    }

    /// Wheel travels in Inc for a robot-frame motion.
    #[must_use]
    pub fn inverse_inc(&self, m: Motion) -> [f64; 3] {
        self.inverse(m).map(|s| s * self.inc_per_metre)
    }

    /// Robot-frame motion for wheel travels in Inc.
    #[must_use]
    pub fn forward_inc(&self, s: [f64; 3]) -> Motion {
        self.forward(s.map(|v| v / self.inc_per_metre))
    }

    /// Metres for a travel in Inc.
    #[must_use]
    pub fn inc_to_metres(&self, inc: f64) -> f64 {
        inc / self.inc_per_metre
    }

    /// Inc for a travel in metres.
    #[must_use]
    pub fn metres_to_inc(&self, metres: f64) -> f64 {
        metres * self.inc_per_metre
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn drive_directions_match_the_formulas() {
        // u_i from the angle table equals the coefficients of sx, sy in s_i; the mount
        // point p_i satisfies u_i = z x p_i / R.
        let g = Geometry::default();
        for i in 0..3 {
            let (uy, ux) = DRIVE_DIRECTION_DEG[i].to_radians().sin_cos();
            let s = g.inverse(Motion::new(1.0, 0.0, 0.0))[i];
            assert!((s - ux).abs() < 1e-12);
            let s = g.inverse(Motion::new(0.0, 1.0, 0.0))[i];
            assert!((s - uy).abs() < 1e-12);
            let (py, px) = MOUNT_ANGLE_DEG[i].to_radians().sin_cos();
            assert!((-py - ux).abs() < 1e-12 && (px - uy).abs() < 1e-12);
        }
    }
}
