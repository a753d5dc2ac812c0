//! Error types: decoding (the bytes are not a POWERLINK frame we can represent) and encoding
//! (our own misuse: a field value that cannot be put on the wire).

use thiserror::Error;

/// Why a byte sequence is not a valid POWERLINK frame.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum DecodeError {
    /// The frame ends before a field of `what` (lengths count from the first byte of the
    /// Ethernet frame, FCS excluded).
    #[error("{what}: frame too short, needs {needed} bytes, got {got}")]
    TooShort {
        /// The frame part or message that did not fit.
        what: &'static str,
        /// Bytes needed.
        needed: usize,
        /// Bytes present.
        got: usize,
    },
    /// The EtherType (after an optional 802.1Q tag) is not 0x88AB.
    #[error("EtherType {ethertype:#06x} is not POWERLINK (0x88ab)")]
    NotPowerlink {
        /// The EtherType found.
        ethertype: u16,
    },
    /// The message type (low 7 bits of the first EPL byte) is not one POWERLINK defines
    /// (0x01 SoC, 0x03 PReq, 0x04 PRes, 0x05 SoA, 0x06 ASnd, 0x07 AMNI, 0x0D AInv).
    #[error("unknown POWERLINK message type {0:#04x}")]
    UnknownMessageType(u8),
    /// A PReq/PRes announces more payload than the frame holds.
    #[error("{what}: payload size {size} at frame byte {offset} goes beyond the frame ({frame_len} bytes)")]
    PayloadBeyondFrame {
        /// "PReq" or "PRes".
        what: &'static str,
        /// Payload size field.
        size: u16,
        /// Frame offset of the payload.
        offset: usize,
        /// Frame length.
        frame_len: usize,
    },
}

/// Why a frame cannot be encoded (our own misuse, not a bus failure).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum EncodeError {
    /// A numeric field is beyond what its bits can hold.
    #[error("{field} = {value} does not fit (maximum {max})")]
    FieldOutOfRange {
        /// Field name.
        field: &'static str,
        /// Value given.
        value: u64,
        /// Largest value the field can hold.
        max: u64,
    },
    /// A byte field is longer than its room on the wire.
    #[error("{field} is {got} bytes, at most {max} fit")]
    TooLong {
        /// Field name.
        field: &'static str,
        /// Length given.
        got: usize,
        /// Largest length allowed.
        max: usize,
    },
}
