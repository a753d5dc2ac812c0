//! Emergency producer (CiA 301 §7.2.7, specs/canopen.md 3.4): the error register 0x1001,
//! the pre-defined error field 0x1003 (newest first, at most 8) and the EMCY frame
//! (0x80 + id: code LE, register, 5 manufacturer bytes). A fault reset sends code 0x0000.

/// Error register bits set by an error code (bit 0 generic always; 1 current 0x2xxx;
/// 2 voltage 0x3xxx; 3 temperature 0x4xxx; 4 communication 0x81xx/0x82xx; 5 device
/// profile for the CiA 402 monitoring codes 0x86xx / 0x7121).
pub fn register_bits(code: u16) -> u8 {
    let class = match code {
        0x2000..=0x2FFF => 0x02,
        0x3000..=0x3FFF => 0x04,
        0x4000..=0x4FFF => 0x08,
        0x8100..=0x82FF => 0x10,
        0x8600..=0x86FF | 0x7121 => 0x20,
        _ => 0x00,
    };
    0x01 | class
}

/// Error state of one node.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Emcy {
    register: u8,
    history: Vec<u32>,
    /// Last error code (0x603F), 0 when reset.
    code: u16,
}

impl Emcy {
    /// The error register 0x1001.
    pub fn register(&self) -> u8 {
        self.register
    }

    /// The last error code (0x603F).
    pub fn code(&self) -> u16 {
        self.code
    }

    /// The error history, newest first (0x1003 sub 1..).
    pub fn history(&self) -> &[u32] {
        &self.history
    }

    /// Clears the history (0x1003:0 written with 0).
    pub fn clear_history(&mut self) {
        self.history.clear();
    }

    /// Records an error; returns the 8 EMCY data bytes.
    pub fn raise(&mut self, code: u16, info: [u8; 5]) -> [u8; 8] {
        self.register |= register_bits(code);
        self.code = code;
        self.history.insert(0, u32::from(code));
        self.history.truncate(8);
        Self::frame(code, self.register, info)
    }

    /// A one-off EMCY (e.g. PDO length) that does not latch in the register.
    pub fn transient(&mut self, code: u16) -> [u8; 8] {
        self.history.insert(0, u32::from(code));
        self.history.truncate(8);
        Self::frame(code, self.register | register_bits(code), [0; 5])
    }

    /// All errors gone: register 0, code 0; returns the "error reset" EMCY bytes.
    pub fn reset(&mut self) -> [u8; 8] {
        self.register = 0;
        self.code = 0;
        Self::frame(0, 0, [0; 5])
    }

    fn frame(code: u16, register: u8, info: [u8; 5]) -> [u8; 8] {
        let [c0, c1] = code.to_le_bytes();
        let [m0, m1, m2, m3, m4] = info;
        [c0, c1, register, m0, m1, m2, m3, m4]
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn overtemperature_then_reset() {
        let mut e = Emcy::default();
        // 0x4310 LE 10 43; register = generic (bit 0) + temperature (bit 3) = 0x09.
        assert_eq!(e.raise(0x4310, [0; 5]), [0x10, 0x43, 0x09, 0, 0, 0, 0, 0]);
        // Following error 0x8611: generic + device profile (bit 5) -> 0x09 | 0x21 = 0x29.
        assert_eq!(e.raise(0x8611, [0; 5]), [0x11, 0x86, 0x29, 0, 0, 0, 0, 0]);
        assert_eq!(e.history(), &[0x8611, 0x4310]);
        assert_eq!(e.code(), 0x8611);
        assert_eq!(e.reset(), [0; 8]);
        assert_eq!((e.register(), e.code()), (0, 0));
        assert_eq!(e.history().len(), 2, "history survives a reset");
        for i in 0..10 {
            e.raise(0x1000 + i, [0; 5]);
        }
        assert_eq!(e.history().len(), 8);
        assert_eq!(e.history()[0], 0x1009);
    }
}
