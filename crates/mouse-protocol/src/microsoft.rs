//! The Microsoft 2-button serial mouse protocol (1200 bit/s, 7 data bits, no parity,
//! 1 stop bit), which the converter's `'i'` device type names.
//!
//! Sources: seed 000, section 8.1.2 table "dvou tlačítkové myši"; the CuteMouse driver's
//! protocol notes (FreeDOS `CTMOUSE/PROTOCOL.TXT`, "Serial Microsoft mode"); the PC-8801
//! serial mouse memo (hitchhikr.net, "PC-8801 Serial mouse": "right direction is positive",
//! "downward direction is positive").
//!
//! ```text
//! byte 0   0 1 L R Y7 Y6 X7 X6     bit 6 set marks the first byte; L, R = 1 if pressed
//! byte 1   0 0 X5 X4 X3 X2 X1 X0
//! byte 2   0 0 Y5 Y4 Y3 Y2 Y1 Y0
//! ```
//!
//! dx, dy are 8-bit two's complement, split over the bytes; dx positive right, dy
//! positive **down**. With 7 data bits a UART set to 8 bits reads the stop bit as bit 7
//! (the seed's table shows bit 7 "always 1"): the decoders ignore bit 7.

use serde::{Deserialize, Serialize};

use crate::error::PacketError;
use motus_wire::Stream;

use crate::scan::PacketScanner;
use crate::MouseReport;

/// Bytes in one Microsoft packet.
pub const PACKET_LEN: usize = 3;
pub(crate) const SYNC: u8 = 0x40;
const DATA7: u8 = 0x7F;

/// One Microsoft-protocol packet.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct MicrosoftPacket {
    /// Left button pressed.
    pub left: bool,
    /// Right button pressed.
    pub right: bool,
    /// Motion to the right, counts.
    pub dx: i8,
    /// Motion **down** (toward the user), counts.
    pub dy: i8,
}

impl MicrosoftPacket {
    /// The 3 wire bytes (bit 7 clear).
    #[must_use]
    pub fn encode(&self) -> [u8; PACKET_LEN] {
        let x = self.dx as u8;
        let y = self.dy as u8;
        let b0 = SYNC
            | if self.left { 0x20 } else { 0 }
            | if self.right { 0x10 } else { 0 }
            | ((y >> 6) << 2)
            | (x >> 6);
        [b0, x & 0x3F, y & 0x3F]
    }

    /// Decodes exactly one packet (bit 7 of every byte is ignored).
    ///
    /// # Errors
    /// [`PacketError::Length`], [`PacketError::MicrosoftHeader`] if bit 6 of the first
    /// byte is clear, [`PacketError::MicrosoftData`] if bit 6 of a data byte is set.
    pub fn decode(bytes: &[u8]) -> Result<MicrosoftPacket, PacketError> {
        let arr: &[u8; PACKET_LEN] = bytes
            .try_into()
            .map_err(|_| PacketError::Length { expected: PACKET_LEN, received: bytes.len() })?;
        let [b0, b1, b2] = arr.map(|b| b & DATA7);
        if b0 & SYNC == 0 {
            return Err(PacketError::MicrosoftHeader(b0));
        }
        for (index, byte) in [(1, b1), (2, b2)] {
            if byte & SYNC != 0 {
                return Err(PacketError::MicrosoftData { index, byte });
            }
        }
        Ok(MicrosoftPacket {
            left: b0 & 0x20 != 0,
            right: b0 & 0x10 != 0,
            dx: (((b0 & 0x03) << 6) | (b1 & 0x3F)) as i8,
            dy: (((b0 & 0x0C) << 4) | (b2 & 0x3F)) as i8,
        })
    }

    /// The motion in the common convention (y up: `dy` negated).
    #[must_use]
    pub fn report(&self) -> MouseReport {
        MouseReport {
            dx: i16::from(self.dx),
            dy: -i16::from(self.dy),
            left: self.left,
            middle: false,
            right: self.right,
        }
    }
}

/// Streaming decoder for a Microsoft mouse (`MicrosoftStream::default()`): a packet starts
/// at a byte with bit 6 set and needs two following bytes with bit 6 clear; otherwise the
/// start byte is dropped and the search resumes at the next byte (so the `'M'` a mouse
/// sends after reset is skipped). At most 2 bytes of an incomplete packet are pending.
pub type MicrosoftStream = Stream<PacketScanner<MicrosoftPacket>>;

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn hand_computed_vectors() {
        // By hand from the layout above: left pressed, dx = -3 = 0b1111_1101 (X7X6 = 11,
        // X5..X0 = 111101 = 0x3D), dy = +65 = 0b0100_0001 (Y7Y6 = 01, Y5..Y0 = 000001).
        // byte 0 = 0 1 1 0 | 01 | 11 = 0x67.
        let p = MicrosoftPacket { left: true, right: false, dx: -3, dy: 65 };
        assert_eq!(p.encode(), [0x67, 0x3D, 0x01]);
        assert_eq!(MicrosoftPacket::decode(&[0x67, 0x3D, 0x01]).unwrap(), p);
        // As the seed's UART sees it (bit 7 = stop bit = 1): same packet.
        assert_eq!(MicrosoftPacket::decode(&[0xE7, 0xBD, 0x81]).unwrap(), p);
        // Right button only, no motion: 0b0101_0000.
        let p = MicrosoftPacket { right: true, ..MicrosoftPacket::default() };
        assert_eq!(p.encode(), [0x50, 0x00, 0x00]);
        // Common convention: y up.
        let r = MicrosoftPacket { left: false, right: false, dx: 5, dy: 7 }.report();
        assert_eq!((r.dx, r.dy), (5, -7));
    }

    #[test]
    fn typed_errors() {
        assert_eq!(MicrosoftPacket::decode(&[0x40]), Err(PacketError::Length { expected: 3, received: 1 }));
        assert_eq!(MicrosoftPacket::decode(&[0x00, 0, 0]), Err(PacketError::MicrosoftHeader(0)));
        assert_eq!(
            MicrosoftPacket::decode(&[0x40, 0, 0x41]),
            Err(PacketError::MicrosoftData { index: 2, byte: 0x41 })
        );
    }

    #[test]
    fn stream_skips_reset_m_and_garbage() {
        let p = MicrosoftPacket { left: false, right: true, dx: -128, dy: 127 };
        // Garbage, then the 'M' a mouse sends after reset, then a packet: the candidate
        // starting at 'M' has the packet's header as its second byte, so only 'M' is dropped.
        let mut bytes = vec![0x01, 0x02, b'M'];
        bytes.extend_from_slice(&p.encode());
        bytes.push(0x4D);
        let mut s = MicrosoftStream::default();
        let mut got = Vec::new();
        for b in &bytes {
            s.push(std::slice::from_ref(b));
            got.extend(std::iter::from_fn(|| s.next_frame()));
        }
        assert_eq!(got, vec![p]);
        assert_eq!((s.stats().frames, s.stats().garbage_bytes), (1, 3));
        assert_eq!(s.pending(), 1);
    }
}
