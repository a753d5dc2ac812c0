//! Position samples with host timestamps, their history (a ring buffer), "position at
//! time t" by interpolation, and the plausibility gate that keeps corrupt values out.
//!
//! # When was a sample taken?
//! A sample carries the host [`Instant`] just before its request was handed to the line
//! and the one just after its answer was decoded. The instant it stands for
//! ([`PositionSample::at`]) is based on their **midpoint**, which needs no clock shared
//! with the device and is insensitive to a constant host latency on either side. The
//! 1209A answers with the values it published at the end of its last 1 ms regulator cycle
//! before the request's last byte arrived, so the true instant lies between the end of the
//! request and the start of the answer; the scheduler moves the midpoint back by what is
//! known of that interval ([`latch_correction`]): half the difference of the answer's and
//! the request's wire times, half the slave's turnaround, and the mean age of a published
//! value (half a regulator period). Over the simulated line the error left is about
//! ±0.5 ms (the regulator's quantisation) plus host scheduling jitter, i.e. a few
//! hundredths of a degree at the pan-tilt head's 30 deg/s.
//!
//! # Interpolation
//! [`SampleHistory::position_at`] interpolates linearly between the two samples around
//! `t`, extrapolates from the last two samples for at most a small margin after the newest
//! one, and refuses anything else (older than the history, newer than the margin, or
//! inside a gap of missed samples longer than the allowed gap).
//!
//! # Plausibility
//! The NFv2 CRC-8 misses some single-byte corruptions, so [`Gate`] accepts a position only
//! if it is kinematically consistent with the previous accepted one (within the speed and
//! acceleration the drive can reach); after a jump (homing resets the counter) two
//! mutually consistent samples re-anchor it.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// One position reading of one slave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PositionSample {
    /// Just before the request was handed to the line.
    pub request_at: Instant,
    /// Just after the answer was decoded.
    pub reply_at: Instant,
    /// The instant the value stands for: the midpoint, moved back by the latch correction.
    pub at: Instant,
    /// The position counter, encoder counts.
    pub counts: i64,
}

impl PositionSample {
    /// A sample standing for the midpoint of request and reply, moved back by `correction`.
    #[must_use]
    pub fn new(request_at: Instant, reply_at: Instant, counts: i64, correction: Duration) -> Self {
        let midpoint = request_at + reply_at.saturating_duration_since(request_at) / 2;
        let at = midpoint.checked_sub(correction).unwrap_or(midpoint).max(request_at);
        PositionSample { request_at, reply_at, at, counts }
    }

    /// The midpoint of request and reply.
    #[must_use]
    pub fn midpoint(&self) -> Instant {
        self.request_at + self.reply_at.saturating_duration_since(self.request_at) / 2
    }

    /// The instant the sample stands for (see the module documentation).
    #[must_use]
    pub fn at(&self) -> Instant {
        self.at
    }
}

/// How far before the midpoint of request and reply the value of an answer was latched:
/// `(wire(answer) - wire(request)) / 2 + turnaround / 2 + latch_age`, where `latch_age` is
/// the mean age of a published value when the request arrives (half the slave's regulator
/// period). Never negative.
#[must_use]
pub fn latch_correction(
    request: Duration,
    answer: Duration,
    turnaround: Duration,
    latch_age: Duration,
) -> Duration {
    let half = |d: Duration| d / 2;
    (half(answer) + half(turnaround) + latch_age).saturating_sub(half(request))
}

/// Why a position at a given time cannot be given.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum WhereError {
    /// No sample yet.
    #[error("no position sample yet")]
    NoSamples,
    /// Older than the oldest sample kept.
    #[error("time is {before:?} before the oldest sample kept")]
    TooOld {
        /// How far before the oldest sample.
        before: Duration,
    },
    /// Newer than the newest sample by more than the extrapolation margin.
    #[error("time is {after:?} after the newest sample (extrapolation allowed up to {margin:?})")]
    TooNew {
        /// How far after the newest sample.
        after: Duration,
        /// The extrapolation margin.
        margin: Duration,
    },
    /// Inside a gap of missed samples too long to interpolate across.
    #[error("time falls in a gap of {gap:?} without samples (at most {max_gap:?} is interpolated)")]
    Gap {
        /// Length of the gap.
        gap: Duration,
        /// The longest gap interpolated across.
        max_gap: Duration,
    },
}

/// A bounded history of samples, oldest first (a ring buffer: the oldest sample is
/// dropped when full).
#[derive(Debug, Clone)]
pub struct SampleHistory {
    samples: VecDeque<PositionSample>,
    capacity: usize,
    /// How far after the newest sample extrapolation is allowed.
    pub margin: Duration,
    /// The longest gap between two samples interpolated across.
    pub max_gap: Duration,
}

impl SampleHistory {
    /// An empty history of at most `capacity` samples (at least 2).
    #[must_use]
    pub fn new(capacity: usize, margin: Duration, max_gap: Duration) -> Self {
        let capacity = capacity.max(2);
        SampleHistory { samples: VecDeque::with_capacity(capacity), capacity, margin, max_gap }
    }

