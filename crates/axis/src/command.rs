//! Commands an axis accepts and the capabilities that say which.

use serde::{Deserialize, Serialize};

/// Direction of a jog.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    /// Towards larger positions.
    Positive,
    /// Towards smaller positions.
    Negative,
}

impl Direction {
    /// +1.0 or -1.0.
    pub fn sign(self) -> f64 {
        match self {
            Direction::Positive => 1.0,
            Direction::Negative => -1.0,
        }
    }
}

/// Velocity and acceleration limits of one move, in SI units (m/s, m/s^2 or rad/s,
/// rad/s^2). `None` means "the device's configured default".
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct MotionProfile {
    /// Cruise velocity (positive).
    pub velocity: Option<f64>,
    /// Acceleration (positive).
    pub acceleration: Option<f64>,
    /// Deceleration (positive); defaults to the acceleration.
    pub deceleration: Option<f64>,
}

/// A command to an axis. Positions and distances are SI.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "command", rename_all = "snake_case")]
pub enum AxisCommand {
    /// Switch the power stage / drive on.
    Enable,
    /// Switch the power stage / drive off (after stopping).
    Disable,
    /// Run the device's homing (reference) procedure.
    Home,
    /// Move to an absolute position.
    MoveAbsolute {
        /// Target position.
        target: f64,
        /// Profile of the move.
        #[serde(default)]
        profile: MotionProfile,
    },
    /// Move by a distance from the current target (or position when idle).
    MoveRelative {
        /// Signed distance.
        distance: f64,
        /// Profile of the move.
        #[serde(default)]
        profile: MotionProfile,
    },
    /// Move continuously in one direction until stopped or a limit is reached.
    Jog {
        /// Direction of travel.
        direction: Direction,
        /// Profile (velocity and acceleration) of the jog.
        #[serde(default)]
        profile: MotionProfile,
    },
    /// Decelerate to standstill with the normal deceleration.
    Stop,
    /// Stop as fast as the device can (quick stop / emergency ramp).
    QuickStop,
    /// Clear a latched fault whose cause is gone.
    FaultReset,
}

impl AxisCommand {
    /// A short lowercase name for messages and logs.
    pub fn name(&self) -> &'static str {
        match self {
            AxisCommand::Enable => "enable",
            AxisCommand::Disable => "disable",
            AxisCommand::Home => "home",
            AxisCommand::MoveAbsolute { .. } => "move-abs",
            AxisCommand::MoveRelative { .. } => "move-rel",
            AxisCommand::Jog { .. } => "jog",
            AxisCommand::Stop => "stop",
            AxisCommand::QuickStop => "quick-stop",
            AxisCommand::FaultReset => "fault-reset",
        }
    }

    /// True if the command may start motion.
    pub fn starts_motion(&self) -> bool {
        matches!(
            self,
            AxisCommand::Home
                | AxisCommand::MoveAbsolute { .. }
                | AxisCommand::MoveRelative { .. }
                | AxisCommand::Jog { .. }
        )
    }
}

/// Which commands and readings a device supports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Capabilities {
    /// Enable / Disable.
    pub enable: bool,
    /// Home.
    pub home: bool,
    /// MoveAbsolute.
    pub move_absolute: bool,
    /// MoveRelative.
    pub move_relative: bool,
    /// Jog.
    pub jog: bool,
    /// Stop.
    pub stop: bool,
    /// QuickStop.
    pub quick_stop: bool,
    /// FaultReset.
    pub fault_reset: bool,
    /// The state carries a velocity reading.
    pub reports_velocity: bool,
    /// The state carries a current reading.
    pub reports_current: bool,
    /// The state carries a following error.
    pub reports_following_error: bool,
    /// The device has a holding brake it reports.
    pub brake: bool,
}

impl Capabilities {
    /// A positioning axis: every command supported, no optional readings or brake.
    /// Drivers start from this and switch off what their device lacks.
    pub const POSITIONING: Capabilities = Capabilities {
        enable: true,
        home: true,
        move_absolute: true,
        move_relative: true,
        jog: true,
        stop: true,
        quick_stop: true,
        fault_reset: true,
        reports_velocity: false,
        reports_current: false,
        reports_following_error: false,
        brake: false,
    };

    /// True if this command kind is supported.
    pub fn supports(&self, command: &AxisCommand) -> bool {
        match command {
            AxisCommand::Enable | AxisCommand::Disable => self.enable,
            AxisCommand::Home => self.home,
            AxisCommand::MoveAbsolute { .. } => self.move_absolute,
            AxisCommand::MoveRelative { .. } => self.move_relative,
            AxisCommand::Jog { .. } => self.jog,
            AxisCommand::Stop => self.stop,
            AxisCommand::QuickStop => self.quick_stop,
            AxisCommand::FaultReset => self.fault_reset,
        }
    }
}
