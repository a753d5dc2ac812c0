//! Rate-limited logging of a failure that repeats (a closed bus fails every receive, every
//! heartbeat): one line when it starts, while it lasts at most one summary per period, and
//! one line when it ends. Time is an argument, so it is tested on virtual time.

use std::time::{Duration, Instant};

/// What to log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Note {
    /// The first failure.
    Started {
        /// Its error.
        error: String,
    },
    /// Still failing.
    Summary {
        /// Failures since it started.
        failures: u64,
        /// For this long.
        failing_for: Duration,
        /// The last error.
        last_error: String,
    },
    /// It works again.
    Ended {
        /// Failures in all.
        failures: u64,
        /// It failed for this long.
        failing_for: Duration,
    },
}

struct Run {
    since: Instant,
    failures: u64,
    last_note: Instant,
}

/// One repeating failure's log (see the module documentation).
pub(crate) struct FailureLog {
    what: &'static str,
    summary_every: Duration,
    run: Option<Run>,
}

impl FailureLog {
    /// The log of `what` (e.g. "CAN receive"), with a summary at most every `summary_every`.
    pub(crate) fn new(what: &'static str, summary_every: Duration) -> Self {
        Self { what, summary_every, run: None }
    }

    /// A failure at `now`.
    pub(crate) fn failed(&mut self, now: Instant, error: &dyn std::fmt::Display) -> Option<Note> {
        match &mut self.run {
            None => {
                self.run = Some(Run { since: now, failures: 1, last_note: now });
                Some(Note::Started { error: error.to_string() })
            }
            Some(r) => {
                r.failures = r.failures.saturating_add(1);
                if now.saturating_duration_since(r.last_note) < self.summary_every {
                    return None;
                }
                r.last_note = now;
                Some(Note::Summary {
                    failures: r.failures,
                    failing_for: now.saturating_duration_since(r.since),
                    last_error: error.to_string(),
                })
            }
        }
    }

    /// A success at `now`.
    pub(crate) fn succeeded(&mut self, now: Instant) -> Option<Note> {
        let r = self.run.take()?;
        Some(Note::Ended { failures: r.failures, failing_for: now.saturating_duration_since(r.since) })
    }

    /// Logs `note` (about `bus`).
    pub(crate) fn emit(&self, note: &Note, bus: &str) {
        let what = self.what;
        match note {
            Note::Started { error } => tracing::warn!(bus, %error, "{what} failed"),
            Note::Summary { failures, failing_for, last_error } => {
                tracing::warn!(bus, failures, ?failing_for, %last_error, "{what} still failing")
            }
            Note::Ended { failures, failing_for } => {
                tracing::info!(bus, failures, ?failing_for, "{what} works again")
            }
        }
    }

    /// [`Self::failed`] and [`Self::emit`].
    pub(crate) fn fail(&mut self, now: Instant, error: &dyn std::fmt::Display, bus: &str) {
        if let Some(n) = self.failed(now, error) {
            self.emit(&n, bus);
        }
    }

    /// [`Self::succeeded`] and [`Self::emit`].
    pub(crate) fn succeed(&mut self, now: Instant, bus: &str) {
        if let Some(n) = self.succeeded(now) {
            self.emit(&n, bus);
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn a_failure_every_20_ms_for_12_s_is_three_lines_and_one_when_it_ends() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut log = FailureLog::new("CAN receive", Duration::from_secs(5));
        assert_eq!(log.succeeded(t0), None, "nothing to say while it works");
        let notes: Vec<Note> = (0..600u64).filter_map(|i| log.failed(t0 + ms(i * 20), &"closed")).collect();
        assert_eq!(
            notes,
            vec![
                Note::Started { error: "closed".into() },
                Note::Summary { failures: 251, failing_for: ms(5000), last_error: "closed".into() },
                Note::Summary { failures: 501, failing_for: ms(10_000), last_error: "closed".into() },
            ]
        );
        assert_eq!(
            log.succeeded(t0 + ms(12_000)),
            Some(Note::Ended { failures: 600, failing_for: ms(12_000) })
        );
        assert_eq!(log.failed(t0 + ms(12_020), &"again"), Some(Note::Started { error: "again".into() }));
    }
}
