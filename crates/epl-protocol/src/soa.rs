//! Start of Asynchronous phase (`specs/powerlink.md` §3.5): MN -> all, src 240, dst 255,
//! MAC 01:11:1E:00:00:03, 54 bytes without padding. Bytes 24..54 carry the SyncRequest
//! fields when the requested service is SyncRequest (0x06) and are zero otherwise.

use serde::{Deserialize, Serialize};

use crate::codes::{NmtState, RequestedService};
use crate::error::DecodeError;
use crate::ethernet::MacAddr;
use crate::flags::Flags;
use crate::wire::{is_zero, Rd};

/// Length of a SoA counted from the message type byte (frame bytes 14..54).
pub const SOA_LEN: usize = 40;
/// Offset of the SyncRequest area counted from the message type byte (frame byte 24).
const SYNC_OFFSET: usize = 10;

/// The SyncRequest fields of a SoA (frame bytes 24..54), all little-endian u32 except the MAC.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct SyncRequest {
    /// SyncControl.
    pub sync_control: u32,
    /// PResTimeFirst (ns).
    pub pres_time_first: u32,
    /// PResTimeSecond (ns).
    pub pres_time_second: u32,
    /// SyncMNDelayFirst (ns).
    pub sync_mn_delay_first: u32,
    /// SyncMNDelaySecond (ns).
    pub sync_mn_delay_second: u32,
    /// PResFallBackTimeout (ns).
    pub pres_fallback_timeout: u32,
    /// DestMacAddress.
    pub dest_mac: MacAddr,
}

impl SyncRequest {
    fn decode(rd: &Rd<'_>) -> Result<Self, DecodeError> {
        let o = SYNC_OFFSET;
        Ok(Self {
            sync_control: rd.u32(o)?,
            pres_time_first: rd.u32(o + 4)?,
            pres_time_second: rd.u32(o + 8)?,
            sync_mn_delay_first: rd.u32(o + 12)?,
            sync_mn_delay_second: rd.u32(o + 16)?,
            pres_fallback_timeout: rd.u32(o + 20)?,
            dest_mac: MacAddr(rd.array::<6>(o + 24)?),
        })
    }

    fn encode_into(&self, out: &mut Vec<u8>) {
        for v in [
            self.sync_control,
            self.pres_time_first,
            self.pres_time_second,
            self.sync_mn_delay_first,
            self.sync_mn_delay_second,
            self.pres_fallback_timeout,
        ] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&self.dest_mac.0);
    }
}

/// A Start of Asynchronous phase message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Soa {
    /// NMT state of the MN.
    pub nmt_state: NmtState,
    /// Flags: EA 0x04, ER 0x02.
    pub flags: Flags,
    /// RequestedServiceID.
    pub requested_service: RequestedService,
    /// RequestedServiceTarget: the node allowed to send in the async slot (0 if none).
    pub target: u8,
    /// EPLVersion (0x20 = V2.0).
    pub epl_version: u8,
    /// Flag byte 3: 0x01 MR (MN redundancy); other bits kept raw.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub flags3: u8,
    /// SyncRequest fields: present for a SyncRequest, or when frame bytes 24..54 are not all
    /// zero (kept so that re-encoding gives the same bytes). `None` encodes as 30 zero bytes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sync_request: Option<SyncRequest>,
    /// Frame byte 19 (reserved).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub reserved: u8,
}

impl Soa {
    /// A SoA from the MN in `nmt_state` inviting `target` to `service` (EPL version 0x20).
    pub fn new(nmt_state: NmtState, requested_service: RequestedService, target: u8) -> Self {
        Self {
            nmt_state,
            flags: Flags::empty(),
            requested_service,
            target,
            epl_version: 0x20,
            flags3: 0,
            sync_request: None,
            reserved: 0,
        }
    }

    pub(crate) fn decode(rd: &Rd<'_>) -> Result<(Self, usize), DecodeError> {
        rd.need(SOA_LEN)?;
        let requested_service = RequestedService::from_raw(rd.u8(6)?);
        let sync_area = rd.bytes(SYNC_OFFSET, SOA_LEN - SYNC_OFFSET)?;
        let sync_request =
            if requested_service == RequestedService::SyncRequest || sync_area.iter().any(|&b| b != 0) {
                Some(SyncRequest::decode(rd)?)
            } else {
                None
            };
        let soa = Soa {
            nmt_state: NmtState::from_raw(rd.u8(3)?),
            flags: Flags::from_bits_retain(rd.u8(4)?),
            reserved: rd.u8(5)?,
            requested_service,
            target: rd.u8(7)?,
            epl_version: rd.u8(8)?,
            flags3: rd.u8(9)?,
            sync_request,
        };
        Ok((soa, SOA_LEN))
    }

    pub(crate) fn encode_into(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&[
            self.nmt_state.raw(),
            self.flags.bits(),
            self.reserved,
            self.requested_service.raw(),
            self.target,
            self.epl_version,
            self.flags3,
        ]);
        match &self.sync_request {
            Some(s) => s.encode_into(out),
            None => out.resize(out.len() + SOA_LEN - SYNC_OFFSET, 0),
        }
    }
}
