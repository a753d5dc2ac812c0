//! Status bytes and measurement data carried in module replies: the D1 status byte of joints
//! 1-5 and of the gripper, the D3 resolver packing, the D4 voltages and the D5 gripper load.

use serde::{Deserialize, Serialize};

/// D1 reply status of joints 1-5, also the status bits in the D2/D3 resolver reply (all
/// modules, the gripper included). Bits 4-7 are always 0.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct JointStatus {
    /// Bit 3: the brake is released.
    pub brake_released: bool,
    /// Bit 2: the limit switch is pressed.
    pub limit_switch: bool,
    /// Bit 1: LSSTOP, the module blocks speed commands after a limit-switch stop.
    pub lsstop: bool,
    /// Bit 0: restricted mode (driving out of a limit switch at |speed| <= 399 rpm).
    pub restricted_mode: bool,
}

impl JointStatus {
    /// The four flags from the low nibble of `bits` (the high nibble is ignored).
    #[must_use]
    pub const fn from_bits(bits: u8) -> Self {
        Self {
            brake_released: bits & 0x08 != 0,
            limit_switch: bits & 0x04 != 0,
            lsstop: bits & 0x02 != 0,
            restricted_mode: bits & 0x01 != 0,
        }
    }

    /// The status for a D1 reply byte, `None` when a reserved bit (4-7) is set.
    #[must_use]
    pub const fn from_byte(byte: u8) -> Option<Self> {
        if byte & 0xF0 == 0 {
            Some(Self::from_bits(byte))
        } else {
            None
        }
    }

    /// The status byte (bits 0-3).
    #[must_use]
    pub const fn bits(self) -> u8 {
        (self.brake_released as u8) << 3
            | (self.limit_switch as u8) << 2
            | (self.lsstop as u8) << 1
            | self.restricted_mode as u8
    }
}

/// D1 reply status of the gripper module (0xE6): the open/close drive. Bits 3-7 are 0.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct GripperStatus {
    /// Bit 2, LIMIT: the current limitation of the open/close motor is on.
    pub current_limit: bool,
    /// Bit 1, PHASE: 1 = opening, 0 = closing.
    pub opening: bool,
    /// Bit 0, BRAKE: the software brake is released.
    pub brake_released: bool,
}

impl GripperStatus {
    /// The status for a D1 reply byte, `None` when a reserved bit (3-7) is set.
    #[must_use]
    pub const fn from_byte(byte: u8) -> Option<Self> {
        if byte & 0xF8 == 0 {
            Some(Self {
                current_limit: byte & 0x04 != 0,
                opening: byte & 0x02 != 0,
                brake_released: byte & 0x01 != 0,
            })
        } else {
            None
        }
    }

    /// The status byte (bits 0-2).
    #[must_use]
    pub const fn bits(self) -> u8 {
        (self.current_limit as u8) << 2 | (self.opening as u8) << 1 | self.brake_released as u8
    }
}

/// D3 (and D2) reply: 16-bit resolver position (no offset correction; 12-bit on the gripper
/// module) and the joint status bits, packed in three 7-bit bytes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct ResolverReading {
    /// Raw position, ResH:ResL, 65 536 counts per turn.
    pub position: u16,
    /// The status bits of byte 3 (same meaning as the D1 reply of joints 1-5).
    #[serde(flatten)]
    pub status: JointStatus,
}

impl ResolverReading {
    /// Unpacks the three data bytes: `[ResH.6..0, ResL.6..0, ResH.7<<5 | ResL.7<<4 | status]`.
    /// `None` when a bit that must be 0 is set (bit 7 of any byte, bit 6 of byte 3).
    #[must_use]
    pub const fn from_bytes(bytes: [u8; 3]) -> Option<Self> {
        let [b1, b2, b3] = bytes;
        if (b1 | b2 | b3) & 0x80 != 0 || b3 & 0x40 != 0 {
            return None;
        }
        let res_h = b1 | (b3 & 0x20) << 2;
        let res_l = b2 | (b3 & 0x10) << 3;
        Some(Self { position: (res_h as u16) << 8 | res_l as u16, status: JointStatus::from_bits(b3) })
    }

