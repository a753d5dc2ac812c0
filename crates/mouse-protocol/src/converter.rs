//! The converter packet: what the ATmega PS/2 -> RS-232 converter under the robot sends
//! (seed 000, appendix 1; digest `specs/omni-robot.md`, "Optical-mouse odometry sensor").
//!
//! ```text
//! byte 0   'a' (0x61)  start
//! byte 1   device type: 'i' Microsoft-protocol mouse, 'm' Mouse Systems mouse,
//!          'n' nothing connected, 'd' unknown device, 'k' keyboard
//! byte 2   X1  \ x increment: X1:X2 is a little-endian signed 16-bit count
//! byte 3   X2  /   (X2 = 0x00 for positive, 0xFF "-1" for negative, i.e. the sign
//!                   extension of PS/2's 9-bit movement)
//! byte 4   Y1  \ y increment, same layout
//! byte 5   Y2  /
//! byte 6   'x' (0x78)  end
//! ```
//!
//! The line is 9600 bit/s, 8N1, one-way (converter -> PLC): 7 bytes take 7.29 ms.
//! [`ConverterStream`] finds `'a'` anywhere in the byte stream: a candidate whose seventh
//! byte is not `'x'` is a false start, and only its `'a'` is dropped, so a false `'a'`
//! inside garbage never hides a real packet that starts within the next six bytes —
//! unless that false candidate happens to end in `'x'` (e.g. `'a'` two bytes before a
//! packet whose Y1 is 120): such a candidate is a valid packet on the wire and cannot be
//! told apart; the packets after it are found again by the same rule.

use serde::{Deserialize, Serialize};

use crate::error::PacketError;
use motus_wire::Stream;

use crate::scan::PacketScanner;

/// Bytes in one converter packet.
pub const PACKET_LEN: usize = 7;
/// First byte of a packet.
pub const START: u8 = b'a';
/// Last byte of a packet.
pub const END: u8 = b'x';

/// What the converter reports is plugged into its PS/2 port (byte 1). Total: a byte the
/// spec does not list is kept as [`DeviceType::Unknown`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(tag = "type", content = "code", rename_all = "snake_case")]
pub enum DeviceType {
    /// `'i'`: a mouse speaking the Microsoft protocol (the default).
    #[default]
    Microsoft,
    /// `'m'`: a mouse speaking the Mouse Systems protocol.
    MouseSystems,
    /// `'n'`: nothing connected.
    Nothing,
    /// `'d'`: an unknown device.
    UnknownDevice,
    /// `'k'`: a keyboard.
    Keyboard,
    /// Any other byte.
    Unknown(u8),
}

impl DeviceType {
    /// The device type of a wire byte.
    #[must_use]
    pub fn from_byte(b: u8) -> DeviceType {
        match b {
            b'i' => DeviceType::Microsoft,
            b'm' => DeviceType::MouseSystems,
            b'n' => DeviceType::Nothing,
            b'd' => DeviceType::UnknownDevice,
            b'k' => DeviceType::Keyboard,
            other => DeviceType::Unknown(other),
        }
    }

    /// The wire byte.
    #[must_use]
    pub fn to_byte(self) -> u8 {
        match self {
            DeviceType::Microsoft => b'i',
            DeviceType::MouseSystems => b'm',
            DeviceType::Nothing => b'n',
            DeviceType::UnknownDevice => b'd',
            DeviceType::Keyboard => b'k',
            DeviceType::Unknown(b) => b,
        }
    }

    /// True for the two mouse types, whose counts are motion.
    #[must_use]
    pub fn is_mouse(self) -> bool {
        matches!(self, DeviceType::Microsoft | DeviceType::MouseSystems)
    }
}

/// One converter packet: the device type and the counts since the previous packet.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct ConverterPacket {
    /// What is connected.
    pub device: DeviceType,
    /// x counts (X1:X2).
    pub dx: i16,
    /// y counts (Y1:Y2).
    pub dy: i16,
}

impl ConverterPacket {
    /// A packet from a Microsoft-protocol mouse (device type `'i'`).
    #[must_use]
    pub fn motion(dx: i16, dy: i16) -> ConverterPacket {
        ConverterPacket { device: DeviceType::Microsoft, dx, dy }
    }

    /// The 7 wire bytes.
    #[must_use]
    pub fn encode(&self) -> [u8; PACKET_LEN] {
        let [x1, x2] = self.dx.to_le_bytes();
        let [y1, y2] = self.dy.to_le_bytes();
        [START, self.device.to_byte(), x1, x2, y1, y2, END]
    }

