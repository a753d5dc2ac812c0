//! StatusResponse (`specs/powerlink.md` §3.6, ASnd service 2): CN -> all, dst 255, at least
//! 72 bytes: flags, PR/RS, NMT state, the 8-byte static error bit field and 20-byte
//! error/event entries up to the end of the frame.
//!
//! ASnd has no length field, so the entry list is taken to end at the last entry that is not
//! all zero; the two entry slots of the 72-byte minimum frame are always written (zero-filled)
//! on encode, and a decoded frame shorter than 72 bytes is rejected.

use serde::{Deserialize, Serialize};

use crate::codes::NmtState;
use crate::error::{DecodeError, EncodeError};
use crate::flags::{Flags, PrRs};
use crate::soc::NetTime;
use crate::wire::{is_zero, Rd};

/// Offset of the first entry counted from the message type byte (frame byte 32).
const ENTRIES_OFFSET: usize = 18;
/// Size of one error/event entry.
pub const ENTRY_LEN: usize = 20;
/// Entry slots of the minimum (72-byte) StatusResponse.
const MIN_ENTRIES: usize = 2;

/// One error/event entry of a StatusResponse.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct StatusEntry {
    /// Entry type.
    pub entry_type: u16,
    /// Error code.
    pub code: u16,
    /// Time stamp (NetTime).
    pub time: NetTime,
    /// Additional information.
    pub info: u64,
}

/// A StatusResponse body (frame bytes 18..).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct StatusResponse {
    /// Flags: 0x10 EN, 0x08 EC.
    pub flags: Flags,
    /// PR / RS.
    pub pr_rs: PrRs,
    /// NMT state of the sender.
    pub nmt_state: NmtState,
    /// Static error bit field (byte 0 = ErrorRegister 0x1001).
    pub static_errors: [u8; 8],
    /// The entries, up to the last one that is not all zero.
    #[serde(default)]
    pub entries: Vec<StatusEntry>,
    /// Frame bytes 21..24 (reserved).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub reserved: [u8; 3],
}

impl StatusResponse {
    pub(crate) fn decode(rd: &Rd<'_>) -> Result<(Self, usize), DecodeError> {
        rd.need(ENTRIES_OFFSET + MIN_ENTRIES * ENTRY_LEN)?;
        let count = rd.buf.len().saturating_sub(ENTRIES_OFFSET) / ENTRY_LEN;
        let mut entries = Vec::with_capacity(count);
        for i in 0..count {
            let o = ENTRIES_OFFSET + i * ENTRY_LEN;
            entries.push(StatusEntry {
                entry_type: rd.u16(o)?,
                code: rd.u16(o + 2)?,
                time: NetTime::decode(rd, o + 4)?,
                info: rd.u64(o + 12)?,
            });
        }
        while entries.last().is_some_and(|e| *e == StatusEntry::default()) {
            entries.pop();
        }
        let slots = entries.len().max(MIN_ENTRIES);
        let status = StatusResponse {
            flags: Flags::from_bits_retain(rd.u8(4)?),
            pr_rs: PrRs::from_raw(rd.u8(5)?),
            nmt_state: NmtState::from_raw(rd.u8(6)?),
            reserved: rd.array::<3>(7)?,
            static_errors: rd.array::<8>(10)?,
            entries,
        };
        Ok((status, ENTRIES_OFFSET + slots * ENTRY_LEN))
    }

    pub(crate) fn encode_into(&self, out: &mut Vec<u8>) -> Result<(), EncodeError> {
        out.extend_from_slice(&[self.flags.bits(), self.pr_rs.raw()?, self.nmt_state.raw()]);
        out.extend_from_slice(&self.reserved);
        out.extend_from_slice(&self.static_errors);
        for e in &self.entries {
            out.extend_from_slice(&e.entry_type.to_le_bytes());
            out.extend_from_slice(&e.code.to_le_bytes());
            e.time.encode_into(out);
            out.extend_from_slice(&e.info.to_le_bytes());
        }
        let missing = MIN_ENTRIES.saturating_sub(self.entries.len());
        out.resize(out.len() + missing * ENTRY_LEN, 0);
        Ok(())
    }
}
