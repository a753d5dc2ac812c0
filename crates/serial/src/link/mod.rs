//! The byte-IO seam and its implementations.

/// Methods a decorator passes through to its `inner` link unchanged (the caller imports
/// `io`, `Duration` and `LineSettings`).
macro_rules! pass_through {
    ($($method:ident),*) => { $(pass_through!(@ $method);)* };
    (@ read) => {
        fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
            self.inner.read(buf, timeout)
        }
    };
    (@ discard_input) => {
        fn discard_input(&mut self) -> io::Result<()> {
            self.inner.discard_input()
        }
    };
    (@ line) => {
        fn line(&self) -> LineSettings {
            self.inner.line()
        }
    };
}

pub mod fault;
pub mod framed;
pub mod paced;
pub mod pty;
pub mod serial_port;
pub mod sim;
pub mod trace;

use std::io;
use std::time::Duration;

/// Framing of characters on the line: the wire time of a byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineSettings {
    /// Bits per second.
    pub baud: u32,
    /// Bits per character on the wire: start + data + parity + stop (10 for 8N1).
    pub bits_per_char: u32,
}

impl LineSettings {
    /// 8 data bits, no parity, 1 stop bit.
    pub fn n81(baud: u32) -> Self {
        LineSettings { baud, bits_per_char: 10 }
    }

    /// Time one character occupies the line.
    pub fn char_time(&self) -> Duration {
        self.wire_time(1)
    }

    /// Time `bytes` characters occupy the line.
    pub fn wire_time(&self, bytes: usize) -> Duration {
        let bits = u64::try_from(bytes).unwrap_or(u64::MAX).saturating_mul(u64::from(self.bits_per_char));
        let nanos = bits.saturating_mul(1_000_000_000) / u64::from(self.baud.max(1));
        Duration::from_nanos(nanos)
    }
}

/// A bidirectional byte stream: a serial port, one side of a pseudo-terminal, or a
/// decorator around another link.
pub trait Link: Send {
    /// Writes all bytes (returns when they are handed to the OS, or, for paced links,
    /// when they would have left the wire).
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()>;

    /// Reads what is available, waiting at most `timeout` for the first byte.
    /// `Ok(0)` means the time-out elapsed with nothing received.
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;

    /// Drops bytes received but not yet read.
    fn discard_input(&mut self) -> io::Result<()>;

    /// Baud rate and character framing.
    fn line(&self) -> LineSettings;

    /// A description for messages (e.g. the device path).
    fn describe(&self) -> String;
}

/// A link behind a pointer is a link (a boxed one, or a borrowed one that outlives a
/// decorator).
macro_rules! link_behind {
    ($pointer:ty) => {
        impl<L: Link + ?Sized> Link for $pointer {
            fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
                (**self).write_all(bytes)
            }
            fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
                (**self).read(buf, timeout)
            }
            fn discard_input(&mut self) -> io::Result<()> {
                (**self).discard_input()
            }
            fn line(&self) -> LineSettings {
                (**self).line()
            }
            fn describe(&self) -> String {
                (**self).describe()
            }
        }
    };
}

link_behind!(Box<L>);
link_behind!(&mut L);

/// A link shared between owners: one gives it to a bus master or a framed reader, another
/// keeps a handle to look at it (an in-process [`crate::SimLink`]'s counters, say). Each call
/// takes the lock for its duration.
#[derive(Debug, Default)]
pub struct SharedLink<L>(std::sync::Arc<std::sync::Mutex<L>>);

impl<L> Clone for SharedLink<L> {
    fn clone(&self) -> Self {
        SharedLink(std::sync::Arc::clone(&self.0))
    }
}

impl<L> SharedLink<L> {
    /// Shares `link`.
    pub fn new(link: L) -> Self {
        SharedLink(std::sync::Arc::new(std::sync::Mutex::new(link)))
    }

    /// The link, locked (a poisoned lock is taken all the same).
    pub fn get(&self) -> std::sync::MutexGuard<'_, L> {
        self.0.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

impl<L: Link> Link for SharedLink<L> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.get().write_all(bytes)
    }
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        self.get().read(buf, timeout)
    }
    fn discard_input(&mut self) -> io::Result<()> {
        self.get().discard_input()
    }
    fn line(&self) -> LineSettings {
        self.get().line()
    }
    fn describe(&self) -> String {
        self.get().describe()
    }
}

/// A shared link is a link: the owner of the other handle can still reach it (e.g. a test
/// that gave a [`sim::SimLink`] to a bus master and reads its statistics).
impl<L: Link + ?Sized> Link for std::sync::Arc<std::sync::Mutex<L>> {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        lock(self).write_all(bytes)
    }
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        lock(self).read(buf, timeout)
    }
    fn discard_input(&mut self) -> io::Result<()> {
        lock(self).discard_input()
    }
    fn line(&self) -> LineSettings {
        lock(self).line()
    }
    fn describe(&self) -> String {
        lock(self).describe()
    }
}

fn lock<L: ?Sized>(link: &std::sync::Mutex<L>) -> std::sync::MutexGuard<'_, L> {
    link.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_time_at_9600() {
        // 12 bytes of 10 bits at 9600 Bd = 12.5 ms.
        assert_eq!(LineSettings::n81(9600).wire_time(12), Duration::from_micros(12_500));
    }
}
