//! The wall clock the server reads (injectable so tests can expire sessions and lockouts).

use std::sync::atomic::{AtomicI64, Ordering};
use std::time::{Duration, SystemTime};

use motus_lab::UnixMs;

/// A source of the current time.
pub trait Clock: Send + Sync {
    /// Now.
    fn now(&self) -> UnixMs;
}

/// The system clock.
#[derive(Debug, Clone, Copy, Default)]
pub struct SystemClock;

impl Clock for SystemClock {
    fn now(&self) -> UnixMs {
        UnixMs::from(SystemTime::now())
    }
}

/// The system clock plus an offset that tests advance (time never goes backwards).
#[derive(Debug, Default)]
pub struct OffsetClock {
    offset_ms: AtomicI64,
}

impl OffsetClock {
    /// A clock equal to the system clock.
    #[must_use]
    pub fn new() -> Self {
        OffsetClock { offset_ms: AtomicI64::new(0) }
    }

    /// Moves this clock `d` ahead.
    pub fn advance(&self, d: Duration) {
        let ms = i64::try_from(d.as_millis()).unwrap_or(i64::MAX);
        self.offset_ms.fetch_add(ms, Ordering::SeqCst);
    }
}

impl Clock for OffsetClock {
    fn now(&self) -> UnixMs {
        let UnixMs(t) = SystemClock.now();
        UnixMs(t.saturating_add(self.offset_ms.load(Ordering::SeqCst)))
    }
}
