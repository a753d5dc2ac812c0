//! 24-bit values, least significant byte first on the wire.

use serde::{Deserialize, Serialize};

/// An unsigned 24-bit value (absolute target, position, maximum position).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize)]
#[serde(try_from = "u32", into = "u32")]
pub struct U24(u32);

impl U24 {
    /// Largest value, 2^24 - 1.
    pub const MAX: U24 = U24(0x00FF_FFFF);
    /// The factory-default maximum position, 0x00FFFF.
    pub const DEFAULT_MAX_POSITION: U24 = U24(0x00_FFFF);

    /// `Some` if `v` fits in 24 bits.
    pub const fn new(v: u32) -> Option<U24> {
        if v <= 0x00FF_FFFF {
            Some(U24(v))
        } else {
            None
        }
    }

    /// The value.
    pub const fn get(self) -> u32 {
        self.0
    }

    /// Wraps any integer modulo 2^24 (what a 24-bit counter shows).
    pub fn wrapping(v: i64) -> U24 {
        U24((v.rem_euclid(1 << 24)) as u32)
    }

    /// Reads 3 bytes, LSB first.
    pub fn from_le(b: [u8; 3]) -> U24 {
        U24(u32::from(b[0]) | (u32::from(b[1]) << 8) | (u32::from(b[2]) << 16))
    }

    /// Writes 3 bytes, LSB first.
    pub fn to_le(self) -> [u8; 3] {
        let [a, b, c, _] = self.0.to_le_bytes();
        [a, b, c]
    }

    /// The value read as two's complement 24-bit.
    pub fn as_signed(self) -> i32 {
        ((self.0 << 8) as i32) >> 8
    }
}

impl TryFrom<u32> for U24 {
    type Error = String;
    fn try_from(v: u32) -> Result<Self, Self::Error> {
        U24::new(v).ok_or_else(|| format!("{v} does not fit in 24 bits (max 16777215)"))
    }
}

impl From<U24> for u32 {
    fn from(v: U24) -> u32 {
        v.0
    }
}

/// A signed 24-bit value in two's complement (relative move increment).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize)]
#[serde(try_from = "i32", into = "i32")]
pub struct I24(i32);

impl I24 {
    /// Smallest value, -2^23.
    pub const MIN: I24 = I24(-(1 << 23));
    /// Largest value, 2^23 - 1.
    pub const MAX: I24 = I24((1 << 23) - 1);

    /// `Some` if `v` fits in 24-bit two's complement.
    pub const fn new(v: i32) -> Option<I24> {
        if v >= -(1 << 23) && v < (1 << 23) {
            Some(I24(v))
        } else {
            None
        }
    }

    /// The value.
    pub const fn get(self) -> i32 {
        self.0
    }

    /// Reads 3 bytes, LSB first, sign-extending bit 23.
    pub fn from_le(b: [u8; 3]) -> I24 {
        I24(U24::from_le(b).as_signed())
    }

    /// Writes 3 bytes, LSB first, two's complement.
    pub fn to_le(self) -> [u8; 3] {
        let [a, b, c, _] = self.0.to_le_bytes();
        [a, b, c]
    }
}

impl TryFrom<i32> for I24 {
    type Error = String;
    fn try_from(v: i32) -> Result<Self, Self::Error> {
        I24::new(v).ok_or_else(|| format!("{v} does not fit in signed 24 bits (-8388608 ..= 8388607)"))
    }
}

impl From<I24> for i32 {
    fn from(v: I24) -> i32 {
        v.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn twos_complement_examples() {
        // -1 -> FF FF FF; -2^23 -> 00 00 80; 2^23-1 -> FF FF 7F (computed by hand)
        assert_eq!(I24::new(-1).map(I24::to_le), Some([0xFF, 0xFF, 0xFF]));
        assert_eq!(I24::MIN.to_le(), [0x00, 0x00, 0x80]);
        assert_eq!(I24::MAX.to_le(), [0xFF, 0xFF, 0x7F]);
        assert_eq!(I24::from_le([0x18, 0xFC, 0xFF]).get(), -1000);
        assert_eq!(I24::new(1 << 23), None);
        assert_eq!(U24::new(1 << 24), None);
        assert_eq!(U24::wrapping(-1).get(), 0xFF_FFFF);
    }
}
