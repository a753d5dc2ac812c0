//! Dead reckoning from the wheel positions (Inc, as read from the drives' 0x6064).
//!
//! Each update turns the wheel increments since the previous one into a robot-frame
//! motion (forward kinematics) and advances the pose with the midpoint heading
//! ([`Pose::advance`]), which is exact while the wheels move in proportion, as they do
//! in a synchronised move. Call it often (every controller cycle) so that moves that are
//! not synchronised are integrated in small steps.

use crate::kinematics::{Geometry, Motion, Pose};

/// One odometry step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WheelStep {
    /// Wheel travels since the previous update, metres.
    pub travel: [f64; 3],
    /// The robot-frame motion they imply.
    pub motion: Motion,
}

/// Wheel-only dead reckoning.
#[derive(Debug, Clone)]
pub struct WheelOdometry {
    geometry: Geometry,
    last: Option<[i32; 3]>,
    pose: Pose,
}

impl WheelOdometry {
    /// Starts at `pose`; the first update only records the positions.
    #[must_use]
    pub fn new(geometry: Geometry, pose: Pose) -> WheelOdometry {
        WheelOdometry { geometry, last: None, pose }
    }

    /// Integrates new wheel positions (Inc). Wraps around like the drives' 32-bit counters.
    pub fn update(&mut self, positions: [i32; 3]) -> WheelStep {
        let Some(last) = self.last.replace(positions) else {
            return WheelStep::default();
        };
        let mut travel = [0.0; 3];
        for ((t, p), l) in travel.iter_mut().zip(positions).zip(last) {
            *t = self.geometry.inc_to_metres(f64::from(p.wrapping_sub(l)));
        }
        let motion = self.geometry.forward(travel);
        self.pose = self.pose.advance(motion);
        WheelStep { travel, motion }
    }

    /// The dead-reckoned pose.
    #[must_use]
    pub fn pose(&self) -> Pose {
        self.pose
    }

    /// Sets the pose (positions keep being tracked).
    pub fn set_pose(&mut self, pose: Pose) {
        self.pose = pose;
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
    fn straight_line_and_wrap() {
        let g = Geometry::default();
        let mut o = WheelOdometry::new(g, Pose::default());
        o.update([i32::MAX - 10, 0, 0]);
        // Wheel 1 +565 Inc (wrapping), wheels 2, 3 -282.5 -> 1 m forward, no rotation.
        let step = o.update([(i32::MAX - 10).wrapping_add(565), -282, -283]);
        assert!((step.motion.x - 1.0).abs() < 1e-3, "{step:?}");
        assert!(step.motion.theta.abs() < 1e-2);
        assert!((o.pose().x - 1.0).abs() < 1e-3);
    }
}
