//! Triggers: start a capture on a condition of one signal, with pre-trigger samples.

use std::time::Duration;

use super::ring::Sample;
use super::SignalId;

/// When a trigger fires, evaluated on every new sample of its signal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Condition {
    /// The value crosses the threshold upwards (previous < threshold <= new).
    Rising(f64),
    /// The value crosses the threshold downwards (previous > threshold >= new).
    Falling(f64),
    /// The value is above the threshold.
    Above(f64),
    /// The value is below the threshold.
    Below(f64),
}

impl Condition {
    /// Whether the condition holds for `new` after `previous` (`None`: first sample,
    /// where edges cannot fire).
    pub fn fires(&self, previous: Option<f64>, new: f64) -> bool {
        match *self {
            Condition::Rising(th) => previous.is_some_and(|p| p < th && new >= th),
            Condition::Falling(th) => previous.is_some_and(|p| p > th && new <= th),
            Condition::Above(th) => new > th,
            Condition::Below(th) => new < th,
        }
    }
}

/// A capture request: when `condition` holds on `signal`, keep the window from
/// `pre_samples` samples before to `post_samples` samples after (counted on the trigger
/// signal), for every signal. One-shot: the trigger disarms when it fires.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trigger {
    /// The watched signal.
    pub signal: SignalId,
    /// When to fire.
    pub condition: Condition,
    /// Samples of the trigger signal kept before the trigger sample.
    pub pre_samples: usize,
    /// Samples of the trigger signal recorded after the trigger sample before the capture
    /// is complete.
    pub post_samples: usize,
}

/// Identifies an armed trigger.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TriggerId(pub u64);

/// The samples of one signal in a capture.
#[derive(Debug, Clone, PartialEq)]
pub struct CapturedSignal {
    /// Which signal.
    pub signal: SignalId,
    /// Its samples inside the window, oldest first.
    pub samples: Vec<Sample>,
}

/// A completed capture.
#[derive(Debug, Clone, PartialEq)]
pub struct Capture {
    /// The trigger that fired.
    pub id: TriggerId,
    /// Its definition.
    pub trigger: Trigger,
    /// Time of the sample that fired it.
    pub fired_at: Duration,
    /// The value that fired it.
    pub fired_value: f64,
    /// Window start and end (times of the first and last trigger-signal samples kept).
    pub window: (Duration, Duration),
    /// Every signal's samples in the window, in registration order.
    pub signals: Vec<CapturedSignal>,
}

/// A trigger waiting to fire or to complete.
#[derive(Debug, Clone)]
pub(crate) struct Armed {
    pub id: TriggerId,
    pub trigger: Trigger,
    /// Set when fired: (time, value, trigger signal's sequence number, window start).
    pub fired: Option<(Duration, f64, u64, Duration)>,
}

impl Armed {
    pub(crate) fn new(id: TriggerId, trigger: Trigger) -> Self {
        Armed { id, trigger, fired: None }
    }

    /// Called with the trigger signal's new sample (`seq`), its previous value and the
    /// time of the sample `pre_samples` before; returns true when the capture is complete.
    pub(crate) fn on_sample(&mut self, prev: Option<f64>, s: Sample, seq: u64, pre_start: Duration) -> bool {
        match self.fired {
            None => {
                if self.trigger.condition.fires(prev, s.value) {
                    self.fired = Some((s.t, s.value, seq, pre_start));
                    self.trigger.post_samples == 0
                } else {
                    false
                }
            }
            Some((_, _, at, _)) => seq >= at + self.trigger.post_samples as u64,
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn conditions() {
        assert!(Condition::Rising(1.0).fires(Some(0.5), 1.0));
        assert!(!Condition::Rising(1.0).fires(Some(1.0), 2.0)); // was not below
        assert!(!Condition::Rising(1.0).fires(None, 2.0));
        assert!(Condition::Falling(0.0).fires(Some(0.1), -0.1));
        assert!(!Condition::Falling(0.0).fires(Some(-0.1), -0.2));
        assert!(Condition::Above(3.0).fires(None, 3.5));
        assert!(!Condition::Above(3.0).fires(None, 3.0));
        assert!(Condition::Below(3.0).fires(Some(9.0), 2.0));
    }
}
