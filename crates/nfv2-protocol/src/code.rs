//! Command codes (the byte after the address / after each previous command).
//!
//! Codes and names come from the reference implementation's `nfv2.h`
//! (`NF_COMMAND_*`). The table is total: any other byte is [`CommandCode::Unknown`],
//! so logs and JSON keep the raw value. Whether a code has a known value width depends
//! on the [`Revision`](crate::Revision), not on this table.
//!
//! JSON form: a known code is its snake_case name (`"set_drives_position"`), an unknown
//! one its number (`96`). Decoding also accepts a number for a known code (`19`) or a
//! `"0x13"` hex string, and maps them to the named variant.

use core::fmt;

use serde::de::{self, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

macro_rules! command_codes {
    ($( $(#[$doc:meta])* $variant:ident = $code:literal, $name:literal; )*) => {
        /// An NFv2 command / query code (total: unknown bytes are kept).
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum CommandCode {
            $( $(#[$doc])* $variant, )*
            /// A code not in the reference table; the raw byte is kept.
            Unknown(u8),
        }

        impl CommandCode {
            /// Every named code, in table order.
            pub const ALL: &'static [CommandCode] = &[$(CommandCode::$variant,)*];

            /// Maps a wire byte to a code (never fails).
            #[must_use]
            pub const fn from_u8(raw: u8) -> Self {
                match raw {
                    $( $code => CommandCode::$variant, )*
                    other => CommandCode::Unknown(other),
                }
            }

            /// The wire byte.
            #[must_use]
            pub const fn to_u8(self) -> u8 {
                match self {
                    $( CommandCode::$variant => $code, )*
                    CommandCode::Unknown(raw) => raw,
                }
            }

            /// The snake_case name used in JSON, or `None` for an unknown code.
            #[must_use]
            pub const fn name(self) -> Option<&'static str> {
                match self {
                    $( CommandCode::$variant => Some($name), )*
                    CommandCode::Unknown(_) => None,
                }
            }

            /// Looks a code up by its snake_case name.
            #[must_use]
            pub fn from_name(name: &str) -> Option<Self> {
                match name {
                    $( $name => Some(CommandCode::$variant), )*
                    _ => None,
                }
            }
        }
    };
}

command_codes! {
    /// 0x02: device status register (2 bytes per value).
    ReadDeviceStatus = 0x02, "read_device_status";
    /// 0x03: device vitals, e.g. supply voltages (2 bytes per value; 1209A: 4 values).
    ReadDeviceVitals = 0x03, "read_device_vitals";
    /// 0x10: drive mode (1 byte per drive, see [`DriveMode`](crate::DriveMode)).
    SetDrivesMode = 0x10, "set_drives_mode";
    /// 0x11: speed set-point (signed; 2 bytes before 2013, 4 since).
    SetDrivesSpeed = 0x11, "set_drives_speed";
    /// 0x12: current set-point (2 bytes).
    SetDrivesCurrent = 0x12, "set_drives_current";
    /// 0x13: position set-point (signed, 4 bytes).
    SetDrivesPosition = 0x13, "set_drives_position";
    /// 0x14: PWM duty (signed, 2 bytes).
    SetDrivesPwm = 0x14, "set_drives_pwm";
    /// 0x15: current limit (2 bytes).
    SetDrivesMaxCurrent = 0x15, "set_drives_max_current";
    /// 0x16: speed limit (2 bytes before 2014, 4 since).
    SetDrivesMaxSpeed = 0x16, "set_drives_max_speed";
    /// 0x17: lower position limit (4 bytes).
    SetDrivesMinPosition = 0x17, "set_drives_min_position";
    /// 0x18: upper position limit (4 bytes).
    SetDrivesMaxPosition = 0x18, "set_drives_max_position";
    /// 0x19: acceleration limit (4 bytes; later revisions only).
    SetDrivesMaxAcceleration = 0x19, "set_drives_max_acceleration";
    /// 0x1A: measured position (4 bytes).
    ReadDrivesPosition = 0x1A, "read_drives_position";
    /// 0x1B: measured current (2 bytes).
    ReadDrivesCurrent = 0x1B, "read_drives_current";
    /// 0x1C: measured speed (later revisions only; 2 bytes in 2013, 4 since 2014).
    ReadDrivesSpeed = 0x1C, "read_drives_speed";
    /// 0x1D: motion duration (4 bytes; later revisions only).
    SetDrivesMotionDuration = 0x1D, "set_drives_motion_duration";
    /// 0x1E: miscellaneous flags (4 bytes, see [`DrivesMisc`](crate::DrivesMisc)).
    SetDrivesMisc = 0x1E, "set_drives_misc";
    /// 0x1F: drive status register (2 bytes, see [`DriveStatus`](crate::DriveStatus)).
    ReadDrivesStatus = 0x1F, "read_drives_status";
    /// 0x20: RC servo mode (1 byte).
    SetServosMode = 0x20, "set_servos_mode";
    /// 0x21: RC servo position (2 bytes).
    SetServosPosition = 0x21, "set_servos_position";
    /// 0x22: RC servo speed (2 bytes).
    SetServosSpeed = 0x22, "set_servos_speed";
    /// 0x26: RC servo speed limit (2 bytes).
    SetServosMaxSpeed = 0x26, "set_servos_max_speed";
    /// 0x27: RC servo lower position limit (2 bytes).
    SetServosMinPosition = 0x27, "set_servos_min_position";
    /// 0x28: RC servo upper position limit (2 bytes).
    SetServosMaxPosition = 0x28, "set_servos_max_position";
    /// 0x29: RC servo position adjustment (2 bytes).
    SetServosPositionAdj = 0x29, "set_servos_position_adj";
    /// 0x2A: RC servo position (2 bytes).
    ReadServosPosition = 0x2A, "read_servos_position";
    /// 0x2B: RC servo current (2 bytes).
    ReadServosCurrent = 0x2B, "read_servos_current";
    /// 0x2E: RC servo miscellaneous flags (4 bytes).
    SetServosMisc = 0x2E, "set_servos_misc";
    /// 0x2F: RC servo status (2 bytes).
    ReadServosStatus = 0x2F, "read_servos_status";
    /// 0x30: digital inputs (1 byte).
    ReadDigitalInputs = 0x30, "read_digital_inputs";
    /// 0x31: digital outputs (1 byte).
    SetDigitalOutputs = 0x31, "set_digital_outputs";
    /// 0x3D: distance sensor (2 bytes).
    ReadDistance = 0x3D, "read_distance";
    /// 0x3E: analog inputs (2 bytes; 1209A: AI0, AI1).
    ReadAnalogInputs = 0x3E, "read_analog_inputs";
    /// 0x40: current regulator P, I, D, T (four u16 = 8 bytes).
    SetCurrentRegulator = 0x40, "set_current_regulator";
    /// 0x41: speed regulator P, I, D, T (8 bytes).
    SetSpeedRegulator = 0x41, "set_speed_regulator";
    /// 0x42: position regulator P, I, D, T (8 bytes).
    SetPositionRegulator = 0x42, "set_position_regulator";
    /// 0x50: display mode (1 byte).
    SetDisplayMode = 0x50, "set_display_mode";
    /// 0x51: display text (1 byte per character).
    SetDisplayText = 0x51, "set_display_text";
    /// 0x52: display backlight (1 byte).
    SetDisplayBacklight = 0x52, "set_display_backlight";
}

impl CommandCode {
    /// True for the read-type codes, which a slave answers with data when queried (k = 0).
    #[must_use]
    pub fn is_read(self) -> bool {
        self.name().is_some_and(|name| name.starts_with("read_"))
    }
}

impl From<u8> for CommandCode {
    fn from(raw: u8) -> Self {
        Self::from_u8(raw)
    }
}

impl From<CommandCode> for u8 {
    fn from(code: CommandCode) -> Self {
        code.to_u8()
    }
}

impl fmt::Display for CommandCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.name() {
            Some(name) => write!(f, "{name} ({:#04x})", self.to_u8()),
            None => write!(f, "unknown ({:#04x})", self.to_u8()),
        }
    }
}

impl Serialize for CommandCode {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self.name() {
            Some(name) => serializer.serialize_str(name),
            None => serializer.serialize_u8(self.to_u8()),
        }
    }
}

impl<'de> Deserialize<'de> for CommandCode {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_any(CodeVisitor)
    }
}