    /// Packs the reading into the three data bytes (bit 7 of every byte is 0).
    #[must_use]
    pub const fn to_bytes(self) -> [u8; 3] {
        let [res_h, res_l] = self.position.to_be_bytes();
        [res_h & 0x7F, res_l & 0x7F, (res_h & 0x80) >> 2 | (res_l & 0x80) >> 3 | self.status.bits()]
    }

    /// The raw position in degrees (0..360), without the joint offset.
    #[must_use]
    pub fn raw_degrees(self) -> f64 {
        f64::from(self.position) * 360.0 / 65536.0
    }
}

/// `deg` normalised to (-180, 180].
#[must_use]
pub fn normalise_deg(deg: f64) -> f64 {
    let r = deg.rem_euclid(360.0);
    if r > 180.0 {
        r - 360.0
    } else {
        r
    }
}

/// The joint angle of a raw resolver reading (`specs/kv01.md`, D3 and "Joint offsets and
/// soft limits": the module reports `joint angle + offset` without correction):
/// `raw * 360 / 2^bits - offset_deg`, normalised to (-180, 180]. `bits` is 16 on joints 1-5
/// and 12 on the gripper.
#[must_use]
pub fn joint_angle_deg(raw: u16, offset_deg: f64, bits: u8) -> f64 {
    let per_turn = f64::from(1u32 << bits.min(16));
    normalise_deg(f64::from(raw) * 360.0 / per_turn - offset_deg)
}

/// Volts per count of the 24 V measurement.
pub const VOLTS_PER_COUNT_24V: f64 = 0.027_402_343_75;
/// Volts per count of the 12 V measurement.
pub const VOLTS_PER_COUNT_12V: f64 = 0.013_105_468_75;
/// Volts per count of the 5 V measurement.
pub const VOLTS_PER_COUNT_5V: f64 = 0.006_552_734_375;

/// D4 reply: the module's supply voltages, raw (H*256+L) as sent. The JSON form adds the
/// values in volts (`volts_24v`...); they are ignored when read back.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(into = "VoltagesJson", from = "VoltagesJson")]
pub struct Voltages {
    /// Raw 24 V count (data bytes 1-2).
    pub raw_24v: u16,
    /// Raw 5 V count (data bytes 3-4).
    pub raw_5v: u16,
    /// Raw 12 V count (data bytes 5-6).
    pub raw_12v: u16,
}

impl Voltages {
    /// Reads the six data bytes 24V_H, 24V_L, 5V_H, 5V_L, 12V_H, 12V_L.
    #[must_use]
    pub const fn from_bytes(bytes: [u8; 6]) -> Self {
        let [a, b, c, d, e, f] = bytes;
        Self {
            raw_24v: u16::from_be_bytes([a, b]),
            raw_5v: u16::from_be_bytes([c, d]),
            raw_12v: u16::from_be_bytes([e, f]),
        }
    }

    /// The six data bytes.
    #[must_use]
    pub const fn to_bytes(self) -> [u8; 6] {
        let [a, b] = self.raw_24v.to_be_bytes();
        let [c, d] = self.raw_5v.to_be_bytes();
        let [e, f] = self.raw_12v.to_be_bytes();
        [a, b, c, d, e, f]
    }

    /// The 24 V supply in volts.
    #[must_use]
    pub fn volts_24v(self) -> f64 {
        f64::from(self.raw_24v) * VOLTS_PER_COUNT_24V
    }

    /// The 5 V supply in volts.
    #[must_use]
    pub fn volts_5v(self) -> f64 {
        f64::from(self.raw_5v) * VOLTS_PER_COUNT_5V
    }

    /// The 12 V supply in volts.
    #[must_use]
    pub fn volts_12v(self) -> f64 {
        f64::from(self.raw_12v) * VOLTS_PER_COUNT_12V
    }
}

/// JSON shape of [`Voltages`]: raw counts plus (output only) volts.
#[derive(Serialize, Deserialize)]
struct VoltagesJson {
    raw_24v: u16,
    raw_5v: u16,
    raw_12v: u16,
    #[serde(default)]
    volts_24v: f64,
    #[serde(default)]
    volts_5v: f64,
    #[serde(default)]
    volts_12v: f64,
}

