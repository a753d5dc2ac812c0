//! Flag bytes (`specs/powerlink.md` §4.1): the shared flag-1 bits ([`Flags`]) and the
//! PR/RS byte of PRes, StatusResponse and IdentResponse ([`PrRs`]).

use serde::{Deserialize, Serialize};

use crate::error::EncodeError;
use crate::wire::check_max;

bitflags::bitflags! {
    /// Flag byte 1 (frame byte 18 of SoC, PReq, PRes, SoA, StatusResponse, IdentResponse).
    /// Each message uses some of the bits; unknown bits are kept. JSON: `"RD | EN"`.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
    pub struct Flags: u8 {
        /// 0x01 RD ready: the payload is valid (PReq, PRes).
        const RD = 0x01;
        /// 0x02 ER exception reset (SoA).
        const ER = 0x02;
        /// 0x04 EA exception acknowledge (PReq, SoA).
        const EA = 0x04;
        /// 0x08 EC exception clear (StatusResponse, IdentResponse), AN in a SoC (DNA).
        const EC = 0x08;
        /// 0x10 EN exception new (PRes, StatusResponse).
        const EN = 0x10;
        /// 0x20 MS multiplexed slot (PReq, PRes).
        const MS = 0x20;
        /// 0x40 PS prescaled slot (SoC).
        const PS = 0x40;
        /// 0x80 MC multiplexed cycle completed (SoC).
        const MC = 0x80;
    }
}

/// The PR/RS byte (frame byte 19 of PRes; 19 of StatusResponse/IdentResponse): RS in bits
/// 0-2, PR in bits 3-5, and the link-status bits 0x40 SLS / 0x80 FLS newer wireshark decodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub struct PrRs {
    /// Priority of the requested async frame (0-7; 7 = NMT request, 3 = generic).
    pub pr: u8,
    /// Number of pending async requests (0-7).
    pub rs: u8,
    /// Bits 6-7 (SLS 0x40, FLS 0x80), shifted down: 0-3.
    #[serde(default, skip_serializing_if = "crate::wire::is_zero")]
    pub link: u8,
}

impl PrRs {
    /// Splits the raw byte.
    pub fn from_raw(b: u8) -> Self {
        Self { pr: (b >> 3) & 0x07, rs: b & 0x07, link: b >> 6 }
    }

    /// The raw byte; fails if a field is out of range.
    pub fn raw(self) -> Result<u8, EncodeError> {
        check_max("PR", self.pr.into(), 7)?;
        check_max("RS", self.rs.into(), 7)?;
        check_max("PR/RS link bits", self.link.into(), 3)?;
        Ok(self.link << 6 | self.pr << 3 | self.rs)
    }
}