    /// Adds a sample; samples must come in order of [`PositionSample::at`] (older ones
    /// are ignored).
    pub fn push(&mut self, sample: PositionSample) {
        if self.samples.back().is_some_and(|last| sample.at() <= last.at()) {
            return;
        }
        if self.samples.len() == self.capacity {
            self.samples.pop_front();
        }
        self.samples.push_back(sample);
    }

    /// The newest sample.
    #[must_use]
    pub fn latest(&self) -> Option<PositionSample> {
        self.samples.back().copied()
    }

    /// Number of samples kept.
    #[must_use]
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// True if no sample is kept.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// All samples, oldest first.
    pub fn iter(&self) -> impl Iterator<Item = &PositionSample> {
        self.samples.iter()
    }

    /// The velocity over the last two samples, counts/s.
    #[must_use]
    pub fn velocity(&self) -> Option<f64> {
        let n = self.samples.len();
        let (a, b) = (self.samples.get(n.checked_sub(2)?)?, self.samples.get(n - 1)?);
        velocity(a, b)
    }

    /// The position (counts, fractional) at `t`: linear between the samples around it,
    /// extrapolated from the last two for at most [`SampleHistory::margin`].
    ///
    /// # Errors
    /// [`WhereError`] when `t` is outside the history (plus margin) or in a long gap.
    pub fn position_at(&self, t: Instant) -> Result<f64, WhereError> {
        let (Some(first), Some(last)) = (self.samples.front(), self.samples.back()) else {
            return Err(WhereError::NoSamples);
        };
        if t < first.at() {
            return Err(WhereError::TooOld { before: first.at() - t });
        }
        if t >= last.at() {
            let after = t - last.at();
            if after > self.margin {
                return Err(WhereError::TooNew { after, margin: self.margin });
            }
            let v = self.velocity().unwrap_or(0.0);
            return Ok(last.counts as f64 + v * after.as_secs_f64());
        }
        // first.at() <= t < last.at(): the first sample after t exists and is not the first.
        let i = self.samples.partition_point(|s| s.at() <= t);
        let (Some(a), Some(b)) = (i.checked_sub(1).and_then(|j| self.samples.get(j)), self.samples.get(i))
        else {
            return Err(WhereError::NoSamples);
        };
        let gap = b.at() - a.at();
        if gap > self.max_gap {
            return Err(WhereError::Gap { gap, max_gap: self.max_gap });
        }
        let f = (t - a.at()).as_secs_f64() / gap.as_secs_f64().max(f64::MIN_POSITIVE);
        Ok(a.counts as f64 + f * (b.counts - a.counts) as f64)
    }
}

fn velocity(a: &PositionSample, b: &PositionSample) -> Option<f64> {
    let dt = b.at().checked_duration_since(a.at())?.as_secs_f64();
    (dt > 0.0).then(|| (b.counts - a.counts) as f64 / dt)
}

/// Kinematic bounds of the plausibility gate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GateBounds {
    /// Fastest plausible speed, counts/s.
    pub speed: f64,
    /// Largest plausible acceleration, counts/s².
    pub acceleration: f64,
    /// Allowance for encoder noise and servo jitter, counts.
    pub base: f64,
    /// Uncertainty of a sample's time (host scheduling), applied to the speed.
    pub jitter: Duration,
}

/// What the gate did with a sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Consistent with the history: use it.
    Accept,
    /// Inconsistent: a corrupt value (or the first of a real jump); do not use it.
    Reject,
}

/// The plausibility gate of one slave's positions (see the module documentation).
#[derive(Debug, Clone, Default)]
pub struct Gate {
    last: Option<PositionSample>,
    velocity: Option<f64>,
    suspect: Option<PositionSample>,
}

impl Gate {
    /// Judges `sample` against the last accepted one.
    pub fn check(&mut self, sample: PositionSample, bounds: &GateBounds) -> Verdict {
        let agrees = match self.last {
            Some(last) => consistent(&last, self.velocity, &sample, bounds),
            None => false,
        };
        if agrees {
            self.accept(sample);
            return Verdict::Accept;
        }
        // A jump (or the first sample): accept once two samples agree with each other.
        let confirmed = self.suspect.is_some_and(|s| consistent(&s, None, &sample, bounds));
        if confirmed {
            self.velocity = None;
            self.last = None;
            self.accept(sample);
            self.suspect = None;
            Verdict::Accept
        } else {
            self.suspect = Some(sample);
            Verdict::Reject
        }
    }

    /// Forgets the history (after a known jump such as homing).
    pub fn reset(&mut self) {
        *self = Gate::default();
    }

    fn accept(&mut self, sample: PositionSample) {
        if let Some(last) = self.last {
            self.velocity = velocity(&last, &sample);
        }
        self.last = Some(sample);
        self.suspect = None;
    }
}

