//! Asynchronous Send (`specs/powerlink.md` §3.6): ServiceID at frame byte 17, then the
//! service body. Known services are decoded ([`IdentResponse`], [`StatusResponse`],
//! [`NmtRequest`], [`NmtCommand`], [`SdoFrame`]); others are kept raw.
//!
//! ASnd has no length field. Where a service's data area has no stated length (NMT command
//! and request data, unknown services), trailing zero bytes are treated as Ethernet padding
//! (see [`crate::Padding`]), so the decoded data ends at its last non-zero byte.

use serde::{Deserialize, Serialize};

use crate::codes::NmtCommandId;
use crate::error::{DecodeError, EncodeError};
use crate::ident::IdentResponse;
use crate::sdo::SdoFrame;
use crate::status::StatusResponse;
use crate::wire::{is_zero, trim_zeros, Rd};

/// Offset of NMT command/request data counted from the message type byte (frame byte 20).
const NMT_DATA_OFFSET: usize = 6;
/// Room for NMT command/request data (frame bytes 20..52).
pub const NMT_DATA_LEN: usize = 32;

/// NMTCommand body (service 4, MN -> CN or broadcast).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct NmtCommand {
    /// Command ID (frame byte 18).
    pub command: NmtCommandId,
    /// Command data (frame bytes 20..52, trailing zeros dropped).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub data: Vec<u8>,
    /// Frame byte 19 (reserved).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub reserved: u8,
}

/// NMTRequest body (service 3, CN -> MN after an NMTRequestInvite).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct NmtRequest {
    /// Requested command ID (frame byte 18).
    pub command: NmtCommandId,
    /// Target node (frame byte 19).
    pub target: u8,
    /// Command data (frame bytes 20..52, trailing zeros dropped).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub data: Vec<u8>,
}

/// An ASnd message, by service.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "service", rename_all = "snake_case")]
pub enum Asnd {
    /// 0x01 IdentResponse.
    IdentResponse(IdentResponse),
    /// 0x02 StatusResponse.
    StatusResponse(StatusResponse),
    /// 0x03 NMTRequest.
    NmtRequest(NmtRequest),
    /// 0x04 NMTCommand.
    NmtCommand(NmtCommand),
    /// 0x05 SDO.
    Sdo(SdoFrame),
    /// Any other service (SyncResponse 0x06, manufacturer-specific 0xA0..=0xFE...), raw.
    Other {
        /// ServiceID.
        service_id: u8,
        /// Body (frame bytes 18.., trailing zeros dropped).
        #[serde(default)]
        data: Vec<u8>,
    },
}

fn nmt_data(rd: &Rd<'_>) -> Vec<u8> {
    let area = rd.rest(NMT_DATA_OFFSET);
    trim_zeros(area.get(..NMT_DATA_LEN).unwrap_or(area)).to_vec()
}

impl Asnd {
    /// The ServiceID byte.
    pub fn service_id(&self) -> u8 {
        match self {
            Asnd::IdentResponse(_) => 0x01,
            Asnd::StatusResponse(_) => 0x02,
            Asnd::NmtRequest(_) => 0x03,
            Asnd::NmtCommand(_) => 0x04,
            Asnd::Sdo(_) => 0x05,
            Asnd::Other { service_id, .. } => *service_id,
        }
    }

    pub(crate) fn decode(rd: &Rd<'_>) -> Result<(Self, usize), DecodeError> {
        rd.need(4)?;
        let service_id = rd.u8(3)?;
        let with = |what| Rd { what, ..*rd };
        Ok(match service_id {
            0x01 => {
                let (b, n) = IdentResponse::decode(&with("ASnd IdentResponse"))?;
                (Asnd::IdentResponse(b), n)
            }
            0x02 => {
                let (b, n) = StatusResponse::decode(&with("ASnd StatusResponse"))?;
                (Asnd::StatusResponse(b), n)
            }
            0x03 => {
                let rd = with("ASnd NMTRequest");
                rd.need(NMT_DATA_OFFSET)?;
                let data = nmt_data(&rd);
                let n = NMT_DATA_OFFSET + data.len();
                (
                    Asnd::NmtRequest(NmtRequest {
                        command: NmtCommandId::from_raw(rd.u8(4)?),
                        target: rd.u8(5)?,
                        data,
                    }),
                    n,
                )
            }
            0x04 => {
                let rd = with("ASnd NMTCommand");
                rd.need(NMT_DATA_OFFSET)?;
                let data = nmt_data(&rd);
                let n = NMT_DATA_OFFSET + data.len();
                (
                    Asnd::NmtCommand(NmtCommand {
                        command: NmtCommandId::from_raw(rd.u8(4)?),
                        reserved: rd.u8(5)?,
                        data,
                    }),
                    n,
                )
            }
            0x05 => {
                let (b, n) = SdoFrame::decode(&with("ASnd SDO"))?;
                (Asnd::Sdo(b), n)
            }
            _ => {
                let data = trim_zeros(rd.rest(4)).to_vec();
                let n = 4 + data.len();
                (Asnd::Other { service_id, data }, n)
            }
        })
    }

    pub(crate) fn encode_into(&self, out: &mut Vec<u8>) -> Result<(), EncodeError> {
        out.push(self.service_id());
        match self {
            Asnd::IdentResponse(b) => b.encode_into(out),
            Asnd::StatusResponse(b) => b.encode_into(out),
            Asnd::NmtRequest(b) => {
                out.extend_from_slice(&[b.command.raw(), b.target]);
                put_data(out, &b.data)
            }
            Asnd::NmtCommand(b) => {
                out.extend_from_slice(&[b.command.raw(), b.reserved]);
                put_data(out, &b.data)
            }
            Asnd::Sdo(b) => b.encode_into(out),
            Asnd::Other { data, .. } => {
                out.extend_from_slice(data);
                Ok(())
            }
        }
    }
}

/// NMT data: at most 32 bytes, written as given (padding follows from [`crate::Padding`]).
fn put_data(out: &mut Vec<u8>, data: &[u8]) -> Result<(), EncodeError> {
    if data.len() > NMT_DATA_LEN {
        return Err(EncodeError::TooLong { field: "NMT data", got: data.len(), max: NMT_DATA_LEN });
    }
    out.extend_from_slice(data);
    Ok(())
}
