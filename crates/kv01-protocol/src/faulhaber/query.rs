//! Faulhaber query commands (`specs/faulhaber.md` §1.4 "Queries"): no argument, the
//! controller answers with one value in every answer mode.

use serde::{Deserialize, Serialize};

/// A query command: no argument, the controller answers with one value (§1.4 "Queries").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Query {
    /// `POS`: actual position (increments).
    Position,
    /// `TPOS`: target position.
    TargetPosition,
    /// `GV`: target velocity (rpm).
    TargetVelocity,
    /// `GN`: actual velocity (rpm), as hosts use it.
    Velocity,
    /// `GU`: PWM value in voltage mode.
    Pwm,
    /// `GRU`: current controller output value.
    ControllerOutput,
    /// `GCL`: current limitation current (mA).
    CurrentLimit,
    /// `GRC`: actual current (mA).
    Current,
    /// `TEM`: housing temperature (°C).
    Temperature,
    /// `OST`: operation status bits.
    OperationStatus,
    /// `GST`: legacy status string.
    Status,
    /// `GFS`: legacy fault string.
    FaultStatus,
    /// `GAST`: legacy additional status string.
    AdditionalStatus,
    /// `SWS`: limit switch settings.
    SwitchSettings,
    /// `CST`: configuration status.
    ConfigurationStatus,
    /// `VER`: firmware version.
    Version,
    /// `GTYP`: controller type.
    Type,
    /// `GSER`: serial number.
    SerialNumber,
    /// `GNODEADR`: node address.
    NodeAddress,
    /// `GSP`: maximum speed.
    MaxSpeed,
    /// `GAC`: acceleration.
    Acceleration,
    /// `GDEC`: deceleration.
    Deceleration,
    /// `GPL`: positive position limit.
    PositiveLimit,
    /// `GNL`: negative position limit.
    NegativeLimit,
    /// `GPC`: peak current limit.
    PeakCurrent,
    /// `GCC`: continuous current limit.
    ContinuousCurrent,
    /// `MEM`: free program memory (words).
    Memory,
}

impl Query {
    /// Every query with its mnemonic.
    pub const ALL: [(Query, &'static str); 27] = [
        (Query::Position, "POS"),
        (Query::TargetPosition, "TPOS"),
        (Query::TargetVelocity, "GV"),
        (Query::Velocity, "GN"),
        (Query::Pwm, "GU"),
        (Query::ControllerOutput, "GRU"),
        (Query::CurrentLimit, "GCL"),
        (Query::Current, "GRC"),
        (Query::Temperature, "TEM"),
        (Query::OperationStatus, "OST"),
        (Query::Status, "GST"),
        (Query::FaultStatus, "GFS"),
        (Query::AdditionalStatus, "GAST"),
        (Query::SwitchSettings, "SWS"),
        (Query::ConfigurationStatus, "CST"),
        (Query::Version, "VER"),
        (Query::Type, "GTYP"),
        (Query::SerialNumber, "GSER"),
        (Query::NodeAddress, "GNODEADR"),
        (Query::MaxSpeed, "GSP"),
        (Query::Acceleration, "GAC"),
        (Query::Deceleration, "GDEC"),
        (Query::PositiveLimit, "GPL"),
        (Query::NegativeLimit, "GNL"),
        (Query::PeakCurrent, "GPC"),
        (Query::ContinuousCurrent, "GCC"),
        (Query::Memory, "MEM"),
    ];

    /// The mnemonic (upper case).
    #[must_use]
    pub fn mnemonic(self) -> &'static str {
        Self::ALL.iter().find(|(q, _)| *q == self).map_or("", |(_, m)| m)
    }

    /// The query for an upper-case mnemonic.
    #[must_use]
    pub fn from_mnemonic(m: &str) -> Option<Self> {
        Self::ALL.iter().find(|(_, s)| *s == m).map(|(q, _)| *q)
    }
}
