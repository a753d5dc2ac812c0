//! Communication-module addresses: 0xE1..=0xE6 for joints 1..6 (0xE6 is the gripper).

use std::fmt;

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// The address of one communication module (0xE1..=0xE6). In JSON it is the plain number
/// (`226` for 0xE2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(try_from = "u8", into = "u8")]
pub struct Address(u8);

/// A byte that is not a module address.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
#[error("{0:#04x} is not a KV-01 module address (0xE1..=0xE6)")]
pub struct InvalidAddress(pub u8);

impl Address {
    /// Lowest address (joint 1).
    pub const FIRST: u8 = 0xE1;
    /// Highest address (joint 6, the gripper).
    pub const LAST: u8 = 0xE6;
    /// The gripper module (joint 6: gripper rotation and open/close).
    pub const GRIPPER: Address = Address(0xE6);

    /// The address for a raw byte, if it is one.
    #[must_use]
    pub const fn new(raw: u8) -> Option<Self> {
        if raw >= Self::FIRST && raw <= Self::LAST {
            Some(Self(raw))
        } else {
            None
        }
    }

    /// The address of joint `joint` (1..=6).
    #[must_use]
    pub const fn joint(joint: u8) -> Option<Self> {
        if joint >= 1 && joint <= 6 {
            Some(Self(Self::FIRST - 1 + joint))
        } else {
            None
        }
    }

    /// The raw byte.
    #[must_use]
    pub const fn raw(self) -> u8 {
        self.0
    }

    /// The joint number (1..=6).
    #[must_use]
    pub const fn joint_number(self) -> u8 {
        self.0 - (Self::FIRST - 1)
    }

    /// Whether this is the gripper module (0xE6).
    #[must_use]
    pub const fn is_gripper(self) -> bool {
        self.0 == Self::LAST
    }

    /// All six addresses, joint 1 first.
    pub fn all() -> impl Iterator<Item = Address> {
        (Self::FIRST..=Self::LAST).map(Address)
    }
}

impl TryFrom<u8> for Address {
    type Error = InvalidAddress;
    fn try_from(raw: u8) -> Result<Self, Self::Error> {
        Self::new(raw).ok_or(InvalidAddress(raw))
    }
}

impl From<Address> for u8 {
    fn from(a: Address) -> u8 {
        a.0
    }
}

impl fmt::Display for Address {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:#04X}", self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range() {
        assert_eq!(Address::new(0xE0), None);
        assert_eq!(Address::new(0xE7), None);
        assert_eq!(Address::joint(2).map(Address::raw), Some(0xE2));
        assert_eq!(Address::joint(0), None);
        assert_eq!(Address::joint(7), None);
        assert!(Address::GRIPPER.is_gripper());
        assert_eq!(Address::all().count(), 6);
        assert_eq!(Address::GRIPPER.joint_number(), 6);
    }
}
