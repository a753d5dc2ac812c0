//! Decoding and encoding errors, each naming what was wrong.

/// A frame could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// Fewer bytes than the frame needs.
    #[error("frame too short: need {needed} bytes, got {got}")]
    TooShort {
        /// Bytes needed.
        needed: usize,
        /// Bytes present.
        got: usize,
    },
    /// More bytes than the frame's length field says.
    #[error("frame too long: N = {declared} implies {expected} bytes, got {got}")]
    TooLong {
        /// The N byte.
        declared: u8,
        /// Frame length N implies.
        expected: usize,
        /// Bytes present.
        got: usize,
    },
    /// The command code is not one of 0..=10.
    #[error("unknown command code {0} (valid codes are 0..=10)")]
    UnknownCode(u8),
    /// N does not match the number of parameters of the command.
    #[error("wrong length for command {code} ({name}): N = {declared}, the command takes {expected} parameter bytes")]
    WrongParameterCount {
        /// Command code.
        code: u8,
        /// Command name.
        name: &'static str,
        /// The N byte.
        declared: u8,
        /// Parameter bytes the command takes.
        expected: u8,
    },
    /// A status reply must have N = 5.
    #[error("wrong length byte in status reply: N = {0}, expected 5")]
    WrongReplyLength(u8),
    /// The checksum does not match.
    #[error("checksum error: expected 0x{expected:02X}, received 0x{received:02X}")]
    Checksum {
        /// Sum computed over the received bytes.
        expected: u8,
        /// Checksum byte received.
        received: u8,
    },
    /// A parameter is outside its valid range.
    #[error("invalid parameter {name} = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name from the spec.
        name: &'static str,
        /// Raw value.
        value: u32,
        /// Valid range.
        reason: &'static str,
    },
}

/// A frame could not be encoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EncodeError {
    /// The output buffer is too small.
    #[error("output buffer too small: need {needed} bytes, have {have}")]
    BufferTooSmall {
        /// Bytes needed.
        needed: usize,
        /// Bytes available.
        have: usize,
    },
}
