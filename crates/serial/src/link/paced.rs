//! Pacing: bytes leave at the real baud rate, as on a UART, so a simulator on a pty
//! takes the same wire time as a real module.

use super::{LineSettings, Link};
use std::io;
use std::time::{Duration, Instant};

/// Writes byte by byte, each completing one character time after the previous one
/// (deadlines are absolute, so scheduler overshoot does not accumulate).
pub struct Paced<L> {
    inner: L,
    line_free_at: Instant,
}

impl<L: Link> Paced<L> {
    /// Paces `inner` at its own line settings.
    pub fn new(inner: L) -> Self {
        Paced { inner, line_free_at: Instant::now() }
    }

    /// The wrapped link.
    pub fn inner_mut(&mut self) -> &mut L {
        &mut self.inner
    }
}

/// Sleeps until `deadline`, spinning for the last stretch for precision.
pub fn sleep_until(deadline: Instant) {
    const SPIN: Duration = Duration::from_micros(150);
    loop {
        let now = Instant::now();
        if now >= deadline {
            return;
        }
        let left = deadline - now;
        if left > SPIN {
            std::thread::sleep(left - SPIN);
        } else {
            std::hint::spin_loop();
        }
    }
}

impl<L: Link> Link for Paced<L> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        let ct = self.inner.line().char_time();
        let mut t = self.line_free_at.max(Instant::now());
        for b in bytes {
            t += ct;
            sleep_until(t);
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
