//! Protocol revisions and the per-(revision, code) value-width table.
//!
//! The reference implementation changed value widths over time (specs/nfv2.md, "Command
//! codes"; cross-checked against successive versions of the reference `nfv2.h`):
//!
//! | code | name | [`Rev2012`](Revision::Rev2012) | [`Rev2013`](Revision::Rev2013) | [`Rev2014`](Revision::Rev2014) |
//! |---|---|---|---|---|
//! | 0x11 | SetDrivesSpeed | i16 | i32 | i32 |
//! | 0x16 | SetDrivesMaxSpeed | i16 | i16 | i32 |
//! | 0x19 | SetDrivesMaxAcceleration | – | i32 | i32 |
//! | 0x1C | ReadDrivesSpeed | – | i16 | i32 |
//! | 0x1D | SetDrivesMotionDuration | – | i32 | i32 |
//!
//! Every other code has the same width in all three. "–" means the revision does not
//! know the command: a receiver skips it by its length, and so does our decoder (it
//! keeps it as [`Command::Unknown`](crate::Command::Unknown)).
//!
//! Signedness follows the reference's C types, except registers of bits (status words,
//! digital I/O), which we show unsigned.

use core::fmt;
use core::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::code::CommandCode;
use crate::value::ValueKind;

/// A revision of the NFv2 command table. Chosen per device; [`Revision::LATEST`] by default.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Revision {
    /// Revisions before 2013: 2-byte speeds, no 0x19 / 0x1C / 0x1D.
    Rev2012,
    /// 2013: 4-byte `SetDrivesSpeed`, 2-byte `SetDrivesMaxSpeed` and `ReadDrivesSpeed`.
    Rev2013,
    /// 2014 and later (latest): 4-byte speeds and speed limit.
    #[default]
    Rev2014,
}

impl Revision {
    /// The newest revision, the default.
    pub const LATEST: Revision = Revision::Rev2014;

    /// All revisions, oldest first.
    pub const ALL: [Revision; 3] = [Revision::Rev2012, Revision::Rev2013, Revision::Rev2014];

    /// The kind (width, signedness) of one value of `code` in this revision, or `None` if
    /// this revision does not define `code`.
    #[must_use]
    pub const fn value_kind(self, code: CommandCode) -> Option<ValueKind> {
        use CommandCode as C;
        use ValueKind as K;
        let early = matches!(self, Revision::Rev2012);
        let latest = matches!(self, Revision::Rev2014);
        let kind = match code {
            C::ReadDeviceStatus => K::U16,
            C::ReadDeviceVitals => K::I16,
            C::SetDrivesMode => K::U8,
            C::SetDrivesSpeed => {
                if early {
                    K::I16
                } else {
                    K::I32
                }
            }
            C::SetDrivesCurrent | C::SetDrivesPwm | C::SetDrivesMaxCurrent => K::I16,
            C::SetDrivesPosition | C::SetDrivesMinPosition | C::SetDrivesMaxPosition => K::I32,
            C::SetDrivesMaxSpeed => {
                if latest {
                    K::I32
                } else {
                    K::I16
                }
            }
            C::SetDrivesMaxAcceleration | C::SetDrivesMotionDuration => {
                if early {
                    return None;
                }
                K::I32
            }
            C::ReadDrivesPosition => K::I32,
            C::ReadDrivesCurrent => K::I16,
            C::ReadDrivesSpeed => match self {
                Revision::Rev2012 => return None,
                Revision::Rev2013 => K::I16,
                Revision::Rev2014 => K::I32,
            },
            C::SetDrivesMisc | C::SetServosMisc => K::U32,
            C::ReadDrivesStatus | C::ReadServosStatus | C::ReadDistance => K::U16,
            C::SetServosMode => K::U8,
            C::SetServosPosition
            | C::SetServosSpeed
            | C::SetServosMaxSpeed
            | C::SetServosMinPosition
            | C::SetServosMaxPosition
            | C::SetServosPositionAdj
            | C::ReadServosPosition
            | C::ReadServosCurrent
            | C::ReadAnalogInputs => K::I16,
            C::ReadDigitalInputs | C::SetDigitalOutputs => K::U8,
            C::SetCurrentRegulator | C::SetSpeedRegulator | C::SetPositionRegulator => K::Regulator,
            C::SetDisplayMode | C::SetDisplayText | C::SetDisplayBacklight => K::U8,
            C::Unknown(_) => return None,
        };
        Some(kind)
    }

