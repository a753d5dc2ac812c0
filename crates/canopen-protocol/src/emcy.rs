//! EMCY error codes (CiA 301 §7.2.7.3.1, table 21): classified by their high bits.

use serde::{Deserialize, Serialize};

/// Class of an emergency error code. Total: codes outside the table are `Unknown`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EmcyClass {
    /// 0x0000: error reset / no error.
    ErrorReset,
    /// 0x10xx: generic error.
    Generic,
    /// 0x2xxx: current.
    Current,
    /// 0x3xxx: voltage.
    Voltage,
    /// 0x4xxx: temperature.
    Temperature,
    /// 0x50xx: device hardware.
    DeviceHardware,
    /// 0x6xxx: device software.
    DeviceSoftware,
    /// 0x70xx: additional modules.
    AdditionalModules,
    /// 0x81xx: communication (0x8110 CAN overrun, 0x8120 error passive, 0x8130 heartbeat, 0x8140 bus off).
    Communication,
    /// 0x82xx: protocol error.
    Protocol,
    /// 0x90xx: external error.
    External,
    /// 0xF0xx: additional functions.
    AdditionalFunctions,
    /// 0xFFxx: device specific.
    DeviceSpecific,
    /// Any other code.
    Unknown,
}

impl EmcyClass {
    /// Classifies an emergency error code.
    pub fn of(code: u16) -> Self {
        match code {
            0x0000 => Self::ErrorReset,
            0x1000..=0x10FF => Self::Generic,
            0x2000..=0x2FFF => Self::Current,
            0x3000..=0x3FFF => Self::Voltage,
            0x4000..=0x4FFF => Self::Temperature,
            0x5000..=0x50FF => Self::DeviceHardware,
            0x6000..=0x6FFF => Self::DeviceSoftware,
            0x7000..=0x70FF => Self::AdditionalModules,
            0x8100..=0x81FF => Self::Communication,
            0x8200..=0x82FF => Self::Protocol,
            0x9000..=0x90FF => Self::External,
            0xF000..=0xF0FF => Self::AdditionalFunctions,
            0xFF00..=0xFFFF => Self::DeviceSpecific,
            _ => Self::Unknown,
        }
    }

    /// Human-readable class name.
    pub fn description(self) -> &'static str {
        match self {
            Self::ErrorReset => "error reset",
            Self::Generic => "generic",
            Self::Current => "current",
            Self::Voltage => "voltage",
            Self::Temperature => "temperature",
            Self::DeviceHardware => "device hardware",
            Self::DeviceSoftware => "device software",
            Self::AdditionalModules => "additional modules",
            Self::Communication => "communication",
            Self::Protocol => "protocol",
            Self::External => "external",
            Self::AdditionalFunctions => "additional functions",
            Self::DeviceSpecific => "device specific",
            Self::Unknown => "unknown",
        }
    }
}
