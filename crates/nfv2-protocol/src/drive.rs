//! Typed views of drive values: modes (`SetDrivesMode`), status bits
//! (`ReadDrivesStatus`) and misc flags (`SetDrivesMisc`).
//!
//! Frames carry the raw integers (so any value round-trips); these types interpret them.
//! Mode numbers changed between revisions of the reference:
//!
//! | raw | Rev2012 | Rev2013 | Rev2014 (latest) |
//! |---|---|---|---|
//! | 0x00..0x05 | ERROR, MANUAL, SPEED, CURRENT, POSITION, PWM | same | same |
//! | 0x06 | – | PVT | PVT |
//! | 0x07 | – | – | POS_INCREMENT |
//! | 0x10 | SYNC_PWM0 | SYNC_PWM0 | – |
//! | 0x11 | SYNC_POS0 | SYNC_CURRENT0 | – |
//! | 0x12 | – | SYNC_POS0 | HOMING |

use core::fmt;

use crate::revision::Revision;

/// A drive mode (`SetDrivesMode` value). Total: unknown numbers are kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DriveMode {
    /// 0x00: error state (display "E").
    Error,
    /// 0x01: manual, motor driven by analog input AI0.
    Manual,
    /// 0x02: speed regulator ("S").
    Speed,
    /// 0x03: current regulator ("C").
    Current,
    /// 0x04: position regulator ("P").
    Position,
    /// 0x05: PWM duty set by the PC ("d").
    Pwm,
    /// 0x06 (2013+): PVT trajectory.
    Pvt,
    /// 0x07 (2014+): speed through the position trajectory generator.
    PosIncrement,
    /// 0x12 (2014+): homing (calibration on the HOME sensor edge).
    Homing,
    /// 0x10 (before 2014): synchronisation in PWM.
    SyncPwm0,
    /// 0x11 (2013): synchronisation in current mode.
    SyncCurrent0,
    /// 0x11 (before 2013) / 0x12 (2013): synchronisation in position mode.
    SyncPos0,
    /// A number this revision does not define.
    Unknown(u8),
}

impl DriveMode {
    /// Interprets a raw mode byte in `rev`.
    #[must_use]
    pub fn from_raw(raw: u8, rev: Revision) -> Self {
        use Revision as R;
        match (raw, rev) {
            (0x00, _) => DriveMode::Error,
            (0x01, _) => DriveMode::Manual,
            (0x02, _) => DriveMode::Speed,
            (0x03, _) => DriveMode::Current,
            (0x04, _) => DriveMode::Position,
            (0x05, _) => DriveMode::Pwm,
            (0x06, R::Rev2013 | R::Rev2014) => DriveMode::Pvt,
            (0x07, R::Rev2014) => DriveMode::PosIncrement,
            (0x10, R::Rev2012 | R::Rev2013) => DriveMode::SyncPwm0,
            (0x11, R::Rev2012) => DriveMode::SyncPos0,
            (0x11, R::Rev2013) => DriveMode::SyncCurrent0,
            (0x12, R::Rev2013) => DriveMode::SyncPos0,
            (0x12, R::Rev2014) => DriveMode::Homing,
            (other, _) => DriveMode::Unknown(other),
        }
    }

    /// The raw byte for this mode in `rev`; `None` if `rev` has no such mode.
    #[must_use]
    pub fn to_raw(self, rev: Revision) -> Option<u8> {
        let raw = match self {
            DriveMode::Error => 0x00,
            DriveMode::Manual => 0x01,
            DriveMode::Speed => 0x02,
            DriveMode::Current => 0x03,
            DriveMode::Position => 0x04,
            DriveMode::Pwm => 0x05,
            DriveMode::Pvt => 0x06,
            DriveMode::PosIncrement => 0x07,
            DriveMode::Homing => 0x12,
            DriveMode::SyncPos0 if rev == Revision::Rev2012 => 0x11,
            DriveMode::SyncPos0 => 0x12,
            DriveMode::SyncPwm0 => 0x10,
            DriveMode::SyncCurrent0 => 0x11,
            DriveMode::Unknown(raw) => return Some(raw),
        };
        (Self::from_raw(raw, rev) == self).then_some(raw)
    }
}

/// `ReadDrivesStatus` bits (specs/nfv2.md, "ReadDrivesStatus bits").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct DriveStatus(pub u16);

