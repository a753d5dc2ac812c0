//! Finding PS1A frames in received bytes: the scanners of command frames (a module's side
//! of the line) and of status replies (the host's side), and their resynchronising stream
//! decoders ([`motus_wire::Stream`]: after any inconsistency the decoder drops one byte and
//! searches again, so it resynchronises on the next valid frame; it never panics).

use crate::command::CommandFrame;
use crate::error::DecodeError;
use crate::layout::{ADDRESS_INDEX, LENGTH_INDEX};
use crate::reply::StatusReply;
use crate::REPLY_LEN;
use motus_wire::{Scan, Scanner, Stream};

/// A frame-shaped byte sequence whose checksum is wrong. A module answers such a frame to
/// its address with the checksum-error bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChecksumError {
    /// First byte of the sequence (the address).
    pub addr: u8,
    /// Sum computed over the received bytes.
    pub expected: u8,
    /// Checksum byte received.
    pub received: u8,
}

/// What a PS1A stream decoder reports.
pub type StreamEvent<F> = motus_wire::StreamEvent<F, ChecksumError>;

/// Finds command frames (host -> module).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CommandScanner;

impl Scanner for CommandScanner {
    type Frame = CommandFrame;
    type Error = ChecksumError;

    fn scan(&self, buf: &[u8]) -> Scan<CommandFrame, ChecksumError> {
        let len = match CommandFrame::frame_len_from_header(buf) {
            Ok(len) => len,
            Err(DecodeError::TooShort { .. }) => return Scan::Incomplete,
            Err(_) => return Scan::Skip,
        };
        if buf.len() < len {
            return Scan::Incomplete;
        }
        checked(CommandFrame::decode_prefix(buf), len, buf.get(ADDRESS_INDEX))
    }
}

/// Finds status replies (module -> host).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReplyScanner;

impl Scanner for ReplyScanner {
    type Frame = StatusReply;
    type Error = ChecksumError;

    fn scan(&self, buf: &[u8]) -> Scan<StatusReply, ChecksumError> {
        match buf.get(LENGTH_INDEX) {
            None => return Scan::Incomplete,
            Some(&5) => {}
            Some(_) => return Scan::Skip,
        }
        if buf.len() < REPLY_LEN {
            return Scan::Incomplete;
        }
        checked(StatusReply::decode_prefix(buf), REPLY_LEN, buf.first())
    }
}

/// The scan result of a complete candidate of `len` bytes starting with `addr`.
fn checked<F>(decoded: Result<F, DecodeError>, len: usize, addr: Option<&u8>) -> Scan<F, ChecksumError> {
    match decoded {
        Ok(frame) => Scan::Frame { frame, len },
        Err(DecodeError::Checksum { expected, received }) => {
            Scan::Corrupt(ChecksumError { addr: addr.copied().unwrap_or(0), expected, received })
        }
        Err(_) => Scan::Skip,
    }
}

/// Streaming decoder of command frames (the module's side of the line):
/// `CommandStream::default()`.
pub type CommandStream = Stream<CommandScanner>;
/// Streaming decoder of status replies (the host's side of the line):
/// `ReplyStream::default()`.
pub type ReplyStream = Stream<ReplyScanner>;
