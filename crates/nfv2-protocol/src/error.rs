//! Typed errors: one enum for decoding (bytes from a wire) and one for encoding (our own
//! frames, i.e. caller misuse).
//!
//! Blame is explicit. Every [`DecodeError`] is a bus / framing problem or a frame the peer
//! built in a way this revision's table does not accept; the device never "refuses"
//! anything at this layer (NFv2 has no error replies). Every [`EncodeError`] is a misuse by
//! the caller (value out of range, command unknown in the chosen revision, frame too long).

use crate::code::CommandCode;
use crate::revision::Revision;
use crate::value::ValueKind;

/// Why a byte sequence is not a valid NFv2 frame.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// Byte 0 is not the start byte `'#'` (0x23).
    #[error("bad start byte {found:#04x} (expected '#' = 0x23)")]
    BadStart {
        /// The byte found at offset 0.
        found: u8,
    },
    /// Byte 2 is not the bitwise NOT of byte 1.
    #[error("length byte n = {n:#04x} does not match its complement {complement:#04x} (expected {:#04x})", !n)]
    Length {
        /// Byte 1: index of the last (CRC) byte.
        n: u8,
        /// Byte 2: should be `!n`.
        complement: u8,
    },
    /// `n <= 3`: receivers accept n > 3 only (the smallest frame is `'#' n ~n addr crc`).
    #[error("length byte n = {n} is too small (receivers accept n > 3 only)")]
    TooShort {
        /// Byte 1.
        n: u8,
    },
    /// Fewer bytes than the header announces.
    #[error("frame truncated: expected {expected} bytes, got {received}")]
    Truncated {
        /// Bytes needed (at least).
        expected: usize,
        /// Bytes available.
        received: usize,
    },
    /// More bytes than the header announces (a single frame was expected).
    #[error("{} trailing bytes after the frame: expected {expected} bytes, got {received}", received.saturating_sub(*expected))]
    TrailingBytes {
        /// `n + 1`.
        expected: usize,
        /// Bytes given.
        received: usize,
    },
    /// The CRC byte does not match the CRC-8 of bytes 3..n-1.
    #[error("CRC mismatch: computed {expected:#04x}, frame carries {received:#04x}")]
    Crc {
        /// CRC-8 computed over bytes 3..n-1.
        expected: u8,
        /// Byte n.
        received: u8,
    },
    /// A command code is the last byte before the CRC: its length byte `k` is missing.
    #[error("command {code:#04x} at offset {offset} has no length byte")]
    MissingLength {
        /// Offset of the code byte in the frame.
        offset: usize,
        /// The code byte.
        code: u8,
    },
    /// A command's `k` runs past the end of the frame (its length cannot be trusted, so
    /// decoding stops here).
    #[error("command {code:#04x} at offset {offset} announces {len} parameter bytes, only {available} left")]
    CommandOverrun {
        /// Offset of the code byte in the frame.
        offset: usize,
        /// The code byte.
        code: u8,
        /// Its `k`.
        len: u8,
        /// Parameter bytes left before the CRC.
        available: usize,
    },
    /// `k` is not a multiple of the command's value width: the last value is cut
    /// (typically a device of another [`Revision`]).
    #[error("truncated value for {code}: {len} parameter bytes is not a multiple of the {width}-byte value ({revision})")]
    TruncatedValue {
        /// The command.
        code: CommandCode,
        /// Its `k`.
        len: u8,
        /// Bytes per value in `revision`.
        width: usize,
        /// The revision used to decode.
        revision: Revision,
    },
}

/// Why a frame could not be encoded.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EncodeError {
    /// The encoded frame would exceed 256 bytes (n must fit in one byte).
    #[error("frame of {len} bytes exceeds the 256-byte maximum")]
    FrameTooLong {
        /// Encoded length it would have.
        len: usize,
    },
    /// A command would carry more than 255 parameter bytes (k is one byte).
    #[error("command {code} carries {len} parameter bytes, more than 255")]
    CommandTooLong {
        /// The command.
        code: CommandCode,
        /// Its parameter bytes.
        len: usize,
    },
    /// A value does not fit the command's width in the chosen revision.
    #[error("value {value} out of range for {code} ({kind})")]
    ValueOutOfRange {
        /// The command.
        code: CommandCode,
        /// The offending value.
        value: i64,
        /// The kind it must fit.
        kind: ValueKind,
    },
    /// The chosen revision defines no value width for this code: send it as
    /// [`Command::Unknown`](crate::Command::Unknown) with raw bytes, or as a query.
    #[error("{code} has no value width in {revision}")]
    NoWidth {
        /// The command.
        code: CommandCode,
        /// The revision used to encode.
        revision: Revision,
    },
    /// Integer values given for a regulator command, or regulators for an integer one.
    #[error("{code} takes {kind} values")]
    PayloadMismatch {
        /// The command.
        code: CommandCode,
        /// The kind it takes.
        kind: ValueKind,
    },
    /// The output buffer of `encode_into` is too small.
    #[error("buffer of {available} bytes too small, {needed} needed")]
    BufferTooSmall {
        /// Bytes the frame needs.
        needed: usize,
        /// Bytes given.
        available: usize,
    },
}
