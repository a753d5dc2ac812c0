//! Streaming decoder: bytes pushed in arbitrary chunks, typed messages out.
//!
//! Messages are delimited by LENGTH (standard) or by their fixed 4-byte form (short:
//! ADDRESS, 'A'..'Z', 'A'..'Z', 0xF0); the decoder never scans for 0xF0 to find an end. On
//! any inconsistency (address not 0xE1..=0xE6, LENGTH below 5, END byte not 0xF0, bad CRC in
//! strict mode, 0xF0 before END in a host -> module message) it drops **one** byte and
//! retries at the next, so it resynchronises after garbage and never loses a valid message
//! that starts after the garbage.
//!
//! A garbage byte that looks like a header with a large LENGTH holds the decoder until that
//! many bytes have arrived. A bus master that knows the line has gone quiet (its reply
//! time-out) calls [`StreamDecoder::flush`]: everything buffered is then resolved, and an
//! incomplete candidate is dropped byte by byte like any other garbage.

use serde::{Deserialize, Serialize};

use crate::frame::{scan, Scan};
use crate::message::{rules, to_decoded};
use crate::{CrcMismatch, CrcMode, DecodeError, Decoded, Direction};

/// What the decoder reports.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StreamEvent {
    /// A message.
    Frame(Decoded),
    /// `bytes` bytes were skipped as garbage since the previous event (reported before the
    /// next message, or when the decoder runs out of data).
    Garbage {
        /// Number of bytes skipped.
        bytes: usize,
    },
    /// A well-formed candidate with a bad CRC was rejected (strict mode). Its first byte is
    /// counted as garbage and the bytes after it are examined again.
    CrcFailure {
        /// The candidate's address byte.
        address: u8,
        /// Expected and received CRC.
        mismatch: CrcMismatch,
    },
}

/// Running totals since the decoder was created (for a bus master's error counters).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct StreamStats {
    /// Messages decoded.
    pub frames: u64,
    /// Bytes skipped as garbage.
    pub garbage_bytes: u64,
    /// Candidates rejected for a bad CRC (strict mode).
    pub crc_failures: u64,
    /// Messages accepted with a bad CRC (lenient mode).
    pub crc_mismatches_accepted: u64,
}

/// Streaming decoder for one direction (use [`StreamDecoder::replies`] on the host side and
/// [`StreamDecoder::requests`] in a simulator).
#[derive(Debug, Clone)]
pub struct StreamDecoder {
    direction: Direction,
    mode: CrcMode,
    buf: Vec<u8>,
    start: usize,
    pending_garbage: usize,
    idle: bool,
    stats: StreamStats,
}

impl StreamDecoder {
    /// A decoder for messages travelling in `direction` ([`Direction::Auto`] guesses per
    /// message and accepts short messages).
    #[must_use]
    pub fn new(direction: Direction, mode: CrcMode) -> Self {
        Self {
            direction,
            mode,
            buf: Vec::with_capacity(512),
            start: 0,
            pending_garbage: 0,
            idle: false,
            stats: StreamStats::default(),
        }
    }

    /// A decoder for module -> host messages (the host side).
    #[must_use]
    pub fn replies(mode: CrcMode) -> Self {
        Self::new(Direction::FromModule, mode)
    }

    /// A decoder for host -> module messages (the simulator side).
    #[must_use]
    pub fn requests(mode: CrcMode) -> Self {
        Self::new(Direction::ToModule, mode)
    }

    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        if self.start > 0 {
            self.buf.drain(..self.start);
            self.start = 0;
        }
        self.buf.extend_from_slice(bytes);
        self.idle = false;
    }

    /// Tells the decoder the line is idle: no more bytes will complete what is buffered.
    /// The next calls to [`Self::next_event`] resolve the whole buffer (until more bytes are
    /// pushed).
    pub fn flush(&mut self) {
        self.idle = true;
    }

    /// Drops everything buffered (not counted as garbage); keeps the statistics.
    pub fn clear(&mut self) {
        self.buf.clear();
        self.start = 0;
        self.pending_garbage = 0;
        self.idle = false;
    }

    /// Bytes buffered but not yet consumed.
    #[must_use]
    pub fn buffered(&self) -> usize {
        self.buf.len().saturating_sub(self.start)
    }

    /// Totals so far.
    #[must_use]
    pub fn stats(&self) -> StreamStats {
        self.stats
    }

    fn take_garbage(&mut self) -> Option<StreamEvent> {
        let bytes = std::mem::take(&mut self.pending_garbage);
        (bytes > 0).then_some(StreamEvent::Garbage { bytes })
    }

    fn skip_one(&mut self) {
        self.start += 1;
        self.pending_garbage += 1;
        self.stats.garbage_bytes += 1;
    }

    /// The next event, or `None` when more bytes are needed.
    pub fn next_event(&mut self) -> Option<StreamEvent> {
        let rules = rules(self.direction, self.mode);
        loop {
            let avail = self.buf.get(self.start..).unwrap_or_default();
            match scan(avail, rules) {
                Scan::NeedMore { .. } if !self.idle || avail.is_empty() => {
                    return self.take_garbage();
                }
                Scan::NeedMore { .. } => self.skip_one(),
                Scan::Invalid(DecodeError::Crc { expected, received }) => {
                    let address = avail.first().copied().unwrap_or_default();
                    self.skip_one();
                    self.stats.crc_failures += 1;
                    return Some(StreamEvent::CrcFailure {
                        address,
                        mismatch: CrcMismatch { expected, received },
                    });
                }
                Scan::Invalid(_) => self.skip_one(),
                Scan::Frame(framed) => {
                    if self.pending_garbage > 0 {
                        let bytes = std::mem::take(&mut self.pending_garbage);
                        return Some(StreamEvent::Garbage { bytes });
                    }
                    let decoded = to_decoded(&framed, self.direction);
                    self.start += framed.len;
                    self.stats.frames += 1;
                    if decoded.crc_mismatch.is_some() {
                        self.stats.crc_mismatches_accepted += 1;
                    }
                    return Some(StreamEvent::Frame(decoded));
                }
            }
        }
    }

    /// The next message, skipping the other events (they still count in [`Self::stats`]).
    pub fn next_frame(&mut self) -> Option<Decoded> {
        loop {
            match self.next_event()? {
                StreamEvent::Frame(d) => return Some(d),
                StreamEvent::Garbage { .. } | StreamEvent::CrcFailure { .. } => {}
            }
        }
    }
}

/// Yields [`StreamDecoder::next_event`]. `None` only means "push more bytes": iterating again
/// after a [`StreamDecoder::push`] yields more (the iterator is not fused).
impl Iterator for StreamDecoder {
    type Item = StreamEvent;
    fn next(&mut self) -> Option<StreamEvent> {
        self.next_event()
    }
}
