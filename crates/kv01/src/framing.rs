//! Finding a KV-01 reply in received bytes for the bus master: delimited by LENGTH (or the
//! fixed 4-byte short form), never by scanning for 0xF0.

use motus_kv01_protocol::{
    decode_message, Address, CrcMode, DecodeError, Decoded, Direction, END, SHORT_LEN,
};
use motus_serial::FrameScan;

/// Looks for one module -> host message at the start of `buf`.
pub fn scan_reply(buf: &[u8], mode: CrcMode) -> FrameScan<Decoded> {
    let Some(&addr) = buf.first() else { return FrameScan::Incomplete };
    if Address::new(addr).is_none() {
        return FrameScan::Skip { corrupt: false };
    }
    let Some(&second) = buf.get(1) else { return FrameScan::Incomplete };
    if second.is_ascii_uppercase() {
        match (buf.get(2), buf.get(3)) {
            (Some(c), Some(&END)) if c.is_ascii_uppercase() => {
                return match decode_message(buf.get(..SHORT_LEN).unwrap_or(&[]), Direction::FromModule, mode)
                {
                    Ok(frame) => FrameScan::Frame { frame, len: SHORT_LEN },
                    Err(_) => FrameScan::Skip { corrupt: true },
                };
            }
            (None, _) | (Some(_), None) => return FrameScan::Incomplete,
            _ => {}
        }
    }
    let len = usize::from(second);
    if len < motus_kv01_protocol::MIN_STANDARD_LEN {
        return FrameScan::Skip { corrupt: false };
    }
    let Some(frame) = buf.get(..len) else { return FrameScan::Incomplete };
    match decode_message(frame, Direction::FromModule, mode) {
        Ok(frame) => FrameScan::Frame { frame, len },
        Err(DecodeError::Crc { .. }) => FrameScan::Skip { corrupt: true },
        Err(_) => FrameScan::Skip { corrupt: false },
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use motus_kv01_protocol::{Message, Reply, ReplyBody, ShortCode};

    #[test]
    fn finds_replies_after_garbage_and_short_messages() {
        let a = Address::joint(2).unwrap();
        let ok =
            Message::Reply(Reply::new(a, ReplyBody::Short { text: ShortCode::Timeout })).encode().unwrap();
        assert!(matches!(scan_reply(&ok, CrcMode::Strict), FrameScan::Frame { len: 4, .. }));
        assert!(matches!(scan_reply(&[0x00, 0xE2], CrcMode::Strict), FrameScan::Skip { corrupt: false }));
        assert!(matches!(scan_reply(&ok[..2], CrcMode::Strict), FrameScan::Incomplete));
        // The source's example reply fails the published CRC: corrupt in strict mode.
        let example = [0xE2, 0x07, 0xD0, 0x4F, 0x4B, 0xB5, 0xF0];
        assert!(matches!(scan_reply(&example, CrcMode::Strict), FrameScan::Skip { corrupt: true }));
        assert!(matches!(scan_reply(&example, CrcMode::Lenient), FrameScan::Frame { len: 7, .. }));
    }
}
