//! The CiA 402 drive profile ("drives and motion control"), sans-IO: what a drive and its
//! master agree on, whatever carries it.
//!
//! * [`index`]: object dictionary indices of the CiA 402 objects Motus uses.
//! * [`cw`] and [`sw`]: controlword (0x6040) and statusword (0x6041) bits.
//! * The power drive system state machine: [`PowerState`] decoded from a statusword with
//!   the masks of the profile, [`DeviceCommand`] decoded from a controlword, and
//!   [`next_state`] (transitions 0-16).
//! * [`Mode`] (modes of operation, 0x6060/0x6061) and [`HomingStatus`].
//!
//! Pure definitions shared by the master side (the driver, `motus-cia402`) and the device
//! side (the simulated drive, `motus-icla-sim`); no IO, threads or clocks. The profile does
//! not depend on CANopen's codec: the objects travel by SDO and PDO over CANopen today, and
//! would equally over another transport of the object dictionary.
//! Source: `specs/canopen.md` part 2 (tables 2.1-2.9).
//!
//! ```
//! use motus_cia402_protocol::{next_state, sw, DeviceCommand, PowerState};
//! let state = PowerState::from_statusword(sw::SWITCH_ON_DISABLED);
//! assert_eq!(state, PowerState::SwitchOnDisabled);
//! let command = DeviceCommand::from_controlword(0x0006);
//! assert_eq!(command, Some(DeviceCommand::Shutdown));
//! // transition 2: "switch on disabled" -> "ready to switch on"
//! assert_eq!(next_state(state, DeviceCommand::Shutdown, 2), Some((PowerState::ReadyToSwitchOn, 2)));
//! ```
#![forbid(unsafe_code)]

mod mode;
mod power;

pub use mode::{HomingStatus, Mode};
pub use power::{next_state, DeviceCommand, PowerState};

/// Object dictionary indices of the CiA 402 objects Motus uses (spec 2.8).
pub mod index {
    /// Error code (UNSIGNED16, ro).
    pub const ERROR_CODE: u16 = 0x603F;
    /// Controlword (UNSIGNED16, rw).
    pub const CONTROLWORD: u16 = 0x6040;
    /// Statusword (UNSIGNED16, ro).
    pub const STATUSWORD: u16 = 0x6041;
    /// Quick stop option code (INTEGER16).
    pub const QUICK_STOP_OPTION: u16 = 0x605A;
    /// Shutdown option code (INTEGER16).
    pub const SHUTDOWN_OPTION: u16 = 0x605B;
    /// Disable operation option code (INTEGER16).
    pub const DISABLE_OPERATION_OPTION: u16 = 0x605C;
    /// Fault reaction option code (INTEGER16).
    pub const FAULT_REACTION_OPTION: u16 = 0x605E;
    /// Modes of operation (INTEGER8, rw).
    pub const MODES_OF_OPERATION: u16 = 0x6060;
    /// Modes of operation display (INTEGER8, ro).
    pub const MODES_DISPLAY: u16 = 0x6061;
    /// Position actual value (INTEGER32).
    pub const POSITION_ACTUAL: u16 = 0x6064;
    /// Following error window (UNSIGNED32).
    pub const FOLLOWING_ERROR_WINDOW: u16 = 0x6065;
    /// Following error time-out (UNSIGNED16, ms).
    pub const FOLLOWING_ERROR_TIMEOUT: u16 = 0x6066;
    /// Position window (UNSIGNED32).
    pub const POSITION_WINDOW: u16 = 0x6067;
    /// Position window time (UNSIGNED16, ms).
    pub const POSITION_WINDOW_TIME: u16 = 0x6068;
    /// Velocity actual value (INTEGER32).
    pub const VELOCITY_ACTUAL: u16 = 0x606C;
    /// Target position (INTEGER32).
    pub const TARGET_POSITION: u16 = 0x607A;
    /// Home offset (INTEGER32).
    pub const HOME_OFFSET: u16 = 0x607C;
    /// Software position limit (ARRAY of INTEGER32: sub1 min, sub2 max).
    pub const SOFTWARE_POSITION_LIMIT: u16 = 0x607D;
    /// Profile velocity (UNSIGNED32).
    pub const PROFILE_VELOCITY: u16 = 0x6081;
    /// Profile acceleration (UNSIGNED32).
    pub const PROFILE_ACCELERATION: u16 = 0x6083;
    /// Profile deceleration (UNSIGNED32).
    pub const PROFILE_DECELERATION: u16 = 0x6084;
    /// Quick stop deceleration (UNSIGNED32).
    pub const QUICK_STOP_DECELERATION: u16 = 0x6085;
    /// Homing method (INTEGER8).
    pub const HOMING_METHOD: u16 = 0x6098;
    /// Homing speeds (ARRAY of UNSIGNED32: sub1 switch search, sub2 zero search).
    pub const HOMING_SPEEDS: u16 = 0x6099;
    /// Homing acceleration (UNSIGNED32).
    pub const HOMING_ACCELERATION: u16 = 0x609A;
    /// Target velocity (INTEGER32).
    pub const TARGET_VELOCITY: u16 = 0x60FF;
    /// Supported drive modes (UNSIGNED32).
    pub const SUPPORTED_MODES: u16 = 0x6502;
}

