//! Configuration of one simulated drive: node id (or LSS-unconfigured), identity (the
//! 128-bit LSS address), bit timing, heartbeat, boot delay, limit switches and motor model.

use std::time::Duration;

/// Vendor-ID 0x1018:1. 0x0800005A is the CiA vendor-ID used by Schneider Electric, owner
/// of the Berger Lahr / SIG Positec IclA line [U: not checked against a real IclA].
pub const VENDOR_ID: u32 = 0x0800_005A;
/// Product code 0x1018:2 (simulator value: "D065").
pub const PRODUCT_CODE: u32 = 0x0000_0065;
/// Revision number 0x1018:3 (major 1, minor 0).
pub const REVISION: u32 = 0x0001_0000;
/// Node id of an IclA out of the box (specs/omni-robot.md).
pub const DEFAULT_NODE_ID: u8 = 127;
/// LSS "unconfigured" node id.
pub const UNCONFIGURED: u8 = 0xFF;

/// The 128-bit LSS address (object 0x1018 sub 1-4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Identity {
    /// Vendor-ID.
    pub vendor: u32,
    /// Product code.
    pub product: u32,
    /// Revision number.
    pub revision: u32,
    /// Serial number (must differ between drives on one bus for LSS selective / fastscan).
    pub serial: u32,
}

impl Identity {
    /// The IclA simulator identity with this serial number.
    pub fn icla(serial: u32) -> Self {
        Self { vendor: VENDOR_ID, product: PRODUCT_CODE, revision: REVISION, serial }
    }

    /// The part selected by an LSS sub (0 vendor, 1 product, 2 revision, 3 serial).
    pub fn part(&self, lss_sub: u8) -> Option<u32> {
        Some(match lss_sub {
            0 => self.vendor,
            1 => self.product,
            2 => self.revision,
            3 => self.serial,
            _ => return None,
        })
    }
}

/// Everything that makes one simulated drive.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// Node id 1-127, or [`UNCONFIGURED`] (0xFF): silent until LSS gives it an id.
    pub node_id: u8,
    /// LSS address.
    pub identity: Identity,
    /// LSS bit-timing table index (7 = 20 kbit/s, the robot's rate).
    pub bit_timing: u8,
    /// Producer heartbeat time 0x1017 default in ms (1000).
    pub heartbeat_ms: u16,
    /// Delay between power-on (first poll) and the boot-up message (the real IclA: ~4 s).
    pub boot_delay: Duration,
    /// Negative limit switch position in world increments (used by homing method 17).
    pub negative_limit_switch: Option<f64>,
    /// Positive limit switch position in world increments (used by homing method 18).
    pub positive_limit_switch: Option<f64>,
    /// Motor model: first-order lag time constant of the actual position behind the demand (s).
    pub lag_time: f64,
    /// Position (Inc) at power-on (the IclA keeps its 32-bit position across power-off).
    pub initial_position: i32,
}

impl SimConfig {
    /// A drive at node `node_id` with serial number = node id.
    pub fn node(node_id: u8) -> Self {
        Self {
            node_id,
            identity: Identity::icla(u32::from(node_id)),
            bit_timing: 7,
            heartbeat_ms: 1000,
            boot_delay: Duration::ZERO,
            negative_limit_switch: Some(-500.0),
            positive_limit_switch: Some(500.0),
            lag_time: 0.01,
            initial_position: 0,
        }
    }

    /// An LSS-unconfigured drive (node id 0xFF) with this serial number.
    pub fn unconfigured(serial: u32) -> Self {
        let mut c = Self::node(UNCONFIGURED);
        c.identity = Identity::icla(serial);
        c
    }
}

impl Default for SimConfig {
    fn default() -> Self {
        Self::node(DEFAULT_NODE_ID)
    }
}

/// Bit rate of an LSS bit-timing table index (CiA 305 standard table, specs/canopen.md
/// part 4); `None` for reserved index 5, automatic detection (9) and unknown indices.
pub fn bitrate_of_index(index: u8) -> Option<u32> {
    Some(match index {
        0 => 1_000_000,
        1 => 800_000,
        2 => 500_000,
        3 => 250_000,
        4 => 125_000,
        6 => 50_000,
        7 => 20_000,
        8 => 10_000,
        _ => return None,
    })
}

/// A node list that is not `2,3,4`-style ids in 1..=127.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("invalid node id {0:?} (expected a comma-separated list of 1..=127)")]
pub struct NodeListError(pub String);

/// Parses a node list such as `2,3,4`.
pub fn parse_nodes(text: &str) -> Result<Vec<u8>, NodeListError> {
    text.split(',')
        .map(str::trim)
        .map(|t| {
            t.parse::<u8>().ok().filter(|n| (1..=127).contains(n)).ok_or_else(|| NodeListError(t.to_owned()))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn node_lists_and_bit_timing_table() {
        assert_eq!(parse_nodes("2,3, 4"), Ok(vec![2, 3, 4]));
        assert_eq!(parse_nodes("0"), Err(NodeListError("0".into())));
        assert_eq!(parse_nodes("2,x"), Err(NodeListError("x".into())));
        // Spec part 4 table: 7 = 20 kbit/s; 5 reserved, 9 automatic.
        assert_eq!(bitrate_of_index(7), Some(20_000));
        assert_eq!(bitrate_of_index(5), None);
        assert_eq!(bitrate_of_index(9), None);
    }
}
