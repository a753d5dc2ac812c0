//! A snapshot of an axis.

use serde::{Deserialize, Serialize};

/// Boolean conditions of an axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct AxisFlags {
    /// Power stage / drive enabled.
    pub enabled: bool,
    /// The position reference is valid (homed since the last reset).
    pub homed: bool,
    /// A move, jog or homing is running.
    pub moving: bool,
    /// The last commanded target was reached and motion has ended.
    pub target_reached: bool,
    /// The negative limit switch is pressed (or was crossed, where the device latches it).
    pub limit_negative: bool,
    /// The positive limit switch is pressed (or was crossed, where the device latches it).
    pub limit_positive: bool,
    /// The holding brake is engaged, where the device has one and reports it.
    pub brake_engaged: Option<bool>,
}

/// Broad category of a fault, for decisions; the device's own words are in [`Fault::reason`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    /// A limit switch was crossed.
    LimitSwitch,
    /// Following error too large.
    FollowingError,
    /// Encoder / position measurement fault.
    Encoder,
    /// The device restarted (power loss, reset): position reference lost.
    DeviceReset,
    /// A communication watchdog on the device tripped.
    CommunicationTimeout,
    /// Emergency stop / enable input removed.
    EmergencyStop,
    /// Anything else the device reports.
    Other,
}

/// A fault with the device's reason.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Fault {
    /// Category.
    pub kind: FaultKind,
    /// Human-readable reason, naming the device's own status bit or code.
    pub reason: String,
}

/// A state snapshot in SI units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisState {
    /// Actual position (m or rad).
    pub position: f64,
    /// Raw position in device units, as reported on the wire.
    pub position_raw: i64,
    /// Actual velocity (m/s or rad/s), where known.
    pub velocity: Option<f64>,
    /// Motor current (A), where reported.
    pub current: Option<f64>,
    /// Following error (m or rad), where reported.
    pub following_error: Option<f64>,
    /// Conditions.
    pub flags: AxisFlags,
    /// Active faults (empty when healthy).
    pub faults: Vec<Fault>,
}

impl AxisState {
    /// True if no fault is active.
    pub fn is_healthy(&self) -> bool {
        self.faults.is_empty()
    }
}
