//! Driver settings: time-outs and profile defaults.

use std::time::Duration;

/// A motion profile in drive units (inc, inc/s, inc/s^2), written to 0x6081/0x6083/0x6084.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Profile {
    /// Profile velocity 0x6081.
    pub velocity: u32,
    /// Profile acceleration 0x6083.
    pub acceleration: u32,
    /// Profile deceleration 0x6084.
    pub deceleration: u32,
}

impl Profile {
    /// The seed's IclA profile: 248 Inc/s (70 rpm at the output), 1000 Inc/s^2 up,
    /// 400 Inc/s^2 down (specs/omni-robot.md).
    pub const ICLA_SEED: Profile = Profile { velocity: 248, acceleration: 1000, deceleration: 400 };
}

/// Time-outs and polling of the driver.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveSettings {
    /// Longest wait for one power-state transition.
    pub transition_timeout: Duration,
    /// Longest wait for the set-point acknowledge (bit 12).
    pub set_point_timeout: Duration,
    /// Statusword polling interval while waiting.
    pub poll_interval: Duration,
    /// How long the fault-reset bit is held high.
    pub fault_reset_pulse: Duration,
    /// Homing method used by `home` (35 = current position, the IclA robot's choice).
    pub homing_method: i8,
}

impl Default for DriveSettings {
    fn default() -> Self {
        Self {
            transition_timeout: Duration::from_millis(1000),
            set_point_timeout: Duration::from_millis(1000),
            poll_interval: Duration::from_millis(5),
            fault_reset_pulse: Duration::from_millis(20),
            homing_method: 35,
        }
    }
}
