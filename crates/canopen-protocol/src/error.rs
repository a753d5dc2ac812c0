//! Error types, one per layer: frame construction, candump parsing, message encoding.

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

/// A message could not be encoded because one of its fields is invalid (our own misuse).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum EncodeError {
    /// Node id outside 1..=127 (or 0..=127 for NMT commands).
    #[error("invalid node id {0} (want 1..=127)")]
    InvalidNode(u8),
    /// PDO number outside 1..=4.
    #[error("invalid PDO number {0} (want 1..=4)")]
    InvalidPdoNumber(u8),
    /// A data field is too long or too short for its frame layout.
    #[error("data length {len} outside {min}..={max}")]
    DataLength {
        /// Minimum allowed length.
        min: usize,
        /// Maximum allowed length.
        max: usize,
        /// The length given.
        len: usize,
    },
    /// A field value is out of its range (e.g. LSS identify selector above 5).
    #[error("field {field} has invalid value {value}")]
    InvalidField {
        /// Field name.
        field: &'static str,
        /// The value given.
        value: u32,
    },
    /// The resulting frame is invalid.
    #[error(transparent)]
    Frame(#[from] FrameError),
}

/// Checks that `len` is within `min..=max`.
pub(crate) fn check_len(len: usize, min: usize, max: usize) -> Result<(), EncodeError> {
    if (min..=max).contains(&len) {
        Ok(())
    } else {
        Err(EncodeError::DataLength { min, max, len })
    }
}