impl From<Voltages> for VoltagesJson {
    fn from(v: Voltages) -> Self {
        Self {
            raw_24v: v.raw_24v,
            raw_5v: v.raw_5v,
            raw_12v: v.raw_12v,
            volts_24v: v.volts_24v(),
            volts_5v: v.volts_5v(),
            volts_12v: v.volts_12v(),
        }
    }
}

impl From<VoltagesJson> for Voltages {
    fn from(j: VoltagesJson) -> Self {
        Self { raw_24v: j.raw_24v, raw_5v: j.raw_5v, raw_12v: j.raw_12v }
    }
}

/// D5 reply of the gripper module: load of the open/close motor and two status bits.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct GripperLoad {
    /// Bits 6..2: actual motor load (0..=31, unit not stated by the source).
    pub load: u8,
    /// Bit 1, PHASE: 1 = opening.
    pub opening: bool,
    /// Bit 0, BRAKE: the software brake is released.
    pub brake_released: bool,
}

impl GripperLoad {
    /// Largest load value (5 bits).
    pub const MAX_LOAD: u8 = 31;

    /// The load for a D5 reply byte, `None` when bit 7 is set.
    #[must_use]
    pub const fn from_byte(byte: u8) -> Option<Self> {
        if byte & 0x80 != 0 {
            return None;
        }
        Some(Self { load: byte >> 2, opening: byte & 0x02 != 0, brake_released: byte & 0x01 != 0 })
    }

    /// The reply byte, `None` when `load` is above [`Self::MAX_LOAD`].
    #[must_use]
    pub const fn to_byte(self) -> Option<u8> {
        if self.load > Self::MAX_LOAD {
            return None;
        }
        Some(self.load << 2 | (self.opening as u8) << 1 | self.brake_released as u8)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolver_packing_by_hand() {
        // Position 0x92B4 = ResH 1001_0010, ResL 1011_0100; status brake released + LSSTOP.
        // Byte 1 = ResH.6..0 = 0x12, byte 2 = ResL.6..0 = 0x34,
        // byte 3 = ResH.7 (b5) | ResL.7 (b4) | released (b3) | LSSTOP (b1) = 0x3A.
        let r = ResolverReading {
            position: 0x92B4,
            status: JointStatus { brake_released: true, lsstop: true, ..JointStatus::default() },
        };
        assert_eq!(r.to_bytes(), [0x12, 0x34, 0x3A]);
        assert_eq!(ResolverReading::from_bytes([0x12, 0x34, 0x3A]), Some(r));
        assert_eq!(ResolverReading::from_bytes([0x80, 0, 0]), None);
        assert_eq!(ResolverReading::from_bytes([0, 0, 0x40]), None);
    }

    #[test]
    fn voltages_by_hand() {
        // 0x036B = 875 counts * 0.02740234375 = 23.977... V
        let v = Voltages::from_bytes([0x03, 0x6B, 0x02, 0xFA, 0x03, 0x94]);
        assert_eq!((v.raw_24v, v.raw_5v, v.raw_12v), (875, 762, 916));
        assert!((v.volts_24v() - 23.977_050_781_25).abs() < 1e-12);
        assert!((v.volts_5v() - 4.993_183_593_75).abs() < 1e-12);
        assert!((v.volts_12v() - 12.004_609_375).abs() < 1e-12);
        assert_eq!(v.to_bytes(), [0x03, 0x6B, 0x02, 0xFA, 0x03, 0x94]);
    }

    #[test]
    fn status_bytes() {
        // Source example reply byte 0x08 = brake released only.
        assert_eq!(
            JointStatus::from_byte(0x08),
            Some(JointStatus { brake_released: true, ..JointStatus::default() })
        );
        assert_eq!(JointStatus::from_byte(0x10), None);
        assert_eq!(GripperStatus::from_byte(0x08), None);
        assert_eq!(GripperStatus::from_byte(0x05).map(GripperStatus::bits), Some(0x05));
        // 0x27 = load 9 (0b01001 << 2), PHASE, BRAKE.
        let l = GripperLoad::from_byte(0x27);
        assert_eq!(l, Some(GripperLoad { load: 9, opening: true, brake_released: true }));
        assert_eq!(l.and_then(GripperLoad::to_byte), Some(0x27));
        assert_eq!(GripperLoad::from_byte(0x80), None);
    }
}