fn consistent(a: &PositionSample, v: Option<f64>, b: &PositionSample, bounds: &GateBounds) -> bool {
    let Some(dt) = b.at().checked_duration_since(a.at()) else { return false };
    let dt = dt.as_secs_f64();
    let moved = (b.counts - a.counts) as f64;
    match v {
        Some(v) => {
            let predicted = v * dt;
            let allowed =
                bounds.base + v.abs() * bounds.jitter.as_secs_f64() + 0.5 * bounds.acceleration * dt * dt;
            (moved - predicted).abs() <= allowed
        }
        None => moved.abs() <= bounds.base + bounds.speed * (dt + bounds.jitter.as_secs_f64()),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn sample(t0: Instant, ms: u64, counts: i64) -> PositionSample {
        // A 2 ms exchange whose midpoint is at `ms`.
        let at = t0 + Duration::from_millis(ms);
        let (request_at, reply_at) = (at - Duration::from_millis(1), at + Duration::from_millis(1));
        PositionSample::new(request_at, reply_at, counts, Duration::ZERO)
    }

    #[test]
    fn the_latch_correction() {
        // Request 15 B, answer 19 B at 57600 Bd: (3.299 - 2.604) / 2 + 0.1 + 0.5 ms.
        let (rq, an) =
            (motus_nfv2_protocol::wire_time(15, 57_600), motus_nfv2_protocol::wire_time(19, 57_600));
        let c = latch_correction(rq, an, Duration::from_micros(200), Duration::from_micros(500));
        assert_eq!(c.as_micros(), 947);
        let t0 = Instant::now();
        let s = PositionSample::new(t0, t0 + Duration::from_millis(6), 0, c);
        assert_eq!(s.midpoint() - s.at(), c);
        // Never before the request.
        let s = PositionSample::new(t0, t0 + Duration::from_micros(100), 0, c);
        assert_eq!(s.at(), t0);
    }

    #[test]
    fn interpolates_between_samples_and_refuses_outside() {
        let t0 = Instant::now() + Duration::from_secs(1);
        let mut h = SampleHistory::new(3, Duration::from_millis(5), Duration::from_millis(50));
        assert_eq!(h.position_at(t0), Err(WhereError::NoSamples));
        h.push(sample(t0, 0, 0));
        h.push(sample(t0, 10, 100));
        h.push(sample(t0, 20, 300));
        assert_eq!(h.position_at(t0 + Duration::from_millis(5)), Ok(50.0));
        assert_eq!(h.position_at(t0 + Duration::from_millis(15)), Ok(200.0));
        // Extrapolated from the last two samples (20 counts/ms) within the margin.
        assert_eq!(h.position_at(t0 + Duration::from_millis(24)), Ok(380.0));
        assert!(matches!(h.position_at(t0 + Duration::from_millis(26)), Err(WhereError::TooNew { .. })));
        assert!(matches!(h.position_at(t0 - Duration::from_millis(1)), Err(WhereError::TooOld { .. })));
        // The ring drops the oldest sample.
        h.push(sample(t0, 30, 400));
        assert_eq!(h.len(), 3);
        assert!(matches!(h.position_at(t0 + Duration::from_millis(5)), Err(WhereError::TooOld { .. })));
        // A gap longer than max_gap is not interpolated across.
        h.push(sample(t0, 100, 400));
        assert!(matches!(h.position_at(t0 + Duration::from_millis(60)), Err(WhereError::Gap { .. })));
        // Out-of-order samples are ignored.
        h.push(sample(t0, 90, 0));
        assert_eq!(h.latest().map(|s| s.counts), Some(400));
    }

    #[test]
    fn gate_rejects_a_corrupt_low_byte_and_follows_a_real_jump() {
        let t0 = Instant::now();
        let bounds = GateBounds {
            speed: 120_000.0,
            acceleration: 111_112.0,
            base: 20.0,
            jitter: Duration::from_millis(1),
        };
        let mut g = Gate::default();
        // The first sample needs a second one to agree with it.
        assert_eq!(g.check(sample(t0, 0, 1000), &bounds), Verdict::Reject);
        assert_eq!(g.check(sample(t0, 10, 1100), &bounds), Verdict::Accept);
        assert_eq!(g.check(sample(t0, 20, 1200), &bounds), Verdict::Accept);
        // 1300 = 0x0514 with its low byte XORed by 0xEC (a pattern CRC-8 0xD8 misses):
        // 0x05F8 = 1528, 228 counts off the 10 counts/ms line.
        assert_eq!(g.check(sample(t0, 30, 0x05F8), &bounds), Verdict::Reject);
        assert_eq!(g.check(sample(t0, 40, 1400), &bounds), Verdict::Accept);
        // Homing resets the counter: the first new value is refused, the second agrees.
        assert_eq!(g.check(sample(t0, 50, -3), &bounds), Verdict::Reject);
        assert_eq!(g.check(sample(t0, 60, 0), &bounds), Verdict::Accept);
        assert_eq!(g.check(sample(t0, 70, 1), &bounds), Verdict::Accept);
    }
}
