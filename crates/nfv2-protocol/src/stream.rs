//! Finding frames in a noisy byte stream (RS-485, USB, radio): [`FrameScanner`], and the
//! resynchronising [`StreamDecoder`] over it ([`motus_wire::Stream`]).
//!
//! NFv2 marks a frame start by `'#'` followed by `n` and `!n`, not by line silence,
//! because the protocol also runs over noisy radio links. At the start of a buffer:
//!
//! 1. a byte other than `'#'` is garbage;
//! 2. `'#'` must be followed by `n, !n`; if they do not match (or `n <= 3`) the `'#'` was
//!    noise (garbage);
//! 3. the `n + 1` bytes of the candidate frame must pass the CRC; a bad CRC is a corrupt
//!    candidate: the decoder counts it and skips **one** byte (the `'#'`), so a real frame
//!    starting inside the bad candidate is still found;
//! 4. the commands are split with the [`Revision`] set for the frame's address; a frame
//!    whose CRC is good but whose commands cannot be split is also a corrupt candidate
//!    (its [`DecodeError`] says why), resynchronised by one byte.
//!
//! Bytes can be pushed in chunks of any size; at most one partial frame (< 256 bytes) is
//! kept between pushes. The decoder never panics.

use motus_wire::{Scan, Scanner, Stream};

use crate::error::DecodeError;
use crate::frame::{Frame, RawFrame, START};
use crate::revision::Revision;

/// What an NFv2 stream decoder reports; a corrupt candidate carries its [`DecodeError`]
/// (a bad CRC, or commands that cannot be split).
pub type StreamEvent = motus_wire::StreamEvent<Frame, DecodeError>;

/// Incremental NFv2 frame finder: `StreamDecoder::default()` (latest revision) or
/// `StreamDecoder::new(FrameScanner::new(rev))`.
pub type StreamDecoder = Stream<FrameScanner>;

/// Finds one frame, splitting its commands with the revision of its address.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameScanner {
    revisions: [Revision; 256],
}

impl Default for FrameScanner {
    fn default() -> Self {
        Self::new(Revision::LATEST)
    }
}

impl FrameScanner {
    /// A scanner using `rev` for every address.
    #[must_use]
    pub fn new(rev: Revision) -> Self {
        FrameScanner { revisions: [rev; 256] }
    }

    /// Uses `rev` for frames from / to `address` (devices may differ in revision).
    pub fn set_address_revision(&mut self, address: u8, rev: Revision) {
        if let Some(slot) = self.revisions.get_mut(usize::from(address)) {
            *slot = rev;
        }
    }

    /// The revision used for `address`.
    #[must_use]
    pub fn address_revision(&self, address: u8) -> Revision {
        self.revisions.get(usize::from(address)).copied().unwrap_or_default()
    }
}

impl Scanner for FrameScanner {
    type Frame = Frame;
    type Error = DecodeError;

    fn scan(&self, buf: &[u8]) -> Scan<Frame, DecodeError> {
        let Some(&[start, n, complement]) = buf.first_chunk::<3>() else {
            return match buf.first() {
                Some(&b) if b != START => Scan::Skip,
                _ => Scan::Incomplete,
            };
        };
        if start != START || complement != !n || n <= 3 {
            return Scan::Skip;
        }
        let len = usize::from(n) + 1;
        let Some(candidate) = buf.get(..len) else { return Scan::Incomplete };
        match RawFrame::parse(candidate) {
            Ok(raw) => match raw.decode(self.address_revision(raw.address)) {
                Ok(frame) => Scan::Frame { frame, len },
                Err(e) => Scan::Corrupt(e),
            },
            Err(e @ DecodeError::Crc { .. }) => Scan::Corrupt(e),
            Err(_) => Scan::Skip,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // From tests/vectors.rs (CRC by the independent Python script):
    // query ReadDrivesPosition to address 1.
    const QUERY: [u8; 7] = [0x23, 0x06, 0xF9, 0x01, 0x1A, 0x00, 0x20];

    fn frames(d: &mut StreamDecoder) -> usize {
        std::iter::from_fn(|| d.next_frame()).count()
    }

    #[test]
    fn byte_by_byte_with_noise() {
        let mut d = StreamDecoder::default();
        let mut stream = vec![0x00, 0x23, 0x23, 0xFF];
        stream.extend_from_slice(&QUERY);
        stream.extend_from_slice(&[0x55]);
        let mut found = 0;
        for &b in &stream {
            d.push(&[b]);
            found += frames(&mut d);
        }
        assert_eq!(found, 1);
        let s = d.stats();
        assert_eq!(s.frames, 1);
        assert_eq!(s.frame_bytes, 7);
        assert_eq!(s.garbage_bytes + s.frame_bytes + d.pending() as u64, s.bytes_in);
        assert_eq!(d.pending(), 0);
    }

    #[test]
    fn bad_crc_then_good_frame() {
        let mut bad = QUERY;
        bad[6] ^= 0x01;
        let mut stream = bad.to_vec();
        stream.extend_from_slice(&QUERY);
        let mut d = StreamDecoder::default();
        d.push(&stream);
        assert_eq!(frames(&mut d), 1);
        assert_eq!(d.stats().corrupt_frames, 1);
        assert_eq!(d.stats().garbage_bytes, 7);
    }

    #[test]
    fn frame_hidden_inside_a_false_header_is_found() {
        // '#', n = 0x10, !n = 0xEF announces 17 bytes; the real frame starts right after.
        let mut stream = vec![0x23, 0x10, 0xEF];
        stream.extend_from_slice(&QUERY);
        stream.extend_from_slice(&[0u8; 20]);
        let mut d = StreamDecoder::default();
        d.push(&stream);
        assert_eq!(frames(&mut d), 1);
        assert_eq!(d.stats().corrupt_frames, 1);
    }

    #[test]
    fn a_scanner_finds_one_frame_and_flags_bad_crcs() {
        let scanner = FrameScanner::default();
        assert_eq!(scanner.scan(&[0x00]), Scan::Skip);
        assert_eq!(scanner.scan(&QUERY[..2]), Scan::Incomplete);
        assert_eq!(scanner.scan(&QUERY[..6]), Scan::Incomplete);
        assert!(matches!(scanner.scan(&QUERY), Scan::Frame { frame, len: 7 } if frame.address == 1));
        let mut bad = QUERY;
        bad[6] ^= 1;
        assert!(matches!(scanner.scan(&bad), Scan::Corrupt(DecodeError::Crc { .. })));
        // '#' with a wrong complement is not a frame start.
        assert_eq!(scanner.scan(&[0x23, 0x06, 0xF8, 1, 2, 3, 4]), Scan::Skip);
    }
}
