//! The Mouse Systems 3-button serial mouse protocol (1200 bit/s, 8N1), which the
//! converter's `'m'` device type names.
//!
//! Sources: seed 000, section 8.1.2 table "tří tlačítkové myši" (its button polarities are
//! inconsistent); the CuteMouse driver's protocol notes (FreeDOS `CTMOUSE/PROTOCOL.TXT`,
//! "Serial Mouse Systems mode": buttons "0 if pressed", "Xb/Yb - movement of the mouse
//! since Xa/Ya", "positive movement value indicates motion to the right/upward"), which
//! this module follows.
//!
//! ```text
//! byte 0   1 0 0 0 0 L M R    0x80..=0x87; a button bit is 0 while pressed
//! byte 1   Xa  \ signed bytes: motion since the previous packet
//! byte 2   Ya  /
//! byte 3   Xb  \ signed bytes: motion while bytes 0-2 were sent
//! byte 4   Yb  /
//! ```
//!
//! Total motion: dx = Xa + Xb (right positive), dy = Ya + Yb (**up** positive).
//! Data bytes can look like a header (-128..=-121), so after garbage the stream decoder may
//! take a data byte for a header; it resynchronises at the next header it meets, as a
//! PC driver does.

use serde::{Deserialize, Serialize};

use crate::error::PacketError;
use motus_wire::Stream;

use crate::scan::PacketScanner;
use crate::MouseReport;

/// Bytes in one Mouse Systems packet.
pub const PACKET_LEN: usize = 5;
pub(crate) const HEADER_MASK: u8 = 0xF8;
pub(crate) const HEADER: u8 = 0x80;

/// One Mouse Systems packet.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct MouseSystemsPacket {
    /// Left button pressed.
    pub left: bool,
    /// Middle button pressed.
    pub middle: bool,
    /// Right button pressed.
    pub right: bool,
    /// First x motion (Xa), right positive.
    pub dx1: i8,
    /// First y motion (Ya), up positive.
    pub dy1: i8,
    /// Second x motion (Xb).
    pub dx2: i8,
    /// Second y motion (Yb).
    pub dy2: i8,
}

impl MouseSystemsPacket {
    /// The 5 wire bytes.
    #[must_use]
    pub fn encode(&self) -> [u8; PACKET_LEN] {
        let b0 = HEADER
            | if self.left { 0 } else { 0x04 }
            | if self.middle { 0 } else { 0x02 }
            | if self.right { 0 } else { 0x01 };
        [b0, self.dx1 as u8, self.dy1 as u8, self.dx2 as u8, self.dy2 as u8]
    }

    /// Decodes exactly one packet.
    ///
    /// # Errors
    /// [`PacketError::Length`], [`PacketError::MouseSystemsHeader`] if the first byte is
    /// not 0x80..=0x87.
    pub fn decode(bytes: &[u8]) -> Result<MouseSystemsPacket, PacketError> {
        let arr: &[u8; PACKET_LEN] = bytes
            .try_into()
            .map_err(|_| PacketError::Length { expected: PACKET_LEN, received: bytes.len() })?;
        let [b0, x1, y1, x2, y2] = *arr;
        if b0 & HEADER_MASK != HEADER {
            return Err(PacketError::MouseSystemsHeader(b0));
        }
        Ok(MouseSystemsPacket {
            left: b0 & 0x04 == 0,
            middle: b0 & 0x02 == 0,
            right: b0 & 0x01 == 0,
            dx1: x1 as i8,
            dy1: y1 as i8,
            dx2: x2 as i8,
            dy2: y2 as i8,
        })
    }

    /// Total x motion (Xa + Xb), right positive.
    #[must_use]
    pub fn dx(&self) -> i16 {
        i16::from(self.dx1) + i16::from(self.dx2)
    }

    /// Total y motion (Ya + Yb), up positive.
    #[must_use]
    pub fn dy(&self) -> i16 {
        i16::from(self.dy1) + i16::from(self.dy2)
    }

    /// The motion in the common convention (already y up).
    #[must_use]
    pub fn report(&self) -> MouseReport {
        MouseReport { dx: self.dx(), dy: self.dy(), left: self.left, middle: self.middle, right: self.right }
    }
}

/// Streaming decoder for a Mouse Systems mouse (`MouseSystemsStream::default()`): a packet
/// starts at a byte 0x80..=0x87 and takes the four bytes after it. At most 4 bytes of an
/// incomplete packet are pending.
pub type MouseSystemsStream = Stream<PacketScanner<MouseSystemsPacket>>;

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn hand_computed_vectors() {
        // By hand from the layout above: no button pressed -> 0x87 (all bits 1 = released);
        // Xa = +10 = 0x0A, Ya = -2 = 0xFE, Xb = +1, Yb = -128 = 0x80.
        let p = MouseSystemsPacket { dx1: 10, dy1: -2, dx2: 1, dy2: -128, ..Default::default() };
        assert_eq!(p.encode(), [0x87, 0x0A, 0xFE, 0x01, 0x80]);
        assert_eq!(MouseSystemsPacket::decode(&[0x87, 0x0A, 0xFE, 0x01, 0x80]).unwrap(), p);
        assert_eq!((p.dx(), p.dy()), (11, -130));
        // Left pressed only: bit 2 cleared -> 0x83.
        let p = MouseSystemsPacket::decode(&[0x83, 0, 0, 0, 0]).unwrap();
        assert!(p.left && !p.middle && !p.right);
        // All pressed -> 0x80.
        let p = MouseSystemsPacket::decode(&[0x80, 0x7F, 0x7F, 0x7F, 0x7F]).unwrap();
        assert!(p.left && p.middle && p.right);
        assert_eq!(p.report().dx, 254);
    }

    #[test]
    fn typed_errors() {
        assert_eq!(
            MouseSystemsPacket::decode(&[0x88, 0, 0, 0, 0]),
            Err(PacketError::MouseSystemsHeader(0x88))
        );
        assert_eq!(MouseSystemsPacket::decode(&[]), Err(PacketError::Length { expected: 5, received: 0 }));
    }

    #[test]
    fn stream_skips_garbage() {
        let p = MouseSystemsPacket { right: true, dx1: -5, dy1: 5, dx2: 0, dy2: 1, ..Default::default() };
        let mut bytes = vec![0x00, 0x7F, 0x90];
        bytes.extend_from_slice(&p.encode());
        bytes.extend_from_slice(&p.encode());
        let mut s = MouseSystemsStream::default();
        s.push(&bytes);
        assert_eq!(std::iter::from_fn(|| s.next_frame()).collect::<Vec<_>>(), vec![p, p]);
        assert_eq!((s.stats().frames, s.stats().garbage_bytes), (2, 3));
    }
}
