//! A link whose received bytes go through a codec's stream decoder.

use super::Link;
use motus_clock::{SharedClock, SystemClock};
use motus_wire::{Scanner, Stream};
use std::io;
use std::time::Duration;

/// A link read frame by frame with a codec's resynchronising [`Stream`]: what a simple
/// reader uses (a sensor reader, a host tool, the host side of a simulator test) where the
/// request/response [`crate::BusMaster`] does not fit. Time-outs are on a
/// [clock](motus_clock::Clock) (the system clock unless made with
/// [`FramedLink::with_clock`]).
pub struct FramedLink<S> {
    link: Box<dyn Link>,
    stream: Stream<S>,
    clock: SharedClock,
}

impl<S: Scanner> FramedLink<S> {
    /// Reads `link` with `scanner`, on the system clock.
    pub fn new(link: Box<dyn Link>, scanner: S) -> Self {
        Self::with_clock(link, scanner, SystemClock::shared())
    }

    /// Reads `link` with `scanner`, its time-outs on `clock` (a virtual clock with an
    /// in-process [`crate::SimLink`] on the same clock).
    pub fn with_clock(link: Box<dyn Link>, scanner: S, clock: SharedClock) -> Self {
        FramedLink { link, stream: Stream::new(scanner), clock }
    }

    /// The clock of the time-outs.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }

    /// The link.
    pub fn link_mut(&mut self) -> &mut dyn Link {
        &mut *self.link
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
        let deadline = self.clock.now() + timeout;
        let mut buf = [0u8; 256];
        loop {
            if let Some(frame) = self.stream.next_frame() {
                return Ok(Some(frame));
            }
            let before = self.clock.now();
            let left = deadline.saturating_duration_since(before);
            if left.is_zero() {
                return Ok(None);
            }
            let n = self.link.read(&mut buf, left)?;
            if n == 0 && self.clock.now() == before {
                // The link waited without moving the clock (a real link on a virtual
                // clock): the wait is over, so is the time on the clock.
                self.clock.sleep_until(deadline);
            }
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
