//! # motus-omni — the 3-wheel omnidirectional robot base
//!
//! Pure math and control for the robot of `specs/omni-robot.md` (seed 000): three omni
//! wheels at 120 deg, each on an IclA D065 drive (213 Inc per wheel revolution of 37.7 cm),
//! an optical-mouse sensor under the chassis.
//!
//! * [`kinematics`]: geometry, full 3-DOF inverse and forward kinematics (the spec's
//!   corrected formulas plus rotation), world <-> robot frame.
//! * [`programs`]: the seed's demo programs (line, square, octagon with the corrected
//!   order, return to zero) and ramps.
//! * [`sync_profile`]: per-wheel velocity/acceleration/deceleration so all wheels of a
//!   move start and finish together.
//! * [`odometry`]: dead reckoning from wheel positions.
//! * [`fusion`]: wheel odometry fused with the mouse sensor, slip detection.
//! * [`world`]: a simulated world (the true pose, wheel slip) for tests and simulators.
//! * [`controller`]: the supervisory controller over a [`controller::WheelDrives`] seam.
//!
//! No IO here: the CANopen implementation of [`controller::WheelDrives`] lives elsewhere.

#![forbid(unsafe_code)]

pub mod controller;
pub mod fusion;
pub mod kinematics;
pub mod odometry;
pub mod programs;
pub mod sync_profile;
pub mod world;

pub use controller::{Robot, RobotConfig, RobotError, SensorInput, WheelDrives};
pub use fusion::{FusedPose, Fusion, SlipEvent, SlipTolerance};
pub use kinematics::{Geometry, Motion, Pose};
pub use odometry::WheelOdometry;
pub use programs::{Program, Ramp, Step};
pub use sync_profile::{synchronise, ScaledProfile, WheelProfile};
pub use world::RobotWorld;
