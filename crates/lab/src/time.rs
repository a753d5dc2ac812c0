//! Wall-clock instants as milliseconds since the Unix epoch.
//!
//! Every operation of this crate takes the current time as an argument (`now`), so the logic
//! never reads a clock and tests are deterministic. The station converts
//! `SystemTime::now()` with [`UnixMs::from`] at its edge.

use std::fmt;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use serde::{Deserialize, Serialize};

/// An instant: milliseconds since 1970-01-01T00:00:00Z (negative before it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize)]
#[serde(transparent)]
pub struct UnixMs(pub i64);

impl UnixMs {
    /// The epoch itself.
    pub const EPOCH: UnixMs = UnixMs(0);

    /// This instant plus `d` (saturating at the end of the range).
    #[must_use]
    pub fn plus(self, d: Duration) -> UnixMs {
        UnixMs(self.0.saturating_add(duration_ms(d)))
    }

    /// This instant minus `d` (saturating at the start of the range).
    #[must_use]
    pub fn minus(self, d: Duration) -> UnixMs {
        UnixMs(self.0.saturating_sub(duration_ms(d)))
    }

    /// Time elapsed from `earlier` to `self`; zero when `earlier` is later.
    #[must_use]
    pub fn since(self, earlier: UnixMs) -> Duration {
        let ms = self.0.saturating_sub(earlier.0);
        Duration::from_millis(u64::try_from(ms).unwrap_or(0))
    }

    /// Converts to a `SystemTime` (saturating at the epoch for negative values).
    #[must_use]
    pub fn to_system_time(self) -> SystemTime {
        UNIX_EPOCH + Duration::from_millis(u64::try_from(self.0).unwrap_or(0))
    }
}

impl From<SystemTime> for UnixMs {
    /// Truncates to whole milliseconds; instants before the epoch become negative.
    fn from(t: SystemTime) -> Self {
        match t.duration_since(UNIX_EPOCH) {
            Ok(d) => UnixMs(duration_ms(d)),
            Err(e) => UnixMs(duration_ms(e.duration()).saturating_neg()),
        }
    }
}

impl fmt::Display for UnixMs {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}ms", self.0)
    }
}

/// A duration in whole milliseconds as `i64`, saturating.
pub(crate) fn duration_ms(d: Duration) -> i64 {
    i64::try_from(d.as_millis()).unwrap_or(i64::MAX)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn arithmetic_and_conversion() {
        let t = UnixMs(1_000);
        assert_eq!(t.plus(Duration::from_secs(2)), UnixMs(3_000));
        assert_eq!(t.minus(Duration::from_millis(1_500)), UnixMs(-500));
        assert_eq!(UnixMs(3_000).since(t), Duration::from_secs(2));
        assert_eq!(t.since(UnixMs(3_000)), Duration::ZERO);
        let st = UNIX_EPOCH + Duration::from_millis(1_234_567);
        assert_eq!(UnixMs::from(st), UnixMs(1_234_567));
        assert_eq!(UnixMs(1_234_567).to_system_time(), st);
        assert_eq!(UnixMs::from(UNIX_EPOCH - Duration::from_millis(5)), UnixMs(-5));
        assert_eq!(UnixMs(i64::MAX).plus(Duration::from_secs(1)), UnixMs(i64::MAX));
    }
}
