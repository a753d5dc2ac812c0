//! EMCY consumer (CiA 301 §7.2.7): decodes emergency frames (COB-ID 0x080 + node, 8 bytes)
//! into an [`Emergency`] with the code class, the error register bits by name and the
//! manufacturer-specific bytes.

use std::fmt;

use motus_canopen_protocol::{CanFrame, EmcyClass};

/// Names of the error register (0x1001) bits 0..=7 (CiA 301 §7.5.2.2).
pub const ERROR_REGISTER_BITS: [&str; 8] = [
    "generic",
    "current",
    "voltage",
    "temperature",
    "communication",
    "device profile",
    "reserved",
    "manufacturer",
];

/// The error register byte (copy of 0x1001).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ErrorRegister(pub u8);

impl ErrorRegister {
    /// Names of the bits that are set, bit 0 first.
    pub fn names(self) -> Vec<&'static str> {
        ERROR_REGISTER_BITS
            .iter()
            .enumerate()
            .filter(|(i, _)| self.0 & (1 << i) != 0)
            .map(|(_, n)| *n)
            .collect()
    }
}

/// A decoded emergency message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Emergency {
    /// Producing node.
    pub node: u8,
    /// Emergency error code (0x0000 = error reset).
    pub code: u16,
    /// Class of the code.
    pub class: EmcyClass,
    /// Error register.
    pub register: ErrorRegister,
    /// Manufacturer-specific error field (bytes 3–7).
    pub manufacturer: [u8; 5],
}

/// Result of looking at a frame in the EMCY range.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum EmcyParse {
    /// Not an EMCY COB-ID (0x081..=0x0FF).
    NotEmcy,
    /// An EMCY COB-ID with a wrong length or RTR: malformed.
    Malformed,
    /// A valid emergency.
    Emergency(Emergency),
}

impl Emergency {
    /// Classifies and decodes a frame.
    pub fn parse(frame: &CanFrame) -> EmcyParse {
        let id = frame.id();
        if frame.is_extended() || !(0x081..=0x0FF).contains(&id) {
            return EmcyParse::NotEmcy;
        }
        let Ok(node) = u8::try_from(id - 0x080) else { return EmcyParse::NotEmcy };
        let Ok([c0, c1, register, m0, m1, m2, m3, m4]) = <[u8; 8]>::try_from(frame.data()) else {
            return EmcyParse::Malformed;
        };
        if frame.is_remote() {
            return EmcyParse::Malformed;
        }
        let code = u16::from_le_bytes([c0, c1]);
        EmcyParse::Emergency(Emergency {
            node,
            code,
            class: EmcyClass::of(code),
            register: ErrorRegister(register),
            manufacturer: [m0, m1, m2, m3, m4],
        })
    }

    /// Whether this is an "error reset / no error" message (code 0x0000).
    pub fn is_reset(&self) -> bool {
        self.code == 0
    }
}

impl fmt::Display for Emergency {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "EMCY from node {}: 0x{:04X} ({})", self.node, self.code, self.class.description())?;
        let names = self.register.names();
        if names.is_empty() {
            write!(f, ", error register 0x{:02X}", self.register.0)?;
        } else {
            write!(f, ", error register 0x{:02X} [{}]", self.register.0, names.join(", "))?;
        }
        let m = self.manufacturer;
        write!(f, ", manufacturer data {:02X} {:02X} {:02X} {:02X} {:02X}", m[0], m[1], m[2], m[3], m[4])
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn decodes_over_current() {
        // 085 = EMCY of node 5; 10 23 = code 0x2310 (current, output side) LE; 03 = register
        // bits 0 (generic) + 1 (current); 01 02 03 04 05 = manufacturer bytes.
        let frame: CanFrame = "085#1023030102030405".parse().unwrap();
        let EmcyParse::Emergency(e) = Emergency::parse(&frame) else { panic!() };
        assert_eq!(e.node, 5);
        assert_eq!(e.code, 0x2310);
        assert_eq!(e.class, EmcyClass::Current);
        assert_eq!(e.register.names(), vec!["generic", "current"]);
        assert_eq!(
            e.to_string(),
            "EMCY from node 5: 0x2310 (current), error register 0x03 [generic, current], manufacturer data 01 02 03 04 05"
        );
        assert!(!e.is_reset());
    }

    #[test]
    fn malformed_and_foreign() {
        assert_eq!(Emergency::parse(&"085#102303".parse().unwrap()), EmcyParse::Malformed);
        assert_eq!(Emergency::parse(&"080#".parse().unwrap()), EmcyParse::NotEmcy); // SYNC
        assert_eq!(Emergency::parse(&"185#00".parse().unwrap()), EmcyParse::NotEmcy);
        let EmcyParse::Emergency(e) = Emergency::parse(&"0FF#0000000000000000".parse().unwrap()) else {
            panic!()
        };
        assert!(e.is_reset());
        assert_eq!(e.node, 127);
    }
}
