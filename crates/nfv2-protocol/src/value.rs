//! Value kinds (width and signedness) and their little-endian wire form.
//!
//! NFv2 has no type information on the wire: a command carries `k` parameter bytes and
//! the receiver splits them into values of the width its command table gives
//! ([`Revision::value_kind`](crate::Revision::value_kind)). The reference copies the
//! MCU's memory (little-endian ARM), so every multi-byte value is little-endian.

use core::fmt;

use serde::{Deserialize, Serialize};

/// The type of one value of a command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ValueKind {
    /// Unsigned 8-bit (modes, digital I/O, display).
    U8,
    /// Unsigned 16-bit little-endian (status registers, distances).
    U16,
    /// Signed 16-bit little-endian (currents, PWM, old speeds).
    I16,
    /// Unsigned 32-bit little-endian (flag words).
    U32,
    /// Signed 32-bit little-endian (positions, speeds since 2013).
    I32,
    /// A regulator setting: four u16 `P, I, D, T` (8 bytes).
    Regulator,
}

impl ValueKind {
    /// Bytes per value on the wire.
    #[must_use]
    pub const fn width(self) -> usize {
        match self {
            ValueKind::U8 => 1,
            ValueKind::U16 | ValueKind::I16 => 2,
            ValueKind::U32 | ValueKind::I32 => 4,
            ValueKind::Regulator => Regulator::WIRE_LEN,
        }
    }

    /// Inclusive range of an integer kind, `None` for [`ValueKind::Regulator`].
    #[must_use]
    pub const fn range(self) -> Option<(i64, i64)> {
        match self {
            ValueKind::U8 => Some((0, u8::MAX as i64)),
            ValueKind::U16 => Some((0, u16::MAX as i64)),
            ValueKind::I16 => Some((i16::MIN as i64, i16::MAX as i64)),
            ValueKind::U32 => Some((0, u32::MAX as i64)),
            ValueKind::I32 => Some((i32::MIN as i64, i32::MAX as i64)),
            ValueKind::Regulator => None,
        }
    }
}

impl fmt::Display for ValueKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ValueKind::U8 => "u8",
            ValueKind::U16 => "u16",
            ValueKind::I16 => "i16",
            ValueKind::U32 => "u32",
            ValueKind::I32 => "i32",
            ValueKind::Regulator => "regulator (4 x u16)",
        })
    }
}

/// Regulator parameters of `SetCurrentRegulator` / `SetSpeedRegulator` /
/// `SetPositionRegulator`: four little-endian u16 in the order P, I, D, T.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Regulator {
    /// Proportional gain (raw device units).
    pub p: u16,
    /// Integral gain (raw device units).
    pub i: u16,
    /// Derivative gain (raw device units).
    pub d: u16,
    /// Fourth parameter `t` of the reference's `NF_STRUCT_Regulator` (raw device units).
    pub t: u16,
}

impl Regulator {
    /// Bytes of one regulator setting on the wire.
    pub const WIRE_LEN: usize = 8;

    /// Wire form: P, I, D, T, each little-endian.
    #[must_use]
    pub fn to_bytes(self) -> [u8; 8] {
        let [p0, p1] = self.p.to_le_bytes();
        let [i0, i1] = self.i.to_le_bytes();
        let [d0, d1] = self.d.to_le_bytes();
        let [t0, t1] = self.t.to_le_bytes();
        [p0, p1, i0, i1, d0, d1, t0, t1]
    }

    /// Parses the wire form.
    #[must_use]
    pub fn from_bytes(bytes: [u8; 8]) -> Self {
        let [p0, p1, i0, i1, d0, d1, t0, t1] = bytes;
        Regulator {
            p: u16::from_le_bytes([p0, p1]),
            i: u16::from_le_bytes([i0, i1]),
            d: u16::from_le_bytes([d0, d1]),
            t: u16::from_le_bytes([t0, t1]),
        }
    }
}

/// Reads one integer of `kind` from exactly `kind.width()` bytes.
/// `None` if the length is wrong or `kind` is not an integer kind.
pub(crate) fn read_int(kind: ValueKind, bytes: &[u8]) -> Option<i64> {
    match kind {
        ValueKind::U8 => <[u8; 1]>::try_from(bytes).ok().map(|b| i64::from(u8::from_le_bytes(b))),
        ValueKind::U16 => <[u8; 2]>::try_from(bytes).ok().map(|b| i64::from(u16::from_le_bytes(b))),
        ValueKind::I16 => <[u8; 2]>::try_from(bytes).ok().map(|b| i64::from(i16::from_le_bytes(b))),
        ValueKind::U32 => <[u8; 4]>::try_from(bytes).ok().map(|b| i64::from(u32::from_le_bytes(b))),
        ValueKind::I32 => <[u8; 4]>::try_from(bytes).ok().map(|b| i64::from(i32::from_le_bytes(b))),
        ValueKind::Regulator => None,
    }
}

/// Little-endian bytes of `value` as `kind`: the first `kind.width()` bytes of the array
/// are meaningful. `None` if `value` is out of the kind's range (or `kind` is not an
/// integer kind).
pub(crate) fn int_to_le(kind: ValueKind, value: i64) -> Option<[u8; 4]> {
    match kind {
        ValueKind::U8 => u8::try_from(value).ok().map(|v| [v, 0, 0, 0]),
        ValueKind::U16 => u16::try_from(value).ok().map(|v| {
            let [a, b] = v.to_le_bytes();
            [a, b, 0, 0]
        }),
        ValueKind::I16 => i16::try_from(value).ok().map(|v| {
            let [a, b] = v.to_le_bytes();
            [a, b, 0, 0]
        }),
        ValueKind::U32 => u32::try_from(value).ok().map(u32::to_le_bytes),
        ValueKind::I32 => i32::try_from(value).ok().map(i32::to_le_bytes),
        ValueKind::Regulator => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const INT_KINDS: [ValueKind; 5] =
        [ValueKind::U8, ValueKind::U16, ValueKind::I16, ValueKind::U32, ValueKind::I32];

    #[test]
    fn little_endian_and_sign() {
        // -100 as i16 is 0xFF9C, sent LSB first: 9C FF.
        assert_eq!(int_to_le(ValueKind::I16, -100), Some([0x9C, 0xFF, 0, 0]));
        assert_eq!(read_int(ValueKind::I16, &[0x9C, 0xFF]), Some(-100));
        assert_eq!(read_int(ValueKind::U16, &[0x9C, 0xFF]), Some(0xFF9C));
        // 1000 = 0x000003E8 -> E8 03 00 00.
        assert_eq!(int_to_le(ValueKind::I32, 1000), Some([0xE8, 0x03, 0, 0]));
    }

    #[test]
    fn range_edges() {
        for kind in INT_KINDS {
            let (lo, hi) = kind.range().unwrap_or_default();
            for v in [lo, hi] {
                let bytes = int_to_le(kind, v).unwrap_or_default();
                let w = kind.width();
                assert_eq!(read_int(kind, bytes.get(..w).unwrap_or_default()), Some(v));
            }
            assert_eq!(int_to_le(kind, lo - 1), None, "{kind} below range");
            assert_eq!(int_to_le(kind, hi + 1), None, "{kind} above range");
        }
    }

    #[test]
    fn regulator_order_is_p_i_d_t() {
        let r = Regulator { p: 0x0102, i: 0x0304, d: 0x0506, t: 0x0708 };
        assert_eq!(r.to_bytes(), [0x02, 0x01, 0x04, 0x03, 0x06, 0x05, 0x08, 0x07]);
        assert_eq!(Regulator::from_bytes(r.to_bytes()), r);
    }
}
