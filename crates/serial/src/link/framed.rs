//! A link whose received bytes go through a codec's stream decoder.

use super::Link;
use motus_wire::{Scanner, Stream};
use std::io;
use std::time::{Duration, Instant};

/// A link read frame by frame with a codec's resynchronising [`Stream`]: what a simple
/// reader uses (a sensor reader, a host tool, the host side of a simulator test) where the
/// request/response [`crate::BusMaster`] does not fit.
pub struct FramedLink<S> {
    link: Box<dyn Link>,
    stream: Stream<S>,
}

impl<S: Scanner> FramedLink<S> {
    /// Reads `link` with `scanner`.
    pub fn new(link: Box<dyn Link>, scanner: S) -> Self {
        FramedLink { link, stream: Stream::new(scanner) }
    }

    /// Writes `bytes`.
    ///
    /// # Errors
    /// An IO error of the link.
    pub fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.link.write_all(bytes)
    }

    /// The next frame, reading until one arrives or `timeout` passes (`None`). Other events
    /// are skipped (they count in the stream's statistics); bytes after the frame stay
    /// buffered for the next call.
    ///
    /// # Errors
    /// An IO error of the link.
    pub fn receive(&mut self, timeout: Duration) -> io::Result<Option<S::Frame>> {
        let deadline = Instant::now() + timeout;
        let mut buf = [0u8; 256];
        loop {
            if let Some(frame) = self.stream.next_frame() {
                return Ok(Some(frame));
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(None);
            }
            let n = self.link.read(&mut buf, left)?;
            self.stream.push(buf.get(..n).unwrap_or_default());
        }
    }

    /// The stream decoder (statistics, buffered bytes).
    pub fn stream(&self) -> &Stream<S> {
        &self.stream
    }

    /// The stream decoder, e.g. to drop a partial frame after a time-out.
    pub fn stream_mut(&mut self) -> &mut Stream<S> {
        &mut self.stream
    }
}
