//! Slave addresses, and what address 0 means.
//!
//! The frame's byte 3 is a plain `u8` ([`Frame::address`](crate::Frame::address)); its
//! meaning is a property of the installation, not of the frame, and the two sources
//! disagree:
//!
//! - the seed (1209A documentation): the 4-bit DIP address **0** makes a module the bus
//!   master / **gateway** relaying between a PC on its USB and the other modules; a PC on
//!   USB talks to module 0, which reaches every other module;
//! - the reference implementation: `NF_BroadcastAddress` is a per-firmware configuration
//!   value, **0** in some configurations (every slave accepts it, none answers), `0xFF` in
//!   others (including the reference's pan-tilt firmware configuration, which also sets
//!   `NF_MasterAddress`).
//!
//! [`AddressPlan`] keeps both representable; the default is the seed's (0 = gateway, no
//! broadcast address), because that is the device this crate drives.

use serde::{Deserialize, Serialize};

/// What an address means in an installation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(tag = "role", rename_all = "snake_case")]
pub enum AddressRole {
    /// An ordinary slave.
    Slave {
        /// The address.
        address: u8,
    },
    /// The gateway / bus master module (seed: DIP address 0).
    Gateway,
    /// Every slave accepts the frame; none answers (reference: `NF_BroadcastAddress`).
    Broadcast,
}

/// The installation's special addresses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct AddressPlan {
    /// The broadcast address, if the installation has one.
    pub broadcast: Option<u8>,
    /// The gateway module's address, if the installation has one.
    pub gateway: Option<u8>,
}

impl AddressPlan {
    /// The seed's 1209A convention: address 0 is the gateway, no broadcast.
    pub const SEED_1209A: AddressPlan = AddressPlan { broadcast: None, gateway: Some(0) };

    /// The reference configuration where address 0 is broadcast.
    pub const REFERENCE_BROADCAST_0: AddressPlan = AddressPlan { broadcast: Some(0), gateway: None };

    /// The reference configurations with broadcast 0xFF (e.g. the pan-tilt firmware's).
    pub const REFERENCE_BROADCAST_FF: AddressPlan = AddressPlan { broadcast: Some(0xFF), gateway: None };

    /// The role of `address`; broadcast wins if it equals the gateway address.
    #[must_use]
    pub fn role(&self, address: u8) -> AddressRole {
        if self.broadcast == Some(address) {
            AddressRole::Broadcast
        } else if self.gateway == Some(address) {
            AddressRole::Gateway
        } else {
            AddressRole::Slave { address }
        }
    }

    /// Whether a slave at `own` processes a frame addressed to `frame_address`
    /// (its own address, or broadcast).
    #[must_use]
    pub fn accepts(&self, own: u8, frame_address: u8) -> bool {
        frame_address == own || self.broadcast == Some(frame_address)
    }

    /// Whether a slave at `own` answers the queries of a frame addressed to
    /// `frame_address` (only frames addressed to it, never broadcasts).
    #[must_use]
    pub fn answers(&self, own: u8, frame_address: u8) -> bool {
        frame_address == own && self.broadcast != Some(frame_address)
    }
}

impl Default for AddressPlan {
    fn default() -> Self {
        Self::SEED_1209A
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn address_zero_both_ways() {
        assert_eq!(AddressPlan::SEED_1209A.role(0), AddressRole::Gateway);
        assert_eq!(AddressPlan::REFERENCE_BROADCAST_0.role(0), AddressRole::Broadcast);
        assert_eq!(AddressPlan::default().role(3), AddressRole::Slave { address: 3 });
        let b = AddressPlan::REFERENCE_BROADCAST_0;
        assert!(b.accepts(3, 0) && !b.answers(3, 0));
        assert!(b.accepts(3, 3) && b.answers(3, 3));
        let g = AddressPlan::SEED_1209A;
        assert!(!g.accepts(3, 0));
        assert!(g.accepts(0, 0) && g.answers(0, 0));
    }
}
