//! [`Stream`]: the one resynchronising stream decoder, over any codec's [`Scanner`].
//!
//! Bytes are pushed in chunks of any size (with garbage, on a noisy line); events come out:
//! frames, the garbage skipped before them, and corrupt candidates. After any inconsistency
//! the decoder drops **one** byte and looks again, so it never loses a valid frame that
//! starts inside garbage or inside a damaged candidate. It never panics.
//!
//! A candidate that is consistent but incomplete (e.g. a garbage header announcing a long
//! frame) holds the decoder until enough bytes arrive. A reader that knows the line went
//! quiet (an idle gap, a reply time-out) calls [`Stream::flush`]: the buffered bytes are
//! then resolved, an incomplete candidate dropped byte by byte like any other garbage.

use crate::scan::{Scan, Scanner};
use crate::stats::StreamStats;
use std::convert::Infallible;

/// What a [`Stream`] reports.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StreamEvent<F, E = Infallible> {
    /// A valid frame.
    Frame(F),
    /// `bytes` bytes were skipped as garbage since the previous event (reported before the
    /// next frame, or when the decoder runs out of bytes).
    Garbage {
        /// Number of bytes skipped.
        bytes: usize,
    },
    /// A frame-shaped candidate failed its integrity check (checksum, CRC) or did not
    /// decode. Its first byte is counted as garbage and the bytes after it are examined
    /// again.
    Corrupt(E),
}

/// A resynchronising stream decoder over the scanner `S` (see the module documentation).
#[derive(Debug, Clone)]
pub struct Stream<S> {
    scanner: S,
    buf: Vec<u8>,
    start: usize,
    pending_garbage: usize,
    idle: bool,
    stats: StreamStats,
}

impl<S: Scanner + Default> Default for Stream<S> {
    fn default() -> Self {
        Stream::new(S::default())
    }
}

impl<S: Scanner> Stream<S> {
    /// An empty decoder finding frames with `scanner`.
    pub fn new(scanner: S) -> Self {
        Stream {
            scanner,
            buf: Vec::new(),
            start: 0,
            pending_garbage: 0,
            idle: false,
            stats: StreamStats::default(),
        }
    }

    /// The scanner.
    pub fn scanner(&self) -> &S {
        &self.scanner
    }

    /// The scanner, to change its configuration (e.g. a protocol revision).
    pub fn scanner_mut(&mut self) -> &mut S {
        &mut self.scanner
    }

    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        if self.start > 0 {
            self.buf.drain(..self.start.min(self.buf.len()));
            self.start = 0;
        }
        self.buf.extend_from_slice(bytes);
        self.stats.bytes_in += bytes.len() as u64;
        self.idle = false;
    }

    /// Tells the decoder the line is quiet: no more bytes will complete what is buffered.
    /// The next calls to [`Stream::next_event`] resolve the whole buffer (until more bytes
    /// are pushed).
    pub fn flush(&mut self) {
        self.idle = true;
    }

    /// Drops the buffered bytes, counted as garbage (e.g. after a bus time-out: a partial
    /// frame will not be completed); keeps the statistics.
    pub fn clear(&mut self) {
        self.stats.garbage_bytes += self.pending() as u64;
        self.buf.clear();
        self.start = 0;
        self.pending_garbage = 0;
        self.idle = false;
    }

    /// Bytes buffered and not yet resolved.
    pub fn pending(&self) -> usize {
        self.buf.len().saturating_sub(self.start)
    }

    /// Totals so far.
    pub fn stats(&self) -> StreamStats {
        self.stats
    }

    fn skip_one(&mut self) {
        self.start += 1;
        self.pending_garbage += 1;
        self.stats.garbage_bytes += 1;
    }

    fn take_garbage(&mut self) -> Option<StreamEvent<S::Frame, S::Error>> {
        let bytes = std::mem::take(&mut self.pending_garbage);
        (bytes > 0).then_some(StreamEvent::Garbage { bytes })
    }

    /// The next event, or `None` when more bytes are needed.
    pub fn next_event(&mut self) -> Option<StreamEvent<S::Frame, S::Error>> {
        loop {
            let avail = self.buf.get(self.start..).unwrap_or_default();
            if avail.is_empty() {
                return self.take_garbage();
            }
            let available = avail.len();
            match self.scanner.scan(avail) {
                Scan::Incomplete if !self.idle => return self.take_garbage(),
                Scan::Incomplete | Scan::Skip => self.skip_one(),
                Scan::Corrupt(error) => {
                    self.skip_one();
                    self.stats.corrupt_frames += 1;
                    return Some(StreamEvent::Corrupt(error));
                }
                Scan::Frame { frame, len } => {
                    if self.pending_garbage > 0 {
                        // The frame is found again by the next call.
                        return self.take_garbage();
                    }
                    let len = len.clamp(1, available);
                    self.start += len;
                    self.stats.frames += 1;
                    self.stats.frame_bytes += len as u64;
                    return Some(StreamEvent::Frame(frame));
                }
            }
        }
    }

    /// The next frame, skipping the other events (they still count in [`Stream::stats`]).
    pub fn next_frame(&mut self) -> Option<S::Frame> {
        loop {
            if let StreamEvent::Frame(frame) = self.next_event()? {
                return Some(frame);
            }
        }
    }
}