    /// Decodes exactly one packet.
    ///
    /// # Errors
    /// [`PacketError::Length`] unless `bytes` is 7 bytes long, [`PacketError::Start`] /
    /// [`PacketError::End`] for a wrong first / last byte. Any X2/Y2 is accepted (the
    /// counts are read as signed 16-bit values).
    pub fn decode(bytes: &[u8]) -> Result<ConverterPacket, PacketError> {
        let arr: &[u8; PACKET_LEN] = bytes
            .try_into()
            .map_err(|_| PacketError::Length { expected: PACKET_LEN, received: bytes.len() })?;
        let [start, device, x1, x2, y1, y2, end] = *arr;
        if start != START {
            return Err(PacketError::Start(start));
        }
        if end != END {
            return Err(PacketError::End(end));
        }
        Ok(ConverterPacket {
            device: DeviceType::from_byte(device),
            dx: i16::from_le_bytes([x1, x2]),
            dy: i16::from_le_bytes([y1, y2]),
        })
    }

    /// True when X2 and Y2 are pure sign bytes (0x00 or 0xFF), i.e. the counts fit PS/2's
    /// 9-bit range -256..=255 as the real converter sends them.
    #[must_use]
    pub fn fits_ps2_range(&self) -> bool {
        (-256..=255).contains(&self.dx) && (-256..=255).contains(&self.dy)
    }
}

/// Streaming decoder for the converter's byte stream (bytes pushed in arbitrary chunks;
/// `ConverterStream::default()`): a false start drops its `'a'` only. At most 6 bytes of an
/// incomplete candidate are pending; [`motus_wire::Stream::clear`] drops them (e.g. after
/// a line time-out), counted as garbage.
pub type ConverterStream = Stream<PacketScanner<ConverterPacket>>;

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn hand_computed_vectors() {
        // Computed by hand from specs/omni-robot.md, "converter packet, 7 bytes":
        // 'a'=0x61, 'i'=0x69, X1:X2 = +100 = 0x64 0x00, Y1:Y2 = -1 = 0xFF 0xFF, 'x'=0x78.
        let bytes = [0x61, 0x69, 0x64, 0x00, 0xFF, 0xFF, 0x78];
        let p = ConverterPacket::decode(&bytes).unwrap();
        assert_eq!(p, ConverterPacket::motion(100, -1));
        assert_eq!(p.encode(), bytes);
        // -200 = 0xFF38 (X1 = 0x38, X2 = 0xFF: "direction -1"), +255 = 0x00FF; keyboard 'k'.
        let bytes = [0x61, 0x6B, 0x38, 0xFF, 0xFF, 0x00, 0x78];
        let p = ConverterPacket::decode(&bytes).unwrap();
        assert_eq!(p, ConverterPacket { device: DeviceType::Keyboard, dx: -200, dy: 255 });
        assert!(p.fits_ps2_range());
        // Unknown device byte 'z' is kept raw.
        let p = ConverterPacket::decode(&[0x61, b'z', 0, 0, 0, 0, 0x78]).unwrap();
        assert_eq!(p.device, DeviceType::Unknown(b'z'));
        assert_eq!(p.encode()[1], b'z');
    }

    #[test]
    fn typed_errors() {
        assert_eq!(
            ConverterPacket::decode(&[0x61, 0x69, 0, 0, 0, 0]),
            Err(PacketError::Length { expected: 7, received: 6 })
        );
        assert_eq!(ConverterPacket::decode(&[0x62, 0x69, 0, 0, 0, 0, 0x78]), Err(PacketError::Start(0x62)));
        assert_eq!(ConverterPacket::decode(&[0x61, 0x69, 0, 0, 0, 0, 0x79]), Err(PacketError::End(0x79)));
    }

    #[test]
    fn device_bytes_round_trip() {
        for b in 0..=255u8 {
            assert_eq!(DeviceType::from_byte(b).to_byte(), b);
        }
        assert!(DeviceType::Microsoft.is_mouse() && !DeviceType::Nothing.is_mouse());
    }

    #[test]
    fn stream_skips_garbage_and_false_starts() {
        let good = ConverterPacket::motion(3, -4).encode();
        // Garbage with a false 'a' two bytes before a real packet: the candidate starting
        // at the false 'a' ends at good[4], not 'x', so only that 'a' is dropped.
        let mut bytes = vec![0x00, 0x13, b'a', 0x55];
        bytes.extend_from_slice(&good);
        bytes.extend_from_slice(b"aa");
        let mut s = ConverterStream::default();
        let mut got = Vec::new();
        for chunk in bytes.chunks(3) {
            s.push(chunk);
            got.extend(std::iter::from_fn(|| s.next_frame()));
        }
        assert_eq!(got, vec![ConverterPacket::motion(3, -4)]);
        assert_eq!((s.stats().frames, s.stats().garbage_bytes), (1, 4));
        assert_eq!(s.pending(), 2);
        s.clear();
        assert_eq!(s.stats().garbage_bytes, 6);
    }

    #[test]
    fn counts_containing_start_and_end_bytes() {
        // dx = 0x7861 has X1 = 'a' and X2 = 'x'; dy = 0x6178 likewise.
        let p = ConverterPacket::motion(0x7861, 0x6178);
        let mut s = ConverterStream::default();
        let mut bytes = p.encode().to_vec();
        bytes.extend_from_slice(&p.encode());
        s.push(&bytes);
        assert_eq!(std::iter::from_fn(|| s.next_frame()).collect::<Vec<_>>(), vec![p, p]);
    }
}
