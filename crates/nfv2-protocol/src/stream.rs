//! Streaming decoder: finds frames in a noisy byte stream (RS-485, USB, radio).
//!
//! NFv2 marks a frame start by `'#'` followed by `n` and `!n`, not by line silence,
//! because the protocol also runs over noisy radio links. The decoder:
//!
//! 1. skips bytes up to the next `'#'` (counted as garbage);
//! 2. waits for `n, !n`; if they do not match (or `n <= 3`) the `'#'` was noise: skip one
//!    byte and search again;
//! 3. waits for the `n + 1` bytes of the candidate frame and checks its CRC; on a bad CRC
//!    it counts a CRC failure, skips **one** byte (the `'#'`) and searches again, so a
//!    real frame starting inside the bad candidate is still found;
//! 4. splits the commands with the [`Revision`] set for the frame's address; a frame
//!    whose CRC is good but whose commands cannot be split is reported as an error item,
//!    counted as malformed, and also resynchronised by one byte.
//!
//! Bytes can be pushed in chunks of any size; at most one partial frame (< 256 bytes) is
//! kept between pushes. The decoder never panics.

use crate::error::DecodeError;
use crate::frame::{Frame, RawFrame, START};
use crate::revision::Revision;

/// Counters of a [`StreamDecoder`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamStats {
    /// Bytes pushed so far.
    pub bytes_in: u64,
    /// Frames decoded.
    pub frames: u64,
    /// Bytes of the decoded frames.
    pub frame_bytes: u64,
    /// Bytes discarded (noise, bad headers, the skipped start byte of rejected candidates).
    pub garbage_bytes: u64,
    /// Candidates (`'#' n !n` and `n + 1` bytes) whose CRC did not match.
    pub crc_errors: u64,
    /// Candidates with a good CRC whose commands could not be split.
    pub malformed: u64,
}

/// Incremental NFv2 frame finder. See the module documentation.
#[derive(Clone, Debug)]
pub struct StreamDecoder {
    buf: Vec<u8>,
    revisions: [Revision; 256],
    stats: StreamStats,
}

impl Default for StreamDecoder {
    fn default() -> Self {
        Self::new(Revision::LATEST)
    }
}

impl StreamDecoder {
    /// A decoder using `rev` for every address.
    #[must_use]
    pub fn new(rev: Revision) -> Self {
        StreamDecoder { buf: Vec::with_capacity(512), revisions: [rev; 256], stats: StreamStats::default() }
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

    /// Counters so far.
    #[must_use]
    pub fn stats(&self) -> StreamStats {
        self.stats
    }

    /// Bytes held back as the start of a possible frame.
    #[must_use]
    pub fn pending(&self) -> usize {
        self.buf.len()
    }

    /// Drops any partial frame (e.g. after a bus time-out); the counters are kept and
    /// the dropped bytes are counted as garbage.
    pub fn reset(&mut self) {
        self.stats.garbage_bytes += self.buf.len() as u64;
        self.buf.clear();
    }

    /// Pushes received bytes; returns the frames completed by them, in order. An `Err`
    /// item is a frame with a good CRC whose commands could not be split (see
    /// [`DecodeError`]); noise and CRC failures are only counted in [`StreamStats`].
    pub fn push(&mut self, bytes: &[u8]) -> Vec<Result<Frame, DecodeError>> {
        let mut out = Vec::new();
        self.push_with(bytes, |item| out.push(item));
        out
    }

    /// As [`StreamDecoder::push`], handing each item to `sink` instead of collecting them.
    pub fn push_with(&mut self, bytes: &[u8], mut sink: impl FnMut(Result<Frame, DecodeError>)) {
        self.stats.bytes_in += bytes.len() as u64;
        self.buf.extend_from_slice(bytes);
        let mut pos = 0;
        loop {
            let rest = self.buf.get(pos..).unwrap_or_default();
            let Some(skip) = rest.iter().position(|&b| b == START) else {
                self.stats.garbage_bytes += rest.len() as u64;
                pos = self.buf.len();
                break;
            };
            self.stats.garbage_bytes += skip as u64;
            pos += skip;
            let rest = self.buf.get(pos..).unwrap_or_default();
            let Some(&[_, n, complement]) = rest.first_chunk::<3>() else {
                break; // wait for n and !n
            };
            if complement != !n || n <= 3 {
                self.stats.garbage_bytes += 1;
                pos += 1;
                continue;
            }
            let Some(candidate) = rest.get(..=usize::from(n)) else {
                break; // wait for the rest of the candidate frame
            };
            let total = candidate.len();
            match RawFrame::parse(candidate) {
                Ok(raw) => match raw.decode(self.address_revision(raw.address)) {
                    Ok(frame) => {
                        self.stats.frames += 1;
                        self.stats.frame_bytes += total as u64;
                        pos += total;
                        sink(Ok(frame));
                    }
                    Err(e) => {
                        self.stats.malformed += 1;
                        self.stats.garbage_bytes += 1;
                        pos += 1;
                        sink(Err(e));
                    }
                },
                Err(e) => {
                    if matches!(e, DecodeError::Crc { .. }) {
                        self.stats.crc_errors += 1;
                    }
                    self.stats.garbage_bytes += 1;
                    pos += 1;
                }
            }
        }
        self.buf.drain(..pos.min(self.buf.len()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // From tests/vectors.rs (CRC by the independent Python script):
    // query ReadDrivesPosition to address 1.
    const QUERY: [u8; 7] = [0x23, 0x06, 0xF9, 0x01, 0x1A, 0x00, 0x20];

    #[test]
    fn byte_by_byte_with_noise() {
        let mut d = StreamDecoder::default();
        let mut stream = vec![0x00, 0x23, 0x23, 0xFF];
        stream.extend_from_slice(&QUERY);
        stream.extend_from_slice(&[0x55]);
        let mut frames = Vec::new();
        for &b in &stream {
            frames.extend(d.push(&[b]));
        }
        assert_eq!(frames.len(), 1);
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
        let frames = d.push(&stream);
        assert_eq!(frames.len(), 1);
        assert_eq!(d.stats().crc_errors, 1);
        assert_eq!(d.stats().garbage_bytes, 7);
    }

    #[test]
    fn frame_hidden_inside_a_false_header_is_found() {
        // '#', n = 0x10, !n = 0xEF announces 17 bytes; the real frame starts right after.
        let mut stream = vec![0x23, 0x10, 0xEF];
        stream.extend_from_slice(&QUERY);
        stream.extend_from_slice(&[0u8; 20]);
        let mut d = StreamDecoder::default();
        let frames = d.push(&stream);
        assert_eq!(frames.len(), 1);
        assert_eq!(d.stats().crc_errors, 1);
    }
}
