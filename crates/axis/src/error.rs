//! Why an axis command was refused or failed.

use std::time::Duration;

/// Who is to blame for an error: decides whether retrying can help.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Blame {
    /// The communication failed (time-out, corrupted frames): the device may be fine.
    Bus,
    /// The device answered and refused or reported a fault.
    Device,
    /// The request was invalid for the current state or configuration.
    Caller,
}

/// A refused or failed axis command, saying why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AxisError {
    /// Motion needs a valid position reference.
    #[error("axis {axis} is not homed: run `home` first{detail}")]
    NotHomed {
        /// Axis name.
        axis: String,
        /// Extra explanation (e.g. a reset was detected), starting with "; " or empty.
        detail: String,
    },
    /// The target is outside the allowed range.
    #[error("target {target} is beyond the limit of axis {axis} (allowed {min} .. {max}, {unit})")]
    BeyondLimit {
        /// Axis name.
        axis: String,
        /// Requested target.
        target: f64,
        /// Lowest allowed position.
        min: f64,
        /// Highest allowed position.
        max: f64,
        /// Unit of the numbers ("device units", "m", "rad", "deg").
        unit: String,
    },
    /// The drive must be enabled first.
    #[error("axis {axis} is not enabled: run `enable` first")]
    NotEnabled {
        /// Axis name.
        axis: String,
    },
    /// The device reports a fault.
    #[error("axis {axis}: device fault: {reason}")]
    DeviceFault {
        /// Axis name.
        axis: String,
        /// The device's reason.
        reason: String,
    },
    /// The device refused the command (with its own words).
    #[error("axis {axis}: device refused {command}: {reason}")]
    Refused {
        /// Axis name.
        axis: String,
        /// Command name.
        command: String,
        /// The device's reason.
        reason: String,
    },
    /// No (valid) answer in time.
    #[error("axis {axis}: no valid reply within {timeout:?} after {attempts} attempt(s){detail}")]
    Timeout {
        /// Axis name.
        axis: String,
        /// Time-out per attempt.
        timeout: Duration,
        /// Attempts made.
        attempts: u32,
        /// Extra explanation, starting with "; " or empty.
        detail: String,
    },
    /// The bus or link failed (port closed, IO error).
    #[error("axis {axis}: communication failed: {reason}")]
    Communication {
        /// Axis name.
        axis: String,
        /// What failed.
        reason: String,
    },
    /// The device does not support the command.
    #[error("axis {axis} does not support {command}")]
    Unsupported {
        /// Axis name.
        axis: String,
        /// Command name.
        command: String,
    },
    /// The command's arguments are invalid (not a number, zero velocity...).
    #[error("invalid argument for axis {axis}: {reason}")]
    InvalidArgument {
        /// Axis name.
        axis: String,
        /// What is wrong.
        reason: String,
    },
    /// Waiting for motion to end took too long.
    #[error("axis {axis}: {what} did not finish within {timeout:?}")]
    WaitTimeout {
        /// Axis name.
        axis: String,
        /// What was awaited.
        what: String,
        /// How long we waited.
        timeout: Duration,
    },
}

impl AxisError {
    /// Who is to blame.
    pub fn blame(&self) -> Blame {
        match self {
            AxisError::Timeout { .. } | AxisError::Communication { .. } => Blame::Bus,
            AxisError::DeviceFault { .. } | AxisError::Refused { .. } | AxisError::WaitTimeout { .. } => {
                Blame::Device
            }
            AxisError::NotHomed { .. }
            | AxisError::BeyondLimit { .. }
            | AxisError::NotEnabled { .. }
            | AxisError::Unsupported { .. }
            | AxisError::InvalidArgument { .. } => Blame::Caller,
        }
    }
}
