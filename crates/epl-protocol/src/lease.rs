//! The Motus safety lease: a manufacturer-specific ASnd (ServiceID [`SAFETY_LEASE_SERVICE_ID`])
//! by which a supervisor grants drives permission to run for a limited time, or revokes it at
//! once (quick stop).
//!
//! Body (frame bytes 18.., little-endian; the codec drops trailing zeros, so a short body is
//! read as if zero-padded to [`SAFETY_LEASE_LEN`] bytes):
//! | offset | type | meaning |
//! |---|---|---|
//! | 0 | u8 | layout version, 1 |
//! | 1 | u8 | bit 0: safe to run (0 = revoke now) |
//! | 2 | u16 | sequence number (wraps) |
//! | 4 | u32 | validity from reception, microseconds (0 with a revoke) |
//! | 8 | [u8; 8] | first 8 bytes of the approved configuration fingerprint |
//!
//! A drive that requires a lease runs only while the newest lease says safe and has not expired;
//! a revoke or an expiry makes it quick-stop. The ASnd is a Motus convention (not in the
//! POWERLINK specification; ServiceIDs 0xA0..=0xFE are reserved for manufacturer-specific
//! services), sent outside the schedule from [`LEASE_ASND_NODE_ID`] only: a drive ignores a
//! lease ASnd from any other node.
//!
//! On a segment with foreign nodes the supervisor is a CN instead, a *safety node*: the same
//! body is the payload of its PRes, mapped from its dictionary (object 0x2100,
//! [`crate::od::SAFETY_LEASE_OBJECT`]), with the sequence number as a lease counter that
//! advances with every PRes. The PRes travels in the POWERLINK schedule, and every node
//! receives it.

use crate::asnd::Asnd;
use serde::{Deserialize, Serialize};

/// The node the lease ASnd comes from (253, POWERLINK's diagnostic device): drives take a
/// lease ASnd from this node only.
pub const LEASE_ASND_NODE_ID: u8 = 253;

/// ServiceID of the safety lease ASnd.
pub const SAFETY_LEASE_SERVICE_ID: u8 = 0xA5;
/// Body length of a safety lease.
pub const SAFETY_LEASE_LEN: usize = 16;
/// Layout version written by [`SafetyLease::to_asnd`].
pub const SAFETY_LEASE_VERSION: u8 = 1;

/// One safety lease message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct SafetyLease {
    /// Permission to run (false: stop now).
    pub safe: bool,
    /// Sequence number.
    pub seq: u16,
    /// Validity from reception in microseconds.
    pub valid_for_us: u32,
    /// First bytes of the approved configuration fingerprint.
    pub fingerprint: [u8; 8],
}

impl SafetyLease {
    /// A revocation (quick stop now).
    pub fn revoke(seq: u16, fingerprint: [u8; 8]) -> Self {
        Self { safe: false, seq, valid_for_us: 0, fingerprint }
    }

    /// The ASnd body.
    pub fn encode(&self) -> [u8; SAFETY_LEASE_LEN] {
        let mut b = [0u8; SAFETY_LEASE_LEN];
        let [s0, s1] = self.seq.to_le_bytes();
        let [v0, v1, v2, v3] = self.valid_for_us.to_le_bytes();
        let head = [SAFETY_LEASE_VERSION, u8::from(self.safe), s0, s1, v0, v1, v2, v3];
        for (dst, src) in b.iter_mut().zip(head.iter().chain(self.fingerprint.iter())) {
            *dst = *src;
        }
        b
    }

    /// Decodes a body; `None` for another layout version.
    pub fn decode(body: &[u8]) -> Option<Self> {
        let mut b = [0u8; SAFETY_LEASE_LEN];
        for (dst, src) in b.iter_mut().zip(body) {
            *dst = *src;
        }
        let [version, flags, s0, s1, v0, v1, v2, v3, f @ ..] = b;
        (version == SAFETY_LEASE_VERSION).then_some(Self {
            safe: flags & 1 != 0,
            seq: u16::from_le_bytes([s0, s1]),
            valid_for_us: u32::from_le_bytes([v0, v1, v2, v3]),
            fingerprint: f,
        })
    }

    /// As an ASnd message.
    pub fn to_asnd(&self) -> Asnd {
        let mut data = self.encode().to_vec();
        while data.last() == Some(&0) {
            data.pop();
        }
        Asnd::Other { service_id: SAFETY_LEASE_SERVICE_ID, data }
    }

    /// Reads a lease from an ASnd, if it is one.
    pub fn from_asnd(asnd: &Asnd) -> Option<Self> {
        match asnd {
            Asnd::Other { service_id: SAFETY_LEASE_SERVICE_ID, data } => Self::decode(data),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use crate::{EplFrame, MacAddr, Message, BROADCAST_NODE_ID};

    #[test]
    fn lease_frame_by_hand() {
        let lease = SafetyLease { safe: true, seq: 0x0102, valid_for_us: 800, fingerprint: [0xAA; 8] };
        let frame = EplFrame::new(
            MacAddr([2, 0, 0, 0, 0, 0xfd]),
            MacAddr::BROADCAST,
            BROADCAST_NODE_ID,
            253,
            Message::Asnd(lease.to_asnd()),
        );
        let bytes = frame.encode().unwrap();
        // 14: type ASnd, 15: dst 255, 16: src 253, 17: ServiceID 0xA5, 18: version 1,
        // 19: safe, 20..22: seq 0x0102 LE, 22..26: 800 = 0x320 LE, 26..34: fingerprint.
        assert_eq!(&bytes[14..26], &[0x06, 0xff, 0xfd, 0xa5, 1, 1, 0x02, 0x01, 0x20, 0x03, 0, 0]);
        assert_eq!(&bytes[26..34], &[0xAA; 8]);
        let back = EplFrame::decode(&bytes).unwrap();
        let Message::Asnd(a) = &back.message else { panic!("not an ASnd") };
        assert_eq!(SafetyLease::from_asnd(a), Some(lease));
    }

    #[test]
    fn revoke_with_trailing_zeros_dropped() {
        let r = SafetyLease::revoke(0, [0; 8]);
        let asnd = r.to_asnd();
        assert_eq!(asnd, Asnd::Other { service_id: 0xA5, data: vec![1] });
        assert_eq!(SafetyLease::from_asnd(&asnd), Some(r));
        assert_eq!(SafetyLease::decode(&[2, 1]), None, "other layout version");
    }
}
