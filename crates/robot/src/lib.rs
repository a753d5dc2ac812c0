//! # motus-robot — the 3-wheel omnidirectional robot of seed 000 on CANopen drives
//!
//! - [`wheels`]: the three wheel drives (CiA 402 over the CANopen master) as the
//!   controller's `WheelDrives`: bring-up (boot-up, heartbeat consumer, PDO set, enable,
//!   homing), synchronous starts (RPDO2 + one SYNC), and a watchdog that quick-stops every
//!   wheel when one drive's heartbeat stops or it signals an emergency.
//! - [`sim`]: the simulated robot — three simulated IclA drives on a CAN bus, the true
//!   pose with configurable wheel slip, and the optical-mouse sensor fed by the true motion.
//! - [`sensor`]: reads the optical-mouse converter on a serial line into the controller.
//!
//! The math (kinematics, programs, odometry, fusion, controller) is in `motus-omni`.

#![forbid(unsafe_code)]

pub mod sensor;
pub mod sim;
pub mod wheels;

pub use wheels::{CanopenWheels, WheelError, WheelSettings};