/// Yields [`Stream::next_event`]. `None` only means "push more bytes": iterating again
/// after a [`Stream::push`] yields more (the iterator is not fused).
impl<S: Scanner> Iterator for Stream<S> {
    type Item = StreamEvent<S::Frame, S::Error>;
    fn next(&mut self) -> Option<Self::Item> {
        self.next_event()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    /// Frames `[0xA5, n, n bytes..., sum]`: the sum of the payload bytes, wrapping.
    #[derive(Debug, Default)]
    struct Sum;

    impl Scanner for Sum {
        type Frame = Vec<u8>;
        type Error = u8;
        fn scan(&self, buf: &[u8]) -> Scan<Vec<u8>, u8> {
            match buf {
                [] | [0xA5] => Scan::Incomplete,
                [0xA5, n, rest @ ..] => {
                    let n = usize::from(*n);
                    let Some((&sum, payload)) = rest.get(..=n).and_then(<[u8]>::split_last) else {
                        return Scan::Incomplete;
                    };
                    if payload.iter().fold(0u8, |a, b| a.wrapping_add(*b)) == sum {
                        Scan::Frame { frame: payload.to_vec(), len: n + 3 }
                    } else {
                        Scan::Corrupt(sum)
                    }
                }
                _ => Scan::Skip,
            }
        }
    }

    fn events(s: &mut Stream<Sum>) -> Vec<StreamEvent<Vec<u8>, u8>> {
        s.by_ref().collect()
    }

    #[test]
    fn garbage_is_reported_before_the_next_frame_in_any_chunking() {
        let bytes = [0x00, 0x11, 0xA5, 0x02, 1, 2, 3, 0xA5];
        for chunk in 1..=bytes.len() {
            let mut s = Stream::new(Sum);
            let mut got = Vec::new();
            for c in bytes.chunks(chunk) {
                s.push(c);
                got.extend(events(&mut s));
            }
            // Garbage comes out when the decoder runs out of bytes or before the frame.
            let (frame_at, garbage) = got.iter().enumerate().fold((None, 0), |(f, g), (i, e)| match e {
                StreamEvent::Frame(v) => (Some((i, v.clone())), g),
                StreamEvent::Garbage { bytes } if f.is_none() => (f, g + bytes),
                _ => (f, g),
            });
            assert_eq!(frame_at, Some((got.len() - 1, vec![1, 2])), "chunk {chunk}: {got:?}");
            assert_eq!(garbage, 2, "chunk {chunk}");
            let st = s.stats();
            assert_eq!(st.bytes_in, st.frame_bytes + st.garbage_bytes + s.pending() as u64);
            assert_eq!((st.frames, st.frame_bytes, s.pending()), (1, 5, 1));
        }
    }

    #[test]
    fn a_corrupt_candidate_drops_one_byte_and_a_frame_inside_it_is_found() {
        // A damaged candidate whose payload holds a real frame.
        let mut s = Stream::new(Sum);
        s.push(&[0xA5, 0x03, 0xA5, 0x01, 7, 7, 0xA5]);
        let ev = events(&mut s);
        assert_eq!(
            ev,
            vec![StreamEvent::Corrupt(7), StreamEvent::Garbage { bytes: 2 }, StreamEvent::Frame(vec![7])]
        );
        assert_eq!(s.stats().corrupt_frames, 1);
        assert_eq!(s.pending(), 1);
    }

    #[test]
    fn an_incomplete_candidate_waits_until_flush() {
        // 0xA5 0xFF announces a long frame; a real one follows.
        let mut s = Stream::new(Sum);
        s.push(&[0xA5, 0xFF, 0xA5, 0x01, 9, 9]);
        assert_eq!(events(&mut s), vec![]);
        s.flush();
        assert_eq!(events(&mut s), vec![StreamEvent::Garbage { bytes: 2 }, StreamEvent::Frame(vec![9])]);
        s.push(&[0xA5, 0x03]);
        s.flush();
        assert_eq!(events(&mut s), vec![StreamEvent::Garbage { bytes: 2 }]);
        s.push(&[0xA5]);
        s.clear();
        let st = s.stats();
        assert_eq!((st.garbage_bytes, s.pending()), (5, 0));
        assert_eq!(st.bytes_in, st.frame_bytes + st.garbage_bytes);
    }
}
