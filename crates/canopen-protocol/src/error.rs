//! The message encoding error (frame construction and candump parsing errors are
//! [`motus_can_frame`]'s).

use motus_can_frame::FrameError;
use thiserror::Error;

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
