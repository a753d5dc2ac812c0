//! [`Scan`] and [`Scanner`]: how a codec says what the bytes at the start of a buffer are.
//!
//! One scanner per frame type is all a codec writes to find its frames in received bytes:
//! the resynchronising [`crate::Stream`] decoder and the serial bus master both drive it.

use std::convert::Infallible;

/// Outcome of looking for one frame at the start of a buffer.
///
/// `Skip` and `Corrupt` both mean "drop the first byte and look again at the next one", so
/// that a real frame starting inside a false or damaged candidate is still found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Scan<F, E = Infallible> {
    /// A valid frame occupying the first `len` bytes.
    Frame {
        /// The frame.
        frame: F,
        /// Its length in bytes (at least 1).
        len: usize,
    },
    /// Consistent so far: more bytes are needed to decide.
    Incomplete,
    /// The first byte cannot start a frame: it is garbage.
    Skip,
    /// The bytes have a frame's shape but fail its integrity check (checksum, CRC) or do
    /// not decode; `E` says how. Counted as a corrupt frame, its first byte as garbage.
    Corrupt(E),
}

/// A codec's frame finder: looks at the start of a buffer, never panics, keeps no state
/// between calls (configuration only, e.g. a CRC mode or protocol revision).
pub trait Scanner {
    /// The decoded frame.
    type Frame;
    /// What a corrupt candidate reports ([`Infallible`] for a protocol without integrity
    /// check).
    type Error;

    /// Looks for a frame at the start of `buf`.
    fn scan(&self, buf: &[u8]) -> Scan<Self::Frame, Self::Error>;
}

impl<S: Scanner + ?Sized> Scanner for &S {
    type Frame = S::Frame;
    type Error = S::Error;
    fn scan(&self, buf: &[u8]) -> Scan<S::Frame, S::Error> {
        (**self).scan(buf)
    }
}
