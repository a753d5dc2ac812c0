//! Poll Response (`specs/powerlink.md` §3.4): CN -> all, multicast 01:11:1E:00:00:02,
//! src = the CN (or 240 for a PResMN), dst 255. Payload (TPDO data) from frame byte 24.

use serde::{Deserialize, Serialize};

use crate::codes::NmtState;
use crate::error::{DecodeError, EncodeError};
use crate::flags::{Flags, PrRs};
use crate::preq::{decode_payload, encode_payload};
use crate::wire::{is_zero, Rd};

/// A Poll Response.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct PRes {
    /// NMT state of the sender.
    pub nmt_state: NmtState,
    /// Flags: MS 0x20, EN 0x10, RD 0x01.
    pub flags: Flags,
    /// PR / RS (and link-status bits).
    pub pr_rs: PrRs,
    /// PDO version (high nibble main, low nibble sub).
    pub pdo_version: u8,
    /// The payload (its length is the size field).
    pub payload: Vec<u8>,
    /// Frame byte 21 (reserved).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub reserved: u8,
}

impl PRes {
    /// True when the payload may be trusted as process data: RD set and the sender
    /// OPERATIONAL (`specs/powerlink.md` §7, "Validity for a supervisor").
    pub fn is_valid_data(&self) -> bool {
        self.flags.contains(Flags::RD) && self.nmt_state == NmtState::Operational
    }

    pub(crate) fn decode(rd: &Rd<'_>) -> Result<(Self, usize), DecodeError> {
        let (payload, end) = decode_payload(rd)?;
        let pres = PRes {
            nmt_state: NmtState::from_raw(rd.u8(3)?),
            flags: Flags::from_bits_retain(rd.u8(4)?),
            pr_rs: PrRs::from_raw(rd.u8(5)?),
            pdo_version: rd.u8(6)?,
            reserved: rd.u8(7)?,
            payload,
        };
        Ok((pres, end))
    }

    pub(crate) fn encode_into(&self, out: &mut Vec<u8>) -> Result<(), EncodeError> {
        out.extend_from_slice(&[
            self.nmt_state.raw(),
            self.flags.bits(),
            self.pr_rs.raw()?,
            self.pdo_version,
            self.reserved,
        ]);
        encode_payload(out, "PRes payload", &self.payload)
    }
}