impl DriveStatus {
    /// Bit 0: upper limit switch.
    pub const LIMIT_SWITCH_UP: u16 = 1 << 0;
    /// Bit 1: lower limit switch.
    pub const LIMIT_SWITCH_DOWN: u16 = 1 << 1;
    /// Bit 2: synchro (home) switch.
    pub const SYNCHRO_SWITCH: u16 = 1 << 2;
    /// Bit 3: encoder index.
    pub const ENCODER_INDEX: u16 = 1 << 3;
    /// Bit 4: synchronized (homed).
    pub const SYNCHRONIZED: u16 = 1 << 4;
    /// Bit 5: PVT trajectory accomplished.
    pub const PVT_ACCOMPLISHED: u16 = 1 << 5;
    /// Bit 6: PVT buffer empty.
    pub const PVT_BUFFER_EMPTY: u16 = 1 << 6;
    /// Bit 7: communication fault.
    pub const COMMUNICATION_FAULT: u16 = 1 << 7;
    /// Bit 8: trajectory following error.
    pub const FOLLOWING_ERROR: u16 = 1 << 8;
    /// Bit 9: power stage voltage low (power supply missing: everything but motion works).
    pub const POWER_STAGE_VOLTAGE_LOW: u16 = 1 << 9;
    /// Bit 10: position limit.
    pub const POSITION_LIMIT: u16 = 1 << 10;
    /// Bit 11: speed limit.
    pub const SPEED_LIMIT: u16 = 1 << 11;
    /// Bit 12: current limit.
    pub const CURRENT_LIMIT: u16 = 1 << 12;
    /// Bit 13: over-current.
    pub const OVERCURRENT: u16 = 1 << 13;
    /// Bit 14: power stage fault.
    pub const POWER_STAGE_FAULT: u16 = 1 << 14;
    /// Bit 15: error.
    pub const ERROR: u16 = 1 << 15;

    const NAMES: [&'static str; 16] = [
        "limit_switch_up",
        "limit_switch_down",
        "synchro_switch",
        "encoder_index",
        "synchronized",
        "pvt_accomplished",
        "pvt_buffer_empty",
        "communication_fault",
        "following_error",
        "power_stage_voltage_low",
        "position_limit",
        "speed_limit",
        "current_limit",
        "overcurrent",
        "power_stage_fault",
        "error",
    ];

    /// True if every bit of `mask` is set.
    #[must_use]
    pub fn contains(self, mask: u16) -> bool {
        self.0 & mask == mask
    }

    /// Names of the set bits, low bit first.
    pub fn names(self) -> impl Iterator<Item = &'static str> {
        Self::NAMES
            .into_iter()
            .enumerate()
            .filter(move |&(bit, _)| self.0 & (1 << bit) != 0)
            .map(|(_, name)| name)
    }
}

impl fmt::Display for DriveStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:#06x}", self.0)?;
        for (i, name) in self.names().enumerate() {
            f.write_str(if i == 0 { " " } else { "|" })?;
            f.write_str(name)?;
        }
        Ok(())
    }
}

/// `SetDrivesMisc` flags.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct DrivesMisc(pub u32);

impl DrivesMisc {
    /// Bit 0: mark the axis as synchronized (homed).
    pub const SET_SYNCHRONIZED: u32 = 1 << 0;
    /// Bit 1: clear the synchronized flag.
    pub const RESET_SYNCHRONIZED: u32 = 1 << 1;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_round_trip_per_revision() {
        for rev in Revision::ALL {
            for raw in 0..=255u8 {
                let mode = DriveMode::from_raw(raw, rev);
                assert_eq!(mode.to_raw(rev), Some(raw), "{raw:#04x} in {rev}");
            }
        }
    }

    #[test]
    fn revision_differences() {
        assert_eq!(DriveMode::from_raw(0x12, Revision::Rev2014), DriveMode::Homing);
        assert_eq!(DriveMode::from_raw(0x12, Revision::Rev2013), DriveMode::SyncPos0);
        assert_eq!(DriveMode::from_raw(0x11, Revision::Rev2012), DriveMode::SyncPos0);
        assert_eq!(DriveMode::from_raw(0x10, Revision::Rev2014), DriveMode::Unknown(0x10));
        assert_eq!(DriveMode::Homing.to_raw(Revision::Rev2012), None);
        assert_eq!(DriveMode::SyncPos0.to_raw(Revision::Rev2012), Some(0x11));
        assert_eq!(DriveMode::PosIncrement.to_raw(Revision::Rev2013), None);
    }

    #[test]
    fn status_names() {
        let s = DriveStatus(DriveStatus::SYNCHRONIZED | DriveStatus::ERROR);
        assert!(s.contains(DriveStatus::ERROR));
        assert_eq!(s.names().collect::<Vec<_>>(), ["synchronized", "error"]);
        assert_eq!(s.to_string(), "0x8010 synchronized|error");
    }
}
