//! Streaming decoders: bytes arrive in arbitrary chunks (and with garbage, on a noisy
//! line); frames come out. After any inconsistency the decoder drops one byte and
//! searches again, so it resynchronises on the next valid frame. It never panics.

use crate::command::CommandFrame;
use crate::error::DecodeError;
use crate::layout::{ADDRESS_INDEX, LENGTH_INDEX};
use crate::reply::StatusReply;
use crate::REPLY_LEN;

/// What a streaming decoder found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StreamEvent<F> {
    /// A valid frame.
    Frame(F),
    /// A frame-shaped byte sequence whose checksum is wrong; `addr` is its first byte
    /// (a module answers such a frame to its address with the checksum-error bit).
    ChecksumError {
        /// First byte of the sequence.
        addr: u8,
        /// Sum computed over the received bytes.
        expected: u8,
        /// Checksum byte received.
        received: u8,
    },
}

/// Outcome of looking for one frame at the start of a buffer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Scan<F> {
    /// A frame of `len` bytes.
    Frame {
        /// The frame.
        frame: F,
        /// Its length.
        len: usize,
    },
    /// More bytes are needed to decide.
    Incomplete,
    /// The first byte cannot start a valid frame: drop it. `checksum` is set when the
    /// bytes had a frame's shape but a wrong checksum.
    Skip {
        /// `(addr, expected, received)` for a checksum failure.
        checksum: Option<(u8, u8, u8)>,
    },
}

/// Looks for a command frame at the start of `buf`.
pub fn scan_command(buf: &[u8]) -> Scan<CommandFrame> {
    let len = match CommandFrame::frame_len_from_header(buf) {
        Ok(len) => len,
        Err(DecodeError::TooShort { .. }) => return Scan::Incomplete,
        Err(_) => return Scan::Skip { checksum: None },
    };
    if buf.len() < len {
        return Scan::Incomplete;
    }
    match CommandFrame::decode_prefix(buf) {
        Ok(frame) => Scan::Frame { frame, len },
        Err(DecodeError::Checksum { expected, received }) => {
            Scan::Skip { checksum: Some((buf.get(ADDRESS_INDEX).copied().unwrap_or(0), expected, received)) }
        }
        Err(_) => Scan::Skip { checksum: None },
    }
}

/// Looks for a status reply at the start of `buf`.
pub fn scan_reply(buf: &[u8]) -> Scan<StatusReply> {
    match buf.get(LENGTH_INDEX) {
        None => return Scan::Incomplete,
        Some(&5) => {}
        Some(_) => return Scan::Skip { checksum: None },
    }
    if buf.len() < REPLY_LEN {
        return Scan::Incomplete;
    }
    match StatusReply::decode_prefix(buf) {
        Ok(frame) => Scan::Frame { frame, len: REPLY_LEN },
        Err(DecodeError::Checksum { expected, received }) => {
            Scan::Skip { checksum: Some((buf.first().copied().unwrap_or(0), expected, received)) }
        }
        Err(_) => Scan::Skip { checksum: None },
    }
}

/// Counters of a streaming decoder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StreamStats {
    /// Valid frames returned.
    pub frames: u64,
    /// Bytes dropped while resynchronising.
    pub garbage_bytes: u64,
    /// Frame-shaped sequences with a wrong checksum.
    pub checksum_errors: u64,
}

/// A resynchronising stream decoder over a scan function.
#[derive(Debug, Clone)]
pub struct Stream<F> {
    buf: Vec<u8>,
    start: usize,
    stats: StreamStats,
    scan: fn(&[u8]) -> Scan<F>,
    max_frame: usize,
}

/// Streaming decoder of command frames (the module's side of the line).
pub type CommandStream = Stream<CommandFrame>;
/// Streaming decoder of status replies (the host's side of the line).
pub type ReplyStream = Stream<StatusReply>;

impl CommandStream {
    /// A decoder for host -> module traffic.
    pub fn commands() -> Self {
        Stream::with_scanner(scan_command, crate::MAX_COMMAND_LEN)
    }
}

impl ReplyStream {
    /// A decoder for module -> host traffic.
    pub fn replies() -> Self {
        Stream::with_scanner(scan_reply, REPLY_LEN)
    }
}

impl<F> Stream<F> {
    fn with_scanner(scan: fn(&[u8]) -> Scan<F>, max_frame: usize) -> Self {
        Stream { buf: Vec::with_capacity(256), start: 0, stats: StreamStats::default(), scan, max_frame }
    }

    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        if self.start > 0 && self.start >= self.buf.len() / 2 {
            self.buf.drain(..self.start);
            self.start = 0;
        }
        self.buf.extend_from_slice(bytes);
    }

    /// The next event, or `None` when more bytes are needed.
    pub fn next_event(&mut self) -> Option<StreamEvent<F>> {
        loop {
            let pending = self.buf.get(self.start..).unwrap_or(&[]);
            if pending.is_empty() {
                return None;
            }
            match (self.scan)(pending) {
                Scan::Frame { frame, len } => {
                    self.start += len;
                    self.stats.frames += 1;
                    return Some(StreamEvent::Frame(frame));
                }
                Scan::Incomplete => return None,
                Scan::Skip { checksum } => {
                    self.start += 1;
                    if let Some((addr, expected, received)) = checksum {
                        self.stats.checksum_errors += 1;
                        return Some(StreamEvent::ChecksumError { addr, expected, received });
                    }
                    self.stats.garbage_bytes += 1;
                }
            }
        }
    }

    /// Drops buffered bytes (e.g. after an idle gap on the line: a partial frame will not
    /// be completed). Counted as garbage.
    pub fn clear(&mut self) {
        self.stats.garbage_bytes += self.pending_len() as u64;
        self.buf.clear();
        self.start = 0;
    }

    /// Bytes waiting for a decision.
    pub fn pending_len(&self) -> usize {
        self.buf.len().saturating_sub(self.start)
    }

    /// Longest frame this decoder accepts.
    pub fn max_frame_len(&self) -> usize {
        self.max_frame
    }

    /// Counters.
    pub fn stats(&self) -> StreamStats {
        self.stats
    }
}