/// Controlword (0x6040) bits (spec 2.1, 2.7, 2.9).
pub mod cw {
    /// Bit 0: switch on.
    pub const SWITCH_ON: u16 = 0x0001;
    /// Bit 1: enable voltage.
    pub const ENABLE_VOLTAGE: u16 = 0x0002;
    /// Bit 2: quick stop (0 = quick stop requested).
    pub const QUICK_STOP: u16 = 0x0004;
    /// Bit 3: enable operation.
    pub const ENABLE_OPERATION: u16 = 0x0008;
    /// Bit 4 in profile position: new set-point (0 -> 1 edge).
    pub const NEW_SET_POINT: u16 = 0x0010;
    /// Bit 5 in profile position: change set immediately.
    pub const CHANGE_SET_IMMEDIATELY: u16 = 0x0020;
    /// Bit 6 in profile position: the target is relative.
    pub const RELATIVE: u16 = 0x0040;
    /// Bit 7: fault reset (acts on a 0 -> 1 edge).
    pub const FAULT_RESET: u16 = 0x0080;
    /// Bit 8: halt.
    pub const HALT: u16 = 0x0100;
    /// Bit 4 in homing mode: homing operation start.
    pub const HOMING_START: u16 = 0x0010;
}

/// Statusword (0x6041) bits (spec 2.3, 2.7, 2.9).
pub mod sw {
    /// Bit 0: ready to switch on.
    pub const READY_TO_SWITCH_ON: u16 = 0x0001;
    /// Bit 1: switched on.
    pub const SWITCHED_ON: u16 = 0x0002;
    /// Bit 2: operation enabled.
    pub const OPERATION_ENABLED: u16 = 0x0004;
    /// Bit 3: fault.
    pub const FAULT: u16 = 0x0008;
    /// Bit 4: voltage enabled.
    pub const VOLTAGE_ENABLED: u16 = 0x0010;
    /// Bit 5: quick stop (0 = quick stop active).
    pub const QUICK_STOP: u16 = 0x0020;
    /// Bit 6: switch on disabled.
    pub const SWITCH_ON_DISABLED: u16 = 0x0040;
    /// Bit 7: warning.
    pub const WARNING: u16 = 0x0080;
    /// Bit 9: remote (controlword processed).
    pub const REMOTE: u16 = 0x0200;
    /// Bit 10: target reached.
    pub const TARGET_REACHED: u16 = 0x0400;
    /// Bit 11: internal limit active.
    pub const INTERNAL_LIMIT: u16 = 0x0800;
    /// Bit 12 in profile position: set-point acknowledge.
    pub const SET_POINT_ACKNOWLEDGE: u16 = 0x1000;
    /// Bit 13 in profile position: following error.
    pub const FOLLOWING_ERROR: u16 = 0x2000;
    /// Bit 12 in homing mode: homing attained.
    pub const HOMING_ATTAINED: u16 = 0x1000;
    /// Bit 13 in homing mode: homing error.
    pub const HOMING_ERROR: u16 = 0x2000;
    /// Bit 12 in profile velocity mode: speed is zero.
    pub const SPEED_ZERO: u16 = 0x1000;
}
