//! Modes of operation (0x6060 / 0x6061, spec 2.6) and the homing status (spec 2.9).

use serde::{Deserialize, Serialize};

/// A mode of operation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// 0: no mode.
    NoMode,
    /// 1: profile position (pp).
    ProfilePosition,
    /// 2: velocity (vl).
    Velocity,
    /// 3: profile velocity (pv).
    ProfileVelocity,
    /// 4: profile torque (tq).
    ProfileTorque,
    /// 6: homing (hm).
    Homing,
    /// 7: interpolated position (ip).
    InterpolatedPosition,
    /// 8: cyclic synchronous position (csp).
    CyclicSyncPosition,
    /// 9: cyclic synchronous velocity (csv).
    CyclicSyncVelocity,
    /// 10: cyclic synchronous torque (cst).
    CyclicSyncTorque,
    /// Any other value (reserved or manufacturer specific).
    Other(i8),
}

impl Mode {
    /// Decodes 0x6060 / 0x6061.
    pub fn from_i8(v: i8) -> Self {
        match v {
            0 => Self::NoMode,
            1 => Self::ProfilePosition,
            2 => Self::Velocity,
            3 => Self::ProfileVelocity,
            4 => Self::ProfileTorque,
            6 => Self::Homing,
            7 => Self::InterpolatedPosition,
            8 => Self::CyclicSyncPosition,
            9 => Self::CyclicSyncVelocity,
            10 => Self::CyclicSyncTorque,
            other => Self::Other(other),
        }
    }

    /// The value written to 0x6060.
    pub fn to_i8(self) -> i8 {
        match self {
            Self::NoMode => 0,
            Self::ProfilePosition => 1,
            Self::Velocity => 2,
            Self::ProfileVelocity => 3,
            Self::ProfileTorque => 4,
            Self::Homing => 6,
            Self::InterpolatedPosition => 7,
            Self::CyclicSyncPosition => 8,
            Self::CyclicSyncVelocity => 9,
            Self::CyclicSyncTorque => 10,
            Self::Other(v) => v,
        }
    }

    /// The bit of this mode in 0x6502 (supported drive modes), if the standard defines one.
    pub fn supported_bit(self) -> Option<u32> {
        let bit = match self {
            Self::ProfilePosition => 0,
            Self::Velocity => 1,
            Self::ProfileVelocity => 2,
            Self::ProfileTorque => 3,
            Self::Homing => 5,
            Self::InterpolatedPosition => 6,
            Self::CyclicSyncPosition => 7,
            Self::CyclicSyncVelocity => 8,
            Self::CyclicSyncTorque => 9,
            Self::NoMode | Self::Other(_) => return None,
        };
        Some(1 << bit)
    }

    /// The mode's name.
    pub fn name(self) -> &'static str {
        match self {
            Self::NoMode => "no mode",
            Self::ProfilePosition => "profile position",
            Self::Velocity => "velocity",
            Self::ProfileVelocity => "profile velocity",
            Self::ProfileTorque => "profile torque",
            Self::Homing => "homing",
            Self::InterpolatedPosition => "interpolated position",
            Self::CyclicSyncPosition => "cyclic synchronous position",
            Self::CyclicSyncVelocity => "cyclic synchronous velocity",
            Self::CyclicSyncTorque => "cyclic synchronous torque",
            Self::Other(v) if v < 0 => "manufacturer specific",
            Self::Other(_) => "reserved",
        }
    }
}

impl std::fmt::Display for Mode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({})", self.name(), self.to_i8())
    }
}

/// The homing state read from statusword bits 10, 12, 13 (mask 0x3400, spec 2.9).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HomingStatus {
    /// 0x0000: homing in progress.
    InProgress,
    /// 0x0400: interrupted or not started.
    Interrupted,
    /// 0x1000: attained, target not yet reached.
    AttainedNotReached,
    /// 0x1400: completed.
    Completed,
    /// 0x2000: error, velocity not 0.
    ErrorMoving,
    /// 0x2400 (and the undefined 0x3000 / 0x3400): error, velocity 0.
    ErrorStopped,
}

impl HomingStatus {
    /// Decodes the homing state of a statusword.
    pub fn from_statusword(sw: u16) -> Self {
        match sw & 0x3400 {
            0x0000 => Self::InProgress,
            0x0400 => Self::Interrupted,
            0x1000 => Self::AttainedNotReached,
            0x1400 => Self::Completed,
            0x2000 => Self::ErrorMoving,
            _ => Self::ErrorStopped,
        }
    }

    /// The statusword bits (10, 12, 13) of this homing state.
    pub fn statusword_bits(self) -> u16 {
        match self {
            Self::InProgress => 0x0000,
            Self::Interrupted => 0x0400,
            Self::AttainedNotReached => 0x1000,
            Self::Completed => 0x1400,
            Self::ErrorMoving => 0x2000,
            Self::ErrorStopped => 0x2400,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_round_trip_and_supported_bits_follow_the_table() {
        for v in i8::MIN..=i8::MAX {
            assert_eq!(Mode::from_i8(v).to_i8(), v);
        }
        // 0x6502 bits: pp 0, pv 2, hm 5 -> the IclA's pp+pv+hm set is 0x25.
        let set = [Mode::ProfilePosition, Mode::ProfileVelocity, Mode::Homing]
            .iter()
            .filter_map(|m| m.supported_bit())
            .fold(0, |a, b| a | b);
        assert_eq!(set, 0x25);
    }

    #[test]
    fn homing_states_decode_with_mask_0x3400() {
        assert_eq!(HomingStatus::from_statusword(0x1637), HomingStatus::Completed);
        assert_eq!(HomingStatus::from_statusword(0x0237), HomingStatus::InProgress);
        assert_eq!(HomingStatus::from_statusword(0x2637), HomingStatus::ErrorStopped);
        for s in [
            HomingStatus::InProgress,
            HomingStatus::Interrupted,
            HomingStatus::AttainedNotReached,
            HomingStatus::Completed,
            HomingStatus::ErrorMoving,
            HomingStatus::ErrorStopped,
        ] {
            assert_eq!(HomingStatus::from_statusword(s.statusword_bits() | 0x0027), s);
        }
    }
}
