//! Faulhaber status words (`specs/faulhaber.md` §1.4): the `OST` bit field and the legacy
//! `GST` / `GFS` / `GAST` strings of '0'/'1' characters.

use serde::{Deserialize, Serialize};

/// `OST` operation status bits (the decimal answer to `OST`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct OperationStatus(pub u32);

impl OperationStatus {
    /// Bit 0: homing running.
    pub const HOMING: u32 = 1 << 0;
    /// Bit 1: program sequence running.
    pub const PROGRAM_RUNNING: u32 = 1 << 1;
    /// Bit 2: program stopped by DELAY.
    pub const PROGRAM_DELAY: u32 = 1 << 2;
    /// Bit 3: program stopped by NOTIFY.
    pub const PROGRAM_NOTIFY: u32 = 1 << 3;
    /// Bit 4: current limitation active.
    pub const CURRENT_LIMITED: u32 = 1 << 4;
    /// Bit 5: deviation error.
    pub const DEVIATION_ERROR: u32 = 1 << 5;
    /// Bit 6: overvoltage.
    pub const OVERVOLTAGE: u32 = 1 << 6;
    /// Bit 7: overtemperature.
    pub const OVERTEMPERATURE: u32 = 1 << 7;
    /// Bit 16: position attained.
    pub const POSITION_ATTAINED: u32 = 1 << 16;

    /// Whether every bit of `mask` is set.
    #[must_use]
    pub const fn has(self, mask: u32) -> bool {
        self.0 & mask == mask
    }

    /// Status of digital input `n` (1..=5, bits 8-12); `None` for other `n`.
    #[must_use]
    pub const fn input(self, n: u8) -> Option<bool> {
        if n >= 1 && n <= 5 {
            Some(self.0 & (1 << (7 + n as u32)) != 0)
        } else {
            None
        }
    }

    /// From a reply value (`None` when negative or above 32 bits).
    #[must_use]
    pub fn from_value(v: i64) -> Option<Self> {
        u32::try_from(v).ok().map(Self)
    }
}

/// Reads a string of '0'/'1' characters of exactly `N` characters.
fn flags<const N: usize>(text: &str) -> Option<[bool; N]> {
    let mut out = [false; N];
    let mut chars = text.chars();
    for slot in &mut out {
        *slot = match chars.next()? {
            '0' => false,
            '1' => true,
            _ => return None,
        };
    }
    chars.next().is_none().then_some(out)
}

/// Legacy `GST` status: 7 characters, position 0 first.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Gst {
    /// 0: position controller active (else speed controller).
    pub position_control: bool,
    /// 1: velocity preset analog or PWM (else RS-232).
    pub analog_or_pwm: bool,
    /// 2: PWM (else analog), valid when `analog_or_pwm`.
    pub pwm: bool,
    /// 3: drive enabled.
    pub enabled: bool,
    /// 4: target position reached.
    pub target_reached: bool,
    /// 5: positive limit-switch edge effective.
    pub positive_edge: bool,
    /// 6: limit switch at high level.
    pub switch_high: bool,
}

impl Gst {
    /// Parses the 7-character answer to `GST`.
    #[must_use]
    pub fn parse(text: &str) -> Option<Self> {
        let [a, b, c, d, e, f, g] = flags::<7>(text)?;
        Some(Self {
            position_control: a,
            analog_or_pwm: b,
            pwm: c,
            enabled: d,
            target_reached: e,
            positive_edge: f,
            switch_high: g,
        })
    }
}

/// Legacy `GFS` fault status: 4 characters, '1' = error.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Gfs {
    /// 0: overtemperature protection.
    pub overtemperature: bool,
    /// 1: current-limiting controller.
    pub current_limiting: bool,
    /// 3: overvoltage regulator.
    pub overvoltage: bool,
}

impl Gfs {
    /// Parses the 4-character answer to `GFS`.
    #[must_use]
    pub fn parse(text: &str) -> Option<Self> {
        let [a, b, _, d] = flags::<4>(text)?;
        Some(Self { overtemperature: a, current_limiting: b, overvoltage: d })
    }
}

/// Legacy `GAST` additional status: 4 characters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Gast {
    /// 0: limit switch 2 high.
    pub switch2_high: bool,
    /// 1: limit switch 3 high.
    pub switch3_high: bool,
    /// 2: clockwise rotation for positive values.
    pub clockwise_positive: bool,
    /// 3: homing still active.
    pub homing_active: bool,
}

impl Gast {
    /// Parses the 4-character answer to `GAST`.
    #[must_use]
    pub fn parse(text: &str) -> Option<Self> {
        let [a, b, c, d] = flags::<4>(text)?;
        Some(Self { switch2_high: a, switch3_high: b, clockwise_positive: c, homing_active: d })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strings() {
        let g = Gst::parse("0001100");
        assert_eq!(g.map(|g| (g.enabled, g.target_reached)), Some((true, true)));
        assert_eq!(Gst::parse("000110"), None);
        assert_eq!(Gst::parse("00011000"), None);
        assert_eq!(Gst::parse("000x100"), None);
        assert_eq!(Gast::parse("1011").map(|g| g.homing_active), Some(true));
        assert_eq!(Gfs::parse("0100").map(|g| g.current_limiting), Some(true));
        let o = OperationStatus(1 << 16 | 1 << 8);
        assert!(o.has(OperationStatus::POSITION_ATTAINED));
        assert_eq!(o.input(1), Some(true));
        assert_eq!(o.input(6), None);
    }
}
