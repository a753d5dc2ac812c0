//! The PS1A checksum: the 8-bit sum of all bytes from ADR to the last parameter, carry
//! ignored (spec: "8-bit sum of all bytes from ADR to PN, carry ignored (mod 256)").

/// Sum of `bytes` modulo 256.
#[inline]
pub fn sum8(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0u8, |acc, b| acc.wrapping_add(*b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn carry_is_ignored() {
        assert_eq!(sum8(&[]), 0);
        assert_eq!(sum8(&[0xFF, 0x02]), 0x01);
        // 3 + 3 + 4 + 0xE8 + 0x03 + 0x00 = 0xF5 (move absolute to 1000, addr 3)
        assert_eq!(sum8(&[0x03, 0x03, 0x04, 0xE8, 0x03, 0x00]), 0xF5);
    }
}
