//! Errors of the master runtime. Blame is explicit: a silent node (time-out), a device
//! refusal (SDO abort, LSS error code), a protocol violation, a transport failure, or our
//! own misuse (invalid argument).

use std::time::Duration;

use motus_can::CanError;
use motus_canopen_protocol::SdoAbortCode;

use crate::eds::EdsError;
use crate::lss::LssError;
use crate::pdo::PdoError;
use crate::sdo_client::SdoError;

/// Errors of [`crate::Master`].
#[derive(Debug, thiserror::Error)]
pub enum MasterError {
    /// An SDO transfer failed: device abort, time-out or protocol error (see [`SdoError`]).
    #[error(transparent)]
    Sdo(#[from] SdoError),
    /// An SDO upload returned a length the typed helper cannot use.
    #[error("node {node}: 0x{index:04X}:{sub:02X} returned {len} bytes, expected {want}")]
    Length {
        /// Node.
        node: u8,
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Bytes received.
        len: usize,
        /// Bytes expected.
        want: usize,
    },
    /// The CAN transport failed.
    #[error("CAN transport error while {context}: {source}")]
    Transport {
        /// What the master was doing.
        context: String,
        /// The transport error.
        #[source]
        source: CanError,
    },
    /// An LSS service failed (refused, no answer, bad argument).
    #[error(transparent)]
    Lss(#[from] LssError),
    /// A node did not do something in time (boot-up, state change).
    #[error("node {node}: no {what} within {timeout:?}")]
    NodeTimeout {
        /// Node.
        node: u8,
        /// What was awaited.
        what: String,
        /// The time-out.
        timeout: Duration,
    },
    /// A PDO configuration is invalid (nothing was written).
    #[error("PDO configuration for node {node}: {source}")]
    Pdo {
        /// Node.
        node: u8,
        /// The problem.
        #[source]
        source: PdoError,
    },
    /// The EDS could not be loaded.
    #[error(transparent)]
    Eds(#[from] EdsError),
    /// `dump` needs an EDS (see `load_eds`).
    #[error("no EDS loaded")]
    NoEds,
    /// Our own misuse.
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
}

impl MasterError {
    /// Whether the peer was silent (SDO, LSS or node time-out).
    pub fn is_timeout(&self) -> bool {
        matches!(
            self,
            Self::Sdo(SdoError::Timeout { .. })
                | Self::Lss(LssError::Timeout { .. })
                | Self::NodeTimeout { .. }
        )
    }

    /// The abort code, if the device aborted an SDO transfer.
    pub fn abort_code(&self) -> Option<SdoAbortCode> {
        match self {
            Self::Sdo(SdoError::Aborted { code, .. }) => Some(*code),
            _ => None,
        }
    }

    pub(crate) fn transport(context: impl Into<String>, source: CanError) -> Self {
        Self::Transport { context: context.into(), source }
    }
}
