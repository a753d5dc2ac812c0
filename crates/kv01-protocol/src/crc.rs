//! The KV-01 message CRC (`specs/kv01.md`, section "CRC"; source: seed 003, chapter 2.11).
//!
//! The CRC covers every byte of a standard message before the CRC itself (ADDRESS, LENGTH,
//! COMMAND, DATA). The published procedure, transcribed literally by [`update_bitwise`], is:
//!
//! ```text
//! B = 0
//! for each byte A of the message:
//!     repeat 8 times:
//!         if (A xor B) bit0 == 1: B = ((B xor 0x18) >> 1) | 0x80
//!         else:                   B = B >> 1
//!         A = rotate A right by one bit
//! CRC = B
//! ```
//!
//! and a final value of 0xF0 is sent as **0xF1** (by the module and by the host), so the end
//! byte 0xF0 never appears in the CRC position ([`finish`]).
//!
//! The procedure is the 1-Wire (Dallas/Maxim) CRC-8, so it is also computed by the usual
//! 256-entry table ([`update`], [`TABLE`]); a test checks both agree on all 65 536
//! (crc, byte) pairs. The four example messages printed in the source do **not** carry the
//! CRC this procedure gives; see [`crate::CrcMode`] for how a receiver deals with that.

/// The byte a computed CRC of 0xF0 is replaced with.
pub const F0_SUBSTITUTE: u8 = 0xF1;

/// One byte of the published bitwise procedure: `crc` is B before the byte, the result is B
/// after it. Kept literally as printed (including the rotation of A) as the reference.
#[must_use]
pub fn update_bitwise(crc: u8, byte: u8) -> u8 {
    let mut a = byte;
    let mut b = crc;
    for _ in 0..8 {
        if (a ^ b) & 0x01 == 1 {
            b = ((b ^ 0x18) >> 1) | 0x80;
        } else {
            b >>= 1;
        }
        a = a.rotate_right(1);
    }
    b
}

// `i < 256` bounds the only index.
#[allow(clippy::indexing_slicing)]
const fn build_table() -> [u8; 256] {
    let mut table = [0u8; 256];
    let mut i = 0;
    while i < 256 {
        // The same procedure as `update_bitwise(0, i)`, written for a const context.
        let mut b = i as u8;
        let mut k = 0;
        while k < 8 {
            b = if b & 1 == 1 { ((b ^ 0x18) >> 1) | 0x80 } else { b >> 1 };
            k += 1;
        }
        table[i] = b;
        i += 1;
    }
    table
}

/// `TABLE[x]` is the bitwise procedure run over the byte `x` from B = 0. Because the
/// procedure is linear and reflected, `update(crc, byte) == TABLE[crc ^ byte]`.
pub static TABLE: [u8; 256] = build_table();

/// One byte of the CRC, table-driven (equal to [`update_bitwise`] for every input).
#[inline]
#[must_use]
pub fn update(crc: u8, byte: u8) -> u8 {
    // A u8 index is always in bounds of the 256-entry table; `get` keeps clippy quiet and
    // compiles to the plain load.
    TABLE.get(usize::from(crc ^ byte)).copied().unwrap_or(0)
}

/// The raw CRC of `bytes` (no 0xF0 substitution), table-driven.
#[must_use]
pub fn raw(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0, |crc, &b| update(crc, b))
}

/// The raw CRC of `bytes` (no 0xF0 substitution) by the literal bitwise procedure.
#[must_use]
pub fn raw_bitwise(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0, |crc, &b| update_bitwise(crc, b))
}

/// Applies the 0xF0 -> 0xF1 substitution to a raw CRC.
#[inline]
#[must_use]
pub fn finish(raw: u8) -> u8 {
    if raw == crate::END {
        F0_SUBSTITUTE
    } else {
        raw
    }
}

/// The CRC byte to send for a message whose bytes before the CRC are `bytes`
/// (ADDRESS..DATA), with the 0xF0 -> 0xF1 substitution applied.
#[must_use]
pub fn compute(bytes: &[u8]) -> u8 {
    finish(raw(bytes))
}

#[cfg(test)]
#[allow(clippy::indexing_slicing)]
mod tests {
    use super::*;

    #[test]
    fn table_equals_bitwise_for_all_pairs() {
        for crc in 0..=255u8 {
            for byte in 0..=255u8 {
                assert_eq!(update(crc, byte), update_bitwise(crc, byte), "{crc:#x} {byte:#x}");
            }
        }
    }

    #[test]
    fn check_value_is_maxim_crc8() {
        // "123456789" -> 0xA1 by the independent Python transcription (see tests/vectors.rs),
        // which is also the published check value of CRC-8/MAXIM-DOW.
        assert_eq!(compute(b"123456789"), 0xA1);
        assert_eq!(raw_bitwise(b"123456789"), 0xA1);
    }

    #[test]
    fn substitution() {
        // E1 06 D1 77: raw CRC 0xF0 (found by the Python script), sent as 0xF1.
        let body = [0xE1, 0x06, 0xD1, 0x77];
        assert_eq!(raw(&body), 0xF0);
        assert_eq!(compute(&body), 0xF1);
        assert_eq!(finish(0x12), 0x12);
    }
}
