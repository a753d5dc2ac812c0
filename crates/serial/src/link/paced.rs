//! Pacing: bytes leave at the real baud rate, as on a UART, so a simulator on a pty
//! takes the same wire time as a real module.

use super::{LineSettings, Link};
use motus_clock::{SharedClock, SystemClock};
use std::io;
use std::time::{Duration, Instant};

/// Writes byte by byte, each completing one character time after the previous one
/// (deadlines are absolute, so scheduler overshoot does not accumulate). The waits are on
/// a [clock](motus_clock::Clock) (the system clock unless made with [`Paced::with_clock`]).
pub struct Paced<L> {
    inner: L,
    line_free_at: Instant,
    clock: SharedClock,
}

impl<L: Link> Paced<L> {
    /// Paces `inner` at its own line settings, on the system clock.
    pub fn new(inner: L) -> Self {
        Self::with_clock(inner, SystemClock::shared())
    }

    /// Paces `inner` at its own line settings, waiting on `clock`.
    pub fn with_clock(inner: L, clock: SharedClock) -> Self {
        Paced { inner, line_free_at: clock.now(), clock }
    }

    /// The wrapped link.
    pub fn inner_mut(&mut self) -> &mut L {
        &mut self.inner
    }

    /// The clock of the waits.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }
}

impl<L: Link> Link for Paced<L> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        let ct = self.inner.line().char_time();
        let mut t = self.line_free_at.max(self.clock.now());
        for b in bytes {
            t += ct;
            self.clock.sleep_until_precise(t);
            self.inner.write_all(std::slice::from_ref(b))?;
        }
        self.line_free_at = t;
        Ok(())
    }

    fn describe(&self) -> String {
        format!("paced({})", self.inner.describe())
    }

    pass_through!(read, discard_input, line);
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use motus_clock::{Clock, VirtualClock};

    /// Records the clock time of every byte written.
    struct Stamps(SharedClock, Vec<Duration>, Instant);

    impl Link for Stamps {
        fn write_all(&mut self, _: &[u8]) -> io::Result<()> {
            self.1.push(self.0.elapsed(self.2));
            Ok(())
        }
        fn read(&mut self, _: &mut [u8], _: Duration) -> io::Result<usize> {
            Ok(0)
        }
        fn discard_input(&mut self) -> io::Result<()> {
            Ok(())
        }
        fn line(&self) -> LineSettings {
            LineSettings::n81(10_000)
        }
        fn describe(&self) -> String {
            "stamps".into()
        }
    }

    #[test]
    fn bytes_leave_one_character_time_apart_on_the_clock() {
        let clock = VirtualClock::new();
        let t0 = clock.now();
        let mut link = Paced::with_clock(Stamps(clock.shared(), Vec::new(), t0), clock.shared());
        link.write_all(&[1, 2, 3]).unwrap();
        // The next write follows the first on the line.
        link.write_all(&[4]).unwrap();
        let ms: Vec<u128> = link.inner_mut().1.iter().map(Duration::as_micros).collect();
        assert_eq!(ms, vec![1000, 2000, 3000, 4000]);
        assert_eq!(clock.since_base(), Duration::from_millis(4));
    }
}
