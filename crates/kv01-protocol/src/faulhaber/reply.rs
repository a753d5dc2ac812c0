//! Faulhaber controller replies (`specs/faulhaber.md` §1.3), terminator stripped.
//!
//! [`Reply::parse`] is total and exact: a string is only given a typed variant when
//! formatting that variant gives back the very same string, so `parse(s).to_string() == s`
//! for every `s` and a reply survives any decode/encode round trip.

use std::fmt;

use serde::{Deserialize, Serialize};

/// An error string a controller in answer mode 2 sends (§1.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ControllerError {
    /// `Unknown command`.
    UnknownCommand,
    /// `Invalid parameter`.
    InvalidParameter,
    /// `Command not available`.
    CommandNotAvailable,
    /// `Overtemperature - drive disabled` (ASCII hyphen; the manual prints an en dash).
    Overtemperature,
}

impl ControllerError {
    /// The exact text the controller sends.
    #[must_use]
    pub const fn text(self) -> &'static str {
        match self {
            Self::UnknownCommand => "Unknown command",
            Self::InvalidParameter => "Invalid parameter",
            Self::CommandNotAvailable => "Command not available",
            Self::Overtemperature => "Overtemperature - drive disabled",
        }
    }

    const ALL: [Self; 4] =
        [Self::UnknownCommand, Self::InvalidParameter, Self::CommandNotAvailable, Self::Overtemperature];
}

/// A controller reply. In JSON it is the reply text itself (a string).
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(from = "String", into = "String")]
pub enum Reply {
    /// `OK`: a set or motion command was accepted (answer mode 2).
    Ok,
    /// A decimal value (query answer), in canonical form (no `+`, no leading zeros, no `-0`).
    Value(i64),
    /// One of the four error strings.
    Error(ControllerError),
    /// `EEPROM writing done` (after `SAVE`/`EEPSAV`).
    EepromWritingDone,
    /// `Flash defect` (after `SAVE`/`EEPSAV`).
    FlashDefect,
    /// `p`: asynchronous "position reached" after `NP`.
    PositionReached,
    /// `v`: asynchronous "velocity reached" after `NV` (character assumed, spec \[U\]).
    VelocityReached,
    /// Anything else, as received (e.g. a GST status string `0001000`, a version string).
    Text(String),
}

impl Reply {
    /// Classifies a reply string. Total and exact (see the module docs).
    #[must_use]
    pub fn parse(text: &str) -> Self {
        match text {
            "OK" => return Self::Ok,
            "EEPROM writing done" => return Self::EepromWritingDone,
            "Flash defect" => return Self::FlashDefect,
            "p" => return Self::PositionReached,
            "v" => return Self::VelocityReached,
            _ => {}
        }
        if let Some(e) = ControllerError::ALL.iter().find(|e| e.text() == text) {
            return Self::Error(*e);
        }
        match text.parse::<i64>() {
            Ok(v) if v.to_string() == text => Self::Value(v),
            _ => Self::Text(text.to_owned()),
        }
    }

    /// The value of a numeric reply.
    #[must_use]
    pub fn value(&self) -> Option<i64> {
        match self {
            Self::Value(v) => Some(*v),
            _ => None,
        }
    }
}

impl fmt::Display for Reply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Ok => f.write_str("OK"),
            Self::Value(v) => write!(f, "{v}"),
            Self::Error(e) => f.write_str(e.text()),
            Self::EepromWritingDone => f.write_str("EEPROM writing done"),
            Self::FlashDefect => f.write_str("Flash defect"),
            Self::PositionReached => f.write_str("p"),
            Self::VelocityReached => f.write_str("v"),
            Self::Text(t) => f.write_str(t),
        }
    }
}

impl From<String> for Reply {
    fn from(s: String) -> Self {
        Self::parse(&s)
    }
}

impl From<Reply> for String {
    fn from(r: Reply) -> Self {
        r.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classify() {
        assert_eq!(Reply::parse("OK"), Reply::Ok);
        assert_eq!(Reply::parse("98956"), Reply::Value(98956));
        assert_eq!(Reply::parse("-12"), Reply::Value(-12));
        assert_eq!(Reply::parse("+12"), Reply::Text("+12".into()));
        assert_eq!(Reply::parse("0012"), Reply::Text("0012".into()));
        assert_eq!(Reply::parse("-0"), Reply::Text("-0".into()));
        assert_eq!(Reply::parse("0001000"), Reply::Text("0001000".into()));
        assert_eq!(Reply::parse("Invalid parameter"), Reply::Error(ControllerError::InvalidParameter));
        assert_eq!(Reply::parse("EEPROM writing done"), Reply::EepromWritingDone);
        assert_eq!(Reply::parse("99999999999999999999").value(), None);
        for s in ["", "ok", "p", "Overtemperature - drive disabled", "1.5"] {
            assert_eq!(Reply::parse(s).to_string(), s);
        }
    }
}
