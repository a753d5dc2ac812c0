//! The one error type of the codecs: what was wrong with a packet handed to a `decode`.

/// A packet that does not decode. The streaming decoders never return these: they skip
/// the offending byte and resynchronise.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum PacketError {
    /// The slice does not hold exactly one packet.
    #[error("a packet is {expected} bytes, got {received}")]
    Length {
        /// Bytes of one packet of this protocol.
        expected: usize,
        /// Bytes given.
        received: usize,
    },
    /// A converter packet must start with `'a'` (0x61).
    #[error("converter packet must start with 'a' (0x61), got 0x{0:02X}")]
    Start(u8),
    /// A converter packet must end with `'x'` (0x78).
    #[error("converter packet must end with 'x' (0x78), got 0x{0:02X}")]
    End(u8),
    /// A Microsoft packet's first byte must have bit 6 set.
    #[error("Microsoft mouse packet must start with a byte with bit 6 set, got 0x{0:02X}")]
    MicrosoftHeader(u8),
    /// A Microsoft packet's second and third bytes must have bit 6 clear.
    #[error("Microsoft mouse data byte {index} must have bit 6 clear, got 0x{byte:02X}")]
    MicrosoftData {
        /// Position in the packet (1 or 2).
        index: usize,
        /// The byte received.
        byte: u8,
    },
    /// A Mouse Systems packet must start with a byte 0x80..=0x87.
    #[error("Mouse Systems packet must start with 0x80..=0x87, got 0x{0:02X}")]
    MouseSystemsHeader(u8),
}