    /// Bytes per value of `code` in this revision, `None` if the revision does not define it.
    #[must_use]
    pub const fn width(self, code: CommandCode) -> Option<usize> {
        match self.value_kind(code) {
            Some(kind) => Some(kind.width()),
            None => None,
        }
    }

    /// Short name: `"rev2012"`, `"rev2013"`, `"rev2014"`.
    #[must_use]
    pub const fn as_str(self) -> &'static str {
        match self {
            Revision::Rev2012 => "rev2012",
            Revision::Rev2013 => "rev2013",
            Revision::Rev2014 => "rev2014",
        }
    }
}

impl fmt::Display for Revision {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Error of [`Revision::from_str`].
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown NFv2 revision {0:?} (expected rev2012, rev2013, rev2014 or latest)")]
pub struct ParseRevisionError(pub String);

impl FromStr for Revision {
    type Err = ParseRevisionError;

    /// Accepts `rev2012` / `2012`, `rev2013` / `2013`, `rev2014` / `2014` / `latest`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().trim_start_matches("rev") {
            "2012" => Ok(Revision::Rev2012),
            "2013" => Ok(Revision::Rev2013),
            "2014" | "latest" => Ok(Revision::Rev2014),
            _ => Err(ParseRevisionError(s.to_owned())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speed_widths_change_between_revisions() {
        let c = CommandCode::SetDrivesSpeed;
        assert_eq!(Revision::Rev2012.width(c), Some(2));
        assert_eq!(Revision::Rev2013.width(c), Some(4));
        assert_eq!(Revision::Rev2014.width(c), Some(4));
        let m = CommandCode::SetDrivesMaxSpeed;
        assert_eq!(Revision::Rev2012.width(m), Some(2));
        assert_eq!(Revision::Rev2013.width(m), Some(2));
        assert_eq!(Revision::Rev2014.width(m), Some(4));
        assert_eq!(Revision::Rev2012.width(CommandCode::ReadDrivesSpeed), None);
        assert_eq!(Revision::Rev2013.width(CommandCode::ReadDrivesSpeed), Some(2));
        assert_eq!(Revision::Rev2014.width(CommandCode::ReadDrivesSpeed), Some(4));
    }

    #[test]
    fn every_named_code_has_a_width_in_the_latest_revision() {
        for &code in CommandCode::ALL {
            assert!(Revision::LATEST.width(code).is_some(), "{code}");
        }
        assert_eq!(Revision::LATEST.width(CommandCode::Unknown(0x60)), None);
    }

    #[test]
    fn reference_widths() {
        // specs/nfv2.md, "Command codes" column "bytes".
        let r = Revision::LATEST;
        assert_eq!(r.width(CommandCode::ReadDeviceStatus), Some(2));
        assert_eq!(r.width(CommandCode::SetDrivesMode), Some(1));
        assert_eq!(r.width(CommandCode::SetDrivesPosition), Some(4));
        assert_eq!(r.width(CommandCode::SetDrivesMisc), Some(4));
        assert_eq!(r.width(CommandCode::ReadDigitalInputs), Some(1));
        assert_eq!(r.width(CommandCode::SetPositionRegulator), Some(8));
        assert_eq!(r.width(CommandCode::SetDisplayText), Some(1));
    }

    #[test]
    fn parse_and_default() {
        assert_eq!(Revision::default(), Revision::LATEST);
        assert_eq!("2012".parse(), Ok(Revision::Rev2012));
        assert_eq!("Rev2013".parse(), Ok(Revision::Rev2013));
        assert_eq!("latest".parse(), Ok(Revision::Rev2014));
        assert!("2011".parse::<Revision>().is_err());
        for r in Revision::ALL {
            assert_eq!(r.as_str().parse(), Ok(r));
        }
    }
}
