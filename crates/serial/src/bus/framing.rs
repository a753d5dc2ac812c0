//! How the bus master finds a reply in received bytes: a protocol plugs in its scanner.

/// Outcome of looking for one reply frame at the start of a buffer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FrameScan<F> {
    /// A valid frame of `len` bytes.
    Frame {
        /// The frame.
        frame: F,
        /// Its length in bytes.
        len: usize,
    },
    /// More bytes are needed.
    Incomplete,
    /// Drop the first byte and look again; `corrupt` is true when the bytes had the shape
    /// of a frame but failed its check (checksum, CRC).
    Skip {
        /// A frame-shaped sequence failed its integrity check.
        corrupt: bool,
    },
}

/// A protocol's reply scanner.
pub trait Framing {
    /// The decoded reply.
    type Frame;
    /// Looks for a reply at the start of `buf`.
    fn scan(&self, buf: &[u8]) -> FrameScan<Self::Frame>;
}

impl<F, T: Fn(&[u8]) -> FrameScan<F>> Framing for T {
    type Frame = F;
    fn scan(&self, buf: &[u8]) -> FrameScan<F> {
        self(buf)
    }
}
