//! Poll Request (`specs/powerlink.md` §3.3): MN -> one CN, unicast MAC, src 240,
//! dst = the CN. Payload (RPDO data for the CN) from frame byte 24, `size` bytes.

use serde::{Deserialize, Serialize};

use crate::error::{DecodeError, EncodeError};
use crate::flags::Flags;
use crate::wire::{is_zero, Rd};
use crate::PDO_PAYLOAD_OFFSET;

/// A Poll Request.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct PReq {
    /// Flags: MS 0x20, EA 0x04, RD 0x01.
    pub flags: Flags,
    /// PDO version (high nibble main, low nibble sub).
    pub pdo_version: u8,
    /// The payload (its length is the size field).
    pub payload: Vec<u8>,
    /// Frame byte 19: reserved in the spec; newer wireshark shows 0x80 FLS, 0x40 SLS here.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub flags2: u8,
    /// Frame byte 17 (reserved).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub reserved1: u8,
    /// Frame byte 21 (reserved).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub reserved2: u8,
}

/// Reads the size field at EPL+8 and the payload that follows; shared with PRes.
pub(crate) fn decode_payload(rd: &Rd<'_>) -> Result<(Vec<u8>, usize), DecodeError> {
    rd.need(PDO_PAYLOAD_OFFSET)?;
    let size = rd.u16(8)?;
    let end = PDO_PAYLOAD_OFFSET + usize::from(size);
    let payload = rd.buf.get(PDO_PAYLOAD_OFFSET..end).ok_or(DecodeError::PayloadBeyondFrame {
        what: rd.what,
        size,
        offset: rd.base + PDO_PAYLOAD_OFFSET,
        frame_len: rd.base + rd.buf.len(),
    })?;
    Ok((payload.to_vec(), end))
}

/// Writes the size field and the payload; shared with PRes.
pub(crate) fn encode_payload(
    out: &mut Vec<u8>,
    what: &'static str,
    payload: &[u8],
) -> Result<(), EncodeError> {
    let size = u16::try_from(payload.len()).map_err(|_| EncodeError::TooLong {
        field: what,
        got: payload.len(),
        max: usize::from(u16::MAX),
    })?;
    out.extend_from_slice(&size.to_le_bytes());
    out.extend_from_slice(payload);
    Ok(())
}

impl PReq {
    pub(crate) fn decode(rd: &Rd<'_>) -> Result<(Self, usize), DecodeError> {
        let (payload, end) = decode_payload(rd)?;
        let preq = PReq {
            reserved1: rd.u8(3)?,
            flags: Flags::from_bits_retain(rd.u8(4)?),
            flags2: rd.u8(5)?,
            pdo_version: rd.u8(6)?,
            reserved2: rd.u8(7)?,
            payload,
        };
        Ok((preq, end))
    }

    pub(crate) fn encode_into(&self, out: &mut Vec<u8>) -> Result<(), EncodeError> {
        out.extend_from_slice(&[
            self.reserved1,
            self.flags.bits(),
            self.flags2,
            self.pdo_version,
            self.reserved2,
        ]);
        encode_payload(out, "PReq payload", &self.payload)
    }
}
