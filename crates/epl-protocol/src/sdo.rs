//! SDO over ASnd (`specs/powerlink.md` §3.6, ASnd service 5): the sequence layer (frame
//! bytes 18..22) and the command layer (22..30) followed by `segment_size` data bytes.

use serde::{Deserialize, Serialize};

use crate::codes::SdoCommandId;
use crate::error::{DecodeError, EncodeError};
use crate::wire::{check_max, is_zero, Rd};

/// Offset of the command layer counted from the message type byte (frame byte 22).
const COMMAND_OFFSET: usize = 8;
/// Offset of the command-layer data counted from the message type byte (frame byte 30).
const DATA_OFFSET: usize = 16;

/// The SDO command layer.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SdoCommand {
    /// Transaction ID.
    pub transaction_id: u8,
    /// 0x80: this is a response.
    pub response: bool,
    /// 0x40: transfer aborted (data = abort code).
    pub abort: bool,
    /// Segmentation (0 expedited, 1 initiate, 2 segment, 3 complete).
    pub segmentation: u8,
    /// Pad size (0-3).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub pad_size: u8,
    /// Command ID.
    pub command_id: SdoCommandId,
    /// Segment size field. For frames built by hand set it to `data.len()`; decoded frames
    /// keep the wire value even where it disagrees with the data present.
    pub segment_size: u16,
    /// Command data (`segment_size` bytes, fewer if the frame ends first).
    #[serde(default)]
    pub data: Vec<u8>,
    /// Flag bits 0x0C (unassigned), shifted down (0-3).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub flags_reserved: u8,
    /// Frame byte 22 (reserved).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub reserved1: u8,
    /// Frame bytes 28..30 (reserved).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub reserved2: u16,
}

impl SdoCommand {
    /// Index, subindex and value of a (Write/Read)ByIndex request (data = index u16,
    /// subindex u8, reserved u8, value).
    pub fn by_index(&self) -> Option<(u16, u8, &[u8])> {
        let by_index = matches!(self.command_id, SdoCommandId::WriteByIndex | SdoCommandId::ReadByIndex);
        if !by_index || self.response || self.abort {
            return None;
        }
        let (head, value) = self.data.split_at_checked(4)?;
        let [i0, i1, sub, _] = <[u8; 4]>::try_from(head).ok()?;
        Some((u16::from_le_bytes([i0, i1]), sub, value))
    }

    /// The abort code of an aborted transfer (first four data bytes, LE).
    pub fn abort_code(&self) -> Option<u32> {
        if !self.abort {
            return None;
        }
        let b: [u8; 4] = self.data.get(..4)?.try_into().ok()?;
        Some(u32::from_le_bytes(b))
    }
}

/// An SDO ASnd body: the sequence layer and, when the frame is long enough, the command layer.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SdoFrame {
    /// Receive sequence number (0-63).
    pub receive_sequence: u8,
    /// Receive connection state (0 none, 1 initialization, 2 valid, 3 retransmission/error).
    pub receive_con: u8,
    /// Send sequence number (0-63).
    pub send_sequence: u8,
    /// Send connection state (0-3).
    pub send_con: u8,
    /// Command layer (absent when the frame ends before frame byte 30).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub command: Option<SdoCommand>,
    /// Frame bytes 20..22 (reserved).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub reserved: u16,
}

impl SdoFrame {
    pub(crate) fn decode(rd: &Rd<'_>) -> Result<(Self, usize), DecodeError> {
        rd.need(COMMAND_OFFSET)?;
        let r = rd.u8(4)?;
        let s = rd.u8(5)?;
        let (command, end) = if rd.buf.len() >= DATA_OFFSET {
            let flags = rd.u8(10)?;
            let segment_size = rd.u16(12)?;
            let data_end = (DATA_OFFSET + usize::from(segment_size)).min(rd.buf.len());
            let data = rd.bytes(DATA_OFFSET, data_end - DATA_OFFSET)?.to_vec();
            let cmd = SdoCommand {
                reserved1: rd.u8(8)?,
                transaction_id: rd.u8(9)?,
                response: flags & 0x80 != 0,
                abort: flags & 0x40 != 0,
                segmentation: (flags >> 4) & 0x03,
                flags_reserved: (flags >> 2) & 0x03,
                pad_size: flags & 0x03,
                command_id: SdoCommandId::from_raw(rd.u8(11)?),
                segment_size,
                reserved2: rd.u16(14)?,
                data,
            };
            (Some(cmd), data_end)
        } else {
            (None, COMMAND_OFFSET)
        };
        let sdo = SdoFrame {
            receive_sequence: r >> 2,
            receive_con: r & 0x03,
            send_sequence: s >> 2,
            send_con: s & 0x03,
            reserved: rd.u16(6)?,
            command,
        };
        Ok((sdo, end))
    }

    pub(crate) fn encode_into(&self, out: &mut Vec<u8>) -> Result<(), EncodeError> {
        check_max("SDO receive_sequence", self.receive_sequence.into(), 63)?;
        check_max("SDO send_sequence", self.send_sequence.into(), 63)?;
        check_max("SDO receive_con", self.receive_con.into(), 3)?;
        check_max("SDO send_con", self.send_con.into(), 3)?;
        out.push(self.receive_sequence << 2 | self.receive_con);
        out.push(self.send_sequence << 2 | self.send_con);
        out.extend_from_slice(&self.reserved.to_le_bytes());
        if let Some(c) = &self.command {
            check_max("SDO segmentation", c.segmentation.into(), 3)?;
            check_max("SDO pad_size", c.pad_size.into(), 3)?;
            check_max("SDO flags_reserved", c.flags_reserved.into(), 3)?;
            let flags = u8::from(c.response) << 7
                | u8::from(c.abort) << 6
                | c.segmentation << 4
                | c.flags_reserved << 2
                | c.pad_size;
            out.extend_from_slice(&[c.reserved1, c.transaction_id, flags, c.command_id.raw()]);
            out.extend_from_slice(&c.segment_size.to_le_bytes());
            out.extend_from_slice(&c.reserved2.to_le_bytes());
            if c.data.len() > usize::from(c.segment_size) {
                return Err(EncodeError::TooLong {
                    field: "SDO data (beyond segment_size)",
                    got: c.data.len(),
                    max: c.segment_size.into(),
                });
            }
            out.extend_from_slice(&c.data);
        }
        Ok(())
    }
}
