//! Ethernet II header (`specs/powerlink.md` §1): destination and source MAC, an optional
//! 802.1Q tag (tolerated on decode, written back on encode) and the EtherType, which must be
//! 0x88AB for POWERLINK. Also the POWERLINK multicast addresses.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::error::DecodeError;

/// POWERLINK EtherType (big-endian on the wire).
pub const ETHERTYPE_EPL: u16 = 0x88AB;
/// 802.1Q VLAN tag protocol identifier.
pub const ETHERTYPE_VLAN: u16 = 0x8100;
/// Minimum Ethernet frame length without FCS; [`crate::Padding::Auto`] pads to it.
pub const MIN_FRAME_LEN: usize = 60;
/// Largest Ethernet frame without FCS.
pub const MAX_FRAME_LEN: usize = 1514;

/// A 48-bit MAC address. JSON and `Display`: `01:11:1e:00:00:01`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, PartialOrd, Ord)]
pub struct MacAddr(pub [u8; 6]);

impl MacAddr {
    /// SoC multicast destination 01:11:1E:00:00:01.
    pub const SOC: MacAddr = MacAddr([0x01, 0x11, 0x1E, 0, 0, 0x01]);
    /// PRes multicast destination 01:11:1E:00:00:02.
    pub const PRES: MacAddr = MacAddr([0x01, 0x11, 0x1E, 0, 0, 0x02]);
    /// SoA multicast destination 01:11:1E:00:00:03.
    pub const SOA: MacAddr = MacAddr([0x01, 0x11, 0x1E, 0, 0, 0x03]);
    /// ASnd multicast destination 01:11:1E:00:00:04.
    pub const ASND: MacAddr = MacAddr([0x01, 0x11, 0x1E, 0, 0, 0x04]);
    /// AMNI multicast destination 01:11:1E:00:00:05.
    pub const AMNI: MacAddr = MacAddr([0x01, 0x11, 0x1E, 0, 0, 0x05]);
    /// Ethernet broadcast ff:ff:ff:ff:ff:ff.
    pub const BROADCAST: MacAddr = MacAddr([0xFF; 6]);
}

impl fmt::Display for MacAddr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [a, b, c, d, e, g] = self.0;
        write!(f, "{a:02x}:{b:02x}:{c:02x}:{d:02x}:{e:02x}:{g:02x}")
    }
}

/// A MAC address string that is not six `:`- or `-`-separated hex bytes.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("invalid MAC address {0:?} (expected six hex bytes like 01:11:1e:00:00:01)")]
pub struct InvalidMac(pub String);

impl FromStr for MacAddr {
    type Err = InvalidMac;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let mut out = [0u8; 6];
        let mut parts = s.split([':', '-']);
        for slot in &mut out {
            let part = parts.next().ok_or_else(|| InvalidMac(s.to_owned()))?;
            if part.len() != 2 {
                return Err(InvalidMac(s.to_owned()));
            }
            *slot = u8::from_str_radix(part, 16).map_err(|_| InvalidMac(s.to_owned()))?;
        }
        if parts.next().is_some() {
            return Err(InvalidMac(s.to_owned()));
        }
        Ok(MacAddr(out))
    }
}

impl Serialize for MacAddr {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for MacAddr {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

/// The Ethernet II header of a POWERLINK frame. The EtherType is implied (0x88AB).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct EthernetHeader {
    /// Destination MAC.
    pub dst: MacAddr,
    /// Source MAC.
    pub src: MacAddr,
    /// 802.1Q tag control information (PCP, DEI, VLAN ID) when the frame carries a tag.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vlan_tci: Option<u16>,
}

impl EthernetHeader {
    /// Header with no VLAN tag.
    pub fn new(dst: MacAddr, src: MacAddr) -> Self {
        Self { dst, src, vlan_tci: None }
    }

    /// Header length on the wire: 14, or 18 with a VLAN tag.
    pub fn len(&self) -> usize {
        if self.vlan_tci.is_some() {
            18
        } else {
            14
        }
    }

    /// Always false (a header is never empty); present for clippy's `len_without_is_empty`.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Decodes the header; returns it and the frame offset where the EPL part begins.
    pub fn decode(frame: &[u8]) -> Result<(Self, usize), DecodeError> {
        let too_short = |needed| DecodeError::TooShort { what: "Ethernet header", needed, got: frame.len() };
        let head: &[u8; 14] = frame.get(..14).and_then(|s| s.try_into().ok()).ok_or(too_short(14))?;
        let (macs, ty) = head.split_at(12);
        let mut dst = [0u8; 6];
        let mut src = [0u8; 6];
        dst.copy_from_slice(macs.get(..6).unwrap_or(&[0; 6]));
        src.copy_from_slice(macs.get(6..).unwrap_or(&[0; 6]));
        let mut ethertype =
            u16::from_be_bytes([ty.first().copied().unwrap_or(0), ty.get(1).copied().unwrap_or(0)]);
        let mut vlan_tci = None;
        let mut start = 14;
        if ethertype == ETHERTYPE_VLAN {
            let tag: [u8; 4] = frame.get(14..18).and_then(|s| s.try_into().ok()).ok_or(too_short(18))?;
            let [t0, t1, e0, e1] = tag;
            vlan_tci = Some(u16::from_be_bytes([t0, t1]));
            ethertype = u16::from_be_bytes([e0, e1]);
            start = 18;
        }
        if ethertype != ETHERTYPE_EPL {
            return Err(DecodeError::NotPowerlink { ethertype });
        }
        Ok((Self { dst: MacAddr(dst), src: MacAddr(src), vlan_tci }, start))
    }

    /// Appends the header (with EtherType 0x88AB) to `out`.
    pub fn encode_into(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.dst.0);
        out.extend_from_slice(&self.src.0);
        if let Some(tci) = self.vlan_tci {
            out.extend_from_slice(&ETHERTYPE_VLAN.to_be_bytes());
            out.extend_from_slice(&tci.to_be_bytes());
        }
        out.extend_from_slice(&ETHERTYPE_EPL.to_be_bytes());
    }
}
