//! Error types: one enum for decoding (what came off the wire is not a valid message) and one
//! for encoding (our own misuse: the message asked for cannot be sent).
//!
//! Neither is a device refusal: a module's "UC"/"TO" short messages and its "LSSTOP"/"LIMVAL"
//! answers are valid messages and decode to [`crate::ShortCode`] / [`crate::Answer`] variants.

use thiserror::Error;

/// Why a byte sequence is not a valid KV-01 message (a bus-level failure).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum DecodeError {
    /// Fewer bytes than the smallest message (4 for a short message, 5 for a standard one).
    #[error("message too short: {received} byte(s)")]
    TooShort {
        /// Number of bytes received.
        received: usize,
    },
    /// The first byte is not a module address (0xE1..=0xE6).
    #[error("byte {0:#04x} is not a module address (0xE1..=0xE6)")]
    Address(u8),
    /// The LENGTH byte cannot be the length of a standard message (it must be 5..=255).
    #[error("LENGTH byte {0} is below the minimum standard message length 5")]
    LengthField(u8),
    /// LENGTH does not match the number of bytes given.
    #[error("LENGTH says {expected} bytes, got {received}")]
    Length {
        /// Message length announced by the LENGTH byte.
        expected: usize,
        /// Number of bytes actually given.
        received: usize,
    },
    /// The last byte is not the end byte 0xF0.
    #[error("END byte is {received:#04x}, expected 0xf0")]
    End {
        /// The byte found in the END position.
        received: u8,
    },
    /// The CRC byte is wrong ([`crate::CrcMode::Strict`] only).
    #[error("CRC mismatch: expected {expected:#04x}, received {received:#04x}")]
    Crc {
        /// CRC computed over the received ADDRESS..DATA (after the 0xF0 -> 0xF1 rule).
        expected: u8,
        /// CRC byte found in the message.
        received: u8,
    },
    /// A host -> module message carries 0xF0 before its END byte (a module rejects it).
    #[error("0xf0 at byte offset {offset} before END in a host -> module message")]
    EndInBody {
        /// Offset of the misplaced 0xF0 from the start of the message (ADDRESS = 0).
        offset: usize,
    },
    /// A short message (CM -> host only) was decoded as host -> module.
    #[error("short message form in the host -> module direction")]
    ShortToModule,
}

/// Why a message cannot be encoded (our own misuse, never a device's fault).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum EncodeError {
    /// A host -> module message would contain 0xF0 before its END byte. A module rejects such
    /// a message and may hang until power-cycled, so it is never sent.
    #[error("host -> module message would contain 0xf0 at byte offset {offset} (ADDRESS = 0)")]
    EndInData {
        /// Offset of the 0xF0 from the start of the message (ADDRESS = 0, first data byte = 3).
        offset: usize,
    },
    /// The message would be longer than LENGTH can say (255 bytes, i.e. 250 data bytes).
    #[error("message would be {len} bytes long, the maximum is 255")]
    TooLong {
        /// Length the message would have.
        len: usize,
    },
    /// The output buffer is too small.
    #[error("buffer too small: need {needed} bytes, have {available}")]
    BufferTooSmall {
        /// Bytes the message needs.
        needed: usize,
        /// Bytes available in the buffer.
        available: usize,
    },
    /// A field is out of its range (e.g. a gripper speed above 31).
    #[error("{field} = {value} is out of range (maximum {max})")]
    OutOfRange {
        /// Name of the field.
        field: &'static str,
        /// The value given.
        value: u32,
        /// The largest value allowed.
        max: u32,
    },
    /// Text data holds a character that is not one byte (above U+00FF). Text is sent as
    /// Latin-1: each character is one byte.
    #[error("character {ch:?} at byte offset {offset} does not fit in one byte")]
    NotLatin1 {
        /// The character.
        ch: char,
        /// Offset it would have in the message (ADDRESS = 0).
        offset: usize,
    },
    /// A short message code is not two ASCII capital letters.
    #[error("short message code {0:?} is not two ASCII capital letters")]
    ShortCode([u8; 2]),
    /// A D1 status reply does not fit its address: joint status bits come from 0xE1..=0xE5,
    /// gripper status bits from 0xE6 (the decoder tells them apart by the address).
    #[error("{what} cannot be sent from address {address:#04x}")]
    StatusAddress {
        /// Which status kind was asked for.
        what: &'static str,
        /// The address given.
        address: u8,
    },
    /// A raw reply would read back as a short message (its first four bytes would be
    /// ADDRESS, 'A'..'Z', 'A'..'Z', 0xF0).
    #[error("raw reply would be read back as a short message")]
    LooksShort,
}
