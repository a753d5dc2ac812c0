//! Hex dumps of all traffic to `tracing` at TRACE level.

use super::{LineSettings, Link};
use std::io;
use std::time::Duration;

/// Logs every write and read as hex.
pub struct Traced<L> {
    inner: L,
}

impl<L: Link> Traced<L> {
    /// Wraps `inner`.
    pub fn new(inner: L) -> Self {
        Traced { inner }
    }
}

/// Uppercase hex bytes separated by spaces.
pub fn hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 3);
    for (i, b) in bytes.iter().enumerate() {
        if i > 0 {
            s.push(' ');
        }
        s.push_str(&format!("{b:02X}"));
    }
    s
}

impl<L: Link> Link for Traced<L> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        tracing::trace!(link = %self.inner.describe(), tx = %hex(bytes));
        self.inner.write_all(bytes)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let n = self.inner.read(buf, timeout)?;
        if n > 0 {
            tracing::trace!(link = %self.inner.describe(), rx = %hex(buf.get(..n).unwrap_or(&[])));
        }
        Ok(n)
    }

    fn describe(&self) -> String {
        self.inner.describe()
    }

    pass_through!(discard_input, line);
}
