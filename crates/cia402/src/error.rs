//! Errors of the CiA 402 driver.

use crate::io::IoError;
use motus_cia402_protocol::{Mode, PowerState};
use std::time::Duration;

/// Why a drive operation failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DriveError {
    /// Object access failed.
    #[error(transparent)]
    Io(#[from] IoError),
    /// The drive did not reach a power state in time.
    #[error("node {node}: stuck in \"{state}\" (statusword 0x{statusword:04X}) while going to \"{target}\" for {waited:?}")]
    StateTimeout {
        /// Node id.
        node: u8,
        /// Last state seen.
        state: PowerState,
        /// Statusword seen last.
        statusword: u16,
        /// Wanted state.
        target: PowerState,
        /// Time waited.
        waited: Duration,
    },
    /// The drive is in fault (with its error code 0x603F when readable).
    #[error("node {node}: drive in fault{}", code.map(|c| format!(", error code 0x{c:04X}")).unwrap_or_default())]
    Fault {
        /// Node id.
        node: u8,
        /// 0x603F error code.
        code: Option<u16>,
    },
    /// Fault reset did not clear the fault (its cause is still present).
    #[error("node {node}: fault reset refused, the cause is still present{}", code.map(|c| format!(" (error code 0x{c:04X})")).unwrap_or_default())]
    FaultPersists {
        /// Node id.
        node: u8,
        /// 0x603F error code.
        code: Option<u16>,
    },
    /// The drive did not take the mode of operation (0x6061 shows another one).
    #[error("node {node}: mode {wanted} requested, the drive displays {displayed}")]
    ModeRefused {
        /// Node id.
        node: u8,
        /// Requested mode.
        wanted: Mode,
        /// Mode in 0x6061.
        displayed: Mode,
    },
    /// The drive does not list the mode in 0x6502.
    #[error("node {node}: mode {mode} is not supported (0x6502 = 0x{supported:08X})")]
    ModeUnsupported {
        /// Node id.
        node: u8,
        /// Mode.
        mode: Mode,
        /// 0x6502 value.
        supported: u32,
    },
    /// The operation needs "operation enabled".
    #[error("node {node}: not enabled (state \"{state}\")")]
    NotEnabled {
        /// Node id.
        node: u8,
        /// Current state.
        state: PowerState,
    },
    /// The drive did not acknowledge a set-point (statusword bit 12).
    #[error("node {node}: set-point not acknowledged within {waited:?} (statusword 0x{statusword:04X})")]
    SetPointNotAcknowledged {
        /// Node id.
        node: u8,
        /// Statusword seen last.
        statusword: u16,
        /// Time waited.
        waited: Duration,
    },
    /// A motion did not finish in time.
    #[error("node {node}: {what} not finished within {waited:?} (statusword 0x{statusword:04X})")]
    MotionTimeout {
        /// Node id.
        node: u8,
        /// What was awaited.
        what: String,
        /// Statusword seen last.
        statusword: u16,
        /// Time waited.
        waited: Duration,
    },
    /// The drive reported a following error (statusword bit 13).
    #[error("node {node}: following error (statusword 0x{statusword:04X})")]
    FollowingError {
        /// Node id.
        node: u8,
        /// Statusword.
        statusword: u16,
    },
    /// Homing ended in error.
    #[error("node {node}: homing failed (statusword 0x{statusword:04X})")]
    HomingFailed {
        /// Node id.
        node: u8,
        /// Statusword.
        statusword: u16,
    },
    /// A target beyond the software position limits.
    #[error("node {node}: target {target} is outside the software limits {min} .. {max}")]
    BeyondLimit {
        /// Node id.
        node: u8,
        /// Target.
        target: i64,
        /// Lower limit.
        min: i32,
        /// Upper limit.
        max: i32,
    },
    /// An argument is invalid.
    #[error("node {node}: {reason}")]
    InvalidArgument {
        /// Node id.
        node: u8,
        /// What is wrong.
        reason: String,
    },
}
