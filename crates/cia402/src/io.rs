//! How the driver reaches a drive's objects.

use motus_canopen_protocol::SdoAbortCode;
use motus_cia402_protocol::index;
use motus_clock::{SharedClock, SystemClock};

/// Why an object access failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IoError {
    /// The drive did not answer in time (bus or node silent).
    #[error("node {node}: no answer on 0x{index:04X}:{sub:02X} ({detail})")]
    Timeout {
        /// Node id.
        node: u8,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// What timed out.
        detail: String,
    },
    /// The drive refused the access (SDO abort), with the standard's name of the code.
    #[error("node {node}: 0x{index:04X}:{sub:02X} refused: {} (0x{:08X})", code.description(), code.raw())]
    Refused {
        /// Node id.
        node: u8,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The abort code.
        code: SdoAbortCode,
    },
    /// The node was lost (heartbeat time-out) or is not operational.
    #[error("node {node}: {reason}")]
    NodeLost {
        /// Node id.
        node: u8,
        /// Why it counts as lost.
        reason: String,
    },
    /// The answer had the wrong size or shape.
    #[error("node {node}: 0x{index:04X}:{sub:02X}: {reason}")]
    Malformed {
        /// Node id.
        node: u8,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// What was wrong.
        reason: String,
    },
    /// Transport failure.
    #[error("node {node}: bus failure: {reason}")]
    Bus {
        /// Node id.
        node: u8,
        /// What failed.
        reason: String,
    },
}

/// Access to one drive's objects. Implementations must be usable from one thread at a
/// time (`&self`, internally synchronised).
pub trait DriveIo: Send {
    /// The drive's node id (for messages).
    fn node(&self) -> u8;
    /// Reads an object (SDO upload or a cached PDO value).
    fn read(&self, index: u16, sub: u8) -> Result<Vec<u8>, IoError>;
    /// Writes an object (SDO download).
    fn write(&self, index: u16, sub: u8, data: &[u8]) -> Result<(), IoError>;
    /// Writes the controlword (an RPDO where one is mapped, else an SDO write).
    fn write_controlword(&self, cw: u16) -> Result<(), IoError> {
        self.write(index::CONTROLWORD, 0, &cw.to_le_bytes())
    }
    /// Reads the statusword (a fresh TPDO value where one is mapped, else an SDO read).
    fn statusword(&self) -> Result<u16, IoError> {
        let raw = self.read(index::STATUSWORD, 0)?;
        fixed::<2>(self.node(), index::STATUSWORD, 0, &raw).map(u16::from_le_bytes)
    }
    /// Reads the actual position 0x6064.
    fn position(&self) -> Result<i32, IoError> {
        let raw = self.read(index::POSITION_ACTUAL, 0)?;
        fixed::<4>(self.node(), index::POSITION_ACTUAL, 0, &raw).map(i32::from_le_bytes)
    }
    /// The clock of the transport (the system clock unless the transport runs on a
    /// virtual one); [`crate::Drive`] waits on it.
    fn clock(&self) -> SharedClock {
        SystemClock::shared()
    }
}

/// Interprets a little-endian value of exactly `N` bytes (a drive may answer with more
/// bytes for a segmented upload; fewer is an error).
pub(crate) fn fixed<const N: usize>(node: u8, index: u16, sub: u8, raw: &[u8]) -> Result<[u8; N], IoError> {
    raw.get(..N).and_then(|s| s.try_into().ok()).ok_or_else(|| IoError::Malformed {
        node,
        index,
        sub,
        reason: format!("expected {N} bytes, received {}", raw.len()),
    })
}
