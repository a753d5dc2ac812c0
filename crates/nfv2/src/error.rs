//! Typed errors of the driver, with explicit blame: a bus failure (no or corrupt answer,
//! IO), a device refusal or fault (status bits, ERROR mode, a missing ENABLE), and our own
//! misuse (a value out of range, an unknown slave, a stopped scheduler).

use std::time::Duration;

use motus_nfv2_protocol::EncodeError;
use motus_serial::BusError;

/// Why an NFv2 operation failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Nfv2Error {
    /// The line failed or the slave did not answer in time (bus blame).
    #[error(transparent)]
    Bus(#[from] BusError),
    /// The frame could not be encoded (caller blame: a value out of range, a code the
    /// slave's revision does not know, a frame over 256 bytes).
    #[error("frame not sent: {0}")]
    Encode(#[from] EncodeError),
    /// The drive is in ERROR (switched off): enable it first (caller blame).
    #[error("address {0}: the drive is not enabled (mode ERROR): enable it first")]
    NotEnabled(u8),
    /// No slave with this address is configured on the scheduler (caller blame).
    #[error("no 1209A at address {0} on this bus")]
    UnknownSlave(u8),
    /// A command was not acknowledged: no valid answer to a frame carrying it arrived in
    /// time (bus blame; the slave may or may not have it).
    #[error("address {address}: {what} not acknowledged within {waited:?} (no valid answer to a frame carrying it)")]
    NotConfirmed {
        /// Slave address.
        address: u8,
        /// What was sent.
        what: String,
        /// How long we waited.
        waited: Duration,
    },
    /// The device reports a fault, or refuses in its own way (device blame).
    #[error("address {address}: {reason}")]
    Device {
        /// Slave address.
        address: u8,
        /// The device's reason (status bit, mode, input).
        reason: String,
    },
    /// The request is invalid for this device or its state (caller blame).
    #[error("{0}")]
    InvalidArgument(String),
    /// Waiting for a condition took too long (device blame: it did not get there).
    #[error("address {address}: {what} did not finish within {timeout:?}")]
    WaitTimeout {
        /// Slave address.
        address: u8,
        /// What was awaited.
        what: String,
        /// How long we waited.
        timeout: Duration,
    },
    /// The scheduler thread is not running any more (shut down, or it failed to start).
    #[error("the NFv2 bus scheduler is stopped")]
    Stopped,
    /// The serial port could not be opened.
    #[error("cannot open {path}: {reason}")]
    Open {
        /// Port path.
        path: String,
        /// The OS error.
        reason: String,
    },
}

impl Nfv2Error {
    /// Who is to blame (decides whether a retry can help).
    #[must_use]
    pub fn blame(&self) -> motus_axis::Blame {
        use motus_axis::Blame;
        match self {
            Nfv2Error::Bus(_)
            | Nfv2Error::NotConfirmed { .. }
            | Nfv2Error::Stopped
            | Nfv2Error::Open { .. } => Blame::Bus,
            Nfv2Error::Device { .. } | Nfv2Error::WaitTimeout { .. } => Blame::Device,
            Nfv2Error::Encode(_)
            | Nfv2Error::UnknownSlave(_)
            | Nfv2Error::NotEnabled(_)
            | Nfv2Error::InvalidArgument(_) => Blame::Caller,
        }
    }
}
