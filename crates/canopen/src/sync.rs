//! SYNC producer schedule (CiA 301 §7.2.5): absolute deadlines `start + k·period` and an
//! optional 1-byte counter that runs 1..=overflow (object 0x1019, 2..=240).

use std::time::{Duration, Instant};

use motus_canopen_protocol::{CanFrame, FrameError};

/// COB-ID of SYNC (default of 0x1005).
pub const SYNC_COB_ID: u32 = 0x080;

/// Why a SYNC schedule cannot be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SyncError {
    /// The period is zero.
    #[error("SYNC period must be positive")]
    ZeroPeriod,
    /// The counter overflow value is outside 2..=240 (CiA 301, object 0x1019).
    #[error("SYNC counter overflow {0} outside 2..=240")]
    BadOverflow(u8),
}

/// The SYNC frame: DLC 0 without counter, DLC 1 with it.
pub fn sync_frame(counter: Option<u8>) -> Result<CanFrame, FrameError> {
    match counter {
        Some(c) => CanFrame::new(SYNC_COB_ID, &[c]),
        None => CanFrame::new(SYNC_COB_ID, &[]),
    }
}

/// SYNC producer schedule.
#[derive(Debug, Clone)]
pub struct SyncSchedule {
    period: Duration,
    overflow: Option<u8>,
    counter: u8,
    next: Instant,
    sent: u64,
}

impl SyncSchedule {
    /// A schedule whose first SYNC is due at `start`.
    pub fn new(period: Duration, counter_overflow: Option<u8>, start: Instant) -> Result<Self, SyncError> {
        if period.is_zero() {
            return Err(SyncError::ZeroPeriod);
        }
        if let Some(o) = counter_overflow {
            if !(2..=240).contains(&o) {
                return Err(SyncError::BadOverflow(o));
            }
        }
        Ok(Self { period, overflow: counter_overflow, counter: 1, next: start, sent: 0 })
    }

    /// When the next SYNC is due.
    pub fn next_deadline(&self) -> Instant {
        self.next
    }

    /// The period.
    pub fn period(&self) -> Duration {
        self.period
    }

    /// SYNC frames produced so far.
    pub fn sent(&self) -> u64 {
        self.sent
    }

    /// If a SYNC is due at `now`, returns it and advances to the next absolute deadline.
    /// Deadlines missed entirely (the caller was late by more than a period) are skipped,
    /// not sent in a burst.
    pub fn poll(&mut self, now: Instant) -> Option<CanFrame> {
        if now < self.next {
            return None;
        }
        let counter = self.overflow.map(|o| {
            let c = self.counter;
            self.counter = if c >= o { 1 } else { c + 1 };
            c
        });
        self.next += self.period;
        while self.next <= now {
            self.next += self.period;
        }
        self.sent += 1;
        // 0x080 with 0 or 1 byte is always a valid frame.
        sync_frame(counter).ok()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn counter_wraps_at_overflow_and_deadlines_are_absolute() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut s = SyncSchedule::new(ms(10), Some(3), t0).unwrap();
        let mut frames = Vec::new();
        for k in 0..5u32 {
            // Late by 3 ms each time: deadlines stay on the t0 + k·10 ms grid.
            frames.push(s.poll(t0 + ms(10) * k + ms(3)).unwrap().to_string());
            assert_eq!(s.next_deadline(), t0 + ms(10) * (k + 1));
        }
        // 080#01 .. counter 1, 2, 3, then back to 1 (CiA 301: counter 1..=overflow).
        assert_eq!(frames, ["080#01", "080#02", "080#03", "080#01", "080#02"]);
        assert!(s.poll(t0 + ms(45)).is_none());
    }

    #[test]
    fn without_counter_dlc_is_zero_and_missed_deadlines_are_skipped() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut s = SyncSchedule::new(ms(10), None, t0).unwrap();
        assert_eq!(s.poll(t0).unwrap().dlc(), 0);
        // 35 ms late: one SYNC, next deadline on the grid after now (t0 + 40).
        assert!(s.poll(t0 + ms(35)).is_some());
        assert_eq!(s.next_deadline(), t0 + ms(40));
        assert_eq!(SyncSchedule::new(ms(1), Some(1), t0).unwrap_err(), SyncError::BadOverflow(1));
        assert_eq!(SyncSchedule::new(ms(0), None, t0).unwrap_err(), SyncError::ZeroPeriod);
    }
}
