//! Error types: frame construction and candump parsing.

use thiserror::Error;

/// A CAN frame could not be built (our own misuse or bad input, never a bus failure).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum FrameError {
    /// The identifier does not fit 11 bits (standard) or 29 bits (extended).
    #[error("CAN identifier {id:#x} out of range (extended: {extended})")]
    IdOutOfRange {
        /// The identifier given.
        id: u32,
        /// Whether an extended (29-bit) frame was asked for.
        extended: bool,
    },
    /// More than 8 data bytes (classic CAN) or a data length code above 8.
    #[error("CAN frame length {len} exceeds 8 bytes")]
    TooLong {
        /// The length given.
        len: usize,
    },
}

/// A line in candump notation (`ID#DATA`, `ID#R`) could not be parsed.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ParseError {
    /// No `#` between identifier and data.
    #[error("missing '#' separator")]
    MissingSeparator,
    /// The identifier is not 3 (standard) or 8 (extended) hex digits.
    #[error("bad CAN identifier {0:?} (want 3 or 8 hex digits)")]
    BadId(String),
    /// The data field is not pairs of hex digits (optionally '.'-separated) or `R[dlc]`.
    #[error("bad data field {0:?}")]
    BadData(String),
    /// CAN FD (`##`) is not supported by this codec.
    #[error("CAN FD frames are not supported")]
    CanFd,
    /// The parsed values do not form a valid frame.
    #[error(transparent)]
    Frame(#[from] FrameError),
}
