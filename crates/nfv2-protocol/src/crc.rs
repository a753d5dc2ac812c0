//! The NFv2 CRC-8.
//!
//! As in the reference implementation (`nfv2.c`, `NFv2_CrcInit` / `NFv2_CrcFast`):
//!
//! - polynomial **0xD8**, processed most-significant bit first
//!   ("remainder << 1 ^ POLY when the top bit is set");
//! - initial value **0x00**, no input or output reflection, no final XOR;
//! - computed over frame bytes **3 ..= n-1**: the address byte and every command byte
//!   (code, k, parameters), i.e. everything after `'#', n, ~n` and before the CRC byte
//!   itself. The start byte and the length pair are *not* covered (they are checked by
//!   the `n == !~n` rule instead).
//!
//! 0xD8 written MSB-first is not one of the catalogued CRC-8 polynomials (its lowest bit
//! is 0, so it is an even polynomial with a weaker error-detection profile than e.g. 0x07);
//! we implement it literally because that is what the devices compute.

/// The generator polynomial, MSB-first, as the reference writes it.
pub const POLYNOMIAL: u8 = 0xD8;

/// Initial remainder.
pub const INIT: u8 = 0x00;

/// Byte-wise lookup table, built at compile time from [`POLYNOMIAL`].
const TABLE: [u8; 256] = build_table();

// The index is a loop counter bounded by the array length, not data from the wire.
#[allow(clippy::indexing_slicing)]
const fn build_table() -> [u8; 256] {
    let mut table = [0u8; 256];
    let mut dividend = 0usize;
    while dividend < 256 {
        table[dividend] = step_byte(dividend as u8);
        dividend += 1;
    }
    table
}

/// Divides one byte (already XORed with the remainder) by the polynomial, bit by bit.
const fn step_byte(byte: u8) -> u8 {
    let mut remainder = byte;
    let mut bit = 0;
    while bit < 8 {
        remainder = if remainder & 0x80 != 0 { (remainder << 1) ^ POLYNOMIAL } else { remainder << 1 };
        bit += 1;
    }
    remainder
}

/// CRC-8 of `bytes` (pass frame bytes `3..n`, i.e. address up to the last parameter).
#[must_use]
pub fn crc8(bytes: &[u8]) -> u8 {
    bytes.iter().fold(INIT, |crc, &byte| {
        // `usize::from(u8)` is always < 256 = TABLE.len(), so `get` never fails.
        TABLE.get(usize::from(crc ^ byte)).copied().unwrap_or(0)
    })
}

/// Bit-by-bit CRC-8 without the table: slower, kept as an independent cross-check.
#[must_use]
pub fn crc8_bitwise(bytes: &[u8]) -> u8 {
    bytes.iter().fold(INIT, |crc, &byte| step_byte(crc ^ byte))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_matches_bitwise_for_every_single_byte() {
        for b in 0..=255u8 {
            assert_eq!(crc8(&[b]), crc8_bitwise(&[b]), "byte {b:#04x}");
        }
    }

    #[test]
    fn check_value_from_independent_script() {
        // Computed once with a 10-line Python script that implements the published
        // polynomial literally (bitwise, MSB first, init 0, no reflection, no XOR-out):
        // crc8(b"123456789") = 0xF8, crc8([0x01]) = 0xD8, crc8([0x00]) = 0x00,
        // crc8([0x80]) = 0xE0.
        assert_eq!(crc8(b"123456789"), 0xF8);
        assert_eq!(crc8(&[0x01]), 0xD8);
        assert_eq!(crc8(&[0x00]), 0x00);
        assert_eq!(crc8(&[0x80]), 0xE0);
        assert_eq!(crc8(&[]), INIT);
    }

    #[test]
    fn appending_the_crc_gives_zero_remainder() {
        // A property of any CRC without final XOR / reflection: crc(m ++ crc(m)) == 0.
        let msg = [0x01, 0x13, 0x04, 0x78, 0xEC, 0xFF, 0xFF];
        let mut with_crc = msg.to_vec();
        with_crc.push(crc8(&msg));
        assert_eq!(crc8(&with_crc), 0);
    }
}
