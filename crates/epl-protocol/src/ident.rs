//! IdentResponse (`specs/powerlink.md` §3.6, ASnd service 1): CN -> all, dst 255,
//! 176 bytes. Every field is little-endian, including the IP address fields.

use std::net::Ipv4Addr;

use serde::{Deserialize, Serialize};

use crate::codes::NmtState;
use crate::error::{DecodeError, EncodeError};
use crate::flags::{Flags, PrRs};
use crate::wire::{is_zero, put_padded, trim_zeros, Rd};

/// Length of an IdentResponse counted from the message type byte (frame bytes 14..176).
pub const IDENT_RESPONSE_LEN: usize = 162;

/// A fixed-size text field (the 32-byte host name): a string when the bytes are UTF-8 up to
/// the first NUL and zero after it, the raw bytes (trailing zeros dropped) otherwise.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum FixedText {
    /// Clean text.
    Text(String),
    /// Bytes that are not clean text.
    Bytes(Vec<u8>),
}

impl Default for FixedText {
    fn default() -> Self {
        FixedText::Text(String::new())
    }
}

impl FixedText {
    fn from_field(field: &[u8]) -> Self {
        let nul = field.iter().position(|&b| b == 0).unwrap_or(field.len());
        let (text, rest) = field.split_at(nul);
        match std::str::from_utf8(text) {
            Ok(s) if rest.iter().all(|&b| b == 0) => FixedText::Text(s.to_owned()),
            _ => FixedText::Bytes(trim_zeros(field).to_vec()),
        }
    }

    fn as_bytes(&self) -> &[u8] {
        match self {
            FixedText::Text(s) => s.as_bytes(),
            FixedText::Bytes(b) => b,
        }
    }
}

/// An IdentResponse body (frame bytes 18..176).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct IdentResponse {
    /// Flags (0x10 EN, 0x08 EC in wireshark).
    pub flags: Flags,
    /// PR / RS.
    pub pr_rs: PrRs,
    /// NMT state of the sender.
    pub nmt_state: NmtState,
    /// EPL profile version (0x20).
    pub epl_version: u8,
    /// FeatureFlags (object 0x1F82), bit meanings in §3.6.
    pub feature_flags: u32,
    /// Async MTU.
    pub mtu: u16,
    /// PollInSize (PReq payload limit).
    pub poll_in_size: u16,
    /// PollOutSize (PRes payload limit).
    pub poll_out_size: u16,
    /// ResponseTime = PResMaxLatency (ns).
    pub response_time: u32,
    /// DeviceType (0x1000): low u16 device profile, high u16 additional info.
    pub device_type: u32,
    /// VendorId.
    pub vendor_id: u32,
    /// ProductCode.
    pub product_code: u32,
    /// RevisionNumber.
    pub revision_number: u32,
    /// SerialNumber.
    pub serial_number: u32,
    /// Vendor-specific extension 1 (8 bytes).
    pub vendor_ext1: [u8; 8],
    /// VerifyConfiguration date.
    pub verify_conf_date: u32,
    /// VerifyConfiguration time.
    pub verify_conf_time: u32,
    /// ApplicationSw date.
    pub app_sw_date: u32,
    /// ApplicationSw time.
    pub app_sw_time: u32,
    /// IP address.
    pub ip_address: Ipv4Addr,
    /// Subnet mask.
    pub subnet_mask: Ipv4Addr,
    /// Default gateway.
    pub default_gateway: Ipv4Addr,
    /// Host name (32 bytes on the wire).
    pub host_name: FixedText,
    /// Vendor-specific extension 2 (48 bytes on the wire; trailing zeros dropped).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub vendor_ext2: Vec<u8>,
    /// Frame byte 21 (ident-response flags, reserved).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub reserved1: u8,
    /// Frame byte 23 (reserved).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub reserved2: u8,
    /// Frame bytes 38..40 (reserved).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub reserved3: u16,
}

fn ip(rd: &Rd<'_>, off: usize) -> Result<Ipv4Addr, DecodeError> {
    Ok(Ipv4Addr::from(rd.u32(off)?))
}

impl IdentResponse {
    pub(crate) fn decode(rd: &Rd<'_>) -> Result<(Self, usize), DecodeError> {
        rd.need(IDENT_RESPONSE_LEN)?;
        let ident = IdentResponse {
            flags: Flags::from_bits_retain(rd.u8(4)?),
            pr_rs: PrRs::from_raw(rd.u8(5)?),
            nmt_state: NmtState::from_raw(rd.u8(6)?),
            reserved1: rd.u8(7)?,
            epl_version: rd.u8(8)?,
            reserved2: rd.u8(9)?,
            feature_flags: rd.u32(10)?,
            mtu: rd.u16(14)?,
            poll_in_size: rd.u16(16)?,
            poll_out_size: rd.u16(18)?,
            response_time: rd.u32(20)?,
            reserved3: rd.u16(24)?,
            device_type: rd.u32(26)?,
            vendor_id: rd.u32(30)?,
            product_code: rd.u32(34)?,
            revision_number: rd.u32(38)?,
            serial_number: rd.u32(42)?,
            vendor_ext1: rd.array::<8>(46)?,
            verify_conf_date: rd.u32(54)?,
            verify_conf_time: rd.u32(58)?,
            app_sw_date: rd.u32(62)?,
            app_sw_time: rd.u32(66)?,
            ip_address: ip(rd, 70)?,
            subnet_mask: ip(rd, 74)?,
            default_gateway: ip(rd, 78)?,
            host_name: FixedText::from_field(rd.bytes(82, 32)?),
            vendor_ext2: trim_zeros(rd.bytes(114, 48)?).to_vec(),
        };
        Ok((ident, IDENT_RESPONSE_LEN))
    }

    pub(crate) fn encode_into(&self, out: &mut Vec<u8>) -> Result<(), EncodeError> {
        out.extend_from_slice(&[
            self.flags.bits(),
            self.pr_rs.raw()?,
            self.nmt_state.raw(),
            self.reserved1,
            self.epl_version,
            self.reserved2,
        ]);
        out.extend_from_slice(&self.feature_flags.to_le_bytes());
        for v in [self.mtu, self.poll_in_size, self.poll_out_size] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&self.response_time.to_le_bytes());
        out.extend_from_slice(&self.reserved3.to_le_bytes());
        for v in
            [self.device_type, self.vendor_id, self.product_code, self.revision_number, self.serial_number]
        {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&self.vendor_ext1);
        for v in [self.verify_conf_date, self.verify_conf_time, self.app_sw_date, self.app_sw_time] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for a in [self.ip_address, self.subnet_mask, self.default_gateway] {
            out.extend_from_slice(&u32::from(a).to_le_bytes());
        }
        put_padded(out, "IdentResponse host name", self.host_name.as_bytes(), 32)?;
        put_padded(out, "IdentResponse vendor_ext2", &self.vendor_ext2, 48)
    }
}
