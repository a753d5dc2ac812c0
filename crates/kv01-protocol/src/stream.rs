//! Finding messages in received bytes: [`MessageScanner`] for one direction, and the
//! resynchronising [`StreamDecoder`] over it ([`motus_wire::Stream`]).
//!
//! Messages are delimited by LENGTH (standard) or by their fixed 4-byte form (short:
//! ADDRESS, 'A'..'Z', 'A'..'Z', 0xF0); the scanner never scans for 0xF0 to find an end. On
//! any inconsistency (address not 0xE1..=0xE6, LENGTH below 5, END byte not 0xF0, bad CRC in
//! strict mode, 0xF0 before END in a host -> module message) the decoder drops **one** byte
//! and retries at the next, so it resynchronises after garbage and never loses a valid
//! message that starts after the garbage.
//!
//! A garbage byte that looks like a header with a large LENGTH holds the decoder until that
//! many bytes have arrived. A reader that knows the line has gone quiet (its reply
//! time-out, an idle gap) calls [`motus_wire::Stream::flush`]: everything buffered is then
//! resolved, and an incomplete candidate is dropped byte by byte like any other garbage.

use motus_wire::{Scan, Scanner, Stream};

use crate::frame::{scan, Scan as FrameScan};
use crate::message::{rules, to_decoded};
use crate::{CrcMismatch, CrcMode, DecodeError, Decoded, Direction};

/// A well-formed candidate with a bad CRC, rejected (strict mode).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CrcFailure {
    /// The candidate's address byte.
    pub address: u8,
    /// Expected and received CRC.
    pub mismatch: CrcMismatch,
}

/// What a KV-01 stream decoder reports.
pub type StreamEvent = motus_wire::StreamEvent<Decoded, CrcFailure>;

/// Streaming decoder of one direction: `StreamDecoder::new(MessageScanner::replies(mode))`
/// on the host side, [`MessageScanner::requests`] in a simulator.
pub type StreamDecoder = Stream<MessageScanner>;

/// Finds one message travelling in a direction, with a CRC mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MessageScanner {
    direction: Direction,
    mode: CrcMode,
}

impl MessageScanner {
    /// A scanner of messages travelling in `direction` ([`Direction::Auto`] guesses per
    /// message and accepts short messages).
    #[must_use]
    pub const fn new(direction: Direction, mode: CrcMode) -> Self {
        Self { direction, mode }
    }

    /// Module -> host messages (the host side).
    #[must_use]
    pub const fn replies(mode: CrcMode) -> Self {
        Self::new(Direction::FromModule, mode)
    }

    /// Host -> module messages (the simulator side).
    #[must_use]
    pub const fn requests(mode: CrcMode) -> Self {
        Self::new(Direction::ToModule, mode)
    }
}

impl Scanner for MessageScanner {
    type Frame = Decoded;
    type Error = CrcFailure;

    fn scan(&self, buf: &[u8]) -> Scan<Decoded, CrcFailure> {
        match scan(buf, rules(self.direction, self.mode)) {
            FrameScan::NeedMore { .. } => Scan::Incomplete,
            FrameScan::Invalid(DecodeError::Crc { expected, received }) => Scan::Corrupt(CrcFailure {
                address: buf.first().copied().unwrap_or_default(),
                mismatch: CrcMismatch { expected, received },
            }),
            FrameScan::Invalid(_) => Scan::Skip,
            FrameScan::Frame(framed) => {
                Scan::Frame { frame: to_decoded(&framed, self.direction), len: framed.len }
            }
        }
    }
}
