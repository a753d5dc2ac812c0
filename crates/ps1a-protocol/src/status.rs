//! The status bytes of the reply: LBS (low) and HBS (high).

use serde::{Deserialize, Serialize};

/// LBS, the low status byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(transparent)]
pub struct LowStatus(pub u8);

impl LowStatus {
    /// Bit 0: module after reset (power-on or command 8); cleared when the reference point
    /// has been reached.
    pub const AFTER_RESET: u8 = 1 << 0;
    /// Bit 1: checksum error in the received command; cleared after reported once.
    pub const CHECKSUM_ERROR: u8 = 1 << 1;
    /// Bit 2: emergency limit (limit switch) crossed; cleared after reported.
    pub const LIMIT_SWITCH: u8 = 1 << 2;
    /// Bit 3: encoder error; cleared after reported.
    pub const ENCODER_ERROR: u8 = 1 << 3;
    /// Bit 4: parameters (command 1) were not sent before a motion command.
    pub const NO_PARAMETERS: u8 = 1 << 4;
    /// Bit 5: moving to a commanded coordinate; cleared when the move ends.
    pub const IN_MOTION: u8 = 1 << 5;
    /// Bit 6: requested end point beyond the maximum position (move refused).
    pub const BEYOND_MAX_POSITION: u8 = 1 << 6;
    /// Bit 7: following-error overflow during motion; cleared after reported.
    pub const FOLLOWING_ERROR: u8 = 1 << 7;

    /// Bits that the module clears once they have been reported.
    pub const CLEARED_AFTER_REPORT: u8 =
        Self::CHECKSUM_ERROR | Self::LIMIT_SWITCH | Self::ENCODER_ERROR | Self::FOLLOWING_ERROR;

    const NAMES: [(u8, &'static str); 8] = [
        (Self::AFTER_RESET, "after_reset"),
        (Self::CHECKSUM_ERROR, "checksum_error"),
        (Self::LIMIT_SWITCH, "limit_switch"),
        (Self::ENCODER_ERROR, "encoder_error"),
        (Self::NO_PARAMETERS, "no_parameters"),
        (Self::IN_MOTION, "in_motion"),
        (Self::BEYOND_MAX_POSITION, "beyond_max_position"),
        (Self::FOLLOWING_ERROR, "following_error"),
    ];

    /// True if every bit of `mask` is set.
    pub fn has(self, mask: u8) -> bool {
        self.0 & mask == mask
    }

    /// Names of the set bits, in bit order.
    pub fn names(self) -> Vec<&'static str> {
        Self::NAMES.iter().filter(|(m, _)| self.0 & m != 0).map(|(_, n)| *n).collect()
    }
}

/// HBS, the high status byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(transparent)]
pub struct HighStatus(pub u8);

impl HighStatus {
    /// Bit 0: reference switch reached (cleared by reset or a new homing request).
    pub const REFERENCE_SWITCH: u8 = 1 << 0;
    /// Bit 1: encoder zero pulse reached (cleared by reset or a new homing request).
    pub const ENCODER_ZERO: u8 = 1 << 1;

    /// True if every bit of `mask` is set.
    pub fn has(self, mask: u8) -> bool {
        self.0 & mask == mask
    }

    /// Names of the set bits (undefined bits as `bit<n>`).
    pub fn names(self) -> Vec<&'static str> {
        const NAMES: [&str; 8] =
            ["reference_switch", "encoder_zero", "bit2", "bit3", "bit4", "bit5", "bit6", "bit7"];
        NAMES.iter().enumerate().filter(|(i, _)| self.0 & (1 << i) != 0).map(|(_, n)| *n).collect()
    }
}
