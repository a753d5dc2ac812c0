//! The simulator's error type: bad configuration and misuse of the test hooks (our own
//! misuse, never a device refusal: refusals are replies like "LSSTOP" or "TO").

use thiserror::Error;

/// What went wrong setting up or poking the simulated arm.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum SimError {
    /// The configuration cannot be simulated (the message names the field).
    #[error("invalid arm configuration: {0}")]
    Config(String),
    /// There is no joint with this number (1..=6).
    #[error("joint {0} does not exist (joints are 1..=6)")]
    NoSuchJoint(u8),
    /// The joint has no limit switch (joints 4 and 6 turn endlessly).
    #[error("joint {joint} has no limit switch")]
    NoLimitSwitch {
        /// The joint asked for.
        joint: u8,
    },
    /// The module has no gripper (only 0xE6 drives the jaws).
    #[error("joint {joint} has no gripper")]
    NoGripper {
        /// The joint asked for.
        joint: u8,
    },
}