struct CodeVisitor;

impl Visitor<'_> for CodeVisitor {
    type Value = CommandCode;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a command name such as \"read_drives_position\", or a code 0..=255")
    }

    fn visit_u64<E: de::Error>(self, v: u64) -> Result<CommandCode, E> {
        u8::try_from(v)
            .map(CommandCode::from_u8)
            .map_err(|_| E::invalid_value(de::Unexpected::Unsigned(v), &self))
    }

    fn visit_i64<E: de::Error>(self, v: i64) -> Result<CommandCode, E> {
        u8::try_from(v)
            .map(CommandCode::from_u8)
            .map_err(|_| E::invalid_value(de::Unexpected::Signed(v), &self))
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<CommandCode, E> {
        if let Some(hex) = v.strip_prefix("0x").or_else(|| v.strip_prefix("0X")) {
            return u8::from_str_radix(hex, 16)
                .map(CommandCode::from_u8)
                .map_err(|_| E::invalid_value(de::Unexpected::Str(v), &self));
        }
        CommandCode::from_name(v).ok_or_else(|| E::invalid_value(de::Unexpected::Str(v), &self))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_byte_round_trips() {
        for raw in 0..=255u8 {
            assert_eq!(CommandCode::from_u8(raw).to_u8(), raw);
        }
    }

    #[test]
    fn names_are_unique_and_round_trip() {
        for &code in CommandCode::ALL {
            let name = code.name().unwrap_or_default();
            assert_eq!(CommandCode::from_name(name), Some(code));
        }
        let mut bytes: Vec<u8> = CommandCode::ALL.iter().map(|c| c.to_u8()).collect();
        bytes.sort_unstable();
        bytes.dedup();
        assert_eq!(bytes.len(), CommandCode::ALL.len());
    }

    #[test]
    fn reference_codes() {
        // Spot checks against the reference table (specs/nfv2.md, "Command codes").
        assert_eq!(CommandCode::SetDrivesPosition.to_u8(), 0x13);
        assert_eq!(CommandCode::ReadDrivesStatus.to_u8(), 0x1F);
        assert_eq!(CommandCode::ReadAnalogInputs.to_u8(), 0x3E);
        assert_eq!(CommandCode::SetDisplayBacklight.to_u8(), 0x52);
        assert_eq!(CommandCode::from_u8(0x23), CommandCode::Unknown(0x23));
        assert!(CommandCode::ReadDrivesPosition.is_read());
        assert!(!CommandCode::SetDrivesPosition.is_read());
        assert!(!CommandCode::Unknown(0x60).is_read());
    }
}
